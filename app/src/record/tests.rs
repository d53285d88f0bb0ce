//! Tests of [`crate::record`]: uploads accepted and refused whole, the record in force kept.

use super::*;
extern crate std;
use rths_link::record_checksum;
use std::vec::Vec;

const COMPILED: [f64; 5] = [0.0, 0.1, -0.2, 0.05, 0.0];
const DT: f64 = 0.01;

fn ramp(n: usize) -> Vec<f64> {
    (0..n).map(|i| libm::sin(i as f64 * 0.37) * 0.3).collect()
}

/// Upload `samples` in chunks; the first refusal.
fn upload(s: &mut RecordStore<'_>, samples: &[f64], dt_s: f64) -> Result<RecordInfo, NackReason> {
    let c = record_checksum(samples, dt_s);
    s.begin(samples.len() as u32, dt_s, 1.0, c, true)?;
    for (i, ch) in samples.chunks(RECORD_CHUNK).enumerate() {
        let mut v = [0.0; RECORD_CHUNK];
        v[..ch.len()].copy_from_slice(ch);
        s.chunk(i as u32, ch.len() as u8, &v, true)?;
    }
    s.commit(true)
}

fn chunk_of(samples: &[f64], i: usize) -> (u8, [f64; RECORD_CHUNK]) {
    let ch = samples.chunks(RECORD_CHUNK).nth(i).unwrap();
    let mut v = [0.0; RECORD_CHUNK];
    v[..ch.len()].copy_from_slice(ch);
    (ch.len() as u8, v)
}

#[test]
fn the_compiled_record_plays_until_an_upload_is_committed() {
    let mut buf = [0.0; 200];
    let ticks = Record::new(&COMPILED, DT).ticks(DT_S) as u32;
    let mut s = RecordStore::new(&COMPILED, DT, ticks, &mut buf);
    assert_eq!(s.capacity(), 100);
    let i = s.info();
    assert_eq!(i.source, RecordSource::Compiled);
    assert_eq!(i.checksum, record_checksum(&COMPILED, DT));
    assert_eq!(s.ticks(), ticks);
    let compiled = Record::new(&COMPILED, DT);
    for k in 0..ticks {
        assert_eq!(
            s.accel_mm_s2(k).to_bits(),
            compiled.accel_mm_s2(k as usize, DT_S).to_bits()
        );
    }
    assert_eq!(s.accel_mm_s2(ticks), 0.0, "0 after the end");

    let new = ramp(97);
    let info = upload(&mut s, &new, 0.02).unwrap();
    assert_eq!(info.source, RecordSource::Uploaded);
    assert_eq!(info.samples, 97);
    let host = Record::new(&new, 0.02);
    assert_eq!(info.ticks as usize, host.ticks(DT_S));
    for k in 0..info.ticks {
        assert_eq!(
            s.accel_mm_s2(k).to_bits(),
            host.accel_mm_s2(k as usize, DT_S).to_bits(),
            "tick {k}: the host's interpolation bit for bit"
        );
    }
    // A second upload goes to the other half and replaces it; a third back into the first.
    let second = ramp(100);
    upload(&mut s, &second, 0.005).unwrap();
    let third = ramp(30);
    upload(&mut s, &third, DT).unwrap();
    assert_eq!(s.info().checksum, record_checksum(&third, DT));
    let host = Record::new(&third, DT);
    for k in 0..s.ticks() {
        assert_eq!(s.accel_mm_s2(k), host.accel_mm_s2(k as usize, DT_S));
    }
}

#[test]
fn bad_uploads_are_refused_whole_and_the_record_in_force_stays() {
    let mut buf = [0.0; 200];
    let mut s = RecordStore::new(&COMPILED, DT, 10, &mut buf);
    let good = ramp(50);
    let good_info = upload(&mut s, &good, DT).unwrap();
    let keep = |s: &RecordStore<'_>| {
        assert_eq!(s.info(), good_info);
        let host = Record::new(&good, DT);
        for k in (0..good_info.ticks).step_by(7) {
            assert_eq!(s.accel_mm_s2(k), host.accel_mm_s2(k as usize, DT_S));
        }
    };
    let new = ramp(40);
    let c = record_checksum(&new, DT);

    // Header refusals.
    assert_eq!(s.begin(101, DT, 1.0, c, true), Err(NackReason::TooLong));
    assert_eq!(s.begin(1, DT, 1.0, c, true), Err(NackReason::TooLong));
    for dt in [f64::NAN, 0.0, -0.01, 1e-4, 0.5, f64::INFINITY] {
        assert_eq!(s.begin(40, dt, 1.0, c, true), Err(NackReason::Rate), "{dt}");
    }
    assert_eq!(
        s.begin(40, DT, f64::NAN, c, true),
        Err(NackReason::NotFinite)
    );
    assert_eq!(s.begin(40, DT, 1.0, c, false), Err(NackReason::Busy));
    keep(&s);

    // A chunk or commit without a begin.
    let (n0, v0) = chunk_of(&new, 0);
    assert_eq!(s.chunk(0, n0, &v0, true), Err(NackReason::Sequence));
    assert_eq!(s.commit(true), Err(NackReason::Sequence));

    // Reordered (chunk 1 first), duplicated (chunk 0 twice), skipped (truncated in the middle).
    let (n1, v1) = chunk_of(&new, 1);
    s.begin(40, DT, 1.0, c, true).unwrap();
    assert_eq!(s.chunk(1, n1, &v1, true), Err(NackReason::Sequence));
    assert!(!s.uploading(), "dropped whole");
    assert_eq!(
        s.chunk(0, n0, &v0, true),
        Err(NackReason::Sequence),
        "must begin again"
    );
    s.begin(40, DT, 1.0, c, true).unwrap();
    s.chunk(0, n0, &v0, true).unwrap();
    assert_eq!(s.chunk(0, n0, &v0, true), Err(NackReason::Sequence));
    keep(&s);

    // Truncated: commit before the last chunk.
    s.begin(40, DT, 1.0, c, true).unwrap();
    for i in 0..3 {
        let (n, v) = chunk_of(&new, i);
        s.chunk(i as u32, n, &v, true).unwrap();
    }
    assert_eq!(s.commit(true), Err(NackReason::Incomplete));
    keep(&s);

    // Corrupted: a sample changed (the frame CRC passed: a host bug) fails the end-to-end checksum.
    s.begin(40, DT, 1.0, c, true).unwrap();
    for i in 0..4 {
        let (n, mut v) = chunk_of(&new, i);
        if i == 2 {
            v[3] = f64::from_bits(v[3].to_bits() ^ 1);
        }
        s.chunk(i as u32, n, &v, true).unwrap();
    }
    assert_eq!(s.commit(true), Err(NackReason::Checksum));
    keep(&s);

    // A NaN, a count of 0, a count past the announced length, a chunk or commit under a test.
    s.begin(40, DT, 1.0, c, true).unwrap();
    let (n, mut v) = chunk_of(&new, 0);
    v[5] = f64::NAN;
    assert_eq!(s.chunk(0, n, &v, true), Err(NackReason::NotFinite));
    s.begin(40, DT, 1.0, c, true).unwrap();
    assert_eq!(s.chunk(0, 0, &v0, true), Err(NackReason::Incomplete));
    s.begin(14, DT, 1.0, c, true).unwrap();
    s.chunk(0, n0, &v0, true).unwrap();
    assert_eq!(s.chunk(1, n1, &v1, true), Err(NackReason::Incomplete));
    s.begin(40, DT, 1.0, c, true).unwrap();
    assert_eq!(s.chunk(0, n0, &v0, false), Err(NackReason::Busy));
    assert!(s.uploading(), "refused as busy: the upload is still there");
    for i in 0..4 {
        let (n, v) = chunk_of(&new, i);
        s.chunk(i as u32, n, &v, true).unwrap();
    }
    assert_eq!(s.commit(false), Err(NackReason::Busy));
    keep(&s);
    // ... and once at rest it commits.
    let info = s.commit(true).unwrap();
    assert_eq!(info.checksum, c);
}

#[test]
fn a_board_without_a_buffer_refuses_uploads() {
    let mut s = RecordStore::new(&COMPILED, DT, 10, &mut []);
    assert_eq!(s.capacity(), 0);
    assert_eq!(s.begin(2, DT, 1.0, 0, true), Err(NackReason::Unsupported));
    assert_eq!(s.info().source, RecordSource::Compiled);
}

/// Fill the ring of the stream in progress (the host's prefill): chunks from `*next` while the
/// stream can take a whole one; the last answer.
fn feed(s: &mut RecordStore<'_>, samples: &[f64], next: &mut usize) -> Option<ChunkAnswer> {
    let mut last = None;
    while let Some(ch) = samples.chunks(RECORD_CHUNK).nth(*next) {
        let free = s.stream_status().unwrap().free as usize;
        if free < ch.len() {
            break;
        }
        let (n, v) = chunk_of(samples, *next);
        let a = s.stream_chunk(*next as u32, n, &v).unwrap();
        assert_eq!(a.next_seq as usize, *next + 1, "taken");
        *next += 1;
        last = Some(a);
    }
    last
}

/// A record ten times the ring, streamed as the run reads it (the host topping the ring up before
/// every tick), plays the host's interpolation of the whole record bit for bit, and its end-to-end
/// checksum is checked when its last sample arrives.
#[test]
fn a_streamed_record_ten_times_the_ring_plays_the_whole_records_interpolation() {
    let mut buf = [0.0; 200];
    let mut s = RecordStore::new(&COMPILED, DT, 10, &mut buf);
    let long = ramp(1000);
    let dt = 0.005;
    s.stream_begin(1000, dt, 0.5, record_checksum(&long, dt), true)
        .unwrap();
    let mut next = 0;
    feed(&mut s, &long, &mut next);
    let st = s.stream_status().unwrap();
    assert!(!st.in_force);
    assert_eq!(
        (st.received, st.free),
        (96, 4),
        "the ring's 100 samples in chunks of 12"
    );
    assert_eq!(
        s.info().source,
        RecordSource::Compiled,
        "not in force before its commit"
    );
    let info = s.commit(true).unwrap();
    assert_eq!(info.source, RecordSource::Streamed);
    assert_eq!((info.samples, info.scale), (1000, 0.5));
    let host = Record::new(&long, dt);
    assert_eq!(info.ticks as usize, host.ticks(DT_S));
    assert!(s.playable());
    for k in 0..info.ticks {
        feed(&mut s, &long, &mut next);
        let p = s.play(k);
        assert!(!p.underrun, "tick {k}");
        assert_eq!(
            p.accel_mm_s2.to_bits(),
            host.accel_mm_s2(k as usize, DT_S).to_bits(),
            "tick {k}"
        );
    }
    assert_eq!(s.play(info.ticks).accel_mm_s2, 0.0, "0 after the end");
    let st = s.stream_status().unwrap();
    assert_eq!((st.received, st.underrun_ticks), (1000, 0));
    assert_eq!(st.checksum_ok, Some(true));
    assert!(
        !s.playable(),
        "played once: its ring no longer holds its start"
    );
    // Tick 0 again (a real rig at rest after the run): a read, not an underrun.
    assert!(!s.play(0).underrun);
    assert_eq!(s.stream_status().unwrap().underrun_ticks, 0);
}

/// A host that stops sending: the ticks whose samples have not arrived play 0 g and are counted,
/// the first one named; once the samples come again the record plays on, bit for bit.
#[test]
fn a_stream_that_runs_dry_counts_its_underrun_and_plays_on_when_samples_come() {
    let mut buf = [0.0; 200];
    let mut s = RecordStore::new(&COMPILED, DT, 10, &mut buf);
    let long = ramp(500);
    let dt = 0.005;
    s.stream_begin(500, dt, 1.0, record_checksum(&long, dt), true)
        .unwrap();
    let mut next = 0;
    feed(&mut s, &long, &mut next);
    s.commit(true).unwrap();
    let host = Record::new(&long, dt);
    // 96 samples held: tick k reads samples i and i + 1, i = floor(k·DT_S/dt).
    let dry = (0..)
        .find(|k| (*k as f64 * DT_S / dt).floor() as usize + 1 >= 96)
        .unwrap();
    for k in 0..dry + 50 {
        let p = s.play(k);
        if k < dry {
            assert_eq!(
                p.accel_mm_s2,
                host.accel_mm_s2(k as usize, DT_S),
                "tick {k}"
            );
        } else {
            assert!(p.underrun && p.accel_mm_s2 == 0.0, "tick {k}");
        }
    }
    let st = s.stream_status().unwrap();
    assert_eq!(st.underrun_ticks, 50);
    assert_eq!(st.first_underrun_tick, Some(dry));
    // The host catches up: the samples the run has passed are taken and skipped.
    for k in dry + 50..host.ticks(DT_S) as u32 {
        feed(&mut s, &long, &mut next);
        let p = s.play(k);
        assert!(!p.underrun, "tick {k}");
        assert_eq!(p.accel_mm_s2, host.accel_mm_s2(k as usize, DT_S));
    }
    assert_eq!(s.stream_status().unwrap().underrun_ticks, 50);
}

/// The flow control and the stream's refusals: a chunk out of order or more than the ring can
/// take is not taken and the answer says where the stream stands; a NaN or a bad count is refused
/// with the stream unchanged; a commit needs the ring full; a wrong checksum is found when the
/// last sample arrives (at the commit if the whole record fits the ring).
#[test]
fn a_stream_takes_only_what_its_ring_can_hold_and_refuses_bad_chunks() {
    let mut buf = [0.0; 200];
    let mut s = RecordStore::new(&COMPILED, DT, 10, &mut buf);
    let long = ramp(300);
    let c = record_checksum(&long, DT);
    let (n0, v0) = chunk_of(&long, 0);
    assert_eq!(
        s.stream_chunk(0, n0, &v0),
        Err(NackReason::Sequence),
        "no stream"
    );
    assert_eq!(s.stream_status(), None);
    // Header refusals: as a whole upload's, and a record lasting more ticks than a u32 counts.
    assert_eq!(
        s.stream_begin(1, DT, 1.0, c, true),
        Err(NackReason::TooLong)
    );
    assert_eq!(
        s.stream_begin(u32::MAX, 0.1, 1.0, c, true),
        Err(NackReason::TooLong)
    );
    assert_eq!(
        s.stream_begin(300, 0.5, 1.0, c, true),
        Err(NackReason::Rate)
    );
    assert_eq!(
        s.stream_begin(300, DT, 1.0, c, false),
        Err(NackReason::Busy)
    );
    s.stream_begin(300, DT, 1.0, c, true).unwrap();
    // Out of order: not taken.
    let (n1, v1) = chunk_of(&long, 1);
    let a = s.stream_chunk(1, n1, &v1).unwrap();
    assert_eq!((a.seq, a.next_seq, a.free), (1, 0, 100));
    // A NaN, a count of 0: refused, the stream as it was.
    let mut nan = v0;
    nan[2] = f64::NAN;
    assert_eq!(s.stream_chunk(0, n0, &nan), Err(NackReason::NotFinite));
    assert_eq!(s.stream_chunk(0, 0, &v0), Err(NackReason::Incomplete));
    assert_eq!(s.stream_status().unwrap().next_seq, 0);
    // Too early a commit: the ring is not full.
    s.stream_chunk(0, n0, &v0).unwrap();
    assert_eq!(s.commit(true), Err(NackReason::Incomplete));
    assert_eq!(
        s.info().source,
        RecordSource::Compiled,
        "dropped, the compiled one stays"
    );
    // Filled: the ninth chunk does not fit the 4 samples left and is not taken.
    s.stream_begin(300, DT, 1.0, c, true).unwrap();
    let mut next = 0;
    feed(&mut s, &long, &mut next);
    assert_eq!(next, 8);
    let (n8, v8) = chunk_of(&long, 8);
    let a = s.stream_chunk(8, n8, &v8).unwrap();
    assert_eq!((a.next_seq, a.free), (8, 4));
    assert_eq!(s.commit(true).unwrap().source, RecordSource::Streamed);
    // A wrong checksum, the whole record in the ring: refused at the commit.
    let short = ramp(50);
    s.stream_begin(50, DT, 1.0, record_checksum(&short, DT) ^ 1, true)
        .unwrap();
    let mut next = 0;
    feed(&mut s, &short, &mut next);
    assert_eq!(s.stream_status().unwrap().checksum_ok, Some(false));
    assert_eq!(s.commit(true), Err(NackReason::Checksum));
    assert_eq!(s.info().checksum, c, "the stream in force stays");
}

/// A streamed record in force is replaced by an upload, and a stream begun beside an upload in
/// force goes into the other half and leaves it playing until its own commit.
#[test]
fn streams_and_uploads_replace_each_other_only_at_their_commit() {
    let mut buf = [0.0; 200];
    let mut s = RecordStore::new(&COMPILED, DT, 10, &mut buf);
    let good = ramp(60);
    upload(&mut s, &good, DT).unwrap();
    let long = ramp(400);
    s.stream_begin(400, DT, 1.0, record_checksum(&long, DT), true)
        .unwrap();
    let mut next = 0;
    feed(&mut s, &long, &mut next);
    let host = Record::new(&good, DT);
    for k in 0..s.ticks() {
        assert_eq!(s.accel_mm_s2(k), host.accel_mm_s2(k as usize, DT_S));
    }
    s.commit(true).unwrap();
    assert_eq!(s.info().samples, 400);
    let long_host = Record::new(&long, DT);
    for k in (0..300).step_by(11) {
        assert_eq!(s.accel_mm_s2(k), long_host.accel_mm_s2(k as usize, DT_S));
    }
    // Played past its start: not playable; an upload replaces it.
    s.play(0);
    assert!(s.playable());
    s.play(1);
    assert!(!s.playable());
    upload(&mut s, &good, DT).unwrap();
    assert!(s.playable());
    assert_eq!(s.stream_status(), None);
}

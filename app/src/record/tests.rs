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

//! The flow control against the device's own record store (`rths_app::record::RecordStore`, the
//! code the board runs) over a channel with latency and losses.

use super::*;
use rths_app::record::RecordStore;
use rths_core::motion::Record;
use rths_core::params::DT_S;
use rths_link::{DeviceMsg, RecordSource};
use std::collections::VecDeque;

/// What happened in a simulated run.
struct Outcome {
    underruns: u32,
    resent: usize,
    identical: bool,
    checksum_ok: Option<bool>,
}

/// Stream `samples` (every `dt_s`) to a store with a `ring`-sample ring over a link that delays
/// each frame by `latency` ticks both ways and loses every `lose_every`-th host frame (0: none);
/// the host polls the stream status when it cannot send and goes back after `stall` quiet ticks.
fn simulate(samples: &[f64], dt_s: f64, ring: usize, latency: usize, lose_every: usize) -> Outcome {
    let mut buf = vec![0.0; 2 * ring];
    let mut store = RecordStore::new(&[0.0, 0.0], 0.01, 1, &mut buf);
    let (begin, chunks) = crate::link_host::wire::stream_messages(samples, dt_s, 1.0).unwrap();
    let HostMsg::StreamBegin {
        samples: n,
        checksum,
        ..
    } = begin
    else {
        unreachable!()
    };
    store.stream_begin(n, dt_s, 1.0, checksum, true).unwrap();
    // The fill at rest, one chunk at a time as `Link::stream_record` does.
    let mut sent = 0;
    let mut free = ring;
    for c in &chunks {
        let HostMsg::StreamChunk { seq, count, values } = *c else {
            unreachable!()
        };
        if usize::from(count) > free {
            break;
        }
        let a = store.stream_chunk(seq, count, &values).unwrap();
        assert_eq!(a.next_seq, seq + 1);
        free = a.free as usize;
        sent += 1;
    }
    store.commit(true).unwrap();
    assert_eq!(store.info().source, RecordSource::Streamed);
    let mut feed = StreamFeed::new(chunks, sent, free);
    let host = Record::new(samples, dt_s);
    // Frames in flight, each with the tick it arrives at.
    let mut to_dev: VecDeque<(usize, HostMsg)> = VecDeque::new();
    let mut to_host: VecDeque<(usize, DeviceMsg)> = VecDeque::new();
    let (mut frames, mut quiet, mut identical) = (0usize, 0usize, true);
    let stall = 4 * latency + 8;
    for k in 0..store.ticks() {
        let now = k as usize;
        // Host: answers that arrived, then what it may send.
        while to_host.front().is_some_and(|(t, _)| *t <= now) {
            match to_host.pop_front().unwrap().1 {
                DeviceMsg::StreamAck {
                    seq,
                    next_seq,
                    free,
                } => feed.answered(seq, next_seq, free),
                DeviceMsg::StreamStatus(st) => feed.status(&st),
                other => panic!("{other:?}"),
            }
            quiet = 0;
        }
        quiet += 1;
        if feed.in_flight() > 0 && quiet > stall {
            feed.go_back();
            quiet = 0;
        }
        while let Some(m) = feed.due() {
            frames += 1;
            if lose_every == 0 || frames % lose_every != 0 {
                to_dev.push_back((now + latency, m));
            }
        }
        // Nothing in flight and more to send: ask for the room (the session asks every 20 ms).
        if !feed.done() && feed.in_flight() == 0 && now % 40 == 0 {
            to_dev.push_back((now + latency, HostMsg::StreamStatus));
        }
        // Device: the frames that arrived, then the tick.
        while to_dev.front().is_some_and(|(t, _)| *t <= now) {
            let answer = match to_dev.pop_front().unwrap().1 {
                HostMsg::StreamChunk { seq, count, values } => {
                    let a = store.stream_chunk(seq, count, &values).unwrap();
                    DeviceMsg::StreamAck {
                        seq: a.seq,
                        next_seq: a.next_seq,
                        free: a.free,
                    }
                }
                HostMsg::StreamStatus => DeviceMsg::StreamStatus(store.stream_status().unwrap()),
                other => panic!("{other:?}"),
            };
            to_host.push_back((now + latency, answer));
        }
        let p = store.play(k);
        identical &= p.accel_mm_s2.to_bits() == host.accel_mm_s2(k as usize, DT_S).to_bits();
    }
    let st = store.stream_status().unwrap();
    Outcome {
        underruns: st.underrun_ticks,
        resent: feed.resent(),
        identical,
        checksum_ok: st.checksum_ok,
    }
}

fn record(n: usize) -> Vec<f64> {
    (0..n).map(|i| (i as f64 * 0.013).sin() * 0.4).collect()
}

/// A record 20 times the ring, 5 ms each way: played whole, bit for bit, nothing resent.
#[test]
fn a_long_record_streams_through_a_small_ring_without_an_underrun() {
    let o = simulate(&record(2000), 0.005, 100, 10, 0);
    assert_eq!((o.underruns, o.resent), (0, 0));
    assert!(o.identical);
    assert_eq!(o.checksum_ok, Some(true));
}

/// Every 7th chunk lost on the wire: the device refuses the next one out of order, the host goes
/// back, and the run still plays every sample in time.
#[test]
fn chunks_lost_on_the_wire_are_sent_again_in_time() {
    let o = simulate(&record(2000), 0.005, 200, 10, 7);
    assert!(o.resent > 0);
    assert_eq!(o.underruns, 0);
    assert!(o.identical);
    assert_eq!(o.checksum_ok, Some(true));
}

/// Every 3rd chunk lost, so a second loss comes while the chunks of the first are being sent
/// again: each is found on its own refusal, and the run still plays every sample in time.
#[test]
fn a_second_loss_during_a_go_back_is_found_on_its_refusal() {
    let o = simulate(&record(2000), 0.005, 400, 10, 3);
    assert!(o.resent > 0);
    assert_eq!(o.underruns, 0);
    assert!(o.identical);
    assert_eq!(o.checksum_ok, Some(true));
}

/// A link too slow for the record (a ring of 30 samples, 200 ms each way): the ticks whose samples
/// did not arrive are counted, never played wrong: the test reports it.
#[test]
fn a_link_too_slow_for_the_record_underruns_and_says_so() {
    let o = simulate(&record(600), 0.005, 30, 400, 0);
    assert!(o.underruns > 0);
    assert!(!o.identical);
    assert_ne!(o.checksum_ok, Some(false), "no sample came wrong");
}

/// The credit counts the chunks in flight: never more than the room the device last reported.
#[test]
fn the_credit_counts_what_is_in_flight() {
    let (_, chunks) = crate::link_host::wire::stream_messages(&record(100), 0.01, 1.0).unwrap();
    let mut f = StreamFeed::new(chunks, 2, 30);
    assert_eq!(f.credit(), 30);
    assert!(f.due().is_some() && f.due().is_some());
    assert_eq!((f.credit(), f.in_flight()), (6, 2));
    assert!(f.due().is_none(), "a third chunk of 12 does not fit 6");
    // The device took chunk 2 and has 18 free: chunk 3 (12) is still in flight.
    f.answered(2, 3, 18);
    assert_eq!(f.credit(), 6);
    // Chunk 3 refused out of order (chunk 2 lost instead): back to 2.
    f.answered(3, 2, 30);
    assert_eq!((f.in_flight(), f.resent()), (0, 2));
    assert_eq!(f.credit(), 30);
}

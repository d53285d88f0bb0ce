//! A record streamed through a ring during its run: the samples pass through a half of the record
//! buffer (the ring), written as their chunks arrive and released as the run reads past them, so a
//! record of any length plays from a buffer of fixed size. The flow control is the ring's room
//! ([`Stream::free`]): the host never sends more, and a chunk that would overwrite a sample the run
//! may still read is refused. A tick whose samples have not arrived is an underrun: it plays 0 g
//! and is counted; what the run does about it is the caller's (the run's link-loss policy).

use crate::chunks::Chunks;
use rths_core::motion::{accel_at_mm_s2, tick_position};
use rths_core::params::DT_S;
use rths_link::{NackReason, RecordDigest, RecordInfo, StreamStatus, RECORD_CHUNK};

/// What one tick of a run reads from the record in force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Played {
    /// Ground acceleration, mm/s².
    pub accel_mm_s2: f64,
    /// The tick's samples had not arrived (a streamed record's underrun): `accel_mm_s2` is 0.
    pub underrun: bool,
}

/// A streamed record: what it is, where its stream stands, what its run read.
#[derive(Clone)]
pub(super) struct Stream {
    /// The whole record as announced (`samples`, `ticks`, `checksum` of all of it).
    pub(super) info: RecordInfo,
    chunks: Chunks,
    digest: RecordDigest,
    checksum_ok: Option<bool>,
    /// The lowest sample the run may still read (every one below it may be overwritten).
    low: usize,
    /// A tick after the first has been played: the ring no longer holds the record's start.
    played: bool,
    underrun_ticks: u32,
    first_underrun_tick: Option<u32>,
}

/// The answer to one chunk: the chunk, the next one expected, the room left.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ChunkAnswer {
    /// The chunk answered.
    pub seq: u32,
    /// The chunk number expected next (`seq + 1` if this one was taken).
    pub next_seq: u32,
    /// Samples the ring can take now.
    pub free: u32,
}

impl Stream {
    /// A stream of the record `info` announces, nothing received.
    pub(super) fn new(info: RecordInfo) -> Self {
        Self {
            info,
            chunks: Chunks::new(info.samples as usize),
            digest: RecordDigest::new(),
            checksum_ok: None,
            low: 0,
            played: false,
            underrun_ticks: 0,
            first_underrun_tick: None,
        }
    }

    /// Samples a ring of `cap` can take now: up to `cap` past the lowest sample the run may still
    /// read, and no more than the record has left.
    pub(super) fn free(&self, cap: usize) -> u32 {
        let room = self
            .low
            .saturating_add(cap)
            .saturating_sub(self.chunks.written());
        let left = self.chunks.total().saturating_sub(self.chunks.written());
        u32::try_from(room.min(left)).unwrap_or(u32::MAX)
    }

    /// The ring of `cap` holds the whole record, or cannot take another whole chunk: the run may
    /// start.
    pub(super) fn filled(&self, cap: usize) -> bool {
        self.chunks.complete() || (self.free(cap) as usize) < RECORD_CHUNK
    }

    /// Every sample arrived and the end-to-end checksum matched (`None`: not all arrived yet).
    pub(super) fn checksum_ok(&self) -> Option<bool> {
        self.checksum_ok
    }

    /// The record can be played from its start (no run has read past its first tick).
    pub(super) fn playable(&self) -> bool {
        !self.played
    }

    /// Where it stands; `in_force`: committed.
    pub(super) fn status(&self, cap: usize, in_force: bool) -> StreamStatus {
        StreamStatus {
            in_force,
            next_seq: self.chunks.next_seq(),
            received: u32::try_from(self.chunks.written()).unwrap_or(u32::MAX),
            free: self.free(cap),
            underrun_ticks: self.underrun_ticks,
            first_underrun_tick: self.first_underrun_tick,
            checksum_ok: self.checksum_ok,
        }
    }

    /// Take chunk `seq` (the first `count` of `values`, g) into `ring`. Out of order, or more than
    /// the ring can take: not taken, answered with where the stream stands (the host sends again).
    /// A bad count or a non-finite sample: refused (the stream stays as it was).
    pub(super) fn chunk(
        &mut self,
        ring: &mut [f64],
        seq: u32,
        count: u8,
        values: &[f64; RECORD_CHUNK],
    ) -> Result<ChunkAnswer, NackReason> {
        let cap = ring.len();
        let answer = |s: &Self| ChunkAnswer {
            seq,
            next_seq: s.chunks.next_seq(),
            free: s.free(cap),
        };
        let vals = match self.chunks.check(seq, count, values) {
            Ok(v) => v,
            Err(NackReason::Sequence) => return Ok(answer(self)),
            Err(e) => return Err(e),
        };
        if vals.len() > self.free(cap) as usize {
            return Ok(answer(self));
        }
        let first = self.chunks.written();
        for (j, v) in vals.iter().enumerate() {
            let slot = first
                .saturating_add(j)
                .checked_rem(cap)
                .and_then(|i| ring.get_mut(i))
                .ok_or(NackReason::Unsupported)?;
            *slot = *v;
        }
        self.digest.update(vals);
        self.chunks.advance(vals.len());
        if self.chunks.complete() {
            let digest = core::mem::take(&mut self.digest);
            self.checksum_ok = Some(digest.finalize(self.info.dt_s) == self.info.checksum);
        }
        Ok(answer(self))
    }

    /// Ground acceleration at tick `k` of a run from `ring` (0 after the record's end), as
    /// [`Self::read`]; from tick 1 on the ring no longer holds the record's start, the samples
    /// below the tick's are released, and an underrun is counted.
    pub(super) fn play(&mut self, ring: &[f64], k: u32) -> Played {
        if self.played && k == 0 {
            // Tick 0 again after the run began: a read of a record already played (the caller
            // plays only a run's ticks; this keeps an idle tick from counting as an underrun).
            return Played {
                accel_mm_s2: self.read(ring, k).accel_mm_s2,
                underrun: false,
            };
        }
        if k < self.info.ticks {
            let (i, _) = tick_position(k as usize, DT_S, self.info.dt_s);
            let first = i.min(self.chunks.total().saturating_sub(1));
            self.played |= k > 0;
            self.low = self.low.max(first);
        }
        let p = self.read(ring, k);
        if p.underrun {
            self.underrun_ticks = self.underrun_ticks.saturating_add(1);
            self.first_underrun_tick.get_or_insert(k);
        }
        p
    }

    /// Ground acceleration at tick `k` from `ring` (0 after the record's end), by the interpolation
    /// a record held whole plays (`rths_core::motion::accel_at_mm_s2`), so the host and the board
    /// see the same ü_g bit for bit; 0 and `underrun` if the ring does not hold its samples.
    pub(super) fn read(&self, ring: &[f64], k: u32) -> Played {
        let cap = ring.len();
        let total = self.chunks.total();
        if k >= self.info.ticks || total == 0 {
            return Played {
                accel_mm_s2: 0.0,
                underrun: false,
            };
        }
        let (i, _) = tick_position(k as usize, DT_S, self.info.dt_s);
        // The samples the interpolation reads: i and i + 1 of those the record has.
        let first = i.min(total - 1);
        let last = i.saturating_add(1).min(total - 1);
        if first < self.low || last >= self.chunks.written() {
            return Played {
                accel_mm_s2: 0.0,
                underrun: true,
            };
        }
        let sample_g = |j: usize| {
            if j < total {
                j.checked_rem(cap).and_then(|s| ring.get(s)).copied()
            } else {
                None
            }
        };
        Played {
            accel_mm_s2: accel_at_mm_s2(total, sample_g, k as usize, DT_S, self.info.dt_s),
            underrun: false,
        }
    }
}

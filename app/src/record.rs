//! The ground-motion record the control task plays: the compiled-in one, or one uploaded over the
//! link into the board's record buffer. An upload is validated on the device as it arrives (chunk
//! order, finiteness, length against the buffer, step) and at its commit (count, end-to-end
//! checksum); it is refused whole on the first error, and the record in force stays in force until a
//! commit succeeds: the buffer is split in two halves, the new record is written into the half the
//! active one does not use. A record longer than a half is streamed through it during its run
//! ([`stream`]).

use crate::chunks::Chunks;
use rths_core::motion::{record_ticks, Record};
use rths_core::params::DT_S;
use rths_link::{
    NackReason, RecordDigest, RecordInfo, RecordSource, StreamStatus, RECORD_CHUNK,
    RECORD_DT_MAX_S, RECORD_DT_MIN_S,
};

mod stream;

use stream::Stream;
pub use stream::{ChunkAnswer, Played};

/// A whole upload in progress.
#[derive(Clone)]
struct Staging {
    samples: u32,
    dt_s: f64,
    scale: f64,
    checksum: u32,
    /// Chunk order and count.
    chunks: Chunks,
    digest: RecordDigest,
}

/// What an upload in progress is.
#[derive(Clone)]
enum Pending {
    /// A record sent whole before its run.
    Whole(Staging),
    /// A streamed record filling its ring.
    Streamed(Stream),
}

/// What an uploaded record in force is.
#[derive(Clone)]
enum Held {
    /// Held whole: the first `samples` of its half.
    Whole(RecordInfo),
    /// Streamed through its half during its run.
    Streamed(Stream),
}

/// The records the board holds and the upload in progress.
pub struct RecordStore<'a> {
    compiled: Record<'a>,
    compiled_info: RecordInfo,
    buf: &'a mut [f64],
    /// The uploaded record in force: its half of `buf` and what it is.
    active: Option<(usize, Held)>,
    /// The upload in progress: the half of `buf` it is written into and what it is.
    staging: Option<(usize, Pending)>,
}

impl<'a> RecordStore<'a> {
    /// The compiled-in record (`compiled_g` in g every `dt_s`, lasting `ticks` controller ticks, as
    /// the build computed them), and `buf` for uploads (empty: the board takes none). Computes the
    /// compiled record's checksum (once, at boot).
    pub fn new(compiled_g: &'a [f64], dt_s: f64, ticks: u32, buf: &'a mut [f64]) -> Self {
        let compiled_info = RecordInfo {
            source: RecordSource::Compiled,
            samples: u32::try_from(compiled_g.len()).unwrap_or(u32::MAX),
            dt_s,
            scale: 1.0,
            ticks,
            checksum: rths_link::record_checksum(compiled_g, dt_s),
        };
        Self {
            compiled: Record::new(compiled_g, dt_s),
            compiled_info,
            buf,
            active: None,
            staging: None,
        }
    }

    /// The largest record an upload may have, samples (half the buffer); a streamed record's ring.
    pub fn capacity(&self) -> u32 {
        u32::try_from(self.half_len()).unwrap_or(u32::MAX)
    }

    fn half_len(&self) -> usize {
        self.buf.len() / 2
    }

    /// The record in force.
    pub fn info(&self) -> RecordInfo {
        match &self.active {
            Some((_, Held::Whole(i))) => *i,
            Some((_, Held::Streamed(s))) => s.info,
            None => self.compiled_info,
        }
    }

    /// Controller ticks the record in force lasts.
    pub fn ticks(&self) -> u32 {
        self.info().ticks
    }

    /// An upload is in progress.
    pub fn uploading(&self) -> bool {
        self.staging.is_some()
    }

    /// The record in force can be played from its start: a streamed one only until its run has
    /// read past its first tick (its ring no longer holds the start: stream it again).
    pub fn playable(&self) -> bool {
        match &self.active {
            Some((_, Held::Streamed(s))) => s.playable(),
            _ => true,
        }
    }

    /// Where the streamed record stands: the one filling its ring, else the one in force (`None`:
    /// no stream).
    pub fn stream_status(&self) -> Option<StreamStatus> {
        let cap = self.half_len();
        match (&self.staging, &self.active) {
            (Some((_, Pending::Streamed(s))), _) => Some(s.status(cap, false)),
            (_, Some((_, Held::Streamed(s)))) => Some(s.status(cap, true)),
            _ => None,
        }
    }

    fn half(&self, half: usize, len: u32) -> &[f64] {
        let cap = self.half_len();
        let start = half * cap;
        self.buf
            .get(start..start + (len as usize).min(cap))
            .unwrap_or(&[])
    }

    /// Ground acceleration of the record in force at tick `k`, mm/s²; 0 after its end (the
    /// interpolation the host's `GroundMotion::resample_mm_s2` runs, so both see the same ü_g).
    /// A read only: a streamed record's sample not held reads 0 here, uncounted ([`Self::play`]
    /// is the run's).
    #[inline]
    pub fn accel_mm_s2(&self, k: u32) -> f64 {
        let info = self.info();
        if k >= info.ticks {
            return 0.0;
        }
        match &self.active {
            Some((half, Held::Whole(i))) => Record::new(self.half(*half, i.samples), i.dt_s),
            Some((half, Held::Streamed(s))) => {
                return s.read(self.half(*half, u32::MAX), k).accel_mm_s2;
            }
            None => self.compiled,
        }
        .accel_mm_s2(k as usize, DT_S)
    }

    /// Ground acceleration at tick `k` of a run that plays the record, mm/s², as
    /// [`Self::accel_mm_s2`]; for a streamed record it releases the samples the run has read past
    /// and counts an underrun (a tick whose samples have not arrived plays 0 g). At rest, read
    /// with [`Self::accel_mm_s2`].
    pub fn play(&mut self, k: u32) -> Played {
        let cap = self.half_len();
        match &mut self.active {
            Some((half, Held::Streamed(s))) => {
                let start = *half * cap;
                let ring = self.buf.get(start..start + cap).unwrap_or(&[]);
                s.play(ring, k)
            }
            _ => Played {
                accel_mm_s2: self.accel_mm_s2(k),
                underrun: false,
            },
        }
    }

    /// The checks of a record's header common to a whole upload and a stream: at rest, a buffer,
    /// the step, the scale, at least 2 samples. The half it goes into (the one the record in force
    /// does not use).
    fn check_header(
        &self,
        samples: u32,
        dt_s: f64,
        scale: f64,
        at_rest: bool,
    ) -> Result<usize, NackReason> {
        if !at_rest {
            return Err(NackReason::Busy);
        }
        if self.buf.len() < 4 {
            return Err(NackReason::Unsupported);
        }
        if !(dt_s.is_finite() && (RECORD_DT_MIN_S..=RECORD_DT_MAX_S).contains(&dt_s)) {
            return Err(NackReason::Rate);
        }
        if !scale.is_finite() {
            return Err(NackReason::NotFinite);
        }
        if samples < 2 {
            return Err(NackReason::TooLong);
        }
        Ok(self.active.as_ref().map_or(0, |(h, _)| 1 - h))
    }

    /// Begin an upload of `samples` samples every `dt_s` (`scale`: what the host multiplied them by,
    /// reported only; `checksum`: `rths_link::record_checksum` of them all). Replaces an upload in
    /// progress; the record in force is untouched. `at_rest`: the controller is at rest.
    pub fn begin(
        &mut self,
        samples: u32,
        dt_s: f64,
        scale: f64,
        checksum: u32,
        at_rest: bool,
    ) -> Result<(), NackReason> {
        let half = self.check_header(samples, dt_s, scale, at_rest)?;
        if samples > self.capacity() {
            return Err(NackReason::TooLong);
        }
        let staging = Staging {
            samples,
            dt_s,
            scale,
            checksum,
            chunks: Chunks::new(samples as usize),
            digest: RecordDigest::new(),
        };
        self.staging = Some((half, Pending::Whole(staging)));
        Ok(())
    }

    /// Begin a streamed record of `samples` samples (any number lasting at most `u32::MAX` ticks)
    /// every `dt_s`, as [`Self::begin`]; its chunks ([`Self::stream_chunk`]) fill a ring of
    /// [`Self::capacity`] samples, and its commit needs the ring full (or the whole record).
    pub fn stream_begin(
        &mut self,
        samples: u32,
        dt_s: f64,
        scale: f64,
        checksum: u32,
        at_rest: bool,
    ) -> Result<(), NackReason> {
        let half = self.check_header(samples, dt_s, scale, at_rest)?;
        // `record_ticks` saturates (at `usize::MAX`, which is `u32::MAX` on the MCU): a record
        // lasting that long is refused, whatever the word size.
        let ticks = u32::try_from(record_ticks(samples as usize, dt_s, DT_S))
            .ok()
            .filter(|t| *t < u32::MAX)
            .ok_or(NackReason::TooLong)?;
        if ticks == 0 {
            return Err(NackReason::Rate);
        }
        let info = RecordInfo {
            source: RecordSource::Streamed,
            samples,
            dt_s,
            scale,
            ticks,
            checksum,
        };
        self.staging = Some((half, Pending::Streamed(Stream::new(info))));
        Ok(())
    }

    /// The next chunk of the streamed record, the one filling its ring or the one in force (during
    /// its run too): taken or not, where the stream stands ([`ChunkAnswer`]). No stream:
    /// `Sequence`; a bad count or a non-finite sample: refused, the stream as it was.
    pub fn stream_chunk(
        &mut self,
        seq: u32,
        count: u8,
        values: &[f64; RECORD_CHUNK],
    ) -> Result<ChunkAnswer, NackReason> {
        let cap = self.half_len();
        let (half, stream) = match (&mut self.staging, &mut self.active) {
            (Some((h, Pending::Streamed(s))), _) => (*h, s),
            (_, Some((h, Held::Streamed(s)))) => (*h, s),
            _ => return Err(NackReason::Sequence),
        };
        let start = half * cap;
        let ring = self
            .buf
            .get_mut(start..start + cap)
            .ok_or(NackReason::Unsupported)?;
        stream.chunk(ring, seq, count, values)
    }

    /// The next chunk of the upload: chunk `seq` with the first `count` of `values` (g). Out of
    /// order, duplicated, a bad count or a non-finite sample drops the upload (refused whole).
    pub fn chunk(
        &mut self,
        seq: u32,
        count: u8,
        values: &[f64; RECORD_CHUNK],
        at_rest: bool,
    ) -> Result<(), NackReason> {
        if !at_rest {
            return Err(NackReason::Busy);
        }
        let Some((half, Pending::Whole(mut st))) = self.staging.take() else {
            return Err(NackReason::Sequence);
        };
        let vals = st.chunks.check(seq, count, values)?;
        let n = vals.len();
        let cap = self.half_len();
        let start = half * cap + st.chunks.written();
        let dest = self
            .buf
            .get_mut(start..start + n)
            .ok_or(NackReason::TooLong)?;
        dest.copy_from_slice(vals);
        st.digest.update(vals);
        st.chunks.advance(n);
        self.staging = Some((half, Pending::Whole(st)));
        Ok(())
    }

    /// Check the upload (every sample arrived, the checksum matches; a stream: its ring full, the
    /// checksum matched if every sample came) and make it the record in force. Refused: the
    /// upload is dropped and the record in force stays.
    pub fn commit(&mut self, at_rest: bool) -> Result<RecordInfo, NackReason> {
        if !at_rest {
            return Err(NackReason::Busy);
        }
        let Some((half, pending)) = self.staging.take() else {
            return Err(NackReason::Sequence);
        };
        let st = match pending {
            Pending::Whole(st) => st,
            Pending::Streamed(s) => {
                if !s.filled(self.half_len()) {
                    return Err(NackReason::Incomplete);
                }
                if s.checksum_ok() == Some(false) {
                    return Err(NackReason::Checksum);
                }
                let info = s.info;
                self.active = Some((half, Held::Streamed(s)));
                return Ok(info);
            }
        };
        if !st.chunks.complete() {
            return Err(NackReason::Incomplete);
        }
        if st.digest.finalize(st.dt_s) != st.checksum {
            return Err(NackReason::Checksum);
        }
        let ticks = Record::new(self.half(half, st.samples), st.dt_s).ticks(DT_S);
        let ticks = u32::try_from(ticks)
            .ok()
            .filter(|t| *t > 0)
            .ok_or(NackReason::Rate)?;
        let info = RecordInfo {
            source: RecordSource::Uploaded,
            samples: st.samples,
            dt_s: st.dt_s,
            scale: st.scale,
            ticks,
            checksum: st.checksum,
        };
        self.active = Some((half, Held::Whole(info)));
        Ok(info)
    }
}

#[cfg(test)]
mod tests;

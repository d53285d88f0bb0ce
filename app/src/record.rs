//! The ground-motion record the control task plays: the compiled-in one, or one uploaded over the
//! link into the board's record buffer. An upload is validated on the device as it arrives (chunk
//! order, finiteness, length against the buffer, step) and at its commit (count, end-to-end
//! checksum); it is refused whole on the first error, and the record in force stays in force until a
//! commit succeeds: the buffer is split in two halves, the new record is written into the half the
//! active one does not use.

use crate::chunks::Chunks;
use rths_core::motion::Record;
use rths_core::params::DT_S;
use rths_link::{
    NackReason, RecordDigest, RecordInfo, RecordSource, RECORD_CHUNK, RECORD_DT_MAX_S,
    RECORD_DT_MIN_S,
};

/// An upload in progress.
#[derive(Clone)]
struct Staging {
    /// Half of the buffer it is written into.
    half: usize,
    samples: u32,
    dt_s: f64,
    scale: f64,
    checksum: u32,
    /// Chunk order and count.
    chunks: Chunks,
    digest: RecordDigest,
}

/// The records the board holds and the upload in progress.
pub struct RecordStore<'a> {
    compiled: Record<'a>,
    compiled_info: RecordInfo,
    buf: &'a mut [f64],
    /// The uploaded record in force: its half of `buf` and what it is.
    active: Option<(usize, RecordInfo)>,
    staging: Option<Staging>,
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

    /// The largest record an upload may have, samples (half the buffer).
    pub fn capacity(&self) -> u32 {
        u32::try_from(self.buf.len() / 2).unwrap_or(u32::MAX)
    }

    /// The record in force.
    pub fn info(&self) -> RecordInfo {
        self.active.map_or(self.compiled_info, |(_, i)| i)
    }

    /// Controller ticks the record in force lasts.
    pub fn ticks(&self) -> u32 {
        self.info().ticks
    }

    /// An upload is in progress.
    pub fn uploading(&self) -> bool {
        self.staging.is_some()
    }

    fn half(&self, half: usize, len: u32) -> &[f64] {
        let cap = self.buf.len() / 2;
        let start = half * cap;
        self.buf
            .get(start..start + (len as usize).min(cap))
            .unwrap_or(&[])
    }

    /// Ground acceleration of the record in force at tick `k`, mm/s²; 0 after its end (the
    /// interpolation the host's `GroundMotion::resample_mm_s2` runs, so both see the same ü_g).
    #[inline]
    pub fn accel_mm_s2(&self, k: u32) -> f64 {
        let info = self.info();
        if k >= info.ticks {
            return 0.0;
        }
        match self.active {
            Some((half, i)) => Record::new(self.half(half, i.samples), i.dt_s),
            None => self.compiled,
        }
        .accel_mm_s2(k as usize, DT_S)
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
        if samples < 2 || samples > self.capacity() {
            return Err(NackReason::TooLong);
        }
        let half = self.active.map_or(0, |(h, _)| 1 - h);
        self.staging = Some(Staging {
            half,
            samples,
            dt_s,
            scale,
            checksum,
            chunks: Chunks::new(samples as usize),
            digest: RecordDigest::new(),
        });
        Ok(())
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
        let Some(mut st) = self.staging.take() else {
            return Err(NackReason::Sequence);
        };
        let vals = st.chunks.check(seq, count, values)?;
        let n = vals.len();
        let cap = self.buf.len() / 2;
        let start = st.half * cap + st.chunks.written();
        let dest = self
            .buf
            .get_mut(start..start + n)
            .ok_or(NackReason::TooLong)?;
        dest.copy_from_slice(vals);
        st.digest.update(vals);
        st.chunks.advance(n);
        self.staging = Some(st);
        Ok(())
    }

    /// Check the upload (every sample arrived, the checksum matches) and make it the record in
    /// force. Refused: the upload is dropped and the record in force stays.
    pub fn commit(&mut self, at_rest: bool) -> Result<RecordInfo, NackReason> {
        if !at_rest {
            return Err(NackReason::Busy);
        }
        let Some(st) = self.staging.take() else {
            return Err(NackReason::Sequence);
        };
        if !st.chunks.complete() {
            return Err(NackReason::Incomplete);
        }
        if st.digest.finalize(st.dt_s) != st.checksum {
            return Err(NackReason::Checksum);
        }
        let ticks = Record::new(self.half(st.half, st.samples), st.dt_s).ticks(DT_S);
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
        self.active = Some((st.half, info));
        Ok(info)
    }
}

#[cfg(test)]
mod tests;

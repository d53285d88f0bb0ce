//! The bookkeeping of a chunked upload (a ground-motion record, a model), one home for both: chunk
//! numbers from 0 with no gap, a count of 1..=[`RECORD_CHUNK`] that does not pass the announced
//! total, and finite values; anything else drops the upload (the caller discards it whole).

use rths_link::{NackReason, RECORD_CHUNK};

/// Where a chunked upload stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Chunks {
    /// Values announced.
    total: usize,
    /// Values received so far.
    written: usize,
    /// Next chunk number expected.
    next_seq: u32,
}

impl Chunks {
    /// An upload of `total` values, nothing received.
    pub const fn new(total: usize) -> Self {
        Self {
            total,
            written: 0,
            next_seq: 0,
        }
    }

    /// Values received so far (the offset of the next chunk's first value).
    pub fn written(&self) -> usize {
        self.written
    }

    /// The chunk number expected next (= chunks received).
    pub fn next_seq(&self) -> u32 {
        self.next_seq
    }

    /// Values announced.
    pub fn total(&self) -> usize {
        self.total
    }

    /// Every value arrived.
    pub fn complete(&self) -> bool {
        self.written == self.total
    }

    /// Check chunk `seq` carrying the first `count` of `values`: its values, to be stored at
    /// [`Self::written`]; then call [`Self::advance`]. Out of order or duplicated: `Sequence`; a
    /// count of 0, over [`RECORD_CHUNK`] or past the total: `Incomplete`; a NaN or infinity:
    /// `NotFinite`.
    pub fn check<'v>(
        &self,
        seq: u32,
        count: u8,
        values: &'v [f64; RECORD_CHUNK],
    ) -> Result<&'v [f64], NackReason> {
        if seq != self.next_seq {
            return Err(NackReason::Sequence);
        }
        let n = usize::from(count);
        if n == 0 || n > RECORD_CHUNK || n > self.total - self.written {
            return Err(NackReason::Incomplete);
        }
        let vals = values.get(..n).ok_or(NackReason::Incomplete)?;
        if vals.iter().any(|v| !v.is_finite()) {
            return Err(NackReason::NotFinite);
        }
        Ok(vals)
    }

    /// The checked chunk of `n` values is stored.
    pub fn advance(&mut self, n: usize) {
        self.written += n;
        self.next_seq = self.next_seq.wrapping_add(1);
    }
}

//! Chunked model uploads (a model of more values than one frame holds: LRX), validated on the
//! device as the values arrive (order, count, finiteness) and at the commit (end-to-end checksum,
//! then the model's own checks as `rths_core::model::assemble` makes them); refused whole, the model
//! in force kept. The values wait in a small staging area of the link's session.

use rths_core::compensator::{LeadParams, LEAD_TAPS};
use rths_core::control::Controller;
use rths_core::metamodel::LrxParams;
use rths_link::{ModelKind, NackReason, LRX_VALUES, MODEL_MAX_VALUES, RECORD_CHUNK};

/// The model upload in progress, if any.
#[derive(Debug, Clone, Copy, Default)]
pub struct ModelStaging {
    staged: Option<Staged>,
}

#[derive(Debug, Clone, Copy)]
struct Staged {
    kind: ModelKind,
    count: usize,
    delay_steps: u16,
    checksum: u32,
    next_seq: u32,
    written: usize,
    values: [f64; MODEL_MAX_VALUES],
}

/// The values a kind's upload has; `None` for a kind that cannot be uploaded in chunks.
pub fn values_of(kind: ModelKind) -> Option<usize> {
    match kind {
        ModelKind::Lrx => Some(LRX_VALUES),
        // An RNN's weights (up to 1159 values at 32 units) and its 9 kB parts are not staged on
        // the device; the FE model has no weights to upload.
        ModelKind::Rnn | ModelKind::FeAts | ModelKind::Lr => None,
    }
}

impl ModelStaging {
    /// Nothing staged.
    pub const fn new() -> Self {
        Self { staged: None }
    }

    /// An upload is in progress.
    pub fn uploading(&self) -> bool {
        self.staged.is_some()
    }

    /// Begin an upload of a `kind` model of `values` values (`build`: the kind this firmware runs;
    /// another kind is refused `Unsupported`). Replaces an upload in progress.
    pub fn begin(
        &mut self,
        kind: ModelKind,
        values: u16,
        delay_steps: u16,
        checksum: u32,
        build: ModelKind,
        at_rest: bool,
    ) -> Result<(), NackReason> {
        if !at_rest {
            return Err(NackReason::Busy);
        }
        let expected = values_of(kind).ok_or(NackReason::Unsupported)?;
        if kind != build {
            return Err(NackReason::Unsupported);
        }
        if usize::from(values) != expected || expected > MODEL_MAX_VALUES {
            return Err(NackReason::Shape);
        }
        self.staged = Some(Staged {
            kind,
            count: expected,
            delay_steps,
            checksum,
            next_seq: 0,
            written: 0,
            values: [0.0; MODEL_MAX_VALUES],
        });
        Ok(())
    }

    /// The next chunk: out of order, duplicated, a bad count or a non-finite value drops the upload.
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
        let Some(mut st) = self.staged.take() else {
            return Err(NackReason::Sequence);
        };
        if seq != st.next_seq {
            return Err(NackReason::Sequence);
        }
        let n = usize::from(count);
        if n == 0 || n > RECORD_CHUNK || n > st.count - st.written {
            return Err(NackReason::Incomplete);
        }
        let vals = values.get(..n).ok_or(NackReason::Incomplete)?;
        if vals.iter().any(|v| !v.is_finite()) {
            return Err(NackReason::NotFinite);
        }
        st.values
            .get_mut(st.written..st.written + n)
            .ok_or(NackReason::Incomplete)?
            .copy_from_slice(vals);
        st.written += n;
        st.next_seq = st.next_seq.wrapping_add(1);
        self.staged = Some(st);
        Ok(())
    }

    /// Check the upload and swap the model into `ctl` (analytical part and compensator, whole).
    /// Returns its checksum. Refused: the upload is dropped, the model in force stays.
    ///
    /// Out of line: the new parts are built (in place, `Controller::set_lrx`) only when an upload
    /// is committed, and whatever frame that takes is not reserved for every request.
    #[inline(never)]
    pub fn commit(&mut self, ctl: &mut Controller, at_rest: bool) -> Result<u32, NackReason> {
        if !at_rest {
            return Err(NackReason::Busy);
        }
        let st = self.staged.take().ok_or(NackReason::Sequence)?;
        if st.written != st.count {
            return Err(NackReason::Incomplete);
        }
        let v = st.values.get(..st.count).ok_or(NackReason::Shape)?;
        if rths_link::model_values_checksum(st.kind, v, st.delay_steps) != st.checksum {
            return Err(NackReason::Checksum);
        }
        if st.kind != ModelKind::Lrx {
            return Err(NackReason::Unsupported);
        }
        let (frame, lead) = lrx_parts(v)?;
        ctl.set_lrx(frame, lead).map_err(|_| NackReason::Busy)?;
        Ok(st.checksum)
    }
}

/// The LRX frame model and lead filter of an upload's values (`rths_link::lrx_values`' order),
/// validated by core's own checks (shapes, finiteness, ranges); the stride must be a whole number
/// of ticks.
fn lrx_parts(v: &[f64]) -> Result<(LrxParams, LeadParams), NackReason> {
    let stride = *v.get(19).ok_or(NackReason::Shape)?;
    if !((1.0..=64.0).contains(&stride) && libm::floor(stride) == stride) {
        return Err(NackReason::OutOfRange);
    }
    let frame = LrxParams::from_slice(
        v.get(..9).ok_or(NackReason::Shape)?,
        *v.get(9).ok_or(NackReason::Shape)?,
        *v.get(10).ok_or(NackReason::Shape)?,
    )
    .map_err(|_| NackReason::OutOfRange)?;
    let weights: [f64; LEAD_TAPS] = v
        .get(11..19)
        .and_then(|w| w.try_into().ok())
        .ok_or(NackReason::Shape)?;
    let lead = LeadParams::new(weights, stride as usize).map_err(|_| NackReason::OutOfRange)?;
    Ok((frame, lead))
}

/// The link checksum of a compiled-in LRX model (what the status reports until an upload).
pub fn lrx_checksum(
    coeffs: &[f64],
    k_corr_kn_per_mm: f64,
    k_adapt_ticks: f64,
    lead_weights: &[f64],
    lead_stride: usize,
    delay_steps: u16,
) -> u32 {
    rths_link::lrx_values(
        coeffs,
        k_corr_kn_per_mm,
        k_adapt_ticks,
        lead_weights,
        lead_stride,
    )
    .map_or(0, |v| {
        rths_link::model_values_checksum(ModelKind::Lrx, &v, delay_steps)
    })
}

#[cfg(test)]
mod tests;

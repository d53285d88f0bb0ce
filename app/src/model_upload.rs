//! Chunked model uploads of any kind into any image (LRX, an RNN of any hidden size up to the
//! controller's capacity, FE + ATS), validated on the device as the values arrive (order, count,
//! finiteness) and at the commit (end-to-end checksum, the board's tick budget, then the model's
//! own checks as `rths_core::model` makes them); refused whole, the model in force kept. The values
//! wait in one staging area of [`rths_link::MODEL_MAX_VALUES`]; the new parts are built in the
//! controller in place (`Controller::install_rnn`, `install_ats`: no ~9 kB RNN or 33 KiB ATS on
//! the stack).

use rths_core::compensator::{AtsConfig, AtsParams};
use rths_core::compensator::{LeadParams, LEAD_TAPS};
use rths_core::control::{Controller, FeModel, ReplaceError};
use rths_core::metamodel::{LrxParams, RnnScaling, RnnWeights, RNN_INPUTS};
use rths_core::params::{Prototype, DT_S};
use rths_link::{
    ModelKind, NackReason, FE_ATS_VALUES, LRX_VALUES, RECORD_CHUNK, RNN_UPLOAD_MAX_HIDDEN,
};

use crate::chunks::Chunks;
use crate::tick_cost::TickBudget;

/// The model upload in progress, if any, and the staging area its values wait in.
#[derive(Debug)]
pub struct ModelStaging<'a> {
    staged: Option<Staged>,
    area: &'a mut [f64],
}

#[derive(Debug, Clone, Copy)]
struct Staged {
    kind: ModelKind,
    count: usize,
    delay_steps: u16,
    checksum: u32,
    chunks: Chunks,
}

/// A `kind` upload of `values` values has its kind's shape: LRX [`LRX_VALUES`], FE + ATS
/// [`FE_ATS_VALUES`], an RNN [`rths_link::rnn_value_count`] of 1..=[`RNN_UPLOAD_MAX_HIDDEN`]
/// units. `Err(Unsupported)` for a kind that is not uploaded in chunks (an LR goes in one
/// `UploadLr`), `Err(Shape)` for another count.
pub fn shape_ok(kind: ModelKind, values: usize) -> Result<(), NackReason> {
    let ok = match kind {
        ModelKind::Lrx => values == LRX_VALUES,
        ModelKind::FeAts => values == FE_ATS_VALUES,
        ModelKind::Rnn => {
            rths_link::rnn_hidden_of(values).is_some_and(|h| h <= RNN_UPLOAD_MAX_HIDDEN)
        }
        ModelKind::Lr => return Err(NackReason::Unsupported),
    };
    if ok {
        Ok(())
    } else {
        Err(NackReason::Shape)
    }
}

impl<'a> ModelStaging<'a> {
    /// Nothing staged; uploads wait in `area`.
    pub fn new(area: &'a mut [f64]) -> Self {
        Self { staged: None, area }
    }

    /// An upload is in progress.
    pub fn uploading(&self) -> bool {
        self.staged.is_some()
    }

    /// Begin an upload of a `kind` model of `values` values (any kind the link lays out in chunks,
    /// whatever the image's compiled-in model: [`shape_ok`]; more than the staging area holds
    /// `TooLong`). Replaces an upload in progress.
    pub fn begin(
        &mut self,
        kind: ModelKind,
        values: u16,
        delay_steps: u16,
        checksum: u32,
        at_rest: bool,
    ) -> Result<(), NackReason> {
        if !at_rest {
            return Err(NackReason::Busy);
        }
        let count = usize::from(values);
        shape_ok(kind, count)?;
        if count > self.area.len() {
            return Err(NackReason::TooLong);
        }
        self.staged = Some(Staged {
            kind,
            count,
            delay_steps,
            checksum,
            chunks: Chunks::new(count),
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
        let vals = st.chunks.check(seq, count, values)?;
        let at = st.chunks.written();
        self.area
            .get_mut(at..at + vals.len())
            .ok_or(NackReason::TooLong)?
            .copy_from_slice(vals);
        st.chunks.advance(vals.len());
        self.staged = Some(st);
        Ok(())
    }

    /// Check the upload and make it the controller's analytical part and compensator (whole): its
    /// checksum, then whether `budget`'s tick can run it (`TickBudget`), then the model's own
    /// checks. Returns the model's kind and checksum. Refused: the upload is dropped, the model in
    /// force stays.
    ///
    /// Out of line: the new parts are built (in place) only when an upload is committed, and
    /// whatever frame that takes is not reserved for every request.
    #[inline(never)]
    pub fn commit(
        &mut self,
        ctl: &mut Controller,
        at_rest: bool,
        budget: &TickBudget,
    ) -> Result<(ModelKind, u32), NackReason> {
        if !at_rest {
            return Err(NackReason::Busy);
        }
        let st = self.staged.take().ok_or(NackReason::Sequence)?;
        if !st.chunks.complete() {
            return Err(NackReason::Incomplete);
        }
        let v = self.area.get(..st.count).ok_or(NackReason::Shape)?;
        if rths_link::model_values_checksum(st.kind, v, st.delay_steps) != st.checksum {
            return Err(NackReason::Checksum);
        }
        let rnn_hidden = rths_link::rnn_hidden_of(v.len()).unwrap_or(0);
        if !budget.fits(st.kind, rnn_hidden) {
            return Err(NackReason::TickBudget);
        }
        match st.kind {
            ModelKind::Lrx => {
                let (frame, lead) = lrx_parts(v)?;
                ctl.set_lrx(frame, lead).map_err(|_| NackReason::Busy)?;
            }
            ModelKind::Rnn => {
                let (weights, scaling) = rnn_parts(v)?;
                ctl.install_rnn(weights, scaling).map_err(replace_nack)?;
            }
            ModelKind::FeAts => {
                let &[expected_delay_s] = v else {
                    return Err(NackReason::Shape);
                };
                // Checked before anything changes; the same parts as `assemble_in`'s FE + ATS,
                // built here by their own installs: `assemble_in` called with a run-time spec
                // holds every kind's temporaries in one ~47 KiB frame.
                let ats = AtsParams::new(AtsConfig::paper(DT_S, expected_delay_s))
                    .map_err(|_| NackReason::OutOfRange)?;
                let fe =
                    FeModel::new(Prototype::paper(), DT_S).map_err(|_| NackReason::OutOfRange)?;
                ctl.install_fe(fe).map_err(replace_nack)?;
                ctl.install_ats(ats).map_err(replace_nack)?;
            }
            ModelKind::Lr => return Err(NackReason::Unsupported),
        }
        Ok((st.kind, st.checksum))
    }
}

/// The link's reason for a controller's refusal to take new parameters.
pub fn replace_nack(e: ReplaceError) -> NackReason {
    match e {
        ReplaceError::Busy(_) => NackReason::Busy,
        ReplaceError::Kind => NackReason::Unsupported,
        ReplaceError::Model(_) => NackReason::OutOfRange,
    }
}

/// The RNN weights and scaling of an upload's values (`rths_link::rnn_value_count`'s order), as
/// slices of them; the hidden size is the count's.
fn rnn_parts(v: &[f64]) -> Result<(RnnWeights<'_>, RnnScaling), NackReason> {
    let h = rths_link::rnn_hidden_of(v.len()).ok_or(NackReason::Shape)?;
    let (w_ih, rest) = v
        .split_at_checked(h * RNN_INPUTS)
        .ok_or(NackReason::Shape)?;
    let (w_hh, rest) = rest.split_at_checked(h * h).ok_or(NackReason::Shape)?;
    let (b_h, rest) = rest.split_at_checked(h).ok_or(NackReason::Shape)?;
    let (w_ho, rest) = rest.split_at_checked(h).ok_or(NackReason::Shape)?;
    let &[b_o, m0, m1, s0, s1, out_mean, out_std] = rest else {
        return Err(NackReason::Shape);
    };
    Ok((
        RnnWeights {
            w_ih,
            w_hh,
            b_h,
            w_ho,
            b_o,
        },
        RnnScaling {
            input_mean: [m0, m1],
            input_std: [s0, s1],
            output_mean: out_mean,
            output_std: out_std,
        },
    ))
}

/// The flat values of an RNN's weights and scaling (`rths_link::rnn_value_count`'s order), into
/// `out`; the count written, `None` if `out` is too short. The host sends these; the compiled-in
/// model's checksum is theirs.
pub fn rnn_values(w: &RnnWeights<'_>, s: &RnnScaling, out: &mut [f64]) -> Option<usize> {
    let ([m0, m1], [s0, s1]) = (s.input_mean, s.input_std);
    let tail = [w.b_o, m0, m1, s0, s1, s.output_mean, s.output_std];
    let mut n = 0;
    for x in w
        .w_ih
        .iter()
        .chain(w.w_hh)
        .chain(w.b_h)
        .chain(w.w_ho)
        .chain(&tail)
    {
        *out.get_mut(n)? = *x;
        n += 1;
    }
    Some(n)
}

/// The link checksum of a compiled-in RNN (what the status reports until an upload, and what an
/// upload of the same model file reports), its values laid out in `scratch`; 0 if it is too short.
pub fn rnn_checksum(
    w: &RnnWeights<'_>,
    s: &RnnScaling,
    delay_steps: u16,
    scratch: &mut [f64],
) -> u32 {
    match rnn_values(w, s, scratch).and_then(|n| scratch.get(..n)) {
        Some(v) => rths_link::model_values_checksum(ModelKind::Rnn, v, delay_steps),
        None => 0,
    }
}

/// The lead stride of an upload's value: a whole number of ticks in 1..=64 (the lead's own check
/// then bounds it further).
pub(crate) fn stride_of(x: f64) -> Result<usize, NackReason> {
    if (1.0..=64.0).contains(&x) && libm::floor(x) == x {
        Ok(x as usize)
    } else {
        Err(NackReason::OutOfRange)
    }
}

/// The LRX frame model and lead filter of an upload's values (`rths_link::lrx_values`' order),
/// validated by core's own checks (shapes, finiteness, ranges); the stride must be a whole number
/// of ticks.
fn lrx_parts(v: &[f64]) -> Result<(LrxParams, LeadParams), NackReason> {
    let stride = stride_of(*v.get(19).ok_or(NackReason::Shape)?)?;
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
    let lead = LeadParams::new(weights, stride).map_err(|_| NackReason::OutOfRange)?;
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

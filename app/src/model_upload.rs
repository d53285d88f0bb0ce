//! Chunked model uploads of any kind into any image (LRX, an RNN of any hidden size up to the
//! controller's capacity, FE + ATS, and the structure parts: a structure's finite elements, linear
//! or yielding, its structure metamodel, its modal-hysteretic model, an imported structure's
//! reduced model), validated on the device as the values arrive (order, count, finiteness) and at
//! the commit (end-to-end checksum, the sizes the values announce, the board's tick budget, then
//! the model's own checks as `rths_core::model` makes them); refused whole, the model in force
//! kept. The values wait in one staging area of [`rths_link::MODEL_MAX_VALUES`]; their layout is
//! `rths_link::layout`'s, and [`install`] builds them in the controller in place
//! (`rths_core::model::assemble_in`: no ~9 kB RNN or 33 KiB ATS on the stack), for an upload and
//! for the image's compiled-in default alike.

use rths_core::control::{Controller, ReplaceError};
use rths_core::metamodel::{RnnScaling, RnnWeights};
use rths_core::model::{assemble_in, ModelSpec};
use rths_core::params::{Prototype, DT_S};
use rths_link::layout::{self, LayoutError};
use rths_link::{ModelKind, NackReason, RECORD_CHUNK};

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

/// A `kind` upload of `values` values may have its kind's shape (`rths_link::layout::count_fits`;
/// the sizes the values announce are checked at the commit). `Err(Unsupported)` for a kind that
/// is not uploaded in chunks (an LR goes in one `UploadLr`), `Err(Shape)` for another count.
pub fn shape_ok(kind: ModelKind, values: usize) -> Result<(), NackReason> {
    if kind == ModelKind::Lr {
        return Err(NackReason::Unsupported);
    }
    layout::count_fits(kind, values).map_err(layout_nack)
}

/// The link's reason for values that are no model of their kind.
pub fn layout_nack(e: LayoutError) -> NackReason {
    match e {
        LayoutError::Shape => NackReason::Shape,
        LayoutError::Value => NackReason::OutOfRange,
        LayoutError::Kind => NackReason::Unsupported,
    }
}

/// Build the `kind` model of `values` (`rths_link::layout`'s layout) in `ctl`, in place, as the
/// controller's analytical part and compensator (`rths_core::model::assemble_in`, the host's
/// assembly); only at rest. The controller starts over from its own configuration. Refused
/// (values that are no model of the kind `Shape`, a value out of its range `OutOfRange`, under a
/// test `Busy`): the controller's parts are unspecified only if core refused a part it had
/// begun to build, which its checks before building prevent.
#[inline(never)]
pub fn install(ctl: &mut Controller, kind: ModelKind, values: &[f64]) -> Result<(), NackReason> {
    if !ctl.supervisor().at_rest() {
        return Err(NackReason::Busy);
    }
    layout::with_spec(kind, values, |spec| {
        assemble_in(ctl, spec, Prototype::paper(), DT_S)
    })
    .map_err(layout_nack)?
    .map_err(replace_nack)
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
        let dims = layout::dims(st.kind, v).map_err(layout_nack)?;
        if !budget.fits_dims(st.kind, &dims) {
            return Err(NackReason::TickBudget);
        }
        install(ctl, st.kind, v)?;
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

/// The flat values of an RNN's weights and scaling (`rths_link::rnn_value_count`'s order), into
/// `out`; the count written, `None` if `out` is too short. The host sends these; the compiled-in
/// model's checksum is theirs.
pub fn rnn_values(w: &RnnWeights<'_>, s: &RnnScaling, out: &mut [f64]) -> Option<usize> {
    let spec = ModelSpec::Rnn {
        weights: *w,
        scaling: *s,
    };
    layout::lay_out(&spec, out).ok().map(|(_, n)| n)
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

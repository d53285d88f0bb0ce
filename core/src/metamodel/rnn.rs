//! A basic Elman RNN metamodel (inference only; training is on the host).

use super::{all_finite, shape, ModelError};
use crate::filter::{finite, InputError};

/// Number of RNN inputs: [ü_g (mm/s²), F_fb (kN)].
pub const RNN_INPUTS: usize = 2;

/// Input order of the RNN (model files carry it).
pub const RNN_INPUT_NAMES: [&str; RNN_INPUTS] = ["ground_accel_mm_s2", "brace_force_fb_kn"];

/// Largest supported RNN hidden size (storage is fixed at this capacity).
pub const RNN_MAX_HIDDEN: usize = 32;

/// Raw weights of an Elman RNN with hidden size H, row-major, as a model file stores them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RnnWeights<'a> {
    /// Input-to-hidden W_ih, H×[`RNN_INPUTS`] row-major (row j = hidden unit j).
    pub w_ih: &'a [f64],
    /// Hidden-to-hidden W_hh, H×H row-major.
    pub w_hh: &'a [f64],
    /// Hidden bias b_h, H (the sum of PyTorch-style b_ih + b_hh, if the trainer has both).
    pub b_h: &'a [f64],
    /// Hidden-to-output W_ho, 1×H.
    pub w_ho: &'a [f64],
    /// Output bias b_o.
    pub b_o: f64,
}

/// Input normalization and output de-normalization of the RNN: `in_n = (in − mean)/std`,
/// `y = y_n·std + mean`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RnnScaling {
    /// Per-input mean, order [`RNN_INPUT_NAMES`] (mm/s², kN).
    pub input_mean: [f64; RNN_INPUTS],
    /// Per-input standard deviation (> 0).
    pub input_std: [f64; RNN_INPUTS],
    /// Output mean, mm.
    pub output_mean: f64,
    /// Output standard deviation, mm (> 0).
    pub output_std: f64,
}

/// Validated Elman RNN parameters in fixed-capacity storage (sized for [`RNN_MAX_HIDDEN`]; entries
/// beyond the hidden size are zero and never read).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RnnParams {
    hidden: usize,
    // Row-major with row length H (not the capacity), so the first H·2 and H·H entries are exactly
    // the slices [`elman_step`] takes.
    w_ih: [f64; RNN_INPUTS * RNN_MAX_HIDDEN],
    w_hh: [f64; RNN_MAX_HIDDEN * RNN_MAX_HIDDEN],
    b_h: [f64; RNN_MAX_HIDDEN],
    w_ho: [f64; RNN_MAX_HIDDEN],
    b_o: f64,
    scaling: RnnScaling,
}

impl RnnParams {
    /// Validate shapes (hidden size H = `b_h.len()` in 1..=32; W_ih H×2, W_hh H×H, W_ho 1×H),
    /// finiteness of every weight and scale, and std > 0.
    pub fn new(w: RnnWeights<'_>, scaling: RnnScaling) -> Result<Self, ModelError> {
        let h = Self::check(&w, &scaling)?;
        let mut p = Self {
            hidden: h,
            w_ih: [0.0; RNN_INPUTS * RNN_MAX_HIDDEN],
            w_hh: [0.0; RNN_MAX_HIDDEN * RNN_MAX_HIDDEN],
            b_h: [0.0; RNN_MAX_HIDDEN],
            w_ho: [0.0; RNN_MAX_HIDDEN],
            b_o: w.b_o,
            scaling,
        };
        p.w_ih.iter_mut().zip(w.w_ih).for_each(|(d, s)| *d = *s);
        p.w_hh.iter_mut().zip(w.w_hh).for_each(|(d, s)| *d = *s);
        p.b_h.iter_mut().zip(w.b_h).for_each(|(d, s)| *d = *s);
        p.w_ho.iter_mut().zip(w.w_ho).for_each(|(d, s)| *d = *s);
        Ok(p)
    }

    /// Replace these parameters with `w` and `scaling`, validated as [`Self::new`] does, in place
    /// (no ~9 kB value on the stack: a device loads an uploaded RNN this way). Refused: nothing
    /// changes. The result equals `Self::new(w, scaling)`.
    pub fn assign(&mut self, w: RnnWeights<'_>, scaling: RnnScaling) -> Result<(), ModelError> {
        let h = Self::check(&w, &scaling)?;
        self.hidden = h;
        fill(&mut self.w_ih, w.w_ih);
        fill(&mut self.w_hh, w.w_hh);
        fill(&mut self.b_h, w.b_h);
        fill(&mut self.w_ho, w.w_ho);
        self.b_o = w.b_o;
        self.scaling = scaling;
        Ok(())
    }

    /// The checks of [`Self::new`]; the hidden size.
    pub(crate) fn check(w: &RnnWeights<'_>, scaling: &RnnScaling) -> Result<usize, ModelError> {
        let h = w.b_h.len();
        if h == 0 || h > RNN_MAX_HIDDEN {
            return Err(ModelError::HiddenSize(h));
        }
        shape(w.w_ih, h * RNN_INPUTS, "RNN W_ih")?;
        shape(w.w_hh, h * h, "RNN W_hh")?;
        shape(w.w_ho, h, "RNN W_ho")?;
        all_finite(w.w_ih, "RNN W_ih")?;
        all_finite(w.w_hh, "RNN W_hh")?;
        all_finite(w.b_h, "RNN b_h")?;
        all_finite(w.w_ho, "RNN W_ho")?;
        all_finite(&[w.b_o], "RNN b_o")?;
        all_finite(&scaling.input_mean, "RNN input mean")?;
        all_finite(&[scaling.output_mean], "RNN output mean")?;
        for s in scaling.input_std {
            crate::params::positive(s, "RNN input std")?;
        }
        crate::params::positive(scaling.output_std, "RNN output std")?;
        Ok(h)
    }

    /// Hidden size H.
    pub fn hidden(&self) -> usize {
        self.hidden
    }

    /// Normalization constants.
    pub fn scaling(&self) -> &RnnScaling {
        &self.scaling
    }

    /// The weights as the H-sized slices they were given in.
    pub fn weights(&self) -> RnnWeights<'_> {
        let h = self.hidden;
        // `h ≤ RNN_MAX_HIDDEN` (checked in `new`), so every `get` succeeds; `get` rather than
        // indexing keeps a panic path out of the control step.
        RnnWeights {
            w_ih: self.w_ih.get(..RNN_INPUTS * h).unwrap_or(&[]),
            w_hh: self.w_hh.get(..h * h).unwrap_or(&[]),
            b_h: self.b_h.get(..h).unwrap_or(&[]),
            w_ho: self.w_ho.get(..h).unwrap_or(&[]),
            b_o: self.b_o,
        }
    }
}

/// `dest` = `src` followed by zeros (the capacity beyond the hidden size is zero, as `new` leaves it).
fn fill(dest: &mut [f64], src: &[f64]) {
    let mut it = src.iter();
    for d in dest.iter_mut() {
        *d = it.next().copied().unwrap_or(0.0);
    }
}

/// One Elman step in normalized units, the single definition of the RNN's forward pass (this
/// crate's [`Rnn::predict`] and the host trainer both call it):
/// `h_next = tanh(W_ih·input + W_hh·h + b_h)`, returns `y = W_ho·h_next + b_o`. The hidden size H
/// is `w.b_h.len()`; only the first H values of `h` and `h_next` are read and written (a
/// fixed-capacity state may be passed whole).
///
/// The operation order is part of the contract, so that every implementation gives the same bits
/// (model files document it): pre-activation `(Σ_k w_ih[j][k]·input_k + Σ_k w_hh[j][k]·h_k) +
/// b_h[j]`, each sum in index order, `tanh` is `libm::tanh`; output `(Σ_j w_ho[j]·h_next_j) + b_o`.
///
/// No checks (it is the inner loop of training): shapes are the caller's (validated by
/// [`RnnParams::new`]; a short slice shortens the sums, it does not panic), and a non-finite input
/// or weight propagates into the outputs.
#[inline]
pub fn elman_step(
    w: &RnnWeights<'_>,
    h: &[f64],
    input: &[f64; RNN_INPUTS],
    h_next: &mut [f64],
) -> f64 {
    let n = w.b_h.len();
    // `max(1)`: `chunks_exact(0)` panics; with H = 0 there are no rows anyway.
    let rows = w
        .w_ih
        .chunks_exact(RNN_INPUTS)
        .zip(w.w_hh.chunks_exact(n.max(1)))
        .zip(w.b_h);
    for (hj, ((wi, wh), b)) in h_next.iter_mut().zip(rows) {
        let from_in: f64 = wi.iter().zip(input).map(|(w, v)| w * v).sum();
        let from_h: f64 = wh.iter().zip(h).map(|(w, v)| w * v).sum();
        *hj = libm::tanh(from_in + from_h + b);
    }
    let y: f64 = w.w_ho.iter().zip(&*h_next).map(|(w, v)| w * v).sum();
    y + w.b_o
}

/// The inputs of one RNN step (time i).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RnnInputs {
    /// Ground acceleration ü_g(i), mm/s².
    pub ground_accel_mm_s2: f64,
    /// Prototype brace axial force F_fb(i), kN.
    pub brace_force_fb_kn: f64,
}

/// Recurrent state of the RNN: the hidden vector (first H entries used).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RnnState {
    /// Hidden activations h(i).
    pub hidden: [f64; RNN_MAX_HIDDEN],
}

impl RnnState {
    /// Zero hidden vector.
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

/// Elman RNN metamodel: parameters plus state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rnn {
    params: RnnParams,
    pub(super) state: RnnState,
}

impl Rnn {
    /// Every byte zero (hidden size 0): not a usable model, a placeholder that reserves its ~9 kB
    /// where it will live (a zero constant is written as a memset); [`Self::load`] makes it a
    /// model.
    pub const PARKED: Self = Self {
        params: RnnParams {
            hidden: 0,
            w_ih: [0.0; RNN_INPUTS * RNN_MAX_HIDDEN],
            w_hh: [0.0; RNN_MAX_HIDDEN * RNN_MAX_HIDDEN],
            b_h: [0.0; RNN_MAX_HIDDEN],
            w_ho: [0.0; RNN_MAX_HIDDEN],
            b_o: 0.0,
            scaling: RnnScaling {
                input_mean: [0.0; RNN_INPUTS],
                input_std: [0.0; RNN_INPUTS],
                output_mean: 0.0,
                output_std: 0.0,
            },
        },
        state: RnnState {
            hidden: [0.0; RNN_MAX_HIDDEN],
        },
    };

    /// A model with a zero hidden state.
    pub fn new(params: RnnParams) -> Self {
        Self {
            params,
            state: RnnState::default(),
        }
    }

    /// The weights.
    pub fn params(&self) -> &RnnParams {
        &self.params
    }

    /// The hidden state.
    pub fn state(&self) -> &RnnState {
        &self.state
    }

    /// Zero hidden state.
    pub fn reset(&mut self) {
        self.state.reset();
    }

    /// Load new parameters in place ([`RnnParams::assign`]) and zero the state; refused: nothing
    /// changes.
    pub fn load(&mut self, w: RnnWeights<'_>, scaling: RnnScaling) -> Result<(), ModelError> {
        self.params.assign(w, scaling)?;
        self.reset();
        Ok(())
    }

    /// One step: `h = tanh(W_ih·in_n + W_hh·h + b_h)`, `y = (W_ho·h + b_o)·std + mean`, in mm
    /// ([`elman_step`] between the normalization and the de-normalization). Refuses non-finite
    /// inputs (or a non-finite hidden/output) and keeps the state.
    pub fn predict(&mut self, inputs: RnnInputs) -> Result<f64, InputError> {
        let p = &self.params;
        let s = &p.scaling;
        let raw = [
            finite(inputs.ground_accel_mm_s2, "ground_accel_mm_s2")?,
            finite(inputs.brace_force_fb_kn, "brace_force_fb_kn")?,
        ];
        let mut x = [0.0; RNN_INPUTS];
        for (((xn, r), m), sd) in x.iter_mut().zip(raw).zip(s.input_mean).zip(s.input_std) {
            *xn = finite((r - m) / sd, "normalized RNN input")?;
        }
        let mut h_new = [0.0; RNN_MAX_HIDDEN];
        // The step reads and writes only the first H entries.
        let y_n = elman_step(&p.weights(), &self.state.hidden, &x, &mut h_new);
        // tanh saturates at ±1, so only ∞ − ∞ (a NaN pre-activation) can make a hidden value
        // non-finite.
        for v in h_new.iter().take(p.hidden) {
            finite(*v, "RNN hidden state")?;
        }
        let y = finite(y_n * s.output_std + s.output_mean, "RNN prediction")?;
        self.state.hidden = h_new;
        Ok(y)
    }
}

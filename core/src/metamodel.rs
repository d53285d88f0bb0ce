//! Metamodel inference (DESIGN §5): the linear-regression (LR) model of the paper's Eq. 6 with a bias,
//! and a basic Elman RNN. Training lives on the host; this is the `no_std`, allocation-free inference
//! the firmware runs at 2048 Hz.
//!
//! Units of every feature: ground acceleration ü_g in mm/s², measured brace deformation x_fb in mm
//! (prototype scale = actuator stroke), prototype brace axial force F_fb in kN (= 1000 × load cell),
//! output x̂ = brace deformation command in mm.
//!
//! Non-finite input policy: a NaN or infinite feature (or a prediction that would overflow) is
//! *refused* with [`InputError`] and the recurrent state is left exactly as it was, so one bad sample
//! cannot poison the model forever. The caller (the supervisor) is expected to trip on the refusal;
//! if it chooses to continue, the next valid sample continues from the last good state.

use crate::filter::finite;
pub use crate::filter::InputError;
use crate::params::ParamError;

/// Number of LR coefficients (θ0..θ5).
pub const LR_COEFFS: usize = 6;

/// Feature order of the LR model, one name per coefficient θ0..θ5. Model files carry this list and
/// loaders must check it: x̂(i+1) = θ0 + θ1·ü_g(i) + θ2·x_fb(i) + θ3·F_fb(i) + θ4·x̂(i) + θ5·x̂(i−1).
pub const LR_FEATURE_NAMES: [&str; LR_COEFFS] = [
    "bias",
    "ground_accel_mm_s2",
    "brace_disp_fb_mm",
    "brace_force_fb_kn",
    "pred_disp_mm(i)",
    "pred_disp_mm(i-1)",
];

/// Number of RNN inputs: [ü_g (mm/s²), F_fb (kN)].
pub const RNN_INPUTS: usize = 2;

/// Input order of the RNN (model files carry it).
pub const RNN_INPUT_NAMES: [&str; RNN_INPUTS] = ["ground_accel_mm_s2", "brace_force_fb_kn"];

/// Largest supported RNN hidden size (storage is fixed at this capacity).
pub const RNN_MAX_HIDDEN: usize = 32;

/// A model whose shape or values failed validation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelError {
    /// A weight array has the wrong number of elements.
    Shape {
        /// Which array.
        what: &'static str,
        /// Elements required by the model's sizes.
        expected: usize,
        /// Elements supplied.
        got: usize,
    },
    /// The RNN hidden size is not in 1..=[`RNN_MAX_HIDDEN`].
    HiddenSize(usize),
    /// A value failed validation (non-finite weight, non-positive std).
    Param(ParamError),
}

impl From<ParamError> for ModelError {
    fn from(e: ParamError) -> Self {
        ModelError::Param(e)
    }
}

impl core::fmt::Display for ModelError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ModelError::Shape {
                what,
                expected,
                got,
            } => {
                write!(f, "{what} has {got} elements, expected {expected}")
            }
            ModelError::HiddenSize(h) => {
                write!(f, "hidden size {h} is not in 1..={RNN_MAX_HIDDEN}")
            }
            ModelError::Param(e) => write!(f, "{e}"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for ModelError {}

fn all_finite(values: &[f64], what: &'static str) -> Result<(), ParamError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(ParamError::NotFinite(what))
    }
}

fn shape(values: &[f64], expected: usize, what: &'static str) -> Result<(), ModelError> {
    if values.len() == expected {
        Ok(())
    } else {
        Err(ModelError::Shape {
            what,
            expected,
            got: values.len(),
        })
    }
}

// ---------------------------------------------------------------------------------------------------
// LR
// ---------------------------------------------------------------------------------------------------

/// Validated coefficients θ0..θ5 of the LR metamodel (order: [`LR_FEATURE_NAMES`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LrParams {
    theta: [f64; LR_COEFFS],
}

impl LrParams {
    /// From the six coefficients; all must be finite.
    pub fn new(theta: [f64; LR_COEFFS]) -> Result<Self, ModelError> {
        all_finite(&theta, "LR coefficient")?;
        Ok(Self { theta })
    }

    /// From a slice (as read from a model file); must hold exactly [`LR_COEFFS`] finite values.
    pub fn from_slice(theta: &[f64]) -> Result<Self, ModelError> {
        shape(theta, LR_COEFFS, "LR coefficients")?;
        let mut t = [0.0; LR_COEFFS];
        t.iter_mut().zip(theta).for_each(|(d, s)| *d = *s);
        Self::new(t)
    }

    /// The coefficients θ0..θ5.
    pub fn theta(&self) -> &[f64; LR_COEFFS] {
        &self.theta
    }
}

/// The exogenous features of one LR step (time i).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Features {
    /// Ground acceleration ü_g(i), mm/s².
    pub ground_accel_mm_s2: f64,
    /// Measured brace deformation x_fb(i), mm (= actuator stroke, displacement scale 1).
    pub brace_disp_fb_mm: f64,
    /// Prototype brace axial force F_fb(i), kN (= 1000 × load-cell force).
    pub brace_force_fb_kn: f64,
}

/// Recurrent state of the LR model: the last two predictions.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LrState {
    /// x̂(i), mm.
    pub pred_mm: f64,
    /// x̂(i−1), mm.
    pub prev_pred_mm: f64,
}

impl LrState {
    /// At rest (both predictions zero, as the structure starts).
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

/// LR metamodel: parameters plus state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lr {
    params: LrParams,
    state: LrState,
}

impl Lr {
    /// A model at rest.
    pub fn new(params: LrParams) -> Self {
        Self {
            params,
            state: LrState::default(),
        }
    }

    /// The coefficients.
    pub fn params(&self) -> &LrParams {
        &self.params
    }

    /// The recurrent state.
    pub fn state(&self) -> &LrState {
        &self.state
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.state.reset();
    }

    /// x̂(i+1) from the features at i and the last two predictions; shifts the state.
    /// Refuses non-finite features (or an overflowing prediction) and keeps the state.
    pub fn predict(&mut self, f: Features) -> Result<f64, InputError> {
        let ag = finite(f.ground_accel_mm_s2, "ground_accel_mm_s2")?;
        let x_fb = finite(f.brace_disp_fb_mm, "brace_disp_fb_mm")?;
        let f_fb = finite(f.brace_force_fb_kn, "brace_force_fb_kn")?;
        let [t0, t1, t2, t3, t4, t5] = self.params.theta;
        // Summed in feature order, as the trainer does; the bias needs no multiplication by 1 (the
        // MCU does f64 in software, so each operation saved is ~60 instructions).
        let y = finite(
            t0 + t1 * ag
                + t2 * x_fb
                + t3 * f_fb
                + t4 * self.state.pred_mm
                + t5 * self.state.prev_pred_mm,
            "LR prediction",
        )?;
        self.state = LrState {
            pred_mm: y,
            prev_pred_mm: self.state.pred_mm,
        };
        Ok(y)
    }
}

// ---------------------------------------------------------------------------------------------------
// RNN
// ---------------------------------------------------------------------------------------------------

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
    w_ih: [[f64; RNN_INPUTS]; RNN_MAX_HIDDEN],
    w_hh: [[f64; RNN_MAX_HIDDEN]; RNN_MAX_HIDDEN],
    b_h: [f64; RNN_MAX_HIDDEN],
    w_ho: [f64; RNN_MAX_HIDDEN],
    b_o: f64,
    scaling: RnnScaling,
}

impl RnnParams {
    /// Validate shapes (hidden size H = `b_h.len()` in 1..=32; W_ih H×2, W_hh H×H, W_ho 1×H),
    /// finiteness of every weight and scale, and std > 0.
    pub fn new(w: RnnWeights<'_>, scaling: RnnScaling) -> Result<Self, ModelError> {
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

        let mut p = Self {
            hidden: h,
            w_ih: [[0.0; RNN_INPUTS]; RNN_MAX_HIDDEN],
            w_hh: [[0.0; RNN_MAX_HIDDEN]; RNN_MAX_HIDDEN],
            b_h: [0.0; RNN_MAX_HIDDEN],
            w_ho: [0.0; RNN_MAX_HIDDEN],
            b_o: w.b_o,
            scaling,
        };
        for (row, src) in p.w_ih.iter_mut().zip(w.w_ih.chunks_exact(RNN_INPUTS)) {
            row.iter_mut().zip(src).for_each(|(d, s)| *d = *s);
        }
        for (row, src) in p.w_hh.iter_mut().zip(w.w_hh.chunks_exact(h)) {
            row.iter_mut().zip(src).for_each(|(d, s)| *d = *s);
        }
        p.b_h.iter_mut().zip(w.b_h).for_each(|(d, s)| *d = *s);
        p.w_ho.iter_mut().zip(w.w_ho).for_each(|(d, s)| *d = *s);
        Ok(p)
    }

    /// Hidden size H.
    pub fn hidden(&self) -> usize {
        self.hidden
    }

    /// Normalization constants.
    pub fn scaling(&self) -> &RnnScaling {
        &self.scaling
    }
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
    state: RnnState,
}

impl Rnn {
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

    /// One step: `h = tanh(W_ih·in_n + W_hh·h + b_h)`, `y = (W_ho·h + b_o)·std + mean`, in mm.
    /// Refuses non-finite inputs (or a non-finite hidden/output) and keeps the state.
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
        let hidden_rows = p.w_ih.iter().zip(&p.w_hh).zip(&p.b_h).take(p.hidden);
        for (hj, ((wi, wh), b)) in h_new.iter_mut().zip(hidden_rows) {
            let from_in: f64 = wi.iter().zip(&x).map(|(w, v)| w * v).sum();
            let from_h: f64 = wh
                .iter()
                .zip(&self.state.hidden)
                .take(p.hidden)
                .map(|(w, v)| w * v)
                .sum();
            // tanh saturates at ±1, so only ∞ − ∞ (a NaN pre-activation) can make this non-finite.
            *hj = finite(libm::tanh(from_in + from_h + b), "RNN hidden state")?;
        }
        let y_n: f64 = p
            .w_ho
            .iter()
            .zip(&h_new)
            .take(p.hidden)
            .map(|(w, v)| w * v)
            .sum::<f64>()
            + p.b_o;
        let y = finite(y_n * s.output_std + s.output_mean, "RNN prediction")?;
        self.state.hidden = h_new;
        Ok(y)
    }
}

// ---------------------------------------------------------------------------------------------------
// LRX: a specimen-faithful linear metamodel of the analytical substructure
// ---------------------------------------------------------------------------------------------------

/// Lags of each LRX input (own prediction, ground acceleration, corrected brace force). Three is the
/// order of Chang's discrete frame model (state d, v, a), so the identified ARX can be exact.
pub const LRX_ORDER: usize = 3;

/// Number of LRX coefficients: `a` (own predictions), `b` (ground acceleration), `c` (force).
pub const LRX_COEFFS: usize = 3 * LRX_ORDER;

/// Coefficient order of the LRX model (model files carry it):
/// d̂(i+1) = Σ_j a_j·d̂(i−j) + Σ_j b_j·ü_g(i−j) + Σ_j c_j·F̃(i−j), j = 0..[`LRX_ORDER`], with the
/// brace force corrected to the model's own displacement, F̃(i) = F_fb(i) + k_c·(d̂(i) − x_fb(i)).
pub const LRX_FEATURE_NAMES: [&str; LRX_COEFFS] = [
    "pred_disp_mm(i)",
    "pred_disp_mm(i-1)",
    "pred_disp_mm(i-2)",
    "ground_accel_mm_s2(i)",
    "ground_accel_mm_s2(i-1)",
    "ground_accel_mm_s2(i-2)",
    "corrected_force_kn(i)",
    "corrected_force_kn(i-1)",
    "corrected_force_kn(i-2)",
];

/// Validated LRX parameters.
///
/// The model is a linear input–output (ARX) model of the *analytical substructure only* (frame, mass,
/// damping): it maps the ground acceleration and the brace force to the brace deformation, and has no
/// notion of the specimen's stiffness. The measured force is a genuine input. Before it enters, the
/// force is corrected to the model's own displacement, F̃ = F_fb + k̂·(d̂ − x_fb), with k̂ an estimate
/// of the specimen's stiffness (prototype scale): the force the specimen would have at the target
/// displacement. That removes, to first order, the effect of the actuator's tracking error (its
/// residual delay) on the computed structure; an error in k̂ only scales that small correction.
///
/// k̂ starts at the nominal `k_corr` (the paper's brace) and, if `adapt_ticks` > 0, follows the
/// specimen by exponentially weighted least squares of the measured force on the measured
/// displacement, k̂ = Σλ^j·F·x / Σλ^j·x² with λ = 1 − 1/`adapt_ticks`, while the weighted RMS
/// displacement exceeds [`LRX_ADAPT_MIN_RMS_MM`] (below it the last estimate holds), bounded to
/// [`LRX_ADAPT_BOUNDS`] × nominal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LrxParams {
    coeffs: [f64; LRX_COEFFS],
    k_corr_kn_per_mm: f64,
    adapt_ticks: f64,
    // The stiffness estimate runs in f32 (the MCU's FPU; f64 is software there): it only scales
    // the small force correction, so 1e-7 relative rounding does not matter.
    forgetting: f32,
    min_sxx: f32,
    k_lo: f32,
    k_hi: f32,
}

/// Weighted RMS brace deformation (mm) above which the stiffness estimate is used.
pub const LRX_ADAPT_MIN_RMS_MM: f64 = 0.25;

/// Bounds of the stiffness estimate, relative to the nominal `k_corr`.
pub const LRX_ADAPT_BOUNDS: [f64; 2] = [0.25, 4.0];

impl LrxParams {
    /// From the coefficients (order [`LRX_FEATURE_NAMES`]), the nominal force-correction stiffness
    /// (kN/mm, prototype brace axial; 0 disables the correction) and the time constant of its
    /// online estimate in ticks (0: fixed at nominal; else ≥ 1). All finite and ≥ 0.
    pub fn new(
        coeffs: [f64; LRX_COEFFS],
        k_corr_kn_per_mm: f64,
        adapt_ticks: f64,
    ) -> Result<Self, ModelError> {
        all_finite(&coeffs, "LRX coefficient")?;
        all_finite(&[k_corr_kn_per_mm, adapt_ticks], "LRX correction parameter")?;
        if k_corr_kn_per_mm < 0.0 {
            return Err(ModelError::Param(ParamError::OutOfRange(
                "LRX force-correction stiffness",
            )));
        }
        if adapt_ticks != 0.0 && adapt_ticks < 1.0 {
            return Err(ModelError::Param(ParamError::OutOfRange(
                "LRX stiffness-estimate time constant",
            )));
        }
        let (forgetting, min_sxx) = if adapt_ticks > 0.0 {
            (
                (1.0 - 1.0 / adapt_ticks) as f32,
                (LRX_ADAPT_MIN_RMS_MM * LRX_ADAPT_MIN_RMS_MM * adapt_ticks) as f32,
            )
        } else {
            (0.0, f32::INFINITY)
        };
        let [lo, hi] = LRX_ADAPT_BOUNDS;
        Ok(Self {
            coeffs,
            k_corr_kn_per_mm,
            adapt_ticks,
            forgetting,
            min_sxx,
            k_lo: (lo * k_corr_kn_per_mm) as f32,
            k_hi: (hi * k_corr_kn_per_mm) as f32,
        })
    }

    /// From a slice (as read from a model file); exactly [`LRX_COEFFS`] values.
    pub fn from_slice(
        coeffs: &[f64],
        k_corr_kn_per_mm: f64,
        adapt_ticks: f64,
    ) -> Result<Self, ModelError> {
        shape(coeffs, LRX_COEFFS, "LRX coefficients")?;
        let mut c = [0.0; LRX_COEFFS];
        c.iter_mut().zip(coeffs).for_each(|(d, s)| *d = *s);
        Self::new(c, k_corr_kn_per_mm, adapt_ticks)
    }

    /// The coefficients, order [`LRX_FEATURE_NAMES`].
    pub fn coeffs(&self) -> &[f64; LRX_COEFFS] {
        &self.coeffs
    }

    /// The nominal force-correction stiffness, kN/mm.
    pub fn k_corr_kn_per_mm(&self) -> f64 {
        self.k_corr_kn_per_mm
    }

    /// Time constant of the stiffness estimate, ticks (0: fixed).
    pub fn adapt_ticks(&self) -> f64 {
        self.adapt_ticks
    }
}

/// The exogenous inputs of one LRX step (time i), prototype units.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LrxInputs {
    /// Ground acceleration ü_g(i), mm/s².
    pub ground_accel_mm_s2: f64,
    /// Measured brace deformation x_fb(i), mm.
    pub brace_disp_fb_mm: f64,
    /// Measured brace axial force F_fb(i), kN.
    pub brace_force_fb_kn: f64,
}

/// LRX recurrent state: the last predictions and inputs (all zero at rest).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LrxState {
    /// d̂(i), d̂(i−1), d̂(i−2), mm.
    pub pred_mm: [f64; LRX_ORDER],
    /// ü_g(i−1), ü_g(i−2), mm/s².
    pub ground_accel_mm_s2: [f64; LRX_ORDER - 1],
    /// F̃(i−1), F̃(i−2), kN.
    pub force_kn: [f64; LRX_ORDER - 1],
    /// Weighted Σ x_fb², mm² (f32: see [`LrxParams`]).
    pub sxx: f32,
    /// Weighted Σ F_fb·x_fb, kN·mm.
    pub sfx: f32,
    /// The stiffness estimate in use, kN/mm (0 at rest: the nominal is used until the first estimate).
    pub k_est_kn_per_mm: f64,
}

impl LrxState {
    /// At rest.
    pub fn reset(&mut self) {
        *self = Self::default();
    }
}

/// The LRX metamodel: parameters plus state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lrx {
    params: LrxParams,
    state: LrxState,
}

impl Lrx {
    /// A model at rest.
    pub fn new(params: LrxParams) -> Self {
        Self {
            params,
            state: LrxState::default(),
        }
    }

    /// The parameters.
    pub fn params(&self) -> &LrxParams {
        &self.params
    }

    /// The recurrent state.
    pub fn state(&self) -> &LrxState {
        &self.state
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.state.reset();
    }

    /// d̂(i+1) from the inputs at i and the state; shifts the state. Refuses non-finite inputs (or an
    /// overflowing prediction) and keeps the state.
    pub fn predict(&mut self, inp: LrxInputs) -> Result<f64, InputError> {
        let ag = finite(inp.ground_accel_mm_s2, "ground_accel_mm_s2")?;
        let x_fb = finite(inp.brace_disp_fb_mm, "brace_disp_fb_mm")?;
        let f_fb = finite(inp.brace_force_fb_kn, "brace_force_fb_kn")?;
        let s = &self.state;
        let p = &self.params;
        let [d0, d1, d2] = s.pred_mm;
        let [g1, g2] = s.ground_accel_mm_s2;
        let [f1, f2] = s.force_kn;
        // The last estimate holds while the motion is too small to estimate (0 at rest: nominal).
        let k_held = if s.k_est_kn_per_mm > 0.0 {
            s.k_est_kn_per_mm
        } else {
            p.k_corr_kn_per_mm
        };
        let (mut sxx, mut sfx, mut k) = (s.sxx, s.sfx, k_held);
        if p.forgetting > 0.0 {
            let (x, f) = (x_fb as f32, f_fb as f32);
            sxx = p.forgetting * sxx + x * x;
            sfx = p.forgetting * sfx + f * x;
            if !(sxx.is_finite() && sfx.is_finite()) {
                return Err(InputError::NotFinite("LRX stiffness sum"));
            }
            if sxx > p.min_sxx {
                k = f64::from((sfx / sxx).max(p.k_lo).min(p.k_hi));
            }
        }
        let f0 = finite(f_fb + k * (d0 - x_fb), "LRX corrected force")?;
        let [a0, a1, a2, b0, b1, b2, c0, c1, c2] = p.coeffs;
        let y = finite(
            a0 * d0 + a1 * d1 + a2 * d2 + b0 * ag + b1 * g1 + b2 * g2 + c0 * f0 + c1 * f1 + c2 * f2,
            "LRX prediction",
        )?;
        self.state = LrxState {
            pred_mm: [y, d0, d1],
            ground_accel_mm_s2: [ag, g1],
            force_kn: [f0, f1],
            sxx,
            sfx,
            k_est_kn_per_mm: k,
        };
        Ok(y)
    }
}

#[cfg(test)]
mod tests;

//! The linear-regression (LR) metamodel of the paper's Eq. 6, with a bias.

use super::{all_finite, shape, ModelError};
use crate::filter::{finite, InputError};

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
    pub(super) state: LrState,
}

impl Lr {
    /// All coefficients zero, at rest: the placeholder a controller is reserved with before its
    /// analytical part is built in place (`Controller::init_in`).
    pub const PARKED: Self = Self {
        params: LrParams {
            theta: [0.0; LR_COEFFS],
        },
        state: LrState {
            pred_mm: 0.0,
            prev_pred_mm: 0.0,
        },
    };

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

//! LRX: a specimen-faithful linear metamodel of the analytical substructure.

use super::{all_finite, shape, ModelError};
use crate::filter::{finite, InputError};
use crate::params::ParamError;

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
    // The specimen's own inertia and damping (prototype scale), removed from the measured force;
    // f32 coefficients on the model's own differences: a correction of a few % of the force.
    mass_kn_s2_per_mm: f64,
    damping_kn_s_per_mm: f64,
    mass_per_tick2: f32,
    damping_per_tick: f32,
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
            mass_kn_s2_per_mm: 0.0,
            damping_kn_s_per_mm: 0.0,
            mass_per_tick2: 0.0,
            damping_per_tick: 0.0,
        })
    }

    /// The same model with the specimen's own moving mass and damping (prototype brace scale,
    /// kN·s²/mm and kN·s/mm, both ≥ 0, e.g. `rths identify`'s specimen fit) removed from the
    /// measured force: `F_fb − m·ẍ − c·ẋ` is the force of the specimen's spring alone, the part the
    /// computed structure stands for. The derivatives are those of the model's own displacement
    /// (noise-free; the compensated actuator follows it), backward differences at step `dt_s`.
    /// Both 0: the force is used as measured (as before this option existed).
    pub fn with_specimen_dynamics(
        mut self,
        mass_kn_s2_per_mm: f64,
        damping_kn_s_per_mm: f64,
        dt_s: f64,
    ) -> Result<Self, ModelError> {
        all_finite(
            &[mass_kn_s2_per_mm, damping_kn_s_per_mm, dt_s],
            "LRX specimen dynamics",
        )?;
        if mass_kn_s2_per_mm < 0.0 || damping_kn_s_per_mm < 0.0 || dt_s <= 0.0 {
            return Err(ModelError::Param(ParamError::OutOfRange(
                "LRX specimen mass, damping (>= 0) or dt_s (> 0)",
            )));
        }
        self.mass_kn_s2_per_mm = mass_kn_s2_per_mm;
        self.damping_kn_s_per_mm = damping_kn_s_per_mm;
        self.mass_per_tick2 = (mass_kn_s2_per_mm / (dt_s * dt_s)) as f32;
        self.damping_per_tick = (0.5 * damping_kn_s_per_mm / dt_s) as f32;
        Ok(self)
    }

    /// The specimen's moving mass and damping removed from the measured force (prototype scale).
    pub fn specimen_dynamics(&self) -> (f64, f64) {
        (self.mass_kn_s2_per_mm, self.damping_kn_s_per_mm)
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
    pub(super) state: LrxState,
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
        let s = &self.state;
        let p = &self.params;
        let [d0, d1, d2] = s.pred_mm;
        let mut f_fb = finite(inp.brace_force_fb_kn, "brace_force_fb_kn")?;
        if p.mass_per_tick2 != 0.0 || p.damping_per_tick != 0.0 {
            // Velocity and acceleration of the model's displacement one tick back (central
            // differences), in f32 (the MCU's FPU): the second difference of ~10 mm loses ~1e-6 mm
            // to rounding, 0.3% of its value at 2 Hz, of a force term that is itself a few %.
            let (e0, e1, e2) = (d0 as f32, d1 as f32, d2 as f32);
            let a = (e0 - e1) - (e1 - e2);
            let spurious = p.mass_per_tick2 * a + p.damping_per_tick * (e0 - e2);
            f_fb = finite(f_fb - f64::from(spurious), "LRX spring force")?;
        }
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

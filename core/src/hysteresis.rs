//! Hysteretic story laws: the force–drift relation of a story that yields (docs/design.md §3.2).
//!
//! Two laws, both rate-independent and evaluated once per integration step at the step's drift
//! (an explicit integrator fixes the displacement before the force is needed, so no iteration):
//!
//! - **Bilinear kinematic hardening**: elastic slope `k0` inside a yield band that translates along
//!   the hardening line `α·k0·u`. The force is the elastic trial clamped to the band
//!   `α·k0·u ± (1−α)·fy`, which is the exact return map of the law, so loops are exact
//!   parallelograms (area `4·(1−α)·fy·(u_max − u_y)` per symmetric cycle).
//! - **Bouc–Wen**: `f = α·k0·u + (1−α)·fy·z`, `dz/du = (1 − |z|ⁿ·(β·sgn(du·z) + γ))/u_y`, with
//!   `u_y = fy/k0`; `z` is integrated over the step's drift increment by midpoint (RK2) sub-steps of
//!   at most [`BOUC_WEN_MAX_SUBSTEP`]·`u_y` (bounded count, so the cost per tick is bounded).
//!
//! Units: mm, kN.

use crate::params::{positive, ParamError};

/// Lowest admissible post-yield stiffness ratio `α`. Mild softening (P-Δ) is allowed; steeper
/// negative stiffness makes the story collapse under its own drift and is refused.
pub const MIN_POST_YIELD_RATIO: f64 = -0.1;
/// Highest admissible post-yield stiffness ratio (exclusive): `α = 1` is no yielding at all.
pub const MAX_POST_YIELD_RATIO: f64 = 1.0;
/// Admissible Bouc–Wen exponents `n` (sharpness of the yield knee).
pub const BOUC_WEN_EXPONENT_RANGE: (f64, f64) = (1.0, 20.0);
/// Largest Bouc–Wen sub-step, as a fraction of the yield drift `u_y`.
pub const BOUC_WEN_MAX_SUBSTEP: f64 = 0.05;
/// Most sub-steps per update (a drift jump larger than this many sub-steps is integrated in this
/// many equal, coarser steps: the cost per tick stays bounded).
pub const BOUC_WEN_MAX_SUBSTEPS: usize = 64;

fn post_yield_ratio(alpha: f64) -> Result<f64, ParamError> {
    if !alpha.is_finite() {
        Err(ParamError::NotFinite("post-yield ratio"))
    } else if !(MIN_POST_YIELD_RATIO..MAX_POST_YIELD_RATIO).contains(&alpha) {
        Err(ParamError::OutOfRange("post-yield ratio (-0.1 ≤ α < 1)"))
    } else {
        Ok(alpha)
    }
}

/// A validated hysteresis law of one story (built only by [`Law::bilinear`] and
/// [`Law::bouc_wen`], so every law in use passed their checks).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Law(Kind);

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Bilinear {
        k0_kn_per_mm: f64,
        yield_force_kn: f64,
        post_yield_ratio: f64,
    },
    BoucWen {
        k0_kn_per_mm: f64,
        yield_force_kn: f64,
        post_yield_ratio: f64,
        exponent: f64,
        beta: f64,
        gamma: f64,
        /// `(β+γ)^(−1/n)`, the bound of `|z|`.
        z_max: f64,
        /// `n` when it is a whole number (then `|z|ⁿ` is a few products, not `pow`), else 0.
        whole_exponent: u32,
    },
}

impl Law {
    /// Bilinear kinematic hardening: `k0 > 0`, `fy > 0`, `α` in [[`MIN_POST_YIELD_RATIO`], 1).
    pub fn bilinear(
        k0_kn_per_mm: f64,
        yield_force_kn: f64,
        post_yield_ratio_: f64,
    ) -> Result<Self, ParamError> {
        Ok(Law(Kind::Bilinear {
            k0_kn_per_mm: positive(k0_kn_per_mm, "initial story stiffness")?,
            yield_force_kn: positive(yield_force_kn, "yield force")?,
            post_yield_ratio: post_yield_ratio(post_yield_ratio_)?,
        }))
    }

    /// Bouc–Wen: as [`Law::bilinear`], plus `n` in [`BOUC_WEN_EXPONENT_RANGE`], `β > 0` and
    /// `|γ| ≤ β` (the loop is traversed clockwise and dissipates energy) and `β + γ > 0` (z is
    /// bounded, so the story yields at `fy·(β+γ)^(−1/n)`; `β = γ = ½` yields at `fy`).
    pub fn bouc_wen(
        k0_kn_per_mm: f64,
        yield_force_kn: f64,
        post_yield_ratio_: f64,
        exponent: f64,
        beta: f64,
        gamma: f64,
    ) -> Result<Self, ParamError> {
        let k0 = positive(k0_kn_per_mm, "initial story stiffness")?;
        let fy = positive(yield_force_kn, "yield force")?;
        let alpha = post_yield_ratio(post_yield_ratio_)?;
        if !exponent.is_finite() || !gamma.is_finite() {
            return Err(ParamError::NotFinite("Bouc-Wen n or γ"));
        }
        let (lo, hi) = BOUC_WEN_EXPONENT_RANGE;
        if !(lo..=hi).contains(&exponent) {
            return Err(ParamError::OutOfRange("Bouc-Wen exponent n (1..=20)"));
        }
        let beta = positive(beta, "Bouc-Wen β")?;
        if gamma.abs() > beta || gamma <= -beta {
            return Err(ParamError::OutOfRange("Bouc-Wen γ (−β < γ ≤ β)"));
        }
        Ok(Law(Kind::BoucWen {
            k0_kn_per_mm: k0,
            yield_force_kn: fy,
            post_yield_ratio: alpha,
            exponent,
            beta,
            gamma,
            z_max: libm::pow(beta + gamma, -1.0 / exponent),
            whole_exponent: if libm::floor(exponent) == exponent {
                // In 1..=20 here (validated above), so the cast is exact.
                exponent as u32
            } else {
                0
            },
        }))
    }

    /// Initial stiffness, kN/mm.
    pub fn k0_kn_per_mm(&self) -> f64 {
        match self.0 {
            Kind::Bilinear { k0_kn_per_mm, .. } | Kind::BoucWen { k0_kn_per_mm, .. } => {
                k0_kn_per_mm
            }
        }
    }

    /// Yield force, kN.
    pub fn yield_force_kn(&self) -> f64 {
        match self.0 {
            Kind::Bilinear { yield_force_kn, .. } | Kind::BoucWen { yield_force_kn, .. } => {
                yield_force_kn
            }
        }
    }

    /// Yield drift `fy/k0`, mm: the unit of ductility.
    pub fn yield_drift_mm(&self) -> f64 {
        self.yield_force_kn() / self.k0_kn_per_mm()
    }

    /// Post-yield stiffness over initial stiffness `α`.
    pub fn post_yield_ratio(&self) -> f64 {
        match self.0 {
            Kind::Bilinear {
                post_yield_ratio, ..
            }
            | Kind::BoucWen {
                post_yield_ratio, ..
            } => post_yield_ratio,
        }
    }

    /// Bouc–Wen's `[n, β, γ]` (`None`: bilinear). With [`Self::k0_kn_per_mm`],
    /// [`Self::yield_force_kn`] and [`Self::post_yield_ratio`] they rebuild the law exactly (the
    /// firmware's build script compiles a structure file's laws in this way).
    pub fn bouc_wen_shape(&self) -> Option<[f64; 3]> {
        match self.0 {
            Kind::Bilinear { .. } => None,
            Kind::BoucWen {
                exponent,
                beta,
                gamma,
                ..
            } => Some([exponent, beta, gamma]),
        }
    }
}

/// A story's small state under its law (16 bytes: last drift and the law's internal variable),
/// kept apart from the law so that a model with fixed laws copies only this per step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StoryState {
    drift_mm: f64,
    /// Bilinear: the force, kN. Bouc–Wen: `z`.
    internal: f64,
}

impl StoryState {
    /// At rest, virgin.
    pub const REST: Self = Self {
        drift_mm: 0.0,
        internal: 0.0,
    };

    /// The drift of the last update, mm.
    pub fn drift_mm(&self) -> f64 {
        self.drift_mm
    }
}

impl Law {
    /// The force of a story in `state` under this law, kN.
    #[inline]
    pub fn force_kn(&self, state: &StoryState) -> f64 {
        match self.0 {
            Kind::Bilinear { .. } => state.internal,
            Kind::BoucWen {
                k0_kn_per_mm,
                yield_force_kn,
                post_yield_ratio,
                ..
            } => {
                post_yield_ratio * k0_kn_per_mm * state.drift_mm
                    + (1.0 - post_yield_ratio) * yield_force_kn * state.internal
            }
        }
    }

    /// Move `state` to `drift_mm` (the path from the last drift is taken as monotonic) and return
    /// the story force, kN. A non-finite drift leaves the state unchanged.
    #[inline]
    pub fn update(&self, state: &mut StoryState, drift_mm: f64) -> f64 {
        if !drift_mm.is_finite() {
            return self.force_kn(state);
        }
        let du = drift_mm - state.drift_mm;
        match self.0 {
            Kind::Bilinear {
                k0_kn_per_mm,
                yield_force_kn,
                post_yield_ratio,
            } => {
                let trial = state.internal + k0_kn_per_mm * du;
                let back = post_yield_ratio * k0_kn_per_mm * drift_mm;
                let band = (1.0 - post_yield_ratio) * yield_force_kn;
                state.internal = clamp(trial, back - band, back + band);
            }
            Kind::BoucWen {
                k0_kn_per_mm,
                yield_force_kn,
                exponent,
                beta,
                gamma,
                z_max,
                whole_exponent,
                ..
            } => {
                let uy = yield_force_kn / k0_kn_per_mm;
                let ratio = libm::fabs(du) / (BOUC_WEN_MAX_SUBSTEP * uy);
                // `ratio` is finite and ≥ 0 here; the cast saturates.
                let steps = (libm::ceil(ratio) as usize).clamp(1, BOUC_WEN_MAX_SUBSTEPS);
                let h = du / steps as f64;
                let rate = |z: f64| {
                    let sign = if h * z >= 0.0 { 1.0 } else { -1.0 };
                    let zn = if whole_exponent > 0 {
                        powi(libm::fabs(z), whole_exponent)
                    } else {
                        libm::pow(libm::fabs(z), exponent)
                    };
                    (1.0 - zn * (beta * sign + gamma)) / uy
                };
                // `|z|` never exceeds its bound `(β+γ)^(−1/n)` (where dz/du vanishes); clamping
                // to it keeps a drift jump far larger than the sub-step cap from overshooting.
                let mut z = state.internal;
                for _ in 0..steps {
                    let mid = clamp(z + 0.5 * h * rate(z), -z_max, z_max);
                    z = clamp(z + h * rate(mid), -z_max, z_max);
                }
                state.internal = z;
            }
        }
        state.drift_mm = drift_mm;
        self.force_kn(state)
    }
}

/// A story: its law and its small state ([`StoryState`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Story {
    law: Law,
    state: StoryState,
}

impl Story {
    /// A story at rest.
    pub fn new(law: Law) -> Self {
        Self {
            law,
            state: StoryState::REST,
        }
    }

    /// The law.
    pub fn law(&self) -> &Law {
        &self.law
    }

    /// Its state.
    pub fn state(&self) -> &StoryState {
        &self.state
    }

    /// Back to rest, virgin state.
    pub fn reset(&mut self) {
        self.state = StoryState::REST;
    }

    /// The drift of the last update, mm.
    pub fn drift_mm(&self) -> f64 {
        self.state.drift_mm
    }

    /// The force at the last update, kN.
    pub fn force_kn(&self) -> f64 {
        self.law.force_kn(&self.state)
    }

    /// Move to `drift_mm` ([`Law::update`]) and return the story force, kN. A non-finite drift
    /// leaves the state unchanged.
    pub fn update(&mut self, drift_mm: f64) -> f64 {
        self.law.update(&mut self.state, drift_mm)
    }
}

/// `x^n` for a whole `n ≥ 1` by squaring: on a Cortex-M a general `pow` costs hundreds of
/// instructions per call, and Bouc–Wen calls it twice per sub-step. Equal to `pow` for `n = 1, 2`
/// (`x`, `x·x`), within a few ulps otherwise.
#[inline]
fn powi(x: f64, n: u32) -> f64 {
    let mut base = x;
    let mut e = n;
    let mut acc = 1.0;
    while e > 0 {
        if e & 1 == 1 {
            acc *= base;
        }
        e >>= 1;
        if e > 0 {
            base *= base;
        }
    }
    acc
}

/// `f64::clamp`'s result without its `min <= max` assertion: the bounds here are ordered by the
/// law's validation, which the compiler cannot see, and the control step must not reach a panic
/// (the firmware's panic check).
#[inline]
fn clamp(x: f64, lo: f64, hi: f64) -> f64 {
    let mut y = x;
    if y < lo {
        y = lo;
    }
    if y > hi {
        y = hi;
    }
    y
}

#[cfg(test)]
mod tests;

//! Chang's explicit method on uncoupled modal equations of unit mass, the integrator the
//! modal-hysteretic (`modal_hyst.rs`) and the reduced modal (`reduced_modal.rs`) models share: the
//! scalar case of [`crate::structure_n::ChangN`]'s `D = M + ½ΔtC + ¼Δt²K0`, `β1 = D⁻¹(M + ½ΔtC)`,
//! `β2 = D⁻¹·½M`. Each model sizes its arrays by its own largest number of modes (`N`).

use super::ModelError;
use crate::params::ParamError;

/// A finite, positive time step.
pub(super) fn time_step(dt_s: f64) -> Result<f64, ModelError> {
    if !dt_s.is_finite() {
        Err(ParamError::NotFinite("time step").into())
    } else if dt_s <= 0.0 {
        Err(ParamError::NotPositive("time step").into())
    } else {
        Ok(dt_s)
    }
}

/// Chang's coefficients of one modal equation of unit mass.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct ModeStep {
    /// Damping `2ζω`, 1/s.
    pub(super) c: f64,
    /// Stiffness `ω²`, 1/s².
    pub(super) k: f64,
    /// `β1·Δt`.
    pub(super) b1_dt: f64,
    /// `β2·Δt²`.
    pub(super) b2_dt2: f64,
    /// `1 / (1 + ½Δt·c)`.
    pub(super) solve: f64,
}

impl ModeStep {
    /// The coefficients of a mode of circular frequency `omega_rad_s` and damping ratio
    /// `damping_ratio` at step `dt_s`.
    pub(super) fn new(omega_rad_s: f64, damping_ratio: f64, dt_s: f64) -> Self {
        let c = 2.0 * damping_ratio * omega_rad_s;
        let k = omega_rad_s * omega_rad_s;
        let m_half_c = 1.0 + 0.5 * dt_s * c;
        let d = m_half_c + 0.25 * dt_s * dt_s * k;
        Self {
            c,
            k,
            b1_dt: m_half_c / d * dt_s,
            b2_dt2: 0.5 / d * dt_s * dt_s,
            solve: 1.0 / m_half_c,
        }
    }
}

/// Chang's explicit prediction `d₁ = d₀ + β1Δt·v₀ + β2Δt²·a₀` of the first `r` modes, and whether
/// all are finite.
#[inline]
pub(super) fn predict<const N: usize>(
    step: &[ModeStep; N],
    d: &[f64; N],
    v: &[f64; N],
    a: &[f64; N],
    r: usize,
) -> ([f64; N], bool) {
    let mut next = [0.0; N];
    let mut ok = true;
    for ((((x, s), d), v), a) in next.iter_mut().zip(step).zip(d).zip(v).zip(a).take(r) {
        *x = d + s.b1_dt * v + s.b2_dt2 * a;
        ok &= x.is_finite();
    }
    (next, ok)
}

//! The structure metamodel: a fixed-order ARX model of an N-DOF numerical substructure at its
//! specimen's DOF, in backward-difference (delta) form (docs/benchmark.md, "The metamodel").
//!
//! `d(k+1) − d(k) = Σ_j a_j·Δʲd(k) + Σ_j b_j·Δʲü_g(k) + Σ_j c_j·ΔʲF̃(k)`, j < [`DELTA_ARX_ORDER`],
//! with `Δʲ` the j-th backward difference. An exact input-output model of an N-DOF part at one DOF
//! has order 2N, so order 6 is exact for 3 stories (Chang's step is a linear map); at 4096 Hz the
//! AR roots cluster near z = 1 and a shift-form fit is ill-conditioned, which the delta basis
//! avoids. Per tick it costs 3·[`DELTA_ARX_ORDER`] multiply-adds plus the differences, whatever N
//! is: the point of a metamodel of a large structure.
//!
//! The force it takes is corrected to the model's own displacement, `F̃ = F_m + k_c·(d̂ − x_m)`
//! ([`DeltaArx::predict`]), as the LRX does: the force the specimen would have at the target.
//! Training (host, `rths train meta`) fits the coefficients; this is the `no_std`,
//! allocation-free inference the controller and the benchmark share.

use super::{all_finite, shape, ModelError};
use crate::filter::{finite, InputError};
use crate::params::ParamError;

/// Lags of each input (and of the output).
pub const DELTA_ARX_ORDER: usize = 6;

/// Number of coefficients: `a` (own displacement), `b` (ground acceleration), `c` (force), each
/// [`DELTA_ARX_ORDER`] long, in that order.
pub const DELTA_ARX_COEFFS: usize = 3 * DELTA_ARX_ORDER;

/// A history, newest first: `h[i] = s(k − i)`.
pub type DeltaArxHistory = [f64; DELTA_ARX_ORDER];

/// `Δʲs(k)`, j < [`DELTA_ARX_ORDER`], from `h[i] = s(k − i)`.
#[inline]
fn deltas(h: &DeltaArxHistory) -> DeltaArxHistory {
    let mut out = [0.0; DELTA_ARX_ORDER];
    let mut row = *h;
    for o in out.iter_mut() {
        *o = row[0];
        // Next order: Δs(k − i) = s(k − i) − s(k − i − 1); the oldest has no predecessor (0).
        let mut next = [0.0; DELTA_ARX_ORDER];
        for ((n, a), b) in next.iter_mut().zip(&row).zip(row.iter().skip(1)) {
            *n = a - b;
        }
        row = next;
    }
    out
}

/// Shift `v` into a history (newest first).
#[inline]
pub fn push_history(h: &mut DeltaArxHistory, v: f64) {
    h.copy_within(0..DELTA_ARX_ORDER - 1, 1);
    h[0] = v;
}

/// The regressors of one tick: the backward differences of the own displacement, the ground
/// acceleration and the force histories, in the coefficients' order (training builds its rows
/// with it, so fit and inference share one definition).
#[inline]
pub fn delta_features(
    disp: &DeltaArxHistory,
    ag: &DeltaArxHistory,
    force: &DeltaArxHistory,
) -> [f64; DELTA_ARX_COEFFS] {
    let mut phi = [0.0; DELTA_ARX_COEFFS];
    for (chunk, h) in phi.chunks_mut(DELTA_ARX_ORDER).zip([disp, ag, force]) {
        chunk.copy_from_slice(&deltas(h));
    }
    phi
}

/// Validated structure-metamodel parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeltaArxParams {
    theta: [f64; DELTA_ARX_COEFFS],
    k_corr_kn_per_mm: f64,
}

impl DeltaArxParams {
    /// `theta` ([`DELTA_ARX_COEFFS`] finite values, order of [`delta_features`]) and the force
    /// correction's stiffness `k_corr_kn_per_mm` (finite, ≥ 0; 0: the force as measured).
    pub fn from_slice(theta: &[f64], k_corr_kn_per_mm: f64) -> Result<Self, ModelError> {
        shape(theta, DELTA_ARX_COEFFS, "structure metamodel coefficients")?;
        all_finite(theta, "structure metamodel coefficients")?;
        if !k_corr_kn_per_mm.is_finite() {
            return Err(ParamError::NotFinite("force-correction stiffness").into());
        }
        if k_corr_kn_per_mm < 0.0 {
            return Err(ParamError::OutOfRange("force-correction stiffness (≥ 0)").into());
        }
        let mut t = [0.0; DELTA_ARX_COEFFS];
        t.copy_from_slice(theta);
        Ok(Self {
            theta: t,
            k_corr_kn_per_mm,
        })
    }

    /// The coefficients.
    pub fn theta(&self) -> &[f64; DELTA_ARX_COEFFS] {
        &self.theta
    }

    /// The force correction's stiffness, kN/mm.
    pub fn k_corr_kn_per_mm(&self) -> f64 {
        self.k_corr_kn_per_mm
    }
}

/// The structure metamodel and its histories (at rest: all zero).
#[derive(Debug, Clone, PartialEq)]
pub struct DeltaArx {
    params: DeltaArxParams,
    disp: DeltaArxHistory,
    ag: DeltaArxHistory,
    force: DeltaArxHistory,
}

impl DeltaArx {
    /// At rest.
    pub fn new(params: DeltaArxParams) -> Self {
        Self {
            params,
            disp: [0.0; DELTA_ARX_ORDER],
            ag: [0.0; DELTA_ARX_ORDER],
            force: [0.0; DELTA_ARX_ORDER],
        }
    }

    /// The parameters.
    pub fn params(&self) -> &DeltaArxParams {
        &self.params
    }

    /// Back to rest (parameters kept).
    pub fn reset(&mut self) {
        *self = Self::new(self.params);
    }

    /// Tick k: the own displacement d(k) is the last prediction; take ü_g(k) and the (already
    /// corrected) force F̃(k), return d(k+1). A non-finite input or result is refused and the
    /// histories are left as they were.
    #[inline]
    pub fn step(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, InputError> {
        let (mut ag, mut force) = (self.ag, self.force);
        push_history(&mut ag, finite(ag_mm_s2, "ground acceleration")?);
        push_history(&mut force, finite(force_kn, "structure force")?);
        let phi = delta_features(&self.disp, &ag, &force);
        let inc: f64 = phi.iter().zip(&self.params.theta).map(|(p, t)| p * t).sum();
        let next = finite(self.disp[0] + inc, "structure metamodel output")?;
        self.ag = ag;
        self.force = force;
        push_history(&mut self.disp, next);
        Ok(next)
    }

    /// Tick k with the measured displacement `disp_fb_mm` and force `force_fb_kn` at the specimen's
    /// DOF: the force corrected to the model's own displacement, `F̃ = F_m + k_c·(d̂(k) − x_m)`,
    /// then [`Self::step`].
    #[inline]
    pub fn predict(
        &mut self,
        ag_mm_s2: f64,
        disp_fb_mm: f64,
        force_fb_kn: f64,
    ) -> Result<f64, InputError> {
        let d_k = self.disp[0];
        self.step(
            ag_mm_s2,
            force_fb_kn + self.params.k_corr_kn_per_mm * (d_k - disp_fb_mm),
        )
    }

    /// The displacement of the current tick (the last prediction), mm.
    pub fn current_mm(&self) -> f64 {
        self.disp[0]
    }
}

//! Online adaptation of the lead filter: a bounded gain-and-delay correction stage in front of the
//! (fixed, identified) lead, fitted by exponentially weighted least squares from the measured
//! displacement (docs/design.md §6, "Adaptive lead").
//!
//! The lead `W` inverts the actuator `H` as well as its 8 taps and the identification allow; what
//! is left, `W·H ≈ g·e^{−sδ}` with g ≈ 1 and δ a few ms at most, drifts with the plant. Its inverse
//! to first order is `v = b0·x + b1·ẋ` with `b0 = 1/g`, `b1 = δ/g` (ATS's law, one term shorter:
//! the Taylor series of a small residual delay needs no second-order term). The stage feeds
//! `v = b0·x_t + b1·Δx_t` (Δ: one tick) to the lead and fits `b0, b1` online by regressing the lead
//! input it sent on the displacement that answered it: `v(j−1) ≈ b0·x_m(j) + b1·ẋ_m(j)`, where the
//! velocity is the centered difference `(x_m(j+m) − x_m(j−m))/2m` (ticks; the span `m` =
//! [`LEAD_ADAPT_SPAN`] averages the sensor noise so that the regressor's noise does not bias `b1`).
//!
//! Bounds, as ATS has them: `b0 ∈` [`LEAD_ADAPT_GAIN_BOUNDS`], `b1 ∈` [`LEAD_ADAPT_DELAY_BOUNDS_TICKS`],
//! each coefficient moves at most [`LEAD_ADAPT_MAX_STEP`] per tick towards its least-squares value,
//! and the fit is frozen (coefficients held) while the weighted RMS displacement is below
//! [`LEAD_ADAPT_MIN_RMS_MM`], the weighted RMS velocity below [`LEAD_ADAPT_MIN_VEL_MM_PER_TICK`], or
//! the two regressors are nearly collinear ([`LEAD_ADAPT_MAX_CORRELATION`]). The controller only
//! runs the compensator while the supervisor is `Running`, so it is frozen outside a test too.
//!
//! Single precision (the MCU's FPU): 5 running sums and a 2×2 solve per tick. The two regressors
//! are nearly orthogonal for an oscillation, so the solve does not amplify the sums' rounding
//! (it would for the 8 lead weights, whose normal matrix f32 cannot hold: docs/design.md §6). On the
//! firmware this stage and the specimen-dynamics removal cost ~660 instructions per tick.

use super::input;
use crate::filter::InputError;
use crate::params::ParamError;

/// Half-span of the centered velocity of the regression, ticks.
pub const LEAD_ADAPT_SPAN: usize = 8;

/// Bounds of the gain correction b0.
pub const LEAD_ADAPT_GAIN_BOUNDS: [f32; 2] = [0.8, 1.25];

/// Bounds of the delay correction b1, ticks (±6 ms at 2048 Hz).
pub const LEAD_ADAPT_DELAY_BOUNDS_TICKS: [f32; 2] = [-12.0, 12.0];

/// Largest change per tick of [b0, b1 (ticks)]: the full gain range takes ~2 s, 1 ms of delay
/// correction ~0.5 s at 2048 Hz.
pub const LEAD_ADAPT_MAX_STEP: [f32; 2] = [2.0e-4, 2.0e-3];

/// Weighted RMS measured displacement (mm) below which the fit is frozen (as ATS's start threshold).
pub const LEAD_ADAPT_MIN_RMS_MM: f32 = 0.25;

/// Weighted RMS measured velocity (mm per tick) below which the fit is frozen: 1 mm/s at 2048 Hz.
pub const LEAD_ADAPT_MIN_VEL_MM_PER_TICK: f32 = 1.0 / 2048.0;

/// Largest |correlation| of the two regressors at which the fit is used.
pub const LEAD_ADAPT_MAX_CORRELATION: f32 = 0.99;

/// Ring of the measured displacement and of the lead input: the last 2·span of each (a power of
/// two, so the index wraps by a mask).
const RING: usize = (2 * LEAD_ADAPT_SPAN).next_power_of_two();

/// Validated settings of the adaptation: its time constant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeadAdaptParams {
    ticks: f64,
    forgetting: f32,
    min_sxx: f32,
    min_sdd: f32,
}

impl LeadAdaptParams {
    /// The time constant of the exponentially weighted fit, ticks (≥ 4·[`LEAD_ADAPT_SPAN`]: the
    /// window must hold several velocity spans).
    pub fn new(ticks: f64) -> Result<Self, ParamError> {
        if !ticks.is_finite() {
            return Err(ParamError::NotFinite("lead adaptation time constant"));
        }
        if ticks < 4.0 * LEAD_ADAPT_SPAN as f64 || ticks > 1.0e7 {
            return Err(ParamError::OutOfRange(
                "lead adaptation time constant (32..=1e7 ticks)",
            ));
        }
        let n = ticks as f32;
        Ok(Self {
            ticks,
            forgetting: 1.0 - 1.0 / n,
            min_sxx: LEAD_ADAPT_MIN_RMS_MM * LEAD_ADAPT_MIN_RMS_MM * n,
            min_sdd: LEAD_ADAPT_MIN_VEL_MM_PER_TICK * LEAD_ADAPT_MIN_VEL_MM_PER_TICK * n,
        })
    }

    /// The time constant, ticks.
    pub fn ticks(&self) -> f64 {
        self.ticks
    }
}

/// The state of the adaptation: coefficients, weighted sums and the short histories it needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeadAdaptState {
    /// The gain correction in use.
    pub gain: f32,
    /// The delay correction in use, ticks.
    pub delay_ticks: f32,
    /// Weighted Σ x², Σ x·ẋ, Σ ẋ², Σ v·x, Σ v·ẋ (x: measured, ẋ per tick, v: lead input).
    pub sums: [f32; 5],
    /// Ticks at which the fit moved the coefficients.
    pub updates: u32,
    x_ring: [f32; RING],
    v_ring: [f32; RING],
    newest: usize,
    last_target: f32,
}

impl Default for LeadAdaptState {
    fn default() -> Self {
        Self {
            gain: 1.0,
            delay_ticks: 0.0,
            sums: [0.0; 5],
            updates: 0,
            x_ring: [0.0; RING],
            v_ring: [0.0; RING],
            newest: 0,
            last_target: 0.0,
        }
    }
}

/// `v` moved towards `goal` by at most `step`, inside `[lo, hi]`.
fn approach(v: f32, goal: f32, step: f32, [lo, hi]: [f32; 2]) -> f32 {
    let goal = goal.max(lo).min(hi);
    let next = if goal > v + step {
        v + step
    } else if goal < v - step {
        v - step
    } else {
        goal
    };
    next.max(lo).min(hi)
}

/// What one accepted tick changes in a [`LeadAdaptState`] (small: the rings are written in place by
/// [`LeadAdaptState::commit`], never copied, which costs the MCU more than the arithmetic).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct LeadAdaptStep {
    gain: f32,
    delay_ticks: f32,
    sums: [f32; 5],
    updated: bool,
    measured: f32,
    input: f32,
    target: f32,
}

impl LeadAdaptState {
    fn at(ring: &[f32; RING], newest: usize, back: usize) -> f32 {
        ring.get(newest.wrapping_sub(back) & (RING - 1))
            .copied()
            .unwrap_or(0.0)
    }

    /// The lead input for this tick from the target and the measured displacement (mm), and the
    /// change to the state, applied by [`Self::commit`] only once the lead accepted the input (so a
    /// refused tick leaves everything as it was). Refuses non-finite or out-of-range inputs.
    pub(super) fn correct(
        &self,
        p: &LeadAdaptParams,
        target_mm: f64,
        measured_mm: f64,
    ) -> Result<(f64, LeadAdaptStep), InputError> {
        let xt = input(target_mm, "target_mm")? as f32;
        let xm = input(measured_mm, "measured_mm")? as f32;
        // Regression sample at j = k − m: v(j − 1) against x_m(j) and its centered velocity. The
        // rings' newest entries are x_m(k − 1) and v(k − 1) (this tick's go in at commit).
        let m = LEAD_ADAPT_SPAN;
        let x = Self::at(&self.x_ring, self.newest, m - 1);
        let xd = (xm - Self::at(&self.x_ring, self.newest, 2 * m - 1)) * (0.5 / m as f32);
        let y = Self::at(&self.v_ring, self.newest, m);
        let l = p.forgetting;
        let [sxx, sxd, sdd, svx, svd] = self.sums;
        let sums = [
            l * sxx + x * x,
            l * sxd + x * xd,
            l * sdd + xd * xd,
            l * svx + y * x,
            l * svd + y * xd,
        ];
        if !sums.iter().all(|v| v.is_finite()) {
            return Err(InputError::NotFinite("lead adaptation sum"));
        }
        let [sxx, sxd, sdd, svx, svd] = sums;
        let det = sxx * sdd - sxd * sxd;
        let excited = sxx > p.min_sxx && sdd > p.min_sdd;
        let separable =
            det > (1.0 - LEAD_ADAPT_MAX_CORRELATION * LEAD_ADAPT_MAX_CORRELATION) * sxx * sdd;
        let (mut gain, mut delay_ticks, mut updated) = (self.gain, self.delay_ticks, false);
        if excited && separable {
            let g = (svx * sdd - svd * sxd) / det;
            let d = (svd * sxx - svx * sxd) / det;
            if g.is_finite() && d.is_finite() {
                let [sg, sd] = LEAD_ADAPT_MAX_STEP;
                gain = approach(gain, g, sg, LEAD_ADAPT_GAIN_BOUNDS);
                delay_ticks = approach(delay_ticks, d, sd, LEAD_ADAPT_DELAY_BOUNDS_TICKS);
                updated = true;
            }
        }
        let v = gain * xt + delay_ticks * (xt - self.last_target);
        if !v.is_finite() {
            return Err(InputError::NotFinite("lead adaptation output"));
        }
        Ok((
            f64::from(v),
            LeadAdaptStep {
                gain,
                delay_ticks,
                sums,
                updated,
                measured: xm,
                input: v,
                target: xt,
            },
        ))
    }

    /// Apply an accepted tick.
    pub(super) fn commit(&mut self, step: LeadAdaptStep) {
        self.newest = (self.newest + 1) & (RING - 1);
        if let Some(slot) = self.x_ring.get_mut(self.newest) {
            *slot = step.measured;
        }
        if let Some(slot) = self.v_ring.get_mut(self.newest) {
            *slot = step.input;
        }
        self.gain = step.gain;
        self.delay_ticks = step.delay_ticks;
        self.sums = step.sums;
        if step.updated {
            self.updates = self.updates.saturating_add(1);
        }
        self.last_target = step.target;
    }
}

//! The learned (fixed) lead filter of the LRX path: an FIR predictor of the target.

use super::input;
use super::lead_adapt::{LeadAdaptParams, LeadAdaptState};
use crate::filter::{finite, InputError};
use crate::params::ParamError;

/// Taps of the learned lead filter.
pub const LEAD_TAPS: usize = 8;

/// Longest tap spacing of the lead filter, ticks.
pub const LEAD_MAX_STRIDE: usize = 8;

/// Ring length of the lead filter's target history (power of two ≥ (taps−1)·max stride + 1).
const LEAD_RING: usize = ((LEAD_TAPS - 1) * LEAD_MAX_STRIDE + 1).next_power_of_two();

/// Validated parameters of the learned lead filter: u(k) = Σ_i w_i·x_t(k − i·stride).
///
/// A fixed linear inverse of the plant (delay and gain), identified offline by least squares from
/// plant runs (`rths train lrx`): the same form as the ATS law (a0·x + a1·ẋ + a2·ẍ is a 3-tap filter
/// at stride 1) with more taps, at a fraction of its cost. Optionally with an online, bounded
/// gain-and-delay correction in front of it ([`LeadParams::with_adaptation`], `lead_adapt.rs`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeadParams {
    weights: [f64; LEAD_TAPS],
    stride: usize,
    adapt: Option<LeadAdaptParams>,
}

impl LeadParams {
    /// From the weights (finite) and the tap spacing in ticks (1..=[`LEAD_MAX_STRIDE`]).
    pub fn new(weights: [f64; LEAD_TAPS], stride: usize) -> Result<Self, ParamError> {
        if !weights.iter().all(|w| w.is_finite()) {
            return Err(ParamError::NotFinite("lead filter weight"));
        }
        if !(1..=LEAD_MAX_STRIDE).contains(&stride) {
            return Err(ParamError::OutOfRange("lead filter stride"));
        }
        Ok(Self {
            weights,
            stride,
            adapt: None,
        })
    }

    /// The same filter with the online correction stage in front of it (`None`: fixed, as before).
    pub fn with_adaptation(mut self, adapt: Option<LeadAdaptParams>) -> Self {
        self.adapt = adapt;
        self
    }

    /// The online correction's settings, if it adapts.
    pub fn adaptation(&self) -> Option<&LeadAdaptParams> {
        self.adapt.as_ref()
    }

    /// The weights, newest tap first.
    pub fn weights(&self) -> &[f64; LEAD_TAPS] {
        &self.weights
    }

    /// Tap spacing, ticks.
    pub fn stride(&self) -> usize {
        self.stride
    }
}

/// The learned lead filter: parameters plus the last targets (zeros at rest).
///
/// It runs in single precision (the MCU's FPU is single precision; f64 is software): the command is
/// a sum of 8 products of magnitude ≲ 10× the target, so f32 rounding (6e-8 relative) costs
/// ≲ 1e-5 mm, 80× below the DAC's 16-bit step (0.78 µm over ±25.4 mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lead {
    params: LeadParams,
    weights: [f32; LEAD_TAPS],
    ring: [f32; LEAD_RING],
    newest: usize,
    adapt: LeadAdaptState,
}

impl Lead {
    /// A filter at rest.
    pub fn new(params: LeadParams) -> Self {
        let mut weights = [0.0f32; LEAD_TAPS];
        weights
            .iter_mut()
            .zip(&params.weights)
            .for_each(|(d, s)| *d = *s as f32);
        Self {
            params,
            weights,
            ring: [0.0; LEAD_RING],
            newest: 0,
            adapt: LeadAdaptState::default(),
        }
    }

    /// The parameters.
    pub fn params(&self) -> &LeadParams {
        &self.params
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.ring = [0.0; LEAD_RING];
        self.newest = 0;
        self.adapt = LeadAdaptState::default();
    }

    /// The online correction's state (gain 1, delay 0 while it does not adapt).
    pub fn adaptation_state(&self) -> &LeadAdaptState {
        &self.adapt
    }

    /// One tick of the compensator: the command (mm) for the target, the correction stage fed
    /// with the measured displacement first if the filter adapts (else the measured value is only
    /// checked). Refuses a bad target or measurement and keeps all state.
    pub fn step(&mut self, target_mm: f64, measured_mm: f64) -> Result<f64, InputError> {
        match self.params.adapt {
            None => {
                input(measured_mm, "measured_mm")?;
                self.compensate(target_mm)
            }
            Some(p) => {
                let (v, step) = self.adapt.correct(&p, target_mm, measured_mm)?;
                let u = self.compensate(v)?;
                self.adapt.commit(step);
                Ok(u)
            }
        }
    }

    /// Push the new target and return the command, mm. Refuses a bad target and keeps the history.
    pub fn compensate(&mut self, target_mm: f64) -> Result<f64, InputError> {
        let xt = input(target_mm, "target_mm")? as f32;
        let newest = (self.newest + 1) & (LEAD_RING - 1);
        let mut u = 0.0f32;
        let mut i = newest;
        for (k, w) in self.weights.iter().enumerate() {
            let x = if k == 0 {
                xt
            } else {
                self.ring.get(i).copied().unwrap_or(0.0)
            };
            u += w * x;
            i = i.wrapping_sub(self.params.stride) & (LEAD_RING - 1);
        }
        let u = finite(f64::from(u), "lead command")?;
        if let Some(slot) = self.ring.get_mut(newest) {
            *slot = xt;
        }
        self.newest = newest;
        Ok(u)
    }
}

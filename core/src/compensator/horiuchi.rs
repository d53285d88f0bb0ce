//! Horiuchi's polynomial extrapolation of the target over the expected delay.

use super::input;
use crate::filter::{finite, InputError};
use crate::params::{positive, ParamError};

/// Highest Horiuchi extrapolation order.
pub const HORIUCHI_MAX_ORDER: usize = 3;

/// Validated Horiuchi polynomial extrapolation (Horiuchi et al. 1999): order n, delay, step, and the
/// Lagrange weights of the n+1 most recent targets.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoriuchiParams {
    order: usize,
    delay_s: f64,
    dt_s: f64,
    weights: [f64; HORIUCHI_MAX_ORDER + 1],
}

impl HoriuchiParams {
    /// Order n in 1..=3, delay in [0, 1] s (extrapolating further is meaningless), dt > 0.
    pub fn new(order: usize, delay_s: f64, dt_s: f64) -> Result<Self, ParamError> {
        if order == 0 || order > HORIUCHI_MAX_ORDER {
            return Err(ParamError::OutOfRange("Horiuchi order (1..=3)"));
        }
        let dt = positive(dt_s, "Horiuchi dt_s")?;
        if !delay_s.is_finite() {
            return Err(ParamError::NotFinite("Horiuchi delay"));
        }
        if !(0.0..=1.0).contains(&delay_s) {
            return Err(ParamError::OutOfRange("Horiuchi delay (0..=1 s)"));
        }
        // Nodes at t = −j·dt (j = 0..n), evaluate at t = +delay: w_j = Π_{m≠j} (s + m)/(m − j).
        let s = delay_s / dt;
        let mut weights = [0.0; HORIUCHI_MAX_ORDER + 1];
        for (j, w) in weights.iter_mut().enumerate().take(order + 1) {
            *w = (0..=order)
                .filter(|&m| m != j)
                .map(|m| (s + m as f64) / (m as f64 - j as f64))
                .product();
        }
        Ok(Self {
            order,
            delay_s,
            dt_s: dt,
            weights,
        })
    }

    /// Extrapolation order n.
    pub fn order(&self) -> usize {
        self.order
    }

    /// Extrapolation horizon, s.
    pub fn delay_s(&self) -> f64 {
        self.delay_s
    }

    /// Sample step, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Weights of the targets, newest first (zero beyond the order).
    pub fn weights(&self) -> &[f64; HORIUCHI_MAX_ORDER + 1] {
        &self.weights
    }
}

/// Horiuchi extrapolation: parameters plus the last n+1 targets (initially zero: the rig at rest).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Horiuchi {
    params: HoriuchiParams,
    history: [f64; HORIUCHI_MAX_ORDER + 1],
}

impl Horiuchi {
    /// An extrapolator at rest.
    pub fn new(params: HoriuchiParams) -> Self {
        Self {
            params,
            history: [0.0; HORIUCHI_MAX_ORDER + 1],
        }
    }

    /// The parameters.
    pub fn params(&self) -> &HoriuchiParams {
        &self.params
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.history = [0.0; HORIUCHI_MAX_ORDER + 1];
    }

    /// Push the new target and return its extrapolation `delay_s` ahead, mm.
    pub fn compensate(&mut self, target_mm: f64) -> Result<f64, InputError> {
        let xt = input(target_mm, "target_mm")?;
        let mut h = self.history;
        h.rotate_right(1);
        if let Some(first) = h.first_mut() {
            *first = xt;
        }
        let u = finite(
            self.params.weights.iter().zip(&h).map(|(w, x)| w * x).sum(),
            "Horiuchi command",
        )?;
        self.history = h;
        Ok(u)
    }
}

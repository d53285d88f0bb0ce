//! Butterworth low-pass filter of even order, as cascaded biquads (used by the ATS compensator, docs/design.md §6).
//!
//! Designed once at construction by the bilinear transform with frequency prewarping, so the digital
//! response at the cutoff is exactly the analog prototype's −3.01 dB:
//! `|H(e^{jωT})| = 1 / sqrt(1 + (tan(ωT/2) / tan(ω_c T/2))^{2N})`.
//! The analog prototype's N poles are grouped into N/2 conjugate pairs, each a second-order section
//! with quality factor `Q_k = 1 / (2 sin((2k − 1)π / (2N)))`, k = 1..N/2. Sections run in direct form II
//! transposed (two state words per section, good round-off behaviour in f64).
//!
//! Also home of [`InputError`], the typed refusal of a non-finite or absurd input shared by the
//! metamodels and compensators: a refused input leaves the state untouched.

use crate::params::{positive, ParamError};
use libm::{cos, sin, sqrt, tan};

/// Largest supported filter order (four biquads).
pub const MAX_ORDER: usize = 8;

const MAX_SECTIONS: usize = MAX_ORDER / 2;

/// A per-tick input that was refused. The state that would have consumed it is left untouched, so a
/// single bad sample cannot poison the filter/model forever; the supervisor is expected to trip on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputError {
    /// The named input (or a result computed from it) was NaN or infinite.
    NotFinite(&'static str),
    /// The named input was finite but beyond the documented admissible magnitude.
    OutOfRange(&'static str),
}

impl core::fmt::Display for InputError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            InputError::NotFinite(what) => write!(f, "input {what} is not finite"),
            InputError::OutOfRange(what) => write!(f, "input {what} is out of range"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for InputError {}

/// Refuse a non-finite value.
pub(crate) fn finite(value: f64, what: &'static str) -> Result<f64, InputError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(InputError::NotFinite(what))
    }
}

/// Coefficients of one normalized biquad `(b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²)`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Biquad {
    b0: f64,
    b1: f64,
    b2: f64,
    a1: f64,
    a2: f64,
}

impl Biquad {
    /// All coefficients zero (a placeholder, see [`ButterworthParams::PARKED`]).
    const ZERO: Self = Self {
        b0: 0.0,
        b1: 0.0,
        b2: 0.0,
        a1: 0.0,
        a2: 0.0,
    };

    /// |H(e^{jθ})| of this section at normalized angular frequency θ (rad/sample).
    fn magnitude(&self, theta: f64) -> f64 {
        let (c1, s1) = (cos(theta), sin(theta));
        let (c2, s2) = (cos(2.0 * theta), sin(2.0 * theta));
        let num_re = self.b0 + self.b1 * c1 + self.b2 * c2;
        let num_im = -(self.b1 * s1 + self.b2 * s2);
        let den_re = 1.0 + self.a1 * c1 + self.a2 * c2;
        let den_im = -(self.a1 * s1 + self.a2 * s2);
        sqrt((num_re * num_re + num_im * num_im) / (den_re * den_re + den_im * den_im))
    }
}

/// Validated design of a Butterworth low-pass: order, cutoff, sample rate and the biquad coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ButterworthParams {
    order: usize,
    cutoff_hz: f64,
    sample_rate_hz: f64,
    sections: [Biquad; MAX_SECTIONS],
}

impl ButterworthParams {
    /// All zero: not a filter, a placeholder that lets a compensator be reserved in place (all
    /// zero bytes, so a static of it costs no flash) before [`Self::new`]'s design replaces it.
    pub(crate) const PARKED: Self = Self {
        order: 0,
        cutoff_hz: 0.0,
        sample_rate_hz: 0.0,
        sections: [Biquad::ZERO; MAX_SECTIONS],
    };

    /// Design an `order`-th order low-pass (even, 2..=[`MAX_ORDER`]) with −3.01 dB at `cutoff_hz`,
    /// for a sample rate `sample_rate_hz`. Requires `0 < cutoff_hz < sample_rate_hz / 2`.
    pub fn new(order: usize, cutoff_hz: f64, sample_rate_hz: f64) -> Result<Self, ParamError> {
        if !(2..=MAX_ORDER).contains(&order) || order % 2 != 0 {
            return Err(ParamError::OutOfRange("Butterworth order (even, 2..=8)"));
        }
        let fs = positive(sample_rate_hz, "Butterworth sample rate")?;
        let fc = positive(cutoff_hz, "Butterworth cutoff")?;
        if fc >= 0.5 * fs {
            return Err(ParamError::OutOfRange(
                "Butterworth cutoff (must be below Nyquist)",
            ));
        }
        // Prewarped analog cutoff, in units of 2·fs: the bilinear map sends it exactly onto fc.
        let k = tan(core::f64::consts::PI * fc / fs);
        let k2 = k * k;
        let n = order as f64;
        let mut sections = [Biquad::default(); MAX_SECTIONS];
        for (idx, sec) in sections.iter_mut().take(order / 2).enumerate() {
            let pair = idx as f64 + 1.0;
            // 1/Q = 2 sin((2k−1)π/(2N)): damping of the k-th conjugate pole pair of the prototype.
            let inv_q = 2.0 * sin((2.0 * pair - 1.0) * core::f64::consts::PI / (2.0 * n));
            let norm = 1.0 / (1.0 + k * inv_q + k2);
            let b0 = k2 * norm;
            *sec = Biquad {
                b0,
                b1: 2.0 * b0,
                b2: b0,
                a1: 2.0 * (k2 - 1.0) * norm,
                a2: (1.0 - k * inv_q + k2) * norm,
            };
        }
        Ok(Self {
            order,
            cutoff_hz: fc,
            sample_rate_hz: fs,
            sections,
        })
    }

    /// Filter order N.
    pub fn order(&self) -> usize {
        self.order
    }

    /// −3.01 dB cutoff, Hz.
    pub fn cutoff_hz(&self) -> f64 {
        self.cutoff_hz
    }

    /// Sample rate, Hz.
    pub fn sample_rate_hz(&self) -> f64 {
        self.sample_rate_hz
    }

    fn active(&self) -> impl Iterator<Item = &Biquad> {
        self.sections.iter().take(self.order / 2)
    }

    /// Magnitude of the designed digital filter at `f_hz` (evaluated from the biquad coefficients).
    pub fn magnitude(&self, f_hz: f64) -> f64 {
        let theta = 2.0 * core::f64::consts::PI * f_hz / self.sample_rate_hz;
        self.active().map(|s| s.magnitude(theta)).product()
    }

    /// Magnitude the bilinear design must reproduce: the analog Butterworth prototype at the
    /// prewarped frequency, `1 / sqrt(1 + (tan(π f/fs) / tan(π fc/fs))^{2N})`.
    pub fn prototype_magnitude(&self, f_hz: f64) -> f64 {
        let pi = core::f64::consts::PI;
        let ratio =
            tan(pi * f_hz / self.sample_rate_hz) / tan(pi * self.cutoff_hz / self.sample_rate_hz);
        1.0 / sqrt(1.0 + libm::pow(ratio, 2.0 * self.order as f64))
    }
}

/// A Butterworth low-pass: validated design plus the biquads' state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Butterworth {
    params: ButterworthParams,
    state: [[f64; 2]; MAX_SECTIONS],
}

impl Butterworth {
    /// The [`ButterworthParams::PARKED`] placeholder at rest.
    pub(crate) const PARKED: Self = Self {
        params: ButterworthParams::PARKED,
        state: [[0.0; 2]; MAX_SECTIONS],
    };

    /// A filter at rest (all state zero).
    pub fn new(params: ButterworthParams) -> Self {
        Self {
            params,
            state: [[0.0; 2]; MAX_SECTIONS],
        }
    }

    /// The design.
    pub fn params(&self) -> &ButterworthParams {
        &self.params
    }

    /// Back to rest (zero input history).
    pub fn reset(&mut self) {
        self.state = [[0.0; 2]; MAX_SECTIONS];
    }

    /// Filter one sample. A non-finite input (or a result that overflows) is refused and leaves the
    /// state untouched.
    pub fn step(&mut self, x: f64) -> Result<f64, InputError> {
        let mut next = self.state;
        let y = finite(
            Self::run(&self.params, &mut next, finite(x, "filter input")?),
            "filter output",
        )?;
        if next.iter().flatten().all(|v| v.is_finite()) {
            self.state = next;
            Ok(y)
        } else {
            Err(InputError::NotFinite("filter state"))
        }
    }

    fn run(params: &ButterworthParams, state: &mut [[f64; 2]; MAX_SECTIONS], x: f64) -> f64 {
        params
            .active()
            .zip(state.iter_mut())
            .fold(x, |input, (c, s)| {
                let [s0, s1] = s;
                let y = c.b0 * input + *s0;
                *s0 = c.b1 * input - c.a1 * y + *s1;
                *s1 = c.b2 * input - c.a2 * y;
                y
            })
    }
}

#[cfg(test)]
mod tests;

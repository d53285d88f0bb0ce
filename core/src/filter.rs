//! Butterworth low-pass filter of even order, as cascaded biquads (used by the ATS compensator, DESIGN §6).
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
mod tests {
    extern crate std;
    use super::*;
    use proptest::prelude::*;

    const FS: f64 = 2048.0;

    fn db(m: f64) -> f64 {
        20.0 * libm::log10(m)
    }

    #[test]
    fn sixth_order_20hz_key_points() {
        let p = ButterworthParams::new(6, 20.0, FS).unwrap();
        // −3.0103 dB at the cutoff (1/√2), exactly by prewarping.
        assert!(
            (db(p.magnitude(20.0)) + 3.0103).abs() < 1e-3,
            "{}",
            db(p.magnitude(20.0))
        );
        // One octave up: |H| ≈ 1/sqrt(1 + 2^12) = −36.12 dB (a hair lower from tan warping).
        let at_2fc = db(p.magnitude(40.0));
        assert!((at_2fc + 36.12).abs() < 0.1, "{at_2fc}");
        // DC gain 1.
        assert!((p.magnitude(0.0) - 1.0).abs() < 1e-12);
        // Nyquist: the bilinear zeros at z = −1 give a true zero.
        assert!(p.magnitude(FS / 2.0) < 1e-12);
    }

    #[test]
    fn matches_prewarped_analog_prototype() {
        for order in [2, 4, 6, 8] {
            for fc in [5.0, 20.0, 200.0, 900.0] {
                let p = ButterworthParams::new(order, fc, FS).unwrap();
                for i in 0..200 {
                    let f = (i as f64 + 0.5) * (FS / 2.0) / 200.0;
                    let (got, want) = (p.magnitude(f), p.prototype_magnitude(f));
                    assert!(
                        (got - want).abs() < 1e-9 * want.max(1e-6) + 1e-12,
                        "N={order} fc={fc} f={f}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn time_domain_sine_gain_matches_design() {
        let p = ButterworthParams::new(6, 20.0, FS).unwrap();
        let mut f = Butterworth::new(p);
        for freq in [5.0, 20.0, 30.0] {
            f.reset();
            let w = 2.0 * core::f64::consts::PI * freq / FS;
            let mut peak = 0.0_f64;
            for i in 0..(8 * 2048) {
                let y = f.step(libm::sin(w * i as f64)).unwrap();
                if i > 4 * 2048 {
                    peak = peak.max(y.abs());
                }
            }
            assert!((peak - p.magnitude(freq)).abs() < 2e-3, "{freq} Hz: {peak}");
        }
        // DC: a constant passes with gain 1.
        f.reset();
        let mut y = 0.0;
        for _ in 0..4096 {
            y = f.step(3.0).unwrap();
        }
        assert!((y - 3.0).abs() < 1e-9);
    }

    #[test]
    fn filter_size() {
        std::println!(
            "size_of: Butterworth {} B",
            core::mem::size_of::<Butterworth>()
        );
        assert!(core::mem::size_of::<Butterworth>() <= 256);
    }

    #[test]
    fn rejects_bad_designs() {
        assert!(ButterworthParams::new(5, 20.0, FS).is_err());
        assert!(ButterworthParams::new(0, 20.0, FS).is_err());
        assert!(ButterworthParams::new(10, 20.0, FS).is_err());
        assert!(ButterworthParams::new(6, 1024.0, FS).is_err());
        assert!(ButterworthParams::new(6, 0.0, FS).is_err());
        assert!(ButterworthParams::new(6, f64::NAN, FS).is_err());
        assert!(ButterworthParams::new(6, 20.0, f64::INFINITY).is_err());
    }

    #[test]
    fn non_finite_input_is_refused_and_state_kept() {
        let mut f = Butterworth::new(ButterworthParams::new(6, 20.0, FS).unwrap());
        for i in 0..100 {
            f.step(libm::sin(i as f64 * 0.05)).unwrap();
        }
        let before = f;
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(f.step(bad), Err(InputError::NotFinite("filter input")));
            assert_eq!(f, before);
        }
    }

    proptest! {
        #[test]
        fn output_finite_or_refused(xs in proptest::collection::vec(
            prop_oneof![
                8 => -1e3f64..1e3,
                1 => Just(f64::NAN),
                1 => Just(f64::INFINITY),
                1 => Just(f64::NEG_INFINITY),
            ], 1..400)) {
            let mut f = Butterworth::new(ButterworthParams::new(6, 20.0, FS).unwrap());
            for x in xs {
                match f.step(x) {
                    Ok(y) => { prop_assert!(x.is_finite() && y.is_finite()); }
                    Err(_) => prop_assert!(!x.is_finite()),
                }
            }
        }
    }
}

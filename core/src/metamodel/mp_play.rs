//! The Menegotto–Pinto play: a play operator whose reversals are rounded by the previous
//! excursion (the Bauschinger effect of steel), for the floor-hysteron model
//! ([`super::FloorHysteron`], docs/opensees-nonlinear.md "The floor-hysteron form").
//!
//! A play of threshold `r` is `p(δ) = δ − σ(δ)` with `σ` an elastic–perfectly-plastic element of
//! unit stiffness yielding at `r`; its loops obey Masing's rule (every reversal curve is the
//! virgin curve scaled by two), so a steel member's reversals, softened right after the turn by
//! the previous plastic excursion, are outside it. Here `σ` is Menegotto and Pinto's curve as
//! OpenSees's `Steel02` evaluates it, without hardening (`b = 0`: the hardening is the elastic
//! part the hysterons leave) and without isotropic hardening: from the last reversal `(ε_r, σ_r)`
//! toward the asymptote's corner `(ε_0, ±r)`,
//! `σ = σ_r + (±r − σ_r)·ε*/(1 + |ε*|^R)^{1/R}`, `ε* = (δ − ε_r)/(ε_0 − ε_r)`,
//! `R = R₀·(1 − c_R1·ξ/(c_R2 + ξ))`, `ξ` the previous excursion's plastic strain over `r`. The
//! virgin branch is sharp (`R₀`), a reversal after a large excursion round (small `R`). With
//! `c_R1 = 0` and a large `R₀` it is the play.
//!
//! Passive as the play: `|σ| ≤ r`, the tangent `dσ/dδ` is in `[0, 1]`, and every closed loop
//! dissipates. The cost is two `pow` per hysteron and step.

use crate::params::ParamError;

/// The shape of the Menegotto–Pinto curve: `R₀`, `c_R1`, `c_R2` (OpenSees's `Steel02` names).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MpShape {
    r0: f64,
    cr1: f64,
    cr2: f64,
}

/// The admissible `R₀` (the virgin curve's sharpness).
pub const MP_R0_RANGE: (f64, f64) = (1.0, 50.0);
/// `c_R1` at most this (the reversal's `R` stays at least `R₀·(1 − c_R1)`).
pub const MP_CR1_MAX: f64 = 0.95;
/// The smallest `R` a reversal reaches (a rounder curve is a different element).
pub const MP_R_MIN: f64 = 0.5;

impl MpShape {
    /// Validate: `R₀` in [`MP_R0_RANGE`], `0 ≤ c_R1 ≤` [`MP_CR1_MAX`], `c_R2 > 0`, finite, and
    /// `R₀·(1 − c_R1) ≥` [`MP_R_MIN`].
    pub fn new(r0: f64, cr1: f64, cr2: f64) -> Result<Self, ParamError> {
        if !(r0.is_finite() && cr1.is_finite() && cr2.is_finite()) {
            return Err(ParamError::NotFinite("Menegotto–Pinto shape"));
        }
        if !(MP_R0_RANGE.0..=MP_R0_RANGE.1).contains(&r0) {
            return Err(ParamError::OutOfRange("Menegotto–Pinto R0 (1..=50)"));
        }
        if !(0.0..=MP_CR1_MAX).contains(&cr1) {
            return Err(ParamError::OutOfRange("Menegotto–Pinto cR1 (0..=0.95)"));
        }
        if cr2 <= 0.0 {
            return Err(ParamError::NotPositive("Menegotto–Pinto cR2"));
        }
        if r0 * (1.0 - cr1) < MP_R_MIN {
            return Err(ParamError::OutOfRange(
                "Menegotto–Pinto shape (R0·(1 − cR1) below 0.5)",
            ));
        }
        Ok(Self { r0, cr1, cr2 })
    }

    /// `R₀`.
    pub fn r0(&self) -> f64 {
        self.r0
    }
    /// `c_R1`.
    pub fn cr1(&self) -> f64 {
        self.cr1
    }
    /// `c_R2`.
    pub fn cr2(&self) -> f64 {
        self.cr2
    }
}

/// The state of one Menegotto–Pinto play (its last input and the branch it is on).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MpState {
    /// Last input `δ`, mm.
    eps: f64,
    /// Its `σ`, mm (of unit stiffness).
    sig: f64,
    /// The branch's reversal point.
    eps_r: f64,
    sig_r: f64,
    /// The branch's asymptote corner (its `σ` is `dir·r`).
    eps_0: f64,
    /// The extreme inputs reached (the plastic excursion's ends).
    eps_min: f64,
    eps_max: f64,
    /// The branch: 0 virgin at rest, +1 loading up, −1 down.
    dir: i8,
}

impl MpState {
    /// At rest, virgin.
    pub const REST: Self = Self {
        eps: 0.0,
        sig: 0.0,
        eps_r: 0.0,
        sig_r: 0.0,
        eps_0: 0.0,
        eps_min: 0.0,
        eps_max: 0.0,
        dir: 0,
    };
}

/// `ε*/(1 + |ε*|^R)^{1/R}` without overflow (for `|ε*| ≥ 1` as `sgn·(1 + |ε*|^{−R})^{−1/R}`).
fn transition(e: f64, r: f64) -> f64 {
    let a = libm::fabs(e);
    if a < 1.0 {
        e / libm::pow(1.0 + libm::pow(a, r), 1.0 / r)
    } else {
        let s = if e < 0.0 { -1.0 } else { 1.0 };
        s / libm::pow(1.0 + libm::pow(a, -r), 1.0 / r)
    }
}

/// Move the play of threshold `r` (> 0) and `shape` in `st` to `delta` (finite) and return its
/// output `p = δ − σ`, mm.
#[inline]
pub fn mp_play(shape: &MpShape, r: f64, st: &mut MpState, delta: f64) -> f64 {
    let d = delta - st.eps;
    if st.dir == 0 {
        if d == 0.0 {
            return delta - st.sig;
        }
        st.eps_max = r;
        st.eps_min = -r;
        st.dir = if d > 0.0 { 1 } else { -1 };
        st.eps_0 = f64::from(st.dir) * r;
    } else if (st.dir < 0 && d > 0.0) || (st.dir > 0 && d < 0.0) {
        // A reversal: the branch starts at the last point, toward the other corner.
        if st.dir < 0 {
            st.eps_min = st.eps_min.min(st.eps);
        } else {
            st.eps_max = st.eps_max.max(st.eps);
        }
        st.dir = -st.dir;
        st.eps_r = st.eps;
        st.sig_r = st.sig;
        st.eps_0 = f64::from(st.dir) * r - st.sig_r + st.eps_r;
    }
    let target = f64::from(st.dir) * r;
    // ξ: the plastic excursion of the previous branch, over r (Steel02's epspl − epss0).
    let pl = if st.dir > 0 { st.eps_max } else { st.eps_min };
    let xi = libm::fabs((pl - st.eps_0) / r);
    let big_r = (shape.r0 * (1.0 - shape.cr1 * xi / (shape.cr2 + xi))).max(MP_R_MIN);
    let span = st.eps_0 - st.eps_r;
    let sig = if libm::fabs(span) > 1e-12 * r {
        st.sig_r + (target - st.sig_r) * transition((delta - st.eps_r) / span, big_r)
    } else {
        // At the corner already: elastic from it, within the yield band. Written out rather than
        // `f64::clamp`, whose check of its bounds is a panic path on the board's tick.
        let s = st.sig_r + (delta - st.eps_r);
        if s < -r {
            -r
        } else if s > r {
            r
        } else {
            s
        }
    };
    st.eps = delta;
    st.sig = sig;
    delta - sig
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shape() -> MpShape {
        MpShape::new(20.0, 0.925, 0.15).expect("valid")
    }

    /// The virgin curve is elastic up to near the threshold and flat past it; with c_R1 = 0 and a
    /// sharp R₀ the loops are the play's (Masing).
    #[test]
    fn sharp_and_without_degradation_it_is_the_play() {
        let s = MpShape::new(50.0, 0.0, 1.0).expect("valid");
        let r = 2.0;
        let (mut st, mut y) = (MpState::REST, 0.0_f64);
        let mut worst = 0.0_f64;
        for k in 0..4000 {
            let d = 6.0 * libm::sin(k as f64 * 0.01) * (1.0 + k as f64 * 1e-4);
            let p = mp_play(&s, r, &mut st, d);
            y = y.max(d - r).min(d + r);
            worst = worst.max(libm::fabs(p - y));
        }
        // Near each corner R = 50 rounds by 2^(−1/50) ≈ 1.4 % of r.
        assert!(worst < 0.03 * r, "worst {worst}");
    }

    /// σ stays within ±r, the tangent within [0, 1], and a closed cycle dissipates.
    #[test]
    fn bounded_monotone_and_dissipative() {
        let s = shape();
        let r = 1.5;
        let mut st = MpState::REST;
        let (mut last_d, mut last_sig) = (0.0, 0.0);
        let mut work = 0.0;
        for k in 1..20_000 {
            let d = 5.0 * libm::sin(k as f64 * 0.003) + 0.7 * libm::sin(k as f64 * 0.041);
            let p = mp_play(&s, r, &mut st, d);
            let sig = d - p;
            assert!(libm::fabs(sig) <= r * (1.0 + 1e-12), "σ {sig}");
            let dd = d - last_d;
            if libm::fabs(dd) > 1e-9 {
                let t = (sig - last_sig) / dd;
                assert!((-1e-9..=1.0 + 1e-9).contains(&t), "tangent {t} at {k}");
            }
            work += 0.5 * (sig + last_sig) * dd;
            last_d = d;
            last_sig = sig;
        }
        // Stored energy is at most r²/2; the rest of the work was dissipated.
        assert!(work > 10.0 * r * r, "work {work}");
    }

    /// After a large excursion the reversal softens right after the turn (the Bauschinger
    /// effect): back by r the force has fallen less than the elastic line's r.
    #[test]
    fn a_reversal_after_a_large_excursion_is_rounded() {
        let s = shape();
        let r = 1.0;
        let mut st = MpState::REST;
        for k in 0..=100 {
            mp_play(&s, r, &mut st, 0.1 * k as f64); // up to 10 r
        }
        let top = st.sig;
        assert!(libm::fabs(top - r) < 1e-6);
        // Back by r: an elastic reversal would be at σ = 0; the rounded one has fallen less.
        let mut sig = 0.0;
        for k in 1..=10 {
            sig = 10.0 * r - 0.1 * k as f64 - mp_play(&s, r, &mut st, 10.0 - 0.1 * k as f64);
        }
        assert!(sig > 0.05 * r, "σ {sig}");
        // The virgin curve at r/2 was elastic.
        let mut v = MpState::REST;
        let p = mp_play(&s, r, &mut v, 0.5 * r);
        assert!(libm::fabs(p) < 1e-6, "p {p}");
    }

    #[test]
    fn shapes_outside_the_ranges_are_refused() {
        assert!(MpShape::new(0.5, 0.0, 1.0).is_err());
        assert!(MpShape::new(20.0, 0.99, 1.0).is_err());
        assert!(MpShape::new(20.0, 0.5, 0.0).is_err());
        assert!(MpShape::new(f64::NAN, 0.5, 1.0).is_err());
        assert!(MpShape::new(1.0, 0.9, 1.0).is_err());
        assert!(MpShape::new(18.0, 0.925, 0.15).is_ok());
    }

    /// Huge inputs do not overflow the transition.
    #[test]
    fn huge_inputs_stay_finite() {
        let s = shape();
        let mut st = MpState::REST;
        for d in [1e3, -1e9, 1e12, -5.0, 1e15] {
            let p = mp_play(&s, 0.01, &mut st, d);
            assert!(p.is_finite());
        }
    }
}

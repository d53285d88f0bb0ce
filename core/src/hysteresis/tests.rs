use std::string::ToString;

use super::*;

const K0: f64 = 100.0;
const FY: f64 = 50.0;
const ALPHA: f64 = 0.05;

fn laws() -> [Law; 2] {
    [
        Law::bilinear(K0, FY, ALPHA).unwrap(),
        Law::bouc_wen(K0, FY, ALPHA, 2.0, 0.5, 0.5).unwrap(),
    ]
}

/// Drive a story through `drifts`, returning the dissipated energy `∮f·du` (trapezoids).
fn energy(story: &mut Story, drifts: impl Iterator<Item = f64>) -> f64 {
    let (mut e, mut u0, mut f0) = (0.0, story.drift_mm(), story.force_kn());
    for u in drifts {
        let f = story.update(u);
        e += 0.5 * (f + f0) * (u - u0);
        (u0, f0) = (u, f);
    }
    e
}

/// A triangular path 0 → +amp → −amp → 0, `per_leg` steps per quarter.
fn cycle(amp: f64, per_leg: usize) -> impl Iterator<Item = f64> {
    let q = per_leg as f64;
    (1..=4 * per_leg).map(move |i| {
        let t = i as f64 / q;
        if t <= 1.0 {
            amp * t
        } else if t <= 3.0 {
            amp * (2.0 - t)
        } else {
            amp * (t - 4.0)
        }
    })
}

#[test]
fn monotonic_envelope_is_elastic_then_hardening() {
    let uy = FY / K0;
    let mut s = Story::new(laws()[0]);
    assert!((s.update(0.5 * uy) - 0.5 * FY).abs() < 1e-12);
    assert!((s.update(uy) - FY).abs() < 1e-12);
    let f = s.update(3.0 * uy);
    assert!((f - (FY + ALPHA * K0 * 2.0 * uy)).abs() < 1e-9, "{f}");
    // Bouc–Wen: elastic slope at the origin, the same asymptote far past yield.
    let mut b = Story::new(laws()[1]);
    let f_small = b.update(1e-3 * uy);
    assert!((f_small / (1e-3 * uy) - K0).abs() / K0 < 1e-3);
    let mut prev = f_small;
    for i in 2..=100 {
        let f = b.update(i as f64 * 0.1 * uy);
        assert!(f > prev, "monotonic");
        prev = f;
    }
    let asymptote = ALPHA * K0 * 10.0 * uy + (1.0 - ALPHA) * FY;
    assert!(
        (prev - asymptote).abs() / asymptote < 0.01,
        "{prev} vs {asymptote}"
    );
}

#[test]
fn unloading_is_elastic_with_the_initial_stiffness() {
    let uy = FY / K0;
    for law in laws() {
        let mut s = Story::new(law);
        for i in 1..=40 {
            s.update(i as f64 * 0.1 * uy);
        }
        let f0 = s.force_kn();
        let du = 1e-4 * uy;
        let f1 = s.update(4.0 * uy - du);
        let k = (f0 - f1) / du;
        assert!(
            (k - K0).abs() / K0 < 1e-3,
            "{law:?}: unloading stiffness {k}"
        );
    }
}

#[test]
fn every_cycle_past_yield_dissipates_energy_and_an_elastic_one_does_not() {
    let uy = FY / K0;
    for law in laws() {
        let mut s = Story::new(law);
        assert!(
            energy(&mut s, cycle(4.0 * uy, 400)) > 0.5 * FY * uy,
            "{law:?}"
        );
        assert!(
            energy(&mut s, cycle(4.0 * uy, 400)) > 0.5 * FY * uy,
            "{law:?}"
        );
    }
    let mut s = Story::new(laws()[0]);
    assert!(energy(&mut s, cycle(0.9 * uy, 400)).abs() < 1e-9);
}

#[test]
fn bilinear_is_the_exact_kinematic_hardening_parallelogram() {
    let uy = FY / K0;
    let um = 4.0 * uy;
    let mut s = Story::new(laws()[0]);
    energy(&mut s, cycle(um, 400)); // first cycle from the virgin state
    let area = energy(&mut s, cycle(um, 400));
    let exact = 4.0 * (1.0 - ALPHA) * FY * (um - uy);
    assert!((area - exact).abs() / exact < 1e-3, "{area} vs {exact}");
    // Upper corner on the hardening line.
    s.update(um);
    assert!((s.force_kn() - (ALPHA * K0 * um + (1.0 - ALPHA) * FY)).abs() < 1e-9);
}

#[test]
fn reset_returns_to_the_virgin_state() {
    for law in laws() {
        let mut s = Story::new(law);
        let first: [f64; 3] = [s.update(1.0), s.update(2.0), s.update(-1.0)];
        s.reset();
        assert_eq!(s.force_kn(), 0.0);
        assert_eq!([s.update(1.0), s.update(2.0), s.update(-1.0)], first);
    }
}

#[test]
fn non_physical_laws_are_refused_with_the_reason() {
    let msg = |r: Result<Law, ParamError>| r.map(|_| ()).unwrap_err().to_string();
    assert!(msg(Law::bilinear(K0, FY, -0.5)).contains("post-yield ratio"));
    assert!(msg(Law::bilinear(K0, FY, 1.0)).contains("post-yield ratio"));
    assert!(msg(Law::bilinear(K0, f64::NAN, ALPHA)).contains("not finite"));
    assert!(msg(Law::bilinear(K0, 0.0, ALPHA)).contains("yield force"));
    assert!(msg(Law::bilinear(-1.0, FY, ALPHA)).contains("stiffness"));
    assert!(msg(Law::bouc_wen(K0, FY, ALPHA, 0.5, 0.5, 0.5)).contains("exponent"));
    assert!(msg(Law::bouc_wen(K0, FY, ALPHA, 2.0, 0.5, -0.5)).contains("γ"));
    assert!(msg(Law::bouc_wen(K0, FY, ALPHA, 2.0, 0.5, 0.9)).contains("γ"));
    assert!(msg(Law::bouc_wen(K0, FY, ALPHA, f64::NAN, 0.5, 0.5)).contains("not finite"));
    assert!(msg(Law::bouc_wen(K0, FY, ALPHA, 2.0, 0.0, 0.0)).contains("β"));
}

#[test]
fn a_non_finite_drift_leaves_the_state_unchanged() {
    for law in laws() {
        let mut s = Story::new(law);
        let f = s.update(0.3);
        assert_eq!(s.update(f64::NAN), f);
        assert_eq!(s.drift_mm(), 0.3);
    }
}

proptest::proptest! {
    /// Any admissible law on any drift path: finite forces, the bilinear force inside its band,
    /// the Bouc–Wen `z` inside its bound.
    #[test]
    fn admissible_laws_stay_bounded(
        k0 in 1.0..1000.0_f64,
        fy in 0.1..5000.0_f64,
        alpha in MIN_POST_YIELD_RATIO..0.99,
        n in 1.0..20.0_f64,
        gamma_over_beta in -0.99..1.0_f64,
        path in proptest::collection::vec(-50.0..50.0_f64, 1..200),
    ) {
        let beta = 0.5;
        let gamma = gamma_over_beta * beta;
        let mut b = Story::new(Law::bilinear(k0, fy, alpha).unwrap());
        let mut w = Story::new(Law::bouc_wen(k0, fy, alpha, n, beta, gamma).unwrap());
        let z_max = libm::pow(1.0 / (beta + gamma), 1.0 / n) * (1.0 + 1e-6) + 1e-9;
        for u in path {
            let f = b.update(u);
            proptest::prop_assert!(f.is_finite());
            proptest::prop_assert!((f - alpha * k0 * u).abs() <= (1.0 - alpha) * fy * (1.0 + 1e-12) + 1e-9);
            let g = w.update(u);
            proptest::prop_assert!(g.is_finite());
            let z = (g - alpha * k0 * u) / ((1.0 - alpha) * fy);
            proptest::prop_assert!(z.abs() <= z_max.max(1.0) + 1e-6, "z = {} > {}", z, z_max);
        }
    }
}

#[test]
fn whole_exponent_power_matches_pow() {
    // n = 1 and 2 are pow's own exact cases: bit for bit, so the shipped n = 2 frames are unchanged.
    for i in 0..=300 {
        let x = f64::from(i) * 0.005;
        assert_eq!(powi(x, 1).to_bits(), libm::pow(x, 1.0).to_bits());
        assert_eq!(powi(x, 2).to_bits(), libm::pow(x, 2.0).to_bits());
        for n in 3..=20_u32 {
            let p = libm::pow(x, f64::from(n));
            assert!(
                (powi(x, n) - p).abs() <= 1e-14 * p.abs(),
                "x = {x}, n = {n}"
            );
        }
    }
}

#[test]
fn whole_and_fractional_exponents_give_the_same_loop() {
    // A whole n takes the product path, n + 1e-12 the pow path: the same loop to round-off.
    let mut a = Story::new(Law::bouc_wen(100.0, 50.0, 0.05, 3.0, 0.5, 0.5).unwrap());
    let mut b = Story::new(Law::bouc_wen(100.0, 50.0, 0.05, 3.0 + 1e-12, 0.5, 0.5).unwrap());
    for k in 0..4000 {
        let u = 2.0 * libm::sin(f64::from(k) * 0.01) * (1.0 + f64::from(k) / 1000.0);
        let (fa, fb) = (a.update(u), b.update(u));
        assert!(
            (fa - fb).abs() <= 1e-6 * (1.0 + fb.abs()),
            "step {k}: {fa} vs {fb}"
        );
    }
}

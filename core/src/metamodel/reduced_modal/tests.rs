use super::*;
use proptest::prelude::*;

const DT_4096_S: f64 = 1.0 / 4096.0;

fn one_mode(omega: f64, zeta: f64, gamma: f64, phi: f64) -> ReducedMode {
    ReducedMode {
        omega_rad_s: omega,
        damping_ratio: zeta,
        ground_participation: gamma,
        interface_shape: phi,
    }
}

fn two_mode_params(g: f64) -> ReducedModalParams {
    ReducedModalParams::new(
        DT_4096_S,
        &[
            one_mode(10.0, 0.02, 1.2, 0.8),
            one_mode(60.0, 0.05, -0.3, 0.5),
        ],
        &[0.4, -0.2],
        StaticCorrection {
            ground_mm_per_mm_s2: 1e-6,
            force_mm_per_kn: g,
        },
        &[StaticCorrection {
            ground_mm_per_mm_s2: 2e-6,
            force_mm_per_kn: 1e-4,
        }],
        5.0,
    )
    .expect("valid")
}

#[test]
fn a_constant_ground_acceleration_settles_at_the_static_response() {
    // One mode, no specimen: q → −Γ·ü_g/ω², the interface → φ·q − h·ü_g.
    let (omega, gamma, phi, h) = (20.0, 1.5, 0.7, 3e-5);
    let p = ReducedModalParams::new(
        DT_4096_S,
        &[one_mode(omega, 0.2, gamma, phi)],
        &[],
        StaticCorrection {
            ground_mm_per_mm_s2: h,
            force_mm_per_kn: 0.0,
        },
        &[],
        0.0,
    )
    .expect("valid");
    let mut m = ReducedModal::new(p);
    let ag = 1000.0;
    let mut target = 0.0;
    for _ in 0..4096 * 10 {
        target = m.step(ag, 0.0).expect("finite");
    }
    let expected = -phi * gamma * ag / (omega * omega) - h * ag;
    assert!(
        (target - expected).abs() < 1e-9 * expected.abs().max(1.0),
        "{target} vs {expected}"
    );
    assert!((m.interface_mm() - expected).abs() < 1e-9 * expected.abs().max(1.0));
}

#[test]
fn the_nominal_specimen_force_leaves_the_modes_unforced() {
    // Fed back F = k_e·target, ΔF = 0: the same response as the same modes with no specimen.
    let p = two_mode_params(1e-3);
    let unloaded = ReducedModalParams::new(
        DT_4096_S,
        p.mode_list(),
        &[0.4, -0.2],
        StaticCorrection {
            ground_mm_per_mm_s2: 1e-6,
            force_mm_per_kn: 1e-3,
        },
        &[StaticCorrection {
            ground_mm_per_mm_s2: 2e-6,
            force_mm_per_kn: 1e-4,
        }],
        0.0,
    )
    .expect("valid");
    let mut fed = ReducedModal::new(p);
    let mut free = ReducedModal::new(unloaded);
    let mut t = fed.target_mm();
    let mut moved = 0.0f64;
    for k in 0..20_000 {
        let ag = 500.0 * libm::sin(k as f64 * 0.01);
        t = fed.step(ag, p.specimen_k_kn_per_mm() * t).expect("finite");
        let t_free = free.step(ag, 0.0).expect("finite");
        assert!(
            (t - t_free).abs() <= 1e-12 * t_free.abs().max(1e-9),
            "{t} vs {t_free}"
        );
        moved = moved.max(t.abs());
    }
    assert!(moved > 1.0, "the run moved: {moved} mm");
}

#[test]
fn a_non_finite_input_is_refused_and_the_state_kept() {
    let mut m = ReducedModal::new(two_mode_params(1e-3));
    for k in 0..100 {
        m.step(100.0 * k as f64, 0.1).expect("finite");
    }
    let before = m;
    assert!(m.step(f64::NAN, 0.0).is_err());
    assert!(m.step(0.0, f64::INFINITY).is_err());
    assert_eq!(m, before);
}

#[test]
fn reset_repeats_a_run_bit_for_bit() {
    let mut m = ReducedModal::new(two_mode_params(1e-3));
    let run = |m: &mut ReducedModal| -> [u64; 3] {
        let mut last = 0.0;
        for k in 0..5000 {
            last = m
                .step(300.0 * libm::cos(k as f64 * 0.003), 0.2)
                .expect("finite");
        }
        [
            last.to_bits(),
            m.interface_mm().to_bits(),
            m.output_mm(0).to_bits(),
        ]
    };
    let a = run(&mut m);
    m.reset();
    assert_eq!(a, run(&mut m));
}

#[test]
fn invalid_parameters_are_refused() {
    let ok = one_mode(10.0, 0.02, 1.0, 1.0);
    let none = StaticCorrection::default();
    let bad = |modes: &[ReducedMode], shapes: &[f64], outs: &[StaticCorrection], g: f64, k: f64| {
        ReducedModalParams::new(
            DT_4096_S,
            modes,
            shapes,
            StaticCorrection {
                ground_mm_per_mm_s2: 0.0,
                force_mm_per_kn: g,
            },
            outs,
            k,
        )
        .is_err()
    };
    assert!(bad(&[], &[], &[], 0.0, 1.0), "no mode");
    assert!(
        bad(&[ok; REDUCED_MAX_MODES + 1], &[], &[], 0.0, 1.0),
        "too many modes"
    );
    assert!(
        bad(&[one_mode(0.0, 0.02, 1.0, 1.0)], &[], &[], 0.0, 1.0),
        "ω = 0"
    );
    assert!(
        bad(&[one_mode(1.0, 1.0, 1.0, 1.0)], &[], &[], 0.0, 1.0),
        "ζ = 1"
    );
    assert!(
        bad(&[one_mode(1.0, 0.0, f64::NAN, 1.0)], &[], &[], 0.0, 1.0),
        "NaN Γ"
    );
    assert!(bad(&[ok], &[1.0], &[], 0.0, 1.0), "shapes without outputs");
    assert!(
        bad(&[ok], &[], &[none], 0.0, 1.0),
        "an output without shapes"
    );
    assert!(
        bad(&[ok], &[], &[], 0.0, -1.0),
        "negative specimen stiffness"
    );
    assert!(
        bad(&[ok], &[], &[], 0.5, 2.0),
        "residual flexibility beyond the specimen's"
    );
    assert!(bad(&[ok], &[], &[], f64::NAN, 2.0), "NaN static correction");
    assert!(
        ReducedModalParams::new(0.0, &[ok], &[], none, &[], 1.0).is_err(),
        "dt = 0"
    );
}

proptest! {
    #[test]
    fn any_finite_inputs_give_a_finite_target_or_a_refusal(
        inputs in proptest::collection::vec((-1e5f64..1e5, -1e3f64..1e3), 1..300),
    ) {
        let mut m = ReducedModal::new(two_mode_params(1e-3));
        for (ag, f) in inputs {
            let before = m;
            match m.step(ag, f) {
                Ok(t) => prop_assert!(t.is_finite()),
                Err(_) => prop_assert_eq!(m, before),
            }
        }
    }
}

#[test]
fn the_static_force_cutoff_changes_nothing_without_a_force_deviation_and_damps_a_noisy_one() {
    let plain = two_mode_params(2e-3);
    let cut = plain.with_static_force_cutoff_hz(2.0).expect("valid");
    assert!(plain.with_static_force_cutoff_hz(0.0).is_err());
    assert!(plain.with_static_force_cutoff_hz(f64::NAN).is_err());
    let (mut a, mut b) = (ReducedModal::new(plain), ReducedModal::new(cut));
    // The nominal specimen's force at the target: ΔF = 0, bit for bit the same.
    let (mut ta, mut tb) = (0.0, 0.0);
    for k in 0..2000 {
        let ag = 500.0 * (k as f64 * 0.01).sin();
        ta = a.step(ag, 5.0 * ta).expect("finite");
        tb = b.step(ag, 5.0 * tb).expect("finite");
        assert_eq!(ta.to_bits(), tb.to_bits());
    }
    // An alternating force deviation (noise at the Nyquist rate): the filtered static term passes
    // a small fraction of what the plain one does.
    let (mut a, mut b) = (ReducedModal::new(plain), ReducedModal::new(cut));
    let (mut ea, mut eb): (f64, f64) = (0.0, 0.0);
    for k in 0..200 {
        let f = if k % 2 == 0 { 3.0 } else { -3.0 };
        let (ya, yb) = (
            a.step(0.0, f).expect("finite"),
            b.step(0.0, f).expect("finite"),
        );
        if k > 100 {
            ea = ea.max(ya.abs());
            eb = eb.max(yb.abs());
        }
    }
    assert!(eb < 0.1 * ea, "filtered {eb}, plain {ea}");
}

use super::*;
use crate::checksum::Fnv1a64;
use crate::structure_n::{StructureN, MAX_DOF};
use crate::structure_nl::NonlinearFrame;

const DT_2048_S: f64 = 1.0 / 2048.0;

/// One yielding story of mass `m` on the specimen `k_e`, as the FE's numerical part and as the
/// modal model with its one mode: the two must be the same computation.
#[test]
fn one_mode_one_spring_is_the_fe_pure_loop() {
    let (m, c, k0, k_e) = (1.75, 0.9, 176.75, 622.54);
    let law = Law::bilinear(k0, 1569.2, 0.05).expect("valid law");
    let model = StructureN::new(1, &[m], &[c], &[0.0], &[k0 + k_e], &[m]).expect("valid");
    let mut fe = NonlinearFrame::new(model, &[law], DT_2048_S).expect("valid frame");
    let w = ((k0 + k_e) / m).sqrt();
    let phi = 1.0 / m.sqrt();
    let mode = ModalMode {
        omega_rad_s: w,
        damping_ratio: c / (2.0 * m * w),
        ground_participation: phi * m,
    };
    let p =
        ModalHystParams::new(DT_2048_S, &[mode], &[phi], 0, k_e, &[law], &[phi]).expect("valid");
    let mut mm = ModalHyst::new(p);
    let ag = |k: usize| 9000.0 * libm::sin(k as f64 * 0.01) * libm::sin(k as f64 * 3e-4);
    fe.reset(ag(0));
    mm.reset_at(ag(0));
    let mut peak: f64 = 0.0;
    let mut worst: f64 = 0.0;
    for k in 1..40_000 {
        let target = mm.target_mm();
        let mut r = [0.0; MAX_DOF];
        r[0] = k_e * fe.next_displacement()[0];
        fe.advance(ag(k), &r);
        mm.step(ag(k), k_e * target).expect("finite step");
        let x = fe.chang().disp()[0];
        peak = peak.max(x.abs());
        worst = worst.max((mm.floor_disp_mm(0) - x).abs());
    }
    // It yields (the bilinear frame's u_y is 8.9 mm) and stays equal.
    assert!(peak > 2.0 * 1569.2 / k0, "peak {peak}");
    assert!(worst <= 1e-9 * peak, "worst {worst} of {peak}");
}

fn small() -> ModalHystParams {
    let mode = ModalMode {
        omega_rad_s: 20.0,
        damping_ratio: 0.02,
        ground_participation: 1.0,
    };
    let law = Law::bouc_wen(100.0, 50.0, 0.05, 2.0, 0.5, 0.5).expect("valid law");
    ModalHystParams::new(DT_2048_S, &[mode], &[1.0], 0, 10.0, &[law], &[1.0]).expect("valid")
}

#[test]
fn bad_params_are_refused_with_the_reason() {
    let mode = ModalMode {
        omega_rad_s: 20.0,
        damping_ratio: 0.02,
        ground_participation: 1.0,
    };
    let law = Law::bilinear(100.0, 50.0, 0.05).expect("valid law");
    let ok = |dt: f64, modes: &[ModalMode], shape: &[f64], dof: usize, k: f64, drift: &[f64]| {
        ModalHystParams::new(dt, modes, shape, dof, k, &[law], drift)
    };
    assert!(ok(DT_2048_S, &[mode], &[1.0], 0, 1.0, &[1.0]).is_ok());
    assert!(ok(0.0, &[mode], &[1.0], 0, 1.0, &[1.0]).is_err());
    assert!(ok(f64::NAN, &[mode], &[1.0], 0, 1.0, &[1.0]).is_err());
    assert!(ok(DT_2048_S, &[], &[1.0], 0, 1.0, &[1.0]).is_err());
    let neg = ModalMode {
        omega_rad_s: -1.0,
        ..mode
    };
    assert!(ok(DT_2048_S, &[neg], &[1.0], 0, 1.0, &[1.0]).is_err());
    let overdamped = ModalMode {
        damping_ratio: 1.0,
        ..mode
    };
    assert!(ok(DT_2048_S, &[overdamped], &[1.0], 0, 1.0, &[1.0]).is_err());
    let nan = ModalMode {
        ground_participation: f64::NAN,
        ..mode
    };
    assert!(ok(DT_2048_S, &[nan], &[1.0], 0, 1.0, &[1.0]).is_err());
    assert!(
        ok(DT_2048_S, &[mode], &[1.0], 1, 1.0, &[1.0]).is_err(),
        "dof past floors"
    );
    assert!(ok(DT_2048_S, &[mode], &[1.0], 0, -1.0, &[1.0]).is_err());
    assert!(ok(DT_2048_S, &[mode], &[f64::INFINITY], 0, 1.0, &[1.0]).is_err());
    assert!(matches!(
        ok(DT_2048_S, &[mode], &[1.0], 0, 1.0, &[1.0, 2.0]),
        Err(ModelError::Shape {
            expected: 1,
            got: 2,
            ..
        })
    ));
    assert!(
        ok(DT_2048_S, &[mode], &[1.0; 9], 0, 1.0, &[1.0]).is_err(),
        "9 floors"
    );
    assert!(ModalHystParams::new(DT_2048_S, &[mode], &[1.0], 0, 1.0, &[], &[]).is_err());
}

#[test]
fn non_finite_input_is_refused_and_leaves_the_state() {
    let mut m = ModalHyst::new(small());
    for k in 0..100 {
        m.step(1000.0 * f64::from(k % 7), 0.0).expect("finite");
    }
    let before = m;
    assert!(m.step(f64::NAN, 0.0).is_err());
    assert!(m.step(0.0, f64::INFINITY).is_err());
    assert_eq!(m, before);
    // An input that overflows the step is refused too.
    assert!(m.step(1e308, 1e308).is_err());
    assert_eq!(m, before);
}

#[test]
fn reset_repeats_the_path_bit_for_bit() {
    let mut m = ModalHyst::new(small());
    let run = |m: &mut ModalHyst| {
        m.reset();
        (0..5000)
            .map(|k| {
                m.step(5000.0 * libm::sin(k as f64 * 0.02), 3.0)
                    .expect("finite")
            })
            .collect::<std::vec::Vec<_>>()
    };
    let a = run(&mut m);
    let b = run(&mut m);
    assert_eq!(a, b);
    assert!(a.iter().any(|x| x.abs() > 1.0));
}

/// The step's numbers are pinned bit for bit: a 20 000-step run of a two-mode model with a Bouc–Wen
/// spring of non-integer exponent and a bilinear one, both driven far past yield, hashes (FNV-1a of
/// the targets and floors) to what it did before the springs' states were split from their laws.
#[test]
fn the_step_is_pinned_bit_for_bit() {
    let modes = [
        ModalMode {
            omega_rad_s: 12.0,
            damping_ratio: 0.02,
            ground_participation: 1.1,
        },
        ModalMode {
            omega_rad_s: 35.0,
            damping_ratio: 0.04,
            ground_participation: -0.4,
        },
    ];
    let laws = [
        Law::bouc_wen(150.0, 60.0, 0.05, 3.7, 0.6, 0.3).expect("valid law"),
        Law::bilinear(220.0, 40.0, 0.1).expect("valid law"),
    ];
    let p = ModalHystParams::new(
        1.0 / 4096.0,
        &modes,
        &[0.7, 0.4, 1.0, -0.5],
        0,
        50.0,
        &laws,
        &[0.7, 0.4, 0.3, -0.9],
    )
    .expect("valid");
    let mut m = ModalHyst::new(p);
    let ag = |k: usize| {
        let t = k as f64 / 4096.0;
        4000.0 * libm::sin(9.0 * t + 0.5 * t * t)
    };
    m.reset_at(ag(0));
    let mut h = Fnv1a64::new();
    let mut peak: f64 = 0.0;
    for k in 1..20_000 {
        let f = 45.0 * m.target_mm();
        let y = m.step(ag(k), f).expect("finite step");
        for x in [y, m.floor_disp_mm(0), m.floor_disp_mm(1)] {
            h.write_f64(x);
        }
        peak = peak.max(libm::fabs(m.spring_drift_mm(1)));
    }
    assert!(
        peak > 5.0 * 40.0 / 220.0,
        "the bilinear spring yields: {peak}"
    );
    let h = h.finish();
    assert_eq!(h, 0xece1_0616_2a44_6ac3, "{h:016x}");
}

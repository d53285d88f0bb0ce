//! Tests of [`crate::structure_n`].

use super::*;
use crate::integrator::{Chang, ExplicitIntegrator, Newmark};
use crate::params::{Prototype, DT_S};
use crate::structure::{LinearStructure, ShearBuilding, Vector};
use proptest::prelude::*;

/// The one-DOF run-time model of the paper's hybrid split.
fn paper_hybrid_n(p: &Prototype) -> Result<StructureN, ParamError> {
    StructureN::sdof(
        p.mass_kn_s2_per_mm(),
        p.damping_kn_s_per_mm(),
        p.frame_stiffness_kn_per_mm(),
        p.total_stiffness_kn_per_mm(),
    )
}

/// A smooth, broadband ground acceleration, mm/s².
fn ground(i: usize, dt: f64) -> f64 {
    let t = i as f64 * dt;
    3000.0 * (libm::sin(2.0 * core::f64::consts::PI * 1.7 * t) + 0.5 * libm::sin(23.0 * t))
}

#[test]
fn one_dof_equals_the_sdof_chang_path() -> Result<(), ParamError> {
    let p = Prototype::paper();
    let mut fixed = Chang::new(LinearStructure::prototype_hybrid(&p)?, DT_S)?;
    let mut runtime = ChangN::new(paper_hybrid_n(&p)?, DT_S)?;
    fixed.reset(ground(0, DT_S));
    runtime.reset(ground(0, DT_S));
    let mut worst = 0.0_f64;
    for i in 1..20_000 {
        // The brace force at the commanded displacement, fed through the hook.
        let r = p.brace_lateral_stiffness_kn_per_mm() * fixed.next_displacement()[0];
        let r_n = p.brace_lateral_stiffness_kn_per_mm() * runtime.next_displacement()[0];
        fixed.advance(ground(i, DT_S), &Vector::<1>::new(r));
        let mut ext = [0.0; MAX_DOF];
        ext[0] = r_n;
        runtime.advance(ground(i, DT_S), &ext);
        let scale = fixed.state().disp[0].abs().max(1.0);
        worst = worst.max((fixed.state().disp[0] - runtime.disp()[0]).abs() / scale);
        worst = worst
            .max((fixed.next_displacement()[0] - runtime.next_displacement()[0]).abs() / scale);
    }
    assert!(worst < 1e-12, "N-DOF path with N = 1 vs Chang<1>: {worst}");
    Ok(())
}

/// A 5-story building as a run-time model with nothing subtracted.
fn building_n<const N: usize>() -> Result<(LinearStructure<N>, StructureN), ParamError> {
    let b = ShearBuilding::<N>::uniform(0.5, 300.0, 0.03).model()?;
    let flat = |m: &crate::structure::Mat<N>| {
        let mut v = [0.0; MAX_DOF * MAX_DOF];
        for i in 0..N {
            for j in 0..N {
                v[i * N + j] = m[(i, j)];
            }
        }
        v
    };
    let mi = b.mass() * Vector::<N>::repeat(1.0);
    let n = StructureN::new(
        N,
        &flat(b.mass())[..N * N],
        &flat(b.damping())[..N * N],
        &flat(b.stiffness())[..N * N],
        &flat(b.initial_stiffness())[..N * N],
        mi.as_slice(),
    )?;
    Ok((b, n))
}

#[test]
fn five_dofs_match_the_fixed_size_chang_and_newmark() -> Result<(), ParamError> {
    let (fixed_model, model) = building_n::<5>()?;
    let mut fixed = Chang::new(fixed_model, DT_S)?;
    let mut runtime = ChangN::new(model, DT_S)?;
    let mut nm = Newmark::new(fixed_model, DT_S)?;
    fixed.reset(ground(0, DT_S));
    runtime.reset(ground(0, DT_S));
    nm.reset(ground(0, DT_S));
    let (mut worst, mut peak, mut vs_newmark) = (0.0_f64, 0.0_f64, 0.0_f64);
    for i in 1..8192 {
        fixed.advance(ground(i, DT_S), &Vector::<5>::zeros());
        runtime.advance(ground(i, DT_S), &[0.0; MAX_DOF]);
        let reference = nm.step(ground(i, DT_S));
        for j in 0..5 {
            worst = worst.max((fixed.state().disp[j] - runtime.disp()[j]).abs());
            vs_newmark = vs_newmark.max((reference.disp[j] - runtime.disp()[j]).abs());
            peak = peak.max(reference.disp[j].abs());
        }
    }
    assert!(peak > 1.0, "the test excites the building: peak {peak} mm");
    assert!(worst < 1e-10 * peak, "vs Chang<5>: {worst}");
    // With damping Chang's explicit velocity predictor departs slightly from Newmark average
    // acceleration (identical without damping): a small fraction of the peak at 2048 Hz.
    assert!(
        vs_newmark < 1e-3 * peak,
        "vs Newmark: {vs_newmark} of peak {peak}"
    );
    Ok(())
}

#[test]
fn stable_and_energy_bounded_at_a_large_step() -> Result<(), ParamError> {
    // 8 DOFs, highest mode far above 1/dt: explicit but unconditionally stable. Free vibration
    // from an initial kick: undamped energy must not grow.
    let b = ShearBuilding::<8>::uniform(0.01, 5000.0, 0.0).model()?;
    let w_max = b.natural_frequencies_rad_s()?[7];
    let dt = 0.05;
    assert!(w_max * dt > 20.0, "ω_max·Δt = {}", w_max * dt);
    let mut v = [0.0; 64];
    let mut m = [0.0; 64];
    let mut k = [0.0; 64];
    for i in 0..8 {
        for j in 0..8 {
            m[i * 8 + j] = b.mass()[(i, j)];
            k[i * 8 + j] = b.stiffness()[(i, j)];
        }
    }
    let model = StructureN::new(8, &m, &v, &k, &k, &[0.01; 8])?;
    let mut integ = ChangN::new(model, dt)?;
    integ.reset(-1.0e5);
    let energy = |s: &ChangN| {
        let (d, vel) = (s.disp(), s.vel());
        let (kd, mv) = (mul(&model.stiffness, d, 8), mul(&model.mass, vel, 8));
        0.5 * (0..8).map(|i| d[i] * kd[i] + vel[i] * mv[i]).sum::<f64>()
    };
    integ.advance(0.0, &[0.0; MAX_DOF]);
    let e0 = energy(&integ);
    assert!(e0 > 0.0);
    for _ in 0..10_000 {
        integ.advance(0.0, &[0.0; MAX_DOF]);
        let e = energy(&integ);
        assert!(
            e.is_finite() && e <= e0 * (1.0 + 1e-9),
            "energy grew: {e} > {e0}"
        );
    }
    v[0] = f64::NAN;
    assert!(StructureN::new(8, &m, &v, &k, &k, &[0.01; 8]).is_err());
    Ok(())
}

#[test]
fn bad_models_are_refused() {
    assert!(matches!(
        StructureN::new(9, &[1.0; 81], &[0.0; 81], &[1.0; 81], &[1.0; 81], &[1.0; 9]),
        Err(ParamError::OutOfRange(_))
    ));
    assert!(matches!(
        StructureN::new(2, &[1.0; 3], &[0.0; 4], &[1.0; 4], &[1.0; 4], &[1.0; 2]),
        Err(ParamError::OutOfRange(_))
    ));
    // Not positive definite.
    assert!(matches!(
        StructureN::new(
            2,
            &[1.0, 2.0, 2.0, 1.0],
            &[0.0; 4],
            &[1.0; 4],
            &[1.0; 4],
            &[1.0; 2]
        ),
        Err(ParamError::Singular(_))
    ));
    assert!(StructureN::sdof(0.0, 0.0, 1.0, 1.0).is_err());
    assert!(StructureN::sdof(1.0, 0.0, 1.0, 1.0)
        .and_then(|m| ChangN::new(m, 0.0))
        .is_err());
}

/// `lu_inverse` against nalgebra's `try_inverse` (the algorithm it writes out): the same bits, or
/// both none, on random 8×8 matrices, structure-like ones (a padded N×N block) and singular ones.
fn same_inverse(m: Padded) {
    let ours = lu_inverse(&m);
    let theirs = m.try_inverse();
    match (ours, theirs) {
        (None, None) => {}
        (Some(a), Some(b)) => {
            for (x, y) in a.iter().zip(b.iter()) {
                assert_eq!(x.to_bits(), y.to_bits(), "{m}");
            }
        }
        (a, b) => panic!("{m}: ours {a:?}, nalgebra's {b:?}"),
    }
}

#[test]
fn the_written_out_inverse_is_nalgebra_s_bit_for_bit_on_the_shipped_kinds_of_matrix() {
    // A padded 3-DOF shear building's D matrix, and singular ones.
    let mut m = Padded::identity();
    let k = [
        [550.0, -250.0, 0.0],
        [-250.0, 450.0, -200.0],
        [0.0, -200.0, 200.0],
    ];
    for (i, row) in k.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            m[(i, j)] = 1.5 * f64::from(u8::from(i == j)) + 1e-6 * v;
        }
    }
    same_inverse(m);
    same_inverse(Padded::zeros());
    let mut s = Padded::identity();
    s[(3, 3)] = 0.0;
    same_inverse(s);
    let mut r = Padded::identity();
    r.swap_rows(2, 5);
    same_inverse(r);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    #[test]
    fn the_written_out_inverse_is_nalgebra_s_bit_for_bit(
        v in prop::collection::vec(-1e3f64..1e3, 64),
        zero_col in prop::option::of(0usize..8),
    ) {
        let mut m = Padded::from_iterator(v);
        if let Some(c) = zero_col {
            m.column_mut(c).fill(0.0);
        }
        same_inverse(m);
    }
}

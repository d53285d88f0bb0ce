//! Tests of [`crate::structure_nl`].

use super::*;
use crate::params::DT_S;
use crate::structure::{Mat, ShearBuilding};

const N: usize = 3;
const K_STORY: f64 = 200.0;

fn row_major(a: &Mat<N>) -> [f64; N * N] {
    let mut out = [0.0; N * N];
    for i in 0..N {
        for j in 0..N {
            out[i * N + j] = a[(i, j)];
        }
    }
    out
}

/// The 3-story building as a linear `StructureN` (`linear = true`) or with zero linear stiffness
/// (the stories carry it all).
fn model(linear: bool) -> StructureN {
    let b = ShearBuilding::<N>::uniform(0.5, K_STORY, 0.02)
        .model()
        .unwrap();
    let k = row_major(b.stiffness());
    let k_lin = if linear { k } else { [0.0; N * N] };
    let gm: [f64; N] = core::array::from_fn(|i| b.mass().row(i).sum());
    StructureN::new(
        N,
        &row_major(b.mass()),
        &row_major(b.damping()),
        &k_lin,
        &k,
        &gm,
    )
    .unwrap()
}

fn ground(i: usize, amp_mm_s2: f64) -> f64 {
    let t = i as f64 * DT_S;
    let ramp = if t < 4.0 { t / 4.0 } else { 1.0 };
    let taper = if t < 8.0 { 1.0 } else { 0.0 };
    amp_mm_s2
        * ramp
        * taper
        * (libm::sin(2.0 * core::f64::consts::PI * 2.1 * t) + 0.4 * libm::sin(17.0 * t))
}

fn frame(fy: f64) -> NonlinearFrame {
    let law = Law::bilinear(K_STORY, fy, 0.05).unwrap();
    NonlinearFrame::new(model(false), &[law; N], DT_S).unwrap()
}

#[test]
fn elastic_stories_give_the_linear_chang_path() {
    let mut lin = ChangN::new(model(true), DT_S).unwrap();
    let mut nl = frame(1e9);
    let zero = [0.0; MAX_DOF];
    let mut worst = 0.0_f64;
    for i in 1..40_000 {
        lin.advance(ground(i, 3000.0), &zero);
        nl.advance(ground(i, 3000.0), &zero);
        for j in 0..N {
            let scale = lin.disp()[j].abs().max(1.0);
            worst = worst.max((lin.disp()[j] - nl.chang().disp()[j]).abs() / scale);
        }
    }
    assert!(worst < 1e-9, "elastic nonlinear vs linear: {worst}");
}

#[test]
fn yielding_stories_stay_on_their_envelope_and_leave_a_residual_drift() {
    let fy = 40.0;
    let mut nl = frame(fy);
    let zero = [0.0; MAX_DOF];
    let (mut peak_drift, mut peak_force) = (0.0_f64, 0.0_f64);
    for i in 1..(20.0 / DT_S) as usize {
        nl.advance(ground(i, 8000.0), &zero);
        let d = nl.story_drift_mm();
        for (&dj, &f) in d.iter().zip(nl.story_force_kn()).take(N) {
            // Kinematic hardening: the force never leaves the band around the hardening line.
            let back = 0.05 * K_STORY * dj;
            assert!((f - back).abs() <= 0.95 * fy + 1e-9);
            peak_drift = peak_drift.max(dj.abs());
            peak_force = peak_force.max(f.abs());
        }
    }
    let uy = fy / K_STORY;
    assert!(peak_drift > 2.0 * uy, "ductility {}", peak_drift / uy);
    assert!(peak_force > fy);
    // After 12 s of free vibration the frame is at rest, off its origin.
    let residual = nl.story_drift_mm()[0].abs();
    assert!(residual > 0.05 * uy, "residual drift {residual} mm");
    assert!(
        nl.chang().vel()[0].abs() < 1.0,
        "at rest: {}",
        nl.chang().vel()[0]
    );
    // Reset is a virgin frame.
    nl.reset(0.0);
    assert_eq!(nl.story_force_kn(), &[0.0; MAX_DOF]);
    assert_eq!(nl.chang().disp(), &[0.0; MAX_DOF]);
}

#[test]
fn the_external_force_enters_like_a_story_spring() {
    // A spring to ground at floor 1 passed as r_ext equals a stiffer first story.
    let law = Law::bilinear(K_STORY, 1e9, 0.05).unwrap();
    let stiff = Law::bilinear(K_STORY + 50.0, 1e9, 0.05).unwrap();
    let mut a = NonlinearFrame::new(model(false), &[law; N], DT_S).unwrap();
    let mut b = NonlinearFrame::new(model(false), &[stiff, law, law], DT_S).unwrap();
    let zero = [0.0; MAX_DOF];
    for i in 1..20_000 {
        let mut r = [0.0; MAX_DOF];
        r[0] = 50.0 * a.next_displacement()[0];
        a.advance(ground(i, 3000.0), &r);
        b.advance(ground(i, 3000.0), &zero);
    }
    let (x, y) = (a.chang().disp()[2], b.chang().disp()[2]);
    assert!((x - y).abs() <= 1e-9 * y.abs().max(1.0), "{x} vs {y}");
}

#[test]
fn one_law_per_story_is_required() {
    let law = Law::bilinear(K_STORY, 10.0, 0.05).unwrap();
    assert_eq!(
        NonlinearFrame::new(model(false), &[law; 2], DT_S).unwrap_err(),
        ParamError::OutOfRange("one story law per DOF")
    );
}

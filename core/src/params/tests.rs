//! Tests of [`crate::params`].

use super::*;

#[test]
fn paper_period_and_damping() {
    let p = Prototype::paper();
    assert!(
        (p.period_s() - 0.294).abs() <= 0.001,
        "T = {}",
        p.period_s()
    );
    assert!((p.brace_lateral_stiffness_kn_per_mm() - 622.54).abs() < 0.01);
    assert!((p.damping_kn_s_per_mm() - 1.496).abs() < 0.001);
}

#[test]
fn brace_kinematics_round_trip() {
    let p = Prototype::paper();
    let x = 17.76;
    let d = p.brace_disp_mm(x);
    assert!((p.story_disp_mm(d) - x).abs() < 1e-12);
    // Story force from the brace equals k_e·x.
    let r = p.story_force_kn(p.brace_force_kn(d));
    assert!((r - p.brace_lateral_stiffness_kn_per_mm() * x).abs() < 1e-9);
}

#[test]
fn rejects_bad_parameters() {
    assert_eq!(
        Prototype::new(f64::NAN, 1.0, 1.0, 0.5, 0.02),
        Err(ParamError::NotFinite("mass"))
    );
    assert_eq!(
        Prototype::new(1.0, -1.0, 1.0, 0.5, 0.02),
        Err(ParamError::NotPositive("frame stiffness"))
    );
    assert_eq!(
        Prototype::new(1.0, 1.0, 1.0, 1.5, 0.02),
        Err(ParamError::OutOfRange("cos²θ"))
    );
    assert!(SpecimenScale::new(0.0, 1.0).is_err());
}

#[test]
fn specimen_scale() {
    let s = SpecimenScale::default();
    let k = s.specimen_stiffness_kn_per_mm(BRACE_AXIAL_STIFFNESS_KN_PER_MM);
    assert!((k - 1.2241).abs() < 1e-12);
    assert!((s.prototype_force_kn(s.specimen_force_kn(123.0)) - 123.0).abs() < 1e-12);
}

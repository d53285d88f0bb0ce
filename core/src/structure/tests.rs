//! Tests of [`crate::structure`].

use super::*;

#[test]
fn prototype_period() {
    let s = LinearStructure::prototype_pure(&Prototype::paper()).unwrap();
    let t = s.natural_periods_s().unwrap()[0];
    assert!((t - 0.294).abs() <= 0.001, "T = {t}");
}

#[test]
fn uniform_shear_building_periods_match_closed_form() {
    // ω_j = 2·sqrt(k/m)·sin((2j−1)π / (2(2N+1))) for a uniform shear building.
    const N: usize = 5;
    let (m, k) = (1.75, 800.0);
    let s = ShearBuilding::<N>::uniform(m, k, 0.02).model().unwrap();
    let w = s.natural_frequencies_rad_s().unwrap();
    for j in 1..=N {
        let expect = 2.0
            * libm::sqrt(k / m)
            * libm::sin((2 * j - 1) as f64 * core::f64::consts::PI / (2.0 * (2 * N + 1) as f64));
        assert!((w[j - 1] - expect).abs() / expect < 1e-9, "mode {j}");
    }
}

#[test]
fn rejects_singular_mass_and_nan() {
    assert_eq!(
        LinearStructure::sdof(1.0, f64::NAN, 1.0, 1.0),
        Err(ParamError::NotFinite("damping matrix"))
    );
    assert!(LinearStructure::sdof(0.0, 1.0, 1.0, 1.0).is_err());
    let b = ShearBuilding::<2> {
        floor_mass_kn_s2_per_mm: [1.0, 1.0],
        story_stiffness_kn_per_mm: [1.0, -1.0],
        damping_ratio: 0.02,
    };
    assert!(b.model().is_err());
}

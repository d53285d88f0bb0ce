//! Tests of [`crate::filter`].

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

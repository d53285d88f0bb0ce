//! Tests of [`crate::metrics`].

use super::*;

fn sine(n: usize, lag: usize) -> [f64; 2000] {
    let mut out = [0.0; 2000];
    for (i, v) in out.iter_mut().enumerate().take(n) {
        let t = i as f64 - lag as f64;
        *v = libm::sin(t * 0.05) + 0.3 * libm::sin(t * 0.013);
    }
    out
}

#[test]
fn nrmse_of_identical_is_zero_and_of_offset_is_known() {
    let x = sine(2000, 0);
    assert_eq!(nrmse_pct(&x, &x), Ok(0.0));
    let mut y = x;
    y.iter_mut().for_each(|v| *v += 0.1);
    let e = nrmse_pct(&y, &x).unwrap();
    assert!((e - 100.0 * 0.1 / peak_abs(&x)).abs() < 1e-9);
}

#[test]
fn delay_is_found() {
    let t = sine(2000, 0);
    let m = sine(2000, 28);
    assert_eq!(delay_steps(&m, &t, 100), Ok(28));
    assert_eq!(delay_steps(&t, &t, 100), Ok(0));
}

#[test]
fn errors_are_typed() {
    assert_eq!(
        nrmse_pct(&[1.0], &[1.0, 2.0]),
        Err(MetricError::LengthMismatch)
    );
    assert_eq!(nrmse_pct(&[], &[]), Err(MetricError::Empty));
    assert_eq!(nrmse_pct(&[1.0], &[0.0]), Err(MetricError::ZeroReference));
    assert_eq!(nrmse_pct(&[f64::NAN], &[1.0]), Err(MetricError::NotFinite));
    assert_eq!(
        delay_steps(&[1.0; 5], &[1.0; 5], 5),
        Err(MetricError::Empty)
    );
}

#[test]
fn tracking_of_perfect_run() {
    let x = sine(2000, 0);
    let t = tracking(&x, &x, &x, 50).unwrap();
    assert_eq!(t.j1_steps, 0);
    assert!(t.j2_pct.abs() < 1e-12 && t.j3_pct.abs() < 1e-12);
}

#[test]
fn signed_delay_finds_lead_and_lag() {
    let t = sine(2000, 0);
    assert_eq!(delay_steps_signed(&sine(2000, 28), &t, 100), Ok(28));
    assert_eq!(delay_steps_signed(&t, &sine(2000, 5), 100), Ok(-5));
    assert_eq!(delay_steps_signed(&t, &t, 100), Ok(0));
}

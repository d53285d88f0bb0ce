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

/// The one-lag-at-a-time J1 search the blocked [`delay_steps`] must reproduce exactly.
fn delay_steps_naive(measured: &[f64], target: &[f64], max_lag: usize) -> usize {
    let mut best = (0usize, f64::NEG_INFINITY);
    for lag in 0..=max_lag {
        let n = target.len() - lag;
        let c: f64 = target[..n]
            .iter()
            .zip(&measured[lag..])
            .map(|(t, m)| t * m)
            .sum::<f64>()
            / n as f64;
        if c > best.1 {
            best = (lag, c);
        }
    }
    best.0
}

/// The one-lag-at-a-time signed J1 search the blocked [`delay_steps_signed`] must reproduce exactly.
fn delay_steps_signed_naive(measured: &[f64], target: &[f64], max_lag: usize) -> isize {
    let corr = |a: &[f64], b: &[f64]| {
        a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>() / a.len().min(b.len()) as f64
    };
    let mut best = (0isize, f64::NEG_INFINITY);
    for lag in 0..=max_lag {
        let n = target.len() - lag;
        let trail = corr(&target[..n], &measured[lag..]);
        if trail > best.1 {
            best = (lag as isize, trail);
        }
        let lead = corr(&measured[..n], &target[lag..]);
        if lag > 0 && lead > best.1 {
            best = (-(lag as isize), lead);
        }
    }
    best.0
}

/// A structure-like response: two decaying modes, a drift and seeded noise (as a measured signal).
fn response_like(n: usize, shift: f64, noise: f64, seed: u64) -> std::vec::Vec<f64> {
    let mut state = seed | 1;
    (0..n)
        .map(|i| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let u = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            let t = (i as f64 - shift) / 2048.0;
            12.0 * libm::exp(-0.3 * t) * libm::sin(21.4 * t)
                + 3.0 * libm::sin(5.1 * t + 0.4)
                + 0.01 * t
                + noise * u
        })
        .collect()
}

#[test]
fn blocked_delay_equals_naive_on_response_like_signals() {
    let target = response_like(20_000, 0.0, 0.0, 1);
    for (shift, noise, max_lag) in [
        (28.0, 0.01, 205),
        (0.0, 0.0, 205),
        (-7.0, 0.5, 100),
        (3.5, 2.0, 17),
    ] {
        let measured = response_like(20_000, shift, noise, 7);
        assert_eq!(
            delay_steps(&measured, &target, max_lag),
            Ok(delay_steps_naive(&measured, &target, max_lag))
        );
        assert_eq!(
            delay_steps_signed(&measured, &target, max_lag),
            Ok(delay_steps_signed_naive(&measured, &target, max_lag))
        );
        assert_eq!(
            delay_steps_both(&measured, &target, max_lag),
            Ok((
                delay_steps_naive(&measured, &target, max_lag),
                delay_steps_signed_naive(&measured, &target, max_lag)
            ))
        );
    }
}

proptest::proptest! {
    #[test]
    fn blocked_delay_equals_naive_on_random_signals(
        pairs in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3), 1..300),
        lag_frac in 0.0f64..1.0,
    ) {
        let (m, t): (std::vec::Vec<f64>, std::vec::Vec<f64>) = pairs.into_iter().unzip();
        let max_lag = ((m.len() - 1) as f64 * lag_frac) as usize;
        proptest::prop_assert_eq!(delay_steps(&m, &t, max_lag), Ok(delay_steps_naive(&m, &t, max_lag)));
        proptest::prop_assert_eq!(
            delay_steps_signed(&m, &t, max_lag),
            Ok(delay_steps_signed_naive(&m, &t, max_lag))
        );
        proptest::prop_assert_eq!(
            delay_steps_both(&m, &t, max_lag),
            Ok((delay_steps_naive(&m, &t, max_lag), delay_steps_signed_naive(&m, &t, max_lag)))
        );
    }

    #[test]
    fn blocked_delay_equals_naive_on_lagged_noisy_signals(
        len in 300usize..3000,
        shift in -60.0f64..60.0,
        noise in 0.0f64..5.0,
        seed in 1u64..1000,
        max_lag in 0usize..250,
    ) {
        let t = response_like(len, 0.0, 0.0, seed);
        let m = response_like(len, shift, noise, seed + 1);
        proptest::prop_assert_eq!(delay_steps(&m, &t, max_lag), Ok(delay_steps_naive(&m, &t, max_lag)));
        proptest::prop_assert_eq!(
            delay_steps_signed(&m, &t, max_lag),
            Ok(delay_steps_signed_naive(&m, &t, max_lag))
        );
        proptest::prop_assert_eq!(
            delay_steps_both(&m, &t, max_lag),
            Ok((delay_steps_naive(&m, &t, max_lag), delay_steps_signed_naive(&m, &t, max_lag)))
        );
    }
}

/// The two-pass standard deviation by `Iterator::sum`, as the metrics computed it before their
/// passes were fused.
fn std_dev_naive(x: impl Iterator<Item = f64> + Clone, n: usize) -> f64 {
    let mean = x.clone().sum::<f64>() / n as f64;
    sqrt(x.map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64)
}

proptest::proptest! {
    #[test]
    fn fused_passes_equal_the_separate_ones_bit_for_bit(
        pairs in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3), 1..500),
    ) {
        let (x, t): (std::vec::Vec<f64>, std::vec::Vec<f64>) = pairs.into_iter().unzip();
        let n = x.len();
        let s_t = std_dev_naive(t.iter().copied(), n);
        let j2 = normalized_std_error_pct(&x, &t);
        if s_t == 0.0 {
            proptest::prop_assert_eq!(j2, Err(MetricError::ZeroReference));
        } else {
            let s_d = std_dev_naive(x.iter().zip(&t).map(|(a, b)| a - b), n);
            proptest::prop_assert_eq!(j2.map(f64::to_bits), Ok((100.0 * s_d / s_t).to_bits()));
        }
        let peak = peak_abs(&t);
        let sum: f64 = x.iter().zip(&t).map(|(a, b)| (a - b) * (a - b)).sum();
        let nrmse = 100.0 * sqrt(sum / n as f64) / peak;
        proptest::prop_assert_eq!(nrmse_pct(&x, &t).map(f64::to_bits), Ok(nrmse.to_bits()));
    }
}

#[test]
fn fused_passes_equal_the_separate_ones_on_response_like_signals() {
    let t = response_like(30_000, 0.0, 0.0, 3);
    let x = response_like(30_000, 28.0, 0.3, 5);
    let n = x.len();
    let s_t = std_dev_naive(t.iter().copied(), n);
    let s_d = std_dev_naive(x.iter().zip(&t).map(|(a, b)| a - b), n);
    assert_eq!(
        normalized_std_error_pct(&x, &t).map(f64::to_bits),
        Ok((100.0 * s_d / s_t).to_bits())
    );
    let sum: f64 = x.iter().zip(&t).map(|(a, b)| (a - b) * (a - b)).sum();
    let nrmse = 100.0 * sqrt(sum / n as f64) / peak_abs(&t);
    assert_eq!(nrmse_pct(&x, &t).map(f64::to_bits), Ok(nrmse.to_bits()));
}

#[test]
fn benchmark_criteria_on_known_signals() -> Result<(), MetricError> {
    // Floor 1 measured = target delayed by 12 samples; floors 2-3 scaled copies of the reference.
    // (Content at 15 Hz and above: J1's overlap-averaged correlation favours longer lags by
    // n/(n − lag), which a slow signal's flat correlation peak would not outweigh.)
    let dt = 1.0 / 4096.0;
    let n = 8192;
    // A broadband burst that starts and ends at rest, as an earthquake response does.
    let sig = |k: usize, f: f64| {
        let w = 2.0 * core::f64::consts::PI * k as f64 * dt;
        let env = libm::sin(0.5 * w / 2.0);
        env * env * (libm::sin(f * w) + 0.7 * libm::sin(3.3 * f * w) + 0.4 * libm::sin(7.9 * f * w))
    };
    let target: [f64; 8192] = core::array::from_fn(|k| sig(k, 15.0));
    let measured: [f64; 8192] =
        core::array::from_fn(|k| if k >= 12 { target[k - 12] } else { 0.0 });
    let r1 = target;
    let r2: [f64; 8192] = core::array::from_fn(|k| 2.0 * sig(k, 15.0));
    let r3: [f64; 8192] = core::array::from_fn(|k| 3.0 * sig(k, 15.0));
    let x2: [f64; 8192] = core::array::from_fn(|k| 1.1 * r2[k]); // 10% too large
    let x3: [f64; 8192] = core::array::from_fn(|k| 0.95 * r3[k]); // 5% too small
    let j = benchmark_criteria(&measured, &target, [&x2, &x3], [&r1, &r2, &r3], dt)?;
    assert_eq!(j.j1_ms, 12.0 * dt * 1e3);
    assert_eq!(
        j.j2_pct, j.j4_pct,
        "target and reference 1 are the same signal"
    );
    assert!(
        (j.j6_pct - 10.0).abs() < 1e-9 && (j.j8_pct - 10.0).abs() < 1e-9,
        "{j:?}"
    );
    assert!(
        (j.j7_pct - 5.0).abs() < 1e-9 && (j.j9_pct - 5.0).abs() < 1e-9,
        "{j:?}"
    );
    assert_eq!(j.as_array()[0], j.j1_ms);
    assert_eq!(n, measured.len());
    // A zero reference floor is refused, not divided by.
    let zero = [0.0; 8192];
    assert_eq!(
        benchmark_criteria(&measured, &target, [&x2, &x3], [&r1, &zero, &r3], dt),
        Err(MetricError::ZeroReference)
    );
    Ok(())
}

#[test]
fn median_of_odd_even_and_empty_counts() {
    assert_eq!(median(&mut []), None);
    assert_eq!(median(&mut [3.0]), Some(3.0));
    assert_eq!(median(&mut [5.0, 1.0, 3.0]), Some(3.0));
    // Even count: the mean of the two middle values, not the upper one.
    assert_eq!(median(&mut [8.0, 2.0, 5.0, 4.0]), Some(4.5));
    assert_eq!(median(&mut [-1.0, 1.0]), Some(0.0));
}

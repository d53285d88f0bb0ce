//! Cost of the J1 delay search (`rths_core::metrics::delay_steps` and `delay_steps_signed`) over
//! ±205 lags of an El Centro-length run (81 900 samples), beside the one-lag-at-a-time loop it
//! replaced (same result, bit for bit; see the metrics tests).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use rths_core::metrics::{delay_steps, delay_steps_signed};

const N: usize = 81_900;
const MAX_LAG: usize = 205;

/// A structure-like displacement, `shift` samples late, with a little deterministic noise.
fn signal(shift: f64, noise: f64) -> Vec<f64> {
    (0..N)
        .map(|i| {
            let t = (i as f64 - shift) / 2048.0;
            12.0 * (-0.05 * t).exp() * (21.4 * t).sin()
                + 3.0 * (5.1 * t + 0.4).sin()
                + noise * ((i * 7919 % 1000) as f64 / 1000.0 - 0.5)
        })
        .collect()
}

/// The previous implementation: one lag at a time.
fn delay_steps_one_lag_at_a_time(measured: &[f64], target: &[f64], max_lag: usize) -> usize {
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

fn bench_j1(c: &mut Criterion) {
    let target = signal(0.0, 0.0);
    let measured = signal(27.0, 0.05);
    assert_eq!(
        delay_steps(&measured, &target, MAX_LAG).ok(),
        Some(delay_steps_one_lag_at_a_time(&measured, &target, MAX_LAG))
    );
    let mut g = c.benchmark_group("j1_81900_samples");
    g.sample_size(20);
    g.bench_function("delay_steps", |b| {
        b.iter(|| delay_steps(black_box(&measured), black_box(&target), MAX_LAG))
    });
    g.bench_function("delay_steps_signed", |b| {
        b.iter(|| delay_steps_signed(black_box(&measured), black_box(&target), MAX_LAG))
    });
    g.bench_function("one_lag_at_a_time (before)", |b| {
        b.iter(|| delay_steps_one_lag_at_a_time(black_box(&measured), black_box(&target), MAX_LAG))
    });
    g.finish();
}

criterion_group!(benches, bench_j1);
criterion_main!(benches);

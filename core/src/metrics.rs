//! Accuracy and tracking metrics of an RTHS run (DESIGN §7).
//!
//! - NRMSE = RMS(x − x_ref) / max|x_ref| × 100 (the study's figure).
//! - RTHS benchmark criteria (Silva et al. 2020): J1 = delay (lag, in samples, that maximizes the
//!   correlation of measured with target), J2 = 100·std(x_m − x_t)/std(x_t),
//!   J3 = 100·max|x_m − x_t|/max|x_t|; J4/J5 are J2/J3 against the reference response.
//!
//! All functions take slices and allocate nothing.

use libm::sqrt;

/// Why a metric could not be computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MetricError {
    /// The two series differ in length.
    LengthMismatch,
    /// A series is empty (or too short for the requested lag).
    Empty,
    /// The normalizing series is identically zero.
    ZeroReference,
    /// A series holds NaN or infinity.
    NotFinite,
}

impl core::fmt::Display for MetricError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            MetricError::LengthMismatch => "series differ in length",
            MetricError::Empty => "series is empty",
            MetricError::ZeroReference => "reference series is zero",
            MetricError::NotFinite => "series holds a non-finite value",
        })
    }
}

#[cfg(feature = "std")]
impl std::error::Error for MetricError {}

fn check(a: &[f64], b: &[f64]) -> Result<(), MetricError> {
    if a.len() != b.len() {
        return Err(MetricError::LengthMismatch);
    }
    if a.is_empty() {
        return Err(MetricError::Empty);
    }
    if a.iter().chain(b).any(|v| !v.is_finite()) {
        return Err(MetricError::NotFinite);
    }
    Ok(())
}

/// Largest absolute value of a series (0 for an empty one).
pub fn peak_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0_f64, |m, v| m.max(v.abs()))
}

/// Root mean square of a series (0 for an empty one).
pub fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    sqrt(x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64)
}

fn std_dev(x: impl Iterator<Item = f64> + Clone, n: usize) -> f64 {
    let mean = x.clone().sum::<f64>() / n as f64;
    sqrt(x.map(|v| (v - mean) * (v - mean)).sum::<f64>() / n as f64)
}

/// NRMSE in percent: `RMS(x − x_ref) / max|x_ref| × 100`.
pub fn nrmse_pct(x: &[f64], x_ref: &[f64]) -> Result<f64, MetricError> {
    check(x, x_ref)?;
    let peak = peak_abs(x_ref);
    if peak == 0.0 {
        return Err(MetricError::ZeroReference);
    }
    let sum: f64 = x.iter().zip(x_ref).map(|(a, b)| (a - b) * (a - b)).sum();
    Ok(100.0 * sqrt(sum / x.len() as f64) / peak)
}

/// Lags per interleaved block of [`lag_sums`].
const LAG_BLOCK: usize = 8;

/// `out[j] = Σ_{k < n − (lag0 + j)} a[k]·b[k + lag0 + j]` for `j < out.len() ≤ LAG_BLOCK`, where
/// `n = a.len() = b.len()` and `lag0 + out.len() ≤ n`.
///
/// Each lag's sum is accumulated in ascending `k` from `-0.0` (as `Iterator::sum` of `f64` does), so
/// every sum is bit-identical to the naive one-lag-at-a-time loop: only the *interleaving* of the
/// lags changes, which turns one long chain of dependent additions (latency-bound) into
/// `LAG_BLOCK` independent chains the CPU overlaps (and the compiler vectorizes across lags).
fn lag_sums(a: &[f64], b: &[f64], lag0: usize, out: &mut [f64]) {
    let count = out.len();
    let mut acc = [-0.0_f64; LAG_BLOCK];
    // The range every lag of the block shares: k < n − (lag0 + count − 1).
    let common = a.len() + 1 - lag0 - count;
    let b_block = &b[lag0..];
    if count == LAG_BLOCK {
        for (k, &x) in a[..common].iter().enumerate() {
            let w = &b_block[k..k + LAG_BLOCK];
            for j in 0..LAG_BLOCK {
                acc[j] += x * w[j];
            }
        }
    } else {
        for (k, &x) in a[..common].iter().enumerate() {
            for j in 0..count {
                acc[j] += x * b_block[k + j];
            }
        }
    }
    // The tails: lag lag0 + j runs count − 1 − j samples further than the shared range.
    for (j, s) in acc.iter_mut().enumerate().take(count) {
        for k in common..a.len() - lag0 - j {
            *s += a[k] * b_block[k + j];
        }
    }
    out.copy_from_slice(&acc[..count]);
}

/// J1: the lag in samples, `0..=max_lag`, by which `measured` trails `target`, chosen to maximize
/// their (unnormalized, overlap-averaged) cross-correlation
/// `c(lag) = Σ_{k < n−lag} target[k]·measured[k+lag] / (n − lag)` (the first lag on a tie).
pub fn delay_steps(measured: &[f64], target: &[f64], max_lag: usize) -> Result<usize, MetricError> {
    check(measured, target)?;
    let n = target.len();
    if n <= max_lag {
        return Err(MetricError::Empty);
    }
    let mut best = (0usize, f64::NEG_INFINITY);
    let mut sums = [0.0_f64; LAG_BLOCK];
    let mut lag0 = 0;
    while lag0 <= max_lag {
        let count = (max_lag + 1 - lag0).min(LAG_BLOCK);
        lag_sums(target, measured, lag0, &mut sums[..count]);
        for (j, s) in sums[..count].iter().enumerate() {
            let lag = lag0 + j;
            let c = s / (n - lag) as f64;
            if c > best.1 {
                best = (lag, c);
            }
        }
        lag0 += count;
    }
    Ok(best.0)
}

/// J1 with a sign: the lag in samples, `-max_lag..=max_lag`, that maximizes the overlap-averaged
/// cross-correlation; positive when `measured` trails `target`, negative when it leads (an
/// over-compensated actuator). Lags are tried in the order 0, 1, −1, 2, −2, … and the first
/// maximum wins.
pub fn delay_steps_signed(
    measured: &[f64],
    target: &[f64],
    max_lag: usize,
) -> Result<isize, MetricError> {
    check(measured, target)?;
    let n = target.len();
    if n <= max_lag {
        return Err(MetricError::Empty);
    }
    let mut best = (0isize, f64::NEG_INFINITY);
    let (mut trail, mut lead) = ([0.0_f64; LAG_BLOCK], [0.0_f64; LAG_BLOCK]);
    let mut lag0 = 0;
    while lag0 <= max_lag {
        let count = (max_lag + 1 - lag0).min(LAG_BLOCK);
        // measured trails: measured[k + lag] ~ target[k]; leads: target[k + lag] ~ measured[k].
        lag_sums(target, measured, lag0, &mut trail[..count]);
        lag_sums(measured, target, lag0, &mut lead[..count]);
        for j in 0..count {
            let lag = lag0 + j;
            let len = (n - lag) as f64;
            let c = trail[j] / len;
            if c > best.1 {
                best = (lag as isize, c);
            }
            let c = lead[j] / len;
            if lag > 0 && c > best.1 {
                best = (-(lag as isize), c);
            }
        }
        lag0 += count;
    }
    Ok(best.0)
}

/// J2 (or J4 against the reference): `100·std(x − x_t)/std(x_t)`, percent.
pub fn normalized_std_error_pct(x: &[f64], x_t: &[f64]) -> Result<f64, MetricError> {
    check(x, x_t)?;
    let n = x.len();
    let s_t = std_dev(x_t.iter().copied(), n);
    if s_t == 0.0 {
        return Err(MetricError::ZeroReference);
    }
    let diff = x.iter().zip(x_t).map(|(a, b)| a - b);
    Ok(100.0 * std_dev(diff, n) / s_t)
}

/// J3 (or J5 against the reference): `100·max|x − x_t|/max|x_t|`, percent.
pub fn normalized_peak_error_pct(x: &[f64], x_t: &[f64]) -> Result<f64, MetricError> {
    check(x, x_t)?;
    let peak = peak_abs(x_t);
    if peak == 0.0 {
        return Err(MetricError::ZeroReference);
    }
    let e = x
        .iter()
        .zip(x_t)
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    Ok(100.0 * e / peak)
}

/// The RTHS benchmark tracking criteria of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tracking {
    /// J1: delay of measured behind command, samples.
    pub j1_steps: usize,
    /// J2: normalized RMS tracking error, %.
    pub j2_pct: f64,
    /// J3: normalized peak tracking error, %.
    pub j3_pct: f64,
    /// J4: normalized RMS error of measured against the reference response, %.
    pub j4_pct: f64,
    /// J5: normalized peak error of measured against the reference response, %.
    pub j5_pct: f64,
}

/// All five benchmark criteria: `measured` and `target` (command) displacements, and the reference
/// (pure analytical) response; `max_lag` bounds the J1 search.
pub fn tracking(
    measured: &[f64],
    target: &[f64],
    reference: &[f64],
    max_lag: usize,
) -> Result<Tracking, MetricError> {
    Ok(Tracking {
        j1_steps: delay_steps(measured, target, max_lag)?,
        j2_pct: normalized_std_error_pct(measured, target)?,
        j3_pct: normalized_peak_error_pct(measured, target)?,
        j4_pct: normalized_std_error_pct(measured, reference)?,
        j5_pct: normalized_peak_error_pct(measured, reference)?,
    })
}

#[cfg(test)]
mod tests;

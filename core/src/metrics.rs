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

/// J1: the lag in samples, `0..=max_lag`, by which `measured` trails `target`, chosen to maximize
/// their (unnormalized, overlap-averaged) cross-correlation.
pub fn delay_steps(measured: &[f64], target: &[f64], max_lag: usize) -> Result<usize, MetricError> {
    check(measured, target)?;
    if measured.len() <= max_lag {
        return Err(MetricError::Empty);
    }
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
    Ok(best.0)
}

/// J1 with a sign: the lag in samples, `-max_lag..=max_lag`, that maximizes the overlap-averaged
/// cross-correlation; positive when `measured` trails `target`, negative when it leads (an
/// over-compensated actuator).
pub fn delay_steps_signed(
    measured: &[f64],
    target: &[f64],
    max_lag: usize,
) -> Result<isize, MetricError> {
    check(measured, target)?;
    if measured.len() <= max_lag {
        return Err(MetricError::Empty);
    }
    let corr = |a: &[f64], b: &[f64]| {
        a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>() / a.len().min(b.len()) as f64
    };
    let mut best = (0isize, f64::NEG_INFINITY);
    for lag in 0..=max_lag {
        let n = target.len() - lag;
        // measured trails: measured[k + lag] ~ target[k]
        let trail = corr(&target[..n], &measured[lag..]);
        if trail > best.1 {
            best = (lag as isize, trail);
        }
        let lead = corr(&measured[..n], &target[lag..]);
        if lag > 0 && lead > best.1 {
            best = (-(lag as isize), lead);
        }
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

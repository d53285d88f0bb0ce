//! Accuracy and tracking metrics of an RTHS run (docs/design.md §7).
//!
//! - NRMSE = RMS(x − x_ref) / max|x_ref| × 100 (the study's figure).
//! - RTHS benchmark criteria (Silva et al. 2020): J1 = delay (lag, in samples, that maximizes the
//!   correlation of measured with target), J2 = 100·std(x_m − x_t)/std(x_t),
//!   J3 = 100·max|x_m − x_t|/max|x_t|; J4/J5 are J2/J3 against the reference response.
//! - The vRTHS benchmark's J6-J9 ([`benchmark_criteria`]): J4/J5 for the numerical floors 2 and 3
//!   against the reference structure's.
//!
//! All functions take slices and allocate nothing.

use libm::sqrt;

/// The median of `values` (the mean of the two middle values when their count is even), `None`
/// when empty; sorts the slice in place (total order). The one median of every study and report.
pub fn median(values: &mut [f64]) -> Option<f64> {
    values.sort_unstable_by(f64::total_cmp);
    let n = values.len();
    let upper = *values.get(n / 2)?;
    Some(if n % 2 == 1 {
        upper
    } else {
        0.5 * (values.get(n / 2 - 1).copied().unwrap_or(upper) + upper)
    })
}

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
    if !(all_finite(a) && all_finite(b)) {
        return Err(MetricError::NotFinite);
    }
    Ok(())
}

/// No NaN or infinity in `x`. Chunks without an early exit inside: the compiler vectorizes them
/// (a per-value early exit scanned a value at a time, a pass as slow as a sum's).
fn all_finite(x: &[f64]) -> bool {
    x.chunks(64)
        .all(|c| c.iter().fold(true, |ok, v| ok & v.is_finite()))
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

/// Largest `max_lag` of the pruned J1 search (its per-lag state lives on the stack); beyond it,
/// every lag is summed.
const PRUNED_MAX_LAG: usize = 255;

/// How far apart the *computed* lagged sums `S̃(l) = Σ_{k < n−l} a[k]·b[k+l]` of two series can be:
/// `|S̃(l) − S̃(g)| ≤ |l − g|·slope + slack`.
///
/// One lag step changes the exact sum by `Σ a[k]·(b[k+l+1] − b[k+l]) − a[n−l−1]·b[n−1]`, so by
/// Cauchy–Schwarz `|S(l+1) − S(l)| ≤ ‖a‖·‖Δb‖ + max|a|·max|b|`, and (shifting `a` instead)
/// `≤ ‖Δa‖·‖b‖ + max|a|·max|b|`: the smaller is the slope, small for smooth signals such as
/// displacements at 2048 Hz. Each computed sum is within `γ_n·‖a‖·‖b‖` (`γ_n ≈ n·2⁻⁵³`) of the
/// exact one, hence the slack; both are inflated far beyond the rounding of their own computation.
struct Lipschitz {
    slope: f64,
    slack: f64,
}

impl Lipschitz {
    /// The bound for `a`, `b` (finite, same length); `None` when it is not finite (then every lag
    /// is summed) or `max_lag` is beyond [`PRUNED_MAX_LAG`].
    fn new(a: &[f64], b: &[f64], max_lag: usize) -> Option<Self> {
        if max_lag > PRUNED_MAX_LAG {
            return None;
        }
        // One pass for the six figures (independent accumulators: cheap next to one lag's sum).
        let (mut aa, mut bb, mut da, mut db, mut pa, mut pb) =
            (0.0, 0.0, 0.0, 0.0, 0.0_f64, 0.0_f64);
        let (mut a_prev, mut b_prev) = (a.first().copied()?, b.first().copied()?);
        for (&x, &y) in a.iter().zip(b) {
            aa += x * x;
            bb += y * y;
            da += (x - a_prev) * (x - a_prev);
            db += (y - b_prev) * (y - b_prev);
            pa = pa.max(x.abs());
            pb = pb.max(y.abs());
            (a_prev, b_prev) = (x, y);
        }
        let (na, nb) = (sqrt(aa), sqrt(bb));
        let (diff_a, diff_b) = (sqrt(da), sqrt(db));
        let edge = pa * pb;
        let slope = (na * diff_b).min(diff_a * nb) + edge;
        let slack = 8.0 * a.len() as f64 * f64::EPSILON * na * nb;
        let lip = Self {
            slope: slope * (1.0 + 1e-6),
            slack: slack + 1e-300,
        };
        (lip.slope.is_finite() && lip.slack.is_finite()).then_some(lip)
    }
}

/// The lagged sums `S̃(l) = Σ_{k < n−l} a[k]·b[k+l]` of one pair of series, summed on demand.
struct LagSums<'a> {
    a: &'a [f64],
    b: &'a [f64],
    /// Lags `min_lag..=max_lag` compete for the maximum.
    min_lag: usize,
    max_lag: usize,
    sum: [f64; PRUNED_MAX_LAG + 1],
    done: [bool; PRUNED_MAX_LAG + 1],
}

impl<'a> LagSums<'a> {
    fn new(a: &'a [f64], b: &'a [f64], max_lag: usize, min_lag: usize) -> Self {
        Self {
            a,
            b,
            min_lag,
            max_lag,
            sum: [0.0; PRUNED_MAX_LAG + 1],
            done: [false; PRUNED_MAX_LAG + 1],
        }
    }

    /// The correlation at `lag` (exactly as the one-lag loop computes it), if it was summed.
    fn corr(&self, lag: usize) -> Option<f64> {
        (lag >= self.min_lag && self.done[lag]).then(|| self.sum[lag] / (self.a.len() - lag) as f64)
    }

    /// Upper bounds on the correlation at every lag, from every summed lag (+∞ before any):
    /// `min_g S̃(g) + |lag − g|·slope + slack`, by one sweep each way, then divided by the overlap.
    fn bounds(&self, lip: &Lipschitz) -> [f64; PRUNED_MAX_LAG + 1] {
        let (lo, hi) = (self.min_lag, self.max_lag);
        let mut ub = [f64::INFINITY; PRUNED_MAX_LAG + 1];
        let mut peak = 0.0_f64;
        let lags = lo..=hi;
        let mut run = f64::INFINITY;
        for ((u, &done), &sum) in ub[lags.clone()]
            .iter_mut()
            .zip(&self.done[lags.clone()])
            .zip(&self.sum[lags.clone()])
        {
            run += lip.slope;
            if done {
                run = run.min(sum);
                peak = peak.max(sum.abs());
            }
            *u = run;
        }
        run = f64::INFINITY;
        for ((u, &done), &sum) in ub[lags.clone()]
            .iter_mut()
            .zip(&self.done[lags.clone()])
            .zip(&self.sum[lags])
            .rev()
        {
            run += lip.slope;
            if done {
                run = run.min(sum);
            }
            *u = u.min(run);
        }
        // The rounding of the sweeps themselves (≤ 2·256 additions): far below this.
        let margin = lip.slack + 1e-9 * (peak + lip.slack + (hi + 1) as f64 * lip.slope);
        for (lag, u) in ub.iter_mut().enumerate().take(hi + 1).skip(lo) {
            let c = (*u + margin) / (self.a.len() - lag) as f64;
            *u = c + c.abs() * 1e-12;
        }
        ub
    }

    /// Sum the block of lags `lag0..lag0 + LAG_BLOCK` (clipped to `max_lag`) in one pass.
    fn sum_block(&mut self, lag0: usize) {
        let count = (self.max_lag + 1 - lag0).min(LAG_BLOCK);
        lag_sums(self.a, self.b, lag0, &mut self.sum[lag0..lag0 + count]);
        self.done[lag0..lag0 + count].fill(true);
    }

    /// The highest correlation bound among the lags of the unsummed block at `lag0` that compete
    /// and reach `best` (`None`: the block is summed, or cannot reach `best`).
    fn block_reach(&self, lag0: usize, ub: &[f64], best: f64) -> Option<f64> {
        if self.done[lag0] {
            return None;
        }
        let end = (lag0 + LAG_BLOCK - 1).min(self.max_lag);
        let mut high: Option<f64> = None;
        for &u in &ub[lag0.max(self.min_lag)..=end] {
            let below = u < best;
            if !below {
                // A NaN bound (none expected) reaches everything.
                let u = if u.is_nan() { f64::INFINITY } else { u };
                high = Some(high.map_or(u, |h: f64| h.max(u)));
            }
        }
        high
    }
}

/// Sum, block by block (the most promising first), every block of [`LAG_BLOCK`] lags holding a
/// lag whose correlation bound reaches the best correlation summed so far (over all pairs); the
/// lags left out provably stay below it.
fn search(pairs: &mut [&mut LagSums<'_>], lip: &Lipschitz) {
    loop {
        let mut best = f64::NEG_INFINITY;
        for p in pairs.iter() {
            for lag in p.min_lag..=p.max_lag {
                if let Some(c) = p.corr(lag) {
                    best = best.max(c);
                }
            }
        }
        let mut choice: Option<(usize, usize, f64)> = None;
        for (i, p) in pairs.iter().enumerate() {
            let ub = p.bounds(lip);
            for lag0 in (0..=p.max_lag).step_by(LAG_BLOCK) {
                if let Some(high) = p.block_reach(lag0, &ub, best) {
                    if choice.is_none_or(|c| high > c.2) {
                        choice = Some((i, lag0, high));
                    }
                }
            }
        }
        match choice {
            Some((i, lag0, _)) => pairs[i].sum_block(lag0),
            None => return,
        }
    }
}

/// J1: the lag in samples, `0..=max_lag`, by which `measured` trails `target`, chosen to maximize
/// their (unnormalized, overlap-averaged) cross-correlation
/// `c(lag) = Σ_{k < n−lag} target[k]·measured[k+lag] / (n − lag)` (the first lag on a tie).
///
/// Only the lags whose correlation can still reach the best one found are summed (see
/// [`Lipschitz`]); the result is the one of summing every lag, bit for bit.
pub fn delay_steps(measured: &[f64], target: &[f64], max_lag: usize) -> Result<usize, MetricError> {
    check(measured, target)?;
    let n = target.len();
    if n <= max_lag {
        return Err(MetricError::Empty);
    }
    let Some(lip) = Lipschitz::new(measured, target, max_lag) else {
        return Ok(delay_steps_all(measured, target, max_lag));
    };
    let mut trail = LagSums::new(target, measured, max_lag, 0);
    search(&mut [&mut trail], &lip);
    Ok(best_trailing(&trail))
}

/// The first lag of the highest summed correlation of the trailing sums.
fn best_trailing(trail: &LagSums<'_>) -> usize {
    let mut best = (0usize, f64::NEG_INFINITY);
    for lag in 0..=trail.max_lag {
        if let Some(c) = trail.corr(lag) {
            if c > best.1 {
                best = (lag, c);
            }
        }
    }
    best.0
}

/// [`delay_steps`] summing every lag (inputs checked, `max_lag < n`).
fn delay_steps_all(measured: &[f64], target: &[f64], max_lag: usize) -> usize {
    let n = target.len();
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
    best.0
}

/// J1 with a sign: the lag in samples, `-max_lag..=max_lag`, that maximizes the overlap-averaged
/// cross-correlation; positive when `measured` trails `target`, negative when it leads (an
/// over-compensated actuator). Lags are tried in the order 0, 1, −1, 2, −2, … and the first
/// maximum wins. Pruned like [`delay_steps`], with the same result as summing every lag.
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
    // The bound is symmetric in its two series: one serves both directions.
    let Some(lip) = Lipschitz::new(measured, target, max_lag) else {
        return Ok(delay_steps_signed_all(measured, target, max_lag));
    };
    let mut trail = LagSums::new(target, measured, max_lag, 0);
    let mut lead = LagSums::new(measured, target, max_lag, 1);
    search(&mut [&mut trail, &mut lead], &lip);
    Ok(best_signed(&trail, &lead))
}

/// The first lag, in the order 0, 1, −1, 2, −2, …, of the highest summed correlation.
fn best_signed(trail: &LagSums<'_>, lead: &LagSums<'_>) -> isize {
    let mut best = (0isize, f64::NEG_INFINITY);
    for lag in 0..=trail.max_lag {
        if let Some(c) = trail.corr(lag) {
            if c > best.1 {
                best = (lag as isize, c);
            }
        }
        if let Some(c) = lead.corr(lag) {
            if c > best.1 {
                best = (-(lag as isize), c);
            }
        }
    }
    best.0
}

/// [`delay_steps`] and [`delay_steps_signed`] of the same pair at once: the signed search starts
/// from the trailing lags the unsigned one summed (each search is exact from any set of summed
/// lags, so both results are those of the two functions).
pub fn delay_steps_both(
    measured: &[f64],
    target: &[f64],
    max_lag: usize,
) -> Result<(usize, isize), MetricError> {
    check(measured, target)?;
    let n = target.len();
    if n <= max_lag {
        return Err(MetricError::Empty);
    }
    let Some(lip) = Lipschitz::new(measured, target, max_lag) else {
        return Ok((
            delay_steps_all(measured, target, max_lag),
            delay_steps_signed_all(measured, target, max_lag),
        ));
    };
    let mut trail = LagSums::new(target, measured, max_lag, 0);
    search(&mut [&mut trail], &lip);
    let unsigned = best_trailing(&trail);
    let mut lead = LagSums::new(measured, target, max_lag, 1);
    search(&mut [&mut trail, &mut lead], &lip);
    Ok((unsigned, best_signed(&trail, &lead)))
}

/// [`delay_steps_signed`] summing every lag (inputs checked, `max_lag < n`).
fn delay_steps_signed_all(measured: &[f64], target: &[f64], max_lag: usize) -> isize {
    let n = target.len();
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
    best.0
}

/// J2 (or J4 against the reference): `100·std(x − x_t)/std(x_t)`, percent.
pub fn normalized_std_error_pct(x: &[f64], x_t: &[f64]) -> Result<f64, MetricError> {
    check(x, x_t)?;
    let (s_t, s_diff) = std_devs(x, x_t);
    if s_t == 0.0 {
        return Err(MetricError::ZeroReference);
    }
    Ok(100.0 * s_diff / s_t)
}

/// `(std(x_t), std(x − x_t))` (same non-empty length), each exactly as the two-pass mean and
/// deviation sum of `Iterator::sum` compute it:
/// the two means, then the two deviation sums, share a pass, each sum still in ascending order
/// from `-0.0` (as `Iterator::sum`), so two independent chains of additions overlap in the CPU.
fn std_devs(x: &[f64], x_t: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let (mut sum_t, mut sum_d) = (-0.0_f64, -0.0_f64);
    for (a, b) in x.iter().zip(x_t) {
        sum_t += b;
        sum_d += a - b;
    }
    let (mean_t, mean_d) = (sum_t / n, sum_d / n);
    let (mut var_t, mut var_d) = (-0.0_f64, -0.0_f64);
    for (a, b) in x.iter().zip(x_t) {
        let d = a - b;
        var_t += (b - mean_t) * (b - mean_t);
        var_d += (d - mean_d) * (d - mean_d);
    }
    (sqrt(var_t / n), sqrt(var_d / n))
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
    tracking_with_delay(
        delay_steps(measured, target, max_lag)?,
        measured,
        target,
        reference,
    )
}

/// [`tracking`] with J1 given (e.g. from [`delay_steps_both`]).
pub fn tracking_with_delay(
    j1_steps: usize,
    measured: &[f64],
    target: &[f64],
    reference: &[f64],
) -> Result<Tracking, MetricError> {
    Ok(Tracking {
        j1_steps,
        j2_pct: normalized_std_error_pct(measured, target)?,
        j3_pct: normalized_peak_error_pct(measured, target)?,
        j4_pct: normalized_std_error_pct(measured, reference)?,
        j5_pct: normalized_peak_error_pct(measured, reference)?,
    })
}

/// Largest lag of the vRTHS benchmark's J1 search, samples (lags 0..49).
pub const BENCHMARK_MAX_LAG: usize = 49;

/// The nine criteria of the vRTHS benchmark (Silva et al. 2020) of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BenchmarkCriteria {
    /// J1: delay of the measured first floor behind its target, ms.
    pub j1_ms: f64,
    /// J2: `100·std(x_m − x_t)/std(x_t)`, %.
    pub j2_pct: f64,
    /// J3: `100·peak(x_m − x_t)/peak(x_t)`, %.
    pub j3_pct: f64,
    /// J4: `100·std(x_m − x_r1)/std(x_r1)`, %.
    pub j4_pct: f64,
    /// J5: `100·peak(x_m − x_r1)/peak(x_r1)`, %.
    pub j5_pct: f64,
    /// J6: J4 of floor 2 (numerical against reference), %.
    pub j6_pct: f64,
    /// J7: J4 of floor 3, %.
    pub j7_pct: f64,
    /// J8: J5 of floor 2, %.
    pub j8_pct: f64,
    /// J9: J5 of floor 3, %.
    pub j9_pct: f64,
}

impl BenchmarkCriteria {
    /// J1..J9 in order (J1 in ms, the others in %).
    pub fn as_array(&self) -> [f64; 9] {
        [
            self.j1_ms,
            self.j2_pct,
            self.j3_pct,
            self.j4_pct,
            self.j5_pct,
            self.j6_pct,
            self.j7_pct,
            self.j8_pct,
            self.j9_pct,
        ]
    }
}

/// J1-J9 of a three-story vRTHS run: `measured` and `target` first-floor displacements, the
/// numerical floors 2 and 3 (`upper`), the reference structure's floors 1-3, and the sample step
/// `dt_s` (J1 is reported in ms, searched over lags `0..=`[`BENCHMARK_MAX_LAG`]).
pub fn benchmark_criteria(
    measured: &[f64],
    target: &[f64],
    upper: [&[f64]; 2],
    reference: [&[f64]; 3],
    dt_s: f64,
) -> Result<BenchmarkCriteria, MetricError> {
    let [r1, r2, r3] = reference;
    let [x2, x3] = upper;
    let t = tracking(measured, target, r1, BENCHMARK_MAX_LAG)?;
    Ok(BenchmarkCriteria {
        j1_ms: t.j1_steps as f64 * dt_s * 1e3,
        j2_pct: t.j2_pct,
        j3_pct: t.j3_pct,
        j4_pct: t.j4_pct,
        j5_pct: t.j5_pct,
        j6_pct: normalized_std_error_pct(x2, r2)?,
        j7_pct: normalized_std_error_pct(x3, r3)?,
        j8_pct: normalized_peak_error_pct(x2, r2)?,
        j9_pct: normalized_peak_error_pct(x3, r3)?,
    })
}

#[cfg(test)]
mod tests;

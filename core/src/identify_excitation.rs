//! The identification excitation, one home for host and firmware: a periodic multisine,
//! band-limited to the test's band, with a low crest factor, ramped in and out, scaled to a small
//! stroke and a safe velocity, and slew-rate limited as a last guard. A pure function of its
//! settings: no rig, no randomness, no allocation.
//!
//! Why a periodic multisine rather than random noise: with whole periods in steady state, the DFT
//! of each period sees only the excited lines, without leakage and without windowing, so the H1
//! estimate at each line is unbiased and its coherence over the periods measures only the noise
//! (and any nonlinearity), not the estimator.
//!
//! The pieces, each computed once and used by both sides: [`Multisine`] (one period of the unit
//! signal, sample `t` on demand from a table of one cycle of cos, [`unit_cos`]), [`UnitStats`] (its
//! peak and peak rate, which set the scale), [`Schedule`] (envelope, scale and slew limit: the
//! command at tick `k`, from the [`Tables`] of the unit period and of the ramp's cosines,
//! [`ramp_cos`]) and [`Player`] (the schedule played tick by tick).
//!
//! The cosines come from a [`Trig`]: the host's is std's (the platform libm), and no two libms
//! agree to the last bit (glibc's and the `libm` crate's `cos` differ in 696 of the 20 480 table
//! entries). So the tables are computed on the host, once: `rths identify` in memory, the
//! firmware's build script into flash (160 KiB of unit period and 32 KiB of ramp at 2048 Hz), and
//! the device reads them: its excitation is the host's to the bit, and 200 lines of f64 cosines
//! per tick would not fit the Cortex-M4's tick anyway (`docs/link.md`, "Identify through the
//! board").

use core::f64::consts::PI;

use crate::params::ACTUATOR_STROKE_MM;

/// Largest excitation amplitude, mm: 10% of the ±25.4 mm stroke.
pub const MAX_AMPLITUDE_MM: f64 = 0.1 * ACTUATOR_STROKE_MM;

/// Most excited lines a [`Multisine`] holds (the default has 200).
pub const MAX_LINES: usize = 256;

/// Why an excitation cannot be made.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ExcitationError {
    /// The amplitude is not in (0, [`MAX_AMPLITUDE_MM`]] (the value given, mm).
    Amplitude(f64),
    /// The tick, the band's low end or the rate limit is not positive.
    NotPositive,
    /// The band is not f_lo < f_hi < a quarter of the sample rate.
    Band,
    /// The corner, ramp or settling time is negative or not finite.
    Timing,
    /// Fewer than 2 analysed periods (the coherence needs averages).
    Periods,
    /// The period (ticks) is not a multiple of 4 (the table's quarter-cycle shift must be exact).
    PeriodTicks(usize),
    /// More lines than [`MAX_LINES`].
    TooManyLines(usize),
    /// The band excites nothing.
    EmptyBand,
}

impl core::fmt::Display for ExcitationError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Amplitude(a) => write!(
                f,
                "amplitude {a} mm not in (0, {MAX_AMPLITUDE_MM}] (10% of the stroke)"
            ),
            Self::NotPositive => f.write_str("dt, band and rate limit must be positive"),
            Self::Band => f.write_str("band: need f_lo < f_hi < a quarter of the sample rate"),
            Self::Timing => f.write_str("corner, ramp and settling must be positive"),
            Self::Periods => f.write_str("at least 2 periods (the coherence needs averages)"),
            Self::PeriodTicks(n) => write!(
                f,
                "period of {n} ticks: must be a multiple of 4 (choose f_lo = fs/(4m))"
            ),
            Self::TooManyLines(n) => write!(f, "{n} lines: at most {MAX_LINES}"),
            Self::EmptyBand => f.write_str("empty band"),
        }
    }
}

/// Settings of the excitation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExcitationConfig {
    /// Peak command, mm (≤ [`MAX_AMPLITUDE_MM`]).
    pub amplitude_mm: f64,
    /// Lowest excited frequency, Hz (also the line spacing: the period is `1/f_lo`).
    pub band_lo_hz: f64,
    /// Highest excited frequency, Hz.
    pub band_hi_hz: f64,
    /// Corner above which the line amplitudes fall as 1/f (constant velocity), Hz: keeps the
    /// command's velocity far below the actuator's while the low band gets the stroke.
    pub corner_hz: f64,
    /// Largest command velocity, mm/s: the signal is scaled to stay under 80% of it, and a slew
    /// limiter enforces it.
    pub rate_limit_mm_s: f64,
    /// Ramp-in and ramp-out duration, s (raised-cosine envelope).
    pub ramp_s: f64,
    /// Full-amplitude time before the analysed periods, s (the transient of the ramp decays).
    pub settle_s: f64,
    /// Number of analysed periods (≥ 2: the coherence needs averages).
    pub periods: usize,
    /// Controller tick, s.
    pub dt_s: f64,
}

impl ExcitationConfig {
    /// The defaults: at most 2 mm peak (7.9% of the stroke), 0.1–20 Hz with lines every 0.1 Hz,
    /// 1/f above 5 Hz, 100 mm/s rate limit (30% of the actuator's 338.84 mm/s), 2 s ramps, 2 s
    /// settling, 5 periods of 10 s: 56 s of rig time. The velocity bound binds first: the peak
    /// is 0.82 mm. The corner sets how the lead fit weighs high against low frequencies; 5 Hz
    /// gave LRX a lower NRMSE on El Centro and Kobe than 2 Hz or 0.5 Hz (`docs/identify.md`).
    pub const fn new(dt_s: f64) -> Self {
        Self {
            amplitude_mm: 2.0,
            band_lo_hz: 0.1,
            band_hi_hz: 20.0,
            corner_hz: 5.0,
            rate_limit_mm_s: 100.0,
            ramp_s: 2.0,
            settle_s: 2.0,
            periods: 5,
            dt_s,
        }
    }

    /// Check every setting's range.
    pub fn validate(&self) -> Result<(), ExcitationError> {
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !(pos(self.amplitude_mm) && self.amplitude_mm <= MAX_AMPLITUDE_MM) {
            return Err(ExcitationError::Amplitude(self.amplitude_mm));
        }
        if !(pos(self.dt_s) && pos(self.band_lo_hz) && pos(self.rate_limit_mm_s)) {
            return Err(ExcitationError::NotPositive);
        }
        if !(self.band_hi_hz > self.band_lo_hz && self.band_hi_hz < 0.25 / self.dt_s) {
            return Err(ExcitationError::Band);
        }
        let non_negative = |v: f64| v.is_finite() && v >= 0.0;
        if !(pos(self.corner_hz) && non_negative(self.ramp_s) && non_negative(self.settle_s)) {
            return Err(ExcitationError::Timing);
        }
        if self.periods < 2 {
            return Err(ExcitationError::Periods);
        }
        Ok(())
    }

    /// Ticks of one period (the period is `1/f_lo`, rounded to whole ticks).
    pub fn period_ticks(&self) -> usize {
        libm::round(1.0 / (self.band_lo_hz * self.dt_s)) as usize
    }

    /// Total rig time, s.
    pub fn duration_s(&self) -> f64 {
        let (ramp, settle) = self.ramp_settle_ticks();
        (2 * ramp + settle + self.periods * self.period_ticks()) as f64 * self.dt_s
    }

    /// Ticks of each ramp and of the settling.
    pub fn ramp_settle_ticks(&self) -> (usize, usize) {
        (
            libm::round(self.ramp_s / self.dt_s) as usize,
            libm::round(self.settle_s / self.dt_s) as usize,
        )
    }
}

/// The cosine and sine the tables are computed with.
pub trait Trig {
    /// cos x.
    fn cos(x: f64) -> f64;
    /// sin x.
    fn sin(x: f64) -> f64;
}

/// The `libm` crate's (a `no_std` user without the host's tables; not bit-equal to std's).
#[derive(Debug, Clone, Copy)]
pub struct Libm;

impl Trig for Libm {
    fn cos(x: f64) -> f64 {
        libm::cos(x)
    }
    fn sin(x: f64) -> f64 {
        libm::sin(x)
    }
}

/// std's (the platform libm): what the host and the firmware's build script compute the tables
/// with, so that the device plays the host's excitation to the bit.
#[cfg(feature = "std")]
#[derive(Debug, Clone, Copy)]
pub struct Std;

#[cfg(feature = "std")]
impl Trig for Std {
    fn cos(x: f64) -> f64 {
        x.cos()
    }
    fn sin(x: f64) -> f64 {
        x.sin()
    }
}

/// Entry `i` of the table of one cycle of cos over `n` samples: `cos(2π·i/n)`. Line `k` at tick
/// `t` reads entry `(k·t) mod n`, exact and fast.
pub fn unit_cos<T: Trig>(i: usize, n: usize) -> f64 {
    T::cos(2.0 * PI * i as f64 / n as f64)
}

/// Entry `j` (0..ramp) of the ramps' table: `cos(π·j/ramp)`; the ramp-in envelope is
/// `0.5 − 0.5·cos(π·t/ramp)`, the ramp-out one `0.5 + 0.5·cos(π·j/ramp)`.
pub fn ramp_cos<T: Trig>(j: usize, ramp: usize) -> f64 {
    T::cos(PI * j as f64 / ramp as f64)
}

/// What a [`Schedule`] reads: the unit period and the ramp's cosines, tabulated.
pub trait Tables {
    /// Sample `i` of the unit period ([`Multisine::unit_at`]).
    fn unit(&self, i: usize) -> f64;
    /// [`ramp_cos`]`(j, ramp)`.
    fn ramp_cos(&self, j: usize) -> f64;
}

/// One period of the unit multisine: lines `k` with amplitudes `a_k` (flat below the corner, ∝ 1/f
/// above) and Schroeder's phases for arbitrary amplitudes,
/// `φ_k = −2π Σ_{l<k} (k−l)·a_l²/Σa²`, which sweep the lines in turn like a chirp (crest factor ≈
/// 1.5–2 instead of √(2N) for equal phases).
#[derive(Debug, Clone, PartialEq)]
pub struct Multisine {
    n: usize,
    k_lo: usize,
    count: usize,
    amps: [f64; MAX_LINES],
    cos_ph: [f64; MAX_LINES],
    sin_ph: [f64; MAX_LINES],
    shift: usize,
}

impl Multisine {
    /// The multisine of `cfg` (validated), its phases' cos and sin from `T`.
    pub fn new<T: Trig>(cfg: &ExcitationConfig) -> Result<Self, ExcitationError> {
        cfg.validate()?;
        let n = cfg.period_ticks();
        if n % 4 != 0 || n == 0 {
            return Err(ExcitationError::PeriodTicks(n));
        }
        let df = 1.0 / (n as f64 * cfg.dt_s);
        let k_lo = libm::round(cfg.band_lo_hz / df).max(1.0) as usize;
        let k_hi = libm::round(cfg.band_hi_hz / df) as usize;
        if k_hi < k_lo {
            return Err(ExcitationError::EmptyBand);
        }
        let count = k_hi - k_lo + 1;
        if count > MAX_LINES {
            return Err(ExcitationError::TooManyLines(count));
        }
        let mut amps = [0.0; MAX_LINES];
        for (j, a) in amps.iter_mut().take(count).enumerate() {
            let f = (k_lo + j) as f64 * df;
            *a = if f <= cfg.corner_hz {
                1.0
            } else {
                cfg.corner_hz / f
            };
        }
        let used = amps.get(..count).unwrap_or(&[]);
        let total: f64 = used.iter().map(|a| a * a).sum();
        let (mut cos_ph, mut sin_ph) = ([0.0; MAX_LINES], [0.0; MAX_LINES]);
        for k in 0..count {
            let s: f64 = (0..k)
                .zip(used)
                .map(|(l, a)| (k - l) as f64 * a * a / total)
                .sum();
            let ph = -2.0 * PI * s;
            if let (Some(c), Some(si)) = (cos_ph.get_mut(k), sin_ph.get_mut(k)) {
                *c = T::cos(ph);
                *si = T::sin(ph);
            }
        }
        // A quarter cycle of the table: sin x is the table a quarter cycle on, negated.
        let shift = libm::round(n as f64 / 4.0) as usize;
        Ok(Self {
            n,
            k_lo,
            count,
            amps,
            cos_ph,
            sin_ph,
            shift,
        })
    }

    /// Ticks per period.
    pub fn period_ticks(&self) -> usize {
        self.n
    }

    /// The excited lines (DFT bins: cycles per period).
    pub fn lines(&self) -> core::ops::Range<usize> {
        self.k_lo..self.k_lo + self.count
    }

    /// Sample `t` (0..n) of the unit period, with `cos_table(i)` = [`unit_cos`]`(i, n)`:
    /// `Σ a_k·cos(x + φ_k)` with `cos(x + φ) = cos x·cos φ − sin x·sin φ`, `x = 2πkt/n` from the
    /// table: exact phases at two table reads per line.
    pub fn unit_at(&self, t: usize, cos_table: impl Fn(usize) -> f64) -> f64 {
        let n = self.n;
        let mut acc = 0.0;
        for (j, ((&a, &c), &s)) in self
            .amps
            .iter()
            .zip(&self.cos_ph)
            .zip(&self.sin_ph)
            .take(self.count)
            .enumerate()
        {
            let i = ((self.k_lo + j) * t) % n;
            let cos_x = cos_table(i);
            let sin_x = -cos_table((i + self.shift) % n);
            acc += a * (cos_x * c - sin_x * s);
        }
        acc
    }
}

/// The unit period's peak and peak rate (they set the scale).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitStats {
    /// Peak |unit|.
    pub peak: f64,
    /// Peak |per-tick difference| / Δt, 1/s (periodic: the last sample's difference wraps).
    pub peak_rate_per_s: f64,
}

impl UnitStats {
    /// The stats of the unit period `unit(t)`, `t` in `0..n`, at tick `dt_s`.
    pub fn of(n: usize, dt_s: f64, unit: impl Fn(usize) -> f64) -> Self {
        let peak = (0..n).map(&unit).fold(0.0f64, |m, v| m.max(v.abs()));
        let peak_rate_per_s = (0..n)
            .map(|t| (unit((t + 1) % n) - unit(t)).abs() / dt_s)
            .fold(0.0f64, f64::max);
        Self {
            peak,
            peak_rate_per_s,
        }
    }
}

/// The command at every tick: the unit multisine scaled so that its peak is the amplitude and its
/// peak velocity at most 80% of the rate limit (the smaller scale wins), under a raised-cosine
/// envelope in and out, through a slew limiter at the rate limit; the last tick is 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Schedule {
    /// The scale applied to the unit signal, mm.
    pub scale_mm: f64,
    /// Ticks of one period.
    pub period_ticks: usize,
    /// First tick of the analysed periods (aligned to phase 0 of a period).
    pub window_start: usize,
    ramp: usize,
    body: usize,
    offset: usize,
    max_step_mm: f64,
}

impl Schedule {
    /// The schedule of `cfg` for a unit period of `n` ticks with `stats`.
    pub fn new(
        cfg: &ExcitationConfig,
        n: usize,
        stats: UnitStats,
    ) -> Result<Self, ExcitationError> {
        cfg.validate()?;
        if !(stats.peak > 0.0 && stats.peak_rate_per_s > 0.0) || n == 0 {
            return Err(ExcitationError::EmptyBand);
        }
        let scale_mm =
            (cfg.amplitude_mm / stats.peak).min(0.8 * cfg.rate_limit_mm_s / stats.peak_rate_per_s);
        let (ramp, settle) = cfg.ramp_settle_ticks();
        let window_start = ramp + settle;
        Ok(Self {
            scale_mm,
            period_ticks: n,
            window_start,
            ramp,
            body: settle + cfg.periods * n,
            // The signal is aligned so that the analysed window starts at phase 0 of a period.
            offset: n - window_start % n,
            max_step_mm: cfg.rate_limit_mm_s * cfg.dt_s,
        })
    }

    /// Ticks of each ramp (the length of the ramp table).
    pub fn ramp_ticks(&self) -> usize {
        self.ramp
    }

    /// Ticks of the whole excitation, the final 0 included.
    pub fn ticks(&self) -> usize {
        2 * self.ramp + self.body + 1
    }

    /// Index of the unit period played at tick `t`.
    pub fn unit_index(&self, t: usize) -> usize {
        // checked_rem: no division-by-zero panic path in the firmware's control task (`new`
        // refuses a period of 0 ticks).
        t.wrapping_add(self.offset)
            .checked_rem(self.period_ticks)
            .unwrap_or(0)
    }

    /// The wanted command at tick `t` (before the slew limiter); 0 from the last tick on.
    pub fn wanted_mm(&self, t: usize, tables: &impl Tables) -> f64 {
        let (ramp, body) = (self.ramp, self.body);
        if t >= 2 * ramp + body {
            return 0.0;
        }
        let env = if t < ramp {
            0.5 - 0.5 * tables.ramp_cos(t)
        } else if t >= ramp + body {
            0.5 + 0.5 * tables.ramp_cos(t - ramp - body)
        } else {
            1.0
        };
        self.scale_mm * env * tables.unit(self.unit_index(t))
    }

    /// The slew limiter: the command after `prev_mm` toward `want_mm`, and whether it limited.
    pub fn slew(&self, prev_mm: f64, want_mm: f64) -> (f64, bool) {
        let step = want_mm - prev_mm;
        if step > self.max_step_mm {
            (prev_mm + self.max_step_mm, true)
        } else if step < -self.max_step_mm {
            (prev_mm - self.max_step_mm, true)
        } else {
            (want_mm, false)
        }
    }
}

/// A [`Schedule`] played tick by tick (the firmware's control task calls [`Player::next`] once per
/// tick; the host collects every value).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Player {
    /// The schedule.
    pub schedule: Schedule,
    t: usize,
    prev_mm: f64,
    limited: usize,
}

impl Player {
    /// At tick 0, the command at 0 mm.
    pub fn new(schedule: Schedule) -> Self {
        Self {
            schedule,
            t: 0,
            prev_mm: 0.0,
            limited: 0,
        }
    }

    /// The command of the next tick, mm, or `None` after the last one (the final tick is exactly
    /// 0).
    pub fn next(&mut self, tables: &impl Tables) -> Option<f64> {
        let t = self.t;
        let last = self.schedule.ticks() - 1;
        if t > last {
            return None;
        }
        self.t += 1;
        if t == last {
            return Some(0.0);
        }
        let want = self.schedule.wanted_mm(t, tables);
        let (v, limited) = self.schedule.slew(self.prev_mm, want);
        if limited {
            self.limited += 1;
        }
        self.prev_mm = v;
        Some(v)
    }

    /// Ticks played so far.
    pub fn tick(&self) -> usize {
        self.t
    }

    /// Ticks at which the slew limiter changed the signal (0 by design; a guard).
    pub fn rate_limited_ticks(&self) -> usize {
        self.limited
    }
}

/// Every table of an excitation, computed with std's cosines: what `rths identify` plays from and
/// what the firmware's build script writes into flash (the device's [`Tables`]).
#[cfg(feature = "std")]
#[derive(Debug, Clone, PartialEq)]
pub struct StdTables {
    /// The multisine.
    pub multisine: Multisine,
    /// One period of the unit multisine.
    pub unit: std::vec::Vec<f64>,
    /// Its peak and peak rate.
    pub stats: UnitStats,
    /// `cos(π·j/ramp)`, `j` in `0..ramp` ([`ramp_cos`]).
    pub ramp_cos: std::vec::Vec<f64>,
    /// The schedule of `cfg`.
    pub schedule: Schedule,
}

#[cfg(feature = "std")]
impl StdTables {
    /// The tables of `cfg`.
    pub fn new(cfg: &ExcitationConfig) -> Result<Self, ExcitationError> {
        let multisine = Multisine::new::<Std>(cfg)?;
        let n = multisine.period_ticks();
        let table: std::vec::Vec<f64> = (0..n).map(|i| unit_cos::<Std>(i, n)).collect();
        let cos = |i: usize| table.get(i).copied().unwrap_or(f64::NAN);
        let unit: std::vec::Vec<f64> = (0..n).map(|t| multisine.unit_at(t, cos)).collect();
        let stats = UnitStats::of(n, cfg.dt_s, |i| unit.get(i).copied().unwrap_or(f64::NAN));
        let schedule = Schedule::new(cfg, n, stats)?;
        let ramp = schedule.ramp_ticks();
        let ramp_cos = (0..ramp).map(|j| ramp_cos::<Std>(j, ramp)).collect();
        Ok(Self {
            multisine,
            unit,
            stats,
            ramp_cos,
            schedule,
        })
    }
}

#[cfg(feature = "std")]
impl Tables for StdTables {
    fn unit(&self, i: usize) -> f64 {
        self.unit.get(i).copied().unwrap_or(f64::NAN)
    }
    fn ramp_cos(&self, j: usize) -> f64 {
        self.ramp_cos.get(j).copied().unwrap_or(f64::NAN)
    }
}

#[cfg(test)]
mod tests;

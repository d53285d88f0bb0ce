//! The identification excitation: a periodic multisine, band-limited to the test's band, with a low
//! crest factor, ramped in and out, scaled to a small stroke and a safe velocity, and slew-rate
//! limited as a last guard. A pure function of its settings: no rig, no randomness.
//!
//! Why a periodic multisine rather than random noise: with whole periods in steady state, the DFT
//! of each period sees only the excited lines, without leakage and without windowing, so the H1
//! estimate at each line is unbiased and its coherence over the periods measures only the noise
//! (and any nonlinearity), not the estimator.

use std::f64::consts::PI;

use super::IdentifyError;

/// Largest excitation amplitude, mm: 10% of the ±25.4 mm stroke.
pub const MAX_AMPLITUDE_MM: f64 = 0.1 * rths_core::params::ACTUATOR_STROKE_MM;

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
    pub fn new(dt_s: f64) -> Self {
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

    fn validate(&self) -> Result<(), IdentifyError> {
        let bad = |what: &str| Err(IdentifyError::Setting(what.to_string()));
        let pos = |v: f64| v.is_finite() && v > 0.0;
        if !(pos(self.amplitude_mm) && self.amplitude_mm <= MAX_AMPLITUDE_MM) {
            return bad(&format!(
                "amplitude {} mm not in (0, {MAX_AMPLITUDE_MM}] (10% of the stroke)",
                self.amplitude_mm
            ));
        }
        if !(pos(self.dt_s) && pos(self.band_lo_hz) && pos(self.rate_limit_mm_s)) {
            return bad("dt, band and rate limit must be positive");
        }
        if !(self.band_hi_hz > self.band_lo_hz && self.band_hi_hz < 0.25 / self.dt_s) {
            return bad("band: need f_lo < f_hi < a quarter of the sample rate");
        }
        if !(pos(self.corner_hz) && self.ramp_s >= 0.0 && self.settle_s >= 0.0) {
            return bad("corner, ramp and settling must be positive");
        }
        if self.periods < 2 {
            return bad("at least 2 periods (the coherence needs averages)");
        }
        Ok(())
    }

    /// Ticks of one period (the period is `1/f_lo`, rounded to whole ticks).
    pub fn period_ticks(&self) -> usize {
        (1.0 / (self.band_lo_hz * self.dt_s)).round() as usize
    }

    /// Total rig time, s.
    pub fn duration_s(&self) -> f64 {
        let (ramp, settle) = self.ramp_settle_ticks();
        (2 * ramp + settle + self.periods * self.period_ticks()) as f64 * self.dt_s
    }

    fn ramp_settle_ticks(&self) -> (usize, usize) {
        (
            (self.ramp_s / self.dt_s).round() as usize,
            (self.settle_s / self.dt_s).round() as usize,
        )
    }
}

/// The generated excitation.
#[derive(Debug, Clone, PartialEq)]
pub struct Excitation {
    /// The settings it was made from.
    pub config: ExcitationConfig,
    /// Command at every tick, mm (starts and ends at 0).
    pub command_mm: Vec<f64>,
    /// First tick of the analysed periods.
    pub window_start: usize,
    /// Ticks per period.
    pub period_ticks: usize,
    /// DFT bin (cycles per period) of each excited line.
    pub lines: Vec<usize>,
    /// Peak |command|, mm.
    pub peak_mm: f64,
    /// Peak |command velocity| (per-tick difference / Δt), mm/s.
    pub peak_velocity_mm_s: f64,
    /// Ticks at which the slew limiter changed the signal (0 by design; a guard).
    pub rate_limited_ticks: usize,
}

impl Excitation {
    /// Frequencies of the excited lines, Hz.
    pub fn line_freqs_hz(&self) -> Vec<f64> {
        let df = 1.0 / (self.period_ticks as f64 * self.config.dt_s);
        self.lines.iter().map(|&k| k as f64 * df).collect()
    }

    /// One past the last tick of the analysed periods.
    pub fn window_end(&self) -> usize {
        self.window_start + self.config.periods * self.period_ticks
    }
}

/// One period of the unit multisine: lines `k` with amplitudes `a_k` (flat below the corner, ∝ 1/f
/// above) and Schroeder's phases for arbitrary amplitudes,
/// `φ_k = −2π Σ_{l<k} (k−l)·a_l²/Σa²`, which sweep the lines in turn like a chirp (crest factor ≈
/// 1.5–2 instead of √(2N) for equal phases).
fn unit_period(cfg: &ExcitationConfig, n: usize, lines: &[usize]) -> Vec<f64> {
    let df = 1.0 / (n as f64 * cfg.dt_s);
    let amps: Vec<f64> = lines
        .iter()
        .map(|&k| {
            let f = k as f64 * df;
            if f <= cfg.corner_hz {
                1.0
            } else {
                cfg.corner_hz / f
            }
        })
        .collect();
    let total: f64 = amps.iter().map(|a| a * a).sum();
    let mut phases = Vec::with_capacity(lines.len());
    for k in 0..lines.len() {
        let s: f64 = (0..k)
            .map(|l| (k - l) as f64 * amps[l] * amps[l] / total)
            .sum();
        phases.push(-2.0 * PI * s);
    }
    // A table of one cycle of cos: line k at tick t reads index (k·t) mod n, exact and fast.
    let table: Vec<f64> = (0..n)
        .map(|t| (2.0 * PI * t as f64 / n as f64).cos())
        .collect();
    let quarter = n as f64 / 4.0;
    let mut out = vec![0.0; n];
    for ((&k, &a), &ph) in lines.iter().zip(&amps).zip(&phases) {
        // cos(x + φ) = cos x·cos φ − sin x·sin φ with x = 2πkt/n from the table (sin x is the
        // table a quarter cycle on, negated): exact phases at two table reads per sample.
        let (c, s) = (ph.cos(), ph.sin());
        let shift = quarter.round() as usize;
        for (t, o) in out.iter_mut().enumerate() {
            let i = (k * t) % n;
            let cos_x = table[i];
            let sin_x = -table[(i + shift) % n];
            *o += a * (cos_x * c - sin_x * s);
        }
    }
    out
}

/// Build the excitation: the unit multisine scaled so that its peak is the amplitude and its peak
/// velocity at most 80% of the rate limit (the smaller scale wins), under a raised-cosine envelope
/// in and out, through a slew limiter at the rate limit.
pub fn generate(cfg: &ExcitationConfig) -> Result<Excitation, IdentifyError> {
    cfg.validate()?;
    let n = cfg.period_ticks();
    if n % 4 != 0 {
        return Err(IdentifyError::Setting(format!(
            "period of {n} ticks: must be a multiple of 4 (choose f_lo = fs/(4m))"
        )));
    }
    let df = 1.0 / (n as f64 * cfg.dt_s);
    let k_lo = (cfg.band_lo_hz / df).round().max(1.0) as usize;
    let k_hi = (cfg.band_hi_hz / df).round() as usize;
    let lines: Vec<usize> = (k_lo..=k_hi).collect();
    let unit = unit_period(cfg, n, &lines);
    let peak = unit.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let peak_vel = (0..n)
        .map(|t| (unit[(t + 1) % n] - unit[t]).abs() / cfg.dt_s)
        .fold(0.0f64, f64::max);
    if !(peak > 0.0 && peak_vel > 0.0) {
        return Err(IdentifyError::Setting("empty band".into()));
    }
    let scale = (cfg.amplitude_mm / peak).min(0.8 * cfg.rate_limit_mm_s / peak_vel);
    let (ramp, settle) = cfg.ramp_settle_ticks();
    let body = settle + cfg.periods * n;
    let total = 2 * ramp + body;
    let max_step = cfg.rate_limit_mm_s * cfg.dt_s;
    let mut command_mm = Vec::with_capacity(total + 1);
    let (mut prev, mut limited) = (0.0f64, 0usize);
    // The signal is aligned so that the analysed window starts at phase 0 of a period.
    let window_start = ramp + settle;
    let offset = n - window_start % n;
    for t in 0..total {
        let env = if t < ramp {
            0.5 - 0.5 * (PI * t as f64 / ramp as f64).cos()
        } else if t >= ramp + body {
            0.5 + 0.5 * (PI * (t - ramp - body) as f64 / ramp as f64).cos()
        } else {
            1.0
        };
        let want = scale * env * unit[(t + offset) % n];
        let step = want - prev;
        let v = if step > max_step {
            limited += 1;
            prev + max_step
        } else if step < -max_step {
            limited += 1;
            prev - max_step
        } else {
            want
        };
        command_mm.push(v);
        prev = v;
    }
    command_mm.push(0.0);
    let peak_mm = command_mm.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let peak_velocity_mm_s = command_mm
        .windows(2)
        .map(|w| (w[1] - w[0]).abs() / cfg.dt_s)
        .fold(0.0f64, f64::max);
    Ok(Excitation {
        config: *cfg,
        command_mm,
        window_start,
        period_ticks: n,
        lines,
        peak_mm,
        peak_velocity_mm_s,
        rate_limited_ticks: limited,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_excitation_is_small_slow_and_periodic() {
        let cfg = ExcitationConfig::new(rths_core::params::DT_S);
        let e = generate(&cfg).unwrap();
        assert!(e.peak_mm <= cfg.amplitude_mm + 1e-12, "{}", e.peak_mm);
        assert!(e.peak_velocity_mm_s <= cfg.rate_limit_mm_s);
        assert_eq!(e.rate_limited_ticks, 0);
        assert!(cfg.duration_s() <= 60.0);
        assert_eq!(e.command_mm.first(), Some(&0.0));
        assert_eq!(e.command_mm.last(), Some(&0.0));
        let (s, n) = (e.window_start, e.period_ticks);
        for t in 0..n {
            assert!((e.command_mm[s + t] - e.command_mm[s + 4 * n + t]).abs() < 1e-12);
        }
        let f = e.line_freqs_hz();
        assert!((f[0] - 0.1).abs() < 1e-9 && (f[f.len() - 1] - 20.0).abs() < 1e-9);
    }

    #[test]
    fn refuses_a_large_amplitude() {
        let mut cfg = ExcitationConfig::new(rths_core::params::DT_S);
        cfg.amplitude_mm = 3.0;
        assert!(generate(&cfg).is_err());
    }
}

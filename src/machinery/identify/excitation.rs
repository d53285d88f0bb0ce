//! The identification excitation as the host plays it: the whole command sequence, built from the
//! one home of the formula, `rths_core::identify_excitation` (the firmware plays the same values
//! tick by tick over the link: `rths link ... identify`).

pub use rths_core::identify_excitation::{ExcitationConfig, MAX_AMPLITUDE_MM};
use rths_core::identify_excitation::{Player, StdTables};

use super::error::IdentifyError;

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

/// Build the excitation (`rths_core::identify_excitation`: its [`StdTables`] and [`Schedule`]:
/// scale, envelope, slew limit).
///
/// [`Schedule`]: rths_core::identify_excitation::Schedule
pub fn generate(cfg: &ExcitationConfig) -> Result<Excitation, IdentifyError> {
    let tables = StdTables::new(cfg).map_err(|e| IdentifyError::Setting(e.to_string()))?;
    let schedule = tables.schedule;
    let n = tables.multisine.period_ticks();
    let mut player = Player::new(schedule);
    let mut command_mm = Vec::with_capacity(schedule.ticks());
    while let Some(v) = player.next(&tables) {
        command_mm.push(v);
    }
    let peak_mm = command_mm.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let peak_velocity_mm_s = command_mm
        .windows(2)
        .map(|w| (w[1] - w[0]).abs() / cfg.dt_s)
        .fold(0.0f64, f64::max);
    Ok(Excitation {
        config: *cfg,
        command_mm,
        window_start: schedule.window_start,
        period_ticks: n,
        lines: tables.multisine.lines().collect(),
        peak_mm,
        peak_velocity_mm_s,
        rate_limited_ticks: player.rate_limited_ticks(),
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

//! The rig file: what `rths identify` measured of a rig, versioned JSON, validated on load and
//! before it is written.
//!
//! A rig file belongs to one preset (on real hardware: one actuator) and one board;
//! [`RigFile::check`] refuses it for a run of another.

use std::path::{Path, PathBuf};

use rths_core::checksum::{fnv1a64, Fnv1a64Label};
use rths_core::compensator::{LeadParams, LEAD_MAX_STRIDE, LEAD_TAPS};
use rths_hal_sim::RigConfig;
use serde::{Deserialize, Serialize};

use super::estimate::{FrfLine, SpecimenFit};

/// The `format` tag of every rig file.
pub const RIG_FORMAT: &str = "rths-rig";
/// The rig-file schema version this code reads and writes.
pub const SCHEMA_VERSION: u64 = 1;
/// The `board` of a rig identified on the host's virtual plant (`rths identify`, and what every
/// host run's plant is: `rths simulate`, `rths site` on the virtual rig).
pub const VIRTUAL_BOARD: &str = "virtual";

/// The excitation, as played.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExcitationInfo {
    /// Requested peak command, mm.
    pub amplitude_mm: f64,
    /// Peak command sent, mm.
    pub peak_command_mm: f64,
    /// Excited band [lo, hi], Hz.
    pub band_hz: [f64; 2],
    /// Corner above which the line amplitudes fall as 1/f, Hz.
    pub corner_hz: f64,
    /// Rig time, s.
    pub duration_s: f64,
    /// Slew-rate limit, mm/s.
    pub rate_limit_mm_s: f64,
    /// Peak command velocity sent, mm/s.
    pub peak_velocity_mm_s: f64,
    /// Period of the multisine, s.
    pub period_s: f64,
    /// Analysed periods.
    pub periods: usize,
    /// Excited lines.
    pub lines: usize,
}

/// The actuator's dynamics as the controller sees them (command sent → displacement read).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActuatorInfo {
    /// Controller tick, s.
    pub dt_s: f64,
    /// Phase delay at low frequency (phase slope, 0.1–1 Hz), ms.
    pub delay_ms: f64,
    /// Dead time τ of the model `g·e^{−jωτ}/(1 + jωT)`, ms.
    pub dead_time_ms: f64,
    /// Lag time constant T of the model, ms.
    pub lag_ms: f64,
    /// Low-frequency gain g of the model.
    pub gain: f64,
    /// The measured frequency response at every excited line.
    pub frf: Vec<FrfLine>,
}

/// The compensation identified for the actuator.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CompensationInfo {
    /// Lead-filter weights, newest tap first (`rths_core::compensator::Lead`).
    pub lead_weights: Vec<f64>,
    /// Lead-filter tap spacing, ticks.
    pub lead_stride: usize,
    /// ATS initial [a0, a1 (s), a2 (s²)].
    pub ats_initial: [f64; 3],
}

/// Fit quality.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct QualityInfo {
    /// Smallest coherence over the lines.
    pub min_coherence: f64,
    /// Mean coherence over the lines.
    pub mean_coherence: f64,
    /// Fraction of the lines with coherence ≥ 0.9.
    pub good_line_fraction: f64,
    /// RMS relative error of the model `g·e^{−jωτ}/(1 + jωT)` against the measured response, %.
    pub frf_fit_error_pct: f64,
    /// NRMSE of the lead fit, %.
    pub lead_fit_nrmse_pct: f64,
    /// RMS of |lead·H·e^{jωΔt} − 1| over the band, %.
    pub lead_residual_pct: f64,
    /// R² of the specimen's force model.
    pub stiffness_r2: f64,
}

/// Where the file came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// `rths` version.
    pub rths_version: String,
    /// The command line.
    pub command_line: String,
    /// The device that played the excitation and measured the rig (`rths link ... identify`:
    /// its link, build and model, and that the excitation ran on it); absent for `rths identify`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device: Option<String>,
}

/// A whole rig file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RigFile {
    /// Always [`RIG_FORMAT`].
    pub format: String,
    /// Always [`SCHEMA_VERSION`].
    pub schema_version: u64,
    /// Plant preset (`unr-compact`, `benchmark`).
    pub preset: String,
    /// Board the rig was driven from (`virtual` for the host simulator).
    pub board: String,
    /// Specimen model of the virtual rig (`linear`, `bouc-wen`).
    pub specimen: String,
    /// Specimen stiffness factor of the virtual rig.
    pub specimen_stiffness_factor: f64,
    /// Seed of the sensor noise (and of the parameters with `uncertainty`).
    pub seed: u64,
    /// The plant parameters were drawn from the benchmark's uncertainty.
    pub uncertainty: bool,
    /// When, UTC, ISO 8601.
    pub date_utc: String,
    /// The excitation.
    pub excitation: ExcitationInfo,
    /// The actuator.
    pub actuator: ActuatorInfo,
    /// The compensation.
    pub compensation: CompensationInfo,
    /// The specimen.
    pub specimen_fit: SpecimenFit,
    /// Fit quality.
    pub quality: QualityInfo,
    /// Provenance.
    pub provenance: Provenance,
}

/// Why a rig file was rejected.
#[derive(Debug, thiserror::Error)]
pub enum RigFileError {
    /// Reading or writing failed.
    #[error("cannot access rig file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Not JSON, or not the expected structure.
    #[error("rig file is not valid JSON of the expected shape: {0}")]
    Json(#[from] serde_json::Error),
    /// Not a rig file.
    #[error("not a rig file (format `{found}`, expected `{RIG_FORMAT}`)")]
    UnknownFormat {
        /// The format tag found.
        found: String,
    },
    /// A schema this code does not read.
    #[error("rig file schema version {found} is not supported (this rths reads {SCHEMA_VERSION})")]
    UnsupportedVersion {
        /// The version found.
        found: u64,
    },
    /// A field is invalid.
    #[error("rig file field `{field}`: {reason}")]
    Invalid {
        /// The field.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// The rig file is for another rig than the run's.
    #[error("rig file is for {what} `{file}`, this run uses `{run}`")]
    Mismatch {
        /// `preset` or `board`.
        what: &'static str,
        /// The file's.
        file: String,
        /// The run's.
        run: String,
    },
}

/// Largest magnitude of a lead-filter weight, ATS initial value or a filter's gain in a rig file
/// (an identified lead has weights of a few units; beyond this the fit is broken or the file edited).
pub const MAX_COMPENSATION_VALUE: f64 = 1e3;
/// Specimen stiffness range of a rig file, kN/mm (a lab specimen: from a soft coupon to a stiff
/// brace).
pub const SPECIMEN_STIFFNESS_RANGE_KN_PER_MM: (f64, f64) = (1e-6, 1e5);
/// Largest specimen mass of a rig file, kN·s²/mm (10⁶ t: no specimen on a rig weighs more).
pub const MAX_SPECIMEN_MASS_KN_S2_PER_MM: f64 = 1e3;
/// Largest specimen damping of a rig file, kN·s/mm.
pub const MAX_SPECIMEN_DAMPING_KN_S_PER_MM: f64 = 1e5;
/// Largest actuator delay of a rig file, ms (a second: far beyond any servo-hydraulic rig).
pub const MAX_ACTUATOR_DELAY_MS: f64 = 1e3;

#[derive(Deserialize)]
struct Header {
    format: Option<String>,
    schema_version: Option<u64>,
}

fn invalid(field: &'static str, reason: impl Into<String>) -> RigFileError {
    RigFileError::Invalid {
        field,
        reason: reason.into(),
    }
}

fn finite(field: &'static str, v: &[f64]) -> Result<(), RigFileError> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(invalid(field, format!("value {i} is not finite"))),
        None => Ok(()),
    }
}

/// Refuse `value` of `field` outside `[lo, hi]`, naming both limits (values printed compactly).
fn within(
    field: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    unit: &str,
) -> Result<(), RigFileError> {
    if !(lo..=hi).contains(&value) {
        return Err(invalid(
            field,
            format!("{value:.6e}{unit} is outside the physical range [{lo:e}, {hi:e}]{unit}"),
        ));
    }
    Ok(())
}

impl RigFile {
    /// Check tags, shapes, finiteness and physical ranges (refused with the field and the limit,
    /// never clamped), and that it was identified at this build's controller rate.
    pub fn validate(&self) -> Result<(), RigFileError> {
        if self.format != RIG_FORMAT {
            return Err(RigFileError::UnknownFormat {
                found: self.format.clone(),
            });
        }
        if self.schema_version != SCHEMA_VERSION {
            return Err(RigFileError::UnsupportedVersion {
                found: self.schema_version,
            });
        }
        if !matches!(self.preset.as_str(), "unr-compact" | "benchmark") {
            return Err(invalid(
                "preset",
                format!("unknown preset `{}`", self.preset),
            ));
        }
        if self.board.is_empty() {
            return Err(invalid("board", "empty"));
        }
        // The virtual rig's specimen was this factor times the paper's: `rths identify` refuses
        // one that is not positive, so a file holding one was not written by it.
        let f = self.specimen_stiffness_factor;
        if !(f.is_finite() && f > 0.0) {
            return Err(invalid(
                "specimen_stiffness_factor",
                format!("{f}: must be a finite number > 0"),
            ));
        }
        let a = &self.actuator;
        finite(
            "actuator",
            &[a.dt_s, a.delay_ms, a.dead_time_ms, a.lag_ms, a.gain],
        )?;
        if !(a.dt_s > 0.0 && a.gain > 0.0 && a.delay_ms >= 0.0) {
            return Err(invalid(
                "actuator",
                "dt_s and gain must be > 0, delay_ms ≥ 0",
            ));
        }
        rths_files::rate::check_dt(
            "the rig file",
            a.dt_s,
            rths_core::params::DT_S,
            "rths identify --preset PRESET --out RIG.json",
        )
        .map_err(|e| invalid("actuator.dt_s", e.to_string()))?;
        within("actuator.gain", a.gain, 1e-3, MAX_COMPENSATION_VALUE, "")?;
        within(
            "actuator.delay_ms",
            a.delay_ms,
            0.0,
            MAX_ACTUATOR_DELAY_MS,
            " ms",
        )?;
        if a.frf.is_empty() {
            return Err(invalid("actuator.frf", "empty"));
        }
        for l in &a.frf {
            finite(
                "actuator.frf",
                &[l.freq_hz, l.gain, l.phase_deg, l.coherence],
            )?;
        }
        let c = &self.compensation;
        if c.lead_weights.len() != LEAD_TAPS {
            return Err(invalid(
                "compensation.lead_weights",
                format!("{} weights, expected {LEAD_TAPS}", c.lead_weights.len()),
            ));
        }
        finite("compensation.lead_weights", &c.lead_weights)?;
        for w in &c.lead_weights {
            let m = MAX_COMPENSATION_VALUE;
            within("compensation.lead_weights", *w, -m, m, "")?;
        }
        if !(1..=LEAD_MAX_STRIDE).contains(&c.lead_stride) {
            return Err(invalid(
                "compensation.lead_stride",
                format!("{} not in 1..={LEAD_MAX_STRIDE}", c.lead_stride),
            ));
        }
        finite("compensation.ats_initial", &c.ats_initial)?;
        for a in &c.ats_initial {
            let m = MAX_COMPENSATION_VALUE;
            within("compensation.ats_initial", *a, -m, m, "")?;
        }
        let s = &self.specimen_fit;
        finite(
            "specimen_fit",
            &[
                s.stiffness_kn_per_mm,
                s.damping_kn_s_per_mm,
                s.mass_kn_s2_per_mm,
                s.r2,
            ],
        )?;
        let (k_lo, k_hi) = SPECIMEN_STIFFNESS_RANGE_KN_PER_MM;
        within(
            "specimen_fit.stiffness_kn_per_mm",
            s.stiffness_kn_per_mm,
            k_lo,
            k_hi,
            " kN/mm",
        )?;
        // A fit's mass and damping may come out a hair below zero (noise on a negligible term);
        // a negative value larger than that is not a specimen: refused, not clamped to 0.
        let tol = 1e-6 * s.stiffness_kn_per_mm;
        within(
            "specimen_fit.mass_kn_s2_per_mm",
            s.mass_kn_s2_per_mm,
            -tol,
            MAX_SPECIMEN_MASS_KN_S2_PER_MM,
            " kN·s²/mm",
        )?;
        within(
            "specimen_fit.damping_kn_s_per_mm",
            s.damping_kn_s_per_mm,
            -tol,
            MAX_SPECIMEN_DAMPING_KN_S_PER_MM,
            " kN·s/mm",
        )?;
        let q = &self.quality;
        finite(
            "quality",
            &[
                q.min_coherence,
                q.mean_coherence,
                q.good_line_fraction,
                q.frf_fit_error_pct,
                q.lead_fit_nrmse_pct,
                q.lead_residual_pct,
                q.stiffness_r2,
            ],
        )?;
        let e = &self.excitation;
        finite(
            "excitation",
            &[
                e.amplitude_mm,
                e.peak_command_mm,
                e.band_hz[0],
                e.band_hz[1],
                e.duration_s,
                e.rate_limit_mm_s,
                e.peak_velocity_mm_s,
            ],
        )?;
        Ok(())
    }

    /// The identified lead filter, validated for the core's `Lead`.
    pub fn lead_params(&self) -> Result<LeadParams, RigFileError> {
        let mut w = [0.0; LEAD_TAPS];
        if self.compensation.lead_weights.len() != LEAD_TAPS {
            return Err(invalid("compensation.lead_weights", "wrong length"));
        }
        w.copy_from_slice(&self.compensation.lead_weights);
        LeadParams::new(w, self.compensation.lead_stride)
            .map_err(|e| invalid("compensation", format!("{e:?}")))
    }

    /// Refuse the file if it was identified on another plant than the run's `rig` (configured with specimen
    /// stiffness factor `factor`): another specimen model or factor, or another draw of the uncertain
    /// parameters (`--uncertainty`, and its seed). Without a draw the seed sets the sensor noise alone:
    /// the plant is the same one and its rig file fits. Preset and board: [`Self::check`].
    pub fn check_plant(&self, rig: &RigConfig, factor: f64) -> anyhow::Result<()> {
        let run_specimen = rig.specimen.name();
        if self.specimen != run_specimen {
            anyhow::bail!(
                "the rig was identified with the {} specimen, this run has the {run_specimen} one",
                self.specimen
            );
        }
        let f_file = self.specimen_stiffness_factor;
        // Both come from the same kind of argument; a relative 1e-9 only absorbs printing round-off.
        if (f_file - factor).abs() > 1e-9 * factor.abs().max(1.0) {
            anyhow::bail!(
                "the rig was identified with specimen stiffness factor {f_file}, this run has {factor}"
            );
        }
        let draw = |u: bool, seed: u64| {
            if u {
                format!("the uncertainty draw of seed {seed}")
            } else {
                "the nominal plant (no --uncertainty)".to_string()
            }
        };
        if self.uncertainty != rig.uncertainty || (rig.uncertainty && self.seed != rig.seed) {
            anyhow::bail!(
                "the rig was identified on {}, this run is on {}: another plant",
                draw(self.uncertainty, self.seed),
                draw(rig.uncertainty, rig.seed)
            );
        }
        Ok(())
    }

    /// Refuse the file for a run on another preset or board.
    pub fn check(&self, preset: &str, board: &str) -> Result<(), RigFileError> {
        if self.preset != preset {
            return Err(RigFileError::Mismatch {
                what: "preset",
                file: self.preset.clone(),
                run: preset.to_string(),
            });
        }
        if self.board != board {
            return Err(RigFileError::Mismatch {
                what: "board",
                file: self.board.clone(),
                run: board.to_string(),
            });
        }
        Ok(())
    }

    /// Parse and validate from JSON text (format and version first, so a newer file says so).
    pub fn from_json(text: &str) -> Result<Self, RigFileError> {
        let header: Header = serde_json::from_str(text)?;
        let format = header.format.unwrap_or_default();
        if format != RIG_FORMAT {
            return Err(RigFileError::UnknownFormat { found: format });
        }
        let version = header.schema_version.unwrap_or(0);
        if version != SCHEMA_VERSION {
            return Err(RigFileError::UnsupportedVersion { found: version });
        }
        let rig: RigFile = serde_json::from_str(text)?;
        rig.validate()?;
        Ok(rig)
    }

    /// Pretty JSON of a validated file.
    pub fn to_json(&self) -> Result<String, RigFileError> {
        self.validate()?;
        Ok(serde_json::to_string_pretty(self)?)
    }

    /// Read and validate a rig file.
    pub fn load(path: &Path) -> Result<Self, RigFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| RigFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text)
    }

    /// Validate and write pretty JSON (with a final newline).
    pub fn save(&self, path: &Path) -> Result<(), RigFileError> {
        let mut text = self.to_json()?;
        text.push('\n');
        std::fs::write(path, text).map_err(|source| RigFileError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}

/// A checksum of a file's bytes (FNV-1a, 64 bit), hex: identifies the rig file a model was trained
/// with (not a security hash).
pub fn checksum_hex(bytes: &[u8]) -> String {
    Fnv1a64Label(fnv1a64(bytes)).to_string()
}

/// `t` as ISO 8601 UTC (`YYYY-MM-DDTHH:MM:SSZ`), from the Unix time (days to civil date by Howard
/// Hinnant's algorithm; no date crate needed).
pub fn iso8601_utc(t: std::time::SystemTime) -> String {
    let secs = t
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates() {
        let t = |s| std::time::UNIX_EPOCH + std::time::Duration::from_secs(s);
        assert_eq!(iso8601_utc(t(0)), "1970-01-01T00:00:00Z");
        assert_eq!(iso8601_utc(t(951_782_400)), "2000-02-29T00:00:00Z");
        assert_eq!(iso8601_utc(t(1_798_761_599)), "2026-12-31T23:59:59Z");
    }

    #[test]
    fn checksums_differ() {
        assert_ne!(checksum_hex(b"a"), checksum_hex(b"b"));
        assert_eq!(checksum_hex(b""), "fnv1a64:cbf29ce484222325");
    }

    /// Found by the `rig_file` fuzz target: a factor of 0 was read, and every run that took the
    /// file then scaled its virtual specimen to nothing.
    #[test]
    fn a_specimen_factor_that_is_not_positive_is_refused() {
        let text = include_str!("../../../fuzz/seeds/rig_file/rig.json");
        assert!(RigFile::from_json(text).is_ok());
        let mut v: serde_json::Value = serde_json::from_str(text).unwrap();
        for bad in [0.0, -1.0] {
            v["specimen_stiffness_factor"] = serde_json::json!(bad);
            let e = RigFile::from_json(&v.to_string()).unwrap_err().to_string();
            assert!(e.contains("specimen_stiffness_factor"), "{e}");
        }
    }
}

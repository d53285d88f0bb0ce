//! `rths identify`: characterize a rig from its measured signals only.
//!
//! 1. [`excitation`]: a small (≤ 10% of the stroke), band-limited (0.1–20 Hz), rate-limited
//!    periodic multisine, ramped in and out.
//! 2. [`runner`]: drive any `Daq + Actuator` with it through a controller's [`Supervisor`], tick by
//!    tick with the board's identification tick (`rths_app::identify::identify_step`) through the
//!    host's driver, recording command, displacement and force as read.
//! 3. [`estimate`]: from those arrays alone, the actuator's frequency response (H1, coherence), its
//!    gain and delay, the lead filter and ATS initial values, and the specimen's stiffness; then
//!    the checks that refuse a poor characterization.
//! 4. [`rig_file`]: the versioned, validated rig file; [`figure`]: its frequency-response figure.
//!
//! How no simulator value can leak in: [`estimate`] takes only `&[f64]` arrays of the record, and
//! [`runner::run`] touches the rig only through `Daq::read` and `Actuator::command` (plus the
//! caller's "next tick", which on the virtual rig advances the plant). `docs/identify.md` has the
//! derivations and the measured figures.
//!
//! [`Supervisor`]: rths_core::supervisor::Supervisor

pub mod error;
pub mod estimate;
pub mod excitation;
pub mod figure;
pub mod rig_file;
pub mod runner;

use rths_core::compensator::LEAD_MAX_STRIDE;
use rths_core::params::DT_S;
use rths_core::supervisor::Limits;
use rths_hal_sim::{FaultPlan, RigConfig, VirtualRig};

pub use error::IdentifyError;
pub use estimate::{Characterization, Design, Signals};
pub use excitation::{Excitation, ExcitationConfig};
pub use rig_file::RigFile;
pub use runner::IdentificationRecord;

/// The settings of one identification.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifyConfig {
    /// The excitation.
    pub excitation: ExcitationConfig,
    /// Lead-filter tap spacing, ticks.
    pub lead_stride: usize,
    /// Low-pass of the stiffness fit, Hz.
    pub stiffness_cutoff_hz: f64,
}

impl Default for IdentifyConfig {
    /// [`ExcitationConfig::new`] at the controller's tick; lead stride 8, whose span (7·8 ticks =
    /// 27 ms) covers the slowest preset's 25 ms delay (measured: LRX on El Centro and Kobe, median
    /// NRMSE 2.38% on `benchmark` and 0.70% on `unr-compact` against 2.46% and 0.71% at stride 6);
    /// and a 30 Hz stiffness low-pass (1.5× the band: the band passes, the noise above does not).
    fn default() -> Self {
        Self::at_tick(DT_S)
    }
}

impl IdentifyConfig {
    /// The defaults at another tick `dt_s` (e.g. the vRTHS benchmark's 4096 Hz): the same
    /// excitation in seconds and hertz, the lead's span kept in seconds as far as
    /// [`LEAD_MAX_STRIDE`] allows (at 4096 Hz stride 8 spans 13.7 ms, not 27 ms: the residual
    /// delay is left to the lead's online correction). At the controller's tick this is
    /// [`IdentifyConfig::default`], bit for bit.
    pub fn at_tick(dt_s: f64) -> Self {
        // 8 ticks at the controller's tick, in seconds, rounded to whole ticks of dt_s.
        let stride = (8.0 * DT_S / dt_s)
            .round()
            .clamp(1.0, LEAD_MAX_STRIDE as f64) as usize;
        Self {
            excitation: ExcitationConfig::new(dt_s),
            lead_stride: stride,
            stiffness_cutoff_hz: 30.0,
        }
    }

    /// What the estimators need to know of an excitation.
    pub fn design(&self, e: &Excitation) -> Design {
        Design {
            window_start: e.window_start,
            period_ticks: e.period_ticks,
            periods: e.config.periods,
            lines: e.lines.clone(),
            lead_stride: self.lead_stride,
            stiffness_cutoff_hz: self.stiffness_cutoff_hz,
        }
    }
}

/// A finished identification: the excitation, the record and what was identified.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The excitation played.
    pub excitation: Excitation,
    /// The measured record.
    pub record: IdentificationRecord,
    /// What was identified.
    pub identification: Characterization,
}

/// Identify on any rig: generate, run under the paper actuator's limits at the excitation's tick
/// ([`limits_at`]), estimate.
pub fn identify_rig<R, A, F>(
    rig: &mut R,
    cfg: &IdentifyConfig,
    next_tick: F,
) -> Result<Outcome, IdentifyError>
where
    R: rths_core::hal::Daq<Error = A> + rths_core::hal::Actuator<Error = A>,
    A: rths_core::hal::Error,
    F: FnMut(&mut R),
{
    identify_rig_with_limits(rig, cfg, limits_at(cfg.excitation.dt_s)?, next_tick)
}

/// [`identify_rig`] under the given supervisor limits.
pub fn identify_rig_with_limits<R, A, F>(
    rig: &mut R,
    cfg: &IdentifyConfig,
    limits: Limits,
    next_tick: F,
) -> Result<Outcome, IdentifyError>
where
    R: rths_core::hal::Daq<Error = A> + rths_core::hal::Actuator<Error = A>,
    A: rths_core::hal::Error,
    F: FnMut(&mut R),
{
    let excitation = excitation::generate(&cfg.excitation)?;
    let record = runner::run(rig, &excitation, limits, next_tick)?;
    let sig = Signals {
        dt_s: record.dt_s,
        command_mm: &record.command_mm,
        measured_mm: &record.measured_mm,
        force_kn: &record.force_kn,
    };
    let identification = estimate::identify(sig, &cfg.design(&excitation))?;
    Ok(Outcome {
        excitation,
        record,
        identification,
    })
}

/// The paper actuator's limits ([`Limits::paper_actuator`]) with their per-tick steps at `dt_s`
/// (the limits are rates; their steps scale with the tick). At the controller's tick, exactly
/// [`Limits::paper_actuator`].
pub fn limits_at(dt_s: f64) -> Result<Limits, IdentifyError> {
    let p = Limits::paper_actuator();
    if dt_s == DT_S {
        return Ok(p);
    }
    // The sensor timeout and overrun counts stay in ticks (8 and 4, as the paper actuator's).
    Limits::new(
        p.stroke_mm(),
        p.velocity_mm_s(),
        p.force_kn(),
        8,
        4,
        p.fault_ramp_rate_mm_s(),
        p.end_ramp_rate_mm_s(),
        dt_s,
    )
    .and_then(|l| l.with_following_error_mm(p.following_error_mm()))
    .map_err(|e| IdentifyError::Setting(format!("supervisor limits at dt {dt_s} s: {e:?}")))
}

/// Identify on the virtual rig of `rig` with `faults`; its clock is `advance_tick`, nothing else of
/// the simulator is read.
pub fn identify_virtual(
    rig: &RigConfig,
    faults: FaultPlan,
    cfg: &IdentifyConfig,
) -> Result<Outcome, IdentifyError> {
    let params = rig
        .build()
        .map_err(|e| IdentifyError::Plant(e.to_string()))?;
    let mut vr = VirtualRig::with_faults(params, faults);
    identify_rig(&mut vr, cfg, |r| r.advance_tick())
}

//! Soak test: a long `lr-online` run against the virtual plant with sensor noise, to show that nothing
//! drifts, no value goes non-finite and the error stays bounded over an hour of test time.
//!
//! The ground motion is the El Centro record played again and again, each time followed by a quiet
//! gap that pads the cycle to 60 s (the 2%-damped structure's free vibration decays by e^-8.6 in
//! it), so one hour is 60 cycles: 7 372 800 ticks at 2048 Hz. The reference is the pure FE response
//! of one cycle from rest, tiled; [`SoakReport::reference_tiling_error_mm`] measures what tiling
//! costs (the residue of the previous cycle).
//!
//! Statistics are taken per window (10 min for the hour): mean command, RMS and peak of
//! target − reference, RMS of measured − command (tracking), peak |target| (the LR's state).

use rths_core::params::DT_S;
use rths_hal_sim::{Preset, Specimen};
use serde::Serialize;

use crate::machinery::model_file::ModelFile;
use crate::machinery::motion::GroundMotion;
use crate::studies::faults::FaultsError;
use crate::studies::scenario::{self, Injection, ScenarioId, ScenarioSetup, TickRow};

/// One cycle of the soak motion, s (the record plus a quiet gap).
pub const CYCLE_S: f64 = 60.0;
/// Ticks in one hour of test time.
pub const HOUR_TICKS: usize = 7_372_800;

/// Statistics of one window of the run.
#[derive(Debug, Clone, Serialize)]
pub struct Window {
    /// Window start, s.
    pub start_s: f64,
    /// Mean command, mm.
    pub mean_command_mm: f64,
    /// RMS of target − reference, mm.
    pub rms_error_mm: f64,
    /// Peak |target − reference|, mm.
    pub peak_error_mm: f64,
    /// RMS of measured − command, mm (the actuator's tracking, noise and delay included).
    pub rms_tracking_mm: f64,
    /// Peak |target| (the LR's state), mm.
    pub peak_target_mm: f64,
    /// Peak |command|, mm.
    pub peak_command_mm: f64,
}

/// The figures of a soak run.
#[derive(Debug, Clone, Serialize)]
pub struct SoakReport {
    /// Ticks run.
    pub ticks: usize,
    /// Test time, s.
    pub duration_s: f64,
    /// The supervisor's stop (reason, time), if it tripped.
    pub stop: Option<(String, f64)>,
    /// Non-finite targets, commands or measurements seen.
    pub non_finite: u64,
    /// Per-window statistics, in time order.
    pub windows: Vec<Window>,
    /// Largest |Δ| between the second and the first cycle of the pure reference, mm.
    pub reference_tiling_error_mm: f64,
    /// Sensor noise σ of the run: LVDT mm, load cell kN.
    pub noise: (f64, f64),
}

impl SoakReport {
    /// Last window's RMS error over the first's.
    pub fn error_growth(&self) -> f64 {
        match (self.windows.first(), self.windows.last()) {
            (Some(a), Some(b)) if a.rms_error_mm > 0.0 => b.rms_error_mm / a.rms_error_mm,
            _ => f64::NAN,
        }
    }
}

#[derive(Default)]
struct Acc {
    n: u64,
    sum_cmd: f64,
    sum_err2: f64,
    peak_err: f64,
    sum_track2: f64,
    peak_target: f64,
    peak_cmd: f64,
}

impl Acc {
    fn window(&self, start_s: f64) -> Window {
        let n = self.n.max(1) as f64;
        Window {
            start_s,
            mean_command_mm: self.sum_cmd / n,
            rms_error_mm: (self.sum_err2 / n).sqrt(),
            peak_error_mm: self.peak_err,
            rms_tracking_mm: (self.sum_track2 / n).sqrt(),
            peak_target_mm: self.peak_target,
            peak_command_mm: self.peak_cmd,
        }
    }
}

/// Run `lr-online` (shipped LR model, `unr-compact`, linear specimen, default sensor noise, `seed`)
/// for `ticks`, with statistics per `window_ticks`.
pub fn run(ticks: usize, window_ticks: usize, seed: u64) -> Result<SoakReport, FaultsError> {
    let record = GroundMotion::el_centro().resample_mm_s2(DT_S);
    let cycle = (CYCLE_S / DT_S).round() as usize;
    let mut one = record.clone();
    one.resize(cycle.max(record.len()), 0.0);
    let cycle = one.len();
    let two: Vec<f64> = one.iter().chain(one.iter()).copied().collect();
    let ref_two = crate::studies::study::reference_mm(&two, 1.0)
        .map_err(|e| FaultsError::Reference(e.to_string()))?;
    let tiling = ref_two[..cycle]
        .iter()
        .zip(&ref_two[cycle..])
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let ag: Vec<f64> = one.iter().cycle().take(ticks).copied().collect();
    let reference: Vec<f64> = ref_two[..cycle]
        .iter()
        .cycle()
        .take(ticks)
        .copied()
        .collect();

    let model = ModelFile::from_json(include_str!("../../data/models/lr.json"))
        .map_err(|e| FaultsError::Model(e.to_string()))?;
    let lr = crate::machinery::models::lr_params(&model)
        .map_err(|e| FaultsError::Model(e.to_string()))?;
    let rig =
        crate::machinery::reference::rig_config(Preset::UnrCompact, Specimen::Linear, 1.0, seed);
    let noise = (rig.sensors.disp_noise_mm, rig.sensors.force_noise_kn);
    let setup = ScenarioSetup {
        id: ScenarioId::LrOnline,
        ground_accel_mm_s2: &ag,
        reference_mm: &reference,
        rig,
        stiffness_factor: 1.0,
        lr: Some(lr),
        rnn: None,
        lrx: None,
        delay_steps: model.delay_steps,
    };
    let window_ticks = window_ticks.max(1);
    let mut windows = Vec::new();
    let mut acc = Acc::default();
    let mut non_finite = 0u64;
    let stop = scenario::simulate_observed(&setup, &Injection::default(), |r: &TickRow| {
        if !(r.target_mm.is_finite() && r.command_mm.is_finite() && r.measured_mm.is_finite()) {
            non_finite += 1;
        }
        let e = r.target_mm - r.reference_mm;
        let tr = r.measured_mm - r.command_mm;
        acc.n += 1;
        acc.sum_cmd += r.command_mm;
        acc.sum_err2 += e * e;
        acc.peak_err = acc.peak_err.max(e.abs());
        acc.sum_track2 += tr * tr;
        acc.peak_target = acc.peak_target.max(r.target_mm.abs());
        acc.peak_cmd = acc.peak_cmd.max(r.command_mm.abs());
        if (r.k + 1) % window_ticks == 0 {
            windows.push(acc.window((r.k + 1 - window_ticks) as f64 * DT_S));
            acc = Acc::default();
        }
    })?;
    if acc.n > 0 {
        windows.push(acc.window((ticks - acc.n as usize) as f64 * DT_S));
    }
    Ok(SoakReport {
        ticks,
        duration_s: ticks as f64 * DT_S,
        stop,
        non_finite,
        windows,
        reference_tiling_error_mm: tiling,
        noise,
    })
}

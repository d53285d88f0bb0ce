//! Evaluation of a trained nonlinear metamodel against the FE reference (evaluation only: it knows
//! the true structure): the pure loop on a record at a scale, its NRMSE at the specimen's DOF, the
//! peak ductility and residual drift of both, and the error of the first seconds against the rest
//! (a model that rings at start-up shows there).

use rths_core::metamodel::ModalHyst;
use rths_files::nl_model_file::NlModelFile;
use rths_files::structure_file::Structure;

use crate::machinery::motion::GroundMotion;
use crate::machinery::structure::ResidualTail;
use crate::machinery::train::nonlinear::runs::{fe_run, pure_loop, FeRun};
use crate::machinery::train::TrainError;

/// The start-up stretch compared with the rest, s.
pub const STARTUP_S: f64 = 2.0;

/// One evaluated run.
#[derive(Debug, Clone)]
pub struct EvalRow {
    /// `record:scale`.
    pub label: String,
    /// Peak ductility of the FE reference and of the model (the true yield drifts).
    pub ductility_ref: f64,
    /// As above, the model's.
    pub ductility_model: f64,
    /// Pure-loop NRMSE at the specimen's DOF over the record and the free vibration, %.
    pub nrmse_pct: f64,
    /// Residual drift of each story, FE reference, mm.
    pub residual_ref_mm: Vec<f64>,
    /// How much each story of the reference still swings over the residual window, mm
    /// (peak-to-peak).
    pub residual_ref_swing_mm: Vec<f64>,
    /// Residual drift of each story, model, mm.
    pub residual_model_mm: Vec<f64>,
    /// RMS error over the first [`STARTUP_S`] and over the rest, % of the reference's peak.
    pub startup_rms_pct: f64,
    /// See above.
    pub rest_rms_pct: f64,
}

/// Evaluate `file` on `structure` under `motion × scale` at `dt_s`.
pub fn evaluate(
    file: &NlModelFile,
    structure: &Structure,
    motion: &GroundMotion,
    scale: f64,
    dt_s: f64,
) -> Result<EvalRow, TrainError> {
    let run = fe_run(structure, motion, scale, dt_s)?;
    evaluate_run(file, structure, &run, dt_s)
}

/// Evaluate `file` on an FE run.
pub fn evaluate_run(
    file: &NlModelFile,
    structure: &Structure,
    run: &FeRun,
    dt_s: f64,
) -> Result<EvalRow, TrainError> {
    let p = file
        .params(dt_s)
        .map_err(|e| TrainError::Setting(format!("model file: {e}")))?;
    let mut m = ModalHyst::new(p);
    let x = pure_loop(
        &mut m,
        file.specimen_stiffness_kn_per_mm,
        &run.ground_accel_mm_s2,
    )
    .ok_or_else(|| TrainError::Diverged(format!("the model diverged on {}", run.label)))?;
    let s = file.specimen_dof;
    let (xm, xr) = match (x.get(s), run.floor_disp_mm.get(s)) {
        (Some(a), Some(b)) => (a, b),
        _ => return Err(TrainError::Setting("specimen DOF past the floors".into())),
    };
    let nrmse_pct = rths_core::metrics::nrmse_pct(xm, xr)?;
    let peak = xr.iter().fold(0.0_f64, |a, v| a.max(v.abs())).max(1e-12);
    let split = ((STARTUP_S / dt_s) as usize).min(xr.len());
    let rms = |a: &[f64], b: &[f64]| {
        let n = a.len().max(1) as f64;
        100.0 * (a.iter().zip(b).map(|(p, q)| (p - q) * (p - q)).sum::<f64>() / n).sqrt() / peak
    };
    let drifts = |floors: &[Vec<f64>]| -> Vec<Vec<f64>> {
        floors
            .iter()
            .enumerate()
            .map(
                |(i, f)| match i.checked_sub(1).and_then(|j| floors.get(j)) {
                    Some(below) => f.iter().zip(below).map(|(a, b)| a - b).collect(),
                    None => f.clone(),
                },
            )
            .collect()
    };
    let (dm, dr) = (drifts(&x), drifts(&run.floor_disp_mm));
    let uy: Vec<f64> = structure
        .story_laws()
        .map(|l| l.iter().map(|l| l.yield_drift_mm()).collect())
        .unwrap_or_default();
    let ductility = |d: &[Vec<f64>]| {
        d.iter()
            .zip(&uy)
            .map(|(d, u)| d.iter().fold(0.0_f64, |a, v| a.max(v.abs())) / u)
            .fold(0.0, f64::max)
    };
    let tails = |d: &[Vec<f64>]| -> Vec<ResidualTail> {
        d.iter().map(|d| ResidualTail::of(d, dt_s)).collect()
    };
    let (tr, tm) = (tails(&dr), tails(&dm));
    Ok(EvalRow {
        label: run.label.clone(),
        ductility_ref: ductility(&dr),
        ductility_model: ductility(&dm),
        nrmse_pct,
        residual_ref_mm: tr.iter().map(|t| t.mean_mm).collect(),
        residual_ref_swing_mm: tr.iter().map(|t| t.swing_mm).collect(),
        residual_model_mm: tm.iter().map(|t| t.mean_mm).collect(),
        startup_rms_pct: rms(&xm[..split], &xr[..split]),
        rest_rms_pct: rms(&xm[split..], &xr[split..]),
    })
}

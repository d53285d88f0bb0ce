//! The runs the nonlinear metamodel is trained and scored on: FE reference runs of the whole
//! yielding structure at a scale found for a target peak ductility, and the model's pure loop on
//! the same ground motion (the specimen force is the linear specimen at the model's own target,
//! as inside the FE reference).

use rayon::prelude::*;
use rths_core::metamodel::ModalHyst;
use rths_files::structure_file::Structure;

use crate::machinery::motion::GroundMotion;
use crate::machinery::structure::fe_reference;
use crate::machinery::train::TrainError;

/// One FE run: the input and the floors' displacements it gives.
#[derive(Debug, Clone)]
pub struct FeRun {
    /// `record:scale`.
    pub label: String,
    /// The record's name.
    pub record: String,
    /// The scale of the record.
    pub scale: f64,
    /// The FE run's peak ductility.
    pub ductility: f64,
    /// Ground acceleration over the record and the free vibration, mm/s².
    pub ground_accel_mm_s2: Vec<f64>,
    /// `floor_disp_mm[floor][step]`.
    pub floor_disp_mm: Vec<Vec<f64>>,
    /// Steps of the record itself.
    pub record_steps: usize,
    /// Each story's residual drift, mm.
    pub residual_drift_mm: Vec<f64>,
    /// The FE's story drifts, `story_drift_mm[story][step]`, mm: with [`Self::story_force_kn`]
    /// the lab's own numerical model's output that stage 1 of the training fits each spring to.
    pub story_drift_mm: Vec<Vec<f64>>,
    /// The FE's numerical story forces (the specimen's not included), `[story][step]`, kN.
    pub story_force_kn: Vec<Vec<f64>>,
}

fn to_err(e: anyhow::Error) -> TrainError {
    TrainError::Diverged(format!("FE reference: {e:#}"))
}

/// The FE reference of `structure` under `motion × scale` at `dt_s`, with the free vibration.
pub fn fe_run(
    structure: &Structure,
    motion: &GroundMotion,
    scale: f64,
    dt_s: f64,
) -> Result<FeRun, TrainError> {
    let ag = motion.scaled(scale).resample_mm_s2(dt_s);
    let r = fe_reference(structure, &ag, dt_s).map_err(to_err)?;
    let n = r.story_drift_mm.len();
    let steps = r.time_s.len();
    let mut floors = vec![Vec::with_capacity(steps); n];
    for k in 0..steps {
        let mut x = 0.0;
        for (f, d) in floors.iter_mut().zip(&r.story_drift_mm) {
            x += d[k];
            f.push(x);
        }
    }
    Ok(FeRun {
        label: format!("{}:{}", motion.name, fmt_scale(scale)),
        record: motion.name.clone(),
        scale,
        ductility: r.peak_ductility(),
        ground_accel_mm_s2: r.ground_accel_mm_s2.clone(),
        floor_disp_mm: floors,
        record_steps: r.record_steps,
        residual_drift_mm: r.residual_drift_mm(dt_s),
        story_drift_mm: r.story_drift_mm,
        story_force_kn: r.story_force_kn,
    })
}

/// A scale printed with 4 significant digits (the file records it).
pub fn fmt_scale(s: f64) -> String {
    format!("{:.4}", s)
}

/// The scale of `motion` whose FE run reaches `ductility` (bisection on the log of the scale over
/// [1e-3, 1e3], to 4 decimals).
pub fn scale_for_ductility(
    structure: &Structure,
    motion: &GroundMotion,
    ductility: f64,
    dt_s: f64,
) -> Result<f64, TrainError> {
    let mu = |s: f64| -> Result<f64, TrainError> {
        let ag = motion.scaled(s).resample_mm_s2(dt_s);
        Ok(fe_reference(structure, &ag, dt_s)
            .map_err(to_err)?
            .peak_ductility())
    };
    let (mut lo, mut hi) = (1e-3_f64.ln(), 1e3_f64.ln());
    for _ in 0..18 {
        let mid = 0.5 * (lo + hi);
        if mu(mid.exp())? < ductility {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let s = (0.5 * (lo + hi)).exp();
    // Round so the file and the log name the scale that was run.
    fmt_scale(s)
        .parse::<f64>()
        .map_err(|e| TrainError::Setting(format!("scale: {e}")))
}

/// FE runs of every `(record, ductility)` pair, in parallel, in the order given.
pub fn fe_runs_for_ductilities(
    structure: &Structure,
    records: &[GroundMotion],
    ductilities: &[f64],
    dt_s: f64,
) -> Result<Vec<FeRun>, TrainError> {
    let jobs: Vec<(&GroundMotion, f64)> = records
        .iter()
        .flat_map(|m| ductilities.iter().map(move |d| (m, *d)))
        .collect();
    jobs.par_iter()
        .map(|(m, d)| {
            let s = scale_for_ductility(structure, m, *d, dt_s)?;
            fe_run(structure, m, s, dt_s)
        })
        .collect()
}

/// The model's pure loop over `ground_accel_mm_s2` (reset at its first sample, as the FE): the
/// specimen's force is `k_e` times the model's own target. `floor_disp_mm[floor][step]`, or
/// `None` if the model refused a step (it diverged).
pub fn pure_loop(
    model: &mut ModalHyst,
    specimen_k_kn_per_mm: f64,
    ground_accel_mm_s2: &[f64],
) -> Option<Vec<Vec<f64>>> {
    let floors = model.params().floors();
    let mut out = vec![Vec::with_capacity(ground_accel_mm_s2.len()); floors];
    model.reset_at(ground_accel_mm_s2.first().copied().unwrap_or(0.0));
    let mut target = model.target_mm();
    for (k, &ag) in ground_accel_mm_s2.iter().enumerate() {
        if k > 0 {
            target = model.step(ag, specimen_k_kn_per_mm * target).ok()?;
        }
        for (i, f) in out.iter_mut().enumerate() {
            f.push(model.floor_disp_mm(i));
        }
    }
    Some(out)
}

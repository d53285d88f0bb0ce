//! Nonlinear numerical substructures from structure files with a `hysteresis` section: the FE
//! reference response (the whole yielding structure under a ground motion, Chang's explicit step
//! with the story forces evaluated each step), its peak ductility and residual drift, and the
//! hysteresis plot (`rths analyze --structure`; docs/nonlinear.md). With them what a structure
//! file's runs are built from: its learned model ([`model`]) and the rig compensation of its hybrid
//! runs ([`rig`]). The scenarios and the study are `crate::studies::nonlinear`.

pub mod model;
pub mod plot;
pub mod rig;

use anyhow::Context;
use rths_core::metrics::nrmse_pct;
use rths_core::structure_n::{ChangN, MAX_DOF};
use rths_files::structure_file::Structure;

/// Free vibration appended to every record so the frame comes to rest and its residual drift is
/// defined, s.
pub const FREE_VIBRATION_S: f64 = 10.0;
/// The residual drift is the mean drift over this last stretch of the free vibration, s.
pub const RESIDUAL_WINDOW_S: f64 = 2.0;

/// The response of a nonlinear structure, one row per step.
#[derive(Debug, Clone, Default)]
pub struct NlResponse {
    /// Time, s.
    pub time_s: Vec<f64>,
    /// Ground acceleration, mm/s².
    pub ground_accel_mm_s2: Vec<f64>,
    /// Story drifts, mm: `story_drift_mm[story][step]`.
    pub story_drift_mm: Vec<Vec<f64>>,
    /// The numerical (yielding) story forces, kN: `story_force_kn[story][step]`.
    pub story_force_kn: Vec<Vec<f64>>,
    /// Yield drift of each story, mm.
    pub yield_drift_mm: Vec<f64>,
    /// Steps of the record itself (the rest is free vibration).
    pub record_steps: usize,
}

impl NlResponse {
    /// Peak `|drift| / u_y` over stories and time.
    pub fn peak_ductility(&self) -> f64 {
        self.story_drift_mm
            .iter()
            .zip(&self.yield_drift_mm)
            .map(|(d, uy)| d.iter().fold(0.0_f64, |m, v| m.max(v.abs())) / uy)
            .fold(0.0, f64::max)
    }

    /// Residual drift of each story: the mean over the last [`RESIDUAL_WINDOW_S`], mm.
    pub fn residual_drift_mm(&self, dt_s: f64) -> Vec<f64> {
        let w = ((RESIDUAL_WINDOW_S / dt_s) as usize).max(1);
        self.story_drift_mm
            .iter()
            .map(|d| {
                let tail = &d[d.len().saturating_sub(w)..];
                tail.iter().sum::<f64>() / tail.len().max(1) as f64
            })
            .collect()
    }

    /// Peak `|force|` of each numerical story, kN.
    pub fn peak_story_force_kn(&self) -> Vec<f64> {
        self.story_force_kn
            .iter()
            .map(|f| f.iter().fold(0.0_f64, |m, v| m.max(v.abs())))
            .collect()
    }
}

/// The whole nonlinear structure under `ground_accel_mm_s2` (sampled at `dt_s`) followed by
/// [`FREE_VIBRATION_S`] at rest: the FE reference. Evaluation only (it knows the true structure).
pub fn fe_reference(
    structure: &Structure,
    ground_accel_mm_s2: &[f64],
    dt_s: f64,
) -> anyhow::Result<NlResponse> {
    let mut frame = structure
        .nonlinear_whole(dt_s)
        .with_context(|| format!("structure {}", structure.name()))?;
    let n = frame.dofs();
    let free = (FREE_VIBRATION_S / dt_s) as usize;
    let total = ground_accel_mm_s2.len() + free;
    let ag = |i: usize| ground_accel_mm_s2.get(i).copied().unwrap_or(0.0);
    let mut r = NlResponse {
        time_s: Vec::with_capacity(total),
        ground_accel_mm_s2: Vec::with_capacity(total),
        story_drift_mm: vec![Vec::with_capacity(total); n],
        story_force_kn: vec![Vec::with_capacity(total); n],
        yield_drift_mm: frame
            .stories()
            .iter()
            .flatten()
            .map(|s| s.law().yield_drift_mm())
            .collect(),
        record_steps: ground_accel_mm_s2.len(),
    };
    frame.reset(ag(0));
    let zero = [0.0; MAX_DOF];
    for i in 0..total {
        if i > 0 {
            frame.advance(ag(i), &zero);
        }
        r.time_s.push(i as f64 * dt_s);
        r.ground_accel_mm_s2.push(ag(i));
        let d = frame.story_drift_mm();
        for (j, (dr, fr)) in r
            .story_drift_mm
            .iter_mut()
            .zip(&mut r.story_force_kn)
            .enumerate()
        {
            dr.push(d[j]);
            fr.push(frame.story_force_kn()[j]);
        }
    }
    if r.story_drift_mm.iter().flatten().any(|v| !v.is_finite()) {
        anyhow::bail!("the nonlinear response diverged (non-finite drift)");
    }
    Ok(r)
}

/// Story drifts of the *elastic* whole structure (every story at its initial stiffness, Chang's
/// linear path) over the same steps as `r`: what a linear numerical substructure, or a linear
/// metamodel fitted to one, would give. `story_drift_mm[story][step]`.
pub fn elastic_drifts(
    structure: &Structure,
    r: &NlResponse,
    dt_s: f64,
) -> anyhow::Result<Vec<Vec<f64>>> {
    let mut lin = ChangN::new(structure.whole()?, dt_s)?;
    let n = structure.dofs();
    let mut out = vec![Vec::with_capacity(r.time_s.len()); n];
    lin.reset(r.ground_accel_mm_s2.first().copied().unwrap_or(0.0));
    let zero = [0.0; MAX_DOF];
    for (i, &ag) in r.ground_accel_mm_s2.iter().enumerate() {
        if i > 0 {
            lin.advance(ag, &zero);
        }
        let mut below = 0.0;
        for (story, x) in out.iter_mut().zip(lin.disp()) {
            story.push(x - below);
            below = *x;
        }
    }
    Ok(out)
}

/// NRMSE (%) of each story's drift in `drifts` against the nonlinear reference `r`.
pub fn drift_nrmse_pct(drifts: &[Vec<f64>], r: &NlResponse) -> anyhow::Result<Vec<f64>> {
    drifts
        .iter()
        .zip(&r.story_drift_mm)
        .map(|(x, x_ref)| nrmse_pct(x, x_ref).map_err(|e| anyhow::anyhow!("NRMSE: {e:?}")))
        .collect()
}

//! Scoring a learned model of either form against a lab's held-out runs (evaluation only: the
//! held-out histories are read here and never by the training): the pure loop (the model with the
//! stand-in specimen) and the hybrid loop (core's controller on the virtual rig, with the rig's
//! identified lead and force correction: `nl-online`), each at the interface and every floor, and
//! the residual drift of the story with the largest reference residual (where the reference has
//! come to rest). The hybrid loop's
//! interface is the displacement the rig was *measured* to impose (prototype scale), not the
//! model's own target: that is what the specimen went through; its other floors are the model's.

use anyhow::Context;
use rths_core::compensator::{Compensator, Lead};
use rths_core::metrics;
use rths_core::params::{SpecimenScale, DT_S};
use rths_hal_sim::{Preset, RigConfig};

use crate::machinery::imported::fe::FeHistory;
use crate::machinery::structure::rig;
pub use crate::machinery::structure::ResidualJudgement;
use crate::machinery::train::nonlinear::floors::{residual_tails, FloorRun};
use crate::machinery::train::nonlinear::score::{length_scale, loop_score, Learned, LoopScore};
use crate::studies::imported_hybrid::{self, Compensation};

/// A held-out run's figures.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RunScore {
    /// The history's file name.
    pub label: String,
    /// The reference's peak interface displacement, mm.
    pub peak_interface_mm: f64,
    /// The reference's residual drifts, mm.
    pub residual_ref_mm: Vec<f64>,
    /// How much the reference still swings over the residual window, story by story, mm
    /// (peak-to-peak).
    pub residual_ref_swing_mm: Vec<f64>,
    /// The pure loop.
    pub pure: LoopScore,
    /// The hybrid loop (`None`: not run).
    pub hybrid: Option<LoopScore>,
    /// The length scale of the hybrid run.
    pub length_scale: f64,
}

impl RunScore {
    /// The residual-drift error of `l` at the story with the largest reference residual, % of it,
    /// where that residual is 0.1 mm or more and the reference has come to rest.
    pub fn residual_error(&self, l: &LoopScore) -> ResidualJudgement {
        ResidualJudgement::of(
            &self.residual_ref_mm,
            &self.residual_ref_swing_mm,
            &l.residual_mm,
        )
    }
}

/// The rig a hybrid run of a structure whose specimen is `k_e` uses, and the identified
/// compensation (once per study: a lab identifies its rig before it tests).
pub struct HybridRig {
    preset: Preset,
    config: RigConfig,
    comp: rig::RigCompensation,
}

impl HybridRig {
    /// `preset` with the paper's brace, sensor noise `seed`, identified now.
    pub fn identified(name: &str, preset: Preset, seed: u64) -> anyhow::Result<Self> {
        let (config, factor) = imported_hybrid::rig_of(preset, seed, false);
        let comp = rig::identify_rig(name, &config, factor)?;
        Ok(Self {
            preset,
            config,
            comp,
        })
    }
}

/// Score `model` (specimen nominal stiffness `k_e`) on the held-out `run`: the pure loop, and the
/// hybrid loop on `rig` if given.
pub fn score_run(
    model: &Learned,
    k_e: f64,
    run: &FloorRun,
    rig: Option<&HybridRig>,
) -> anyhow::Result<RunScore> {
    let (sf, _) = model.specimen();
    let ag = &run.ground_accel_mm_s2;
    let pure_floors = model
        .pure_loop(k_e, ag)
        .with_context(|| format!("the {} model diverged on {}", model.form(), run.label))?;
    let pure = loop_score(&pure_floors, run, sf);
    let (hybrid, length) = match rig {
        None => (None, length_scale(&pure_floors[sf])),
        Some(r) => {
            let (h, measured, stop, length) = run_hybrid_measured(model, k_e, ag, r)?;
            let mut cols: Vec<Vec<f64>> = (0..pure_floors.len())
                .map(|i| {
                    h.outputs_mm
                        .iter()
                        .map(|o| o.get(i).copied().unwrap_or(f64::NAN))
                        .collect()
                })
                .collect();
            let own = cols.get(sf).and_then(|c| {
                let n = c.len().min(run.floor_disp_mm[sf].len());
                metrics::nrmse_pct(&c[..n], &run.floor_disp_mm[sf][..n]).ok()
            });
            // The specimen's floor is what the rig imposed.
            if let Some(c) = cols.get_mut(sf) {
                *c = measured;
            }
            let mut s = loop_score(&cols, run, sf);
            s.stopped = stop;
            s.model_interface_nrmse_pct = own;
            (Some(s), length)
        }
    };
    let tails = residual_tails(&run.floor_disp_mm, DT_S);
    Ok(RunScore {
        label: run.label.clone(),
        peak_interface_mm: metrics::peak_abs(&run.floor_disp_mm[sf]),
        residual_ref_mm: tails.iter().map(|t| t.mean_mm).collect(),
        residual_ref_swing_mm: tails.iter().map(|t| t.swing_mm).collect(),
        pure,
        hybrid,
        length_scale: length,
    })
}

/// The hybrid loop of `model` (specimen nominal `k_e`) under `ag` on `rig`, at the length scale a
/// lab would choose from the model's own pure-loop prediction: the model's floors at each tick
/// (columns `floor_<i>`), why it stopped if it did, and the length scale.
pub fn run_hybrid(
    model: &Learned,
    k_e: f64,
    ag: &[f64],
    rig: &HybridRig,
) -> anyhow::Result<(FeHistory, Option<String>, f64)> {
    let (h, _, stop, length) = run_hybrid_measured(model, k_e, ag, rig)?;
    Ok((h, stop, length))
}

/// [`run_hybrid`], with the interface displacement the rig was measured to impose at each tick
/// (prototype scale, mm).
pub fn run_hybrid_measured(
    model: &Learned,
    k_e: f64,
    ag: &[f64],
    rig: &HybridRig,
) -> anyhow::Result<(FeHistory, Vec<f64>, Option<String>, f64)> {
    let (sf, _) = model.specimen();
    let pure = model
        .pure_loop(k_e, ag)
        .with_context(|| format!("the {} model diverged", model.form()))?;
    let length = length_scale(&pure[sf]);
    let rig_k = RigConfig::new(rig.preset).specimen_stiffness_kn_per_mm;
    let scale = SpecimenScale::new(length, k_e * length / rig_k)
        .map_err(|e| anyhow::anyhow!("specimen scale: {e:?}"))?;
    let c = &rig.comp.corrected_lead;
    let floors = pure.len();
    let (online, stop) = imported_hybrid::run_online(
        scale,
        model.analytical(),
        Compensation {
            compensator: Compensator::Lead(Lead::new(c.lead)),
            correction: c.correction,
        },
        &rig.config,
        ag,
        // The part's own read-outs: its floors, and the specimen's floor as the interface.
        (0..floors).map(|i| format!("floor_{i}")).collect(),
    )?;
    Ok((
        online.model,
        online.measured_mm,
        stop.map(|(why, t)| format!("{why} at {t:.2} s")),
        length,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scored(ref_mm: [f64; 2], swing_mm: [f64; 2], model_mm: [f64; 2]) -> (RunScore, LoopScore) {
        let l = LoopScore {
            interface_nrmse_pct: Some(1.0),
            model_interface_nrmse_pct: None,
            floor_nrmse_pct: vec![Some(1.0); 2],
            residual_mm: model_mm.to_vec(),
            stopped: None,
        };
        let r = RunScore {
            label: "run".into(),
            peak_interface_mm: 40.0,
            residual_ref_mm: ref_mm.to_vec(),
            residual_ref_swing_mm: swing_mm.to_vec(),
            pure: l.clone(),
            hybrid: None,
            length_scale: 1.0,
        };
        (r, l)
    }

    #[test]
    fn the_residual_is_judged_at_the_largest_story_once_at_rest() {
        // Story 2 holds the larger residual (10 mm), at rest: the model's 12 mm is 20 % off.
        let (r, l) = scored([0.5, -10.0], [0.4, 1.0], [0.0, -12.0]);
        let ResidualJudgement::Judged(p) = r.residual_error(&l) else {
            panic!("{:?}", r.residual_error(&l));
        };
        assert!((p - 20.0).abs() < 1e-9, "{p}");
        // The story the evaluation's table names (the second, by magnitude, not by sign).
        assert_eq!(ResidualJudgement::story(&r.residual_ref_mm), Some(1));
        assert_eq!(ResidualJudgement::story(&[]), None);
        // The same run still swinging 5 mm about its 10 mm: no figure, and why.
        let (r, l) = scored([0.5, -10.0], [0.4, 5.0], [0.0, -12.0]);
        assert_eq!(
            r.residual_error(&l),
            ResidualJudgement::NotAtRest {
                residual_mm: -10.0,
                swing_mm: 5.0
            }
        );
        assert_eq!(r.residual_error(&l).pct(), None);
        // A run that comes back under 0.1 mm: nothing to judge.
        let (r, l) = scored([0.05, -0.08], [0.0, 0.0], [1.0, 1.0]);
        assert_eq!(r.residual_error(&l), ResidualJudgement::Small);
    }
}

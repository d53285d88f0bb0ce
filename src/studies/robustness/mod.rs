//! `rths robustness`: the robustness study (issue 12). Monte-Carlo over draws of the benchmark's
//! uncertainty (β1, β2, a3 and the specimen stiffness), on both plant presets, for a softer, the
//! nominal and a stiffer specimen (F = 0.7 / 1.0 / 1.3) and the yielding Bouc–Wen brace, on
//! records no model was trained on.
//!
//! Each draw is handled as a lab would handle a new rig: identify it from its measured signals
//! (`rths identify`'s runner and estimators, [`crate::machinery::identify`]), build the identified LRX
//! metamodel for it (the frame fit, which does not depend on the rig, once; the rig's identified
//! lead filter per draw, as `rths train lrx --rig` does) and start the ATS from the rig's
//! identified initial values. Then `lr-online` (the shipped LR), `fe-online-ats` and `lrx-online`
//! run on every held-out record, and each run is judged against the structure with the specimen
//! the plant really has ([`study::reference_for_rig`]).
//!
//! What each side sees: the identification reads only the commands it sent and the displacement
//! and force as measured (noisy, quantized); the controllers see only the DAQ. The draw
//! ([`DrawnPlant`]) is read by the evaluation alone (fair reference, report).
//!
//! The runs are independent closed loops: rayon spreads the (preset, draw, specimen) jobs over
//! every core and collects them in order, so the figures do not depend on the scheduling.
//! [`report`] writes the table, the JSON, the per-run CSV; [`figure`] the figure.

pub mod figure;
pub mod report;

use std::path::PathBuf;

use anyhow::Context;
use rayon::prelude::*;
use rths_core::compensator::LEAD_TAPS;
use rths_core::params::{DT_S, PAPER_DELAY_STEPS};
use rths_hal_sim::{BoucWen, FaultPlan, Preset, Specimen};
use serde::Serialize;

use crate::machinery::identify::{self, IdentifyConfig};
use crate::machinery::model_file::ModelFile;
use crate::machinery::models;
use crate::machinery::motion::{parse_csv, GroundMotion};
use crate::machinery::train::lrx;
use crate::studies::scenario::{self, ScenarioId, ScenarioSetup};
use crate::studies::study::{self, DrawnPlant};
use crate::studies::sweep;

/// The shipped LR (the paper's, phase 2, trained on El Centro): what `lr-online` runs.
const SHIPPED_LR: &str = include_str!("../../../data/models/lr.json");

/// Morgan Hill, from the vRTHS benchmark's data (`time_s,accel_g`): embedded, so the study runs
/// from any directory.
const MORGAN_HILL_CSV: &str = include_str!("../../../data/vrths_benchmark/morgan.csv");

/// The specimen stiffness factors of the linear cases.
pub const ROBUSTNESS_FACTORS: [f64; 3] = [0.7, 1.0, 1.3];

/// The controllers compared, in report order: the specimen sweep's `lr-online`, `fe-online-ats`,
/// `lrx-online`.
pub const CONTROLLERS: [ScenarioId; 3] = sweep::SCENARIOS;

/// Draws of `--quick` (a smoke run for the tests).
pub const QUICK_DRAWS: usize = 2;

/// The goals the identified metamodel is measured against (issue 12), %.
pub mod goals {
    /// Median measured NRMSE over a row's runs.
    pub const NRMSE_MEDIAN_PCT: f64 = 1.0;
    /// Largest measured NRMSE of a row.
    pub const NRMSE_MAX_PCT: f64 = 2.5;
    /// Median J4 over a row's runs.
    pub const J4_MEDIAN_PCT: f64 = 5.0;
}

/// The specimen cases: linear at [`ROBUSTNESS_FACTORS`], then the default (yielding) Bouc–Wen brace at 1.
pub fn cases() -> Vec<(Specimen, f64)> {
    let mut c: Vec<(Specimen, f64)> = ROBUSTNESS_FACTORS
        .iter()
        .map(|f| (Specimen::Linear, *f))
        .collect();
    c.push((Specimen::BoucWen(BoucWen::default()), 1.0));
    c
}

/// Short label of a case: `F = 0.7` or `Bouc–Wen`.
pub fn case_label(specimen: Specimen, factor: f64) -> String {
    match specimen {
        Specimen::Linear => format!("F = {factor}"),
        Specimen::BoucWen(_) => "Bouc–Wen".to_string(),
    }
}

/// What to run.
#[derive(Debug, Clone)]
pub struct RobustnessConfig {
    /// Draws per preset; the uncertainty seeds are `first_seed .. first_seed + draws`.
    pub draws: usize,
    /// The plant presets.
    pub presets: Vec<Preset>,
    /// The first draw's seed (the seed also sets the sensor noise).
    pub first_seed: u64,
    /// Output directory.
    pub out_dir: PathBuf,
    /// No progress bar.
    pub quiet: bool,
}

/// A held-out record, as run.
#[derive(Debug, Clone, Serialize)]
pub struct HeldOutRecord {
    /// Record name.
    pub name: String,
    /// Where it comes from.
    pub source: String,
    /// Scale applied ([`sweep::fitting_scale_for_delay`]: the reference of every specimen fits the
    /// actuator's velocity, stroke and following-error interlocks at the slowest nominal rig's
    /// identified delay).
    pub scale: f64,
    /// Duration, s.
    pub duration_s: f64,
    /// Ground acceleration at every tick, mm/s² (scaled).
    #[serde(skip)]
    pub ag_mm_s2: Vec<f64>,
}

/// The held-out records: El Centro and Kobe (embedded) and Morgan Hill (vRTHS benchmark), each at
/// the largest scale that fits the actuator with a delay of `delay_s`.
pub fn held_out_records(delay_s: f64) -> anyhow::Result<Vec<HeldOutRecord>> {
    let morgan = parse_csv(MORGAN_HILL_CSV, "morgan-hill")
        .context("the embedded data/vrths_benchmark/morgan.csv")?;
    let mut out = Vec::new();
    for (motion, source) in [
        (
            GroundMotion::try_embedded("el-centro")?,
            "embedded (data/ground_motions/IELC180.AT2)",
        ),
        (
            GroundMotion::try_embedded("kobe")?,
            "embedded (data/ground_motions/TAK000.AT2)",
        ),
        (morgan, "data/vrths_benchmark/morgan.csv"),
    ] {
        let scale = sweep::fitting_scale_for_delay(&motion.resample_mm_s2(DT_S), delay_s)?;
        let ag = motion.scaled(scale).resample_mm_s2(DT_S);
        out.push(HeldOutRecord {
            name: motion.name.clone(),
            source: source.to_string(),
            scale,
            duration_s: ag.len().saturating_sub(1) as f64 * DT_S,
            ag_mm_s2: ag,
        });
    }
    Ok(out)
}

/// What the identification of one drawn rig gave (the controller's knowledge of the rig).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct RigSummary {
    /// Identified phase delay, ms.
    pub delay_ms: f64,
    /// Identified low-frequency gain.
    pub gain: f64,
    /// ATS initial values [a0, a1 (s), a2 (s²)].
    pub ats_initial: [f64; 3],
    /// Identified specimen stiffness, kN/mm.
    pub stiffness_kn_per_mm: f64,
}

/// One (preset, draw, specimen) job: the drawn plant, what was identified, and its runs.
#[derive(Debug, Clone, Serialize)]
pub struct DrawCase {
    /// Preset name.
    pub preset: String,
    /// Uncertainty seed.
    pub seed: u64,
    /// Case label ([`case_label`]).
    pub case: String,
    /// `linear` or `bouc-wen`.
    pub specimen: String,
    /// Configured specimen stiffness factor.
    pub stiffness_factor: f64,
    /// The drawn plant (known to the evaluation only).
    pub plant: DrawnPlant,
    /// What the identification gave (`null` if it was refused).
    pub rig: Option<RigSummary>,
    /// Why the identification was refused, if it was (then only `lr-online` runs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub identification_refused: Option<String>,
    /// The runs, record by record, controller by controller.
    pub runs: Vec<RobustnessRun>,
}

/// One closed-loop run.
#[derive(Debug, Clone, Serialize)]
pub struct RobustnessRun {
    /// Record name.
    pub record: String,
    /// Controller (scenario id).
    pub controller: String,
    /// The supervisor never tripped (and the run could be set up).
    pub stable: bool,
    /// Why it stopped (or could not run).
    pub stop_reason: Option<String>,
    /// Measured displacement vs the fair reference, NRMSE %.
    pub nrmse_measured_pct: Option<f64>,
    /// J4: std-normalized error of measured vs the fair reference, %.
    pub j4_pct: Option<f64>,
}

/// The whole study.
#[derive(Debug, Clone, Serialize)]
pub struct Robustness {
    /// Draws per preset.
    pub draws: usize,
    /// First uncertainty seed.
    pub first_seed: u64,
    /// Presets, in order.
    pub presets: Vec<String>,
    /// The delay the records are scaled for: the largest identified delay of the presets' nominal
    /// rigs, s.
    pub planning_delay_s: f64,
    /// The held-out records.
    pub records: Vec<HeldOutRecord>,
    /// The training motions of the identified LRX's frame fit.
    pub lrx_training: String,
    /// Every job, in (preset, seed, case) order.
    pub jobs: Vec<DrawCase>,
}

fn identified(
    rig: &rths_hal_sim::RigConfig,
    frame: &ModelFile,
) -> Result<(RigSummary, ModelFile), String> {
    let cfg = IdentifyConfig::default();
    let o = identify::identify_virtual(rig, FaultPlan::none(), &cfg).map_err(|e| e.to_string())?;
    let id = &o.identification;
    // `rths train lrx --rig`: the frame model with the rig's identified lead filter.
    let mut file = frame.clone();
    let w = file
        .lrx
        .as_mut()
        .ok_or_else(|| "the LRX training gave no LRX section".to_string())?;
    w.lead_weights = id.lead_weights.to_vec();
    w.lead_stride = cfg.lead_stride;
    // As `train lrx --rig` writes them: the lead's online gain-and-delay adaptation and the
    // specimen's identified mass and damping, removed from the measured force.
    w.lead_adapt_ticks = Some(lrx::RIG_LEAD_ADAPT_TICKS);
    let [mass, damping] = lrx::prototype_dynamics(&id.specimen);
    w.specimen_mass_kn_s2_per_mm = Some(mass);
    w.specimen_damping_kn_s_per_mm = Some(damping);
    Ok((
        RigSummary {
            delay_ms: id.delay_s * 1e3,
            gain: id.model.gain,
            ats_initial: id.ats_initial,
            stiffness_kn_per_mm: id.specimen.stiffness_kn_per_mm,
        },
        file,
    ))
}

fn failed(record: &str, id: ScenarioId, why: String) -> RobustnessRun {
    RobustnessRun {
        record: record.to_string(),
        controller: id.to_string(),
        stable: false,
        stop_reason: Some(why),
        nrmse_measured_pct: None,
        j4_pct: None,
    }
}

/// One job: identify the drawn rig, then every record × controller.
fn run_job(
    preset: Preset,
    seed: u64,
    (specimen, factor): (Specimen, f64),
    records: &[HeldOutRecord],
    lr: rths_core::metamodel::LrParams,
    frame: &ModelFile,
) -> anyhow::Result<DrawCase> {
    let mut rig = crate::machinery::reference::rig_config(preset, specimen, factor, seed);
    rig.uncertainty = true;
    let ident = identified(&rig, frame);
    let lrx_params = match &ident {
        Ok((_, file)) => Some(models::lrx_params(file)?),
        Err(_) => None,
    };
    let ats_initial = ident.as_ref().ok().map(|(s, _)| s.ats_initial);
    let mut runs = Vec::with_capacity(records.len() * CONTROLLERS.len());
    for rec in records {
        let (reference, _) = study::reference_for_rig(&rec.ag_mm_s2, &rig, factor)?;
        for id in CONTROLLERS {
            if id != ScenarioId::LrOnline {
                if let Err(why) = &ident {
                    runs.push(failed(
                        &rec.name,
                        id,
                        format!("identification refused: {why}"),
                    ));
                    continue;
                }
            }
            let setup = ScenarioSetup {
                id,
                ground_accel_mm_s2: &rec.ag_mm_s2,
                reference_mm: &reference,
                rig,
                stiffness_factor: factor,
                lr: Some(lr),
                rnn: None,
                delay_steps: PAPER_DELAY_STEPS,
                lrx: lrx_params,
            };
            let start = (id == ScenarioId::FeOnlineAts)
                .then_some(ats_initial)
                .flatten();
            let r = scenario::report_with_ats_start(&setup, start)?;
            runs.push(RobustnessRun {
                record: rec.name.clone(),
                controller: r.id,
                stable: r.stable,
                stop_reason: r.stop_reason,
                nrmse_measured_pct: r.nrmse_measured_pct,
                j4_pct: r.j4_pct,
            });
        }
    }
    Ok(DrawCase {
        preset: preset.name().to_string(),
        seed,
        case: case_label(specimen, factor),
        specimen: specimen.name().to_string(),
        stiffness_factor: factor,
        plant: DrawnPlant::of(&rig, factor)?,
        identification_refused: ident.as_ref().err().cloned(),
        rig: ident.ok().map(|(s, _)| s),
        runs,
    })
}

/// One progress bar (hidden with `quiet` or when stderr is not a terminal).
fn progress(quiet: bool, units: u64) -> indicatif::ProgressBar {
    crate::machinery::progress::styled(
        units,
        "{bar:30} {pos}/{len} draws × specimens [{elapsed}]",
        quiet,
    )
}

/// A lead filter that passes its input through (weight 1 on the newest tap).
fn pass_through() -> [f64; LEAD_TAPS] {
    let mut w = [0.0; LEAD_TAPS];
    w[0] = 1.0;
    w
}

/// Run the study (nothing written: [`report::write`] does).
pub fn run(cfg: &RobustnessConfig) -> anyhow::Result<Robustness> {
    if cfg.draws == 0 {
        anyhow::bail!("--draws must be at least 1");
    }
    if cfg.presets.is_empty() {
        anyhow::bail!("no preset to run");
    }
    for (i, p) in cfg.presets.iter().enumerate() {
        // The rows group runs by preset: a preset twice would count its runs twice.
        if cfg.presets.iter().take(i).any(|q| q == p) {
            anyhow::bail!("preset `{}` is listed twice", p.name());
        }
    }
    if cfg.first_seed.checked_add(cfg.draws as u64).is_none() {
        anyhow::bail!(
            "--seed {} + --draws {} overflows",
            cfg.first_seed,
            cfg.draws
        );
    }
    // The test is planned as a lab plans it: identify each preset's nominal rig and scale the
    // records so a compensated command fits the slowest one's following error. One scale per
    // record for every preset and draw keeps the rows comparable.
    let mut planning_delay_s: f64 = 0.0;
    for &p in &cfg.presets {
        let rig = crate::machinery::reference::rig_config(p, Specimen::Linear, 1.0, cfg.first_seed);
        let o = identify::identify_virtual(&rig, FaultPlan::none(), &IdentifyConfig::default())
            .map_err(|e| anyhow::anyhow!("identifying the nominal {} rig: {e}", p.name()))?;
        planning_delay_s = planning_delay_s.max(o.identification.delay_s);
    }
    let records = held_out_records(planning_delay_s)?;
    let lr = models::lr_params(
        &ModelFile::from_json(SHIPPED_LR).context("the shipped data/models/lr.json")?,
    )?;
    // The frame fit does not depend on the rig: once. Its lead is replaced by each rig's
    // identified one, so the simulator's lead fit is skipped (a given lead, never run).
    let mut lrx_cfg = lrx::LrxConfig::new()?;
    lrx_cfg.given_lead = Some(lrx::GivenLead {
        weights: pass_through(),
        stride: 1,
        fit_nrmse_pct: f64::NAN,
    });
    let frame = lrx::train(&lrx_cfg)?.file;
    let jobs: Vec<(Preset, u64, (Specimen, f64))> = cfg
        .presets
        .iter()
        .flat_map(|&p| {
            (0..cfg.draws as u64)
                .flat_map(move |d| cases().into_iter().map(move |c| (p, cfg.first_seed + d, c)))
        })
        .collect();
    let bar = progress(cfg.quiet, jobs.len() as u64);
    let done = jobs
        .par_iter()
        .map(|&(p, seed, case)| {
            let r = run_job(p, seed, case, &records, lr, &frame);
            bar.inc(1);
            r
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    bar.finish_and_clear();
    Ok(Robustness {
        draws: cfg.draws,
        first_seed: cfg.first_seed,
        presets: cfg.presets.iter().map(|p| p.name().to_string()).collect(),
        planning_delay_s,
        records,
        lrx_training: frame.training.motion.clone(),
        jobs: done,
    })
}

//! The scoring study of the nonlinear scenarios (`rths nonlinear-study`, docs/nonlinear.md): the
//! held-out records El Centro, Kobe and Morgan Hill, each at three intensities (the scales at which
//! the structure's FE reference reaches the ductilities [`TARGET_DUCTILITIES`]: elastic, about 2,
//! past 4), every scenario of [`STRUCTURE_SCENARIOS`] that applies, and the goal table.
//!
//! The line between control and evaluation: every run sees only the ground acceleration and what
//! the virtual DAQ measures; the reference (whole structure, noise-free) and the intensity search
//! on it are evaluation, which picks the rows as a lab would pick its test levels from an analysis.
//! Each row's length scale ([`plan_length_scale`]) is the test plan an engineer makes from the
//! lab's own FE prediction (the structure's numerical part with its specimen, `fe-pure`), never
//! from the reference.

use anyhow::Context;
use rayon::prelude::*;
use rths_core::control::Analytical;
use rths_core::metrics;
use rths_core::params::DT_S;
use rths_files::structure_file::Structure;
use serde::Serialize;

use super::scenario::{
    self as nl, check_applies, numerical_fe, rig_demand, run_pure, LengthScale, ScenarioInputs,
    SimScenario, StructureCase, StructureReport, STRUCTURE_SCENARIOS,
};
use crate::machinery::motion::GroundMotion;
use crate::machinery::structure::rig::RigCompensation;
use crate::machinery::structure::{elastic_drifts, fe_reference};
use crate::studies::scenario::ScenarioId;

/// The length scales a row's test plan chooses from ([`plan_length_scale`]), smallest first.
pub const LENGTH_SCALES: [f64; 6] = [1.0, 1.5, 2.0, 3.0, 4.0, 6.0];
/// The test plan keeps the FE prediction within this fraction of the supervisor's stroke and
/// velocity limits: headroom for the compensated command, which leads the target and overshoots
/// it a little, and for the model's error.
pub const PLAN_FRACTION: f64 = 0.8;

/// The test plan of a case: the smallest of [`LENGTH_SCALES`] at which the lab's FE prediction
/// (the structure's numerical part with its linear specimen in the pure loop: `fe-pure`, which
/// the lab has before the test) asks at most [`PLAN_FRACTION`] of the actuator's supervised
/// stroke and velocity. `None`: even the largest does not fit.
pub fn plan_length_scale(case: &StructureCase) -> anyhow::Result<Option<LengthScale>> {
    let (prediction, stop) = run_pure(case, &numerical_fe(&case.structure)?);
    if let Some((why, t)) = stop {
        anyhow::bail!("the FE prediction of the test plan stopped: {why} at {t:.3} s");
    }
    let lim = rths_core::supervisor::Limits::paper_actuator();
    for l in LENGTH_SCALES {
        let length = LengthScale::new(l)?;
        let (peak_mm, vel_mm_s) = rig_demand(&prediction.target_mm, length);
        if peak_mm <= PLAN_FRACTION * lim.stroke_mm()
            && vel_mm_s <= PLAN_FRACTION * lim.velocity_mm_s()
        {
            return Ok(Some(length));
        }
    }
    Ok(None)
}

/// The scoring records (never trained on: `rths train nonlinear` uses others).
pub const RECORDS: [&str; 3] = ["el-centro", "kobe", "morgan"];
/// The peak ductilities the three intensities of a record aim at: elastic, about 2, past 4.
pub const TARGET_DUCTILITIES: [f64; 3] = [0.8, 2.0, 4.5];
/// The intensity search stops within this relative distance of its target ductility.
pub const DUCTILITY_TOLERANCE: f64 = 0.02;
/// Residual drifts below this are not judged against the 10 % goal, mm: 50 × the displacement
/// transducer's noise (`DEFAULT_DISP_NOISE_MM` = 0.002 mm), and about 1 % of the shipped
/// structures' yield drifts.
pub const RESIDUAL_MIN_MM: f64 = 0.1;

/// A scoring record: El Centro and Kobe as embedded (`rths analyze --motion NAME`), Morgan Hill
/// from the vRTHS benchmark's file (`data/vrths_benchmark/morgan.csv`).
pub fn record(name: &str) -> anyhow::Result<GroundMotion> {
    if name == "morgan" {
        return crate::studies::benchmark::BenchmarkRecord::Morgan.motion();
    }
    GroundMotion::try_embedded(name).with_context(|| format!("embedded record {name}"))
}

/// The scale of `motion` at which `structure`'s reference peaks at ductility `target` (bisection
/// on the logarithm of the scale in [1/64, 64]): (scale, ductility reached).
pub fn scale_for_ductility(
    structure: &Structure,
    motion: &GroundMotion,
    target: f64,
) -> anyhow::Result<(f64, f64)> {
    let mu = |s: f64| -> anyhow::Result<f64> {
        Ok(fe_reference(structure, &motion.scaled(s).resample_mm_s2(DT_S), DT_S)?.peak_ductility())
    };
    let (mut lo, mut hi) = ((1.0_f64 / 64.0).ln(), 64.0_f64.ln());
    let mut best = (1.0, mu(1.0)?);
    for _ in 0..40 {
        let s = (0.5 * (lo + hi)).exp();
        let m = mu(s)?;
        if (m - target).abs() < (best.1 - target).abs() {
            best = (s, m);
        }
        if (m - target).abs() <= DUCTILITY_TOLERANCE * target {
            break;
        }
        if m < target {
            lo = s.ln();
        } else {
            hi = s.ln();
        }
    }
    Ok(best)
}

/// Builds the learned model of a structure for `nl-pure`/`nl-online` (`None`: no model for it).
pub type ModelFactory<'a> = &'a (dyn Fn(&Structure) -> anyhow::Result<Option<Analytical>> + Sync);

/// What the study runs with.
pub struct NonlinearStudyConfig<'a> {
    /// The structures (yielding ones: the shipped three by default).
    pub structures: Vec<Structure>,
    /// The learned models (`nl-*` rows), by structure.
    pub models: ModelFactory<'a>,
    /// `lr-online`'s model (the shipped LR).
    pub lr: Option<rths_core::metamodel::LrParams>,
    /// `lrx-online`'s model and lead (the shipped LRX).
    pub lrx: Option<(
        rths_core::metamodel::LrxParams,
        rths_core::compensator::LeadParams,
    )>,
    /// The LR/LRX feedback delay, ticks.
    pub delay_steps: usize,
    /// Plant preset.
    pub preset: rths_hal_sim::Preset,
    /// Sensor-noise seed.
    pub seed: u64,
    /// Records (default [`RECORDS`]).
    pub records: Vec<String>,
    /// Target ductilities (default [`TARGET_DUCTILITIES`]).
    pub ductilities: Vec<f64>,
}

/// A scenario the study did not run on a row, and why.
#[derive(Debug, Clone, Serialize)]
pub struct Skipped {
    /// The scenario.
    pub scenario: String,
    /// Why.
    pub reason: String,
}

/// One row: a structure, a record at one intensity, every scenario's figures.
#[derive(Debug, Clone, Serialize)]
pub struct StudyRow {
    /// Structure name.
    pub structure: String,
    /// Record.
    pub record: String,
    /// Factor on the record.
    pub scale: f64,
    /// The ductility the intensity aimed at.
    pub target_ductility: f64,
    /// Peak ductility of the reference (all stories).
    pub peak_ductility: f64,
    /// NRMSE of the elastic path of the same structure at the specimen DOF, %: what a linear
    /// numerical substructure gives at best.
    pub elastic_nrmse_pct: f64,
    /// The test plan's length scale of the row's hybrid runs ([`plan_length_scale`]; the
    /// largest of [`LENGTH_SCALES`] if none fits). `lr-online` and `lrx-online` run at 1 (they
    /// are `rths simulate`'s runs of the paper's frame); each run states its own.
    pub length_scale: f64,
    /// Why the reference is beyond the actuator at the row's length scale, if it is (its hybrid
    /// runs are stopped).
    pub beyond_rig: Option<String>,
    /// The runs.
    pub runs: Vec<StructureReport>,
    /// Scenarios not run here.
    pub skipped: Vec<Skipped>,
}

/// One line of the goal table.
#[derive(Debug, Clone, Serialize)]
pub struct Goal {
    /// The goal, as the issue words it.
    pub goal: String,
    /// The scenario judged.
    pub scenario: String,
    /// The measured figure (`null`: nothing to measure).
    pub measured: Option<f64>,
    /// The limit.
    pub limit: f64,
    /// Met (`null`: not measured).
    pub met: Option<bool>,
    /// Rows it was judged on.
    pub rows: usize,
    /// What was (not) counted.
    pub note: String,
}

/// The most of a record the rig can test on a structure.
#[derive(Debug, Clone, Serialize)]
pub struct RigCapacity {
    /// Structure name.
    pub structure: String,
    /// Record.
    pub record: String,
    /// The largest scale whose reference stays within the actuator's stroke and velocity at
    /// length scale 1 (to 1 %).
    pub max_scale: f64,
    /// The reference's peak ductility at that scale.
    pub peak_ductility: f64,
}

/// The largest scale of `motion` whose reference the rig can follow at length scale 1 (bisection on the logarithm
/// of the scale in [1/64, 64], to 1 %), and the ductility there.
pub fn rig_capacity(structure: &Structure, motion: &GroundMotion) -> anyhow::Result<(f64, f64)> {
    let fits = |s: f64| -> anyhow::Result<(bool, f64)> {
        let case = StructureCase::new(structure.clone(), &motion.scaled(s).resample_mm_s2(DT_S))?;
        Ok((case.beyond_rig().is_none(), case.reference.peak_ductility()))
    };
    let (mut lo, mut hi) = ((1.0_f64 / 64.0).ln(), 64.0_f64.ln());
    let mut best = (lo.exp(), fits(lo.exp())?.1);
    while hi - lo > 0.01 {
        let s = (0.5 * (lo + hi)).exp();
        let (ok, mu) = fits(s)?;
        if ok {
            best = (s, mu);
            lo = s.ln();
        } else {
            hi = s.ln();
        }
    }
    Ok(best)
}

/// The whole study.
#[derive(Debug, Clone, Serialize)]
pub struct StudyReport {
    /// Each structure's identified rig: the compensation of its hybrid runs.
    pub identified_rigs: Vec<RigCompensation>,
    /// Every row.
    pub rows: Vec<StudyRow>,
    /// What the rig can test, by structure and record.
    pub rig_capacity: Vec<RigCapacity>,
    /// The goals, met or not, with the numbers.
    pub goals: Vec<Goal>,
}

/// Run one row.
fn row(
    cfg: &NonlinearStudyConfig<'_>,
    structure: &Structure,
    comp: &RigCompensation,
    record_name: &str,
    target: f64,
) -> anyhow::Result<StudyRow> {
    let motion = record(record_name)?;
    let (scale, _) = scale_for_ductility(structure, &motion, target)?;
    let ag = motion.scaled(scale).resample_mm_s2(DT_S);
    let unit_case = StructureCase::new(structure.clone(), &ag)?;
    let length = plan_length_scale(&unit_case)?
        .unwrap_or(LengthScale::new(LENGTH_SCALES[LENGTH_SCALES.len() - 1])?);
    let case = unit_case.clone().with_length_scale(length);
    let dof = structure.specimen_dof();
    let elastic = elastic_drifts(structure, &case.reference, DT_S)?;
    let floor = |d: &[Vec<f64>]| -> Vec<f64> {
        (0..case.reference_mm.len())
            .map(|k| d[..=dof].iter().map(|s| s[k]).sum())
            .collect()
    };
    let elastic_nrmse_pct =
        metrics::nrmse_pct(&floor(&elastic), &floor(&case.reference.story_drift_mm))
            .map_err(|e| anyhow::anyhow!("elastic NRMSE: {e:?}"))?;
    let mut runs = Vec::new();
    let mut skipped = Vec::new();
    for sc in STRUCTURE_SCENARIOS {
        if let Err(e) = check_applies(sc, structure) {
            skipped.push(Skipped {
                scenario: sc.to_string(),
                reason: format!("{e:#}"),
            });
            continue;
        }
        let model = match sc {
            SimScenario::NlPure | SimScenario::NlOnline => match (cfg.models)(structure)? {
                Some(m) => Some(m),
                None => {
                    skipped.push(Skipped {
                        scenario: sc.to_string(),
                        reason: format!("no learned model of {} given", structure.name()),
                    });
                    continue;
                }
            },
            _ => None,
        };
        let inputs = ScenarioInputs {
            preset: cfg.preset,
            seed: cfg.seed,
            ats_initial: Some(comp.ats_initial),
            corrected_lead: Some(comp.corrected_lead),
            lr: cfg.lr,
            lrx: cfg.lrx,
            delay_steps: cfg.delay_steps,
            nl_model: model.as_ref(),
        };
        // The shipped linear models run exactly as `rths simulate` runs them: at length scale 1.
        let sc_case = match sc {
            SimScenario::Study(ScenarioId::LrOnline | ScenarioId::LrxOnline) => &unit_case,
            _ => &case,
        };
        let (report, _) = nl::run_scenario(sc_case, sc, inputs)
            .with_context(|| format!("{sc} on {} {record_name}", structure.name()))?;
        runs.push(report);
    }
    Ok(StudyRow {
        structure: structure.name().to_string(),
        record: record_name.to_string(),
        scale,
        target_ductility: target,
        peak_ductility: case.reference.peak_ductility(),
        elastic_nrmse_pct,
        length_scale: length.get(),
        beyond_rig: case.beyond_rig(),
        runs,
        skipped,
    })
}

/// Run the study (rows in parallel on rayon's pool). Each structure's rig is identified first
/// ([`crate::machinery::structure::rig::identify`]); its hybrid runs use that compensation.
pub fn run(cfg: &NonlinearStudyConfig<'_>) -> anyhow::Result<StudyReport> {
    // One bar over the three phases: the rigs, the rows, each record's capacity on each rig.
    let units = cfg.structures.len() * (1 + cfg.records.len() * (cfg.ductilities.len() + 1));
    let bar = crate::machinery::progress::bar(units as u64, "rigs, rows and capacities", false);
    let rigs = cfg
        .structures
        .par_iter()
        .map(|s| {
            let rig = crate::machinery::structure::rig::identify(s, cfg.preset, cfg.seed);
            bar.inc(1);
            rig
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let jobs: Vec<(&Structure, &RigCompensation, &str, f64)> = cfg
        .structures
        .iter()
        .zip(&rigs)
        .flat_map(|(s, c)| {
            cfg.records.iter().flat_map(move |r| {
                cfg.ductilities
                    .iter()
                    .map(move |&mu| (s, c, r.as_str(), mu))
            })
        })
        .collect();
    let rows = jobs
        .par_iter()
        .map(|&(s, c, r, mu)| {
            let row = row(cfg, s, c, r, mu);
            bar.inc(1);
            row
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let pairs: Vec<(&Structure, &str)> = cfg
        .structures
        .iter()
        .flat_map(|s| cfg.records.iter().map(move |r| (s, r.as_str())))
        .collect();
    let rig_capacity = pairs
        .par_iter()
        .map(|&(s, r)| {
            let (max_scale, peak_ductility) = rig_capacity(s, &record(r)?)?;
            bar.inc(1);
            Ok(RigCapacity {
                structure: s.name().to_string(),
                record: r.to_string(),
                max_scale,
                peak_ductility,
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    bar.finish_and_clear();
    let goals = goals(&rows);
    Ok(StudyReport {
        identified_rigs: rigs,
        rows,
        rig_capacity,
        goals,
    })
}

/// The runs of scenario `name` over `rows`, with their row.
fn runs_of<'a>(
    rows: &'a [StudyRow],
    name: &'a str,
) -> impl Iterator<Item = (&'a StudyRow, &'a StructureReport)> + 'a {
    rows.iter().flat_map(move |r| {
        r.runs
            .iter()
            .filter(move |x| x.report.id == name)
            .map(move |x| (r, x))
    })
}

fn max(v: &[f64]) -> Option<f64> {
    v.iter().copied().reduce(f64::max)
}

/// The goals over the study's rows (all intensities, elastic to past 4).
pub fn goals(rows: &[StudyRow]) -> Vec<Goal> {
    let mut out = Vec::new();
    let goal = |goal: &str, sc: &str, measured: Option<f64>, limit: f64, rows: usize, note| Goal {
        goal: goal.to_string(),
        scenario: sc.to_string(),
        measured,
        limit,
        met: measured.map(|m| m <= limit),
        rows,
        note,
    };
    for pure in ["nl-pure", "fe-pure"] {
        let mut v: Vec<f64> = runs_of(rows, pure)
            .filter_map(|(_, x)| x.report.nrmse_pct)
            .collect();
        let n = runs_of(rows, pure).count();
        let note = format!("{} of {n} runs finished", v.len());
        let mx = if v.len() == n { max(&v) } else { None };
        out.push(goal(
            "pure-loop NRMSE max ≤ 6 %",
            pure,
            mx,
            6.0,
            n,
            note.clone(),
        ));
        out.push(goal(
            "pure-loop NRMSE median ≤ 3 %",
            pure,
            metrics::median(&mut v),
            3.0,
            n,
            note,
        ));
    }
    for hybrid in [
        "nl-online",
        "fe-online-ats",
        "fe-online-lead",
        "lr-online",
        "lrx-online",
    ] {
        let within: Vec<_> = runs_of(rows, hybrid)
            .filter(|(_, x)| x.beyond_rig.is_none())
            .collect();
        let v: Vec<f64> = within
            .iter()
            .filter_map(|(_, x)| x.report.nrmse_measured_pct)
            .collect();
        let beyond = runs_of(rows, hybrid).count() - within.len();
        let stopped = within.len() - v.len();
        let mut g = goal(
            "hybrid-loop measured NRMSE max ≤ 5 %",
            hybrid,
            max(&v),
            5.0,
            within.len(),
            format!(
                "rows within the rig's stroke and velocity at their length scale ({beyond} \
                 beyond it not counted); {stopped} stopped by the supervisor"
            ),
        );
        // A run the supervisor stopped on a record the rig can do has failed.
        if stopped > 0 {
            g.met = Some(false);
        }
        out.push(g);
    }
    for sc in ["nl-pure", "nl-online", "fe-online-ats", "fe-online-lead"] {
        let with_residual: Vec<_> = runs_of(rows, sc)
            .filter_map(|(_, x)| {
                Some((
                    x.figures.residual_drift_mm?,
                    x.figures.residual_drift_error_pct?,
                ))
            })
            .collect();
        let judged: Vec<f64> = with_residual
            .iter()
            .filter(|(d, _)| d.reference.abs() >= RESIDUAL_MIN_MM)
            .map(|(_, e)| *e)
            .collect();
        // Say what the threshold left out, so the verdict can be read without it.
        let left_out = with_residual
            .iter()
            .filter(|(d, _)| d.reference.abs() < RESIDUAL_MIN_MM && d.reference.abs() > 1e-3)
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(String::new(), |(d, e)| {
                format!(
                    "; the worst row below it: {e:.1} % ({:.3} mm for {:.3} mm)",
                    d.model, d.reference
                )
            });
        out.push(goal(
            "residual drift within 10 % of the reference",
            sc,
            max(&judged),
            10.0,
            judged.len(),
            format!("worst row; rows whose reference residual is ≥ {RESIDUAL_MIN_MM} mm{left_out}"),
        ));
        if sc == "nl-online" {
            out.push(loop_floor_goal(rows));
        }
        let startup: Vec<f64> = runs_of(rows, sc)
            .filter_map(|(_, x)| x.figures.startup_error_ratio)
            .collect();
        out.push(goal(
            "start-up: RMS error of the first 2 s ≤ the rest's",
            sc,
            max(&startup),
            1.0,
            startup.len(),
            "worst row (ratio)".to_string(),
        ));
    }
    out
}

/// The learned model's residual drift in the hybrid loop against what the loop itself reaches: on
/// each row whose reference residual is ≥ [`RESIDUAL_MIN_MM`], `nl-online`'s error over the larger
/// of 10 % of the reference and `fe-online-lead`'s error on the same row (the exact numerical part
/// on the same rig, compensation, length scale and noise: the loop's floor). Measured: the worst ratio, met at
/// ≤ 1. The raw 10 % line stays in the table above it.
fn loop_floor_goal(rows: &[StudyRow]) -> Goal {
    let residual = |r: &StudyRow, id: &str| {
        r.runs
            .iter()
            .find(|x| x.report.id == id)
            .and_then(|x| x.figures.residual_drift_mm)
    };
    let ratios: Vec<f64> = rows
        .iter()
        .filter_map(|r| {
            let (nl, fe) = (residual(r, "nl-online")?, residual(r, "fe-online-lead")?);
            if nl.reference.abs() < RESIDUAL_MIN_MM || nl.story != fe.story {
                return None;
            }
            let floor = (0.1 * nl.reference.abs()).max((fe.model - fe.reference).abs());
            Some((nl.model - nl.reference).abs() / floor)
        })
        .collect();
    let measured = max(&ratios);
    Goal {
        goal: "residual drift within 10 % of the reference or the loop's own error".to_string(),
        scenario: "nl-online".to_string(),
        measured,
        limit: 1.0,
        met: measured.map(|m| m <= 1.0),
        rows: ratios.len(),
        note: format!(
            "worst row of the error over the larger of 10 % of the reference and fe-online-lead's \
             error on the row; rows whose reference residual is ≥ {RESIDUAL_MIN_MM} mm"
        ),
    }
}

/// The study as Markdown: the rows' table and the goal table.
pub fn markdown(r: &StudyReport) -> String {
    let o = |v: Option<f64>, d: usize| v.map_or("—".to_string(), |x| format!("{x:.d$}"));
    let mut s = String::from(
        "| structure | rig identified: delay ms | gain | specimen kN/mm (rig) | lead residual % | ATS start a0 / a1 s / a2 s² |\n|---|---|---|---|---|---|\n",
    );
    for c in &r.identified_rigs {
        s += &format!(
            "| {} | {:.3} | {:.4} | {:.4} | {:.2} | {:.4} / {:.5} / {:.3e} |\n",
            c.structure,
            c.delay_ms,
            c.gain,
            c.specimen_k_kn_per_mm,
            c.lead_residual_pct,
            c.ats_initial[0],
            c.ats_initial[1],
            c.ats_initial[2]
        );
    }
    s += "\n";
    s += &String::from(
        "| structure | record | scale | μ ref | elastic NRMSE % | scenario | L | NRMSE % | measured % | J4 % | μ run | residual story: ref / run mm | residual err % | start-up | note |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for row in &r.rows {
        for x in &row.runs {
            let f = &x.figures;
            let mut note = match (&x.report.stop_reason, x.report.stop_time_s) {
                (Some(why), Some(t)) => format!("stopped: {why} at {t:.2} s"),
                _ => String::new(),
            };
            if let Some(why) = &x.beyond_rig {
                note = format!(
                    "{note}{}beyond the rig: {why}",
                    if note.is_empty() { "" } else { "; " }
                );
            }
            // Below the threshold the reference has no residual drift to speak of.
            let res_err = match f.residual_drift_mm {
                Some(d) if d.reference.abs() >= RESIDUAL_MIN_MM => f.residual_drift_error_pct,
                _ => None,
            };
            s += &format!(
                "| {} | {} | {:.3} | {:.2} | {:.2} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                row.structure,
                row.record,
                row.scale,
                row.peak_ductility,
                row.elastic_nrmse_pct,
                x.report.id,
                x.length_scale.map_or("—".to_string(), |l| format!("{l}")),
                o(x.report.nrmse_pct, 2),
                o(x.report.nrmse_measured_pct, 2),
                o(x.report.j4_pct, 2),
                o(f.peak_ductility_model, 2),
                f.residual_drift_mm.map_or("—".to_string(), |d| format!(
                    "{}: {:.3} / {:.3}",
                    d.story, d.reference, d.model
                )),
                o(res_err, 1),
                o(f.startup_error_ratio, 2),
                note
            );
        }
    }
    s += "\n| structure | record | the rig follows up to scale (L = 1) | peak ductility there |\n|---|---|---|---|\n";
    for c in &r.rig_capacity {
        s += &format!(
            "| {} | {} | {:.3} | {:.2} |\n",
            c.structure, c.record, c.max_scale, c.peak_ductility
        );
    }
    s += "\n| goal | scenario | measured | limit | met | rows | note |\n|---|---|---|---|---|---|---|\n";
    for g in &r.goals {
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} |\n",
            g.goal,
            g.scenario,
            o(g.measured, 2),
            g.limit,
            match g.met {
                Some(true) => "met",
                Some(false) => "**not met**",
                None => "not measured",
            },
            g.rows,
            g.note
        );
    }
    s
}

//! The robustness study's outputs: the rows (preset × specimen × controller), the goal check,
//! `report.md`, `robustness.json` and the per-run `runs.csv` with every run's drawn parameters.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::Serialize;

use rths_core::metrics::median;

use super::{case_label, cases, goals, DrawCase, Robustness, RobustnessRun, CONTROLLERS};
use crate::studies::scenario::ScenarioId;
use crate::studies::study::DrawnPlant;

/// One row of the table: a controller on one preset and specimen case, over every draw and record.
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    /// Preset name.
    pub preset: String,
    /// Case label (`F = 0.7`, `Bouc–Wen`).
    pub case: String,
    /// Controller (scenario id).
    pub controller: String,
    /// Runs (draws × records).
    pub runs: usize,
    /// Runs the supervisor never stopped.
    pub stable: usize,
    /// Median measured NRMSE over the stable runs, %.
    pub nrmse_median_pct: Option<f64>,
    /// Largest measured NRMSE over the stable runs, %.
    pub nrmse_max_pct: Option<f64>,
    /// Median J4 over the stable runs, %.
    pub j4_median_pct: Option<f64>,
    /// Largest J4 over the stable runs, %.
    pub j4_max_pct: Option<f64>,
}

/// The identified metamodel (`lrx-online`) against the goals, on one preset and specimen case.
#[derive(Debug, Clone, Serialize)]
pub struct GoalCheck {
    /// Preset name.
    pub preset: String,
    /// Case label.
    pub case: String,
    /// Every run stable.
    pub all_stable: bool,
    /// Median measured NRMSE ≤ [`goals::NRMSE_MEDIAN_PCT`].
    pub nrmse_median_ok: bool,
    /// Largest measured NRMSE ≤ [`goals::NRMSE_MAX_PCT`].
    pub nrmse_max_ok: bool,
    /// Median J4 ≤ [`goals::J4_MEDIAN_PCT`].
    pub j4_median_ok: bool,
    /// Lower median and lower largest measured NRMSE than `fe-online-ats` on the same row, and at
    /// least as many stable runs.
    pub ahead_of_ats: bool,
    /// All of the above.
    pub meets: bool,
}

/// Min / median / max of a drawn or identified quantity over a preset's jobs.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Spread {
    /// Smallest.
    pub min: f64,
    /// Median.
    pub median: f64,
    /// Largest.
    pub max: f64,
}

/// What was drawn and identified on one preset.
#[derive(Debug, Clone, Serialize)]
pub struct DrawSummary {
    /// Preset name.
    pub preset: String,
    /// β1 at the benchmark's time scale, 1/s.
    pub beta1: Option<Spread>,
    /// β2 at the benchmark's time scale, 1/s².
    pub beta2: Option<Spread>,
    /// a3 at the benchmark's time scale, 1/s.
    pub a3: Option<Spread>,
    /// Drawn specimen stiffness over the configured one (F × this is the effective factor).
    pub specimen_stiffness_ratio: Option<Spread>,
    /// Identified delay, ms.
    pub identified_delay_ms: Option<Spread>,
    /// Identified ATS initial a1, s.
    pub ats_a1_s: Option<Spread>,
}

/// `robustness.json` (and `--json`).
#[derive(Debug, Clone, Serialize)]
pub struct RobustnessJson<'a> {
    /// Draws per preset.
    pub draws: usize,
    /// First uncertainty seed.
    pub first_seed: u64,
    /// Presets.
    pub presets: &'a [String],
    /// The held-out records.
    pub records: &'a [super::HeldOutRecord],
    /// Training motions of the identified LRX's frame fit.
    pub lrx_training: &'a str,
    /// rayon threads used.
    pub threads: usize,
    /// Wall time of the study, s.
    pub wall_time_s: f64,
    /// The table.
    pub rows: Vec<Row>,
    /// The goal check of the identified metamodel.
    pub goals: Vec<GoalCheck>,
    /// Every goal met.
    pub goals_met: bool,
    /// Spread of the draws and identifications per preset.
    pub drawn: Vec<DrawSummary>,
    /// Every (preset, draw, specimen) job: the drawn plant and what was identified (the runs are
    /// in `runs.csv`).
    pub jobs: Vec<JobJson<'a>>,
}

/// A job of [`RobustnessJson`] without its runs.
#[derive(Debug, Clone, Serialize)]
pub struct JobJson<'a> {
    /// Preset name.
    pub preset: &'a str,
    /// Uncertainty seed.
    pub seed: u64,
    /// `linear` or `bouc-wen`.
    pub specimen: &'a str,
    /// Configured specimen stiffness factor.
    pub stiffness_factor: f64,
    /// The drawn plant.
    pub plant: &'a DrawnPlant,
    /// What was identified.
    pub rig: Option<&'a super::RigSummary>,
    /// Why the identification was refused.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub identification_refused: Option<&'a str>,
}

/// Unstable runs listed one by one in `report.md` (all are in `runs.csv`).
const MAX_LISTED: usize = 40;

fn spread(mut v: Vec<f64>) -> Option<Spread> {
    let med = median(&mut v)?;
    Some(Spread {
        min: *v.first()?,
        median: med,
        max: *v.last()?,
    })
}

/// The runs of one preset, case and controller, over every draw and record.
fn runs_of<'a>(
    r: &'a Robustness,
    preset: &'a str,
    case: &'a str,
    id: ScenarioId,
) -> impl Iterator<Item = &'a RobustnessRun> + 'a {
    let name = id.to_string();
    r.jobs
        .iter()
        .filter(move |j| j.preset == preset && j.case == case)
        .flat_map(|j| j.runs.iter())
        .filter(move |x| x.controller == name)
}

/// The table, in (preset, case, controller) order.
pub fn rows(r: &Robustness) -> Vec<Row> {
    let mut out = Vec::new();
    for preset in &r.presets {
        for (spec, f) in cases() {
            let case = case_label(spec, f);
            for id in CONTROLLERS {
                let runs: Vec<&RobustnessRun> = runs_of(r, preset, &case, id).collect();
                let stable: Vec<&RobustnessRun> =
                    runs.iter().copied().filter(|x| x.stable).collect();
                let mut nrmse: Vec<f64> =
                    stable.iter().filter_map(|x| x.nrmse_measured_pct).collect();
                let mut j4: Vec<f64> = stable.iter().filter_map(|x| x.j4_pct).collect();
                let (nrmse_median_pct, j4_median_pct) = (median(&mut nrmse), median(&mut j4));
                out.push(Row {
                    preset: preset.clone(),
                    case: case.clone(),
                    controller: id.to_string(),
                    runs: runs.len(),
                    stable: stable.len(),
                    nrmse_median_pct,
                    nrmse_max_pct: nrmse.last().copied(),
                    j4_median_pct,
                    j4_max_pct: j4.last().copied(),
                });
            }
        }
    }
    out
}

/// The goal check of `lrx-online` on every preset and case.
pub fn goal_checks(rows: &[Row]) -> Vec<GoalCheck> {
    let find = |preset: &str, case: &str, id: ScenarioId| {
        let name = id.to_string();
        rows.iter()
            .find(|x| x.preset == preset && x.case == case && x.controller == name)
    };
    let le = |v: Option<f64>, goal: f64| v.is_some_and(|x| x <= goal);
    let lt = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) => a < b,
        (Some(_), None) => true,
        _ => false,
    };
    rows.iter()
        .filter(|x| x.controller == ScenarioId::LrxOnline.to_string())
        .map(|lrx| {
            let ats = find(&lrx.preset, &lrx.case, ScenarioId::FeOnlineAts);
            let all_stable = lrx.runs > 0 && lrx.stable == lrx.runs;
            let nrmse_median_ok = le(lrx.nrmse_median_pct, goals::NRMSE_MEDIAN_PCT);
            let nrmse_max_ok = le(lrx.nrmse_max_pct, goals::NRMSE_MAX_PCT);
            let j4_median_ok = le(lrx.j4_median_pct, goals::J4_MEDIAN_PCT);
            let ahead_of_ats = ats.is_none_or(|a| {
                lrx.stable >= a.stable
                    && lt(lrx.nrmse_median_pct, a.nrmse_median_pct)
                    && lt(lrx.nrmse_max_pct, a.nrmse_max_pct)
            });
            GoalCheck {
                preset: lrx.preset.clone(),
                case: lrx.case.clone(),
                all_stable,
                nrmse_median_ok,
                nrmse_max_ok,
                j4_median_ok,
                ahead_of_ats,
                meets: all_stable
                    && nrmse_median_ok
                    && nrmse_max_ok
                    && j4_median_ok
                    && ahead_of_ats,
            }
        })
        .collect()
}

/// The spread of the draws and identifications per preset.
pub fn draw_summaries(r: &Robustness) -> Vec<DrawSummary> {
    r.presets
        .iter()
        .map(|preset| {
            let jobs: Vec<&DrawCase> = r.jobs.iter().filter(|j| &j.preset == preset).collect();
            let of = |f: &dyn Fn(&DrawCase) -> Option<f64>| {
                spread(jobs.iter().filter_map(|j| f(j)).collect())
            };
            DrawSummary {
                preset: preset.clone(),
                beta1: of(&|j| Some(j.plant.beta1)),
                beta2: of(&|j| Some(j.plant.beta2)),
                a3: of(&|j| Some(j.plant.a3)),
                specimen_stiffness_ratio: of(&|j| {
                    Some(j.plant.specimen_stiffness_factor / j.stiffness_factor)
                }),
                identified_delay_ms: of(&|j| j.rig.map(|s| s.delay_ms)),
                ats_a1_s: of(&|j| j.rig.map(|s| s.ats_initial[1])),
            }
        })
        .collect()
}

/// The JSON summary.
pub fn json(r: &Robustness, threads: usize, wall_time_s: f64) -> RobustnessJson<'_> {
    let rows = rows(r);
    let goals = goal_checks(&rows);
    RobustnessJson {
        draws: r.draws,
        first_seed: r.first_seed,
        presets: &r.presets,
        records: &r.records,
        lrx_training: &r.lrx_training,
        threads,
        wall_time_s,
        goals_met: !goals.is_empty() && goals.iter().all(|g| g.meets),
        rows,
        goals,
        drawn: draw_summaries(r),
        jobs: r
            .jobs
            .iter()
            .map(|j| JobJson {
                preset: &j.preset,
                seed: j.seed,
                specimen: &j.specimen,
                stiffness_factor: j.stiffness_factor,
                plant: &j.plant,
                rig: j.rig.as_ref(),
                identification_refused: j.identification_refused.as_deref(),
            })
            .collect(),
    }
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or_else(|| "—".to_string(), |x| format!("{x:.digits$}"))
}

fn yes(ok: bool) -> &'static str {
    if ok {
        "yes"
    } else {
        "**no**"
    }
}

fn spread_cell(s: Option<Spread>, digits: usize) -> String {
    s.map_or_else(
        || "—".to_string(),
        |s| {
            format!(
                "{:.d$} / {:.d$} / {:.d$}",
                s.min,
                s.median,
                s.max,
                d = digits
            )
        },
    )
}

/// `report.md`.
pub fn markdown(r: &Robustness, j: &RobustnessJson<'_>) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# rths robustness: report\n");
    let _ = writeln!(
        s,
        "{} draws of the benchmark's uncertainty (β1, β2, a3, specimen stiffness; seeds {}–{}) on \
         {}; specimens F = 0.7 / 1.0 / 1.3 (linear) and the yielding Bouc–Wen brace. {} closed \
         loops and {} identifications in {:.1} s on {} threads.\n",
        r.draws,
        r.first_seed,
        r.first_seed + r.draws as u64 - 1,
        r.presets
            .iter()
            .map(|p| format!("`{p}`"))
            .collect::<Vec<_>>()
            .join(" and "),
        r.jobs.iter().map(|x| x.runs.len()).sum::<usize>(),
        r.jobs.len(),
        j.wall_time_s,
        j.threads
    );
    let _ = writeln!(s, "## What runs\n");
    let _ = writeln!(
        s,
        "Each draw is a new rig, handled as a lab would: `rths identify`'s excitation and estimators \
         on the drawn plant with its specimen installed (reading only the commands sent and the \
         measured, noisy displacement and force), then\n\n\
         - `lr-online`: the paper's LR, the shipped `data/models/lr.json`;\n\
         - `fe-online-ats`: FE of the frame with the ATS starting from the rig's identified initial \
           values;\n\
         - `lrx-online`: the identified metamodel, the LRX frame model (fitted once on {}: it does not \
           depend on the rig) with the rig's identified lead filter (`rths train lrx --rig`).\n\n\
         Every run is judged against the structure with the specimen the plant really has (the drawn \
         stiffness; `study::reference_for_rig`): NRMSE of the measured displacement, and J4 = \
         100·std(x_m − x_r)/std(x_r), the benchmark's criterion. A run the supervisor stopped counts \
         as unstable and has no figures; medians and maxima are over the stable runs.\n",
        r.lrx_training
    );
    let _ = writeln!(s, "## Held-out records\n");
    let _ = writeln!(s, "| record | source | scale | duration s |");
    let _ = writeln!(s, "|---|---|---|---|");
    for rec in &r.records {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.1} |",
            rec.name, rec.source, rec.scale, rec.duration_s
        );
    }
    let _ = writeln!(
        s,
        "\nNo model of the study was fitted on them: the LRX frame on {} (force-perturbed frame \
         runs), the identified lead on the identification's multisine, the ATS adapts online from the \
         rig's values. The one exception is `lr-online`'s shipped LR, the paper's model, trained on \
         El Centro: its El Centro runs are not held out. Each record is scaled so the reference of \
         every specimen of the sweep (F = 0.6–1.4, Bouc–Wen) stays within 90% of the actuator's \
         velocity, stroke and following-error interlocks, the last at the slowest nominal rig's \
         identified delay, {:.2} ms (`sweep::fitting_scale_for_delay`: a compensated command leads the \
         measurement by the whole delay). That covers the drawn stiffness (±2.5σ = ±10%).\n",
        r.lrx_training,
        r.planning_delay_s * 1e3
    );
    let _ = writeln!(s, "## Results\n");
    let _ = writeln!(
        s,
        "| preset | specimen | controller | runs | stable | NRMSE median % | NRMSE max % | J4 median % | J4 max % |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for x in &j.rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            x.preset,
            x.case,
            x.controller,
            x.runs,
            x.stable,
            opt(x.nrmse_median_pct, 2),
            opt(x.nrmse_max_pct, 2),
            opt(x.j4_median_pct, 2),
            opt(x.j4_max_pct, 2)
        );
    }
    let _ = writeln!(s, "\n### Per record\n");
    let _ = writeln!(
        s,
        "Measured NRMSE median / max %, over every specimen and draw (over the stable runs; in \
         brackets: stable runs of all).\n"
    );
    let _ = writeln!(
        s,
        "| preset | record | {} |",
        CONTROLLERS.map(|c| c.to_string()).join(" | ")
    );
    let _ = writeln!(s, "|---|---|---|---|---|");
    for preset in &r.presets {
        for rec in &r.records {
            let cells: Vec<String> = CONTROLLERS
                .iter()
                .map(|id| {
                    let name = id.to_string();
                    let runs: Vec<&RobustnessRun> = r
                        .jobs
                        .iter()
                        .filter(|x| &x.preset == preset)
                        .flat_map(|x| x.runs.iter())
                        .filter(|x| x.record == rec.name && x.controller == name)
                        .collect();
                    let mut v: Vec<f64> = runs
                        .iter()
                        .filter(|x| x.stable)
                        .filter_map(|x| x.nrmse_measured_pct)
                        .collect();
                    let stable = runs.iter().filter(|x| x.stable).count();
                    format!(
                        "{} / {} ({stable} of {})",
                        opt(median(&mut v), 2),
                        opt(v.last().copied(), 2),
                        runs.len()
                    )
                })
                .collect();
            let _ = writeln!(s, "| {preset} | {} | {} |", rec.name, cells.join(" | "));
        }
    }
    let _ = writeln!(s, "\n## Goals of the identified metamodel (`lrx-online`)\n");
    let _ = writeln!(
        s,
        "Every run stable; measured NRMSE median ≤ {} %, max ≤ {} %; J4 median ≤ {} %; ahead of \
         `fe-online-ats` (lower median and max NRMSE, no fewer stable runs) on the same row.\n",
        goals::NRMSE_MEDIAN_PCT,
        goals::NRMSE_MAX_PCT,
        goals::J4_MEDIAN_PCT
    );
    let _ = writeln!(
        s,
        "| preset | specimen | all stable | NRMSE median | NRMSE max | J4 median | ahead of ATS | meets |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for g in &j.goals {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            g.preset,
            g.case,
            yes(g.all_stable),
            yes(g.nrmse_median_ok),
            yes(g.nrmse_max_ok),
            yes(g.j4_median_ok),
            yes(g.ahead_of_ats),
            yes(g.meets)
        );
    }
    let _ = writeln!(
        s,
        "\nAll goals met: {}.\n",
        if j.goals_met { "yes" } else { "**no**" }
    );
    let _ = writeln!(s, "## Drawn and identified\n");
    let _ = writeln!(
        s,
        "min / median / max over every draw and specimen (β1, β2, a3 at the benchmark's time scale, \
         where its σ are published; the drawn specimen stiffness over the configured one). Each \
         run's values are in `runs.csv`.\n"
    );
    let _ = writeln!(
        s,
        "| preset | β1 1/s | β2 1/s² | a3 1/s | k drawn / configured | identified delay ms | ATS a1 s |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|");
    for d in &j.drawn {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} |",
            d.preset,
            spread_cell(d.beta1, 1),
            spread_cell(d.beta2, 0),
            spread_cell(d.a3, 2),
            spread_cell(d.specimen_stiffness_ratio, 4),
            spread_cell(d.identified_delay_ms, 2),
            spread_cell(d.ats_a1_s, 5)
        );
    }
    let unstable: Vec<String> = r
        .jobs
        .iter()
        .flat_map(|x| {
            x.runs.iter().filter(|run| !run.stable).map(move |run| {
                format!(
                    "- `{}` on `{}`, seed {}, {}, {}: {}",
                    run.controller,
                    x.preset,
                    x.seed,
                    x.case,
                    run.record,
                    run.stop_reason.as_deref().unwrap_or("stopped")
                )
            })
        })
        .collect();
    let _ = writeln!(s, "\n## Unstable runs\n");
    if unstable.is_empty() {
        let _ = writeln!(s, "None.");
    }
    for line in unstable.iter().take(MAX_LISTED) {
        let _ = writeln!(s, "{line}");
    }
    if unstable.len() > MAX_LISTED {
        let _ = writeln!(
            s,
            "- … and {} more (`runs.csv`)",
            unstable.len() - MAX_LISTED
        );
    }
    let refused = r
        .jobs
        .iter()
        .filter(|x| x.identification_refused.is_some())
        .count();
    let _ = writeln!(
        s,
        "\nIdentifications refused: {refused} of {}.\n",
        r.jobs.len()
    );
    let _ = writeln!(
        s,
        "Files: `robustness.json` (this summary), `runs.csv` (every run with its drawn parameters), \
         `robustness.png` (the measured NRMSE of every run)."
    );
    s
}

/// `runs.csv`: one line per run, with the drawn plant and what was identified.
pub fn csv(r: &Robustness) -> String {
    let mut s = String::from(
        "preset,seed,specimen,stiffness_factor,effective_stiffness_factor,beta1,beta2,a3,\
         specimen_stiffness_n_per_m,identified_delay_ms,identified_gain,ats_a0,ats_a1_s,ats_a2_s2,\
         identified_stiffness_kn_per_mm,record,record_scale,controller,stable,stop_reason,\
         nrmse_measured_pct,j4_pct\n",
    );
    let o = |v: Option<f64>| v.map_or_else(String::new, |x| format!("{x}"));
    for j in &r.jobs {
        let p = &j.plant;
        let rig = j.rig;
        for run in &j.runs {
            let scale = r
                .records
                .iter()
                .find(|x| x.name == run.record)
                .map(|x| x.scale);
            let _ = writeln!(
                s,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                j.preset,
                j.seed,
                j.specimen,
                j.stiffness_factor,
                p.specimen_stiffness_factor,
                p.beta1,
                p.beta2,
                p.a3,
                p.specimen_stiffness_n_per_m,
                o(rig.map(|x| x.delay_ms)),
                o(rig.map(|x| x.gain)),
                o(rig.map(|x| x.ats_initial[0])),
                o(rig.map(|x| x.ats_initial[1])),
                o(rig.map(|x| x.ats_initial[2])),
                o(rig.map(|x| x.stiffness_kn_per_mm)),
                run.record,
                o(scale),
                run.controller,
                run.stable,
                // Reasons are debug names or refusals: keep the CSV's commas its own.
                run.stop_reason.as_deref().unwrap_or("").replace(',', ";"),
                o(run.nrmse_measured_pct),
                o(run.j4_pct)
            );
        }
    }
    s
}

/// Write `report.md`, `robustness.json`, `runs.csv` and `robustness.png` into `dir`; returns the
/// files written.
pub fn write(r: &Robustness, j: &RobustnessJson<'_>, dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let files = [
        (dir.join("report.md"), markdown(r, j)),
        (
            dir.join("robustness.json"),
            serde_json::to_string_pretty(j)? + "\n",
        ),
        (dir.join("runs.csv"), csv(r)),
    ];
    let mut written = Vec::new();
    for (path, text) in files {
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        written.push(path);
    }
    let png = dir.join("robustness.png");
    super::figure::draw(r, &png)?;
    written.push(png);
    Ok(written)
}

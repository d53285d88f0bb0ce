//! The lead's online adaptation (`rths_core::compensator::LeadAdaptParams`): the identified LRX with
//! and without it against `fe-online-ats`, over uncertainty draws, specimens and records LRX never
//! saw; the drifting actuator; and what the adaptation must never do (bounds, NaN, frozen sensor).
//!
//! The controller side sees only the DAQ: each draw's lead comes from `rths identify` on that drawn
//! rig (measured signals), the adaptation from the measured displacement. Only the evaluation reads
//! the truth: the fair reference of the drawn specimen (`study::reference_for_rig`).
#![cfg(feature = "sim")]

use rayon::prelude::*;
use rths::identify::{identify_virtual, IdentifyConfig};
use rths::model_file::ModelFile;
use rths::motion::GroundMotion;
use rths::scenario::{rig_config, ScenarioId, ScenarioReport, ScenarioSetup};
use rths::train::lrx::prototype_dynamics;
use rths_core::compensator::{LeadAdaptParams, LeadParams};
use rths_core::metamodel::LrxParams;
use rths_core::params::{DT_S, PAPER_DELAY_STEPS};
use rths_hal_sim::{BoucWen, Drift, FaultPlan, Preset, RigConfig, Specimen};

/// The shipped model's frame part (the lead is replaced by each rig's identified one).
fn shipped() -> (LrxParams, LeadParams) {
    let m = ModelFile::from_json(include_str!("../data/models/lrx.json")).unwrap();
    rths::models::lrx_params(&m).unwrap()
}

/// What `rths identify` finds on `rig` (measured signals only): the lead, and the specimen's mass
/// and damping at prototype scale (kN·s²/mm, kN·s/mm).
fn identified(rig: &RigConfig) -> (LeadParams, [f64; 2]) {
    let o = identify_virtual(rig, FaultPlan::none(), &IdentifyConfig::default()).unwrap();
    let id = &o.identification;
    (
        LeadParams::new(id.lead_weights, id.lead_stride).unwrap(),
        prototype_dynamics(&id.specimen),
    )
}

/// The plant's true specimen mass and damping (diagnosis only), prototype scale.
fn true_dynamics(rig: &RigConfig) -> [f64; 2] {
    let p = rig.build().unwrap();
    // kg and N·s/m are 1e-6 kN·s²/mm and kN·s/mm.
    prototype_dynamics(&rths::identify::estimate::SpecimenFit {
        stiffness_kn_per_mm: 1.0,
        damping_kn_s_per_mm: p.specimen_damping_n_s_per_m() * 1e-6,
        mass_kn_s2_per_mm: p.specimen_mass_kg() * 1e-6,
        r2: 1.0,
    })
}

/// A held-out record, scaled to fit: (label, ground acceleration). The scale is the sweep's
/// (velocity and stroke within 90% of the interlocks) and, in steps of 0.05, also keeps the
/// following error a delay of `delay_s` (identified on the nominal rig) causes at the reference's
/// peak velocity within 90% of the interlock: on `benchmark` (25 ms) that binds first. A test
/// planned for a drifting actuator passes the delay it will reach (a compensated command leads the
/// measured displacement by the whole delay, so the following error grows with it).
fn record(name: &str, delay_s: f64) -> (String, Vec<f64>) {
    let m = match name {
        "morgan" => GroundMotion::from_path(std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/data/vrths_benchmark/morgan.csv"
        )))
        .unwrap(),
        n => GroundMotion::embedded(n).unwrap(),
    };
    let ag1 = m.resample_mm_s2(DT_S);
    let mut scale = rths::sweep::fitting_scale(&ag1).unwrap();
    let limit = rths_core::supervisor::Limits::paper_actuator().following_error_mm();
    for (spec, f) in rths::sweep::cases() {
        let r = rths::study::reference_for(&ag1, spec, f).unwrap();
        let v = r
            .windows(2)
            .map(|w| ((w[1] - w[0]) / DT_S).abs())
            .fold(0.0, f64::max);
        let fit = rths::sweep::MARGIN * limit / (v * delay_s);
        scale = scale.min((fit * 20.0).floor() / 20.0);
    }
    (
        format!("{name}×{scale}"),
        m.scaled(scale).resample_mm_s2(DT_S),
    )
}

/// One run's figures.
fn run(
    id: ScenarioId,
    ag: &[f64],
    reference: &[f64],
    rig: RigConfig,
    f: f64,
    lrx: Option<(LrxParams, LeadParams)>,
) -> ScenarioReport {
    rths::scenario::run(&ScenarioSetup {
        id,
        ground_accel_mm_s2: ag,
        reference_mm: reference,
        rig,
        stiffness_factor: f,
        lr: None,
        rnn: None,
        delay_steps: PAPER_DELAY_STEPS,
        lrx,
    })
    .unwrap()
    .report
}

fn median_max(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[v.len() - 1])
}

/// The measured table: rows = record × specimen × draw; columns = LRX identified fixed, LRX
/// identified adaptive (`adapt_ticks`), `fe-online-ats`. Prints every row and the summary; returns
/// (median, max) measured NRMSE and the J4 median per column, and whether the adaptive LRX beat
/// `fe-online-ats` on every row.
fn table(preset: Preset, draws: u64, adapt_ticks: f64, drift: f64) -> Vec<(f64, f64, f64)> {
    let (frame, _) = shipped();
    let adapt = LeadAdaptParams::new(adapt_ticks).unwrap();
    let cases = [
        (Specimen::Linear, 0.7),
        (Specimen::Linear, 1.0),
        (Specimen::Linear, 1.3),
        (Specimen::BoucWen(BoucWen::default()), 1.0),
    ];
    let nominal = rig_config(preset, Specimen::Linear, 1.0, 1);
    let delay_s = identify_virtual(&nominal, FaultPlan::none(), &IdentifyConfig::default())
        .unwrap()
        .identification
        .delay_s;
    let records: Vec<(String, Vec<f64>)> = ["el-centro", "kobe", "morgan"]
        .iter()
        .map(|n| record(n, delay_s / (1.0 - drift)))
        .collect();
    let mut jobs = Vec::new();
    for seed in 1..=draws {
        for (spec, f) in cases {
            jobs.push((seed, spec, f));
        }
    }
    // Identify each drawn rig once with its specimen installed, as a lab would.
    let leads: Vec<(LeadParams, [f64; 2])> = jobs
        .par_iter()
        .map(|&(seed, spec, f)| {
            let mut rig = rig_config(preset, spec, f, seed);
            rig.uncertainty = true;
            identified(&rig)
        })
        .collect();
    let mut rows: Vec<(String, [ScenarioReport; 6])> = jobs
        .par_iter()
        .zip(&leads)
        .flat_map(|(&(seed, spec, f), (lead, [m, c]))| {
            records
                .par_iter()
                .map(|(name, ag)| {
                    let mut rig = rig_config(preset, spec, f, seed);
                    rig.uncertainty = true;
                    // The actuator drifts during the test, after its identification.
                    rig.drift = Drift::over(drift, ag.len() as u64);
                    let (reference, _) = rths::study::reference_for_rig(ag, &rig, f).unwrap();
                    let fixed = run(
                        ScenarioId::LrxOnline,
                        ag,
                        &reference,
                        rig,
                        f,
                        Some((frame, *lead)),
                    );
                    let adaptive = run(
                        ScenarioId::LrxOnline,
                        ag,
                        &reference,
                        rig,
                        f,
                        Some((frame, lead.with_adaptation(Some(adapt)))),
                    );
                    let ats = run(ScenarioId::FeOnlineAts, ag, &reference, rig, f, None);
                    let lead_a = lead.with_adaptation(Some(adapt));
                    let fm = frame.with_specimen_dynamics(*m, *c, DT_S).unwrap();
                    let full = run(
                        ScenarioId::LrxOnline,
                        ag,
                        &reference,
                        rig,
                        f,
                        Some((fm, lead_a)),
                    );
                    let fixed_mc = run(
                        ScenarioId::LrxOnline,
                        ag,
                        &reference,
                        rig,
                        f,
                        Some((fm, *lead)),
                    );
                    let [mt, ct] = true_dynamics(&rig);
                    let ft = frame.with_specimen_dynamics(mt, ct, DT_S).unwrap();
                    let oracle = run(
                        ScenarioId::LrxOnline,
                        ag,
                        &reference,
                        rig,
                        f,
                        Some((ft, lead_a)),
                    );
                    let label =
                        format!("{} {name} {} F={f} draw {seed}", preset.name(), spec.name());
                    (label, [fixed, adaptive, ats, full, oracle, fixed_mc])
                })
                .collect::<Vec<_>>()
        })
        .collect();
    rows.sort_by(|a, b| a.0.cmp(&b.0));
    let meas = |r: &ScenarioReport| r.nrmse_measured_pct.unwrap_or(f64::INFINITY);
    let j4 = |r: &ScenarioReport| r.j4_pct.unwrap_or(f64::INFINITY);
    let mut behind = 0;
    for (label, r) in &rows {
        let ahead = meas(&r[3]) < meas(&r[2]);
        behind += usize::from(!ahead);
        println!(
            "{label:44} fixed {:5.2}%  adaptive {:5.2}%  fixed+m,c {:5.2}%  adaptive+m,c {:5.2}% (true m,c {:5.2}%)  fe-online-ats {:5.2}%{}",
            meas(&r[0]),
            meas(&r[1]),
            meas(&r[5]),
            meas(&r[3]),
            meas(&r[4]),
            meas(&r[2]),
            if ahead { "" } else { "  <- not ahead" }
        );
        if std::env::var_os("RTHS_DIAG").is_some() {
            for (n, x) in ["fixed", "adaptive", "ats", "+m,c", "+true", "fixed+m,c"]
                .iter()
                .zip(r)
            {
                if let Some(why) = &x.stop_reason {
                    println!("    {n:9} stopped: {why} at {:?} s", x.stop_time_s);
                }
                println!(
                    "    {n:9} target-vs-ref {:.3}%  J1/J2 vs target {:.3} ms / {:.3}%  J4 {:.3}%",
                    x.nrmse_pct.unwrap_or(f64::NAN),
                    x.j1_target_ms.unwrap_or(f64::NAN),
                    x.j2_target_pct.unwrap_or(f64::NAN),
                    x.j4_pct.unwrap_or(f64::NAN)
                );
            }
        }
    }
    let mut out = Vec::new();
    for (j, name) in [
        "lrx fixed",
        "lrx adaptive",
        "fe-online-ats",
        "lrx adaptive+m,c",
        "lrx adaptive+true m,c",
        "lrx fixed+m,c",
    ]
    .iter()
    .enumerate()
    {
        let (med, max) = median_max(rows.iter().map(|r| meas(&r.1[j])).collect());
        let (j4m, _) = median_max(rows.iter().map(|r| j4(&r.1[j])).collect());
        println!(
            "{} {name:14} measured NRMSE median {med:.2}% max {max:.2}%  J4 median {j4m:.2}%  ({} rows)",
            preset.name(),
            rows.len()
        );
        out.push((med, max, j4m));
    }
    println!(
        "{}: adaptive+m,c LRX behind fe-online-ats on {behind} of {} rows",
        preset.name(),
        rows.len()
    );
    out
}

fn draws() -> u64 {
    std::env::var("RTHS_DRAWS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10)
}

fn drift() -> f64 {
    std::env::var("RTHS_DRIFT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.0)
}

fn adapt_ticks() -> f64 {
    std::env::var("RTHS_LEAD_ADAPT_TICKS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(4096.0)
}

/// The measurement behind docs/lrx.md's adaptation table on `benchmark` (slow: `--ignored`;
/// `RTHS_DRAWS`, `RTHS_LEAD_ADAPT_TICKS` override the 10 draws and the time constant;
/// `RTHS_DRIFT=F` makes every actuator drift by F over the record).
#[test]
#[ignore]
fn adaptation_table_benchmark() {
    table(Preset::Benchmark, draws(), adapt_ticks(), drift());
}

/// The same on `unr-compact` (slow: `--ignored`).
#[test]
#[ignore]
fn adaptation_table_unr_compact() {
    table(Preset::UnrCompact, draws(), adapt_ticks(), drift());
}

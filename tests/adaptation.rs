//! The lead's online adaptation (`rths_core::compensator::LeadAdaptParams`): the identified LRX with
//! and without it against `fe-online-ats`, over uncertainty draws, specimens and records LRX never
//! saw; the drifting actuator; and what the adaptation must never do (bounds, NaN, frozen sensor).
//!
//! The controller side sees only the DAQ: each draw's lead comes from `rths identify` on that drawn
//! rig (measured signals), the adaptation from the measured displacement. Only the evaluation reads
//! the truth: the fair reference of the drawn specimen (`study::reference_for_rig`).
#![cfg(feature = "sim")]

mod common;
use common::*;
use std::path::Path;
use std::process::Command;

use rayon::prelude::*;
use rths::machinery::identify::{identify_virtual, IdentifyConfig};
use rths::machinery::model_file::ModelFile;
use rths::machinery::motion::GroundMotion;
use rths::machinery::reference::rig_config;
use rths::machinery::train::lrx::prototype_dynamics;
use rths::studies::scenario::{ScenarioId, ScenarioReport, ScenarioSetup};
use rths_core::compensator::{LeadAdaptParams, LeadParams};
use rths_core::metamodel::LrxParams;
use rths_core::params::{DT_S, PAPER_DELAY_STEPS};
use rths_hal_sim::{BoucWen, Drift, FaultPlan, Preset, RigConfig, Specimen};

/// The shipped model's frame part (the lead is replaced by each rig's identified one).
fn shipped() -> (LrxParams, LeadParams) {
    let m = ModelFile::from_json(include_str!("../data/models/lrx.json")).unwrap();
    rths::machinery::models::lrx_params(&m).unwrap()
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
    prototype_dynamics(&rths::machinery::identify::estimate::SpecimenFit {
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
    let scale =
        rths::studies::sweep::fitting_scale_for_delay(&m.resample_mm_s2(DT_S), delay_s).unwrap();
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
    rths::studies::scenario::run(&ScenarioSetup {
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
    let med = rths_core::metrics::median(&mut v).expect("rows");
    (med, v[v.len() - 1])
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
                    let (reference, _) =
                        rths::studies::study::reference_for_rig(ag, &rig, f).unwrap();
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

/// `rths identify` then `rths train lrx --rig` on a preset's nominal rig (seed 1), in `dir`:
/// the model file, as a lab would make it.
fn rig_model(dir: &Path, preset: &str) -> ModelFile {
    let rig = dir.join("rig.json");
    let model = dir.join("lrx.json");
    let o = Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(["identify", "--preset", preset, "--out"])
        .arg(&rig)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(["train", "lrx", "--quiet", "--rig"])
        .arg(&rig)
        .arg("--out")
        .arg(&model)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    ModelFile::load(&model).unwrap()
}

/// El Centro's first `seconds` at `scale`.
fn el_centro(scale: f64, seconds: f64) -> Vec<f64> {
    let mut ag = GroundMotion::el_centro().scaled(scale).resample_mm_s2(DT_S);
    ag.truncate((seconds / DT_S) as usize);
    ag
}

/// A rig model adapts on a plant it was not identified on, through a drift: identified on the
/// nominal `benchmark` rig, run on a drawn rig (seed 7) whose actuator slows by 30% over the run.
/// The fixed lead's tracking degrades with the drift; the adapted one holds the goal.
#[test]
fn adaptation_holds_the_goal_on_another_plant_through_a_drift() {
    let dir = tempfile::tempdir().unwrap();
    let file = rig_model(dir.path(), "benchmark");
    let w = file.lrx.as_ref().unwrap();
    assert_eq!(
        w.lead_adapt_ticks,
        Some(rths::machinery::train::lrx::RIG_LEAD_ADAPT_TICKS)
    );
    assert!(w.specimen_mass_kn_s2_per_mm.unwrap() > 0.0);
    let (frame, lead) = rths::machinery::models::lrx_params(&file).unwrap();
    assert!(lead.adaptation().is_some());
    let ag = el_centro(0.8, 30.0);
    let mut rig = rig_config(Preset::Benchmark, Specimen::Linear, 1.0, 7);
    rig.uncertainty = true;
    rig.drift = Drift::over(0.3, ag.len() as u64);
    let (reference, _) = rths::studies::study::reference_for_rig(&ag, &rig, 1.0).unwrap();
    let fixed_lead = LeadParams::new(*lead.weights(), lead.stride()).unwrap();
    let fixed = run(
        ScenarioId::LrxOnline,
        &ag,
        &reference,
        rig,
        1.0,
        Some((frame, fixed_lead)),
    );
    let adaptive = run(
        ScenarioId::LrxOnline,
        &ag,
        &reference,
        rig,
        1.0,
        Some((frame, lead)),
    );
    let meas = |r: &ScenarioReport| r.nrmse_measured_pct.unwrap();
    println!(
        "drift 0.3, draw 7: measured NRMSE fixed {:.3}% adaptive {:.3}%; tracking J2 {:.3}% vs {:.3}%",
        meas(&fixed),
        meas(&adaptive),
        fixed.j2_target_pct.unwrap(),
        adaptive.j2_target_pct.unwrap()
    );
    assert!(meas(&adaptive) < 1.0, "{adaptive:?}");
    assert!(meas(&adaptive) < 0.6 * meas(&fixed));
    assert!(adaptive.j2_target_pct.unwrap() < 0.5 * fixed.j2_target_pct.unwrap());
}

/// The drift slows the actuator as documented (delay × ~1/(1 − F) at the end, DC gain kept), it
/// is off by default (the undrifted plant keeps its exact ticks: every existing plant figure and
/// the firmware's bit-identity tests are unchanged), and a bad drift is refused.
#[test]
fn the_drift_slows_the_actuator_and_is_off_by_default() {
    let rig = rig_config(Preset::Benchmark, Specimen::Linear, 1.0, 1);
    assert_eq!(rig.drift, Drift::none());
    let p = rig.build().unwrap();
    let delay_ms =
        |q: &rths_hal_sim::PlantParams| -q.frequency_response(0.5).phase_deg / (360.0 * 0.5) * 1e3;
    let slowed = p.with_actuator_speed(0.7);
    let (d0, d1) = (delay_ms(&p), delay_ms(&slowed));
    println!("benchmark delay {d0:.2} ms, after a 30% drift {d1:.2} ms");
    assert!(d1 > 1.25 * d0 && d1 < 1.5 * d0, "{d0} -> {d1}");
    let g = |q: &rths_hal_sim::PlantParams| q.frequency_response(0.01).gain;
    assert!((g(&slowed) / g(&p) - 1.0).abs() < 1e-3);
    // A drifting rig departs from the still one under the same commands.
    let mut a = rths_hal_sim::VirtualRig::new(p);
    let mut drifting = rig;
    drifting.drift = Drift::over(0.3, 1000);
    assert!(drifting.build().unwrap().drift().is_active());
    let mut b = rths_hal_sim::VirtualRig::new(drifting.build().unwrap());
    use rths_core::hal::{Actuator, Daq};
    let mut differ = false;
    for k in 0..2000 {
        let u = (k as f64 * 0.01).sin();
        a.command(u).unwrap();
        b.command(u).unwrap();
        a.advance_tick();
        b.advance_tick();
        differ |= a.read().unwrap() != b.read().unwrap();
    }
    assert!(differ, "a 30% drift changed nothing");
    let mut bad = rig;
    bad.drift = Drift::over(0.95, 10);
    assert!(bad.build().is_err());
    bad.drift = Drift::over(0.2, 0);
    assert!(bad.build().is_err());
}

/// A model file written before the adaptation (the shipped one) loads to a fixed lead and the
/// force as measured, and is written back without the new fields; bad new fields are refused by
/// name.
#[test]
fn an_old_model_file_behaves_as_before_and_bad_fields_are_refused() {
    let text = include_str!("../data/models/lrx.json");
    let m = ModelFile::from_json(text).unwrap();
    let (frame, lead) = rths::machinery::models::lrx_params(&m).unwrap();
    assert!(lead.adaptation().is_none());
    assert_eq!(frame.specimen_dynamics(), (0.0, 0.0));
    let again = m.to_json().unwrap();
    assert!(!again.contains("lead_adapt_ticks") && !again.contains("specimen_mass"));
    for (field, value, named) in [
        ("lead_adapt_ticks", "5.0", "lrx.lead_adapt_ticks"),
        (
            "specimen_mass_kn_s2_per_mm",
            "-1.0",
            "lrx.specimen_mass_kn_s2_per_mm",
        ),
        (
            "specimen_damping_kn_s_per_mm",
            "-0.5",
            "lrx.specimen_damping_kn_s_per_mm",
        ),
    ] {
        let bad = text.replacen(
            "\"lead_stride\": 6",
            &format!("\"lead_stride\": 6, \"{field}\": {value}"),
            1,
        );
        assert_ne!(bad, text);
        let e = ModelFile::from_json(&bad)
            .and_then(|f| f.validate().map(|_| f))
            .unwrap_err();
        assert!(e.to_string().contains(named), "{e}");
    }
}

/// The adaptive LRX (a `rths train lrx --rig` model) in the firmware: the same command as the host,
/// within the timing budget, 0 overruns and faults. Needs QEMU (skipped loudly without it).
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn adaptive_lrx_firmware_matches_the_host_and_fits_the_budget() {
    if qemu_missing("adaptive LRX firmware test") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let file = rig_model(dir.path(), "unr-compact");
    let status = Command::new(env!("CARGO"))
        .current_dir(firmware_dir())
        .args(["build", "--release"])
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("RTHS_STRUCTURE")
        .env_remove("RTHS_BUDGET")
        .env("RTHS_MODEL", dir.path().join("lrx.json"))
        .status()
        .unwrap();
    assert!(
        status.success(),
        "firmware build (the adaptive LRX default) failed"
    );
    let elf = dir.path().join("rths-firmware-lrx-adaptive.elf");
    std::fs::copy(
        firmware_dir().join("target/thumbv7em-none-eabihf/release/rths-firmware"),
        &elf,
    )
    .unwrap();
    let (exit, r) = run_elf_in_qemu(&elf);
    assert!(exit.success(), "{r}");
    assert_eq!(r["ticks"], 81_900);
    assert_eq!(r["overruns"], 0);
    assert_eq!(r["faults"], 0);
    let max = r["instr_per_tick"]["max"].as_f64().unwrap();
    let share = max * CYCLES_PER_INSTR / CPU_HZ * 2048.0;
    println!(
        "adaptive lrx firmware: max {max} instructions per tick = {:.2}% of the tick",
        share * 100.0
    );
    assert!(share <= MAX_TICK_SHARE, "{max} instructions");
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    let reference = rths::studies::study::reference_for(&ag, Specimen::Linear, 1.0).unwrap();
    let host = run(
        ScenarioId::LrxOnline,
        &ag,
        &reference,
        rig_config(Preset::UnrCompact, Specimen::Linear, 1.0, 1),
        1.0,
        Some(rths::machinery::models::lrx_params(&file).unwrap()),
    );
    let (h, f) = (host.nrmse_pct.unwrap(), r["nrmse_pct"].as_f64().unwrap());
    println!("NRMSE host {h} % vs firmware {f} %");
    assert!((h - f).abs() < 1e-9, "host {h} vs firmware {f}");
}

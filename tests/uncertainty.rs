//! Fair references (issue 12): a run on a drawn plant is judged against the structure with the
//! specimen the plant really has, and a model or rig file of another rig is refused.
#![cfg(feature = "sim")]

use std::process::Command;

use rths::machinery::model_file::ModelFile;
use rths::machinery::models;
use rths::machinery::motion::GroundMotion;
use rths::studies::scenario::{self, ScenarioId, ScenarioRun, ScenarioSetup};
use rths::studies::study::{self, DrawnPlant};
use rths_core::metrics;
use rths_core::params::{DT_S, PAPER_DELAY_STEPS};
use rths_hal_sim::{BoucWen, Preset, RigConfig, Specimen};

const LR: &str = include_str!("../data/models/lr.json");
const LRX: &str = include_str!("../data/models/lrx.json");

/// A held-out record (the shipped LRX was trained on Northridge and Loma Prieta) at the scale the
/// specimen sweep gives it (Kobe × 0.4, El Centro × 0.85).
fn held_out(name: &str) -> (Vec<f64>, f64) {
    let m = GroundMotion::embedded(name).unwrap();
    let scale = rths::studies::sweep::fitting_scale(&m.resample_mm_s2(DT_S)).unwrap();
    (m.scaled(scale).resample_mm_s2(DT_S), scale)
}

fn uncertain_rig(seed: u64) -> RigConfig {
    let mut rig =
        rths::machinery::reference::rig_config(Preset::UnrCompact, Specimen::Linear, 1.0, seed);
    rig.uncertainty = true;
    rig
}

/// One closed loop of `id` (shipped models) on `rig`, judged against `reference`.
fn run(id: ScenarioId, ag: &[f64], reference: &[f64], rig: RigConfig) -> ScenarioRun {
    let lr = models::lr_params(&ModelFile::from_json(LR).unwrap()).unwrap();
    let lrx = models::lrx_params(&ModelFile::from_json(LRX).unwrap()).unwrap();
    scenario::run(&ScenarioSetup {
        id,
        ground_accel_mm_s2: ag,
        reference_mm: reference,
        rig,
        stiffness_factor: 1.0,
        lr: Some(lr),
        rnn: None,
        delay_steps: PAPER_DELAY_STEPS,
        lrx: Some(lrx),
    })
    .unwrap()
}

#[test]
fn a_nominal_plant_keeps_its_reference_bit_for_bit() {
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    for (specimen, f) in [
        (Specimen::Linear, 1.0),
        (Specimen::Linear, 0.8),
        (Specimen::BoucWen(BoucWen::default()), 1.0),
    ] {
        let rig = rths::machinery::reference::rig_config(Preset::UnrCompact, specimen, f, 1);
        let (fair, draw) = study::reference_for_rig(&ag, &rig, f).unwrap();
        assert!(!draw.uncertainty);
        assert_eq!(draw.specimen_stiffness_factor.to_bits(), f.to_bits());
        assert_eq!(draw.beta1, rths_hal_sim::params::NOMINAL_BETA1);
        assert_eq!(draw.beta2, rths_hal_sim::params::NOMINAL_BETA2);
        assert_eq!(draw.a3, rths_hal_sim::params::NOMINAL_A3);
        let nominal = study::reference_for(&ag, specimen, f).unwrap();
        assert!(fair
            .iter()
            .zip(&nominal)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}

#[test]
fn the_draw_is_the_plants_and_the_reference_follows_it() {
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    let rig = uncertain_rig(3);
    let plant = rig.build().unwrap();
    let (fair, draw) = study::reference_for_rig(&ag, &rig, 1.0).unwrap();
    assert!(draw.uncertainty && draw.seed == 3);
    assert_eq!(
        draw.specimen_stiffness_n_per_m,
        plant.specimen_stiffness_n_per_m()
    );
    let r = plant.time_scale();
    assert!((draw.beta1 * r / plant.beta1() - 1.0).abs() < 1e-12);
    assert!((draw.beta2 * r * r / plant.beta2() - 1.0).abs() < 1e-12);
    assert!((draw.a3 * r / plant.a3() - 1.0).abs() < 1e-12);
    let nominal_k = RigConfig::new(Preset::UnrCompact).specimen_stiffness_kn_per_mm * 1e6;
    let f = draw.specimen_stiffness_factor;
    assert!((f - plant.specimen_stiffness_n_per_m() / nominal_k).abs() < 1e-12);
    // At F = 0.8 the same seed draws the same offset (σ·z is additive), and the effective factor
    // is the drawn stiffness over the paper's brace.
    let mut c08 =
        rths::machinery::reference::rig_config(Preset::UnrCompact, Specimen::Linear, 0.8, 3);
    c08.uncertainty = true;
    let d08 = DrawnPlant::of(&c08, 0.8).unwrap();
    let k08 = c08.specimen_stiffness_kn_per_mm * 1e6;
    let offset = draw.specimen_stiffness_n_per_m - nominal_k;
    assert!((d08.specimen_stiffness_n_per_m - k08 - offset).abs() < 1e-6);
    assert!(
        (d08.specimen_stiffness_factor - d08.specimen_stiffness_n_per_m / nominal_k).abs() < 1e-12
    );
    let expect = study::reference_for(&ag, Specimen::Linear, f).unwrap();
    assert_eq!(fair, expect);
}

/// Seed 3 draws a specimen 6 % stiffer than the paper's brace: judged against the nominal
/// structure, `lrx-online` seems to miss by several percent; against the structure it really
/// tested, it tracks within about 1 %.
#[test]
fn a_drawn_specimen_is_judged_against_its_own_structure() {
    let (ag, _) = held_out("kobe");
    let rig = uncertain_rig(3);
    let (fair, draw) = study::reference_for_rig(&ag, &rig, 1.0).unwrap();
    assert!(
        (draw.specimen_stiffness_factor - 1.0).abs() > 0.03,
        "{draw:?}"
    );
    let nominal = study::reference_for(&ag, Specimen::Linear, 1.0).unwrap();
    let out = run(ScenarioId::LrxOnline, &ag, &fair, rig);
    let fair_pct = out.report.nrmse_measured_pct.unwrap();
    let nominal_pct = metrics::nrmse_pct(&out.history.measured_mm, &nominal).unwrap();
    println!("lrx-online kobe seed 3: fair {fair_pct:.3} %, nominal {nominal_pct:.3} %");
    assert!(fair_pct < 1.5, "fair {fair_pct} %");
    assert!(nominal_pct > 3.0, "nominal {nominal_pct} %");
}

fn stats(v: &mut [f64]) -> (f64, f64, f64) {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let median = if n % 2 == 0 {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    } else {
        v[n / 2]
    };
    (v[0], median, v[n - 1])
}

/// The figures: 20 draws on the held-out records, measured NRMSE against the nominal and
/// the fair reference (`cargo test --release --features sim --test uncertainty -- --ignored
/// --nocapture`).
#[test]
#[ignore = "measurement: 120 closed loops"]
fn measure_twenty_draws_on_held_out_records() {
    let mut all: Vec<(ScenarioId, Vec<f64>, Vec<f64>)> = Vec::new();
    for name in ["kobe", "el-centro"] {
        let (ag, scale) = held_out(name);
        let nominal = study::reference_for(&ag, Specimen::Linear, 1.0).unwrap();
        let mut draws: Vec<(RigConfig, Vec<f64>, DrawnPlant)> = Vec::new();
        for seed in 1..=20 {
            let rig = uncertain_rig(seed);
            let (fair, draw) = study::reference_for_rig(&ag, &rig, 1.0).unwrap();
            draws.push((rig, fair, draw));
        }
        let mut fs: Vec<f64> = draws
            .iter()
            .map(|d| d.2.specimen_stiffness_factor)
            .collect();
        let (lo, med, hi) = stats(&mut fs);
        println!("{name} × {scale}: effective F {lo:.4} / {med:.4} / {hi:.4} (min/median/max)");
        for id in [
            ScenarioId::LrxOnline,
            ScenarioId::FeOnlineAts,
            ScenarioId::LrOnline,
        ] {
            let (mut old, mut new) = (Vec::new(), Vec::new());
            for (rig, fair, _) in &draws {
                let out = run(id, &ag, fair, *rig);
                new.push(out.report.nrmse_measured_pct.unwrap_or(f64::NAN));
                old.push(
                    metrics::nrmse_pct(&out.history.measured_mm, &nominal).unwrap_or(f64::NAN),
                );
            }
            match all.iter_mut().find(|a| a.0 == id) {
                Some(a) => {
                    a.1.extend(&old);
                    a.2.extend(&new);
                }
                None => all.push((id, old.clone(), new.clone())),
            }
            let (o0, o1, o2) = stats(&mut old);
            let (n0, n1, n2) = stats(&mut new);
            println!(
                "  {:14} measured NRMSE nominal ref {o0:6.2} / {o1:6.2} / {o2:6.2} %   fair ref {n0:6.2} / {n1:6.2} / {n2:6.2} %",
                id.to_string()
            );
        }
    }
    println!("both records (40 runs each):");
    for (id, mut old, mut new) in all {
        let (o0, o1, o2) = stats(&mut old);
        let (n0, n1, n2) = stats(&mut new);
        println!(
            "  {:14} measured NRMSE nominal ref {o0:6.2} / {o1:6.2} / {o2:6.2} %   fair ref {n0:6.2} / {n1:6.2} / {n2:6.2} %",
            id.to_string()
        );
    }
}

fn simulate(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_rths"))
        .arg("simulate")
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn the_json_reports_the_plant() {
    let o = simulate(&[
        "--scenario",
        "fe-online",
        "--uncertainty",
        "--seed",
        "3",
        "--json",
    ]);
    // Stopped by the supervisor (fe-online diverges): its object printed, then exit status 3.
    assert!(
        o.status.code() == Some(3),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let p = &v["plant"];
    assert_eq!(p["uncertainty"], true);
    assert_eq!(p["seed"], 3);
    let k = uncertain_rig(3)
        .build()
        .unwrap()
        .specimen_stiffness_n_per_m();
    assert_eq!(p["specimen_stiffness_n_per_m"].as_f64().unwrap(), k);
    for f in ["beta1", "beta2", "a3", "specimen_stiffness_factor"] {
        assert!(p[f].as_f64().is_some(), "{f}");
    }
    // No plant in a pure run.
    let o = simulate(&["--scenario", "fe-pure", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["plant"].is_null() && v["scenarios"].is_array());
}

/// The shipped LRX with `training.rig` set as `rths train lrx --rig` writes it.
fn lrx_of_rig(dir: &std::path::Path, rig: &str) -> std::path::PathBuf {
    let mut m = ModelFile::from_json(LRX).unwrap();
    m.training.rig = Some(rig.into());
    let path = dir.join(format!("lrx-{}.json", rig.replace(' ', "-")));
    std::fs::write(&path, m.to_json().unwrap()).unwrap();
    path
}

fn refused(o: &std::process::Output, reason: &str) {
    let stderr = String::from_utf8_lossy(&o.stderr);
    println!("{stderr}");
    assert!(!o.status.success(), "ran: {stderr}");
    assert!(o.stdout.is_empty(), "something ran");
    assert!(stderr.contains(reason), "{stderr}");
}

#[test]
fn a_model_or_rig_file_of_another_rig_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A model whose lead filter came from a benchmark rig, on the (default) unr-compact preset.
    let m = lrx_of_rig(d, "benchmark virtual 0123456789abcdef");
    let ms = m.to_str().unwrap();
    refused(
        &simulate(&["--scenario", "lrx-online", "--model", ms]),
        "trained for the rig `benchmark virtual",
    );
    // … or from a real board.
    let m2 = lrx_of_rig(d, "unr-compact stm32f4 0123456789abcdef");
    refused(
        &simulate(&["--scenario", "lrx-online", "--model", m2.to_str().unwrap()]),
        "board virtual",
    );
    // On its own preset it runs.
    let o = simulate(&[
        "--scenario",
        "lrx-online",
        "--preset",
        "benchmark",
        "--model",
        ms,
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));

    // A rig file of the benchmark preset: refused on unr-compact, and against a model of
    // another identification; accepted with the model trained on it.
    let rig = d.join("rig.json");
    let o = Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(["identify", "--preset", "benchmark", "--out"])
        .arg(&rig)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rs = rig.to_str().unwrap();
    refused(
        &simulate(&["--scenario", "fe-online", "--rig", rs]),
        "preset",
    );
    refused(
        &simulate(&[
            "--scenario",
            "lrx-online",
            "--preset",
            "benchmark",
            "--rig",
            rs,
            "--model",
            ms,
        ]),
        "another identification",
    );
    let sum = rths::machinery::identify::rig_file::checksum_hex(&std::fs::read(&rig).unwrap());
    let own = lrx_of_rig(d, &format!("benchmark virtual {sum}"));
    let o = simulate(&[
        "--scenario",
        "lrx-online",
        "--preset",
        "benchmark",
        "--rig",
        rs,
        "--model",
        own.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

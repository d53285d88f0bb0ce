//! `rths robustness` (issue 12): the study's rows and reports, and the rig checks it relies on —
//! `simulate --rig` refuses a rig identified on another plant, and `fe-online-ats` starts its ATS
//! from the rig's identified initial values.
#![cfg(feature = "sim")]

use std::path::Path;
use std::process::{Command, Output};

use rths::machinery::motion::GroundMotion;
use rths::studies::scenario::{self, ScenarioId, ScenarioSetup};
use rths::studies::study::{self, DrawnPlant};
use rths_core::params::{DT_S, PAPER_DELAY_STEPS};
use rths_hal_sim::{Preset, Specimen};

fn rths(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(args)
        .output()
        .unwrap()
}

fn ok(o: &Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `rths identify` with `extra` arguments into `path`.
fn identify(path: &Path, extra: &[&str]) {
    let mut args = vec!["identify", "--out", path.to_str().unwrap()];
    args.extend_from_slice(extra);
    ok(&rths(&args));
}

#[test]
fn a_quick_study_has_every_row_and_lists_the_draws() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rob");
    let o = rths(&[
        "robustness",
        "--quick",
        "--seed",
        "5",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    ok(&o);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let draws = v["draws"].as_u64().unwrap() as usize;
    assert_eq!(draws, rths::studies::robustness::QUICK_DRAWS);
    let records = v["records"].as_array().unwrap();
    let names: Vec<&str> = records
        .iter()
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["el-centro", "kobe", "morgan-hill"]);
    for r in records {
        let s = r["scale"].as_f64().unwrap();
        assert!(s > 0.0 && s <= 1.0, "{r}");
    }
    // 2 presets × 4 specimens × 3 controllers, each over draws × records runs.
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2 * 4 * 3);
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r["runs"].as_u64().unwrap() as usize, draws * 3, "{r}");
        let stable = r["stable"].as_u64().unwrap();
        assert!(stable <= r["runs"].as_u64().unwrap());
        let id = ["lr-online", "fe-online-ats", "lrx-online"][i % 3];
        assert_eq!(r["controller"], id);
        if stable > 0 {
            let (med, max) = (
                r["nrmse_median_pct"].as_f64().unwrap(),
                r["nrmse_max_pct"].as_f64().unwrap(),
            );
            assert!(med > 0.0 && med <= max, "{r}");
            assert!(r["j4_median_pct"].as_f64().unwrap() > 0.0, "{r}");
        }
    }
    assert_eq!(rows[0]["preset"], "unr-compact");
    assert_eq!(rows[12]["preset"], "benchmark");
    assert_eq!(v["goals"].as_array().unwrap().len(), 2 * 4);
    assert!(v["threads"].as_u64().unwrap() >= 1);

    // Every job's plant is the draw of its seed, as the simulator has it; the identification saw
    // an actuator of about the preset's delay.
    let jobs = v["jobs"].as_array().unwrap();
    assert_eq!(jobs.len(), 2 * draws * 4);
    for j in jobs {
        let preset = match j["preset"].as_str().unwrap() {
            "benchmark" => Preset::Benchmark,
            _ => Preset::UnrCompact,
        };
        let f = j["stiffness_factor"].as_f64().unwrap();
        let seed = j["seed"].as_u64().unwrap();
        assert!((5..5 + draws as u64).contains(&seed));
        let mut rig = rths::machinery::reference::rig_config(preset, Specimen::Linear, f, seed);
        rig.uncertainty = true;
        let d = DrawnPlant::of(&rig, f).unwrap();
        assert_eq!(j["plant"]["beta1"].as_f64().unwrap(), d.beta1);
        assert_eq!(j["plant"]["a3"].as_f64().unwrap(), d.a3);
        assert_ne!(d.beta1, rths_hal_sim::params::NOMINAL_BETA1);
        let delay = j["rig"]["delay_ms"].as_f64().unwrap();
        let nominal = if preset == Preset::Benchmark {
            25.4
        } else {
            13.9
        };
        assert!((delay / nominal - 1.0).abs() < 0.15, "{j}");
    }

    // The files: the table, the JSON, the figure and one CSV line per run with its draw.
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    for needle in [
        "| preset | specimen | controller | runs |",
        "morgan-hill",
        "β1",
        "held out",
    ] {
        assert!(report.contains(needle), "report.md lacks {needle}");
    }
    assert!(out.join("robustness.png").metadata().unwrap().len() > 10_000);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("robustness.json")).unwrap())
            .unwrap();
    assert_eq!(json["rows"], v["rows"]);
    let csv = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    for col in [
        "seed",
        "beta1",
        "beta2",
        "a3",
        "specimen_stiffness_n_per_m",
        "ats_a1_s",
    ] {
        assert!(header.contains(&col), "{col}");
    }
    let body: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert_eq!(body.len(), 2 * draws * 4 * 3 * 3);
    assert!(body.iter().all(|r| r.len() == header.len()));
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let first = &body[0];
    let mut rig = rths::machinery::reference::rig_config(
        Preset::UnrCompact,
        Specimen::Linear,
        first[col("stiffness_factor")].parse().unwrap(),
        first[col("seed")].parse().unwrap(),
    );
    rig.uncertainty = true;
    let f: f64 = first[col("stiffness_factor")].parse().unwrap();
    let d = DrawnPlant::of(&rig, f).unwrap();
    assert_eq!(first[col("beta2")].parse::<f64>().unwrap(), d.beta2);
    assert_eq!(
        first[col("specimen_stiffness_n_per_m")]
            .parse::<f64>()
            .unwrap(),
        d.specimen_stiffness_n_per_m
    );
}

fn refused(o: &Output, reason: &str) {
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "ran: {stderr}");
    assert!(o.stdout.is_empty(), "something ran");
    assert!(stderr.contains(reason), "{stderr}");
}

#[test]
fn simulate_refuses_a_rig_identified_on_another_plant() {
    let dir = tempfile::tempdir().unwrap();
    let rig = dir.path().join("rig.json");
    identify(&rig, &["--seed", "2", "--uncertainty"]);
    let rs = rig.to_str().unwrap();
    let out = dir.path().join("never");
    let os = out.to_str().unwrap();
    let sim = |extra: &[&str]| {
        let mut a = vec![
            "simulate",
            "--scenario",
            "fe-online-ats",
            "--rig",
            rs,
            "--out",
            os,
        ];
        a.extend_from_slice(extra);
        rths(&a)
    };
    refused(
        &sim(&["--uncertainty", "--seed", "3"]),
        "identified on the uncertainty draw of seed 2, this run is on the uncertainty draw of seed 3",
    );
    refused(&sim(&["--seed", "2"]), "this run is on the nominal plant");
    refused(
        &sim(&["--uncertainty", "--seed", "2", "--specimen", "bouc-wen"]),
        "identified with the linear specimen, this run has the bouc-wen one",
    );
    refused(
        &sim(&[
            "--uncertainty",
            "--seed",
            "2",
            "--specimen-stiffness-factor",
            "0.7",
        ]),
        "specimen stiffness factor 1, this run has 0.7",
    );
    refused(
        &sim(&["--uncertainty", "--seed", "2", "--preset", "benchmark"]),
        "rig file is for preset `unr-compact`, this run uses `benchmark`",
    );
    assert!(!out.exists(), "a refused run wrote {}", out.display());
    // Its own plant runs; a nominal rig's file fits any noise seed (the seed is only the noise).
    ok(&sim(&["--uncertainty", "--seed", "2"]));
    assert!(out.join("history.csv").exists());
    let nominal = dir.path().join("nominal.json");
    identify(&nominal, &["--seed", "4"]);
    let o = rths(&[
        "simulate",
        "--scenario",
        "fe-online-ats",
        "--rig",
        nominal.to_str().unwrap(),
        "--seed",
        "9",
        "--json",
    ]);
    ok(&o);
}

#[test]
fn fe_online_ats_starts_from_the_identified_values() {
    let dir = tempfile::tempdir().unwrap();
    let rig = dir.path().join("rig.json");
    identify(&rig, &["--preset", "benchmark"]);
    let file = rths::machinery::identify::RigFile::load(&rig).unwrap();
    let identified = file.compensation.ats_initial;
    // The paper's start is the expected delay of 28 ticks; the benchmark actuator is slower.
    let tau = PAPER_DELAY_STEPS as f64 * DT_S;
    let paper = [1.0, tau, 0.5 * tau * tau];
    assert!(identified[1] > 1.5 * paper[1], "{identified:?}");

    let run = |rig_arg: bool| {
        let mut a = vec![
            "simulate",
            "--scenario",
            "fe-online-ats",
            "--preset",
            "benchmark",
            "--motion",
            "kobe",
            "--scale",
            "0.4",
            "--json",
        ];
        if rig_arg {
            a.extend_from_slice(&["--rig", rig.to_str().unwrap()]);
        }
        let o = rths(&a);
        ok(&o);
        serde_json::from_slice::<serde_json::Value>(&o.stdout).unwrap()
    };
    let (with, without) = (run(true), run(false));
    assert!(without.get("ats_initial").is_none(), "{without}");
    let used: Vec<f64> = with["ats_initial"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert_eq!(used, identified);
    let nrmse = |v: &serde_json::Value| v["scenarios"][0]["nrmse_measured_pct"].as_f64().unwrap();
    assert_ne!(nrmse(&with).to_bits(), nrmse(&without).to_bits());

    // In the library: the paper's values through the override are the default run bit for bit,
    // the identified ones change the commands from the first motion on.
    let ag = GroundMotion::embedded("kobe")
        .unwrap()
        .scaled(0.4)
        .resample_mm_s2(DT_S);
    let ag = &ag[..20_000];
    let rig_cfg =
        rths::machinery::reference::rig_config(Preset::Benchmark, Specimen::Linear, 1.0, 1);
    let reference = study::reference_for(ag, Specimen::Linear, 1.0).unwrap();
    let setup = ScenarioSetup {
        id: ScenarioId::FeOnlineAts,
        ground_accel_mm_s2: ag,
        reference_mm: &reference,
        rig: rig_cfg,
        stiffness_factor: 1.0,
        lr: None,
        rnn: None,
        delay_steps: PAPER_DELAY_STEPS,
        lrx: None,
    };
    let default = scenario::run(&setup).unwrap().history.command_mm;
    let same = scenario::run_with_ats_start(&setup, Some(paper))
        .unwrap()
        .history
        .command_mm;
    assert!(default
        .iter()
        .zip(&same)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    let moved = scenario::run_with_ats_start(&setup, Some(identified))
        .unwrap()
        .history
        .command_mm;
    let differ = default
        .iter()
        .zip(&moved)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    assert!(differ > ag.len() / 2, "{differ} of {}", ag.len());
    // Out-of-bounds values are refused, not clamped.
    assert!(scenario::run_with_ats_start(&setup, Some([2.0, 0.01, 0.0])).is_err());
}

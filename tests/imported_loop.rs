//! An imported OpenSees structure's reduced model in the hybrid loop (`rths simulate --structure
//! S.json --scenario meta-online`): on the virtual rig of both presets, the benchmark's
//! uncertainty and a rig file, the run is stable and its J4 (the measured interface against the
//! whole model with the rig's true specimen) small; the history has the pure scenarios'
//! columns; bad input is refused with the reason. Cheap in debug: the 72-DOF frame and 4 s of El
//! Centro.
#![cfg(feature = "sim")]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use rths::machinery::imported::reduced;
use rths::machinery::imported::ImportedStructure;
use rths_core::params::DT_S;
use rths_files::motion::GroundMotion;

const SMALL: &str = "data/structures/opensees-frame-2x3.json";
/// The test's bound on J4, %: the release runs measure 1.0-1.4 % on this frame (docs/opensees.md).
const J4_BOUND_PCT: f64 = 3.0;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn rths(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rths"))
        .current_dir(root())
        .args(args)
        .output()
        .expect("the binary runs")
}

/// A model of the small frame (`rths train meta`'s training), and 4 s of El
/// Centro as a CSV record, in `dir`: (model, record).
fn inputs(dir: &Path) -> (String, String) {
    let s = ImportedStructure::load(&root().join(SMALL)).expect("the shipped frame loads");
    // The whole training records: a model chosen on 2 s of each keeps other modes, and on the
    // benchmark preset that loop trips the command-velocity interlock at 0.15 s
    // (docs/opensees.md, "Not yet done").
    let records = reduced::training_records(DT_S).expect("embedded");
    let file = reduced::train(&s, &records, DT_S, |_, _, _| {}).expect("training");
    let model = dir.join("m.json");
    std::fs::write(&model, file.to_json().expect("json")).expect("write model");
    let m = GroundMotion::embedded("el-centro").expect("embedded");
    let n = (4.0 / m.dt_s) as usize;
    let mut csv = String::from("time_s,accel_g\n");
    for (k, a) in m.accel_g.iter().take(n).enumerate() {
        csv.push_str(&format!("{},{a}\n", k as f64 * m.dt_s));
    }
    let record = dir.join("el-centro-4s.csv");
    std::fs::write(&record, csv).expect("write record");
    (model.display().to_string(), record.display().to_string())
}

fn json(args: &[&str]) -> serde_json::Value {
    let out = rths(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

#[test]
fn meta_online_is_stable_and_tracks_on_both_presets_the_uncertainty_and_a_rig_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (model, record) = inputs(dir.path());
    let out = dir.path().join("run");
    let base = [
        "simulate",
        "--structure",
        SMALL,
        "--scenario",
        "meta-online",
        "--model",
        &model,
        "--motion",
        &record,
    ];
    let run = |extra: &[&str]| {
        let mut a: Vec<&str> = base.to_vec();
        a.extend_from_slice(extra);
        a.push("--json");
        let j = json(&a);
        let score = &j["score"];
        assert_eq!(score["stable"], true, "{extra:?}: {score}");
        let j4 = score["j4_pct"].as_f64().expect("J4");
        eprintln!("{extra:?}: J4 {j4:.3} %");
        assert!(j4 < J4_BOUND_PCT, "{extra:?}: J4 {j4} %");
        for o in score["outputs"].as_array().expect("outputs") {
            assert!(o["std_error_pct"].as_f64().expect("output figure") < J4_BOUND_PCT);
        }
        j
    };
    let out_s = out.display().to_string();
    run(&["--preset", "unr-compact", "--out", &out_s]);
    let csv = std::fs::read_to_string(out.join("history.csv")).expect("history.csv");
    let header = csv.lines().next().expect("header");
    assert!(
        header.starts_with("time_s,interface_mm,out_4_1_mm,out_7_1_mm,out_10_1_mm,"),
        "{header}"
    );
    let rows = csv.lines().count() - 1;
    assert!((rows as f64 * DT_S - 4.0).abs() < 0.05, "{rows} rows");
    run(&["--preset", "benchmark"]);
    // The drawn specimen is the reference's, not the controller's.
    let drawn = run(&["--preset", "benchmark", "--uncertainty", "--seed", "2"]);
    let k = drawn["true_specimen_k_kn_per_mm"].as_f64().expect("k");
    assert!((k - 50.0).abs() > 1e-3 && (k - 50.0).abs() < 10.0, "{k}");
    // A rig file of another preset is refused, naming it.
    let rig = dir.path().join("rig.json");
    let rig_s = rig.display().to_string();
    let id = rths(&["identify", "--preset", "benchmark", "--out", &rig_s]);
    assert!(
        id.status.success(),
        "{}",
        String::from_utf8_lossy(&id.stderr)
    );
    run(&["--preset", "benchmark", "--rig", &rig_s]);
    let mut a: Vec<&str> = base.to_vec();
    a.extend_from_slice(&["--preset", "unr-compact", "--rig", &rig_s]);
    let refused = rths(&a);
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("rig.json"), "{err}");
}

#[test]
fn meta_online_refuses_a_missing_model_and_the_flags_it_does_not_take() {
    let base = [
        "simulate",
        "--structure",
        SMALL,
        "--scenario",
        "meta-online",
        "--motion",
        "el-centro",
    ];
    let refused = |extra: &[&str], says: &str| {
        let mut a: Vec<&str> = base.to_vec();
        a.extend_from_slice(extra);
        let out = rths(&a);
        assert!(!out.status.success(), "{extra:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{extra:?}: {err}");
    };
    refused(&[], "--model M.json");
    refused(&["--model", "no-such.json", "--drift", "0.2"], "--drift");
    refused(&["--model", "no-such.json"], "no-such.json");
}

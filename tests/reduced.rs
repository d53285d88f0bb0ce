//! The reduced-order model of an imported structure (`rths train meta` on an OpenSees import):
//! trained on the training records only, it stays within the 0.5 % NRMSE of the host FE on
//! held-out records at the interface and every output (the host FE equals OpenSees's own run,
//! tests/opensees.rs) of the embedded El Centro and Kobe, for the 48-mass-DOF and the 936-mass-DOF shipped frames; the same input
//! gives the same bytes; a model for another structure, or a corrupted one, is refused.
#![cfg(feature = "sim")]

use std::path::PathBuf;

use rths::machinery::imported::reduced::{self, ReducedModelFile, REDUCED_TRAINING_RECORDS};
use rths::machinery::imported::{fe, ImportedStructure};
use rths_core::params::DT_S;
use rths_files::motion::GroundMotion;

const SMALL: &str = "data/structures/opensees-frame-2x3.json";
const LARGE: &str = "data/structures/opensees-frame-5x12.json";
/// The held-out records: none is a training record.
const HELD_OUT: [&str; 2] = ["el-centro", "kobe"];
/// The goal against OpenSees, % NRMSE.
const GOAL_PCT: f64 = 0.5;

fn load(file: &str) -> ImportedStructure {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(file);
    ImportedStructure::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn record(name: &str, seconds: Option<f64>) -> Vec<f64> {
    let ag = GroundMotion::embedded(name)
        .unwrap_or_else(|| panic!("{name} is embedded"))
        .resample_mm_s2(DT_S);
    match seconds {
        Some(s) => ag.into_iter().take((s / DT_S) as usize).collect(),
        None => ag,
    }
}

fn train(s: &ImportedStructure) -> ReducedModelFile {
    let records = reduced::training_records(DT_S).expect("embedded training records");
    reduced::train(s, &records, DT_S, |_, _, _| {}).expect("training")
}

/// Worst held-out `(interface, output)` NRMSE of `file` on `s`, %.
fn held_out_error(s: &ImportedStructure, file: &ReducedModelFile, seconds: Option<f64>) -> f64 {
    let params = file
        .arrays_for(s)
        .expect("the model is this structure's")
        .spec()
        .params(DT_S)
        .expect("valid");
    let mut worst: f64 = 0.0;
    for name in HELD_OUT {
        assert!(!REDUCED_TRAINING_RECORDS.contains(&name));
        let ag = record(name, seconds);
        let truth = fe::run_pure(s, &ag, DT_S, |_| {}).expect("host FE");
        let run = reduced::run_pure(params, file.outputs.clone(), &ag).expect("reduced run");
        let (i, o) = reduced::history_nrmse_pct(&run, &truth);
        eprintln!("{} {name}: interface {i:.4} %, outputs {o:.4} %", s.name());
        worst = worst.max(i).max(o);
    }
    worst
}

#[test]
fn the_small_frame_reduced_model_meets_the_goal_on_held_out_records_and_is_reproducible() {
    let s = load(SMALL);
    let file = train(&s);
    assert!(
        file.modes.len() < s.mass_dofs(),
        "it is reduced: {} modes",
        file.modes.len()
    );
    assert!(file.training.error_bound_pct <= reduced::REDUCED_TARGET_NRMSE_PCT);
    let worst = held_out_error(&s, &file, None);
    assert!(worst <= GOAL_PCT, "held-out NRMSE {worst} %");
    // The same input gives the same bytes, and the bytes read back to the same model.
    let json = file.to_json().expect("json");
    assert_eq!(json, train(&s).to_json().expect("json"));
    assert_eq!(
        ReducedModelFile::from_json(&json).expect("reads back"),
        file
    );
}

#[test]
fn the_thousand_dof_frame_reduced_model_meets_the_goal_on_held_out_records() {
    let s = load(LARGE);
    assert!(s.equations().len() >= 1000 && s.mass_dofs() >= 500);
    let file = train(&s);
    eprintln!(
        "{} modes of {}; error bound {} %",
        file.modes.len(),
        file.training.total_modes,
        file.training.error_bound_pct
    );
    assert!(file.modes.len() <= 32);
    // The first 20 s of each held-out record: its strong motion, at a test's cost.
    let worst = held_out_error(&s, &file, Some(20.0));
    assert!(worst <= GOAL_PCT, "held-out NRMSE {worst} %");
}

#[test]
fn a_model_for_another_structure_or_a_corrupted_one_is_refused() {
    let s = load(SMALL);
    let file = train(&s);
    let other = load(LARGE);
    let e = file.arrays_for(&other).expect_err("another structure");
    assert!(
        e.to_string().contains("trained for structure frame-2x3"),
        "{e}"
    );
    let mut bad = file.clone();
    bad.modes[0].omega_rad_s = f64::NAN;
    assert!(bad.arrays().is_err(), "a NaN frequency");
    let mut bad = file.clone();
    bad.modes[0].output_shape.pop();
    let e = bad.arrays().expect_err("a short output shape");
    assert!(e.to_string().contains("mode 0"), "{e}");
    let mut bad = file.clone();
    bad.structure_checksum = "fnv1a64:0000000000000000".into();
    assert!(
        bad.arrays_for(&s).is_err(),
        "a checksum that is not the structure's"
    );
    let json = file
        .to_json()
        .expect("json")
        .replace("rths-reduced-model", "rths-other");
    assert!(
        ReducedModelFile::from_json(&json).is_err(),
        "another format"
    );
    assert!(ReducedModelFile::from_json("{").is_err(), "truncated JSON");
}

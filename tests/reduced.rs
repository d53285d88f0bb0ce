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
        .arrays_for(s, DT_S)
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
    let e = file
        .arrays_for(&other, DT_S)
        .expect_err("another structure");
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
        bad.arrays_for(&s, DT_S).is_err(),
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

/// The training's reference runs (what the mode count is chosen against) are the modal
/// superposition of all the modes for the shipped frames (Rayleigh damping of the numerical part),
/// and equal the sparse host FE's runs of the whole uncondensed model within the condensation's
/// round-off (the bound tests/opensees.rs sets the condensed model against the whole one, 1e-6 %
/// NRMSE) at the interface and every output. (Against the condensed model's own Newmark they agree
/// to round-off: tests/opensees.rs.)
#[test]
fn the_modal_training_reference_is_the_sparse_host_fe_to_round_off() {
    for (file, seconds) in [(SMALL, None), (LARGE, Some(10.0))] {
        let s = load(file);
        let records: Vec<(String, Vec<f64>)> = REDUCED_TRAINING_RECORDS
            .iter()
            .map(|n| (n.to_string(), record(n, seconds)))
            .collect();
        let (runs, kind) = reduced::training_reference(&s, &records, DT_S).expect("reference");
        assert!(
            matches!(kind, reduced::TrainingReference::Modal { modes, .. } if modes == s.mass_dofs()),
            "{}: {kind}",
            s.name()
        );
        for ((name, ag), modal) in records.iter().zip(&runs) {
            let fe = fe::run_pure(&s, ag, DT_S, |_| {}).expect("host FE");
            assert_eq!(modal.output_columns, fe.output_columns);
            assert_eq!(modal.interface_mm.len(), fe.interface_mm.len());
            let peak = fe.interface_mm.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            let mut worst: f64 = 0.0;
            for (k, (a, b)) in modal.interface_mm.iter().zip(&fe.interface_mm).enumerate() {
                worst = worst.max((a - b).abs());
                for (x, y) in modal.outputs_mm[k].iter().zip(&fe.outputs_mm[k]) {
                    worst = worst.max((x - y).abs());
                }
            }
            let (i, o) = reduced::history_nrmse_pct(modal, &fe);
            eprintln!(
                "{} {name}: modal vs sparse FE: largest difference {worst:.3e} mm (peak \
                 interface {peak:.3} mm), NRMSE interface {i:.2e} %, outputs {o:.2e} %; {kind}",
                s.name()
            );
            assert!(peak > 1.0, "the frame moved: {peak} mm");
            assert!(i < 1e-6 && o < 1e-6, "modal vs sparse FE: {i} %, {o} %");
        }
    }
}

/// Where the damping is not classical (a dashpot of its own at a massless DOF, which the
/// condensation cannot keep exactly; or at a DOF with mass away from the specimen, which couples the
/// modes), the training's reference is the sparse host FE's run itself, and says why.
#[test]
fn damping_that_is_not_classical_falls_back_to_the_sparse_host_fe() {
    use rths::machinery::imported::modal_reference::NotClassical;
    use serde_json::Value;
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(SMALL);
    let json: Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("the shipped frame"))
            .expect("JSON");
    let triplets = |key: &str| -> Vec<(u64, u64, f64)> {
        json[key]
            .as_array()
            .expect("triplets")
            .iter()
            .map(|t| {
                let (r, c) = (t[0].as_u64().expect("row"), t[1].as_u64().expect("column"));
                (r, c, t[2].as_f64().expect("value"))
            })
            .collect()
    };
    let massive: Vec<u64> = triplets("mass")
        .into_iter()
        .filter(|&(r, c, v)| r == c && v > 0.0)
        .map(|(r, _, _)| r)
        .collect();
    let equations = json["equations"].as_array().expect("equations");
    let specimen = &json["specimen"]["at"];
    let massless = (0..equations.len() as u64)
        .find(|e| !massive.contains(e))
        .expect("a massless DOF");
    let away = *massive
        .iter()
        .find(|&&e| &equations[e as usize] != specimen)
        .expect("a DOF with mass away from the specimen");
    let ag = record("northridge", Some(2.0));
    let records = vec![("northridge".to_string(), ag.clone())];
    for equation in [massless, away] {
        // Half as much damping again on the DOF's diagonal: a dashpot of its own.
        let mut changed = json.clone();
        for t in changed["damping"].as_array_mut().expect("triplets") {
            if t[0].as_u64() == Some(equation) && t[1].as_u64() == Some(equation) {
                t[2] = Value::from(t[2].as_f64().expect("value") * 1.5);
            }
        }
        let s = ImportedStructure::from_json(&changed.to_string()).expect("a valid structure");
        let (runs, kind) = reduced::training_reference(&s, &records, DT_S).expect("reference");
        eprintln!("a dashpot at equation {equation}: {kind}");
        match &kind {
            reduced::TrainingReference::SparseFe {
                why: NotClassical::MasslessDamping { equation: e, .. },
            } => assert_eq!((equation, *e as u64), (massless, massless)),
            reduced::TrainingReference::SparseFe {
                why: NotClassical::Coupled { .. },
            } => assert_eq!(equation, away),
            other => panic!("equation {equation}: {other}"),
        }
        let fe = fe::run_pure(&s, &ag, DT_S, |_| {}).expect("host FE");
        assert_eq!(runs[0].interface_mm, fe.interface_mm);
        assert_eq!(runs[0].outputs_mm, fe.outputs_mm);
    }
}

fn rths(dir: &std::path::Path, args: &[&str]) -> (bool, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rths"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("rths runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A reduced model trained at the other controller rate (`rths train meta --rate`) is refused
/// where the controller's part is read (`rths simulate`, `rths check-model`; the link's upload and
/// the firmware's default: rths-files' unit tests), naming both rates and how to train one at
/// this build's: its mode count and error bound were measured at its own rate.
#[test]
fn a_model_trained_at_the_other_rate_is_refused_with_both_rates() {
    use rths_core::params::{CONTROL_RATES_HZ, CONTROL_RATE_HZ};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let frame =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/structures/opensees-frame-1x1.json");
    let frame = frame.display().to_string();
    let other = CONTROL_RATES_HZ
        .iter()
        .find(|&&r| r != CONTROL_RATE_HZ)
        .copied()
        .unwrap();
    for (rate, name) in [(CONTROL_RATE_HZ, "own.json"), (other, "other.json")] {
        let (ok, _, err) = rths(
            d,
            &[
                "train",
                "meta",
                "--structure",
                &frame,
                "--rate",
                &rate.to_string(),
                "--out",
                name,
            ],
        );
        assert!(ok, "{err}");
    }
    let simulate = |model: &str| {
        rths(
            d,
            &[
                "simulate",
                "--structure",
                &frame,
                "--scenario",
                "meta-pure",
                "--model",
                model,
                "--motion",
                "el-centro",
                "--scale",
                "0.1",
                "--out",
                "run",
            ],
        )
    };
    let (ok, _, err) = simulate("own.json");
    assert!(ok, "the model of this build's rate runs: {err}");
    let (ok, _, err) = simulate("other.json");
    assert!(!ok, "the other rate's model ran");
    let (ok2, _, err2) = rths(d, &["check-model", "other.json"]);
    assert!(!ok2, "check-model accepted the other rate's model");
    for e in [&err, &err2] {
        for part in [
            format!("the reduced model of frame-1x1 was made at {other} Hz"),
            format!("this controller runs at {CONTROL_RATE_HZ} Hz"),
            format!("`rths train meta --structure S.json --rate {CONTROL_RATE_HZ} --out M.json`"),
        ] {
            assert!(e.contains(&part), "{part:?} in: {e}");
        }
    }
}

/// `rths train meta --modes R` keeps exactly the `R` lowest modes and prints their error bound;
/// an order the structure or core's controller cannot hold, and `--modes` on a structure that is
/// not imported, are refused with the reason.
#[test]
fn a_fixed_order_is_kept_or_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/structures");
    let frame = data.join("opensees-frame-1x1.json").display().to_string();
    let train = |modes: &str| {
        rths(
            d,
            &[
                "train",
                "meta",
                "--structure",
                &frame,
                "--modes",
                modes,
                "--out",
                "m.json",
            ],
        )
    };
    let (ok, out, err) = train("7");
    assert!(ok, "{err}");
    assert!(out.contains("7 of 10 modes kept (--modes)"), "{out}");
    assert!(out.contains("error bound "), "{out}");
    let file = ReducedModelFile::load(&d.join("m.json")).unwrap();
    assert_eq!(file.modes.len(), 7);
    assert!(file.training.error_bound_pct.is_finite());
    for (modes, reason) in [
        ("0", "--modes 0: a reduced model keeps at least 1 mode"),
        (
            "11",
            "--modes 11: frame-1x1 has 10 modes (its DOFs with mass)",
        ),
        ("33", "--modes 33: core's controller holds at most 32 modes"),
    ] {
        let (ok, _, err) = train(modes);
        assert!(!ok, "--modes {modes} was kept");
        assert!(err.contains(reason), "{reason:?} in: {err}");
    }
    let (ok, _, err) = rths(
        d,
        &[
            "train",
            "meta",
            "--structure",
            &data.join("shear8.json").display().to_string(),
            "--modes",
            "3",
            "--out",
            "x.json",
        ],
    );
    assert!(!ok && err.contains("is not an imported structure"), "{err}");
}

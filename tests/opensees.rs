//! Imported OpenSees structures: the shipped frames import to the shipped bytes, their condensed
//! model (the metamodel's API) integrates to the sparse host FE, and the host FE equals OpenSees's
//! own transient analysis of the same model (≤ 0.1 % NRMSE at the interface and every output).
//!
//! The tests that run OpenSees print `SKIPPED: openseespy (...)` without python3/openseespy
//! (`RTHS_PYTHON` names the interpreter), and fail instead when `RTHS_REQUIRE_OPENSEES=1` (CI).
#![cfg(feature = "sim")]

use std::ffi::OsString;
use std::path::PathBuf;

use nalgebra::DVector;
use rths::machinery::imported::export::{self, ImportRequest};
use rths::machinery::imported::{fe, DofLabel, ImportedStructure};
use rths_core::metrics::nrmse_pct;
use rths_core::params::DT_S;
use rths_files::motion::GroundMotion;

const SMALL: &str = "data/structures/opensees-frame-2x3.json";
const LARGE: &str = "data/structures/opensees-frame-5x12.json";
/// Seconds of El Centro the comparisons run (its strong motion).
const RECORD_S: f64 = 10.0;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn load(file: &str) -> ImportedStructure {
    let path = root().join(file);
    ImportedStructure::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Whether OpenSees can run here; prints the SKIPPED line (or fails under RTHS_REQUIRE_OPENSEES).
fn opensees_available(test: &str) -> bool {
    match export::python_command() {
        Ok(_) => true,
        Err(e) => {
            if std::env::var("RTHS_REQUIRE_OPENSEES").as_deref() == Ok("1") {
                panic!("RTHS_REQUIRE_OPENSEES=1 but OpenSees cannot run: {e}");
            }
            println!("SKIPPED: openseespy ({test}: {e})");
            eprintln!("SKIPPED: openseespy ({test}: {e})");
            false
        }
    }
}

fn el_centro() -> Vec<f64> {
    let ag = GroundMotion::try_el_centro()
        .expect("embedded El Centro")
        .resample_mm_s2(DT_S);
    let n = (RECORD_S / DT_S) as usize;
    ag.into_iter().take(n).collect()
}

fn label(s: &str) -> DofLabel {
    s.parse().expect("a NODE:DOF label")
}

/// The shipped file's import request (the commands in docs/opensees.md).
fn request(script: &str, specimen: &str, outputs: &[&str]) -> ImportRequest {
    ImportRequest {
        model: root().join("data/structures/opensees").join(script),
        specimen: label(specimen),
        specimen_stiffness_kn_per_mm: 50.0,
        outputs: outputs.iter().map(|o| label(o)).collect(),
        units: None,
    }
}

#[test]
#[cfg_attr(
    rths_no_opensees,
    ignore = "needs openseespy, not found when the tests were built (docs/ci.md)"
)]
fn the_shipped_frames_import_to_the_shipped_bytes() {
    if !opensees_available("import") {
        return;
    }
    for (req, shipped) in [
        (
            request("frame-2x3.py", "4:1", &["4:1", "7:1", "10:1"]),
            SMALL,
        ),
        (
            request("frame-5x12.py", "7:1", &["7:1", "43:1", "73:1"]),
            LARGE,
        ),
        // The firmware budget's small and middle frames (docs/firmware.md, the structure budget).
        (
            request("frame-1x1.py", "3:1", &["3:1"]),
            "data/structures/opensees-frame-1x1.json",
        ),
        (
            request("frame-2x4.py", "4:1", &["4:1", "7:1", "10:1", "13:1"]),
            "data/structures/opensees-frame-2x4.json",
        ),
    ] {
        let dir = tempfile::tempdir().expect("a temporary directory");
        export::export(&req, dir.path()).expect("the export runs");
        let file = export::read_export(&req, dir.path()).expect("the export reads");
        file.validate().expect("the frame is accepted");
        let json = file.to_json().expect("JSON");
        let want = std::fs::read_to_string(root().join(shipped)).expect("the shipped file");
        assert!(json == want, "{shipped} is not what the import writes now");
    }
}

#[test]
#[cfg_attr(
    rths_no_opensees,
    ignore = "needs openseespy, not found when the tests were built (docs/ci.md)"
)]
fn the_exporter_refuses_a_missing_specimen_dof_and_a_mechanism() {
    if !opensees_available("refusals") {
        return;
    }
    let dir = tempfile::tempdir().expect("a temporary directory");
    let req = request("frame-2x3.py", "999:1", &[]);
    export::export(&req, dir.path()).expect("the export runs");
    let e = export::read_export(&req, dir.path())
        .expect("the export reads")
        .validate()
        .map(|_| ())
        .expect_err("no node 999");
    assert!(e.to_string().contains("specimen DOF 999:1"), "{e}");
    // A cantilever whose tip rotation is released by a second, pinned node: a mechanism.
    let model = dir.path().join("mechanism.py");
    std::fs::write(
        &model,
        "import openseespy.opensees as ops\nRTHS_UNITS = 'mm-kn'\nops.wipe()\n\
         ops.model('basic', '-ndm', 2, '-ndf', 3)\nops.node(1, 0, 0)\nops.node(2, 1000, 0)\n\
         ops.node(3, 2000, 0)\nops.fix(1, 1, 1, 1)\nops.geomTransf('Linear', 1)\n\
         ops.element('elasticBeamColumn', 1, 1, 2, 100.0, 200.0, 1e6, 1, '-mass', 1e-6)\n\
         ops.element('truss', 2, 2, 3, 100.0, 1)\nops.uniaxialMaterial('Elastic', 1, 200.0)\n",
    )
    .expect("write the model");
    let req = ImportRequest {
        model,
        ..request("frame-2x3.py", "2:1", &[])
    };
    let out = export::export(&req, dir.path())
        .map_err(|e| e.to_string())
        .and_then(|()| {
            export::read_export(&req, dir.path())
                .map_err(|e| e.to_string())?
                .validate()
                .map(|_| ())
                .map_err(|e| e.to_string())
        });
    let e = out.expect_err("a mechanism is refused");
    assert!(e.contains("mechanism") || e.contains("singular"), "{e}");
}

/// Newmark's average acceleration on the condensed dense model, coupled with the stand-in.
fn dense_newmark(s: &ImportedStructure, ag: &[f64]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let (m, c, mut k) = s.condensed_dense();
    let i = s.interface_index();
    k[(i, i)] += s.specimen_stiffness_kn_per_mm();
    let n = m.nrows();
    let g = &m * s.condensed_influence();
    let (a0, a1, a2) = (4.0 / (DT_S * DT_S), 2.0 / DT_S, 4.0 / DT_S);
    let k_eff = &k + &m * a0 + &c * a1;
    let chol = k_eff.cholesky().expect("K̂ positive definite");
    let (mut u, mut v, mut a) = (DVector::zeros(n), DVector::zeros(n), DVector::zeros(n));
    let (mut x, mut outs) = (vec![0.0], vec![vec![0.0; s.outputs().len()]]);
    let idx = s.output_indices();
    for &ag_k in ag.iter().skip(1) {
        let rhs: DVector<f64> = &m * (&u * a0 + &v * a2 + &a) + &c * (&u * a1 + &v) - &g * ag_k;
        let u_new = chol.solve(&rhs);
        let a_new: DVector<f64> = (&u_new - &u) * a0 - &v * a2 - &a;
        v += (&a + &a_new) * (0.5 * DT_S);
        a = a_new;
        u = u_new;
        x.push(u[i]);
        outs.push(idx.iter().map(|&j| u[j]).collect());
    }
    (x, outs)
}

fn column(rows: &[Vec<f64>], i: usize) -> Vec<f64> {
    rows.iter().map(|r| r[i]).collect()
}

#[test]
fn the_condensed_model_integrates_to_the_sparse_host_fe() {
    let s = load(SMALL);
    assert_eq!((s.equations().len(), s.mass_dofs()), (72, 48));
    let (m, c, k) = s.condensed_dense();
    for a in [&m, &c, &k] {
        assert_eq!(a.shape(), (48, 48));
        assert!((a - a.transpose()).amax() <= 1e-12 * a.amax());
    }
    let ag = el_centro();
    let full = fe::run_pure(&s, &ag, DT_S, |_| {}).expect("the host FE runs");
    let (x, outs) = dense_newmark(&s, &ag);
    let e = nrmse_pct(&x, &full.interface_mm).expect("nrmse");
    assert!(e < 1e-6, "interface: condensed vs whole {e} %");
    for i in 0..s.outputs().len() {
        let e = nrmse_pct(&column(&outs, i), &column(&full.outputs_mm, i)).expect("nrmse");
        assert!(e < 1e-6, "output {i}: condensed vs whole {e} %");
    }
    // The interface is the first output of the shipped file: the same series.
    assert_eq!(full.interface_mm, column(&full.outputs_mm, 0));
}

/// OpenSees's transient analysis of `script` under `ag` at the `dofs`: (samples × dofs, s/step).
fn opensees_transient(script: &str, ag: &[f64], dofs: &[DofLabel]) -> (Vec<Vec<f64>>, f64) {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let record = dir.path().join("ag.txt");
    let text: String = ag.iter().map(|v| format!("{v:e}\n")).collect();
    std::fs::write(&record, text).expect("write the record");
    let out = dir.path().join("out.csv");
    let list: Vec<String> = dofs.iter().map(|d| d.to_string()).collect();
    let args: Vec<OsString> = vec![
        root().join("data/structures/opensees").join(script).into(),
        "--record".into(),
        record.into(),
        "--dt".into(),
        format!("{DT_S:e}").into(),
        "--dofs".into(),
        list.join(",").into(),
        "--out".into(),
        out.clone().into(),
    ];
    let stdout = export::run_script(export::TRANSIENT, "transient.py", dir.path(), &args)
        .expect("OpenSees's transient analysis runs");
    let timing: serde_json::Value = serde_json::from_str(stdout.trim()).expect("timing JSON");
    let per_step = timing["per_step_s"].as_f64().expect("per_step_s");
    let csv = std::fs::read_to_string(&out).expect("OpenSees's output");
    let rows = csv
        .lines()
        .skip(1)
        .map(|l| {
            l.split(',')
                .skip(1)
                .map(|v| v.parse().expect("a number"))
                .collect()
        })
        .collect();
    (rows, per_step)
}

fn compare_with_opensees(file: &str, script: &str) {
    let s = load(file);
    let ag = el_centro();
    let t0 = std::time::Instant::now();
    let ours = fe::run_pure(&s, &ag, DT_S, |_| {}).expect("the host FE runs");
    let our_step = t0.elapsed().as_secs_f64() / (ag.len() - 1) as f64;
    let mut dofs = vec![s.specimen()];
    dofs.extend_from_slice(s.outputs());
    let (theirs, their_step) = opensees_transient(script, &ag, &dofs);
    assert_eq!(theirs.len(), ours.interface_mm.len());
    let e = nrmse_pct(&ours.interface_mm, &column(&theirs, 0)).expect("nrmse");
    println!(
        "{file}: interface NRMSE {e:.2e} % vs OpenSees; OpenSees {:.1} us/step, rths host FE \
         {:.1} us/step (this build, not a benchmark)",
        their_step * 1e6,
        our_step * 1e6
    );
    assert!(e <= 0.1, "{file}: interface NRMSE {e} % > 0.1 %");
    for (i, o) in s.outputs().iter().enumerate() {
        let e = nrmse_pct(&column(&ours.outputs_mm, i), &column(&theirs, i + 1)).expect("nrmse");
        println!("{file}: output {o} NRMSE {e:.2e} %");
        assert!(e <= 0.1, "{file}: output {o} NRMSE {e} % > 0.1 %");
    }
}

#[test]
#[cfg_attr(
    rths_no_opensees,
    ignore = "needs openseespy, not found when the tests were built (docs/ci.md)"
)]
fn the_host_fe_equals_opensees_on_the_small_frame() {
    if opensees_available("host FE vs OpenSees, frame-2x3") {
        compare_with_opensees(SMALL, "frame-2x3.py");
    }
}

#[test]
#[cfg_attr(
    rths_no_opensees,
    ignore = "needs openseespy, not found when the tests were built (docs/ci.md)"
)]
fn the_host_fe_equals_opensees_on_the_large_frame() {
    if opensees_available("host FE vs OpenSees, frame-5x12") {
        compare_with_opensees(LARGE, "frame-5x12.py");
    }
}

#[test]
fn the_shipped_large_frame_has_over_500_dofs_with_mass() {
    let s = load(LARGE);
    assert_eq!((s.equations().len(), s.mass_dofs()), (1404, 936));
}

#[test]
fn without_python_the_import_says_how_to_install_it() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(["import", "opensees"])
        .arg(root().join("data/structures/opensees/frame-2x3.py"))
        .args(["--specimen", "4:1", "--specimen-stiffness", "50", "--out"])
        .arg(std::env::temp_dir().join("rths-no-python.json"))
        .env("RTHS_PYTHON", "/nonexistent/python3")
        .output()
        .expect("rths runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("pip install openseespy==3.7.1.2"), "{err}");
    assert!(err.contains("RTHS_PYTHON"), "{err}");
}

#[test]
fn a_version_1_command_names_what_a_version_2_file_is() {
    let text = std::fs::read_to_string(root().join(SMALL)).expect("the shipped file");
    let e = rths_files::structure_file::Structure::from_json(&text)
        .map(|_| ())
        .expect_err("version 2 is not a version-1 structure");
    assert!(e.to_string().contains("rths import opensees"), "{e}");
}

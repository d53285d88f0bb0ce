//! Nonlinear numerical substructures: the shipped yielding structure files (their yield forces are
//! what their descriptions say), the FE reference (elastic = linear, yielding = ductility and
//! residual drift), and bad files refused with the reason.

use std::path::Path;

use rths::machinery::motion::GroundMotion;
use rths::machinery::structure::fe_reference;
use rths_core::params::DT_S;
use rths_core::structure_n::{ChangN, MAX_DOF};
use rths_files::structure_file::Structure;

fn root(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn el_centro(scale: f64) -> Vec<f64> {
    GroundMotion::try_el_centro()
        .unwrap()
        .scaled(scale)
        .resample_mm_s2(DT_S)
}

/// The file's text with every yield force set so high that nothing yields.
fn elastic(path: &str) -> Structure {
    let text = std::fs::read_to_string(root(path)).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    for law in v["stories"]["hysteresis"].as_array_mut().unwrap() {
        law["yield_force"] = serde_json::json!(1e12);
    }
    Structure::from_json(&v.to_string()).unwrap()
}

#[test]
fn shipped_yield_forces_are_half_the_elastic_peak_under_el_centro() {
    for path in [
        "data/structures/paper-frame-yielding.json",
        "data/structures/shear3-yielding.json",
    ] {
        let s = Structure::load(&root(path)).unwrap();
        let r = fe_reference(&elastic(path), &el_centro(1.0), DT_S).unwrap();
        for (law, peak) in s.story_laws().unwrap().iter().zip(r.peak_story_force_kn()) {
            let half = 0.5 * peak;
            assert!(
                (law.yield_force_kn() - half).abs() / half < 1e-3,
                "{path}: yield {} vs half the elastic peak {half}",
                law.yield_force_kn()
            );
        }
    }
}

#[test]
fn the_elastic_fe_reference_is_the_linear_chang_path() {
    let s = elastic("data/structures/shear3-yielding.json");
    let ag = el_centro(1.0);
    let r = fe_reference(&s, &ag, DT_S).unwrap();
    let mut lin = ChangN::new(s.whole().unwrap(), DT_S).unwrap();
    lin.reset(ag[0]);
    let zero = [0.0; MAX_DOF];
    let mut worst = 0.0_f64;
    for (i, &a) in ag.iter().enumerate().skip(1) {
        lin.advance(a, &zero);
        let d = lin.disp();
        let drift = [d[0], d[1] - d[0], d[2] - d[1]];
        for (j, dj) in drift.iter().enumerate() {
            worst = worst.max((dj - r.story_drift_mm[j][i]).abs());
        }
    }
    assert!(worst < 1e-6, "elastic nonlinear vs linear: {worst} mm");
}

#[test]
fn yielding_frames_reach_ductility_four_and_keep_a_residual_drift() {
    let s = Structure::load(&root("data/structures/paper-frame-yielding.json")).unwrap();
    let r1 = fe_reference(&s, &el_centro(1.0), DT_S).unwrap();
    assert!(
        (1.0..3.0).contains(&r1.peak_ductility()),
        "{}",
        r1.peak_ductility()
    );
    let r = fe_reference(&s, &el_centro(2.5), DT_S).unwrap();
    assert!(r.peak_ductility() >= 4.0, "{}", r.peak_ductility());
    assert!(r.residual_drift_mm(DT_S)[0].abs() > 0.01);
    let s3 = Structure::load(&root("data/structures/shear3-yielding.json")).unwrap();
    let r3 = fe_reference(&s3, &el_centro(3.0), DT_S).unwrap();
    assert!(r3.peak_ductility() >= 4.0, "{}", r3.peak_ductility());
    assert!(r3.residual_drift_mm(DT_S).iter().any(|d| d.abs() > 1.0));
}

#[test]
fn a_linear_file_is_refused_by_the_nonlinear_path() {
    let s = Structure::load(&root("data/structures/paper-frame.json")).unwrap();
    let e = fe_reference(&s, &el_centro(1.0), DT_S).unwrap_err();
    assert!(format!("{e:#}").contains("linear"), "{e:#}");
}

#[test]
fn analyze_structure_prints_ductility_and_refuses_a_non_physical_law() {
    let bin = env!("CARGO_BIN_EXE_rths");
    let good = root("data/structures/paper-frame-yielding.json");
    let out = std::process::Command::new(bin)
        .args(["analyze", "--structure"])
        .arg(&good)
        .args(["--scale", "2.5"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("peak ductility         4.685"), "{text}");
    let bad_text = std::fs::read_to_string(&good)
        .unwrap()
        .replace("\"post_yield_ratio\": 0.05", "\"post_yield_ratio\": -0.5");
    let bad = std::env::temp_dir().join(format!("rths-nl-bad-{}.json", std::process::id()));
    std::fs::write(&bad, bad_text).unwrap();
    let out = std::process::Command::new(bin)
        .args(["analyze", "--structure"])
        .arg(&bad)
        .output()
        .unwrap();
    let _ = std::fs::remove_file(&bad);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("story 1 hysteresis: post-yield ratio"),
        "{err}"
    );
}

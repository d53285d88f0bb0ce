//! `rths check-model FILE`: exit 0 with a summary for a valid file, 1 with the reason otherwise.

use std::path::Path;
use std::process::Command;

const LR: &str = include_str!("../data/models/lr.json");

fn check(text: &str, extra: &[&str]) -> (bool, String, String) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.json");
    std::fs::write(&path, text).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_rths"))
        .arg("check-model")
        .arg(&path)
        .args(extra)
        .output()
        .unwrap();
    assert!(
        out.status.success() || out.status.code() == Some(1),
        "exit status {:?}",
        out.status
    );
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn edited(f: impl FnOnce(&mut serde_json::Value)) -> String {
    let mut v: serde_json::Value = serde_json::from_str(LR).unwrap();
    f(&mut v);
    serde_json::to_string(&v).unwrap()
}

#[test]
fn shipped_models_are_valid_with_a_summary() {
    let (ok, out, _) = check(LR, &[]);
    assert!(ok);
    assert!(out.contains("valid rths model file"), "{out}");
    assert!(out.contains("kind              lr"), "{out}");
    assert!(out.contains("delay_steps       28"), "{out}");
    let rnn = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models/rnn-10.json"),
    )
    .unwrap();
    let (ok, out, _) = check(&rnn, &["--kind", "rnn"]);
    assert!(ok, "{out}");
    assert!(out.contains("hidden            10"), "{out}");
}

#[test]
fn bad_files_are_rejected_with_the_reason() {
    let cases: Vec<(String, Vec<&str>, &str)> = vec![
        (
            "{\"format\": \"rths-model\", \"version\": 1,".to_string(),
            vec![],
            "malformed model file",
        ),
        ("".to_string(), vec![], "malformed model file"),
        (
            edited(|v| v["version"] = 7.into()),
            vec![],
            "unsupported model file version 7",
        ),
        (
            edited(|v| v["format"] = "onnx".into()),
            vec![],
            "unknown model format",
        ),
        (
            edited(|v| v["kind"] = "cnn".into()),
            vec![],
            "malformed model file",
        ),
        (
            LR.to_string(),
            vec!["--kind", "rnn"],
            "wrong model kind: expected rnn, file holds lr",
        ),
        (
            edited(|v| v["lr"]["theta"] = serde_json::json!([1.0, 2.0])),
            vec![],
            "wrong shape of lr.theta",
        ),
        (
            LR.replacen("\"theta\": [", "\"theta\": [1e999, ", 1)
                .replacen(",\n      -", ",\n      ", 0),
            vec![],
            "rejected",
        ),
        (
            edited(|v| v["lr"]["theta"][0] = serde_json::json!(null)),
            vec![],
            "malformed model file",
        ),
        (
            edited(|v| v["dt_s"] = serde_json::json!(-1.0)),
            vec![],
            "dt_s",
        ),
        (
            edited(|v| v["delay_steps"] = serde_json::json!(1000)),
            vec![],
            "delay_steps 1000 exceeds",
        ),
        (
            edited(|v| {
                v.as_object_mut().unwrap().remove("lr");
            }),
            vec![],
            "section is missing",
        ),
        // The feature names are rths-core's; a file with the old LR names is refused, naming both.
        (
            edited(|v| v["features"][2] = "disp_fb_mm".into()),
            vec![],
            "feature names of a lr model: expected [\"bias\", \"ground_accel_mm_s2\", \"brace_disp_fb_mm\"",
        ),
        (
            edited(|v| v["features"][3] = "force_fb_kn".into()),
            vec![],
            "found [\"bias\", \"ground_accel_mm_s2\", \"brace_disp_fb_mm\", \"force_fb_kn\"",
        ),
    ];
    for (text, extra, why) in cases {
        let (ok, out, err) = check(&text, &extra);
        assert!(!ok, "accepted: {why}: {out}");
        assert!(err.contains("rejected"), "{why}: {err}");
        assert!(err.contains(why), "expected `{why}` in: {err}");
    }
}

#[test]
fn a_missing_file_is_rejected() {
    let out = Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(["check-model", "/nonexistent/model.json"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot access model file"));
}

/// Every shipped model carries rths-core's feature names, in order, so every loader accepts it.
#[test]
fn shipped_models_name_cores_features() {
    use rths::machinery::model_file::ModelFile;
    use rths_core::metamodel::{LRX_FEATURE_NAMES, LR_FEATURE_NAMES, RNN_INPUT_NAMES};
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models");
    for (file, names) in [
        ("lr.json", &LR_FEATURE_NAMES[..]),
        ("lrx.json", &LRX_FEATURE_NAMES[..]),
        ("rnn-5.json", &RNN_INPUT_NAMES[..]),
        ("rnn-10.json", &RNN_INPUT_NAMES[..]),
        ("rnn-20.json", &RNN_INPUT_NAMES[..]),
    ] {
        let m = ModelFile::load(&dir.join(file)).unwrap();
        assert_eq!(m.features, names, "{file}");
        assert_eq!(
            rths::machinery::model_file::feature_names(m.kind),
            names,
            "{file}"
        );
    }
}

/// The reduced model `rths train meta` writes for an imported structure (it was read as an LR/RNN
/// file and refused for its format) and the structure metamodel at another rate (accepted before:
/// every file made at a controller rate follows `rths_files::rate`).
#[test]
fn reduced_models_are_checked_and_metamodels_at_another_rate_refused() {
    let reduced = include_str!("../fuzz/seeds/meta_model_file/frame-1x1-reduced.json");
    let (ok, out, err) = check(reduced, &[]);
    assert!(ok, "{err}");
    assert!(
        out.contains("rths-reduced-model") && out.contains("frame-1x1"),
        "{out}"
    );
    let (ok, _, _) = check(reduced, &["--kind", "meta"]);
    assert!(ok);
    let (ok, _, err) = check(reduced, &["--kind", "lr"]);
    assert!(!ok && err.contains("wrong model kind"), "{err}");
    let meta = include_str!("../fuzz/seeds/meta_model_file/shear3-yielding-meta.json");
    let (ok, out, err) = check(meta, &[]);
    assert!(ok && out.contains("structure-meta"), "{err}");
    let mut v: serde_json::Value = serde_json::from_str(meta).unwrap();
    v["dt_s"] = serde_json::json!(1.0 / 4096.0);
    let (ok, _, err) = check(&v.to_string(), &[]);
    assert!(!ok && err.contains("made at 4096 Hz"), "{err}");
}

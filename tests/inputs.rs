//! Lab-grade inputs (issue 27): every bad file or argument a user may hand the `rths` binary is
//! refused with one clear message naming the file, the row or field, the value and the limit;
//! never a panic, an abort, a silent clamp or gigabytes of memory.

use std::path::Path;
use std::process::{Command, Stdio};

/// Run `rths ARGS` in `dir`: (exit code, stdout, stderr).
fn rths_in(dir: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Run in the repository root.
fn rths(args: &[&str]) -> (Option<i32>, String, String) {
    rths_in(repo(), args)
}

/// `rths ARGS` must fail with exit 1 and an error containing every one of `needles`, printed once.
fn refused(args: &[&str], needles: &[&str]) -> String {
    let (code, _, err) = rths(args);
    assert_eq!(
        code,
        Some(1),
        "rths {args:?} should be refused, stderr: {err}"
    );
    for n in needles {
        assert!(err.contains(n), "rths {args:?}: `{n}` not in: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

#[test]
fn long_records_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let big = write(
        dir.path(),
        "big.csv",
        "time_s,accel_g\n0,0.1\n1e6,0.2\n2e6,0.1\n",
    );
    let values = "0.1\n".repeat(4000);
    let dt100 = write(
        dir.path(),
        "dt100.AT2",
        &format!("T\nE\nU\nNPTS= 4000, DT= 100 SEC\n{values}"),
    );
    let dt10 = write(
        dir.path(),
        "dt10.AT2",
        &format!("T\nE\nU\nNPTS= 4000, DT= 10 SEC\n{values}"),
    );
    for (file, line) in [(&big, "line 4"), (&dt100, "line 4"), (&dt10, "line 4")] {
        for args in [
            vec!["analyze", "--motion", file.as_str()],
            vec![
                "simulate",
                "--scenario",
                "fe-pure",
                "--motion",
                file.as_str(),
            ],
            vec![
                "train",
                "lr",
                "--motion",
                file.as_str(),
                "--out",
                "/dev/null",
            ],
        ] {
            let err = refused(&args, &[file.as_str(), line, "limit of 600 s"]);
            assert_eq!(err.matches("limit of 600 s").count(), 1, "{err}");
        }
    }
}

#[test]
fn a_closed_stdout_ends_quietly() {
    // `rths … | head -1`: the reader goes away after one line.
    let dir = tempfile::tempdir().unwrap();
    let closed_out = dir.path().join("imported");
    for args in [
        vec![
            "analyze",
            "--structure",
            "data/structures/shear8-yielding.json",
        ],
        vec!["plant"],
        // An imported structure's run prints its summary after writing its history.
        vec![
            "simulate",
            "--structure",
            "data/structures/opensees-frame-1x1.json",
            "--scenario",
            "fe-pure",
            "--motion",
            "el-centro",
            "--out",
            closed_out.to_str().unwrap(),
        ],
    ] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_rths"))
            .args(&args)
            .current_dir(repo())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take()); // closed before the first line
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "rths {args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}

/// An edit of a rig file's JSON.
type Edit = fn(&mut serde_json::Value);

#[test]
fn silently_accepted_inputs_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("x.json").display().to_string();
    let o = out.as_str();
    // A model made at another rate: refused with the command that makes one at this rate.
    let lr = std::fs::read_to_string(repo().join("data/models/lr.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&lr).unwrap();
    v["dt_s"] = (1.0 / 4096.0).into();
    let lr4096 = write(d, "lr4096.json", &v.to_string());
    refused(
        &["simulate", "--scenario", "lr-online", "--model", &lr4096],
        &["4096", "`rths train lr --out FILE`"],
    );
    refused(&["check-model", &lr4096], &["`rths train lr --out FILE`"]);
    // A model the scenario does not run.
    refused(
        &[
            "simulate",
            "--scenario",
            "fe-online",
            "--model",
            "data/models/lr.json",
        ],
        &["runs no metamodel"],
    );
    // Flags a kind ignores or values out of range.
    refused(
        &["train", "lr", "--rate", "4096", "--out", o],
        &["--rate 4096"],
    );
    refused(
        &["train", "lr", "--delay-steps", "100000", "--out", o],
        &["delay_steps 100000 exceeds the controller's maximum 64"],
    );
    refused(
        &["train", "lrx", "--perturbation=-1", "--out", o],
        &["--perturbation -1"],
    );
    refused(
        &[
            "train",
            "nonlinear",
            "--structure",
            "data/structures/shear3-yielding.json",
            "--modes",
            "0",
            "--out",
            o,
        ],
        &["--modes 0", "1..=3"],
    );
    refused(
        &["analyze", "--scale", "0"],
        &["--scale must be a positive"],
    );
    refused(&["analyze", "--scale=-1"], &["--scale must be a positive"]);
    // Rig files: another rate, values out of physical range (named, with the limit).
    let rig = d.join("rig.json").display().to_string();
    let (code, _, err) = rths(&["identify", "--out", &rig]);
    assert_eq!(code, Some(0), "{err}");
    let text = std::fs::read_to_string(&rig).unwrap();
    let edits: [(&str, Edit, &str); 4] = [
        (
            "dt",
            |v| v["actuator"]["dt_s"] = (1.0 / 4096.0).into(),
            "rths identify",
        ),
        (
            "lead",
            |v| v["compensation"]["lead_weights"][0] = 1e308.into(),
            "compensation.lead_weights",
        ),
        (
            "k",
            |v| v["specimen_fit"]["stiffness_kn_per_mm"] = 1e300.into(),
            "specimen_fit.stiffness_kn_per_mm",
        ),
        (
            "m",
            |v| v["specimen_fit"]["mass_kn_s2_per_mm"] = (-1.0).into(),
            "specimen_fit.mass_kn_s2_per_mm",
        ),
    ];
    for (name, edit, field) in edits {
        let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
        edit(&mut v);
        let p = write(d, &format!("rig-{name}.json"), &v.to_string());
        let err = refused(
            &["simulate", "--scenario", "fe-online-ats", "--rig", &p],
            &[field],
        );
        assert!(err.len() < 600, "compact: {err}");
    }
}

#[test]
fn check_model_takes_every_kind_and_agrees_with_the_runs() {
    for m in [
        "lr",
        "lrx",
        "rnn-5",
        "nl-paper-frame-yielding",
        "nl-shear3-yielding",
        "nl-shear8-yielding",
    ] {
        let (code, out, err) = rths(&["check-model", &format!("data/models/{m}.json")]);
        assert_eq!(code, Some(0), "{m}: {err}");
        assert!(out.contains("valid rths model file"), "{out}");
    }
    let dir = tempfile::tempdir().unwrap();
    let meta = dir.path().join("meta.json").display().to_string();
    let (code, _, err) = rths(&[
        "train",
        "meta",
        "--structure",
        "data/structures/shear8.json",
        "--out",
        &meta,
    ]);
    assert_eq!(code, Some(0), "{err}");
    let (code, out, err) = rths(&["check-model", &meta]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("structure-meta"), "{out}");
}

/// Every test that returns early without QEMU or openseespy is also marked `#[ignore]`d when the
/// tool was absent at build time (build.rs), so `cargo test` counts it as ignored, with the reason,
/// instead of printing "ok" for a test that did not run.
#[test]
fn every_test_that_needs_qemu_or_openseespy_is_ignored_without_it() {
    let marks = [
        ("qemu_missing(", "rths_no_qemu"),
        ("opensees_available(", "rths_no_opensees"),
        ("opensees(\"", "rths_no_opensees"),
    ];
    // `#[cfg_attr(FLAG, ignore = ...)]`, or `#[cfg_attr(any(.., FLAG, ..), ignore = ...)]` for a
    // test that needs both tools (whitespace removed).
    let ignored_without = |attrs: &str, flag: &str| {
        attrs.split("#[cfg_attr(").skip(1).any(|a| {
            a.split_once(",ignore=").is_some_and(|(cond, _)| {
                cond == flag
                    || cond
                        .strip_prefix("any(")
                        .is_some_and(|c| c.trim_end_matches(')').split(',').any(|f| f == flag))
            })
        })
    };
    let mut checked = 0;
    for entry in std::fs::read_dir(repo().join("tests")).unwrap() {
        let path = entry.unwrap().path();
        // This file names the calls without making them.
        if path.extension().is_none_or(|e| e != "rs") || path.ends_with("inputs.rs") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            for (call, mark) in marks {
                if !line.contains(call)
                    || line.contains("fn ")
                    || line.trim_start().starts_with("//")
                {
                    continue;
                }
                // The attributes above the enclosing test function.
                let test = lines[..i]
                    .iter()
                    .rposition(|l| l.trim() == "#[test]")
                    .unwrap_or_else(|| panic!("{}:{}: not in a test", path.display(), i + 1));
                // Whitespace-free, as formatted on one line or several.
                let attrs: String = lines[test..i].concat().split_whitespace().collect();
                assert!(
                    ignored_without(&attrs, mark),
                    "{}:{}: a test that skips without the tool has no \
                     `#[cfg_attr({mark}, ignore = ...)]` (or `any(.., {mark}, ..)`)",
                    path.display(),
                    i + 1
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 27, "only {checked} tests found");
}

/// Each cause is printed once, naming the file; huge values in exponent form; no Debug structs.
#[test]
fn errors_print_each_cause_once_and_readably() {
    let err = refused(
        &["analyze", "--motion", "data/"],
        &["data/", "Is a directory"],
    );
    assert_eq!(err.matches("Is a directory").count(), 1, "{err}");
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "file", "not a folder");
    let rig = format!("{file}/rig.json");
    let err = refused(&["identify", "--out", &rig], &["cannot write", "rig.json"]);
    assert!(!err.contains("Os {") && !err.contains("IoError("), "{err}");
    let png = format!("{file}/bode.png");
    let err = refused(&["plant", "--bode", &png], &["cannot write", "bode.png"]);
    assert!(!err.contains("Os {") && !err.contains("IoError("), "{err}");
    let out = dir.path().join("rig.json").display().to_string();
    let err = refused(
        &["identify", "--amplitude-mm", "1e300", "--out", &out],
        &["--amplitude-mm", "got 1e300"],
    );
    assert!(!err.contains("0000000000"), "{err}");
    refused(
        &[
            "link",
            "--tcp",
            "127.0.0.1:9",
            "--timeout-s",
            "1e300",
            "status",
        ],
        &["--timeout-s must be a positive number of seconds, got 1e300"],
    );
}

/// The long commands refuse an output folder they cannot write before computing (their first line
/// of output is the refusal).
#[test]
fn long_commands_check_their_output_folder_first() {
    let dir = tempfile::tempdir().unwrap();
    let file = write(dir.path(), "file", "not a folder");
    let out = format!("{file}/out");
    for args in [
        vec!["robustness", "--quick", "--out", &out],
        vec!["nonlinear-study", "--out", &out],
        vec!["benchmark", "--out", &out],
    ] {
        let (code, stdout, err) = rths(&args);
        assert_eq!(code, Some(1), "{args:?}: {err}");
        assert!(
            err.contains("cannot create the output folder") && err.contains(&out),
            "{args:?}: {err}"
        );
        assert!(
            stdout.is_empty(),
            "{args:?} printed before refusing: {stdout}"
        );
    }
}

/// One exit status for a stopped run (docs/commands.md): 3 from `simulate` and `benchmark` alike,
/// after the figures; 0 for a run to its end.
#[test]
fn a_stopped_run_exits_3_from_every_command() {
    let (code, out, err) = rths(&["simulate", "--scenario", "fe-online"]);
    assert_eq!(code, Some(3), "{err}");
    assert!(out.contains("stable              no"), "{out}");
    assert!(
        err.starts_with("stopped: the supervisor stopped the run: CommandVelocity at 2.35"),
        "{err}"
    );
    let (code, _, err) = rths(&["simulate", "--scenario", "fe-pure"]);
    assert_eq!(code, Some(0), "{err}");
    // The benchmark's frame without delay compensation goes unstable (as `fe-online` does).
    let (code, out, err) = rths(&[
        "benchmark",
        "--case",
        "1",
        "--record",
        "el-centro",
        "--controller",
        "fe",
    ]);
    assert_eq!(code, Some(3), "{err}");
    assert!(out.contains("UNSTABLE"), "{out}");
    assert_eq!(
        err.matches("the supervisor stopped the run").count(),
        1,
        "{err}"
    );
}

/// `train nonlinear --evaluate` finds its scoring records (embedded) from any working directory.
#[test]
fn train_nonlinear_evaluate_runs_outside_the_repository() {
    let dir = tempfile::tempdir().unwrap();
    let structure = repo().join("data/structures/paper-frame-yielding.json");
    let model = repo().join("data/models/nl-paper-frame-yielding.json");
    let (code, out, err) = rths_in(
        dir.path(),
        &[
            "train",
            "nonlinear",
            "--structure",
            structure.to_str().unwrap(),
            "--out",
            model.to_str().unwrap(),
            "--evaluate",
        ],
    );
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("pure loop of"), "{out}");
    assert!(out.to_lowercase().contains("morgan"), "{out}");
}

/// The benchmark grid's progress bar is drawn only on a terminal: captured, its output holds the
/// table and no bar.
#[test]
fn progress_bars_are_hidden_when_stderr_is_not_a_terminal() {
    let (code, out, err) = rths(&["benchmark", "--perturbed", "0"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(out.contains("(12 runs in"), "{out}");
    assert!(!err.contains("benchmark runs"), "{err}");
}

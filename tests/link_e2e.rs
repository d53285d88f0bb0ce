//! The lab workflow over the link, end to end, with the firmware's LRX build in QEMU (issue 13,
//! item 5): identify the rig through the board → train LRX for that rig → upload the model and a
//! record that is not compiled in (a CSV file) → run → record → report. Every step is the `rths`
//! command a lab types. Checked: the rig file's estimates equal `rths identify`'s of the same
//! virtual rig to the bit (the emulated board's plant is `unr-compact`, linear, seed 1); the
//! recorded commands equal the host simulation's bit for bit; the report's figures equal `rths
//! simulate`'s. What the controller and the identification saw is only the device's stream (the
//! estimators take its arrays); the reference is used by the report alone.
//!
//! Skipped (with a loud message) only when `qemu-system-arm` is not installed; with
//! `RTHS_REQUIRE_QEMU` set (CI) a missing QEMU fails instead.
#![cfg(feature = "sim")]

mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The link image with the shipped LRX model as its default (`--features link`,
/// `RTHS_MODEL=data/models/lrx.json`): every link image identifies (the excitation's tables) and
/// takes an uploaded LRX model.
fn lrx_link_elf() -> PathBuf {
    static ELF: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    ELF.get_or_init(|| {
        let lrx = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models/lrx.json");
        build_elf_model(
            &["--features", "link"],
            None,
            Some(&lrx.display().to_string()),
            "rths-firmware-e2e.elf",
        )
    })
    .clone()
}

/// Build the firmware with `args` (and the `fault-inject` plan `fault`) and copy its ELF to `name`;
/// one build at a time (they share the firmware's target directory and its output path).
fn build_elf(args: &[&str], fault: Option<&str>, name: &str) -> PathBuf {
    build_elf_model(args, fault, None, name)
}

/// [`build_elf`] with the default model `model` (`RTHS_MODEL`; unset if `None`).
fn build_elf_model(args: &[&str], fault: Option<&str>, model: Option<&str>, name: &str) -> PathBuf {
    static BUILD: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one = BUILD.lock().unwrap_or_else(|e| e.into_inner());
    let mut cmd = Command::new(env!("CARGO"));
    cmd.current_dir(firmware_dir())
        .args(["build", "--release"])
        .args(args)
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("RTHS_STRUCTURE")
        .env_remove("RTHS_BUDGET");
    match fault {
        Some(f) => cmd.env("RTHS_FAULT", f),
        None => cmd.env_remove("RTHS_FAULT"),
    };
    match model {
        Some(m) => cmd.env("RTHS_MODEL", m),
        None => cmd.env_remove("RTHS_MODEL"),
    };
    assert!(
        cmd.status().unwrap().success(),
        "firmware build {args:?} failed"
    );
    let elf = firmware_dir().join("target/thumbv7em-none-eabihf/release/rths-firmware");
    let dest = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::copy(&elf, &dest).unwrap();
    dest
}

/// `rths ARGS` in `dir`: its stdout (the test fails with its stderr if it failed).
fn rths(dir: &Path, args: &[&str]) -> String {
    let t = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "rths {args:?}:\n{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    println!(
        "rths {} ({:.1} s)",
        args.join(" "),
        t.elapsed().as_secs_f64()
    );
    text
}

fn json(text: &str) -> serde_json::Value {
    serde_json::from_str(text).unwrap()
}

#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn identify_train_upload_run_and_report_through_the_board() {
    if qemu_missing("link e2e test") {
        return;
    }
    let t0 = Instant::now();
    let elf = lrx_link_elf();
    let elf = elf.to_str().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    println!("firmware build: {:.1} s", t0.elapsed().as_secs_f64());

    // 1. Identify through the board, and the same virtual rig on the host.
    let t = Instant::now();
    let out = rths(d, &["link", "--qemu", elf, "identify", "--out", "rig.json"]);
    println!(
        "{out}identify through the board: {:.1} s",
        t.elapsed().as_secs_f64()
    );
    rths(
        d,
        &[
            "identify",
            "--preset",
            "unr-compact",
            "--out",
            "host-rig.json",
        ],
    );
    let board: serde_json::Value = json(&std::fs::read_to_string(d.join("rig.json")).unwrap());
    let host: serde_json::Value = json(&std::fs::read_to_string(d.join("host-rig.json")).unwrap());
    assert!(
        board["provenance"]["device"]
            .as_str()
            .unwrap()
            .contains("excitation played by the device"),
        "{}",
        board["provenance"]
    );
    assert!(host["provenance"].get("device").is_none());
    // Same plant, same noise stream, same excitation, same estimators: the same estimates, bit
    // for bit (serde_json's float_roundtrip: equal text is equal f64).
    for key in [
        "preset",
        "board",
        "specimen",
        "seed",
        "excitation",
        "actuator",
        "compensation",
        "specimen_fit",
        "quality",
    ] {
        assert_eq!(board[key], host[key], "{key}");
    }
    println!(
        "board rig: delay {} ms, gain {}, stiffness {} kN/mm: equal to `rths identify`'s",
        board["actuator"]["delay_ms"], board["actuator"]["gain"], board["specimen_fit"]
    );

    // 2. Train LRX for that rig (the lead filter and the specimen's dynamics from the rig file).
    let t = Instant::now();
    rths(
        d,
        &[
            "train", "lrx", "--rig", "rig.json", "--quiet", "--out", "lrx.json",
        ],
    );
    println!("train lrx --rig: {:.1} s", t.elapsed().as_secs_f64());
    // The rig-trained model is uploaded whole: its 20 chunked values, then its lead adaptation and
    // specimen mass and damping as the rig compensation (`Link::upload`).
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("lrx.json")).unwrap()).unwrap();
    for extra in [
        "lead_adapt_ticks",
        "specimen_mass_kn_s2_per_mm",
        "specimen_damping_kn_s_per_mm",
    ] {
        assert!(
            m["lrx"].get(extra).is_some(),
            "a rig-trained model has {extra}"
        );
    }

    // 3. Upload the model and a CSV record the firmware does not have compiled in, run, record:
    // the first 10 s of the benchmark's Morgan Hill record (2001 samples at 0.005 s; its strong
    // motion starts within them).
    let morgan = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/vrths_benchmark/morgan.csv"),
    )
    .unwrap();
    let head: Vec<&str> = morgan.lines().take(1 + 2001).collect();
    std::fs::write(d.join("morgan-10s.csv"), head.join("\n") + "\n").unwrap();
    let motion = "morgan-10s.csv";
    let scale = "0.5";
    let t = Instant::now();
    rths(
        d,
        &[
            "link", "--qemu", elf, "run", "--model", "lrx.json", "--motion", motion, "--scale",
            scale, "--out", "run.csv",
        ],
    );
    println!("run through the board: {:.1} s", t.elapsed().as_secs_f64());

    // 4. The commands, bit for bit, against the host simulation of the same rig (the emulated
    // board's plant: unr-compact, linear, seed 1), record (as the CSV file reads back), scale and
    // model: what `rths simulate` runs (its history.csv rounds to 1e-6 mm, so compare in process).
    use rths::studies::scenario::{self, ScenarioId, ScenarioSetup};
    let rec = rths::link_host::read_recording(&std::fs::read_to_string(d.join("run.csv")).unwrap())
        .unwrap();
    assert_eq!(rec.header.get("scenario"), Some("lrx-online"));
    let model = rths::machinery::model_file::ModelFile::load(&d.join("lrx.json")).unwrap();
    let ag = rths::machinery::motion::GroundMotion::from_path(&d.join(motion))
        .unwrap()
        .scaled(0.5)
        .resample_mm_s2(rths_core::params::DT_S);
    let reference = rths::studies::study::reference_mm(&ag, 1.0).unwrap();
    let host = scenario::run(&ScenarioSetup {
        id: ScenarioId::LrxOnline,
        ground_accel_mm_s2: &ag,
        reference_mm: &reference,
        rig: rths::machinery::reference::rig_config(
            rths_hal_sim::Preset::UnrCompact,
            rths_hal_sim::Specimen::Linear,
            1.0,
            1,
        ),
        stiffness_factor: 1.0,
        lr: None,
        rnn: None,
        lrx: Some(rths::machinery::models::lrx_params(&model).unwrap()),
        delay_steps: model.delay_steps,
    })
    .unwrap();
    let host_cmd = &host.history.command_mm;
    assert!(
        rec.rows.len() + 1 >= host_cmd.len(),
        "{} rows",
        rec.rows.len()
    );
    let mut identical = 0;
    for (row, h) in rec.rows.iter().zip(&host_cmd[1..]) {
        assert_eq!(row.command_mm.to_bits(), h.to_bits(), "tick {}", row.tick);
        identical += 1;
    }
    println!("{identical} commands bit-identical to the host simulation");
    assert_eq!(identical, ag.len() - 1);
    let sim_args = [
        "simulate",
        "--scenario",
        "lrx-online",
        "--model",
        "lrx.json",
        "--motion",
        motion,
        "--scale",
        scale,
        "--rig",
        "rig.json",
        "--json",
    ];
    let sim = json(&rths(d, &sim_args));

    // 5. The report's figures equal the simulation's.
    let rep = json(&rths(d, &["report", "run.csv", "--json"]));
    println!("report   {}", rep["scenarios"][0]);
    println!("simulate {}", sim["scenarios"][0]);
    assert_eq!(rep["scenarios"][0], sim["scenarios"][0]);
    assert!(rep["scenarios"][0]["nrmse_measured_pct"].as_f64().unwrap() > 0.0);
    println!("e2e wall time: {:.1} s", t0.elapsed().as_secs_f64());
}

/// A device refuses an identification while a test is armed, and after its emulated plant has run
/// (`Busy`, `Unsupported`); the host writes nothing.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn an_identification_is_refused_while_armed_and_nothing_is_written() {
    if qemu_missing("link e2e test") {
        return;
    }
    use rths::link_host::{LinkHostError, Qemu};
    use rths_link::{NackReason, Request};
    let elf = lrx_link_elf();
    let dir = tempfile::tempdir().unwrap();
    let mut q = Qemu::start(&elf, dir.path()).unwrap();
    let link = &mut q.link;
    link.arm(1).unwrap();
    match link.identify(2.0, std::time::Duration::from_secs(5)) {
        Err(LinkHostError::Refused(Request::Identify, NackReason::Busy)) => {}
        r => panic!("expected Busy, got {r:?}"),
    }
    match link.identify(3.0, std::time::Duration::from_secs(5)) {
        Err(LinkHostError::Refused(Request::Identify, NackReason::OutOfRange)) => {}
        r => panic!("expected OutOfRange, got {r:?}"),
    }
    drop(q);
    // Through the CLI: refused, no rig file.
    let out = Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(["link", "--qemu"])
        .arg(&elf)
        .args(["identify", "--amplitude-mm", "3", "--out", "rig.json"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(!dir.path().join("rig.json").exists());
}

/// A NaN on the displacement sensor 5 s into the identification (`fault-inject`, `nan-disp@5`): the
/// device's supervisor trips and ramps to rest, the host reports the fault and writes nothing.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn a_nan_during_an_identification_trips_and_nothing_is_written() {
    if qemu_missing("link e2e test") {
        return;
    }
    let elf = build_elf(
        &["--features", "link,fault-inject"],
        Some("nan-disp@5"),
        "rths-firmware-e2e-nan.elf",
    );
    let dir = tempfile::tempdir().unwrap();
    let t = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(["link", "--qemu"])
        .arg(&elf)
        .args(["identify", "--out", "rig.json"])
        .current_dir(dir.path())
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{text}({:.1} s)", t.elapsed().as_secs_f64());
    assert!(!out.status.success());
    assert!(text.contains("fault-NonFiniteSample"), "{text}");
    assert!(text.contains("nothing written"), "{text}");
    assert!(!dir.path().join("rig.json").exists());
    assert!(!dir.path().join("rig.png").exists());
}

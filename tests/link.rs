//! The command link end to end: the firmware built with `--features link` runs in QEMU with its
//! USART2 (QEMU's second serial port) on a loopback socket; the host (`rths::link_host`) uploads a freshly trained LR model,
//! runs El Centro, records the telemetry to CSV and checks it against the host simulation of the
//! same scenario, model and seed. Corrupted and invalid uploads are refused and the old model stays.
//!
//! Skipped (with a loud message) only when `qemu-system-arm` is not installed; with
//! `RTHS_REQUIRE_QEMU` set (CI) a missing QEMU fails instead.
#![cfg(feature = "sim")]

mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use rths::link_host::{upload_message, LinkHostError, Qemu};
use rths::machinery::model_file::ModelFile;
use rths::machinery::train::{data, lr};
use rths::studies::scenario::{self, ScenarioId, ScenarioRun, ScenarioSetup};
use rths::studies::study;
use rths_core::metamodel::LrParams;
use rths_core::params::{Prototype, DT_S, PAPER_DELAY_STEPS};
use rths_hal_sim::{Preset, Specimen};
use rths_link::{HostMsg, NackReason, Request, RunState};

/// `cargo build --release --features link` of the firmware, ELF copied to a private path. Built
/// once per test binary.
fn link_elf() -> PathBuf {
    static ELF: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    ELF.get_or_init(|| build_elf(&["--features", "link"], "rths-firmware-link.elf"))
        .clone()
}

/// The link image with the shipped LRX model as its default (`--features link`,
/// `RTHS_MODEL=data/models/lrx.json`).
fn lrx_link_elf() -> PathBuf {
    static ELF: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    ELF.get_or_init(|| {
        build_elf_default(
            &["--features", "link"],
            "rths-firmware-lrx-link.elf",
            &shipped_path("lrx.json"),
        )
    })
    .clone()
}

/// The shipped model file `name` (`data/models/`).
fn shipped_path(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/models")
        .join(name)
        .display()
        .to_string()
}

/// Build the firmware with `args` and copy its ELF to `name`; one build at a time (they share the
/// firmware's target directory and its output path).
fn build_elf(args: &[&str], name: &str) -> PathBuf {
    build_elf_with(args, name, None)
}

/// [`build_elf`] with the default model `model` (`RTHS_MODEL`: a model file, or `fe-ats`).
fn build_elf_default(args: &[&str], name: &str, model: &str) -> PathBuf {
    build_elf_env(args, name, None, Some(model))
}

/// [`build_elf`] with the `fault-inject` plan `RTHS_FAULT` set to `fault` (or unset).
fn build_elf_with(args: &[&str], name: &str, fault: Option<&str>) -> PathBuf {
    build_elf_env(args, name, fault, None)
}

/// [`build_elf`] with the fault plan `fault` and the default model `model` (each unset if `None`).
fn build_elf_env(args: &[&str], name: &str, fault: Option<&str>, model: Option<&str>) -> PathBuf {
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
    let status = cmd.status().unwrap();
    assert!(status.success(), "firmware build {args:?} failed");
    let elf = firmware_dir().join("target/thumbv7em-none-eabihf/release/rths-firmware");
    let dest = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::copy(&elf, &dest).unwrap();
    dest
}

struct Trained {
    ag: Vec<f64>,
    reference: Vec<f64>,
    phase1: ModelFile,
    phase2: ModelFile,
}

/// The paper's two-phase LR training, from scratch (as `rths reproduce` does it).
fn train() -> Trained {
    let ag = rths::machinery::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
    let proto = Prototype::paper();
    let reference = study::reference_mm(&ag, 1.0).unwrap();
    let resp = data::pure_response(&proto, &ag, DT_S).unwrap();
    let fit1 = lr::fit_pure(
        &resp,
        PAPER_DELAY_STEPS,
        proto.brace_axial_stiffness_kn_per_mm(),
        lr::DEFAULT_RCOND,
    )
    .unwrap();
    let phase1 = ModelFile::new_lr(fit1.solution.theta.to_vec(), PAPER_DELAY_STEPS, DT_S);
    let offline = scenario::run(&setup(
        ScenarioId::LrOffline,
        &ag,
        &reference,
        &fit1.solution.theta,
    ))
    .unwrap();
    let (phase2, _) = study::lr_phase2(&ag, &reference, &offline, lr::DEFAULT_RCOND).unwrap();
    Trained {
        ag,
        reference,
        phase1,
        phase2,
    }
}

fn setup<'a>(
    id: ScenarioId,
    ag: &'a [f64],
    reference: &'a [f64],
    theta: &[f64],
) -> ScenarioSetup<'a> {
    ScenarioSetup {
        id,
        ground_accel_mm_s2: ag,
        reference_mm: reference,
        // The qemu board's plant: unr-compact, linear specimen, seed 1.
        rig: rths::machinery::reference::rig_config(Preset::UnrCompact, Specimen::Linear, 1.0, 1),
        stiffness_factor: 1.0,
        lr: Some(LrParams::from_slice(theta).unwrap()),
        rnn: None,
        lrx: None,
        delay_steps: PAPER_DELAY_STEPS,
    }
}

fn theta(m: &ModelFile) -> [f64; 6] {
    m.lr.as_ref().unwrap().theta.clone().try_into().unwrap()
}

fn checksum_of(m: &ModelFile) -> u32 {
    match upload_message(m).unwrap() {
        HostMsg::UploadLr { checksum, .. } => checksum,
        _ => unreachable!(),
    }
}

struct Row {
    seq: u32,
    tick: u32,
    state: String,
    command_mm: f64,
    target_mm: f64,
}

fn read_csv(path: &Path) -> Vec<Row> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(rths::link_host::CSV_HEADER));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 8, "{l}");
            Row {
                seq: f[0].parse().unwrap(),
                tick: f[1].parse().unwrap(),
                state: f[3].to_string(),
                command_mm: f[4].parse().unwrap(),
                target_mm: f[5].parse().unwrap(),
            }
        })
        .collect()
}

fn nrmse_pct(x: &[f64], reference: &[f64]) -> f64 {
    let n = reference.len() as f64;
    let peak = reference.iter().fold(0.0f64, |m, r| m.max(r.abs()));
    let ss: f64 = x.iter().zip(reference).map(|(a, b)| (a - b).powi(2)).sum();
    100.0 * (ss / n).sqrt() / peak
}

/// The board's own report: the last `RESULT` line of its semihosting output, parsed.
fn board_result(stdout: &str) -> serde_json::Value {
    let line = stdout
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("RESULT "))
        .expect("the board printed no RESULT line");
    serde_json::from_str(line).unwrap()
}

#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn upload_run_and_record_el_centro_over_the_link_matches_the_host() {
    if qemu_missing("link test") {
        return;
    }
    let t = train();
    let elf = link_elf();
    let dir = tempfile::tempdir().unwrap();
    let mut q = Qemu::start(&elf, dir.path()).unwrap();
    let link = &mut q.link;
    link.timeout = Duration::from_secs(20);

    // Boot: the compiled-in model (data/models/lr.json) is active, the run idle.
    let s0 = link.status().unwrap();
    assert_eq!(s0.state, RunState::Idle);
    let compiled =
        ModelFile::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models/lr.json"))
            .unwrap();
    // The compiled-in coefficients are the file's exact f64 values (build.rs parses with
    // serde_json's float_roundtrip), so the checksums agree.
    assert_eq!(
        s0.model_checksum,
        checksum_of(&compiled),
        "boot model vs data/models/lr.json"
    );

    // A fresh phase-1 model: accepted, now active.
    let c1 = link.upload(&t.phase1).unwrap();
    assert_eq!(c1, checksum_of(&t.phase1));
    assert_eq!(link.status().unwrap().model_checksum, c1);

    // A corrupted upload of the phase-2 model (one bit flipped on the wire): the frame is dropped
    // (CRC), counted, no answer; the phase-1 model stays.
    let mut frame = [0u8; rths_link::MAX_FRAME + 1];
    let n = rths_link::encode(&upload_message(&t.phase2).unwrap(), &mut frame).unwrap();
    frame[n / 2] ^= 0x10;
    link.send_raw(&[0]).unwrap();
    link.send_raw(&frame[..n]).unwrap();
    let s = link.status().unwrap();
    assert_eq!(
        s.model_checksum, c1,
        "a corrupted upload must not change the model"
    );
    assert_eq!(
        s.bad_frames,
        s0.bad_frames + 1,
        "the corrupted frame is counted"
    );

    // Well-framed but invalid uploads: refused whole, the old model kept.
    let good = upload_message(&t.phase2).unwrap();
    let HostMsg::UploadLr {
        theta: th,
        delay_steps,
        checksum,
        ..
    } = good
    else {
        unreachable!()
    };
    let mut nan = th;
    nan[3] = f64::NAN;
    let cases = [
        (
            HostMsg::UploadLr {
                features: 5,
                theta: th,
                delay_steps,
                checksum,
            },
            NackReason::Shape,
        ),
        (
            HostMsg::UploadLr {
                features: 6,
                theta: nan,
                delay_steps,
                checksum: rths_link::model_checksum(&nan, delay_steps),
            },
            NackReason::NotFinite,
        ),
        (
            HostMsg::UploadLr {
                features: 6,
                theta: th,
                delay_steps,
                checksum: checksum ^ 1,
            },
            NackReason::Checksum,
        ),
    ];
    for (msg, why) in cases {
        match link.request(&msg) {
            Err(LinkHostError::Refused(Request::UploadLr, got)) => assert_eq!(got, why),
            other => panic!("expected a refusal ({why:?}), got {other:?}"),
        }
        assert_eq!(link.status().unwrap().model_checksum, c1);
    }
    // Start before arm is refused.
    assert!(matches!(
        link.start(),
        Err(LinkHostError::Refused(
            Request::Start,
            NackReason::InvalidState
        ))
    ));

    // The phase-2 model: accepted; arm, start, record the whole run.
    let c2 = link.upload(&t.phase2).unwrap();
    assert_eq!(link.status().unwrap().model_checksum, c2);
    link.arm(1).unwrap();
    link.start().unwrap();
    let csv = dir.path().join("run.csv");
    let summary = rths::cmd::link::record_csv(link, &csv, Duration::from_secs(60)).unwrap();
    println!("{summary:?}");
    assert!(summary.complete(), "lost telemetry: {summary:?}");
    let (end, ticks, _, _) = summary.end.unwrap();
    assert_eq!(end, RunState::Done);
    assert_eq!(ticks, t.ag.len() as u32, "the whole El Centro record");

    // The recording against the host simulation of the same scenario, model and seed.
    let rows = read_csv(&csv);
    assert_eq!(rows.len(), summary.records);
    for (i, r) in rows.iter().enumerate() {
        assert_eq!((r.seq, r.tick), (i as u32, i as u32), "row {i}");
    }
    let host: ScenarioRun = scenario::run(&setup(
        ScenarioId::LrOnline,
        &t.ag,
        &t.reference,
        &theta(&t.phase2),
    ))
    .unwrap();
    assert!(host.report.stable);
    let h = &host.history;
    let n = t.ag.len();
    // Firmware record k holds the command of tick k; host row k+1 holds it (row k is the command in
    // force at time k).
    let mut max_cmd = 0.0f64;
    let mut identical = 0usize;
    for (row, hs) in rows.iter().zip(&h.command_mm[1..]) {
        let fw = row.command_mm;
        max_cmd = max_cmd.max((fw - hs).abs());
        identical += usize::from(fw.to_bits() == hs.to_bits());
    }
    // Target rows as the host counts them: row k = target produced at tick k−1 (0 at k = 0).
    let target_rows: Vec<f64> = (0..n)
        .map(|k| if k == 0 { 0.0 } else { rows[k - 1].target_mm })
        .collect();
    let fw_nrmse = nrmse_pct(&target_rows, &t.reference);
    let host_nrmse = host.report.nrmse_pct.unwrap();
    println!(
        "command history: max |firmware − host| = {max_cmd:e} mm over {} ticks, {identical} bit-identical; \
         NRMSE from the recording {fw_nrmse:?} %, host {host_nrmse:?} %",
        n - 1
    );
    assert!(max_cmd <= 1e-9, "command history differs by {max_cmd} mm");
    assert!(
        (fw_nrmse - host_nrmse).abs() <= 0.01,
        "NRMSE {fw_nrmse} vs host {host_nrmse}"
    );
    assert!((fw_nrmse - host_nrmse).abs() <= 1e-6 * host_nrmse.abs());
    // The end of the record: a ramp to zero, ending done at 0 mm.
    let last = rows.last().unwrap();
    assert_eq!(last.state, "done");
    assert_eq!(last.command_mm, 0.0);
    // The board's own report (semihosting RESULT) agrees.
    let r = board_result(&q.stdout());
    assert_eq!(r["end_state"], "done");
    assert_eq!(r["telemetry_dropped"], 0);
    let fw_result = r["nrmse_pct"].as_f64().unwrap();
    assert!(
        (fw_result - fw_nrmse).abs() <= 1e-9 * fw_nrmse,
        "{fw_result} vs {fw_nrmse}"
    );
    // A second run needs a new power-up on the emulated board.
    assert!(matches!(
        q.link.arm(1),
        Err(LinkHostError::Refused(
            Request::Arm,
            NackReason::Unsupported
        ))
    ));
}

#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn limits_arm_abort_over_the_link() {
    if qemu_missing("link test") {
        return;
    }
    let elf = link_elf();
    let dir = tempfile::tempdir().unwrap();
    let mut q = Qemu::start(&elf, dir.path()).unwrap();
    let link = &mut q.link;
    // Limits: a bad one is refused, a good one shows in the status.
    assert!(matches!(
        link.set_limits(-1.0, 300.0, 25.0),
        Err(LinkHostError::Refused(
            Request::SetLimits,
            NackReason::OutOfRange
        ))
    ));
    assert!(matches!(
        link.set_limits(f64::NAN, 300.0, 25.0),
        Err(LinkHostError::Refused(
            Request::SetLimits,
            NackReason::NotFinite
        ))
    ));
    link.set_limits(20.0, 300.0, 25.0).unwrap();
    let s = link.status().unwrap();
    assert_eq!(
        (s.stroke_mm, s.velocity_mm_s, s.force_kn),
        (20.0, 300.0, 25.0)
    );
    assert!(matches!(
        link.arm(0),
        Err(LinkHostError::Refused(Request::Arm, NackReason::OutOfRange))
    ));
    // Arm, start with telemetry every 4th tick, abort after ~1 s of test time.
    link.arm(4).unwrap();
    assert!(matches!(
        link.upload(&ModelFile::new_lr(vec![0.0; 6], 28, DT_S)),
        Err(LinkHostError::Refused(Request::UploadLr, NackReason::Busy))
    ));
    assert!(matches!(
        link.set_limits(20.0, 300.0, 25.0),
        Err(LinkHostError::Refused(Request::SetLimits, NackReason::Busy))
    ));
    link.start().unwrap();
    let mut got = Vec::new();
    while got.len() < 512 {
        if let rths_link::DeviceMsg::Telemetry(t) = link.recv(Duration::from_secs(20)).unwrap() {
            got.push(t);
        }
    }
    link.abort().unwrap();
    let mut rest = Vec::new();
    let summary = link
        .record(Duration::from_secs(20), got.len() as u32, |t| {
            rest.push(*t);
            Ok(())
        })
        .unwrap();
    assert!(summary.gaps.is_empty(), "{summary:?}");
    let all: Vec<_> = got.iter().chain(&rest).collect();
    for (i, t) in all.iter().enumerate() {
        assert_eq!(t.seq, i as u32);
        assert_eq!(t.tick, 4 * i as u32, "decimated by 4");
    }
    let (end, ticks, sent, dropped) = summary.end.unwrap();
    assert_eq!(end, RunState::Done);
    assert_eq!((sent as usize, dropped), (all.len(), 0));
    assert!(ticks < 81_900, "aborted early: {ticks} ticks");
    // The abort ramps to zero no faster than the end ramp (10 mm/s: 4 ticks ≤ 4 × 0.00488 mm).
    let after: Vec<_> = all
        .iter()
        .filter(|t| matches!(t.state, RunState::RampDown | RunState::Done))
        .collect();
    assert!(!after.is_empty());
    for w in after.windows(2) {
        assert!((w[1].command_mm - w[0].command_mm).abs() <= 4.0 * 10.0 * DT_S * (1.0 + 1e-9));
    }
    assert!(all.last().unwrap().command_mm.abs() <= 4.0 * 10.0 * DT_S);
    println!(
        "aborted at tick {} from {:.4} mm, done after {ticks} ticks",
        after[0].tick, after[0].command_mm
    );
}

/// The `rths link` command itself: `--qemu ELF status`, and `--port` on the pty QEMU gives with
/// `-serial pty` (the serial-port path a real board uses).
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn the_cli_talks_through_its_own_qemu_and_through_a_pty() {
    if qemu_missing("link test") {
        return;
    }
    let elf = link_elf();
    let exe = env!("CARGO_BIN_EXE_rths");
    let out = Command::new(exe)
        .args(["link", "--qemu"])
        .arg(&elf)
        .arg("status")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("state            idle"), "{text}");
    assert!(text.contains("bad frames       0"), "{text}");

    // QEMU on a pty: it prints the pty's path first.
    let dir = tempfile::tempdir().unwrap();
    let mut args = rths::link_host::qemu_args(&elf, 0);
    // The link port is the last `-serial` (USART2).
    let i = args.iter().rposition(|a| a == "-serial").unwrap();
    args[i + 1] = "pty".into();
    let log = dir.path().join("qemu.txt");
    let mut child = Command::new("qemu-system-arm")
        .args(&args)
        .current_dir(dir.path())
        .stdout(std::fs::File::create(&log).unwrap())
        .stderr(std::fs::File::create(dir.path().join("err.txt")).unwrap())
        .spawn()
        .unwrap();
    let mut pty = None;
    for _ in 0..100 {
        let s = std::fs::read_to_string(&log).unwrap_or_default()
            + &std::fs::read_to_string(dir.path().join("err.txt")).unwrap_or_default();
        if let Some(p) = s.split_whitespace().find(|w| w.starts_with("/dev/pts/")) {
            pty = Some(p.to_string());
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let Some(pty) = pty else {
        let _ = child.kill();
        panic!("QEMU printed no pty path");
    };
    let out = Command::new(exe)
        .args(["link", "--port", &pty, "status"])
        .output()
        .unwrap();
    let _ = child.kill();
    let _ = child.wait();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("state            idle"), "{text}");
}

/// A record upload request; the device's refusal reason, if any.
fn refusal(link: &mut rths::link_host::Link, msg: &HostMsg) -> Option<NackReason> {
    match link.request(msg) {
        Ok(_) => None,
        Err(LinkHostError::Refused(_, why)) => Some(why),
        Err(e) => panic!("{msg:?}: {e}"),
    }
}

#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn bad_record_uploads_are_refused_with_their_reason_and_the_record_in_force_stays() {
    use rths_link::{RecordSource, RECORD_CHUNK};
    if qemu_missing("link test") {
        return;
    }
    let elf = link_elf();
    let dir = tempfile::tempdir().unwrap();
    let mut q = Qemu::start(&elf, dir.path()).unwrap();
    let link = &mut q.link;
    link.timeout = Duration::from_secs(20);

    // Boot: the compiled-in El Centro, the host's embedded one bit for bit.
    let s0 = link.status().unwrap();
    let el = rths::machinery::motion::GroundMotion::el_centro();
    assert_eq!(s0.record.source, RecordSource::Compiled);
    assert_eq!(
        s0.record.checksum,
        rths_link::record_checksum(&el.accel_g, el.dt_s)
    );
    assert_eq!(s0.record.ticks as usize, el.resample_mm_s2(DT_S).len());
    assert_eq!(s0.record_capacity, 4096, "64 KiB, two halves of f64");
    println!(
        "record capacity {} samples: {:.2} s at 0.01 s, {:.2} s at 0.02 s",
        s0.record_capacity,
        (s0.record_capacity - 1) as f64 * 0.01,
        (s0.record_capacity - 1) as f64 * 0.02
    );

    // A good upload first (Northridge × 0.5): in force, and reported.
    let nr = rths::machinery::motion::GroundMotion::try_embedded("northridge")
        .unwrap()
        .scaled(0.5);
    let c = link.upload_record(&nr.accel_g, nr.dt_s, 0.5).unwrap();
    let good = link.status().unwrap().record;
    assert_eq!(good.source, RecordSource::Uploaded);
    assert_eq!(good.checksum, c);
    assert_eq!((good.samples, good.dt_s, good.scale), (2000, 0.02, 0.5));
    let in_force = |link: &mut rths::link_host::Link, what: &str| {
        assert_eq!(link.status().unwrap().record, good, "after {what}");
    };

    let msgs = rths::link_host::record_messages(&nr.accel_g, nr.dt_s, 0.5).unwrap();
    let (begin, chunks, commit) = (&msgs[0], &msgs[1..msgs.len() - 1], &msgs[msgs.len() - 1]);
    let HostMsg::RecordBegin { checksum, .. } = *begin else {
        unreachable!()
    };
    // Too long for memory: Loma Prieta's 7998 samples.
    let lp = rths::machinery::motion::GroundMotion::try_embedded("loma-prieta").unwrap();
    let lp_begin = rths::link_host::record_messages(&lp.accel_g, lp.dt_s, 1.0).unwrap()[0];
    assert_eq!(refusal(link, &lp_begin), Some(NackReason::TooLong));
    // Wrong rates: 0.5 s (a unit mistake), 0.1 ms (faster than the controller), NaN.
    for dt_s in [0.5, 1e-4, f64::NAN] {
        let m = HostMsg::RecordBegin {
            samples: 2000,
            dt_s,
            scale: 0.5,
            checksum,
        };
        assert_eq!(refusal(link, &m), Some(NackReason::Rate), "dt {dt_s}");
    }
    in_force(link, "bad headers");
    // A NaN in a chunk.
    assert_eq!(refusal(link, begin), None);
    let HostMsg::RecordChunk { seq, count, values } = chunks[0] else {
        unreachable!()
    };
    let mut nan = values;
    nan[RECORD_CHUNK / 2] = f64::NAN;
    let m = HostMsg::RecordChunk {
        seq,
        count,
        values: nan,
    };
    assert_eq!(refusal(link, &m), Some(NackReason::NotFinite));
    in_force(link, "a NaN");
    // Reordered (chunk 1 before 0) and duplicated (chunk 0 twice).
    assert_eq!(refusal(link, begin), None);
    assert_eq!(refusal(link, &chunks[1]), Some(NackReason::Sequence));
    assert_eq!(refusal(link, begin), None);
    assert_eq!(refusal(link, &chunks[0]), None);
    assert_eq!(refusal(link, &chunks[0]), Some(NackReason::Sequence));
    in_force(link, "reordered and duplicated chunks");
    // Truncated: the commit before the last chunk.
    assert_eq!(refusal(link, begin), None);
    for ch in &chunks[..chunks.len() - 1] {
        assert_eq!(refusal(link, ch), None);
    }
    assert_eq!(refusal(link, commit), Some(NackReason::Incomplete));
    in_force(link, "a truncated upload");
    // Corrupted on the wire: chunk 3's frame with a bit flipped is dropped (bad frame, no answer),
    // so chunk 4 comes out of sequence.
    let bad0 = link.status().unwrap().bad_frames;
    assert_eq!(refusal(link, begin), None);
    for ch in &chunks[..3] {
        assert_eq!(refusal(link, ch), None);
    }
    let mut frame = [0u8; rths_link::MAX_FRAME + 1];
    let n = rths_link::encode(&chunks[3], &mut frame).unwrap();
    frame[n / 2] ^= 0x04;
    link.send_raw(&[0]).unwrap();
    link.send_raw(&frame[..n]).unwrap();
    assert_eq!(refusal(link, &chunks[4]), Some(NackReason::Sequence));
    assert_eq!(link.status().unwrap().bad_frames, bad0 + 1);
    in_force(link, "a corrupted chunk");
    // Samples changed (each frame intact, the end-to-end checksum not): refused at the commit.
    let HostMsg::RecordBegin {
        samples,
        dt_s,
        scale,
        ..
    } = *begin
    else {
        unreachable!()
    };
    let wrong = HostMsg::RecordBegin {
        samples,
        dt_s,
        scale,
        checksum: checksum ^ 1,
    };
    assert_eq!(refusal(link, &wrong), None);
    for ch in chunks {
        assert_eq!(refusal(link, ch), None);
    }
    assert_eq!(refusal(link, commit), Some(NackReason::Checksum));
    in_force(link, "a wrong checksum");
    // An upload while a test is armed: refused Busy.
    link.arm(1).unwrap();
    assert_eq!(refusal(link, begin), Some(NackReason::Busy));
    assert_eq!(refusal(link, commit), Some(NackReason::Busy));
    assert_eq!(link.status().unwrap().record, good, "armed");
}

/// `rths link --qemu ELF run --motion CSV --scale 0.5 --on-link-loss ramp-down --out RUN` in `dir`
/// (ramp down if this host falls silent: its heartbeats keep the run going to the end); its
/// stdout, the run required to succeed.
fn cli_link_run(elf: &Path, dir: &Path, csv_motion: &Path, run_csv: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(["link", "--qemu"])
        .arg(elf)
        .args(["run", "--motion"])
        .arg(csv_motion)
        .args(["--scale", "0.5", "--on-link-loss", "ramp-down", "--out"])
        .arg(run_csv)
        .current_dir(dir)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{text}");
    text
}

/// The recording's commands, bit for bit, against the host simulation of the same record (as the
/// CSV file reads back) × 0.5 with the compiled-in model (data/models/lr.json).
fn assert_lr_commands_equal_the_host(rec: &rths::link_host::Recording, csv_motion: &Path) {
    let motion = rths::machinery::motion::GroundMotion::from_path(csv_motion)
        .unwrap()
        .scaled(0.5);
    let ag = motion.resample_mm_s2(DT_S);
    let reference = study::reference_mm(&ag, 1.0).unwrap();
    let lr_file =
        ModelFile::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models/lr.json"))
            .unwrap();
    let host = scenario::run(&setup(
        ScenarioId::LrOnline,
        &ag,
        &reference,
        &theta(&lr_file),
    ))
    .unwrap();
    assert!(rec.rows.len() >= ag.len());
    let mut identical = 0;
    for (row, hs) in rec.rows.iter().zip(&host.history.command_mm[1..]) {
        assert_eq!(row.command_mm.to_bits(), hs.to_bits(), "tick {}", row.tick);
        identical += 1;
    }
    println!(
        "{identical} of {} commands bit-identical to the host",
        ag.len() - 1
    );
    assert_eq!(identical, ag.len() - 1);
}

/// `rths ARGS` in `dir`, required to succeed: its stdout as JSON.
fn cli_json(dir: &Path, args: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_rths"))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

/// The ground motion as a CSV file the firmware does not have compiled in, the `rths link run`
/// of it in QEMU, and `rths report` of the recording against `rths simulate` of the same record.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn a_csv_record_uploaded_run_and_reported_equals_the_host_simulation() {
    if qemu_missing("link test") {
        return;
    }
    let elf = link_elf();
    let exe = env!("CARGO_BIN_EXE_rths");
    let dir = tempfile::tempdir().unwrap();
    let csv_motion = dir.path().join("northridge.csv");
    let nr = rths::machinery::motion::GroundMotion::try_embedded("northridge").unwrap();
    std::fs::write(&csv_motion, nr.to_csv()).unwrap();
    let run_csv = dir.path().join("run.csv");
    cli_link_run(&elf, dir.path(), &csv_motion, &run_csv);

    // The commands, bit for bit, against the host simulation of the same record (as the CSV file
    // reads back), scale and model (the compiled-in data/models/lr.json).
    let rec = rths::link_host::read_recording(&std::fs::read_to_string(&run_csv).unwrap()).unwrap();
    assert_eq!(rec.header.get("scale"), Some("0.5"));
    assert_eq!(rec.header.get("scenario"), Some("lr-online"));
    assert_lr_commands_equal_the_host(&rec, &csv_motion);

    // `rths report --json` equals `rths simulate --json` on every figure.
    let json = |args: &[&str]| cli_json(dir.path(), args);
    let rep = json(&["report", run_csv.to_str().unwrap(), "--json"]);
    let sim = json(&[
        "simulate",
        "--scenario",
        "lr-online",
        "--motion",
        csv_motion.to_str().unwrap(),
        "--scale",
        "0.5",
        "--json",
    ]);
    println!("report   {}", rep["scenarios"][0]);
    println!("simulate {}", sim["scenarios"][0]);
    assert_eq!(rep["scenarios"][0], sim["scenarios"][0]);
    assert!(rep["scenarios"][0]["nrmse_measured_pct"].as_f64().unwrap() > 0.0);

    // With --out: the same history file and figure as `rths simulate --out`.
    let rep_dir = dir.path().join("report");
    let sim_dir = dir.path().join("simulate");
    json(&[
        "report",
        run_csv.to_str().unwrap(),
        "--json",
        "--out",
        rep_dir.to_str().unwrap(),
    ]);
    json(&[
        "simulate",
        "--scenario",
        "lr-online",
        "--motion",
        csv_motion.to_str().unwrap(),
        "--scale",
        "0.5",
        "--json",
        "--out",
        sim_dir.to_str().unwrap(),
    ]);
    assert_eq!(
        std::fs::read_to_string(rep_dir.join("history.csv")).unwrap(),
        std::fs::read_to_string(sim_dir.join("history.csv")).unwrap()
    );
    assert!(rep_dir.join("lr-online.png").exists());

    // A recording whose record is not the one named is refused.
    let text = std::fs::read_to_string(&run_csv).unwrap();
    let other = dir.path().join("other.csv");
    std::fs::write(&other, text.replace("# scale: 0.5", "# scale: 0.6")).unwrap();
    let out = Command::new(exe)
        .args(["report", other.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not the record of this recording"));
}

/// An LRX model uploaded in chunks to the LR image runs El Centro exactly as the host simulation
/// of that model; the LRX image takes an LR model and refuses an RNN-10 for the M4's tick; bad
/// model uploads are refused with their reason, the model in force kept.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn an_lrx_model_uploaded_to_the_lr_image_runs_as_the_host_simulates_it() {
    if qemu_missing("link test") {
        return;
    }
    let shipped =
        ModelFile::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models/lrx.json"))
            .unwrap();
    let checksum = |m: &ModelFile| match rths::link_host::model_messages(m).unwrap()[0] {
        HostMsg::ModelBegin { checksum, .. } => checksum,
        _ => unreachable!(),
    };
    // Another valid LRX model: the shipped one with a 10% larger correction stiffness.
    let mut other = shipped.clone();
    other.lrx.as_mut().unwrap().k_corr_kn_per_mm *= 1.1;
    assert_ne!(checksum(&other), checksum(&shipped));

    // The LRX image: its compiled-in model; an RNN-10 refused at the commit for the M4's tick
    // (104 %), the model in force kept; an LR model taken (any image takes any kind).
    let dir = tempfile::tempdir().unwrap();
    {
        let mut q = Qemu::start(&lrx_link_elf(), dir.path()).unwrap();
        let link = &mut q.link;
        link.timeout = Duration::from_secs(20);
        let s0 = link.status().unwrap();
        assert_eq!(s0.model_kind, rths_link::ModelKind::Lrx);
        assert_eq!(
            s0.model_checksum,
            checksum(&shipped),
            "the compiled-in lrx.json"
        );
        let rnn =
            ModelFile::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models/rnn-10.json"))
                .unwrap();
        match link.upload(&rnn) {
            Err(LinkHostError::Refused(Request::ModelCommit, NackReason::TickBudget)) => {}
            r => panic!("expected TickBudget, got {r:?}"),
        }
        let s1 = link.status().unwrap();
        assert_eq!(
            (s1.model_kind, s1.model_checksum),
            (s0.model_kind, s0.model_checksum)
        );
        let lr_file =
            ModelFile::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models/lr.json"))
                .unwrap();
        let c = link.upload(&lr_file).unwrap();
        let s2 = link.status().unwrap();
        assert_eq!(
            (s2.model_kind, s2.model_checksum),
            (rths_link::ModelKind::Lr, c)
        );
    }

    // The LR image takes the LRX model; bad uploads first.
    let elf = link_elf();
    let mut q = Qemu::start(&elf, dir.path()).unwrap();
    let link = &mut q.link;
    link.timeout = Duration::from_secs(20);
    let s0 = link.status().unwrap();
    assert_eq!(s0.model_kind, rths_link::ModelKind::Lr);
    // A NaN in a chunk, a wrong checksum, a stride that is not the lead filter's: refused whole.
    let msgs = rths::link_host::model_messages(&other).unwrap();
    let mut nan = msgs.clone();
    if let HostMsg::ModelChunk { values, .. } = &mut nan[1] {
        values[2] = f64::NAN;
    }
    assert_eq!(refusal(link, &nan[0]), None);
    assert_eq!(refusal(link, &nan[1]), Some(NackReason::NotFinite));
    let mut wrong = msgs.clone();
    if let HostMsg::ModelBegin { checksum, .. } = &mut wrong[0] {
        *checksum ^= 1;
    }
    for m in &wrong[..wrong.len() - 1] {
        assert_eq!(refusal(link, m), None);
    }
    assert_eq!(
        refusal(link, wrong.last().unwrap()),
        Some(NackReason::Checksum)
    );
    let mut bad_stride = other.clone();
    bad_stride.lrx.as_mut().unwrap().lead_stride = 9;
    match link.upload(&bad_stride) {
        Err(LinkHostError::Refused(Request::ModelCommit, NackReason::OutOfRange)) => {}
        r => panic!("expected OutOfRange, got {r:?}"),
    }
    let s1 = link.status().unwrap();
    assert_eq!(
        (s1.model_kind, s1.model_checksum),
        (s0.model_kind, s0.model_checksum)
    );

    // The other model: accepted, run, recorded.
    let c = link.upload(&other).unwrap();
    assert_eq!(c, checksum(&other));
    let s2 = link.status().unwrap();
    assert_eq!(
        (s2.model_kind, s2.model_checksum),
        (rths_link::ModelKind::Lrx, c)
    );
    link.arm(1).unwrap();
    link.start().unwrap();
    let csv = dir.path().join("run.csv");
    let summary = rths::cmd::link::record_csv(link, &csv, Duration::from_secs(60)).unwrap();
    assert!(summary.complete(), "lost telemetry: {summary:?}");
    let rows = read_csv(&csv);

    let ag = rths::machinery::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
    let reference = study::reference_mm(&ag, 1.0).unwrap();
    let mut st = setup(ScenarioId::LrxOnline, &ag, &reference, &[0.0; 6]);
    st.lr = None;
    st.lrx = Some(rths::machinery::models::lrx_params(&other).unwrap());
    st.delay_steps = other.delay_steps;
    let host = scenario::run(&st).unwrap();
    let mut identical = 0;
    for (row, hs) in rows.iter().zip(&host.history.command_mm[1..]) {
        assert_eq!(row.command_mm.to_bits(), hs.to_bits(), "tick {}", row.tick);
        identical += 1;
    }
    println!("lrx-online, uploaded model: {identical} commands bit-identical to the host");
    assert_eq!(identical, ag.len() - 1);
    let r = board_result(&q.stdout());
    println!("RESULT {r}");
    assert_eq!(r["end_state"], "done");
    // The RESULT line names the part uploaded, not the image's default (it said lr-online).
    assert_eq!(r["scenario"], "lrx-online", "{r}");
    assert_eq!(r["model"], "uploaded over the link", "{r}");
    let stack = r["stack_bytes"].as_u64().unwrap();
    let avail = r["stack_avail_bytes"].as_u64().unwrap();
    println!("LR link image with an uploaded LRX model: stack {stack} of {avail} bytes");
    assert!(stack < avail);
}

/// The control task stalls (fault-inject `stall@1`: from tick 2048 on it never returns): the
/// watchdog (TIM5 above the control task in QEMU; the IWDG on the real board) ends the run within
/// its period with a `WATCHDOG` line and a failure status instead of leaving the actuator on the
/// last command.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn the_watchdog_catches_a_stalled_control_task() {
    if qemu_missing("watchdog test") {
        return;
    }
    let elf = build_elf_with(
        &["--features", "fault-inject"],
        "rths-firmware-stall.elf",
        Some("stall@1"),
    );
    let dir = tempfile::tempdir().unwrap();
    let mut args = rths::link_host::qemu_args(&elf, 0);
    let i = args.iter().rposition(|a| a == "-serial").unwrap();
    args.drain(i..i + 2);
    let start = std::time::Instant::now();
    let out = Command::new("qemu-system-arm")
        .args(&args)
        .current_dir(dir.path())
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    println!("{text}(in {:?})", start.elapsed());
    assert!(text.contains("WATCHDOG the control task stalled"), "{text}");
    assert!(
        !text.contains("RESULT"),
        "the run must not complete: {text}"
    );
    assert_eq!(out.status.code(), Some(1));
}

/// A run armed to ramp down on a lost link, whose host then falls silent (no heartbeat, it only
/// listens): 1 s of silence later the device ramps the command to zero and ends the run early. The
/// same silence under `Complete` (the existing tests' `arm`) lets the run finish.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn a_silent_host_ramps_the_run_down_when_armed_so() {
    if qemu_missing("link test") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let mut q = Qemu::start(&link_elf(), dir.path()).unwrap();
    let link = &mut q.link;
    link.timeout = Duration::from_secs(20);
    link.heartbeat = None;
    link.arm_owned(1, rths_link::LinkLoss::RampDown).unwrap();
    // Another host's start (without the token) is refused; this host's goes through.
    assert_eq!(refusal(link, &HostMsg::Start), Some(NackReason::NotOwner));
    link.start().unwrap();
    let mut rows = Vec::new();
    let summary = link
        .record(Duration::from_secs(60), 0, |t| {
            rows.push(*t);
            Ok(())
        })
        .unwrap();
    let (end, ticks, _, _) = summary.end.unwrap();
    println!(
        "silent host: run ended {end:?} after {ticks} ticks ({} records)",
        rows.len()
    );
    assert_eq!(end, RunState::Done);
    let timeout = rths_link::LINK_TIMEOUT_TICKS;
    assert!(ticks > timeout && ticks < 81_900, "{ticks}");
    let first_ramp = rows
        .iter()
        .position(|t| t.state == RunState::RampDown)
        .unwrap();
    println!("ramp-down from tick {}", rows[first_ramp].tick);
    // Silent since its `Start`: the ramp begins once the silence exceeds the timeout.
    assert!(rows[first_ramp].tick >= timeout && rows[first_ramp].tick < timeout + 2048);
    // The ramp to zero is never faster than the end ramp's 10 mm/s.
    for w in rows[first_ramp..].windows(2) {
        assert!((w[1].command_mm - w[0].command_mm).abs() <= 10.0 * DT_S + 1e-12);
    }
    assert_eq!(rows.last().unwrap().command_mm, 0.0);
}

/// The link image with the shipped RNN-10 as its default (`--features link`,
/// `RTHS_MODEL=data/models/rnn-10.json`; the emulated M4 builds it, to measure it).
fn rnn_link_elf() -> PathBuf {
    static ELF: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    ELF.get_or_init(|| {
        build_elf_default(
            &["--features", "link"],
            "rths-firmware-rnn-link.elf",
            &shipped_path("rnn-10.json"),
        )
    })
    .clone()
}

/// The link image with FE + ATS as its default (`--features link`, `RTHS_MODEL=fe-ats`).
fn fe_ats_link_elf() -> PathBuf {
    static ELF: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    ELF.get_or_init(|| {
        build_elf_default(
            &["--features", "link"],
            "rths-firmware-fe-ats-link.elf",
            "fe-ats",
        )
    })
    .clone()
}

fn shipped_model(name: &str) -> ModelFile {
    ModelFile::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("data/models")
            .join(name),
    )
    .unwrap()
}

/// The `ModelBegin` checksum of a chunked model upload.
fn chunked_checksum(m: &ModelFile) -> u32 {
    match rths::link_host::model_messages(m).unwrap()[0] {
        HostMsg::ModelBegin { checksum, .. } => checksum,
        _ => unreachable!(),
    }
}

/// The commands of a recorded run equal the host simulation's, bit for bit, for every tick of
/// the record; the run's stack figure from its RESULT line.
fn assert_bit_identical(rows: &[Row], host: &ScenarioRun, ticks: usize, what: &str) {
    let mut identical = 0;
    for (row, hs) in rows.iter().zip(&host.history.command_mm[1..]) {
        assert_eq!(
            row.command_mm.to_bits(),
            hs.to_bits(),
            "{what}: tick {}",
            row.tick
        );
        identical += 1;
    }
    println!("{what}: {identical} commands bit-identical to the host");
    assert_eq!(identical, ticks - 1, "{what}");
}

/// Record the armed-and-started run to `csv`; its rows (no telemetry lost).
fn record_run(link: &mut rths::link_host::Link, csv: &Path) -> Vec<Row> {
    let summary = rths::cmd::link::record_csv(link, csv, Duration::from_secs(120)).unwrap();
    assert!(summary.complete(), "lost telemetry: {summary:?}");
    read_csv(csv)
}

/// An RNN of another size (the shipped rnn-5.json) uploaded in chunks to the RNN-10 image (loaded
/// in place) runs El Centro exactly as the host simulates it; bad RNN uploads (an RNN-10, which
/// the M4's tick cannot run, a count that is no RNN's, a NaN, a duplicated chunk, a truncated
/// upload, a corrupted value, under a test) are refused with their reason and the device's
/// holdings stay as they were.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn an_rnn_of_another_size_uploaded_to_the_rnn_image_runs_as_the_host_simulates_it_and_bad_ones_are_refused(
) {
    if qemu_missing("link test") {
        return;
    }
    let shipped = shipped_model("rnn-10.json");
    let dir = tempfile::tempdir().unwrap();
    let mut q = Qemu::start(&rnn_link_elf(), dir.path()).unwrap();
    let link = &mut q.link;
    link.timeout = Duration::from_secs(20);
    let h0 = link.holdings().unwrap();
    assert_eq!(h0.model_kind, rths_link::ModelKind::Rnn);
    assert_eq!(h0.model_source, rths_link::RecordSource::Compiled);
    assert_eq!(
        h0.model_checksum,
        chunked_checksum(&shipped),
        "the compiled-in rnn-10.json"
    );
    assert_eq!(h0.rig_checksum, 0, "an RNN has no rig compensation");
    assert_eq!(h0.rate_hz, rths_core::params::CONTROL_RATE_HZ);
    assert_ne!(h0.build_id, 0);

    // The emulated board is a Cortex-M4: an uploaded RNN-10 is refused for its tick (104 %; the
    // compiled-in one runs only because QEMU does not keep time), at the commit.
    match link.upload(&shipped) {
        Err(LinkHostError::Refused(Request::ModelCommit, NackReason::TickBudget)) => {}
        r => panic!("expected TickBudget, got {r:?}"),
    }
    // A count that is no RNN's.
    let mut odd = rths::link_host::model_messages(&shipped).unwrap();
    if let HostMsg::ModelBegin { values, .. } = &mut odd[0] {
        *values += 1;
    }
    assert_eq!(refusal(link, &odd[0]), Some(NackReason::Shape));
    // No rig compensation in this build.
    match link.upload_rig(rths_link::ModelKind::Rnn, &[1.0]) {
        Err(LinkHostError::Refused(Request::UploadRig, NackReason::Unsupported)) => {}
        r => panic!("expected Unsupported, got {r:?}"),
    }
    let msgs = rths::link_host::model_messages(&shipped).unwrap();
    let n = msgs.len();
    // A NaN in a chunk.
    let mut nan = msgs.clone();
    if let HostMsg::ModelChunk { values, .. } = &mut nan[3] {
        values[5] = f64::NAN;
    }
    for m in &nan[..3] {
        assert_eq!(refusal(link, m), None);
    }
    assert_eq!(refusal(link, &nan[3]), Some(NackReason::NotFinite));
    // A duplicated chunk, then a reordered one.
    for m in &msgs[..3] {
        assert_eq!(refusal(link, m), None);
    }
    assert_eq!(refusal(link, &msgs[2]), Some(NackReason::Sequence));
    assert_eq!(refusal(link, &msgs[0]), None);
    assert_eq!(refusal(link, &msgs[2]), Some(NackReason::Sequence));
    // Truncated: the commit before the last chunk.
    for m in &msgs[..n - 2] {
        assert_eq!(refusal(link, m), None);
    }
    assert_eq!(refusal(link, &msgs[n - 1]), Some(NackReason::Incomplete));
    // A value corrupted in transit (its frame intact): the end-to-end checksum.
    let mut bad = msgs.clone();
    if let HostMsg::ModelChunk { values, .. } = &mut bad[4] {
        values[0] += 1e-9;
    }
    for m in &bad[..n - 1] {
        assert_eq!(refusal(link, m), None);
    }
    assert_eq!(refusal(link, &bad[n - 1]), Some(NackReason::Checksum));
    assert_eq!(link.holdings().unwrap(), h0, "nothing changed");

    // An RNN of another size: accepted, reported as uploaded with its checksum.
    let five = shipped_model("rnn-5.json");
    assert_eq!(link.upload(&five).unwrap(), chunked_checksum(&five));
    let h1 = link.holdings().unwrap();
    assert_eq!(
        (h1.model_kind, h1.model_source, h1.model_checksum),
        (
            rths_link::ModelKind::Rnn,
            rths_link::RecordSource::Uploaded,
            chunked_checksum(&five)
        )
    );
    link.arm(1).unwrap();
    link.start().unwrap();
    // Under a test: refused, busy.
    assert_eq!(refusal(link, &msgs[0]), Some(NackReason::Busy));
    let rows = record_run(link, &dir.path().join("run.csv"));

    let ag = rths::machinery::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
    let reference = study::reference_mm(&ag, 1.0).unwrap();
    let mut st = setup(ScenarioId::RnnOnline(5), &ag, &reference, &[0.0; 6]);
    st.lr = None;
    st.rnn = Some(rths::machinery::models::rnn_params(&five).unwrap());
    st.delay_steps = five.delay_steps;
    let host = scenario::run(&st).unwrap();
    assert_bit_identical(
        &rows,
        &host,
        ag.len(),
        "rnn-online-5, rnn-5.json uploaded to the RNN-10 image",
    );
    let r = board_result(&q.stdout());
    assert_eq!(r["end_state"], "done");
    // The RESULT line names the part uploaded, not the image's default.
    assert_eq!(r["scenario"], "rnn-online-5", "{r}");
    assert_eq!(r["model"], "uploaded over the link", "{r}");
    println!(
        "RNN-10 link image with an uploaded RNN-5: stack {} of {} bytes",
        r["stack_bytes"], r["stack_avail_bytes"]
    );
}

/// A rig file's ATS start (`rths identify` on the emulated board's plant) uploaded to the FE + ATS
/// build runs El Centro exactly as `rths simulate fe-online-ats --rig` does on the host; bad rig
/// uploads (a NaN, outside the ATS's bounds, a wrong count, another kind, a corrupted value, under
/// a test) are refused with their reason and the compensation in force stays.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn a_rig_compensation_uploaded_to_the_fe_ats_build_runs_as_the_host_simulates_it() {
    if qemu_missing("link test") {
        return;
    }
    use rths::cmd::identify::{run_with_faults, Args};
    use rths::cmd::plant::{PresetArg, SpecimenArg};
    use rths_core::compensator::{AtsConfig, AtsParams};
    use rths_link::ModelKind as K;
    let dir = tempfile::tempdir().unwrap();
    // The emulated board's plant: unr-compact, linear specimen, seed 1.
    let a = Args {
        preset: PresetArg::UnrCompact,
        seed: 1,
        uncertainty: false,
        specimen: SpecimenArg::Linear,
        specimen_stiffness_factor: 1.0,
        amplitude_mm: 2.0,
        lead_stride: 8,
        out: dir.path().join("rig.json"),
        plot: None,
    };
    let rig = run_with_faults(&a, rths_hal_sim::FaultPlan::none()).unwrap();
    let initial = rig.compensation.ats_initial;
    let values = rths::link_host::rig_values(&rig, K::FeAts, 0.0).unwrap();
    assert_eq!(values, initial);

    let mut q = Qemu::start(&fe_ats_link_elf(), dir.path()).unwrap();
    let link = &mut q.link;
    link.timeout = Duration::from_secs(20);
    let h0 = link.holdings().unwrap();
    assert_eq!(h0.model_kind, K::FeAts);
    let paper = AtsParams::new(AtsConfig::paper(DT_S, PAPER_DELAY_STEPS as f64 * DT_S))
        .unwrap()
        .initial();
    assert_ne!(
        initial, paper,
        "the rig's start differs from the compiled-in one"
    );
    assert_eq!(
        (h0.rig_source, h0.rig_checksum),
        (
            rths_link::RecordSource::Compiled,
            rths_link::rig_checksum(K::FeAts, &paper)
        ),
        "the compiled-in ATS start"
    );
    let refused = |link: &mut rths::link_host::Link, kind, v: &[f64]| match link.upload_rig(kind, v)
    {
        Err(LinkHostError::Refused(Request::UploadRig, why)) => why,
        r => panic!("{v:?}: expected a refusal, got {r:?}"),
    };
    assert_eq!(
        refused(link, K::FeAts, &[f64::NAN, initial[1], initial[2]]),
        NackReason::NotFinite
    );
    assert_eq!(
        refused(link, K::FeAts, &[1e6, initial[1], initial[2]]),
        NackReason::OutOfRange
    );
    assert_eq!(refused(link, K::FeAts, &initial[..2]), NackReason::Shape);
    assert_eq!(refused(link, K::Lrx, &[0.0; 12]), NackReason::Unsupported);
    let mut corrupted = rths::link_host::rig_message(K::FeAts, &initial).unwrap();
    if let HostMsg::UploadRig { values, .. } = &mut corrupted {
        values[1] *= 1.5;
    }
    assert_eq!(refusal(link, &corrupted), Some(NackReason::Checksum));
    assert_eq!(link.holdings().unwrap(), h0, "nothing changed");

    let c = link.upload_rig(K::FeAts, &values).unwrap();
    let h1 = link.holdings().unwrap();
    assert_eq!(
        (h1.rig_source, h1.rig_checksum),
        (rths_link::RecordSource::Uploaded, c)
    );
    link.arm(1).unwrap();
    link.start().unwrap();
    assert_eq!(refused(link, K::FeAts, &paper), NackReason::Busy);
    let rows = record_run(link, &dir.path().join("run.csv"));

    let ag = rths::machinery::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
    let reference = study::reference_mm(&ag, 1.0).unwrap();
    let st = setup(ScenarioId::FeOnlineAts, &ag, &reference, &[0.0; 6]);
    let host = scenario::run_with_ats_start(&st, Some(initial)).unwrap();
    assert_bit_identical(
        &rows,
        &host,
        ag.len(),
        "fe-online-ats, uploaded rig ATS start",
    );
    let r = board_result(&q.stdout());
    assert_eq!(r["end_state"], "done");
    println!(
        "FE+ATS link build with an uploaded rig: stack {} of {} bytes",
        r["stack_bytes"], r["stack_avail_bytes"]
    );
}

/// The LR image becomes FE + ATS at run time (`rths link upload --fe-ats`: the device's own finite
/// elements, the ATS from the paper's delay) and runs El Centro exactly as the host's
/// `fe-online-ats`; no re-flash between an LR test and an FE + ATS one. A delay outside the ATS's
/// bounds is refused, the model in force kept.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn the_lr_image_made_fe_ats_at_run_time_runs_as_the_host_simulates_it() {
    if qemu_missing("link test") {
        return;
    }
    use rths_link::ModelKind as K;
    let dir = tempfile::tempdir().unwrap();
    let mut q = Qemu::start(&link_elf(), dir.path()).unwrap();
    let link = &mut q.link;
    link.timeout = Duration::from_secs(20);
    let h0 = link.holdings().unwrap();
    assert_eq!(h0.model_kind, K::Lr);
    match link.upload_fe_ats(0.5) {
        Err(LinkHostError::Refused(Request::ModelCommit, NackReason::OutOfRange)) => {}
        r => panic!("expected OutOfRange, got {r:?}"),
    }
    assert_eq!(link.holdings().unwrap(), h0, "nothing changed");
    let delay_s = PAPER_DELAY_STEPS as f64 * DT_S;
    let c = link.upload_fe_ats(delay_s).unwrap();
    let h1 = link.holdings().unwrap();
    assert_eq!(
        (h1.model_kind, h1.model_source, h1.model_checksum),
        (K::FeAts, rths_link::RecordSource::Uploaded, c)
    );
    link.arm(1).unwrap();
    link.start().unwrap();
    let rows = record_run(link, &dir.path().join("run.csv"));

    let ag = rths::machinery::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
    let reference = study::reference_mm(&ag, 1.0).unwrap();
    let st = setup(ScenarioId::FeOnlineAts, &ag, &reference, &[0.0; 6]);
    let host = scenario::run_with_ats_start(&st, None).unwrap();
    assert_bit_identical(
        &rows,
        &host,
        ag.len(),
        "fe-online-ats, uploaded to the LR image",
    );
    let r = board_result(&q.stdout());
    assert_eq!(r["end_state"], "done");
    // The RESULT line names the part uploaded, not the image's default.
    assert_eq!(r["scenario"], "fe-online-ats", "{r}");
    assert_eq!(r["model"], "uploaded over the link", "{r}");
    println!(
        "LR link image made FE + ATS: stack {} of {} bytes",
        r["stack_bytes"], r["stack_avail_bytes"]
    );
}

/// The first `samples` samples of El Centro at `dt_s` (linear between its 20 ms samples).
fn el_centro_at(dt_s: f64, samples: usize) -> rths::machinery::motion::GroundMotion {
    let el = rths::machinery::motion::GroundMotion::el_centro();
    let accel_g = (0..samples)
        .map(|i| {
            let pos = i as f64 * dt_s / el.dt_s;
            let j = pos.floor() as usize;
            let f = pos - j as f64;
            el.accel_g[j] + f * (el.accel_g[j + 1] - el.accel_g[j])
        })
        .collect();
    rths::machinery::motion::GroundMotion {
        name: format!("el-centro-{samples}-at-{dt_s}"),
        dt_s,
        accel_g,
    }
}

/// A record longer than the board's memory, run with `rths link run`: streamed during the run
/// (flow-controlled by the board's ring), every command bit-identical to the host simulation of
/// the whole record, and `rths report` of the recording equal to `rths simulate`.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn a_record_longer_than_the_boards_memory_is_streamed_and_every_command_equals_the_host() {
    if qemu_missing("link test") {
        return;
    }
    let elf = link_elf();
    let exe = env!("CARGO_BIN_EXE_rths");
    let dir = tempfile::tempdir().unwrap();
    let csv_motion = dir.path().join("long.csv");
    // 34 s at 250 Hz: 8,501 samples, more than the board's whole record memory (64 KiB: 8,192
    // samples; an upload holds 4,096).
    std::fs::write(&csv_motion, el_centro_at(0.004, 8501).to_csv()).unwrap();
    let motion = rths::machinery::motion::GroundMotion::from_path(&csv_motion)
        .unwrap()
        .scaled(0.5);
    assert!(
        motion.accel_g.len() > 8192,
        "longer than the board's memory"
    );
    let run_csv = dir.path().join("run.csv");
    let text = cli_link_run(&elf, dir.path(), &csv_motion, &run_csv);
    assert!(text.contains("streaming ground motion"), "{text}");
    assert!(
        text.contains("record streamed: 8501 samples arrived") && text.contains(" 0 tick(s)"),
        "{text}"
    );

    let rec = rths::link_host::read_recording(&std::fs::read_to_string(&run_csv).unwrap()).unwrap();
    assert_eq!(rec.header.get("record_streamed"), Some("yes"));
    assert_eq!(rec.header.get("record_samples"), Some("8501"));
    assert_lr_commands_equal_the_host(&rec, &csv_motion);

    let json = |args: &[&str]| cli_json(dir.path(), args);
    let rep = json(&["report", run_csv.to_str().unwrap(), "--json"]);
    let sim = json(&[
        "simulate",
        "--scenario",
        "lr-online",
        "--motion",
        csv_motion.to_str().unwrap(),
        "--scale",
        "0.5",
        "--json",
    ]);
    assert_eq!(rep["scenarios"][0], sim["scenarios"][0]);

    // `rths link upload` holds a record whole: this one is refused, naming the command that
    // streams it.
    let out = Command::new(exe)
        .args(["link", "--qemu"])
        .arg(&elf)
        .args(["upload", "--motion"])
        .arg(&csv_motion)
        .current_dir(dir.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("8501 samples, the device holds 4096") && err.contains("rths link run"),
        "{err}"
    );
}

/// A host that stops streaming after filling the ring: the run's link-loss policy decides.
/// `Complete` runs the record to its end, each tick past the ring's samples at 0 g and counted
/// from the first one the ring lacked; `RampDown` ramps down from that tick. Either way the host
/// is told (`StreamStatus`), and a second arm is refused (the ring no longer holds the start).
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn a_stream_that_falls_behind_follows_the_link_loss_policy_chosen_at_arm_time() {
    use rths_link::LinkLoss;
    if qemu_missing("link test") {
        return;
    }
    // 10 s at 1 kHz: 10,001 samples, 4,092 of them sent before the run.
    let long = el_centro_at(0.001, 10_001);
    let ticks = rths_core::motion::record_ticks(long.accel_g.len(), long.dt_s, DT_S) as u32;
    for policy in [LinkLoss::Complete, LinkLoss::RampDown] {
        let dir = tempfile::tempdir().unwrap();
        let mut q = Qemu::start(&link_elf(), dir.path()).unwrap();
        let link = &mut q.link;
        link.timeout = Duration::from_secs(20);
        // With telemetry every 16th tick QEMU runs several times faster than the wall clock: a
        // status every 20 ms keeps the host heard within the board's 1 s (of its clock).
        link.heartbeat = Some(Duration::from_millis(20));
        link.stream_record(&long.accel_g, long.dt_s, 1.0).unwrap();
        let st = link.stream_status().unwrap();
        // 341 chunks of 12 fill 4,092 of the ring's 4,096 samples.
        assert_eq!((st.in_force, st.received, st.free), (true, 4092, 4));
        assert_eq!(link.status().unwrap().record.ticks, ticks);
        link.stop_streaming();
        link.arm_owned(16, policy).unwrap();
        link.start().unwrap();
        let mut rows = Vec::new();
        let summary = link
            .record(Duration::from_secs(60), 0, |t| {
                rows.push(*t);
                Ok(())
            })
            .unwrap();
        let (end, run_ticks, _, _) = summary.end.unwrap();
        let st = link.stream_status().unwrap();
        // Tick k reads samples floor(k·DT_S/dt) and the next: the first tick past sample 4,091.
        let dry = (0..ticks)
            .find(|k| ((*k as f64 * DT_S / long.dt_s).floor() as usize) + 1 >= 4092)
            .unwrap();
        println!(
            "{policy:?}: run ended {end:?} after {run_ticks} ticks; underrun from tick {:?}, {} \
             ticks",
            st.first_underrun_tick, st.underrun_ticks
        );
        assert_eq!(end, RunState::Done);
        assert_eq!(st.first_underrun_tick, Some(dry));
        assert_eq!(st.checksum_ok, None, "not every sample came");
        match policy {
            LinkLoss::Complete => {
                // Every tick from the dry one to the record's end played 0 g.
                assert_eq!(st.underrun_ticks, ticks - dry);
                assert!(rows
                    .iter()
                    .all(|t| t.state != RunState::RampDown || t.tick >= ticks - 1));
            }
            LinkLoss::RampDown => {
                let first_ramp = rows
                    .iter()
                    .find(|t| t.state == RunState::RampDown)
                    .unwrap()
                    .tick;
                println!("ramp-down from tick {first_ramp}");
                assert!(first_ramp >= dry && first_ramp <= dry + 32, "{first_ramp}");
            }
        }
        assert_eq!(
            refusal(link, &HostMsg::Arm { telemetry_every: 1 }),
            Some(NackReason::Incomplete)
        );
    }
}

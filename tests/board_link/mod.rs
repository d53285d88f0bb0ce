//! One structure part on the emulated Cortex-M7 and on the host (tests/structure_board.rs at the
//! build's rate, tests/board_4096.rs at 4096 Hz): the M7's link image at the host's rate, the lab's
//! command `rths link --qemu ELF run` with the lab's files, the same controller on the host (the
//! device's own install functions from the same values, `rths::machinery::drive` against the same
//! virtual rig, the run's statistics by `rths_app::run::Run`), every command and the RESULT line's
//! figures compared.

use std::mem::MaybeUninit;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::Command;

use rths::machinery::drive::Stop;
use rths::machinery::motion::GroundMotion;
use rths_app::rig_upload::{dims_of, install_rig, InForce};
use rths_app::run::{Run, TickFacts};
use rths_app::tick_cost::TickBudget;
use rths_core::control::{ControlConfig, Controller, FeedbackSource};
use rths_core::params::{Prototype, SpecimenScale, CONTROL_RATE_HZ, DT_S};
use rths_core::supervisor::Limits;
use rths_hal_sim::{Preset, Specimen};

use crate::common::firmware_dir;

/// `rths ARGS` in `dir`: success, stdout, stderr.
pub fn rths(dir: &Path, args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rths"))
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

/// `rths identify` of the emulated board's plant (the `unr-compact` virtual rig), as a lab
/// identifies its own rig, into the file `rig.json` in `dir`.
pub fn identified_rig(dir: &Path) -> PathBuf {
    let (ok, _, err) = rths(
        dir,
        &["identify", "--preset", "unr-compact", "--out", "rig.json"],
    );
    assert!(ok, "{err}");
    dir.join("rig.json")
}

/// The share of the emulated Cortex-M7's tick at this build's rate that `instr` instructions take,
/// % (480 MHz at the budget's cycles per instruction: `rths_app::tick_cost`).
pub fn m7_tick_pct(instr: f64) -> f64 {
    100.0 * instr / TickBudget::cortex_m7_480mhz(f64::from(CONTROL_RATE_HZ)).instr_per_tick()
}

/// The emulated Cortex-M7's link image at the host's rate (what runs is uploaded). At 2048 Hz its
/// default is the shipped LR; a `rate-4096` build makes the 4096 Hz image with its default FE +
/// ATS, which needs no model file of that rate.
pub fn m7_link_elf() -> PathBuf {
    let mut build = Command::new(env!("CARGO"));
    if cfg!(feature = "rate-4096") {
        build.env("RTHS_MODEL", "fe-ats").args([
            "build-m7",
            "--no-default-features",
            "--features",
            "board-mps2-an500,link,rate-4096",
        ]);
    } else {
        build.env_remove("RTHS_MODEL").args([
            "build-m7",
            "--no-default-features",
            "--features",
            "board-mps2-an500,link",
        ]);
    }
    let status = build
        .current_dir(firmware_dir())
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("RTHS_FAULT")
        .env_remove("RTHS_STRUCTURE")
        .env_remove("RTHS_BUDGET")
        .status()
        .expect("cargo");
    assert!(
        status.success(),
        "firmware build (M7, link, {CONTROL_RATE_HZ} Hz) failed"
    );
    let dest = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("rths-firmware-m7-link-{CONTROL_RATE_HZ}.elf"));
    std::fs::copy(
        firmware_dir().join("target/m7/thumbv7em-none-eabihf/release/rths-firmware"),
        &dest,
    )
    .expect("the M7 image");
    dest
}

/// The controller the board builds, on the host: the image's own configuration
/// (`firmware/src/analytical.rs`), the part installed from the same values by the device's own
/// function (`model_upload::install`), then the rig compensation (`rig_upload::install_rig`).
fn host_controller<'s>(
    slot: &'s mut MaybeUninit<Controller>,
    laid: &rths_files::upload::LaidOut,
    rig: &[f64],
) -> &'s mut Controller {
    let cfg = ControlConfig::new(
        Prototype::paper().with_brace_factor(1.0).unwrap(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let ctl = Controller::init_in(slot, cfg);
    rths_app::model_upload::install(ctl, laid.kind, &laid.values).unwrap();
    let part = InForce {
        kind: laid.kind,
        dims: dims_of(ctl),
        budget: Some(TickBudget::cortex_m7_480mhz(f64::from(CONTROL_RATE_HZ))),
    };
    install_rig(ctl, &part, laid.kind, rig).unwrap();
    ctl
}

/// What [`board_and_host`] leaves for further checks.
pub struct BoardAndHost {
    /// The board's RESULT line.
    pub result: serde_json::Value,
    /// The board's recording (`rths link run --out`).
    #[allow(dead_code)] // read by tests/structure_board.rs's report check only
    pub recording: PathBuf,
    /// The host's rows as `run_hybrid` takes them: target, command, measured, measured force.
    pub rows: Vec<[f64; 4]>,
    /// Why the host's run ended.
    #[allow(dead_code)] // read by tests/structure_board.rs's report check only
    pub stop: Stop,
}

/// One structure part on the board and on the host: `rths link run` with the lab's files (the
/// `unr-compact` virtual rig, seed 1, in the MCU; the whole El Centro record), then the same
/// controller on the host against the same virtual rig; every command bit for bit, the RESULT
/// line's ticks, command checksum and overruns (none) asserted.
#[allow(clippy::too_many_arguments)]
pub fn board_and_host(
    elf: &Path,
    dir: &Path,
    what: &str,
    scenario: &str,
    model: Option<&Path>,
    structure: &Path,
    rig: &Path,
    length_scale: f64,
) -> BoardAndHost {
    let csv = dir.join(format!("{what}.csv"));
    let mut args: Vec<String> = ["link", "--qemu"]
        .iter()
        .map(|s| s.to_string())
        .chain([elf.display().to_string(), "run".into()])
        .collect();
    if let Some(m) = model {
        args.extend(["--model".into(), m.display().to_string()]);
    }
    args.extend([
        "--structure".into(),
        structure.display().to_string(),
        "--rig".into(),
        rig.display().to_string(),
        "--length-scale".into(),
        format!("{length_scale}"),
        "--out".into(),
        csv.display().to_string(),
    ]);
    let argv: Vec<&str> = args.iter().map(String::as_str).collect();
    let (ok, out, err) = rths(dir, &argv);
    println!("{what}: {out}{err}");
    assert!(ok, "{what}: rths link run failed: {err}");
    let line = out
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("RESULT "))
        .expect("the board's RESULT line");
    let r: serde_json::Value = serde_json::from_str(line).unwrap();
    assert_eq!(r["scenario"], scenario, "{what}: {r}");
    assert_eq!(r["model"], "uploaded over the link", "{what}");
    let rec = rths::link_host::read_recording_file(&csv).unwrap();

    // The host: the same files laid out, the same controller, the same virtual rig and record.
    let laid = rths_files::upload::lay_out_files(model, Some(structure), DT_S).unwrap();
    let rig_file = rths::machinery::identify::RigFile::load(rig).unwrap();
    let rig_values = rths::link_host::structure_rig_values(
        &rig_file,
        laid.specimen_k_kn_per_mm.unwrap(),
        length_scale,
        rths::machinery::train::lrx::RIG_LEAD_ADAPT_TICKS,
    )
    .unwrap();
    let mut slot = Box::new(MaybeUninit::uninit());
    let ctl = host_controller(&mut slot, &laid, &rig_values);
    assert_eq!(ctl.scenario_name().0, scenario);
    let mut plant = rths_hal_sim::VirtualRig::new(
        rths::machinery::reference::rig_config(Preset::UnrCompact, Specimen::Linear, 1.0, 1)
            .build()
            .unwrap(),
    );
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    let mut run = Run::new();
    let mut commands = Vec::with_capacity(ag.len());
    let mut rows: Vec<[f64; 4]> = Vec::with_capacity(ag.len());
    let stop = rths::machinery::drive::run(ctl, Some(&mut plant), &ag, None, DT_S, |st, _, _| {
        commands.push(st.out.command_mm);
        rows.push([
            st.target_mm,
            st.command_mm,
            st.measured_mm,
            st.measured_force_kn,
        ]);
        let notify = run.after_tick(&TickFacts {
            k: st.k as u32,
            counted: true,
            row: None,
            instr: 0,
            command_mm: st.out.command_mm,
            measured_mm: st.measured_mm,
            state: st.out.state,
            overrun: false,
            queued: true,
        });
        if notify && run.fault_settled() {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    let host_fnv = format!("{:016x}", run.command_fnv.finish());
    let mut identical = 0usize;
    for (row, host) in rec.rows.iter().zip(&commands) {
        assert_eq!(
            row.command_mm.to_bits(),
            host.to_bits(),
            "{what}: tick {}: board {} mm, host {host} mm",
            row.tick,
            row.command_mm
        );
        identical += 1;
    }
    println!(
        "{what} on the M7 at {CONTROL_RATE_HZ} Hz: {} ticks, {}, command FNV board {} host \
         {host_fnv}; {identical} commands bit-identical; instructions per tick {}; stack {} B",
        r["ticks"], r["end_state"], r["command_fnv"], r["instr_per_tick"], r["stack_bytes"]
    );
    assert_eq!(
        identical,
        commands.len(),
        "{what}: every tick of the host's run"
    );
    assert_eq!(r["ticks"], run.ticks, "{what}");
    assert_eq!(r["command_fnv"], host_fnv, "{what}");
    assert_eq!(r["overruns"], 0, "{what}");
    BoardAndHost {
        result: r,
        recording: csv,
        rows,
        stop,
    }
}

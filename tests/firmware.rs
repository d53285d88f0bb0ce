//! The firmware in the loop: builds `firmware/` for the emulated STM32F405 and runs it in QEMU
//! (`qemu-system-arm`, netduinoplus2, `-icount shift=0`), then checks its RESULT line against the host
//! simulation of the same scenario and seed, the supervisor's trip and ramp under an injected fault,
//! and the timing budget; the same for the emulated Cortex-M7 (mps2-an500, `cargo build-m7`).
//!
//! Skipped (with a loud message) only when `qemu-system-arm` is not installed; CI installs it.
#![cfg(feature = "sim")]

mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use rths::machinery::motion::GroundMotion;
use rths::studies::analysis::{pure_response, Method};
use rths::studies::scenario::{self, ScenarioId, ScenarioSetup};
use rths_core::params::{Prototype, DT_S};
use rths_hal_sim::{Preset, Specimen};

/// Builds share `firmware/target`: one at a time, and each ELF is copied before the next build.
static BUILD: Mutex<()> = Mutex::new(());

/// The target for the LR path: at most 2000 instructions per control tick.
const MAX_LR_INSTR: f64 = 2000.0;

/// The emulated boards: the Cortex-M4 (`board-qemu`, netduinoplus2) and the Cortex-M7
/// (`board-mps2-an500`, built with `cargo build-m7`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Emulated {
    M4,
    M7,
}

impl Emulated {
    /// The cargo subcommand (an alias of `firmware/.cargo/config.toml` for the M7) and the ELF.
    fn build_cmd(self) -> (&'static str, &'static str) {
        match self {
            Emulated::M4 => (
                "build",
                "target/thumbv7em-none-eabihf/release/rths-firmware",
            ),
            Emulated::M7 => (
                "build-m7",
                "target/m7/thumbv7em-none-eabihf/release/rths-firmware",
            ),
        }
    }
    /// The board feature.
    fn board(self) -> &'static str {
        match self {
            Emulated::M4 => "board-qemu",
            Emulated::M7 => "board-mps2-an500",
        }
    }
}

/// `cargo build --release` of the firmware with `features` (on top of the defaults unless
/// `no_default`), ELF copied to a private path.
fn build(name: &str, no_default: bool, features: &str) -> PathBuf {
    build_env(name, no_default, features, None)
}

/// [`build`] with the `fault-inject` plan `RTHS_FAULT` set to `fault` (or unset: the default plan).
fn build_env(name: &str, no_default: bool, features: &str, fault: Option<&str>) -> PathBuf {
    build_on(Emulated::M4, name, no_default, features, fault)
}

/// The firmware for the emulated board `on` with `features` (the board's feature is added when
/// `no_default`).
fn build_on(
    on: Emulated,
    name: &str,
    no_default: bool,
    features: &str,
    fault: Option<&str>,
) -> PathBuf {
    build_on_env(on, name, no_default, features, fault, &[])
}

/// [`build_on`] with the build-time inputs `env` (e.g. `RTHS_STRUCTURE`) set; unset otherwise.
fn build_on_env(
    on: Emulated,
    name: &str,
    no_default: bool,
    features: &str,
    fault: Option<&str>,
    env: &[(&str, &Path)],
) -> PathBuf {
    let _guard = BUILD.lock().unwrap_or_else(|e| e.into_inner());
    let (sub, elf) = on.build_cmd();
    let mut cmd = Command::new(env!("CARGO"));
    cmd.current_dir(firmware_dir())
        .arg(sub)
        // The outer cargo's target dir belongs to the host workspace.
        .env_remove("CARGO_TARGET_DIR");
    if on == Emulated::M4 {
        cmd.arg("--release");
    }
    match fault {
        Some(f) => cmd.env("RTHS_FAULT", f),
        None => cmd.env_remove("RTHS_FAULT"),
    };
    for var in ["RTHS_MODEL", "RTHS_STRUCTURE", "RTHS_BUDGET"] {
        cmd.env_remove(var);
    }
    for (var, value) in env {
        cmd.env(var, value);
    }
    let features = if no_default && on == Emulated::M7 {
        features.replace("board-qemu", on.board())
    } else {
        features.to_string()
    };
    if no_default {
        cmd.arg("--no-default-features");
    }
    if !features.is_empty() {
        cmd.args(["--features", &features]);
    }
    let status = cmd.status().unwrap();
    assert!(
        status.success(),
        "firmware build ({features}, {on:?}) failed"
    );
    let dest = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("rths-firmware-{name}.elf"));
    std::fs::copy(firmware_dir().join(elf), &dest).unwrap();
    dest
}

/// The QEMU command line of `firmware/.cargo/config.toml`'s runner (one source of truth): the
/// target's `runner` for the M4, the `run-m7` alias's for the M7.
fn runner(on: Emulated) -> Vec<String> {
    match on {
        Emulated::M4 => firmware_runner(),
        Emulated::M7 => {
            let cfg = std::fs::read_to_string(firmware_dir().join(".cargo/config.toml")).unwrap();
            let line = cfg
                .lines()
                .find(|l| l.trim_start().starts_with("run-m7"))
                .unwrap();
            let at = line.find("runner='").unwrap() + "runner='".len();
            line[at..]
                .split('\'')
                .next()
                .unwrap()
                .split_whitespace()
                .map(str::to_string)
                .collect()
        }
    }
}

/// Run an ELF in QEMU (5 min timeout); its RESULT line as JSON and the exit status.
fn run(elf: &Path) -> (serde_json::Value, bool) {
    run_on(Emulated::M4, elf)
}

/// [`run`] on the emulated board `on`.
fn run_on(on: Emulated, elf: &Path) -> (serde_json::Value, bool) {
    let (result, _, ok) = run_full(on, elf);
    (result, ok)
}

/// [`run_on`], with the CALIB line as JSON too.
fn run_full(on: Emulated, elf: &Path) -> (serde_json::Value, serde_json::Value, bool) {
    let (status, out) = run_qemu(&runner(on), elf);
    println!("{out}");
    (
        serde_json::from_str(tagged_line(&out, "RESULT ")).unwrap(),
        serde_json::from_str(tagged_line(&out, "CALIB ")).unwrap(),
        status.success(),
    )
}

/// The shipped model file `name` (`data/models/`).
fn shipped(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/models")
        .join(name)
}

fn f(v: &serde_json::Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("{key} missing in {v}"))
}

/// The host simulation of `lr-online` with the `rths reproduce` defaults (unr-compact, linear
/// specimen, seed 1) and the model the firmware compiled in.
fn host_lr_online_nrmse() -> f64 {
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    let reference = pure_response(&Prototype::paper(), &ag, DT_S, Method::Chang)
        .unwrap()
        .brace_disp_mm;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models/lr.json");
    let model = rths::machinery::model_file::ModelFile::load(&path).unwrap();
    let theta: [f64; 6] = model.lr.as_ref().unwrap().theta.clone().try_into().unwrap();
    let setup = ScenarioSetup {
        id: ScenarioId::LrOnline,
        ground_accel_mm_s2: &ag,
        reference_mm: &reference,
        rig: rths::machinery::reference::rig_config(Preset::UnrCompact, Specimen::Linear, 1.0, 1),
        stiffness_factor: 1.0,
        lr: Some(rths_core::metamodel::LrParams::new(theta).unwrap()),
        rnn: None,
        delay_steps: model.delay_steps,
        lrx: None,
    };
    let run = scenario::run(&setup).unwrap();
    assert!(run.report.stable, "host run stopped: {:?}", run.report);
    run.report.nrmse_pct.unwrap()
}

fn tick_share(instr: f64) -> f64 {
    instr * CYCLES_PER_INSTR / (CPU_HZ * DT_S)
}

/// The Cortex-M7 board's clock (STM32H743), Hz: the emulated M7's counts are placed on it.
const M7_CPU_HZ: f64 = 480e6;

/// The target for the LR path on the Cortex-M7: at most 500 instructions per control tick.
const MAX_M7_LR_INSTR: f64 = 500.0;

/// The share of the tick `instr` instructions take on the Cortex-M7 board (same cycles per
/// instruction as the M4's budget: conservative for the dual-issue M7).
fn m7_tick_share(instr: f64) -> f64 {
    instr * CYCLES_PER_INSTR / (M7_CPU_HZ * DT_S)
}

#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn lr_online_in_qemu_matches_the_host_and_fits_the_budget() {
    if qemu_missing("firmware-in-the-loop test") {
        return;
    }
    let elf = build("lr", false, "");
    let (r, ok) = run(&elf);
    assert!(ok, "firmware exit status was not 0: {r}");
    assert_eq!(r["scenario"], "lr-online");
    assert_eq!(r["ticks"], 81_900, "the whole El Centro record");
    assert_eq!(r["overruns"], 0);
    assert_eq!(r["faults"], 0);
    let fw = f(&r, "nrmse_pct");
    let host = host_lr_online_nrmse();
    println!(
        "lr-online NRMSE: firmware {fw:?} %, host {host:?} %, bit-identical: {}",
        fw.to_bits() == host.to_bits()
    );
    // The bound (0.01 percentage points), and a real one: the same code on both sides
    // agrees to the last few bits (measured: 6e-11 pp on 4.9e-4 %, i.e. 1.2e-7 relative).
    assert!(
        (fw - host).abs() <= 0.01,
        "firmware {fw} % vs host {host} %"
    );
    assert!(
        (fw - host).abs() <= 1e-6 * host.abs(),
        "firmware {fw} % vs host {host} %: more than float noise"
    );

    // End of test: the supervisor ramps to zero, never faster than its end ramp, and reports Done.
    assert_eq!(r["end_state"], "done");
    assert!(f(&r, "ramp_ticks") > 1.0);
    let end_step = f(&r["step_limits_mm"], "end");
    assert!(f(&r, "max_ramp_step_mm") <= end_step * (1.0 + 1e-9));
    assert_eq!(f(&r, "final_cmd_mm"), 0.0);

    // Timing budget: the controller's worst tick within 10% of the 488 µs tick at 168 MHz.
    let max = f(&r["instr_per_tick"], "max");
    let share = tick_share(max);
    println!(
        "LR budget: max {max} instructions/tick = {:.2}% of the tick",
        share * 100.0
    );
    assert!(share <= MAX_TICK_SHARE, "{:.2}% of the tick", share * 100.0);
    assert!(
        max <= MAX_LR_INSTR,
        "LR path: {max} instructions per tick > {MAX_LR_INSTR}"
    );
}

/// The Cortex-M7 (QEMU mps2-an500, f64 in hardware) runs the same firmware: the same RESULT as the
/// host simulation, within the LR budget of the M7 (≤ 500 instructions per tick).
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn lr_online_on_the_m7_matches_the_host_and_fits_the_budget() {
    if qemu_missing("firmware-in-the-loop test (Cortex-M7)") {
        return;
    }
    let elf = build_on(Emulated::M7, "m7-lr", true, "board-qemu", None);
    let (r, calib, ok) = run_full(Emulated::M7, &elf);
    assert!(ok, "firmware exit status was not 0: {r}");
    // The emulated core reports a double-precision FPU (MVFR0), which the build uses (no software
    // f64 routine is reachable from the control step: budget.sh's panic check).
    assert_eq!(calib["fpu_f64"], true, "{calib}");
    assert_eq!(r["scenario"], "lr-online");
    assert_eq!(r["ticks"], 81_900, "the whole El Centro record");
    assert_eq!(r["overruns"], 0);
    assert_eq!(r["faults"], 0);
    assert_eq!(r["end_state"], "done");
    assert_eq!(f(&r, "final_cmd_mm"), 0.0);
    let fw = f(&r, "nrmse_pct");
    let host = host_lr_online_nrmse();
    println!(
        "M7 lr-online NRMSE: firmware {fw:?} %, host {host:?} %, bit-identical: {}",
        fw.to_bits() == host.to_bits()
    );
    assert!(
        (fw - host).abs() <= 1e-6 * host.abs(),
        "firmware {fw} % vs host {host} %: more than float noise"
    );
    let max = f(&r["instr_per_tick"], "max");
    let share = m7_tick_share(max);
    println!(
        "M7 LR budget: max {max} instructions/tick = {:.3}% of the tick at 480 MHz",
        share * 100.0
    );
    assert!(
        max <= MAX_M7_LR_INSTR,
        "M7 LR path: {max} instructions per tick > {MAX_M7_LR_INSTR}"
    );
    assert!(share <= MAX_TICK_SHARE, "{:.2}% of the tick", share * 100.0);
}

/// Every other analytical part on the Cortex-M7: builds, runs the whole record, and fits 10% of the
/// tick at 480 MHz (hardware f64: the RNN-10 that overruns the M4's tick fits here).
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn every_analytical_part_fits_the_m7_budget() {
    if qemu_missing("firmware-in-the-loop test (Cortex-M7)") {
        return;
    }
    for (name, model) in [
        ("rnn", shipped("rnn-10.json")),
        ("fe-ats", PathBuf::from("fe-ats")),
        ("lrx", shipped("lrx.json")),
    ] {
        // The one image, with this part as its default (`RTHS_MODEL`).
        let elf = build_on_env(
            Emulated::M7,
            &format!("m7-{name}"),
            true,
            "board-qemu",
            None,
            &[("RTHS_MODEL", &model)],
        );
        let (r, _) = run_on(Emulated::M7, &elf);
        let max = f(&r["instr_per_tick"], "max");
        let share = m7_tick_share(max);
        println!(
            "M7 {name}: {} max {max} instructions/tick = {:.2}% of the tick at 480 MHz",
            r["scenario"],
            share * 100.0
        );
        assert_eq!(r["ticks"], 81_900, "{name}: {r}");
        assert_eq!(r["overruns"], 0, "{name}: {r}");
        assert!(max > 0.0, "{name}: {r}");
        assert!(
            share <= MAX_TICK_SHARE,
            "M7 {name}: {:.2}% of the tick",
            share * 100.0
        );
    }
}

#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn injected_sensor_fault_trips_and_ramps_without_a_jump() {
    if qemu_missing("firmware-in-the-loop test") {
        return;
    }
    let elf = build("fault", false, "fault-inject");
    let (r, ok) = run(&elf);
    assert!(ok, "fault build did not end as planned: {r}");
    assert_eq!(r["faults"], 1);
    assert_eq!(r["end_state"], "fault");
    assert_eq!(r["fault_reason"], "NonFiniteSample");
    // The NaN appears in the sample of tick 10 s (20480 ticks).
    assert_eq!(r["fault_tick"], 20_480);
    assert!(r["nrmse_pct"].is_null(), "a stopped run has no figure");
    let fault_step = f(&r["step_limits_mm"], "fault");
    assert!(f(&r, "max_step_after_fault_mm") <= fault_step * (1.0 + 1e-9));
    // Ramps at the fault rate back to the safe position (where the test was armed, 0 mm): as many
    // ticks as the distance takes at that step, and ends exactly there.
    assert_eq!(f(&r, "final_cmd_mm"), 0.0);
    let before = f(&r, "cmd_before_fault_mm").abs();
    let ramp = f(&r, "fault_ramp_ticks");
    assert!(
        before > 0.1,
        "the fault should strike mid-motion: {before} mm"
    );
    let expect = (before / fault_step).ceil();
    assert!(
        (ramp - expect).abs() <= 1.0,
        "ramp of {ramp} ticks for {before} mm"
    );
    println!(
        "fault ramp: {before:.3} mm in {ramp} ticks ({:.1} ms)",
        ramp / 2.048
    );
}

/// The other analytical parts: they must build and run the whole record in QEMU; their instructions
/// per tick are reported (the 10% budget is the LR path's: f64 on the F4's single-precision FPU is
/// software floating point, and the RNN's tanh alone costs thousands of instructions).
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn rnn_and_fe_ats_paths_build_and_run() {
    if qemu_missing("firmware-in-the-loop test") {
        return;
    }
    for (name, model) in [
        ("rnn", shipped("rnn-10.json")),
        ("fe-ats", PathBuf::from("fe-ats")),
    ] {
        // The one image, with this part as its default (`RTHS_MODEL`).
        let elf = build_on_env(
            Emulated::M4,
            name,
            true,
            "board-qemu",
            None,
            &[("RTHS_MODEL", &model)],
        );
        let (r, _) = run(&elf);
        let max = f(&r["instr_per_tick"], "max");
        println!(
            "{name}: {} max {max} instructions/tick = {:.2}% of the tick",
            r["scenario"],
            tick_share(max) * 100.0
        );
        assert_eq!(r["ticks"], 81_900, "{name}: {r}");
        assert!(max > 0.0, "{name}: {r}");
    }
}

/// A subset of the fault matrix (`rths faults`) in QEMU: the firmware built with a compile-time fault
/// plan (`RTHS_FAULT`) must trip (or not) exactly as the host run of the same case, at the same tick,
/// for the same reason, and keep the command within the envelope.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn fault_matrix_subset_in_qemu_matches_the_host() {
    if qemu_missing("firmware-in-the-loop test") {
        return;
    }
    let bench = rths::studies::faults::Bench::el_centro().unwrap();
    let cases = rths::studies::faults::cases().unwrap();
    let lim = rths_core::supervisor::Limits::paper_actuator();
    for (spec, host_name) in [
        ("dropout@10+7", "dropout 7 ticks"),
        ("dropout@10+8", "dropout 8 ticks"),
        ("stuck-disp@10", "LVDT stuck"),
        ("overrun@10+4", "overrun 4 ticks"),
    ] {
        let case = cases
            .iter()
            .find(|c| {
                c.name == host_name && c.start_s == 10.0 && c.scenario == ScenarioId::LrOnline
            })
            .unwrap();
        let host = bench.run_case(case).unwrap();
        assert!(host.pass, "host case failed: {host:?}");
        let elf = build_env(
            &format!("fault-{host_name}"),
            false,
            "fault-inject",
            Some(spec),
        );
        let (r, ok) = run(&elf);
        assert!(ok, "{spec}: the firmware's own checks failed: {r}");
        assert_eq!(r["fault"], spec);
        // The envelope, on target.
        assert!(
            f(&r, "max_step_mm") <= lim.max_step_mm() * (1.0 + 1e-9),
            "{spec}: {r}"
        );
        assert!(f(&r, "peak_cmd_mm") <= lim.stroke_mm(), "{spec}: {r}");
        match (&host.reason, host.time_to_trip_ms) {
            (Some(reason), Some(ms)) => {
                assert_eq!(r["end_state"], "fault", "{spec}: {r}");
                assert_eq!(r["fault_reason"].as_str(), Some(reason.as_str()), "{spec}");
                let host_tick = 20_480.0 + (ms * 2.048).round();
                assert_eq!(f(&r, "fault_tick"), host_tick, "{spec}: trip tick");
            }
            _ => {
                assert_eq!(r["end_state"], "done", "{spec}: {r}");
                assert_eq!(r["faults"], 0, "{spec}");
                assert_eq!(r["ticks"], 81_900, "{spec}");
            }
        }
        println!(
            "qemu {spec}: {} (host: {:?} after {:?} ms), max jump {} mm",
            r["fault_reason"], host.reason, host.time_to_trip_ms, r["max_step_mm"]
        );
    }
}

/// An imported OpenSees frame's reduced-order model on the emulated Cortex-M7 against the emulated
/// plant (the image's default: `RTHS_STRUCTURE` and an `rths-reduced-model` file as `RTHS_MODEL`) and the host's run of the same
/// controller (`rths::machinery::drive`, the same `VirtualRig` and seed, the same El Centro ticks): the
/// command of every tick of the record, bit for bit (the RESULT line's `command_fnv` against the
/// host's, both through `rths_app::run::Run`), and the same trip, if any, at the same tick.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn reduced_model_on_the_m7_matches_the_host_tick_by_tick() {
    use rths::machinery::imported::reduced::{self, ReducedModelFile};
    use rths::machinery::imported::ImportedStructure;
    use rths_app::run::{Run, TickFacts};
    use rths_core::control::{ControlConfig, Controller, FeedbackSource};
    use rths_core::model::{assemble, ModelSpec};
    use rths_core::params::SpecimenScale;
    use rths_core::supervisor::{Limits, State};
    use std::ops::ControlFlow;

    if qemu_missing("firmware-in-the-loop test (Cortex-M7, reduced model)") {
        return;
    }
    // The small frame (10 DOFs with mass): its reduced model trains in a fraction of a second.
    let structure_path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/structures/opensees-frame-1x1.json");
    let structure =
        ImportedStructure::from_json(&std::fs::read_to_string(&structure_path).unwrap()).unwrap();
    let records = reduced::training_records(DT_S).unwrap();
    let file = reduced::train(&structure, &records, DT_S, |_, _, _| {}).unwrap();
    let model_path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("reduced-frame-1x1.json");
    std::fs::write(&model_path, file.to_json().unwrap()).unwrap();
    let elf = build_on_env(
        Emulated::M7,
        "m7-reduced",
        true,
        "board-qemu",
        None,
        &[
            ("RTHS_STRUCTURE", &structure_path),
            ("RTHS_MODEL", &model_path),
        ],
    );
    let (r, _) = run_on(Emulated::M7, &elf);
    // The RESULT line names the part in force: the image's default is the reduced model.
    assert_eq!(r["scenario"], "structure-reduced", "{r}");
    // A model trained for another structure fails the build, naming both (only build.rs runs).
    let other =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("data/structures/opensees-frame-2x4.json");
    let refused = {
        let _guard = BUILD.lock().unwrap_or_else(|e| e.into_inner());
        Command::new(env!("CARGO"))
            .current_dir(firmware_dir())
            .env_remove("CARGO_TARGET_DIR")
            .env_remove("RTHS_FAULT")
            .env("RTHS_STRUCTURE", &other)
            .env("RTHS_MODEL", &model_path)
            .env_remove("RTHS_BUDGET")
            .args([
                Emulated::M7.build_cmd().0,
                "--no-default-features",
                "--features",
                "board-mps2-an500",
            ])
            .output()
            .unwrap()
    };
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success(), "built for another structure");
    assert!(
        stderr.contains("trained for structure frame-1x1, not frame-2x4"),
        "{stderr}"
    );
    assert_eq!(r["overruns"], 0, "{r}");

    // The host: the firmware's controller (`firmware/src/analytical.rs`) from the same file.
    let arrays = ReducedModelFile::load(&model_path)
        .unwrap()
        .arrays_for(&structure, DT_S)
        .unwrap();
    let spec = ModelSpec::StructureReduced {
        model: arrays.spec(),
    };
    let (analytical, compensator) = assemble(&spec, Prototype::paper(), DT_S).unwrap();
    let cfg = ControlConfig::new(
        Prototype::paper().with_brace_factor(1.0).unwrap(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let mut ctl = Controller::new(cfg, analytical, compensator);
    let mut rig = rths_hal_sim::VirtualRig::new(
        rths::machinery::reference::rig_config(Preset::UnrCompact, Specimen::Linear, 1.0, 1)
            .build()
            .unwrap(),
    );
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    let mut run = Run::new();
    rths::machinery::drive::run(&mut ctl, Some(&mut rig), &ag, None, DT_S, |st, _, _| {
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
        // The emulated board stops once a fault has held still (its supervisor task).
        if notify && run.fault_settled() {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    let host_fnv = format!("{:016x}", run.command_fnv.finish());
    println!(
        "reduced model ({} modes) on the M7: {} ticks, {}; host {} ticks, {:?}; command FNV firmware \
         {} host {host_fnv}; max {} instructions per tick",
        file.modes.len(),
        r["ticks"],
        r["end_state"],
        run.ticks,
        run.state,
        r["command_fnv"],
        r["instr_per_tick"]["max"]
    );
    assert_eq!(r["ticks"], run.ticks, "ticks: firmware {r}, host {run:?}");
    assert_eq!(
        r["fault_tick"].as_u64(),
        run.fault_tick.map(u64::from),
        "the trip: firmware {r}, host {run:?}"
    );
    assert_eq!(
        r["command_fnv"], host_fnv,
        "the command streams differ: firmware {r}, host {run:?}"
    );
    assert!(run.ticks > 0 && run.state != State::Idle, "{run:?}");
}

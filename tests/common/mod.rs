//! Helpers shared by the integration tests that run the firmware in QEMU.
#![allow(dead_code)] // each test binary uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Core clock of the STM32F405/407, Hz.
pub const CPU_HZ: f64 = 168e6;
/// Cycles per instruction assumed by the timing budget: the board's (`rths_app::tick_cost`).
#[allow(unused_imports)] // each test binary uses its own subset
pub use rths_app::tick_cost::CYCLES_PER_INSTR;
/// The timing budget: the controller's share of the 488 µs tick.
pub const MAX_TICK_SHARE: f64 = 0.10;

/// The firmware workspace.
pub fn firmware_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("firmware")
}

/// True (after a loud SKIPPED line naming `what`) when `qemu-system-arm` cannot run here. CI sets
/// RTHS_REQUIRE_QEMU once it has installed QEMU: a skip there would hide a failure, so it panics.
pub fn qemu_missing(what: &str) -> bool {
    let found = Command::new("qemu-system-arm")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !found {
        assert!(
            std::env::var_os("RTHS_REQUIRE_QEMU").is_none(),
            "RTHS_REQUIRE_QEMU is set but `qemu-system-arm` cannot be run"
        );
        eprintln!(
            "\n*** SKIPPED: {what}: `qemu-system-arm` is not installed \
             (apt-get install qemu-system-arm). CI installs it, so this never skips there. ***\n"
        );
    }
    !found
}

/// Run a firmware ELF in QEMU with the firmware's own runner line (`firmware/.cargo/config.toml`),
/// from an empty directory, at most 300 s; print and return its exit status and its `RESULT` object.
pub fn run_elf_in_qemu(elf: &Path) -> (std::process::ExitStatus, serde_json::Value) {
    let (exit, out) = run_qemu(&firmware_runner(), elf);
    let result = tagged_line(&out, "RESULT ");
    let r: serde_json::Value = serde_json::from_str(result).unwrap();
    println!("{r}");
    (exit, r)
}

/// The QEMU command line of the firmware's target `runner` (`firmware/.cargo/config.toml`, the
/// emulated Cortex-M4), one word an entry.
pub fn firmware_runner() -> Vec<String> {
    let cfg = std::fs::read_to_string(firmware_dir().join(".cargo/config.toml")).unwrap();
    let line = cfg
        .lines()
        .find(|l| l.trim_start().starts_with("runner"))
        .unwrap();
    line.split('"')
        .nth(1)
        .unwrap()
        .split_whitespace()
        .map(str::to_string)
        .collect()
}

/// Run `elf` by the QEMU command line `argv` from an empty directory, at most 300 s (a hung
/// emulation is killed and the test fails); its exit status and its standard output.
pub fn run_qemu(argv: &[String], elf: &Path) -> (std::process::ExitStatus, String) {
    use std::time::{Duration, Instant};
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(&argv[0])
        .args(&argv[1..])
        .arg(elf)
        .current_dir(dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let exit = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > Duration::from_secs(300) {
            let _ = child.kill();
            panic!("QEMU did not finish within 300 s");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut out = String::new();
    std::io::Read::read_to_string(&mut child.stdout.take().unwrap(), &mut out).unwrap();
    (exit, out)
}

/// The last line of `out` that starts with `tag`, without it (the test fails without one).
pub fn tagged_line<'a>(out: &'a str, tag: &str) -> &'a str {
    out.lines()
        .rev()
        .find_map(|l| l.strip_prefix(tag))
        .unwrap_or_else(|| panic!("no {tag}line in:\n{out}"))
}

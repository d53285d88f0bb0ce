//! Helpers shared by the integration tests that run the firmware in QEMU.
#![allow(dead_code)] // each test binary uses its own subset

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Core clock of the STM32F405/407, Hz.
pub const CPU_HZ: f64 = 168e6;
/// Cycles per instruction assumed by the timing budget.
pub const CYCLES_PER_INSTR: f64 = 1.5;
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

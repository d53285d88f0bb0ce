//! Marks the tests that need an outside tool `#[ignore]`d (with the reason) when the tool is absent,
//! so `cargo test` counts them as "ignored" instead of printing "ok" for a test that did not run
//! (docs/ci.md#tests-that-need-qemu-or-openseespy).
//!
//! - `rths_no_qemu`: `qemu-system-arm --version` cannot run (the firmware and link tests).
//! - `rths_no_opensees`: the Python in `RTHS_PYTHON` (default `python3`) has no openseespy.
//!
//! With `RTHS_REQUIRE_QEMU` (any value) or `RTHS_REQUIRE_OPENSEES=1` set (CI) a missing tool fails
//! the build instead: a required test can never be ignored.

use std::process::{Command, ExitCode, Stdio};

fn main() -> ExitCode {
    // A new PATH, Python or requirement is a new answer; installing a tool without changing them
    // needs `touch build.rs` (the ignore reasons say so).
    for var in [
        "PATH",
        "RTHS_PYTHON",
        "RTHS_REQUIRE_QEMU",
        "RTHS_REQUIRE_OPENSEES",
    ] {
        println!("cargo:rerun-if-env-changed={var}");
    }
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rustc-check-cfg=cfg(rths_no_qemu)");
    println!("cargo:rustc-check-cfg=cfg(rths_no_opensees)");

    let qemu = Command::new("qemu-system-arm")
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !qemu {
        if std::env::var_os("RTHS_REQUIRE_QEMU").is_some() {
            eprintln!("RTHS_REQUIRE_QEMU is set but `qemu-system-arm --version` cannot be run");
            return ExitCode::FAILURE;
        }
        println!("cargo:rustc-cfg=rths_no_qemu");
    }

    let python = std::env::var("RTHS_PYTHON").unwrap_or_else(|_| "python3".into());
    // Only whether the package is there: importing it needs its library path, which the tests set.
    let opensees = Command::new(&python)
        .args([
            "-c",
            "import importlib.util as u, sys; sys.exit(0 if u.find_spec('openseespy') else 1)",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !opensees {
        if std::env::var("RTHS_REQUIRE_OPENSEES").as_deref() == Ok("1") {
            eprintln!("RTHS_REQUIRE_OPENSEES=1 but {python} has no openseespy (set RTHS_PYTHON)");
            return ExitCode::FAILURE;
        }
        println!("cargo:rustc-cfg=rths_no_opensees");
    }
    ExitCode::SUCCESS
}

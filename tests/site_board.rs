//! `rths site --link`: the board as the experimental site. A raw `genericClient` client (the
//! protocol OpenSees speaks, no OpenSees needed) drives `rths site --link --qemu ELF`, the emulated
//! board's controller (core's predictor-corrector tick) and plant; the same client drives `rths
//! site` on the host's virtual rig of the same rig file, and the two are compared bit for bit.
//!
//! Skipped (with a loud message) only when `qemu-system-arm` is not installed; with
//! `RTHS_REQUIRE_QEMU` set (CI) a missing QEMU fails instead.
#![cfg(feature = "sim")]

mod common;
use common::*;
mod site_common;
use site_common::*;

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::Command;

/// Ticks per integration step of the client.
const TICKS: f64 = 4.0;
/// Integration steps the client runs (1 s of analysis).
const STEPS: usize = 512;

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rths-site-board-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d.join(name)
}

/// `cargo build --release --features link` of the firmware, its ELF copied to a private path.
fn link_elf() -> PathBuf {
    let status = Command::new(env!("CARGO"))
        .current_dir(firmware_dir())
        .args(["build", "--release", "--features", "link"])
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("RTHS_FAULT")
        .env_remove("RTHS_MODEL")
        .env_remove("RTHS_STRUCTURE")
        .env_remove("RTHS_BUDGET")
        .status()
        .expect("cargo");
    assert!(status.success(), "firmware build failed");
    let elf = firmware_dir().join("target/thumbv7em-none-eabihf/release/rths-firmware");
    let dest = Path::new(env!("CARGO_TARGET_TMPDIR")).join("rths-firmware-site.elf");
    std::fs::copy(&elf, &dest).expect("copy the ELF");
    dest
}

fn message(action: f64, d: f64, t: f64) -> Vec<u8> {
    let mut v = [0.0f64; 8];
    v[0] = action;
    v[1] = d;
    v[4] = t;
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A NewmarkExplicit-like client of one DOF: a 2 Hz, 2 mm oscillation that starts smoothly; each
/// step setTrialResponse, getForce, the same trial again, commitState; then DIE. The forces the
/// site returned.
fn client(addr: SocketAddr) -> Vec<f64> {
    let mut s = TcpStream::connect(addr).expect("connect");
    let hs: Vec<u8> = [1i32, 1, 1, 0, 1, 0, 0, 0, 1, 0, 8]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    s.write_all(&hs).expect("handshake");
    let dt = TICKS / 2048.0;
    let mut forces = Vec::with_capacity(STEPS);
    for i in 1..=STEPS {
        let t = i as f64 * dt;
        let ramp = (t / 0.25).min(1.0);
        let d = 2.0 * ramp * ramp * (2.0 * std::f64::consts::PI * 2.0 * t).sin();
        s.write_all(&message(3.0, d, t)).expect("trial");
        s.write_all(&message(10.0, d, t)).expect("getForce");
        let mut r = [0u8; 64];
        s.read_exact(&mut r).expect("the force");
        forces.push(f64::from_le_bytes(r[..8].try_into().expect("8 bytes")));
        s.write_all(&message(3.0, d, t)).expect("trial again");
        s.write_all(&message(5.0, d, t)).expect("commit");
    }
    s.write_all(&message(99.0, 0.0, 0.0)).expect("DIE");
    forces
}

/// Run a site with `args`, drive it; (success, stderr, stdout-less summary, forces, CSV rows).
fn run_site(args: &[&str], out: &Path) -> (bool, String, Vec<f64>, Vec<String>) {
    let out_s = out.display().to_string();
    let mut a: Vec<&str> = vec!["--listen", "127.0.0.1:0", "--out", &out_s];
    a.extend_from_slice(args);
    let (child, addrs) = start_site(&a, 1);
    let forces = client(addrs[0]);
    let (ok, err) = finish(child);
    (ok, err, forces, rows_of(out))
}

/// A recording's rows (every tick), as text.
fn rows_of(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("seq"))
        .map(str::to_string)
        .collect()
}

/// `rths identify --preset unr-compact`'s rig file (the emulated board's plant), as `name`.
fn identified_rig(name: &str) -> PathBuf {
    let rig = tmp(name);
    let st = Command::new(RTHS)
        .args(["identify", "--preset", "unr-compact", "--out"])
        .arg(&rig)
        .status()
        .expect("rths identify");
    assert!(st.success());
    rig
}

#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn the_board_in_qemu_is_the_site_and_matches_the_virtual_rig_bit_for_bit() {
    if qemu_missing("rths site --link") {
        return;
    }
    let elf = link_elf();
    let rig = identified_rig("rig.json");
    let rig_s = rig.display().to_string();
    let elf_s = elf.display().to_string();

    let (ok_b, err_b, f_board, rows_board) = run_site(
        &["--link", "--qemu", &elf_s, "--rig", &rig_s],
        &tmp("board.csv"),
    );
    assert!(ok_b, "the board's site failed: {err_b}");
    let (ok_h, err_h, f_host, rows_host) = run_site(&["--rig", &rig_s], &tmp("host.csv"));
    assert!(ok_h, "the host's site failed: {err_h}");

    assert_eq!(f_board.len(), STEPS);
    let peak = f_board.iter().fold(0.0f64, |m, f| m.max(f.abs()));
    // 2 mm on the 1224 kN/mm prototype brace.
    assert!(peak > 2000.0 && peak < 3000.0, "peak force {peak} kN");
    for (i, (b, h)) in f_board.iter().zip(&f_host).enumerate() {
        assert_eq!(
            b.to_bits(),
            h.to_bits(),
            "step {i}: board {b} kN, host {h} kN"
        );
    }
    // Every tick: the board's telemetry equals the host's rows, the end ramp included.
    assert!(rows_board.len() > STEPS * 4, "{} rows", rows_board.len());
    assert_eq!(rows_board.len(), rows_host.len());
    for (b, h) in rows_board.iter().zip(&rows_host) {
        assert_eq!(b, h);
    }
    assert!(
        rows_board.last().is_some_and(|l| l.contains(",done,")),
        "the board's test ends done: {:?}",
        rows_board.last()
    );
    let header = std::fs::read_to_string(tmp("board.csv")).expect("recording");
    assert!(header.contains("# link: qemu"), "{header}");
}

/// The shipped 3-story frame (`scripts/opensees/site_3story.py`, openseespy), its two
/// genericClient elements each on its own emulated board (`rths site --elements 2 --link --qemu
/// ELF`: two QEMUs, two actuators), and the same analysis on two virtual rigs of the same rig file
/// (`--elements 2 --rig`): per element every recorded tick (the end ramp included), and OpenSees's
/// floor displacements, bit for bit.
#[test]
#[cfg_attr(
    any(rths_no_qemu, rths_no_opensees),
    ignore = "needs qemu-system-arm and openseespy, not found when the tests were built (docs/ci.md)"
)]
fn two_boards_in_qemu_are_the_3_story_frames_two_elements_bit_for_bit() {
    if qemu_missing("rths site --elements 2 --link") {
        return;
    }
    let Some(py) = opensees("two_boards_in_qemu_are_the_3_story_frames_two_elements_bit_for_bit")
    else {
        return;
    };
    let elf = link_elf();
    let rig = identified_rig("rig-3story.json");
    let rig_s = rig.display().to_string();
    let elf_s = elf.display().to_string();
    let run = |name: &str, side: &[&str]| {
        let port = free_ports();
        let listen = format!("127.0.0.1:{port}");
        let out = tmp(&format!("{name}.csv"));
        let out_s = out.display().to_string();
        let mut args = vec![
            "--listen",
            &listen,
            "--elements",
            "2",
            "--rig",
            &rig_s,
            "--out",
            &out_s,
        ];
        args.extend_from_slice(side);
        let (child, addrs) = start_site(&args, 2);
        assert_eq!(addrs[1].port(), port + 1);
        let client = [
            "--port",
            &port.to_string(),
            "--scale",
            "0.3",
            "--duration",
            "3",
        ]
        .map(str::to_string);
        let script = run_script(
            &py,
            "site_3story.py",
            &client,
            &tmp(&format!("{name}.json")),
        );
        let (ok, err) = finish(child);
        assert!(ok, "{name}: rths site failed: {err}");
        let rows: Vec<Vec<String>> = (1..=2)
            .map(|i| rows_of(&tmp(&format!("{name}-{i}.csv"))))
            .collect();
        (script, rows, err)
    };
    let (board, board_rows, board_err) = run("boards3", &["--link", "--qemu", &elf_s]);
    let (host, host_rows, _) = run("rigs3", &[]);
    println!("{board_err}");
    let header = std::fs::read_to_string(tmp("boards3-2.csv")).expect("recording");
    assert!(
        header.contains("# link: qemu") && header.contains("# element: 2"),
        "{header}"
    );
    assert_eq!(board.disp.len(), 1536, "3 s of 4-tick steps");
    for (k, (b, h)) in board.disp.iter().zip(&host.disp).enumerate() {
        for (j, (x, y)) in b.iter().zip(h).enumerate() {
            assert_eq!(
                x.to_bits(),
                y.to_bits(),
                "step {k}, floor {}: {x} vs {y} mm",
                j + 1
            );
        }
    }
    let peak = board.disp.iter().fold(0.0f64, |m, d| m.max(d[2].abs()));
    assert!(peak > 1.0, "the roof moves: {peak} mm");
    for (i, (b, h)) in board_rows.iter().zip(&host_rows).enumerate() {
        // Every tick of the 1536 steps of 4 ticks, and the end ramp.
        assert!(b.len() > 1536 * 4, "element {}: {} rows", i + 1, b.len());
        assert_eq!(b.len(), h.len(), "element {}", i + 1);
        for (rb, rh) in b.iter().zip(h) {
            assert_eq!(rb, rh, "element {}", i + 1);
        }
        assert!(
            b.last().is_some_and(|l| l.contains(",done,")),
            "element {}'s test ends done",
            i + 1
        );
    }
}

#[test]
fn a_board_site_needs_its_rig_file_and_a_board_per_element() {
    let dir = tmp("no-rig");
    std::fs::create_dir_all(&dir).expect("dir");
    let o = Command::new(RTHS)
        .current_dir(&dir)
        .args(["site", "--link", "--qemu", "x.elf"])
        .output()
        .expect("rths");
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("rig.json") && e.contains("identify"), "{e}");
    // Two elements need two boards: a serial port each.
    let o = Command::new(RTHS)
        .args(["site", "--link", "--port", "/dev/null", "--elements", "2"])
        .output()
        .expect("rths");
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("--port given 1× for 2 elements") && e.contains("own board"),
        "{e}"
    );
    let o = Command::new(RTHS)
        .args([
            "site",
            "--link",
            "--port",
            "/dev/null",
            "--port",
            "/dev/null",
            "--elements",
            "2",
        ])
        .output()
        .expect("rths");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("given twice"));
    // --rig once for all, or once per element.
    let o = Command::new(RTHS)
        .args([
            "site",
            "--link",
            "--qemu",
            "x.elf",
            "--elements",
            "3",
            "--rig",
            "a.json",
            "--rig",
            "b.json",
        ])
        .output()
        .expect("rths");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--rig given 2× for 3 elements"));
}

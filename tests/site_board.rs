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

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

const RTHS: &str = env!("CARGO_BIN_EXE_rths");

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

/// `rths site ARGS` started; its address once it prints it.
fn start_site(args: &[&str]) -> (Child, SocketAddr) {
    let mut child = Command::new(RTHS)
        .arg("site")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("rths site starts");
    let mut out = BufReader::new(child.stdout.take().expect("stdout"));
    let addr = loop {
        let mut l = String::new();
        if out.read_line(&mut l).expect("reading rths site") == 0 {
            let mut e = String::new();
            let _ = child.stderr.take().map(|mut s| s.read_to_string(&mut e));
            panic!("rths site ended before listening: {e}");
        }
        if let Some(a) = l.trim().strip_prefix("listening on ") {
            break a.parse().expect("an address");
        }
    };
    std::thread::spawn(move || {
        let mut rest = String::new();
        let _ = out.read_to_string(&mut rest);
        print!("{rest}");
    });
    (child, addr)
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
    let (mut child, addr) = start_site(&a);
    let forces = client(addr);
    let mut err = String::new();
    if let Some(mut s) = child.stderr.take() {
        let _ = s.read_to_string(&mut err);
    }
    let ok = child.wait().expect("rths site ends").success();
    let text = std::fs::read_to_string(out).unwrap_or_default();
    let rows = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("seq"))
        .map(str::to_string)
        .collect();
    (ok, err, forces, rows)
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
    let rig = tmp("rig.json");
    let st = Command::new(RTHS)
        .args(["identify", "--preset", "unr-compact", "--out"])
        .arg(&rig)
        .status()
        .expect("rths identify");
    assert!(st.success());
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

#[test]
fn a_board_site_needs_its_rig_file_and_one_element() {
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
    let o = Command::new(RTHS)
        .args(["site", "--link", "--qemu", "x.elf", "--elements", "2"])
        .output()
        .expect("rths");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("one actuator"));
}

//! `rths site` end to end: OpenSees (openseespy, the shipped scripts) as the client of the virtual
//! rig, against the same OpenSees model with elastic braces; and the faults of a raw client.
//!
//! Python is `RTHS_PYTHON` (default `python3`); without openseespy the OpenSees tests print
//! `SKIPPED: ...`, and fail instead with `RTHS_REQUIRE_OPENSEES=1`.

mod site_common;
use site_common::*;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::PathBuf;
use std::process::Command;
/// The prototype brace's stiffness, kN/mm (the rig's nominal specimen × the force scale).
const BRACE_K: &str = "1224.1";

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("rths-site-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("tmp dir");
    d.join(name)
}

/// The paper's frame with its brace on the virtual rig (unr-compact, identified at start):
/// slowed down ×10 within 0.1 % NRMSE of the elastic brace, real time (TCP and UDP) within 2 %,
/// and `rths report` reads the recording.
#[test]
#[cfg_attr(
    rths_no_opensees,
    ignore = "needs openseespy, not found when the tests were built (docs/ci.md)"
)]
fn the_paper_frame_from_opensees() {
    let Some(py) = opensees("the_paper_frame_from_opensees") else {
        return;
    };
    let reference = run_script(
        &py,
        "site_paper_frame.py",
        &["--elastic".into(), BRACE_K.into()],
        &tmp("elastic.json"),
    );
    let mut overhead = Vec::new();
    for (udp, rate, limit_pct) in [(false, "10", 0.1), (false, "1", 2.0), (true, "1", 2.0)] {
        let rec = tmp(&format!("run-{udp}-{rate}.csv"));
        let rec_s = rec.display().to_string();
        let mut args = vec![
            "--listen",
            "127.0.0.1:0",
            "--preset",
            "unr-compact",
            "--rate-factor",
            rate,
            "--out",
            &rec_s,
        ];
        if udp {
            args.push("--udp");
        }
        let (child, addrs) = start_site(&args, 1);
        let mut extra = vec!["--port".to_string(), addrs[0].port().to_string()];
        if udp {
            extra.push("--udp".into());
        }
        let run = run_script(&py, "site_paper_frame.py", &extra, &tmp("client.json"));
        let (ok, err) = finish(child);
        assert!(ok, "rths site failed: {err}");
        let e = nrmse_pct(&run.disp, &reference.disp, 0);
        let added_ms = (run.wall_per_step_s - reference.wall_per_step_s) * 1e3;
        println!(
            "paper frame, {} rate factor {rate}: NRMSE {e:.4} % (limit {limit_pct} %), added \
             latency {added_ms:.4} ms per step",
            if udp { "UDP" } else { "TCP" }
        );
        assert!(e < limit_pct, "NRMSE {e} % ≥ {limit_pct} %");
        if rate == "1" {
            overhead.push(added_ms);
        }
        let rep = Command::new(RTHS)
            .args(["report", &rec_s, "--json"])
            .output()
            .expect("rths report");
        assert!(
            rep.status.success(),
            "rths report: {}",
            String::from_utf8_lossy(&rep.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&rep.stdout).expect("report json");
        assert_eq!(v["scenarios"][0]["stable"], true, "{v}");
        assert_eq!(v["recording"]["source"], "site");
        assert!(v["scenarios"][0]["nrmse_measured_pct"].as_f64().is_some());
    }
    // Loopback; the goal is ≤ 1 ms per step. A loaded CI machine may be slower: reported, with a
    // generous bound that still catches a stall on delayed ACKs (tens of ms).
    for ms in overhead {
        assert!(ms < 10.0, "added latency {ms} ms per step");
    }
}

/// The 3-story frame with two genericClient elements (two actuators): real time within 2 % of
/// the elastic braces at every floor.
#[test]
#[cfg_attr(
    rths_no_opensees,
    ignore = "needs openseespy, not found when the tests were built (docs/ci.md)"
)]
fn the_three_story_frame_with_two_actuators() {
    let Some(py) = opensees("the_three_story_frame_with_two_actuators") else {
        return;
    };
    let scale = ["--scale".to_string(), "0.3".to_string()];
    let mut e_args = vec!["--elastic".to_string(), BRACE_K.to_string()];
    e_args.extend(scale.clone());
    let reference = run_script(&py, "site_3story.py", &e_args, &tmp("elastic3.json"));
    let port = free_ports();
    let listen = format!("127.0.0.1:{port}");
    let rec = tmp("run3.csv").display().to_string();
    let (child, addrs) = start_site(&["--listen", &listen, "--elements", "2", "--out", &rec], 2);
    assert_eq!(addrs[1].port(), port + 1);
    let mut extra = vec!["--port".to_string(), port.to_string()];
    extra.extend(scale);
    let run = run_script(&py, "site_3story.py", &extra, &tmp("client3.json"));
    let (ok, err) = finish(child);
    assert!(ok, "rths site failed: {err}");
    for j in 0..3 {
        let e = nrmse_pct(&run.disp, &reference.disp, j);
        println!("3-story, floor {}: NRMSE {e:.4} %", j + 1);
        assert!(e < 2.0, "floor {}: NRMSE {e} %", j + 1);
    }
    for i in 1..=2 {
        let p = tmp(&format!("run3-{i}.csv"));
        assert!(p.exists(), "{} written", p.display());
    }
}

// ---- faults, from a raw client (no OpenSees needed) ----

fn handshake() -> Vec<u8> {
    [1i32, 1, 1, 0, 1, 0, 0, 0, 1, 0, 8]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect()
}

fn msg(action: f64, d: f64, t: f64) -> Vec<u8> {
    let mut v = [0.0f64; 8];
    v[0] = action;
    v[1] = d;
    v[4] = t;
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Drive a site with `script` (messages), then close; the site's success, stderr, recording.
fn raw_client(name: &str, script: &[Vec<u8>]) -> (bool, String, String) {
    let rec = tmp(&format!("{name}.csv"));
    let rec_s = rec.display().to_string();
    let (child, addrs) = start_site(&["--listen", "127.0.0.1:0", "--out", &rec_s], 1);
    {
        let mut s = TcpStream::connect(addrs[0]).expect("connect");
        s.write_all(&handshake()).expect("handshake");
        for m in script {
            if s.write_all(m).is_err() {
                break;
            }
            if m[..8] == 10.0f64.to_le_bytes() {
                let mut r = [0u8; 64];
                if s.read_exact(&mut r).is_err() {
                    break;
                }
            }
        }
    }
    let (ok, err) = finish(child);
    let text = std::fs::read_to_string(&rec).unwrap_or_default();
    (ok, err, text)
}

/// The last row's command, mm.
fn last_command(recording: &str) -> f64 {
    let l = recording.lines().last().expect("rows");
    l.split(',')
        .nth(4)
        .and_then(|x| x.parse().ok())
        .expect("command")
}

const DT: f64 = 4.0 / 2048.0;

#[test]
fn faults_bring_the_actuator_to_its_safe_position_and_keep_the_recording() {
    // Some steps to 2 mm (a smooth start: the lead filter in front of the actuator amplifies a
    // sudden velocity), then each fault.
    let steps: Vec<Vec<u8>> = (1..=20)
        .flat_map(|i| {
            let t = i as f64 * DT;
            let d = 1.0 - (std::f64::consts::PI * i as f64 / 20.0).cos();
            [msg(3.0, d, t), msg(10.0, d, t), msg(5.0, d, t)]
        })
        .collect();
    let t = 21.0 * DT;
    let cases: [(&str, Vec<Vec<u8>>, &str); 4] = [
        ("vanished", vec![msg(3.0, 2.0, t)], "vanished"),
        ("unknown", vec![msg(42.0, 2.0, t)], "unknown action 42"),
        (
            "velocity",
            vec![msg(3.0, 5.0, t), msg(10.0, 5.0, t)],
            "CommandVelocity",
        ),
        (
            "iterative",
            vec![msg(3.0, 2.0, t), msg(3.0, 2.01, t)],
            "iterative",
        ),
    ];
    for (name, tail, why) in cases {
        let mut script = steps.clone();
        script.extend(tail);
        let (ok, err, rec) = raw_client(name, &script);
        assert!(!ok, "{name}: the site must report the stop");
        assert!(err.contains(why), "{name}: `{why}` not in: {err}");
        assert!(
            rec.contains("fault-"),
            "{name}: the recording shows the fault"
        );
        assert!(
            rec.contains("# stop_reason:"),
            "{name}: the reason is recorded"
        );
        // The supervisor's ramp ended at the safe position (where the test was armed: 0).
        assert_eq!(last_command(&rec), 0.0, "{name}");
        let rows = rec.lines().filter(|l| l.contains(",running,")).count();
        assert!(rows >= 80, "{name}: {rows} running rows kept");
    }
    // A target beyond the stroke, approached within the velocity limit (1000 ticks a step).
    let (ok, err, rec) = raw_client("stroke", &[msg(3.0, 30.0, 1000.0 / 2048.0)]);
    assert!(!ok);
    assert!(err.contains("CommandStroke"), "{err}");
    assert!(rec.contains("fault-CommandStroke"));
    assert_eq!(last_command(&rec), 0.0);
}

#[test]
fn a_malformed_handshake_is_refused_and_a_second_client_too() {
    let (child, addrs) = start_site(&["--listen", "127.0.0.1:0"], 1);
    let mut first = TcpStream::connect(addrs[0]).expect("connect");
    first.write_all(&handshake()).expect("handshake");
    // A second client while the first's test runs: closed at once.
    let mut second = TcpStream::connect(addrs[0]).expect("connect");
    second
        .set_read_timeout(Some(std::time::Duration::from_secs(10)))
        .expect("timeout");
    let mut b = [0u8; 1];
    assert_eq!(
        second.read(&mut b).unwrap_or(0),
        0,
        "the second client is closed"
    );
    first.write_all(&msg(99.0, 0.0, 0.0)).expect("die");
    let (ok, err) = finish(child);
    assert!(ok, "{err}");
    assert!(err.contains("refused a second client"), "{err}");

    let (child, addrs) = start_site(&["--listen", "127.0.0.1:0"], 1);
    let mut s = TcpStream::connect(addrs[0]).expect("connect");
    let mut bad = handshake();
    bad[40..44].copy_from_slice(&(1i32 << 24).to_le_bytes());
    s.write_all(&bad).expect("bad handshake");
    let (ok, err) = finish(child);
    assert!(!ok);
    assert!(err.contains("dataSize"), "{err}");
}

// ---- UDP: a datagram lost, duplicated, reordered or malformed ----

/// Drive a UDP site with `script` (datagrams, after the 'a'/'b' exchange and the handshake),
/// reading a reply to every getForce; the site's success, stderr, recording.
fn udp_client(name: &str, script: &[Vec<u8>]) -> (bool, String, String) {
    let rec = tmp(&format!("udp-{name}.csv"));
    let rec_s = rec.display().to_string();
    let (child, addrs) = start_site(&["--listen", "127.0.0.1:0", "--udp", "--out", &rec_s], 1);
    {
        let s = std::net::UdpSocket::bind("127.0.0.1:0").expect("bind");
        s.connect(addrs[0]).expect("connect");
        s.set_read_timeout(Some(std::time::Duration::from_secs(5)))
            .expect("timeout");
        s.send(b"a").expect("a");
        let mut b = [0u8; 64];
        assert_eq!(s.recv(&mut b).expect("b"), 1);
        s.send(&handshake()).expect("handshake");
        for m in script {
            s.send(m).expect("send");
            if m.len() >= 8 && m[..8] == 10.0f64.to_le_bytes() && s.recv(&mut b).is_err() {
                break;
            }
        }
    }
    let (ok, err) = finish(child);
    let text = std::fs::read_to_string(&rec).unwrap_or_default();
    (ok, err, text)
}

#[test]
fn udp_datagrams_lost_reordered_or_malformed_stop_the_test_safely() {
    let step = |i: usize| {
        let t = i as f64 * DT;
        let d = 1.0 - (std::f64::consts::PI * i as f64 / 20.0).cos();
        (d, t)
    };
    let steps: Vec<Vec<u8>> = (1..=20)
        .flat_map(|i| {
            let (d, t) = step(i);
            [
                msg(3.0, d, t),
                msg(10.0, d, t),
                msg(3.0, d, t),
                msg(5.0, d, t),
            ]
        })
        .collect();
    let (d20, t20) = step(20);
    let (d21, t21) = step(21);
    let (d22, t22) = step(22);
    let cases: [(&str, Vec<Vec<u8>>, &str); 4] = [
        // Step 21's trial lost: its getForce arrives for a trial the site never imposed.
        ("lost", vec![msg(10.0, d21, t21)], "never received"),
        // Step 20's trial again, late, after step 21's.
        (
            "reordered",
            vec![msg(3.0, d21, t21), msg(3.0, d20, t20)],
            "out of order",
        ),
        // A datagram cut short.
        (
            "malformed",
            vec![msg(3.0, d21, t21)[..40].to_vec()],
            "40 bytes",
        ),
        // A step lost whole: the next one is two steps on.
        ("step-lost", vec![msg(3.0, d22, t22)], "changed from 4 to 8"),
    ];
    for (name, tail, why) in cases {
        let mut script = steps.clone();
        script.extend(tail);
        let (ok, err, rec) = udp_client(name, &script);
        assert!(!ok, "{name}: the site must report the stop");
        assert!(err.contains(why), "{name}: `{why}` not in: {err}");
        assert!(rec.contains("fault-EmergencyStop"), "{name}: {rec:.300}");
        assert!(rec.contains("# stop_reason:"), "{name}");
        assert_eq!(last_command(&rec), 0.0, "{name}: at the safe position");
    }
    // Duplicated setTrialResponse and commitState datagrams are the same trial again: ignored,
    // and the test ends normally.
    let mut script = Vec::new();
    for i in 1..=20 {
        let (d, t) = step(i);
        script.extend([
            msg(3.0, d, t),
            msg(3.0, d, t),
            msg(10.0, d, t),
            msg(5.0, d, t),
            msg(5.0, d, t),
        ]);
    }
    script.push(msg(99.0, 0.0, 0.0));
    let (ok, err, rec) = udp_client("duplicated", &script);
    assert!(ok, "{err}");
    assert!(rec.contains("# steps: 20"), "{rec:.400}");
}

#[test]
fn real_time_holds_the_virtual_rig_to_the_wall_clock() {
    let rec = tmp("real-time.csv");
    let rec_s = rec.display().to_string();
    let (child, addrs) = start_site(
        &["--listen", "127.0.0.1:0", "--real-time", "--out", &rec_s],
        1,
    );
    let steps = 100;
    let start;
    {
        let mut s = TcpStream::connect(addrs[0]).expect("connect");
        s.write_all(&handshake()).expect("handshake");
        start = std::time::Instant::now();
        for i in 1..=steps {
            let t = i as f64 * DT;
            // A small, smooth motion: a late client (a loaded host) must not trip the velocity.
            let d = 0.1 * (1.0 - (std::f64::consts::PI * i as f64 / 50.0).cos());
            for m in [msg(3.0, d, t), msg(10.0, d, t)] {
                s.write_all(&m).expect("send");
            }
            let mut r = [0u8; 64];
            s.read_exact(&mut r).expect("the force");
            s.write_all(&msg(5.0, d, t)).expect("commit");
        }
        s.write_all(&msg(99.0, 0.0, 0.0)).expect("die");
    }
    let elapsed = start.elapsed().as_secs_f64();
    let (ok, err) = finish(child);
    assert!(ok, "{err}");
    let text = std::fs::read_to_string(&rec).expect("recording");
    assert!(text.contains("# pacing: wall-clock"));
    // Paced, the client cannot get its steps faster than the rig's clock: 4 ticks each. The rig's
    // clock starts at the handshake, before the client's: one step of it may be under way already.
    let floor = (steps - 1) as f64 * 4.0 / 2048.0;
    assert!(
        elapsed >= floor,
        "{elapsed} s for {steps} steps, at least {floor} s"
    );
    let rows = text.lines().filter(|l| l.contains(",running,")).count();
    assert!(rows >= steps * 4, "{rows} running ticks");
}

//! Helpers of the `rths site` tests (`tests/site.rs`, `tests/site_board.rs`): the site started
//! and finished, the shipped OpenSees scripts run with openseespy.
#![allow(dead_code)] // each test binary uses its own subset

use std::io::{BufRead, BufReader, Read};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// The `rths` binary under test.
pub const RTHS: &str = env!("CARGO_BIN_EXE_rths");

/// The repository.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// El Centro's AT2 file.
pub fn record() -> PathBuf {
    root().join("data/ground_motions/IELC180.AT2")
}

/// Python with openseespy, and the LD_LIBRARY_PATH its library needs; `None` (after a loud
/// SKIPPED line) when missing, a panic when `RTHS_REQUIRE_OPENSEES=1`.
pub fn opensees(test: &str) -> Option<(String, Option<String>)> {
    let py = std::env::var("RTHS_PYTHON").unwrap_or_else(|_| "python3".into());
    let find = Command::new(&py)
        .args([
            "-c",
            "import importlib.util, os; s = importlib.util.find_spec('openseespy'); \
             print(os.path.dirname(s.origin) if s else '')",
        ])
        .output();
    let dir = match find {
        Ok(o) if o.status.success() => String::from_utf8_lossy(&o.stdout).trim().to_string(),
        _ => String::new(),
    };
    let lib = Path::new(&dir)
        .parent()
        .map(|p| p.join("openseespylinux/lib"));
    let ld = lib.filter(|l| l.is_dir()).map(|l| l.display().to_string());
    let ok = !dir.is_empty() && {
        let mut c = Command::new(&py);
        c.args(["-c", "import openseespy.opensees"]);
        if let Some(l) = &ld {
            c.env("LD_LIBRARY_PATH", l);
        }
        c.output().map(|o| o.status.success()).unwrap_or(false)
    };
    if ok {
        return Some((py, ld));
    }
    let why = format!("{py} has no working openseespy (set RTHS_PYTHON)");
    if std::env::var("RTHS_REQUIRE_OPENSEES").as_deref() == Ok("1") {
        panic!("{test}: RTHS_REQUIRE_OPENSEES=1 but {why}");
    }
    println!("SKIPPED: {test} (openseespy: {why})");
    None
}

/// `rths site ARGS`, started; its element addresses once it prints them.
pub fn start_site(args: &[&str], elements: usize) -> (Child, Vec<SocketAddr>) {
    let mut child = Command::new(RTHS)
        .arg("site")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("rths site starts");
    let mut out = BufReader::new(child.stdout.take().expect("stdout"));
    let mut addrs = Vec::new();
    while addrs.len() < elements {
        let mut l = String::new();
        if out.read_line(&mut l).expect("reading rths site") == 0 {
            let mut e = String::new();
            let _ = child.stderr.take().map(|mut s| s.read_to_string(&mut e));
            panic!("rths site ended before listening: {e}");
        }
        if let Some(a) = l.trim().strip_prefix("listening on ") {
            addrs.push(a.parse().expect("an address"));
        }
    }
    // Keep draining stdout so the site never blocks on a full pipe.
    let mut rest = String::new();
    std::thread::spawn(move || {
        let _ = out.read_to_string(&mut rest);
        print!("{rest}");
    });
    (child, addrs)
}

/// Wait for the site; its exit success and stderr.
pub fn finish(mut child: Child) -> (bool, String) {
    let mut err = String::new();
    if let Some(mut s) = child.stderr.take() {
        let _ = s.read_to_string(&mut err);
    }
    let ok = child.wait().expect("rths site ends").success();
    (ok, err)
}

/// A free port with the next one free too (two elements).
pub fn free_ports() -> u16 {
    for _ in 0..50 {
        let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
        let p = l.local_addr().expect("addr").port();
        if p < 65000 && std::net::TcpListener::bind(("127.0.0.1", p + 1)).is_ok() {
            return p;
        }
    }
    panic!("no two free ports")
}

/// What a shipped script wrote.
pub struct ScriptRun {
    /// Displacements, one row a step.
    pub disp: Vec<Vec<f64>>,
    /// Its wall time per step, s.
    pub wall_per_step_s: f64,
}

/// Run the shipped script `script` with El Centro and `extra`, its output in `out`.
pub fn run_script(
    py: &(String, Option<String>),
    script: &str,
    extra: &[String],
    out: &Path,
) -> ScriptRun {
    let mut c = Command::new(&py.0);
    c.arg(root().join("scripts/opensees").join(script))
        .arg("--record")
        .arg(record())
        .args(extra)
        .arg("--out")
        .arg(out);
    if let Some(l) = &py.1 {
        c.env("LD_LIBRARY_PATH", l);
    }
    let o = c.output().expect("python runs");
    assert!(
        o.status.success(),
        "{script} failed: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out).expect("script output")).expect("json");
    let disp = v["disp_mm"]
        .as_array()
        .expect("disp")
        .iter()
        .map(|x| match x.as_array() {
            Some(a) => a.iter().map(|y| y.as_f64().unwrap_or(f64::NAN)).collect(),
            None => vec![x.as_f64().unwrap_or(f64::NAN)],
        })
        .collect();
    let steps = v["steps"].as_f64().unwrap_or(1.0);
    ScriptRun {
        disp,
        wall_per_step_s: v["wall_s"].as_f64().unwrap_or(f64::NAN) / steps,
    }
}

/// NRMSE of column `j` of `x` against `reference`, % of the reference's range.
pub fn nrmse_pct(x: &[Vec<f64>], reference: &[Vec<f64>], j: usize) -> f64 {
    assert_eq!(x.len(), reference.len());
    let (a, b): (Vec<f64>, Vec<f64>) = x.iter().zip(reference).map(|(p, q)| (p[j], q[j])).unzip();
    rths_core::metrics::nrmse_pct(&a, &b).expect("nrmse")
}

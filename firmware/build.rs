//! Compiles the model and the ground motion into the firmware.
//!
//! - `RTHS_MODEL=path`: the LR model file (default `../data/models/lr.json`, the model `rths reproduce`
//!   trains). With feature `model-rnn`: `RTHS_RNN_MODEL=path` (default `../data/models/rnn-10.json`);
//!   if that file does not exist, a deterministic dummy net of hidden size 10 is generated, good only
//!   for the instruction-count budget (the firmware says so in its output).
//! - With feature `model-lrx`: `RTHS_LRX_MODEL=path` (default `../data/models/lrx.json`), the LRX
//!   frame model and its lead filter (`rths train lrx`).
//! - The El Centro record `../data/ground_motions/IELC180.AT2` (values in g), embedded as f64 exactly
//!   as the host parses it.
//!
//! A bad file fails the build with a message naming the file and the problem.
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn fail(msg: String) -> ! {
    eprintln!("error: {msg}");
    panic!("rths-firmware build script: {msg}");
}

fn read(path: &Path) -> String {
    println!("cargo:rerun-if-changed={}", path.display());
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| fail(format!("cannot read {}: {e}", path.display())))
}

fn floats(v: &serde_json::Value, what: &str, file: &Path) -> Vec<f64> {
    let arr = v
        .as_array()
        .unwrap_or_else(|| fail(format!("{}: `{what}` is not an array", file.display())));
    arr.iter()
        .enumerate()
        .map(|(i, x)| match x.as_f64() {
            Some(f) if f.is_finite() => f,
            _ => fail(format!(
                "{}: `{what}[{i}]` is not a finite number",
                file.display()
            )),
        })
        .collect()
}

fn lit(x: f64) -> String {
    // Debug formatting is the shortest round-trip form: the constant is the same f64 bit for bit.
    let s = format!("{x:?}");
    if s.contains('.') || s.contains('e') || s.contains("inf") || s.contains("NaN") {
        s
    } else {
        format!("{s}.0")
    }
}

fn array(xs: &[f64]) -> String {
    let mut s = String::from("[");
    for x in xs {
        let _ = write!(s, "{},", lit(*x));
    }
    s.push(']');
    s
}

fn lr(out: &mut String, root: &Path) {
    println!("cargo:rerun-if-env-changed=RTHS_MODEL");
    let path = std::env::var_os("RTHS_MODEL")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("data/models/lr.json"));
    let text = read(&path);
    let v: serde_json::Value = serde_json::from_str(&text)
        .unwrap_or_else(|e| fail(format!("{}: not JSON: {e}", path.display())));
    if v["format"] != "rths-model" || v["kind"] != "lr" {
        fail(format!(
            "{}: expected an rths-model file of kind \"lr\"",
            path.display()
        ));
    }
    let theta = floats(&v["lr"]["theta"], "lr.theta", &path);
    if theta.len() != 6 {
        fail(format!(
            "{}: lr.theta has {} coefficients, the LR model needs 6",
            path.display(),
            theta.len()
        ));
    }
    let _ = writeln!(out, "/// LR coefficients θ0..θ5 from `{}`.", path.display());
    let _ = writeln!(out, "pub const LR_THETA: [f64; 6] = {};", array(&theta));
    let _ = writeln!(out, "/// The model file compiled in.");
    let _ = writeln!(
        out,
        "pub const MODEL_SOURCE: &str = {:?};",
        path.display().to_string()
    );
}

fn lrx(out: &mut String, root: &Path) {
    println!("cargo:rerun-if-env-changed=RTHS_LRX_MODEL");
    let path = std::env::var_os("RTHS_LRX_MODEL")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("data/models/lrx.json"));
    let text = read(&path);
    let v: serde_json::Value = serde_json::from_str(&text)
        .unwrap_or_else(|e| fail(format!("{}: not JSON: {e}", path.display())));
    if v["format"] != "rths-model" || v["kind"] != "lrx" {
        fail(format!(
            "{}: expected an rths-model file of kind \"lrx\"",
            path.display()
        ));
    }
    let x = &v["lrx"];
    let coeffs = floats(&x["coeffs"], "lrx.coeffs", &path);
    let lead = floats(&x["lead_weights"], "lrx.lead_weights", &path);
    let scalars = floats(
        &serde_json::json!([x["k_corr_kn_per_mm"], x["k_adapt_ticks"]]),
        "lrx.k_corr_kn_per_mm / lrx.k_adapt_ticks",
        &path,
    );
    let stride = x["lead_stride"].as_u64().unwrap_or(0);
    if coeffs.len() != 9 || lead.len() != 8 || !(1..=8).contains(&stride) {
        fail(format!(
            "{}: lrx needs 9 coeffs, 8 lead_weights and a lead_stride in 1..=8",
            path.display()
        ));
    }
    let _ = writeln!(out, "/// LRX frame coefficients from `{}`.", path.display());
    let _ = writeln!(out, "pub const LRX_COEFFS: [f64; 9] = {};", array(&coeffs));
    let _ = writeln!(out, "/// LRX nominal force-correction stiffness, kN/mm.");
    let _ = writeln!(out, "pub const LRX_K_CORR: f64 = {};", lit(scalars[0]));
    let _ = writeln!(out, "/// LRX stiffness-estimate time constant, ticks.");
    let _ = writeln!(out, "pub const LRX_K_ADAPT: f64 = {};", lit(scalars[1]));
    let _ = writeln!(out, "/// LRX lead-filter weights.");
    let _ = writeln!(out, "pub const LRX_LEAD: [f64; 8] = {};", array(&lead));
    let _ = writeln!(out, "/// LRX lead-filter stride, ticks.");
    let _ = writeln!(out, "pub const LRX_LEAD_STRIDE: usize = {stride};");
    let _ = writeln!(out, "/// The model file compiled in.");
    let _ = writeln!(
        out,
        "pub const MODEL_SOURCE: &str = {:?};",
        path.display().to_string()
    );
}

/// A deterministic pseudo-random value in [-0.5, 0.5) (64-bit LCG, top bits).
fn lcg(state: &mut u64) -> f64 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
}

fn rnn(out: &mut String, root: &Path) {
    println!("cargo:rerun-if-env-changed=RTHS_RNN_MODEL");
    let path = std::env::var_os("RTHS_RNN_MODEL")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("data/models/rnn-10.json"));
    println!("cargo:rerun-if-changed={}", path.display());
    let (h, w_ih, w_hh, b_h, w_ho, b_o, in_mean, in_std, out_mean, out_std, dummy);
    if path.exists() {
        let text = read(&path);
        let v: serde_json::Value = serde_json::from_str(&text)
            .unwrap_or_else(|e| fail(format!("{}: not JSON: {e}", path.display())));
        if v["format"] != "rths-model" || v["kind"] != "rnn" {
            fail(format!(
                "{}: expected an rths-model file of kind \"rnn\"",
                path.display()
            ));
        }
        let r = &v["rnn"];
        h = r["hidden"].as_u64().unwrap_or(0) as usize;
        if !(1..=32).contains(&h) {
            fail(format!("{}: rnn.hidden must be in 1..=32", path.display()));
        }
        let rows = |key: &str, cols: usize| -> Vec<f64> {
            let a = r[key]
                .as_array()
                .unwrap_or_else(|| fail(format!("{}: rnn.{key} missing", path.display())));
            if a.len() != h {
                fail(format!("{}: rnn.{key} must have {h} rows", path.display()));
            }
            a.iter()
                .enumerate()
                .flat_map(|(j, row)| {
                    let f = floats(row, &format!("rnn.{key}[{j}]"), &path);
                    if f.len() != cols {
                        fail(format!(
                            "{}: rnn.{key}[{j}] must have {cols} values",
                            path.display()
                        ));
                    }
                    f
                })
                .collect()
        };
        w_ih = rows("w_ih", 2);
        w_hh = rows("w_hh", h);
        let vec = |key: &str, n: usize| -> Vec<f64> {
            let f = floats(&r[key], &format!("rnn.{key}"), &path);
            if f.len() != n {
                fail(format!(
                    "{}: rnn.{key} must have {n} values",
                    path.display()
                ));
            }
            f
        };
        b_h = vec("b_h", h);
        w_ho = vec("w_ho", h);
        in_mean = vec("input_mean", 2);
        in_std = vec("input_std", 2);
        let scalar = |key: &str| -> f64 {
            match r[key].as_f64() {
                Some(f) if f.is_finite() => f,
                _ => fail(format!(
                    "{}: rnn.{key} is not a finite number",
                    path.display()
                )),
            }
        };
        b_o = scalar("b_o");
        out_mean = scalar("output_mean");
        out_std = scalar("output_std");
        if in_std.iter().chain([&out_std]).any(|s| *s <= 0.0) {
            fail(format!(
                "{}: RNN standard deviations must be > 0",
                path.display()
            ));
        }
        dummy = false;
    } else {
        // Budget only: weights small enough that tanh stays in its ordinary range.
        h = 10;
        let mut s = 0x5eed_0010u64;
        w_ih = (0..h * 2).map(|_| lcg(&mut s)).collect();
        w_hh = (0..h * h).map(|_| 0.3 * lcg(&mut s)).collect();
        b_h = (0..h).map(|_| 0.1 * lcg(&mut s)).collect();
        w_ho = (0..h).map(|_| lcg(&mut s)).collect();
        b_o = 0.0;
        in_mean = vec![0.0, 0.0];
        in_std = vec![3000.0, 10.0];
        out_mean = 0.0;
        out_std = 1e-3;
        dummy = true;
    }
    let _ = writeln!(out, "/// RNN hidden size.");
    let _ = writeln!(out, "pub const RNN_HIDDEN: usize = {h};");
    let _ = writeln!(out, "/// RNN W_ih, H×2 row-major.");
    let _ = writeln!(
        out,
        "pub const RNN_W_IH: [f64; {}] = {};",
        w_ih.len(),
        array(&w_ih)
    );
    let _ = writeln!(out, "/// RNN W_hh, H×H row-major.");
    let _ = writeln!(
        out,
        "pub const RNN_W_HH: [f64; {}] = {};",
        w_hh.len(),
        array(&w_hh)
    );
    let _ = writeln!(out, "/// RNN b_h.");
    let _ = writeln!(
        out,
        "pub const RNN_B_H: [f64; {}] = {};",
        b_h.len(),
        array(&b_h)
    );
    let _ = writeln!(out, "/// RNN W_ho.");
    let _ = writeln!(
        out,
        "pub const RNN_W_HO: [f64; {}] = {};",
        w_ho.len(),
        array(&w_ho)
    );
    let _ = writeln!(out, "/// RNN b_o.");
    let _ = writeln!(out, "pub const RNN_B_O: f64 = {};", lit(b_o));
    let _ = writeln!(out, "/// RNN input mean / std, output mean / std.");
    let _ = writeln!(
        out,
        "pub const RNN_IN_MEAN: [f64; 2] = {};",
        array(&in_mean)
    );
    let _ = writeln!(out, "/// RNN input std.");
    let _ = writeln!(out, "pub const RNN_IN_STD: [f64; 2] = {};", array(&in_std));
    let _ = writeln!(out, "/// RNN output mean.");
    let _ = writeln!(out, "pub const RNN_OUT_MEAN: f64 = {};", lit(out_mean));
    let _ = writeln!(out, "/// RNN output std.");
    let _ = writeln!(out, "pub const RNN_OUT_STD: f64 = {};", lit(out_std));
    let _ = writeln!(
        out,
        "/// The weights are a generated dummy (budget only, no accuracy)."
    );
    let _ = writeln!(out, "pub const RNN_DUMMY: bool = {dummy};");
    let src = if dummy {
        "generated dummy RNN-10 (budget only)".to_string()
    } else {
        path.display().to_string()
    };
    let _ = writeln!(out, "/// The model compiled in.");
    let _ = writeln!(out, "pub const MODEL_SOURCE: &str = {src:?};");
}

/// The AT2 record as the host reads it (`rths::motion::parse_at2`): 4 header lines, NPTS and DT on
/// the 4th, then the values in g.
fn motion(out: &mut String, root: &Path) {
    let path = root.join("data/ground_motions/IELC180.AT2");
    let text = read(&path);
    let mut lines = text.lines();
    let header: Vec<&str> = lines.by_ref().take(4).collect();
    let h4 = header
        .get(3)
        .unwrap_or_else(|| fail(format!("{}: short AT2 header", path.display())))
        .to_ascii_uppercase();
    let field = |key: &str| -> String {
        let rest = h4
            .split_once(key)
            .map(|(_, r)| r)
            .unwrap_or_else(|| fail(format!("{}: no {key} in the AT2 header", path.display())));
        rest.trim_start_matches(|c: char| c == '=' || c == ':' || c.is_whitespace())
            .chars()
            .take_while(|c| c.is_ascii_digit() || *c == '.' || *c == 'E' || *c == '-')
            .collect()
    };
    let npts: usize = field("NPTS")
        .parse()
        .unwrap_or_else(|_| fail(format!("{}: bad NPTS", path.display())));
    let dt_s: f64 = field("DT")
        .parse()
        .unwrap_or_else(|_| fail(format!("{}: bad DT", path.display())));
    let values: Vec<f64> = lines
        .flat_map(|l| l.split_whitespace())
        .map(|t| {
            t.replace('D', "E")
                .parse::<f64>()
                .unwrap_or_else(|_| fail(format!("{}: bad value `{t}`", path.display())))
        })
        .collect();
    if values.len() != npts
        || npts < 2
        || !dt_s.is_finite()
        || dt_s <= 0.0
        || values.iter().any(|v| !v.is_finite())
    {
        fail(format!(
            "{}: expected {npts} finite values at DT > 0, found {}",
            path.display(),
            values.len()
        ));
    }
    // Controller ticks, exactly as `GroundMotion::resample_mm_s2(DT_S)` counts them.
    let dt_tick = 1.0 / 2048.0;
    let duration = (npts - 1) as f64 * dt_s;
    let last = (duration / dt_tick * (1.0 + 1e-12)).floor() as usize;
    let _ = writeln!(out, "/// El Centro 1940 NS (IELC180), g.");
    let _ = writeln!(
        out,
        "pub static MOTION_G: [f64; {npts}] = {};",
        array(&values)
    );
    let _ = writeln!(out, "/// Record step, s.");
    let _ = writeln!(out, "pub const MOTION_DT_S: f64 = {};", lit(dt_s));
    let _ = writeln!(
        out,
        "/// Controller ticks in the record (resampled at 2048 Hz)."
    );
    let _ = writeln!(out, "pub const RECORD_TICKS: u32 = {};", last + 1);
}

/// The compile-time fault plan of a `fault-inject` build: `RTHS_FAULT=KIND@SECONDS[+TICKS]` (default
/// `nan-disp@10`, for ever). KIND: `nan-disp`, `nan-force`, `dropout`, `stuck-disp`, `stuck-force`,
/// `spike-disp:MM`, `spike-force:KN`, `valve:FRACTION`, `stiffness:FACTOR`, `lost` (lost ticks),
/// `overrun` (the controller is told its previous tick overran).
fn fault(out: &mut String) {
    println!("cargo:rerun-if-env-changed=RTHS_FAULT");
    let spec = std::env::var("RTHS_FAULT").unwrap_or_else(|_| "nan-disp@10".to_string());
    let bad = |why: &str| -> ! { fail(format!("RTHS_FAULT={spec}: {why}")) };
    let (kind, when) = spec
        .split_once('@')
        .unwrap_or_else(|| bad("expected KIND@SECONDS[+TICKS]"));
    let (secs, ticks) = match when.split_once('+') {
        Some((s, t)) => (s, Some(t)),
        None => (when, None),
    };
    let secs: f64 = secs
        .parse()
        .unwrap_or_else(|_| bad("start is not a number of seconds"));
    if !(secs.is_finite() && secs >= 0.0) {
        bad("start must be a finite, non-negative number of seconds");
    }
    let start = (secs * 2048.0).round() as u64;
    let ticks = match ticks {
        Some(t) => t
            .parse::<u64>()
            .unwrap_or_else(|_| bad("duration is not a tick count"))
            .to_string(),
        None => "u64::MAX".to_string(),
    };
    let (name, arg) = match kind.split_once(':') {
        Some((n, a)) => {
            let x: f64 = a
                .parse()
                .unwrap_or_else(|_| bad("the magnitude is not a number"));
            if !x.is_finite() {
                bad("the magnitude must be finite");
            }
            (n, Some(x))
        }
        None => (kind, None),
    };
    let need = |a: Option<f64>| a.unwrap_or_else(|| bad("this kind needs a magnitude (KIND:X)"));
    let hs = "rths_hal_sim";
    let kind_expr = match name {
        "nan-disp" => Some(format!("{hs}::FaultKind::NaN({hs}::Channel::Disp)")),
        "nan-force" => Some(format!("{hs}::FaultKind::NaN({hs}::Channel::Force)")),
        "dropout" => Some(format!("{hs}::FaultKind::Dropout")),
        "stuck-disp" => Some(format!("{hs}::FaultKind::Stuck({hs}::Channel::Disp)")),
        "stuck-force" => Some(format!("{hs}::FaultKind::Stuck({hs}::Channel::Force)")),
        "spike-disp" => Some(format!(
            "{hs}::FaultKind::Spike({hs}::Channel::Disp, {})",
            lit(need(arg))
        )),
        "spike-force" => Some(format!(
            "{hs}::FaultKind::Spike({hs}::Channel::Force, {})",
            lit(need(arg))
        )),
        "valve" => Some(format!(
            "{hs}::FaultKind::ValveSaturation({})",
            lit(need(arg))
        )),
        "stiffness" => Some(format!(
            "{hs}::FaultKind::StiffnessChange({})",
            lit(need(arg))
        )),
        "lost" => Some(format!("{hs}::FaultKind::LostTicks")),
        "overrun" => None,
        _ => bad("unknown kind"),
    };
    let _ = writeln!(
        out,
        "/// The fault-inject plan, as given (RTHS_FAULT).\npub const FAULT_SPEC: &str = {spec:?};"
    );
    let _ = writeln!(
        out,
        "/// First faulty tick.\npub const FAULT_START: u64 = {start};"
    );
    let _ = writeln!(
        out,
        "/// Faulty ticks.\npub const FAULT_TICKS: u64 = {ticks};"
    );
    match kind_expr {
        Some(k) => {
            let _ = writeln!(out, "/// The rig fault, if any.\npub const FAULT_KIND: Option<{hs}::FaultKind> = Some({k});");
            let _ = writeln!(
                out,
                "/// Injected overruns.\npub const FAULT_OVERRUN: bool = false;"
            );
        }
        None => {
            let _ = writeln!(
                out,
                "/// The rig fault, if any.\npub const FAULT_KIND: Option<{hs}::FaultKind> = None;"
            );
            let _ = writeln!(
                out,
                "/// Injected overruns.\npub const FAULT_OVERRUN: bool = true;"
            );
        }
    }
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    let root = manifest
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| fail("no parent of the firmware directory".into()));
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").unwrap_or_default());

    // cortex-m-rt's link.x includes memory.x from the linker search path.
    let mem = read(&root.join("memory.x"));
    std::fs::write(out_dir.join("memory.x"), mem)
        .unwrap_or_else(|e| fail(format!("cannot write memory.x: {e}")));
    println!("cargo:rustc-link-search={}", out_dir.display());

    let mut gen = String::from("// Generated by build.rs: the model and the ground motion.\n");
    let rnn_on = std::env::var_os("CARGO_FEATURE_MODEL_RNN").is_some();
    let fe_on = std::env::var_os("CARGO_FEATURE_FE_ATS").is_some();
    let lrx_on = std::env::var_os("CARGO_FEATURE_MODEL_LRX").is_some();
    if rnn_on {
        rnn(&mut gen, &root);
    } else if fe_on {
        gen.push_str("/// The model compiled in.\npub const MODEL_SOURCE: &str = \"finite elements (Chang) + ATS\";\n");
    } else if lrx_on {
        lrx(&mut gen, &root);
    } else {
        lr(&mut gen, &root);
    }
    motion(&mut gen, &root);
    // Only a fault-inject build has a fault plan (and the simulated rig its constants name).
    if std::env::var_os("CARGO_FEATURE_FAULT_INJECT").is_some() {
        fault(&mut gen);
    }
    std::fs::write(out_dir.join("gen.rs"), gen)
        .unwrap_or_else(|e| fail(format!("cannot write gen.rs: {e}")));
    println!("cargo:rerun-if-changed=build.rs");
}

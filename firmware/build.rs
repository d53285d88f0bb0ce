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
//! - With feature `structure-fe`, `structure-nl` or `structure-meta`: `RTHS_STRUCTURE=path`, a
//!   structure file (`data/structures/`), whose numerical part the controller integrates (linear,
//!   or with its yielding stories) or, with `structure-meta`, `RTHS_STRUCTURE_MODEL=path`, its
//!   structure metamodel (`rths train meta --structure path --rate R`), refused if trained for
//!   another structure (name and checksum) or rate. An imported structure (`rths import
//!   opensees`) with its reduced-order model (an `rths-reduced-model` file, `rths train meta` on it)
//!   takes the same path: the build embeds the model's modes and static corrections, refused if
//!   trained for a structure of another name (the checksum of the condensed matrices is the host's:
//!   this script cannot condense) or if core's validation refuses it at this build's step; its
//!   modes are continuous-time, so any training rate runs.
//! - With feature `structure-modal`: `RTHS_STRUCTURE=path` (a yielding structure file) and
//!   `RTHS_STRUCTURE_MODEL=path`, its learned modal-hysteretic metamodel (an `rths-nl-model` file,
//!   `rths train nonlinear`), refused if trained for another structure (name and checksum of its
//!   content). Its modes are continuous-time and its laws rate-independent, so a model trained at
//!   2048 Hz runs at 4096 Hz: no rate check.
//! - With feature `budget-structures`: the budget's structures, FE linear, FE yielding, the
//!   structure metamodel and the modal-hysteretic metamodel for N = 1, 3, 8: `RTHS_BUDGET_LINEAR`,
//!   `RTHS_BUDGET_YIELDING` (three structure files each, comma-separated; default
//!   `paper-frame,vrths-case1,shear8` and `paper-frame-yielding,shear3-yielding,shear8-yielding` in
//!   `data/structures/`), `RTHS_BUDGET_METAS` (the linear ones' metamodels at this build's rate,
//!   required: `budget.sh` trains them) and `RTHS_BUDGET_MODALS` (the yielding ones' modal models;
//!   default `nl-S.json` in `data/models/`), `RTHS_BUDGET_REDUCED` (three reduced-order models of
//!   imported structures, N ≈ 10, 100, 1,000 DOFs with mass, comma-separated: `budget.sh` trains
//!   them; without it the budget has no reduced rows).
//!
//! The files are read by the host's own readers (`rths-files`): a model file is checked exactly as
//! `rths check-model` checks it (feature names included), the record parsed as `rths analyze` parses
//! it. A bad file fails the build with a message naming the file and the problem.
//!
//! The rate (`rate-4096`): the record's ticks and the fault plan's start follow it; the default model
//! files in `data/models/` become `lr-4096.json`, `lrx-4096.json`, `rnn-10-4096.json`, and a model
//! file trained at another rate (its `dt_s`) is refused. The board's core: a Cortex-M7 board needs `-C target-cpu=cortex-m7` (`cargo build-m7`),
//! a Cortex-M4 board must not have it.
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rths_core::params::{dt_s, CONTROL_RATES_HZ};
use rths_files::model_file::{ModelFile, ModelKind};
use rths_files::motion::parse_at2;
use rths_files::nl_model_file::NlModelFile;
use rths_files::reduced_model_file::{imported_structure_name, ReducedModelFile};
use rths_files::structure_file::Structure;
use rths_files::structure_meta::{MetaFile, StructureArrays};

fn fail(msg: String) -> ! {
    eprintln!("error: {msg}");
    panic!("rths-firmware build script: {msg}");
}

/// The controller rate of this build, Hz: `rate-4096` selects core's second rate. (This build
/// script's own rths-core is built without the firmware's features, so it asks the feature itself.)
fn rate_hz() -> u32 {
    if std::env::var_os("CARGO_FEATURE_RATE_4096").is_some() {
        CONTROL_RATES_HZ[1]
    } else {
        CONTROL_RATES_HZ[0]
    }
}

/// The shipped model `stem` for this build's rate, in `data/models/`: `lr.json` at 2048 Hz,
/// `lr-4096.json` at 4096 Hz (stem `lr`).
fn default_model(root: &Path, stem: &str) -> PathBuf {
    let rate = rate_hz();
    if rate == CONTROL_RATES_HZ[0] {
        root.join(format!("data/models/{stem}.json"))
    } else {
        root.join(format!("data/models/{stem}-{rate}.json"))
    }
}

/// A model file that must exist: else the command that trains it at this build's rate.
fn require(path: &Path, train: &str) {
    if !path.exists() {
        let rate = rate_hz();
        let features = if rate == CONTROL_RATES_HZ[0] {
            "sim"
        } else {
            "sim,rate-4096"
        };
        fail(format!(
            "{}: no such model file: train one at {rate} Hz with `cargo run --release --features \
             {features} -- train {train} --out {}` (or point the build at one)",
            path.display(),
            path.display()
        ));
    }
}

/// Refuse a model trained at another rate than this build's: its coefficients are per tick.
fn check_rate(path: &Path, m: &ModelFile) {
    let rate = rate_hz();
    if m.dt_s.to_bits() != dt_s(rate).to_bits() {
        fail(format!(
            "{}: the model was trained at {:.0} Hz (dt_s = {}), this build runs at {rate} Hz: train one \
             at {rate} Hz (`cargo run --release --features sim{} -- train ...`) and point the build at it",
            path.display(),
            1.0 / m.dt_s,
            m.dt_s,
            if rate == CONTROL_RATES_HZ[0] { "" } else { ",rate-4096" }
        ));
    }
}

fn read(path: &Path) -> String {
    println!("cargo:rerun-if-changed={}", path.display());
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| fail(format!("cannot read {}: {e}", path.display())))
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

/// A model file of `kind`, read and checked by the host's loader (format, version, feature names,
/// shapes, finite weights).
fn load_model(path: &Path, kind: ModelKind) -> ModelFile {
    println!("cargo:rerun-if-changed={}", path.display());
    ModelFile::load_kind(path, kind).unwrap_or_else(|e| fail(format!("{}: {e}", path.display())))
}

fn lr(out: &mut String, root: &Path) {
    println!("cargo:rerun-if-env-changed=RTHS_MODEL");
    let path = std::env::var_os("RTHS_MODEL")
        .map(PathBuf::from)
        .unwrap_or_else(|| default_model(root, "lr"));
    require(&path, "lr");
    let m = load_model(&path, ModelKind::Lr);
    check_rate(&path, &m);
    // load_kind checked the section's shape: 6 finite coefficients.
    let theta =
        m.lr.unwrap_or_else(|| fail(format!("{}: no lr section", path.display())))
            .theta;
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
        .unwrap_or_else(|| default_model(root, "lrx"));
    require(&path, "lrx");
    let m = load_model(&path, ModelKind::Lrx);
    check_rate(&path, &m);
    let delay = u16::try_from(m.delay_steps)
        .unwrap_or_else(|_| fail(format!("{}: delay_steps over 16 bits", path.display())));
    let _ = writeln!(
        out,
        "/// LRX feedback delay, ticks (the link checksum covers it)."
    );
    let _ = writeln!(out, "pub const LRX_DELAY_STEPS: u16 = {delay};");
    let x = m
        .lrx
        .unwrap_or_else(|| fail(format!("{}: no lrx section", path.display())));
    let (coeffs, lead, stride) = (x.coeffs, x.lead_weights, x.lead_stride);
    let scalars = [
        x.k_corr_kn_per_mm,
        x.k_adapt_ticks,
        x.lead_adapt_ticks.unwrap_or(0.0),
        x.specimen_mass_kn_s2_per_mm.unwrap_or(0.0),
        x.specimen_damping_kn_s_per_mm.unwrap_or(0.0),
    ];
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
    let _ = writeln!(
        out,
        "/// LRX lead-adaptation time constant, ticks (0: fixed lead)."
    );
    let _ = writeln!(out, "pub const LRX_LEAD_ADAPT: f64 = {};", lit(scalars[2]));
    let _ = writeln!(
        out,
        "/// LRX specimen mass and damping removed from the force (prototype scale)."
    );
    let _ = writeln!(
        out,
        "pub const LRX_SPECIMEN_DYNAMICS: [f64; 2] = {};",
        array(&scalars[3..5])
    );
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
        .unwrap_or_else(|| default_model(root, "rnn-10"));
    println!("cargo:rerun-if-changed={}", path.display());
    let (h, w_ih, w_hh, b_h, w_ho, b_o, in_mean, in_std, out_mean, out_std, dummy, delay);
    if path.exists() {
        let m = load_model(&path, ModelKind::Rnn);
        check_rate(&path, &m);
        delay = u16::try_from(m.delay_steps)
            .unwrap_or_else(|_| fail(format!("{}: delay_steps over 16 bits", path.display())));
        let r = m
            .rnn
            .unwrap_or_else(|| fail(format!("{}: no rnn section", path.display())));
        h = r.hidden;
        w_ih = r.w_ih.concat();
        w_hh = r.w_hh.concat();
        b_h = r.b_h;
        w_ho = r.w_ho;
        b_o = r.b_o;
        in_mean = r.input_mean;
        in_std = r.input_std;
        out_mean = r.output_mean;
        out_std = r.output_std;
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
        delay = 28;
    }
    let _ = writeln!(
        out,
        "/// RNN feedback delay, ticks (the link checksum covers it)."
    );
    let _ = writeln!(out, "pub const RNN_DELAY_STEPS: u16 = {delay};");
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

/// The El Centro record, read by the host's AT2 reader (`rths_files::motion::parse_at2`), and its
/// length in controller ticks by the host's rule (`rths_core::motion::Record::ticks`).
fn motion(out: &mut String, root: &Path) {
    let path = root.join("data/ground_motions/IELC180.AT2");
    let text = read(&path);
    let record =
        parse_at2(&text, "IELC180").unwrap_or_else(|e| fail(format!("{}: {e}", path.display())));
    let ticks = record.record().ticks(dt_s(rate_hz()));
    let ticks = u32::try_from(ticks)
        .ok()
        .filter(|t| *t > 0)
        .unwrap_or_else(|| fail(format!("{}: {ticks} controller ticks", path.display())));
    let (npts, record_dt_s, values) = (record.accel_g.len(), record.dt_s, record.accel_g);
    let _ = writeln!(out, "/// El Centro 1940 NS (IELC180), g.");
    let _ = writeln!(
        out,
        "pub static MOTION_G: [f64; {npts}] = {};",
        array(&values)
    );
    let _ = writeln!(out, "/// Record step, s.");
    let _ = writeln!(out, "pub const MOTION_DT_S: f64 = {};", lit(record_dt_s));
    let _ = writeln!(
        out,
        "/// Controller ticks in the record (resampled at {} Hz).",
        rate_hz()
    );
    let _ = writeln!(out, "pub const RECORD_TICKS: u32 = {ticks};");
}

/// The compile-time fault plan of a `fault-inject` build: `RTHS_FAULT=KIND@SECONDS[+TICKS]` (default
/// `nan-disp@10`, for ever). KIND: `nan-disp`, `nan-force`, `dropout`, `stuck-disp`, `stuck-force`,
/// `spike-disp:MM`, `spike-force:KN`, `valve:FRACTION`, `stiffness:FACTOR`, `lost` (lost ticks),
/// `overrun` (the controller is told its previous tick overran), `stall` (the control task never
/// returns: the watchdog's test).
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
    let start = (secs * f64::from(rate_hz())).round() as u64;
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
        "overrun" | "stall" => None,
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
    let _ = writeln!(
        out,
        "/// The control task stalls from the first faulty tick (the watchdog's test).\npub const FAULT_STALL: bool = {};",
        name == "stall"
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
                "/// Injected overruns.\npub const FAULT_OVERRUN: bool = {};",
                name == "overrun"
            );
        }
    }
}

/// A structure file, read and validated by the host's reader.
fn load_structure(path: &Path) -> Structure {
    println!("cargo:rerun-if-changed={}", path.display());
    Structure::load(path).unwrap_or_else(|e| fail(format!("{}: {e}", path.display())))
}

/// A structure metamodel file checked against `structure` at this build's rate.
fn load_meta(path: &Path, structure: &Structure) -> rths_core::metamodel::DeltaArxParams {
    println!("cargo:rerun-if-changed={}", path.display());
    MetaFile::load(path)
        .and_then(|m| m.check(structure, dt_s(rate_hz())))
        .unwrap_or_else(|e| fail(format!("{}: {e}", path.display())))
}

/// The numerical part of `structure` as a `StructureSpec` expression (linear, or yielding).
fn structure_spec(structure: &Structure, yielding: bool, path: &Path) -> String {
    let a = if yielding {
        StructureArrays::yielding(structure, dt_s(rate_hz()))
    } else {
        StructureArrays::linear(structure)
    }
    .unwrap_or_else(|e| fail(format!("{}: {e}", path.display())));
    // The controller refuses what its integrator cannot step: so does the build.
    let spec = a.spec();
    let built = if yielding {
        spec.yielding(dt_s(rate_hz())).map(|_| ())
    } else {
        spec.linear(dt_s(rate_hz())).map(|_| ())
    };
    if let Err(e) = built {
        fail(format!("{}: {e}", path.display()));
    }
    let laws = law_specs(&a.laws);
    format!(
        "rths_core::control::StructureSpec {{ dofs: {}, mass: &{}, damping: &{}, stiffness: &{}, \
         initial_stiffness: &{}, ground_mass: &{}, specimen_dof: {}, laws: {laws} }}",
        a.dofs,
        array(&a.mass),
        array(&a.damping),
        array(&a.stiffness),
        array(&a.initial_stiffness),
        array(&a.ground_mass),
        a.specimen_dof
    )
}

/// Story laws as a `&[StoryLawSpec]` expression.
fn law_specs(laws: &[rths_core::control::StoryLawSpec]) -> String {
    let mut out = String::from("&[");
    for l in laws {
        let bw = match l.bouc_wen {
            Some(v) => format!("Some({})", array(&v)),
            None => "None".into(),
        };
        let _ = write!(
            out,
            "rths_core::control::StoryLawSpec {{ k0_kn_per_mm: {}, yield_force_kn: {}, \
             post_yield_ratio: {}, bouc_wen: {bw} }},",
            lit(l.k0_kn_per_mm),
            lit(l.yield_force_kn),
            lit(l.post_yield_ratio)
        );
    }
    out.push(']');
    out
}

/// The modal-hysteretic metamodel at `model`, checked against the structure file at `path` (name
/// and checksum) and validated at this build's step, as a `ModelSpec::StructureModal` expression.
fn modal_spec(path: &Path, model: &Path) -> String {
    println!("cargo:rerun-if-changed={}", model.display());
    let f = NlModelFile::load_for(model, path)
        .unwrap_or_else(|e| fail(format!("{} for {}: {e}", model.display(), path.display())));
    // The controller's own validation at its step (the file's step is only where it was trained).
    f.params(dt_s(rate_hz()))
        .unwrap_or_else(|e| fail(format!("{}: {e}", model.display())));
    let mut modes = String::from("&[");
    for m in &f.modes {
        let _ = write!(
            modes,
            "rths_core::metamodel::ModalMode {{ omega_rad_s: {}, damping_ratio: {}, \
             ground_participation: {} }},",
            lit(m.omega_rad_s),
            lit(m.damping_ratio),
            lit(m.ground_participation)
        );
    }
    modes.push(']');
    let laws: Vec<rths_core::control::StoryLawSpec> = f
        .springs
        .iter()
        .map(|s| {
            s.law()
                .map(|l| rths_core::control::StoryLawSpec::of(&l))
                .unwrap_or_else(|e| fail(format!("{}: {e}", model.display())))
        })
        .collect();
    let shape: Vec<f64> = f.shape.iter().flatten().copied().collect();
    let drift: Vec<f64> = f
        .springs
        .iter()
        .flat_map(|s| s.drift.iter().copied())
        .collect();
    format!(
        "rths_core::model::ModelSpec::StructureModal {{ model: rths_core::control::ModalSpec {{ \
         modes: {modes}, shape: &{}, specimen_dof: {}, specimen_k_kn_per_mm: {}, laws: {}, \
         drift: &{} }} }}",
        array(&shape),
        f.specimen_dof,
        lit(f.specimen_stiffness_kn_per_mm),
        law_specs(&laws),
        array(&drift)
    )
}

/// A reduced-order model file (`rths-reduced-model`), read and validated by the host's reader at
/// this build's step, as a `ModelSpec::StructureReduced` expression; `structure`: the imported
/// structure file whose name it must carry (the budget's rows name none).
fn reduced_spec(model: &Path, structure: Option<&Path>) -> (String, ReducedModelFile) {
    let text = read(model);
    let f = ReducedModelFile::from_json(&text)
        .unwrap_or_else(|e| fail(format!("{}: {e}", model.display())));
    let arrays = match structure {
        Some(p) => {
            let name = imported_structure_name(&read(p))
                .unwrap_or_else(|e| fail(format!("{}: {e}", p.display())));
            f.arrays_for_name(&name)
        }
        None => f.arrays(),
    }
    .unwrap_or_else(|e| fail(format!("{}: {e}", model.display())));
    let spec = arrays.spec();
    spec.params(dt_s(rate_hz()))
        .unwrap_or_else(|e| fail(format!("{}: {e}", model.display())));
    let mut modes = String::from("&[");
    for m in spec.modes {
        let _ = write!(
            modes,
            "rths_core::metamodel::ReducedMode {{ omega_rad_s: {}, damping_ratio: {}, \
             ground_participation: {}, interface_shape: {} }},",
            lit(m.omega_rad_s),
            lit(m.damping_ratio),
            lit(m.ground_participation),
            lit(m.interface_shape)
        );
    }
    modes.push(']');
    let correction = |c: &rths_core::metamodel::StaticCorrection| {
        format!(
            "rths_core::metamodel::StaticCorrection {{ ground_mm_per_mm_s2: {}, force_mm_per_kn: {} }}",
            lit(c.ground_mm_per_mm_s2),
            lit(c.force_mm_per_kn)
        )
    };
    let mut outputs = String::from("&[");
    for c in spec.output_static {
        let _ = write!(outputs, "{},", correction(c));
    }
    outputs.push(']');
    let expr = format!(
        "rths_core::model::ModelSpec::StructureReduced {{ model: rths_core::control::ReducedSpec {{ \
         modes: {modes}, output_shape: &{}, interface_static: {}, output_static: {outputs}, \
         specimen_k_kn_per_mm: {} }} }}",
        array(spec.output_shape),
        correction(&spec.interface_static),
        lit(spec.specimen_k_kn_per_mm)
    );
    (expr, f)
}

/// The `ModelSpec` of one structure path: `fe`, `nl`, `meta` or `modal` (`model`: the metamodel
/// file of `meta` and `modal`).
fn structure_model_spec(path: &Path, kind: &str, model: Option<&Path>) -> String {
    let s = load_structure(path);
    let meta = model;
    match kind {
        "fe" => format!(
            "rths_core::model::ModelSpec::StructureFe {{ structure: {} }}",
            structure_spec(&s, false, path)
        ),
        "nl" => format!(
            "rths_core::model::ModelSpec::StructureNl {{ structure: {} }}",
            structure_spec(&s, true, path)
        ),
        "modal" => {
            let m = model.unwrap_or_else(|| fail(format!("{}: no model file", path.display())));
            modal_spec(path, m)
        }
        _ => {
            let m = meta.unwrap_or_else(|| fail(format!("{}: no metamodel file", path.display())));
            let p = load_meta(m, &s);
            format!(
                "rths_core::model::ModelSpec::StructureMeta {{ theta: &{}, k_corr_kn_per_mm: {} }}",
                array(p.theta()),
                lit(p.k_corr_kn_per_mm())
            )
        }
    }
}

/// A build that runs one structure (`structure-fe`, `structure-nl`, `structure-meta`,
/// `structure-modal`).
fn structure(out: &mut String, kind: &str) {
    println!("cargo:rerun-if-env-changed=RTHS_STRUCTURE");
    println!("cargo:rerun-if-env-changed=RTHS_STRUCTURE_MODEL");
    let path = std::env::var_os("RTHS_STRUCTURE")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            fail(
                "a structure build needs RTHS_STRUCTURE=path (a structure file, data/structures/)"
                    .into(),
            )
        });
    let meta = std::env::var_os("RTHS_STRUCTURE_MODEL").map(PathBuf::from);
    if kind == "meta" && meta.is_none() {
        fail(format!(
            "structure-meta needs RTHS_STRUCTURE_MODEL=path: train it with `cargo run --release \
             --features sim -- train meta --structure {} --rate {} --out M.json`",
            path.display(),
            rate_hz()
        ));
    }
    if kind == "modal" && meta.is_none() {
        fail(format!(
            "structure-modal needs RTHS_STRUCTURE_MODEL=path: an rths-nl-model file trained with \
             `cargo run --release --features sim -- train nonlinear --structure {} --out M.json`",
            path.display()
        ));
    }
    let reduced = kind == "meta"
        && meta
            .as_deref()
            .is_some_and(|m| ReducedModelFile::is_reduced(&read(m)));
    let spec = match meta.as_deref() {
        // An imported structure's reduced-order model: the model file carries the whole part.
        Some(m) if reduced => reduced_spec(m, Some(&path)).0,
        _ => structure_model_spec(&path, kind, meta.as_deref()),
    };
    let _ = writeln!(out, "/// The structure (and model) compiled in.");
    let _ = writeln!(
        out,
        "pub const STRUCTURE_SPEC: rths_core::model::ModelSpec<'static> = {spec};"
    );
    let source = match &meta {
        Some(m) if kind == "meta" || kind == "modal" => {
            format!("{} ({})", path.display(), m.display())
        }
        _ => path.display().to_string(),
    };
    let _ = writeln!(out, "/// The model file compiled in.");
    let _ = writeln!(out, "pub const MODEL_SOURCE: &str = {source:?};");
}

/// A comma-separated list of three files from `var`, or the defaults `dir/<name>.json`.
fn three(var: &str, dir: &Path, default: [&str; 3]) -> Vec<PathBuf> {
    println!("cargo:rerun-if-env-changed={var}");
    let v: Vec<PathBuf> = match std::env::var(var) {
        Ok(list) => list.split(',').map(PathBuf::from).collect(),
        Err(_) => default
            .iter()
            .map(|n| dir.join(format!("{n}.json")))
            .collect(),
    };
    if v.len() != 3 {
        fail(format!("{var}: three files (N = 1, 3, 8), got {}", v.len()));
    }
    v
}

/// The budget build (`budget-structures`): the twelve controllers it steps.
fn budget_structures(out: &mut String, root: &Path) {
    let dir = root.join("data/structures");
    let linear = three(
        "RTHS_BUDGET_LINEAR",
        &dir,
        ["paper-frame", "vrths-case1", "shear8"],
    );
    let yielding = three(
        "RTHS_BUDGET_YIELDING",
        &dir,
        ["paper-frame-yielding", "shear3-yielding", "shear8-yielding"],
    );
    println!("cargo:rerun-if-env-changed=RTHS_BUDGET_METAS");
    let metas: Vec<PathBuf> = std::env::var("RTHS_BUDGET_METAS")
        .unwrap_or_else(|_| {
            fail(format!(
                "budget-structures needs RTHS_BUDGET_METAS=m1,m3,m8: the metamodels of {} at {} Hz \
                 (`rths train meta --structure FILE --rate {}`; budget.sh trains them)",
                linear
                    .iter()
                    .map(|p| p.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", "),
                rate_hz(),
                rate_hz()
            ))
        })
        .split(',')
        .map(PathBuf::from)
        .collect();
    if metas.len() != 3 {
        fail(format!(
            "RTHS_BUDGET_METAS: three files, got {}",
            metas.len()
        ));
    }
    let modals = three(
        "RTHS_BUDGET_MODALS",
        &root.join("data/models"),
        [
            "nl-paper-frame-yielding",
            "nl-shear3-yielding",
            "nl-shear8-yielding",
        ],
    );
    let mut rows = String::new();
    for (kind, files, models) in [
        ("fe", &linear, None),
        ("nl", &yielding, None),
        ("meta", &linear, Some(&metas)),
        ("modal", &yielding, Some(&modals)),
    ] {
        for (i, path) in files.iter().enumerate() {
            let s = load_structure(path);
            let model = models.and_then(|m| m.get(i)).map(PathBuf::as_path);
            let spec = structure_model_spec(path, kind, model);
            let path_name = match kind {
                "fe" => "structure-fe",
                "nl" => "structure-nl",
                "meta" => "structure-meta",
                _ => "structure-modal",
            };
            // The specimen's stiffness: the budget's ideal rig holds it (analytical.rs).
            let (_, k_e, _) = s.specimen();
            // One constant spec per row, assembled by its own function: `assemble` is folded to
            // that spec's arm (its generic form inlined holds every arm's parts on the stack).
            let id = rows.matches("BudgetRow").count();
            let _ = writeln!(
                out,
                "const BUDGET_SPEC_{id}: rths_core::model::ModelSpec<'static> = {spec};"
            );
            let _ = writeln!(
                rows,
                "    crate::analytical::BudgetRow {{ path: {path_name:?}, structure: {:?}, dofs: {}, \
                 specimen_kn_per_mm: {}, modes: 0, build: || rths_core::model::assemble(\
                 &BUDGET_SPEC_{id}, rths_core::params::Prototype::paper(), rths_core::params::DT_S) }},",
                s.name(),
                s.dofs(),
                lit(k_e)
            );
        }
    }
    // The imported structures' reduced-order models (N ≈ 10, 100, 1,000 DOFs with mass).
    println!("cargo:rerun-if-env-changed=RTHS_BUDGET_REDUCED");
    let reduced: Vec<PathBuf> = std::env::var("RTHS_BUDGET_REDUCED")
        .map(|l| l.split(',').map(PathBuf::from).collect())
        .unwrap_or_default();
    for m in &reduced {
        let (spec, f) = reduced_spec(m, None);
        let id = rows.matches("BudgetRow").count();
        let _ = writeln!(
            out,
            "const BUDGET_SPEC_{id}: rths_core::model::ModelSpec<'static> = {spec};"
        );
        let _ = writeln!(
            rows,
            "    crate::analytical::BudgetRow {{ path: \"structure-reduced\", structure: {:?}, \
             dofs: {}, specimen_kn_per_mm: {}, modes: {}, build: || rths_core::model::assemble(\
             &BUDGET_SPEC_{id}, rths_core::params::Prototype::paper(), rths_core::params::DT_S) }},",
            f.structure,
            f.mass_dofs,
            lit(f.specimen_k_kn_per_mm),
            f.modes.len()
        );
    }
    let n_rows = rows.matches("BudgetRow").count();
    let _ = writeln!(
        out,
        "/// The budget's controllers: twelve, and the reduced models of `RTHS_BUDGET_REDUCED`."
    );
    let _ = writeln!(
        out,
        "pub const BUDGET_ROWS: [crate::analytical::BudgetRow; {n_rows}] = [\n{rows}];"
    );
    let _ = writeln!(out, "/// The model file compiled in.");
    let _ = writeln!(
        out,
        "pub const MODEL_SOURCE: &str = \"budget: FE linear, FE yielding, metamodel, modal metamodel; N = 1, 3, 8; reduced models\";"
    );
}

/// The identification excitation's tables (every image with the link; `rths link ... identify`): one period of
/// the unit multisine and the ramp's cosines, computed by rths-core with std's cosines exactly as
/// `rths identify` computes them, written as little-endian f64 for `include_bytes!` (flash), with
/// the unit period's stats. Without the link: empty tables (nothing could ask for them).
fn excitation(out: &mut String, out_dir: &Path) {
    use rths_core::identify_excitation::{ExcitationConfig, StdTables};
    let (unit, ramp, peak, rate) = if std::env::var_os("CARGO_FEATURE_LINK").is_some() {
        let t = StdTables::new(&ExcitationConfig::new(dt_s(rate_hz())))
            .unwrap_or_else(|e| fail(format!("identification excitation: {e}")));
        (t.unit, t.ramp_cos, t.stats.peak, t.stats.peak_rate_per_s)
    } else {
        (Vec::new(), Vec::new(), 0.0, 0.0)
    };
    for (name, v) in [
        ("excitation_unit.bin", &unit),
        ("excitation_ramp.bin", &ramp),
    ] {
        let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        std::fs::write(out_dir.join(name), bytes)
            .unwrap_or_else(|e| fail(format!("cannot write {name}: {e}")));
    }
    let _ = writeln!(
        out,
        "/// One period of the identification's unit multisine (f64 LE)."
    );
    let _ = writeln!(
        out,
        "pub static EXCITATION_UNIT: &[u8] = include_bytes!(concat!(env!(\"OUT_DIR\"), \"/excitation_unit.bin\"));"
    );
    let _ = writeln!(out, "/// The ramps' cosines (f64 LE).");
    let _ = writeln!(
        out,
        "pub static EXCITATION_RAMP: &[u8] = include_bytes!(concat!(env!(\"OUT_DIR\"), \"/excitation_ramp.bin\"));"
    );
    let _ = writeln!(out, "/// The unit period's peak and peak rate, 1/s.");
    let _ = writeln!(out, "pub const EXCITATION_PEAK: f64 = {};", lit(peak));
    let _ = writeln!(out, "/// The unit period's peak rate, 1/s.");
    let _ = writeln!(out, "pub const EXCITATION_PEAK_RATE: f64 = {};", lit(rate));
}

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    let root = manifest
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| fail("no parent of the firmware directory".into()));
    let out_dir = PathBuf::from(std::env::var("OUT_DIR").unwrap_or_default());

    // The board's core must match the code generated for it: the M7 boards need `-C
    // target-cpu=cortex-m7` (hardware f64), which `cargo build-m7` passes; an M4 board must not get it.
    let mps2 = std::env::var_os("CARGO_FEATURE_BOARD_MPS2_AN500").is_some();
    let h743 = std::env::var_os("CARGO_FEATURE_BOARD_STM32H743").is_some();
    let m7_board = mps2 || h743;
    let flags = std::env::var("CARGO_ENCODED_RUSTFLAGS").unwrap_or_default();
    let m7_code = flags
        .split('\u{1f}')
        .any(|f| f.contains("target-cpu=cortex-m7"));
    if m7_board && !m7_code {
        fail("a Cortex-M7 board is built with `cargo build-m7` (-C target-cpu=cortex-m7, hardware f64); see firmware/.cargo/config.toml".into());
    }
    if !m7_board && m7_code {
        fail("-C target-cpu=cortex-m7 given for a Cortex-M4 board (the F405/F407 have no double-precision FPU)".into());
    }
    println!("cargo:rerun-if-env-changed=CARGO_ENCODED_RUSTFLAGS");

    // cortex-m-rt's link.x includes memory.x from the linker search path: the board's memory map
    // (the root memory.x serves both STM32F405/407 boards).
    let mem_file = if mps2 {
        root.join("boards/mps2-an500/memory.x")
    } else if h743 {
        root.join("boards/stm32h743/memory.x")
    } else {
        root.join("memory.x")
    };
    let mut mem = read(&mem_file);
    if std::env::var_os("CARGO_FEATURE_BUDGET_STRUCTURES").is_some() {
        // The structure budget builds its twelve controllers one after the other on the stack
        // (each ~45 KB with its compensator's storage, twice while one is assembled): on the
        // emulated M7 it maps 512 KiB of the MPS2's 4 MiB SSRAM2/3. The controllers themselves
        // are unchanged; a structure build (`structure-*`) keeps the board's 128 KiB.
        if !mps2 {
            fail("budget-structures runs on the emulated Cortex-M7 (board-mps2-an500)".into());
        }
        mem = mem.replace("LENGTH = 128K", "LENGTH = 512K");
    }
    std::fs::write(out_dir.join("memory.x"), mem)
        .unwrap_or_else(|e| fail(format!("cannot write memory.x: {e}")));
    println!("cargo:rustc-link-search={}", out_dir.display());

    let mut gen = String::from("// Generated by build.rs: the model and the ground motion.\n");
    let rnn_on = std::env::var_os("CARGO_FEATURE_MODEL_RNN").is_some();
    let fe_on = std::env::var_os("CARGO_FEATURE_FE_ATS").is_some();
    let lrx_on = std::env::var_os("CARGO_FEATURE_MODEL_LRX").is_some();
    let structure_kind = [
        ("CARGO_FEATURE_STRUCTURE_FE", "fe"),
        ("CARGO_FEATURE_STRUCTURE_NL", "nl"),
        ("CARGO_FEATURE_STRUCTURE_META", "meta"),
        ("CARGO_FEATURE_STRUCTURE_MODAL", "modal"),
    ]
    .into_iter()
    .find(|(f, _)| std::env::var_os(f).is_some())
    .map(|(_, k)| k);
    if std::env::var_os("CARGO_FEATURE_BUDGET_STRUCTURES").is_some() {
        budget_structures(&mut gen, &root);
    } else if let Some(kind) = structure_kind {
        structure(&mut gen, kind);
    } else if rnn_on {
        rnn(&mut gen, &root);
    } else if fe_on {
        gen.push_str("/// The model compiled in.\npub const MODEL_SOURCE: &str = \"finite elements (Chang) + ATS\";\n");
    } else if lrx_on {
        lrx(&mut gen, &root);
    } else {
        lr(&mut gen, &root);
    }
    motion(&mut gen, &root);
    excitation(&mut gen, &out_dir);
    // Only a fault-inject build has a fault plan (and the simulated rig its constants name).
    if std::env::var_os("CARGO_FEATURE_FAULT_INJECT").is_some() {
        fault(&mut gen);
    }
    std::fs::write(out_dir.join("gen.rs"), gen)
        .unwrap_or_else(|e| fail(format!("cannot write gen.rs: {e}")));
    println!("cargo:rerun-if-changed=build.rs");
}

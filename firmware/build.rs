//! Compiles the image's default model, the ground motion and the identification's tables into the
//! firmware. The image is one per board: it runs any model kind, uploaded over the link or
//! compiled in as its default; the default is data, laid out here with the link's own layout
//! (`rths_files::upload`, `rths_link::layout`) and installed at boot through the path an upload
//! takes (`rths_app::model_upload::install`).
//!
//! - `RTHS_MODEL=path`: the default model, a model file of any kind (default `../data/models/lr.json`,
//!   the model `rths reproduce` trains; `lr-4096.json` at 4096 Hz), or `fe-ats` (the paper's finite
//!   elements with the ATS starting from the paper's delay). An LR, RNN or LRX file is refused if
//!   trained at another rate than the build's (its `dt_s`); an LRX's lead adaptation and specimen
//!   dynamics, if it has them, are compiled in as its rig compensation, as an upload sends them.
//! - `RTHS_STRUCTURE=path`: a structure file (`data/structures/`). Alone: its finite elements
//!   (linear, or its yielding stories). With `RTHS_MODEL`: that structure's model: its structure
//!   metamodel (`rths train meta`, refused if trained for another structure or rate), its
//!   modal-hysteretic model (`rths train nonlinear`, any rate), or, for an imported structure
//!   (`rths import opensees`), its reduced model (`rths train meta`; refused if trained for a
//!   structure of another name or at another rate). A rig compensation goes over the link (`rths
//!   link upload --rig`).
//! - A default the board's tick cannot run is refused for a real board (the STM32F407: RNN-10,
//!   FE + ATS at 4096 Hz), with the estimate of `rths_app::tick_cost` (the budget's measured
//!   figures), as an upload is refused `TickBudget`; an emulated board builds it, to measure it.
//! - `RTHS_BUDGET=structures`: the structure budget (docs/firmware.md): the image steps each of its
//!   controllers through the whole record on an ideal rig at boot and exits (an emulated board).
//!   Its structures: FE linear, FE yielding, the structure metamodel and the modal-hysteretic
//!   metamodel for N = 1, 3, 8: `RTHS_BUDGET_LINEAR`, `RTHS_BUDGET_YIELDING` (three structure
//!   files each, comma-separated; default `paper-frame,vrths-case1,shear8` and
//!   `paper-frame-yielding,shear3-yielding,shear8-yielding` in `data/structures/`),
//!   `RTHS_BUDGET_METAS` (the linear ones' metamodels at this build's rate, required: `budget.sh`
//!   trains them), `RTHS_BUDGET_MODALS` (the yielding ones' modal models; default `nl-S.json` in
//!   `data/models/`), `RTHS_BUDGET_REDUCED` (reduced models of imported structures,
//!   comma-separated: `budget.sh` trains them; without it the budget has no reduced rows),
//!   `RTHS_BUDGET_HYSTERONS` (floor-hysteron models, their floors in them, comma-separated;
//!   default `data/models/nl-fiber-frame-hysteron.json`, trained from OpenSees runs). The modal,
//!   reduced and floor-hysteron models run a second time with a rig compensation (`nl-online`,
//!   `meta-online`: the lead of `data/models/lrx.json` with its adaptation, a force correction and
//!   the budget's scale), what it adds per tick.
//! - The El Centro record `../data/ground_motions/IELC180.AT2` (values in g), embedded as f64 exactly
//!   as the host parses it.
//!
//! The files are read by the host's own readers (`rths-files`), checked as the host commands check
//! them; a bad file fails the build with a message naming the file and the problem.
//!
//! The rate (`rate-4096`): the record's ticks and the fault plan's start follow it; the default model
//! file becomes `lr-4096.json`. The board's core: a Cortex-M7 board needs `-C target-cpu=cortex-m7`
//! (`cargo build-m7`), a Cortex-M4 board must not have it.
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rths_app::tick_cost::TickBudget;
use rths_core::params::{dt_s, CONTROL_RATES_HZ, FORCE_SCALE, PAPER_DELAY_STEPS};
use rths_files::motion::parse_at2;
use rths_files::reduced_model_file::ReducedModelFile;
use rths_files::structure_file::Structure;
use rths_files::upload::{lay_out_files, LaidOut};
use rths_link::layout::{self, MODEL_MAX_VALUES};

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

/// The board's tick, as an upload is checked against it (`rths_app::tick_cost`).
fn tick_budget(m7: bool) -> TickBudget {
    let rate = f64::from(rate_hz());
    if m7 {
        TickBudget::cortex_m7_480mhz(rate)
    } else {
        TickBudget::cortex_m4_168mhz(rate)
    }
}

/// The image's default model: `RTHS_MODEL` (a model file, or `fe-ats`) and `RTHS_STRUCTURE`, laid
/// out for the link; and where it came from.
fn default_model(root: &Path) -> (LaidOut, String) {
    println!("cargo:rerun-if-env-changed=RTHS_MODEL");
    println!("cargo:rerun-if-env-changed=RTHS_STRUCTURE");
    let model = std::env::var_os("RTHS_MODEL").map(PathBuf::from);
    let structure = std::env::var_os("RTHS_STRUCTURE").map(PathBuf::from);
    let dt = dt_s(rate_hz());
    if model.as_deref() == Some(Path::new("fe-ats")) {
        if structure.is_some() {
            fail("RTHS_MODEL=fe-ats is the paper's frame: no RTHS_STRUCTURE".into());
        }
        let delay_s = PAPER_DELAY_STEPS as f64 * dt;
        let spec = rths_core::model::ModelSpec::FeAts {
            expected_delay_s: delay_s,
        };
        let mut v = vec![0.0; MODEL_MAX_VALUES];
        let (kind, n) =
            layout::lay_out(&spec, &mut v).unwrap_or_else(|e| fail(format!("fe-ats: {e:?}")));
        v.truncate(n);
        let laid = LaidOut {
            kind,
            values: v,
            delay_steps: 0,
            rig: None,
            trained_dt_s: None,
            specimen_k_kn_per_mm: None,
            what: "finite elements (Chang) + ATS".into(),
        };
        return (laid, "finite elements (Chang) + ATS".into());
    }
    let model = match (model, &structure) {
        (Some(m), _) => Some(m),
        (None, Some(_)) => None,
        (None, None) => Some(if rate_hz() == CONTROL_RATES_HZ[0] {
            root.join("data/models/lr.json")
        } else {
            root.join(format!("data/models/lr-{}.json", rate_hz()))
        }),
    };
    for p in model.iter().chain(&structure) {
        println!("cargo:rerun-if-changed={}", p.display());
        if !p.exists() {
            let features = if rate_hz() == CONTROL_RATES_HZ[0] {
                "sim"
            } else {
                "sim,rate-4096"
            };
            fail(format!(
                "{}: no such file: a model file trained at {} Hz (`cargo run --release --features \
                 {features} -- train ... --out FILE`), or point RTHS_MODEL at one",
                p.display(),
                rate_hz()
            ));
        }
    }
    let laid = lay_out_files(model.as_deref(), structure.as_deref(), dt)
        .unwrap_or_else(|e| fail(e.to_string()));
    // A metamodel's coefficients are per tick: it runs only at the rate it was trained at.
    if let (Some(trained), Some(m)) = (laid.trained_dt_s, &model) {
        let rate = rate_hz();
        if trained.to_bits() != dt.to_bits() {
            fail(format!(
                "{}: the model was trained at {:.0} Hz (dt_s = {trained}), this build runs at {rate} \
                 Hz: train one at {rate} Hz (`cargo run --release --features sim{} -- train ...`) \
                 and point the build at it",
                m.display(),
                1.0 / trained,
                if rate == CONTROL_RATES_HZ[0] { "" } else { ",rate-4096" }
            ));
        }
    }
    let source = match (&model, &structure) {
        (Some(m), Some(s)) => format!("{} ({})", s.display(), m.display()),
        (Some(m), None) => m.display().to_string(),
        (None, Some(s)) => s.display().to_string(),
        (None, None) => String::new(),
    };
    (laid, source)
}

/// The default, refused for a real board whose tick cannot run it (an emulated board builds it, to
/// measure it), and written as data: its kind, values, delay and rig compensation.
fn write_default(out: &mut String, root: &Path, m7: bool, real_board: bool) {
    let (laid, source) = default_model(root);
    let dims =
        layout::dims(laid.kind, &laid.values).unwrap_or_else(|e| fail(format!("{source}: {e:?}")));
    let budget = tick_budget(m7);
    let instr = budget.instr_dims(laid.kind, &dims);
    if instr > budget.instr_per_tick() {
        let named = if source == laid.what {
            source.clone()
        } else {
            format!("{source} ({})", laid.what)
        };
        let why = format!(
            "the default model {named} does not fit this board's tick: about {instr:.0} \
             instructions per tick estimated from the measured budget, {:.0} % of the {} Hz tick \
             at {:.0} MHz (docs/firmware.md, the budget table)",
            budget.pct_of_tick_dims(laid.kind, &dims),
            rate_hz(),
            budget.clock_hz / 1e6
        );
        if real_board {
            fail(format!(
                "{why}: build it for a Cortex-M7 board, at 2048 Hz, or upload a model this board \
                 runs (an upload it cannot run is refused TickBudget)"
            ));
        }
        println!("cargo:warning={why}; the emulated board builds it to measure it");
    }
    let _ = writeln!(
        out,
        "/// The default model's kind (`RTHS_MODEL`, `RTHS_STRUCTURE`)."
    );
    let _ = writeln!(
        out,
        "pub const DEFAULT_KIND: rths_link::ModelKind = rths_link::ModelKind::{:?};",
        laid.kind
    );
    let _ = writeln!(
        out,
        "/// Its values, in the link's layout (`rths_link::layout`)."
    );
    let _ = writeln!(
        out,
        "pub static DEFAULT_VALUES: [f64; {}] = {};",
        laid.values.len(),
        array(&laid.values)
    );
    let _ = writeln!(
        out,
        "/// Its feedback delay, ticks (its checksum covers it)."
    );
    let _ = writeln!(out, "pub const DEFAULT_DELAY: u16 = {};", laid.delay_steps);
    let rig = laid.rig.unwrap_or_default();
    let _ = writeln!(
        out,
        "/// The rig compensation its file carries (empty: none), `rths_link::rig_value_count`'s layout."
    );
    let _ = writeln!(
        out,
        "pub static DEFAULT_RIG: [f64; {}] = {};",
        rig.len(),
        array(&rig)
    );
    let _ = writeln!(out, "/// The model file compiled in.");
    let _ = writeln!(out, "pub const MODEL_SOURCE: &str = {source:?};");
}

/// The structure budget's rows (`RTHS_BUDGET=structures`), or none.
fn budget_structures(out: &mut String, root: &Path, emulated: bool) {
    println!("cargo:rerun-if-env-changed=RTHS_BUDGET");
    let mut rows = String::new();
    let mut n_rows = 0usize;
    let on = match std::env::var("RTHS_BUDGET") {
        Ok(v) if v == "structures" => true,
        Ok(v) => fail(format!("RTHS_BUDGET={v}: the one budget is `structures`")),
        Err(_) => false,
    };
    if on && !emulated {
        fail(
            "RTHS_BUDGET=structures runs on an emulated board (its ideal rig and its exit)".into(),
        );
    }
    if on {
        budget_rows(out, &mut rows, &mut n_rows, root);
    }
    let _ = writeln!(
        out,
        "/// The structure budget's controllers (`RTHS_BUDGET=structures`; empty: a normal image)."
    );
    let _ = writeln!(
        out,
        "pub static BUDGET_ROWS: [crate::analytical::BudgetRow; {n_rows}] = [\n{rows}];"
    );
}

/// The structure budget's displacement scale (prototype over actuator): the structures' floors
/// move tens of mm under El Centro ×1, the actuator a tenth of it (inside the supervisor's stroke,
/// velocity and force limits, so every controller stays `Running` the whole record).
const BUDGET_DISP_SCALE: f64 = 10.0;

/// One row: its values and rig compensation as statics, the row itself into `rows`.
#[allow(clippy::too_many_arguments)]
fn budget_row(
    out: &mut String,
    rows: &mut String,
    n: &mut usize,
    path: &str,
    structure: &str,
    dofs: usize,
    modes: usize,
    specimen_k: f64,
    laid: &LaidOut,
    rig: &[f64],
) {
    let id = *n;
    let _ = writeln!(
        out,
        "static BUDGET_VALUES_{id}: [f64; {}] = {};",
        laid.values.len(),
        array(&laid.values)
    );
    let _ = writeln!(
        out,
        "static BUDGET_RIG_{id}: [f64; {}] = {};",
        rig.len(),
        array(rig)
    );
    let _ = writeln!(
        rows,
        "    crate::analytical::BudgetRow {{ path: {path:?}, structure: {structure:?}, dofs: {dofs}, \
         modes: {modes}, specimen_kn_per_mm: {}, kind: rths_link::ModelKind::{:?}, \
         values: &BUDGET_VALUES_{id}, rig: &BUDGET_RIG_{id} }},",
        lit(specimen_k),
        laid.kind
    );
    *n += 1;
}

/// The budget's rig compensation for a part whose ideal rig holds `specimen_k` (kN/mm, prototype):
/// the lead of `data/models/lrx.json` with the host's adaptation (`rths train lrx --rig`'s 4096
/// ticks), a force correction by the rig's specimen (the ideal rig's: it removes the lead's effect
/// from the force, so the part runs as without it), the budget's scale.
fn budget_rig(root: &Path, specimen_k: f64) -> Vec<f64> {
    let path = root.join("data/models/lrx.json");
    println!("cargo:rerun-if-changed={}", path.display());
    let m = rths_files::model_file::ModelFile::load(&path)
        .unwrap_or_else(|e| fail(format!("{}: {e}", path.display())));
    let x = m
        .lrx
        .unwrap_or_else(|| fail(format!("{}: no lrx section", path.display())));
    let rig_k = specimen_k * BUDGET_DISP_SCALE / FORCE_SCALE;
    layout::structure_rig_values(
        &x.lead_weights,
        x.lead_stride,
        4096.0,
        [rig_k, 0.0, 0.0],
        [BUDGET_DISP_SCALE, FORCE_SCALE],
    )
    .unwrap_or_else(|| fail(format!("{}: 8 lead weights", path.display())))
    .to_vec()
}

fn budget_rows(out: &mut String, rows: &mut String, n: &mut usize, root: &Path) {
    let dir = root.join("data/structures");
    let dt = dt_s(rate_hz());
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
                "RTHS_BUDGET=structures needs RTHS_BUDGET_METAS=m1,m3,m8: the metamodels of {} at {} \
                 Hz (`rths train meta --structure FILE --rate {}`; budget.sh trains them)",
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
    for (path_name, files, models) in [
        ("structure-fe", &linear, None),
        ("structure-nl", &yielding, None),
        ("structure-meta", &linear, Some(&metas)),
        ("structure-modal", &yielding, Some(&modals)),
    ] {
        for (i, s) in files.iter().enumerate() {
            println!("cargo:rerun-if-changed={}", s.display());
            let structure =
                Structure::load(s).unwrap_or_else(|e| fail(format!("{}: {e}", s.display())));
            let model = models.and_then(|m| m.get(i)).map(PathBuf::as_path);
            if let Some(m) = model {
                println!("cargo:rerun-if-changed={}", m.display());
            }
            let laid = lay_out_files(model, Some(s), dt).unwrap_or_else(|e| fail(e.to_string()));
            // The specimen's stiffness: the budget's ideal rig holds it (analytical.rs).
            let (_, k_e, _) = structure.specimen();
            let (name, dofs) = (structure.name(), structure.dofs());
            budget_row(out, rows, n, path_name, name, dofs, 0, k_e, &laid, &[]);
            if path_name == "structure-modal" {
                let rig = budget_rig(root, k_e);
                budget_row(out, rows, n, "nl-online", name, dofs, 0, k_e, &laid, &rig);
            }
        }
    }
    // The imported structures' reduced-order models (N ≈ 10, 100, 1,000 DOFs with mass); the rows
    // name no structure file: the model carries its whole part.
    println!("cargo:rerun-if-env-changed=RTHS_BUDGET_REDUCED");
    let reduced: Vec<PathBuf> = std::env::var("RTHS_BUDGET_REDUCED")
        .map(|l| l.split(',').map(PathBuf::from).collect())
        .unwrap_or_default();
    for m in &reduced {
        let f = ReducedModelFile::from_json(&read(m))
            .unwrap_or_else(|e| fail(format!("{}: {e}", m.display())));
        // Trained at this build's rate, as an upload or a default must be (the rows name no
        // structure file, so the name check is not made).
        f.check_rate(dt)
            .unwrap_or_else(|e| fail(format!("{}: {e}", m.display())));
        let arrays = f
            .arrays()
            .unwrap_or_else(|e| fail(format!("{}: {e}", m.display())));
        let spec = arrays.spec();
        spec.params(dt)
            .unwrap_or_else(|e| fail(format!("{}: {e}", m.display())));
        let mut v = vec![0.0; MODEL_MAX_VALUES];
        let (kind, len) = layout::lay_out(
            &rths_core::model::ModelSpec::StructureReduced { model: spec },
            &mut v,
        )
        .unwrap_or_else(|e| fail(format!("{}: {e:?}", m.display())));
        v.truncate(len);
        let laid = LaidOut {
            kind,
            values: v,
            delay_steps: 0,
            rig: None,
            trained_dt_s: None,
            specimen_k_kn_per_mm: Some(f.specimen_k_kn_per_mm),
            what: format!("reduced model of {}", f.structure),
        };
        let k = f.specimen_k_kn_per_mm;
        let modes = f.modes.len();
        let name = f.structure.as_str();
        budget_row(
            out,
            rows,
            n,
            "structure-reduced",
            name,
            f.mass_dofs,
            modes,
            k,
            &laid,
            &[],
        );
        let rig = budget_rig(root, k);
        budget_row(
            out,
            rows,
            n,
            "meta-online",
            name,
            f.mass_dofs,
            modes,
            k,
            &laid,
            &rig,
        );
    }
    // The floor-hysteron models (rate-independent: any build's rate), laid out alone as `rths
    // link upload --model` lays them out; N is the floors.
    println!("cargo:rerun-if-env-changed=RTHS_BUDGET_HYSTERONS");
    let hysterons: Vec<PathBuf> = std::env::var("RTHS_BUDGET_HYSTERONS")
        .map(|l| l.split(',').map(PathBuf::from).collect())
        .unwrap_or_else(|_| vec![root.join("data/models/nl-fiber-frame-hysteron.json")]);
    for m in &hysterons {
        println!("cargo:rerun-if-changed={}", m.display());
        let f = rths_files::hysteron_model_file::HysteronModelFile::from_json(&read(m))
            .unwrap_or_else(|e| fail(format!("{}: {e}", m.display())));
        let laid = lay_out_files(Some(m), None, dt).unwrap_or_else(|e| fail(e.to_string()));
        let k = f.specimen_stiffness_kn_per_mm;
        let (name, floors) = (f.structure.name.as_str(), f.floors.len());
        budget_row(
            out,
            rows,
            n,
            "structure-hysteron",
            name,
            floors,
            0,
            k,
            &laid,
            &[],
        );
        let rig = budget_rig(root, k);
        budget_row(out, rows, n, "nl-online", name, floors, 0, k, &laid, &rig);
    }
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

fn read(path: &Path) -> String {
    println!("cargo:rerun-if-changed={}", path.display());
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| fail(format!("cannot read {}: {e}", path.display())))
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
    let f407 = std::env::var_os("CARGO_FEATURE_BOARD_STM32F4").is_some();
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
    let mem = read(&mem_file);
    std::fs::write(out_dir.join("memory.x"), mem)
        .unwrap_or_else(|e| fail(format!("cannot write memory.x: {e}")));
    println!("cargo:rustc-link-search={}", out_dir.display());

    let mut gen =
        String::from("// Generated by build.rs: the default model and the ground motion.\n");
    let real_board = f407 || h743;
    write_default(&mut gen, &root, m7_board, real_board);
    budget_structures(&mut gen, &root, !real_board);
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

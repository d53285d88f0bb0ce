//! An imported OpenSees structure in the hybrid loop (`rths simulate --structure S.json --scenario
//! meta-online|fe-online-ats`): its reduced model, and its host FE by operator splitting, on the
//! virtual rig of both presets, the benchmark's uncertainty and a rig file: the run is stable and
//! its J4 (the measured interface against the whole model with the rig's true specimen) small;
//! the history has the pure scenarios' columns; bad input is refused with the reason. With a
//! perfect rig the host FE's hybrid loop is its pure loop bit for bit. Cheap in debug: the 72-DOF
//! frame and 4 s of El Centro.
#![cfg(feature = "sim")]

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use rths::machinery::drive::{self, HostPlant};
use rths::machinery::imported::split::{self, OperatorSplitting};
use rths::machinery::imported::ImportedStructure;
use rths::machinery::imported::{fe, reduced};
use rths_core::compensator::Compensator;
use rths_core::control::{
    Analytical, ControlConfig, Controller, FeedbackSource, HostNumerical, StepError, StructureHost,
};
use rths_core::hal::{Actuator, Daq, ErrorKind, Sample};
use rths_core::params::{Prototype, SpecimenScale, DT_S};
use rths_core::supervisor::{Limits, State};
use rths_files::motion::GroundMotion;

const SMALL: &str = "data/structures/opensees-frame-2x3.json";
/// The test's bound on J4, %: the release runs measure 1.0-1.4 % on this frame (docs/opensees.md).
const J4_BOUND_PCT: f64 = 3.0;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn rths(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rths"))
        .current_dir(root())
        .args(args)
        .output()
        .expect("the binary runs")
}

/// A model of the small frame (`rths train meta`'s training), and 4 s of El
/// Centro as a CSV record, in `dir`: (model, record).
fn inputs(dir: &Path) -> (String, String) {
    let s = ImportedStructure::load(&root().join(SMALL)).expect("the shipped frame loads");
    // The whole training records: a model chosen on 2 s of each keeps other modes, and on the
    // benchmark preset that loop trips the command-velocity interlock at 0.15 s
    // (docs/opensees.md, "Not yet done").
    let records = reduced::training_records(DT_S).expect("embedded");
    let file = reduced::train(&s, &records, DT_S, |_, _, _| {}).expect("training");
    let model = dir.join("m.json");
    std::fs::write(&model, file.to_json().expect("json")).expect("write model");
    (model.display().to_string(), inputs_record(dir))
}

/// 4 s of El Centro as a CSV record in `dir`: its path.
fn inputs_record(dir: &Path) -> String {
    let m = GroundMotion::embedded("el-centro").expect("embedded");
    let n = (4.0 / m.dt_s) as usize;
    let mut csv = String::from("time_s,accel_g\n");
    for (k, a) in m.accel_g.iter().take(n).enumerate() {
        csv.push_str(&format!("{},{a}\n", k as f64 * m.dt_s));
    }
    let record = dir.join("el-centro-4s.csv");
    std::fs::write(&record, csv).expect("write record");
    record.display().to_string()
}

fn json(args: &[&str]) -> serde_json::Value {
    let out = rths(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

#[test]
fn meta_online_is_stable_and_tracks_on_both_presets_the_uncertainty_and_a_rig_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (model, record) = inputs(dir.path());
    let out = dir.path().join("run");
    let base = [
        "simulate",
        "--structure",
        SMALL,
        "--scenario",
        "meta-online",
        "--model",
        &model,
        "--motion",
        &record,
    ];
    let run = |extra: &[&str]| {
        let mut a: Vec<&str> = base.to_vec();
        a.extend_from_slice(extra);
        a.push("--json");
        let j = json(&a);
        let score = &j["score"];
        assert_eq!(score["stable"], true, "{extra:?}: {score}");
        let j4 = score["j4_pct"].as_f64().expect("J4");
        eprintln!("{extra:?}: J4 {j4:.3} %");
        assert!(j4 < J4_BOUND_PCT, "{extra:?}: J4 {j4} %");
        for o in score["outputs"].as_array().expect("outputs") {
            assert!(o["std_error_pct"].as_f64().expect("output figure") < J4_BOUND_PCT);
        }
        j
    };
    let out_s = out.display().to_string();
    run(&["--preset", "unr-compact", "--out", &out_s]);
    let csv = std::fs::read_to_string(out.join("history.csv")).expect("history.csv");
    let header = csv.lines().next().expect("header");
    assert!(
        header.starts_with("time_s,interface_mm,out_4_1_mm,out_7_1_mm,out_10_1_mm,"),
        "{header}"
    );
    let rows = csv.lines().count() - 1;
    assert!((rows as f64 * DT_S - 4.0).abs() < 0.05, "{rows} rows");
    run(&["--preset", "benchmark"]);
    // The drawn specimen is the reference's, not the controller's.
    let drawn = run(&["--preset", "benchmark", "--uncertainty", "--seed", "2"]);
    let k = drawn["true_specimen_k_kn_per_mm"].as_f64().expect("k");
    assert!((k - 50.0).abs() > 1e-3 && (k - 50.0).abs() < 10.0, "{k}");
    // A rig file of another preset is refused, naming it.
    let rig = dir.path().join("rig.json");
    let rig_s = rig.display().to_string();
    let id = rths(&["identify", "--preset", "benchmark", "--out", &rig_s]);
    assert!(
        id.status.success(),
        "{}",
        String::from_utf8_lossy(&id.stderr)
    );
    run(&["--preset", "benchmark", "--rig", &rig_s]);
    let mut a: Vec<&str> = base.to_vec();
    a.extend_from_slice(&["--preset", "unr-compact", "--rig", &rig_s]);
    let refused = rths(&a);
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("rig.json"), "{err}");
}

#[test]
fn meta_online_refuses_a_missing_model_and_the_flags_it_does_not_take() {
    let base = [
        "simulate",
        "--structure",
        SMALL,
        "--scenario",
        "meta-online",
        "--motion",
        "el-centro",
    ];
    let refused = |extra: &[&str], says: &str| {
        let mut a: Vec<&str> = base.to_vec();
        a.extend_from_slice(extra);
        let out = rths(&a);
        assert!(!out.status.success(), "{extra:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{extra:?}: {err}");
    };
    refused(&[], "--model M.json");
    refused(&["--model", "no-such.json", "--drift", "0.2"], "--drift");
    refused(&["--model", "no-such.json"], "no-such.json");
}

/// A perfect rig: the specimen is at the command it holds (sent at the last tick), and the load
/// cell reads a spring of `k` there, exactly; `nan_force_at` makes the load cell read NaN from
/// that tick on.
struct PerfectRig {
    k_kn_per_mm: f64,
    held_mm: f64,
    tick: usize,
    nan_force_at: Option<usize>,
}

impl Daq for PerfectRig {
    type Error = ErrorKind;
    fn read(&mut self) -> Result<Sample, ErrorKind> {
        let nan = self.nan_force_at.is_some_and(|t| self.tick >= t);
        Ok(Sample {
            disp_mm: self.held_mm,
            force_kn: if nan {
                f64::NAN
            } else {
                self.k_kn_per_mm * self.held_mm
            },
        })
    }
}

impl Actuator for PerfectRig {
    type Error = ErrorKind;
    fn command(&mut self, disp_mm: f64) -> Result<(), ErrorKind> {
        self.held_mm = disp_mm;
        Ok(())
    }
}

impl HostPlant for PerfectRig {
    fn advance_tick(&mut self) {
        self.tick += 1;
    }
    fn true_disp_mm(&self) -> f64 {
        self.held_mm
    }
    fn true_force_kn(&self) -> f64 {
        self.k_kn_per_mm * self.held_mm
    }
    fn held_command_mm(&self) -> f64 {
        self.held_mm
    }
}

/// The host FE by operator splitting (its specimen estimate `estimate`) in core's controller,
/// run by the host's driver against a perfect rig with a spring of `k` (unit scale, no
/// compensator: the command is the next target, which the rig holds over the tick and is at
/// when its force is read; no limits in the way): the part's interface and outputs per tick, and
/// the supervisor's stop.
fn perfect_rig_run(
    s: &ImportedStructure,
    estimate: f64,
    k: f64,
    ag: &[f64],
    nan_force_at: Option<usize>,
    departure_cutoff_hz: Option<f64>,
) -> (fe::FeHistory, drive::Stop) {
    let config = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::new(1.0, 1.0).expect("unit scale"),
        FeedbackSource::Measured,
        Limits::unbounded(),
    )
    .expect("config");
    let mut part = OperatorSplitting::new(s, estimate, DT_S).expect("the host FE");
    if let Some(f) = departure_cutoff_hz {
        part = part.with_departure_cutoff_hz(f).expect("cutoff");
    }
    let mut ctl = Controller::new(
        config,
        Analytical::StructureHost(StructureHost::new(Box::new(part))),
        Compensator::None,
    );
    let mut rig = PerfectRig {
        k_kn_per_mm: k,
        held_mm: 0.0,
        tick: 0,
        nan_force_at,
    };
    let n_out = s.outputs().len();
    let mut h = fe::FeHistory {
        dt_s: DT_S,
        output_columns: s.outputs().iter().map(|o| o.column()).collect(),
        interface_mm: Vec::new(),
        outputs_mm: Vec::new(),
    };
    let stop = drive::run(&mut ctl, Some(&mut rig), ag, None, DT_S, |st, ctl, _| {
        if st.out.state != State::Running {
            return ControlFlow::Break(());
        }
        let part = ctl.analytical();
        h.interface_mm
            .push(part.interface_disp_mm().expect("interface"));
        h.outputs_mm.push(
            (0..n_out)
                .map(|o| part.output_disp_mm(o).expect("output"))
                .collect(),
        );
        ControlFlow::Continue(())
    });
    (h, stop)
}

fn el_centro(seconds: f64) -> Vec<f64> {
    GroundMotion::embedded("el-centro")
        .expect("embedded")
        .resample_mm_s2(DT_S)
        .into_iter()
        .take((seconds / DT_S) as usize)
        .collect()
}

#[test]
fn the_host_fe_in_the_loop_with_a_perfect_rig_is_its_pure_loop_bit_for_bit() {
    let s = ImportedStructure::load(&root().join(SMALL)).expect("the shipped frame loads");
    let ag = el_centro(6.0);
    let k = s.specimen_stiffness_kn_per_mm();
    let pure = fe::run_pure(&s, &ag, DT_S, |_| {}).expect("the pure loop");
    let peak = pure
        .interface_mm
        .iter()
        .fold(0.0_f64, |m, x| m.max(x.abs()));
    assert!(peak > 1.0, "a response to compare: peak {peak} mm");
    // As `fe-online-ats` builds it (the departure low-passed at the fundamental) and without the
    // low-pass: exactly the pure loop, since the measured force's departure from the estimate is
    // zero and each step is the pure loop's (the same K̂, the same right-hand side).
    let f1 = split::fundamental_hz(&s, k).expect("fundamental");
    assert!((2.0..2.2).contains(&f1), "{f1} Hz");
    let f1 = split::departure_cutoff_hz(&s, k).expect("cutoff");
    assert_eq!(f1, split::MAX_DEPARTURE_CUTOFF_HZ);
    for cutoff in [Some(f1), None] {
        let (hybrid, stop) = perfect_rig_run(&s, k, k, &ag, None, cutoff);
        assert_eq!(stop, None);
        assert_eq!(hybrid.interface_mm.len(), ag.len());
        assert_eq!(hybrid.interface_mm, pure.interface_mm, "{cutoff:?}");
        assert_eq!(hybrid.outputs_mm, pure.outputs_mm, "{cutoff:?}");
    }

    // A specimen 10 % stiffer than the estimate in K̂: the splitting's explicit share is the
    // departure. Measured against the whole model with that specimen: 1.9e-4 % NRMSE at the
    // interface as is; 3.6 % with the departure low-passed at the fundamental, the price of the
    // low-pass the rig needs (its lag on the departure; docs/opensees.md).
    let stiffer = fe::run_with_specimen(&s, 1.1 * k, &ag, DT_S, |_| {}).expect("reference");
    for (cutoff, bound_pct) in [(None, 1e-3), (Some(f1), 5.0)] {
        let (hybrid, stop) = perfect_rig_run(&s, k, 1.1 * k, &ag, None, cutoff);
        assert_eq!(stop, None);
        let e = rths_core::metrics::nrmse_pct(&hybrid.interface_mm, &stiffer.interface_mm)
            .expect("nrmse");
        eprintln!("specimen 1.1 × the estimate, cutoff {cutoff:?}: interface NRMSE {e:.2e} %");
        assert!(e < bound_pct, "{cutoff:?}: {e} %");
    }
}

#[test]
fn a_nan_force_stops_the_host_fe_loop_safely() {
    let s = ImportedStructure::load(&root().join(SMALL)).expect("the shipped frame loads");
    let ag = el_centro(1.0);
    let k = s.specimen_stiffness_kn_per_mm();
    let (h, stop) = perfect_rig_run(&s, k, k, &ag, Some(400), None);
    let (why, t) = stop.expect("the supervisor stops the run");
    assert!((t - 400.0 * DT_S).abs() < 1e-9, "{why} at {t} s");
    assert_eq!(h.interface_mm.len(), 400);
    // The part itself refuses a non-finite input without touching its state.
    let mut part = OperatorSplitting::new(&s, k, DT_S).expect("the host FE");
    part.next_target(0.0, 0.0).expect("tick 0");
    let x = part.next_target(1000.0, 0.0).expect("tick 1");
    assert_eq!(
        part.next_target(1000.0, f64::NAN),
        Err(StepError::NonFiniteOutput)
    );
    assert_eq!(
        part.next_target(f64::INFINITY, 0.0),
        Err(StepError::NonFiniteGroundAccel)
    );
    let mut fresh = OperatorSplitting::new(&s, k, DT_S).expect("the host FE");
    fresh.next_target(0.0, 0.0).expect("tick 0");
    assert_eq!(fresh.next_target(1000.0, 0.0), Ok(x));
    assert_eq!(part.interface_disp_mm(), fresh.interface_disp_mm());
}

/// The test's bound on `fe-online-ats`'s J4 on the small frame, %.
const ATS_J4_BOUND_PCT: f64 = 3.0;

#[test]
fn fe_online_ats_runs_an_imported_frame_end_to_end() {
    let dir = tempfile::tempdir().expect("tempdir");
    let record = inputs_record(dir.path());
    let out = dir.path().join("run");
    let out_s = out.display().to_string();
    let base = [
        "simulate",
        "--structure",
        SMALL,
        "--scenario",
        "fe-online-ats",
        "--motion",
        &record,
    ];
    let run = |extra: &[&str]| {
        let mut a: Vec<&str> = base.to_vec();
        a.extend_from_slice(extra);
        a.push("--json");
        let j = json(&a);
        assert_eq!(j["scenario"], "fe-online-ats");
        let score = &j["score"];
        assert_eq!(score["stable"], true, "{extra:?}: {score}");
        let j4 = score["j4_pct"].as_f64().expect("J4");
        eprintln!("fe-online-ats {extra:?}: J4 {j4:.3} %, {score}");
        assert!(j4 < ATS_J4_BOUND_PCT, "{extra:?}: J4 {j4} %");
        for o in score["outputs"].as_array().expect("outputs") {
            assert!(o["std_error_pct"].as_f64().expect("output figure") < ATS_J4_BOUND_PCT);
        }
        assert!(j["fe_s_per_step"].as_f64().expect("FE time") > 0.0);
        j
    };
    let j = run(&["--preset", "unr-compact", "--out", &out_s]);
    assert_eq!(j["specimen_estimate_kn_per_mm"], 50.0);
    let csv = std::fs::read_to_string(out.join("history.csv")).expect("history.csv");
    let header = csv.lines().next().expect("header");
    assert!(
        header.starts_with("time_s,interface_mm,out_4_1_mm,out_7_1_mm,out_10_1_mm,"),
        "{header}"
    );
    let rows = csv.lines().count() - 1;
    assert!((rows as f64 * DT_S - 4.0).abs() < 0.05, "{rows} rows");
    // With a rig file: its ATS start and its identified specimen (not the drawn one) in K̂.
    let rig = dir.path().join("rig.json");
    let rig_s = rig.display().to_string();
    let id = rths(&["identify", "--preset", "benchmark", "--out", &rig_s]);
    assert!(
        id.status.success(),
        "{}",
        String::from_utf8_lossy(&id.stderr)
    );
    let j = run(&["--preset", "benchmark", "--rig", &rig_s]);
    let est = j["specimen_estimate_kn_per_mm"].as_f64().expect("estimate");
    assert!((est - 50.0).abs() < 2.5 && est != 50.0, "{est}");
    let drawn = run(&["--preset", "benchmark", "--uncertainty", "--seed", "2"]);
    assert_eq!(drawn["specimen_estimate_kn_per_mm"], 50.0);
    // A reduced model is not its analytical part.
    let mut a: Vec<&str> = base.to_vec();
    a.extend_from_slice(&["--model", "m.json"]);
    let refused = rths(&a);
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("--model m.json does not apply"), "{err}");
}

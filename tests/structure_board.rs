//! The nonlinear hybrid on the board (issue 23): one image of the emulated Cortex-M7 (QEMU
//! mps2-an500, `cargo build-m7 --features board-mps2-an500,link`), its analytical part uploaded from
//! the files a lab has with the lab's own command, `rths link --qemu ELF run --model M.json
//! --structure S.json --rig RIG.json`:
//! - `nl-online`: the learned modal-hysteretic model of `shear3-yielding` (`data/models/`), with the
//!   rig's identified lead and its online adaptation, the force correction by the identified
//!   specimen and the compensator given the target in force;
//! - `meta-online`: the reduced model of the imported `opensees-frame-1x1` (trained here), with the
//!   same compensation;
//! - `fe-online-lead`: the yielding finite elements of `shear3-yielding`, the same compensation;
//! - `nl-online` of a floor-hysteron model (issue 25) of `shear3-yielding`: its elastic floors and
//!   plays on its spring network's directions, uploaded with `--model` alone and with
//!   `--structure`, the same compensation;
//! - `nl-online` of the shipped floor-hysteron model of the fiber frame trained from OpenSees runs
//!   (`data/models/nl-fiber-frame-hysteron.json`) with its imported structure, the same
//!   compensation.
//!
//! CI runs these at 2048 Hz; the learned fiber-frame model's run at 4096 Hz is in
//! tests/board_4096.rs.
//!
//! Each runs against the plant in the MCU (the `unr-compact` virtual rig, seed 1) through the whole
//! El Centro record, and the host's run of the same controller (core's, installed by the device's
//! own functions from the same values, driven by `rths::machinery::drive` against the same virtual rig): every
//! command bit for bit, and the RESULT line's ticks and command checksum. The rig file is `rths
//! identify`'s of that virtual rig, as a lab identifies its rig.
//!
//! Skipped (loudly) only when `qemu-system-arm` is missing; CI installs it (`RTHS_REQUIRE_QEMU`).
#![cfg(feature = "sim")]

mod board_link;
mod common;
use board_link::{board_and_host, identified_rig, m7_link_elf, m7_tick_pct, rths};
use common::*;

use std::path::{Path, PathBuf};

use rths::machinery::motion::GroundMotion;
use rths_core::params::{CONTROL_RATE_HZ, DT_S};

fn data(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("data").join(p)
}

/// One structure part on the board and on the host ([`board_and_host`]), then `rths report` of
/// the board's recording against the host's scoring of the same run.
#[allow(clippy::too_many_arguments)]
fn on_the_board_and_the_host(
    elf: &Path,
    dir: &Path,
    what: &str,
    scenario: &str,
    model: Option<&Path>,
    structure: &Path,
    rig: &Path,
    length_scale: f64,
) -> serde_json::Value {
    let run = board_and_host(
        elf,
        dir,
        what,
        scenario,
        model,
        structure,
        rig,
        length_scale,
    );
    report_is_the_hosts_score(
        dir,
        what,
        scenario,
        &run.recording,
        structure,
        length_scale,
        &run.rows,
        run.stop,
    );
    run.result
}

/// `rths report RUN.csv --json` of the board's recording: its study figures are, bit for bit,
/// `rths simulate --structure`'s scoring (`score`: its reference, the series brought to the
/// prototype as `run_hybrid` brings them) of the host's run of the same controller on the same
/// plant, over the record the board played. (`rths simulate --structure` itself runs another
/// plant, the structure's specimen at the rig, where the board's image has the paper's brace,
/// and 10 s of free vibration more: its figures are not the board's.)
#[allow(clippy::too_many_arguments)]
fn report_is_the_hosts_score(
    dir: &Path,
    what: &str,
    scenario: &str,
    csv: &Path,
    structure: &Path,
    length_scale: f64,
    rows: &[[f64; 4]],
    stop: rths::machinery::drive::Stop,
) {
    use rths::studies::nonlinear::scenario as nl;
    let (ok, out, err) = rths(dir, &["report", &csv.display().to_string(), "--json"]);
    let text = std::fs::read_to_string(structure).unwrap();
    if scenario == "meta-online" || rths::machinery::imported::file::is_imported(&text) {
        // An imported structure's reference is not the report's yet: refused, saying so.
        assert!(!ok, "{what}: {out}");
        assert!(err.contains("imported structure"), "{what}: {err}");
        println!("{what}: rths report refuses it: {}", err.trim());
        return;
    }
    assert!(ok, "{what}: rths report failed: {err}");
    let report: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let s = rths_files::structure_file::Structure::from_json(&text).unwrap();
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    let mut case = nl::StructureCase::new(s, &ag)
        .unwrap()
        .with_length_scale(nl::LengthScale::new(length_scale).unwrap());
    case.reference_mm.truncate(ag.len());
    let scale = case.length.specimen_scale();
    let series = nl::StructureSeries {
        target_mm: rows.iter().map(|r| r[0] * case.cos_theta).collect(),
        command_mm: rows.iter().map(|r| scale.prototype_disp_mm(r[1])).collect(),
        measured_mm: rows.iter().map(|r| scale.prototype_disp_mm(r[2])).collect(),
        measured_force_kn: rows.iter().map(|r| r[3]).collect(),
        story_drift_mm: Vec::new(),
    };
    let sc: nl::SimScenario = scenario.parse().unwrap();
    let scored = nl::score(&case, sc, &series, stop);
    let host = serde_json::to_value(&scored.report).unwrap();
    println!("{what}: rths report's figures {}", report["scenarios"][0]);
    // serde_json writes an f64 in its shortest exact form: equal values are equal bits.
    assert_eq!(
        report["scenarios"][0], host,
        "{what}: report vs the host's score"
    );
    assert!(host["nrmse_pct"].is_number(), "{what}: {host}");
    let st = &report["structure"];
    assert_eq!(st["ticks"], ag.len(), "{what}: {st}");
    assert_eq!(st["length_scale"], length_scale, "{what}");
    // The reference's ductility needs no run: `rths simulate --structure`'s, exactly.
    let f = serde_json::to_value(&scored.figures).unwrap();
    assert!(f["peak_ductility"].is_number(), "{what}: {f}");
    for key in ["peak_ductility", "peak_ductility_specimen_story"] {
        assert_eq!(st[key], f[key], "{what}: {key}");
    }
    for absent in [
        "peak_ductility_model",
        "residual_drift_mm",
        "residual_drift_error_pct",
    ] {
        assert!(
            st[absent].is_null(),
            "{what}: {absent} must be absent: {st}"
        );
    }
    assert!(
        st["absent"].as_str().unwrap().contains("story drifts"),
        "{st}"
    );
}

#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn the_nonlinear_hybrid_runs_on_the_m7_bit_for_bit_with_the_host() {
    if qemu_missing("the nonlinear hybrid on the emulated Cortex-M7") {
        return;
    }
    let elf = m7_link_elf();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The rig, identified as a lab identifies its own: the emulated board's plant.
    let rig = identified_rig(d);
    let shear3 = data("structures/shear3-yielding.json");

    let r = on_the_board_and_the_host(
        &elf,
        d,
        "nl-online",
        "nl-online",
        Some(&data("models/nl-shear3-yielding.json")),
        &shear3,
        &rig,
        2.0,
    );
    assert_eq!(r["end_state"], "done", "the whole record: {r}");

    let r = on_the_board_and_the_host(
        &elf,
        d,
        "fe-online-lead",
        "fe-online-lead",
        None,
        &shear3,
        &rig,
        2.0,
    );
    assert_eq!(r["end_state"], "done", "the whole record: {r}");

    // An imported frame's reduced model, trained here as a lab does (`rths train meta`).
    let frame = data("structures/opensees-frame-1x1.json");
    let (ok, _, err) = rths(
        d,
        &[
            "train",
            "meta",
            "--structure",
            &frame.display().to_string(),
            "--out",
            "reduced.json",
        ],
    );
    assert!(ok, "{err}");
    let r = on_the_board_and_the_host(
        &elf,
        d,
        "meta-online",
        "meta-online",
        Some(&d.join("reduced.json")),
        &frame,
        &rig,
        2.0,
    );
    assert_eq!(r["end_state"], "done", "the whole record: {r}");

    // A model trained for another structure: refused by the host before anything is sent.
    let (ok, _, err) = rths(
        d,
        &[
            "link",
            "--qemu",
            &elf.display().to_string(),
            "upload",
            "--model",
            &data("models/nl-shear3-yielding.json").display().to_string(),
            "--structure",
            &data("structures/shear8-yielding.json")
                .display()
                .to_string(),
        ],
    );
    assert!(!ok);
    assert!(
        err.contains("shear3-yielding") && err.contains("shear8-yielding"),
        "{err}"
    );
}

/// A floor-hysteron model of `shear3-yielding` (issue 25): the elastic floors training reduces it
/// to, the basis's directions, two plays on each with part of its stiffness (what a training's
/// least squares gives, without the training's minutes).
fn shear3_hysteron(structure: &Path, out: &Path) {
    use rths::machinery::train::nonlinear::floors::FloorModel;
    use rths::machinery::train::nonlinear::hysteron::directions;
    use rths_files::hysteron_model_file::{
        HysteronModelFile, HysteronSpec, HysteronTraining, OperatorSpec, HYSTERON_KIND,
    };
    use rths_files::nl_model_file::{structure_checksum, NlStructureId, NL_FORMAT, NL_VERSION};
    let text = std::fs::read_to_string(structure).unwrap();
    let fm = FloorModel::from_json(&text).unwrap();
    let (dirs, kappa) = directions(&fm.stiffness);
    let rows = |m: &nalgebra::DMatrix<f64>| -> Vec<Vec<f64>> {
        (0..m.nrows())
            .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
            .collect()
    };
    let hysterons = kappa
        .iter()
        .enumerate()
        .filter(|(_, k)| **k > 0.0)
        .flat_map(|(d, k)| {
            [(2.0, 0.3), (8.0, 0.4)].map(|(r, share)| HysteronSpec {
                direction: d,
                threshold_mm: r,
                weight_kn_per_mm: share * k,
            })
        })
        .collect();
    let f = HysteronModelFile {
        format: NL_FORMAT.into(),
        version: NL_VERSION,
        kind: HYSTERON_KIND.into(),
        structure: NlStructureId {
            name: fm.name.clone(),
            checksum: structure_checksum(&text).unwrap(),
        },
        dt_s: DT_S,
        floors: fm.columns.clone(),
        specimen_floor: fm.specimen_floor,
        specimen_stiffness_kn_per_mm: fm.specimen_k_kn_per_mm,
        mass: rows(&fm.mass),
        damping: rows(&fm.damping),
        stiffness: rows(&fm.stiffness),
        ground_mass: fm.ground_mass.iter().copied().collect(),
        directions: dirs,
        operator: OperatorSpec::Play,
        hysterons,
        training: HysteronTraining::default(),
    };
    f.save(out).unwrap();
}

#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn a_floor_hysteron_model_runs_on_the_m7_bit_for_bit_with_the_host() {
    if qemu_missing("the floor-hysteron model on the emulated Cortex-M7") {
        return;
    }
    let elf = m7_link_elf();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rig = identified_rig(d);
    let shear3 = data("structures/shear3-yielding.json");
    let model = d.join("hysteron.json");
    shear3_hysteron(&shear3, &model);
    // The model file alone: its floors are in it.
    let (ok, out, err) = rths(
        d,
        &[
            "link",
            "--qemu",
            &elf.display().to_string(),
            "upload",
            "--model",
            &model.display().to_string(),
        ],
    );
    assert!(ok, "{err}");
    assert!(
        out.contains("floor-hysteron model of shear3-yielding"),
        "{out}"
    );
    let r = on_the_board_and_the_host(
        &elf,
        d,
        "floor-hysteron nl-online",
        "nl-online",
        Some(&model),
        &shear3,
        &rig,
        2.0,
    );
    assert_eq!(r["end_state"], "done", "the whole record: {r}");
    // Another structure's: refused by the host, naming both.
    let (ok, _, err) = rths(
        d,
        &[
            "link",
            "--qemu",
            &elf.display().to_string(),
            "upload",
            "--model",
            &model.display().to_string(),
            "--structure",
            &data("structures/shear8-yielding.json")
                .display()
                .to_string(),
        ],
    );
    assert!(!ok);
    assert!(
        err.contains("shear3-yielding") && err.contains("shear8-yielding"),
        "{err}"
    );
}

/// The shipped floor-hysteron model of the fiber frame (`data/models/nl-fiber-frame-hysteron.json`,
/// trained by `rths train nonlinear` from OpenSees runs of `opensees-fiber-frame`'s fiber-section
/// model, docs/opensees-nonlinear.md) with its imported structure and the rig's compensation, `nl-online`
/// on the emulated M7 through El Centro bit for bit with the host (`rths report` refuses an
/// imported structure's recording, saying so). The 10 % goal is checked by the structure budget
/// (`firmware/budget.sh`: its floor-hysteron rows at 4096 Hz), not here.
#[test]
#[cfg_attr(
    rths_no_qemu,
    ignore = "needs qemu-system-arm, not found when the tests were built (docs/ci.md)"
)]
fn the_trained_floor_hysteron_model_of_the_fiber_frame_runs_on_the_m7_bit_for_bit() {
    if qemu_missing("the trained floor-hysteron model on the emulated Cortex-M7") {
        return;
    }
    let elf = m7_link_elf();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rig = identified_rig(d);
    let r = on_the_board_and_the_host(
        &elf,
        d,
        "fiber-frame floor-hysteron nl-online",
        "nl-online",
        Some(&data("models/nl-fiber-frame-hysteron.json")),
        &data("structures/opensees-fiber-frame.json"),
        &rig,
        2.0,
    );
    assert_eq!(r["end_state"], "done", "the whole record: {r}");
    let max = r["instr_per_tick"]["max"].as_f64().unwrap();
    println!(
        "fiber-frame floor-hysteron nl-online at {CONTROL_RATE_HZ} Hz: {max} instructions per tick \
         at most, {:.2} % of the tick at 480 MHz and 1.5 cycles per instruction",
        m7_tick_pct(max)
    );
}

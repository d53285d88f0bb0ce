//! The firmware's structure budget (`firmware/budget.sh`, `RTHS_BUDGET=structures`) rerun on the host:
//! the same twelve controllers (FE linear, FE yielding, structure metamodel, modal-hysteretic
//! metamodel of `data/models/nl-S.json`; N = 1, 3, 8), the same
//! El Centro ticks at 4096 Hz, the same ideal rig, and the same FNV-1a checksum of each command
//! stream; two of its reduced-model rows (imported frames) and its floor-hysteron row (the shipped
//! model of the fiber frame). The expected checksums are the
//! emulated Cortex-M7's (`STRUCTURE` lines of its QEMU run, docs/firmware.md#the-structure-budget):
//! host and firmware step these controllers bit for bit.

use rths::studies::benchmark::meta::train_at;
use rths_core::checksum::Fnv1a64;
use rths_core::control::{ControlConfig, Controller, FeedbackSource};
use rths_core::control::{ModalSpec, StoryLawSpec};
use rths_core::hal::Sample;
use rths_core::metamodel::ModalMode;
use rths_core::model::{assemble, ModelSpec};
use rths_core::params::{dt_s, Prototype, SpecimenScale, FORCE_SCALE};
use rths_core::supervisor::{Limits, State};
use rths_files::motion::GroundMotion;
use rths_files::nl_model_file::NlModelFile;
use rths_files::structure_file::Structure;
use rths_files::structure_meta::StructureArrays;

/// The firmware's record length at 4096 Hz (its `RECORD_TICKS`).
const TICKS: usize = 163_800;
/// The budget's prototype-to-actuator displacement scale (`firmware/src/analytical.rs`).
const DISP_SCALE: f64 = 10.0;

fn structure_path(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/structures")
        .join(format!("{name}.json"))
}

fn structure(name: &str) -> Structure {
    Structure::load(&structure_path(name)).unwrap()
}

/// FNV-1a of the command stream of the modal-hysteretic metamodel of `name`
/// (`data/models/nl-S.json`, checked against the structure file) as the firmware builds it:
/// the file's arrays as a `ModelSpec::StructureModal`.
fn run_modal(name: &str, k_e: f64, ag: &[f64]) -> u64 {
    let model = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/models")
        .join(format!("nl-{name}.json"));
    let f = NlModelFile::load_for(&model, &structure_path(name)).unwrap();
    let modes: Vec<ModalMode> = f
        .modes
        .iter()
        .map(|m| ModalMode {
            omega_rad_s: m.omega_rad_s,
            damping_ratio: m.damping_ratio,
            ground_participation: m.ground_participation,
        })
        .collect();
    let laws: Vec<StoryLawSpec> = f
        .springs
        .iter()
        .map(|s| StoryLawSpec::of(&s.law().unwrap()))
        .collect();
    let shape: Vec<f64> = f.shape.iter().flatten().copied().collect();
    let drift: Vec<f64> = f.springs.iter().flat_map(|s| s.drift.clone()).collect();
    let spec = ModelSpec::StructureModal {
        model: ModalSpec {
            modes: &modes,
            shape: &shape,
            specimen_dof: f.specimen_dof,
            specimen_k_kn_per_mm: f.specimen_stiffness_kn_per_mm,
            laws: &laws,
            drift: &drift,
        },
    };
    run(&spec, k_e, ag)
}

/// FNV-1a of the command stream's bits, as the firmware computes it.
fn run(spec: &ModelSpec<'_>, k_e: f64, ag: &[f64]) -> u64 {
    let dt = dt_s(4096);
    let scale = SpecimenScale::new(DISP_SCALE, FORCE_SCALE).unwrap();
    let cfg = ControlConfig::new(
        Prototype::paper(),
        scale,
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let (a, c) = assemble(spec, Prototype::paper(), dt).unwrap();
    let mut ctl = Controller::new(cfg, a, c);
    ctl.supervisor_mut().arm().unwrap();
    ctl.supervisor_mut().start().unwrap();
    let mut fnv = Fnv1a64::new();
    for &g in &ag[..TICKS] {
        let x = ctl.supervisor().output_mm();
        let f_proto = k_e * scale.prototype_disp_mm(x);
        let out = ctl.tick(
            g,
            Ok(Sample {
                disp_mm: x,
                force_kn: f_proto / FORCE_SCALE,
            }),
            false,
        );
        assert_eq!(out.state, State::Running);
        fnv.write_f64(out.command_mm);
    }
    fnv.finish()
}

#[test]
fn the_host_steps_the_structure_budget_as_the_m7_does() {
    let dt = dt_s(4096);
    let ag = GroundMotion::try_el_centro().unwrap().resample_mm_s2(dt);
    assert!(ag.len() >= TICKS);
    let cases: [(&str, &str, u64); 12] = [
        ("fe", "paper-frame", 0x93aa19d5b021bff6),
        ("fe", "vrths-case1", 0xe6553a72110da023),
        ("fe", "shear8", 0xeb26b80c088b0d63),
        ("nl", "paper-frame-yielding", 0x9e9c43e881fda878),
        ("nl", "shear3-yielding", 0x7491f1cc3dac81f6),
        ("nl", "shear8-yielding", 0x8d945f562c63e798),
        ("meta", "paper-frame", 0x41c5b851e3265ce3),
        ("meta", "vrths-case1", 0x511c3a1c7356b7bb),
        ("meta", "shear8", 0x31766306ed5277f0),
        // The modal rows are the shipped model files': a retrained file changes its checksum
        // (`cd firmware && ./budget.sh --structures --json` prints the M7's).
        ("modal", "paper-frame-yielding", 0xf1b013902a0b1a90),
        ("modal", "shear3-yielding", 0x290376fe5ff736e1),
        ("modal", "shear8-yielding", 0xe6ad24eb84de5945),
    ];
    for (kind, name, expected) in cases {
        let s = structure(name);
        let k_e = s.specimen().1;
        let fnv = match kind {
            "fe" => {
                let a = StructureArrays::linear(&s).unwrap();
                run(
                    &ModelSpec::StructureFe {
                        structure: a.spec(),
                    },
                    k_e,
                    &ag,
                )
            }
            "nl" => {
                let a = StructureArrays::yielding(&s, dt).unwrap();
                run(
                    &ModelSpec::StructureNl {
                        structure: a.spec(),
                    },
                    k_e,
                    &ag,
                )
            }
            "modal" => run_modal(name, k_e, &ag),
            _ => {
                let m = train_at(&s, rths::studies::benchmark::DEFAULT_INTENSITY, dt).unwrap();
                let p = m.params();
                let spec = ModelSpec::StructureMeta {
                    theta: p.theta(),
                    k_corr_kn_per_mm: p.k_corr_kn_per_mm(),
                };
                run(&spec, k_e, &ag)
            }
        };
        assert_eq!(fnv, expected, "{kind} {name}: {fnv:016x}");
    }
}

/// The budget's reduced-model rows (`RTHS_BUDGET_REDUCED`, `budget.sh`: the imported frames'
/// reduced-order models trained at 4096 Hz) rerun on the host: the M7's command checksums. The
/// small and the middle frame (10 and 104 DOFs with mass); the 936-DOF frame's training takes
/// half a minute of CPU and is left to `budget.sh`.
#[test]
fn the_host_steps_the_reduced_rows_as_the_m7_does() {
    use rths::machinery::imported::reduced;
    use rths::machinery::imported::ImportedStructure;
    let dt = dt_s(4096);
    let ag = GroundMotion::try_el_centro().unwrap().resample_mm_s2(dt);
    let records = reduced::training_records(dt).unwrap();
    for (name, expected) in [
        ("opensees-frame-1x1", 0x58f2e4fe753d96d4_u64),
        ("opensees-frame-2x4", 0x5e6efc6bbca05ed5),
    ] {
        let text = std::fs::read_to_string(structure_path(name)).unwrap();
        let s = ImportedStructure::from_json(&text).unwrap();
        let file = reduced::train(&s, &records, dt, |_, _, _| {}).unwrap();
        let arrays = file.arrays_for(&s, dt).unwrap();
        let spec = ModelSpec::StructureReduced {
            model: arrays.spec(),
        };
        let fnv = run(&spec, file.specimen_k_kn_per_mm, &ag);
        assert_eq!(fnv, expected, "reduced {name}: {fnv:016x}");
    }
}

/// The budget's floor-hysteron row (`structure-hysteron`: the shipped model of the fiber frame
/// trained from OpenSees runs, laid out alone as `rths link upload --model` lays it out) rerun on
/// the host: the M7's command checksum at 4096 Hz (its `STRUCTURE` line, docs/firmware.md).
#[test]
fn the_host_steps_the_floor_hysteron_row_as_the_m7_does() {
    let dt = dt_s(4096);
    let ag = GroundMotion::try_el_centro().unwrap().resample_mm_s2(dt);
    let model = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data/models/nl-fiber-frame-hysteron.json");
    let laid = rths_files::upload::lay_out_files(Some(&model), None, dt).unwrap();
    let k = laid.specimen_k_kn_per_mm.unwrap();
    let fnv =
        rths_link::layout::with_spec(laid.kind, &laid.values, |spec| run(spec, k, &ag)).unwrap();
    assert_eq!(
        fnv, 0xe3ee4a2925250417_u64,
        "floor-hysteron fiber_frame: {fnv:016x}"
    );
}

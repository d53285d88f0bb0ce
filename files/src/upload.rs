//! A lab's model files as the link carries them: a model of any kind read by its own reader,
//! checked as the host commands check it, and laid out with `rths_link::layout` (the one layout
//! of every kind). The host uploads these values (`rths link upload|run`) and the firmware's build
//! script compiles them in as the image's default (`RTHS_MODEL`, `RTHS_STRUCTURE`), so an image
//! runs its default through the same decode path an upload takes.
//!
//! The files, and the kind they make:
//! - a model file alone (`rths train lr|rnn|lrx`): `Lr`, `Rnn`, `Lrx` (an LRX's lead adaptation
//!   and specimen dynamics, if it has them, are its rig compensation's values); a floor-hysteron
//!   model alone (its floors' matrices are in it): `StructureHysteron`;
//! - a dense structure file alone (`data/structures/`): its finite elements, `StructureFe`
//!   (linear) or `StructureNl` (yielding stories);
//! - a structure file and its model, by the model's `format` and `kind`: the structure metamodel
//!   (`rths train meta`, `StructureMeta`), the modal-hysteretic model (`rths train nonlinear`,
//!   `StructureModal`; its floor-hysteron form, `StructureHysteron`), or an imported structure's
//!   reduced model (`rths train meta` on an `rths import opensees` file, `StructureReduced`). A
//!   model trained for another structure is refused.

use std::path::Path;

use rths_core::control::{FloorHysteronSpec, StoryLawSpec};
use rths_core::metamodel::{FloorStructure, ModalMode};
use rths_core::model::ModelSpec;
use rths_link::layout::{lay_out, lrx_rig_values, MODEL_MAX_VALUES};
use rths_link::ModelKind;

use crate::hysteron_model_file::{HysteronModelFile, HYSTERON_KIND};
use crate::model_file::{ModelFile, ModelKind as FileKind};
use crate::nl_model_file::{NlModelFile, NL_FORMAT};
use crate::reduced_model_file::{imported_structure_name, ReducedModelFile};
use crate::structure_file::Structure;
use crate::structure_meta::{MetaFile, StructureArrays};

/// A model laid out for the link.
#[derive(Debug, Clone, PartialEq)]
pub struct LaidOut {
    /// Its kind on the link.
    pub kind: ModelKind,
    /// Its values (`rths_link::layout`).
    pub values: Vec<f64>,
    /// Its feedback delay, ticks (the model file's; 0 for the structure kinds).
    pub delay_steps: u16,
    /// The rig compensation its file carries, if any (an LRX trained for a rig: its lead's
    /// adaptation and the specimen's dynamics, `rths_link::rig_values`' layout).
    pub rig: Option<Vec<f64>>,
    /// The step the model was trained at, s (LR, LRX, RNN: they run only at it; the structure
    /// kinds are checked here against the step asked, or run at any).
    pub trained_dt_s: Option<f64>,
    /// The structure's specimen stiffness the part stands for, kN/mm (the structure kinds): what
    /// a rig compensation's force scale maps the rig's specimen to.
    pub specimen_k_kn_per_mm: Option<f64>,
    /// What the files are, for a message (the model's kind and the structure's name).
    pub what: String,
}

/// A file that cannot be laid out: which, and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct UploadFileError(pub String);

fn err(path: &Path, e: impl std::fmt::Display) -> UploadFileError {
    UploadFileError(format!("{}: {e}", path.display()))
}

/// Lay `spec` out (its kind, its values).
fn laid(spec: &ModelSpec<'_>, path: &Path) -> Result<(ModelKind, Vec<f64>), UploadFileError> {
    let mut out = vec![0.0; MODEL_MAX_VALUES];
    let (kind, n) = lay_out(spec, &mut out).map_err(|e| err(path, format!("{e:?}")))?;
    out.truncate(n);
    Ok((kind, out))
}

/// The model of the files a lab has, laid out for the link: a model file alone (`model`), a
/// structure file alone (its finite elements), or a structure file and its model; the structure
/// kinds checked for the controller step `dt_s`. Refused with the file and the reason.
pub fn lay_out_files(
    model: Option<&Path>,
    structure: Option<&Path>,
    dt_s: f64,
) -> Result<LaidOut, UploadFileError> {
    match (model, structure) {
        (Some(m), None) => model_file(m, dt_s),
        (None, Some(s)) => structure_fe(s, dt_s),
        (Some(m), Some(s)) => structure_model(m, s, dt_s),
        (None, None) => Err(UploadFileError(
            "no model: a model file, a structure file, or both".into(),
        )),
    }
}

/// The `format` and `kind` of a model file's JSON (`None`: absent, or not JSON).
#[derive(serde::Deserialize)]
struct Tags {
    format: Option<String>,
    kind: Option<String>,
}

/// A floor-hysteron model file (`rths train nonlinear`): its floors' matrices are in it, so it is
/// laid out without its structure file too.
fn is_hysteron(text: &str) -> bool {
    serde_json::from_str::<Tags>(text).is_ok_and(|t| {
        t.format.as_deref() == Some(NL_FORMAT) && t.kind.as_deref() == Some(HYSTERON_KIND)
    })
}

/// Whether the model file at `path` carries its whole part without a structure file (a
/// floor-hysteron model): `rths link upload --model M.json` lays it out alone.
pub fn is_self_contained(path: &Path) -> bool {
    std::fs::read_to_string(path).is_ok_and(|t| is_hysteron(&t))
}

/// An LR, LRX or RNN model file, or a floor-hysteron model alone.
fn model_file(path: &Path, dt_s: f64) -> Result<LaidOut, UploadFileError> {
    let text = std::fs::read_to_string(path).map_err(|e| err(path, e))?;
    if is_hysteron(&text) {
        return hysteron(path, &text, None, dt_s);
    }
    let m = ModelFile::from_json(&text).map_err(|e| err(path, e))?;
    lay_out_model_file(&m, path)
}

/// An LR, LRX or RNN model file already read (`path`: its name in a message).
pub fn lay_out_model_file(m: &ModelFile, path: &Path) -> Result<LaidOut, UploadFileError> {
    let delay_steps =
        u16::try_from(m.delay_steps).map_err(|_| err(path, "delay_steps does not fit 16 bits"))?;
    let missing = |what: &str| err(path, format!("no {what} section"));
    let (kind, values, rig) = match m.kind {
        FileKind::Lr => {
            let theta = &m.lr.as_ref().ok_or_else(|| missing("lr"))?.theta;
            let (k, v) = laid(&ModelSpec::Lr { theta }, path)?;
            (k, v, None)
        }
        FileKind::Lrx => {
            let x = m.lrx.as_ref().ok_or_else(|| missing("lrx"))?;
            let spec = ModelSpec::Lrx {
                coeffs: &x.coeffs,
                k_corr_kn_per_mm: x.k_corr_kn_per_mm,
                k_adapt_ticks: x.k_adapt_ticks,
                lead_weights: &x.lead_weights,
                lead_stride: x.lead_stride,
                lead_adapt_ticks: x.lead_adapt_ticks.unwrap_or(0.0),
                specimen_dynamics: [
                    x.specimen_mass_kn_s2_per_mm.unwrap_or(0.0),
                    x.specimen_damping_kn_s_per_mm.unwrap_or(0.0),
                ],
            };
            let (k, v) = laid(&spec, path)?;
            (k, v, lrx_rig_values(&spec).map(|r| r.to_vec()))
        }
        FileKind::Rnn => {
            let r = m.rnn.as_ref().ok_or_else(|| missing("rnn"))?;
            let (w_ih, w_hh) = (r.w_ih.concat(), r.w_hh.concat());
            let spec = ModelSpec::Rnn {
                weights: rths_core::metamodel::RnnWeights {
                    w_ih: &w_ih,
                    w_hh: &w_hh,
                    b_h: &r.b_h,
                    w_ho: &r.w_ho,
                    b_o: r.b_o,
                },
                scaling: rths_core::metamodel::RnnScaling {
                    input_mean: two(&r.input_mean, path)?,
                    input_std: two(&r.input_std, path)?,
                    output_mean: r.output_mean,
                    output_std: r.output_std,
                },
            };
            let (k, v) = laid(&spec, path)?;
            (k, v, None)
        }
    };
    Ok(LaidOut {
        kind,
        values,
        delay_steps,
        rig,
        trained_dt_s: Some(m.dt_s),
        specimen_k_kn_per_mm: None,
        what: format!("{} model", m.kind),
    })
}

fn two(v: &[f64], path: &Path) -> Result<[f64; 2], UploadFileError> {
    v.try_into()
        .map_err(|_| err(path, "the RNN's input scaling has two entries"))
}

fn load_structure(path: &Path) -> Result<Structure, UploadFileError> {
    Structure::load(path).map_err(|e| err(path, e))
}

/// A structure laid out as a spec's kind, with what it stands for.
fn structure_laid(
    spec: &ModelSpec<'_>,
    path: &Path,
    specimen_k: f64,
    what: String,
    trained_dt_s: Option<f64>,
) -> Result<LaidOut, UploadFileError> {
    let (kind, values) = laid(spec, path)?;
    Ok(LaidOut {
        kind,
        values,
        delay_steps: 0,
        rig: None,
        trained_dt_s,
        specimen_k_kn_per_mm: Some(specimen_k),
        what,
    })
}

/// A dense structure's finite elements (linear, or its yielding stories), refused if the
/// controller's integrator cannot step it at `dt_s`.
fn structure_fe(path: &Path, dt_s: f64) -> Result<LaidOut, UploadFileError> {
    let s = load_structure(path)?;
    let yielding = s.story_laws().is_some();
    let a = if yielding {
        StructureArrays::yielding(&s, dt_s)
    } else {
        StructureArrays::linear(&s)
    }
    .map_err(|e| err(path, e))?;
    let spec = a.spec();
    let built = if yielding {
        spec.yielding(dt_s).map(|_| ())
    } else {
        spec.linear(dt_s).map(|_| ())
    };
    built.map_err(|e| err(path, e))?;
    let (spec, what) = if yielding {
        (
            ModelSpec::StructureNl { structure: spec },
            "yielding finite elements",
        )
    } else {
        (
            ModelSpec::StructureFe { structure: spec },
            "finite elements",
        )
    };
    structure_laid(
        &spec,
        path,
        s.specimen().1,
        format!("{what} of {}", s.name()),
        None,
    )
}

/// A structure's model: its `format` and `kind` pick the reader.
fn structure_model(model: &Path, structure: &Path, dt_s: f64) -> Result<LaidOut, UploadFileError> {
    let text = std::fs::read_to_string(model).map_err(|e| err(model, e))?;
    if ReducedModelFile::is_reduced(&text) {
        return reduced(model, &text, structure, dt_s);
    }
    let tags: Tags = serde_json::from_str(&text).map_err(|e| err(model, e))?;
    if tags.format.as_deref() == Some(NL_FORMAT) {
        if tags.kind.as_deref() == Some(HYSTERON_KIND) {
            return hysteron(model, &text, Some(structure), dt_s);
        }
        return modal(model, structure, dt_s);
    }
    let s = load_structure(structure)?;
    let p = MetaFile::from_json(&text)
        .and_then(|m| m.check(&s, dt_s))
        .map_err(|e| err(model, e))?;
    structure_laid(
        &ModelSpec::StructureMeta {
            theta: p.theta(),
            k_corr_kn_per_mm: p.k_corr_kn_per_mm(),
        },
        model,
        s.specimen().1,
        format!("structure metamodel of {}", s.name()),
        Some(dt_s),
    )
}

/// The modal-hysteretic model of a yielding structure, checked against it (name and checksum)
/// and validated at `dt_s` (its modes are continuous-time: any rate runs).
fn modal(model: &Path, structure: &Path, dt_s: f64) -> Result<LaidOut, UploadFileError> {
    let f = NlModelFile::load_for(model, structure)
        .map_err(|e| err(model, format!("for {}: {e}", structure.display())))?;
    f.params(dt_s).map_err(|e| err(model, e))?;
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
        .map(|s| s.law().map(|l| StoryLawSpec::of(&l)))
        .collect::<Result<_, _>>()
        .map_err(|e| err(model, e))?;
    let shape: Vec<f64> = f.shape.iter().flatten().copied().collect();
    let drift: Vec<f64> = f
        .springs
        .iter()
        .flat_map(|s| s.drift.iter().copied())
        .collect();
    let spec = ModelSpec::StructureModal {
        model: rths_core::control::ModalSpec {
            modes: &modes,
            shape: &shape,
            specimen_dof: f.specimen_dof,
            specimen_k_kn_per_mm: f.specimen_stiffness_kn_per_mm,
            laws: &laws,
            drift: &drift,
        },
    };
    structure_laid(
        &spec,
        model,
        f.specimen_stiffness_kn_per_mm,
        format!("modal-hysteretic model of {}", f.structure.name),
        None,
    )
}

/// The floor-hysteron model of a yielding structure (a dense structure file or an imported one),
/// checked against it if given (name and checksum) and validated at `dt_s` (continuous-time floors
/// and rate-independent operators: any rate runs).
fn hysteron(
    model: &Path,
    text: &str,
    structure: Option<&Path>,
    dt_s: f64,
) -> Result<LaidOut, UploadFileError> {
    let f = HysteronModelFile::from_json(text).map_err(|e| err(model, e))?;
    if let Some(structure) = structure {
        let stext = std::fs::read_to_string(structure).map_err(|e| err(structure, e))?;
        f.check_structure(&stext)
            .map_err(|e| err(model, format!("for {}: {e}", structure.display())))?;
    }
    // Every field checked, with its name, before the values are laid out.
    f.params(dt_s).map_err(|e| err(model, e))?;
    let flat = |m: &[Vec<f64>]| m.iter().flatten().copied().collect::<Vec<f64>>();
    let (mass, damping, stiffness) = (flat(&f.mass), flat(&f.damping), flat(&f.stiffness));
    let directions = flat(&f.directions);
    let hysterons: Vec<f64> = f
        .hysterons
        .iter()
        .flat_map(|h| [h.direction as f64, h.threshold_mm, h.weight_kn_per_mm])
        .collect();
    let operator = f.operator.operator().map_err(|e| err(model, e))?;
    let spec = ModelSpec::StructureHysteron {
        model: FloorHysteronSpec {
            floors: FloorStructure {
                floors: f.floors.len(),
                mass: &mass,
                damping: &damping,
                stiffness: &stiffness,
                ground_mass: &f.ground_mass,
                specimen_floor: f.specimen_floor,
                specimen_k_kn_per_mm: f.specimen_stiffness_kn_per_mm,
            },
            directions: &directions,
            hysterons: &hysterons,
            operator,
        },
    };
    structure_laid(
        &spec,
        model,
        f.specimen_stiffness_kn_per_mm,
        format!("floor-hysteron model of {}", f.structure.name),
        None,
    )
}

/// An imported structure's reduced model, refused if trained for a structure of another name
/// (the checksum of the condensed matrices is the host's: it needs the condensation) or at
/// another rate than `dt_s`'s (its mode count and error bound are its training rate's), and
/// validated at `dt_s`.
fn reduced(
    model: &Path,
    text: &str,
    structure: &Path,
    dt_s: f64,
) -> Result<LaidOut, UploadFileError> {
    let f = ReducedModelFile::from_json(text).map_err(|e| err(model, e))?;
    let stext = std::fs::read_to_string(structure).map_err(|e| err(structure, e))?;
    let name = imported_structure_name(&stext).map_err(|e| err(structure, e))?;
    let arrays = f.arrays_for_name(&name, dt_s).map_err(|e| err(model, e))?;
    let spec = arrays.spec();
    spec.params(dt_s).map_err(|e| err(model, e))?;
    structure_laid(
        &ModelSpec::StructureReduced { model: spec },
        model,
        spec.specimen_k_kn_per_mm,
        format!("reduced model of {name}"),
        None,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(p: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../data")
            .join(p)
    }

    #[test]
    fn the_shipped_files_lay_out_as_their_kinds() {
        let dt = rths_core::params::DT_S;
        let lr = lay_out_files(Some(&data("models/lr.json")), None, dt).unwrap();
        assert_eq!(
            (lr.kind, lr.values.len(), lr.delay_steps),
            (ModelKind::Lr, 6, 28)
        );
        let rnn = lay_out_files(Some(&data("models/rnn-10.json")), None, dt).unwrap();
        assert_eq!((rnn.kind, rnn.values.len()), (ModelKind::Rnn, 147));
        let lrx = lay_out_files(Some(&data("models/lrx.json")), None, dt).unwrap();
        assert_eq!((lrx.kind, lrx.values.len()), (ModelKind::Lrx, 20));
        let fe = lay_out_files(None, Some(&data("structures/shear8.json")), dt).unwrap();
        assert_eq!(fe.kind, ModelKind::StructureFe);
        let nl = lay_out_files(None, Some(&data("structures/shear3-yielding.json")), dt).unwrap();
        assert_eq!(nl.kind, ModelKind::StructureNl);
        let modal = lay_out_files(
            Some(&data("models/nl-shear3-yielding.json")),
            Some(&data("structures/shear3-yielding.json")),
            dt,
        )
        .unwrap();
        assert_eq!(modal.kind, ModelKind::StructureModal);
        assert_eq!(modal.specimen_k_kn_per_mm, Some(100.0));
        // Another structure's model: refused, naming both.
        let e = lay_out_files(
            Some(&data("models/nl-shear3-yielding.json")),
            Some(&data("structures/paper-frame-yielding.json")),
            dt,
        )
        .unwrap_err();
        assert!(
            e.0.contains("shear3-yielding") && e.0.contains("paper-frame-yielding"),
            "{e}"
        );
        assert!(lay_out_files(None, None, dt).is_err());
    }

    /// A reduced model trained at 2048 Hz (the fuzz seed of frame-1x1's) lays out for a 2048 Hz
    /// controller, and is refused for a 4096 Hz one (an upload to a 4096 Hz board, a 4096 Hz
    /// image's default), naming both rates and the command that trains one at 4096 Hz.
    #[test]
    fn a_reduced_model_is_refused_at_another_rate_than_its_training() {
        use rths_core::params::dt_s;
        let model = data("../fuzz/seeds/meta_model_file/frame-1x1-reduced.json");
        let frame = data("structures/opensees-frame-1x1.json");
        let laid = lay_out_files(Some(&model), Some(&frame), dt_s(2048)).unwrap();
        assert_eq!(laid.kind, ModelKind::StructureReduced);
        let e = lay_out_files(Some(&model), Some(&frame), dt_s(4096)).unwrap_err();
        for part in [
            "frame-1x1-reduced.json",
            "the reduced model of frame-1x1 was made at 2048 Hz",
            "this controller runs at 4096 Hz",
            "`rths train meta --structure S.json --rate 4096 --out M.json`",
        ] {
            assert!(e.0.contains(part), "{part:?} in: {e}");
        }
        // The reader itself, as the host commands call it, and at the file's own rate.
        let f = ReducedModelFile::load(&model).unwrap();
        assert!(f.arrays_for_name("frame-1x1", dt_s(2048)).is_ok());
        let e = f.arrays_for_name("frame-1x1", dt_s(4096)).unwrap_err();
        assert!(
            matches!(e, crate::reduced_model_file::ReducedFileError::OtherRate(_)),
            "{e}"
        );
        // The structure's name is checked first: another structure is named as such.
        let e = f.arrays_for_name("frame-2x4", dt_s(4096)).unwrap_err();
        assert!(e.to_string().contains("not frame-2x4"), "{e}");
    }

    /// A floor-hysteron model of `shear3-yielding` (3 floors, its story drifts and one
    /// two-story direction) with the operator `operator`, written to a file of its own.
    fn hysteron_file(
        operator: crate::hysteron_model_file::OperatorSpec,
        dir: &Path,
    ) -> (std::path::PathBuf, HysteronModelFile) {
        use crate::hysteron_model_file::{HysteronSpec, HysteronTraining};
        let text = std::fs::read_to_string(data("structures/shear3-yielding.json")).unwrap();
        let eye = |x: f64| {
            (0..3)
                .map(|i| (0..3).map(|j| if i == j { x } else { 0.0 }).collect())
                .collect::<Vec<Vec<f64>>>()
        };
        let f = HysteronModelFile {
            format: NL_FORMAT.into(),
            version: crate::nl_model_file::NL_VERSION,
            kind: HYSTERON_KIND.into(),
            structure: crate::nl_model_file::NlStructureId {
                name: "shear3-yielding".into(),
                checksum: crate::nl_model_file::structure_checksum(&text).unwrap(),
            },
            dt_s: rths_core::params::DT_S,
            floors: vec![
                "out_1_1_mm".into(),
                "out_2_1_mm".into(),
                "out_3_1_mm".into(),
            ],
            specimen_floor: 0,
            specimen_stiffness_kn_per_mm: 100.0,
            mass: eye(0.25),
            damping: eye(0.05),
            stiffness: vec![
                vec![400.0, -200.0, 0.0],
                vec![-200.0, 400.0, -200.0],
                vec![0.0, -200.0, 200.0],
            ],
            ground_mass: vec![0.25; 3],
            directions: vec![
                vec![1.0, 0.0, 0.0],
                vec![-1.0, 1.0, 0.0],
                vec![0.0, -1.0, 1.0],
                vec![-1.0, 0.0, 1.0],
            ],
            operator,
            hysterons: (0..8)
                .map(|i| HysteronSpec {
                    direction: i % 4,
                    threshold_mm: 1.0 + i as f64,
                    weight_kn_per_mm: 10.0 + i as f64,
                })
                .collect(),
            training: HysteronTraining::default(),
        };
        let path = dir.join("hysteron.json");
        f.save(&path).unwrap();
        (path, f)
    }

    #[test]
    fn a_floor_hysteron_model_lays_out_as_the_parameters_the_host_runs() {
        use crate::hysteron_model_file::OperatorSpec;
        let dt = rths_core::params::DT_S;
        let mp = OperatorSpec::MenegottoPinto {
            r0: 20.0,
            cr1: 0.925,
            cr2: 0.15,
        };
        for (op, tag) in [(OperatorSpec::Play, "play"), (mp, "mp")] {
            let dir = tempfile::tempdir().unwrap();
            let (path, f) = hysteron_file(op, dir.path());
            let laid = lay_out_files(
                Some(&path),
                Some(&data("structures/shear3-yielding.json")),
                dt,
            )
            .unwrap();
            assert_eq!(laid.kind, ModelKind::StructureHysteron);
            assert_eq!(laid.specimen_k_kn_per_mm, Some(100.0));
            assert_eq!(
                laid.values.len(),
                rths_link::layout::hysteron_value_count(3, 4, 8)
            );
            // What the device reads back is the host's model, to the bit (the same parameters).
            let back = rths_link::layout::with_spec(laid.kind, &laid.values, |spec| {
                let ModelSpec::StructureHysteron { model } = spec else {
                    panic!("{spec:?}");
                };
                model.params(dt).unwrap()
            })
            .unwrap();
            assert_eq!(back, f.params(dt).unwrap(), "{tag}");
            // The file alone (`rths link upload --model M.json`): the same values.
            assert!(is_self_contained(&path));
            let alone = lay_out_files(Some(&path), None, dt).unwrap();
            assert_eq!((alone.kind, &alone.values), (laid.kind, &laid.values));
            // Another structure: refused, naming both.
            let e = lay_out_files(
                Some(&path),
                Some(&data("structures/paper-frame-yielding.json")),
                dt,
            )
            .unwrap_err();
            assert!(
                e.0.contains("shear3-yielding") && e.0.contains("paper-frame-yielding"),
                "{e}"
            );
        }
    }
}

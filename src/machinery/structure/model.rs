//! The learned model of a structure's numerical part (`rths train nonlinear`: the
//! modal-hysteretic metamodel, `rths_core::metamodel::ModalHyst`, or the floor-hysteron one,
//! `rths_core::metamodel::FloorHysteron`) as the numerical part of the structure scenarios: core's
//! controller part [`StructureModal`] or [`StructureHysteron`] (tick 0 is the initial condition,
//! as the FE's; story drifts from the model's floors), loaded for one structure file and refused
//! for another.

use std::path::Path;

use anyhow::Context;
use rths_core::control::{Analytical, StructureHysteron, StructureModal};
use rths_core::params::DT_S;
use rths_files::hysteron_model_file::{AnyNlModel, HysteronModelFile};
use rths_files::nl_model_file::NlModelFile;

/// Refuse a nonlinear model trained at another controller rate than this build's (its springs were
/// fitted on the pure loop at its own step), with the command that trains one at this rate.
pub fn check_rate(file: &NlModelFile) -> Result<(), rths_files::rate::OtherRate> {
    rths_files::rate::check_dt(
        "the nonlinear model",
        file.dt_s,
        DT_S,
        &format!(
            "rths train nonlinear --structure {}.json --out FILE",
            file.structure.name
        ),
    )
}

/// The learned model of the model file `file` for the structure file whose text is
/// `structure_json`, at rest: refused with the reason unless it was trained for that structure
/// (name and checksum of its content) at this build's rate.
pub fn learned_model(file: &NlModelFile, structure_json: &str) -> anyhow::Result<StructureModal> {
    file.check_structure(structure_json)?;
    check_rate(file)?;
    // The parameters are continuous-time: built for this build's controller step.
    Ok(StructureModal::new(file.params(DT_S)?))
}

/// The floor-hysteron model of the model file `file` for the structure file whose text is
/// `structure_json`, at rest: refused with the reason unless it was trained for that structure at
/// this build's rate.
pub fn hysteron_model(
    file: &HysteronModelFile,
    structure_json: &str,
) -> anyhow::Result<StructureHysteron> {
    file.check_structure(structure_json)?;
    rths_files::rate::check_dt(
        "the nonlinear model",
        file.dt_s,
        DT_S,
        &format!(
            "rths train nonlinear --structure {}.json --histories ... --out FILE",
            file.structure.name
        ),
    )?;
    Ok(StructureHysteron::new(file.params(DT_S)?))
}

/// [`learned_model`] from the model file at `path` (a modal-hysteretic model file only; see
/// [`load_any`] for either form).
pub fn load(path: &Path, structure_json: &str) -> anyhow::Result<StructureModal> {
    let file = NlModelFile::load(path).with_context(|| format!("model {}", path.display()))?;
    learned_model(&file, structure_json)
        .with_context(|| format!("model {} refused", path.display()))
}

/// The controller part of the model file at `path`, of either form by the file's kind
/// ([`learned_model`] or [`hysteron_model`]).
pub fn load_any(path: &Path, structure_json: &str) -> anyhow::Result<Analytical> {
    let file = AnyNlModel::load(path).with_context(|| format!("model {}", path.display()))?;
    match &file {
        AnyNlModel::Modal(f) => learned_model(f, structure_json).map(Analytical::StructureModal),
        AnyNlModel::Hysteron(f) => {
            hysteron_model(f, structure_json).map(Analytical::StructureHysteron)
        }
    }
    .with_context(|| format!("model {} refused", path.display()))
}

/// The shipped learned models (`data/models/nl-S.json`, `rths train nonlinear`), by the name
/// of the structure they were trained for.
pub const SHIPPED: [(&str, &str); 3] = [
    (
        "paper-frame-yielding",
        include_str!("../../../data/models/nl-paper-frame-yielding.json"),
    ),
    (
        "shear3-yielding",
        include_str!("../../../data/models/nl-shear3-yielding.json"),
    ),
    (
        "shear8-yielding",
        include_str!("../../../data/models/nl-shear8-yielding.json"),
    ),
];

/// The learned model of the structure named `name` whose file's text is `structure_json`: the
/// model file at `path` if given, else the shipped one for that name. Refused with the reason if
/// there is none or it was trained for another structure (name and checksum).
pub fn for_structure(
    path: Option<&Path>,
    name: &str,
    structure_json: &str,
) -> anyhow::Result<Analytical> {
    if let Some(p) = path {
        return load_any(p, structure_json);
    }
    let Some((_, text)) = SHIPPED.iter().find(|(n, _)| *n == name) else {
        anyhow::bail!(
            "no shipped learned model of structure {name}: give --model M.json (`rths train \
             nonlinear --structure FILE --out M.json`)"
        );
    };
    let file = NlModelFile::from_json(text)
        .with_context(|| format!("the shipped data/models/nl-{name}.json"))?;
    learned_model(&file, structure_json)
        .map(Analytical::StructureModal)
        .with_context(|| format!("the shipped data/models/nl-{name}.json refused"))
}

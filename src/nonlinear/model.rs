//! The learned model of a structure's numerical part (`rths train nonlinear`: the
//! modal-hysteretic metamodel, `rths_core::metamodel::ModalHyst`, or the floor-hysteron one,
//! `rths_core::metamodel::FloorHysteron`) as a [`StructureModel`] of the
//! structure scenarios, loaded for one structure file and refused for another.

use std::path::Path;

use anyhow::Context;
use rths_core::control::{Analytical, StructureHysteron, StructureModal};
use rths_core::metamodel::{FloorHysteronParams, ModalHystParams};
use rths_core::params::DT_S;
use rths_files::hysteron_model_file::{AnyNlModel, HysteronModelFile};
use rths_files::nl_model_file::NlModelFile;

use super::scenario::StructureModel;

/// A learned model for the controller: core's [`StructureModal`] (tick 0 is the initial
/// condition, as the FE's; story drifts from the model's floors).
#[derive(Debug, Clone)]
pub struct LearnedModel {
    params: Box<Params>,
}

/// Either form's parameters (boxed once, in [`LearnedModel`]).
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
enum Params {
    Modal(ModalHystParams),
    Hysteron(FloorHysteronParams),
}

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

impl LearnedModel {
    /// The model file `file` for the structure file whose text is `structure_json`: refused with
    /// the reason unless it was trained for that structure (name and checksum of its content).
    pub fn new(file: &NlModelFile, structure_json: &str) -> anyhow::Result<Self> {
        file.check_structure(structure_json)?;
        check_rate(file)?;
        // The parameters are continuous-time: built for this build's controller step.
        Ok(Self {
            params: Box::new(Params::Modal(file.params(DT_S)?)),
        })
    }

    /// A floor-hysteron model file for the structure file whose text is `structure_json`, refused
    /// with the reason unless it was trained for that structure at this build's rate.
    pub fn hysteron(file: &HysteronModelFile, structure_json: &str) -> anyhow::Result<Self> {
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
        Ok(Self {
            params: Box::new(Params::Hysteron(file.params(DT_S)?)),
        })
    }

    /// [`Self::new`] (or [`Self::hysteron`], by the file's kind) from the model file at `path`.
    pub fn load(path: &Path, structure_json: &str) -> anyhow::Result<Self> {
        let file = AnyNlModel::load(path).with_context(|| format!("model {}", path.display()))?;
        match &file {
            AnyNlModel::Modal(f) => Self::new(f, structure_json),
            AnyNlModel::Hysteron(f) => Self::hysteron(f, structure_json),
        }
        .with_context(|| format!("model {} refused", path.display()))
    }
}

impl StructureModel for LearnedModel {
    fn analytical(&self) -> Analytical {
        match *self.params {
            Params::Modal(p) => Analytical::StructureModal(StructureModal::new(p)),
            Params::Hysteron(p) => Analytical::StructureHysteron(StructureHysteron::new(p)),
        }
    }
}

/// The shipped learned models (`data/models/nl-S.json`, `rths train nonlinear`), by the name
/// of the structure they were trained for.
pub const SHIPPED: [(&str, &str); 3] = [
    (
        "paper-frame-yielding",
        include_str!("../../data/models/nl-paper-frame-yielding.json"),
    ),
    (
        "shear3-yielding",
        include_str!("../../data/models/nl-shear3-yielding.json"),
    ),
    (
        "shear8-yielding",
        include_str!("../../data/models/nl-shear8-yielding.json"),
    ),
];

/// The learned model of the structure named `name` whose file's text is `structure_json`: the
/// model file at `path` if given, else the shipped one for that name. Refused with the reason if
/// there is none or it was trained for another structure (name and checksum).
pub fn for_structure(
    path: Option<&Path>,
    name: &str,
    structure_json: &str,
) -> anyhow::Result<LearnedModel> {
    if let Some(p) = path {
        return LearnedModel::load(p, structure_json);
    }
    let Some((_, text)) = SHIPPED.iter().find(|(n, _)| *n == name) else {
        anyhow::bail!(
            "no shipped learned model of structure {name}: give --model M.json (`rths train \
             nonlinear --structure FILE --out M.json`)"
        );
    };
    let file = NlModelFile::from_json(text)
        .with_context(|| format!("the shipped data/models/nl-{name}.json"))?;
    LearnedModel::new(&file, structure_json)
        .with_context(|| format!("the shipped data/models/nl-{name}.json refused"))
}

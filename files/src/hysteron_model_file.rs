//! Model files of the floor-hysteron metamodel (`rths train nonlinear`, docs/opensees-nonlinear.md "The
//! floor-hysteron form"): the `rths-nl-model` format with `kind: "floor-hysteron"`, tied to the
//! structure file it was trained for by the same checksum as the modal-hysteretic kind
//! ([`crate::nl_model_file`]).
//!
//! ```json
//! {"format": "rths-nl-model", "version": 1, "kind": "floor-hysteron",
//!  "structure": {"name": "opensees-fiber-frame", "checksum": "fnv1a64:…"},
//!  "dt_s": 0.00048828125, "floors": ["out_5_1_mm", "out_9_1_mm", "out_13_1_mm"],
//!  "specimen_floor": 0, "specimen_stiffness_kn_per_mm": 20.0,
//!  "mass": [[…]], "damping": [[…]], "stiffness": [[…]], "ground_mass": […],
//!  "directions": [[one number per floor], …],
//!  "operator": {"kind": "menegotto-pinto", "r0": 20.0, "cr1": 0.925, "cr2": 0.15},
//!  "hysterons": [{"direction": 0, "threshold_mm": 2.5, "weight_kn_per_mm": 4.1}, …],
//!  "training": {…provenance…}}
//! ```
//!
//! `operator` is the hysterons' operator: `{"kind": "play"}` (the default when absent) or the
//! Menegotto–Pinto play of that shape (`rths_core::metamodel::mp_play`).
//!
//! Every refusal names the field (`hysterons[3].weight_kn_per_mm: …`).

use std::path::Path;

use rths_core::metamodel::{
    FloorHysteronParams, FloorStructure, Hysteron, HysteronOperator, MpShape, HYST_MAX_DIRECTIONS,
    HYST_MAX_HYSTERONS, HYST_MAX_MP,
};
use rths_core::structure_n::MAX_DOF;
use serde::{Deserialize, Serialize};

use crate::nl_model_file::{
    check_kind, parse_header, pretty_json, read_text, write_text, NlModelFile, NlModelFileError,
    NlStructureId,
};

/// The `kind` of a floor-hysteron model file.
pub const HYSTERON_KIND: &str = "floor-hysteron";

/// One hysteron as the file stores it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HysteronSpec {
    /// Index into `directions`.
    pub direction: usize,
    /// Threshold, mm.
    pub threshold_mm: f64,
    /// Weight, kN/mm (≥ 0).
    pub weight_kn_per_mm: f64,
}

/// The hysterons' operator as the file stores it.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum OperatorSpec {
    /// The play (Masing's rule).
    #[default]
    Play,
    /// The Menegotto–Pinto play: `R₀`, `c_R1`, `c_R2`.
    MenegottoPinto {
        /// `R₀`.
        r0: f64,
        /// `c_R1`.
        cr1: f64,
        /// `c_R2`.
        cr2: f64,
    },
}

impl OperatorSpec {
    /// The core operator; a refusal names the field.
    pub fn operator(&self) -> Result<HysteronOperator, NlModelFileError> {
        match *self {
            OperatorSpec::Play => Ok(HysteronOperator::Play),
            OperatorSpec::MenegottoPinto { r0, cr1, cr2 } => MpShape::new(r0, cr1, cr2)
                .map(HysteronOperator::MenegottoPinto)
                .map_err(|e| field(format!("operator: {e}"))),
        }
    }

    /// How it reads in a report.
    pub fn describe(&self) -> String {
        match self {
            OperatorSpec::Play => "play".into(),
            OperatorSpec::MenegottoPinto { r0, cr1, cr2 } => {
                format!("Menegotto–Pinto play (R0 {r0}, cR1 {cr1}, cR2 {cr2})")
            }
        }
    }
}

/// How the model was trained (provenance; no wall time, so the same input writes the same bytes).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct HysteronTraining {
    /// The method.
    pub method: String,
    /// The seed (of the free fit's search, `--free-fit`; the least squares and the refinement are
    /// deterministic without it).
    pub seed: u64,
    /// The training histories.
    pub runs: Vec<String>,
    /// Ridge weight of the least-squares fit (relative to the Gram matrix's mean diagonal).
    pub ridge: f64,
    /// Factor the fitted weights were scaled by to keep the fully yielded tangent positive
    /// definite (1: not needed).
    pub stability_scale: f64,
    /// Relative RMS residual of the restoring-force fit over the training samples, %.
    pub force_fit_pct: f64,
    /// Mean floor NRMSE of the pure loop over the training histories, %.
    pub train_loss_pct: f64,
    /// How the form was chosen (validation losses), if it was.
    #[serde(default)]
    pub choice: String,
    /// Mean floor NRMSE of the pure loop over the training histories after the least-squares
    /// fit alone, %.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub least_squares_loss_pct: Option<f64>,
    /// Mean floor NRMSE of the pure loop over the validation histories (held out of the fit), %.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validation_loss_pct: Option<f64>,
    /// Each operator tried (its description) and its validation loss after the least-squares fit
    /// (mean floor NRMSE of the pure loop on the validation histories, or the training histories
    /// without any), %; the lowest was kept.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub operators_tried: Vec<(String, f64)>,
    /// The refinement on the simulation error, if it ran.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refinement: Option<RefinementRecord>,
    /// The free fit of the thresholds and the operator's shape off the least squares' grid
    /// (`--free-fit`), if it ran: what it did to each candidate refined, and whether it was kept.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub free_fit: Vec<String>,
}

/// What the refinement on the simulation error did (provenance).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RefinementRecord {
    /// Levenberg–Marquardt steps taken.
    pub steps: usize,
    /// The step whose parameters were kept (the lowest validation loss; 0: the least-squares
    /// fit).
    pub kept_step: usize,
    /// The factor on the lab's elastic stiffness (the file's `stiffness` has it applied).
    pub stiffness_scale: f64,
    /// The factor on the lab's damping (the file's `damping` has it applied).
    pub damping_scale: f64,
    /// Why it stopped.
    pub stopped: String,
}

/// A floor-hysteron model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HysteronModelFile {
    /// [`crate::nl_model_file::NL_FORMAT`].
    pub format: String,
    /// [`crate::nl_model_file::NL_VERSION`].
    pub version: u64,
    /// [`HYSTERON_KIND`].
    pub kind: String,
    /// The structure file it was trained for.
    pub structure: NlStructureId,
    /// The control step it was trained at, s (the parameters are continuous-time).
    pub dt_s: f64,
    /// The floors' history columns (`out_<NODE>_<DOF>_mm`), the model's DOFs in order.
    pub floors: Vec<String>,
    /// The specimen's floor, 0-based.
    pub specimen_floor: usize,
    /// The specimen's nominal stiffness, kN/mm.
    pub specimen_stiffness_kn_per_mm: f64,
    /// Mass, kN·s²/mm, floors × floors.
    pub mass: Vec<Vec<f64>>,
    /// Damping, kN·s/mm.
    pub damping: Vec<Vec<f64>>,
    /// The numerical part's elastic stiffness (specimen out), kN/mm.
    pub stiffness: Vec<Vec<f64>>,
    /// `M·ι`, kN·s²/mm.
    pub ground_mass: Vec<f64>,
    /// The directions the hysterons act along, each one number per floor.
    pub directions: Vec<Vec<f64>>,
    /// The hysterons' operator.
    #[serde(default)]
    pub operator: OperatorSpec,
    /// The hysterons.
    pub hysterons: Vec<HysteronSpec>,
    /// Provenance.
    #[serde(default)]
    pub training: HysteronTraining,
}

/// A nonlinear model file of either kind.
// A file is read once per command: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub enum AnyNlModel {
    /// `modal-hysteretic`.
    Modal(NlModelFile),
    /// `floor-hysteron`.
    Hysteron(HysteronModelFile),
}

impl AnyNlModel {
    /// Parse and validate a model file of either kind (chosen by its `kind`).
    pub fn from_json(text: &str) -> Result<Self, NlModelFileError> {
        let v: serde_json::Value = serde_json::from_str(text)?;
        if v.get("kind").and_then(|k| k.as_str()) == Some(HYSTERON_KIND) {
            Ok(Self::Hysteron(HysteronModelFile::from_json(text)?))
        } else {
            Ok(Self::Modal(NlModelFile::from_json(text)?))
        }
    }

    /// Read and validate.
    pub fn load(path: &Path) -> Result<Self, NlModelFileError> {
        Self::from_json(&read_text(path)?)
    }

    /// The structure it was trained for.
    pub fn structure(&self) -> &NlStructureId {
        match self {
            Self::Modal(m) => &m.structure,
            Self::Hysteron(h) => &h.structure,
        }
    }

    /// The step it was trained at, s.
    pub fn dt_s(&self) -> f64 {
        match self {
            Self::Modal(m) => m.dt_s,
            Self::Hysteron(h) => h.dt_s,
        }
    }

    /// Refuse it unless it was trained for this structure file.
    pub fn check_structure(&self, structure_json: &str) -> Result<(), NlModelFileError> {
        match self {
            Self::Modal(m) => m.check_structure(structure_json),
            Self::Hysteron(h) => h.check_structure(structure_json),
        }
    }
}

fn field(what: String) -> NlModelFileError {
    NlModelFileError::Shape(what)
}

impl HysteronModelFile {
    /// Parse and validate.
    pub fn from_json(text: &str) -> Result<Self, NlModelFileError> {
        let v = parse_header(text)?;
        let f: Self = serde_json::from_value(v)?;
        check_kind(&f.kind, HYSTERON_KIND)?;
        f.params(f.dt_s)?;
        Ok(f)
    }

    /// Read and validate a file.
    pub fn load(path: &Path) -> Result<Self, NlModelFileError> {
        Self::from_json(&read_text(path)?)
    }

    /// Pretty JSON with a final newline.
    pub fn to_json(&self) -> Result<String, NlModelFileError> {
        pretty_json(self)
    }

    /// Write the file.
    pub fn save(&self, path: &Path) -> Result<(), NlModelFileError> {
        write_text(path, &self.to_json()?)
    }

    /// Refuse the model unless it was trained for this structure file (name and checksum).
    pub fn check_structure(&self, structure_json: &str) -> Result<(), NlModelFileError> {
        self.structure.check(structure_json)
    }

    /// The validated core parameters at control step `dt_s`; a refusal names the field.
    pub fn params(&self, dt_s: f64) -> Result<FloorHysteronParams, NlModelFileError> {
        let n = self.floors.len();
        if n == 0 || n > MAX_DOF {
            return Err(field(format!("floors: {n} floors (1..={MAX_DOF})")));
        }
        let square = |name: &str, m: &[Vec<f64>]| -> Result<Vec<f64>, NlModelFileError> {
            if m.len() != n {
                return Err(field(format!(
                    "{name}: {} rows, expected {n} (one per floor)",
                    m.len()
                )));
            }
            let mut out = Vec::with_capacity(n * n);
            for (i, row) in m.iter().enumerate() {
                if row.len() != n {
                    return Err(field(format!(
                        "{name}[{i}]: {} entries, expected {n}",
                        row.len()
                    )));
                }
                if let Some(j) = row.iter().position(|v| !v.is_finite()) {
                    return Err(field(format!("{name}[{i}][{j}]: not a finite number")));
                }
                out.extend_from_slice(row);
            }
            Ok(out)
        };
        let mass = square("mass", &self.mass)?;
        let damping = square("damping", &self.damping)?;
        let stiffness = square("stiffness", &self.stiffness)?;
        if self.ground_mass.len() != n {
            return Err(field(format!(
                "ground_mass: {} entries, expected {n}",
                self.ground_mass.len()
            )));
        }
        if self.specimen_floor >= n {
            return Err(field(format!(
                "specimen_floor: {} is past the {n} floors",
                self.specimen_floor
            )));
        }
        if !(self.specimen_stiffness_kn_per_mm.is_finite()
            && self.specimen_stiffness_kn_per_mm >= 0.0)
        {
            return Err(field(format!(
                "specimen_stiffness_kn_per_mm: {} (a finite stiffness ≥ 0)",
                self.specimen_stiffness_kn_per_mm
            )));
        }
        let d = self.directions.len();
        if d == 0 || d > HYST_MAX_DIRECTIONS {
            return Err(field(format!(
                "directions: {d} directions (1..={HYST_MAX_DIRECTIONS})"
            )));
        }
        let directions = square_rows("directions", &self.directions, n)?;
        let h = self.hysterons.len();
        if h == 0 || h > HYST_MAX_HYSTERONS {
            return Err(field(format!(
                "hysterons: {h} hysterons (1..={HYST_MAX_HYSTERONS})"
            )));
        }
        for (i, x) in self.hysterons.iter().enumerate() {
            if x.direction >= d {
                return Err(field(format!(
                    "hysterons[{i}].direction: {} is past the {d} directions",
                    x.direction
                )));
            }
            if !(x.threshold_mm.is_finite() && x.threshold_mm > 0.0) {
                return Err(field(format!(
                    "hysterons[{i}].threshold_mm: {} (a finite threshold > 0)",
                    x.threshold_mm
                )));
            }
            if !(x.weight_kn_per_mm.is_finite() && x.weight_kn_per_mm >= 0.0) {
                return Err(field(format!(
                    "hysterons[{i}].weight_kn_per_mm: {} (a finite weight ≥ 0)",
                    x.weight_kn_per_mm
                )));
            }
        }
        let hs: Vec<Hysteron> = self
            .hysterons
            .iter()
            .map(|x| Hysteron {
                direction: x.direction,
                threshold_mm: x.threshold_mm,
                weight_kn_per_mm: x.weight_kn_per_mm,
            })
            .collect();
        let op = self.operator.operator()?;
        if matches!(op, HysteronOperator::MenegottoPinto(_)) && hs.len() > HYST_MAX_MP {
            return Err(field(format!(
                "hysterons: {} Menegotto–Pinto hysterons (1..={HYST_MAX_MP})",
                hs.len()
            )));
        }
        Ok(FloorHysteronParams::new(
            dt_s,
            &FloorStructure {
                floors: n,
                mass: &mass,
                damping: &damping,
                stiffness: &stiffness,
                ground_mass: &self.ground_mass,
                specimen_floor: self.specimen_floor,
                specimen_k_kn_per_mm: self.specimen_stiffness_kn_per_mm,
            },
            &directions,
            &hs,
        )?
        .with_operator(op)?)
    }
}

/// Rows of `n` finite numbers each, flattened; a refusal names the row and column.
fn square_rows(name: &str, m: &[Vec<f64>], n: usize) -> Result<Vec<f64>, NlModelFileError> {
    let mut out = Vec::with_capacity(m.len() * n);
    for (i, row) in m.iter().enumerate() {
        if row.len() != n {
            return Err(field(format!(
                "{name}[{i}]: {} entries, expected {n} (one per floor)",
                row.len()
            )));
        }
        if let Some(j) = row.iter().position(|v| !v.is_finite()) {
            return Err(field(format!("{name}[{i}][{j}]: not a finite number")));
        }
        if row.iter().all(|v| *v == 0.0) {
            return Err(field(format!("{name}[{i}]: all zero")));
        }
        out.extend_from_slice(row);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file() -> HysteronModelFile {
        HysteronModelFile {
            format: crate::nl_model_file::NL_FORMAT.into(),
            version: crate::nl_model_file::NL_VERSION,
            kind: HYSTERON_KIND.into(),
            structure: NlStructureId {
                name: "s".into(),
                checksum: "fnv1a64:0".into(),
            },
            dt_s: 1.0 / 2048.0,
            floors: vec!["out_1_1_mm".into(), "out_2_1_mm".into()],
            specimen_floor: 0,
            specimen_stiffness_kn_per_mm: 10.0,
            mass: vec![vec![1.0, 0.0], vec![0.0, 1.0]],
            damping: vec![vec![0.1, 0.0], vec![0.0, 0.1]],
            stiffness: vec![vec![300.0, -100.0], vec![-100.0, 100.0]],
            ground_mass: vec![1.0, 1.0],
            directions: vec![vec![1.0, 0.0], vec![-1.0, 1.0]],
            operator: OperatorSpec::Play,
            hysterons: vec![
                HysteronSpec {
                    direction: 0,
                    threshold_mm: 1.0,
                    weight_kn_per_mm: 50.0,
                },
                HysteronSpec {
                    direction: 1,
                    threshold_mm: 2.0,
                    weight_kn_per_mm: 40.0,
                },
            ],
            training: HysteronTraining::default(),
        }
    }

    #[test]
    fn round_trip_and_either_kind() {
        let f = file();
        let text = f.to_json().unwrap();
        assert_eq!(HysteronModelFile::from_json(&text).unwrap(), f);
        assert!(matches!(
            AnyNlModel::from_json(&text).unwrap(),
            AnyNlModel::Hysteron(_)
        ));
    }

    #[test]
    fn the_menegotto_pinto_operator_round_trips_and_a_file_without_one_is_of_plays() {
        let mut f = file();
        f.operator = OperatorSpec::MenegottoPinto {
            r0: 20.0,
            cr1: 0.925,
            cr2: 0.15,
        };
        let text = f.to_json().unwrap();
        assert!(text.contains("\"kind\": \"menegotto-pinto\""), "{text}");
        assert_eq!(HysteronModelFile::from_json(&text).unwrap(), f);
        assert!(matches!(
            f.params(f.dt_s).unwrap().operator(),
            HysteronOperator::MenegottoPinto(_)
        ));
        let old = file()
            .to_json()
            .unwrap()
            .replace("  \"operator\": {\n    \"kind\": \"play\"\n  },\n", "");
        assert!(!old.contains("operator"), "{old}");
        assert_eq!(
            HysteronModelFile::from_json(&old).unwrap().operator,
            OperatorSpec::Play
        );
    }

    #[test]
    fn refusals_name_the_field() {
        let check = |edit: &dyn Fn(&mut HysteronModelFile), want: &str| {
            let mut f = file();
            edit(&mut f);
            let text = f.to_json().unwrap();
            let e = HysteronModelFile::from_json(&text).unwrap_err().to_string();
            assert!(e.contains(want), "{e} (wanted {want})");
        };
        check(
            &|f| f.hysterons[1].weight_kn_per_mm = -1.0,
            "hysterons[1].weight_kn_per_mm",
        );
        check(
            &|f| f.hysterons[0].threshold_mm = 0.0,
            "hysterons[0].threshold_mm",
        );
        check(&|f| f.hysterons[0].direction = 5, "hysterons[0].direction");
        check(&|f| f.mass[1].pop().map(|_| ()).unwrap(), "mass[1]");
        check(
            &|f| f.stiffness.pop().map(|_| ()).unwrap(),
            "stiffness: 1 rows",
        );
        check(&|f| f.ground_mass.push(1.0), "ground_mass");
        check(&|f| f.specimen_floor = 2, "specimen_floor");
        check(
            &|f| f.directions[1] = vec![0.0, 0.0],
            "directions[1]: all zero",
        );
        check(&|f| f.directions.clear(), "directions: 0");
        check(&|f| f.kind = "x".into(), "kind");
        check(&|f| f.version = 9, "version 9");
        check(
            &|f| f.hysterons[0].weight_kn_per_mm = 250.0,
            "positive definite",
        );
        check(&|f| f.stiffness[0][1] = -90.0, "symmetric");
        check(&|f| f.mass[0][0] = -1.0, "mass");
        check(
            &|f| {
                f.operator = OperatorSpec::MenegottoPinto {
                    r0: 20.0,
                    cr1: 1.5,
                    cr2: 0.15,
                }
            },
            "operator: ",
        );
        check(
            &|f| {
                f.operator = OperatorSpec::MenegottoPinto {
                    r0: 20.0,
                    cr1: 0.5,
                    cr2: 0.15,
                };
                f.hysterons = vec![f.hysterons[0]; 33];
                for h in &mut f.hysterons {
                    h.weight_kn_per_mm = 1.0;
                }
            },
            "33 Menegotto–Pinto hysterons",
        );
        let text = file()
            .to_json()
            .unwrap()
            .replace("\"dt_s\": 0.00048828125", "\"dt_s\": -1");
        let e = HysteronModelFile::from_json(&text).unwrap_err().to_string();
        assert!(e.contains("time step"), "{e}");
    }
}

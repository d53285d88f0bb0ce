//! Model files of the nonlinear (modal-hysteretic) metamodel: versioned JSON tied to the structure
//! file it was trained for, validated on load.
//!
//! ```json
//! {"format": "rths-nl-model", "version": 1, "kind": "modal-hysteretic",
//!  "structure": {"name": "paper-frame-yielding", "checksum": "fnv1a64:…"},
//!  "dt_s": 0.00048828125, "specimen_dof": 0, "specimen_stiffness_kn_per_mm": 622.54,
//!  "modes": [{"omega_rad_s": x, "damping_ratio": x, "ground_participation": x}],
//!  "shape": [[one number per mode] per floor],
//!  "springs": [{"law": "bouc-wen", "k0_kn_per_mm": x, "yield_force_kn": x,
//!               "post_yield_ratio": x, "exponent": x, "beta": x, "gamma": x,
//!               "drift": [one number per mode]}],
//!  "training": {...provenance...}}
//! ```
//!
//! The checksum is of the structure file's *canonical content*: its JSON re-serialized without
//! whitespace and without the free-text `description`, so reformatting or re-describing a
//! structure keeps its models, and any change of a number refuses them
//! ([`NlModelFile::check_structure`]). The model's parameters are continuous-time (frequencies,
//! laws), so [`NlModelFile::params`] builds them for any control step.

use std::path::{Path, PathBuf};

use rths_core::checksum::{fnv1a64, Fnv1a64Label};
use rths_core::hysteresis::Law;
use rths_core::metamodel::{
    ModalHystParams, ModalMode, ModelError, MODAL_MAX_FLOORS, MODAL_MAX_MODES, MODAL_MAX_SPRINGS,
};
use serde::{Deserialize, Serialize};

/// The `format` tag of a nonlinear model file.
pub const NL_FORMAT: &str = "rths-nl-model";
/// The version this code reads and writes.
pub const NL_VERSION: u64 = 1;
/// The only kind so far.
pub const NL_KIND: &str = "modal-hysteretic";

/// Which structure file a model was trained for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NlStructureId {
    /// The structure's `name`.
    pub name: String,
    /// [`structure_checksum`] of the structure file.
    pub checksum: String,
}

/// One latent spring: its law and its drift per unit of each mode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SpringSpec {
    /// `"bouc-wen"` or `"bilinear"`.
    pub law: String,
    /// Initial stiffness, kN/mm.
    pub k0_kn_per_mm: f64,
    /// Yield force, kN.
    pub yield_force_kn: f64,
    /// Post-yield stiffness ratio α.
    pub post_yield_ratio: f64,
    /// Bouc–Wen exponent n (ignored for bilinear).
    #[serde(default)]
    pub exponent: f64,
    /// Bouc–Wen β.
    #[serde(default)]
    pub beta: f64,
    /// Bouc–Wen γ.
    #[serde(default)]
    pub gamma: f64,
    /// Drift per unit of each mode's coordinate.
    pub drift: Vec<f64>,
}

impl SpringSpec {
    /// The validated core law.
    pub fn law(&self) -> Result<Law, rths_core::params::ParamError> {
        match self.law.as_str() {
            "bilinear" => Law::bilinear(
                self.k0_kn_per_mm,
                self.yield_force_kn,
                self.post_yield_ratio,
            ),
            "bouc-wen" => Law::bouc_wen(
                self.k0_kn_per_mm,
                self.yield_force_kn,
                self.post_yield_ratio,
                self.exponent,
                self.beta,
                self.gamma,
            ),
            _ => Err(rths_core::params::ParamError::OutOfRange(
                "spring law (\"bouc-wen\" or \"bilinear\")",
            )),
        }
    }
}

/// One mode (serialized form of [`ModalMode`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ModeSpec {
    /// rad/s.
    pub omega_rad_s: f64,
    /// Modal damping ratio.
    pub damping_ratio: f64,
    /// `φᵀMι` of the mass-normalized mode.
    pub ground_participation: f64,
}

/// How the model was trained (provenance; no wall time, so the same seed writes the same bytes).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct NlTraining {
    /// `"cma-es"`.
    pub method: String,
    /// Seed of the random initialization and of the search.
    pub seed: u64,
    /// Training runs, `record:scale` (ductility of the FE run in brackets).
    pub runs: Vec<String>,
    /// Generations run.
    pub generations: usize,
    /// Population size.
    pub population: usize,
    /// Loss of the initial (random) parameters and of the result: mean NRMSE over runs, %.
    pub initial_loss_pct: f64,
    /// Final training loss, %.
    pub final_loss_pct: f64,
    /// The largest training-run NRMSE of the specimen DOF, %.
    pub max_train_nrmse_pct: f64,
}

/// A nonlinear model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NlModelFile {
    /// [`NL_FORMAT`].
    pub format: String,
    /// [`NL_VERSION`].
    pub version: u64,
    /// [`NL_KIND`].
    pub kind: String,
    /// The structure file it was trained for.
    pub structure: NlStructureId,
    /// The control step it was trained at, s (the parameters suit any step).
    pub dt_s: f64,
    /// The specimen's DOF, 0-based.
    pub specimen_dof: usize,
    /// The specimen's stiffness the modes include, kN/mm.
    pub specimen_stiffness_kn_per_mm: f64,
    /// The modes.
    pub modes: Vec<ModeSpec>,
    /// `shape[floor][mode]`.
    pub shape: Vec<Vec<f64>>,
    /// The latent springs.
    pub springs: Vec<SpringSpec>,
    /// Provenance.
    #[serde(default)]
    pub training: NlTraining,
}

/// Why a nonlinear model file was refused.
#[derive(Debug, thiserror::Error)]
pub enum NlModelFileError {
    /// Reading or writing failed.
    #[error("cannot access model file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Not JSON of this schema.
    #[error("malformed nonlinear model file: {0}")]
    Json(#[from] serde_json::Error),
    /// Another format, version or kind.
    #[error("not a nonlinear model file this build reads: {0}")]
    Format(String),
    /// Trained for another structure.
    #[error(
        "this model was trained for structure \"{model_name}\" ({model_checksum}), not for \"{given_name}\" ({given_checksum}): retrain it with `rths train nonlinear --structure FILE`"
    )]
    WrongStructure {
        /// The structure the model is for.
        model_name: String,
        /// Its checksum.
        model_checksum: String,
        /// The structure given.
        given_name: String,
        /// Its checksum.
        given_checksum: String,
    },
    /// The parameters fail validation.
    #[error("invalid model: {0}")]
    Model(#[from] ModelError),
    /// A spring law fails validation.
    #[error("spring {spring}: {source}")]
    Law {
        /// 0-based spring.
        spring: usize,
        /// The cause.
        source: rths_core::params::ParamError,
    },
    /// Shapes disagree.
    #[error("wrong shape: {0}")]
    Shape(String),
}

/// FNV-1a (64 bit) of the structure file's canonical content (see the module docs),
/// `"fnv1a64:<16 hex>"`. A text that is not JSON is refused.
pub fn structure_checksum(structure_json: &str) -> Result<String, NlModelFileError> {
    let mut v: serde_json::Value = serde_json::from_str(structure_json)?;
    if let Some(o) = v.as_object_mut() {
        o.remove("description");
    }
    let canon = serde_json::to_string(&v)?;
    Ok(Fnv1a64Label(fnv1a64(canon.as_bytes())).to_string())
}

/// The structure's `name` field (for the refusal message), or `"?"`.
fn structure_name(structure_json: &str) -> String {
    serde_json::from_str::<serde_json::Value>(structure_json)
        .ok()
        .and_then(|v| v.get("name").and_then(|n| n.as_str()).map(str::to_string))
        .unwrap_or_else(|| "?".to_string())
}

impl NlStructureId {
    /// Refuse the model unless it was trained for this structure file (name and checksum of its
    /// canonical content), with the reason.
    pub fn check(&self, structure_json: &str) -> Result<(), NlModelFileError> {
        let checksum = structure_checksum(structure_json)?;
        let name = structure_name(structure_json);
        if checksum == self.checksum && name == self.name {
            Ok(())
        } else {
            Err(NlModelFileError::WrongStructure {
                model_name: self.name.clone(),
                model_checksum: self.checksum.clone(),
                given_name: name,
                given_checksum: checksum,
            })
        }
    }
}

/// Parse a learned model file's JSON and refuse it unless its format is [`NL_FORMAT`] and its
/// version [`NL_VERSION`]: checked before the fields, so a future file gives a version error.
pub(crate) fn parse_header(text: &str) -> Result<serde_json::Value, NlModelFileError> {
    let v: serde_json::Value = serde_json::from_str(text)?;
    let format = v.get("format").and_then(|f| f.as_str()).unwrap_or("");
    if format != NL_FORMAT {
        return Err(NlModelFileError::Format(format!(
            "format {format:?}, expected \"{NL_FORMAT}\""
        )));
    }
    let version = v.get("version").and_then(|f| f.as_u64()).unwrap_or(0);
    if version != NL_VERSION {
        return Err(NlModelFileError::Format(format!(
            "version {version}, this build reads {NL_VERSION}"
        )));
    }
    Ok(v)
}

/// Refuse a model whose `kind` is not `expected`.
pub(crate) fn check_kind(kind: &str, expected: &str) -> Result<(), NlModelFileError> {
    if kind == expected {
        Ok(())
    } else {
        Err(NlModelFileError::Format(format!(
            "kind {kind:?}, expected \"{expected}\""
        )))
    }
}

/// The text of the file at `path`.
pub(crate) fn read_text(path: &Path) -> Result<String, NlModelFileError> {
    std::fs::read_to_string(path).map_err(|source| NlModelFileError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Pretty JSON with a final newline.
pub(crate) fn pretty_json<T: Serialize>(model: &T) -> Result<String, NlModelFileError> {
    Ok(serde_json::to_string_pretty(model)? + "\n")
}

/// Write `text` to `path`.
pub(crate) fn write_text(path: &Path, text: &str) -> Result<(), NlModelFileError> {
    std::fs::write(path, text).map_err(|source| NlModelFileError::Io {
        path: path.to_path_buf(),
        source,
    })
}

impl NlModelFile {
    /// Parse and validate.
    pub fn from_json(text: &str) -> Result<Self, NlModelFileError> {
        let v = parse_header(text)?;
        let f: Self = serde_json::from_value(v)?;
        check_kind(&f.kind, NL_KIND)?;
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

    /// Refuse the model unless it was trained for this structure file (name and checksum of its
    /// canonical content), with the reason.
    pub fn check_structure(&self, structure_json: &str) -> Result<(), NlModelFileError> {
        self.structure.check(structure_json)
    }

    /// Read the model at `model` and refuse it unless it is for the structure file at `structure`.
    pub fn load_for(model: &Path, structure: &Path) -> Result<Self, NlModelFileError> {
        let f = Self::load(model)?;
        f.check_structure(&read_text(structure)?)?;
        Ok(f)
    }

    /// The validated core parameters for a control step `dt_s`.
    pub fn params(&self, dt_s: f64) -> Result<ModalHystParams, NlModelFileError> {
        let r = self.modes.len();
        if r == 0 || r > MODAL_MAX_MODES {
            return Err(NlModelFileError::Shape(format!(
                "{r} modes (1..={MODAL_MAX_MODES})"
            )));
        }
        if self.shape.is_empty() || self.shape.len() > MODAL_MAX_FLOORS {
            return Err(NlModelFileError::Shape(format!(
                "{} floors in shape (1..={MODAL_MAX_FLOORS})",
                self.shape.len()
            )));
        }
        if self.springs.is_empty() || self.springs.len() > MODAL_MAX_SPRINGS {
            return Err(NlModelFileError::Shape(format!(
                "{} springs (1..={MODAL_MAX_SPRINGS})",
                self.springs.len()
            )));
        }
        if let Some(row) = self.shape.iter().find(|row| row.len() != r) {
            return Err(NlModelFileError::Shape(format!(
                "a shape row has {} entries, expected {r} (one per mode)",
                row.len()
            )));
        }
        if let Some(s) = self.springs.iter().find(|s| s.drift.len() != r) {
            return Err(NlModelFileError::Shape(format!(
                "a spring's drift has {} entries, expected {r} (one per mode)",
                s.drift.len()
            )));
        }
        let modes: Vec<ModalMode> = self
            .modes
            .iter()
            .map(|m| ModalMode {
                omega_rad_s: m.omega_rad_s,
                damping_ratio: m.damping_ratio,
                ground_participation: m.ground_participation,
            })
            .collect();
        let laws = self
            .springs
            .iter()
            .enumerate()
            .map(|(spring, s)| {
                s.law()
                    .map_err(|source| NlModelFileError::Law { spring, source })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let shape: Vec<f64> = self.shape.iter().flatten().copied().collect();
        let drift: Vec<f64> = self
            .springs
            .iter()
            .flat_map(|s| s.drift.iter().copied())
            .collect();
        Ok(ModalHystParams::new(
            dt_s,
            &modes,
            &shape,
            self.specimen_dof,
            self.specimen_stiffness_kn_per_mm,
            &laws,
            &drift,
        )?)
    }
}

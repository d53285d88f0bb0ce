//! The reduced-order model's file (`rths-reduced-model`, written by `rths train meta` on an
//! imported structure; docs/opensees.md "The reduced model"): its schema, its reader and the arrays
//! core's controller runs (`rths_core::control::ReducedSpec`), for the host commands and the
//! firmware's build script alike. The file is tied to its structure by name and a checksum of the
//! structure's condensed matrices, which only the host can compute: [`StructureIdentity`].

use std::path::Path;

use rths_core::control::ReducedSpec;
use rths_core::metamodel::{
    ModelError, ReducedMode, StaticCorrection, REDUCED_MAX_MODES, REDUCED_MAX_OUTPUTS,
};
use serde::{Deserialize, Serialize};

/// The `format` tag of a reduced model file.
pub const REDUCED_FORMAT: &str = "rths-reduced-model";
/// The version of a reduced model file.
pub const REDUCED_VERSION: u64 = 1;
/// Why a reduced model file could not be read or used.
#[derive(Debug, thiserror::Error)]
pub enum ReducedFileError {
    /// The parameters failed core's validation.
    #[error("the reduced model's parameters: {0}")]
    Model(ModelError),
    /// The file is not JSON of the right shape.
    #[error("not a reduced model file: {0}")]
    Json(#[from] serde_json::Error),
    /// The file has another format or version.
    #[error("format {format:?} version {version}, expected {REDUCED_FORMAT:?} version {REDUCED_VERSION}")]
    Format {
        /// The file's format tag.
        format: String,
        /// The file's version.
        version: u64,
    },
    /// The file was trained for another structure.
    #[error(
        "trained for structure {file_name} ({file_checksum}), not {name} ({checksum}): run `rths train meta --structure` on this structure"
    )]
    Structure {
        /// The file's structure name.
        file_name: String,
        /// The file's structure checksum.
        file_checksum: String,
        /// The structure's name.
        name: String,
        /// The structure's checksum.
        checksum: String,
    },
    /// The file was trained for a structure of another name (a reader that cannot compute the
    /// checksum checks the name alone).
    #[error("trained for structure {file_name}, not {name}: run `rths train meta --structure` on this structure")]
    StructureName {
        /// The file's structure name.
        file_name: String,
        /// The structure's name.
        name: String,
    },
    /// An output's shape array has the wrong length.
    #[error("mode {mode}: {got} output shapes for {expected} outputs")]
    Shape {
        /// Mode index (0-based).
        mode: usize,
        /// Shapes given.
        got: usize,
        /// Outputs of the file.
        expected: usize,
    },
    /// The file holds more modes or outputs than the controller runs.
    #[error("{count} {what}, the controller runs at most {max}")]
    Count {
        /// `modes` or `outputs`.
        what: &'static str,
        /// How many the file holds.
        count: usize,
        /// The controller's limit.
        max: usize,
    },
    /// The file was trained at another controller rate (the rule of every file made at a
    /// controller rate, [`crate::rate::check_dt`]): its modes are continuous-time, but its mode
    /// count and its recorded error bound were measured at its own step.
    #[error(transparent)]
    OtherRate(#[from] crate::rate::OtherRate),
    /// Reading the file failed.
    #[error("reading {path}: {source}")]
    Read {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

impl From<ModelError> for ReducedFileError {
    fn from(e: ModelError) -> Self {
        ReducedFileError::Model(e)
    }
}

/// What a reduced model file is checked against: the structure's name and the checksum of what it
/// is (the host's imported structure computes it from its condensed matrices).
pub trait StructureIdentity {
    /// The structure's name.
    fn name(&self) -> &str;
    /// The checksum the file records (`fnv1a64:…`).
    fn checksum(&self) -> String;
}

/// One retained mode as the file stores it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReducedModeEntry {
    /// Natural frequency, Hz (for the reader; `omega_rad_s` is used).
    pub frequency_hz: f64,
    /// Natural circular frequency, rad/s.
    pub omega_rad_s: f64,
    /// Modal damping ratio.
    pub damping_ratio: f64,
    /// Ground participation `φᵀM*ι*`.
    pub ground_participation: f64,
    /// The shape at the interface.
    pub interface_shape: f64,
    /// The shape at each output, in the file's `outputs` order.
    pub output_shape: Vec<f64>,
}

/// A read-out's static correction as the file stores it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StaticEntry {
    /// The truncated modes' static response to a unit ground acceleration, mm per mm/s².
    pub ground_mm_per_mm_s2: f64,
    /// The truncated modes' static response to a unit interface force, mm/kN.
    pub force_mm_per_kn: f64,
}

impl From<StaticEntry> for StaticCorrection {
    fn from(s: StaticEntry) -> Self {
        StaticCorrection {
            ground_mm_per_mm_s2: s.ground_mm_per_mm_s2,
            force_mm_per_kn: s.force_mm_per_kn,
        }
    }
}

/// One training record's pure-loop error against the host FE.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReducedRecordError {
    /// The record.
    pub record: String,
    /// The interface's NRMSE, %.
    pub interface_nrmse_pct: f64,
    /// The largest output NRMSE, %.
    pub max_output_nrmse_pct: f64,
}

/// How the model was trained, and its error bound.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReducedTraining {
    /// The training records (embedded names).
    pub records: Vec<String>,
    /// The pure-loop target the mode count was chosen for, % NRMSE.
    pub target_nrmse_pct: f64,
    /// The largest pure-loop NRMSE over the training records and read-outs, %: the model's error
    /// bound as measured.
    pub error_bound_pct: f64,
    /// Per record.
    pub per_record: Vec<ReducedRecordError>,
    /// The structure's modes (all of them: the condensed model's DOF count).
    pub total_modes: usize,
    /// The lowest truncated mode's frequency, Hz (none when all are kept).
    pub lowest_truncated_hz: Option<f64>,
    /// The largest off-diagonal modal damping `|φᵢᵀCφⱼ| / √(cᵢᵢcⱼⱼ)` among the retained modes:
    /// how far the damping is from classical (0: the modes decouple exactly).
    pub damping_coupling: f64,
}

/// The reduced model's file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReducedModelFile {
    /// [`REDUCED_FORMAT`].
    pub format: String,
    /// [`REDUCED_VERSION`].
    pub version: u64,
    /// The structure's name.
    pub structure: String,
    /// The structure's checksum ([`StructureIdentity::checksum`]).
    pub structure_checksum: String,
    /// The control step it was trained (its size chosen) at, s; the modes are continuous-time and
    /// run at any step.
    pub dt_s: f64,
    /// The whole model's DOFs.
    pub dofs: usize,
    /// The DOFs that carry mass.
    pub mass_dofs: usize,
    /// The stand-in specimen's stiffness the modes include, kN/mm.
    pub specimen_k_kn_per_mm: f64,
    /// The outputs' column names (`out_<NODE>_<DOF>_mm`).
    pub outputs: Vec<String>,
    /// The retained modes, lowest first.
    pub modes: Vec<ReducedModeEntry>,
    /// The interface's static correction.
    pub interface_static: StaticEntry,
    /// The outputs' static corrections.
    pub output_static: Vec<StaticEntry>,
    /// How it was trained.
    pub training: ReducedTraining,
}

/// The arrays a [`ReducedSpec`] borrows.
#[derive(Debug, Clone, PartialEq)]
pub struct ReducedArrays {
    modes: Vec<ReducedMode>,
    output_shape: Vec<f64>,
    interface_static: StaticCorrection,
    output_static: Vec<StaticCorrection>,
    specimen_k_kn_per_mm: f64,
}

impl ReducedArrays {
    /// The controller's model spec over these arrays.
    pub fn spec(&self) -> ReducedSpec<'_> {
        ReducedSpec {
            modes: &self.modes,
            output_shape: &self.output_shape,
            interface_static: self.interface_static,
            output_static: &self.output_static,
            specimen_k_kn_per_mm: self.specimen_k_kn_per_mm,
        }
    }
}

impl ReducedModelFile {
    /// Parse and check the format.
    pub fn from_json(text: &str) -> Result<Self, ReducedFileError> {
        let f: Self = serde_json::from_str(text)?;
        if f.format != REDUCED_FORMAT || f.version != REDUCED_VERSION {
            return Err(ReducedFileError::Format {
                format: f.format,
                version: f.version,
            });
        }
        Ok(f)
    }

    /// Read `path`.
    pub fn load(path: &Path) -> Result<Self, ReducedFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| ReducedFileError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text)
    }

    /// Pretty JSON (shortest round-trip numbers: the same model gives the same bytes).
    pub fn to_json(&self) -> Result<String, ReducedFileError> {
        Ok(serde_json::to_string_pretty(self)? + "\n")
    }

    /// Whether `text` looks like a reduced model file.
    pub fn is_reduced(text: &str) -> bool {
        #[derive(Deserialize)]
        struct Header {
            format: Option<String>,
        }
        serde_json::from_str::<Header>(text)
            .map(|h| h.format.as_deref() == Some(REDUCED_FORMAT))
            .unwrap_or(false)
    }

    /// Refuse the file unless it was trained at the controller step `dt_s` (within
    /// [`crate::rate::DT_TOLERANCE`], as every file made at a controller rate). Its arrays would
    /// run at any step, but the training chose its modes and measured its error bound by the pure
    /// loop at its own step: that bound says nothing of another rate's loop.
    pub fn check_rate(&self, dt_s: f64) -> Result<(), ReducedFileError> {
        let run_hz = if dt_s > 0.0 {
            (1.0 / dt_s).round()
        } else {
            0.0
        };
        crate::rate::check_dt(
            &format!("the reduced model of {}", self.structure),
            self.dt_s,
            dt_s,
            &format!("rths train meta --structure S.json --rate {run_hz:.0} --out M.json"),
        )?;
        Ok(())
    }

    /// The arrays for the controller at step `dt_s`, checked against `structure` (name and
    /// checksum) and the rate ([`Self::check_rate`]).
    pub fn arrays_for(
        &self,
        structure: &impl StructureIdentity,
        dt_s: f64,
    ) -> Result<ReducedArrays, ReducedFileError> {
        let checksum = structure.checksum();
        if self.structure != structure.name() || self.structure_checksum != checksum {
            return Err(ReducedFileError::Structure {
                file_name: self.structure.clone(),
                file_checksum: self.structure_checksum.clone(),
                name: structure.name().to_string(),
                checksum,
            });
        }
        self.check_rate(dt_s)?;
        self.arrays()
    }

    /// The arrays for the controller at step `dt_s`, checked against the structure's name only
    /// (for a reader that cannot condense the structure to compute its checksum: the firmware's
    /// build script and the link's upload; the host commands use [`Self::arrays_for`]) and the
    /// rate ([`Self::check_rate`]).
    pub fn arrays_for_name(
        &self,
        name: &str,
        dt_s: f64,
    ) -> Result<ReducedArrays, ReducedFileError> {
        if self.structure != name {
            return Err(ReducedFileError::StructureName {
                file_name: self.structure.clone(),
                name: name.to_string(),
            });
        }
        self.check_rate(dt_s)?;
        self.arrays()
    }

    /// The arrays for the controller, at no particular rate (shapes checked; values by core's
    /// validation at the file's own step): for the training, which scores them at its step. A
    /// controller takes them through [`Self::arrays_for`] or [`Self::arrays_for_name`], which
    /// refuse another rate's file.
    pub fn arrays(&self) -> Result<ReducedArrays, ReducedFileError> {
        let n_out = self.outputs.len();
        let r = self.modes.len();
        // The counts against core's limits before the read-outs' table is made: a corrupt file's
        // counts would otherwise size it (10⁶ outputs × 10⁴ modes is 80 GB).
        for (what, count, max) in [
            ("modes", r, REDUCED_MAX_MODES),
            ("outputs", n_out, REDUCED_MAX_OUTPUTS),
        ] {
            if count > max {
                return Err(ReducedFileError::Count { what, count, max });
            }
        }
        let mut output_shape = vec![0.0; n_out * r];
        for (j, m) in self.modes.iter().enumerate() {
            if m.output_shape.len() != n_out {
                return Err(ReducedFileError::Shape {
                    mode: j,
                    got: m.output_shape.len(),
                    expected: n_out,
                });
            }
            for (o, v) in m.output_shape.iter().enumerate() {
                if let Some(slot) = output_shape.get_mut(o * r + j) {
                    *slot = *v;
                }
            }
        }
        let a = ReducedArrays {
            modes: self
                .modes
                .iter()
                .map(|m| ReducedMode {
                    omega_rad_s: m.omega_rad_s,
                    damping_ratio: m.damping_ratio,
                    ground_participation: m.ground_participation,
                    interface_shape: m.interface_shape,
                })
                .collect(),
            output_shape,
            interface_static: self.interface_static.into(),
            output_static: self.output_static.iter().map(|s| (*s).into()).collect(),
            specimen_k_kn_per_mm: self.specimen_k_kn_per_mm,
        };
        // Validated once here, so a bad file is refused on load, not at the first tick.
        a.spec().params(self.dt_s)?;
        Ok(a)
    }
}

/// The `name` of an imported structure file's JSON text (`rths-structure` version 2), for a reader
/// that checks a reduced model's structure by name ([`ReducedModelFile::arrays_for_name`]).
pub fn imported_structure_name(text: &str) -> Result<String, ReducedFileError> {
    #[derive(Deserialize)]
    struct Header {
        name: String,
    }
    Ok(serde_json::from_str::<Header>(text)?.name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_name_of_an_imported_structure_and_a_bad_one() {
        let name = imported_structure_name(r#"{"format":"rths-structure","version":2,"name":"f"}"#);
        assert_eq!(name.unwrap(), "f");
        assert!(imported_structure_name("{").is_err());
        assert!(
            imported_structure_name(r#"{"version":2}"#).is_err(),
            "no name"
        );
    }
}

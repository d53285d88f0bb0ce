//! A structure file as the controller runs it, and the structure metamodel's model file.
//!
//! [`StructureArrays`]: the numerical part of a [`Structure`] as the raw row-major arrays of
//! `rths_core::control::StructureSpec` (linear, or with its yielding stories), taken from the
//! validated structure (so the partition is `structure_file`'s, never a copy). The firmware's
//! build script compiles them in; the host builds the same spec from them.
//!
//! The metamodel file (`rths train meta`), JSON:
//!
//! ```json
//! {"format": "rths-model", "version": 1, "kind": "structure-meta",
//!  "structure": {"name": "shear8", "checksum": "fnv1a64:0123456789abcdef"},
//!  "dt_s": 0.000244140625, "order": 6, "theta": [18 numbers], "k_corr_kn_per_mm": 50.0,
//!  "training": {"records": ["northridge", "loma-prieta"], "intensity": 0.4, ...}}
//! ```
//!
//! `theta` is `rths_core::metamodel::DeltaArx`'s (order of `delta_features`); `k_corr_kn_per_mm`
//! the force correction's stiffness. A model is trained for one structure: [`MetaFile::check`]
//! refuses it for a structure of another name or [`structure_checksum`] (any other matrix, specimen
//! or story law), and for another controller step, with the reason.

use std::path::{Path, PathBuf};

use rths_core::checksum::{Fnv1a64, Fnv1a64Label};
use rths_core::control::{StoryLawSpec, StructureSpec};
use rths_core::metamodel::{DeltaArxParams, DELTA_ARX_COEFFS, DELTA_ARX_ORDER};
use rths_core::structure_n::StructureN;
use serde::{Deserialize, Serialize};

use crate::model_file::MODEL_FORMAT;
use crate::structure_file::{Structure, StructureFileError};

/// The schema version.
pub const META_VERSION: u64 = 1;
/// The `kind` tag.
pub const META_KIND: &str = "structure-meta";

/// The numerical part of a structure, row-major, as `StructureSpec` borrows it.
#[derive(Debug, Clone, PartialEq)]
pub struct StructureArrays {
    /// DOFs.
    pub dofs: usize,
    /// Numerical mass, kN·s²/mm.
    pub mass: Vec<f64>,
    /// Numerical damping, kN·s/mm.
    pub damping: Vec<f64>,
    /// Numerical linear stiffness, kN/mm (zero for yielding stories).
    pub stiffness: Vec<f64>,
    /// Whole initial stiffness, kN/mm.
    pub initial_stiffness: Vec<f64>,
    /// Whole `M·ι`, kN·s²/mm.
    pub ground_mass: Vec<f64>,
    /// The specimen's DOF, 0-based.
    pub specimen_dof: usize,
    /// The story laws (empty: linear).
    pub laws: Vec<StoryLawSpec>,
}

fn leading(a: &rths_core::structure_n::Square, n: usize) -> Vec<f64> {
    a.iter()
        .take(n)
        .flat_map(|row| row.iter().take(n).copied())
        .collect()
}

impl StructureArrays {
    fn of(model: &StructureN, structure: &Structure, laws: Vec<StoryLawSpec>) -> Self {
        let n = model.dofs();
        Self {
            dofs: n,
            mass: leading(model.mass(), n),
            damping: leading(model.damping(), n),
            stiffness: leading(model.stiffness(), n),
            initial_stiffness: leading(model.initial_stiffness(), n),
            ground_mass: structure.ground_mass(),
            specimen_dof: structure.specimen_dof(),
            laws,
        }
    }

    /// The linear numerical part ([`Structure::numerical`]).
    pub fn linear(structure: &Structure) -> Result<Self, StructureFileError> {
        Ok(Self::of(&structure.numerical()?, structure, Vec::new()))
    }

    /// The yielding numerical part ([`Structure::nonlinear_numerical`]); refused for a linear
    /// structure.
    pub fn yielding(structure: &Structure, dt_s: f64) -> Result<Self, StructureFileError> {
        let frame = structure.nonlinear_numerical(dt_s)?;
        let laws = structure
            .story_laws()
            .unwrap_or(&[])
            .iter()
            .map(StoryLawSpec::of)
            .collect();
        Ok(Self::of(frame.chang().model(), structure, laws))
    }

    /// The spec the controller builds from.
    pub fn spec(&self) -> StructureSpec<'_> {
        StructureSpec {
            dofs: self.dofs,
            mass: &self.mass,
            damping: &self.damping,
            stiffness: &self.stiffness,
            initial_stiffness: &self.initial_stiffness,
            ground_mass: &self.ground_mass,
            specimen_dof: self.specimen_dof,
            laws: &self.laws,
        }
    }
}

/// A checksum of what a structure *is* (not of its file's text): its DOFs, whole mass, stiffness
/// and damping (rths units, row-major), the specimen's DOF, mass, stiffness and damping, and its
/// story laws, as little-endian f64 bytes. `"fnv1a64:"` and 16 hex digits.
pub fn structure_checksum(structure: &Structure) -> String {
    let n = structure.dofs();
    let mut values: Vec<f64> = vec![n as f64];
    for m in [structure.mass(), structure.stiffness(), structure.damping()] {
        values.extend(m.transpose().iter().copied());
    }
    let (m_e, k_e, c_e) = structure.specimen();
    values.extend([structure.specimen_dof() as f64, m_e, k_e, c_e]);
    for l in structure.story_laws().unwrap_or(&[]) {
        let s = StoryLawSpec::of(l);
        values.extend([s.k0_kn_per_mm, s.yield_force_kn, s.post_yield_ratio]);
        values.extend(s.bouc_wen.unwrap_or([0.0; 3]));
    }
    let mut h = Fnv1a64::new();
    for &v in &values {
        h.write_f64(v);
    }
    Fnv1a64Label(h.finish()).to_string()
}

/// Which structure a metamodel was trained for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StructureId {
    /// The structure file's `name`.
    pub name: String,
    /// [`structure_checksum`].
    pub checksum: String,
}

/// How the metamodel was trained (no dates: a retrain gives the same file).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct MetaTraining {
    /// The records simulated.
    pub records: Vec<String>,
    /// Factor on their ground acceleration.
    pub intensity: f64,
    /// Fitting method.
    pub method: String,
    /// The force correction's stiffness over the specimen's nominal stiffness.
    pub force_correction_ratio: f64,
}

/// A structure-metamodel file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MetaFile {
    /// Always [`MODEL_FORMAT`] (the model files' own tag).
    pub format: String,
    /// Always [`META_VERSION`].
    pub version: u64,
    /// Always [`META_KIND`].
    pub kind: String,
    /// The structure it was trained for.
    pub structure: StructureId,
    /// The controller step it runs at, s.
    pub dt_s: f64,
    /// Lags per input (`DELTA_ARX_ORDER`).
    pub order: usize,
    /// Coefficients (`DELTA_ARX_COEFFS`).
    pub theta: Vec<f64>,
    /// The force correction's stiffness, kN/mm.
    pub k_corr_kn_per_mm: f64,
    /// Provenance.
    #[serde(default)]
    pub training: MetaTraining,
}

/// Why a structure-metamodel file was refused.
#[derive(Debug, thiserror::Error)]
pub enum MetaFileError {
    /// Reading or writing failed.
    #[error("cannot access structure metamodel file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Not JSON of this schema.
    #[error("structure metamodel file: {0}")]
    Json(#[from] serde_json::Error),
    /// Another format, version or kind.
    #[error("not a structure metamodel: format {format:?} version {version} kind {kind:?} (expected {MODEL_FORMAT:?} {META_VERSION} {META_KIND:?})")]
    NotMeta {
        /// Found format.
        format: String,
        /// Found version.
        version: u64,
        /// Found kind.
        kind: String,
    },
    /// Order or coefficients refused.
    #[error("structure metamodel: {0}")]
    Model(String),
    /// Trained for another structure.
    #[error("the metamodel was trained for structure {trained} ({trained_checksum}), not {given} ({given_checksum}): train one for it with `rths train meta --structure FILE`")]
    OtherStructure {
        /// Its structure's name.
        trained: String,
        /// Its structure's checksum.
        trained_checksum: String,
        /// The structure given.
        given: String,
        /// Its checksum.
        given_checksum: String,
    },
    /// Trained at another rate (the rule of every file made at a controller rate,
    /// [`crate::rate::check_dt`]).
    #[error(transparent)]
    OtherRate(#[from] crate::rate::OtherRate),
}

impl MetaFile {
    /// A file for `structure` from trained parameters.
    pub fn new(
        structure: &Structure,
        params: &DeltaArxParams,
        dt_s: f64,
        training: MetaTraining,
    ) -> Self {
        Self {
            format: MODEL_FORMAT.into(),
            version: META_VERSION,
            kind: META_KIND.into(),
            structure: StructureId {
                name: structure.name().into(),
                checksum: structure_checksum(structure),
            },
            dt_s,
            order: DELTA_ARX_ORDER,
            theta: params.theta().to_vec(),
            k_corr_kn_per_mm: params.k_corr_kn_per_mm(),
            training,
        }
    }

    /// The validated parameters (format, kind, order, shape, finiteness).
    pub fn params(&self) -> Result<DeltaArxParams, MetaFileError> {
        if self.format != MODEL_FORMAT || self.version != META_VERSION || self.kind != META_KIND {
            return Err(MetaFileError::NotMeta {
                format: self.format.clone(),
                version: self.version,
                kind: self.kind.clone(),
            });
        }
        if self.order != DELTA_ARX_ORDER || self.theta.len() != DELTA_ARX_COEFFS {
            return Err(MetaFileError::Model(format!(
                "order {} with {} coefficients; this build runs order {DELTA_ARX_ORDER} ({DELTA_ARX_COEFFS} coefficients)",
                self.order,
                self.theta.len()
            )));
        }
        if !(self.dt_s.is_finite() && self.dt_s > 0.0) {
            return Err(MetaFileError::Model(format!(
                "dt_s must be positive, got {}",
                crate::readable(self.dt_s)
            )));
        }
        DeltaArxParams::from_slice(&self.theta, self.k_corr_kn_per_mm)
            .map_err(|e| MetaFileError::Model(e.to_string()))
    }

    /// [`Self::params`], refused unless trained for `structure` at step `dt_s`.
    pub fn check(&self, structure: &Structure, dt_s: f64) -> Result<DeltaArxParams, MetaFileError> {
        let p = self.params()?;
        let checksum = structure_checksum(structure);
        if self.structure.name != structure.name() || self.structure.checksum != checksum {
            return Err(MetaFileError::OtherStructure {
                trained: self.structure.name.clone(),
                trained_checksum: self.structure.checksum.clone(),
                given: structure.name().into(),
                given_checksum: checksum,
            });
        }
        self.check_rate(dt_s)?;
        Ok(p)
    }

    /// Refuse the file unless it was trained at the controller step `dt_s` (within
    /// [`crate::rate::DT_TOLERANCE`], as every file made at a controller rate).
    pub fn check_rate(&self, dt_s: f64) -> Result<(), MetaFileError> {
        crate::rate::check_dt(
            "the structure metamodel",
            self.dt_s,
            dt_s,
            &format!(
                "rths train meta --structure {}.json --out FILE",
                self.structure.name
            ),
        )?;
        Ok(())
    }

    /// Parse and validate (not yet against a structure: [`Self::check`]).
    pub fn from_json(text: &str) -> Result<Self, MetaFileError> {
        let f: Self = serde_json::from_str(text)?;
        f.params()?;
        Ok(f)
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> Result<String, MetaFileError> {
        self.params()?;
        Ok(serde_json::to_string_pretty(self)?)
    }

    /// Read and validate.
    pub fn load(path: &Path) -> Result<Self, MetaFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| MetaFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shear(k2: f64, name: &str) -> Structure {
        Structure::from_json(&format!(
            r#"{{"format": "rths-structure", "version": 1, "name": "{name}", "units": "mm-kn",
            "stories": {{"floor_mass": [0.6, 0.5], "story_stiffness": [300, {k2}], "damping_ratio": 0.02}},
            "specimen": {{"dof": 1, "mass": 0, "stiffness": 100, "damping": 0}}}}"#
        ))
        .unwrap()
    }

    fn params() -> DeltaArxParams {
        let mut t = [0.0; DELTA_ARX_COEFFS];
        t[1] = 0.5;
        DeltaArxParams::from_slice(&t, 50.0).unwrap()
    }

    #[test]
    fn a_file_round_trips_and_is_checked_against_its_structure() {
        let s = shear(250.0, "a");
        let f = MetaFile::new(&s, &params(), 1.0 / 4096.0, MetaTraining::default());
        let back = MetaFile::from_json(&f.to_json().unwrap()).unwrap();
        assert_eq!(back, f);
        assert_eq!(back.check(&s, 1.0 / 4096.0).unwrap(), params());
        // Another structure (same name, another stiffness), another name, another rate.
        let e = back
            .check(&shear(251.0, "a"), 1.0 / 4096.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("trained for structure a"), "{e}");
        assert!(back.check(&shear(250.0, "b"), 1.0 / 4096.0).is_err());
        let e = back.check(&s, 1.0 / 2048.0).unwrap_err().to_string();
        assert!(e.contains("4096 Hz"), "{e}");
    }

    #[test]
    fn bad_files_are_refused_with_the_reason() {
        let s = shear(250.0, "a");
        let f = MetaFile::new(&s, &params(), 1.0 / 4096.0, MetaTraining::default());
        let mut short = f.clone();
        short.theta.pop();
        assert!(short.params().unwrap_err().to_string().contains("17"));
        let mut nan = f.clone();
        nan.k_corr_kn_per_mm = -1.0;
        assert!(nan.params().is_err());
        let mut kind = f.clone();
        kind.kind = "lr".into();
        assert!(kind
            .params()
            .unwrap_err()
            .to_string()
            .contains("not a structure metamodel"));
        let text = f
            .to_json()
            .unwrap()
            .replace("\"order\": 6", "\"order\": 6, \"x\": 1");
        assert!(MetaFile::from_json(&text).is_err());
    }

    #[test]
    fn the_arrays_are_the_structure_files_numerical_part() {
        let s = shear(250.0, "a");
        let a = StructureArrays::linear(&s).unwrap();
        let spec = a.spec();
        assert_eq!(spec.numerical().unwrap(), s.numerical().unwrap());
        assert!(StructureArrays::yielding(&s, 1e-3).is_err());
    }
}

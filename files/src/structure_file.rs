//! Structure files: the analytical part of a hybrid test as a linear N-DOF structure, versioned JSON,
//! validated on load.
//!
//! ```json
//! {"format": "rths-structure", "version": 1, "name": "vrths-case1", "description": "...",
//!  "units": "si" | "mm-kn",
//!  "matrices": {"mass": [[..]], "stiffness": [[..]], "damping": [[..]]},        (either this)
//!  "stories": {"floor_mass": [..], "story_stiffness": [..], "damping_ratio": z,  (or this)
//!              "hysteresis": [{"law": "bilinear", "yield_force": fy, "post_yield_ratio": a}, ..]},
//!  "specimen": {"dof": 1, "mass": m, "stiffness": k, "damping_ratio": z | "damping": c}}
//! ```
//!
//! - `units`: `"si"` is kg, N/m, N·s/m (metres); `"mm-kn"` is rths's own kN·s²/mm, kN/mm, kN·s/mm.
//!   Both describe the same dynamics: SI values are multiplied by 1e-6 on load (each of mass,
//!   stiffness and damping), displacements are then in mm and forces in kN.
//! - `matrices`: the *whole* structure's mass, stiffness and damping (N × N, N ≤ [`MAX_DOF`]).
//! - `stories`: a shear building (floor masses and story stiffnesses from the ground up) with
//!   Rayleigh damping of `damping_ratio` in the first and the last mode (`rths_core::structure::ShearBuilding`).
//! - `specimen`: the physical substructure, at `dof` (1-based: 1 is the first floor), with its own
//!   mass, stiffness and damping (a damping coefficient, or a ratio: `c = 2ζ√(k·m)`), which are
//!   subtracted from the whole structure at that DOF to give the numerical part, as the vRTHS
//!   benchmark partitions its frame (`docs/benchmark.md`).
//!
//! - `stories.hysteresis` (optional, one entry per story from the ground up): the numerical
//!   stories yield. `"bilinear"` is kinematic hardening (`yield_force`, `post_yield_ratio`);
//!   `"bouc-wen"` adds `exponent`, `beta`, `gamma` (`rths_core::hysteresis::Law`). The story's
//!   initial stiffness is its `story_stiffness`, minus the specimen's stiffness in the first story:
//!   a hysteretic file puts its specimen on DOF 1, where a spring to ground *is* a story spring, so
//!   the whole structure is the yielding numerical stories plus the linear specimen. Forces are in
//!   N (`"si"`) or kN (`"mm-kn"`). Without it the file loads exactly as before (version 1 kept).
//!
//! [`Structure::from_json`] checks the format tag and version first, then refuses with the reason:
//! N = 0 or N > [`MAX_DOF`], a non-square or ragged matrix, a non-finite value, a matrix that is not
//! symmetric (within [`SYMMETRY_TOLERANCE`] of its largest entry), a mass or stiffness that is not
//! positive definite (Cholesky), a specimen on a DOF that does not exist, a negative specimen
//! property, or a numerical part whose mass is no longer positive definite.

use std::path::{Path, PathBuf};

use nalgebra::DMatrix;
use rths_core::hysteresis::Law;
use rths_core::params::ParamError;
use rths_core::structure::ShearBuilding;
use rths_core::structure_n::StructureN;
use rths_core::structure_nl::NonlinearFrame;
use serde::{Deserialize, Serialize};

/// The `format` tag of every structure file.
pub const STRUCTURE_FORMAT: &str = "rths-structure";
/// The structure-file version this code reads and writes.
pub const STRUCTURE_VERSION: u64 = 1;
/// Largest number of DOFs: core's (the `no_std` integrator's fixed capacity), the one constant.
pub use rths_core::structure_n::MAX_DOF;
/// Relative symmetry tolerance: `|a_ij − a_ji| ≤ tol·max|a|`. The benchmark's matrices are symmetric
/// to 2.6e-15 (round-off of their source); 1e-9 accepts that and refuses any real asymmetry.
pub const SYMMETRY_TOLERANCE: f64 = 1e-9;
/// SI (kg, N/m, N·s/m) to rths units (kN·s²/mm, kN/mm, kN·s/mm): the same factor for all three.
pub const SI_TO_MM_KN: f64 = 1e-6;

/// The unit system of a structure file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Units {
    /// kg, N/m, N·s/m.
    #[serde(rename = "si")]
    Si,
    /// kN·s²/mm, kN/mm, kN·s/mm.
    #[serde(rename = "mm-kn")]
    MmKn,
}

impl Units {
    /// The factor from these units to rths's (mm, kN).
    pub fn to_mm_kn(self) -> f64 {
        match self {
            Units::Si => SI_TO_MM_KN,
            Units::MmKn => 1.0,
        }
    }

    /// The factor from this system's force (N or kN) to kN.
    pub fn force_to_kn(self) -> f64 {
        match self {
            Units::Si => 1e-3,
            Units::MmKn => 1.0,
        }
    }
}

/// The whole structure's matrices, in the file's units, row by row.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Matrices {
    /// Mass matrix.
    pub mass: Vec<Vec<f64>>,
    /// Stiffness matrix.
    pub stiffness: Vec<Vec<f64>>,
    /// Damping matrix.
    pub damping: Vec<Vec<f64>>,
}

/// A shear building: floor masses and story stiffnesses from the ground up, Rayleigh damping.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stories {
    /// Floor masses.
    pub floor_mass: Vec<f64>,
    /// Story stiffnesses.
    pub story_stiffness: Vec<f64>,
    /// Damping ratio of the first and the last mode.
    pub damping_ratio: f64,
    /// The numerical stories' hysteresis laws, from the ground up (absent: linear).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hysteresis: Option<Vec<StoredStoryLaw>>,
}

/// A story's hysteresis law as stored (force in the file's units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "kebab-case", deny_unknown_fields)]
pub enum StoredStoryLaw {
    /// Bilinear kinematic hardening.
    Bilinear {
        /// Yield force.
        yield_force: f64,
        /// Post-yield stiffness over initial stiffness.
        post_yield_ratio: f64,
    },
    /// Bouc–Wen.
    BoucWen {
        /// Yield force.
        yield_force: f64,
        /// Post-yield stiffness over initial stiffness.
        post_yield_ratio: f64,
        /// Sharpness `n`.
        exponent: f64,
        /// `β`.
        beta: f64,
        /// `γ`.
        gamma: f64,
    },
}

/// The physical specimen, in the file's units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SpecimenSpec {
    /// The DOF it sits at, 1-based.
    pub dof: usize,
    /// Its own mass (subtracted from the numerical part).
    pub mass: f64,
    /// Its stiffness.
    pub stiffness: f64,
    /// Its damping coefficient (or give `damping_ratio`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<f64>,
    /// Its damping ratio, `c = 2ζ√(k·m)` (or give `damping`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping_ratio: Option<f64>,
}

/// A structure file as stored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StructureFile {
    /// Always [`STRUCTURE_FORMAT`].
    pub format: String,
    /// Always [`STRUCTURE_VERSION`].
    pub version: u64,
    /// Short name.
    pub name: String,
    /// What it is and where the numbers come from.
    #[serde(default)]
    pub description: String,
    /// Unit system of every number below.
    pub units: Units,
    /// The whole structure's matrices (or `stories`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matrices: Option<Matrices>,
    /// A shear building (or `matrices`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stories: Option<Stories>,
    /// The physical specimen.
    pub specimen: SpecimenSpec,
}

/// Why a structure file was refused.
#[derive(Debug, thiserror::Error)]
pub enum StructureFileError {
    /// Reading failed.
    #[error("cannot read structure file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Not JSON, or not the expected fields.
    #[error("malformed structure file: {0}")]
    Json(#[from] serde_json::Error),
    /// `format` is not "rths-structure".
    #[error("unknown structure format {found:?} (expected \"{STRUCTURE_FORMAT}\")")]
    UnknownFormat {
        /// The tag found.
        found: String,
    },
    /// `version` is not supported.
    #[error(
        "unsupported structure file version {found} (this build reads version {STRUCTURE_VERSION}){}",
        imported_hint(*.found)
    )]
    UnsupportedVersion {
        /// The version found.
        found: u64,
    },
    /// Neither or both of `matrices` and `stories`.
    #[error("give exactly one of \"matrices\" and \"stories\"")]
    Definition,
    /// N is 0 or above [`MAX_DOF`].
    #[error("the structure has {dofs} DOFs; 1..={MAX_DOF} are supported")]
    Dofs {
        /// DOFs found.
        dofs: usize,
    },
    /// A matrix or vector has the wrong shape.
    #[error("{what}: expected {expected} entries in row {row}, found {found}")]
    Shape {
        /// The field.
        what: &'static str,
        /// Row (1-based; 0 for the number of rows or a vector's length).
        row: usize,
        /// Entries expected.
        expected: usize,
        /// Entries found.
        found: usize,
    },
    /// A value is NaN or infinite.
    #[error("{what} holds a non-finite value")]
    NotFinite {
        /// The field.
        what: &'static str,
    },
    /// A matrix is not symmetric.
    #[error("{what} is not symmetric: entry ({i},{j}) = {a_ij} but ({j},{i}) = {a_ji}")]
    NotSymmetric {
        /// The matrix.
        what: &'static str,
        /// Row, 1-based.
        i: usize,
        /// Column, 1-based.
        j: usize,
        /// `a_ij`.
        a_ij: f64,
        /// `a_ji`.
        a_ji: f64,
    },
    /// A matrix is not positive definite.
    #[error("{what} is not positive definite (Cholesky fails)")]
    NotPositiveDefinite {
        /// The matrix.
        what: &'static str,
    },
    /// A matrix that must not feed energy in has a negative eigenvalue.
    #[error(
        "{what} is not positive semi-definite: eigenvalue {eigenvalue:e} < 0 (it would feed \
         energy into the structure)"
    )]
    NotPositiveSemiDefinite {
        /// The matrix.
        what: &'static str,
        /// Its smallest eigenvalue.
        eigenvalue: f64,
    },
    /// The specimen's DOF does not exist.
    #[error("the specimen is on DOF {dof}, but the structure has DOFs 1..={dofs}")]
    SpecimenDof {
        /// The DOF given.
        dof: usize,
        /// DOFs of the structure.
        dofs: usize,
    },
    /// A specimen property is out of range.
    #[error("specimen {what}: {reason}")]
    Specimen {
        /// The property.
        what: &'static str,
        /// Why.
        reason: &'static str,
    },
    /// The core model refused the parameters.
    #[error("invalid structure: {0}")]
    Param(#[from] ParamError),
    /// A story's hysteresis law is refused.
    #[error("{}hysteresis: {reason}", story_prefix(*.story))]
    Hysteresis {
        /// The story, 1-based (0: the section as a whole).
        story: usize,
        /// Why.
        reason: String,
    },
}

/// What a version-2 file is, for the commands that read version 1 only.
fn imported_hint(version: u64) -> &'static str {
    if version == 2 {
        "; version 2 is an imported sparse structure (`rths import opensees`): `rths simulate \
         --structure FILE --scenario fe-pure` runs it"
    } else {
        ""
    }
}

/// `"story N "` for a story's error, nothing for the section's.
fn story_prefix(story: usize) -> String {
    if story == 0 {
        String::new()
    } else {
        format!("story {story} ")
    }
}

/// A validated structure, in rths units (mm, kN, s).
#[derive(Debug, Clone, PartialEq)]
pub struct Structure {
    name: String,
    mass: DMatrix<f64>,
    stiffness: DMatrix<f64>,
    damping: DMatrix<f64>,
    /// 0-based.
    specimen_dof: usize,
    specimen_mass: f64,
    specimen_stiffness: f64,
    specimen_damping: f64,
    /// The numerical stories' laws (rths units), when the file has a `hysteresis` section.
    story_laws: Option<Vec<Law>>,
}

/// The laws of a `hysteresis` section in rths units: story `i`'s initial stiffness is its story
/// stiffness, minus the specimen's in the first story.
fn story_laws(
    s: &Stories,
    specs: &[StoredStoryLaw],
    units: Units,
    specimen_dof: usize,
    specimen_k: f64,
) -> Result<Vec<Law>, StructureFileError> {
    let whole = |reason: &str| StructureFileError::Hysteresis {
        story: 0,
        reason: reason.to_string(),
    };
    if specs.len() != s.story_stiffness.len() {
        return Err(whole(&format!(
            "{} laws for {} stories (give one per story)",
            specs.len(),
            s.story_stiffness.len()
        )));
    }
    if specimen_dof != 1 {
        return Err(whole(
            "a hysteretic frame puts its specimen on DOF 1 (the first story)",
        ));
    }
    let force = units.force_to_kn();
    let mut laws = Vec::with_capacity(specs.len());
    for (i, (spec, k)) in specs.iter().zip(&s.story_stiffness).enumerate() {
        let k0 = k * units.to_mm_kn() - if i == 0 { specimen_k } else { 0.0 };
        let law = match *spec {
            StoredStoryLaw::Bilinear {
                yield_force,
                post_yield_ratio,
            } => Law::bilinear(k0, yield_force * force, post_yield_ratio),
            StoredStoryLaw::BoucWen {
                yield_force,
                post_yield_ratio,
                exponent,
                beta,
                gamma,
            } => Law::bouc_wen(
                k0,
                yield_force * force,
                post_yield_ratio,
                exponent,
                beta,
                gamma,
            ),
        };
        laws.push(law.map_err(|e| StructureFileError::Hysteresis {
            story: i + 1,
            reason: e.to_string(),
        })?);
    }
    Ok(laws)
}

fn matrix(
    rows: &[Vec<f64>],
    what: &'static str,
    scale: f64,
) -> Result<DMatrix<f64>, StructureFileError> {
    let n = rows.len();
    if n == 0 || n > MAX_DOF {
        return Err(StructureFileError::Dofs { dofs: n });
    }
    for (i, r) in rows.iter().enumerate() {
        if r.len() != n {
            return Err(StructureFileError::Shape {
                what,
                row: i + 1,
                expected: n,
                found: r.len(),
            });
        }
        if r.iter().any(|v| !v.is_finite()) {
            return Err(StructureFileError::NotFinite { what });
        }
    }
    Ok(DMatrix::from_fn(n, n, |i, j| {
        rows.get(i).and_then(|r| r.get(j)).copied().unwrap_or(0.0) * scale
    }))
}

fn symmetric(a: &DMatrix<f64>, what: &'static str) -> Result<(), StructureFileError> {
    let scale = a.amax();
    for i in 0..a.nrows() {
        for j in (i + 1)..a.ncols() {
            let (a_ij, a_ji) = (a[(i, j)], a[(j, i)]);
            if (a_ij - a_ji).abs() > SYMMETRY_TOLERANCE * scale {
                return Err(StructureFileError::NotSymmetric {
                    what,
                    i: i + 1,
                    j: j + 1,
                    a_ij,
                    a_ji,
                });
            }
        }
    }
    Ok(())
}

fn positive_definite(a: &DMatrix<f64>, what: &'static str) -> Result<(), StructureFileError> {
    // Symmetric part: the check above allows round-off asymmetry.
    let sym = (a + a.transpose()) * 0.5;
    if sym.cholesky().is_some() {
        Ok(())
    } else {
        Err(StructureFileError::NotPositiveDefinite { what })
    }
}

/// Smallest eigenvalue of the symmetric part at least `−SYMMETRY_TOLERANCE·max|a|` (round-off of
/// a singular but semi-definite matrix, e.g. a numerical part whose only stiffness at a DOF was the
/// specimen's, stays accepted).
fn positive_semi_definite(a: &DMatrix<f64>, what: &'static str) -> Result<(), StructureFileError> {
    let sym = (a + a.transpose()) * 0.5;
    let lowest = sym.symmetric_eigenvalues().min();
    if lowest >= -SYMMETRY_TOLERANCE * a.amax() {
        Ok(())
    } else {
        Err(StructureFileError::NotPositiveSemiDefinite {
            what,
            eigenvalue: lowest,
        })
    }
}

fn non_negative(v: f64, what: &'static str) -> Result<f64, StructureFileError> {
    if !v.is_finite() {
        Err(StructureFileError::Specimen {
            what,
            reason: "not finite",
        })
    } else if v < 0.0 {
        Err(StructureFileError::Specimen {
            what,
            reason: "must be ≥ 0",
        })
    } else {
        Ok(v)
    }
}

/// Mass, stiffness and Rayleigh damping of a shear building, rths units, through core's
/// [`ShearBuilding`] (the one home of its stiffness and damping formulas).
fn shear_building(s: &Stories, scale: f64) -> Result<[DMatrix<f64>; 3], StructureFileError> {
    let n = s.floor_mass.len();
    if n == 0 || n > MAX_DOF {
        return Err(StructureFileError::Dofs { dofs: n });
    }
    if s.story_stiffness.len() != n {
        return Err(StructureFileError::Shape {
            what: "story_stiffness",
            row: 0,
            expected: n,
            found: s.story_stiffness.len(),
        });
    }
    let masses: Vec<f64> = s.floor_mass.iter().map(|m| m * scale).collect();
    let stiffs: Vec<f64> = s.story_stiffness.iter().map(|k| k * scale).collect();
    macro_rules! build {
        ($($n:literal),*) => {
            match n {
                $($n => {
                    let mut b = ShearBuilding::<$n>::uniform(1.0, 1.0, s.damping_ratio);
                    b.floor_mass_kn_s2_per_mm.copy_from_slice(&masses);
                    b.story_stiffness_kn_per_mm.copy_from_slice(&stiffs);
                    let m = b.model()?;
                    let to = |a: &rths_core::structure::Mat<$n>| DMatrix::from_fn(n, n, |i, j| a[(i, j)]);
                    Ok([to(m.mass()), to(m.stiffness()), to(m.damping())])
                })*
                _ => Err(StructureFileError::Dofs { dofs: n }),
            }
        };
    }
    build!(1, 2, 3, 4, 5, 6, 7, 8)
}

impl StructureFile {
    /// Parse a file's JSON text (format and version checked first), not yet validated.
    pub fn parse(text: &str) -> Result<Self, StructureFileError> {
        #[derive(Deserialize)]
        struct Header {
            format: Option<String>,
            version: Option<u64>,
        }
        let header: Header = serde_json::from_str(text)?;
        let format = header.format.unwrap_or_default();
        if format != STRUCTURE_FORMAT {
            return Err(StructureFileError::UnknownFormat { found: format });
        }
        let version = header.version.unwrap_or(0);
        if version != STRUCTURE_VERSION {
            return Err(StructureFileError::UnsupportedVersion { found: version });
        }
        Ok(serde_json::from_str(text)?)
    }

    /// Validate into a [`Structure`] in rths units.
    pub fn validate(&self) -> Result<Structure, StructureFileError> {
        let scale = self.units.to_mm_kn();
        let [mass, stiffness, damping] = match (&self.matrices, &self.stories) {
            (Some(m), None) => {
                let mass = matrix(&m.mass, "mass", scale)?;
                let n = mass.nrows();
                let stiffness = matrix(&m.stiffness, "stiffness", scale)?;
                let damping = matrix(&m.damping, "damping", scale)?;
                for (a, what) in [(&stiffness, "stiffness"), (&damping, "damping")] {
                    if a.nrows() != n {
                        return Err(StructureFileError::Shape {
                            what,
                            row: 0,
                            expected: n,
                            found: a.nrows(),
                        });
                    }
                }
                [mass, stiffness, damping]
            }
            (None, Some(s)) => shear_building(s, scale)?,
            _ => return Err(StructureFileError::Definition),
        };
        symmetric(&mass, "mass")?;
        symmetric(&stiffness, "stiffness")?;
        symmetric(&damping, "damping")?;
        positive_definite(&mass, "mass")?;
        positive_definite(&stiffness, "stiffness")?;
        positive_semi_definite(&damping, "damping")?;
        let n = mass.nrows();
        let sp = &self.specimen;
        if sp.dof == 0 || sp.dof > n {
            return Err(StructureFileError::SpecimenDof {
                dof: sp.dof,
                dofs: n,
            });
        }
        let m_e = non_negative(sp.mass, "mass")? * scale;
        let k_e = non_negative(sp.stiffness, "stiffness")? * scale;
        let c_e = match (sp.damping, sp.damping_ratio) {
            (Some(c), None) => non_negative(c, "damping")? * scale,
            (None, Some(z)) => 2.0 * non_negative(z, "damping ratio")? * (k_e * m_e).sqrt(),
            _ => {
                return Err(StructureFileError::Specimen {
                    what: "damping",
                    reason: "give exactly one of \"damping\" and \"damping_ratio\"",
                })
            }
        };
        let laws = match &self.stories {
            Some(st) => match &st.hysteresis {
                Some(specs) => Some(story_laws(st, specs, self.units, sp.dof, k_e)?),
                None => None,
            },
            None => None,
        };
        let s = Structure {
            name: self.name.clone(),
            mass,
            stiffness,
            damping,
            specimen_dof: sp.dof - 1,
            specimen_mass: m_e,
            specimen_stiffness: k_e,
            specimen_damping: c_e,
            story_laws: laws,
        };
        let (m_n, k_n, c_n) = s.numerical_matrices();
        positive_definite(&m_n, "numerical mass (whole mass minus the specimen's)")?;
        // A specimen stiffer (or more damped) than the structure at its DOF would leave the
        // numerical part a negative spring (dashpot): no structure splits that way.
        positive_semi_definite(
            &k_n,
            "numerical stiffness (whole stiffness minus the specimen's)",
        )?;
        positive_semi_definite(
            &c_n,
            "numerical damping (whole damping minus the specimen's)",
        )?;
        Ok(s)
    }
}

impl Structure {
    /// Parse and validate a structure file's JSON text.
    pub fn from_json(text: &str) -> Result<Self, StructureFileError> {
        StructureFile::parse(text)?.validate()
    }

    /// Read and validate a structure file.
    pub fn load(path: &Path) -> Result<Self, StructureFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| StructureFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text)
    }

    /// Short name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Number of DOFs.
    pub fn dofs(&self) -> usize {
        self.mass.nrows()
    }
    /// Whole-structure mass, kN·s²/mm.
    pub fn mass(&self) -> &DMatrix<f64> {
        &self.mass
    }
    /// Whole-structure stiffness, kN/mm.
    pub fn stiffness(&self) -> &DMatrix<f64> {
        &self.stiffness
    }
    /// Whole-structure damping, kN·s/mm.
    pub fn damping(&self) -> &DMatrix<f64> {
        &self.damping
    }
    /// The specimen's DOF, 0-based.
    pub fn specimen_dof(&self) -> usize {
        self.specimen_dof
    }
    /// The specimen's mass (kN·s²/mm), stiffness (kN/mm) and damping (kN·s/mm).
    pub fn specimen(&self) -> (f64, f64, f64) {
        (
            self.specimen_mass,
            self.specimen_stiffness,
            self.specimen_damping,
        )
    }

    /// `M − M_E`, `K − K_E`, `C − C_E`: the specimen's own properties taken off its DOF.
    pub fn numerical_matrices(&self) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
        let d = self.specimen_dof;
        let (mut m, mut k, mut c) = (
            self.mass.clone(),
            self.stiffness.clone(),
            self.damping.clone(),
        );
        m[(d, d)] -= self.specimen_mass;
        k[(d, d)] -= self.specimen_stiffness;
        c[(d, d)] -= self.specimen_damping;
        (m, k, c)
    }

    /// The numerical substructure for the controller: `M_N`, `C_N`, `K_N`, Chang's initial stiffness
    /// the whole structure's `K`, and the ground force on the whole mass `M·ι`.
    pub fn numerical(&self) -> Result<StructureN, StructureFileError> {
        let (m, k, c) = self.numerical_matrices();
        Ok(StructureN::new(
            self.dofs(),
            &row_major(&m),
            &row_major(&c),
            &row_major(&k),
            &row_major(&self.stiffness),
            &self.ground_mass(),
        )?)
    }

    /// The whole structure (nothing subtracted, no external force): the reference.
    pub fn whole(&self) -> Result<StructureN, StructureFileError> {
        Ok(StructureN::new(
            self.dofs(),
            &row_major(&self.mass),
            &row_major(&self.damping),
            &row_major(&self.stiffness),
            &row_major(&self.stiffness),
            &self.ground_mass(),
        )?)
    }

    /// The numerical stories' hysteresis laws (`None`: a linear structure).
    pub fn story_laws(&self) -> Option<&[Law]> {
        self.story_laws.as_deref()
    }

    /// The nonlinear numerical substructure for a step `dt_s`: mass `M − M_E`, damping `C − C_E`,
    /// the yielding stories, Chang's coefficients on the whole initial `K`; the specimen's force
    /// enters as `r_ext`. Refused for a linear structure.
    pub fn nonlinear_numerical(&self, dt_s: f64) -> Result<NonlinearFrame, StructureFileError> {
        let (m, _, c) = self.numerical_matrices();
        self.nonlinear(&m, &c, &DMatrix::zeros(self.dofs(), self.dofs()), dt_s)
    }

    /// The whole nonlinear structure (the reference): the yielding stories plus the linear
    /// specimen at DOF 1, whole mass and damping.
    pub fn nonlinear_whole(&self, dt_s: f64) -> Result<NonlinearFrame, StructureFileError> {
        let mut k_lin = DMatrix::zeros(self.dofs(), self.dofs());
        k_lin[(self.specimen_dof, self.specimen_dof)] = self.specimen_stiffness;
        self.nonlinear(&self.mass, &self.damping, &k_lin, dt_s)
    }

    fn nonlinear(
        &self,
        m: &DMatrix<f64>,
        c: &DMatrix<f64>,
        k_lin: &DMatrix<f64>,
        dt_s: f64,
    ) -> Result<NonlinearFrame, StructureFileError> {
        let laws = self
            .story_laws
            .as_deref()
            .ok_or_else(|| StructureFileError::Hysteresis {
                story: 0,
                reason: "this structure is linear (no \"hysteresis\" section)".to_string(),
            })?;
        let model = StructureN::new(
            self.dofs(),
            &row_major(m),
            &row_major(c),
            &row_major(k_lin),
            &row_major(&self.stiffness),
            &self.ground_mass(),
        )?;
        Ok(NonlinearFrame::new(model, laws, dt_s)?)
    }

    /// `M·ι`, kN·s²/mm.
    pub fn ground_mass(&self) -> Vec<f64> {
        self.mass.column_sum().iter().copied().collect()
    }

    /// Undamped natural frequencies of the whole structure, Hz, ascending.
    pub fn natural_frequencies_hz(&self) -> Vec<f64> {
        // Symmetric form L⁻¹·K·L⁻ᵀ with M = L·Lᵀ.
        let sym = |a: &DMatrix<f64>| (a + a.transpose()) * 0.5;
        let Some(chol) = sym(&self.mass).cholesky() else {
            return Vec::new();
        };
        let Some(l_inv) = chol.l().try_inverse() else {
            return Vec::new();
        };
        let a = sym(&(&l_inv * &self.stiffness * l_inv.transpose()));
        let mut w: Vec<f64> = a
            .symmetric_eigenvalues()
            .iter()
            .map(|v| v.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
            .collect();
        w.sort_by(f64::total_cmp);
        w
    }
}

fn row_major(a: &DMatrix<f64>) -> Vec<f64> {
    a.transpose().iter().copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(mass: &str, dof: usize) -> String {
        format!(
            r#"{{"format": "rths-structure", "version": 1, "name": "t", "units": "si",
            "matrices": {{"mass": {mass}, "stiffness": [[2e6, -1e6], [-1e6, 1e6]],
                          "damping": [[100, 0], [0, 100]]}},
            "specimen": {{"dof": {dof}, "mass": 10, "stiffness": 1e5, "damping_ratio": 0.01}}}}"#
        )
    }

    #[test]
    fn a_good_file_loads_in_rths_units() -> Result<(), StructureFileError> {
        let s = Structure::from_json(&frame("[[1000, 0], [0, 1000]]", 1))?;
        assert_eq!(s.dofs(), 2);
        assert_eq!(s.mass()[(0, 0)], 1000.0 * SI_TO_MM_KN);
        let (m, k, _) = s.numerical_matrices();
        assert_eq!(m[(0, 0)], (1000.0 - 10.0) * SI_TO_MM_KN);
        assert!((k[(0, 0)] - 1.9e6 * SI_TO_MM_KN).abs() < 1e-12);
        assert_eq!(s.numerical()?.dofs(), 2);
        Ok(())
    }

    #[test]
    fn bad_files_are_refused_with_the_reason() {
        let e = |t: &str| Structure::from_json(t).map(|_| ()).unwrap_err().to_string();
        assert!(e(&frame("[[1000, 1], [0, 1000]]", 1)).contains("not symmetric"));
        assert!(e(&frame("[[1000, 0], [0, -5]]", 1)).contains("not positive definite"));
        assert!(e(&frame("[[1000, 0], [0, 1000]]", 3)).contains("DOF 3"));
        assert!(e(&frame("[[1000, 0], [0, 1000]]", 0)).contains("DOF 0"));
        assert!(e(&frame("[[1000, 0], [0]]", 1)).contains("row 2"));
        assert!(e(&frame("[[5, 0], [0, 1000]]", 1)).contains("numerical mass"));
        assert!(
            e(&frame("[[1000, 0], [0, 1000]]", 1).replace("rths-structure", "x"))
                .contains("format")
        );
        assert!(
            e(&frame("[[1000, 0], [0, 1000]]", 1).replace("\"version\": 1", "\"version\": 2"))
                .contains("version 2")
        );
    }

    fn yielding(laws: &str, dof: usize) -> String {
        format!(
            r#"{{"format": "rths-structure", "version": 1, "name": "y", "units": "mm-kn",
            "stories": {{"floor_mass": [0.5, 0.5], "story_stiffness": [200, 150], "damping_ratio": 0.02,
                         "hysteresis": {laws}}},
            "specimen": {{"dof": {dof}, "mass": 0, "stiffness": 50, "damping": 0}}}}"#
        )
    }

    const TWO_LAWS: &str = r#"[{"law": "bilinear", "yield_force": 30, "post_yield_ratio": 0.05},
        {"law": "bouc-wen", "yield_force": 20, "post_yield_ratio": 0.02, "exponent": 2,
         "beta": 0.5, "gamma": 0.5}]"#;

    #[test]
    fn a_hysteresis_section_gives_yielding_numerical_stories() -> Result<(), StructureFileError> {
        let s = Structure::from_json(&yielding(TWO_LAWS, 1))?;
        let laws = s.story_laws().ok_or(StructureFileError::Definition)?;
        // The specimen's 50 kN/mm comes off the first story only.
        assert_eq!(laws[0].k0_kn_per_mm(), 150.0);
        assert_eq!(laws[1].k0_kn_per_mm(), 150.0);
        assert_eq!(laws[1].yield_force_kn(), 20.0);
        assert_eq!(s.nonlinear_numerical(1.0 / 4096.0)?.dofs(), 2);
        assert_eq!(s.nonlinear_whole(1.0 / 4096.0)?.dofs(), 2);
        // Linear files load as before and refuse the nonlinear path with the reason.
        let lin = Structure::from_json(&frame("[[1000, 0], [0, 1000]]", 1))?;
        assert!(lin.story_laws().is_none());
        let e = lin.nonlinear_whole(1.0 / 4096.0).map(|_| ()).unwrap_err();
        assert!(e.to_string().contains("linear"));
        Ok(())
    }

    #[test]
    fn non_physical_hysteresis_is_refused_with_the_reason() {
        let e = |laws: &str, dof: usize| {
            Structure::from_json(&yielding(laws, dof))
                .map(|_| ())
                .unwrap_err()
                .to_string()
        };
        let bl = |fy: &str, a: &str| {
            format!(
                r#"[{{"law": "bilinear", "yield_force": {fy}, "post_yield_ratio": {a}}},
                   {{"law": "bilinear", "yield_force": 10, "post_yield_ratio": 0.0}}]"#
            )
        };
        assert!(e(&bl("-5", "0.05"), 1).contains("story 1 hysteresis: yield force"));
        assert!(e(&bl("0", "0.05"), 1).contains("yield force"));
        assert!(e(&bl("10", "-0.5"), 1).contains("post-yield ratio"));
        assert!(e(&bl("10", "1.5"), 1).contains("post-yield ratio"));
        // NaN is not JSON; a string or null in its place is refused by the parser.
        assert!(e(&bl("null", "0.05"), 1).contains("malformed"));
        assert!(e(&bl("10", "0.05"), 2).contains("DOF 1"));
        assert!(e(
            r#"[{"law": "bilinear", "yield_force": 10, "post_yield_ratio": 0}]"#,
            1
        )
        .contains("1 laws for 2 stories"));
        assert!(e(&TWO_LAWS.replace("\"gamma\": 0.5", "\"gamma\": -0.5"), 1)
            .contains("story 2 hysteresis: Bouc-Wen γ"));
        assert!(e(&TWO_LAWS.replace("bilinear", "trilinear"), 1).contains("malformed"));
        // A specimen stiffer than the first story leaves it no positive initial stiffness.
        let soft = yielding(TWO_LAWS, 1).replace("[200, 150]", "[40, 150]");
        let err = Structure::from_json(&soft)
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("story 1 hysteresis: initial story stiffness"),
            "{err}"
        );
    }
}

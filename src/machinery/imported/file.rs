//! The structure file of an imported model (`rths-structure` version 2), its validation, and the
//! validated, condensed model.
//!
//! ```json
//! {"format": "rths-structure", "version": 2, "kind": "sparse", "name": "frame-2x3",
//!  "description": "...", "units": "mm-kn" | "si",
//!  "source": {"script": "frame-2x3.py", "checksum": "fnv1a64:..."},
//!  "equations": [[node, dof], ...],
//!  "influence": [1.0, 0.0, ...],
//!  "mass": [[i, j, value], ...], "damping": [[i, j, value], ...], "stiffness": [[i, j, value], ...],
//!  "specimen": {"at": [node, dof], "stiffness_kn_per_mm": 50.0},
//!  "outputs": [[node, dof], ...]}
//! ```
//!
//! - `equations`: the whole model's free DOFs in the order of the matrices (equation `i` is
//!   `equations[i]`, 0-based), each an OpenSees node tag and DOF (1-based).
//! - `mass`, `damping`, `stiffness`: the *whole* structure's matrices (specimen included), sparse
//!   triplets `[row, column, value]`, 0-based, both triangles stored, each entry at most once, in
//!   the file's `units` (`structure_file::Units`: SI or rths's kN·s²/mm, kN·s/mm, kN/mm).
//! - `influence`: the ground motion's influence vector (displacement of each equation under a unit
//!   ground displacement): the ground force is `−M·ι·ü_g`.
//! - `specimen`: the physical substructure, a spring of `stiffness_kn_per_mm` at the DOF `at` in
//!   that DOF's direction; the numerical substructure is the whole model minus it.
//! - `outputs`: the DOFs whose displacements a run writes (`out_<NODE>_<DOF>_mm`).
//!
//! [`ImportedFile::validate`] refuses, naming the entry: a non-finite value, an index out of range
//! or given twice, an asymmetric matrix (beyond `structure_file::SYMMETRY_TOLERANCE` of its largest
//! entry), negative mass or damping on a diagonal, mass coupling a massless DOF, a DOF without
//! stiffness or a singular stiffness (a mechanism), a specimen or output on a DOF that does not
//! exist or carries no mass, a specimen stiffer than the model at its DOF, a condensed mass that is
//! not positive definite.

use std::collections::{BTreeSet, HashSet};
use std::fmt;
use std::path::{Path, PathBuf};

use nalgebra::{DMatrix, DVector};
use nalgebra_sparse::{CooMatrix, CscMatrix};
use rths_files::structure_file::{Units, STRUCTURE_FORMAT, SYMMETRY_TOLERANCE};
use serde::{Deserialize, Serialize};

use super::condense::{self, Condensed, FactorError};

/// The version of an imported structure file.
pub const IMPORTED_VERSION: u64 = 2;
/// The `kind` tag of an imported structure file.
pub const IMPORTED_KIND: &str = "sparse";

/// A DOF of the model: an OpenSees node tag and its DOF (1-based), written `NODE:DOF`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(from = "(u64, u32)", into = "(u64, u32)")]
pub struct DofLabel {
    /// Node tag.
    pub node: u64,
    /// DOF at the node, 1-based (1: horizontal in a plane frame).
    pub dof: u32,
}

impl From<(u64, u32)> for DofLabel {
    fn from((node, dof): (u64, u32)) -> Self {
        Self { node, dof }
    }
}

impl From<DofLabel> for (u64, u32) {
    fn from(l: DofLabel) -> Self {
        (l.node, l.dof)
    }
}

impl fmt::Display for DofLabel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.node, self.dof)
    }
}

impl std::str::FromStr for DofLabel {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let (n, d) = s
            .split_once(':')
            .ok_or_else(|| format!("{s:?} is not NODE:DOF (e.g. 12:1)"))?;
        let node = n
            .trim()
            .parse()
            .map_err(|_| format!("{s:?}: node {n:?} is not a node tag"))?;
        let dof: u32 = d
            .trim()
            .parse()
            .map_err(|_| format!("{s:?}: DOF {d:?} is not a number"))?;
        if dof == 0 {
            return Err(format!("{s:?}: DOFs count from 1"));
        }
        Ok(Self { node, dof })
    }
}

impl DofLabel {
    /// The history column of an output at this DOF: `out_<NODE>_<DOF>_mm`.
    pub fn column(&self) -> String {
        format!("out_{}_{}_mm", self.node, self.dof)
    }
}

/// Where the model came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Source {
    /// The model script's file name.
    pub script: String,
    /// FNV-1a 64 of the script's bytes.
    pub checksum: String,
}

/// The specimen of an imported structure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImportedSpecimen {
    /// The DOF it acts at, in that DOF's direction.
    pub at: DofLabel,
    /// Its stiffness, kN/mm.
    pub stiffness_kn_per_mm: f64,
}

/// A sparse entry `[row, column, value]`, 0-based.
pub type Triplet = (usize, usize, f64);

/// An imported structure file as stored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImportedFile {
    /// Always `structure_file::STRUCTURE_FORMAT`.
    pub format: String,
    /// Always [`IMPORTED_VERSION`].
    pub version: u64,
    /// Always [`IMPORTED_KIND`].
    pub kind: String,
    /// Short name.
    pub name: String,
    /// What it is and where it comes from.
    #[serde(default)]
    pub description: String,
    /// Units of the matrices.
    pub units: Units,
    /// The model script it was exported from.
    pub source: Source,
    /// The model's free DOFs, in equation order.
    pub equations: Vec<DofLabel>,
    /// Ground-motion influence vector, one entry per equation.
    pub influence: Vec<f64>,
    /// Whole mass.
    pub mass: Vec<Triplet>,
    /// Whole damping.
    pub damping: Vec<Triplet>,
    /// Whole stiffness (specimen included).
    pub stiffness: Vec<Triplet>,
    /// The specimen.
    pub specimen: ImportedSpecimen,
    /// The output DOFs.
    pub outputs: Vec<DofLabel>,
}

/// Why an imported structure file was refused.
#[derive(Debug, thiserror::Error)]
pub enum ImportedStructureError {
    /// Reading failed.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Not JSON, or not the expected fields.
    #[error("malformed imported structure file: {0}")]
    Json(#[from] serde_json::Error),
    /// Another format, version or kind.
    #[error("not an imported structure file: {0}")]
    Header(String),
    /// Shapes that do not fit together.
    #[error("{0}")]
    Shape(String),
    /// A value is NaN or infinite.
    #[error("{what} entry {entry} is not finite")]
    NotFinite {
        /// The field.
        what: &'static str,
        /// The entry.
        entry: String,
    },
    /// An entry's index is beyond the equations, or given twice.
    #[error("{what} entry {entry}: {reason}")]
    Entry {
        /// The matrix.
        what: &'static str,
        /// The entry.
        entry: String,
        /// Why.
        reason: String,
    },
    /// A matrix is not symmetric.
    #[error("{what} is not symmetric: entry ({a}, {b}) = {a_ab:e} but ({b}, {a}) = {a_ba:e}")]
    NotSymmetric {
        /// The matrix.
        what: &'static str,
        /// Row DOF.
        a: DofLabel,
        /// Column DOF.
        b: DofLabel,
        /// `a_ab`.
        a_ab: f64,
        /// `a_ba`.
        a_ba: f64,
    },
    /// A negative diagonal entry of the mass or the damping.
    #[error("negative {what} {value:e} at DOF {dof}")]
    Negative {
        /// Mass or damping.
        what: &'static str,
        /// The DOF.
        dof: DofLabel,
        /// The entry.
        value: f64,
    },
    /// Mass off the diagonal of a DOF without mass of its own.
    #[error("mass entry ({a}, {b}) couples DOF {a}, which has no mass of its own")]
    MasslessCoupling {
        /// The massless DOF.
        a: DofLabel,
        /// The other DOF.
        b: DofLabel,
    },
    /// A mechanism: the stiffness is singular on the free DOFs.
    #[error(
        "the model is a mechanism: its stiffness is singular at DOF {dof} ({detail}); restrain \
         it or connect it"
    )]
    Mechanism {
        /// The DOF found singular.
        dof: DofLabel,
        /// What showed it.
        detail: String,
    },
    /// A mechanism found without a DOF to name.
    #[error("the model is a mechanism: its stiffness is not positive definite on the free DOFs")]
    MechanismUnnamed,
    /// The specimen's or an output's DOF is not a free DOF of the model.
    #[error("the {what} DOF {dof} is not a free DOF of the model ({hint})")]
    NoSuchDof {
        /// Specimen or output.
        what: &'static str,
        /// The DOF.
        dof: DofLabel,
        /// Why (node unknown, DOF restrained, ...).
        hint: String,
    },
    /// The specimen's or an output's DOF carries no mass (it is condensed out).
    #[error(
        "the {what} DOF {dof} carries no mass, so it is condensed out: choose a DOF with mass \
         (a floor's horizontal DOF)"
    )]
    Massless {
        /// Specimen or output.
        what: &'static str,
        /// The DOF.
        dof: DofLabel,
    },
    /// An output is named twice.
    #[error("output DOF {0} is given twice")]
    DuplicateOutput(DofLabel),
    /// A bad specimen stiffness.
    #[error("specimen stiffness {0} kN/mm: must be finite and ≥ 0")]
    SpecimenStiffness(f64),
    /// Without the specimen the numerical part is a mechanism.
    #[error(
        "the specimen's {k} kN/mm at DOF {dof} leaves the numerical part (the model minus the \
         specimen) without positive-definite stiffness: is the specimen in the model, with this \
         stiffness? ({detail})"
    )]
    SpecimenTooStiff {
        /// The specimen's DOF.
        dof: DofLabel,
        /// Its stiffness, kN/mm.
        k: f64,
        /// What showed it.
        detail: String,
    },
    /// The condensed model's dense matrices would be too large to build.
    #[error(
        "{mass_dofs} DOFs carry mass and {massless} do not: condensing them needs dense matrices \
         of {entries} entries, more than the {MAX_DENSE_ENTRIES} this build condenses"
    )]
    TooLarge {
        /// DOFs that carry mass (the condensed model's size).
        mass_dofs: usize,
        /// Massless DOFs (condensed out).
        massless: usize,
        /// The larger of `mass_dofs²` and `massless × mass_dofs`.
        entries: usize,
    },
    /// The condensed mass is not positive definite.
    #[error("the mass is not positive definite on the DOFs that carry it (Cholesky fails)")]
    MassNotPositiveDefinite,
}

/// The most entries of one dense matrix the condensation builds (`M*`, `C*`, `K*` are mass DOFs ×
/// mass DOFs, `K_ss⁻¹·K_sr` massless × mass DOFs): 2²⁵, 256 MB each, 5 792 DOFs with mass. The
/// largest shipped frame has 936 (`opensees-frame-5x12`); the file's size alone would otherwise
/// size them (100 000 equations in a 4 MB file ask 80 GB).
pub const MAX_DENSE_ENTRIES: usize = 1 << 25;

type Result<T> = std::result::Result<T, ImportedStructureError>;

/// Whether a structure file's text is an imported (version 2) one: its `format` and `version`.
pub fn is_imported(text: &str) -> bool {
    #[derive(Deserialize)]
    struct Header {
        format: Option<String>,
        version: Option<u64>,
    }
    serde_json::from_str::<Header>(text)
        .map(|h| {
            h.format.as_deref() == Some(STRUCTURE_FORMAT) && h.version == Some(IMPORTED_VERSION)
        })
        .unwrap_or(false)
}

/// A validated imported structure, in rths units (mm, kN, s), with its massless DOFs condensed.
#[derive(Debug, Clone)]
pub struct ImportedStructure {
    name: String,
    equations: Vec<DofLabel>,
    mass: CscMatrix<f64>,
    damping: CscMatrix<f64>,
    stiffness: CscMatrix<f64>,
    influence: Vec<f64>,
    specimen: DofLabel,
    specimen_equation: usize,
    specimen_k: f64,
    outputs: Vec<DofLabel>,
    output_equations: Vec<usize>,
    /// The equations that carry mass (the condensed model's DOFs), ascending.
    retained: Vec<usize>,
    /// The numerical part condensed onto `retained`.
    condensed: Condensed,
}

/// The whole model's numerical part, sparse, for the host FE.
#[derive(Debug, Clone)]
pub struct SparseModel {
    /// `M`, kN·s²/mm.
    pub mass: CscMatrix<f64>,
    /// `C`, kN·s/mm.
    pub damping: CscMatrix<f64>,
    /// `K − k_E·e·eᵀ`, kN/mm.
    pub stiffness: CscMatrix<f64>,
    /// `ι`.
    pub influence: Vec<f64>,
    /// The specimen's equation.
    pub interface: usize,
    /// The outputs' equations.
    pub outputs: Vec<usize>,
}

fn label(equations: &[DofLabel], i: usize) -> DofLabel {
    equations
        .get(i)
        .copied()
        .unwrap_or(DofLabel { node: 0, dof: 0 })
}

/// A matrix's triplets as a CSC matrix in rths units, checked.
fn sparse(
    entries: &[Triplet],
    what: &'static str,
    equations: &[DofLabel],
    scale: f64,
) -> Result<CscMatrix<f64>> {
    let n = equations.len();
    let mut seen = HashSet::with_capacity(entries.len());
    let mut coo = CooMatrix::new(n, n);
    for (idx, &(i, j, v)) in entries.iter().enumerate() {
        let entry = || format!("#{idx} [{i}, {j}]");
        if i >= n || j >= n {
            return Err(ImportedStructureError::Entry {
                what,
                entry: entry(),
                reason: format!("the model has equations 0..{n}"),
            });
        }
        if !v.is_finite() {
            return Err(ImportedStructureError::NotFinite {
                what,
                entry: format!(
                    "{} ({}, {})",
                    entry(),
                    label(equations, i),
                    label(equations, j)
                ),
            });
        }
        if !seen.insert((i, j)) {
            return Err(ImportedStructureError::Entry {
                what,
                entry: entry(),
                reason: "given twice".to_string(),
            });
        }
        if v != 0.0 {
            coo.push(i, j, v * scale);
        }
    }
    let a = CscMatrix::from(&coo);
    let tol = SYMMETRY_TOLERANCE * a.values().iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    for (i, j, v) in a.triplet_iter() {
        let t = a.get_entry(j, i).map_or(0.0, |e| e.into_value());
        if (v - t).abs() > tol {
            return Err(ImportedStructureError::NotSymmetric {
                what,
                a: label(equations, i),
                b: label(equations, j),
                a_ab: *v / scale,
                a_ba: t / scale,
            });
        }
    }
    Ok(a)
}

fn diagonal(a: &CscMatrix<f64>, i: usize) -> f64 {
    a.get_entry(i, i).map_or(0.0, |e| e.into_value())
}

/// The equation of `dof`, or why it has none.
fn equation_of(equations: &[DofLabel], dof: DofLabel, what: &'static str) -> Result<usize> {
    if let Some(i) = equations.iter().position(|l| *l == dof) {
        return Ok(i);
    }
    let hint = if equations.iter().any(|l| l.node == dof.node) {
        format!(
            "node {} has no free DOF {}: restrained or constrained",
            dof.node, dof.dof
        )
    } else {
        format!("no node {} has free DOFs", dof.node)
    };
    Err(ImportedStructureError::NoSuchDof { what, dof, hint })
}

/// `a − k·e_i·e_iᵀ`.
fn minus_diagonal(a: &CscMatrix<f64>, i: usize, k: f64) -> CscMatrix<f64> {
    let mut coo = CooMatrix::new(a.nrows(), a.ncols());
    for (r, c, v) in a.triplet_iter() {
        coo.push(r, c, *v);
    }
    coo.push(i, i, -k);
    CscMatrix::from(&coo)
}

impl ImportedFile {
    /// Parse a file's JSON text (format, version and kind checked first), not yet validated.
    pub fn parse(text: &str) -> Result<Self> {
        #[derive(Deserialize)]
        struct Header {
            format: Option<String>,
            version: Option<u64>,
            kind: Option<String>,
        }
        let h: Header = serde_json::from_str(text)?;
        if h.format.as_deref() != Some(STRUCTURE_FORMAT)
            || h.version != Some(IMPORTED_VERSION)
            || h.kind.as_deref() != Some(IMPORTED_KIND)
        {
            return Err(ImportedStructureError::Header(format!(
                "format {:?}, version {:?}, kind {:?} (expected \"{STRUCTURE_FORMAT}\", {IMPORTED_VERSION}, \"{IMPORTED_KIND}\")",
                h.format, h.version, h.kind
            )));
        }
        Ok(serde_json::from_str(text)?)
    }

    /// The file's JSON: one line, the same bytes for the same structure.
    pub fn to_json(&self) -> Result<String> {
        let mut s = serde_json::to_string(self)?;
        s.push('\n');
        Ok(s)
    }

    /// Validate into an [`ImportedStructure`] in rths units, condensed.
    pub fn validate(&self) -> Result<ImportedStructure> {
        let eqs = &self.equations;
        let n = eqs.len();
        if n == 0 {
            return Err(ImportedStructureError::Shape(
                "the model has no equations".to_string(),
            ));
        }
        let mut unique = HashSet::with_capacity(n);
        for l in eqs {
            if !unique.insert(*l) {
                return Err(ImportedStructureError::Shape(format!(
                    "equations: DOF {l} is listed twice"
                )));
            }
        }
        if self.influence.len() != n {
            return Err(ImportedStructureError::Shape(format!(
                "influence has {} entries for {n} equations",
                self.influence.len()
            )));
        }
        if let Some(i) = self.influence.iter().position(|v| !v.is_finite()) {
            return Err(ImportedStructureError::NotFinite {
                what: "influence",
                entry: format!("#{i} ({})", label(eqs, i)),
            });
        }
        let scale = self.units.to_mm_kn();
        let mass = sparse(&self.mass, "mass", eqs, scale)?;
        let damping = sparse(&self.damping, "damping", eqs, scale)?;
        let stiffness = sparse(&self.stiffness, "stiffness", eqs, scale)?;
        for (a, what) in [(&mass, "mass"), (&damping, "damping")] {
            for i in 0..n {
                let v = diagonal(a, i);
                if v < 0.0 {
                    return Err(ImportedStructureError::Negative {
                        what,
                        dof: label(eqs, i),
                        value: v / scale,
                    });
                }
            }
        }
        let retained: Vec<usize> = (0..n).filter(|&i| diagonal(&mass, i) > 0.0).collect();
        let (mass_dofs, massless) = (retained.len(), n - retained.len());
        let entries = mass_dofs.saturating_mul(mass_dofs.max(massless));
        if entries > MAX_DENSE_ENTRIES {
            return Err(ImportedStructureError::TooLarge {
                mass_dofs,
                massless,
                entries,
            });
        }
        let with_mass: BTreeSet<usize> = retained.iter().copied().collect();
        for (i, j, _) in mass.triplet_iter() {
            if !with_mass.contains(&i) {
                return Err(ImportedStructureError::MasslessCoupling {
                    a: label(eqs, i),
                    b: label(eqs, j),
                });
            }
        }
        for i in 0..n {
            if diagonal(&stiffness, i) <= 0.0 {
                return Err(ImportedStructureError::Mechanism {
                    dof: label(eqs, i),
                    detail: "no positive stiffness on its diagonal".to_string(),
                });
            }
        }
        condense::cholesky(&stiffness).map_err(|e| match e {
            FactorError::Singular { equation, ratio } => ImportedStructureError::Mechanism {
                dof: label(eqs, equation),
                detail: format!("Cholesky pivot {ratio:.1e} of its diagonal"),
            },
            FactorError::NotPositiveDefinite => ImportedStructureError::MechanismUnnamed,
        })?;

        let k = self.specimen.stiffness_kn_per_mm;
        if !(k.is_finite() && k >= 0.0) {
            return Err(ImportedStructureError::SpecimenStiffness(k));
        }
        let at = self.specimen.at;
        let specimen_equation = equation_of(eqs, at, "specimen")?;
        if !with_mass.contains(&specimen_equation) {
            return Err(ImportedStructureError::Massless {
                what: "specimen",
                dof: at,
            });
        }
        let numerical_k = minus_diagonal(&stiffness, specimen_equation, k);
        condense::cholesky(&numerical_k).map_err(|e| ImportedStructureError::SpecimenTooStiff {
            dof: at,
            k,
            detail: match e {
                FactorError::Singular { equation, ratio } => {
                    format!(
                        "singular at DOF {}, pivot {ratio:.1e}",
                        label(eqs, equation)
                    )
                }
                FactorError::NotPositiveDefinite => "Cholesky fails".to_string(),
            },
        })?;
        let mut output_equations = Vec::with_capacity(self.outputs.len());
        let mut seen = HashSet::new();
        for &o in &self.outputs {
            if !seen.insert(o) {
                return Err(ImportedStructureError::DuplicateOutput(o));
            }
            let e = equation_of(eqs, o, "output")?;
            if !with_mass.contains(&e) {
                return Err(ImportedStructureError::Massless {
                    what: "output",
                    dof: o,
                });
            }
            output_equations.push(e);
        }
        let condensed =
            condense::condense(&mass, &damping, &numerical_k, &retained).map_err(|e| match e {
                FactorError::Singular { equation, ratio } => ImportedStructureError::Mechanism {
                    dof: label(eqs, equation),
                    detail: format!(
                        "the massless DOFs' stiffness has a pivot {ratio:.1e} of its diagonal"
                    ),
                },
                FactorError::NotPositiveDefinite => ImportedStructureError::MechanismUnnamed,
            })?;
        if condensed.mass.clone().cholesky().is_none() {
            return Err(ImportedStructureError::MassNotPositiveDefinite);
        }
        Ok(ImportedStructure {
            name: self.name.clone(),
            equations: eqs.clone(),
            mass,
            damping,
            stiffness,
            influence: self.influence.clone(),
            specimen: at,
            specimen_equation,
            specimen_k: k,
            outputs: self.outputs.clone(),
            output_equations,
            retained,
            condensed,
        })
    }
}

impl ImportedStructure {
    /// Parse and validate an imported structure file's JSON text.
    pub fn from_json(text: &str) -> Result<Self> {
        ImportedFile::parse(text)?.validate()
    }

    /// Read and validate an imported structure file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|source| ImportedStructureError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text)
    }

    /// Short name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The whole model's free DOFs, in equation order.
    pub fn equations(&self) -> &[DofLabel] {
        &self.equations
    }

    /// Number of DOFs that carry mass: the size of the condensed model.
    pub fn mass_dofs(&self) -> usize {
        self.retained.len()
    }

    /// The condensed model's DOFs: each one's equation in the whole model, ascending.
    pub fn condensed_equations(&self) -> &[usize] {
        &self.retained
    }

    /// The numerical substructure condensed onto the DOFs that carry mass, dense, in rths units:
    /// `(M*, C*, K*)` (kN·s²/mm, kN·s/mm, kN/mm), where `K*` is the condensed stiffness of the
    /// whole model minus the specimen's [`Self::specimen_stiffness_kn_per_mm`] at
    /// [`Self::interface_index`] (the whole structure is `K* + k_E·e·eᵀ`). DOF `i` of these is
    /// equation [`Self::condensed_equations`]`[i]` of the whole model. The equation of motion is
    /// `M*·ẍ + C*·ẋ + K*·x = −M*·ι*·ü_g − e·f_E`, with `ι*` [`Self::condensed_influence`] and `f_E`
    /// the specimen's force at the interface (`k_E·x_interface` for the numerical stand-in).
    pub fn condensed_dense(&self) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
        (
            self.condensed.mass.clone(),
            self.condensed.damping.clone(),
            self.condensed.stiffness.clone(),
        )
    }

    /// The ground motion's influence vector `ι*` in the condensed DOFs.
    pub fn condensed_influence(&self) -> DVector<f64> {
        DVector::from_iterator(
            self.retained.len(),
            self.retained
                .iter()
                .map(|&i| self.influence.get(i).copied().unwrap_or(0.0)),
        )
    }

    /// The specimen's (interface) DOF index in the condensed numbering.
    pub fn interface_index(&self) -> usize {
        self.condensed_index(self.specimen_equation)
    }

    /// The output DOFs' indices in the condensed numbering, in [`Self::outputs`]'s order.
    pub fn output_indices(&self) -> Vec<usize> {
        self.output_equations
            .iter()
            .map(|&e| self.condensed_index(e))
            .collect()
    }

    fn condensed_index(&self, equation: usize) -> usize {
        // Validation put every specimen and output equation into `retained`.
        self.retained.binary_search(&equation).unwrap_or(0)
    }

    /// The specimen's DOF.
    pub fn specimen(&self) -> DofLabel {
        self.specimen
    }

    /// The specimen's stiffness, kN/mm (the numerical stand-in's too).
    pub fn specimen_stiffness_kn_per_mm(&self) -> f64 {
        self.specimen_k
    }

    /// The output DOFs.
    pub fn outputs(&self) -> &[DofLabel] {
        &self.outputs
    }

    /// The whole model's numerical part, sparse (no condensation), for the host FE.
    pub fn numerical_sparse(&self) -> SparseModel {
        SparseModel {
            mass: self.mass.clone(),
            damping: self.damping.clone(),
            stiffness: minus_diagonal(&self.stiffness, self.specimen_equation, self.specimen_k),
            influence: self.influence.clone(),
            interface: self.specimen_equation,
            outputs: self.output_equations.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Node 2's three DOFs: x and y carry mass, the rotation does not.
    fn file() -> ImportedFile {
        let l = |dof| DofLabel { node: 2, dof };
        ImportedFile {
            format: STRUCTURE_FORMAT.to_string(),
            version: IMPORTED_VERSION,
            kind: IMPORTED_KIND.to_string(),
            name: "t".to_string(),
            description: String::new(),
            units: Units::MmKn,
            source: Source {
                script: "t.py".to_string(),
                checksum: String::new(),
            },
            equations: vec![l(1), l(2), l(3)],
            influence: vec![1.0, 0.0, 0.0],
            mass: vec![(0, 0, 0.01), (1, 1, 0.01)],
            damping: vec![(0, 0, 0.1), (1, 1, 0.1)],
            stiffness: vec![
                (0, 0, 100.0),
                (0, 2, 1000.0),
                (1, 1, 500.0),
                (2, 0, 1000.0),
                (2, 2, 1e5),
            ],
            specimen: ImportedSpecimen {
                at: l(1),
                stiffness_kn_per_mm: 20.0,
            },
            outputs: vec![l(1), l(2)],
        }
    }

    fn refused(f: &ImportedFile) -> String {
        match f.validate() {
            Ok(_) => "accepted".to_string(),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn a_good_file_condenses_its_massless_dof() -> std::result::Result<(), ImportedStructureError> {
        let f = file();
        let s = ImportedStructure::from_json(&f.to_json()?)?;
        assert_eq!((s.equations().len(), s.mass_dofs()), (3, 2));
        let (m, _, k) = s.condensed_dense();
        // K*₀₀ = 100 − 1000²/1e5 − 20 (the specimen).
        assert!((k[(0, 0)] - (100.0 - 10.0 - 20.0)).abs() < 1e-12, "{k}");
        assert_eq!(m[(1, 1)], 0.01);
        assert_eq!(s.interface_index(), 0);
        assert_eq!(s.output_indices(), vec![0, 1]);
        assert_eq!(s.condensed_influence().as_slice(), &[1.0, 0.0]);
        assert_eq!(s.outputs()[1].column(), "out_2_2_mm");
        Ok(())
    }

    #[test]
    fn bad_models_are_refused_naming_the_entry() {
        let mut f = file();
        f.stiffness[1].2 = 999.0;
        let e = refused(&f);
        assert!(
            e.contains("stiffness is not symmetric: entry (2:3, 2:1)"),
            "{e}"
        );
        let mut f = file();
        f.mass[1].2 = -0.01;
        assert!(refused(&f).contains("negative mass"));
        assert!(refused(&f).contains("2:2"));
        let mut f = file();
        f.stiffness[0].2 = f64::NAN;
        assert!(refused(&f).contains("not finite"));
        let mut f = file();
        f.stiffness[0].2 = 10.0; // K₀₀·K₂₂ = 1e6 = K₀₂²: singular.
        assert!(refused(&f).contains("mechanism"), "{}", refused(&f));
        let mut f = file();
        f.stiffness.retain(|&(i, j, _)| i != 1 && j != 1);
        assert!(refused(&f).contains("mechanism: its stiffness is singular at DOF 2:2"));
        let mut f = file();
        f.specimen.at = DofLabel { node: 9, dof: 1 };
        assert!(refused(&f).contains("specimen DOF 9:1 is not a free DOF"));
        let mut f = file();
        f.outputs.push(DofLabel { node: 2, dof: 3 });
        assert!(refused(&f).contains("output DOF 2:3 carries no mass"));
        let mut f = file();
        f.outputs.push(DofLabel { node: 2, dof: 4 });
        assert!(refused(&f).contains("node 2 has no free DOF 4"));
        let mut f = file();
        f.specimen.stiffness_kn_per_mm = 95.0;
        assert!(refused(&f).contains("leaves the numerical part"));
        let mut f = file();
        f.stiffness.push((0, 0, 1.0));
        assert!(refused(&f).contains("given twice"));
        let mut f = file();
        f.mass.push((2, 0, 0.001));
        f.mass.push((0, 2, 0.001));
        assert!(refused(&f).contains("no mass of its own"));
        let mut f = file();
        f.damping[0].0 = 7;
        assert!(refused(&f).contains("equations 0..3"));
        assert!(
            ImportedFile::parse(&file().to_json().unwrap_or_default().replace("sparse", "x"))
                .is_err()
        );
    }

    #[test]
    fn labels_parse_and_refuse_with_the_reason() {
        assert_eq!("12:1".parse(), Ok(DofLabel { node: 12, dof: 1 }));
        assert!("12".parse::<DofLabel>().is_err());
        assert!("12:0".parse::<DofLabel>().is_err());
        assert!("a:1".parse::<DofLabel>().is_err());
    }
}

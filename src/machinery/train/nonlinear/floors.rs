//! The elastic structure reduced to the floors a lab records, and its training runs read from the
//! lab's time histories: the input of the floor-hysteron form ([`super::hysteron`]).
//!
//! A story structure file's floors are its DOFs (`out_<FLOOR>_1_mm`). An imported structure
//! (`rths import opensees`) is reduced from the DOFs that carry mass onto its output DOFs (and the
//! interface, if it is not an output) by its lowest modes (SEREP): with `Φ` the whole structure's
//! (specimen included) `r` lowest mode shapes, `r` the floors, and `Φ_m` their rows at the floors,
//! `T = Φ·Φ_m⁻¹`, `M_r = TᵀMT`, `C_r = TᵀCT`, `K_r = TᵀKT`, `(Mι)_r = TᵀMι`. The reduced model
//! has those `r` modes exactly (frequencies, shapes at the floors, participation, and the modal
//! damping of a Rayleigh `C`); the higher modes are left out. Static condensation (Guyan,
//! `T = [I; −K_ss⁻¹·K_sm]`) keeps the statics instead and misses the dynamics of the masses off the
//! floors: on the shipped fiber frame its first two frequencies were 0.8 % and 8.5 % high and an
//! elastic run missed OpenSees's by 10.3 % (the modal reduction: 0.02 %). Guyan is kept for floors
//! whose lowest modes do not span them (`Φ_m` singular).

use std::path::Path;

use nalgebra::{DMatrix, DVector};
use rths_files::history::{RecorderUnits, TimeHistory};
use rths_files::hysteron_model_file::{AnyNlModel, HysteronModelFile};
use rths_files::structure_file::{Structure, StructureFile};

use crate::machinery::imported::file::{is_imported, ImportedFile};
use crate::machinery::imported::ImportedStructure;
use crate::machinery::structure::ResidualTail;
use crate::machinery::train::TrainError;

/// The elastic floors of a structure, dense, rths units.
#[derive(Debug, Clone)]
pub struct FloorModel {
    /// The structure's name.
    pub name: String,
    /// The floors' history columns, in order.
    pub columns: Vec<String>,
    /// Mass, kN·s²/mm.
    pub mass: DMatrix<f64>,
    /// Damping, kN·s/mm.
    pub damping: DMatrix<f64>,
    /// The numerical part's elastic stiffness (specimen out), kN/mm.
    pub stiffness: DMatrix<f64>,
    /// `M·ι`, kN·s²/mm.
    pub ground_mass: DVector<f64>,
    /// The specimen's floor.
    pub specimen_floor: usize,
    /// The specimen's nominal stiffness, kN/mm.
    pub specimen_k_kn_per_mm: f64,
    /// The recorder files' units of the lab's model.
    pub units: RecorderUnits,
    /// Whether the floors are a story structure's (each floor the story above the one below).
    pub stories: bool,
    /// How the lab's model was reduced onto the floors.
    pub reduction: Reduction,
}

/// How a structure's model was reduced onto its floors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reduction {
    /// A story structure: its floors are its DOFs.
    None,
    /// The lowest modes (SEREP).
    Modal,
    /// Static condensation (Guyan): the floors' lowest modes did not span them.
    Static,
}

impl Reduction {
    /// How it reads in the training's report.
    pub fn describe(self) -> &'static str {
        match self {
            Reduction::None => "the story structure's floors",
            Reduction::Modal => "reduced onto the floors by the lowest modes",
            Reduction::Static => {
                "condensed statically onto the floors (their lowest modes do not span them)"
            }
        }
    }
}

/// How far a model file's elastic floors may be from the structure's, relative to their norm:
/// the same code derives both, so they agree to rounding; an edit or a corruption does not.
pub const ELASTIC_MATCH_TOLERANCE: f64 = 1e-6;

/// Refuse the model `any` unless its elastic floors are the structure file `structure_json`'s
/// ([`FloorModel::check_elastic`]; a modal-hysteretic model's modes are its structure's by its
/// checksum and the core's checks).
pub fn check_model_elastic(any: &AnyNlModel, structure_json: &str) -> Result<(), TrainError> {
    match any {
        AnyNlModel::Hysteron(h) => FloorModel::from_json(structure_json)?.check_elastic(h),
        AnyNlModel::Modal(_) => Ok(()),
    }
}

/// The nonlinear model file at `model` refused unless it was trained for the structure file
/// whose text is `structure_json` (name and checksum first, so another structure's model says so)
/// and its elastic floors are that structure's ([`check_model_elastic`]), naming the model file.
pub fn check_model_file_elastic(model: &Path, structure_json: &str) -> anyhow::Result<()> {
    use anyhow::Context;
    let any = AnyNlModel::load(model).with_context(|| format!("model {}", model.display()))?;
    any.check_structure(structure_json)
        .with_context(|| format!("model {} refused", model.display()))?;
    check_model_elastic(&any, structure_json)
        .with_context(|| format!("model {} refused", model.display()))
}

impl FloorModel {
    /// Number of floors.
    pub fn floors(&self) -> usize {
        self.columns.len()
    }

    /// Refuse the floor-hysteron model `file` unless its elastic floors are this structure's:
    /// the floors, the specimen, the mass and the ground mass as they are, the stiffness and the
    /// damping times the scales its refinement recorded. The checksum ties a model to its
    /// structure file; this ties the numbers in the model to it too, so a corrupted or
    /// hand-edited file is refused naming the field rather than run as another structure.
    pub fn check_elastic(&self, file: &HysteronModelFile) -> Result<(), TrainError> {
        let refuse = |what: String| {
            TrainError::Setting(format!(
                "the model's {what} is not the structure {}'s (a model file's elastic floors are \
                 the structure's, as trained: retrain it with `rths train nonlinear`)",
                self.name
            ))
        };
        if file.floors != self.columns {
            return Err(refuse(format!("floors ({})", file.floors.join(", "))));
        }
        if file.specimen_floor != self.specimen_floor {
            return Err(refuse("specimen floor".into()));
        }
        let (s_k, s_c) = file
            .training
            .refinement
            .as_ref()
            .map_or((1.0, 1.0), |r| (r.stiffness_scale, r.damping_scale));
        let close = |a: &[f64], b: &[f64]| {
            let d: f64 = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum();
            let n: f64 = b.iter().map(|y| y * y).sum();
            a.len() == b.len()
                && d.sqrt() <= ELASTIC_MATCH_TOLERANCE * n.sqrt().max(f64::MIN_POSITIVE)
        };
        let flat = |m: &[Vec<f64>]| m.iter().flatten().copied().collect::<Vec<f64>>();
        let mine = |m: &DMatrix<f64>, s: f64| -> Vec<f64> {
            (0..m.nrows())
                .flat_map(|i| (0..m.ncols()).map(move |j| s * m[(i, j)]))
                .collect()
        };
        let n = self.floors();
        let square = |m: &[Vec<f64>]| m.len() == n && m.iter().all(|r| r.len() == n);
        for (what, theirs, ours) in [
            ("mass", &file.mass, mine(&self.mass, 1.0)),
            ("stiffness", &file.stiffness, mine(&self.stiffness, s_k)),
            ("damping", &file.damping, mine(&self.damping, s_c)),
        ] {
            if !square(theirs) || !close(&flat(theirs), &ours) {
                return Err(refuse(what.into()));
            }
        }
        let gm: Vec<f64> = self.ground_mass.iter().copied().collect();
        if !close(&file.ground_mass, &gm) {
            return Err(refuse("ground mass".into()));
        }
        if !close(
            &[file.specimen_stiffness_kn_per_mm],
            &[self.specimen_k_kn_per_mm],
        ) {
            return Err(refuse("specimen stiffness".into()));
        }
        Ok(())
    }

    /// The elastic floors of the structure file whose text is `json` (a story file or an
    /// imported one).
    pub fn from_json(json: &str) -> Result<Self, TrainError> {
        if is_imported(json) {
            let s = ImportedStructure::from_json(json)
                .map_err(|e| TrainError::Setting(format!("structure file: {e}")))?;
            let units = ImportedFile::parse(json)
                .map_err(|e| TrainError::Setting(format!("structure file: {e}")))?
                .units;
            Self::imported(&s, super::histories::recorder_units(units))
        } else {
            let s = Structure::from_json(json)
                .map_err(|e| TrainError::Setting(format!("structure file: {e}")))?;
            let units = StructureFile::parse(json)
                .map_err(|e| TrainError::Setting(format!("structure file: {e}")))?
                .units;
            Ok(Self::story(&s, super::histories::recorder_units(units)))
        }
    }

    /// A story structure's floors.
    pub fn story(s: &Structure, units: RecorderUnits) -> Self {
        let (m, k, c) = s.numerical_matrices();
        Self {
            name: s.name().to_string(),
            columns: super::histories::floor_outputs(s.dofs())
                .iter()
                .map(|d| d.column())
                .collect(),
            mass: m,
            damping: c,
            stiffness: k,
            ground_mass: DVector::from_vec(s.ground_mass()),
            specimen_floor: s.specimen_dof(),
            specimen_k_kn_per_mm: s.specimen().1,
            units,
            stories: true,
            reduction: Reduction::None,
        }
    }

    /// An imported structure reduced onto its outputs (and interface): by its lowest modes, else
    /// statically (module docs).
    pub fn imported(s: &ImportedStructure, units: RecorderUnits) -> Result<Self, TrainError> {
        let (m, c, k) = s.condensed_dense();
        let iota = s.condensed_influence();
        let mut masters: Vec<usize> = s.output_indices();
        let mut columns: Vec<String> = s.outputs().iter().map(|o| o.column()).collect();
        let iface = s.interface_index();
        if !masters.contains(&iface) {
            masters.insert(0, iface);
            columns.insert(0, s.specimen().column());
        }
        let n = masters.len();
        if n == 0 || n > rths_core::structure_n::MAX_DOF {
            return Err(TrainError::Setting(format!(
                "structure {}: {n} floors (outputs and interface); the floor-hysteron model \
                 takes 1 to {}",
                s.name(),
                rths_core::structure_n::MAX_DOF
            )));
        }
        let total = m.nrows();
        let mut whole = k.clone();
        whole[(iface, iface)] += s.specimen_stiffness_kn_per_mm();
        let (t, reduction) = match modal_basis(&m, &whole, &masters) {
            Some(t) => (t, Reduction::Modal),
            None => (
                static_basis(&k, &masters, total, s.name())?,
                Reduction::Static,
            ),
        };
        let sym = |a: DMatrix<f64>| (&a + a.transpose()) * 0.5;
        let tt = t.transpose();
        Ok(Self {
            name: s.name().to_string(),
            columns,
            mass: sym(&tt * &m * &t),
            damping: sym(&tt * &c * &t),
            stiffness: sym(&tt * &k * &t),
            ground_mass: &tt * (&m * iota),
            specimen_floor: masters.iter().position(|&i| i == iface).unwrap_or(0),
            specimen_k_kn_per_mm: s.specimen_stiffness_kn_per_mm(),
            units,
            stories: false,
            reduction,
        })
    }
}

/// `T = Φ·Φ_m⁻¹` of the `masters.len()` lowest modes of `(k, m)`, or `None` if their rows at the
/// masters are singular (condition number over 1e8) or the eigenproblem fails.
fn modal_basis(m: &DMatrix<f64>, k: &DMatrix<f64>, masters: &[usize]) -> Option<DMatrix<f64>> {
    let total = m.nrows();
    let n = masters.len();
    let l = m.clone().cholesky()?.l();
    let lk = l.solve_lower_triangular(k)?;
    let a = l.solve_lower_triangular(&lk.transpose())?;
    let a = (&a + a.transpose()) * 0.5;
    let eig = a.symmetric_eigen();
    let mut order: Vec<usize> = (0..total).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    if order
        .iter()
        .take(n)
        .any(|&i| !(eig.eigenvalues[i].is_finite() && eig.eigenvalues[i] > 0.0))
    {
        return None;
    }
    // Φ = L⁻ᵀ·V (mass-normalized shapes), the n lowest.
    let v = DMatrix::from_fn(total, n, |r, c| eig.eigenvectors[(r, order[c])]);
    let phi = l.transpose().solve_upper_triangular(&v)?;
    let phi_m = DMatrix::from_fn(n, n, |r, c| phi[(masters[r], c)]);
    let sv = phi_m.clone().svd(false, false).singular_values;
    let (hi, lo) = (sv.max(), sv.min());
    if !(lo > 0.0 && hi / lo < 1e8) {
        return None;
    }
    let inv = phi_m.try_inverse()?;
    let mut t = phi * inv;
    // The masters' rows are the identity up to round-off: make them exact, so the floors are
    // the recorded DOFs themselves.
    for (j, &i) in masters.iter().enumerate() {
        for c in 0..n {
            t[(i, c)] = if c == j { 1.0 } else { 0.0 };
        }
    }
    Some(t)
}

/// Guyan's `T = [I; −K_ss⁻¹·K_sm]` of the stiffness `k` onto `masters`.
fn static_basis(
    k: &DMatrix<f64>,
    masters: &[usize],
    total: usize,
    name: &str,
) -> Result<DMatrix<f64>, TrainError> {
    let n = masters.len();
    let slaves: Vec<usize> = (0..total).filter(|i| !masters.contains(i)).collect();
    let mut t = DMatrix::<f64>::zeros(total, n);
    for (j, &i) in masters.iter().enumerate() {
        t[(i, j)] = 1.0;
    }
    if !slaves.is_empty() {
        let kss = DMatrix::from_fn(slaves.len(), slaves.len(), |a, b| k[(slaves[a], slaves[b])]);
        let ksm = DMatrix::from_fn(slaves.len(), n, |a, b| k[(slaves[a], masters[b])]);
        let x = kss
            .clone()
            .cholesky()
            .map(|ch| ch.solve(&ksm))
            .or_else(|| kss.lu().solve(&ksm))
            .ok_or_else(|| {
                TrainError::Setting(format!(
                    "structure {name}: the DOFs off the floors have a singular stiffness"
                ))
            })?;
        for (a, &i) in slaves.iter().enumerate() {
            for j in 0..n {
                t[(i, j)] = -x[(a, j)];
            }
        }
    }
    Ok(t)
}

/// One training or scoring run in the floors' coordinates.
#[derive(Debug, Clone)]
pub struct FloorRun {
    /// The file's name.
    pub label: String,
    /// Ground acceleration, mm/s².
    pub ground_accel_mm_s2: Vec<f64>,
    /// The stand-in specimen's force, kN.
    pub specimen_force_kn: Vec<f64>,
    /// `floor_disp_mm[floor][step]`.
    pub floor_disp_mm: Vec<Vec<f64>>,
}

impl FloorRun {
    /// Steps.
    pub fn len(&self) -> usize {
        self.ground_accel_mm_s2.len()
    }

    /// Whether it has no steps.
    pub fn is_empty(&self) -> bool {
        self.ground_accel_mm_s2.is_empty()
    }

    /// Drift of story `i` (floor `i` minus floor `i − 1`) at every step.
    pub fn drift_mm(&self, i: usize) -> Vec<f64> {
        match i.checked_sub(1).and_then(|j| self.floor_disp_mm.get(j)) {
            Some(below) => self.floor_disp_mm[i]
                .iter()
                .zip(below)
                .map(|(a, b)| a - b)
                .collect(),
            None => self.floor_disp_mm.get(i).cloned().unwrap_or_default(),
        }
    }

    /// Each story's residual drift: the mean over the last
    /// [`RESIDUAL_WINDOW_S`](crate::machinery::structure::RESIDUAL_WINDOW_S), mm.
    pub fn residual_drift_mm(&self, dt_s: f64) -> Vec<f64> {
        residual_drifts(&self.floor_disp_mm, dt_s)
    }
}

/// Each story's residual drift of `floors` (`[floor][step]`), mm.
pub fn residual_drifts(floors: &[Vec<f64>], dt_s: f64) -> Vec<f64> {
    residual_tails(floors, dt_s)
        .iter()
        .map(|t| t.mean_mm)
        .collect()
}

/// Each story's residual tail of `floors` (`[floor][step]`): its residual drift and how much it
/// still swings.
pub fn residual_tails(floors: &[Vec<f64>], dt_s: f64) -> Vec<ResidualTail> {
    (0..floors.len())
        .map(|i| {
            let d: Vec<f64> = match i.checked_sub(1) {
                Some(j) => floors[i]
                    .iter()
                    .zip(&floors[j])
                    .map(|(a, b)| a - b)
                    .collect(),
                None => floors[i].clone(),
            };
            ResidualTail::of(&d, dt_s)
        })
        .collect()
}

/// The run of the history `h` in the floors of `fm`: every floor's column must be there, and the
/// interface must be the specimen's floor.
pub fn run_from_history(fm: &FloorModel, h: &TimeHistory) -> Result<FloorRun, TrainError> {
    let src = h.source.display().to_string();
    if h.len() < 3 {
        return Err(TrainError::Setting(format!(
            "{src}: {} rows; a run needs at least 3",
            h.len()
        )));
    }
    let mut floors = Vec::with_capacity(fm.floors());
    for c in &fm.columns {
        let v = h
            .outputs
            .iter()
            .find(|(d, _)| d.column() == *c)
            .map(|(_, v)| v.clone())
            .or_else(|| {
                // The interface's own column stands in for an interface that is not an output.
                (floors.len() == fm.specimen_floor).then(|| h.interface_mm.clone())
            })
            .ok_or_else(|| {
                TrainError::Setting(format!(
                    "{src}: no column {c} (a history of {} carries every floor the model has: {})",
                    fm.name,
                    fm.columns.join(", ")
                ))
            })?;
        floors.push(v);
    }
    super::histories::interface_is_floor(
        h,
        &floors[fm.specimen_floor],
        &fm.columns[fm.specimen_floor],
    )?;
    Ok(FloorRun {
        label: h
            .source
            .file_name()
            .map_or_else(|| src.clone(), |f| f.to_string_lossy().into_owned()),
        ground_accel_mm_s2: h.ground_accel_mm_s2.clone(),
        specimen_force_kn: h.specimen_force_kn.clone(),
        floor_disp_mm: floors,
    })
}

/// Read every history at `paths` into runs of `fm`.
pub fn read_runs(fm: &FloorModel, paths: &[&Path], dt_s: f64) -> Result<Vec<FloorRun>, TrainError> {
    paths
        .iter()
        .map(|p| {
            let h = rths_files::history::read(p, fm.units, dt_s)
                .map_err(|e| TrainError::Setting(e.to_string()))?;
            run_from_history(fm, &h)
        })
        .collect()
}

/// The restoring force of the numerical part at every floor and step, recovered by equilibrium
/// from the recorded floors: `R = −M·(ẍ + ι·ü_g) − C·ẋ − e·F_E`, `ẋ, ẍ` central differences.
/// `every`: keep every such step (from step 1 to the second last).
pub fn restoring_force_kn(
    fm: &FloorModel,
    run: &FloorRun,
    dt_s: f64,
    every: usize,
) -> Vec<(usize, DVector<f64>)> {
    let n = fm.floors();
    let steps = run.len();
    let mut out = Vec::new();
    let mut k = 1;
    while k + 1 < steps {
        let vel = DVector::from_fn(n, |i, _| {
            let f = &run.floor_disp_mm[i];
            (f[k + 1] - f[k - 1]) / (2.0 * dt_s)
        });
        let acc = DVector::from_fn(n, |i, _| {
            let f = &run.floor_disp_mm[i];
            (f[k + 1] - 2.0 * f[k] + f[k - 1]) / (dt_s * dt_s)
        });
        let mut r =
            -(&fm.mass * acc) - &fm.damping * vel - &fm.ground_mass * run.ground_accel_mm_s2[k];
        r[fm.specimen_floor] -= run.specimen_force_kn[k];
        out.push((k, r));
        k += every.max(1);
    }
    out
}

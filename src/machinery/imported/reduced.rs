//! The reduced-order model of an imported structure (`rths train meta --structure S.json` on an
//! imported OpenSees model; docs/opensees.md "The reduced model"): its training from the
//! structure's matrices and training records, and its model file (`rths-reduced-model`), tied to the
//! structure by name and checksum.
//!
//! Training: the whole structure's modes (the numerical part plus the stand-in specimen's
//! stiffness `k_e`, mass-normalized, from `M*`'s Cholesky factor and a symmetric eigensolution),
//! the static correction of the modes left out (from `K⁻¹·M·ι` and `K⁻¹·e`), then the number of
//! modes kept: the fewest whose pure loop is within [`REDUCED_TARGET_NRMSE_PCT`] of the host FE
//! ([`super::fe`]) on the training records at every read-out, the interface and each output. The
//! training records' runs are all it sees; held-out records are scored elsewhere.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use rths_core::checksum::{Fnv1a64, Fnv1a64Label};
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource, StructureReduced};
use rths_core::metamodel::{ModelError, ReducedModalParams, REDUCED_MAX_MODES};
use rths_core::metrics::nrmse_pct;
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::Limits;
pub use rths_files::reduced_model_file::{
    ReducedArrays, ReducedFileError, ReducedModeEntry, ReducedModelFile, ReducedRecordError,
    ReducedTraining, StaticEntry, StructureIdentity, REDUCED_FORMAT, REDUCED_VERSION,
};

use super::fe::{self, FeHistory};
use super::modal_reference::{ModalInputs, ModalReference, NotClassical};
use super::ImportedStructure;
use crate::machinery::drive;

/// The records the reduced model is trained (its size chosen) on: the embedded Northridge and
/// Loma Prieta, the structure metamodel's training records; El Centro, Kobe and Morgan Hill stay
/// held out.
pub const REDUCED_TRAINING_RECORDS: [&str; 2] = ["northridge", "loma-prieta"];
/// The pure-loop error the number of modes is chosen for, % NRMSE at every read-out on every
/// training record (a fifth of the 0.5 % goal against OpenSees, so held-out records and
/// the host FE's own difference from OpenSees leave a margin).
pub const REDUCED_TARGET_NRMSE_PCT: f64 = 0.1;

/// Why a reduced model could not be trained, read or used.
#[derive(Debug, thiserror::Error)]
pub enum ReducedError {
    /// The condensed mass is not positive definite.
    #[error("the condensed mass matrix is not positive definite (a DOF without mass was kept)")]
    Mass,
    /// The whole structure's stiffness is not positive definite.
    #[error("the structure's stiffness with its specimen is not positive definite (a mechanism)")]
    Stiffness,
    /// A training record is missing.
    #[error("training record {0} is not embedded")]
    Record(String),
    /// The host FE failed.
    #[error(transparent)]
    Fe(#[from] fe::FeError),
    /// The parameters failed core's validation.
    #[error("the reduced model's parameters: {0}")]
    Model(ModelError),
    /// The model file (its format, its structure, its arrays).
    #[error(transparent)]
    File(#[from] ReducedFileError),
    /// The order asked (`rths train meta --modes R`) cannot be kept.
    #[error("--modes {modes}: {reason}")]
    Order {
        /// The modes asked.
        modes: usize,
        /// Why not.
        reason: String,
    },
    /// The controller's supervisor stopped the pure loop (a step that was not finite).
    #[error("the reduced model's pure loop stopped ({reason}) at {time_s:.3} s")]
    Stopped {
        /// The supervisor's reason.
        reason: String,
        /// When, s.
        time_s: f64,
    },
}

impl From<ModelError> for ReducedError {
    fn from(e: ModelError) -> Self {
        ReducedError::Model(e)
    }
}

/// The model's parameters for a hybrid loop on a rig, at control step `dt_s`, checked against
/// `structure`: the static term's force deviation low-passed at the lowest retained mode's
/// frequency ([`ReducedModalParams::with_static_force_cutoff_hz`]). That deviation is the rig
/// specimen's departure from the nominal (what the static term is for, at the response's own
/// frequencies) plus the load cell's noise and the rig's inertia and tracking error (high
/// frequencies the term must not pass to the target in the same tick). Measured on frame-2x3,
/// benchmark preset: unfiltered, or at the lowest truncated mode (12.0 Hz), the loop oscillates at
/// 68 Hz through the lead and trips the command-velocity interlock at 1.0 s; at 4 Hz, 2.1 Hz (its
/// first mode) or 0.1 Hz it is stable, J4 1.32 % (docs/opensees.md).
pub fn hybrid_params(
    file: &ReducedModelFile,
    structure: &ImportedStructure,
    dt_s: f64,
) -> Result<ReducedModalParams, ReducedError> {
    let arrays = file.arrays_for(structure, dt_s)?;
    Ok(arrays.spec().params(dt_s)?.for_hybrid_loop()?)
}

/// A checksum of what an imported structure *is*: its condensed `M*`, `C*`, `K*` (row-major), the
/// ground influence, the interface and output DOFs and the specimen's stiffness, as little-endian
/// f64 bytes ([`rths_core::checksum`]).
pub fn imported_checksum(s: &ImportedStructure) -> String {
    let (m, c, k) = s.condensed_dense();
    let mut h = Fnv1a64::new();
    h.write_f64(m.nrows() as f64);
    for a in [&m, &c, &k] {
        for v in a.transpose().iter() {
            h.write_f64(*v);
        }
    }
    for v in s.condensed_influence().iter() {
        h.write_f64(*v);
    }
    h.write_f64(s.interface_index() as f64);
    for o in s.output_indices() {
        h.write_f64(o as f64);
    }
    h.write_f64(s.specimen_stiffness_kn_per_mm());
    Fnv1a64Label(h.finish()).to_string()
}

impl StructureIdentity for ImportedStructure {
    fn name(&self) -> &str {
        ImportedStructure::name(self)
    }
    fn checksum(&self) -> String {
        imported_checksum(self)
    }
}

/// The whole structure's modes and static responses, lowest mode first.
struct Modes {
    /// ω², (rad/s)² (the eigenvalues).
    lambda: Vec<f64>,
    /// ω, rad/s.
    omega: Vec<f64>,
    /// Mass-normalized shapes, one column per mode.
    shapes: DMatrix<f64>,
    /// `ζ`.
    zeta: Vec<f64>,
    /// `Γ = φᵀMι`.
    gamma: Vec<f64>,
    /// `ΦᵀCΦ`.
    modal_damping: DMatrix<f64>,
    /// `K⁻¹·M·ι`.
    static_ground: DVector<f64>,
    /// `K⁻¹·e`.
    static_force: DVector<f64>,
    /// [`imported_checksum`] of the structure, once: each mode count tried writes it.
    checksum: String,
}

fn modes_of(s: &ImportedStructure) -> Result<Modes, ReducedError> {
    let (m, c, mut k) = s.condensed_dense();
    let n = m.nrows();
    let e = s.interface_index();
    if let Some(kee) = k.get_mut((e, e)) {
        *kee += s.specimen_stiffness_kn_per_mm();
    }
    let l = m.clone().cholesky().ok_or(ReducedError::Mass)?.l();
    // A = L⁻¹·K·L⁻ᵀ (symmetric): two triangular solves.
    let lk = l.solve_lower_triangular(&k).ok_or(ReducedError::Mass)?;
    let a = l
        .solve_lower_triangular(&lk.transpose())
        .ok_or(ReducedError::Mass)?;
    let a = (&a + a.transpose()) * 0.5;
    let eig = a.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let lt = l.transpose();
    let mut shapes = DMatrix::zeros(n, n);
    let mut omega = Vec::with_capacity(n);
    let mut lambdas = Vec::with_capacity(n);
    for (col, &i) in order.iter().enumerate() {
        let lambda = eig.eigenvalues[i];
        if lambda.is_nan() || lambda <= 0.0 {
            return Err(ReducedError::Stiffness);
        }
        let y = eig.eigenvectors.column(i).into_owned();
        let mut phi = lt.solve_upper_triangular(&y).ok_or(ReducedError::Mass)?;
        // A sign convention (the largest entry positive) so the same structure gives the same file.
        let imax = phi.iamax();
        if phi[imax] < 0.0 {
            phi = -phi;
        }
        shapes.set_column(col, &phi);
        omega.push(lambda.sqrt());
        lambdas.push(lambda);
    }
    let modal_damping = shapes.transpose() * &c * &shapes;
    let zeta = omega
        .iter()
        .enumerate()
        .map(|(j, w)| modal_damping[(j, j)] / (2.0 * w))
        .collect();
    let iota = s.condensed_influence();
    let m_iota = &m * &iota;
    let gamma = (shapes.transpose() * &m_iota).iter().copied().collect();
    let kc = k.cholesky().ok_or(ReducedError::Stiffness)?;
    let static_ground = kc.solve(&m_iota);
    let mut unit = DVector::zeros(n);
    if let Some(u) = unit.get_mut(e) {
        *u = 1.0;
    }
    let static_force = kc.solve(&unit);
    Ok(Modes {
        lambda: lambdas,
        omega,
        shapes,
        zeta,
        gamma,
        modal_damping,
        static_ground,
        static_force,
        checksum: imported_checksum(s),
    })
}

/// The model of the `r` lowest modes (the file without its training record).
fn reduced_of(s: &ImportedStructure, md: &Modes, r: usize, dt_s: f64) -> ReducedModelFile {
    let e = s.interface_index();
    let outs = s.output_indices();
    let correction = |row: usize| {
        let mut g = md.static_ground.get(row).copied().unwrap_or(0.0);
        let mut f = md.static_force.get(row).copied().unwrap_or(0.0);
        for j in 0..r {
            let w2 = md.omega[j] * md.omega[j];
            let phi = md.shapes[(row, j)];
            g -= phi * md.gamma[j] / w2;
            f -= phi * md.shapes[(e, j)] / w2;
        }
        StaticEntry {
            ground_mm_per_mm_s2: g,
            force_mm_per_kn: f,
        }
    };
    let modes = (0..r)
        .map(|j| ReducedModeEntry {
            frequency_hz: md.omega[j] / (2.0 * std::f64::consts::PI),
            omega_rad_s: md.omega[j],
            damping_ratio: md.zeta[j],
            ground_participation: md.gamma[j],
            interface_shape: md.shapes[(e, j)],
            output_shape: outs.iter().map(|&o| md.shapes[(o, j)]).collect(),
        })
        .collect();
    let mut coupling: f64 = 0.0;
    for i in 0..r {
        for j in 0..r {
            if i != j {
                let d = (md.modal_damping[(i, i)] * md.modal_damping[(j, j)])
                    .abs()
                    .sqrt();
                if d > 0.0 {
                    coupling = coupling.max(md.modal_damping[(i, j)].abs() / d);
                }
            }
        }
    }
    ReducedModelFile {
        format: REDUCED_FORMAT.into(),
        version: REDUCED_VERSION,
        structure: s.name().to_string(),
        structure_checksum: md.checksum.clone(),
        dt_s,
        dofs: s.equations().len(),
        mass_dofs: s.mass_dofs(),
        specimen_k_kn_per_mm: s.specimen_stiffness_kn_per_mm(),
        outputs: s.outputs().iter().map(|o| o.column()).collect(),
        modes,
        interface_static: correction(e),
        output_static: outs.iter().map(|&o| correction(o)).collect(),
        training: ReducedTraining {
            records: Vec::new(),
            target_nrmse_pct: REDUCED_TARGET_NRMSE_PCT,
            error_bound_pct: f64::NAN,
            per_record: Vec::new(),
            total_modes: md.omega.len(),
            lowest_truncated_hz: md.omega.get(r).map(|w| w / (2.0 * std::f64::consts::PI)),
            damping_coupling: coupling,
        },
    }
}

/// The pure loop of a reduced model under `ag_mm_s2`, one sample per step (row 0: rest), as
/// [`fe::run_pure`] gives the host FE's: the model as the analytical part of core's controller
/// (`rths_core::control::Controller`, the tick the firmware runs), coupled with the numerical
/// stand-in specimen (`FeedbackSource::OwnLinearSpecimen`: `F = k_e·target`), no actuator, run by
/// the host's driver ([`crate::machinery::drive::run_pure`]); each row the part's interface and
/// outputs as the controller holds them after the tick (`Analytical::interface_disp_mm`,
/// `Analytical::output_disp_mm`).
pub fn run_pure(
    params: ReducedModalParams,
    output_columns: Vec<String>,
    ag_mm_s2: &[f64],
) -> Result<FeHistory, ReducedError> {
    let dt_s = params.dt_s();
    let n_out = params.outputs();
    let config = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::OwnLinearSpecimen {
            stiffness_kn_per_mm: params.specimen_k_kn_per_mm(),
        },
        // No actuator: nothing physical to protect, only a non-finite step trips.
        Limits::unbounded(),
    )
    .map_err(ModelError::from)?;
    let mut ctl = Controller::new(
        config,
        Analytical::StructureReduced(StructureReduced::new(params)),
        Compensator::None,
    );
    let mut interface_mm = Vec::with_capacity(ag_mm_s2.len());
    let mut outputs_mm = Vec::with_capacity(ag_mm_s2.len());
    let stop = drive::run_pure(&mut ctl, ag_mm_s2, dt_s, |_, ctl| {
        let part = ctl.analytical();
        interface_mm.push(part.interface_disp_mm().unwrap_or(f64::NAN));
        outputs_mm.push(
            (0..n_out)
                .map(|o| part.output_disp_mm(o).unwrap_or(f64::NAN))
                .collect(),
        );
        ControlFlow::Continue(())
    });
    if let Some((reason, time_s)) = stop {
        return Err(ReducedError::Stopped { reason, time_s });
    }
    Ok(FeHistory {
        dt_s,
        output_columns,
        interface_mm,
        outputs_mm,
    })
}

/// `(interface, largest output)` NRMSE of `run` against `reference`, %.
pub fn history_nrmse_pct(run: &FeHistory, reference: &FeHistory) -> (f64, f64) {
    let n = run.interface_mm.len().min(reference.interface_mm.len());
    let i = nrmse_pct(&run.interface_mm[..n], &reference.interface_mm[..n]).unwrap_or(f64::NAN);
    let outs = run.outputs_mm.first().map_or(0, Vec::len);
    let mut worst: f64 = 0.0;
    for o in 0..outs {
        let col = |h: &FeHistory| -> Vec<f64> {
            h.outputs_mm
                .iter()
                .take(n)
                .map(|row| row.get(o).copied().unwrap_or(f64::NAN))
                .collect()
        };
        let e = nrmse_pct(&col(run), &col(reference)).unwrap_or(f64::NAN);
        worst = if e.is_nan() { f64::NAN } else { worst.max(e) };
    }
    (i, worst)
}

/// What the training records' runs (the reduced model's reference) were computed with.
#[derive(Debug, Clone, PartialEq)]
pub enum TrainingReference {
    /// Modal superposition of all the structure's modes ([`ModalReference`]): the condensed
    /// model's Newmark to round-off, `O(n)` per step.
    Modal {
        /// The modes superposed (every one).
        modes: usize,
        /// The damping's largest departure from the classical form, relative.
        residual: f64,
    },
    /// The sparse host FE ([`fe::run_pure`]), because the modal superposition does not apply.
    SparseFe {
        /// Why not.
        why: NotClassical,
    },
}

impl std::fmt::Display for TrainingReference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TrainingReference::Modal { modes, residual } => write!(
                f,
                "modal superposition of all {modes} modes (the damping classical but for the \
                 specimen's DOF, to {residual:.1e})"
            ),
            TrainingReference::SparseFe { why } => write!(f, "the sparse host FE ({why})"),
        }
    }
}

/// The modal superposition of all of `structure`'s modes `md`, if its damping allows it.
fn modal_reference(
    structure: &ImportedStructure,
    md: &Modes,
) -> Result<ModalReference, NotClassical> {
    let row = |r: usize| -> Vec<f64> { md.shapes.row(r).iter().copied().collect() };
    ModalReference::new(
        structure.massless_damping_residual(),
        ModalInputs {
            omega_sq: &md.lambda,
            modal_damping: &md.modal_damping,
            gamma: &md.gamma,
            interface_row: row(structure.interface_index()),
            output_rows: structure.output_indices().into_iter().map(row).collect(),
        },
    )
}

/// Run `work` on other threads while this one reports `stage` through `progress` with the count
/// `work` keeps in its counter (out of `total`), every 50 ms: the bar moves while the records run
/// in parallel.
fn reporting<T: Send>(
    stage: &str,
    total: u64,
    progress: &mut impl FnMut(&str, u64, u64),
    work: impl FnOnce(&AtomicU64) -> T + Send,
) -> T {
    let done = AtomicU64::new(0);
    std::thread::scope(|scope| {
        let handle = scope.spawn(|| work(&done));
        while !handle.is_finished() {
            progress(stage, done.load(Ordering::Relaxed).min(total), total);
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        progress(stage, total, total);
        handle
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
    })
}

/// The training's score of the model of the `r` lowest modes.
enum Scored {
    /// Mode `r` cannot be kept (critical damping or beyond: core refuses ζ ≥ 1); the model stops
    /// at the last mode below.
    Stop,
    /// The file's arrays are not a model (the next count may be).
    Skip,
    /// The error bound (the largest NRMSE on the training records, %) and the file with its
    /// training record.
    Model(f64, Box<ReducedModelFile>),
}

/// Score the model of the `r` lowest modes: per record, its pure loop against the reference.
fn score_modes(
    structure: &ImportedStructure,
    md: &Modes,
    r: usize,
    dt_s: f64,
    records: &[(String, Vec<f64>)],
    reference: &[FeHistory],
) -> Result<Scored, ReducedError> {
    if md.zeta.get(r - 1).is_none_or(|z| !(0.0..1.0).contains(z)) {
        return Ok(Scored::Stop);
    }
    let mut file = reduced_of(structure, md, r, dt_s);
    let Ok(arrays) = file.arrays() else {
        return Ok(Scored::Skip);
    };
    let params = arrays.spec().params(dt_s)?;
    let mut per_record = Vec::new();
    let mut bound: f64 = 0.0;
    for ((name, ag), reference) in records.iter().zip(reference) {
        let run = run_pure(params, file.outputs.clone(), ag)?;
        let (i, o) = history_nrmse_pct(&run, reference);
        bound = if i.is_nan() || o.is_nan() {
            f64::INFINITY
        } else {
            bound.max(i).max(o)
        };
        per_record.push(ReducedRecordError {
            record: name.clone(),
            interface_nrmse_pct: i,
            max_output_nrmse_pct: o,
        });
    }
    file.training.records = records.iter().map(|(n, _)| n.clone()).collect();
    file.training.error_bound_pct = bound;
    file.training.per_record = per_record;
    Ok(Scored::Model(bound, Box::new(file)))
}

/// The training records' runs the mode count is chosen against, and what computed them: the
/// modal superposition of all of `structure`'s modes `md` where it applies, else the sparse host
/// FE; the records in parallel.
fn reference_runs(
    structure: &ImportedStructure,
    md: &Modes,
    records: &[(String, Vec<f64>)],
    dt_s: f64,
    mut progress: impl FnMut(&str, u64, u64),
) -> Result<(Vec<FeHistory>, TrainingReference), ReducedError> {
    let steps: u64 = records.iter().map(|(_, ag)| ag.len() as u64).sum();
    let (reference, kind) = match modal_reference(structure, md) {
        Ok(modal) => {
            let columns: Vec<String> = structure.outputs().iter().map(|o| o.column()).collect();
            let runs = reporting(
                "modal reference on the training records",
                steps,
                &mut progress,
                |done| {
                    records
                        .par_iter()
                        .map(|(_, ag)| {
                            let h = modal.run(ag, dt_s, columns.clone());
                            done.fetch_add(ag.len() as u64, Ordering::Relaxed);
                            h
                        })
                        .collect::<Vec<_>>()
                },
            );
            let kind = TrainingReference::Modal {
                modes: modal.modes(),
                residual: modal.residual(),
            };
            (runs, kind)
        }
        Err(why) => {
            let runs = reporting(
                "host FE on the training records",
                steps,
                &mut progress,
                |done| {
                    records
                        .par_iter()
                        .map(|(_, ag)| {
                            let mut last = 0;
                            fe::run_pure(structure, ag, dt_s, |k| {
                                done.fetch_add((k - last) as u64, Ordering::Relaxed);
                                last = k;
                            })
                        })
                        .collect::<Result<Vec<_>, _>>()
                },
            )?;
            (runs, TrainingReference::SparseFe { why })
        }
    };
    Ok((reference, kind))
}

/// The runs [`train`] scores its models against on `records` (name, ground acceleration at
/// `dt_s`), and what computed them ([`TrainingReference`]): evaluation of the training's own
/// reference (tests/reduced.rs compares it with the sparse host FE).
pub fn training_reference(
    structure: &ImportedStructure,
    records: &[(String, Vec<f64>)],
    dt_s: f64,
) -> Result<(Vec<FeHistory>, TrainingReference), ReducedError> {
    let md = modes_of(structure)?;
    reference_runs(structure, &md, records, dt_s, |_, _, _| {})
}

/// Train the reduced model of `structure` at control step `dt_s` on `records` (name, ground
/// acceleration at `dt_s`, mm/s²). `progress(stage, done, total)` reports the work.
pub fn train(
    structure: &ImportedStructure,
    records: &[(String, Vec<f64>)],
    dt_s: f64,
    progress: impl FnMut(&str, u64, u64),
) -> Result<ReducedModelFile, ReducedError> {
    train_reporting(structure, records, dt_s, progress).map(|(file, _)| file)
}

/// How many modes the training keeps.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeChoice {
    /// The fewest within [`REDUCED_TARGET_NRMSE_PCT`] on the training records, else the count with
    /// the smallest bound (the default: each model as accurate as the target asks).
    ForTarget,
    /// Exactly this many, the lowest (`rths train meta --modes R`): a fixed order, so models of
    /// any size cost the same per tick (the cost grows with the modes and outputs, not the DOFs).
    /// Its bound is measured on the training records as the default's is: what the order costs
    /// in accuracy.
    Fixed(usize),
}

/// [`train`], and what the training records' runs were computed with: the modal superposition of
/// all the modes where the damping is classical but for the specimen's DOF, the sparse host FE
/// otherwise. The records run in parallel, and so do the mode counts tried (in batches of the
/// threads; the choice is the sequential one's: the fewest modes within the target, else the
/// smallest bound).
pub fn train_reporting(
    structure: &ImportedStructure,
    records: &[(String, Vec<f64>)],
    dt_s: f64,
    progress: impl FnMut(&str, u64, u64),
) -> Result<(ReducedModelFile, TrainingReference), ReducedError> {
    train_choosing(structure, records, dt_s, ModeChoice::ForTarget, progress)
}

/// [`train_reporting`] with the modes kept chosen by `choice`. A fixed order is refused, with the
/// reason, if it is 0, more than core's controller holds ([`REDUCED_MAX_MODES`]), more than the
/// structure has (its DOFs with mass), or if its highest mode is damped at or beyond critical
/// (core runs modes below it only).
pub fn train_choosing(
    structure: &ImportedStructure,
    records: &[(String, Vec<f64>)],
    dt_s: f64,
    choice: ModeChoice,
    mut progress: impl FnMut(&str, u64, u64),
) -> Result<(ReducedModelFile, TrainingReference), ReducedError> {
    if let ModeChoice::Fixed(r) = choice {
        // Before the modes are computed (the eigen-solution is the training's largest part).
        let reason = if r == 0 {
            Some("a reduced model keeps at least 1 mode".to_string())
        } else if r > REDUCED_MAX_MODES {
            Some(format!(
                "core's controller holds at most {REDUCED_MAX_MODES} modes \
                 (rths_core::metamodel::REDUCED_MAX_MODES)"
            ))
        } else if r > structure.mass_dofs() {
            Some(format!(
                "{} has {} modes (its DOFs with mass)",
                structure.name(),
                structure.mass_dofs()
            ))
        } else {
            None
        };
        if let Some(reason) = reason {
            return Err(ReducedError::Order { modes: r, reason });
        }
    }
    progress("modes", 0, 1);
    let md = modes_of(structure)?;
    progress("modes", 1, 1);
    let (reference, kind) = reference_runs(structure, &md, records, dt_s, &mut progress)?;
    if let ModeChoice::Fixed(r) = choice {
        progress("modes kept", 0, 1);
        let file = match score_modes(structure, &md, r, dt_s, records, &reference)? {
            Scored::Model(_, file) => *file,
            Scored::Stop => {
                return Err(ReducedError::Order {
                    modes: r,
                    reason: format!(
                        "mode {r} ({:.2} Hz) has a damping ratio of {:.3}; core runs modes \
                         below critical damping only: ask for at most {} modes",
                        md.omega[r - 1] / (2.0 * std::f64::consts::PI),
                        md.zeta[r - 1],
                        r - 1
                    ),
                })
            }
            // The arrays' own refusal, named.
            Scored::Skip => {
                return Err(reduced_of(structure, &md, r, dt_s).arrays().err().map_or(
                    ReducedError::Order {
                        modes: r,
                        reason: "the model is not valid".into(),
                    },
                    ReducedError::File,
                ))
            }
        };
        progress("modes kept", 1, 1);
        return Ok((file, kind));
    }
    let max_r = REDUCED_MAX_MODES.min(md.omega.len());
    let batch = rayon::current_num_threads().max(1);
    let mut best: Option<(f64, ReducedModelFile)> = None;
    let mut first = 1;
    'counts: while first <= max_r {
        let counts: Vec<usize> = (first..=(first + batch - 1).min(max_r)).collect();
        progress("modes kept", first as u64 - 1, max_r as u64);
        let scored: Vec<_> = counts
            .par_iter()
            .map(|&r| score_modes(structure, &md, r, dt_s, records, &reference))
            .collect();
        for outcome in scored {
            let (bound, file) = match outcome? {
                Scored::Stop => break 'counts,
                Scored::Skip => continue,
                Scored::Model(bound, file) => (bound, *file),
            };
            if best.as_ref().is_none_or(|(b, _)| bound < *b) {
                best = Some((bound, file));
            }
            if bound <= REDUCED_TARGET_NRMSE_PCT {
                break 'counts;
            }
        }
        first += batch;
    }
    progress("modes kept", max_r as u64, max_r as u64);
    best.map(|(_, f)| (f, kind))
        .ok_or(ReducedError::Model(ModelError::Param(
            rths_core::params::ParamError::OutOfRange("no mode below critical damping"),
        )))
}

/// The embedded training records at `dt_s`, mm/s².
pub fn training_records(dt_s: f64) -> Result<Vec<(String, Vec<f64>)>, ReducedError> {
    REDUCED_TRAINING_RECORDS
        .iter()
        .map(|name| {
            rths_files::motion::GroundMotion::embedded(name)
                .map(|m| (name.to_string(), m.resample_mm_s2(dt_s)))
                .ok_or_else(|| ReducedError::Record(name.to_string()))
        })
        .collect()
}

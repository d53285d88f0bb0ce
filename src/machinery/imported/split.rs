//! The host FE of an imported structure in the hybrid loop (`fe-online-ats`): the operator-splitting
//! method (Nakashima et al. 1990; OpenSees's `AlphaOS` at α = 0) on the host FE's Newmark average
//! acceleration ([`super::fe::SparseNewmark`]), as core's controller runs a host part
//! ([`rths_core::control::HostNumerical`]).
//!
//! Per tick k the controller gives `ü_g(k)` and the specimen's force `r̃_k` measured at the target
//! `ũ_k` this part gave at tick k − 1. The step to k is then Newmark's implicit step of the whole
//! model with the specimen taken in `K̂` at the lab's estimate `k_e` of its stiffness (factorized
//! once) and the measured force's departure from that estimate, `r̃_k − k_e·ũ_k`, as a load at the
//! interface: the specimen's force at the solution `u_k` is taken as `r̃_k + k_e·(u_k − ũ_k)`.
//! The next target is Newmark's predictor `ũ_{k+1} = u_k + Δt·v_k + Δt²/4·a_k` at the interface:
//! known before the force there is measured. With the specimen equal to its estimate the load is
//! zero and the step is the host FE's pure step ([`super::fe::run_pure`]) bit for bit.
//!
//! `k_e` is what the lab knows (the structure file's `--specimen-stiffness`, or the rig file's
//! identified specimen at the structure's scale), never the specimen the plant really has.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

use nalgebra::DMatrix;
use nalgebra_sparse::ops::serial::spmm_csc_dense;
use nalgebra_sparse::ops::Op;
use nalgebra_sparse::{CooMatrix, CscMatrix};
use rths_core::control::{HostNumerical, StepError};

use super::condense;
use super::fe::{FeError, SparseNewmark};
use super::file::ImportedStructure;

/// The highest cutoff of the measured force's departure from the estimate
/// ([`departure_cutoff_hz`]), Hz. Measured with the paper's ATS and a rig file on the benchmark
/// preset: departures low-passed at 9.9-10 Hz tripped the command-velocity interlock on frame-1x1
/// and frame-2x3, at 5 Hz both were stable; 2 Hz leaves a margin (docs/opensees.md).
pub const MAX_DEPARTURE_CUTOFF_HZ: f64 = 2.0;

/// The cutoff `fe-online-ats` low-passes the measured force's departure at: the structure's
/// fundamental frequency ([`fundamental_hz`] with the specimen at `k_e`), at most
/// [`MAX_DEPARTURE_CUTOFF_HZ`], Hz.
pub fn departure_cutoff_hz(
    structure: &ImportedStructure,
    estimate_kn_per_mm: f64,
) -> Result<f64, FeError> {
    Ok(fundamental_hz(structure, estimate_kn_per_mm)?.min(MAX_DEPARTURE_CUTOFF_HZ))
}

/// The fundamental frequency of `structure` with a specimen of `specimen_k_kn_per_mm` at its
/// interface, Hz: inverse iteration on the whole sparse model (`K·x = λ·M·x`; its massless DOFs
/// have no finite eigenvalue), one sparse Cholesky of `K`, at most 500 iterations or until the
/// Rayleigh quotient settles to 1e-12.
pub fn fundamental_hz(
    structure: &ImportedStructure,
    specimen_k_kn_per_mm: f64,
) -> Result<f64, FeError> {
    let model = structure.numerical_sparse();
    let n = model.stiffness.nrows();
    let mut coo = CooMatrix::new(n, n);
    for (i, j, v) in model.stiffness.triplet_iter() {
        coo.push(i, j, *v);
    }
    coo.push(model.interface, model.interface, specimen_k_kn_per_mm);
    let k = CscMatrix::from(&coo);
    let chol = condense::cholesky(&k)?;
    let mut x = DMatrix::from_column_slice(n, 1, &model.influence);
    let mut mx = DMatrix::zeros(n, 1);
    let mut kx = DMatrix::zeros(n, 1);
    let mut lambda = f64::NAN;
    for _ in 0..500 {
        spmm_csc_dense(0.0, &mut mx, 1.0, Op::NoOp(&model.mass), Op::NoOp(&x));
        x = chol.solve(&mx);
        let norm = x.norm();
        if !(norm.is_finite() && norm > 0.0) {
            break;
        }
        x /= norm;
        spmm_csc_dense(0.0, &mut mx, 1.0, Op::NoOp(&model.mass), Op::NoOp(&x));
        spmm_csc_dense(0.0, &mut kx, 1.0, Op::NoOp(&k), Op::NoOp(&x));
        let next = x.dot(&kx) / x.dot(&mx);
        let settled = (next - lambda).abs() <= 1e-12 * next.abs();
        lambda = next;
        if settled {
            break;
        }
    }
    Ok(lambda.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
}

/// The time an [`OperatorSplitting`] part (and its clones) spent in its steps: (ns, steps).
#[derive(Debug, Clone, Default)]
pub struct StepTimer(Arc<(AtomicU64, AtomicU64)>);

impl StepTimer {
    fn add(&self, ns: u64) {
        self.0 .0.fetch_add(ns, Ordering::Relaxed);
        self.0 .1.fetch_add(1, Ordering::Relaxed);
    }

    /// Mean wall time per step, s (`None` before the first step).
    pub fn s_per_step(&self) -> Option<f64> {
        let (ns, n) = (
            self.0 .0.load(Ordering::Relaxed),
            self.0 .1.load(Ordering::Relaxed),
        );
        (n > 0).then(|| ns as f64 * 1e-9 / n as f64)
    }
}

/// The operator-splitting host FE of an imported structure (the module's method): parameters
/// (the model, `k_e`, `K̂`'s factor) fixed at construction, the state the Newmark state, the
/// pending target and whether tick 0 is done.
#[derive(Clone)]
pub struct OperatorSplitting {
    fe: SparseNewmark,
    estimate_kn_per_mm: f64,
    /// The departure's low-pass gain per step (1: none) and its state, kN.
    departure_gain: f64,
    departure_kn: f64,
    started: bool,
    /// The target given at the last tick, `ũ_k`, mm.
    predicted_mm: f64,
    timer: StepTimer,
}

impl std::fmt::Debug for OperatorSplitting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OperatorSplitting")
            .field("dofs", &self.fe.dofs())
            .field("estimate_kn_per_mm", &self.estimate_kn_per_mm)
            .field("started", &self.started)
            .field("predicted_mm", &self.predicted_mm)
            .finish()
    }
}

impl OperatorSplitting {
    /// The part of `structure` at step `dt_s`, the specimen estimated at `estimate_kn_per_mm`
    /// (the lab's: `--specimen-stiffness` or the identified one), at rest.
    pub fn new(
        structure: &ImportedStructure,
        estimate_kn_per_mm: f64,
        dt_s: f64,
    ) -> Result<Self, FeError> {
        Ok(Self {
            fe: SparseNewmark::with_specimen(structure, estimate_kn_per_mm, dt_s)?,
            estimate_kn_per_mm,
            departure_gain: 1.0,
            departure_kn: 0.0,
            started: false,
            predicted_mm: 0.0,
            timer: StepTimer::default(),
        })
    }

    /// The same part with the measured force's departure from the estimate low-passed (first
    /// order) at `cutoff_hz` before it loads the model; zero stays zero (a perfect rig's loop is
    /// unchanged).
    pub fn with_departure_cutoff_hz(self, cutoff_hz: f64) -> Result<Self, FeError> {
        if !(cutoff_hz.is_finite() && cutoff_hz > 0.0) {
            return Err(FeError::Cutoff(cutoff_hz));
        }
        Ok(Self {
            departure_gain: 1.0 - (-2.0 * std::f64::consts::PI * cutoff_hz * self.fe.dt_s()).exp(),
            ..self
        })
    }

    /// The timer its steps (and its clones') add to.
    pub fn timer(&self) -> StepTimer {
        self.timer.clone()
    }

    /// The specimen's stiffness estimate in `K̂`, kN/mm.
    pub fn estimate_kn_per_mm(&self) -> f64 {
        self.estimate_kn_per_mm
    }
}

impl HostNumerical for OperatorSplitting {
    fn next_target(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, StepError> {
        if !ag_mm_s2.is_finite() {
            return Err(StepError::NonFiniteGroundAccel);
        }
        if !force_kn.is_finite() {
            return Err(StepError::NonFiniteOutput);
        }
        let t0 = Instant::now();
        if self.started {
            // The specimen's force at u_k taken as r̃_k + k_e·(u_k − ũ_k): k_e·u_k is in K̂, the
            // rest a load at the interface (the restoring force moves to the right-hand side).
            let departure_kn = force_kn - self.estimate_kn_per_mm * self.predicted_mm;
            if self.departure_gain < 1.0 {
                self.departure_kn += self.departure_gain * (departure_kn - self.departure_kn);
            } else {
                self.departure_kn = departure_kn;
            }
            self.fe.step_loaded(ag_mm_s2, -self.departure_kn);
        } else {
            // Tick 0: at rest with zero acceleration, the host FE's (and OpenSees's) start.
            self.started = true;
        }
        let next = self.fe.interface_predictor_mm();
        self.timer
            .add(u64::try_from(t0.elapsed().as_nanos()).unwrap_or(u64::MAX));
        if !next.is_finite() {
            return Err(StepError::NonFiniteOutput);
        }
        self.predicted_mm = next;
        Ok(next)
    }

    fn interface_disp_mm(&self) -> f64 {
        self.fe.interface_mm()
    }

    fn output_count(&self) -> usize {
        self.fe.output_count()
    }

    fn output_disp_mm(&self, i: usize) -> Option<f64> {
        self.fe.output_mm(i)
    }

    fn reset(&mut self) {
        self.fe.reset();
        self.started = false;
        self.predicted_mm = 0.0;
        self.departure_kn = 0.0;
    }

    fn boxed_clone(&self) -> Box<dyn HostNumerical> {
        Box::new(self.clone())
    }
}

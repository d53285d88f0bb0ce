//! The host FE of an imported structure: Newmark's average acceleration (γ = 1/2, β = 1/4) on the
//! whole sparse model (massless DOFs included, as OpenSees integrates it), the effective stiffness
//! factorized once (sparse Cholesky).
//!
//! Per step, with `a₀ = 4/Δt²`, `a₁ = 2/Δt`:
//! `K̂·u₊ = −M·ι·ü_g₊ + M·(a₀·u + (4/Δt)·v + a) + C·(a₁·u + v)`, `K̂ = K + a₀·M + a₁·C`, then
//! `a₊ = a₀·(u₊ − u) − (4/Δt)·v − a`, `v₊ = v + (Δt/2)·(a + a₊)`. The model starts at rest with
//! zero acceleration (OpenSees's start too).
//!
//! The pure loop couples the numerical part (the model minus the specimen) with the numerical
//! stand-in specimen, a spring of the specimen's stiffness at the interface, taken into `K̂`
//! (implicitly, like every other spring of the model): the whole model.

use nalgebra::DMatrix;
use nalgebra_sparse::factorization::CscCholesky;
use nalgebra_sparse::ops::serial::spmm_csc_dense;
use nalgebra_sparse::ops::Op;
use nalgebra_sparse::{CooMatrix, CscMatrix};

use super::condense::{self, FactorError};
use super::file::{ImportedStructure, SparseModel};

/// Why the integrator cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum FeError {
    /// Δt is not positive and finite.
    #[error("the step must be positive and finite, got {0} s")]
    Step(f64),
    /// The specimen's stiffness is not finite and ≥ 0.
    #[error("the specimen's stiffness must be finite and ≥ 0, got {0} kN/mm")]
    Specimen(f64),
    /// A low-pass cutoff is not positive and finite.
    #[error("the cutoff must be positive and finite, got {0} Hz")]
    Cutoff(f64),
    /// The effective stiffness cannot be factorized.
    #[error("the effective stiffness K + 4/dt²·M + 2/dt·C cannot be factorized: {0}")]
    Factor(#[from] FactorError),
}

/// Newmark's average acceleration on an imported structure coupled with its numerical stand-in
/// specimen. Parameters (matrices, factorization) are fixed at construction; the state is `u`,
/// `v`, `a` ([`Self::reset`]).
#[derive(Clone)]
pub struct SparseNewmark {
    model: SparseModel,
    /// `M·ι`.
    ground_mass: DMatrix<f64>,
    chol: CscCholesky<f64>,
    dt_s: f64,
    u: DMatrix<f64>,
    v: DMatrix<f64>,
    a: DMatrix<f64>,
    rhs: DMatrix<f64>,
    w: DMatrix<f64>,
}

fn matvec(out: &mut DMatrix<f64>, beta: f64, a: &CscMatrix<f64>, x: &DMatrix<f64>) {
    spmm_csc_dense(beta, out, 1.0, Op::NoOp(a), Op::NoOp(x));
}

impl SparseNewmark {
    /// The integrator of `structure` with its stand-in specimen, step `dt_s`.
    pub fn new(structure: &ImportedStructure, dt_s: f64) -> Result<Self, FeError> {
        Self::with_specimen(structure, structure.specimen_stiffness_kn_per_mm(), dt_s)
    }

    /// The integrator of `structure`'s numerical part with a specimen of stiffness
    /// `specimen_k_kn_per_mm` at the interface (e.g. the one a rig really has: evaluation only),
    /// step `dt_s`.
    pub fn with_specimen(
        structure: &ImportedStructure,
        specimen_k_kn_per_mm: f64,
        dt_s: f64,
    ) -> Result<Self, FeError> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(FeError::Step(dt_s));
        }
        if !(specimen_k_kn_per_mm.is_finite() && specimen_k_kn_per_mm >= 0.0) {
            return Err(FeError::Specimen(specimen_k_kn_per_mm));
        }
        let model = structure.numerical_sparse();
        let n = model.stiffness.nrows();
        let (a0, a1) = (4.0 / (dt_s * dt_s), 2.0 / dt_s);
        let mut coo = CooMatrix::new(n, n);
        for (i, j, v) in model.stiffness.triplet_iter() {
            coo.push(i, j, *v);
        }
        coo.push(model.interface, model.interface, specimen_k_kn_per_mm);
        for (i, j, v) in model.mass.triplet_iter() {
            coo.push(i, j, a0 * v);
        }
        for (i, j, v) in model.damping.triplet_iter() {
            coo.push(i, j, a1 * v);
        }
        let chol = condense::cholesky(&CscMatrix::from(&coo))?;
        let iota = DMatrix::from_column_slice(n, 1, &model.influence);
        let mut ground_mass = DMatrix::zeros(n, 1);
        matvec(&mut ground_mass, 0.0, &model.mass, &iota);
        Ok(Self {
            model,
            ground_mass,
            chol,
            dt_s,
            u: DMatrix::zeros(n, 1),
            v: DMatrix::zeros(n, 1),
            a: DMatrix::zeros(n, 1),
            rhs: DMatrix::zeros(n, 1),
            w: DMatrix::zeros(n, 1),
        })
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.u.fill(0.0);
        self.v.fill(0.0);
        self.a.fill(0.0);
    }

    /// One step to the ground acceleration `ag_mm_s2` at its end.
    pub fn step(&mut self, ag_mm_s2: f64) {
        self.step_loaded(ag_mm_s2, 0.0);
    }

    /// One step to the ground acceleration `ag_mm_s2` at its end, with the force
    /// `interface_load_kn` applied at the interface over the step's end (the hybrid loop's
    /// measured force less the stand-in's, [`super::split`]); 0 is [`Self::step`] bit for bit.
    pub fn step_loaded(&mut self, ag_mm_s2: f64, interface_load_kn: f64) {
        let dt = self.dt_s;
        let (a0, a1, a2) = (4.0 / (dt * dt), 2.0 / dt, 4.0 / dt);
        // M·(a₀·u + a₂·v + a)
        for ((w, u), (v, a)) in self
            .w
            .iter_mut()
            .zip(self.u.iter())
            .zip(self.v.iter().zip(self.a.iter()))
        {
            *w = a0 * u + a2 * v + a;
        }
        matvec(&mut self.rhs, 0.0, &self.model.mass, &self.w);
        // + C·(a₁·u + v)
        for (w, (u, v)) in self.w.iter_mut().zip(self.u.iter().zip(self.v.iter())) {
            *w = a1 * u + v;
        }
        matvec(&mut self.rhs, 1.0, &self.model.damping, &self.w);
        // − M·ι·ü_g
        for (r, g) in self.rhs.iter_mut().zip(self.ground_mass.iter()) {
            *r -= g * ag_mm_s2;
        }
        if interface_load_kn != 0.0 {
            if let Some(r) = self.rhs.get_mut((self.model.interface, 0)) {
                *r += interface_load_kn;
            }
        }
        self.chol.solve_mut(&mut self.rhs);
        // a₊ = a₀·(u₊ − u) − a₂·v − a, v₊ = v + Δt/2·(a + a₊), then u₊.
        for (((u_new, u), v), a) in self
            .rhs
            .iter()
            .zip(self.u.iter_mut())
            .zip(self.v.iter_mut())
            .zip(self.a.iter_mut())
        {
            let a_new = a0 * (u_new - *u) - a2 * *v - *a;
            *v += 0.5 * dt * (*a + a_new);
            *a = a_new;
            *u = *u_new;
        }
    }

    /// The interface (specimen) displacement, mm.
    pub fn interface_mm(&self) -> f64 {
        self.u[(self.model.interface, 0)]
    }

    /// Newmark's predictor of the interface's displacement at the end of the coming step,
    /// `u + Δt·v + Δt²/4·a` (what the step's solution adds to it is `Δt²/4·a₊`), mm.
    pub fn interface_predictor_mm(&self) -> f64 {
        let i = (self.model.interface, 0);
        let dt = self.dt_s;
        self.u[i] + dt * self.v[i] + 0.25 * dt * dt * self.a[i]
    }

    /// Output `i`'s displacement (the structure's output order), mm; `None` past them.
    pub fn output_mm(&self, i: usize) -> Option<f64> {
        let e = *self.model.outputs.get(i)?;
        self.u.get((e, 0)).copied()
    }

    /// How many outputs.
    pub fn output_count(&self) -> usize {
        self.model.outputs.len()
    }

    /// The output DOFs' displacements, mm, in the structure's output order.
    pub fn outputs_mm(&self) -> impl Iterator<Item = f64> + '_ {
        self.model.outputs.iter().map(|&e| self.u[(e, 0)])
    }

    /// The step, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Equations of the whole model.
    pub fn dofs(&self) -> usize {
        self.u.nrows()
    }
}

/// A pure run's displacements, one sample per step (row 0: rest).
#[derive(Debug, Clone, PartialEq)]
pub struct FeHistory {
    /// Step, s.
    pub dt_s: f64,
    /// The outputs' column names (`out_<NODE>_<DOF>_mm`).
    pub output_columns: Vec<String>,
    /// Interface displacement, mm.
    pub interface_mm: Vec<f64>,
    /// Output displacements, mm: `outputs_mm[k][i]` is output `i` at sample `k`.
    pub outputs_mm: Vec<Vec<f64>>,
}

impl FeHistory {
    /// Write `time_s,interface_mm,out_<NODE>_<DOF>_mm...` (shortest round-trip numbers).
    pub fn write_csv(&self, path: &std::path::Path) -> std::io::Result<()> {
        use std::io::Write;
        let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
        write!(w, "time_s,interface_mm")?;
        for c in &self.output_columns {
            write!(w, ",{c}")?;
        }
        writeln!(w)?;
        for (k, (x, outs)) in self.interface_mm.iter().zip(&self.outputs_mm).enumerate() {
            write!(w, "{},{x}", k as f64 * self.dt_s)?;
            for o in outs {
                write!(w, ",{o}")?;
            }
            writeln!(w)?;
        }
        w.flush()
    }
}

/// The pure loop of `structure` under `ag_mm_s2` (sample `k` at time `k·dt_s`; the model is at rest
/// at sample 0 and each later sample is one step), `progress` called with the steps done.
pub fn run_pure(
    structure: &ImportedStructure,
    ag_mm_s2: &[f64],
    dt_s: f64,
    progress: impl FnMut(usize),
) -> Result<FeHistory, FeError> {
    run_with_specimen(
        structure,
        structure.specimen_stiffness_kn_per_mm(),
        ag_mm_s2,
        dt_s,
        progress,
    )
}

/// [`run_pure`] with a specimen of stiffness `specimen_k_kn_per_mm` in place of the stand-in: the
/// whole model with the specimen a rig really has (a hybrid run's reference, evaluation only).
pub fn run_with_specimen(
    structure: &ImportedStructure,
    specimen_k_kn_per_mm: f64,
    ag_mm_s2: &[f64],
    dt_s: f64,
    mut progress: impl FnMut(usize),
) -> Result<FeHistory, FeError> {
    let mut fe = SparseNewmark::with_specimen(structure, specimen_k_kn_per_mm, dt_s)?;
    let mut interface_mm = Vec::with_capacity(ag_mm_s2.len());
    let mut outputs_mm = Vec::with_capacity(ag_mm_s2.len());
    for (k, &ag) in ag_mm_s2.iter().enumerate() {
        if k > 0 {
            fe.step(ag);
        }
        interface_mm.push(fe.interface_mm());
        outputs_mm.push(fe.outputs_mm().collect());
        if k % 4096 == 0 {
            progress(k);
        }
    }
    Ok(FeHistory {
        dt_s,
        output_columns: structure.outputs().iter().map(|o| o.column()).collect(),
        interface_mm,
        outputs_mm,
    })
}

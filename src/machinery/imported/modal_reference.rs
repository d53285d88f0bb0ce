//! The pure run of an imported structure by modal superposition of *all* its modes: the host FE's
//! Newmark (average acceleration, [`super::fe`]) written in the whole structure's mass-normalized
//! modal coordinates, where it costs `O(n)` per step instead of a sparse solve. It is the same
//! linear recurrence as the condensed model's Newmark (`Ψᵀ·M*·Ψ = I`, `Ψᵀ·K·Ψ = Ω²`, the
//! specimen's stand-in inside `K`), so the two agree to round-off; `rths train meta` uses it for
//! its training records' runs when it applies ([`ModalReference::new`]) and the sparse host FE
//! otherwise (docs/opensees.md "Training and the error bound").
//!
//! It applies when two things hold:
//! - **The condensation is exact for the damping**: each massless DOF's row of `C` is a multiple
//!   of its row of `K` (zero included; Rayleigh `C = a·M + b·K` gives `b`). Its dashpots then act
//!   on `K_s·x`, which the statics keeps at zero, so the condensed model integrates as the whole
//!   one does ([`super::condense`]).
//! - **The condensed damping is classical but for the specimen's DOF**: in the whole structure's
//!   modes `D = Ψᵀ·C*·Ψ = diag(d) + σ·ψ·ψᵀ`, `ψ` the interface's row of `Ψ`. That covers Rayleigh
//!   damping of the whole structure (`σ = 0`) and of the numerical part alone, the specimen's
//!   stand-in a spring without a dashpot (`σ = −b·k_e`, the shipped frames). Newmark's effective
//!   stiffness `Ω² + a₀·I + a₁·D` is then diagonal plus rank one, solved by Sherman–Morrison.
//!
//! Every other model (damping that is not classical, damped massless DOFs that the statics does
//! not hold) is left to the sparse host FE.

use nalgebra::DMatrix;

use super::fe::FeHistory;

/// The largest departure from a classical damping (diagonal plus the specimen's rank one) that is
/// still round-off, relative to the geometric mean of the two modes' own damping (the training's
/// "damping coupling" measure, less the specimen's rank one): the shipped frames' is 1.2e-13
/// (frame-2x3) and 3.3e-11 (frame-5x12), as `rths train meta` prints it.
pub const CLASSICAL_TOLERANCE: f64 = 1e-9;

/// Why the modal superposition does not apply (the sparse host FE runs instead).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NotClassical {
    /// A massless DOF's damping is not a multiple of its stiffness (its row of `C` over `K`).
    #[error(
        "the damping of massless equation {equation} is not proportional to its stiffness \
         (departure {residual:.2e} of its largest entry): the condensation is not exact for it"
    )]
    MasslessDamping {
        /// The equation, 0-based, in the whole model.
        equation: usize,
        /// The row's departure from `b·K` over its largest `|C|`.
        residual: f64,
    },
    /// The condensed damping couples two modes beyond the specimen's rank one.
    #[error(
        "the damping couples modes {i} and {j} beyond the specimen's DOF (departure {residual:.2e} \
         of their own damping): it is not classical"
    )]
    Coupled {
        /// A mode, 0-based.
        i: usize,
        /// Another mode.
        j: usize,
        /// `|D_ij − σ·ψ_i·ψ_j| / √(D_ii·D_jj)`.
        residual: f64,
    },
}

/// The whole structure's modes as the modal run needs them: `ω²`, the modal damping matrix
/// `Ψᵀ·C*·Ψ`, the ground participations `Γ = Ψᵀ·M*·ι`, and the rows of `Ψ` read out.
pub struct ModalInputs<'a> {
    /// `ω²` of each mode, (rad/s)², the stand-in specimen included.
    pub omega_sq: &'a [f64],
    /// `Ψᵀ·C*·Ψ`, modes × modes.
    pub modal_damping: &'a DMatrix<f64>,
    /// `Γ`.
    pub gamma: &'a [f64],
    /// The interface's row of `Ψ`.
    pub interface_row: Vec<f64>,
    /// Each output's row of `Ψ`.
    pub output_rows: Vec<Vec<f64>>,
}

/// Newmark's average acceleration on all the modes of a structure whose damping is classical but
/// for the specimen's DOF. Parameters only: [`Self::run`] keeps its state on its own stack, so
/// one value runs several records at once.
#[derive(Debug, Clone)]
pub struct ModalReference {
    omega_sq: Vec<f64>,
    /// The diagonal part of the modal damping.
    d: Vec<f64>,
    /// The rank-one part's coefficient `σ`.
    sigma: f64,
    psi_e: Vec<f64>,
    gamma: Vec<f64>,
    outputs: Vec<Vec<f64>>,
    /// The largest departure from the classical form, relative (what [`CLASSICAL_TOLERANCE`]
    /// bounds).
    residual: f64,
}

impl ModalReference {
    /// The modal run of a structure, if its damping allows it: `massless_damping` is the
    /// condensation's check ([`super::condense::massless_damping_residual`]: the worst massless
    /// equation and its departure), `modes` the whole structure's modes.
    pub fn new(
        massless_damping: Option<(usize, f64)>,
        modes: ModalInputs<'_>,
    ) -> Result<Self, NotClassical> {
        if let Some((equation, residual)) = massless_damping {
            if residual.is_nan() || residual > CLASSICAL_TOLERANCE {
                return Err(NotClassical::MasslessDamping { equation, residual });
            }
        }
        let dm = modes.modal_damping;
        let n = modes.omega_sq.len();
        let psi = &modes.interface_row;
        // σ by least squares over the off-diagonal entries.
        let (mut num, mut den) = (0.0, 0.0);
        for j in 0..n {
            for i in 0..n {
                if i != j {
                    let p = psi[i] * psi[j];
                    num += dm[(i, j)] * p;
                    den += p * p;
                }
            }
        }
        let sigma = if den > 0.0 { num / den } else { 0.0 };
        let mut worst = (0, 0, 0.0_f64);
        for j in 0..n {
            for i in 0..n {
                if i != j {
                    let scale = (dm[(i, i)] * dm[(j, j)]).abs().sqrt();
                    let r = (dm[(i, j)] - sigma * psi[i] * psi[j]).abs() / scale;
                    // A NaN (a mode without damping against a coupling) counts as the worst.
                    if r.is_nan() || r > worst.2 {
                        worst = (i, j, r);
                    }
                }
            }
        }
        let (i, j, residual) = worst;
        if residual.is_nan() || residual > CLASSICAL_TOLERANCE {
            return Err(NotClassical::Coupled { i, j, residual });
        }
        Ok(Self {
            omega_sq: modes.omega_sq.to_vec(),
            d: (0..n)
                .map(|k| dm[(k, k)] - sigma * psi[k] * psi[k])
                .collect(),
            sigma,
            psi_e: psi.clone(),
            gamma: modes.gamma.to_vec(),
            outputs: modes.output_rows,
            residual: residual.max(massless_damping.map_or(0.0, |m| m.1)),
        })
    }

    /// The modes superposed.
    pub fn modes(&self) -> usize {
        self.omega_sq.len()
    }

    /// The largest departure from the classical form found, relative.
    pub fn residual(&self) -> f64 {
        self.residual
    }

    /// The pure run under `ag_mm_s2` at step `dt_s`, as [`super::fe::run_pure`] gives it (sample
    /// `k` at time `k·dt_s`; at rest with zero acceleration at sample 0, each later sample one
    /// step), the outputs named `output_columns`.
    pub fn run(&self, ag_mm_s2: &[f64], dt_s: f64, output_columns: Vec<String>) -> FeHistory {
        let n = self.omega_sq.len();
        let (a0, a1, a2) = (4.0 / (dt_s * dt_s), 2.0 / dt_s, 4.0 / dt_s);
        // K̂ = Δ + s·ψψᵀ; K̂⁻¹·r = Δ⁻¹·r − c·(ψᵀΔ⁻¹r)·z, z = Δ⁻¹ψ, c = s/(1 + s·ψᵀz).
        let delta: Vec<f64> = (0..n)
            .map(|k| self.omega_sq[k] + a0 + a1 * self.d[k])
            .collect();
        let s = a1 * self.sigma;
        let z: Vec<f64> = self
            .psi_e
            .iter()
            .zip(&delta)
            .map(|(p, dl)| p / dl)
            .collect();
        let psi_z: f64 = self.psi_e.iter().zip(&z).map(|(p, z)| p * z).sum();
        let c = s / (1.0 + s * psi_z);
        let (mut q, mut v, mut a) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut y = vec![0.0; n];
        let mut w = vec![0.0; n];
        let mut interface_mm = Vec::with_capacity(ag_mm_s2.len());
        let mut outputs_mm = Vec::with_capacity(ag_mm_s2.len());
        let read = |row: &[f64], q: &[f64]| -> f64 { row.iter().zip(q).map(|(r, x)| r * x).sum() };
        for (k, &ag) in ag_mm_s2.iter().enumerate() {
            if k > 0 {
                // w = a₁·q + v; the rank-one damping's share ψᵀw.
                for ((wk, qk), vk) in w.iter_mut().zip(&q).zip(&v) {
                    *wk = a1 * qk + vk;
                }
                let psi_w = read(&self.psi_e, &w);
                for k in 0..n {
                    let r = a0 * q[k]
                        + a2 * v[k]
                        + a[k]
                        + self.d[k] * w[k]
                        + self.sigma * self.psi_e[k] * psi_w
                        - self.gamma[k] * ag;
                    y[k] = r / delta[k];
                }
                let alpha = c * read(&self.psi_e, &y);
                for k in 0..n {
                    let q_new = y[k] - alpha * z[k];
                    let a_new = a0 * (q_new - q[k]) - a2 * v[k] - a[k];
                    v[k] += 0.5 * dt_s * (a[k] + a_new);
                    a[k] = a_new;
                    q[k] = q_new;
                }
            }
            interface_mm.push(read(&self.psi_e, &q));
            outputs_mm.push(self.outputs.iter().map(|row| read(row, &q)).collect());
        }
        FeHistory {
            dt_s,
            output_columns,
            interface_mm,
            outputs_mm,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three modes, classical damping but for a rank one along `ψ` (with two, the one coupling
    /// pair would always fit a rank one).
    fn inputs(coupling: f64) -> (Vec<f64>, DMatrix<f64>, Vec<f64>) {
        let psi = vec![0.8, 0.5, -0.3];
        let sigma = -0.3;
        let mut d = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![0.5, 4.0, 9.0]));
        for i in 0..3 {
            for j in 0..3 {
                d[(i, j)] += sigma * psi[i] * psi[j];
            }
        }
        d[(0, 1)] += coupling;
        d[(1, 0)] += coupling;
        (vec![100.0, 2500.0, 10000.0], d, psi)
    }

    #[test]
    fn a_rank_one_coupling_along_the_interface_is_classical_and_another_is_not() {
        let (w2, d, psi) = inputs(0.0);
        let m = ModalReference::new(
            None,
            ModalInputs {
                omega_sq: &w2,
                modal_damping: &d,
                gamma: &[1.0, 0.2, 0.05],
                interface_row: psi.clone(),
                output_rows: vec![],
            },
        )
        .expect("classical");
        assert!(m.residual() < 1e-15);
        let (w2, d, psi) = inputs(0.05);
        let e = ModalReference::new(
            None,
            ModalInputs {
                omega_sq: &w2,
                modal_damping: &d,
                gamma: &[1.0, 0.2, 0.05],
                interface_row: psi.clone(),
                output_rows: vec![],
            },
        )
        .expect_err("coupled");
        assert!(matches!(e, NotClassical::Coupled { .. }), "{e}");
        let e = ModalReference::new(
            Some((7, 1e-3)),
            ModalInputs {
                omega_sq: &w2,
                modal_damping: &d,
                gamma: &[1.0, 0.2, 0.05],
                interface_row: psi,
                output_rows: vec![],
            },
        )
        .expect_err("massless damping");
        assert!(e.to_string().contains("massless equation 7"), "{e}");
    }

    /// The modal run is the coupled three-DOF Newmark written out (modal coordinates, `M = I`).
    #[test]
    fn the_modal_run_is_newmark_on_the_coupled_modes() {
        let (w2, d, psi) = inputs(0.0);
        let gamma = [1.0, 0.2, 0.05];
        let m = ModalReference::new(
            None,
            ModalInputs {
                omega_sq: &w2,
                modal_damping: &d,
                gamma: &gamma,
                interface_row: psi.clone(),
                output_rows: vec![vec![0.3, -0.7, 0.1]],
            },
        )
        .expect("classical");
        let dt = 1.0 / 2048.0;
        let ag: Vec<f64> = (0..4000)
            .map(|k| 800.0 * (k as f64 * dt * 9.0).sin())
            .collect();
        let h = m.run(&ag, dt, vec!["o".into()]);
        let (a0, a1, a2) = (4.0 / (dt * dt), 2.0 / dt, 4.0 / dt);
        let k = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(w2.clone()));
        let kh = &k + DMatrix::identity(3, 3) * a0 + &d * a1;
        let lu = kh.lu();
        let g = nalgebra::DVector::from_row_slice(&gamma);
        let (mut q, mut v, mut a) = (
            nalgebra::DVector::zeros(3),
            nalgebra::DVector::zeros(3),
            nalgebra::DVector::zeros(3),
        );
        let mut worst: f64 = 0.0;
        let mut peak: f64 = 0.0;
        for (step, &x) in ag.iter().enumerate() {
            if step > 0 {
                let rhs = &q * a0 + &v * a2 + &a + &d * (&q * a1 + &v) - &g * x;
                let q_new = lu.solve(&rhs).expect("solvable");
                let a_new = (&q_new - &q) * a0 - &v * a2 - &a;
                v += (&a + &a_new) * (0.5 * dt);
                a = a_new;
                q = q_new;
            }
            let iface = psi[0] * q[0] + psi[1] * q[1] + psi[2] * q[2];
            let out = 0.3 * q[0] - 0.7 * q[1] + 0.1 * q[2];
            worst = worst
                .max((h.interface_mm[step] - iface).abs())
                .max((h.outputs_mm[step][0] - out).abs());
            peak = peak.max(iface.abs());
        }
        assert!(peak > 1.0, "it moved: {peak}");
        // Round-off only: the two solve the same recurrence in another order (measured 3.5e-12 of
        // the peak over 4,000 steps).
        assert!(worst <= 1e-10 * peak, "{worst} against a peak of {peak}");
    }
}

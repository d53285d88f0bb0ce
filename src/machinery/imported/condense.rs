//! Static condensation of massless DOFs, and the sparse Cholesky factorization it (and the host FE)
//! uses.
//!
//! With the DOFs split into the retained ones `r` (they carry mass) and the condensed ones `s`
//! (massless: their rows and columns of `M` are zero), the condensed DOFs follow the retained ones
//! statically, `x_s = −K_ss⁻¹·K_sr·x_r`, i.e. `x = T·x_r` with `T = [I; −K_ss⁻¹·K_sr]`, and the
//! condensed matrices are `Tᵀ·A·T`:
//!
//! - `K* = K_rr − K_rs·X`, `X = K_ss⁻¹·K_sr` (one sparse Cholesky of `K_ss`, solved for the
//!   columns of `K_sr`);
//! - `M* = M_rr` (nothing else has mass);
//! - `C* = C_rr − P − Pᵀ + Xᵀ·C_ss·X`, `P = C_rs·X`.
//!
//! The condensation is exact for the stiffness and the mass; for the damping it is exact when the
//! damping of the massless DOFs is stiffness-proportional (Rayleigh `C = a·M + b·K`, OpenSees's
//! `rayleigh`), since their dashpots then act on the same combination `K_ss·x_s + K_sr·x_r` that
//! the statics keeps at zero. Other damping is condensed the same way, approximately
//! (docs/opensees.md).

use nalgebra::DMatrix;
use nalgebra_sparse::factorization::CscCholesky;
use nalgebra_sparse::ops::serial::spmm_csc_dense;
use nalgebra_sparse::ops::Op;
use nalgebra_sparse::{CooMatrix, CscMatrix};

/// A pivot of the Cholesky factorization below this fraction of its diagonal entry is a singular
/// matrix that round-off made barely positive (a mechanism: a DOF nothing holds). Well-posed frames
/// keep their pivots above 1e-8 of the diagonal (axial over flexural stiffness of a column is
/// about 1e2-1e4); a mechanism leaves about 1e-16.
pub const PIVOT_TOLERANCE: f64 = 1e-12;

/// Why a symmetric matrix could not be factorized.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FactorError {
    /// The factorization met a pivot that is not positive, at an unknown equation.
    #[error("not positive definite")]
    NotPositiveDefinite,
    /// Equation `equation` (0-based) has a pivot `ratio` of its diagonal (singular there).
    #[error("singular at equation {equation} (pivot {ratio:e} of its diagonal)")]
    Singular {
        /// The equation, 0-based.
        equation: usize,
        /// Pivot over diagonal entry.
        ratio: f64,
    },
}

/// Sparse Cholesky factorization of the symmetric positive-definite `a` (both triangles stored),
/// refused when it fails or a pivot falls below [`PIVOT_TOLERANCE`] of its diagonal.
pub fn cholesky(a: &CscMatrix<f64>) -> Result<CscCholesky<f64>, FactorError> {
    let chol = CscCholesky::factor(a).map_err(|_| FactorError::NotPositiveDefinite)?;
    let l = chol.l();
    for k in 0..a.ncols() {
        let a_kk = a.get_entry(k, k).map_or(0.0, |e| e.into_value());
        let l_kk = l.get_entry(k, k).map_or(0.0, |e| e.into_value());
        let ratio = l_kk * l_kk / a_kk;
        if ratio.is_nan() || ratio <= PIVOT_TOLERANCE {
            return Err(FactorError::Singular { equation: k, ratio });
        }
    }
    Ok(chol)
}

/// Mass, damping and stiffness over the retained DOFs, dense.
#[derive(Debug, Clone, PartialEq)]
pub struct Condensed {
    /// `M*`.
    pub mass: DMatrix<f64>,
    /// `C*`.
    pub damping: DMatrix<f64>,
    /// `K*`.
    pub stiffness: DMatrix<f64>,
}

/// Where a DOF of the whole model goes.
#[derive(Clone, Copy)]
enum Slot {
    Retained(usize),
    Condensed(usize),
}

/// The blocks of one matrix: `A_rr` dense, `A_sr` and `A_ss` sparse.
struct Blocks {
    rr: DMatrix<f64>,
    sr: CscMatrix<f64>,
    ss: CscMatrix<f64>,
}

fn blocks(a: &CscMatrix<f64>, slots: &[Slot], r: usize, s: usize) -> Blocks {
    let mut rr = DMatrix::zeros(r, r);
    let (mut sr, mut ss) = (CooMatrix::new(s, r), CooMatrix::new(s, s));
    for (i, j, v) in a.triplet_iter() {
        match (slots.get(i), slots.get(j)) {
            (Some(Slot::Retained(i)), Some(Slot::Retained(j))) => rr[(*i, *j)] += *v,
            (Some(Slot::Condensed(i)), Some(Slot::Retained(j))) => sr.push(*i, *j, *v),
            (Some(Slot::Condensed(i)), Some(Slot::Condensed(j))) => ss.push(*i, *j, *v),
            // A_rs is A_srᵀ (symmetric matrices).
            _ => {}
        }
    }
    Blocks {
        rr,
        sr: CscMatrix::from(&sr),
        ss: CscMatrix::from(&ss),
    }
}

fn symmetrized(a: DMatrix<f64>) -> DMatrix<f64> {
    (&a + a.transpose()) * 0.5
}

/// `aᵀ·b` for sparse `a` (s × r) and dense `b` (s × c).
fn sparse_t_dense(a: &CscMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(a.ncols(), b.ncols());
    spmm_csc_dense(0.0, &mut out, 1.0, Op::Transpose(a), Op::NoOp(b));
    out
}

/// `a·b` for sparse `a` (s × s) and dense `b` (s × c).
fn sparse_dense(a: &CscMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(a.nrows(), b.ncols());
    spmm_csc_dense(0.0, &mut out, 1.0, Op::NoOp(a), Op::NoOp(b));
    out
}

/// Condense `m`, `c`, `k` (n × n, symmetric, both triangles stored) onto the DOFs `retained`
/// (ascending, 0-based); every other DOF must be massless. The stiffness of the condensed DOFs is
/// factorized once; its failure is returned with the condensed DOF's index in the whole model.
pub fn condense(
    m: &CscMatrix<f64>,
    c: &CscMatrix<f64>,
    k: &CscMatrix<f64>,
    retained: &[usize],
) -> Result<Condensed, FactorError> {
    let n = k.nrows();
    let mut slots = vec![Slot::Condensed(0); n];
    let mut condensed = Vec::with_capacity(n.saturating_sub(retained.len()));
    let mut next = 0;
    for (i, slot) in slots.iter_mut().enumerate() {
        if retained.get(next) == Some(&i) {
            *slot = Slot::Retained(next);
            next += 1;
        } else {
            *slot = Slot::Condensed(condensed.len());
            condensed.push(i);
        }
    }
    let (r, s) = (retained.len(), condensed.len());
    let mb = blocks(m, &slots, r, s);
    let cb = blocks(c, &slots, r, s);
    let kb = blocks(k, &slots, r, s);
    if s == 0 {
        return Ok(Condensed {
            mass: symmetrized(mb.rr),
            damping: symmetrized(cb.rr),
            stiffness: symmetrized(kb.rr),
        });
    }
    let chol = cholesky(&kb.ss).map_err(|e| match e {
        FactorError::Singular { equation, ratio } => FactorError::Singular {
            equation: condensed.get(equation).copied().unwrap_or(equation),
            ratio,
        },
        other => other,
    })?;
    // X = K_ss⁻¹·K_sr, dense s × r.
    let mut x = DMatrix::zeros(s, r);
    for (i, j, v) in kb.sr.triplet_iter() {
        x[(i, j)] = *v;
    }
    chol.solve_mut(&mut x);
    let stiffness = kb.rr - sparse_t_dense(&kb.sr, &x);
    let p = sparse_t_dense(&cb.sr, &x);
    let css_x = sparse_dense(&cb.ss, &x);
    let damping = cb.rr - &p - p.transpose() + x.transpose() * css_x;
    Ok(Condensed {
        mass: symmetrized(mb.rr),
        damping: symmetrized(damping),
        stiffness: symmetrized(stiffness),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn csc(n: usize, entries: &[(usize, usize, f64)]) -> CscMatrix<f64> {
        let mut coo = CooMatrix::new(n, n);
        for &(i, j, v) in entries {
            coo.push(i, j, v);
        }
        CscMatrix::from(&coo)
    }

    #[test]
    fn condensation_equals_the_dense_schur_complement() -> Result<(), FactorError> {
        // DOFs 0 and 2 carry mass, 1 is massless.
        let k = csc(
            3,
            &[
                (0, 0, 4.0),
                (0, 1, -1.0),
                (1, 0, -1.0),
                (1, 1, 3.0),
                (1, 2, -1.5),
                (2, 1, -1.5),
                (2, 2, 2.0),
            ],
        );
        let m = csc(3, &[(0, 0, 2.0), (2, 2, 1.0)]);
        let c = csc(
            3,
            &[
                (0, 0, 0.4),
                (0, 1, -0.1),
                (1, 0, -0.1),
                (1, 1, 0.3),
                (1, 2, -0.15),
                (2, 1, -0.15),
                (2, 2, 0.2),
            ],
        );
        let out = condense(&m, &c, &k, &[0, 2])?;
        // K* = K_rr − K_rs·K_ss⁻¹·K_sr by hand.
        let kd = DMatrix::from_row_slice(2, 2, &[4.0 - 1.0 / 3.0, -0.5, -0.5, 2.0 - 0.75]);
        assert!((&out.stiffness - &kd).amax() < 1e-14, "{}", out.stiffness);
        // C = 0.1·K here: the condensed damping is 0.1·K* exactly.
        assert!((&out.damping - kd * 0.1).amax() < 1e-14, "{}", out.damping);
        assert_eq!(
            out.mass,
            DMatrix::from_row_slice(2, 2, &[2.0, 0.0, 0.0, 1.0])
        );
        Ok(())
    }

    #[test]
    fn a_mechanism_is_named_by_its_equation() {
        // Two springs in series, the middle DOF free: [1 −1; −1 1] is singular.
        let k = csc(2, &[(0, 0, 1.0), (0, 1, -1.0), (1, 0, -1.0), (1, 1, 1.0)]);
        match cholesky(&k) {
            Err(FactorError::Singular { equation: 1, .. })
            | Err(FactorError::NotPositiveDefinite) => {}
            other => panic!("expected a singular matrix, got {other:?}"),
        }
    }
}

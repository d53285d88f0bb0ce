//! Linear structure models of the analytical substructure: the one-DOF braced frame of the study and an
//! N-story shear building (for cost scaling). A model is its mass, damping and stiffness matrices, all
//! validated, plus the initial stiffness `K0` of the *whole* structure (analytical + experimental part)
//! that explicit integrators need for their coefficients.
//!
//! Units: mm, kN, s (mass kN·s²/mm, stiffness kN/mm, damping kN·s/mm).

use nalgebra::{SMatrix, SVector};

use crate::params::{positive, ParamError, Prototype};

/// A square matrix of an N-DOF model.
pub type Mat<const N: usize> = SMatrix<f64, N, N>;
/// A vector of an N-DOF model.
pub type Vector<const N: usize> = SVector<f64, N>;

/// A validated linear structure: `M·ẍ + C·ẋ + K·x + r_ext = −M·ι·ü_g`.
///
/// `stiffness` is the part computed analytically; `r_ext` is the restoring force of the experimental
/// substructure, fed in each step (zero in a pure analysis, where `stiffness` is the whole structure).
/// `initial_stiffness` (`K0`) is the whole structure's, used for integrator coefficients.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearStructure<const N: usize> {
    mass: Mat<N>,
    damping: Mat<N>,
    stiffness: Mat<N>,
    initial_stiffness: Mat<N>,
    influence: Vector<N>,
}

impl<const N: usize> LinearStructure<N> {
    /// Validate and build a model. The mass must be symmetric positive definite; all entries finite.
    pub fn new(
        mass: Mat<N>,
        damping: Mat<N>,
        stiffness: Mat<N>,
        initial_stiffness: Mat<N>,
    ) -> Result<Self, ParamError> {
        for (m, what) in [
            (&mass, "mass matrix"),
            (&damping, "damping matrix"),
            (&stiffness, "stiffness matrix"),
            (&initial_stiffness, "initial stiffness matrix"),
        ] {
            if m.iter().any(|v| !v.is_finite()) {
                return Err(ParamError::NotFinite(what));
            }
        }
        if mass.cholesky().is_none() {
            return Err(ParamError::Singular("mass matrix"));
        }
        Ok(Self {
            mass,
            damping,
            stiffness,
            initial_stiffness,
            influence: Vector::<N>::repeat(1.0),
        })
    }

    /// Mass matrix, kN·s²/mm.
    pub fn mass(&self) -> &Mat<N> {
        &self.mass
    }
    /// Damping matrix, kN·s/mm.
    pub fn damping(&self) -> &Mat<N> {
        &self.damping
    }
    /// Analytical stiffness matrix, kN/mm.
    pub fn stiffness(&self) -> &Mat<N> {
        &self.stiffness
    }
    /// Initial stiffness of the whole structure, kN/mm.
    pub fn initial_stiffness(&self) -> &Mat<N> {
        &self.initial_stiffness
    }
    /// Effective earthquake force `−M·ι·ü_g`, kN, for a ground acceleration in mm/s².
    pub fn ground_force(&self, ground_accel_mm_s2: f64) -> Vector<N> {
        -(self.mass * self.influence) * ground_accel_mm_s2
    }

    /// Undamped natural circular frequencies of `(K0, M)`, rad/s, ascending.
    pub fn natural_frequencies_rad_s(&self) -> Result<Vector<N>, ParamError> {
        // Symmetric form L⁻¹·K0·L⁻ᵀ with M = L·Lᵀ, so the symmetric eigen-solver applies.
        let chol = self
            .mass
            .cholesky()
            .ok_or(ParamError::Singular("mass matrix"))?;
        let l_inv = chol
            .l()
            .try_inverse()
            .ok_or(ParamError::Singular("mass matrix"))?;
        let a = l_inv * self.initial_stiffness * l_inv.transpose();
        let mut w2 = symmetric_eigenvalues((a + a.transpose()) * 0.5);
        let s = w2.as_mut_slice();
        s.sort_unstable_by(|x, y| x.total_cmp(y));
        let mut out = Vector::<N>::zeros();
        for (o, v) in out.iter_mut().zip(s.iter()) {
            if *v < 0.0 {
                return Err(ParamError::OutOfRange("stiffness (negative eigenvalue)"));
            }
            *o = libm::sqrt(*v);
        }
        Ok(out)
    }

    /// Natural periods, s, descending (fundamental first).
    pub fn natural_periods_s(&self) -> Result<Vector<N>, ParamError> {
        let w = self.natural_frequencies_rad_s()?;
        Ok(w.map(|w| 2.0 * core::f64::consts::PI / w))
    }
}

impl LinearStructure<1> {
    /// A one-DOF model: mass, damping, analytical stiffness and whole-structure stiffness.
    pub fn sdof(
        mass_kn_s2_per_mm: f64,
        damping_kn_s_per_mm: f64,
        stiffness_kn_per_mm: f64,
        initial_stiffness_kn_per_mm: f64,
    ) -> Result<Self, ParamError> {
        positive(mass_kn_s2_per_mm, "mass")?;
        Self::new(
            Mat::<1>::new(mass_kn_s2_per_mm),
            Mat::<1>::new(damping_kn_s_per_mm),
            Mat::<1>::new(stiffness_kn_per_mm),
            Mat::<1>::new(initial_stiffness_kn_per_mm),
        )
    }

    /// The whole prototype analysed numerically (frame + brace): the pure finite-element reference.
    pub fn prototype_pure(p: &Prototype) -> Result<Self, ParamError> {
        Self::sdof(
            p.mass_kn_s2_per_mm(),
            p.damping_kn_s_per_mm(),
            p.total_stiffness_kn_per_mm(),
            p.total_stiffness_kn_per_mm(),
        )
    }

    /// The analytical substructure of a hybrid test: frame and mass only; the brace force is fed in.
    pub fn prototype_hybrid(p: &Prototype) -> Result<Self, ParamError> {
        Self::sdof(
            p.mass_kn_s2_per_mm(),
            p.damping_kn_s_per_mm(),
            p.frame_stiffness_kn_per_mm(),
            p.total_stiffness_kn_per_mm(),
        )
    }
}

/// Eigenvalues of a symmetric matrix by cyclic Jacobi rotations. (nalgebra's symmetric eigen-solver
/// needs a type-level dimension, which a `const N` generic cannot name.) Converges quadratically;
/// 50 sweeps is far more than the small models here need.
fn symmetric_eigenvalues<const N: usize>(mut a: Mat<N>) -> Vector<N> {
    let scale = a.norm().max(f64::MIN_POSITIVE);
    for _sweep in 0..50 {
        let mut off = 0.0;
        for p in 0..N {
            for q in (p + 1)..N {
                off += a[(p, q)] * a[(p, q)];
            }
        }
        if libm::sqrt(off) <= 1e-15 * scale {
            break;
        }
        for p in 0..N {
            for q in (p + 1)..N {
                let apq = a[(p, q)];
                if apq == 0.0 {
                    continue;
                }
                // Rotation angle that zeroes a[p][q] (Golub & Van Loan, Alg. 8.4.1).
                let tau = (a[(q, q)] - a[(p, p)]) / (2.0 * apq);
                let t = tau.signum() / (tau.abs() + libm::sqrt(1.0 + tau * tau));
                let t = if tau == 0.0 { 1.0 } else { t };
                let c = 1.0 / libm::sqrt(1.0 + t * t);
                let s = t * c;
                for k in 0..N {
                    let (akp, akq) = (a[(k, p)], a[(k, q)]);
                    a[(k, p)] = c * akp - s * akq;
                    a[(k, q)] = s * akp + c * akq;
                }
                for k in 0..N {
                    let (apk, aqk) = (a[(p, k)], a[(q, k)]);
                    a[(p, k)] = c * apk - s * aqk;
                    a[(q, k)] = s * apk + c * aqk;
                }
            }
        }
    }
    a.diagonal()
}

/// An N-story shear building: lumped floor masses, story stiffnesses, Rayleigh damping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShearBuilding<const N: usize> {
    /// Floor masses from the ground up, kN·s²/mm.
    pub floor_mass_kn_s2_per_mm: [f64; N],
    /// Story stiffnesses from the ground up, kN/mm.
    pub story_stiffness_kn_per_mm: [f64; N],
    /// Damping ratio assigned to the first and the last mode (Rayleigh damping).
    pub damping_ratio: f64,
}

impl<const N: usize> ShearBuilding<N> {
    /// A building whose stories all have the same mass and stiffness.
    pub fn uniform(mass_kn_s2_per_mm: f64, stiffness_kn_per_mm: f64, damping_ratio: f64) -> Self {
        Self {
            floor_mass_kn_s2_per_mm: [mass_kn_s2_per_mm; N],
            story_stiffness_kn_per_mm: [stiffness_kn_per_mm; N],
            damping_ratio,
        }
    }

    /// The tridiagonal story stiffness matrix, kN/mm.
    pub fn stiffness_matrix(&self) -> Result<Mat<N>, ParamError> {
        let mut k = Mat::<N>::zeros();
        for i in 0..N {
            let ki = positive(self.story_stiffness_kn_per_mm[i], "story stiffness")?;
            // Story i joins floor i-1 (or the ground) and floor i.
            k[(i, i)] += ki;
            if i > 0 {
                k[(i - 1, i - 1)] += ki;
                k[(i - 1, i)] -= ki;
                k[(i, i - 1)] -= ki;
            }
        }
        Ok(k)
    }

    /// The linear model (all stiffness analytical), with Rayleigh damping giving `damping_ratio` in
    /// the first and the last mode.
    pub fn model(&self) -> Result<LinearStructure<N>, ParamError> {
        let mut m = Mat::<N>::zeros();
        for i in 0..N {
            m[(i, i)] = positive(self.floor_mass_kn_s2_per_mm[i], "floor mass")?;
        }
        let k = self.stiffness_matrix()?;
        let zeta = self.damping_ratio;
        if !zeta.is_finite() || !(0.0..1.0).contains(&zeta) {
            return Err(ParamError::OutOfRange("damping ratio"));
        }
        let undamped = LinearStructure::new(m, Mat::<N>::zeros(), k, k)?;
        let w = undamped.natural_frequencies_rad_s()?;
        let (wi, wj) = (w[0], w[N - 1]);
        let c = if N == 1 {
            m * (2.0 * zeta * wi)
        } else {
            // a0·M + a1·K with ζ at ω_i and ω_j.
            let a0 = 2.0 * zeta * wi * wj / (wi + wj);
            let a1 = 2.0 * zeta / (wi + wj);
            m * a0 + k * a1
        };
        LinearStructure::new(m, c, k, k)
    }
}

#[cfg(test)]
mod tests;

//! An N-DOF linear analytical substructure whose size is chosen at run time (1 ≤ N ≤ [`MAX_DOF`]),
//! and Chang's explicit integrator for it: the structure a structure file describes, integrated by
//! the same method as the FE path of the one-DOF frame ([`crate::integrator::Chang`], docs/design.md
//! §3 and §3.1).
//!
//! Storage is fixed-capacity (`MAX_DOF`² per matrix) so the controller stays `no_std` and
//! allocation-free; every loop runs over the `N` DOFs in use only, so a step costs O(N²)
//! multiply-adds, not O(`MAX_DOF`²).
//!
//! The model is the numerical part of a partitioned structure:
//! `M_N·ẍ + C_N·ẋ + K_N·x + r_ext = −(M·ι)·ü_g`, where `M_N`, `C_N`, `K_N` are the full structure's
//! matrices with the physical specimen's own mass, damping and stiffness subtracted at its DOF,
//! `r_ext` is the specimen's measured force at that DOF, and the ground force acts on the *full*
//! mass `M` (the specimen's mass is accelerated by the ground too). Chang's coefficients use the
//! initial stiffness `K0` of the whole structure, which keeps the method unconditionally stable for
//! any specimen no stiffer than its nominal.
//!
//! Units: mm, kN, s (mass kN·s²/mm).

use nalgebra::SMatrix;

use crate::params::{positive, ParamError};

/// Largest number of DOFs of a run-time sized structure.
pub const MAX_DOF: usize = 8;

/// A fixed-capacity square matrix (row-major); entries beyond the DOFs in use are zero.
pub type Square = [[f64; MAX_DOF]; MAX_DOF];
/// A fixed-capacity vector; entries beyond the DOFs in use are zero.
pub type Dofs = [f64; MAX_DOF];

/// Story drifts `x_i − x_{i−1}` (the ground is 0) of floor displacements `x` over the leading `n`
/// DOFs (the floors from the ground up), mm; the entries past `n` are zero.
#[inline]
pub fn story_drifts_mm(x: &Dofs, n: usize) -> Dofs {
    let mut d = [0.0; MAX_DOF];
    let mut below = 0.0;
    for (di, xi) in d.iter_mut().zip(x).take(n) {
        *di = xi - below;
        below = *xi;
    }
    d
}

type Padded = SMatrix<f64, MAX_DOF, MAX_DOF>;

/// A validated N-DOF linear structure (the numerical substructure of a partitioned test, or a
/// whole structure when nothing is subtracted and `r_ext` is zero).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StructureN {
    dofs: usize,
    mass: Square,
    damping: Square,
    stiffness: Square,
    initial_stiffness: Square,
    /// `M·ι` of the full structure, kN·s²/mm: the ground force is `−ground_mass·ü_g`.
    ground_mass: Dofs,
}

/// Copy the leading `n×n` of a row-major slice into a padded square.
fn square(n: usize, values: &[f64], what: &'static str) -> Result<Square, ParamError> {
    if values.len() != n * n {
        return Err(ParamError::OutOfRange(what));
    }
    let mut out = [[0.0; MAX_DOF]; MAX_DOF];
    for (i, row) in out.iter_mut().enumerate().take(n) {
        for (j, v) in row.iter_mut().enumerate().take(n) {
            let x = values.get(i * n + j).copied().unwrap_or(f64::NAN);
            if !x.is_finite() {
                return Err(ParamError::NotFinite(what));
            }
            *v = x;
        }
    }
    Ok(out)
}

impl StructureN {
    /// Validate and build a model of `dofs` DOFs from row-major `dofs × dofs` matrices (mass,
    /// damping, analytical stiffness, whole-structure initial stiffness) and the full structure's
    /// `M·ι` (`dofs` values). The mass must be positive definite.
    pub fn new(
        dofs: usize,
        mass: &[f64],
        damping: &[f64],
        stiffness: &[f64],
        initial_stiffness: &[f64],
        ground_mass: &[f64],
    ) -> Result<Self, ParamError> {
        if dofs == 0 || dofs > MAX_DOF {
            return Err(ParamError::OutOfRange("structure DOFs (1..=8)"));
        }
        if ground_mass.len() != dofs {
            return Err(ParamError::OutOfRange("ground mass vector length"));
        }
        let mut gm = [0.0; MAX_DOF];
        for (g, &v) in gm.iter_mut().zip(ground_mass) {
            if !v.is_finite() {
                return Err(ParamError::NotFinite("ground mass vector"));
            }
            *g = v;
        }
        let s = Self {
            dofs,
            mass: square(dofs, mass, "mass matrix")?,
            damping: square(dofs, damping, "damping matrix")?,
            stiffness: square(dofs, stiffness, "stiffness matrix")?,
            initial_stiffness: square(dofs, initial_stiffness, "initial stiffness matrix")?,
            ground_mass: gm,
        };
        if s.padded(&s.mass, 1.0).cholesky().is_none() {
            return Err(ParamError::Singular("mass matrix (not positive definite)"));
        }
        Ok(s)
    }

    /// One DOF: mass, damping, analytical stiffness and whole-structure stiffness (the ground force
    /// acts on `mass`). The run-time sized twin of `LinearStructure::sdof`.
    pub fn sdof(
        mass_kn_s2_per_mm: f64,
        damping_kn_s_per_mm: f64,
        stiffness_kn_per_mm: f64,
        initial_stiffness_kn_per_mm: f64,
    ) -> Result<Self, ParamError> {
        positive(mass_kn_s2_per_mm, "mass")?;
        Self::new(
            1,
            &[mass_kn_s2_per_mm],
            &[damping_kn_s_per_mm],
            &[stiffness_kn_per_mm],
            &[initial_stiffness_kn_per_mm],
            &[mass_kn_s2_per_mm],
        )
    }

    /// Number of DOFs in use.
    pub fn dofs(&self) -> usize {
        self.dofs
    }
    /// Mass matrix, kN·s²/mm.
    pub fn mass(&self) -> &Square {
        &self.mass
    }
    /// Damping matrix, kN·s/mm.
    pub fn damping(&self) -> &Square {
        &self.damping
    }
    /// Analytical stiffness matrix, kN/mm.
    pub fn stiffness(&self) -> &Square {
        &self.stiffness
    }
    /// Initial stiffness of the whole structure, kN/mm.
    pub fn initial_stiffness(&self) -> &Square {
        &self.initial_stiffness
    }

    /// `a` as an nalgebra matrix with `pad` on the unused diagonal: block-diagonal, so inverses and
    /// factorizations of the leading block are those of the padded matrix's.
    fn padded(&self, a: &Square, pad: f64) -> Padded {
        Padded::from_fn(|i, j| {
            if i < self.dofs && j < self.dofs {
                a[i][j]
            } else if i == j {
                pad
            } else {
                0.0
            }
        })
    }

    /// Effective earthquake force `−(M·ι)·ü_g`, kN, for a ground acceleration in mm/s².
    #[inline]
    fn ground_force(&self, ground_accel_mm_s2: f64) -> Dofs {
        let mut f = [0.0; MAX_DOF];
        for (fi, gi) in f.iter_mut().zip(&self.ground_mass).take(self.dofs) {
            *fi = -gi * ground_accel_mm_s2;
        }
        f
    }
}

/// `a·x` over the leading `n` DOFs.
#[inline]
fn mul(a: &Square, x: &Dofs, n: usize) -> Dofs {
    let mut y = [0.0; MAX_DOF];
    for ((yi, row), _) in y.iter_mut().zip(a).zip(0..n) {
        let mut s = 0.0;
        for (aij, xj) in row.iter().zip(x).take(n) {
            s += aij * xj;
        }
        *yi = s;
    }
    y
}

/// The leading `n×n` block of an nalgebra matrix.
fn block(a: &Padded, n: usize) -> Square {
    let mut out = [[0.0; MAX_DOF]; MAX_DOF];
    for (i, row) in out.iter_mut().enumerate().take(n) {
        for (j, v) in row.iter_mut().enumerate().take(n) {
            *v = a[(i, j)];
        }
    }
    out
}

fn invert(m: Padded, what: &'static str) -> Result<Padded, ParamError> {
    let inv = lu_inverse(&m).ok_or(ParamError::Singular(what))?;
    if inv.iter().all(|v| v.is_finite()) {
        Ok(inv)
    } else {
        Err(ParamError::Singular(what))
    }
}

/// The inverse of `m` by nalgebra's own algorithm for an 8×8 matrix (`try_inverse`: LU with
/// partial pivoting, the first largest pivot, then the unit lower and the upper triangular
/// solves), operation for operation, so the bits are the same (a test compares them); `None`
/// where it gives none (a zero pivot). Written out because its generic code keeps index checks
/// that reach a panic in the firmware's link task, which builds an uploaded structure's FE: here
/// every access is checked and a failed one is a refusal.
fn lu_inverse(m: &Padded) -> Option<Padded> {
    const N: usize = MAX_DOF;
    // a[r][c]; nalgebra stores column-major.
    let mut a = [[0.0f64; N]; N];
    for (c, col) in m.as_slice().chunks_exact(N).enumerate() {
        for (r, v) in col.iter().enumerate() {
            *a.get_mut(r)?.get_mut(c)? = *v;
        }
    }
    let mut out = [[0.0f64; N]; N];
    for (i, row) in out.iter_mut().enumerate() {
        *row.get_mut(i)? = 1.0;
    }
    for i in 0..N {
        // `icamax` over the column from the diagonal down: the first largest |a|.
        let mut piv = i;
        let mut best = a.get(i)?.get(i)?.abs();
        for r in i + 1..N {
            let v = a.get(r)?.get(i)?.abs();
            if v > best {
                best = v;
                piv = r;
            }
        }
        let diag = *a.get(piv)?.get(i)?;
        if diag == 0.0 {
            return None;
        }
        let inv_diag = 1.0 / diag;
        if piv != i {
            out.swap(i, piv);
            for c in 0..=i {
                let (x, y) = (*a.get(i)?.get(c)?, *a.get(piv)?.get(c)?);
                *a.get_mut(i)?.get_mut(c)? = y;
                *a.get_mut(piv)?.get_mut(c)? = x;
            }
        }
        for r in i + 1..N {
            let c = a.get_mut(r)?.get_mut(i)?;
            *c *= inv_diag;
        }
        for k in i + 1..N {
            if piv != i {
                let (x, y) = (*a.get(i)?.get(k)?, *a.get(piv)?.get(k)?);
                *a.get_mut(i)?.get_mut(k)? = y;
                *a.get_mut(piv)?.get_mut(k)? = x;
            }
            let p = -*a.get(i)?.get(k)?;
            for r in i + 1..N {
                let coeff = *a.get(r)?.get(i)?;
                let y = a.get_mut(r)?.get_mut(k)?;
                *y += p * coeff;
            }
        }
    }
    for k in 0..N {
        // L (unit diagonal) then U, one column of the identity at a time.
        for i in 0..N - 1 {
            let coeff = -(*out.get(i)?.get(k)? / 1.0);
            for r in i + 1..N {
                let l = *a.get(r)?.get(i)?;
                let y = out.get_mut(r)?.get_mut(k)?;
                *y += coeff * l;
            }
        }
        for i in (0..N).rev() {
            let d = *a.get(i)?.get(i)?;
            if d == 0.0 {
                return None;
            }
            let coeff = *out.get(i)?.get(k)? / d;
            *out.get_mut(i)?.get_mut(k)? = coeff;
            for r in 0..i {
                let u = *a.get(r)?.get(i)?;
                let y = out.get_mut(r)?.get_mut(k)?;
                *y += -coeff * u;
            }
        }
    }
    Some(Padded::from_fn(|r, c| {
        out.get(r)
            .and_then(|row| row.get(c))
            .copied()
            .unwrap_or(f64::NAN)
    }))
}

/// The state of a [`ChangN`] one step changes (see [`ChangN::motion`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChangNMotion {
    disp: Dofs,
    vel: Dofs,
    accel: Dofs,
    next: Dofs,
}

/// Chang's explicit method (2002 form) on a [`StructureN`]: the formulas of
/// [`crate::integrator::Chang`], with loops over the DOFs in use.
///
/// `d₁ = d₀ + β1·Δt·v₀ + β2·Δt²·a₀`; equilibrium at `d₁` with `v₁ = v₀ + Δt/2·(a₀ + a₁)` gives
/// `(M + ½ΔtC)·a₁ = −Mι·ü_g − K·d₁ − r_ext − C·(v₀ + ½Δt·a₀)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChangN {
    model: StructureN,
    dt_s: f64,
    /// `Δt·β1`, `β1 = D⁻¹(M + ½ΔtC)`, `D = M + ½ΔtC + ¼Δt²K0`.
    b1_dt: Square,
    /// `Δt²·β2`, `β2 = D⁻¹(½M)`.
    b2_dt2: Square,
    /// `(M + ½ΔtC)⁻¹`.
    solve: Square,
    /// `M⁻¹`, for the initial acceleration.
    mass_inv: Square,
    disp: Dofs,
    vel: Dofs,
    accel: Dofs,
    next: Dofs,
}

impl ChangN {
    /// Build for a model and a step `dt_s`, at rest.
    pub fn new(model: StructureN, dt_s: f64) -> Result<Self, ParamError> {
        let dt = positive(dt_s, "time step")?;
        let m = model.padded(&model.mass, 1.0);
        // Padding the unused diagonal with 0 in C and K0 keeps D's padding at 1.
        let c = model.padded(&model.damping, 0.0);
        let k0 = model.padded(&model.initial_stiffness, 0.0);
        let m_half_c = m + c * (0.5 * dt);
        let d_inv = invert(m_half_c + k0 * (0.25 * dt * dt), "Chang D matrix")?;
        let b1 = d_inv * m_half_c;
        let b2 = d_inv * (m * 0.5);
        let n = model.dofs;
        let mut s = Self {
            model,
            dt_s: dt,
            b1_dt: block(&(b1 * dt), n),
            b2_dt2: block(&(b2 * (dt * dt)), n),
            solve: block(&invert(m_half_c, "M + Δt/2·C")?, n),
            mass_inv: block(&invert(m, "mass matrix")?, n),
            disp: [0.0; MAX_DOF],
            vel: [0.0; MAX_DOF],
            accel: [0.0; MAX_DOF],
            next: [0.0; MAX_DOF],
        };
        s.reset(0.0);
        Ok(s)
    }

    /// The model integrated.
    pub fn model(&self) -> &StructureN {
        &self.model
    }

    /// The time step, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// The displacement of the next step, mm (the leading [`StructureN::dofs`] entries).
    pub fn next_displacement(&self) -> &Dofs {
        &self.next
    }

    /// Displacement at the last completed step, mm.
    pub fn disp(&self) -> &Dofs {
        &self.disp
    }
    /// Velocity at the last completed step, mm/s.
    pub fn vel(&self) -> &Dofs {
        &self.vel
    }
    /// Acceleration (relative to the ground) at the last completed step, mm/s².
    pub fn accel(&self) -> &Dofs {
        &self.accel
    }

    /// What a step changes, for a caller that may take the step back ([`Self::rewind`]): 256 B,
    /// where a copy of the whole integrator also copies its coefficients (4.4 KB at 8 DOFs).
    pub fn motion(&self) -> ChangNMotion {
        ChangNMotion {
            disp: self.disp,
            vel: self.vel,
            accel: self.accel,
            next: self.next,
        }
    }

    /// Back to the state [`Self::motion`] saved.
    pub fn rewind(&mut self, m: &ChangNMotion) {
        self.disp = m.disp;
        self.vel = m.vel;
        self.accel = m.accel;
        self.next = m.next;
    }

    #[inline]
    fn predict(&mut self) {
        let n = self.model.dofs;
        let bv = mul(&self.b1_dt, &self.vel, n);
        let ba = mul(&self.b2_dt2, &self.accel, n);
        for i in 0..n {
            if let (Some(x), Some(d), Some(v), Some(a)) =
                (self.next.get_mut(i), self.disp.get(i), bv.get(i), ba.get(i))
            {
                *x = d + v + a;
            }
        }
    }

    /// Complete the step at [`Self::next_displacement`]: `ground_accel_mm_s2` is `ü_g` there and
    /// `r_ext_kn` the restoring force of the physical part at each DOF (zero where there is none).
    #[inline]
    pub fn advance(&mut self, ground_accel_mm_s2: f64, r_ext_kn: &Dofs) {
        let n = self.model.dofs;
        let half_dt = 0.5 * self.dt_s;
        let d1 = self.next;
        let mut v_pred = [0.0; MAX_DOF];
        for ((vp, v), a) in v_pred.iter_mut().zip(&self.vel).zip(&self.accel).take(n) {
            *vp = v + a * half_dt;
        }
        let kd = mul(&self.model.stiffness, &d1, n);
        let cv = mul(&self.model.damping, &v_pred, n);
        let mut rhs = self.model.ground_force(ground_accel_mm_s2);
        for i in 0..n {
            if let (Some(r), Some(k), Some(e), Some(c)) =
                (rhs.get_mut(i), kd.get(i), r_ext_kn.get(i), cv.get(i))
            {
                // The order of Chang<N>::advance, so one DOF matches it bit for bit.
                *r = *r - k - e - c;
            }
        }
        let a1 = mul(&self.solve, &rhs, n);
        let mut v1 = [0.0; MAX_DOF];
        for ((v, vp), a) in v1.iter_mut().zip(&v_pred).zip(&a1).take(n) {
            *v = vp + a * half_dt;
        }
        self.disp = d1;
        self.vel = v1;
        self.accel = a1;
        self.predict();
    }

    /// Back to rest (zero displacement and velocity) with the acceleration due to
    /// `ground_accel_mm_s2` at t = 0.
    pub fn reset(&mut self, ground_accel_mm_s2: f64) {
        let n = self.model.dofs;
        self.disp = [0.0; MAX_DOF];
        self.vel = [0.0; MAX_DOF];
        self.accel = mul(
            &self.mass_inv,
            &self.model.ground_force(ground_accel_mm_s2),
            n,
        );
        self.predict();
    }
}

#[cfg(test)]
mod tests;

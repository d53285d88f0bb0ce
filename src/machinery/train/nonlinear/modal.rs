//! The principled part of the nonlinear metamodel's initialization: the elastic eigen-analysis of
//! the whole structure (masses, elastic stiffness with the specimen, damping). Mass-normalized
//! modes, their damping ratios and ground participations, the floors' mode shapes and each
//! story's drift per unit of each mode (docs/design.md §5.5). The hysteresis section of the
//! structure file is never read here: the springs' laws are learned.

use nalgebra::DMatrix;
use rths_files::structure_file::Structure;

use crate::machinery::train::TrainError;

/// The elastic modes of a structure, lowest first.
#[derive(Debug, Clone, PartialEq)]
pub struct ElasticModes {
    /// rad/s.
    pub omega_rad_s: Vec<f64>,
    /// `φᵀCφ / 2ω`.
    pub damping_ratio: Vec<f64>,
    /// `φᵀMι`.
    pub ground_participation: Vec<f64>,
    /// `shape[floor][mode]`, mass-normalized; each mode's largest entry positive.
    pub shape: Vec<Vec<f64>>,
    /// `drift[story][mode]` = `shape[story] − shape[story − 1]`.
    pub drift: Vec<Vec<f64>>,
    /// The initial stiffness of each numerical story (the story stiffness minus the specimen's on
    /// the first), kN/mm: `k0` of the elastic springs.
    pub story_k0_kn_per_mm: Vec<f64>,
}

/// The lowest `modes` elastic modes of `s` (all when `modes` ≥ its DOFs). Refused: a specimen
/// with mass or damping (the modes would double them), a specimen off DOF 1, a singular mass.
pub fn elastic_modes(s: &Structure, modes: usize) -> Result<ElasticModes, TrainError> {
    let n = s.dofs();
    let (m_e, k_e, c_e) = s.specimen();
    if m_e != 0.0 || c_e != 0.0 {
        return Err(TrainError::Setting(format!(
            "structure {}: the nonlinear metamodel takes a specimen without mass or damping \
             (found {m_e} kN·s²/mm, {c_e} kN·s/mm)",
            s.name()
        )));
    }
    if s.specimen_dof() != 0 {
        return Err(TrainError::Setting(
            "the nonlinear metamodel takes the specimen on DOF 1".into(),
        ));
    }
    let sym = |a: &DMatrix<f64>| (a + a.transpose()) * 0.5;
    let chol = sym(s.mass())
        .cholesky()
        .ok_or_else(|| TrainError::Setting("mass matrix is not positive definite".into()))?;
    let l_inv = chol
        .l()
        .try_inverse()
        .ok_or_else(|| TrainError::Setting("mass matrix is singular".into()))?;
    let a = sym(&(&l_inv * s.stiffness() * l_inv.transpose()));
    let eig = a.symmetric_eigen();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let phi_all = l_inv.transpose() * &eig.eigenvectors;
    let iota = nalgebra::DVector::from_element(n, 1.0);
    if !(1..=n).contains(&modes) {
        return Err(TrainError::Setting(format!(
            "--modes {modes}: structure {} has {n} DOFs, so 1..={n} modes",
            s.name()
        )));
    }
    let r = modes;
    let mut out = ElasticModes {
        omega_rad_s: Vec::with_capacity(r),
        damping_ratio: Vec::with_capacity(r),
        ground_participation: Vec::with_capacity(r),
        shape: vec![Vec::with_capacity(r); n],
        drift: vec![Vec::with_capacity(r); n],
        story_k0_kn_per_mm: Vec::with_capacity(n),
    };
    for &j in order.iter().take(r) {
        let lam = eig.eigenvalues[j];
        if lam <= 0.0 || !lam.is_finite() {
            return Err(TrainError::Setting(
                "stiffness matrix is not positive definite".into(),
            ));
        }
        let mut phi = phi_all.column(j).into_owned();
        // A sign convention, so the same structure always gives the same shapes.
        let big = phi
            .iter()
            .fold(0.0_f64, |m, v| if v.abs() > m.abs() { *v } else { m });
        if big < 0.0 {
            phi = -phi;
        }
        let w = lam.sqrt();
        out.omega_rad_s.push(w);
        out.damping_ratio
            .push((phi.transpose() * s.damping() * &phi)[(0, 0)] / (2.0 * w));
        out.ground_participation
            .push((phi.transpose() * s.mass() * &iota)[(0, 0)]);
        let mut below = 0.0;
        for (i, v) in phi.iter().enumerate() {
            out.shape[i].push(*v);
            out.drift[i].push(v - below);
            below = *v;
        }
    }
    // A shear building's K[i][i] is story i's stiffness plus the one above: peel from the top,
    // then take the specimen's off the first story.
    let k = s.stiffness();
    let mut above = 0.0;
    let mut k0 = vec![0.0; n];
    for i in (0..n).rev() {
        k0[i] = k[(i, i)] - above;
        above = k0[i];
    }
    k0[0] -= k_e;
    if k0.iter().any(|v| *v <= 0.0 || !v.is_finite()) {
        return Err(TrainError::Setting(
            "a story has no positive elastic stiffness left".into(),
        ));
    }
    out.story_k0_kn_per_mm = k0;
    Ok(out)
}

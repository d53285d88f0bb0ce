//! Minimum-norm linear least squares `x·θ ≈ y` through an SVD of the column-normalized design
//! matrix, the one solver of every least-squares fit of the trainer (the LR metamodel, the ARX
//! initialization of the RNN, both LRX fits, the phase-2 LR of the study).
//!
//! The columns are scaled to unit norm first, so the cut-off compares directions, not units (mm/s²
//! vs kN vs mm). Singular values at or below `rcond·σ_max` are dropped: a rank-deficient matrix (for
//! a linear specimen `F_fb = k_b·x_fb` exactly) gets its minimum-norm solution instead of a blow-up.
//! The condition number before the cut-off and the rank kept are reported.

use nalgebra::{DMatrix, DVector};

use super::TrainError;

/// A least-squares solution with its conditioning.
#[derive(Debug, Clone, PartialEq)]
pub struct Lstsq {
    /// Coefficients θ, one per column of the design matrix, in its (unnormalized) units.
    pub coeffs: Vec<f64>,
    /// Singular values of the column-normalized design matrix, largest first.
    pub singular_values: Vec<f64>,
    /// `σ_max/σ_min` before the cut-off (infinite when `σ_min` is 0).
    pub condition_number: f64,
    /// Number of singular values kept (above `rcond·σ_max`).
    pub effective_rank: usize,
}

/// Solve `x·θ ≈ y` in the least-squares sense, dropping singular values of the column-normalized
/// `x` at or below `rcond·σ_max` (minimum-norm solution).
///
/// Refused: a shape mismatch, fewer rows than columns (fewer samples than coefficients is a bug in
/// the caller, not a fit), `rcond` outside (0, 1), non-finite data, an all-zero matrix, and a
/// non-finite solution.
pub fn solve(x: &DMatrix<f64>, y: &DVector<f64>, rcond: f64) -> Result<Lstsq, TrainError> {
    if x.nrows() != y.len() || x.ncols() == 0 || x.nrows() < x.ncols() {
        return Err(TrainError::Setting(format!(
            "design matrix {}×{} and target {} do not fit",
            x.nrows(),
            x.ncols(),
            y.len()
        )));
    }
    if !(rcond.is_finite() && rcond > 0.0 && rcond < 1.0) {
        return Err(TrainError::Setting(format!("rcond {rcond} not in (0, 1)")));
    }
    if x.iter().chain(y.iter()).any(|v| !v.is_finite()) {
        return Err(TrainError::Diverged("non-finite training data".into()));
    }
    let scale: Vec<f64> = x
        .column_iter()
        .map(|c| {
            let n = c.norm();
            if n > 0.0 {
                n
            } else {
                1.0
            }
        })
        .collect();
    let mut xn = x.clone();
    for (j, mut c) in xn.column_iter_mut().enumerate() {
        c /= scale[j];
    }
    let svd = xn.svd(true, true);
    let (Some(u), Some(v_t)) = (&svd.u, &svd.v_t) else {
        return Err(TrainError::Diverged("SVD did not converge".into()));
    };
    // nalgebra does not promise an order; the report lists them largest first.
    let mut singular_values: Vec<f64> = svd.singular_values.iter().copied().collect();
    singular_values.sort_by(|a, b| b.total_cmp(a));
    let s_max = singular_values.first().copied().unwrap_or(0.0);
    let s_min = singular_values.last().copied().unwrap_or(0.0);
    if s_max <= 0.0 {
        return Err(TrainError::Diverged("design matrix is zero".into()));
    }
    let condition_number = if s_min > 0.0 {
        s_max / s_min
    } else {
        f64::INFINITY
    };
    // Summed in nalgebra's own order of the singular triplets: the trained coefficients depend on
    // it to the last bit.
    let uty = u.transpose() * y;
    let mut theta_n = DVector::<f64>::zeros(x.ncols());
    let mut effective_rank = 0;
    for (k, &s) in svd.singular_values.iter().enumerate() {
        if s > rcond * s_max {
            effective_rank += 1;
            theta_n += v_t.row(k).transpose() * (uty[k] / s);
        }
    }
    let coeffs: Vec<f64> = theta_n.iter().zip(&scale).map(|(t, s)| t / s).collect();
    if coeffs.iter().any(|t| !t.is_finite()) {
        return Err(TrainError::Diverged(
            "non-finite least-squares coefficients".into(),
        ));
    }
    Ok(Lstsq {
        coeffs,
        singular_values,
        condition_number,
        effective_rank,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_system_is_recovered_and_reported() {
        // Columns of very different units: the normalization makes the fit well conditioned.
        let x = DMatrix::from_fn(50, 3, |i, j| {
            let t = i as f64;
            [1.0, 1e3 * (0.1 * t).sin(), 1e-3 * (0.37 * t).cos()][j]
        });
        let truth = DVector::from_vec(vec![0.5, -2e-3, 40.0]);
        let y = &x * &truth;
        let s = solve(&x, &y, 1e-10).unwrap();
        assert_eq!(s.effective_rank, 3);
        assert_eq!(s.singular_values.len(), 3);
        assert!(s.singular_values.windows(2).all(|w| w[0] >= w[1]));
        assert!(s.condition_number.is_finite() && s.condition_number < 10.0);
        for (got, want) in s.coeffs.iter().zip(truth.iter()) {
            assert!((got - want).abs() < 1e-10 * want.abs(), "{got} vs {want}");
        }
    }

    #[test]
    fn duplicate_column_gives_the_minimum_norm_split() {
        let x = DMatrix::from_fn(40, 2, |i, _| (0.3 * i as f64).sin());
        let y = DVector::from_fn(40, |i, _| 2.0 * (0.3 * i as f64).sin());
        let s = solve(&x, &y, 1e-10).unwrap();
        assert_eq!(s.effective_rank, 1);
        assert!(s.condition_number > 1e12);
        assert!((s.coeffs[0] - 1.0).abs() < 1e-12 && (s.coeffs[1] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_inputs_are_refused() {
        let x = DMatrix::from_element(4, 2, 1.0);
        let y = DVector::from_element(4, 1.0);
        assert!(solve(&x, &DVector::from_element(3, 1.0), 1e-10).is_err());
        assert!(solve(
            &DMatrix::from_element(1, 2, 1.0),
            &DVector::from_element(1, 1.0),
            1e-10
        )
        .is_err());
        for rcond in [0.0, 1.0, -1e-3, f64::NAN] {
            assert!(solve(&x, &y, rcond).is_err(), "rcond {rcond}");
        }
        let mut bad = x.clone();
        bad[(2, 1)] = f64::NAN;
        assert!(matches!(
            solve(&bad, &y, 1e-10),
            Err(TrainError::Diverged(_))
        ));
        let zero = DMatrix::zeros(4, 2);
        assert!(matches!(
            solve(&zero, &y, 1e-10),
            Err(TrainError::Diverged(_))
        ));
    }
}

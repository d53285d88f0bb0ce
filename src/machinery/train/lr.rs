//! The linear-regression metamodel (paper Eq. 6 with a bias):
//! `x̂(i+1) = θ0 + θ1·ü_g(i) + θ2·x_fb(i) + θ3·F_fb(i) + θ4·x̂(i) + θ5·x̂(i−1)`, fitted by least
//! squares through an SVD of the column-normalized design matrix.
//!
//! For a linear specimen `F_fb = k_b·x_fb` exactly, so the design matrix is rank-deficient: singular
//! values below `rcond·σ_max` are dropped (minimum-norm solution, [`super::lstsq`]), and the
//! condition number before the cut-off and the rank kept are reported. The fit is then an ARX model of the whole structure
//! (θ4 ≈ 2, θ5 ≈ −1).

use nalgebra::{DMatrix, DVector};
use rths_core::control::Analytical;
use rths_core::metamodel::{Lr, LrParams, LR_COEFFS};
use rths_core::metrics::nrmse_pct;

use super::data::{delayed, TrainingResponse};
use super::TrainError;
use super::{lstsq, pure};

/// Default relative singular-value cut-off: far above the rounding-level singular value of the
/// exactly collinear `x_fb`/`F_fb` pair (~1e-16), far below the smallest meaningful direction
/// (the second difference of a 2048 Hz signal, ~1e-5 relative).
pub const DEFAULT_RCOND: f64 = 1e-10;

/// Result of a least-squares fit.
#[derive(Debug, Clone, PartialEq)]
pub struct LrSolution {
    /// Coefficients θ0..θ5.
    pub theta: [f64; LR_COEFFS],
    /// Singular values of the column-normalized design matrix, largest first.
    pub singular_values: Vec<f64>,
    /// `σ_max/σ_min` before the cut-off (infinite when `σ_min` is 0).
    pub condition_number: f64,
    /// Number of singular values kept.
    pub effective_rank: usize,
}

/// A phase-1 fit on the pure response, with its scores.
#[derive(Debug, Clone, PartialEq)]
pub struct LrFit {
    /// The least-squares solution.
    pub solution: LrSolution,
    /// NRMSE (%) of the one-step predictions (teacher forcing) against `d(i+1)`.
    pub train_nrmse_pct: f64,
    /// NRMSE (%) of the `lr-pure` loop on the training motion.
    pub pure_nrmse_pct: f64,
    /// The `lr-pure` prediction series.
    pub pure_prediction_mm: Vec<f64>,
}

/// One row of the design matrix, `[1, ü_g(i), x_fb(i), F_fb(i), x̂(i), x̂(i−1)]` (the order of
/// `rths_core::metamodel::LR_FEATURE_NAMES`, whose `Lr::predict` is the one LR inference).
pub fn features(
    ground_accel_mm_s2: f64,
    disp_fb_mm: f64,
    force_fb_kn: f64,
    disp_pred_mm: f64,
    disp_pred_prev_mm: f64,
) -> [f64; LR_COEFFS] {
    [
        1.0,
        ground_accel_mm_s2,
        disp_fb_mm,
        force_fb_kn,
        disp_pred_mm,
        disp_pred_prev_mm,
    ]
}

/// Design matrix and target from aligned series: row `i` (i = 0..n−1) uses `ü_g(i)`, `x_fb(i)`,
/// `F_fb(i)`, `x(i)`, `x(i−1)` (zero at i = 0) and targets `x(i+1)`.
pub fn design_matrix(
    ground_accel_mm_s2: &[f64],
    disp_fb_mm: &[f64],
    force_fb_kn: &[f64],
    disp_mm: &[f64],
) -> Result<(DMatrix<f64>, DVector<f64>), TrainError> {
    let n = disp_mm.len();
    if ground_accel_mm_s2.len() != n || disp_fb_mm.len() != n || force_fb_kn.len() != n {
        return Err(TrainError::Setting("series of different lengths".into()));
    }
    if n < LR_COEFFS + 2 {
        return Err(TrainError::TooShort {
            found: n,
            needed: LR_COEFFS + 2,
        });
    }
    let rows = n - 1;
    let x = DMatrix::from_fn(rows, LR_COEFFS, |i, j| {
        let prev = if i == 0 { 0.0 } else { disp_mm[i - 1] };
        features(
            ground_accel_mm_s2[i],
            disp_fb_mm[i],
            force_fb_kn[i],
            disp_mm[i],
            prev,
        )[j]
    });
    let y = DVector::from_fn(rows, |i, _| disp_mm[i + 1]);
    Ok((x, y))
}

/// Minimum-norm least squares `x·θ ≈ y` ([`super::lstsq::solve`]: SVD of the column-normalized
/// `x`, singular values at or below `rcond·σ_max` dropped), for the [`LR_COEFFS`] LR features.
pub fn solve(x: &DMatrix<f64>, y: &DVector<f64>, rcond: f64) -> Result<LrSolution, TrainError> {
    if x.ncols() != LR_COEFFS {
        return Err(TrainError::Setting(format!(
            "design matrix {}×{} and target {} do not fit",
            x.nrows(),
            x.ncols(),
            y.len()
        )));
    }
    let fit = lstsq::solve(x, y, rcond)?;
    let mut theta = [0.0; LR_COEFFS];
    theta.iter_mut().zip(&fit.coeffs).for_each(|(t, c)| *t = *c);
    Ok(LrSolution {
        theta,
        singular_values: fit.singular_values,
        condition_number: fit.condition_number,
        effective_rank: fit.effective_rank,
    })
}

/// Phase-1 fit: `x_fb(i) = d(i − delay)`, `F_fb(i) = N(i − delay)`, `x̂ = d` (teacher forcing).
pub fn fit_pure(
    response: &TrainingResponse,
    delay_steps: usize,
    brace_k_kn_per_mm: f64,
    rcond: f64,
) -> Result<LrFit, TrainError> {
    let d = &response.brace_disp_mm;
    let x_fb = delayed(d, delay_steps);
    let f_fb = delayed(&response.brace_force_kn, delay_steps);
    let (x, y) = design_matrix(&response.ground_accel_mm_s2, &x_fb, &f_fb, d)?;
    let solution = solve(&x, &y, rcond)?;
    let theta_v = DVector::from_column_slice(&solution.theta);
    let one_step = &x * theta_v;
    let train_nrmse_pct = nrmse_pct(one_step.as_slice(), y.as_slice())?;
    let pure = pure_prediction(
        &solution.theta,
        &response.ground_accel_mm_s2,
        delay_steps,
        brace_k_kn_per_mm,
    )?;
    let pure_nrmse_pct = nrmse_pct(&pure, d)?;
    Ok(LrFit {
        solution,
        train_nrmse_pct,
        pure_nrmse_pct,
        pure_prediction_mm: pure,
    })
}

/// The `lr-pure` run: `theta` as core's LR (`rths_core::metamodel::Lr`, the one LR inference) in
/// the controller, on its own prediction `delay_steps` earlier (`x_fb(i) = x̂(i − delay)`,
/// `F_fb = k_b·x_fb`, zero before the start), no actuator, run by the host's driver
/// ([`super::pure`]). Returns `x̂(0..n)` with `x̂(0) = 0` (at rest).
pub fn pure_prediction(
    theta: &[f64; LR_COEFFS],
    ground_accel_mm_s2: &[f64],
    delay_steps: usize,
    brace_k_kn_per_mm: f64,
) -> Result<Vec<f64>, TrainError> {
    let params = LrParams::new(*theta)
        .map_err(|e| TrainError::Diverged(format!("LR coefficients rejected: {e:?}")))?;
    pure::prediction(
        "lr-pure",
        Analytical::Lr(Lr::new(params)),
        pure::brace_prototype(brace_k_kn_per_mm)?,
        delay_steps,
        ground_accel_mm_s2,
    )
}

/// `lr-pure` NRMSE (%) of `theta` against the pure brace deformation of `response`.
pub fn lr_pure_nrmse_pct(
    theta: &[f64; LR_COEFFS],
    response: &TrainingResponse,
    delay_steps: usize,
    brace_k_kn_per_mm: f64,
) -> Result<f64, TrainError> {
    let x = pure_prediction(
        theta,
        &response.ground_accel_mm_s2,
        delay_steps,
        brace_k_kn_per_mm,
    )?;
    Ok(nrmse_pct(&x, &response.brace_disp_mm)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machinery::train::data::pure_response;
    use rand::{Rng, SeedableRng};
    use rths_core::metamodel::Features;
    use rths_core::params::{Prototype, DT_S, PAPER_DELAY_STEPS};

    /// The series `x(0..n)` (from rest) of the LR model `theta` driven by the given inputs, through
    /// core's inference.
    fn arx_series(theta: [f64; LR_COEFFS], u: &[f64], x_fb: &[f64], f_fb: &[f64]) -> Vec<f64> {
        let mut lr = Lr::new(LrParams::new(theta).unwrap());
        let mut x = vec![0.0];
        for i in 0..u.len() - 1 {
            let f = Features {
                ground_accel_mm_s2: u[i],
                brace_disp_fb_mm: x_fb[i],
                brace_force_fb_kn: f_fb[i],
            };
            x.push(lr.predict(f).unwrap());
        }
        x
    }

    /// A stable ARX system driven by independent random inputs: noise-free data must give back its
    /// coefficients to rounding.
    #[test]
    fn recovers_a_synthetic_arx_system_exactly() {
        let truth = [0.003, 2e-4, -0.05, 1e-3, 1.6, -0.7];
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let n = 4000;
        let u: Vec<f64> = (0..n).map(|_| rng.random_range(-500.0..500.0)).collect();
        let x_fb: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let f_fb: Vec<f64> = (0..n).map(|_| rng.random_range(-100.0..100.0)).collect();
        let x = arx_series(truth, &u, &x_fb, &f_fb);
        let (a, b) = design_matrix(&u, &x_fb, &f_fb, &x).unwrap();
        let s = solve(&a, &b, DEFAULT_RCOND).unwrap();
        assert_eq!(s.effective_rank, 6);
        for (got, want) in s.theta.iter().zip(&truth) {
            assert!(
                (got - want).abs() < 1e-10 * want.abs().max(1.0),
                "{got} vs {want}"
            );
        }
        assert!(s.condition_number.is_finite() && s.condition_number < 1e3);
    }

    /// `F_fb = k·x_fb` exactly: no NaN, rank 5, a huge condition number, and the combined feedback
    /// weight is still recovered.
    #[test]
    fn collinear_feedback_is_handled() {
        let truth = [0.0, 2e-4, -0.05, 0.0, 1.6, -0.7];
        let k = 1224.1;
        let mut rng = rand::rngs::StdRng::seed_from_u64(4);
        let n = 4000;
        let u: Vec<f64> = (0..n).map(|_| rng.random_range(-500.0..500.0)).collect();
        let x_fb: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
        let f_fb: Vec<f64> = x_fb.iter().map(|v| k * v).collect();
        let x = arx_series(truth, &u, &x_fb, &f_fb);
        let (a, b) = design_matrix(&u, &x_fb, &f_fb, &x).unwrap();
        let s = solve(&a, &b, DEFAULT_RCOND).unwrap();
        assert!(s.theta.iter().all(|t| t.is_finite()));
        assert_eq!(s.effective_rank, 5);
        assert!(s.condition_number > 1e12, "cond {}", s.condition_number);
        let combined = s.theta[2] + k * s.theta[3];
        assert!((combined - truth[2]).abs() < 1e-9, "{combined}");
        // Minimum norm in normalized units splits the weight evenly between the two columns.
        assert!((s.theta[2] - k * s.theta[3]).abs() < 1e-6 * combined.abs());
        assert!((s.theta[4] - 1.6).abs() < 1e-9 && (s.theta[5] + 0.7).abs() < 1e-9);
    }

    #[test]
    fn lr_pure_on_el_centro_meets_the_paper() {
        let p = Prototype::paper();
        let ag = crate::machinery::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
        let r = pure_response(&p, &ag, DT_S).unwrap();
        let k_b = p.brace_axial_stiffness_kn_per_mm();
        let fit = fit_pure(&r, PAPER_DELAY_STEPS, k_b, DEFAULT_RCOND).unwrap();
        let t = fit.solution.theta;
        // An ARX model of the whole structure.
        assert!(
            (t[4] - 2.0).abs() < 0.01 && (t[5] + 1.0).abs() < 0.01,
            "{t:?}"
        );
        assert!(fit.solution.effective_rank == 5, "{:?}", fit.solution);
        assert!(fit.solution.condition_number > 1e10);
        assert!(
            fit.pure_nrmse_pct <= 0.15,
            "lr-pure NRMSE {}",
            fit.pure_nrmse_pct
        );
        let again = lr_pure_nrmse_pct(&t, &r, PAPER_DELAY_STEPS, k_b).unwrap();
        assert_eq!(again, fit.pure_nrmse_pct);
    }
}

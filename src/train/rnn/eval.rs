//! A model run over a record: teacher-forced (the true delayed force as input) and `rnn-pure` (its
//! own delayed prediction as the feedback), with the `rnn-pure` score.

use rths_core::metrics::nrmse_pct;

use super::model::{Rnn, N_IN};
use crate::train::data::PureResponse;
use crate::train::TrainError;

/// Run the model over raw inputs from rest; returns `x̂(i+1)` for each input row.
pub(super) fn run_teacher_forced(model: &Rnn, inputs: &[[f64; N_IN]]) -> Vec<f64> {
    let mut h = vec![0.0; model.hidden];
    let mut s = vec![0.0; model.hidden];
    inputs
        .iter()
        .map(|u| model.step(&mut h, &mut s, u[0], u[1]))
        .collect()
}

/// The `rnn-pure` loop: the RNN runs with `F_fb(i) = k_b·x̂(i − delay)` (its own delayed prediction,
/// zero before the start). Returns `x̂(0..n)` with `x̂(0) = 0`.
pub fn run_pure_loop(
    model: &Rnn,
    ground_accel_mm_s2: &[f64],
    delay_steps: usize,
    brace_k_kn_per_mm: f64,
) -> Vec<f64> {
    let n = ground_accel_mm_s2.len();
    let mut x = Vec::with_capacity(n);
    if n == 0 {
        return x;
    }
    x.push(0.0);
    let mut h = vec![0.0; model.hidden];
    let mut s = vec![0.0; model.hidden];
    for i in 0..n - 1 {
        let x_fb = if i >= delay_steps {
            x[i - delay_steps]
        } else {
            0.0
        };
        let next = model.step(
            &mut h,
            &mut s,
            ground_accel_mm_s2[i],
            brace_k_kn_per_mm * x_fb,
        );
        x.push(next);
    }
    x
}

/// `rnn-pure` NRMSE (%) against the pure brace deformation.
pub fn rnn_pure_nrmse_pct(
    model: &Rnn,
    response: &PureResponse,
    delay_steps: usize,
    brace_k_kn_per_mm: f64,
) -> Result<f64, TrainError> {
    let x = run_pure_loop(
        model,
        &response.ground_accel_mm_s2,
        delay_steps,
        brace_k_kn_per_mm,
    );
    Ok(nrmse_pct(&x, &response.brace_disp_mm)?)
}

//! A model run over a record: teacher-forced (the true delayed force as input: training's own
//! evaluation of its f64 net) and `rnn-pure` (its own delayed prediction as the feedback: the model
//! in core's controller, run by the host's driver), with the `rnn-pure` score.

use rths_core::control::Analytical;
use rths_core::metamodel::{Rnn as CoreRnn, RnnParams};
use rths_core::metrics::nrmse_pct;

use super::model::{TrainableRnn, N_IN};
use crate::machinery::train::data::TrainingResponse;
use crate::machinery::train::{pure, TrainError};

/// Run the model over raw inputs from rest; returns `x̂(i+1)` for each input row.
pub(super) fn run_teacher_forced(model: &TrainableRnn, inputs: &[[f64; N_IN]]) -> Vec<f64> {
    let mut h = vec![0.0; model.hidden];
    let mut s = vec![0.0; model.hidden];
    inputs
        .iter()
        .map(|u| model.step(&mut h, &mut s, u[0], u[1]))
        .collect()
}

/// The `rnn-pure` run: the model as core's RNN (`rths_core::metamodel::Rnn`, the same weights and
/// forward step) in the controller, on `F_fb(i) = k_b·x̂(i − delay)` (its own delayed
/// prediction, zero before the start), no actuator, run by the host's driver
/// ([`crate::machinery::train::pure`]). Returns `x̂(0..n)` with `x̂(0) = 0`.
pub fn pure_prediction(
    model: &TrainableRnn,
    ground_accel_mm_s2: &[f64],
    delay_steps: usize,
    brace_k_kn_per_mm: f64,
) -> Result<Vec<f64>, TrainError> {
    let params = RnnParams::new(model.core_weights(), *model.scaling())
        .map_err(|e| TrainError::Diverged(format!("RNN weights rejected: {e:?}")))?;
    pure::prediction(
        "rnn-pure",
        Analytical::Rnn(CoreRnn::new(params)),
        pure::brace_prototype(brace_k_kn_per_mm)?,
        delay_steps,
        ground_accel_mm_s2,
    )
}

/// `rnn-pure` NRMSE (%) against the pure brace deformation.
pub fn rnn_pure_nrmse_pct(
    model: &TrainableRnn,
    response: &TrainingResponse,
    delay_steps: usize,
    brace_k_kn_per_mm: f64,
) -> Result<f64, TrainError> {
    let x = pure_prediction(
        model,
        &response.ground_accel_mm_s2,
        delay_steps,
        brace_k_kn_per_mm,
    )?;
    Ok(nrmse_pct(&x, &response.brace_disp_mm)?)
}

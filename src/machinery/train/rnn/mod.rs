//! The Elman RNN metamodel (paper): inputs `[ü_g(i), F_fb(i)]`, normalized by mean and standard
//! deviation; `h = tanh(W_ih·in + W_hh·h + b_h)`; `y = W_ho·h + b_o`, de-normalized to `x̂(i+1)` (mm).
//!
//! Initialization (default, [`InitMethod::Arx`]): the linear ARX model of the training response is
//! identified by least squares (the LR metamodel's fit, [`super::lr::fit_pure`]) and realized as the
//! RNN in tanh's near-linear range ([`TrainableRnn::from_arx`]). Training from random weights
//! ([`InitMethod::Random`]) learns the one-step map but not the lightly damped 3.4 Hz dynamics at
//! 2048 Hz, and its `rnn-pure` error is ~64 % (`docs/training.md`).
//!
//! Training (offline, phase 1, fine-tuning after the ARX initialization): teacher forcing with the
//! true delayed brace force `F_fb(i) = N(i − delay)` (or, after `teacher_epochs`, the model's own
//! delayed prediction), target `d(i+1)`, mean squared error in normalized units. The record is cut
//! into consecutive windows; every `validation_every`-th window is held out for validation. Each
//! epoch runs the whole record in time order, carrying the hidden state across windows (stateful
//! truncated BPTT: the gradient stops at the window start), and takes one Adam step per training
//! window. Epoch 0 only evaluates the initial weights. Training stops when the validation loss has
//! not improved for `patience` epochs; the best weights (possibly the initial ones) are kept.
//! Inference runs at the full controller rate, like training.
//!
//! Files: `model.rs` the trainable net (parameters, initialization from the ARX model or at
//! random, scaling, model-file conversion; its forward step is `rths-core`'s
//! [`rths_core::metamodel::elman_step`], the one the controller runs), `eval.rs` a model run over a
//! record (teacher-forced, and `rnn-pure` on its own delayed prediction in core's controller), `optimizer.rs` Adam with
//! its per-parameter step scales, `train.rs` the training loop (BPTT windows, validation, early
//! stopping, progress bar) and the model file of a run.

mod eval;
mod model;
mod optimizer;
mod train;

pub use eval::{pure_prediction, rnn_pure_nrmse_pct};
pub use model::{RnnInit, Scaling, TrainableRnn, DEFAULT_ARX_STATE_SCALE, N_IN};
pub use train::{model_file, train, InitMethod, RnnConfig, RnnTraining, ARX_FINE_TUNE_EPOCHS};

#[cfg(test)]
mod tests;

//! The Elman RNN metamodel (paper): inputs `[ü_g(i), F_fb(i)]`, normalized by mean and standard
//! deviation; `h = tanh(W_ih·in + W_hh·h + b_h)`; `y = W_ho·h + b_o`, de-normalized to `x̂(i+1)` (mm).
//!
//! Initialization (default, [`InitMethod::Arx`]): the linear ARX model of the training response is
//! identified by least squares (the LR metamodel's fit, [`super::lr::fit_pure`]) and realized as the
//! RNN in tanh's near-linear range ([`Rnn::from_arx`]). Training from random weights
//! ([`InitMethod::Random`]) learns the one-step map but not the lightly damped 3.4 Hz dynamics at
//! 2048 Hz, and its `rnn-pure` error is ~64 % (`notes/train.md`).
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

use std::io::IsTerminal;
use std::time::Instant;

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rths_core::metrics::nrmse_pct;

use super::data::{delayed, PureResponse};
use super::TrainError;
use crate::model_file::{ModelFile, ModelFileError, RnnWeights, Scores, Training, MAX_HIDDEN};

/// Number of inputs (ü_g, F_fb).
pub const N_IN: usize = 2;

/// Input and output normalization.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scaling {
    /// Means of ü_g (mm/s²) and F_fb (kN).
    pub input_mean: [f64; N_IN],
    /// Standard deviations of ü_g and F_fb (positive).
    pub input_std: [f64; N_IN],
    /// Mean of x̂, mm.
    pub output_mean: f64,
    /// Standard deviation of x̂, mm (positive).
    pub output_std: f64,
}

fn mean_std(x: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = x.clone().count().max(1) as f64;
    let mean = x.clone().sum::<f64>() / n;
    let var = x.map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    // A constant signal keeps a unit scale rather than dividing by zero.
    let std = if var > 0.0 { var.sqrt() } else { 1.0 };
    (mean, std)
}

/// Initial-weight distribution (see [`Rnn::random`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RnnInit {
    /// Scale of the input weights.
    pub input_gain: f64,
    /// Scale of the random part of the recurrent weights.
    pub recurrent_gain: f64,
    /// Identity part of the recurrent weights (near 1: slow, integrator-like initial dynamics, which
    /// a 3.4 Hz structure sampled at 2048 Hz needs; "IRNN" initialization).
    pub recurrent_diag: f64,
}

impl Default for RnnInit {
    fn default() -> Self {
        Self {
            input_gain: 0.1,
            recurrent_gain: 0.05,
            recurrent_diag: 0.99,
        }
    }
}

/// An Elman RNN with its weights in one flat vector
/// `[w_ih (H×2, row-major), w_hh (H×H, row-major), b_h (H), w_ho (H), b_o]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Rnn {
    hidden: usize,
    params: Vec<f64>,
    scaling: Scaling,
}

impl Rnn {
    fn n_params(h: usize) -> usize {
        N_IN * h + h * h + h + h + 1
    }
    fn off_hh(&self) -> usize {
        N_IN * self.hidden
    }
    fn off_bh(&self) -> usize {
        self.off_hh() + self.hidden * self.hidden
    }
    fn off_ho(&self) -> usize {
        self.off_bh() + self.hidden
    }
    fn off_bo(&self) -> usize {
        self.off_ho() + self.hidden
    }

    /// Seeded random initial weights: input weights `N(0, input_gain²/2)`, recurrent weights
    /// `recurrent_diag·I + N(0, recurrent_gain²/H)`, output weights `N(0, 1/H)`, zero biases.
    pub fn random(
        hidden: usize,
        scaling: Scaling,
        seed: u64,
        init: &RnnInit,
    ) -> Result<Self, TrainError> {
        if hidden == 0 || hidden > MAX_HIDDEN {
            return Err(TrainError::Setting(format!(
                "hidden size {hidden} not in 1..={MAX_HIDDEN}"
            )));
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let h = hidden;
        let mut params = vec![0.0; Self::n_params(h)];
        let normal = |s: f64| Normal::new(0.0, s).map_err(|e| TrainError::Setting(e.to_string()));
        let n_in = normal(init.input_gain / (N_IN as f64).sqrt())?;
        let n_hh = normal(init.recurrent_gain / (h as f64).sqrt())?;
        let n_ho = normal(1.0 / (h as f64).sqrt())?;
        let mut s = Self {
            hidden,
            params: Vec::new(),
            scaling,
        };
        for p in &mut params[..s.off_hh()] {
            *p = n_in.sample(&mut rng);
        }
        let (a, b) = (s.off_hh(), s.off_bh());
        for p in &mut params[a..b] {
            *p = n_hh.sample(&mut rng);
        }
        let (a, b) = (s.off_ho(), s.off_bo());
        for p in &mut params[a..b] {
            *p = n_ho.sample(&mut rng);
        }
        for j in 0..h {
            params[a - h - h * h + j * h + j] += init.recurrent_diag;
        }
        s.params = params;
        Ok(s)
    }

    /// The identified linear (ARX) model `x(i+1) = θ0 + θ1·ü_g(i) + θ2·x_fb(i) + θ3·F_fb(i) +
    /// θ4·x(i) + θ5·x(i−1)` (the LR metamodel's features, see [`super::lr`]) realized as an Elman
    /// RNN working in tanh's near-linear range.
    ///
    /// Hidden units 0 and 1 hold `ε·x(i+1)/σ_x` and `ε·x(i)/σ_x` (σ_x = `scaling.output_std`; the
    /// displacement itself, not its deviation from the mean, so that h = 0 is the structure at rest):
    /// `W_hh` is the companion matrix `[[θ4, θ5], [1, 0]]`, the input weights are the ARX input
    /// coefficients with the input normalization folded in and scaled by ε, `W_ho = [1/ε, 0, ..]`.
    /// With `|ε·x/σ_x| ≲ 1e-3`, `tanh(z) = z·(1 − z²/3 + ..)` departs from the linear model by
    /// ~1e-7 relative, far below the 2 % structural damping per cycle. `x_fb = F_fb/k_b` in phase 1
    /// (a linear brace), so θ2 enters as a force weight `θ2/k_b`. Units 2.. are spare: seeded small
    /// random input and recurrent weights at the same scale ε, no path into units 0–1 or the output,
    /// so the model starts exactly as the ARX and fine-tuning may recruit them.
    pub fn from_arx(
        hidden: usize,
        scaling: Scaling,
        theta: &[f64; super::lr::N_THETA],
        brace_k_kn_per_mm: f64,
        state_scale: f64,
        seed: u64,
    ) -> Result<Self, TrainError> {
        if !(2..=MAX_HIDDEN).contains(&hidden) {
            return Err(TrainError::Setting(format!(
                "the ARX initialization needs a hidden size in 2..={MAX_HIDDEN}, found {hidden}"
            )));
        }
        if !(state_scale > 0.0 && state_scale.is_finite() && brace_k_kn_per_mm > 0.0) {
            return Err(TrainError::Setting(
                "ARX state scale and brace stiffness must be > 0".into(),
            ));
        }
        let (h, eps) = (hidden, state_scale);
        let sc = scaling;
        let so = sc.output_std;
        let [th0, th1, th2, th3, th4, th5] = *theta;
        let c_force = th2 / brace_k_kn_per_mm + th3;
        let mut s = Self {
            hidden,
            params: vec![0.0; Self::n_params(h)],
            scaling,
        };
        let (hh, bh, ho, bo) = (s.off_hh(), s.off_bh(), s.off_ho(), s.off_bo());
        let p = &mut s.params;
        // Unit 0: ε·x(i+1)/σ_x from the normalized inputs u_k = (raw_k − μ_k)/σ_k.
        p[0] = eps * th1 * sc.input_std[0] / so;
        p[1] = eps * c_force * sc.input_std[1] / so;
        p[bh] = eps * (th0 + th1 * sc.input_mean[0] + c_force * sc.input_mean[1]) / so;
        p[hh] = th4;
        p[hh + 1] = th5;
        // Unit 1: shift register, ε·x(i)/σ_x.
        p[hh + h] = 1.0;
        // y = (x̂ − μ_x)/σ_x.
        p[ho] = 1.0 / eps;
        p[bo] = -sc.output_mean / so;
        if h > 2 {
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
            let n_in =
                Normal::new(0.0, 0.1 * eps).map_err(|e| TrainError::Setting(e.to_string()))?;
            let n_hh = Normal::new(0.0, 0.05 / (h as f64).sqrt())
                .map_err(|e| TrainError::Setting(e.to_string()))?;
            for j in 2..h {
                p[N_IN * j] = n_in.sample(&mut rng);
                p[N_IN * j + 1] = n_in.sample(&mut rng);
                for k in 2..h {
                    p[hh + j * h + k] = n_hh.sample(&mut rng) + if j == k { 0.9 } else { 0.0 };
                }
            }
        }
        Ok(s)
    }

    /// Hidden size.
    pub fn hidden(&self) -> usize {
        self.hidden
    }

    /// Input/output normalization.
    pub fn scaling(&self) -> &Scaling {
        &self.scaling
    }

    /// The weights as the slices `rths-core`'s inference takes (the flat vector cut at its offsets).
    pub fn core_weights(&self) -> rths_core::metamodel::RnnWeights<'_> {
        let p = &self.params;
        rths_core::metamodel::RnnWeights {
            w_ih: &p[..self.off_hh()],
            w_hh: &p[self.off_hh()..self.off_bh()],
            b_h: &p[self.off_bh()..self.off_ho()],
            w_ho: &p[self.off_ho()..self.off_bo()],
            b_o: p[self.off_bo()],
        }
    }

    /// One step in normalized units: `h_next = tanh(W_ih·input + W_hh·h + b_h)`, returns
    /// `y = W_ho·h_next + b_o`. This is `rths-core`'s [`rths_core::metamodel::elman_step`], the
    /// controller's own forward pass, so training optimizes exactly the function the firmware runs.
    pub fn step_normalized(&self, h: &[f64], input: [f64; N_IN], h_next: &mut [f64]) -> f64 {
        rths_core::metamodel::elman_step(&self.core_weights(), h, &input, h_next)
    }

    /// One step in physical units: `x̂(i+1)` (mm) from `ü_g(i)` (mm/s²) and `F_fb(i)` (kN); `h` is
    /// updated in place (`scratch` must have H elements).
    pub fn step(
        &self,
        h: &mut [f64],
        scratch: &mut [f64],
        ground_accel_mm_s2: f64,
        force_fb_kn: f64,
    ) -> f64 {
        let s = &self.scaling;
        let input = [
            (ground_accel_mm_s2 - s.input_mean[0]) / s.input_std[0],
            (force_fb_kn - s.input_mean[1]) / s.input_std[1],
        ];
        let y = self.step_normalized(h, input, scratch);
        h.copy_from_slice(scratch);
        y * s.output_std + s.output_mean
    }

    /// Loss (mean squared error over the window, normalized units) from initial state `h0`, with its
    /// gradient added to `grad`. `hs` receives the hidden states (the last `H` values are the final
    /// state).
    fn window_grad(
        &self,
        h0: &[f64],
        inputs: &mut [[f64; N_IN]],
        targets: &[f64],
        grad: &mut [f64],
        hs: &mut Vec<f64>,
        mut own: Option<&mut OwnFeedback<'_>>,
    ) -> f64 {
        let n = self.hidden;
        let w = inputs.len();
        hs.clear();
        hs.extend_from_slice(h0);
        hs.resize((w + 1) * n, 0.0);
        let mut ys = Vec::with_capacity(w);
        let sc = self.scaling;
        for t in 0..w {
            if let Some(fb) = own.as_deref_mut() {
                let i = fb.start + t;
                let x_fb = if i >= fb.delay {
                    fb.preds[i - fb.delay]
                } else {
                    0.0
                };
                inputs[t][1] = (fb.k_b * x_fb - sc.input_mean[1]) / sc.input_std[1];
            }
            let (prev, next) = hs.split_at_mut((t + 1) * n);
            let y = self.step_normalized(&prev[t * n..], inputs[t], &mut next[..n]);
            if let Some(fb) = own.as_deref_mut() {
                fb.preds[fb.start + t + 1] = y * sc.output_std + sc.output_mean;
            }
            ys.push(y);
        }
        let p = &self.params;
        let (hh, bh, ho, bo) = (self.off_hh(), self.off_bh(), self.off_ho(), self.off_bo());
        let inv_w = 1.0 / w as f64;
        let mut loss = 0.0;
        let mut dh_next = vec![0.0; n];
        let mut da = vec![0.0; n];
        for t in (0..w).rev() {
            let e = ys[t] - targets[t];
            loss += e * e;
            let dy = 2.0 * e * inv_w;
            let h_t = &hs[(t + 1) * n..(t + 2) * n];
            let h_p = &hs[t * n..(t + 1) * n];
            grad[bo] += dy;
            for j in 0..n {
                grad[ho + j] += dy * h_t[j];
                let dh = p[ho + j] * dy + dh_next[j];
                da[j] = dh * (1.0 - h_t[j] * h_t[j]);
            }
            for j in 0..n {
                let a = da[j];
                grad[N_IN * j] += a * inputs[t][0];
                grad[N_IN * j + 1] += a * inputs[t][1];
                for k in 0..n {
                    grad[hh + j * n + k] += a * h_p[k];
                }
                grad[bh + j] += a;
            }
            for (k, d) in dh_next.iter_mut().enumerate() {
                *d = (0..n).map(|j| p[hh + j * n + k] * da[j]).sum();
            }
        }
        loss * inv_w
    }

    /// Weights for a model file.
    pub fn to_weights(&self) -> RnnWeights {
        let n = self.hidden;
        let p = &self.params;
        RnnWeights {
            hidden: n,
            w_ih: (0..n)
                .map(|j| p[N_IN * j..N_IN * (j + 1)].to_vec())
                .collect(),
            w_hh: (0..n)
                .map(|j| p[self.off_hh() + j * n..self.off_hh() + (j + 1) * n].to_vec())
                .collect(),
            b_h: p[self.off_bh()..self.off_ho()].to_vec(),
            w_ho: p[self.off_ho()..self.off_bo()].to_vec(),
            b_o: p[self.off_bo()],
            input_mean: self.scaling.input_mean.to_vec(),
            input_std: self.scaling.input_std.to_vec(),
            output_mean: self.scaling.output_mean,
            output_std: self.scaling.output_std,
        }
    }

    /// From validated model-file weights.
    pub fn from_weights(w: &RnnWeights) -> Result<Self, ModelFileError> {
        w.validate()?;
        let mut params = Vec::with_capacity(Self::n_params(w.hidden));
        w.w_ih.iter().for_each(|r| params.extend_from_slice(r));
        w.w_hh.iter().for_each(|r| params.extend_from_slice(r));
        params.extend_from_slice(&w.b_h);
        params.extend_from_slice(&w.w_ho);
        params.push(w.b_o);
        let pair = |v: &[f64]| [v[0], v[1]];
        Ok(Self {
            hidden: w.hidden,
            params,
            scaling: Scaling {
                input_mean: pair(&w.input_mean),
                input_std: pair(&w.input_std),
                output_mean: w.output_mean,
                output_std: w.output_std,
            },
        })
    }
}

/// Closed-loop feedback during training: `F_fb(i) = k_b·x̂(i − delay)` from the model's own
/// predictions (`preds[i]` = x̂(i), mm, `preds[0] = 0`), treated as a constant input by the gradient.
struct OwnFeedback<'a> {
    preds: &'a mut [f64],
    start: usize,
    delay: usize,
    k_b: f64,
}

/// Default hidden-state scale ε of the ARX realization: the states stay below ~5e-3 in magnitude
/// (|x|/σ_x ≲ 5), where tanh is linear to ~1e-5 relative.
pub const DEFAULT_ARX_STATE_SCALE: f64 = 1e-3;

/// How the RNN weights start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum InitMethod {
    /// Data-driven: the least-squares ARX model of the training response realized as an RNN
    /// ([`Rnn::from_arx`]), spare units small random.
    #[default]
    Arx,
    /// Seeded random weights ([`Rnn::random`]).
    Random,
}

/// Training settings.
#[derive(Debug, Clone, PartialEq)]
pub struct RnnConfig {
    /// Hidden size H (1..=32).
    pub hidden: usize,
    /// Feedback delay, steps.
    pub delay_steps: usize,
    /// RNG seed of the initial weights.
    pub seed: u64,
    /// Maximum number of epochs.
    pub max_epochs: usize,
    /// Truncated-BPTT window, steps.
    pub window_steps: usize,
    /// Every this-many-th window is a validation window (≥ 2).
    pub validation_every: usize,
    /// Early stopping: epochs without validation improvement.
    pub patience: usize,
    /// Adam learning rate.
    pub learning_rate: f64,
    /// Gradient clipping: largest global gradient norm per step.
    pub clip_norm: f64,
    /// Epochs of teacher forcing (true delayed force) before switching to the model's own delayed
    /// prediction as feedback (`usize::MAX`: teacher forcing throughout).
    pub teacher_epochs: usize,
    /// How the weights start.
    pub init_method: InitMethod,
    /// Random initial weights (with [`InitMethod::Random`]).
    pub init: RnnInit,
    /// Hidden-state scale ε of the ARX realization (see [`Rnn::from_arx`]).
    pub arx_state_scale: f64,
    /// Relative singular-value cut-off of the ARX least squares (see [`super::lr::solve`]).
    pub arx_rcond: f64,
    /// No progress bar.
    pub quiet: bool,
}

impl RnnConfig {
    /// Defaults for hidden size `hidden` with the ARX initialization (see `notes/train.md` for how
    /// they were chosen): windows of 8192 steps (4 s, longer than the ≈ 2.3 s the structure takes
    /// to forget at 2 % damping, so the truncated gradient sees the slow modes), relative Adam
    /// steps of 1e-9 (the recurrent weights fix the 3.4 Hz pole in their fifth digit), 100 epochs.
    pub fn new(hidden: usize) -> Self {
        Self {
            hidden,
            delay_steps: rths_core::params::PAPER_DELAY_STEPS,
            seed: 1,
            max_epochs: 100,
            window_steps: 8192,
            validation_every: 5,
            patience: 40,
            learning_rate: 1e-9,
            clip_norm: 1.0,
            teacher_epochs: usize::MAX,
            init_method: InitMethod::Arx,
            init: RnnInit::default(),
            arx_state_scale: DEFAULT_ARX_STATE_SCALE,
            arx_rcond: super::lr::DEFAULT_RCOND,
            quiet: false,
        }
    }

    /// Defaults with seeded random initial weights (training from scratch; see `notes/train.md`:
    /// it does not reach the paper's accuracy in closed loop).
    pub fn random_init(hidden: usize) -> Self {
        Self {
            max_epochs: 400,
            window_steps: 1024,
            patience: 60,
            learning_rate: 1e-3,
            init_method: InitMethod::Random,
            ..Self::new(hidden)
        }
    }
}

/// Result of a training run.
#[derive(Debug, Clone, PartialEq)]
pub struct RnnTraining {
    /// The best model (lowest validation loss).
    pub model: Rnn,
    /// Epochs run.
    pub epochs: usize,
    /// Epoch (1-based) of the best validation loss.
    pub best_epoch: usize,
    /// Best validation loss (normalized MSE).
    pub best_validation_loss: f64,
    /// (train, validation) loss per epoch.
    pub history: Vec<(f64, f64)>,
    /// NRMSE (%) of the teacher-forced predictions over the whole record.
    pub train_nrmse_pct: f64,
    /// NRMSE (%) of `rnn-pure` on the training motion.
    pub pure_nrmse_pct: f64,
    /// NRMSE (%) of `rnn-pure` of the initial weights, before any gradient step.
    pub init_pure_nrmse_pct: f64,
    /// Wall time of the training, s.
    pub wall_time_s: f64,
}

/// Teacher-forced inputs `[ü_g(i), N(i − delay)]` and targets `d(i+1)`, i = 0..n−1 (raw units).
fn teacher_forced(resp: &PureResponse, delay: usize) -> (Vec<[f64; N_IN]>, Vec<f64>) {
    let f_fb = delayed(&resp.brace_force_kn, delay);
    let n = resp.len().saturating_sub(1);
    let inputs = (0..n)
        .map(|i| [resp.ground_accel_mm_s2[i], f_fb[i]])
        .collect();
    let targets = resp.brace_disp_mm[1..].to_vec();
    (inputs, targets)
}

/// Run the model over raw inputs from rest; returns `x̂(i+1)` for each input row.
fn run_teacher_forced(model: &Rnn, inputs: &[[f64; N_IN]]) -> Vec<f64> {
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

/// Per-parameter step scales. Adam moves every parameter by about the learning rate whatever its
/// magnitude; the ARX realization mixes weights of order 1/ε, 1 and ε·1e-4, and its recurrent
/// weights carry the pole radius 1 − 2e-4 in their fifth digit, so its steps are made relative to
/// each weight's magnitude (the largest in its group where the weight is zero, times 1e-2).
fn step_scales(model: &Rnn, method: InitMethod) -> Vec<f64> {
    let p = &model.params;
    if method == InitMethod::Random {
        return vec![1.0; p.len()];
    }
    let groups = [
        0..model.off_hh(),
        model.off_hh()..model.off_bh(),
        model.off_bh()..model.off_ho(),
        model.off_ho()..model.off_bo(),
        model.off_bo()..p.len(),
    ];
    let mut out = vec![0.0; p.len()];
    for g in groups {
        let top = p[g.clone()].iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        let floor = if top > 0.0 { 1e-2 * top } else { 1e-2 };
        for i in g {
            out[i] = p[i].abs().max(floor);
        }
    }
    out
}

struct Adam {
    m: Vec<f64>,
    v: Vec<f64>,
    t: i32,
}

impl Adam {
    /// One Adam step; parameter `i` moves by about `lr·scale[i]`.
    fn step(&mut self, params: &mut [f64], grad: &[f64], lr: f64, scale: &[f64]) {
        const B1: f64 = 0.9;
        const B2: f64 = 0.999;
        self.t += 1;
        let c1 = 1.0 - B1.powi(self.t);
        let c2 = 1.0 - B2.powi(self.t);
        for i in 0..params.len() {
            self.m[i] = B1 * self.m[i] + (1.0 - B1) * grad[i];
            self.v[i] = B2 * self.v[i] + (1.0 - B2) * grad[i] * grad[i];
            params[i] -= lr * scale[i] * (self.m[i] / c1) / ((self.v[i] / c2).sqrt() + 1e-8);
        }
    }
}

fn progress(epochs: usize, quiet: bool) -> indicatif::ProgressBar {
    if quiet || !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(epochs as u64);
    if let Ok(style) =
        indicatif::ProgressStyle::with_template("{bar:30} epoch {pos}/{len} {msg} [{elapsed}]")
    {
        bar.set_style(style);
    }
    bar
}

/// Train an RNN on the pure response (phase 1, teacher forcing) and score it.
pub fn train(
    response: &PureResponse,
    brace_k_kn_per_mm: f64,
    cfg: &RnnConfig,
) -> Result<RnnTraining, TrainError> {
    let start = Instant::now();
    if cfg.window_steps == 0 || cfg.validation_every < 2 {
        return Err(TrainError::Setting(
            "window_steps ≥ 1 and validation_every ≥ 2 are required".into(),
        ));
    }
    if !(cfg.learning_rate > 0.0 && cfg.learning_rate.is_finite() && cfg.clip_norm > 0.0) {
        return Err(TrainError::Setting(
            "learning rate and clip norm must be > 0".into(),
        ));
    }
    let needed = cfg.window_steps * cfg.validation_every + 1;
    if response.len() < needed {
        return Err(TrainError::TooShort {
            found: response.len(),
            needed,
        });
    }
    let (raw_in, raw_out) = teacher_forced(response, cfg.delay_steps);
    let (m0, s0) = mean_std(raw_in.iter().map(|u| u[0]));
    let (m1, s1) = mean_std(raw_in.iter().map(|u| u[1]));
    let (mo, so) = mean_std(raw_out.iter().copied());
    let scaling = Scaling {
        input_mean: [m0, m1],
        input_std: [s0, s1],
        output_mean: mo,
        output_std: so,
    };
    let inputs: Vec<[f64; N_IN]> = raw_in
        .iter()
        .map(|u| [(u[0] - m0) / s0, (u[1] - m1) / s1])
        .collect();
    let targets: Vec<f64> = raw_out.iter().map(|y| (y - mo) / so).collect();

    let mut model = match cfg.init_method {
        InitMethod::Random => Rnn::random(cfg.hidden, scaling, cfg.seed, &cfg.init)?,
        InitMethod::Arx => {
            let fit =
                super::lr::fit_pure(response, cfg.delay_steps, brace_k_kn_per_mm, cfg.arx_rcond)?;
            Rnn::from_arx(
                cfg.hidden,
                scaling,
                &fit.solution.theta,
                brace_k_kn_per_mm,
                cfg.arx_state_scale,
                cfg.seed,
            )?
        }
    };
    let init_pure_nrmse_pct =
        rnn_pure_nrmse_pct(&model, response, cfg.delay_steps, brace_k_kn_per_mm)?;
    let lr_scale = step_scales(&model, cfg.init_method);
    let np = model.params.len();
    let mut adam = Adam {
        m: vec![0.0; np],
        v: vec![0.0; np],
        t: 0,
    };
    let n = cfg.hidden;
    let mut grad = vec![0.0; np];
    let mut hs = Vec::new();
    let mut h = vec![0.0; n];
    let mut best = (f64::INFINITY, 0, model.clone());
    let mut history = Vec::new();
    let bar = progress(cfg.max_epochs, cfg.quiet);
    let mut epochs = 0;
    let mut preds = vec![0.0; inputs.len() + 1];
    let mut win = Vec::with_capacity(cfg.window_steps);
    // Epoch 0 only evaluates the initial weights, so they stay the result unless training improves
    // on them.
    for epoch in 0..=cfg.max_epochs {
        epochs = epoch;
        let closed = cfg.teacher_epochs == 0 || epoch > cfg.teacher_epochs;
        if closed && cfg.teacher_epochs > 0 && epoch == cfg.teacher_epochs + 1 {
            // The loss changes meaning: restart the early-stopping record.
            best = (f64::INFINITY, epoch, model.clone());
        }
        h.iter_mut().for_each(|v| *v = 0.0);
        preds.iter_mut().for_each(|v| *v = 0.0);
        let (mut train_sum, mut train_n, mut val_sum, mut val_n) = (0.0, 0usize, 0.0, 0usize);
        for (w, (inp, tgt)) in inputs
            .chunks(cfg.window_steps)
            .zip(targets.chunks(cfg.window_steps))
            .enumerate()
        {
            grad.iter_mut().for_each(|g| *g = 0.0);
            win.clear();
            win.extend_from_slice(inp);
            let mut fb = OwnFeedback {
                preds: &mut preds,
                start: w * cfg.window_steps,
                delay: cfg.delay_steps,
                k_b: brace_k_kn_per_mm,
            };
            let own = if closed { Some(&mut fb) } else { None };
            let loss = model.window_grad(&h, &mut win, tgt, &mut grad, &mut hs, own);
            h.copy_from_slice(&hs[hs.len() - n..]);
            if w % cfg.validation_every == cfg.validation_every - 1 {
                val_sum += loss * inp.len() as f64;
                val_n += inp.len();
                continue;
            }
            train_sum += loss * inp.len() as f64;
            train_n += inp.len();
            if epoch == 0 {
                continue;
            }
            let norm = grad.iter().map(|g| g * g).sum::<f64>().sqrt();
            if !norm.is_finite() {
                return Err(TrainError::Diverged(format!(
                    "non-finite gradient in epoch {epoch}"
                )));
            }
            if norm > cfg.clip_norm {
                let k = cfg.clip_norm / norm;
                grad.iter_mut().for_each(|g| *g *= k);
            }
            adam.step(&mut model.params, &grad, cfg.learning_rate, &lr_scale);
        }
        let (tl, vl) = (
            train_sum / train_n.max(1) as f64,
            val_sum / val_n.max(1) as f64,
        );
        history.push((tl, vl));
        if vl < best.0 {
            best = (vl, epoch, model.clone());
        }
        bar.set_position(epoch as u64);
        bar.set_message(format!("train {tl:.2e} val {vl:.2e} best {:.2e}", best.0));
        if epoch - best.1 >= cfg.patience {
            break;
        }
    }
    bar.finish_and_clear();
    let (best_validation_loss, best_epoch, model) = best;
    if !best_validation_loss.is_finite() {
        return Err(TrainError::Diverged("validation loss never finite".into()));
    }
    let tf = run_teacher_forced(&model, &raw_in);
    let train_nrmse_pct = nrmse_pct(&tf, &raw_out)?;
    let pure_nrmse_pct = rnn_pure_nrmse_pct(&model, response, cfg.delay_steps, brace_k_kn_per_mm)?;
    Ok(RnnTraining {
        model,
        epochs,
        best_epoch,
        best_validation_loss,
        history,
        train_nrmse_pct,
        pure_nrmse_pct,
        init_pure_nrmse_pct,
        wall_time_s: start.elapsed().as_secs_f64(),
    })
}

/// The model file of a training run: weights, provenance (`motion` and its step count) and scores.
pub fn model_file(t: &RnnTraining, cfg: &RnnConfig, motion: String, records: usize) -> ModelFile {
    let mut f = ModelFile::new_rnn(
        t.model.to_weights(),
        cfg.delay_steps,
        rths_core::params::DT_S,
    );
    f.training = Training {
        motion,
        records,
        phase: 1,
        method: match cfg.init_method {
            InitMethod::Arx => "arx-least-squares-init+tbptt-adam".into(),
            InitMethod::Random => "tbptt-adam".into(),
        },
        seed: Some(cfg.seed),
        epochs: Some(t.epochs),
        best_epoch: Some(t.best_epoch),
        window_steps: Some(cfg.window_steps),
        learning_rate: Some(cfg.learning_rate),
        ..Training::default()
    };
    f.scores = Scores {
        train_nrmse_pct: Some(t.train_nrmse_pct),
        pure_nrmse_pct: Some(t.pure_nrmse_pct),
        best_validation_loss: Some(t.best_validation_loss),
        ..Scores::default()
    };
    f
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::data::pure_response;
    use rths_core::params::{Prototype, DT_S};

    fn scaling() -> Scaling {
        Scaling {
            input_mean: [0.0, 0.0],
            input_std: [1.0, 1.0],
            output_mean: 0.0,
            output_std: 1.0,
        }
    }

    /// The analytic BPTT gradient agrees with central finite differences of the window loss.
    #[test]
    fn gradient_check() {
        let mut model = Rnn::random(4, scaling(), 11, &RnnInit::default()).unwrap();
        // Non-zero biases so every term is exercised.
        let (bh, bo) = (model.off_bh(), model.off_bo());
        for j in 0..4 {
            model.params[bh + j] = 0.1 * j as f64 - 0.15;
        }
        model.params[bo] = 0.2;
        let h0 = [0.3, -0.2, 0.1, 0.05];
        let inputs: Vec<[f64; 2]> = (0..25)
            .map(|t| [(0.3 * t as f64).sin(), (0.17 * t as f64).cos()])
            .collect();
        let targets: Vec<f64> = (0..25).map(|t| 0.5 * (0.21 * t as f64).sin()).collect();
        let mut grad = vec![0.0; model.params.len()];
        let mut hs = Vec::new();
        let mut inp = inputs.clone();
        model.window_grad(&h0, &mut inp, &targets, &mut grad, &mut hs, None);
        let mut scratch = vec![0.0; model.params.len()];
        let loss = |m: &Rnn, s: &mut Vec<f64>| {
            let mut hs = Vec::new();
            let mut inp = inputs.clone();
            m.window_grad(&h0, &mut inp, &targets, s, &mut hs, None)
        };
        let eps = 1e-6;
        let mut worst: f64 = 0.0;
        for (i, g) in grad.iter().enumerate() {
            let mut plus = model.clone();
            plus.params[i] += eps;
            let mut minus = model.clone();
            minus.params[i] -= eps;
            let fd = (loss(&plus, &mut scratch) - loss(&minus, &mut scratch)) / (2.0 * eps);
            let err = (fd - g).abs() / (fd.abs() + g.abs()).max(1e-6);
            worst = worst.max(err);
        }
        assert!(worst < 1e-6, "worst relative gradient error {worst}");
    }

    #[test]
    fn weights_round_trip_and_physical_step_matches_normalized() {
        let mut m = Rnn::random(5, scaling(), 2, &RnnInit::default()).unwrap();
        m.scaling = Scaling {
            input_mean: [1.0, -2.0],
            input_std: [100.0, 3.0],
            output_mean: 0.5,
            output_std: 2.0,
        };
        let back = Rnn::from_weights(&m.to_weights()).unwrap();
        assert_eq!(back, m);
        let (mut h, mut s) = (vec![0.0; 5], vec![0.0; 5]);
        let x = m.step(&mut h, &mut s, 201.0, 1.0);
        let mut h2 = vec![0.0; 5];
        let y = m.step_normalized(&[0.0; 5], [2.0, 1.0], &mut h2);
        assert_eq!(x, y * 2.0 + 0.5);
        assert_eq!(h, h2);
    }

    /// The same weights in `rths-core`'s `no_std` inference give the same bits, step after step.
    #[test]
    fn bit_identical_to_core_inference() {
        use rths_core::metamodel as core_mm;
        let mut m = Rnn::random(7, scaling(), 5, &RnnInit::default()).unwrap();
        m.scaling = Scaling {
            input_mean: [3.0, -40.0],
            input_std: [900.0, 4000.0],
            output_mean: 0.02,
            output_std: 3.3,
        };
        let p = &m.params;
        let core_params = core_mm::RnnParams::new(
            core_mm::RnnWeights {
                w_ih: &p[..m.off_hh()],
                w_hh: &p[m.off_hh()..m.off_bh()],
                b_h: &p[m.off_bh()..m.off_ho()],
                w_ho: &p[m.off_ho()..m.off_bo()],
                b_o: p[m.off_bo()],
            },
            core_mm::RnnScaling {
                input_mean: m.scaling.input_mean,
                input_std: m.scaling.input_std,
                output_mean: m.scaling.output_mean,
                output_std: m.scaling.output_std,
            },
        )
        .unwrap();
        let mut core_rnn = core_mm::Rnn::new(core_params);
        let (mut h, mut s) = (vec![0.0; 7], vec![0.0; 7]);
        for i in 0..500 {
            let ag = 2000.0 * (0.013 * i as f64).sin();
            let f = 8000.0 * (0.007 * i as f64).cos();
            let ours = m.step(&mut h, &mut s, ag, f);
            let theirs = core_rnn
                .predict(core_mm::RnnInputs {
                    ground_accel_mm_s2: ag,
                    brace_force_fb_kn: f,
                })
                .unwrap();
            assert_eq!(ours.to_bits(), theirs.to_bits(), "step {i}");
        }
    }

    fn short_response() -> PureResponse {
        // The strong first 6 s of El Centro.
        let ag = crate::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
        pure_response(&Prototype::paper(), &ag[..6 * 2048], DT_S).unwrap()
    }

    #[test]
    fn training_reduces_validation_loss_and_is_seed_reproducible() {
        let r = short_response();
        let k_b = Prototype::paper().brace_axial_stiffness_kn_per_mm();
        let mut cfg = RnnConfig::random_init(5);
        cfg.max_epochs = 8;
        cfg.quiet = true;
        let a = train(&r, k_b, &cfg).unwrap();
        let first = a.history[0].1;
        assert!(a.best_validation_loss < 0.5 * first, "{:?}", a.history);
        let b = train(&r, k_b, &cfg).unwrap();
        assert_eq!(a.model, b.model);
        assert_eq!(a.history, b.history);
        cfg.seed = 2;
        let c = train(&r, k_b, &cfg).unwrap();
        assert_ne!(a.model, c.model);
    }

    fn el_centro_response() -> PureResponse {
        let ag = crate::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
        pure_response(&Prototype::paper(), &ag, DT_S).unwrap()
    }

    /// With a tiny state scale, the ARX realization reproduces the linear model's own closed loop
    /// (`lr-pure`, an independent implementation) to rounding; with the default scale the tanh
    /// curvature costs a little accuracy, and it grows as ε² (the error is the cubic term).
    #[test]
    fn arx_realization_matches_the_linear_model() {
        let r = short_response();
        let p = Prototype::paper();
        let k_b = p.brace_axial_stiffness_kn_per_mm();
        let fit = crate::train::lr::fit_pure(&r, 28, k_b, crate::train::lr::DEFAULT_RCOND).unwrap();
        let scaling = Scaling {
            input_mean: [10.0, -3.0],
            input_std: [1500.0, 4000.0],
            output_mean: 0.01,
            output_std: 3.0,
        };
        let lr_loop = &fit.pure_prediction_mm;
        let err = |eps: f64| {
            let m = Rnn::from_arx(6, scaling, &fit.solution.theta, k_b, eps, 3).unwrap();
            let x = run_pure_loop(&m, &r.ground_accel_mm_s2, 28, k_b);
            nrmse_pct(&x, lr_loop).unwrap()
        };
        let (tiny, small, dflt) = (err(1e-6), err(1e-4), err(1e-3));
        assert!(tiny < 1e-5, "ε = 1e-6: {tiny}%");
        // Cubic term: 10× smaller ε, ~100× smaller error.
        assert!(
            small < dflt / 50.0 && dflt < 0.5,
            "ε=1e-4: {small}%, 1e-3: {dflt}%"
        );
        assert!(Rnn::from_arx(1, scaling, &fit.solution.theta, k_b, 1e-3, 3).is_err());
    }

    /// The target: `rnn-pure` (the RNN fed its own prediction 28 steps earlier) on El Centro
    /// for H = 10 at or below the paper's 3.74 % NRMSE; fine-tuning keeps or improves the
    /// initialization on held-out windows, and the run is reproducible.
    #[test]
    fn rnn_pure_el_centro_h10_meets_paper() {
        let r = el_centro_response();
        let k_b = Prototype::paper().brace_axial_stiffness_kn_per_mm();
        let mut cfg = RnnConfig::new(10);
        cfg.quiet = true;
        let t = train(&r, k_b, &cfg).unwrap();
        assert!(
            t.pure_nrmse_pct <= 3.74,
            "rnn-pure NRMSE {}%",
            t.pure_nrmse_pct
        );
        assert!(
            t.init_pure_nrmse_pct <= 3.74,
            "init {}%",
            t.init_pure_nrmse_pct
        );
        assert!(t.best_validation_loss <= t.history[0].1);
        // Recomputed independently of the training code's own figure.
        let x = run_pure_loop(&t.model, &r.ground_accel_mm_s2, 28, k_b);
        assert_eq!(nrmse_pct(&x, &r.brace_disp_mm).unwrap(), t.pure_nrmse_pct);
        cfg.max_epochs = 3;
        let a = train(&r, k_b, &cfg).unwrap();
        let b = train(&r, k_b, &cfg).unwrap();
        assert_eq!(a.model, b.model);
    }

    /// The shipped defaults `data/models/rnn-{5,10,20}.json` load, and run in the core's `no_std`
    /// inference on their own delayed prediction they meet the paper's `rnn-pure` figures on El
    /// Centro (4.23 / 3.74 / 3.88 %).
    #[test]
    fn shipped_models_meet_paper_in_core_closed_loop() {
        use crate::model_file::{ModelFile, ModelKind};
        use rths_core::metamodel as core_mm;
        let r = el_centro_response();
        let k_b = Prototype::paper().brace_axial_stiffness_kn_per_mm();
        for (h, paper) in [(5, 4.23), (10, 3.74), (20, 3.88)] {
            let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join(format!("data/models/rnn-{h}.json"));
            let f = ModelFile::load_kind(&path, ModelKind::Rnn).unwrap();
            let m = Rnn::from_weights(f.rnn.as_ref().unwrap()).unwrap();
            assert_eq!(m.hidden(), h);
            let p = &m.params;
            let params = core_mm::RnnParams::new(
                core_mm::RnnWeights {
                    w_ih: &p[..m.off_hh()],
                    w_hh: &p[m.off_hh()..m.off_bh()],
                    b_h: &p[m.off_bh()..m.off_ho()],
                    w_ho: &p[m.off_ho()..m.off_bo()],
                    b_o: p[m.off_bo()],
                },
                core_mm::RnnScaling {
                    input_mean: m.scaling.input_mean,
                    input_std: m.scaling.input_std,
                    output_mean: m.scaling.output_mean,
                    output_std: m.scaling.output_std,
                },
            )
            .unwrap();
            let mut net = core_mm::Rnn::new(params);
            let mut x = vec![0.0];
            for i in 0..r.len() - 1 {
                let fb = if i >= 28 { x[i - 28] } else { 0.0 };
                let next = net
                    .predict(core_mm::RnnInputs {
                        ground_accel_mm_s2: r.ground_accel_mm_s2[i],
                        brace_force_fb_kn: k_b * fb,
                    })
                    .unwrap();
                x.push(next);
            }
            let e = nrmse_pct(&x, &r.brace_disp_mm).unwrap();
            assert!(e <= paper, "H = {h}: rnn-pure {e}% > paper {paper}%");
        }
    }
}

//! The trainable Elman net: weights in one flat vector, their initialization (from the identified
//! ARX model, or seeded random), the input/output scaling, and the conversion to and from a model
//! file. The forward step is `rths-core`'s [`elman_step`], so training and the controller compute
//! the same function to the bit.

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rths_core::metamodel::{elman_step, RnnScaling, RNN_INPUTS};

use crate::machinery::model_file::{ModelFileError, RnnWeights, MAX_HIDDEN};
use crate::machinery::train::TrainError;

/// Number of inputs (ü_g, F_fb).
pub const N_IN: usize = RNN_INPUTS;

/// Input and output normalization: `rths-core`'s, so a trained model's scaling is the one the
/// controller applies.
pub type Scaling = RnnScaling;

/// Mean and standard deviation (population) of a series, for the scaling.
pub(super) fn mean_std(x: impl Iterator<Item = f64> + Clone) -> (f64, f64) {
    let n = x.clone().count().max(1) as f64;
    let mean = x.clone().sum::<f64>() / n;
    let var = x.map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    // A constant signal keeps a unit scale rather than dividing by zero.
    let std = if var > 0.0 { var.sqrt() } else { 1.0 };
    (mean, std)
}

/// Initial-weight distribution (see [`TrainableRnn::random`]).
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

/// Default hidden-state scale ε of the ARX realization: the states stay below ~5e-3 in magnitude
/// (|x|/σ_x ≲ 5), where tanh is linear to ~1e-5 relative.
pub const DEFAULT_ARX_STATE_SCALE: f64 = 1e-3;

/// An Elman RNN with its weights in one flat vector
/// `[w_ih (H×2, row-major), w_hh (H×H, row-major), b_h (H), w_ho (H), b_o]`.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainableRnn {
    pub(super) hidden: usize,
    pub(super) params: Vec<f64>,
    pub(super) scaling: Scaling,
}

impl TrainableRnn {
    pub(super) fn n_params(h: usize) -> usize {
        N_IN * h + h * h + h + h + 1
    }
    pub(super) fn off_hh(&self) -> usize {
        N_IN * self.hidden
    }
    pub(super) fn off_bh(&self) -> usize {
        self.off_hh() + self.hidden * self.hidden
    }
    pub(super) fn off_ho(&self) -> usize {
        self.off_bh() + self.hidden
    }
    pub(super) fn off_bo(&self) -> usize {
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
    /// θ4·x(i) + θ5·x(i−1)` (the LR metamodel's features, see [`crate::machinery::train::lr`]) realized as an Elman
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
        theta: &[f64; rths_core::metamodel::LR_COEFFS],
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
        elman_step(&self.core_weights(), h, &input, h_next)
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

//! The optimizer of the RNN training: Adam, with per-parameter step scales.

use super::model::TrainableRnn;

/// Per-parameter step scales. Adam moves every parameter by about the learning rate whatever its
/// magnitude; the ARX realization mixes weights of order 1/ε, 1 and ε·1e-4, and its recurrent
/// weights carry the pole radius 1 − 2e-4 in their fifth digit, so its steps are made relative to
/// each weight's magnitude (the largest in its group where the weight is zero, times 1e-2).
/// Without `relative` (random initial weights, all of order 1) every scale is 1.
pub(super) fn step_scales(model: &TrainableRnn, relative: bool) -> Vec<f64> {
    let p = &model.params;
    if !relative {
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

/// Adam (Kingma & Ba, β1 = 0.9, β2 = 0.999, ε = 1e-8) with per-parameter step scales.
pub(super) struct Adam {
    m: Vec<f64>,
    v: Vec<f64>,
    t: i32,
}

impl Adam {
    /// Zero moments for `n` parameters.
    pub(super) fn new(n: usize) -> Self {
        Self {
            m: vec![0.0; n],
            v: vec![0.0; n],
            t: 0,
        }
    }

    /// One Adam step; parameter `i` moves by about `lr·scale[i]`.
    pub(super) fn step(&mut self, params: &mut [f64], grad: &[f64], lr: f64, scale: &[f64]) {
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

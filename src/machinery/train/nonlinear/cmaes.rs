//! CMA-ES (Hansen's (μ/μ_w, λ) evolution strategy with rank-one and rank-μ covariance updates,
//! "The CMA Evolution Strategy: A Tutorial", 2016, default parameters) minimizing a loss over
//! ℝⁿ. The population is evaluated in parallel (rayon); every random draw is made on the calling
//! thread in a fixed order, so the same seed gives the same search bit for bit.

use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

/// The best point found and how the search went.
#[derive(Debug, Clone)]
pub struct CmaResult {
    /// The best point.
    pub best: Vec<f64>,
    /// Its loss.
    pub best_loss: f64,
    /// Generations run.
    pub generations: usize,
    /// Population size λ.
    pub population: usize,
}

/// Minimize `loss` from `x0` with step size `sigma0` for at most `generations` (λ from the
/// dimension unless `population` is given). `on_generation(g, best_loss)` reports progress.
pub fn minimize<F>(
    loss: F,
    x0: &[f64],
    sigma0: f64,
    generations: usize,
    population: Option<usize>,
    seed: u64,
    mut on_generation: impl FnMut(usize, f64),
) -> CmaResult
where
    F: Fn(&[f64]) -> f64 + Sync,
{
    let n = x0.len();
    let nf = n as f64;
    let lambda = population
        .unwrap_or(4 + (3.0 * nf.ln()).floor() as usize)
        .max(4);
    let mu = lambda / 2;
    let raw: Vec<f64> = (0..mu)
        .map(|i| ((lambda as f64 + 1.0) / 2.0).ln() - ((i + 1) as f64).ln())
        .collect();
    let sum: f64 = raw.iter().sum();
    let w: Vec<f64> = raw.iter().map(|x| x / sum).collect();
    let mueff = 1.0 / w.iter().map(|x| x * x).sum::<f64>();
    let cc = (4.0 + mueff / nf) / (nf + 4.0 + 2.0 * mueff / nf);
    let cs = (mueff + 2.0) / (nf + mueff + 5.0);
    let c1 = 2.0 / ((nf + 1.3).powi(2) + mueff);
    let cmu = (1.0 - c1).min(2.0 * (mueff - 2.0 + 1.0 / mueff) / ((nf + 2.0).powi(2) + mueff));
    let damps = 1.0 + 2.0 * (((mueff - 1.0) / (nf + 1.0)).sqrt() - 1.0).max(0.0) + cs;
    let chi_n = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));

    let mut rng = StdRng::seed_from_u64(seed);
    let mut mean = DVector::from_column_slice(x0);
    let mut sigma = sigma0;
    let mut pc = DVector::zeros(n);
    let mut ps = DVector::zeros(n);
    let mut c = DMatrix::<f64>::identity(n, n);
    let mut b = DMatrix::<f64>::identity(n, n);
    let mut d = DVector::from_element(n, 1.0);
    let mut best = x0.to_vec();
    let mut best_loss = loss(x0);
    let mut gens = 0;
    for g in 0..generations {
        gens = g + 1;
        let z: Vec<DVector<f64>> = (0..lambda)
            .map(|_| DVector::from_fn(n, |_, _| StandardNormal.sample(&mut rng)))
            .collect();
        let y: Vec<DVector<f64>> = z.iter().map(|zi| &b * d.component_mul(zi)).collect();
        let x: Vec<DVector<f64>> = y.iter().map(|yi| &mean + yi * sigma).collect();
        let f: Vec<f64> = x.par_iter().map(|xi| loss(xi.as_slice())).collect();
        let mut order: Vec<usize> = (0..lambda).collect();
        // Non-finite losses sort last (total order on f64).
        order.sort_by(|&i, &j| {
            let (a, bb) = (sanitize(f[i]), sanitize(f[j]));
            a.total_cmp(&bb).then(i.cmp(&j))
        });
        if sanitize(f[order[0]]) < best_loss {
            best_loss = sanitize(f[order[0]]);
            best = x[order[0]].as_slice().to_vec();
        }
        on_generation(gens, best_loss);
        let mut y_w = DVector::zeros(n);
        for (wi, &i) in w.iter().zip(&order) {
            y_w += &y[i] * *wi;
        }
        mean += &y_w * sigma;
        // C^(-1/2)·y_w = B·D⁻¹·Bᵀ·y_w.
        let inv_sqrt_y = &b * (b.transpose() * &y_w).component_div(&d);
        ps = &ps * (1.0 - cs) + inv_sqrt_y * (cs * (2.0 - cs) * mueff).sqrt();
        let ps_norm = ps.norm();
        let hsig = ps_norm / (1.0 - (1.0 - cs).powi(2 * gens as i32)).sqrt() / chi_n
            < 1.4 + 2.0 / (nf + 1.0);
        let hs = if hsig { 1.0 } else { 0.0 };
        pc = &pc * (1.0 - cc) + &y_w * (hs * (cc * (2.0 - cc) * mueff).sqrt());
        let mut rank_mu = DMatrix::zeros(n, n);
        for (wi, &i) in w.iter().zip(&order) {
            rank_mu += &y[i] * y[i].transpose() * *wi;
        }
        c = &c * (1.0 - c1 - cmu + (1.0 - hs) * c1 * cc * (2.0 - cc))
            + &pc * pc.transpose() * c1
            + rank_mu * cmu;
        sigma *= ((cs / damps) * (ps_norm / chi_n - 1.0)).exp();
        // Keep C symmetric, then its eigendecomposition C = B·D²·Bᵀ.
        c = (&c + c.transpose()) * 0.5;
        let eig = c.clone().symmetric_eigen();
        b = eig.eigenvectors;
        d = eig.eigenvalues.map(|e| e.max(1e-20).sqrt());
        if sigma * d.max() < 1e-9 {
            break;
        }
    }
    CmaResult {
        best,
        best_loss,
        generations: gens,
        population: lambda,
    }
}

fn sanitize(v: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        f64::MAX
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_minimum_of_a_rotated_ellipsoid_and_repeats_with_the_seed() {
        let f = |x: &[f64]| {
            let (a, b) = (x[0] + x[1] - 2.0, x[0] - x[1]);
            a * a + 100.0 * b * b + (x[2] - 0.5).powi(2)
        };
        let r = minimize(f, &[3.0, -2.0, 4.0], 1.0, 400, None, 7, |_, _| {});
        assert!(r.best_loss < 1e-10, "{}", r.best_loss);
        assert!((r.best[0] - 1.0).abs() < 1e-4 && (r.best[2] - 0.5).abs() < 1e-4);
        let again = minimize(f, &[3.0, -2.0, 4.0], 1.0, 400, None, 7, |_, _| {});
        assert_eq!(r.best, again.best);
    }
}

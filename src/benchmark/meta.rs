//! A fixed-order metamodel of the numerical substructure at the specimen's DOF (host prototype):
//! an ARX model in backward-difference (delta) form, trained from the numerical model alone.
//!
//! `d(k+1) − d(k) = Σ_j a_j·Δʲd(k) + Σ_j b_j·Δʲü_g(k) + Σ_j c_j·ΔʲF̃(k)`, j < [`META_ORDER`], with
//! `Δʲ` the j-th backward difference. An exact input-output model of an N-DOF part at one DOF has
//! order 2N, so order 6 is exact for the benchmark's 3 stories (Chang's step is a linear map); at
//! 4096 Hz the AR roots cluster near z = 1 and a shift-form fit is ill-conditioned, which the delta
//! basis (with column scaling) avoids. Per tick it costs 3·[`META_ORDER`] multiply-adds plus the
//! differences, whatever N is.
//!
//! Training sees only the structure file: the numerical part is simulated (Chang) under two records
//! the benchmark does not score (`northridge`, `loma-prieta`), its specimen force being the nominal
//! linear specimen at the model's own displacement plus a band-limited random force (so the force
//! columns are identifiable). No plant, no record it is scored on.

use anyhow::Context;
use nalgebra::{DMatrix, DVector};
use rths_core::structure_n::{ChangN, MAX_DOF};
use rths_files::structure_file::Structure;

use super::DT_S;
use crate::motion::GroundMotion;

/// Lags of each input (and of the output).
pub const META_ORDER: usize = 6;
const COEFFS: usize = 3 * META_ORDER;

/// `Δʲs(k)`, j < [`META_ORDER`], from `h[i] = s(k − i)`.
fn deltas(h: &[f64; META_ORDER]) -> [f64; META_ORDER] {
    let mut out = [0.0; META_ORDER];
    let mut row = *h;
    for o in out.iter_mut() {
        *o = row[0];
        // Next order: Δs(k − i) = s(k − i) − s(k − i − 1).
        for i in 0..META_ORDER - 1 {
            row[i] -= row[i + 1];
        }
        row[META_ORDER - 1] = 0.0;
    }
    out
}

fn push(h: &mut [f64; META_ORDER], v: f64) {
    h.copy_within(0..META_ORDER - 1, 1);
    h[0] = v;
}

/// A trained metamodel.
#[derive(Debug, Clone, PartialEq)]
pub struct Meta {
    theta: [f64; COEFFS],
    disp: [f64; META_ORDER],
    ag: [f64; META_ORDER],
    force: [f64; META_ORDER],
}

impl Meta {
    fn features(&self) -> [f64; COEFFS] {
        let mut phi = [0.0; COEFFS];
        for (chunk, h) in phi
            .chunks_mut(META_ORDER)
            .zip([&self.disp, &self.ag, &self.force])
        {
            chunk.copy_from_slice(&deltas(h));
        }
        phi
    }

    /// Tick k: the own displacement d(k) is the last prediction; take ü_g(k) and the (corrected)
    /// force F̃(k), return d(k+1).
    pub fn step(&mut self, ag_mm_s2: f64, force_kn: f64) -> f64 {
        push(&mut self.ag, ag_mm_s2);
        push(&mut self.force, force_kn);
        let phi = self.features();
        let inc: f64 = phi.iter().zip(&self.theta).map(|(p, t)| p * t).sum();
        let next = self.disp[0] + inc;
        push(&mut self.disp, next);
        next
    }

    /// The displacement of the current tick, mm.
    pub fn current_mm(&self) -> f64 {
        self.disp[0]
    }
}

/// A smooth random force, kN: a sum of sines with random phases from 0.5 to 40 Hz.
fn random_force(k: usize, amp_kn: f64, phases: &[(f64, f64)]) -> f64 {
    let t = k as f64 * DT_S;
    let s: f64 = phases
        .iter()
        .map(|(f, p)| (2.0 * std::f64::consts::PI * f * t + p).sin())
        .sum();
    amp_kn * s / (phases.len() as f64).sqrt()
}

/// Train for `structure` (numerical part at its specimen DOF) at `intensity`.
pub fn train(structure: &Structure, intensity: f64) -> anyhow::Result<Meta> {
    let dof = structure.specimen_dof();
    let (_, k_e, _) = structure.specimen();
    let mut rows: Vec<[f64; COEFFS]> = Vec::new();
    let mut ys: Vec<f64> = Vec::new();
    // Deterministic phases (a fixed LCG): reproducible training.
    let mut seed: u64 = 0x5eed;
    let mut rnd = move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for name in ["northridge", "loma-prieta"] {
        let ag = GroundMotion::try_embedded(name)
            .with_context(|| format!("training record {name}"))?
            .scaled(intensity)
            .resample_mm_s2(DT_S);
        let phases: Vec<(f64, f64)> = (0..40)
            .map(|i| (0.5 + i as f64, 2.0 * std::f64::consts::PI * rnd()))
            .collect();
        let mut integ = ChangN::new(structure.numerical()?, DT_S)?;
        let mut m = Meta {
            theta: [0.0; COEFFS],
            disp: [0.0; META_ORDER],
            ag: [0.0; META_ORDER],
            force: [0.0; META_ORDER],
        };
        for (k, &a) in ag.iter().enumerate() {
            let d_k = if k == 0 {
                0.0
            } else {
                integ.next_displacement()[dof]
            };
            let f = k_e * d_k + random_force(k, 0.5, &phases);
            if k == 0 {
                integ.reset(a);
            } else {
                let mut r = [0.0; MAX_DOF];
                r[dof] = f;
                integ.advance(a, &r);
            }
            push(&mut m.ag, a);
            push(&mut m.force, f);
            push(&mut m.disp, integ.disp()[dof]);
            if k >= META_ORDER {
                rows.push(m.features());
                ys.push(integ.next_displacement()[dof] - integ.disp()[dof]);
            }
        }
    }
    // Scale every column to unit RMS, solve by SVD, unscale.
    let n = rows.len();
    let mut scale = [0.0; COEFFS];
    for (j, s) in scale.iter_mut().enumerate() {
        let ms = rows.iter().map(|r| r[j] * r[j]).sum::<f64>() / n as f64;
        *s = if ms > 0.0 { ms.sqrt() } else { 1.0 };
    }
    let a = DMatrix::from_fn(n, COEFFS, |i, j| rows[i][j] / scale[j]);
    let y = DVector::from_vec(ys);
    let svd = a.svd(true, true);
    let sol = svd
        .solve(&y, 1e-13)
        .map_err(|e| anyhow::anyhow!("metamodel least squares: {e}"))?;
    let mut theta = [0.0; COEFFS];
    for (j, t) in theta.iter_mut().enumerate() {
        *t = sol[j] / scale[j];
    }
    Ok(Meta {
        theta,
        disp: [0.0; META_ORDER],
        ag: [0.0; META_ORDER],
        force: [0.0; META_ORDER],
    })
}

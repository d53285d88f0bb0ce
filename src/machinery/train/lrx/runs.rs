//! The identification runs of the LRX training: frame runs with a brace force that varies
//! independently of the displacement (band-limited random perturbations), and open-loop runs of the
//! virtual plant.

use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};
use rths_core::filter::{Butterworth, ButterworthParams};
use rths_core::hal::Actuator;
use rths_core::integrator::{Chang, ExplicitIntegrator};
use rths_core::params::{Prototype, DT_S};
use rths_core::structure::{LinearStructure, Vector};
use rths_hal_sim::{Preset, Specimen, VirtualRig};

use crate::machinery::train::TrainError;

/// One frame run: (brace deformation d(i), brace force F(i)) for i = 0..n, prototype units. The
/// brace force is `factor·k_b·d + p(i)` with `p` the given perturbation (p(0) is ignored: at rest).
pub fn frame_run(
    ag_mm_s2: &[f64],
    factor: f64,
    perturbation_kn: &[f64],
) -> Result<(Vec<f64>, Vec<f64>), TrainError> {
    let proto = Prototype::paper();
    let k = factor * proto.brace_axial_stiffness_kn_per_mm();
    let mut ch = Chang::new(LinearStructure::prototype_hybrid(&proto)?, DT_S)?;
    let n = ag_mm_s2.len();
    let (mut d, mut f) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for (i, &ag) in ag_mm_s2.iter().enumerate() {
        if i == 0 {
            ch.reset(ag);
            d.push(0.0);
            f.push(0.0);
            continue;
        }
        let di = proto.brace_disp_mm(ch.next_displacement()[0]);
        let fi = k * di + perturbation_kn.get(i).copied().unwrap_or(0.0);
        ch.advance(ag, &Vector::<1>::new(proto.story_force_kn(fi)));
        d.push(di);
        f.push(fi);
    }
    Ok((d, f))
}

/// Like [`frame_run`], but the reference discretization: the whole structure (frame and a linear
/// brace of `factor`·k_b) by Newmark's average-acceleration method, with the perturbation as an
/// external brace force (known at every step, so the implicit method applies); the frame's damping
/// coefficient is the paper's ([`crate::machinery::reference::specimen_prototype`]). This is the discretization
/// the pure FE reference has (Chang's method equals it when its initial stiffness is the true one;
/// the hybrid Chang, whose initial stiffness is the paper's brace, departs from it by 3e-3% NRMSE at
/// F = 0.6 on El Centro, the ARX fitted on these runs by 6e-4%).
pub fn frame_run_exact(
    ag_mm_s2: &[f64],
    factor: f64,
    perturbation_kn: &[f64],
) -> Result<(Vec<f64>, Vec<f64>), TrainError> {
    let proto = crate::machinery::reference::specimen_prototype(factor)?;
    let (m, c, k) = (
        proto.mass_kn_s2_per_mm(),
        proto.damping_kn_s_per_mm(),
        proto.total_stiffness_kn_per_mm(),
    );
    let dt = DT_S;
    let p = |i: usize| perturbation_kn.get(i).copied().unwrap_or(0.0);
    let load = |i: usize, ag: f64| -m * ag - proto.story_force_kn(if i == 0 { 0.0 } else { p(i) });
    let n = ag_mm_s2.len();
    let (mut d, mut f) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let (mut x, mut v) = (0.0, 0.0);
    let mut a = ag_mm_s2.first().map_or(0.0, |g| load(0, *g) / m);
    let keff = k + 2.0 * c / dt + 4.0 * m / (dt * dt);
    for (i, &ag) in ag_mm_s2.iter().enumerate() {
        if i > 0 {
            let rhs =
                load(i, ag) + m * (4.0 * x / (dt * dt) + 4.0 * v / dt + a) + c * (2.0 * x / dt + v);
            let xn = rhs / keff;
            let vn = 2.0 * (xn - x) / dt - v;
            a = 4.0 * (xn - x) / (dt * dt) - 4.0 * v / dt - a;
            x = xn;
            v = vn;
        }
        let di = proto.brace_disp_mm(x);
        d.push(di);
        f.push(proto.brace_force_kn(di) + if i == 0 { 0.0 } else { p(i) });
    }
    Ok((d, f))
}

/// Gaussian noise through a 6th-order 10 Hz Butterworth low-pass, scaled to RMS `rms`.
pub(super) fn band_limited_noise(
    n: usize,
    rms: f64,
    rng: &mut StdRng,
) -> Result<Vec<f64>, TrainError> {
    let mut filt = Butterworth::new(ButterworthParams::new(6, 10.0, 1.0 / DT_S)?);
    let raw: Vec<f64> = (0..n)
        .map(|_| {
            let w: f64 = StandardNormal.sample(rng);
            filt.step(w).unwrap_or(0.0)
        })
        .collect();
    let r = rms_of(&raw);
    Ok(raw.iter().map(|v| v * rms / r.max(1e-300)).collect())
}

/// Root mean square (0 for an empty series).
pub(super) fn rms_of(x: &[f64]) -> f64 {
    (x.iter().map(|v| v * v).sum::<f64>() / x.len().max(1) as f64).sqrt()
}

/// Open-loop plant run: command the pure brace response `cmd_mm` (specimen scale), return the
/// command in force at each tick and the true actuator displacement then.
pub fn plant_run(
    preset: Preset,
    specimen: Specimen,
    factor: f64,
    seed: u64,
    cmd_mm: &[f64],
) -> Result<(Vec<f64>, Vec<f64>), TrainError> {
    let cfg = crate::machinery::reference::rig_config(preset, specimen, factor, seed);
    let params = cfg
        .build()
        .map_err(|e| TrainError::Setting(format!("plant: {e}")))?;
    let mut rig = VirtualRig::new(params);
    let n = cmd_mm.len();
    let (mut u, mut x) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut held = 0.0;
    for k in 0..n {
        u.push(held);
        x.push(rig.true_disp_mm());
        held = cmd_mm.get(k + 1).copied().unwrap_or(0.0);
        // A clip is reported as an error but applied; the record shows what the plant did.
        let _ = rig.command(held);
        rig.advance_tick();
    }
    Ok((u, x))
}

//! Refinement of the floor-hysteron form on the simulation error (docs/nonlinear.md "The
//! floor-hysteron form"): the least-squares fit ([`super::hysteron::fit`]) matches the restoring
//! force recovered by equilibrium, which is not what the model is judged on; here the weights of
//! every hysteron of the basis (and, with [`RefineConfig::elastic`], a scale of the elastic
//! stiffness and one of the damping) are moved to minimize the pure loop's error over the training
//! histories: every floor's displacement and each story's residual drift at the end of each run.
//!
//! Levenberg–Marquardt: the Jacobian of the residuals by forward differences, every perturbed
//! model run in lockstep with the nominal one along each history (the runs on all cores with
//! rayon; each run's normal equations summed in the runs' order, so the same histories give the
//! same bytes), Marquardt's diagonal scaling, and a projection after each step onto the admissible
//! weights (non-negative, each direction's sum under its cap: the fully yielded tangent keeps
//! [`super::hysteron::MIN_TANGENT_FRACTION`] of the stiffness, so every model tried is one core
//! accepts). It stops on the validation histories (held out of the fit): the weights of the
//! lowest validation loss are kept, and the search ends after [`RefineConfig::patience`] steps
//! without a better one.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use rths_core::metamodel::{FloorHysteron, FloorHysteronParams, HysteronOperator};

use super::floors::{residual_drifts, FloorModel, FloorRun};
use super::hysteron::{self, HysteronFit, MIN_TANGENT_FRACTION};
use crate::machinery::train::TrainError;
use rths_files::history::RecorderUnits;
use rths_files::hysteron_model_file::HysteronSpec;
use std::path::Path;

/// The refinement's name in the model file's method.
pub const REFINE_METHOD: &str = "levenberg-marquardt";

/// How to refine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefineConfig {
    /// Levenberg–Marquardt steps at most.
    pub max_iterations: usize,
    /// Steps without a lower validation loss before the search stops.
    pub patience: usize,
    /// Weight of the residual-drift term against the floors' NRMSE.
    pub residual_weight: f64,
    /// The residuals sample every this many steps (the floors' error; the residual drift uses
    /// every step of its window).
    pub every: usize,
    /// Refine a scale of the elastic stiffness and one of the damping too.
    pub elastic: bool,
}

impl Default for RefineConfig {
    fn default() -> Self {
        Self {
            max_iterations: 30,
            patience: 3,
            residual_weight: RESIDUAL_WEIGHT,
            every: 4,
            elastic: true,
        }
    }
}

/// Default weight of the residual-drift term.
pub const RESIDUAL_WEIGHT: f64 = 0.3;
/// A story's residual-drift error is taken relative to the larger of its reference residual and
/// this fraction of its peak drift (a run that comes to rest near zero is not judged on noise).
pub const RESIDUAL_FLOOR: f64 = 0.05;
/// Bounds of the log stiffness scale and the log damping scale.
const LN_STIFFNESS_BOUND: f64 = 0.3;
const LN_DAMPING_BOUND: f64 = 1.5;
/// Relative forward-difference step of a weight, and its floor as a fraction of its direction's
/// stiffness share; the step of a log scale.
const FD_REL: f64 = 1e-3;
const FD_FLOOR: f64 = 1e-5;
const FD_LOG: f64 = 1e-4;

/// The basis the refinement moves: every candidate hysteron (weight 0 included).
#[derive(Debug, Clone)]
pub struct Basis {
    /// The hysterons' operator.
    pub operator: HysteronOperator,
    /// The threshold range.
    pub range: (f64, f64),
    /// The directions (one number per floor).
    pub directions: Vec<Vec<f64>>,
    /// Each direction's share of the stiffness.
    pub kappa: Vec<f64>,
    /// Every candidate: (direction, threshold mm).
    pub grid: Vec<(usize, f64)>,
}

/// What the refinement did.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineReport {
    /// Accepted steps.
    pub iterations: usize,
    /// The step whose weights were kept (0: the least-squares start).
    pub best_iteration: usize,
    /// Training loss (see [`loss_of`]) before and after (of the kept weights).
    pub fit_loss_start: f64,
    /// See above.
    pub fit_loss_end: f64,
    /// Validation loss before and of the kept weights (`None`: no validation histories).
    pub val_loss_start: Option<f64>,
    /// See above.
    pub val_loss_end: Option<f64>,
    /// The elastic stiffness and damping scales kept.
    pub stiffness_scale: f64,
    /// See above.
    pub damping_scale: f64,
    /// Why it stopped.
    pub stopped: String,
}

/// The parameters θ = `[ln s_K, ln s_C, w_1 … w_H]` of `basis` on `fm`.
struct Problem<'a> {
    fm: &'a FloorModel,
    basis: &'a Basis,
    dt_s: f64,
    cfg: RefineConfig,
}

impl Problem<'_> {
    fn dim(&self) -> usize {
        2 + self.basis.grid.len()
    }

    /// The floors scaled by θ's elastic scales.
    fn scaled(&self, th: &[f64]) -> FloorModel {
        let mut fm = self.fm.clone();
        fm.stiffness *= th[0].exp();
        fm.damping *= th[1].exp();
        fm
    }

    /// The fit θ stands for (zero weights dropped; a model with none keeps one of weight 0).
    fn fit_of(&self, th: &[f64]) -> HysteronFit {
        let mut hysterons: Vec<HysteronSpec> = self
            .basis
            .grid
            .iter()
            .zip(&th[2..])
            .filter(|(_, w)| **w > 0.0)
            .map(|((e, r), w)| HysteronSpec {
                direction: *e,
                threshold_mm: *r,
                weight_kn_per_mm: *w,
            })
            .collect();
        if hysterons.is_empty() {
            if let Some((e, r)) = self.basis.grid.first() {
                hysterons.push(HysteronSpec {
                    direction: *e,
                    threshold_mm: *r,
                    weight_kn_per_mm: 0.0,
                });
            }
        }
        HysteronFit {
            operator: self.basis.operator,
            range: self.basis.range,
            directions: self.basis.directions.clone(),
            hysterons,
            stability_scale: 1.0,
            force_fit_pct: f64::NAN,
        }
    }

    fn params(&self, th: &[f64]) -> Option<FloorHysteronParams> {
        hysteron::params(&self.scaled(th), &self.fit_of(th), self.dt_s).ok()
    }

    /// Onto the admissible set: the scales within their bounds, the weights non-negative and
    /// each direction's sum at most `(1 − ε)·κ·s_K` (scaled down together if over).
    fn project(&self, th: &mut [f64]) {
        th[0] = if self.cfg.elastic {
            th[0].clamp(-LN_STIFFNESS_BOUND, LN_STIFFNESS_BOUND)
        } else {
            0.0
        };
        th[1] = if self.cfg.elastic {
            th[1].clamp(-LN_DAMPING_BOUND, LN_DAMPING_BOUND)
        } else {
            0.0
        };
        let sk = th[0].exp();
        let (head, w) = th.split_at_mut(2);
        let _ = head;
        for v in w.iter_mut() {
            if !v.is_finite() || *v < 0.0 {
                *v = 0.0;
            }
        }
        for (e, kappa) in self.basis.kappa.iter().enumerate() {
            let cap = (1.0 - MIN_TANGENT_FRACTION) * kappa * sk;
            let sum: f64 = self
                .basis
                .grid
                .iter()
                .zip(w.iter())
                .filter(|((d, _), _)| *d == e)
                .map(|(_, v)| *v)
                .sum();
            if sum > cap {
                let f = if sum > 0.0 { cap / sum } else { 0.0 };
                for ((d, _), v) in self.basis.grid.iter().zip(w.iter_mut()) {
                    if *d == e {
                        *v *= f;
                    }
                }
            }
        }
    }

    /// Forward-difference step of parameter `j` at θ.
    fn step_of(&self, th: &[f64], j: usize) -> f64 {
        if j < 2 {
            FD_LOG
        } else {
            let kappa = self.basis.kappa[self.basis.grid[j - 2].0];
            (FD_REL * th[j].abs()).max(FD_FLOOR * kappa).max(1e-9)
        }
    }
}

/// One run's fixed data for the residuals.
struct RunRef<'a> {
    run: &'a FloorRun,
    /// Per floor: 1 / (peak · √(samples · floors · runs)).
    floor_scale: Vec<f64>,
    /// Per story: the reference residual drift and its scale `ρ / (den · √(stories · runs))`.
    residual: Vec<(f64, f64)>,
    window: usize,
    dt_s: f64,
}

fn run_refs<'a>(runs: &'a [FloorRun], dt_s: f64, cfg: &RefineConfig) -> Vec<RunRef<'a>> {
    let nr = runs.len().max(1) as f64;
    let window = ((crate::machinery::structure::RESIDUAL_WINDOW_S / dt_s) as usize).max(1);
    runs.iter()
        .map(|r| {
            let floors = r.floor_disp_mm.len();
            let samples = r.len().div_ceil(cfg.every.max(1)).max(1) as f64;
            let floor_scale = r
                .floor_disp_mm
                .iter()
                .map(|x| {
                    let peak = x.iter().fold(0.0_f64, |m, v| m.max(v.abs())).max(1e-9);
                    1.0 / (peak * (samples * floors as f64 * nr).sqrt())
                })
                .collect();
            let res = r.residual_drift_mm(dt_s);
            let residual = (0..floors)
                .map(|i| {
                    let drift = r.drift_mm(i);
                    let peak = drift.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                    let den = res[i].abs().max(RESIDUAL_FLOOR * peak).max(1e-6);
                    (
                        res[i],
                        cfg.residual_weight / (den * (floors as f64 * nr).sqrt()),
                    )
                })
                .collect();
            RunRef {
                run: r,
                floor_scale,
                residual,
                window,
                dt_s,
            }
        })
        .collect()
}

/// The residual vector of one model along one run, in the order the Jacobian uses: the sampled
/// floors' errors (sample-major), then the residual drifts; `None` if it diverged.
fn residuals_of(p: FloorHysteronParams, rr: &RunRef<'_>, every: usize) -> Option<Vec<f64>> {
    let floors = pure_floors(p, &rr.run.ground_accel_mm_s2)?;
    let n = rr.run.len();
    let mut out = Vec::new();
    let every = every.max(1);
    let mut k = 0;
    while k < n {
        for (i, s) in rr.floor_scale.iter().enumerate() {
            out.push((floors[i][k] - rr.run.floor_disp_mm[i][k]) * s);
        }
        k += every;
    }
    let res = residual_drifts(&floors, rr.dt_s);
    for ((r_ref, s), r) in rr.residual.iter().zip(&res) {
        out.push((r - r_ref) * s);
    }
    Some(out)
}

/// The pure loop (the specimen its nominal spring at the model's own target): every floor.
fn pure_floors(p: FloorHysteronParams, ag: &[f64]) -> Option<Vec<Vec<f64>>> {
    hysteron::pure_loop(p, ag)
}

/// The loss of `p` on `refs`: the sum of the squared residuals (the mean over runs of the mean
/// squared floor NRMSE, as fractions, plus the weighted residual-drift term); infinite if it
/// diverges.
fn loss_on(p: FloorHysteronParams, refs: &[RunRef<'_>], every: usize) -> f64 {
    let per: Vec<f64> = refs
        .par_iter()
        .map(|rr| {
            residuals_of(p, rr, every).map_or(f64::INFINITY, |r| r.iter().map(|v| v * v).sum())
        })
        .collect();
    per.iter().sum()
}

/// The loss of the parameters `p` on `runs` as the refinement measures it (for reports).
pub fn loss_of(p: FloorHysteronParams, runs: &[FloorRun], dt_s: f64, cfg: &RefineConfig) -> f64 {
    loss_on(p, &run_refs(runs, dt_s, cfg), cfg.every)
}

/// A run's normal equations: `JᵀJ`, `Jᵀr`, `rᵀr`.
type Normal = (DMatrix<f64>, DVector<f64>, f64);

/// One run's normal equations at θ, every model (the nominal and one per parameter) stepped in
/// lockstep. `None` if the nominal model diverges.
fn normal_equations(pr: &Problem<'_>, th: &[f64], rr: &RunRef<'_>) -> Option<Normal> {
    let dim = pr.dim();
    let nominal = FloorHysteron::new(pr.params(th)?);
    let mut models = vec![nominal];
    let mut steps = vec![0.0];
    let mut live = vec![true];
    for j in 0..dim {
        let h = pr.step_of(th, j);
        let mut t2 = th.to_vec();
        t2[j] += h;
        // A perturbed model that core refuses (the step crossed the cap) leaves its column 0.
        match pr.params(&t2) {
            Some(p) => {
                models.push(FloorHysteron::new(p));
                live.push(true);
            }
            None => {
                models.push(nominal);
                live.push(false);
            }
        }
        steps.push(h);
    }
    let run = rr.run;
    let ag = &run.ground_accel_mm_s2;
    let floors = run.floor_disp_mm.len();
    let n = run.len();
    let k_e = pr.fm.specimen_k_kn_per_mm;
    for m in models.iter_mut() {
        m.reset_at(ag.first().copied().unwrap_or(0.0));
    }
    let mut jtj = DMatrix::<f64>::zeros(dim, dim);
    let mut jtr = DVector::<f64>::zeros(dim);
    let mut rtr = 0.0;
    let mut row = vec![0.0; dim];
    let every = pr.cfg.every.max(1);
    let window_start = n.saturating_sub(rr.window);
    // Each model's story drifts summed over the residual window.
    let mut tail = vec![vec![0.0; floors]; models.len()];
    for (k, &a) in ag.iter().enumerate().take(n) {
        if k > 0 {
            for (m, ok) in models.iter_mut().zip(live.iter_mut()) {
                let t = m.target_mm();
                if m.step(a, k_e * t).is_err() {
                    *ok = false;
                }
            }
            if !live[0] {
                return None;
            }
        }
        if k % every == 0 {
            for (i, s) in rr.floor_scale.iter().enumerate() {
                let x_ref = run.floor_disp_mm[i][k];
                let r0 = (models[0].floor_disp_mm(i) - x_ref) * s;
                rtr += r0 * r0;
                for j in 0..dim {
                    row[j] = if live[j + 1] {
                        (models[j + 1].floor_disp_mm(i) - models[0].floor_disp_mm(i)) * s
                            / steps[j + 1]
                    } else {
                        0.0
                    };
                }
                accumulate(&row, r0, &mut jtj, &mut jtr);
            }
        }
        if k >= window_start {
            for (m, t) in models.iter().zip(tail.iter_mut()) {
                for (i, ti) in t.iter_mut().enumerate() {
                    *ti += m.story_drift_mm(i);
                }
            }
        }
    }
    let w = (n - window_start).max(1) as f64;
    for (i, (r_ref, s)) in rr.residual.iter().enumerate() {
        let r0 = (tail[0][i] / w - r_ref) * s;
        rtr += r0 * r0;
        for j in 0..dim {
            row[j] = if live[j + 1] {
                (tail[j + 1][i] - tail[0][i]) / w * s / steps[j + 1]
            } else {
                0.0
            };
        }
        accumulate(&row, r0, &mut jtj, &mut jtr);
    }
    for a in 0..dim {
        for b in 0..a {
            jtj[(a, b)] = jtj[(b, a)];
        }
    }
    Some((jtj, jtr, rtr))
}

/// `JᵀJ += row·rowᵀ` (upper triangle) and `Jᵀr += row·r0`.
fn accumulate(row: &[f64], r0: f64, jtj: &mut DMatrix<f64>, jtr: &mut DVector<f64>) {
    let dim = row.len();
    for a in 0..dim {
        let ra = row[a];
        if ra == 0.0 {
            continue;
        }
        jtr[a] += ra * r0;
        for b in a..dim {
            jtj[(a, b)] += ra * row[b];
        }
    }
}

/// The basis of `fm` on `runs` the least-squares fit `start` used (its directions, caps and
/// grid).
pub fn basis(fm: &FloorModel, runs: &[FloorRun], start: &HysteronFit) -> Basis {
    let (directions, kappa) = hysteron::directions(&fm.stiffness);
    let c = hysteron::Candidate {
        operator: start.operator,
        range: start.range,
    };
    let grid = hysteron::thresholds(&directions, &kappa, runs, c);
    Basis {
        operator: start.operator,
        range: start.range,
        directions,
        kappa,
        grid,
    }
}

/// Refine `start` (a least-squares fit on `fit_runs` of `fm`, whose hysterons are on `basis`'s
/// grid) on the simulation error over `fit_runs`, stopping on `val_runs` (may be empty).
/// `on_step(done, max, fit_loss, val_loss)` reports each accepted step. Returns the floors (the
/// elastic scales applied), the fit, and the report.
#[allow(clippy::too_many_arguments)]
pub fn refine(
    fm: &FloorModel,
    basis: &Basis,
    start: &HysteronFit,
    fit_runs: &[FloorRun],
    val_runs: &[FloorRun],
    dt_s: f64,
    cfg: RefineConfig,
    mut on_step: impl FnMut(usize, usize, f64, Option<f64>),
) -> Result<(FloorModel, HysteronFit, RefineReport), TrainError> {
    let pr = Problem {
        fm,
        basis,
        dt_s,
        cfg,
    };
    let mut th = vec![0.0; pr.dim()];
    for h in &start.hysterons {
        if let Some(i) = basis
            .grid
            .iter()
            .position(|(e, r)| *e == h.direction && *r == h.threshold_mm)
        {
            th[2 + i] = h.weight_kn_per_mm;
        }
    }
    pr.project(&mut th);
    let fit_refs = run_refs(fit_runs, dt_s, &cfg);
    let val_refs = run_refs(val_runs, dt_s, &cfg);
    let eval = |th: &[f64], refs: &[RunRef<'_>]| -> f64 {
        pr.params(th)
            .map_or(f64::INFINITY, |p| loss_on(p, refs, cfg.every))
    };
    let mut loss = eval(&th, &fit_refs);
    if !loss.is_finite() {
        return Err(TrainError::Diverged(
            "the least-squares start of the floor-hysteron refinement".into(),
        ));
    }
    let has_val = !val_refs.is_empty();
    let val0 = has_val.then(|| eval(&th, &val_refs));
    let fit_loss_start = loss;
    let mut best = (th.clone(), val0.unwrap_or(loss), 0usize, loss);
    let mut mu = 1e-3;
    let mut since_best = 0;
    let mut iterations = 0;
    let mut stopped = format!("{} steps", cfg.max_iterations);
    on_step(0, cfg.max_iterations, loss, val0);
    while iterations < cfg.max_iterations {
        // The runs' normal equations, summed in the runs' order (deterministic).
        let parts: Vec<Option<Normal>> = fit_refs
            .par_iter()
            .map(|rr| normal_equations(&pr, &th, rr))
            .collect();
        let dim = pr.dim();
        let mut jtj = DMatrix::<f64>::zeros(dim, dim);
        let mut jtr = DVector::<f64>::zeros(dim);
        for p in parts {
            let (a, b, _) = p.ok_or_else(|| {
                TrainError::Diverged("the floor-hysteron model during its refinement".into())
            })?;
            jtj += a;
            jtr += b;
        }
        let mut accepted = None;
        for _ in 0..10 {
            let mut a = jtj.clone();
            for i in 0..dim {
                a[(i, i)] += mu * jtj[(i, i)].max(1e-12);
            }
            let Some(chol) = a.cholesky() else {
                mu *= 4.0;
                continue;
            };
            let d = chol.solve(&(-&jtr));
            let mut t2: Vec<f64> = th.iter().zip(d.iter()).map(|(a, b)| a + b).collect();
            pr.project(&mut t2);
            let l2 = eval(&t2, &fit_refs);
            if l2 < loss {
                accepted = Some((t2, l2));
                mu = (mu / 3.0).max(1e-9);
                break;
            }
            mu *= 4.0;
        }
        let Some((t2, l2)) = accepted else {
            stopped = "no step lowered the training loss".into();
            break;
        };
        let gain = (loss - l2) / loss.max(f64::MIN_POSITIVE);
        th = t2;
        loss = l2;
        iterations += 1;
        let val = has_val.then(|| eval(&th, &val_refs));
        let score = val.unwrap_or(loss);
        on_step(iterations, cfg.max_iterations, loss, val);
        if score < best.1 {
            best = (th.clone(), score, iterations, loss);
            since_best = 0;
        } else {
            since_best += 1;
            if has_val && since_best >= cfg.patience {
                stopped = format!("{} steps without a lower validation loss", cfg.patience);
                break;
            }
        }
        if gain < 1e-5 {
            stopped = "the training loss stopped falling".into();
            break;
        }
    }
    let (th, score, best_iteration, fit_loss_end) = best;
    let fm_out = pr.scaled(&th);
    let mut fit = pr.fit_of(&th);
    fit.force_fit_pct = start.force_fit_pct;
    fit.stability_scale = start.stability_scale;
    Ok((
        fm_out,
        fit,
        RefineReport {
            iterations,
            best_iteration,
            fit_loss_start,
            fit_loss_end,
            val_loss_start: val0,
            val_loss_end: has_val.then_some(score),
            stiffness_scale: th[0].exp(),
            damping_scale: th[1].exp(),
            stopped,
        },
    ))
}

/// The outputs of the history at `path` that are still swinging at its end: `(column, residual
/// mm, swing mm)` where the swing over the residual window is more than
/// [`AT_REST_SWING_RATIO`](crate::machinery::structure::AT_REST_SWING_RATIO) of the larger of the
/// residual and [`RESIDUAL_FLOOR`] of the peak (the scale the
/// refinement's residual-drift term uses). Such a run's free vibration is too short: where it
/// comes to rest is not in it, and the residual the training fits is the swing's phase. The ratio
/// is unitless, so the history is read in any units.
pub fn still_swinging(path: &Path, dt_s: f64) -> Result<Vec<(String, f64, f64)>, TrainError> {
    use crate::machinery::structure::{ResidualTail, AT_REST_SWING_RATIO};
    let h = rths_files::history::read(path, RecorderUnits::MM_KN, dt_s)
        .map_err(|e| TrainError::Setting(e.to_string()))?;
    Ok(h.outputs
        .iter()
        .filter_map(|(d, x)| {
            let t = ResidualTail::of(x, dt_s);
            let peak = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            let scale = t.mean_mm.abs().max(RESIDUAL_FLOOR * peak);
            (t.swing_mm > AT_REST_SWING_RATIO * scale).then(|| (d.column(), t.mean_mm, t.swing_mm))
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machinery::train::nonlinear::hysteron::Candidate;
    use crate::machinery::train::nonlinear::test_runs::{ground, one_floor, run_of, truth};

    /// A history whose floor still swings at its end is named with its column; one at rest is not.
    #[test]
    fn a_run_still_swinging_at_its_end_is_named() {
        let dt = rths_core::params::DT_S;
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, swing_mm: f64| {
            let n = 8 * 2048;
            let x: Vec<f64> = (0..n)
                .map(|k| 5.0 + 0.5 * swing_mm * (6.0 * k as f64 * dt).sin())
                .collect();
            let h = rths_files::history::TimeHistory {
                source: dir.path().join(name),
                dt_s: dt,
                ground_accel_mm_s2: vec![0.0; n],
                specimen_force_kn: vec![0.0; n],
                interface_mm: x.clone(),
                outputs: vec![(rths_files::history::OutputDof { node: 1, dof: 1 }, x)],
            };
            std::fs::write(&h.source, rths_files::history::to_csv(&h)).unwrap();
            h.source
        };
        let swinging = still_swinging(&write("a.csv", 4.0), dt).unwrap();
        assert_eq!(swinging.len(), 1, "{swinging:?}");
        assert_eq!(swinging[0].0, "out_1_1_mm");
        assert!((swinging[0].2 - 4.0).abs() < 0.01, "{swinging:?}");
        assert!(still_swinging(&write("b.csv", 0.5), dt).unwrap().is_empty());
    }

    /// From weights half the truth's, the refinement lowers the simulation error of a known play
    /// model many times, stops on the validation run, and the same input gives the same result.
    #[test]
    fn the_refinement_recovers_a_known_model_deterministically() {
        let fm = one_floor();
        let p = truth(&fm, &[(6.0, 120.0), (14.0, 60.0)], HysteronOperator::Play);
        let runs: Vec<FloorRun> = [(2500.0, 0.0), (4500.0, 1.0), (3500.0, 2.0)]
            .iter()
            .map(|&(a, ph)| run_of(p, ground(5.0, a, ph), &format!("run-{a}")))
            .collect();
        let (fit_runs, val_runs) = (&runs[..2], &runs[2..]);
        let c = Candidate {
            operator: HysteronOperator::Play,
            range: (0.06, 0.8),
        };
        let mut start = hysteron::fit(&fm, fit_runs, DT_S_TEST, c).expect("fit");
        for h in &mut start.hysterons {
            h.weight_kn_per_mm *= 0.5;
        }
        let basis = basis(&fm, fit_runs, &start);
        let cfg = RefineConfig {
            max_iterations: 12,
            ..RefineConfig::default()
        };
        let go = || {
            refine(
                &fm,
                &basis,
                &start,
                fit_runs,
                val_runs,
                DT_S_TEST,
                cfg,
                |_, _, _, _| {},
            )
            .expect("refined")
        };
        let (fm1, fit1, r1) = go();
        let (_, fit2, r2) = go();
        assert_eq!(r1, r2);
        assert_eq!(
            format!("{:?}", fit1.hysterons),
            format!("{:?}", fit2.hysterons)
        );
        assert!(r1.iterations >= 1, "{r1:?}");
        assert!(
            r1.fit_loss_end < 0.2 * r1.fit_loss_start,
            "training loss {} → {}",
            r1.fit_loss_start,
            r1.fit_loss_end
        );
        let (v0, v1) = (
            r1.val_loss_start.expect("val"),
            r1.val_loss_end.expect("val"),
        );
        assert!(v1 < 0.2 * v0, "validation loss {v0} → {v1}");
        // Every model it kept is one core accepts.
        assert!(hysteron::params(&fm1, &fit1, DT_S_TEST).is_ok());
    }

    const DT_S_TEST: f64 = rths_core::params::DT_S;
}

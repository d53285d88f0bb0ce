//! The free fit of the floor-hysteron form (`--free-fit`; docs/opensees-nonlinear.md "The free
//! fit"): the least squares put the hysterons on a grid of thresholds and try a grid of
//! Menegotto–Pinto shapes; here the kept hysterons' thresholds and the operator's shape
//! (`R₀`, `c_R1`, `c_R2`) are moved off the grid to lower the same flexibility-weighted force
//! residual, the weights solved by the same capped least squares at every point (the fit is
//! linear in them). The search is CMA-ES ([`super::cmaes`]), seeded: the same histories and seed
//! give the same bytes.

use nalgebra::{DMatrix, DVector};
use rths_core::metamodel::{HysteronOperator, MpShape, MP_CR1_MAX};

use super::cmaes;
use super::floors::{restoring_force_kn, FloorModel, FloorRun};
use super::hysteron::{
    basis_directions, capped_least_squares, dot, finish, flexibility_squared, nnls,
    not_positive_definite, Bank, Finished, ForceNormal, HysteronFit, FIT_EVERY,
    MIN_TANGENT_FRACTION, RIDGE,
};
use crate::machinery::train::TrainError;

/// The free fit's name in the model file's method (where the kept candidate was moved by it).
pub const FREE_FIT_METHOD: &str = "cma-es-free-fit";
/// CMA-ES generations of the free fit.
pub const SHAPE_GENERATIONS: usize = 60;
/// The search integrates the plays along every this many steps (2048 Hz: 512 Hz, some 100
/// points a cycle of the frames' modes).
pub const SHAPE_EVERY: usize = 4;
/// The search's first step, in the log of a threshold (and of `R₀`, `c_R2`): about ± 20 %.
pub const SHAPE_SIGMA0: f64 = 0.2;

/// A run's direction coordinates along its path (every `path_every`-th step) and, at the fit's
/// samples, the weighted deviation's projections `a_e·W·dev` and plain `a_e·dev`.
struct Sampled {
    /// `delta[point * dirs + e]`.
    delta: Vec<f64>,
    /// (path point, `a_e·W·dev` for every e, `a_e·dev` for every e).
    fit: Vec<(usize, Vec<f64>, Vec<f64>)>,
}

/// The data of the fit: every run sampled, the directions' mutual products, and the norms of
/// the deviation (weighted and plain) and of the recovered force.
struct Data {
    runs: Vec<Sampled>,
    dirs: usize,
    aa: DMatrix<f64>,
    aa_f: DMatrix<f64>,
    dev_w_sq: f64,
    dev_f_sq: f64,
    ref_sq: f64,
}

/// The plays are integrated along every `path_every`-th step (they are rate-independent: a
/// coarser path only rounds its turning points) and fitted at each of its points; on every step
/// (`path_every` 1), at every [`FIT_EVERY`]-th, as many samples as the least squares take (the
/// even steps; the least squares' are the odd ones).
fn sample(
    fm: &FloorModel,
    runs: &[FloorRun],
    dt_s: f64,
    dirs: &[Vec<f64>],
    path_every: usize,
) -> Option<Data> {
    let wmat = flexibility_squared(&fm.stiffness)?;
    let vecs: Vec<DVector<f64>> = dirs.iter().map(|d| DVector::from_column_slice(d)).collect();
    let aa = DMatrix::from_fn(dirs.len(), dirs.len(), |i, j| {
        (vecs[i].transpose() * &wmat * &vecs[j])[(0, 0)]
    });
    let aa_f = DMatrix::from_fn(dirs.len(), dirs.len(), |i, j| dot(&dirs[i], &dirs[j]));
    let (mut dev_w_sq, mut dev_f_sq, mut ref_sq) = (0.0, 0.0, 0.0);
    let mut out = Vec::with_capacity(runs.len());
    let path_every = path_every.max(1);
    let fit_every = if path_every == 1 {
        FIT_EVERY
    } else {
        path_every
    };
    for r in runs {
        let mut delta = Vec::with_capacity(r.len() / path_every * dirs.len() + dirs.len());
        for k in (0..r.len()).step_by(path_every) {
            let x: Vec<f64> = r.floor_disp_mm.iter().map(|f| f[k]).collect();
            delta.extend(dirs.iter().map(|a| dot(a, &x)));
        }
        let fit = restoring_force_kn(fm, r, dt_s, 1)
            .into_iter()
            .filter(|(k, _)| k % fit_every == 0)
            .map(|(k, force)| {
                let x = DVector::from_fn(fm.floors(), |i, _| r.floor_disp_mm[i][k]);
                let dev = &force - &fm.stiffness * x;
                let wdev = &wmat * &dev;
                dev_w_sq += dev.dot(&wdev);
                dev_f_sq += dev.norm_squared();
                ref_sq += force.norm_squared();
                let ad = dirs.iter().map(|a| dot(a, wdev.as_slice())).collect();
                let ad_f = dirs.iter().map(|a| dot(a, dev.as_slice())).collect();
                (k / path_every, ad, ad_f)
            })
            .collect();
        out.push(Sampled { delta, fit });
    }
    Some(Data {
        runs: out,
        dirs: dirs.len(),
        aa,
        aa_f,
        dev_w_sq,
        dev_f_sq,
        ref_sq,
    })
}

/// The normal equations of the hysterons `hs` of `op` (weighted and plain).
struct Normal {
    g: DMatrix<f64>,
    b: DVector<f64>,
    g_f: DMatrix<f64>,
    b_f: DVector<f64>,
}

fn normal(data: &Data, op: HysteronOperator, hs: &[(usize, f64)]) -> Normal {
    let h = hs.len();
    let mut n = Normal {
        g: DMatrix::zeros(h, h),
        b: DVector::zeros(h),
        g_f: DMatrix::zeros(h, h),
        b_f: DVector::zeros(h),
    };
    for r in &data.runs {
        let mut bank = Bank::new(op, h);
        let mut next = 0;
        let steps = r.delta.len() / data.dirs.max(1);
        for k in 0..steps {
            bank.update(hs, &r.delta[k * data.dirs..(k + 1) * data.dirs]);
            let Some((at, ad, ad_f)) = r.fit.get(next) else {
                break;
            };
            if *at != k {
                continue;
            }
            next += 1;
            let p = &bank.out;
            for i in 0..h {
                let ei = hs[i].0;
                n.b[i] -= p[i] * ad[ei];
                n.b_f[i] -= p[i] * ad_f[ei];
                for j in i..h {
                    let pp = p[i] * p[j];
                    n.g[(i, j)] += data.aa[(ei, hs[j].0)] * pp;
                    n.g_f[(i, j)] += data.aa_f[(ei, hs[j].0)] * pp;
                }
            }
        }
    }
    for i in 0..h {
        for j in 0..i {
            n.g[(i, j)] = n.g[(j, i)];
            n.g_f[(i, j)] = n.g_f[(j, i)];
        }
    }
    n
}

/// The capped least squares' weights of `n` (each direction's sum within its cap).
fn weights(n: &Normal, hs: &[(usize, f64)], caps: &[f64]) -> Vec<f64> {
    let h = hs.len();
    let mean_diag = (0..h).map(|i| n.g[(i, i)]).sum::<f64>() / h.max(1) as f64;
    let lambda = RIDGE * mean_diag.max(f64::MIN_POSITIVE);
    let groups: Vec<usize> = hs.iter().map(|(e, _)| *e).collect();
    let start = nnls(&n.g, &n.b, lambda);
    capped_least_squares(&n.g, &n.b, lambda, &groups, caps, &vec![false; h], start)
}

/// The weighted residual left by `w`, relative to the deviation's.
fn relative_residual(data: &Data, n: &Normal, w: &[f64]) -> f64 {
    let wv = DVector::from_column_slice(w);
    let v = data.dev_w_sq - 2.0 * n.b.dot(&wv) + (wv.transpose() * &n.g * &wv)[(0, 0)];
    v.max(0.0) / data.dev_w_sq.max(f64::MIN_POSITIVE)
}

/// The operator of a search point's last three numbers (`ln R₀`, `c_R1` as a logistic of
/// [`MP_CR1_MAX`], `ln c_R2`), or `None` outside the admissible shapes ([`MpShape::new`]).
fn shape_at(tail: &[f64]) -> Option<MpShape> {
    let r0 = tail.first()?.exp();
    let cr1 = MP_CR1_MAX / (1.0 + (-tail.get(1)?).exp());
    let cr2 = tail.get(2)?.exp();
    MpShape::new(r0, cr1, cr2).ok()
}

/// Move `start`'s thresholds (and its Menegotto–Pinto shape) to lower the weighted force
/// residual on `runs`, the weights refitted at every point (on the kept hysterons alone); `start`
/// itself if the search finds nothing lower than its own point.
pub fn free_fit(
    fm: &FloorModel,
    runs: &[FloorRun],
    dt_s: f64,
    start: &HysteronFit,
    seed: u64,
) -> Result<HysteronFit, TrainError> {
    let not_pd = || not_positive_definite(fm);
    let data = sample(fm, runs, dt_s, &start.directions, SHAPE_EVERY).ok_or_else(not_pd)?;
    let (_, kappa) = basis_directions(&fm.stiffness).ok_or_else(not_pd)?;
    let caps: Vec<f64> = kappa
        .iter()
        .map(|k| (1.0 - MIN_TANGENT_FRACTION) * k)
        .collect();
    let dirs_of: Vec<usize> = start.hysterons.iter().map(|h| h.direction).collect();
    let h = dirs_of.len();
    let mut x0: Vec<f64> = start
        .hysterons
        .iter()
        .map(|h| h.threshold_mm.ln())
        .collect();
    if let HysteronOperator::MenegottoPinto(s) = start.operator {
        let q = (s.cr1() / MP_CR1_MAX).clamp(1e-3, 1.0 - 1e-3);
        x0.extend([s.r0().ln(), (q / (1.0 - q)).ln(), s.cr2().ln()]);
    }
    let decode = |x: &[f64]| -> Option<(HysteronOperator, Vec<(usize, f64)>)> {
        let op = match start.operator {
            HysteronOperator::Play => HysteronOperator::Play,
            HysteronOperator::MenegottoPinto(_) => {
                HysteronOperator::MenegottoPinto(shape_at(x.get(h..)?)?)
            }
        };
        let hs = dirs_of
            .iter()
            .zip(x)
            .map(|(e, l)| (*e, l.exp()))
            .collect::<Vec<_>>();
        hs.iter()
            .all(|(_, t)| t.is_finite() && *t > 0.0)
            .then_some((op, hs))
    };
    let loss = |x: &[f64]| -> f64 {
        let Some((op, hs)) = decode(x) else {
            return f64::INFINITY;
        };
        let n = normal(&data, op, &hs);
        let w = weights(&n, &hs, &caps);
        relative_residual(&data, &n, &w)
    };
    let found = cmaes::minimize(
        loss,
        &x0,
        SHAPE_SIGMA0,
        SHAPE_GENERATIONS,
        None,
        seed,
        |_, _| {},
    );
    // Nothing lower than the start: the least squares' own fit stands.
    if found.best == x0 {
        return Ok(start.clone());
    }
    let Some((op, hs)) = decode(&found.best) else {
        return Ok(start.clone());
    };
    // The weights at the point found, the plays integrated along every step.
    let data =
        sample(fm, runs, dt_s, &start.directions, 1).ok_or_else(|| not_positive_definite(fm))?;
    let n = normal(&data, op, &hs);
    let w = weights(&n, &hs, &caps);
    let Finished {
        hysterons,
        scale,
        force_fit_pct,
    } = finish(
        fm,
        &start.directions,
        &hs,
        &w,
        &ForceNormal {
            gram: &n.g_f,
            rhs: &n.b_f,
            dev_sq: data.dev_f_sq,
            ref_sq: data.ref_sq,
        },
    )?;
    if hysterons.is_empty() {
        return Ok(start.clone());
    }
    Ok(HysteronFit {
        operator: op,
        range: start.range,
        directions: start.directions.clone(),
        hysterons,
        stability_scale: scale,
        force_fit_pct,
    })
}

#[cfg(test)]
mod tests {
    use super::super::hysteron::{fit, params, pure_loop, Candidate, THRESHOLD_RANGES};
    use super::super::test_runs::{ground, one_floor, runs_of, truth};
    use super::*;
    use rths_core::params::DT_S;

    /// A floor whose story is one Menegotto–Pinto play of Steel02's shape at 8 mm: the least
    /// squares, on a grid of thresholds and another shape, approach it; the free fit carries the
    /// weight at the true threshold (two hysterons close to it may stand for a rounder shape),
    /// leaves a far smaller residual, follows the truth on a record it was not fitted on, and
    /// repeats with the seed.
    #[test]
    fn the_free_fit_finds_the_threshold_and_the_shape_off_the_grid() {
        let fm = one_floor();
        let steel = MpShape::new(18.0, 0.925, 0.15).expect("valid");
        let p = truth(
            &fm,
            &[(8.0, 190.0)],
            HysteronOperator::MenegottoPinto(steel),
        );
        let runs = runs_of(p, 6.0, &[(5000.0, 0.0), (8000.0, 1.0), (11000.0, 2.0)]);
        let grid = MpShape::new(10.0, 0.5, 0.5).expect("valid");
        let c = Candidate {
            operator: HysteronOperator::MenegottoPinto(grid),
            range: THRESHOLD_RANGES[0],
        };
        let ls = fit(&fm, &runs, DT_S, c).expect("least squares");
        let free = free_fit(&fm, &runs, DT_S, &ls, 1).expect("free fit");
        assert!(
            free.force_fit_pct < 0.2 * ls.force_fit_pct,
            "{} against {}",
            free.force_fit_pct,
            ls.force_fit_pct
        );
        assert!(matches!(free.operator, HysteronOperator::MenegottoPinto(_)));
        // A record neither fit saw: the free fit's pure loop follows the truth's.
        let ag = ground(6.0, 9500.0, 0.5);
        let want = pure_loop(p, &ag).expect("finite");
        let miss = |f: &HysteronFit| {
            let got = pure_loop(params(&fm, f, DT_S).expect("valid"), &ag).expect("finite");
            let (e, r) = got[0]
                .iter()
                .zip(&want[0])
                .fold((0.0_f64, 0.0_f64), |(e, r), (g, w)| {
                    (e + (g - w) * (g - w), r + w * w)
                });
            (e / r).sqrt()
        };
        let (m_ls, m_free) = (miss(&ls), miss(&free));
        assert!(
            m_free < 0.3 * m_ls && m_free < 0.02,
            "{m_free} against {m_ls}"
        );
        // The weight is carried near the true threshold.
        let carried: f64 = free.hysterons.iter().map(|h| h.weight_kn_per_mm).sum();
        let mean_thr = free
            .hysterons
            .iter()
            .map(|h| h.weight_kn_per_mm * h.threshold_mm)
            .sum::<f64>()
            / carried;
        assert!((mean_thr - 8.0).abs() < 0.4, "{:?}", free.hysterons);
        assert!((carried - 190.0).abs() < 8.0, "{:?}", free.hysterons);
        let again = free_fit(&fm, &runs, DT_S, &ls, 1).expect("free fit");
        assert_eq!(format!("{free:?}"), format!("{again:?}"));
    }
}

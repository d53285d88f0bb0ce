//! Training of the floor-hysteron form (docs/opensees-nonlinear.md "The floor-hysteron form"): the elastic
//! floors of the lab's model ([`super::floors`]) plus a restoring-force deviation that is a
//! non-negative combination of play operators, fitted by ridge-regularized non-negative least
//! squares on the restoring force recovered by equilibrium from the training histories (the
//! residual weighted by the flexibility, [`flexibility_squared`]: the model is judged on
//! displacements), each direction's weights capped by its share of the stiffness, then scaled if
//! need be so the fully yielded tangent keeps a positive stiffness, and at most as many
//! hysterons as the board's tick holds ([`max_hysterons`]).
//!
//! The basis ([`basis_directions`]): the story drifts in `K`-orthogonal form ([`story_directions`]:
//! `K` split exactly into positive springs, story 1's coordinate its own drift) and, where a
//! frame's members couple two adjacent stories, their sum and difference; on each, operators at
//! thresholds spaced geometrically from 6 % to 80 % of the largest amplitude that direction
//! reaches in the training runs ([`thresholds`]). The operator is the play or the
//! Menegotto–Pinto play of one shape ([`candidate_operators`]; the training chooses). The
//! operators are integrated exactly along the recorded floors (they are rate-independent), so the
//! fit is linear in the weights, and it is deterministic: the same histories give the same bytes.

use nalgebra::{DMatrix, DVector};
use rths_app::tick_cost::{TickBudget, LEARNED_TICK_SHARE};
use rths_core::metamodel::{
    mp_play, FloorHysteron, FloorHysteronParams, FloorStructure, Hysteron, HysteronOperator,
    MpShape, MpState, HYST_MAX_DIRECTIONS, HYST_MAX_HYSTERONS, HYST_MAX_MP,
};
use rths_core::params::{CONTROL_RATES_HZ, CONTROL_RATE_HZ};
use rths_files::hysteron_model_file::{
    HysteronModelFile, HysteronSpec, HysteronTraining, OperatorSpec, HYSTERON_KIND,
};
use rths_files::nl_model_file::{NlStructureId, NL_FORMAT, NL_VERSION};

use super::floors::{restoring_force_kn, FloorModel, FloorRun};
use crate::machinery::train::TrainError;

/// The method's name in the model file.
pub const HYSTERON_METHOD: &str = "play-operator-nnls";
/// Play operators per direction (fewer when the directions are many: at most
/// [`HYST_MAX_HYSTERONS`] in all).
pub const THRESHOLDS_PER_DIRECTION: usize = 10;
/// Menegotto–Pinto plays per direction (fewer when the directions are many: at most
/// [`HYST_MAX_HYSTERONS`] in the grid, shared by the directions that carry stiffness; the model
/// keeps at most [`HYST_MAX_MP`] of them, and the board's limit is fewer, [`max_hysterons`]).
pub const MP_THRESHOLDS_PER_DIRECTION: usize = 10;

/// The Menegotto–Pinto shapes the training tries (`R₀`, `c_R1`, `c_R2`), beside the play: a grid
/// over the sharpness of the virgin curve and the softening of the reversals (OpenSees's
/// `Steel02` default is `(20, 0.925, 0.15)`); those whose reversal `R` would fall under
/// [`rths_core::metamodel::MP_R_MIN`] are left out.
pub const MP_SHAPES: [(f64, f64, f64); 18] = [
    (5.0, 0.5, 0.15),
    (5.0, 0.5, 0.5),
    (5.0, 0.8, 0.15),
    (5.0, 0.8, 0.5),
    (5.0, 0.925, 0.15),
    (5.0, 0.925, 0.5),
    (10.0, 0.5, 0.15),
    (10.0, 0.5, 0.5),
    (10.0, 0.8, 0.15),
    (10.0, 0.8, 0.5),
    (10.0, 0.925, 0.15),
    (10.0, 0.925, 0.5),
    (20.0, 0.5, 0.15),
    (20.0, 0.5, 0.5),
    (20.0, 0.8, 0.15),
    (20.0, 0.8, 0.5),
    (20.0, 0.925, 0.15),
    (20.0, 0.925, 0.5),
];

/// The bases the training tries: for each range of [`THRESHOLD_RANGES`], the play, then every
/// admissible shape of [`MP_SHAPES`].
pub fn candidates() -> Vec<Candidate> {
    let ops: Vec<HysteronOperator> = std::iter::once(HysteronOperator::Play)
        .chain(
            MP_SHAPES
                .iter()
                .filter_map(|&(a, b, c)| MpShape::new(a, b, c).ok())
                .map(HysteronOperator::MenegottoPinto),
        )
        .collect();
    THRESHOLD_RANGES
        .iter()
        .flat_map(|&range| {
            ops.iter()
                .map(move |&operator| Candidate { operator, range })
        })
        .collect()
}

/// The file's spelling of `op`.
pub fn operator_spec(op: HysteronOperator) -> OperatorSpec {
    match op {
        HysteronOperator::Play => OperatorSpec::Play,
        HysteronOperator::MenegottoPinto(s) => OperatorSpec::MenegottoPinto {
            r0: s.r0(),
            cr1: s.cr1(),
            cr2: s.cr2(),
        },
    }
}

/// The outputs of a bank of operators (each on its direction) integrated along a path.
pub(super) struct Bank {
    op: HysteronOperator,
    play: Vec<f64>,
    mp: Vec<MpState>,
    pub(super) out: Vec<f64>,
}

impl Bank {
    pub(super) fn new(op: HysteronOperator, h: usize) -> Self {
        Self {
            op,
            play: vec![0.0; h],
            mp: vec![MpState::REST; h],
            out: vec![0.0; h],
        }
    }

    /// Move every operator of `grid` to its direction's coordinate in `delta`.
    pub(super) fn update(&mut self, grid: &[(usize, f64)], delta: &[f64]) {
        match self.op {
            HysteronOperator::Play => {
                for ((y, o), (e, thr)) in self.play.iter_mut().zip(&mut self.out).zip(grid) {
                    *y = (*y).max(delta[*e] - thr).min(delta[*e] + thr);
                    *o = *y;
                }
            }
            HysteronOperator::MenegottoPinto(shape) => {
                for ((st, o), (e, thr)) in self.mp.iter_mut().zip(&mut self.out).zip(grid) {
                    *o = mp_play(&shape, *thr, st, delta[*e]);
                }
            }
        }
    }
}
/// The threshold ranges the training tries: the smallest and largest threshold, as fractions of
/// the direction's largest training amplitude. A training set that reaches far past yield puts
/// the yield drifts at a few per cent of its largest amplitude: on the Steel02 frame trained up to
/// 89 mm, the Menegotto–Pinto plays' held-out NRMSE was 11–13 % with the first range and 2.4–3.3 %
/// with the second (from 1.5 % on, small thresholds softened the small-amplitude response of the
/// plays: training loss 14.0 % → 9.5 % with 6 %).
pub const THRESHOLD_RANGES: [(f64, f64); 2] = [(0.06, 0.8), (0.02, 0.6)];

/// One basis the training tries: the operator and the threshold range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// The hysterons' operator.
    pub operator: HysteronOperator,
    /// The threshold range ([`THRESHOLD_RANGES`]).
    pub range: (f64, f64),
}
/// Ridge weight, relative to the Gram matrix's mean diagonal.
pub const RIDGE: f64 = 1e-4;
/// The fully yielded tangent keeps at least this fraction of the elastic stiffness in every
/// direction (`K − Σ w·a·aᵀ ⪰ ε·K`).
pub const MIN_TANGENT_FRACTION: f64 = 0.005;
/// The fit reads every this many samples (the play operators are integrated on every one).
pub const FIT_EVERY: usize = 2;

/// The spring network's directions and their share of the elastic stiffness: the floors' stiffness written
/// as a network of springs, `K = Σ_e κ_e·a_e·a_eᵀ`, with a spring from every floor to the ground
/// (`a = e_i`: for floor 1 the first story's drift) and between every two floors (`a = e_j − e_i`:
/// for neighbours a story drift, otherwise the drift over several stories: the cross-story
/// terms). `κ` is read off `K` (`κ_ij = −K_ij`, `κ_i0 = Σ_j K_ij`); a spring of negative `κ` (a
/// frame's condensed stiffness may have one) gets no share, and the shares are scaled so that
/// `Σ κ_e·a_e·a_eᵀ ⪯ K`. At most [`HYST_MAX_DIRECTIONS`], the stiffest kept.
pub fn directions(k: &DMatrix<f64>) -> (Vec<Vec<f64>>, Vec<f64>) {
    let n = k.nrows();
    let mut springs: Vec<(Vec<f64>, f64)> = Vec::new();
    for i in 0..n {
        let mut a = vec![0.0; n];
        a[i] = 1.0;
        let ground: f64 = (0..n).map(|j| k[(i, j)]).sum();
        springs.push((a, ground));
        for j in i + 1..n {
            let mut a = vec![0.0; n];
            a[j] = 1.0;
            a[i] = -1.0;
            springs.push((a, -k[(i, j)]));
        }
    }
    // The stiffest first (stable order for ties: the loop's).
    let mut order: Vec<usize> = (0..springs.len()).collect();
    order.sort_by(|&x, &y| springs[y].1.total_cmp(&springs[x].1));
    order.truncate(HYST_MAX_DIRECTIONS);
    order.sort_unstable();
    let (dirs, mut kappa): (Vec<Vec<f64>>, Vec<f64>) = order
        .into_iter()
        .map(|i| (springs[i].0.clone(), springs[i].1.max(0.0)))
        .unzip();
    // Σ κ·a·aᵀ ⪯ K: scale by the largest generalized eigenvalue if it is over 1.
    let mut s = DMatrix::<f64>::zeros(n, n);
    for (a, kp) in dirs.iter().zip(&kappa) {
        let v = DVector::from_column_slice(a);
        s += &v * v.transpose() * *kp;
    }
    let mu = largest_generalized_eigenvalue(&s, k).unwrap_or(f64::INFINITY);
    if mu > 1.0 {
        for kp in &mut kappa {
            *kp /= mu;
        }
    }
    (dirs, kappa)
}

/// The floors' stiffness in story drifts `d = D·x`: `K_d = D⁻ᵀ·K·D⁻¹` (`D⁻¹`: `x_i = Σ_{j≤i} d_j`).
fn story_drift_stiffness(k: &DMatrix<f64>) -> DMatrix<f64> {
    let n = k.nrows();
    let dinv = DMatrix::from_fn(n, n, |i, j| if j <= i { 1.0 } else { 0.0 });
    dinv.transpose() * k * &dinv
}

/// The basis's directions: the story drifts in `K`-orthogonal form, and their shares. In story
/// drifts `d = D·x` the floors' stiffness is `K_d = D⁻ᵀ·K·D⁻¹`; factored `K_d = U·Λ·Uᵀ` (`U` unit
/// upper triangular, eliminated from the top story down), `xᵀK·x = Σ_s λ_s·(Uᵀd)_s²`, so direction
/// `s` reads `(Uᵀd)_s = d_s + Σ_{j<s} U_js·d_j`: story 1's own drift, each story above its drift
/// less what the stories below it carry, and `K = Σ λ_s·a_s·a_sᵀ` exactly (`a_s = Dᵀ·U·e_s`,
/// `λ_s > 0`: no negative spring to drop). A shear building's `K_d` is diagonal: these are its
/// story drifts, the spring network's neighbours ([`directions`]), and its fit is the same.
/// Measured on the fiber frame (whose network has two negative springs and kept no hysteron on
/// story 1, the interface story): validation mean floor NRMSE 4.06 % → 3.01 %, 3 → 4 hysterons,
/// 37 kN/mm on story 1 (docs/opensees-nonlinear.md). The network's directions (`None` from here) where
/// `K` is not positive definite.
pub fn story_directions(k: &DMatrix<f64>) -> Option<(Vec<Vec<f64>>, Vec<f64>)> {
    story_directions_of_drift_stiffness(&story_drift_stiffness(k))
}

/// [`story_directions`] from the stiffness in story drifts `K_d` (which [`basis_directions`]
/// also reads, so it is computed once).
fn story_directions_of_drift_stiffness(kd: &DMatrix<f64>) -> Option<(Vec<Vec<f64>>, Vec<f64>)> {
    let n = kd.nrows();
    // U·Λ·Uᵀ from the Cholesky factor of K_d with its order reversed.
    let rev = DMatrix::from_fn(n, n, |i, j| kd[(n - 1 - i, n - 1 - j)]);
    let c = rev.cholesky()?.l();
    let mut dirs = Vec::with_capacity(n);
    let mut kappa = Vec::with_capacity(n);
    for s in 0..n {
        let col = n - 1 - s;
        let pivot = c[(col, col)];
        // Story s's coordinate in drifts: U_js = C[n−1−j][col]/pivot for j ≤ s (U_ss = 1).
        let u: Vec<f64> = (0..n)
            .map(|j| {
                if j <= s {
                    c[(n - 1 - j, col)] / pivot
                } else {
                    0.0
                }
            })
            .collect();
        // a = Dᵀ·u: aᵀx = uᵀ·D·x.
        let a: Vec<f64> = (0..n)
            .map(|i| u[i] - u.get(i + 1).copied().unwrap_or(0.0))
            .collect();
        dirs.push(a);
        kappa.push(pivot * pivot);
    }
    Some((dirs, kappa))
}

/// Two adjacent stories are coupled when their elastic coupling in story drifts,
/// `|K_d[s][s+1]|/√(K_d[s][s]·K_d[s+1][s+1])`, is above this (a shear building's is 0 to
/// round-off; the fiber frame's are 0.41 and 0.35).
pub const STORY_COUPLING_MIN: f64 = 1e-3;

/// The directions the fit chooses its hysterons on, and the share of `K` each alone may carry:
/// the story directions ([`story_directions`]), then, for every two adjacent stories that a
/// frame's beams couple ([`STORY_COUPLING_MIN`]), the sum and the difference of their
/// directions, `a_s ± a_{s+1}`, each with share `1/(1/λ_s + 1/λ_{s+1})` (the most a weight on it
/// alone keeps within `K`: `w·(a_s ± a_{s+1})(…)ᵀ ⪯ K` exactly then). A beam that yields turns
/// the joints it frames, which both stories' drifts feel: a hysteron of one story's coordinate
/// alone cannot say that. Together the weights may pass `K`; the fit's final scale and the
/// refinement's projection hold the bound core requires. Measured on the fiber frame (the
/// twelve runs of the shipped model): the least squares' best validation loss 5.18 % → 4.77 %,
/// refined 3.83 % → 3.80 %, and on four runs of two synthetic records at peak interface
/// 57–92 mm (written for this comparison, not training's) interface NRMSE median 5.30 % → 3.52 %
/// (docs/opensees-nonlinear.md). A shear building's basis is its story directions alone.
pub fn basis_directions(k: &DMatrix<f64>) -> Option<(Vec<Vec<f64>>, Vec<f64>)> {
    let n = k.nrows();
    let kd = story_drift_stiffness(k);
    let (mut dirs, mut kappa) = story_directions_of_drift_stiffness(&kd)?;
    for s in 0..n.saturating_sub(1) {
        let coupling = kd[(s, s + 1)].abs() / (kd[(s, s)] * kd[(s + 1, s + 1)]).sqrt();
        // A NaN coupling (a singular story) is not coupled.
        let coupled = coupling > STORY_COUPLING_MIN;
        if !coupled || dirs.len() + 2 > HYST_MAX_DIRECTIONS {
            continue;
        }
        let share = 1.0 / (1.0 / kappa[s] + 1.0 / kappa[s + 1]);
        for sign in [1.0, -1.0] {
            let a: Vec<f64> = dirs[s]
                .iter()
                .zip(&dirs[s + 1])
                .map(|(x, y)| x + sign * y)
                .collect();
            dirs.push(a);
            kappa.push(share);
        }
    }
    Some((dirs, kappa))
}

/// The largest `μ` with `W·v = μ·K·v` (`K` positive definite), or `None` if it is not.
fn largest_generalized_eigenvalue(w: &DMatrix<f64>, k: &DMatrix<f64>) -> Option<f64> {
    let l_inv = k.clone().cholesky()?.l().try_inverse()?;
    let g = &l_inv * w * l_inv.transpose();
    let g = (&g + g.transpose()) * 0.5;
    Some(g.symmetric_eigen().eigenvalues.max())
}

pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The hysterons' thresholds of the basis `c` on the directions that carry stiffness (`kappa >
/// 0`; the others can hold no weight): per direction, geometric in `c.range` of the largest
/// amplitude the direction reaches in `runs`.
pub fn thresholds(
    dirs: &[Vec<f64>],
    kappa: &[f64],
    runs: &[FloorRun],
    c: Candidate,
) -> Vec<(usize, f64)> {
    let per = match c.operator {
        HysteronOperator::Play => THRESHOLDS_PER_DIRECTION,
        HysteronOperator::MenegottoPinto(_) => MP_THRESHOLDS_PER_DIRECTION,
    };
    // The grid is the training's: the fit keeps at most the board's limit of it.
    let live = kappa.iter().filter(|k| **k > 0.0).count();
    let per = per.min(HYST_MAX_HYSTERONS / live.max(1)).max(1);
    let mut out = Vec::new();
    for (e, a) in dirs.iter().enumerate() {
        if kappa.get(e).is_none_or(|k| *k <= 0.0) {
            continue;
        }
        let mut amp = 0.0_f64;
        for r in runs {
            for k in 0..r.len() {
                let x: Vec<f64> = r.floor_disp_mm.iter().map(|f| f[k]).collect();
                amp = amp.max(dot(a, &x).abs());
            }
        }
        let amp = if amp > 0.0 && amp.is_finite() {
            amp
        } else {
            1.0
        };
        let (lo, hi) = c.range;
        for j in 0..per {
            let f = if per == 1 {
                lo
            } else {
                lo * (hi / lo).powf(j as f64 / (per - 1) as f64)
            };
            out.push((e, f * amp));
        }
    }
    out
}

/// A fitted model and how the fit went.
#[derive(Debug, Clone)]
pub struct HysteronFit {
    /// The hysterons' operator.
    pub operator: HysteronOperator,
    /// The threshold range of its basis.
    pub range: (f64, f64),
    /// The directions.
    pub directions: Vec<Vec<f64>>,
    /// The hysterons (zero weights dropped).
    pub hysterons: Vec<HysteronSpec>,
    /// The factor the weights were scaled by for the tangent (1: none).
    pub stability_scale: f64,
    /// Relative RMS residual of the force fit, %.
    pub force_fit_pct: f64,
}

impl HysteronFit {
    /// The same model without the directions no hysteron acts along (renumbered in order): a
    /// direction costs the board's tick whether or not it carries a hysteron, and one without
    /// adds nothing to the force, so the model steps the same to the bit.
    pub fn without_idle_directions(&self) -> Self {
        let used: Vec<bool> = (0..self.directions.len())
            .map(|e| self.hysterons.iter().any(|h| h.direction == e))
            .collect();
        let mut new_index = vec![0; used.len()];
        let mut next = 0;
        for (e, u) in used.iter().enumerate() {
            new_index[e] = next;
            next += usize::from(*u);
        }
        Self {
            directions: self
                .directions
                .iter()
                .zip(&used)
                .filter(|(_, u)| **u)
                .map(|(a, _)| a.clone())
                .collect(),
            hysterons: self
                .hysterons
                .iter()
                .map(|h| HysteronSpec {
                    direction: new_index[h.direction],
                    ..*h
                })
                .collect(),
            ..self.clone()
        }
    }
}

/// Fit the weights of the hysterons of the basis `c` on `runs` of `fm` at step `dt_s`.
pub fn fit(
    fm: &FloorModel,
    runs: &[FloorRun],
    dt_s: f64,
    c: Candidate,
) -> Result<HysteronFit, TrainError> {
    fit_at_most(fm, runs, dt_s, c, None)
}

/// [`fit`] keeping at most `limit` hysterons (`None`: the board's, [`max_hysterons`]).
fn fit_at_most(
    fm: &FloorModel,
    runs: &[FloorRun],
    dt_s: f64,
    c: Candidate,
    limit: Option<usize>,
) -> Result<HysteronFit, TrainError> {
    let op = c.operator;
    let n = fm.floors();
    let (dirs, kappa) = basis_directions(&fm.stiffness).ok_or_else(|| not_positive_definite(fm))?;
    let hs = thresholds(&dirs, &kappa, runs, c);
    let h = hs.len();
    let mut gram = DMatrix::<f64>::zeros(h, h);
    let mut rhs = DVector::<f64>::zeros(h);
    let mut ref_sq = 0.0;
    // The plain force residual's Gram and right-hand side, for the reported fit residual.
    let mut gram_f = DMatrix::<f64>::zeros(h, h);
    let mut rhs_f = DVector::<f64>::zeros(h);
    let mut dev_f_sq = 0.0;
    let wmat = flexibility_squared(&fm.stiffness).ok_or_else(|| not_positive_definite(fm))?;
    // The directions' mutual products: a_h·W·a_h' for the fit, a_h·a_h' for the plain residual.
    let vecs: Vec<DVector<f64>> = dirs.iter().map(|d| DVector::from_column_slice(d)).collect();
    let aa = DMatrix::from_fn(dirs.len(), dirs.len(), |i, j| {
        (vecs[i].transpose() * &wmat * &vecs[j])[(0, 0)]
    });
    let aa_f = DMatrix::from_fn(dirs.len(), dirs.len(), |i, j| dot(&dirs[i], &dirs[j]));
    for r in runs {
        let forces = restoring_force_kn(fm, r, dt_s, FIT_EVERY);
        let mut bank = Bank::new(op, h);
        let mut next = 0;
        for k in 0..r.len() {
            let x: Vec<f64> = r.floor_disp_mm.iter().map(|f| f[k]).collect();
            let delta: Vec<f64> = dirs.iter().map(|a| dot(a, &x)).collect();
            bank.update(&hs, &delta);
            let play = &bank.out;
            if next < forces.len() && forces[next].0 == k {
                let xv = DVector::from_vec(x);
                // The deviation of the recovered force from the elastic one.
                let dev = &forces[next].1 - &fm.stiffness * xv;
                let wdev = &wmat * &dev;
                dev_f_sq += dev.norm_squared();
                ref_sq += forces[next].1.norm_squared();
                // b_h = −p_h·(a_h·W·dev); the Gram's entries (a_h·W·a_h')·p_h·p_h'.
                let ad: Vec<f64> = dirs.iter().map(|a| dot(a, wdev.as_slice())).collect();
                let ad_f: Vec<f64> = dirs.iter().map(|a| dot(a, dev.as_slice())).collect();
                for (i, (ei, _)) in hs.iter().enumerate() {
                    rhs[i] -= play[i] * ad[*ei];
                    rhs_f[i] -= play[i] * ad_f[*ei];
                }
                for i in 0..h {
                    if play[i] == 0.0 {
                        continue;
                    }
                    let ei = hs[i].0;
                    for j in i..h {
                        let pp = play[i] * play[j];
                        gram[(i, j)] += aa[(ei, hs[j].0)] * pp;
                        gram_f[(i, j)] += aa_f[(ei, hs[j].0)] * pp;
                    }
                }
                next += 1;
            }
        }
    }
    for i in 0..h {
        for j in 0..i {
            gram[(i, j)] = gram[(j, i)];
            gram_f[(i, j)] = gram_f[(j, i)];
        }
    }
    let mean_diag = (0..h).map(|i| gram[(i, i)]).sum::<f64>() / h.max(1) as f64;
    let lambda = RIDGE * mean_diag.max(f64::MIN_POSITIVE);
    // Each direction keeps at least ε of its share once all its hysterons slide:
    // Σ_{h on s} w_h ≤ (1 − ε)·λ_s. The story directions split `K` exactly and are
    // independent, so this is the whole of the bound core requires, K − Σ w·a·aᵀ ⪰ ε·K (data
    // chosen caps within that bound, tried while the basis was a spring network whose negative
    // springs scaled every share down, reduce to these shares here).
    let caps: Vec<f64> = kappa
        .iter()
        .map(|k| (1.0 - MIN_TANGENT_FRACTION) * k)
        .collect();
    let groups: Vec<usize> = hs.iter().map(|(e, _)| *e).collect();
    let start_w = nnls(&gram, &rhs, lambda);
    let mut excluded = vec![false; h];
    let mut w = capped_least_squares(&gram, &rhs, lambda, &groups, &caps, &excluded, start_w);
    // The board's tick holds so many hysterons: past them the one that carries least (its
    // weight times its column's norm, the force it adds) is dropped and the rest refitted. On
    // the fiber frame's runs with 40 s of free vibration the least squares kept 14
    // Menegotto–Pinto plays, 14.7 % of the M7's 4096 Hz tick by the estimate.
    let core_max = match op {
        HysteronOperator::Play => HYST_MAX_HYSTERONS,
        HysteronOperator::MenegottoPinto(_) => HYST_MAX_MP,
    };
    let limit = limit
        .unwrap_or_else(|| max_hysterons(n, dirs.len(), op))
        .min(core_max);
    while w.iter().filter(|x| **x > 0.0).count() > limit {
        let Some(drop) = (0..h).filter(|&i| w[i] > 0.0).min_by(|&a, &b| {
            let size = |i: usize| w[i] * gram[(i, i)].max(0.0).sqrt();
            size(a).total_cmp(&size(b))
        }) else {
            break;
        };
        excluded[drop] = true;
        w[drop] = 0.0;
        w = capped_least_squares(&gram, &rhs, lambda, &groups, &caps, &excluded, w);
    }
    let Finished {
        hysterons,
        scale,
        force_fit_pct: resid,
    } = finish(
        fm,
        &dirs,
        &hs,
        &w,
        &ForceNormal {
            gram: &gram_f,
            rhs: &rhs_f,
            dev_sq: dev_f_sq,
            ref_sq,
        },
    )?;
    if hysterons.is_empty() {
        return Err(TrainError::Setting(
            "the histories show no hysteresis to fit (every weight came out 0): train on runs \
             that yield"
                .into(),
        ));
    }
    Ok(HysteronFit {
        operator: op,
        range: c.range,
        directions: dirs,
        hysterons,
        stability_scale: scale,
        force_fit_pct: resid,
    })
}

/// The error of a structure whose floors' elastic stiffness is not positive definite.
pub(super) fn not_positive_definite(fm: &FloorModel) -> TrainError {
    TrainError::Setting(format!(
        "structure {}: the floors' elastic stiffness is not positive definite",
        fm.name
    ))
}

/// The plain force residual's normal equations: `|dev − Φw|² = dev_sq − 2 rhsᵀw + wᵀ·gram·w`,
/// and the recovered force's squared norm it is reported against.
pub(super) struct ForceNormal<'a> {
    pub(super) gram: &'a DMatrix<f64>,
    pub(super) rhs: &'a DVector<f64>,
    pub(super) dev_sq: f64,
    pub(super) ref_sq: f64,
}

/// A fit's weights made a model's hysterons ([`finish`]).
pub(super) struct Finished {
    /// The hysterons that carry weight, scaled.
    pub(super) hysterons: Vec<HysteronSpec>,
    /// The factor the weights were scaled by (1: none).
    pub(super) scale: f64,
    /// Relative RMS residual of the force fit with the scaled weights, %.
    pub(super) force_fit_pct: f64,
}

/// The end of a fit, the least squares' and the free fit's alike: the weights `w` of the
/// hysterons `hs` on `dirs` scaled if need be so the fully yielded tangent keeps
/// [`MIN_TANGENT_FRACTION`] of `K` (the caps guarantee it; a round-off excess is scaled away),
/// the force residual they leave, and the hysterons that carry weight (possibly none).
pub(super) fn finish(
    fm: &FloorModel,
    dirs: &[Vec<f64>],
    hs: &[(usize, f64)],
    w: &[f64],
    force: &ForceNormal<'_>,
) -> Result<Finished, TrainError> {
    let n = fm.floors();
    let mut wm = DMatrix::<f64>::zeros(n, n);
    for (wi, (e, _)) in w.iter().zip(hs) {
        let a = DVector::from_column_slice(&dirs[*e]);
        wm += &a * a.transpose() * *wi;
    }
    let mu = largest_generalized_eigenvalue(&wm, &fm.stiffness)
        .ok_or_else(|| not_positive_definite(fm))?;
    if !mu.is_finite() {
        return Err(TrainError::Diverged(
            "the hysterons' weights (not finite)".into(),
        ));
    }
    let scale = if mu > 1.0 - MIN_TANGENT_FRACTION {
        (1.0 - MIN_TANGENT_FRACTION) / mu
    } else {
        1.0
    };
    let wv = DVector::from_iterator(w.len(), w.iter().map(|x| x * scale));
    let v = force.dev_sq - 2.0 * force.rhs.dot(&wv) + (wv.transpose() * force.gram * &wv)[(0, 0)];
    let force_fit_pct = 100.0 * (v.max(0.0) / force.ref_sq.max(f64::MIN_POSITIVE)).sqrt();
    let hysterons = w
        .iter()
        .zip(hs)
        .filter(|(wi, _)| **wi > 0.0)
        .map(|(wi, (e, thr))| HysteronSpec {
            direction: *e,
            threshold_mm: *thr,
            weight_kn_per_mm: wi * scale,
        })
        .collect();
    Ok(Finished {
        hysterons,
        scale,
        force_fit_pct,
    })
}

/// The most hysterons of `op` a model of `floors` floors and `directions` directions keeps: the
/// fastest board at the highest rate (the Cortex-M7 at 4096 Hz) runs it with its rig compensation
/// within [`LEARNED_TICK_SHARE`] of the tick, by the board's estimate
/// ([`TickBudget::max_hysterons`]), and never fewer than one.
pub fn max_hysterons(floors: usize, directions: usize, op: HysteronOperator) -> usize {
    let rate_hz = CONTROL_RATES_HZ
        .iter()
        .copied()
        .max()
        .unwrap_or(CONTROL_RATE_HZ);
    TickBudget::cortex_m7_480mhz(f64::from(rate_hz))
        .max_hysterons(
            floors,
            directions,
            matches!(op, HysteronOperator::MenegottoPinto(_)),
            LEARNED_TICK_SHARE,
        )
        .max(1)
}

/// The least squares' weight on the force residual, `W = K⁻²` (`None` if `K` is not positive
/// definite): the model is judged on displacements, and a force error `δf` costs a displacement
/// error of about `K⁻¹·δf`, so the fit minimizes `|K⁻¹·(dev − Φw)|²` rather than `|dev − Φw|²`
/// (no constant to tune). With equal force weights on every floor, the fiber frame's fit gave
/// the interface story too little: validation interface NRMSE 4.98 %; with `K⁻²`, 2.96 % (mean
/// floor NRMSE 4.77 % → 4.60 %; `K⁻¹`, the energy norm, 4.60 % but interface 4.71 %).
pub(super) fn flexibility_squared(k: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let f = k.clone().cholesky()?.inverse();
    Some(&f * &f)
}

/// `min ½wᵀ(G + λI)w − bᵀw` with `w ≥ 0` and each group's sum at most its cap, by accelerated
/// projected gradient (FISTA) from `w0`: the projection onto a group's set is a clip at 0 or, past
/// the cap, the projection onto the scaled simplex. Deterministic.
pub(super) fn capped_least_squares(
    g: &DMatrix<f64>,
    b: &DVector<f64>,
    lambda: f64,
    groups: &[usize],
    caps: &[f64],
    excluded: &[bool],
    w0: Vec<f64>,
) -> Vec<f64> {
    let h = b.len();
    let mut a = g.clone();
    for i in 0..h {
        a[(i, i)] += lambda;
    }
    let l = a
        .clone()
        .symmetric_eigen()
        .eigenvalues
        .max()
        .max(f64::MIN_POSITIVE);
    let project = |v: &mut DVector<f64>| {
        for (e, cap) in caps.iter().enumerate() {
            let idx: Vec<usize> = (0..h).filter(|&i| groups[i] == e).collect();
            for &i in &idx {
                v[i] = if excluded[i] { 0.0 } else { v[i].max(0.0) };
            }
            let sum: f64 = idx.iter().map(|&i| v[i]).sum();
            if sum <= *cap {
                continue;
            }
            if *cap <= 0.0 {
                for &i in &idx {
                    v[i] = 0.0;
                }
                continue;
            }
            let mut u: Vec<f64> = idx.iter().map(|&i| v[i]).collect();
            u.sort_by(|x, y| y.total_cmp(x));
            let (mut acc, mut theta) = (0.0, 0.0);
            for (j, uj) in u.iter().enumerate() {
                acc += uj;
                let t = (acc - cap) / (j + 1) as f64;
                if uj - t > 0.0 {
                    theta = t;
                }
            }
            for &i in &idx {
                v[i] = (v[i] - theta).max(0.0);
            }
        }
    };
    let mut x = DVector::from_vec(w0);
    project(&mut x);
    let mut y = x.clone();
    let mut t = 1.0_f64;
    for _ in 0..20_000 {
        let grad = &a * &y - b;
        let mut next = &y - grad / l;
        project(&mut next);
        let t_next = 0.5 * (1.0 + (1.0 + 4.0 * t * t).sqrt());
        let moved = (&next - &x).amax();
        y = &next + (&next - &x) * ((t - 1.0) / t_next);
        x = next;
        t = t_next;
        if moved <= 1e-13 * x.amax().max(f64::MIN_POSITIVE) {
            break;
        }
    }
    x.iter().copied().collect()
}

/// Non-negative least squares `min ½wᵀ(G + λI)w − bᵀw, w ≥ 0` by Lawson and Hanson's active set
/// (on the normal equations; exact and deterministic: the passive set grows by the steepest
/// violated weight, and a step that would make a weight negative stops at the boundary).
pub(super) fn nnls(g: &DMatrix<f64>, b: &DVector<f64>, lambda: f64) -> Vec<f64> {
    let h = b.len();
    let mut a = g.clone();
    for i in 0..h {
        a[(i, i)] += lambda;
    }
    let mut w = DVector::<f64>::zeros(h);
    let mut passive = vec![false; h];
    let scale = b.amax().max(f64::MIN_POSITIVE);
    let solve = |passive: &[bool]| -> DVector<f64> {
        let idx: Vec<usize> = (0..h).filter(|&i| passive[i]).collect();
        let sub = DMatrix::from_fn(idx.len(), idx.len(), |r, c| a[(idx[r], idx[c])]);
        let rhs = DVector::from_fn(idx.len(), |r, _| b[idx[r]]);
        let z = sub
            .clone()
            .cholesky()
            .map(|ch| ch.solve(&rhs))
            .unwrap_or_else(|| DVector::zeros(idx.len()));
        let mut out = DVector::zeros(h);
        for (r, &i) in idx.iter().enumerate() {
            out[i] = z[r];
        }
        out
    };
    for _ in 0..(3 * h + 10) {
        let grad = b - &a * &w;
        let Some(j) = (0..h)
            .filter(|&i| !passive[i] && grad[i] > 1e-10 * scale)
            .max_by(|&x, &y| grad[x].total_cmp(&grad[y]))
        else {
            break;
        };
        passive[j] = true;
        for _ in 0..(2 * h + 2) {
            let z = solve(&passive);
            if (0..h).all(|i| !passive[i] || z[i] > 0.0) {
                w = z;
                break;
            }
            let mut alpha = 1.0_f64;
            for i in 0..h {
                if passive[i] && z[i] <= 0.0 {
                    let d = w[i] - z[i];
                    if d > 0.0 {
                        alpha = alpha.min(w[i] / d);
                    }
                }
            }
            w += (z - &w) * alpha;
            for i in 0..h {
                if passive[i] && w[i] <= 1e-14 * scale {
                    passive[i] = false;
                    w[i] = 0.0;
                }
            }
        }
    }
    w.iter().map(|x| x.max(0.0)).collect()
}

/// The model file of `fit` on `fm`.
pub fn model_file(
    fm: &FloorModel,
    fit: &HysteronFit,
    structure: NlStructureId,
    dt_s: f64,
    training: HysteronTraining,
) -> HysteronModelFile {
    let rows = |m: &DMatrix<f64>| -> Vec<Vec<f64>> {
        (0..m.nrows())
            .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
            .collect()
    };
    HysteronModelFile {
        format: NL_FORMAT.into(),
        version: NL_VERSION,
        kind: HYSTERON_KIND.into(),
        structure,
        dt_s,
        floors: fm.columns.clone(),
        specimen_floor: fm.specimen_floor,
        specimen_stiffness_kn_per_mm: fm.specimen_k_kn_per_mm,
        mass: rows(&fm.mass),
        damping: rows(&fm.damping),
        stiffness: rows(&fm.stiffness),
        ground_mass: fm.ground_mass.iter().copied().collect(),
        directions: fit.directions.clone(),
        operator: operator_spec(fit.operator),
        hysterons: fit.hysterons.clone(),
        training,
    }
}

/// The core parameters of `fit` on `fm` at `dt_s`.
pub fn params(
    fm: &FloorModel,
    fit: &HysteronFit,
    dt_s: f64,
) -> Result<FloorHysteronParams, TrainError> {
    let flat = |m: &DMatrix<f64>| -> Vec<f64> {
        (0..m.nrows())
            .flat_map(|i| (0..m.ncols()).map(move |j| m[(i, j)]))
            .collect()
    };
    let (m, c, k) = (flat(&fm.mass), flat(&fm.damping), flat(&fm.stiffness));
    let gm: Vec<f64> = fm.ground_mass.iter().copied().collect();
    let dirs: Vec<f64> = fit.directions.iter().flatten().copied().collect();
    let hs: Vec<Hysteron> = fit
        .hysterons
        .iter()
        .map(|x| Hysteron {
            direction: x.direction,
            threshold_mm: x.threshold_mm,
            weight_kn_per_mm: x.weight_kn_per_mm,
        })
        .collect();
    FloorHysteronParams::new(
        dt_s,
        &FloorStructure {
            floors: fm.floors(),
            mass: &m,
            damping: &c,
            stiffness: &k,
            ground_mass: &gm,
            specimen_floor: fm.specimen_floor,
            specimen_k_kn_per_mm: fm.specimen_k_kn_per_mm,
        },
        &dirs,
        &hs,
    )
    .and_then(|p| p.with_operator(fit.operator))
    .map_err(|e| TrainError::Setting(format!("floor-hysteron parameters: {e}")))
}

/// The pure loop of `p` (the specimen its nominal spring at the model's own target) under
/// `ag_mm_s2`: every floor at every step, or `None` if it diverged.
pub fn pure_loop(p: FloorHysteronParams, ag_mm_s2: &[f64]) -> Option<Vec<Vec<f64>>> {
    let mut m = FloorHysteron::new(p);
    let n = p.floors();
    let k_e = p.specimen_k_kn_per_mm();
    let mut out = vec![Vec::with_capacity(ag_mm_s2.len()); n];
    m.reset_at(ag_mm_s2.first().copied().unwrap_or(0.0));
    for (k, &a) in ag_mm_s2.iter().enumerate() {
        if k > 0 {
            let t = m.target_mm();
            m.step(a, k_e * t).ok()?;
        }
        for (i, o) in out.iter_mut().enumerate() {
            o.push(m.floor_disp_mm(i));
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::super::test_runs::{one_floor, runs_of, truth};
    use super::*;

    /// A model of three plays is fitted with at least three hysterons; held to two, it keeps two
    /// (the one that carries least dropped, the rest refitted), and the board's limit is what
    /// the M7's 4096 Hz tick holds.
    #[test]
    fn the_fit_keeps_no_more_hysterons_than_its_limit() {
        let fm = one_floor();
        let p = truth(
            &fm,
            &[(4.0, 40.0), (9.0, 50.0), (16.0, 60.0)],
            HysteronOperator::Play,
        );
        let runs = runs_of(p, 6.0, &[(6000.0, 0.0), (9000.0, 1.0)]);
        let c = Candidate {
            operator: HysteronOperator::Play,
            range: THRESHOLD_RANGES[0],
        };
        let free = fit_at_most(&fm, &runs, rths_core::params::DT_S, c, Some(64)).expect("fit");
        assert!(free.hysterons.len() >= 3, "{:?}", free.hysterons);
        let two = fit_at_most(&fm, &runs, rths_core::params::DT_S, c, Some(2)).expect("fit");
        assert_eq!(two.hysterons.len(), 2, "{:?}", two.hysterons);
        assert!(two.hysterons.iter().all(|h| h.weight_kn_per_mm > 0.0));
        let total = |f: &HysteronFit| f.hysterons.iter().map(|h| h.weight_kn_per_mm).sum::<f64>();
        // The two kept carry most of what the free fit did (the refit moves the dropped one's).
        assert!(
            total(&two) > 0.7 * total(&free),
            "{} {}",
            total(&two),
            total(&free)
        );
        let mp = HysteronOperator::MenegottoPinto(MpShape::new(20.0, 0.925, 0.15).expect("valid"));
        assert_eq!(max_hysterons(3, 3, mp), 8);
        assert!(max_hysterons(3, 3, HysteronOperator::Play) > 8);
    }

    /// A 3-floor stiffness whose spring network has a negative spring (floor 1 to floor 3), as
    /// a frame's condensed stiffness may: kN/mm.
    fn frame_k() -> DMatrix<f64> {
        DMatrix::from_row_slice(
            3,
            3,
            &[180.0, -120.0, 15.0, -120.0, 200.0, -90.0, 15.0, -90.0, 80.0],
        )
    }

    fn sum_of(dirs: &[Vec<f64>], c: &[f64]) -> DMatrix<f64> {
        let mut s = DMatrix::<f64>::zeros(3, 3);
        for (a, ci) in dirs.iter().zip(c) {
            let v = DVector::from_column_slice(a);
            s += &v * v.transpose() * *ci;
        }
        s
    }

    #[test]
    fn the_flexibility_weight_is_the_squared_inverse_stiffness() {
        let k = frame_k();
        let w = flexibility_squared(&k).expect("positive definite");
        let err = (&w * &k * &k - DMatrix::<f64>::identity(3, 3)).abs().max();
        assert!(err < 1e-12, "{err}");
        assert!(
            flexibility_squared(&DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0])).is_none()
        );
    }

    /// The story directions split `K` exactly with positive shares, story 1's is its own drift,
    /// and a shear building's (tridiagonal `K`) are its story drifts.
    #[test]
    fn the_story_directions_split_k_exactly() {
        let k = frame_k();
        let (dirs, kappa) = story_directions(&k).expect("definite");
        assert_eq!(dirs[0], vec![1.0, 0.0, 0.0]);
        assert!(kappa.iter().all(|x| *x > 0.0), "{kappa:?}");
        let err = (sum_of(&dirs, &kappa) - &k).abs().max();
        assert!(err < 1e-10 * k.abs().max(), "{err}");
        let shear = DMatrix::from_row_slice(
            3,
            3,
            &[300.0, -120.0, 0.0, -120.0, 210.0, -90.0, 0.0, -90.0, 90.0],
        );
        let (dirs, kappa) = story_directions(&shear).expect("definite");
        let drifts = [[1.0, 0.0, 0.0], [-1.0, 1.0, 0.0], [0.0, -1.0, 1.0]];
        for ((a, d), (kp, want)) in dirs
            .iter()
            .zip(drifts)
            .zip(kappa.iter().zip([180.0, 120.0, 90.0]))
        {
            let off = a
                .iter()
                .zip(d)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            assert!(off < 1e-12, "{a:?}");
            assert!((kp - want).abs() < 1e-9, "{kappa:?}");
        }
        assert!(story_directions(&DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0])).is_none());
    }

    /// A frame's adjacent stories are coupled: the basis adds the sum and the difference of
    /// their directions, each of whose share alone keeps within `K` exactly; a shear building's
    /// (tridiagonal `K`) basis is its story directions alone.
    #[test]
    fn the_basis_adds_the_coupled_stories_sums_and_differences() {
        let k = frame_k();
        let (story, _) = story_directions(&k).expect("definite");
        let (dirs, kappa) = basis_directions(&k).expect("definite");
        assert_eq!(dirs.len(), 7, "{dirs:?}");
        assert_eq!(dirs[..3], story[..]);
        for (e, (s, sign)) in [(0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0)]
            .iter()
            .enumerate()
        {
            let want: Vec<f64> = story[*s]
                .iter()
                .zip(&story[s + 1])
                .map(|(x, y)| x + sign * y)
                .collect();
            assert_eq!(dirs[3 + e], want);
            let v = DVector::from_column_slice(&dirs[3 + e]);
            let mu = largest_generalized_eigenvalue(&(&v * v.transpose() * kappa[3 + e]), &k)
                .expect("definite");
            assert!((mu - 1.0).abs() < 1e-9, "{mu}");
        }
        let shear = DMatrix::from_row_slice(
            3,
            3,
            &[300.0, -120.0, 0.0, -120.0, 210.0, -90.0, 0.0, -90.0, 90.0],
        );
        let (dirs, _) = basis_directions(&shear).expect("definite");
        assert_eq!(dirs.len(), 3);
    }

    /// Dropping the directions no hysteron acts along renumbers the rest and leaves the model's
    /// steps bit for bit.
    #[test]
    fn idle_directions_are_dropped_and_the_model_steps_the_same() {
        let fm = one_floor();
        let fit = HysteronFit {
            operator: HysteronOperator::Play,
            range: THRESHOLD_RANGES[0],
            directions: vec![vec![1.0], vec![0.5], vec![1.0], vec![0.25]],
            hysterons: vec![
                HysteronSpec {
                    direction: 1,
                    threshold_mm: 20.0,
                    weight_kn_per_mm: 3.0,
                },
                HysteronSpec {
                    direction: 3,
                    threshold_mm: 40.0,
                    weight_kn_per_mm: 5.0,
                },
            ],
            stability_scale: 1.0,
            force_fit_pct: 0.0,
        };
        let lean = fit.without_idle_directions();
        assert_eq!(lean.directions, vec![vec![0.5], vec![0.25]]);
        let dirs: Vec<usize> = lean.hysterons.iter().map(|h| h.direction).collect();
        assert_eq!(dirs, vec![0, 1]);
        let dt = rths_core::params::DT_S;
        let ag: Vec<f64> = (0..6000)
            .map(|k| 40000.0 * (k as f64 * 0.004).sin())
            .collect();
        let run = |f: &HysteronFit| pure_loop(params(&fm, f, dt).expect("valid"), &ag);
        let (a, b) = (run(&fit).expect("stable"), run(&lean).expect("stable"));
        assert_eq!(a, b);
        // The first hysteron yields past 40 mm of the floor (0.5 · 40 = its 20 mm threshold).
        assert!(a[0].iter().any(|x| x.abs() > 45.0), "the run must yield");
    }
}

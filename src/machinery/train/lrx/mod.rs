//! Training of the LRX metamodel (`rths train lrx`): a specimen-faithful linear metamodel of the
//! analytical substructure alone (frame, mass, damping), plus a learned lead filter that compensates
//! the actuator's delay.
//!
//! Two least-squares fits ([`super::lstsq`], SVD of the column-normalized design matrices):
//!
//! 1. **Frame ARX** `d(i+1) = Σ_j a_j·d(i−j) + Σ_j b_j·ü_g(i−j) + Σ_j c_j·F(i−j)`, j = 0..3, on
//!    runs of the frame (by default [`frame_run_exact`], the reference's discretization; or
//!    [`frame_run`], the hybrid split by Chang: frame and mass computed, brace force fed in) in which
//!    the brace force varies independently of the displacement: braces of several stiffness factors
//!    plus band-limited random force perturbations (6th-order 10 Hz Butterworth-filtered Gaussian noise,
//!    RMS a set fraction of the run's RMS brace force), on each training ground motion. Without the
//!    perturbations, F = k·d and the force and displacement columns are collinear: the force's own
//!    effect would not be identifiable (the paper's LR problem).
//! 2. **Lead filter** `u(k) = Σ_i w_i·x_m(k − i·s)`, i = 0..8: the plant's inverse, fitted on open-loop
//!    runs of the virtual plant (`rths-hal-sim`, noise-free true displacement) commanded with the pure
//!    brace response of the training motions, for specimens of several stiffness factors.
//!
//! The force-correction stiffness of the model is the paper's brace axial stiffness k_b (prototype).
//!
//! The runs that generate the identification data are in `runs.rs`; this file holds the settings,
//! the two fits and the model file.

use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rths_core::compensator::{LEAD_MAX_STRIDE, LEAD_TAPS};
use rths_core::control::Analytical;
use rths_core::metamodel::{Lrx, LrxParams, LRX_COEFFS, LRX_ORDER};
use rths_core::metrics;
use rths_core::params::{Prototype, SpecimenScale, DT_S, PAPER_DELAY_STEPS};
use rths_hal_sim::{Preset, Specimen};

use super::lstsq;
use super::TrainError;
use crate::machinery::model_file::{LrxWeights, ModelFile};
use crate::machinery::motion::GroundMotion;

mod runs;

use runs::{band_limited_noise, rms_of};
pub use runs::{frame_run, frame_run_exact, plant_run};

/// Default training motions: `(embedded name, scale)`. Northridge at 0.5: at scale 1 its brace
/// velocity (608 mm/s) exceeds the actuator's 338.84 mm/s (`rths analyze` says ≤ 0.557 fits).
pub const DEFAULT_TRAIN_MOTIONS: [(&str, f64); 2] = [("northridge", 0.5), ("loma-prieta", 1.0)];

/// Default test motions (not used for training): El Centro at 1; Kobe at 0.75 (its velocity at scale
/// 1, 398 mm/s, exceeds the actuator's; ≤ 0.851 fits).
pub const DEFAULT_TEST_MOTIONS: [(&str, f64); 2] = [("el-centro", 1.0), ("kobe", 0.75)];

/// Time constant of the lead's online correction in a model trained on a rig file (`rths train lrx
/// --rig`), ticks: 2 s at 2048 Hz, a few periods of the structure's response, short against a
/// drift (docs/lrx.md, "Online adaptation of the lead", has the comparison).
pub const RIG_LEAD_ADAPT_TICKS: f64 = 4096.0;

/// The identified specimen's moving mass and damping (specimen scale) at prototype brace scale,
/// [kN·s²/mm, kN·s/mm]: a force `m·ẍ` on the load cell is `force_scale·m·ẍ` in the prototype, with
/// `ẍ` scaled as the displacement. A negative estimate (noise around a negligible value) is 0.
pub fn prototype_dynamics(fit: &crate::machinery::identify::estimate::SpecimenFit) -> [f64; 2] {
    let s = SpecimenScale::default();
    let per_mm = s.specimen_disp_mm(1.0);
    [fit.mass_kn_s2_per_mm, fit.damping_kn_s_per_mm]
        .map(|v| s.prototype_force_kn(v.max(0.0) * per_mm))
}

/// Settings of an LRX training run.
#[derive(Debug, Clone)]
pub struct LrxConfig {
    /// Training ground motions and their scales.
    pub motions: Vec<(GroundMotion, f64)>,
    /// Brace stiffness factors of the frame-identification runs.
    pub frame_factors: Vec<f64>,
    /// RMS of the band-limited force perturbation, as a fraction of the run's RMS brace force.
    pub perturbation: f64,
    /// Specimen stiffness factors of the plant-identification runs (lead filter).
    pub lead_factors: Vec<f64>,
    /// Tap spacing of the lead filter, ticks (1..=8).
    pub lead_stride: usize,
    /// Time constant of the model's online stiffness estimate, ticks (0: fixed at nominal).
    pub k_adapt_ticks: f64,
    /// Frame data from the reference discretization ([`frame_run_exact`]) instead of the hybrid
    /// Chang ([`frame_run`]).
    pub exact_frame: bool,
    /// Relative singular-value cut-off of both fits.
    pub rcond: f64,
    /// Plant preset of the lead identification.
    pub preset: Preset,
    /// Seed of the perturbations and the plant.
    pub seed: u64,
    /// A lead filter given instead of fitted (e.g. identified on the rig by `rths identify`):
    /// step 2 is skipped.
    pub given_lead: Option<GivenLead>,
    /// Time constant of the lead's online gain-and-delay correction, ticks (0: fixed lead; the
    /// model file then has no `lead_adapt_ticks` field, as before the adaptation existed).
    pub lead_adapt_ticks: f64,
    /// The specimen's own moving mass and damping to remove from the measured force, prototype
    /// scale (kN·s²/mm, kN·s/mm), e.g. identified on the rig; `None`: the force as measured (the
    /// model file then has no such fields).
    pub specimen_dynamics: Option<[f64; 2]>,
}

/// A lead filter fitted elsewhere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GivenLead {
    /// Weights, newest tap first.
    pub weights: [f64; LEAD_TAPS],
    /// Tap spacing, ticks.
    pub stride: usize,
    /// NRMSE of its fit, % (reported as the lead fit's).
    pub fit_nrmse_pct: f64,
}

impl LrxConfig {
    /// The defaults: [`DEFAULT_TRAIN_MOTIONS`], frame factors 0.5/1.0/1.5 on the reference
    /// discretization, perturbation 0.3, lead factors 0.7/1.0/1.3, stride 6, stiffness time constant
    /// 2048 ticks (1 s), rcond 1e-9, `unr-compact`, seed 1.
    pub fn new() -> Result<Self, TrainError> {
        let motions = DEFAULT_TRAIN_MOTIONS
            .iter()
            .map(|(n, s)| {
                GroundMotion::embedded(n)
                    .map(|m| (m, *s))
                    .ok_or_else(|| TrainError::Setting(format!("no embedded motion {n}")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            motions,
            frame_factors: vec![0.5, 1.0, 1.5],
            perturbation: 0.3,
            lead_factors: vec![0.7, 1.0, 1.3],
            lead_stride: 6,
            k_adapt_ticks: 2048.0,
            exact_frame: true,
            rcond: 1e-9,
            preset: Preset::UnrCompact,
            seed: 1,
            given_lead: None,
            lead_adapt_ticks: 0.0,
            specimen_dynamics: None,
        })
    }
}

/// The trained model and its figures.
#[derive(Debug, Clone)]
pub struct LrxTraining {
    /// The model file (kind "lrx").
    pub file: ModelFile,
    /// The frame ARX coefficients.
    pub coeffs: [f64; LRX_COEFFS],
    /// The lead weights.
    pub lead_weights: [f64; LEAD_TAPS],
    /// One-step NRMSE of the frame fit on its training data, %.
    pub frame_fit_nrmse_pct: f64,
    /// Condition number of the normalized frame design matrix.
    pub frame_condition: f64,
    /// NRMSE of the lead fit (command predicted from the displacement), %.
    pub lead_fit_nrmse_pct: f64,
    /// Condition number of the normalized lead design matrix.
    pub lead_condition: f64,
    /// `lrx-pure` NRMSE on each training motion (own force `k_b·d̂`, no actuator), %.
    pub pure_nrmse_pct: Vec<(String, f64)>,
}

/// `x(i − j)`, zero before the start.
fn lag(x: &[f64], i: usize, j: usize) -> f64 {
    if i >= j {
        x.get(i - j).copied().unwrap_or(0.0)
    } else {
        0.0
    }
}

/// The frame ARX rows of one run, appended to `rows`/`ys`.
fn frame_rows(
    ag: &[f64],
    d: &[f64],
    f: &[f64],
    rows: &mut Vec<[f64; LRX_COEFFS]>,
    ys: &mut Vec<f64>,
) {
    for i in 0..d.len().saturating_sub(1) {
        let mut r = [0.0; LRX_COEFFS];
        for j in 0..LRX_ORDER {
            r[j] = lag(d, i, j);
            r[LRX_ORDER + j] = lag(ag, i, j);
            r[2 * LRX_ORDER + j] = lag(f, i, j);
        }
        rows.push(r);
        ys.push(d[i + 1]);
    }
}

/// `lrx-pure`: the model on its own force `k_b·d̂` (fed back as measured at d̂, so the correction
/// vanishes), no actuator; NRMSE vs the pure FE brace deformation, %. The frame model alone: a
/// specimen mass and damping removal, if the model has one, is off (that force has none). The
/// model runs as core's LRX in the controller, fed its own target in force
/// (`FeedbackSource::OwnDelayed` with no delay), run by the host's driver ([`super::pure`]).
pub fn pure_nrmse_pct(params: LrxParams, ag_mm_s2: &[f64]) -> Result<f64, TrainError> {
    let params = params
        .with_specimen_dynamics(0.0, 0.0, DT_S)
        .map_err(|e| TrainError::Setting(format!("LRX parameters: {e}")))?;
    let proto = Prototype::paper();
    let reference = super::data::pure_response(&proto, ag_mm_s2, DT_S)?.brace_disp_mm;
    super::pure::nrmse(
        "lrx-pure",
        Analytical::Lrx(Lrx::new(params)),
        proto,
        0,
        ag_mm_s2,
        &reference,
    )
}

/// Train the LRX model.
pub fn train(cfg: &LrxConfig) -> Result<LrxTraining, TrainError> {
    if !(1..=LEAD_MAX_STRIDE).contains(&cfg.lead_stride) {
        return Err(TrainError::Setting(format!(
            "lead stride {} not in 1..={LEAD_MAX_STRIDE}",
            cfg.lead_stride
        )));
    }
    if cfg.motions.is_empty() || cfg.frame_factors.is_empty() || cfg.lead_factors.is_empty() {
        return Err(TrainError::Setting("no training motion or factor".into()));
    }
    let proto = Prototype::paper();
    let scale = SpecimenScale::default();
    let mut rng = StdRng::seed_from_u64(cfg.seed);
    let ags: Vec<Vec<f64>> = cfg
        .motions
        .iter()
        .map(|(m, s)| m.scaled(*s).resample_mm_s2(DT_S))
        .collect();
    if let Some(i) = ags.iter().flatten().position(|v| !v.is_finite()) {
        return Err(TrainError::NonFiniteInput(i));
    }

    // 1. Frame ARX.
    let (mut rows, mut ys) = (Vec::new(), Vec::new());
    for ag in &ags {
        for &factor in &cfg.frame_factors {
            let run = if cfg.exact_frame {
                frame_run_exact
            } else {
                frame_run
            };
            let (_, f0) = run(ag, factor, &[])?;
            let p = band_limited_noise(ag.len(), cfg.perturbation * rms_of(&f0), &mut rng)?;
            let (d, f) = run(ag, factor, &p)?;
            frame_rows(ag, &d, &f, &mut rows, &mut ys);
        }
    }
    let x = DMatrix::from_fn(rows.len(), LRX_COEFFS, |i, j| rows[i][j]);
    let y = DVector::from_vec(ys);
    let frame = lstsq::solve(&x, &y, cfg.rcond)?;
    let (theta, frame_condition) = (frame.coeffs, frame.condition_number);
    let fitted = &x * DVector::from_column_slice(&theta);
    let frame_fit_nrmse_pct = metrics::nrmse_pct(fitted.as_slice(), y.as_slice())?;
    let mut coeffs = [0.0; LRX_COEFFS];
    coeffs.iter_mut().zip(&theta).for_each(|(c, t)| *c = *t);

    // 2. Lead filter (plant inverse), unless given.
    let (lead_weights, s, lead_fit_nrmse_pct, lead_condition) = match cfg.given_lead {
        Some(g) => (g.weights, g.stride, g.fit_nrmse_pct, f64::NAN),
        None => fit_lead(cfg, &ags, &scale)?,
    };

    let k_corr = proto.brace_axial_stiffness_kn_per_mm();
    let params = LrxParams::new(coeffs, k_corr, cfg.k_adapt_ticks)
        .map_err(|e| TrainError::Diverged(format!("LRX parameters rejected: {e}")))?;
    let mut pure = Vec::new();
    for ((m, sc), ag) in cfg.motions.iter().zip(&ags) {
        pure.push((format!("{}×{sc}", m.name), pure_nrmse_pct(params, ag)?));
    }

    let mut file = ModelFile::new_lrx(
        LrxWeights {
            coeffs: coeffs.to_vec(),
            k_corr_kn_per_mm: k_corr,
            k_adapt_ticks: cfg.k_adapt_ticks,
            lead_weights: lead_weights.to_vec(),
            lead_stride: s,
            lead_adapt_ticks: (cfg.lead_adapt_ticks != 0.0).then_some(cfg.lead_adapt_ticks),
            specimen_mass_kn_s2_per_mm: cfg.specimen_dynamics.map(|d| d[0]),
            specimen_damping_kn_s_per_mm: cfg.specimen_dynamics.map(|d| d[1]),
        },
        PAPER_DELAY_STEPS,
        DT_S,
    );
    file.training.motion = cfg
        .motions
        .iter()
        .map(|(m, s)| format!("{}×{s}", m.name))
        .collect::<Vec<_>>()
        .join(",");
    file.training.records = ags.iter().map(Vec::len).sum();
    file.training.phase = 1;
    file.training.method =
        "svd-least-squares (frame ARX, force perturbations) + plant-inverse lead".into();
    file.training.seed = Some(cfg.seed);
    file.training.svd_rcond = Some(cfg.rcond);
    file.scores.train_nrmse_pct = Some(frame_fit_nrmse_pct);
    file.scores.pure_nrmse_pct = pure.iter().map(|p| p.1).reduce(f64::max);
    file.scores.lr_condition_number = frame_condition.is_finite().then_some(frame_condition);
    Ok(LrxTraining {
        file,
        coeffs,
        lead_weights,
        frame_fit_nrmse_pct,
        frame_condition,
        lead_fit_nrmse_pct,
        lead_condition,
        pure_nrmse_pct: pure,
    })
}

/// Step 2 of [`train`]: the lead filter fitted on open-loop runs of the virtual plant. Returns
/// (weights, stride, fit NRMSE %, condition number).
fn fit_lead(
    cfg: &LrxConfig,
    ags: &[Vec<f64>],
    scale: &SpecimenScale,
) -> Result<([f64; LEAD_TAPS], usize, f64, f64), TrainError> {
    let s = cfg.lead_stride;
    let (mut rows, mut ys) = (Vec::<[f64; LEAD_TAPS]>::new(), Vec::new());
    for ag in ags {
        for &factor in &cfg.lead_factors {
            let p = crate::machinery::reference::specimen_prototype(factor)?;
            let cmd: Vec<f64> = super::data::pure_response(&p, ag, DT_S)?
                .brace_disp_mm
                .iter()
                .map(|d| scale.specimen_disp_mm(*d))
                .collect();
            let (u, xm) = plant_run(cfg.preset, Specimen::Linear, factor, cfg.seed, &cmd)?;
            for (k, uk) in u.iter().enumerate() {
                let mut r = [0.0; LEAD_TAPS];
                for (i, v) in r.iter_mut().enumerate() {
                    *v = lag(&xm, k, i * s);
                }
                rows.push(r);
                ys.push(*uk);
            }
        }
    }
    let x = DMatrix::from_fn(rows.len(), LEAD_TAPS, |i, j| rows[i][j]);
    let y = DVector::from_vec(ys);
    let lead = lstsq::solve(&x, &y, cfg.rcond)?;
    let (w, lead_condition) = (lead.coeffs, lead.condition_number);
    let fitted = &x * DVector::from_column_slice(&w);
    let lead_fit_nrmse_pct = metrics::nrmse_pct(fitted.as_slice(), y.as_slice())?;
    let mut lead_weights = [0.0; LEAD_TAPS];
    lead_weights.iter_mut().zip(&w).for_each(|(c, t)| *c = *t);
    Ok((lead_weights, s, lead_fit_nrmse_pct, lead_condition))
}

#[cfg(test)]
mod tests;

//! Nonlinear numerical substructures from structure files with a `hysteresis` section: the FE
//! reference response (the whole yielding structure under a ground motion, Chang's explicit step
//! with the story forces evaluated each step), its peak ductility and residual drift, and the
//! hysteresis plot (`rths analyze --structure`; docs/nonlinear.md). With them what a structure
//! file's runs are built from: its learned model ([`model`]) and the rig compensation of its hybrid
//! runs ([`rig`]). The scenarios and the study are `crate::studies::nonlinear`.

pub mod model;
pub mod plot;
pub mod rig;

use anyhow::Context;
use rths_core::metrics::nrmse_pct;
use rths_core::structure_n::{ChangN, MAX_DOF};
use rths_files::structure_file::Structure;

/// Free vibration appended to every record so the frame comes to rest and its residual drift is
/// defined, s.
pub const FREE_VIBRATION_S: f64 = 10.0;
/// The residual drift is the mean drift over this last stretch of the free vibration, s.
pub const RESIDUAL_WINDOW_S: f64 = 2.0;
/// A reference's residual drift is judged only where the run has come to rest: the drift's
/// peak-to-peak swing over [`RESIDUAL_WINDOW_S`] at most this fraction of the residual. The mean of
/// an oscillation of peak-to-peak `s` over a window of one period or more is off by at most
/// `s / 2π`, so at 0.25 the residual is known to 4 % of itself, inside the 20 % a model is allowed.
/// A run still swinging more (a lab's history with too short a free vibration) has no residual drift
/// yet: scoring says so instead of giving a figure.
pub const AT_REST_SWING_RATIO: f64 = 0.25;

/// The tail of one drift history: its mean over the last [`RESIDUAL_WINDOW_S`] (the residual
/// drift) and its peak-to-peak swing there, mm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResidualTail {
    /// The mean over the window, mm.
    pub mean_mm: f64,
    /// Peak-to-peak over the window, mm.
    pub swing_mm: f64,
}

impl ResidualTail {
    /// The tail of `drift_mm` at step `dt_s`.
    pub fn of(drift_mm: &[f64], dt_s: f64) -> Self {
        let w = ((RESIDUAL_WINDOW_S / dt_s) as usize).max(1);
        let tail = &drift_mm[drift_mm.len().saturating_sub(w)..];
        let (lo, hi) = tail
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(*v), h.max(*v))
            });
        Self {
            mean_mm: tail.iter().sum::<f64>() / tail.len().max(1) as f64,
            swing_mm: if tail.is_empty() { 0.0 } else { hi - lo },
        }
    }

    /// Whether the run has come to rest in the sense of [`AT_REST_SWING_RATIO`].
    pub fn at_rest(&self) -> bool {
        self.swing_mm <= AT_REST_SWING_RATIO * self.mean_mm.abs()
    }
}

/// Whether a run's residual drift can be judged, and the error where it can.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ResidualJudgement {
    /// The error of the loop's residual at the story with the largest reference residual, % of it.
    Judged(f64),
    /// The reference's largest residual is under 0.1 mm: nothing to judge.
    Small,
    /// The reference is still swinging over the residual window by more than
    /// [`AT_REST_SWING_RATIO`] of its residual: the history's free vibration is too short for a
    /// residual drift to be defined.
    NotAtRest {
        /// The reference's residual at that story, mm.
        residual_mm: f64,
        /// Its peak-to-peak swing over the window, mm.
        swing_mm: f64,
    },
}

impl ResidualJudgement {
    /// The error, where judged.
    pub fn pct(&self) -> Option<f64> {
        match self {
            Self::Judged(p) => Some(*p),
            _ => None,
        }
    }
}

impl ResidualJudgement {
    /// The story a judgement is made at: the one with the largest reference residual (`None`:
    /// no story).
    pub fn story(ref_mm: &[f64]) -> Option<usize> {
        ref_mm
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .map(|(k, _)| k)
    }

    /// The judgement of a model's residual drifts `model_mm` against a reference's `ref_mm` (each
    /// story's, with their swings `ref_swing_mm` over the residual window): at the story with the
    /// largest reference residual, where that residual is 0.1 mm or more and the reference has
    /// come to rest.
    pub fn of(ref_mm: &[f64], ref_swing_mm: &[f64], model_mm: &[f64]) -> Self {
        let Some((k, r)) = Self::story(ref_mm).and_then(|k| ref_mm.get(k).map(|r| (k, r))) else {
            return Self::Small;
        };
        if r.abs() < 0.1 {
            return Self::Small;
        }
        let tail = ResidualTail {
            mean_mm: *r,
            swing_mm: ref_swing_mm.get(k).copied().unwrap_or(f64::NAN),
        };
        if !tail.at_rest() {
            return Self::NotAtRest {
                residual_mm: *r,
                swing_mm: tail.swing_mm,
            };
        }
        Self::Judged(100.0 * (model_mm.get(k).copied().unwrap_or(f64::NAN) - r).abs() / r.abs())
    }
}

/// The response of a nonlinear structure, one row per step.
#[derive(Debug, Clone, Default)]
pub struct NlResponse {
    /// Time, s.
    pub time_s: Vec<f64>,
    /// Ground acceleration, mm/s².
    pub ground_accel_mm_s2: Vec<f64>,
    /// Story drifts, mm: `story_drift_mm[story][step]`.
    pub story_drift_mm: Vec<Vec<f64>>,
    /// The numerical (yielding) story forces, kN: `story_force_kn[story][step]`.
    pub story_force_kn: Vec<Vec<f64>>,
    /// Yield drift of each story, mm.
    pub yield_drift_mm: Vec<f64>,
    /// Steps of the record itself (the rest is free vibration).
    pub record_steps: usize,
}

impl NlResponse {
    /// Peak `|drift| / u_y` over stories and time.
    pub fn peak_ductility(&self) -> f64 {
        self.story_drift_mm
            .iter()
            .zip(&self.yield_drift_mm)
            .map(|(d, uy)| d.iter().fold(0.0_f64, |m, v| m.max(v.abs())) / uy)
            .fold(0.0, f64::max)
    }

    /// Residual drift of each story: the mean over the last [`RESIDUAL_WINDOW_S`], mm.
    pub fn residual_drift_mm(&self, dt_s: f64) -> Vec<f64> {
        self.story_drift_mm
            .iter()
            .map(|d| ResidualTail::of(d, dt_s).mean_mm)
            .collect()
    }

    /// Peak `|force|` of each numerical story, kN.
    pub fn peak_story_force_kn(&self) -> Vec<f64> {
        self.story_force_kn
            .iter()
            .map(|f| f.iter().fold(0.0_f64, |m, v| m.max(v.abs())))
            .collect()
    }
}

/// The whole nonlinear structure under `ground_accel_mm_s2` (sampled at `dt_s`) followed by
/// [`FREE_VIBRATION_S`] at rest: the FE reference. Evaluation only (it knows the true structure).
pub fn fe_reference(
    structure: &Structure,
    ground_accel_mm_s2: &[f64],
    dt_s: f64,
) -> anyhow::Result<NlResponse> {
    fe_reference_free(structure, ground_accel_mm_s2, dt_s, FREE_VIBRATION_S)
}

/// [`fe_reference`] with `free_s` of free vibration instead of [`FREE_VIBRATION_S`].
pub fn fe_reference_free(
    structure: &Structure,
    ground_accel_mm_s2: &[f64],
    dt_s: f64,
    free_s: f64,
) -> anyhow::Result<NlResponse> {
    let mut frame = structure
        .nonlinear_whole(dt_s)
        .with_context(|| format!("structure {}", structure.name()))?;
    let n = frame.dofs();
    let free = (free_s.max(0.0) / dt_s) as usize;
    let total = ground_accel_mm_s2.len() + free;
    let ag = |i: usize| ground_accel_mm_s2.get(i).copied().unwrap_or(0.0);
    let mut r = NlResponse {
        time_s: Vec::with_capacity(total),
        ground_accel_mm_s2: Vec::with_capacity(total),
        story_drift_mm: vec![Vec::with_capacity(total); n],
        story_force_kn: vec![Vec::with_capacity(total); n],
        yield_drift_mm: frame
            .stories()
            .iter()
            .flatten()
            .map(|s| s.law().yield_drift_mm())
            .collect(),
        record_steps: ground_accel_mm_s2.len(),
    };
    frame.reset(ag(0));
    let zero = [0.0; MAX_DOF];
    for i in 0..total {
        if i > 0 {
            frame.advance(ag(i), &zero);
        }
        r.time_s.push(i as f64 * dt_s);
        r.ground_accel_mm_s2.push(ag(i));
        let d = frame.story_drift_mm();
        for (j, (dr, fr)) in r
            .story_drift_mm
            .iter_mut()
            .zip(&mut r.story_force_kn)
            .enumerate()
        {
            dr.push(d[j]);
            fr.push(frame.story_force_kn()[j]);
        }
    }
    if r.story_drift_mm.iter().flatten().any(|v| !v.is_finite()) {
        anyhow::bail!("the nonlinear response diverged (non-finite drift)");
    }
    Ok(r)
}

/// Story drifts of the *elastic* whole structure (every story at its initial stiffness, Chang's
/// linear path) over the same steps as `r`: what a linear numerical substructure, or a linear
/// metamodel fitted to one, would give. `story_drift_mm[story][step]`.
pub fn elastic_drifts(
    structure: &Structure,
    r: &NlResponse,
    dt_s: f64,
) -> anyhow::Result<Vec<Vec<f64>>> {
    let mut lin = ChangN::new(structure.whole()?, dt_s)?;
    let n = structure.dofs();
    let mut out = vec![Vec::with_capacity(r.time_s.len()); n];
    lin.reset(r.ground_accel_mm_s2.first().copied().unwrap_or(0.0));
    let zero = [0.0; MAX_DOF];
    for (i, &ag) in r.ground_accel_mm_s2.iter().enumerate() {
        if i > 0 {
            lin.advance(ag, &zero);
        }
        let mut below = 0.0;
        for (story, x) in out.iter_mut().zip(lin.disp()) {
            story.push(x - below);
            below = *x;
        }
    }
    Ok(out)
}

/// NRMSE (%) of each story's drift in `drifts` against the nonlinear reference `r`.
pub fn drift_nrmse_pct(drifts: &[Vec<f64>], r: &NlResponse) -> anyhow::Result<Vec<f64>> {
    drifts
        .iter()
        .zip(&r.story_drift_mm)
        .map(|(x, x_ref)| nrmse_pct(x, x_ref).map_err(|e| anyhow::anyhow!("NRMSE: {e:?}")))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT: f64 = 1.0 / 2048.0;

    /// An offset `r` with a sinusoid of peak-to-peak `swing` at `f_hz` over 10 s.
    fn tail(r: f64, swing: f64, f_hz: f64) -> Vec<f64> {
        (0..20480)
            .map(|i| r + 0.5 * swing * (2.0 * std::f64::consts::PI * f_hz * i as f64 * DT).sin())
            .collect()
    }

    #[test]
    fn a_run_at_rest_has_its_offset_as_residual() {
        let t = ResidualTail::of(&tail(2.5, 0.0, 1.0), DT);
        assert!((t.mean_mm - 2.5).abs() < 1e-12);
        assert_eq!(t.swing_mm, 0.0);
        assert!(t.at_rest());
    }

    #[test]
    fn the_swing_allowed_keeps_the_residual_within_four_percent() {
        // The worst window for a mean: not a whole number of periods. At the allowed swing the
        // residual is within s / 2π = 4 % of itself for any frequency with a period in the window.
        for f_hz in [0.5, 0.7, 1.3, 2.9, 7.1] {
            let t = ResidualTail::of(&tail(1.0, AT_REST_SWING_RATIO, f_hz), DT);
            assert!((t.mean_mm - 1.0).abs() <= 0.04, "{f_hz} Hz: {t:?}");
            // Under the allowed swing, with the window's own bias, the run is at rest.
            let t = ResidualTail::of(&tail(1.0, 0.9 * AT_REST_SWING_RATIO, f_hz), DT);
            assert!(t.at_rest(), "{f_hz} Hz: {t:?}");
        }
    }

    #[test]
    fn a_run_still_swinging_is_not_at_rest() {
        // The fiber frame's held-out runs with 5 s of free vibration: a residual of 0.3 mm under a
        // swing of 10 mm.
        let t = ResidualTail::of(&tail(-0.3, 10.0, 0.9), DT);
        assert!(!t.at_rest(), "{t:?}");
        // A run exactly at zero with no swing is at rest (nothing to judge, by the 0.1 mm rule).
        assert!(ResidualTail::of(&[0.0; 8], DT).at_rest());
        // An empty history: no swing, no residual.
        let e = ResidualTail::of(&[], DT);
        assert_eq!((e.mean_mm, e.swing_mm), (0.0, 0.0));
    }
}

//! Scoring a learned model of either form on a lab's runs: the model built for the controller's
//! step ([`Learned`]), one loop's figures against a run ([`loop_score`]), the validation loss that
//! chooses the form, and the length scale a lab would choose from the model's own prediction. The
//! held-out scoring with the hybrid loop is `crate::studies::nonlinear::held_out`.

use rths_core::control::{Analytical, StructureHysteron, StructureModal};
use rths_core::metamodel::{FloorHysteronParams, ModalHyst, ModalHystParams};
use rths_core::metrics;
use rths_core::params::{ACTUATOR_STROKE_MM, ACTUATOR_VELOCITY_MM_S, DT_S};
use rths_files::hysteron_model_file::AnyNlModel;

use super::floors::{residual_drifts, FloorRun};

/// A learned model of either form, built for the controller's step (copied into the controller
/// as its analytical part, so not boxed).
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy)]
pub enum Learned {
    /// The modal-hysteretic form.
    Modal(ModalHystParams),
    /// The floor-hysteron form.
    Hysteron(FloorHysteronParams),
}

impl Learned {
    /// The model of `file` at `dt_s`.
    pub fn of(file: &AnyNlModel, dt_s: f64) -> anyhow::Result<Self> {
        Ok(match file {
            AnyNlModel::Modal(m) => Self::Modal(m.params(dt_s)?),
            AnyNlModel::Hysteron(h) => Self::Hysteron(h.params(dt_s)?),
        })
    }

    /// The form's name.
    pub fn form(&self) -> &'static str {
        match self {
            Self::Modal(_) => "modal-hysteretic",
            Self::Hysteron(_) => "floor-hysteron",
        }
    }

    /// The specimen's floor and nominal stiffness.
    pub fn specimen(&self) -> (usize, f64) {
        match self {
            Self::Modal(p) => {
                // The modal form keeps the specimen's stiffness in its modes; the file has it.
                (p.specimen_dof(), f64::NAN)
            }
            Self::Hysteron(p) => (p.specimen_floor(), p.specimen_k_kn_per_mm()),
        }
    }

    /// The controller's analytical part.
    pub fn analytical(&self) -> Analytical {
        match self {
            Self::Modal(p) => Analytical::StructureModal(StructureModal::new(*p)),
            Self::Hysteron(p) => Analytical::StructureHysteron(StructureHysteron::new(*p)),
        }
    }

    /// The pure loop under `ag` with the specimen `k_e` at the model's own target: every floor.
    pub fn pure_loop(&self, k_e: f64, ag: &[f64]) -> Option<Vec<Vec<f64>>> {
        match self {
            Self::Modal(p) => super::runs::pure_loop(&mut ModalHyst::new(*p), k_e, ag),
            Self::Hysteron(p) => super::hysteron::pure_loop(*p, ag),
        }
    }
}

/// One loop's figures against a held-out run.
#[derive(Debug, Clone, serde::Serialize)]
pub struct LoopScore {
    /// NRMSE of the interface, % (the hybrid loop: the measured displacement).
    pub interface_nrmse_pct: Option<f64>,
    /// The hybrid loop: NRMSE of the model's own interface displacement, % (`None`: pure loop).
    pub model_interface_nrmse_pct: Option<f64>,
    /// NRMSE of each floor, %.
    pub floor_nrmse_pct: Vec<Option<f64>>,
    /// Each story's residual drift, mm.
    pub residual_mm: Vec<f64>,
    /// Why it stopped, if it did.
    pub stopped: Option<String>,
}

/// One loop's figures: the model's `floors` against the reference `run`, the interface at
/// floor `specimen`.
pub fn loop_score(floors: &[Vec<f64>], run: &FloorRun, specimen: usize) -> LoopScore {
    let nr = |a: &[f64], b: &[f64]| {
        let n = a.len().min(b.len());
        metrics::nrmse_pct(&a[..n], &b[..n]).ok()
    };
    LoopScore {
        interface_nrmse_pct: nr(&floors[specimen], &run.floor_disp_mm[specimen]),
        floor_nrmse_pct: floors
            .iter()
            .zip(&run.floor_disp_mm)
            .map(|(a, b)| nr(a, b))
            .collect(),
        residual_mm: residual_drifts(floors, DT_S),
        stopped: None,
        model_interface_nrmse_pct: None,
    }
}

/// The length scale a lab would choose from the model's own pure-loop prediction: the smallest
/// L ≥ 1 (in halves) at which the interface stays within 80 % of the stroke and of the velocity
/// limit.
pub fn length_scale(interface_mm: &[f64]) -> f64 {
    let peak = metrics::peak_abs(interface_mm);
    let vel = interface_mm
        .windows(2)
        .map(|w| (w[1] - w[0]).abs() / DT_S)
        .fold(0.0, f64::max);
    let need = (peak / (0.8 * ACTUATOR_STROKE_MM)).max(vel / (0.8 * ACTUATOR_VELOCITY_MM_S));
    ((need * 2.0).ceil() / 2.0).max(1.0)
}

/// Mean floor NRMSE (%) of the pure loop of `model` over `runs` (the validation loss that chooses
/// the form); `f64::INFINITY` if it diverges on any.
pub fn validation_loss(model: &Learned, k_e: f64, runs: &[FloorRun]) -> f64 {
    let mut total = 0.0;
    for r in runs {
        let Some(f) = model.pure_loop(k_e, &r.ground_accel_mm_s2) else {
            return f64::INFINITY;
        };
        let s = loop_score(&f, r, 0);
        let e: Vec<f64> = s
            .floor_nrmse_pct
            .iter()
            .map(|x| x.unwrap_or(f64::INFINITY))
            .collect();
        total += e.iter().sum::<f64>() / e.len().max(1) as f64;
    }
    total / runs.len().max(1) as f64
}

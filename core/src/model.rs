//! Controller assembly from a model: the analytical part and the compensator a model file (or a
//! scenario) stands for, built in one place for the host scenarios and the firmware apps alike.
//!
//! [`ModelSpec`] borrows the raw weights as a model file stores them (so firmware can keep one in a
//! `const` over its generated `&'static` arrays); [`ModelSpec::validate`] turns it into a [`Model`]
//! of validated parameters, and [`Model::assemble`] builds the parts.

use crate::compensator::{
    Ats, AtsConfig, AtsParams, Compensator, Lead, LeadAdaptParams, LeadParams, LEAD_TAPS,
};
use crate::control::{Analytical, Controller, FeModel, ReplaceError};
use crate::control::{
    FloorHysteronSpec, ModalSpec, ReducedSpec, StructureFe, StructureHysteron, StructureModal,
    StructureNl, StructureReduced, StructureSpec,
};
use crate::hysteresis::Law;
use crate::metamodel::{
    DeltaArx, DeltaArxParams, FloorHysteronParams, ModalHystParams, ReducedModalParams,
};
use crate::metamodel::{
    Lr, LrParams, Lrx, LrxParams, ModelError, Rnn, RnnParams, RnnScaling, RnnWeights,
};
use crate::params::{Prototype, DT_S};
use crate::structure_n::{StructureN, MAX_DOF};

/// The analytical part of a run (and its compensator), with raw weights borrowed as a model file
/// stores them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModelSpec<'a> {
    /// The LR metamodel, no compensator (`lr-*`).
    Lr {
        /// θ0..θ5, order [`crate::metamodel::LR_FEATURE_NAMES`].
        theta: &'a [f64],
    },
    /// An Elman RNN metamodel, no compensator (`rnn-*`).
    Rnn {
        /// Weights, row-major.
        weights: RnnWeights<'a>,
        /// Input and output scaling.
        scaling: RnnScaling,
    },
    /// The LRX frame model with its learned lead filter (`lrx-online`).
    Lrx {
        /// Frame coefficients, order [`crate::metamodel::LRX_FEATURE_NAMES`].
        coeffs: &'a [f64],
        /// Nominal force-correction stiffness, kN/mm.
        k_corr_kn_per_mm: f64,
        /// Time constant of the stiffness estimate, ticks (0: fixed).
        k_adapt_ticks: f64,
        /// Lead-filter weights, newest tap first ([`LEAD_TAPS`] of them).
        lead_weights: &'a [f64],
        /// Lead-filter tap spacing, ticks.
        lead_stride: usize,
        /// Time constant of the lead's online gain-and-delay correction, ticks (0: the lead is
        /// fixed).
        lead_adapt_ticks: f64,
        /// The specimen's own moving mass and damping removed from the measured force, prototype
        /// scale, kN·s²/mm and kN·s/mm (0, 0: the force is used as measured).
        specimen_dynamics: [f64; 2],
    },
    /// Finite elements (Chang) of the hybrid model, no compensator (`fe-pure`, `fe-online`, ...).
    Fe,
    /// Finite elements with the paper's adaptive time-series compensator (`fe-online-ats`).
    FeAts {
        /// The delay the ATS starts from, s.
        expected_delay_s: f64,
    },
    // ---- structure files (issues 15, 16); no compensator.
    /// Finite elements (Chang) of a linear N-DOF structure file's numerical part.
    StructureFe {
        /// The structure (no story laws).
        structure: StructureSpec<'a>,
    },
    /// Finite elements (Chang) of a yielding structure file's numerical part.
    StructureNl {
        /// The structure (one story law per DOF).
        structure: StructureSpec<'a>,
    },
    /// The structure metamodel (`rths train meta`).
    StructureMeta {
        /// Coefficients, [`crate::metamodel::DELTA_ARX_COEFFS`], order of
        /// [`crate::metamodel::delta_features`].
        theta: &'a [f64],
        /// The force correction's stiffness, kN/mm.
        k_corr_kn_per_mm: f64,
    },
    /// The learned modal-hysteretic metamodel of a yielding structure (`rths train nonlinear`):
    /// stepped at the controller's step whatever rate it was trained at (continuous-time modes,
    /// rate-independent laws).
    StructureModal {
        /// The model's arrays.
        model: ModalSpec<'a>,
    },
    /// The reduced-order modal model of a large linear structure (`rths train meta` on an
    /// imported OpenSees model): stepped at the controller's step (continuous-time modes).
    StructureReduced {
        /// The model's arrays.
        model: ReducedSpec<'a>,
    },
    /// The learned floor-hysteron metamodel of a yielding structure (`rths train nonlinear`, issue
    /// 25): stepped at the controller's step (continuous-time floors, rate-independent
    /// operators).
    StructureHysteron {
        /// The model's arrays.
        model: FloorHysteronSpec<'a>,
    },
}

/// A [`ModelSpec`] whose weights passed validation.
// The RNN's fixed-capacity storage dominates; there is no allocator to box it in firmware.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Model {
    /// The LR metamodel.
    Lr(LrParams),
    /// An Elman RNN metamodel.
    Rnn(RnnParams),
    /// The LRX frame model and its lead filter.
    Lrx(LrxParams, LeadParams),
    /// Finite elements, no compensator.
    Fe,
    /// Finite elements with ATS, starting from this delay, s.
    FeAts {
        /// The delay the ATS starts from, s.
        expected_delay_s: f64,
    },
    // ---- structure files (issues 15, 16).
    /// A linear N-DOF numerical part and its specimen's DOF.
    StructureFe(StructureN, usize),
    /// A yielding numerical part, its specimen's DOF and its story laws (the first N).
    StructureNl(StructureN, usize, [Law; MAX_DOF]),
    /// The structure metamodel.
    StructureMeta(DeltaArxParams),
    /// The modal-hysteretic metamodel (validated at [`DT_S`]; assembled at the controller's step).
    StructureModal(ModalHystParams),
    /// The reduced-order modal model (validated at [`DT_S`]; assembled at the controller's step).
    StructureReduced(ReducedModalParams),
    /// The floor-hysteron metamodel (validated at [`DT_S`]; rebuilt at the controller's step).
    StructureHysteron(FloorHysteronParams),
}

impl ModelSpec<'_> {
    /// Validate the weights (shapes, finiteness, ranges).
    pub fn validate(&self) -> Result<Model, ModelError> {
        Ok(match *self {
            ModelSpec::Lr { theta } => Model::Lr(LrParams::from_slice(theta)?),
            ModelSpec::Rnn { weights, scaling } => Model::Rnn(RnnParams::new(weights, scaling)?),
            ModelSpec::Lrx {
                coeffs,
                k_corr_kn_per_mm,
                k_adapt_ticks,
                lead_weights,
                lead_stride,
                lead_adapt_ticks,
                specimen_dynamics,
            } => {
                let (frame, lead) = lrx_params(
                    coeffs,
                    [k_corr_kn_per_mm, k_adapt_ticks],
                    lead_weights,
                    lead_stride,
                    lead_adapt_ticks,
                    specimen_dynamics,
                )?;
                Model::Lrx(frame, lead)
            }
            ModelSpec::Fe => Model::Fe,
            ModelSpec::FeAts { expected_delay_s } => Model::FeAts { expected_delay_s },
            ModelSpec::StructureFe { structure } => {
                // Built once to refuse a structure the integrator cannot step (singular D).
                structure.linear(DT_S)?;
                Model::StructureFe(structure.numerical()?, structure.specimen_dof)
            }
            ModelSpec::StructureNl { structure } => {
                structure.yielding(DT_S)?;
                Model::StructureNl(
                    structure.numerical()?,
                    structure.specimen_dof,
                    structure.story_laws()?,
                )
            }
            ModelSpec::StructureMeta {
                theta,
                k_corr_kn_per_mm,
            } => Model::StructureMeta(DeltaArxParams::from_slice(theta, k_corr_kn_per_mm)?),
            ModelSpec::StructureModal { model } => Model::StructureModal(model.params(DT_S)?),
            ModelSpec::StructureReduced { model } => Model::StructureReduced(model.params(DT_S)?),
            ModelSpec::StructureHysteron { model } => Model::StructureHysteron(model.params(DT_S)?),
        })
    }
}

impl Model {
    /// The analytical part and the compensator. `proto` and `dt_s` are the structure the FE models
    /// integrate and the controller step (the metamodels were trained for theirs and ignore them).
    pub fn assemble(
        &self,
        proto: Prototype,
        dt_s: f64,
    ) -> Result<(Analytical, Compensator), ModelError> {
        match *self {
            Model::Lr(p) => Ok(lr_parts(p)),
            Model::Rnn(p) => Ok(rnn_parts(p)),
            Model::Lrx(p, lead) => Ok(lrx_parts(p, lead)),
            Model::Fe => fe_parts(proto, dt_s, None),
            Model::FeAts { expected_delay_s } => fe_parts(proto, dt_s, Some(expected_delay_s)),
            Model::StructureFe(m, dof) => Ok((
                Analytical::StructureFe(StructureFe::new(m, dof, dt_s)?),
                Compensator::None,
            )),
            Model::StructureNl(m, dof, laws) => Ok((
                Analytical::StructureNl(StructureNl::build(m, &laws, dof, dt_s)?),
                Compensator::None,
            )),
            Model::StructureMeta(p) => Ok(meta_parts(p)),
            Model::StructureModal(p) => Ok(modal_parts(p.at_dt_s(dt_s)?)),
            Model::StructureReduced(p) => Ok(reduced_parts(p.at_dt_s(dt_s)?)),
            Model::StructureHysteron(p) => {
                // Chang's coefficients depend on the step: validated parameters at another step
                // cannot be rebuilt from themselves (assemble the spec instead).
                if p.dt_s() != dt_s {
                    return Err(crate::params::ParamError::OutOfRange(
                        "floor-hysteron step (validated at another step: assemble its spec)",
                    )
                    .into());
                }
                Ok(hysteron_parts(p))
            }
        }
    }
}

/// The LRX frame model and its lead filter, validated.
/// `[k_corr, k_adapt_ticks]` as [`ModelSpec::Lrx`] names them.
fn lrx_params(
    coeffs: &[f64],
    [k_corr_kn_per_mm, k_adapt_ticks]: [f64; 2],
    lead_weights: &[f64],
    lead_stride: usize,
    lead_adapt_ticks: f64,
    [mass, damping]: [f64; 2],
) -> Result<(LrxParams, LeadParams), ModelError> {
    let mut frame = LrxParams::from_slice(coeffs, k_corr_kn_per_mm, k_adapt_ticks)?;
    // The frame ARX is identified at the controller's tick: its own derivatives use that step.
    if mass != 0.0 || damping != 0.0 {
        frame = frame.with_specimen_dynamics(mass, damping, DT_S)?;
    }
    Ok((
        frame,
        lead_params(lead_weights, lead_stride, lead_adapt_ticks)?,
    ))
}

/// The LRX model's lead filter (a model file's or a rig upload's `lead_weights`, `lead_stride`,
/// `lead_adapt_ticks`), validated.
pub fn lead_params(
    lead_weights: &[f64],
    lead_stride: usize,
    lead_adapt_ticks: f64,
) -> Result<LeadParams, ModelError> {
    let weights: [f64; LEAD_TAPS] = lead_weights.try_into().map_err(|_| ModelError::Shape {
        what: "LRX lead weights",
        expected: LEAD_TAPS,
        got: lead_weights.len(),
    })?;
    // 0 (or an old file's missing field) keeps the lead fixed, exactly as before the adaptation.
    let adapt = if lead_adapt_ticks == 0.0 {
        None
    } else {
        Some(LeadAdaptParams::new(lead_adapt_ticks)?)
    };
    Ok(LeadParams::new(weights, lead_stride)?.with_adaptation(adapt))
}

fn lr_parts(p: LrParams) -> (Analytical, Compensator) {
    (Analytical::Lr(Lr::new(p)), Compensator::None)
}

fn rnn_parts(p: RnnParams) -> (Analytical, Compensator) {
    (Analytical::Rnn(Rnn::new(p)), Compensator::None)
}

fn lrx_parts(p: LrxParams, lead: LeadParams) -> (Analytical, Compensator) {
    (
        Analytical::Lrx(Lrx::new(p)),
        Compensator::Lead(Lead::new(lead)),
    )
}

/// The FE model of `proto`, with ATS starting from `ats_delay_s` if given.
fn fe_parts(
    proto: Prototype,
    dt_s: f64,
    ats_delay_s: Option<f64>,
) -> Result<(Analytical, Compensator), ModelError> {
    let compensator = match ats_delay_s {
        Some(delay_s) => {
            Compensator::Ats(Ats::new(AtsParams::new(AtsConfig::paper(dt_s, delay_s))?))
        }
        None => Compensator::None,
    };
    Ok((Analytical::Fe(FeModel::new(proto, dt_s)?), compensator))
}

/// Validate `spec` and build its analytical part and compensator (as [`Model::assemble`] does).
///
/// The FE and RNN kinds are built without a whole [`Model`] in between: a `Model` is as large as its
/// largest variant (an RNN at [`crate::metamodel::RNN_MAX_HIDDEN`], ~9 kB), stack the firmware's
/// start-up cannot spare beside the ~44 kB FE+ATS parts (it overflowed in QEMU).
pub fn assemble(
    spec: &ModelSpec<'_>,
    proto: Prototype,
    dt_s: f64,
) -> Result<(Analytical, Compensator), ModelError> {
    match *spec {
        ModelSpec::Lr { theta } => Ok(lr_parts(LrParams::from_slice(theta)?)),
        ModelSpec::Rnn { weights, scaling } => Ok(rnn_parts(RnnParams::new(weights, scaling)?)),
        // Its parameters are small: through `Model`, as the host validates it.
        ModelSpec::Lrx { .. } => spec.validate()?.assemble(proto, dt_s),
        ModelSpec::Fe => fe_parts(proto, dt_s, None),
        ModelSpec::FeAts { expected_delay_s } => fe_parts(proto, dt_s, Some(expected_delay_s)),
        // Built in place, not through `Model` (stack, as above).
        ModelSpec::StructureFe { structure } => Ok((
            Analytical::StructureFe(structure.linear(dt_s)?),
            Compensator::None,
        )),
        ModelSpec::StructureNl { structure } => Ok((
            Analytical::StructureNl(structure.yielding(dt_s)?),
            Compensator::None,
        )),
        ModelSpec::StructureMeta {
            theta,
            k_corr_kn_per_mm,
        } => Ok(meta_parts(DeltaArxParams::from_slice(
            theta,
            k_corr_kn_per_mm,
        )?)),
        ModelSpec::StructureModal { model } => Ok(modal_parts(model.params(dt_s)?)),
        ModelSpec::StructureReduced { model } => Ok(reduced_parts(model.params(dt_s)?)),
        ModelSpec::StructureHysteron { model } => Ok(hysteron_parts(model.params(dt_s)?)),
    }
}

fn hysteron_parts(p: FloorHysteronParams) -> (Analytical, Compensator) {
    (
        Analytical::StructureHysteron(StructureHysteron::new(p)),
        Compensator::None,
    )
}

fn reduced_parts(p: ReducedModalParams) -> (Analytical, Compensator) {
    (
        Analytical::StructureReduced(StructureReduced::new(p)),
        Compensator::None,
    )
}

fn meta_parts(p: DeltaArxParams) -> (Analytical, Compensator) {
    (
        Analytical::StructureMeta(DeltaArx::new(p)),
        Compensator::None,
    )
}

fn modal_parts(p: ModalHystParams) -> (Analytical, Compensator) {
    (
        Analytical::StructureModal(StructureModal::new(p)),
        Compensator::None,
    )
}

/// Validate `spec` and build its analytical part and compensator into `ctl` in place (a
/// controller from [`Controller::init_in`]): the same controller as
/// `Controller::new(config, assemble(spec, proto, dt_s))`, without the ~44 KiB of parts ever being
/// a value on the stack (the firmware's start-up). Refused: `ctl`'s parts are unspecified (a
/// start-up failure).
pub fn assemble_in(
    ctl: &mut Controller,
    spec: &ModelSpec<'_>,
    proto: Prototype,
    dt_s: f64,
) -> Result<(), ReplaceError> {
    // Each kind is built by its own out-of-line function: a caller with a run-time spec (a model
    // upload, the firmware's compiled-in default) then reserves the frame of one kind, not of
    // every kind's temporaries at once (~47 KiB with the ATS and the structure parts).
    match *spec {
        ModelSpec::Lr { theta } => in_place::lr(ctl, theta),
        ModelSpec::Rnn { weights, scaling } => in_place::rnn(ctl, weights, scaling),
        ModelSpec::Lrx { .. } => in_place::lrx(ctl, spec),
        ModelSpec::Fe => in_place::fe(ctl, proto, dt_s, None),
        ModelSpec::FeAts { expected_delay_s } => {
            in_place::fe(ctl, proto, dt_s, Some(expected_delay_s))
        }
        ModelSpec::StructureFe { structure } => in_place::structure_fe(ctl, &structure, dt_s),
        ModelSpec::StructureNl { structure } => in_place::structure_nl(ctl, &structure, dt_s),
        ModelSpec::StructureMeta {
            theta,
            k_corr_kn_per_mm,
        } => in_place::meta(ctl, theta, k_corr_kn_per_mm),
        ModelSpec::StructureModal { model } => in_place::modal(ctl, &model, dt_s),
        ModelSpec::StructureReduced { model } => in_place::reduced(ctl, &model, dt_s),
        ModelSpec::StructureHysteron { model } => in_place::hysteron(ctl, &model, dt_s),
    }
}

/// [`assemble_in`]'s kinds, one out-of-line function each (see there).
mod in_place {
    use super::*;

    #[inline(never)]
    pub(super) fn lr(ctl: &mut Controller, theta: &[f64]) -> Result<(), ReplaceError> {
        ctl.install_lr(LrParams::from_slice(theta)?)
    }

    #[inline(never)]
    pub(super) fn rnn(
        ctl: &mut Controller,
        weights: RnnWeights<'_>,
        scaling: RnnScaling,
    ) -> Result<(), ReplaceError> {
        ctl.install_rnn(weights, scaling)
    }

    #[inline(never)]
    pub(super) fn lrx(ctl: &mut Controller, spec: &ModelSpec<'_>) -> Result<(), ReplaceError> {
        let ModelSpec::Lrx {
            coeffs,
            k_corr_kn_per_mm,
            k_adapt_ticks,
            lead_weights,
            lead_stride,
            lead_adapt_ticks,
            specimen_dynamics,
        } = *spec
        else {
            return Err(ReplaceError::Kind);
        };
        let (frame, lead) = lrx_params(
            coeffs,
            [k_corr_kn_per_mm, k_adapt_ticks],
            lead_weights,
            lead_stride,
            lead_adapt_ticks,
            specimen_dynamics,
        )?;
        ctl.set_lrx(frame, lead)?;
        Ok(())
    }

    /// The FE model, with the ATS starting from `ats_delay_s` if given (built in place).
    #[inline(never)]
    pub(super) fn fe(
        ctl: &mut Controller,
        proto: Prototype,
        dt_s: f64,
        ats_delay_s: Option<f64>,
    ) -> Result<(), ReplaceError> {
        let ats = match ats_delay_s {
            Some(d) => Some(AtsParams::new(AtsConfig::paper(dt_s, d))?),
            None => None,
        };
        ctl.install_fe(FeModel::new(proto, dt_s)?)?;
        match ats {
            Some(a) => ctl.install_ats(a),
            None => Ok(()),
        }
    }

    #[inline(never)]
    pub(super) fn structure_fe(
        ctl: &mut Controller,
        structure: &StructureSpec<'_>,
        dt_s: f64,
    ) -> Result<(), ReplaceError> {
        ctl.install_plain(Analytical::StructureFe(structure.linear(dt_s)?))
    }

    #[inline(never)]
    pub(super) fn structure_nl(
        ctl: &mut Controller,
        structure: &StructureSpec<'_>,
        dt_s: f64,
    ) -> Result<(), ReplaceError> {
        ctl.install_plain(Analytical::StructureNl(structure.yielding(dt_s)?))
    }

    #[inline(never)]
    pub(super) fn meta(
        ctl: &mut Controller,
        theta: &[f64],
        k_corr_kn_per_mm: f64,
    ) -> Result<(), ReplaceError> {
        ctl.install_plain(meta_parts(DeltaArxParams::from_slice(theta, k_corr_kn_per_mm)?).0)
    }

    #[inline(never)]
    pub(super) fn modal(
        ctl: &mut Controller,
        model: &ModalSpec<'_>,
        dt_s: f64,
    ) -> Result<(), ReplaceError> {
        ctl.install_plain(modal_parts(model.params(dt_s)?).0)
    }

    #[inline(never)]
    pub(super) fn reduced(
        ctl: &mut Controller,
        model: &ReducedSpec<'_>,
        dt_s: f64,
    ) -> Result<(), ReplaceError> {
        ctl.install_plain(reduced_parts(model.params(dt_s)?).0)
    }

    #[inline(never)]
    pub(super) fn hysteron(
        ctl: &mut Controller,
        model: &FloorHysteronSpec<'_>,
        dt_s: f64,
    ) -> Result<(), ReplaceError> {
        ctl.install_plain(hysteron_parts(model.params(dt_s)?).0)
    }
}

#[cfg(test)]
mod tests;

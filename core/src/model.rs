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
#[cfg(feature = "structures")]
use crate::control::{StructureFe, StructureNl, StructureSpec};
#[cfg(feature = "structures")]
use crate::hysteresis::Law;
#[cfg(feature = "structures")]
use crate::metamodel::{DeltaArx, DeltaArxParams};
use crate::metamodel::{
    Lr, LrParams, Lrx, LrxParams, ModelError, Rnn, RnnParams, RnnScaling, RnnWeights,
};
use crate::params::{Prototype, DT_S};
#[cfg(feature = "structures")]
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
    #[cfg(feature = "structures")]
    /// Finite elements (Chang) of a linear N-DOF structure file's numerical part.
    StructureFe {
        /// The structure (no story laws).
        structure: StructureSpec<'a>,
    },
    #[cfg(feature = "structures")]
    /// Finite elements (Chang) of a yielding structure file's numerical part.
    StructureNl {
        /// The structure (one story law per DOF).
        structure: StructureSpec<'a>,
    },
    #[cfg(feature = "structures")]
    /// The structure metamodel (`rths train meta`).
    StructureMeta {
        /// Coefficients, [`crate::metamodel::DELTA_ARX_COEFFS`], order of
        /// [`crate::metamodel::delta_features`].
        theta: &'a [f64],
        /// The force correction's stiffness, kN/mm.
        k_corr_kn_per_mm: f64,
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
    #[cfg(feature = "structures")]
    /// A linear N-DOF numerical part and its specimen's DOF.
    StructureFe(StructureN, usize),
    #[cfg(feature = "structures")]
    /// A yielding numerical part, its specimen's DOF and its story laws (the first N).
    StructureNl(StructureN, usize, [Law; MAX_DOF]),
    #[cfg(feature = "structures")]
    /// The structure metamodel.
    StructureMeta(DeltaArxParams),
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
            #[cfg(feature = "structures")]
            ModelSpec::StructureFe { structure } => {
                // Built once to refuse a structure the integrator cannot step (singular D).
                structure.linear(DT_S)?;
                Model::StructureFe(structure.numerical()?, structure.specimen_dof)
            }
            #[cfg(feature = "structures")]
            ModelSpec::StructureNl { structure } => {
                structure.yielding(DT_S)?;
                Model::StructureNl(
                    structure.numerical()?,
                    structure.specimen_dof,
                    structure.story_laws()?,
                )
            }
            #[cfg(feature = "structures")]
            ModelSpec::StructureMeta {
                theta,
                k_corr_kn_per_mm,
            } => Model::StructureMeta(DeltaArxParams::from_slice(theta, k_corr_kn_per_mm)?),
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
            #[cfg(feature = "structures")]
            Model::StructureFe(m, dof) => Ok((
                Analytical::StructureFe(StructureFe::new(m, dof, dt_s)?),
                Compensator::None,
            )),
            #[cfg(feature = "structures")]
            Model::StructureNl(m, dof, laws) => Ok((
                Analytical::StructureNl(StructureNl::build(m, &laws, dof, dt_s)?),
                Compensator::None,
            )),
            #[cfg(feature = "structures")]
            Model::StructureMeta(p) => Ok(meta_parts(p)),
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
        #[cfg(feature = "structures")]
        ModelSpec::StructureFe { structure } => Ok((
            Analytical::StructureFe(structure.linear(dt_s)?),
            Compensator::None,
        )),
        #[cfg(feature = "structures")]
        ModelSpec::StructureNl { structure } => Ok((
            Analytical::StructureNl(structure.yielding(dt_s)?),
            Compensator::None,
        )),
        #[cfg(feature = "structures")]
        ModelSpec::StructureMeta {
            theta,
            k_corr_kn_per_mm,
        } => Ok(meta_parts(DeltaArxParams::from_slice(
            theta,
            k_corr_kn_per_mm,
        )?)),
    }
}

#[cfg(feature = "structures")]
fn meta_parts(p: DeltaArxParams) -> (Analytical, Compensator) {
    (
        Analytical::StructureMeta(DeltaArx::new(p)),
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
    match *spec {
        ModelSpec::Lr { theta } => ctl.install_lr(LrParams::from_slice(theta)?),
        ModelSpec::Rnn { weights, scaling } => ctl.install_rnn(weights, scaling),
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
            ctl.set_lrx(frame, lead)?;
            Ok(())
        }
        ModelSpec::Fe => ctl.install_fe(FeModel::new(proto, dt_s)?),
        ModelSpec::FeAts { expected_delay_s } => {
            let ats = AtsParams::new(AtsConfig::paper(dt_s, expected_delay_s))?;
            ctl.install_fe(FeModel::new(proto, dt_s)?)?;
            ctl.install_ats(ats)
        }
        #[cfg(feature = "structures")]
        ModelSpec::StructureFe { structure } => {
            ctl.install_plain(Analytical::StructureFe(structure.linear(dt_s)?))
        }
        #[cfg(feature = "structures")]
        ModelSpec::StructureNl { structure } => {
            ctl.install_plain(Analytical::StructureNl(structure.yielding(dt_s)?))
        }
        #[cfg(feature = "structures")]
        ModelSpec::StructureMeta {
            theta,
            k_corr_kn_per_mm,
        } => ctl.install_plain(meta_parts(DeltaArxParams::from_slice(theta, k_corr_kn_per_mm)?).0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const THETA: [f64; 6] = [0.0, 1e-7, 0.0, 0.0, 1.99, -0.99];
    /// Firmware keeps its spec in a `const` over `&'static` arrays.
    const LR: ModelSpec<'static> = ModelSpec::Lr { theta: &THETA };

    #[test]
    fn each_spec_assembles_its_parts() -> Result<(), ModelError> {
        let p = Prototype::paper();
        let (a, c) = assemble(&LR, p, DT_S)?;
        assert!(matches!((a, c), (Analytical::Lr(_), Compensator::None)));
        let lead = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let coeffs = [0.0; 9];
        let lrx = ModelSpec::Lrx {
            coeffs: &coeffs,
            k_corr_kn_per_mm: 1.0,
            k_adapt_ticks: 0.0,
            lead_weights: &lead,
            lead_stride: 2,
            lead_adapt_ticks: 0.0,
            specimen_dynamics: [0.0; 2],
        };
        let (a, c) = assemble(&lrx, p, DT_S)?;
        assert!(matches!((a, c), (Analytical::Lrx(_), Compensator::Lead(_))));
        let (a, c) = assemble(&ModelSpec::Fe, p, DT_S)?;
        assert!(matches!((a, c), (Analytical::Fe(_), Compensator::None)));
        let ats = ModelSpec::FeAts {
            expected_delay_s: 28.0 * DT_S,
        };
        let (a, c) = assemble(&ats, p, DT_S)?;
        assert!(matches!((a, c), (Analytical::Fe(_), Compensator::Ats(_))));
        let h = 2;
        let w = [0.1; 4];
        let rnn = ModelSpec::Rnn {
            weights: RnnWeights {
                w_ih: &w,
                w_hh: &w,
                b_h: &w[..h],
                w_ho: &w[..h],
                b_o: 0.0,
            },
            scaling: RnnScaling {
                input_mean: [0.0; 2],
                input_std: [1.0; 2],
                output_mean: 0.0,
                output_std: 1.0,
            },
        };
        let (a, c) = assemble(&rnn, p, DT_S)?;
        assert!(matches!((a, c), (Analytical::Rnn(_), Compensator::None)));
        Ok(())
    }

    /// `assemble_in` builds exactly the parts `Controller::new` gets from `assemble`, for every
    /// kind, and they run the same.
    #[test]
    fn assemble_in_builds_the_same_controller_in_place() {
        use crate::control::{ControlConfig, FeedbackSource};
        use crate::hal::Sample;
        use crate::params::SpecimenScale;
        use crate::supervisor::Limits;
        let p = Prototype::paper();
        let cfg = ControlConfig::new(
            p,
            SpecimenScale::default(),
            FeedbackSource::Measured,
            Limits::paper_actuator(),
        )
        .unwrap();
        let lead = [1.2, -0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let coeffs = [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.9, -0.9, 0.0];
        let w = [0.1, -0.2, 0.3, 0.05];
        let specs = [
            LR,
            ModelSpec::Lrx {
                coeffs: &coeffs,
                k_corr_kn_per_mm: 12.0,
                k_adapt_ticks: 4096.0,
                lead_weights: &lead,
                lead_stride: 2,
                lead_adapt_ticks: 4096.0,
                specimen_dynamics: [1e-5, 2e-3],
            },
            ModelSpec::Rnn {
                weights: RnnWeights {
                    w_ih: &w,
                    w_hh: &w,
                    b_h: &w[..2],
                    w_ho: &w[2..],
                    b_o: 0.1,
                },
                scaling: RnnScaling {
                    input_mean: [0.5, -0.5],
                    input_std: [100.0, 10.0],
                    output_mean: 0.0,
                    output_std: 2.0,
                },
            },
            ModelSpec::Fe,
            ModelSpec::FeAts {
                expected_delay_s: 28.0 * DT_S,
            },
        ];
        for spec in &specs {
            let (a, c) = assemble(spec, p, DT_S).unwrap();
            let mut by_value = Controller::new(cfg, a, c);
            let mut slot = core::mem::MaybeUninit::uninit();
            let in_place = Controller::init_in(&mut slot, cfg);
            assemble_in(in_place, spec, p, DT_S).unwrap();
            assert_eq!(in_place.analytical(), by_value.analytical(), "{spec:?}");
            assert_eq!(in_place.compensator(), by_value.compensator(), "{spec:?}");
            for ctl in [&mut by_value, &mut *in_place] {
                ctl.supervisor_mut().arm().unwrap();
                ctl.supervisor_mut().start().unwrap();
            }
            for k in 0..400 {
                let ag = 1000.0 * libm::sin(k as f64 * 0.05);
                let s = Sample {
                    disp_mm: 0.01 * libm::sin(k as f64 * 0.05),
                    force_kn: 0.2 * libm::cos(k as f64 * 0.05),
                };
                let x = by_value.tick(ag, Ok(s), false);
                let y = in_place.tick(ag, Ok(s), false);
                let bits = |o: crate::control::TickOutput| {
                    (
                        [o.command_mm, o.target_mm, o.requested_mm].map(f64::to_bits),
                        o.state,
                        o.sample_held,
                    )
                };
                assert_eq!(bits(x), bits(y), "{spec:?} tick {k}");
            }
        }
        // Refused: bad weights.
        let mut slot = core::mem::MaybeUninit::uninit();
        let ctl = Controller::init_in(&mut slot, cfg);
        let bad = ModelSpec::Lr { theta: &[0.0; 5] };
        assert!(assemble_in(ctl, &bad, p, DT_S).is_err());
    }

    #[test]
    fn bad_weights_are_refused() {
        let short = [0.0; 5];
        assert!(matches!(
            assemble(&ModelSpec::Lr { theta: &short }, Prototype::paper(), DT_S),
            Err(ModelError::Shape { .. })
        ));
        let lrx = ModelSpec::Lrx {
            coeffs: &[0.0; 9],
            k_corr_kn_per_mm: 1.0,
            k_adapt_ticks: 0.0,
            lead_weights: &[1.0; 7],
            lead_stride: 1,
            lead_adapt_ticks: 0.0,
            specimen_dynamics: [0.0; 2],
        };
        assert!(matches!(
            lrx.validate(),
            Err(ModelError::Shape {
                expected: 8,
                got: 7,
                ..
            })
        ));
        assert!(assemble(&ModelSpec::Fe, Prototype::paper(), 0.0).is_err());
    }
}

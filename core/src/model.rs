//! Controller assembly from a model: the analytical part and the compensator a model file (or a
//! scenario) stands for, built in one place for the host scenarios and the firmware apps alike.
//!
//! [`ModelSpec`] borrows the raw weights as a model file stores them (so firmware can keep one in a
//! `const` over its generated `&'static` arrays); [`ModelSpec::validate`] turns it into a [`Model`]
//! of validated parameters, and [`Model::assemble`] builds the parts.

use crate::compensator::{Ats, AtsConfig, AtsParams, Compensator, Lead, LeadParams, LEAD_TAPS};
use crate::control::{Analytical, FeModel};
use crate::metamodel::{
    Lr, LrParams, Lrx, LrxParams, ModelError, Rnn, RnnParams, RnnScaling, RnnWeights,
};
use crate::params::Prototype;

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
    },
    /// Finite elements (Chang) of the hybrid model, no compensator (`fe-pure`, `fe-online`, ...).
    Fe,
    /// Finite elements with the paper's adaptive time-series compensator (`fe-online-ats`).
    FeAts {
        /// The delay the ATS starts from, s.
        expected_delay_s: f64,
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
            } => {
                let frame = LrxParams::from_slice(coeffs, k_corr_kn_per_mm, k_adapt_ticks)?;
                let weights: [f64; LEAD_TAPS] =
                    lead_weights.try_into().map_err(|_| ModelError::Shape {
                        what: "LRX lead weights",
                        expected: LEAD_TAPS,
                        got: lead_weights.len(),
                    })?;
                Model::Lrx(frame, LeadParams::new(weights, lead_stride)?)
            }
            ModelSpec::Fe => Model::Fe,
            ModelSpec::FeAts { expected_delay_s } => Model::FeAts { expected_delay_s },
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
        Ok(match *self {
            Model::Lr(p) => (Analytical::Lr(Lr::new(p)), Compensator::None),
            Model::Rnn(p) => (Analytical::Rnn(Rnn::new(p)), Compensator::None),
            Model::Lrx(p, lead) => (
                Analytical::Lrx(Lrx::new(p)),
                Compensator::Lead(Lead::new(lead)),
            ),
            Model::Fe => (
                Analytical::Fe(FeModel::new(proto, dt_s)?),
                Compensator::None,
            ),
            Model::FeAts { expected_delay_s } => (
                Analytical::Fe(FeModel::new(proto, dt_s)?),
                Compensator::Ats(Ats::new(AtsParams::new(AtsConfig::paper(
                    dt_s,
                    expected_delay_s,
                ))?)),
            ),
        })
    }
}

/// Validate `spec` and build its analytical part and compensator (see [`Model::assemble`]).
pub fn assemble(
    spec: &ModelSpec<'_>,
    proto: Prototype,
    dt_s: f64,
) -> Result<(Analytical, Compensator), ModelError> {
    spec.validate()?.assemble(proto, dt_s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::DT_S;

    const THETA: [f64; 6] = [0.0, 1e-7, 0.0, 0.0, 1.99, -0.99];
    /// Firmware keeps its spec in a `const` over `&'static` arrays.
    const LR: ModelSpec<'static> = ModelSpec::Lr { theta: &THETA };

    #[test]
    fn each_spec_assembles_its_parts() {
        let p = Prototype::paper();
        let (a, c) = assemble(&LR, p, DT_S).unwrap();
        assert!(matches!((a, c), (Analytical::Lr(_), Compensator::None)));
        let lead = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let coeffs = [0.0; 9];
        let lrx = ModelSpec::Lrx {
            coeffs: &coeffs,
            k_corr_kn_per_mm: 1.0,
            k_adapt_ticks: 0.0,
            lead_weights: &lead,
            lead_stride: 2,
        };
        let (a, c) = assemble(&lrx, p, DT_S).unwrap();
        assert!(matches!((a, c), (Analytical::Lrx(_), Compensator::Lead(_))));
        let (a, c) = assemble(&ModelSpec::Fe, p, DT_S).unwrap();
        assert!(matches!((a, c), (Analytical::Fe(_), Compensator::None)));
        let ats = ModelSpec::FeAts {
            expected_delay_s: 28.0 * DT_S,
        };
        let (a, c) = assemble(&ats, p, DT_S).unwrap();
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
        let (a, c) = assemble(&rnn, p, DT_S).unwrap();
        assert!(matches!((a, c), (Analytical::Rnn(_), Compensator::None)));
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

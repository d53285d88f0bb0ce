//! From a validated model file to the `no_std` inference parameters the controller runs (through
//! `rths_core::model::ModelSpec`, the firmware's path too).

use rths_core::compensator::LeadParams;
use rths_core::metamodel::{LrParams, LrxParams, ModelError, RnnParams, RnnScaling, RnnWeights};
use rths_core::model::{Model, ModelSpec};

use crate::machinery::model_file::{ModelFile, ModelFileError, ModelKind};

/// Why a model file could not become controller parameters.
#[derive(Debug, thiserror::Error)]
pub enum ToParamsError {
    /// The file itself is invalid or of the other kind.
    #[error(transparent)]
    File(#[from] ModelFileError),
    /// The core validation refused the weights.
    #[error("model rejected by the controller: {0:?}")]
    Core(ModelError),
    /// Made at another controller rate than this build's.
    #[error(transparent)]
    Rate(#[from] rths_files::rate::OtherRate),
}

/// The command that trains a model of `m`'s kind at this build's rate.
fn train_command(m: &ModelFile) -> String {
    match (m.kind, &m.rnn) {
        (ModelKind::Rnn, Some(w)) => format!("rths train rnn --hidden {} --out FILE", w.hidden),
        (kind, _) => format!("rths train {kind} --out FILE"),
    }
}

/// The checks every model file passes before the controller runs it, whoever loads it (`rths
/// simulate`, `rths check-model`, the studies): [`ModelFile::validate`] (format, shapes, weights,
/// `delay_steps` ≤ the controller's maximum) and a `dt_s` equal to this build's
/// [`rths_core::params::DT_S`] (else refused with the command that trains one at this rate).
pub fn check_for_controller(m: &ModelFile) -> Result<(), ToParamsError> {
    m.validate()?;
    rths_files::rate::check_dt(
        &format!("the {} model", m.kind),
        m.dt_s,
        rths_core::params::DT_S,
        &train_command(m),
    )?;
    Ok(())
}

/// The validated controller model of a model file of any kind: the file's weights as a
/// `rths_core::model::ModelSpec`, checked by the same `ModelSpec::validate` the firmware runs.
pub fn model(m: &ModelFile) -> Result<Model, ToParamsError> {
    check_for_controller(m)?;
    let missing = || ModelFileError::MissingSection { kind: m.kind };
    let spec_result = match m.kind {
        ModelKind::Lr => {
            let w = m.lr.as_ref().ok_or_else(missing)?;
            ModelSpec::Lr { theta: &w.theta }.validate()
        }
        ModelKind::Lrx => {
            let w = m.lrx.as_ref().ok_or_else(missing)?;
            ModelSpec::Lrx {
                coeffs: &w.coeffs,
                k_corr_kn_per_mm: w.k_corr_kn_per_mm,
                k_adapt_ticks: w.k_adapt_ticks,
                lead_weights: &w.lead_weights,
                lead_stride: w.lead_stride,
                lead_adapt_ticks: w.lead_adapt_ticks.unwrap_or(0.0),
                specimen_dynamics: [
                    w.specimen_mass_kn_s2_per_mm.unwrap_or(0.0),
                    w.specimen_damping_kn_s_per_mm.unwrap_or(0.0),
                ],
            }
            .validate()
        }
        ModelKind::Rnn => {
            let w = m.rnn.as_ref().ok_or_else(missing)?;
            let w_ih: Vec<f64> = w.w_ih.iter().flatten().copied().collect();
            let w_hh: Vec<f64> = w.w_hh.iter().flatten().copied().collect();
            // validate() checked the two-element shapes.
            let pair = |v: &[f64]| {
                [
                    v.first().copied().unwrap_or(0.0),
                    v.get(1).copied().unwrap_or(0.0),
                ]
            };
            ModelSpec::Rnn {
                weights: RnnWeights {
                    w_ih: &w_ih,
                    w_hh: &w_hh,
                    b_h: &w.b_h,
                    w_ho: &w.w_ho,
                    b_o: w.b_o,
                },
                scaling: RnnScaling {
                    input_mean: pair(&w.input_mean),
                    input_std: pair(&w.input_std),
                    output_mean: w.output_mean,
                    output_std: w.output_std,
                },
            }
            .validate()
        }
    };
    spec_result.map_err(ToParamsError::Core)
}

/// The frame model and the lead filter of an LRX model file.
pub fn lrx_params(m: &ModelFile) -> Result<(LrxParams, LeadParams), ToParamsError> {
    m.expect_kind(ModelKind::Lrx)?;
    match model(m)? {
        Model::Lrx(frame, lead) => Ok((frame, lead)),
        _ => Err(ModelFileError::MissingSection { kind: m.kind }.into()),
    }
}

/// The LR coefficients of an LR model file.
pub fn lr_params(m: &ModelFile) -> Result<LrParams, ToParamsError> {
    m.expect_kind(ModelKind::Lr)?;
    match model(m)? {
        Model::Lr(p) => Ok(p),
        _ => Err(ModelFileError::MissingSection { kind: m.kind }.into()),
    }
}

/// The RNN parameters of an RNN model file.
pub fn rnn_params(m: &ModelFile) -> Result<RnnParams, ToParamsError> {
    m.expect_kind(ModelKind::Rnn)?;
    match model(m)? {
        Model::Rnn(p) => Ok(p),
        _ => Err(ModelFileError::MissingSection { kind: m.kind }.into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machinery::model_file::RnnWeights as FileRnn;

    #[test]
    fn lr_file_to_params_and_kind_checks() {
        let m = ModelFile::new_lr(
            vec![0.0, 1e-7, 0.0, 0.0, 2.0, -1.0],
            28,
            rths_core::params::DT_S,
        );
        assert_eq!(lr_params(&m).unwrap().theta()[4], 2.0);
        assert!(matches!(
            rnn_params(&m),
            Err(ToParamsError::File(ModelFileError::WrongKind { .. }))
        ));
    }

    #[test]
    fn rnn_file_to_params() {
        let h = 3;
        let w = FileRnn {
            hidden: h,
            w_ih: vec![vec![0.1, 0.2]; h],
            w_hh: vec![vec![0.0; h]; h],
            b_h: vec![0.0; h],
            w_ho: vec![1.0; h],
            b_o: 0.5,
            input_mean: vec![0.0, 0.0],
            input_std: vec![1.0, 1.0],
            output_mean: 0.0,
            output_std: 2.0,
        };
        let m = ModelFile::new_rnn(w, 28, rths_core::params::DT_S);
        let p = rnn_params(&m).unwrap();
        assert_eq!(p.hidden(), h);
        let mut bad = m.clone();
        if let Some(r) = bad.rnn.as_mut() {
            r.w_hh[1].pop();
        }
        assert!(matches!(
            rnn_params(&bad),
            Err(ToParamsError::File(ModelFileError::WrongShape { .. }))
        ));
    }

    #[test]
    fn another_rate_or_a_long_delay_is_refused() {
        let dt = rths_core::params::DT_S;
        let theta = vec![0.0, 1e-7, 0.0, 0.0, 2.0, -1.0];
        let e = lr_params(&ModelFile::new_lr(theta.clone(), 28, dt / 2.0)).unwrap_err();
        assert!(matches!(e, ToParamsError::Rate(_)), "{e}");
        assert!(e.to_string().contains("`rths train lr --out FILE`"), "{e}");
        let max = rths_core::control::MAX_DELAY_STEPS;
        lr_params(&ModelFile::new_lr(theta.clone(), max, dt)).unwrap();
        let e = lr_params(&ModelFile::new_lr(theta, 100_000, dt)).unwrap_err();
        assert!(
            matches!(
                e,
                ToParamsError::File(ModelFileError::DelayTooLong { found: 100_000, .. })
            ),
            "{e}"
        );
    }
}

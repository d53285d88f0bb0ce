//! The controller of this build: its analytical part, chosen by feature (exactly one of
//! `model-lr`, `model-rnn`, `fe-ats`, `model-lrx`), fed from the generated `gen` constants.

use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::Limits;

const _: () = assert!(
    cfg!(feature = "model-lr") as u8
        + cfg!(feature = "model-rnn") as u8
        + cfg!(feature = "fe-ats") as u8
        + cfg!(feature = "model-lrx") as u8
        == 1,
    "enable exactly one analytical part: `model-lr`, `model-rnn`, `fe-ats` or `model-lrx`"
);

/// The scenario's name (the RNN's adds its hidden size, [`SCENARIO_SUFFIX`]).
pub const SCENARIO_PREFIX: &str = if cfg!(feature = "model-rnn") {
    "rnn-online-"
} else if cfg!(feature = "fe-ats") {
    "fe-online-ats"
} else if cfg!(feature = "model-lrx") {
    "lrx-online"
} else {
    "lr-online"
};

/// The suffix of the scenario's name: the RNN's hidden size.
#[cfg(feature = "model-rnn")]
pub const SCENARIO_SUFFIX: Option<usize> = Some(crate::gen::RNN_HIDDEN);
/// The suffix of the scenario's name: none.
#[cfg(not(feature = "model-rnn"))]
pub const SCENARIO_SUFFIX: Option<usize> = None;

/// The link's `UploadLr` replaces the analytical part with an LR model (not with an RNN or FE part,
/// whose runs compare against their own reference).
pub const UPLOAD_LR: bool = !cfg!(any(feature = "model-rnn", feature = "fe-ats"));

/// The controller, and the link checksum of its compiled-in LR model (0 for another part).
pub fn controller() -> Result<(Controller, u32), &'static str> {
    let proto = Prototype::paper()
        .with_brace_factor(1.0)
        .map_err(|_| "prototype")?;
    let cfg = ControlConfig::new(
        proto,
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .map_err(|_| "control config")?;
    let (analytical, compensator, checksum) = analytical()?;
    Ok((Controller::new(cfg, analytical, compensator), checksum))
}

/// The analytical part, its compensator and its LR checksum.
fn analytical() -> Result<(Analytical, Compensator, u32), &'static str> {
    #[cfg(feature = "model-lr")]
    {
        use rths_core::metamodel::{Lr, LrParams};
        let p = LrParams::new(crate::gen::LR_THETA).map_err(|_| "LR model")?;
        let crc = rths_app::link::compiled_model_checksum(&crate::gen::LR_THETA);
        Ok((Analytical::Lr(Lr::new(p)), Compensator::None, crc))
    }
    #[cfg(feature = "model-rnn")]
    {
        use rths_core::metamodel::{Rnn, RnnParams, RnnScaling, RnnWeights};
        let w = RnnWeights {
            w_ih: &crate::gen::RNN_W_IH,
            w_hh: &crate::gen::RNN_W_HH,
            b_h: &crate::gen::RNN_B_H,
            w_ho: &crate::gen::RNN_W_HO,
            b_o: crate::gen::RNN_B_O,
        };
        let s = RnnScaling {
            input_mean: crate::gen::RNN_IN_MEAN,
            input_std: crate::gen::RNN_IN_STD,
            output_mean: crate::gen::RNN_OUT_MEAN,
            output_std: crate::gen::RNN_OUT_STD,
        };
        let p = RnnParams::new(w, s).map_err(|_| "RNN model")?;
        Ok((Analytical::Rnn(Rnn::new(p)), Compensator::None, 0))
    }
    #[cfg(feature = "fe-ats")]
    {
        use rths_core::compensator::{Ats, AtsConfig, AtsParams};
        use rths_core::control::FeModel;
        use rths_core::params::{DT_S, PAPER_DELAY_STEPS};
        let fe = FeModel::new(Prototype::paper(), DT_S).map_err(|_| "FE model")?;
        let delay_s = PAPER_DELAY_STEPS as f64 * DT_S;
        let ats = AtsParams::new(AtsConfig::paper(DT_S, delay_s)).map_err(|_| "ATS")?;
        Ok((Analytical::Fe(fe), Compensator::Ats(Ats::new(ats)), 0))
    }
    #[cfg(feature = "model-lrx")]
    {
        use rths_core::compensator::{Lead, LeadParams};
        use rths_core::metamodel::{Lrx, LrxParams};
        let p = LrxParams::new(
            crate::gen::LRX_COEFFS,
            crate::gen::LRX_K_CORR,
            crate::gen::LRX_K_ADAPT,
        )
        .map_err(|_| "LRX model")?;
        let lead = LeadParams::new(crate::gen::LRX_LEAD, crate::gen::LRX_LEAD_STRIDE)
            .map_err(|_| "LRX lead")?;
        Ok((
            Analytical::Lrx(Lrx::new(p)),
            Compensator::Lead(Lead::new(lead)),
            0,
        ))
    }
}

/// The fault plan `RTHS_FAULT` named at build time (`fault-inject`).
#[cfg(feature = "fault-inject")]
pub fn faults() -> rths_hal_sim::FaultPlan {
    use rths_hal_sim::{Fault, FaultPlan};
    match crate::gen::FAULT_KIND {
        Some(kind) => match Fault::new(kind, crate::gen::FAULT_START, crate::gen::FAULT_TICKS)
            .and_then(|f| FaultPlan::none().with(f))
        {
            Ok(p) => p,
            Err(_) => crate::die("RTHS_FAULT: invalid fault"),
        },
        None => FaultPlan::none(),
    }
}

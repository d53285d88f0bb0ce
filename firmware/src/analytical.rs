//! The controller of this build: its analytical part, chosen by feature (exactly one of
//! `model-lr`, `model-rnn`, `fe-ats`, `model-lrx`), fed from the generated `gen` constants.

use core::mem::MaybeUninit;

use rths_core::control::{ControlConfig, Controller, FeedbackSource};
use rths_core::model::{assemble_in, ModelSpec};
use rths_core::params::{Prototype, SpecimenScale, DT_S};
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

/// The kind of this build's analytical part (the link's status reports it).
pub const MODEL_KIND: rths_link::ModelKind = if cfg!(feature = "model-rnn") {
    rths_link::ModelKind::Rnn
} else if cfg!(feature = "fe-ats") {
    rths_link::ModelKind::FeAts
} else if cfg!(feature = "model-lrx") {
    rths_link::ModelKind::Lrx
} else {
    rths_link::ModelKind::Lr
};

/// The link's `UploadLr` replaces the analytical part with an LR model only in the LR build: an LR
/// model in another build would run beside that build's compensator (LRX's lead filter) or against
/// another reference, a controller no host scenario simulates; those builds refuse it
/// `Unsupported`, as they refuse every kind they do not run.
pub const UPLOAD_LR: bool = cfg!(feature = "model-lr");

/// Values of this build's staging area for chunked model uploads (its own kind's count; 0 without
/// the link or a chunked kind).
pub const STAGING: usize = if !cfg!(feature = "link") {
    0
} else {
    kind_values()
};

#[cfg(feature = "model-rnn")]
const fn kind_values() -> usize {
    rths_link::rnn_value_count(crate::gen::RNN_HIDDEN)
}
#[cfg(feature = "model-lrx")]
const fn kind_values() -> usize {
    rths_link::LRX_VALUES
}
#[cfg(not(any(feature = "model-rnn", feature = "model-lrx")))]
const fn kind_values() -> usize {
    0
}

/// The firmware build's identity: CRC-32 of its description (package version, board, analytical
/// part, rate, compiled-in model's source), the same for two identical builds.
pub fn build_id() -> u32 {
    let board = if cfg!(feature = "board-qemu") {
        "qemu-netduinoplus2"
    } else if cfg!(feature = "board-mps2-an500") {
        "qemu-mps2-an500"
    } else if cfg!(feature = "board-stm32f4") {
        "stm32f407"
    } else {
        "stm32h743"
    };
    let mut d = rths_link::MODEL_CRC.digest();
    for part in [
        env!("CARGO_PKG_VERSION"),
        board,
        SCENARIO_PREFIX,
        crate::gen::MODEL_SOURCE,
    ] {
        d.update(part.as_bytes());
        d.update(&[0]);
    }
    d.update(&(SCENARIO_SUFFIX.unwrap_or(0) as u32).to_le_bytes());
    d.update(&rths_core::params::CONTROL_RATE_HZ.to_le_bytes());
    d.update(&[u8::from(cfg!(feature = "link"))]);
    d.finalize()
}

/// The controller, built in place in `slot` (an `init` local, a static): RTIC's resources hold a
/// reference to it, and its parts are built where they live (`rths_core::model::assemble_in`), so
/// the ~44 KiB controller (the ATS's 33 KiB, the RNN's 9 kB) is never a value on the stack. Also
/// the link checksum of its compiled-in model (0 for the FE model, and for an RNN if `scratch`
/// cannot hold its values).
pub fn controller(
    slot: &'static mut MaybeUninit<Controller>,
    scratch: &mut [f64],
) -> Result<(&'static mut Controller, u32), &'static str> {
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
    let ctl = Controller::init_in(slot, cfg);
    // Assembled by core, as the host scenarios are (`assemble`: the same parts, by value).
    assemble_in(ctl, &SPEC, Prototype::paper(), DT_S).map_err(|_| "compiled-in model")?;
    Ok((ctl, checksum(scratch)))
}

/// This build's analytical part as a model file would describe it (the compiled-in `gen` arrays).
#[cfg(feature = "model-lr")]
const SPEC: ModelSpec<'static> = ModelSpec::Lr {
    theta: &crate::gen::LR_THETA,
};
/// This build's analytical part as a model file would describe it (the compiled-in `gen` arrays).
#[cfg(feature = "model-rnn")]
const SPEC: ModelSpec<'static> = ModelSpec::Rnn {
    weights: rths_core::metamodel::RnnWeights {
        w_ih: &crate::gen::RNN_W_IH,
        w_hh: &crate::gen::RNN_W_HH,
        b_h: &crate::gen::RNN_B_H,
        w_ho: &crate::gen::RNN_W_HO,
        b_o: crate::gen::RNN_B_O,
    },
    scaling: rths_core::metamodel::RnnScaling {
        input_mean: crate::gen::RNN_IN_MEAN,
        input_std: crate::gen::RNN_IN_STD,
        output_mean: crate::gen::RNN_OUT_MEAN,
        output_std: crate::gen::RNN_OUT_STD,
    },
};
/// This build's analytical part: the FE model with ATS starting from the paper's delay.
#[cfg(feature = "fe-ats")]
const SPEC: ModelSpec<'static> = ModelSpec::FeAts {
    expected_delay_s: rths_core::params::PAPER_DELAY_STEPS as f64 * DT_S,
};
/// This build's analytical part as a model file would describe it (the compiled-in `gen` arrays).
#[cfg(feature = "model-lrx")]
const SPEC: ModelSpec<'static> = ModelSpec::Lrx {
    coeffs: &crate::gen::LRX_COEFFS,
    k_corr_kn_per_mm: crate::gen::LRX_K_CORR,
    k_adapt_ticks: crate::gen::LRX_K_ADAPT,
    lead_weights: &crate::gen::LRX_LEAD,
    lead_stride: crate::gen::LRX_LEAD_STRIDE,
    lead_adapt_ticks: crate::gen::LRX_LEAD_ADAPT,
    specimen_dynamics: crate::gen::LRX_SPECIMEN_DYNAMICS,
};

/// The link checksum of the compiled-in model: an LR, LRX or RNN model's (what an upload of the
/// same model file reports; an RNN's values are laid out in `scratch`), else 0.
fn checksum(scratch: &mut [f64]) -> u32 {
    let _ = &scratch;
    #[cfg(feature = "model-rnn")]
    if let ModelSpec::Rnn { weights, scaling } = SPEC {
        return rths_app::model_upload::rnn_checksum(
            &weights,
            &scaling,
            crate::gen::RNN_DELAY_STEPS,
            scratch,
        );
    }
    #[cfg(feature = "model-lr")]
    return rths_app::link::compiled_model_checksum(&crate::gen::LR_THETA);
    #[cfg(feature = "model-lrx")]
    return rths_app::model_upload::lrx_checksum(
        &crate::gen::LRX_COEFFS,
        crate::gen::LRX_K_CORR,
        crate::gen::LRX_K_ADAPT,
        &crate::gen::LRX_LEAD,
        crate::gen::LRX_LEAD_STRIDE,
        crate::gen::LRX_DELAY_STEPS,
    );
    #[cfg(not(any(feature = "model-lr", feature = "model-lrx")))]
    0
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

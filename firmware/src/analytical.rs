//! The controller of this build: its analytical part, chosen by feature (exactly one of
//! `model-lr`, `model-rnn`, `fe-ats`, `model-lrx`, the structure-file parts `structure-fe`,
//! `structure-nl`, `structure-meta`, `structure-modal` (`RTHS_STRUCTURE`, build.rs), or
//! `budget-structures`, the
//! structure budget run), fed from the generated `gen` constants.

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
        + cfg!(feature = "structure-fe") as u8
        + cfg!(feature = "structure-nl") as u8
        + cfg!(feature = "structure-meta") as u8
        + cfg!(feature = "structure-modal") as u8
        + cfg!(feature = "budget-structures") as u8
        == 1,
    "enable exactly one analytical part: `model-lr`, `model-rnn`, `fe-ats`, `model-lrx`, \
     `structure-fe`, `structure-nl`, `structure-meta`, `structure-modal` or `budget-structures`"
);

/// A structure-file part (or the structure budget) is built.
const STRUCTURE: bool = cfg!(any(
    feature = "structure-fe",
    feature = "structure-nl",
    feature = "structure-meta",
    feature = "structure-modal",
    feature = "budget-structures"
));

/// The scenario's name (the RNN's adds its hidden size, [`SCENARIO_SUFFIX`]).
pub const SCENARIO_PREFIX: &str = if cfg!(feature = "structure-fe") {
    "structure-fe"
} else if cfg!(feature = "structure-nl") {
    "structure-nl"
} else if cfg!(feature = "structure-meta") {
    "structure-meta"
} else if cfg!(feature = "structure-modal") {
    "structure-modal"
} else if cfg!(feature = "budget-structures") {
    "budget-structures"
} else if cfg!(feature = "model-rnn") {
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

/// The kind of this build's compiled-in analytical part (the link's status reports it until an
/// upload replaces it). The link has no structure-file kind yet: those builds report the
/// finite-element kind.
pub const MODEL_KIND: rths_link::ModelKind = if STRUCTURE {
    rths_link::ModelKind::FeAts
} else if cfg!(feature = "model-rnn") {
    rths_link::ModelKind::Rnn
} else if cfg!(feature = "fe-ats") {
    rths_link::ModelKind::FeAts
} else if cfg!(feature = "model-lrx") {
    rths_link::ModelKind::Lrx
} else {
    rths_link::ModelKind::Lr
};

/// The board's tick, against which an uploaded model is checked (`rths_app::tick_cost`): the
/// Cortex-M7 boards at 480 MHz with hardware f64, the Cortex-M4 boards at 168 MHz, at the
/// controller's rate. An upload of any kind is taken by any image if this tick can run it.
pub const TICK_BUDGET: rths_app::tick_cost::TickBudget = if cfg!(any(
    feature = "board-mps2-an500",
    feature = "board-stm32h743"
)) {
    rths_app::tick_cost::TickBudget::cortex_m7_480mhz(rths_core::params::CONTROL_RATE_HZ as f64)
} else {
    rths_app::tick_cost::TickBudget::cortex_m4_168mhz(rths_core::params::CONTROL_RATE_HZ as f64)
};

/// Values of the staging area for chunked model uploads of any kind (an RNN of the link's largest
/// hidden size, 9,272 bytes; 0 without the link).
pub const STAGING: usize = if cfg!(feature = "link") {
    rths_link::MODEL_MAX_VALUES
} else {
    0
};

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
/// This build's analytical part: the structure file (and metamodel) `RTHS_STRUCTURE` named.
#[cfg(any(
    feature = "structure-fe",
    feature = "structure-nl",
    feature = "structure-meta",
    feature = "structure-modal"
))]
const SPEC: ModelSpec<'static> = crate::gen::STRUCTURE_SPEC;
/// The budget build's app controller (never ticked: `init` runs [`structure_budget`] and exits).
#[cfg(feature = "budget-structures")]
const SPEC: ModelSpec<'static> = ModelSpec::Fe;
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

/// One controller of the structure budget (build.rs generates the rows of `gen::BUDGET_ROWS`).
#[cfg(feature = "budget-structures")]
pub struct BudgetRow {
    /// The budget path: `structure-fe`, `structure-nl`, `structure-meta`, `structure-modal` or
    /// `structure-reduced` (an imported structure's reduced-order model).
    pub path: &'static str,
    /// The structure file's name.
    pub structure: &'static str,
    /// Its DOFs (an imported structure's: those with mass, the reduced model's N).
    pub dofs: usize,
    /// The specimen's stiffness, kN/mm (the ideal rig holds it).
    pub specimen_kn_per_mm: f64,
    /// The retained modes of a reduced-order model (`structure-reduced`; 0 for the other paths):
    /// its cost per tick is set by them, not by `dofs`.
    pub modes: usize,
    /// Its analytical part and compensator, assembled by core from the row's constant spec.
    pub build: fn() -> Result<
        (
            rths_core::control::Analytical,
            rths_core::compensator::Compensator,
        ),
        rths_core::metamodel::ModelError,
    >,
}

/// Prototype displacement over specimen displacement in the structure budget: the structures'
/// floors move tens of mm under El Centro ×1, the actuator a tenth of it (inside the supervisor's
/// stroke, velocity and force limits, so every controller stays `Running` the whole record).
#[cfg(feature = "budget-structures")]
const BUDGET_DISP_SCALE: f64 = 10.0;

/// One controller tick, out of line: the counter's two readings sit around one opaque call the
/// compiler cannot move work across.
#[cfg(feature = "budget-structures")]
#[inline(never)]
fn budget_tick(
    c: &mut Controller,
    ag_mm_s2: f64,
    s: rths_core::hal::Sample,
) -> rths_core::control::TickOutput {
    c.tick(ag_mm_s2, Ok(s), false)
}

/// The structure budget: each controller of `gen::BUDGET_ROWS` (FE linear, FE yielding, the
/// structure metamodel and the modal-hysteretic metamodel for N = 1, 3, 8, then the imported
/// structures' reduced-order models) runs the whole record (`ag_mm_s2(k)`,
/// `ticks`) from rest, one after the other, on an ideal rig: the measured displacement is the
/// command in force, the measured force the structure file's linear specimen at it (the plant does
/// not change the instruction count of these controllers: no branch depends on it). Counted per
/// tick: `Controller::tick` (feedback, the analytical part, the supervisor), less the counter's
/// overhead. Prints one `STRUCTURE {...}` line per controller, then ends the emulation (success:
/// every controller stayed `Running` the whole record). Declared `()` so that `init`'s code after
/// the call stays reachable to the compiler in this build.
#[cfg(feature = "budget-structures")]
pub fn structure_budget<C: rths_app::board::InstrCounter>(
    counter: &C,
    overhead_instr: u32,
    ag_mm_s2: impl Fn(u32) -> f64,
    ticks: u32,
) {
    use rths_app::board::Board as _;
    let mut all_ok = true;
    for row in crate::gen::BUDGET_ROWS.iter() {
        all_ok &= budget_row(row, counter, overhead_instr, &ag_mm_s2, ticks);
    }
    crate::B::exit(all_ok)
}

/// One row of [`structure_budget`]: its controller, run and reported. Out of line: inlined into
/// the loop over the rows, the compiler unrolled it and gave each row's ~12 KB controller
/// its own stack slot (a 111 KB frame, past the RAM).
#[cfg(feature = "budget-structures")]
#[inline(never)]
fn budget_row<C: rths_app::board::InstrCounter>(
    row: &BudgetRow,
    counter: &C,
    overhead_instr: u32,
    ag_mm_s2: &impl Fn(u32) -> f64,
    ticks: u32,
) -> bool {
    use core::fmt::Write as _;
    use rths_app::board::Board as _;
    use rths_core::params::FORCE_SCALE;
    use rths_core::supervisor::State;
    let Ok(scale) = SpecimenScale::new(BUDGET_DISP_SCALE, FORCE_SCALE) else {
        crate::die("budget scale");
    };
    let Ok(cfg) = ControlConfig::new(
        Prototype::paper(),
        scale,
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    ) else {
        crate::die("budget control config");
    };
    let Ok((analytical, compensator)) = (row.build)() else {
        crate::die("the budget's structure would not assemble");
    };
    let mut c = Controller::new(cfg, analytical, compensator);
    let started = {
        let s = c.supervisor_mut();
        s.arm().is_ok() && s.start().is_ok()
    };
    let (mut min, mut max, mut sum, mut n) = (u32::MAX, 0u32, 0u64, 0u32);
    // FNV-1a of the commands' bits: the stream a host run of the same controller must match.
    let mut fnv = rths_core::checksum::Fnv1a64::new();
    let mut state = c.supervisor().state();
    for k in 0..ticks {
        let x = c.supervisor().output_mm();
        let f_proto = row.specimen_kn_per_mm * scale.prototype_disp_mm(x);
        let sample = rths_core::hal::Sample {
            disp_mm: x,
            force_kn: f_proto / FORCE_SCALE,
        };
        let ag = ag_mm_s2(k);
        let t0 = counter.now();
        let out = budget_tick(&mut c, ag, sample);
        let t1 = counter.now();
        let instr = counter.instructions(t0, t1).saturating_sub(overhead_instr);
        state = out.state;
        if state != State::Running {
            break;
        }
        min = min.min(instr);
        max = max.max(instr);
        sum = sum.saturating_add(u64::from(instr));
        n = n.saturating_add(1);
        fnv.write_f64(out.command_mm);
    }
    let ok = started && state == State::Running && n == ticks;
    let mean = if n > 0 { sum as f64 / n as f64 } else { 0.0 };
    let mut l = heapless::String::<320>::new();
    let _ = write!(
        l,
        "STRUCTURE {{\"path\":\"{}\",\"structure\":\"{}\",\"n\":{},\"modes\":{},\"ticks\":{},\
         \"running\":{},\"command_fnv\":\"{:016x}\",\"instr_per_tick\":{{\"min\":{},\"mean\":{:.1},\
         \"max\":{}}}}}",
        row.path,
        row.structure,
        row.dofs,
        row.modes,
        n,
        ok,
        fnv.finish(),
        if n > 0 { min } else { 0 },
        mean,
        max
    );
    crate::B::host_line(&l);
    ok
}

//! The controller of this image. What it runs is data, not a feature: its compiled-in default, a
//! model of any kind laid out by `build.rs` with the link's own layout (`gen::DEFAULT_KIND`,
//! `DEFAULT_VALUES`, and the rig compensation its file carries), installed at boot through the path
//! an upload takes (`rths_app::model_upload::install`, `rths_app::rig_upload::install_rig`); then
//! whatever the host uploads. The structure budget (`RTHS_BUDGET=structures`, build.rs) is data
//! too: its rows, run at boot on an ideal rig.

use core::mem::MaybeUninit;

use rths_app::rig_upload::{dims_of, install_rig, InForce};
use rths_core::control::{ControlConfig, Controller, FeedbackSource};
use rths_core::params::{Prototype, SpecimenScale, FORCE_SCALE};
use rths_core::supervisor::Limits;
use rths_link::ModelKind;

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

/// This image runs the structure budget at boot (`RTHS_BUDGET=structures`) instead of a test.
pub const BUDGET: bool = !crate::gen::BUDGET_ROWS.is_empty();

/// The firmware build's identity: CRC-32 of its description (package version, board, the default
/// model's kind and source, rate, link), the same for two identical builds.
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
    for part in [env!("CARGO_PKG_VERSION"), board, crate::gen::MODEL_SOURCE] {
        d.update(part.as_bytes());
        d.update(&[0]);
    }
    d.update(&[crate::gen::DEFAULT_KIND as u8]);
    d.update(&rths_core::params::CONTROL_RATE_HZ.to_le_bytes());
    d.update(&[u8::from(cfg!(feature = "link"))]);
    d.finalize()
}

/// The board's own configuration of the controller: the paper's prototype and specimen scale, the
/// measured feedback, the paper actuator's limits.
fn board_config() -> Result<ControlConfig, &'static str> {
    let proto = Prototype::paper()
        .with_brace_factor(1.0)
        .map_err(|_| "prototype")?;
    ControlConfig::new(
        proto,
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .map_err(|_| "control config")
}

/// The default model in force at boot: its kind and its link checksum (what an upload of the same
/// files reports).
#[derive(Debug, Clone, Copy)]
pub struct BootModel {
    /// Its kind.
    pub kind: ModelKind,
    /// Its checksum.
    pub checksum: u32,
}

/// The controller, built in place in `slot` (an `init` local, a static): RTIC's resources hold a
/// reference to it, and its parts are built where they live, so the ~44 KiB controller (the ATS's
/// 33 KiB, the RNN's 9 kB) is never a value on the stack. Its default is installed through the
/// path an upload takes, then the rig compensation its file carries.
pub fn controller(
    slot: &'static mut MaybeUninit<Controller>,
) -> Result<(&'static mut Controller, BootModel), &'static str> {
    use crate::gen::{DEFAULT_DELAY, DEFAULT_KIND, DEFAULT_RIG, DEFAULT_VALUES};
    let ctl = Controller::init_in(slot, board_config()?);
    rths_app::model_upload::install(ctl, DEFAULT_KIND, &DEFAULT_VALUES)
        .map_err(|_| "compiled-in model")?;
    if !DEFAULT_RIG.is_empty() {
        let part = InForce {
            kind: DEFAULT_KIND,
            dims: dims_of(ctl),
            budget: Some(TICK_BUDGET),
        };
        install_rig(ctl, &part, DEFAULT_KIND, &DEFAULT_RIG)
            .map_err(|_| "compiled-in rig compensation")?;
    }
    let checksum = match (DEFAULT_KIND, DEFAULT_VALUES.first_chunk()) {
        // An LR goes in one `UploadLr`, whose checksum is its own.
        (ModelKind::Lr, Some(theta)) => rths_link::model_checksum(theta, DEFAULT_DELAY),
        _ => rths_link::model_values_checksum(DEFAULT_KIND, &DEFAULT_VALUES, DEFAULT_DELAY),
    };
    Ok((
        ctl,
        BootModel {
            kind: DEFAULT_KIND,
            checksum,
        },
    ))
}

/// One controller of the structure budget (build.rs writes `gen::BUDGET_ROWS`).
pub struct BudgetRow {
    /// The budget path: `structure-fe`, `structure-nl`, `structure-meta`, `structure-modal`,
    /// `structure-reduced` (an imported structure's reduced-order model), and `nl-online`,
    /// `meta-online` (the modal and reduced models with a rig compensation).
    pub path: &'static str,
    /// The structure file's name.
    pub structure: &'static str,
    /// Its DOFs (an imported structure's: those with mass, the reduced model's N).
    pub dofs: usize,
    /// The retained modes of a reduced-order model (0 for the other paths): its cost per tick is
    /// set by them, not by `dofs`.
    pub modes: usize,
    /// The specimen's stiffness, kN/mm (the ideal rig holds it).
    pub specimen_kn_per_mm: f64,
    /// Its kind and values (`rths_link::layout`), installed as an upload is.
    pub kind: ModelKind,
    /// Its values.
    pub values: &'static [f64],
    /// Its rig compensation (empty: none).
    pub rig: &'static [f64],
}

/// Prototype displacement over specimen displacement in the structure budget: the structures'
/// floors move tens of mm under El Centro ×1, the actuator a tenth of it (inside the supervisor's
/// stroke, velocity and force limits, so every controller stays `Running` the whole record).
const BUDGET_DISP_SCALE: f64 = 10.0;

/// One controller tick, out of line: the counter's two readings sit around one opaque call the
/// compiler cannot move work across.
#[inline(never)]
fn budget_tick(
    c: &mut Controller,
    ag_mm_s2: f64,
    s: rths_core::hal::Sample,
) -> rths_core::control::TickOutput {
    c.tick(ag_mm_s2, Ok(s), false)
}

/// The structure budget: each controller of `gen::BUDGET_ROWS` (FE linear, FE yielding, the
/// structure metamodel and the modal-hysteretic metamodel for N = 1, 3, 8, the imported
/// structures' reduced-order models, and the modal and reduced models with a rig compensation)
/// built in `slot` in place, as the image's own controller is, runs the whole record
/// (`ag_mm_s2(k)`, `ticks`) from rest, one after the other, on an ideal rig: the measured
/// displacement is the command in force, the measured force the structure file's linear
/// specimen at it (the plant does not change the instruction count of these controllers: no
/// branch depends on it). Counted per tick: `Controller::tick` (feedback, the analytical part, the
/// compensator, the supervisor), less the counter's overhead. Prints one `STRUCTURE {...}` line
/// per controller, then ends the emulation (success: every controller stayed `Running` the whole
/// record).
pub fn structure_budget<C: rths_app::board::InstrCounter>(
    slot: &mut MaybeUninit<Controller>,
    counter: &C,
    overhead_instr: u32,
    ag_mm_s2: impl Fn(u32) -> f64,
    ticks: u32,
) {
    use rths_app::board::Board as _;
    let mut all_ok = true;
    for row in crate::gen::BUDGET_ROWS.iter() {
        all_ok &= budget_row(slot, row, counter, overhead_instr, &ag_mm_s2, ticks);
    }
    crate::B::exit(all_ok)
}

/// One row of [`structure_budget`]: its controller, run and reported. Out of line: one row's frame.
#[inline(never)]
fn budget_row<C: rths_app::board::InstrCounter>(
    slot: &mut MaybeUninit<Controller>,
    row: &BudgetRow,
    counter: &C,
    overhead_instr: u32,
    ag_mm_s2: &impl Fn(u32) -> f64,
    ticks: u32,
) -> bool {
    use core::fmt::Write as _;
    use rths_app::board::Board as _;
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
    let c = Controller::init_in(slot, cfg);
    if rths_app::model_upload::install(c, row.kind, row.values).is_err() {
        crate::die("the budget's model would not install");
    }
    if !row.rig.is_empty() {
        // Not checked against the tick: the budget measures what the check estimates from.
        let part = InForce {
            kind: row.kind,
            dims: dims_of(c),
            budget: None,
        };
        if install_rig(c, &part, row.kind, row.rig).is_err() {
            crate::die("the budget's rig compensation would not install");
        }
    }
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
        let out = budget_tick(c, ag, sample);
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

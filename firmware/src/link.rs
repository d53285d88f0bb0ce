//! The command link on the firmware side (feature `link`): the request handlers, board-independent.
//! The protocol and framing are `rths-link`'s; the board provides the byte port (qemu: USART1 on
//! QEMU's first `-serial`; stm32f4: USART1 on PA9/PA10).

use rths_core::control::{Analytical, Controller};
use rths_core::params::{DT_S, PAPER_DELAY_STEPS};
use rths_core::supervisor::{FaultReason, Limits, State, Supervisor};
use rths_link::{NackReason, RunState, Status, LR_COEFFS};

/// The wire state of a supervisor state.
pub fn run_state(s: State) -> RunState {
    match s {
        State::Idle => RunState::Idle,
        State::Armed => RunState::Armed,
        State::Running => RunState::Running,
        State::RampDown => RunState::RampDown,
        State::Done => RunState::Done,
        State::Fault(r) => RunState::Fault(fault_code(r)),
    }
}

/// A fault reason's number on the wire (the order of `rths_core::supervisor::FaultReason`).
pub fn fault_code(r: FaultReason) -> u8 {
    use FaultReason as F;
    match r {
        F::MeasuredStroke => 0,
        F::CommandStroke => 1,
        F::CommandVelocity => 2,
        F::Force => 3,
        F::NonFiniteCommand => 4,
        F::NonFiniteSample => 5,
        F::SensorTimeout => 6,
        F::Overrun => 7,
        F::EmergencyStop => 8,
        F::FollowingError => 9,
        F::ImplausibleMotion => 10,
        F::FrozenSensor => 11,
    }
}

/// The checksum of the compiled-in model.
pub fn compiled_model_checksum(theta: &[f64; LR_COEFFS]) -> u32 {
    rths_link::model_checksum(theta, PAPER_DELAY_STEPS as u16)
}

/// Validate an uploaded LR model and swap it in whole; the old one stays on any refusal.
/// Returns the new model's checksum.
pub fn upload_lr(
    ctl: &mut Controller,
    features: u8,
    theta: &[f64; LR_COEFFS],
    delay_steps: u16,
    checksum: u32,
) -> Result<u32, NackReason> {
    use rths_core::metamodel::{Lr, LrParams};
    if features as usize != LR_COEFFS {
        return Err(NackReason::Shape);
    }
    if theta.iter().any(|t| !t.is_finite()) {
        return Err(NackReason::NotFinite);
    }
    if rths_link::model_checksum(theta, delay_steps) != checksum {
        return Err(NackReason::Checksum);
    }
    if !ctl.supervisor().at_rest() {
        return Err(NackReason::Busy);
    }
    let params = LrParams::new(*theta).map_err(|_| NackReason::NotFinite)?;
    ctl.set_analytical(Analytical::Lr(Lr::new(params)))
        .map_err(|_| NackReason::Busy)?;
    Ok(checksum)
}

/// New stroke, velocity and force limits (the paper actuator's other settings). Only at rest with
/// the command at 0 mm: a new supervisor starts idle at 0 mm, so anything else would move the
/// actuator.
pub fn set_limits(
    ctl: &mut Controller,
    stroke_mm: f64,
    velocity_mm_s: f64,
    force_kn: f64,
) -> Result<(), NackReason> {
    if ![stroke_mm, velocity_mm_s, force_kn]
        .iter()
        .all(|v| v.is_finite())
    {
        return Err(NackReason::NotFinite);
    }
    let d = Limits::paper_actuator();
    let limits = Limits::new(
        stroke_mm,
        velocity_mm_s,
        force_kn,
        8,
        4,
        d.fault_ramp_rate_mm_s(),
        crate::END_RAMP_RATE_MM_S,
        DT_S,
    )
    .map_err(|_| NackReason::OutOfRange)?;
    let s = ctl.supervisor_mut();
    if !s.at_rest() || s.output_mm() != 0.0 {
        return Err(NackReason::Busy);
    }
    *s = Supervisor::new(limits);
    Ok(())
}

/// The status answer.
pub fn status(
    ctl: &Controller,
    model_checksum: u32,
    tick: u32,
    sent: u32,
    dropped: u32,
    bad_frames: u32,
) -> Status {
    let s = ctl.supervisor();
    let l = s.limits();
    Status {
        state: run_state(s.state()),
        model_checksum,
        tick,
        records_sent: sent,
        records_dropped: dropped,
        stroke_mm: l.stroke_mm(),
        velocity_mm_s: l.velocity_mm_s(),
        force_kn: l.force_kn(),
        bad_frames,
    }
}

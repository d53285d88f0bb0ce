//! The safety supervisor: the state machine that stands between the control law and a 31 kN actuator.
//!
//! States: `Idle → Armed → Running → RampDown → Done`, and `Fault` from anywhere a check fails. Every
//! controller tick the supervisor sees the command the control law asks for, the DAQ sample (or its
//! error) and whether the previous tick overran, and returns the command that is actually sent:
//!
//! - Interlocks (each trips `Fault` with its reason): measured stroke beyond the stroke limit,
//!   requested command beyond the stroke limit, requested command velocity beyond the velocity limit,
//!   measured force beyond the force limit, following error (measured vs command, while armed or
//!   running) beyond its limit, a measured displacement change no actuator can make in one tick
//!   (1.5× the velocity limit: a broken sensor or a runaway), a frozen LVDT (its reading unchanged,
//!   bit for bit, while the command moved more than [`FROZEN_SENSOR_MM`]), any non-finite value, `max_daq_errors`
//!   consecutive DAQ errors (sensor timeout), `max_overruns` consecutive overruns.
//! - The output is always rate-limited to `ramp_rate_mm_s`·Δt per tick and clamped to the stroke limit,
//!   so it never jumps, whatever the input.
//! - On a fault the output ramps (at `fault_ramp_rate_mm_s`) from where it is to the *safe position*:
//!   the command held when the test was armed, i.e. where the specimen was installed, unloaded. That
//!   is the last position known to be safe for the specimen: any later one may be the very one that
//!   overloaded it (a force or stroke trip), and holding it would keep the overload. The ramp
//!   continues whatever the sensors say (a NaN or a dead sensor cannot stop it), then holds there.
//!   At the end of a test (`finish()`) or on `abort()`, it ramps to zero (`RampDown`) and then reports
//!   `Done`.
//!
//! Parameters ([`Limits`]) are validated and immutable; [`Supervisor::reset`] returns to `Idle`.

use crate::hal::ErrorKind;
use crate::hal::Sample;
use crate::params::{
    positive, ParamError, ACTUATOR_CAPACITY_KN, ACTUATOR_STROKE_MM, ACTUATOR_VELOCITY_MM_S, DT_S,
};

/// `|x| > limit` for a validated, positive `limit`, as an integer compare of the IEEE bit patterns:
/// non-negative doubles order like their bits, so this is exact, and a NaN `x` counts as beyond (its
/// bits exceed infinity's). On the MCU, whose FPU is single-precision, it replaces a ~30-instruction
/// soft-float compare by a handful of integer instructions.
#[inline]
fn beyond(x: f64, limit: f64) -> bool {
    x.abs().to_bits() > limit.to_bits()
}

/// How far the command may move while the LVDT reading stays bit-for-bit unchanged before the sensor
/// counts as frozen, mm. A design choice: 0.5 mm is ~640 codes of the 16-bit ADC over ±25.4 mm, so a
/// live sensor (which the actuator, following the command, moves by hundreds of codes) never reads
/// the same value over such a move, while a stuck one is caught after 2% of the stroke instead of
/// the 7.6 mm following-error limit.
pub const FROZEN_SENSOR_MM: f64 = 0.5;

/// Standard deviations of the difference of two noisy readings a reading may move in one tick
/// beyond the velocity's step before it is implausible ([`Limits::with_sensor_noise_mm`]): at 8σ a
/// Gaussian noise crosses it about once in 10^15 ticks.
pub const NOISE_SIGMAS: f64 = 8.0;

/// Interlock limits and ramp rates, validated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    stroke_mm: f64,
    velocity_mm_s: f64,
    force_kn: f64,
    max_daq_errors: u32,
    max_overruns: u32,
    fault_ramp_rate_mm_s: f64,
    end_ramp_rate_mm_s: f64,
    dt_s: f64,
    following_error_mm: f64,
    frozen_sensor_mm: f64,
    /// σ of the displacement sensor's noise, mm (0: not known; the plausibility step is the
    /// velocity's alone).
    sensor_noise_mm: f64,
    // Per-tick steps, derived once (the MCU does f64 in software: no multiplications per tick).
    max_step_mm: f64,
    max_step_tol_mm: f64,
    fault_step_mm: f64,
    end_step_mm: f64,
    implausible_step_mm: f64,
    // The two coarse motion checks in single precision (below).
    following_error_f32: f32,
    implausible_step_f32: f32,
    frozen_sensor_f32: f32,
}

impl Limits {
    /// Limits of the paper's actuator (±25.4 mm, 338.84 mm/s, 31.14 kN) with 95% margins, a sensor
    /// timeout of 8 ticks (3.9 ms), 4 consecutive overruns, ramps at 20 mm/s (fault) and 10 mm/s
    /// (end of test): slow enough to be gentle on a specimen, fast enough to be safe within ~1 s; and a
    /// following error of 30% of the stroke (7.6 mm: twice the 3.5 mm a 13.7 ms delay costs at El
    /// Centro's 266 mm/s peak brace velocity).
    pub fn paper_actuator() -> Self {
        Self {
            stroke_mm: 0.95 * ACTUATOR_STROKE_MM,
            velocity_mm_s: 0.95 * ACTUATOR_VELOCITY_MM_S,
            force_kn: 0.95 * ACTUATOR_CAPACITY_KN,
            max_daq_errors: 8,
            max_overruns: 4,
            fault_ramp_rate_mm_s: 20.0,
            end_ramp_rate_mm_s: 10.0,
            dt_s: DT_S,
            following_error_mm: 0.3 * ACTUATOR_STROKE_MM,
            frozen_sensor_mm: FROZEN_SENSOR_MM,
            sensor_noise_mm: 0.0,
            max_step_mm: 0.0,
            max_step_tol_mm: 0.0,
            fault_step_mm: 0.0,
            end_step_mm: 0.0,
            implausible_step_mm: 0.0,
            following_error_f32: 0.0,
            implausible_step_f32: 0.0,
            frozen_sensor_f32: 0.0,
        }
        .derive()
    }

    fn derive(mut self) -> Self {
        self.max_step_mm = self.velocity_mm_s * self.dt_s;
        // A small tolerance so that a command exactly at the velocity limit is not a fault.
        self.max_step_tol_mm = self.max_step_mm * (1.0 + 1e-9);
        self.fault_step_mm = (self.fault_ramp_rate_mm_s * self.dt_s).min(self.max_step_mm);
        self.end_step_mm = (self.end_ramp_rate_mm_s * self.dt_s).min(self.max_step_mm);
        // + 0.0 without a known noise: the velocity's step alone, bit for bit.
        self.implausible_step_mm = 1.5 * self.max_step_mm
            + NOISE_SIGMAS * core::f64::consts::SQRT_2 * self.sensor_noise_mm;
        self.following_error_f32 = self.following_error_mm as f32;
        self.implausible_step_f32 = self.implausible_step_mm as f32;
        self.frozen_sensor_f32 = self.frozen_sensor_mm as f32;
        self
    }

    /// Limits for a run with no actuator (a pure simulation): nothing physical to protect, so the
    /// stroke, velocity, force, following-error and frozen-sensor checks are effectively off (1e9);
    /// non-finite values still trip.
    pub fn unbounded() -> Self {
        Self {
            stroke_mm: 1e9,
            velocity_mm_s: 1e9,
            force_kn: 1e9,
            following_error_mm: 1e9,
            frozen_sensor_mm: 1e9,
            fault_ramp_rate_mm_s: 1e9,
            end_ramp_rate_mm_s: 1e9,
            ..Self::paper_actuator()
        }
        .derive()
    }

    /// The same limits with another following-error limit (mm, > 0).
    pub fn with_following_error_mm(self, following_error_mm: f64) -> Result<Self, ParamError> {
        Ok(Self {
            following_error_mm: positive(following_error_mm, "following error limit")?,
            ..self
        }
        .derive())
    }

    /// The same limits for a displacement sensor whose noise has σ = `sensor_noise_mm` (finite,
    /// ≥ 0): the per-tick plausibility step grows by [`NOISE_SIGMAS`] σ of the difference of two
    /// readings, so that noise alone never trips it (at 4096 Hz the velocity's step is within a
    /// few σ of the vRTHS benchmark's sensor).
    pub fn with_sensor_noise_mm(self, sensor_noise_mm: f64) -> Result<Self, ParamError> {
        if !(sensor_noise_mm.is_finite() && sensor_noise_mm >= 0.0) {
            return Err(ParamError::OutOfRange("sensor noise (finite, ≥ 0)"));
        }
        Ok(Self {
            sensor_noise_mm,
            ..self
        }
        .derive())
    }

    /// Validated limits. Counts must be ≥ 1; all values finite and > 0; the ramp rates must not exceed
    /// the velocity limit.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        stroke_mm: f64,
        velocity_mm_s: f64,
        force_kn: f64,
        max_daq_errors: u32,
        max_overruns: u32,
        fault_ramp_rate_mm_s: f64,
        end_ramp_rate_mm_s: f64,
        dt_s: f64,
    ) -> Result<Self, ParamError> {
        let velocity_mm_s = positive(velocity_mm_s, "velocity limit")?;
        let fault = positive(fault_ramp_rate_mm_s, "fault ramp rate")?;
        let end = positive(end_ramp_rate_mm_s, "end ramp rate")?;
        if fault > velocity_mm_s || end > velocity_mm_s {
            return Err(ParamError::OutOfRange("ramp rate above the velocity limit"));
        }
        if max_daq_errors == 0 || max_overruns == 0 {
            return Err(ParamError::OutOfRange("interlock counts must be ≥ 1"));
        }
        Ok(Self {
            stroke_mm: positive(stroke_mm, "stroke limit")?,
            velocity_mm_s,
            force_kn: positive(force_kn, "force limit")?,
            max_daq_errors,
            max_overruns,
            fault_ramp_rate_mm_s: fault,
            end_ramp_rate_mm_s: end,
            dt_s: positive(dt_s, "time step")?,
            following_error_mm: 0.3 * stroke_mm,
            frozen_sensor_mm: FROZEN_SENSOR_MM,
            sensor_noise_mm: 0.0,
            max_step_mm: 0.0,
            max_step_tol_mm: 0.0,
            fault_step_mm: 0.0,
            end_step_mm: 0.0,
            implausible_step_mm: 0.0,
            following_error_f32: 0.0,
            implausible_step_f32: 0.0,
            frozen_sensor_f32: 0.0,
        }
        .derive())
    }

    /// Stroke limit, ±mm.
    pub fn stroke_mm(&self) -> f64 {
        self.stroke_mm
    }
    /// Command velocity limit, mm/s.
    pub fn velocity_mm_s(&self) -> f64 {
        self.velocity_mm_s
    }
    /// Force limit, ±kN (specimen scale, load cell).
    pub fn force_kn(&self) -> f64 {
        self.force_kn
    }
    /// Largest command change per tick, mm.
    pub fn max_step_mm(&self) -> f64 {
        self.max_step_mm
    }
    /// Largest |measured − command| while armed or running, mm.
    pub fn following_error_mm(&self) -> f64 {
        self.following_error_mm
    }
    /// Largest command move while the LVDT reading stays unchanged, mm.
    pub fn frozen_sensor_mm(&self) -> f64 {
        self.frozen_sensor_mm
    }
    /// Largest command change per tick on the fault ramp, mm.
    pub fn fault_step_mm(&self) -> f64 {
        self.fault_step_mm
    }
    /// Fault ramp rate, mm/s.
    pub fn fault_ramp_rate_mm_s(&self) -> f64 {
        self.fault_ramp_rate_mm_s
    }
    /// End-of-test ramp rate, mm/s.
    pub fn end_ramp_rate_mm_s(&self) -> f64 {
        self.end_ramp_rate_mm_s
    }
}

/// Why the supervisor tripped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultReason {
    /// Measured displacement beyond the stroke limit.
    MeasuredStroke,
    /// Requested command beyond the stroke limit.
    CommandStroke,
    /// Requested command velocity beyond the velocity limit.
    CommandVelocity,
    /// Measured force beyond the force limit.
    Force,
    /// The measured displacement is farther from the command than the following-error limit.
    FollowingError,
    /// The measured displacement moved more in one tick than any actuator can (sensor or runaway).
    ImplausibleMotion,
    /// The LVDT reading stayed bit-for-bit unchanged while the command moved more than
    /// [`FROZEN_SENSOR_MM`]: a stuck sensor or a dead link.
    FrozenSensor,
    /// A non-finite requested command.
    NonFiniteCommand,
    /// A non-finite sensor value.
    NonFiniteSample,
    /// Too many consecutive DAQ errors.
    SensorTimeout,
    /// Too many consecutive overruns of the control tick.
    Overrun,
    /// An external emergency stop.
    EmergencyStop,
}

impl FaultReason {
    /// Every reason with its code and name: the one table the firmware's report, the command link
    /// (`RunState::Fault(code)` on the wire) and the host's display use. The codes are a wire format:
    /// they never change, and a new reason takes the next free code (they do not follow the
    /// declaration order above).
    pub const ALL: [(FaultReason, u8, &'static str); 12] = [
        (FaultReason::MeasuredStroke, 0, "MeasuredStroke"),
        (FaultReason::CommandStroke, 1, "CommandStroke"),
        (FaultReason::CommandVelocity, 2, "CommandVelocity"),
        (FaultReason::Force, 3, "Force"),
        (FaultReason::NonFiniteCommand, 4, "NonFiniteCommand"),
        (FaultReason::NonFiniteSample, 5, "NonFiniteSample"),
        (FaultReason::SensorTimeout, 6, "SensorTimeout"),
        (FaultReason::Overrun, 7, "Overrun"),
        (FaultReason::EmergencyStop, 8, "EmergencyStop"),
        (FaultReason::FollowingError, 9, "FollowingError"),
        (FaultReason::ImplausibleMotion, 10, "ImplausibleMotion"),
        (FaultReason::FrozenSensor, 11, "FrozenSensor"),
    ];

    /// The reason's code on the wire (see [`Self::ALL`]).
    pub fn code(self) -> u8 {
        self.entry().1
    }

    /// The reason's name (the variant's), as reports and the host print it.
    pub fn name(self) -> &'static str {
        self.entry().2
    }

    /// The reason of a wire code; `None` for an unknown code (a newer firmware's).
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL
            .iter()
            .find(|(_, c, _)| *c == code)
            .map(|(r, _, _)| *r)
    }

    fn entry(self) -> (FaultReason, u8, &'static str) {
        // A `match` rather than a search: exhaustive, so a new variant without a row does not
        // compile, and no fallback value is needed.
        use FaultReason as F;
        let i = match self {
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
        };
        Self::ALL[i]
    }
}

/// The supervisor's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum State {
    /// Powered, holding the command; waiting to be armed.
    Idle,
    /// Armed: checks run, command holds; waiting for `start()`.
    Armed,
    /// The test runs: the control law's commands pass (checked and rate-limited).
    Running,
    /// Ramping to zero at the end of the test or after an abort.
    RampDown,
    /// Back at zero after a ramp-down.
    Done,
    /// Tripped: ramping to, then holding, the safe position.
    Fault(FaultReason),
}

/// Why a reset or parameter change was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Busy {
    /// The state at the time.
    pub state: State,
}

/// What the supervisor decided for one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decision {
    /// The command to send to the actuator, mm.
    pub command_mm: f64,
    /// The state after this tick.
    pub state: State,
}

/// Transition requests that are not allowed from the current state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InvalidTransition {
    /// The state the request was made in.
    pub from: State,
}

/// The supervisor: [`Limits`] plus a small state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Supervisor {
    limits: Limits,
    state: State,
    output_mm: f64,
    safe_position_mm: f64,
    last_measured_mm: Option<f32>,
    /// The command (single precision) when the LVDT reading last changed.
    frozen_ref_mm: f32,
    daq_errors: u32,
    overruns: u32,
    total_overruns: u32,
    total_daq_errors: u32,
}

impl Supervisor {
    /// A supervisor in `Idle` holding zero.
    pub fn new(limits: Limits) -> Self {
        Self {
            limits,
            state: State::Idle,
            output_mm: 0.0,
            safe_position_mm: 0.0,
            last_measured_mm: None,
            frozen_ref_mm: 0.0,
            daq_errors: 0,
            overruns: 0,
            total_overruns: 0,
            total_daq_errors: 0,
        }
    }

    /// Back to `Idle`, counters cleared, *holding the current command* (a reset never moves the
    /// actuator). Refused while armed, running, ramping down, or while a fault ramp is still moving.
    pub fn reset(&mut self) -> Result<(), Busy> {
        if !self.at_rest() {
            return Err(Busy { state: self.state });
        }
        let output = self.output_mm;
        *self = Self::new(self.limits);
        self.output_mm = output;
        self.safe_position_mm = output;
        Ok(())
    }

    /// Idle, done, or faulted with the fault ramp finished: nothing is moving or about to.
    pub fn at_rest(&self) -> bool {
        match self.state {
            State::Idle | State::Done => true,
            State::Fault(_) => self.output_mm == self.safe_position_mm,
            State::Armed | State::Running | State::RampDown => false,
        }
    }

    /// The limits in force.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }
    /// The current state.
    pub fn state(&self) -> State {
        self.state
    }
    /// The last command sent, mm.
    pub fn output_mm(&self) -> f64 {
        self.output_mm
    }
    /// Overruns seen since reset (consecutive or not).
    pub fn total_overruns(&self) -> u32 {
        self.total_overruns
    }
    /// DAQ errors seen since reset (consecutive or not).
    pub fn total_daq_errors(&self) -> u32 {
        self.total_daq_errors
    }

    /// `Idle → Armed`; the command held now becomes the safe position a fault ramps back to. The
    /// following-error check then verifies, every tick, that the actuator really is there.
    pub fn arm(&mut self) -> Result<(), InvalidTransition> {
        self.transition(State::Idle, State::Armed)?;
        self.safe_position_mm = self.output_mm;
        Ok(())
    }

    /// `Idle → Armed` at the measured position of the actuator (where the specimen is installed): the
    /// command is set to it first, so the first command sent never steps. Refused (stays `Idle`) if
    /// the position is not finite or beyond the stroke limit.
    pub fn arm_at(&mut self, measured_mm: f64) -> Result<(), InvalidTransition> {
        if self.state != State::Idle
            || !measured_mm.is_finite()
            || beyond(measured_mm, self.limits.stroke_mm)
        {
            return Err(InvalidTransition { from: self.state });
        }
        self.output_mm = measured_mm;
        self.arm()
    }
    /// The position a fault ramps to, mm (the command held when the test was armed).
    pub fn safe_position_mm(&self) -> f64 {
        self.safe_position_mm
    }
    /// `Armed → Running`.
    pub fn start(&mut self) -> Result<(), InvalidTransition> {
        self.transition(State::Armed, State::Running)
    }
    /// `Running → RampDown` at the end of the test.
    pub fn finish(&mut self) -> Result<(), InvalidTransition> {
        self.transition(State::Running, State::RampDown)
    }
    /// Operator abort: ramp to zero from `Armed` or `Running`; a fault stays a fault.
    pub fn abort(&mut self) {
        match self.state {
            State::Idle | State::Done | State::Fault(_) | State::RampDown => {}
            State::Armed | State::Running => self.state = State::RampDown,
        }
    }
    /// Hardware emergency stop: trip, whatever the state.
    pub fn emergency_stop(&mut self) {
        self.trip(FaultReason::EmergencyStop);
    }

    fn transition(&mut self, from: State, to: State) -> Result<(), InvalidTransition> {
        if self.state == from {
            self.state = to;
            Ok(())
        } else {
            Err(InvalidTransition { from: self.state })
        }
    }

    fn trip(&mut self, reason: FaultReason) {
        if !matches!(self.state, State::Fault(_)) {
            self.state = State::Fault(reason);
        }
    }

    /// Move the output toward `goal` by at most `step_mm` (never more than the velocity limit).
    fn ramp_toward(&mut self, goal: f64, step_mm: f64) {
        let delta = goal - self.output_mm;
        // Land exactly on the goal when within reach (no rounding residue on pass-through). Written
        // with comparisons, not `clamp`, which has a panic path.
        self.output_mm = if delta > step_mm {
            self.output_mm + step_mm
        } else if delta < -step_mm {
            self.output_mm - step_mm
        } else {
            goal
        };
    }

    /// One controller tick. `requested_mm` is what the control law asks for (ignored unless
    /// `Running`), `sample` the DAQ result of this tick, `overrun` whether the previous tick missed its
    /// deadline. Returns the command to send: finite, within the stroke limit, and within one
    /// velocity-limited step of the previous command.
    pub fn tick(
        &mut self,
        requested_mm: f64,
        sample: Result<Sample, ErrorKind>,
        overrun: bool,
    ) -> Decision {
        let lim = self.limits;
        // Counters run in every state: a sensor that dies while armed must be noticed.
        if overrun {
            self.overruns = self.overruns.saturating_add(1);
            self.total_overruns = self.total_overruns.saturating_add(1);
        } else {
            self.overruns = 0;
        }
        match sample {
            Ok(s) => {
                self.daq_errors = 0;
                if !s.disp_mm.is_finite() || !s.force_kn.is_finite() {
                    self.trip(FaultReason::NonFiniteSample);
                } else {
                    if beyond(s.disp_mm, lim.stroke_mm) {
                        self.trip(FaultReason::MeasuredStroke);
                    } else if beyond(s.force_kn, lim.force_kn) {
                        self.trip(FaultReason::Force);
                    }
                    // Following error and motion per tick in single precision: 2 µm resolution at
                    // full stroke, far finer than their limits (7.6 mm, 0.24 mm), and the F4's FPU
                    // does it in hardware (f64 is software there).
                    let x = s.disp_mm as f32;
                    if matches!(self.state, State::Armed | State::Running)
                        && (x - self.output_mm as f32).abs() > lim.following_error_f32
                    {
                        self.trip(FaultReason::FollowingError);
                    }
                    let out = self.output_mm as f32;
                    match self.last_measured_mm {
                        // Unchanged reading: the command may not have moved far since it changed.
                        Some(prev) if prev == x => {
                            if self.state == State::Running
                                && (out - self.frozen_ref_mm).abs() > lim.frozen_sensor_f32
                            {
                                self.trip(FaultReason::FrozenSensor);
                            }
                        }
                        Some(prev) => {
                            if (x - prev).abs() > lim.implausible_step_f32 {
                                self.trip(FaultReason::ImplausibleMotion);
                            }
                            self.frozen_ref_mm = out;
                        }
                        None => self.frozen_ref_mm = out,
                    }
                    self.last_measured_mm = Some(x);
                }
            }
            Err(_) => {
                // The actuator moves on while a sample is missing: do not compare across the gap.
                self.last_measured_mm = None;
                self.daq_errors = self.daq_errors.saturating_add(1);
                self.total_daq_errors = self.total_daq_errors.saturating_add(1);
            }
        }
        if self.daq_errors >= lim.max_daq_errors {
            self.trip(FaultReason::SensorTimeout);
        }
        if self.overruns >= lim.max_overruns {
            self.trip(FaultReason::Overrun);
        }
        if self.state == State::Running {
            self.check_request(requested_mm);
        }
        match self.state {
            // check_request passed: the request is finite, within the stroke and within one
            // velocity-limited step of the last command, so it is sent as it is.
            State::Running => self.output_mm = requested_mm,
            State::Fault(_) => self.ramp_toward(self.safe_position_mm, lim.fault_step_mm),
            State::RampDown => {
                self.ramp_toward(0.0, lim.end_step_mm);
                if self.output_mm == 0.0 {
                    self.state = State::Done;
                }
            }
            State::Idle | State::Armed | State::Done => {}
        }
        Decision {
            command_mm: self.output_mm,
            state: self.state,
        }
    }

    fn check_request(&mut self, requested_mm: f64) {
        let lim = self.limits;
        if !requested_mm.is_finite() {
            self.trip(FaultReason::NonFiniteCommand);
        } else if beyond(requested_mm, lim.stroke_mm) {
            self.trip(FaultReason::CommandStroke);
        } else if beyond(requested_mm - self.output_mm, lim.max_step_tol_mm) {
            self.trip(FaultReason::CommandVelocity);
        }
    }
}

#[cfg(test)]
mod tests;

//! The experimental side of one `rths site` element: what the protocol loop asks of an actuator,
//! whatever runs it (the virtual rig on the host, or the board over the link), and the ticks it
//! records.

use rths_link::RunState;

/// One controller tick, as `rths link run --out` records it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SiteRow {
    /// Tick from the start.
    pub tick: u32,
    /// Supervisor state after the tick.
    pub state: RunState,
    /// Command sent at this tick, mm.
    pub command_mm: f64,
    /// Target (the predictor-corrector's) at this tick, mm.
    pub target_mm: f64,
    /// Measured displacement read at this tick, mm.
    pub measured_mm: f64,
    /// Measured force read at this tick, kN.
    pub force_kn: f64,
}

/// What the DAQ read at the tick a step ended (specimen units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    /// Measured displacement, mm.
    pub measured_mm: f64,
    /// Measured force, kN.
    pub force_kn: f64,
}

/// Why an experiment stopped a test.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// The supervisor tripped (its reason's name).
    #[error("supervisor: {0}")]
    Supervisor(String),
    /// The board's link failed or the board refused.
    #[error("the board: {0}")]
    Link(#[from] crate::link_host::LinkHostError),
    /// The board sent something the site cannot use.
    #[error("the board: {0}")]
    Board(String),
    /// The site's controller refused (a target, a step size).
    #[error("the site's controller: {0}")]
    Controller(String),
}

/// Wall-clock pacing of a site's ticks, measured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PacingStats {
    /// Ticks paced.
    pub ticks: u64,
    /// Achieved tick rate, Hz (ticks over the wall time from the first to the last).
    pub rate_hz: f64,
    /// RMS of each tick's start minus its deadline, s.
    pub jitter_rms_s: f64,
    /// Largest tick start minus its deadline, s.
    pub late_max_s: f64,
}

/// An element's actuator and its control, the controller being core's (`Controller::tick` as a
/// site: the predictor-corrector, the rig's lead, the supervisor).
pub trait Experiment: Send {
    /// Arm and start a site of `ticks_per_step` controller ticks a step.
    fn begin(&mut self, ticks_per_step: u32) -> Result<(), ExperimentError>;
    /// Impose `target_mm` (the prototype's coordinates) over the next step; the DAQ's reading at
    /// its end.
    fn step(&mut self, target_mm: f64) -> Result<Reading, ExperimentError>;
    /// A wall-clock deadline for the next tick while the site waits for its client (`None`: the
    /// rig waits with it, simulated time).
    fn idle_deadline(&self) -> Option<std::time::Instant>;
    /// One tick while the site waits for its client (at [`Self::idle_deadline`]).
    fn idle_tick(&mut self);
    /// Bring the actuator to its safe state by the supervisor's fault ramp, to rest.
    fn safe_stop(&mut self);
    /// End the test: the supervisor's end ramp to zero, to rest.
    fn finish(&mut self);
    /// The supervisor's state.
    fn state(&self) -> RunState;
    /// Every tick so far (taken).
    fn take_rows(&mut self) -> Vec<SiteRow>;
    /// The wall-clock pacing achieved, if paced.
    fn pacing(&self) -> Option<PacingStats>;
}

/// The link's state of a supervisor state (the recording's names), as the board sends it.
pub fn run_state(s: rths_core::supervisor::State) -> RunState {
    use rths_core::supervisor::State;
    match s {
        State::Idle => RunState::Idle,
        State::Armed => RunState::Armed,
        State::Running => RunState::Running,
        State::RampDown => RunState::RampDown,
        State::Done => RunState::Done,
        State::Fault(r) => RunState::Fault(r.code()),
    }
}

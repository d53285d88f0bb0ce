//! The host's control step: the one loop that drives `rths_core::control::Controller` on the
//! host, in the form of the firmware's control task (`app/src/control.rs` `control_step`): per
//! tick `k` the plant's sample → `Controller::tick(ü_g(k), sample, overrun)` → the command to the
//! actuator → the plant holds it for one tick. Every study runs its controller through it: the
//! scenarios (`rths simulate`, `reproduce`, `robustness`), the structure scenarios and the
//! nonlinear study (`rths simulate --structure`, `rths nonlinear-study`) and the vRTHS benchmark
//! (`rths benchmark`), and training's pure scores (`rths train`, `src/machinery/train/pure.rs`).
//! Identification (`rths identify`) runs the board's identification tick (`rths_app::identify`'s
//! `identify_step`, which the firmware's control task runs while identifying) through [`identify`].
//!
//! What a study keeps of a tick it reads from the [`Step`] (and, for the analytical part's state,
//! e.g. story drifts, from the controller); the truths of the plant ([`HostPlant`]) are for
//! evaluation only, the controller never sees them.

use std::ops::ControlFlow;

use heapless::spsc::Queue;
use rths_app::identify::{identify_step, Identification};
use rths_app::TelemetryRecord;
use rths_core::control::{Controller, TickOutput};
use rths_core::hal::{Actuator, Daq, Error, ErrorKind, Sample};
use rths_core::identify_excitation::Tables;
use rths_core::identify_session::IdentifyPhase;
use rths_core::supervisor::State;
use rths_hal_sim::VirtualRig;

/// Why and when the supervisor stopped a run: (reason, time s), `None` if it never tripped.
pub type Stop = Option<(String, f64)>;

/// A plant the host drives: what the controller's step sees (the DAQ and the actuator), the
/// plant's clock, and its truths for the evaluation.
pub trait HostPlant: Daq + Actuator {
    /// Move the plant one controller tick holding the last command.
    fn advance_tick(&mut self);
    /// The true (noise-free) actuator displacement, mm: evaluation only.
    fn true_disp_mm(&self) -> f64;
    /// The true force on the specimen, kN: evaluation only.
    fn true_force_kn(&self) -> f64;
    /// The command the servo-controller holds (what reached it), mm.
    fn held_command_mm(&self) -> f64;
}

impl HostPlant for VirtualRig {
    fn advance_tick(&mut self) {
        VirtualRig::advance_tick(self);
    }
    fn true_disp_mm(&self) -> f64 {
        VirtualRig::true_disp_mm(self)
    }
    fn true_force_kn(&self) -> f64 {
        VirtualRig::true_force_kn(self)
    }
    fn held_command_mm(&self) -> f64 {
        VirtualRig::held_command_mm(self)
    }
}

/// One tick as the driver saw it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// Tick index k.
    pub k: usize,
    /// Ground acceleration at k, mm/s².
    pub ground_accel_mm_s2: f64,
    /// The target in force at k (produced at tick k−1; the last finite one), the analytical
    /// part's coordinates, mm.
    pub target_mm: f64,
    /// The command in force at k (produced at tick k−1), mm.
    pub command_mm: f64,
    /// What the DAQ gave at k (a pure run without a plant: a zero sample).
    pub sample: Result<Sample, ErrorKind>,
    /// The measured displacement at k, mm (NaN without a plant or on a DAQ error).
    pub measured_mm: f64,
    /// The measured force at k, kN (NaN without a plant or on a DAQ error).
    pub measured_force_kn: f64,
    /// What the controller produced at k (its command for k+1, its state).
    pub out: TickOutput,
    /// The plant's true displacement at k, mm (NaN without a plant): evaluation only.
    pub true_disp_mm: f64,
    /// The plant's true force at k, kN (NaN without a plant): evaluation only.
    pub true_force_kn: f64,
    /// The command the servo-controller holds during tick k, mm (NaN without a plant).
    pub servo_command_mm: f64,
}

/// Ticks on which the controller is told the previous tick overran: (first tick, count).
pub type Overruns = Option<(u64, u64)>;

/// The host's tick, one at a time: for a study whose inputs arrive as it runs (`rths site`),
/// the same tick [`run`] loops over. [`Driver::tick`] reads the plant and ticks the controller;
/// [`Driver::actuate`] then sends the command to the plant and moves it one tick.
#[derive(Debug, Clone, PartialEq)]
pub struct Driver {
    k: usize,
    command: f64,
    target: f64,
    stop: Stop,
    dt_s: f64,
}

impl Driver {
    /// Arm and start `ctl` (at rest): tick 0 comes next.
    pub fn start(ctl: &mut Controller, dt_s: f64) -> Self {
        // Idle → Armed → Running cannot fail on a controller at rest; a failure would be a logic
        // error the run shows as an immediate stop.
        let _ = ctl.supervisor_mut().arm();
        let _ = ctl.supervisor_mut().start();
        Self {
            k: 0,
            command: 0.0,
            target: 0.0,
            stop: None,
            dt_s,
        }
    }

    /// The supervisor's first stop so far.
    pub fn stop(&self) -> &Stop {
        &self.stop
    }

    /// Ticks done.
    pub fn ticks(&self) -> usize {
        self.k
    }

    /// Tick k: the plant's sample (`None`: a pure run, a zero sample), `ctl.tick(ü_g, sample,
    /// overrun)`; the [`Step`] as the study sees it.
    pub fn tick<P: HostPlant>(
        &mut self,
        ctl: &mut Controller,
        mut plant: Option<&mut P>,
        ag: f64,
        overrun: bool,
    ) -> Step {
        let k = self.k;
        let sample = match plant.as_deref_mut() {
            Some(p) => p.read().map_err(|e| e.kind()),
            None => Ok(Sample::default()),
        };
        let (measured_mm, measured_force_kn) = match (&plant, sample) {
            (Some(_), Ok(s)) => (s.disp_mm, s.force_kn),
            _ => (f64::NAN, f64::NAN),
        };
        let out = ctl.tick(ag, sample, overrun);
        let truth = |f: fn(&P) -> f64| plant.as_deref().map_or(f64::NAN, f);
        let step = Step {
            k,
            ground_accel_mm_s2: ag,
            target_mm: self.target,
            command_mm: self.command,
            sample,
            measured_mm,
            measured_force_kn,
            out,
            true_disp_mm: truth(P::true_disp_mm),
            true_force_kn: truth(P::true_force_kn),
            servo_command_mm: truth(P::held_command_mm),
        };
        self.command = out.command_mm;
        if out.target_mm.is_finite() {
            self.target = out.target_mm;
        }
        if let (State::Fault(reason), None) = (out.state, &self.stop) {
            self.stop = Some((format!("{reason:?}"), k as f64 * self.dt_s));
        }
        self.k += 1;
        step
    }

    /// The command of the last tick to the plant, which holds it for one tick.
    pub fn actuate<P: HostPlant>(&self, plant: Option<&mut P>) {
        if let Some(p) = plant {
            // The supervisor's command is finite and within the stroke, so the actuator accepts
            // it; an error would only report a clip, which the next reading shows.
            let _ = p.command(self.command);
            p.advance_tick();
        }
    }
}

/// Arm and start `ctl` (at rest), then run it over `ground_accel_mm_s2` against `plant` (`None`:
/// a pure run, the DAQ a zero sample): one tick per sample, as the firmware's control step. After
/// each tick `observe` sees the [`Step`], the controller and the plant, and may end the run
/// ([`ControlFlow::Break`]). Returns the supervisor's first stop.
pub fn run<P: HostPlant>(
    ctl: &mut Controller,
    mut plant: Option<&mut P>,
    ground_accel_mm_s2: &[f64],
    overruns: Overruns,
    dt_s: f64,
    mut observe: impl FnMut(&Step, &Controller, Option<&P>) -> ControlFlow<()>,
) -> Stop {
    let mut d = Driver::start(ctl, dt_s);
    for (k, &ag) in ground_accel_mm_s2.iter().enumerate() {
        let overrun = overruns.is_some_and(|(first, count)| (k as u64).wrapping_sub(first) < count);
        let step = d.tick(ctl, plant.as_deref_mut(), ag, overrun);
        if observe(&step, ctl, plant.as_deref()).is_break() {
            break;
        }
        d.actuate(plant.as_deref_mut());
    }
    d.stop
}

/// [`run`] with no plant: a pure run, the DAQ a zero sample every tick.
pub fn run_pure(
    ctl: &mut Controller,
    ground_accel_mm_s2: &[f64],
    dt_s: f64,
    mut observe: impl FnMut(&Step, &Controller) -> ControlFlow<()>,
) -> Stop {
    run::<VirtualRig>(ctl, None, ground_accel_mm_s2, None, dt_s, |st, c, _| {
        observe(st, c)
    })
}

/// The host's identification, as the firmware's control task runs one: per tick the board's
/// identification tick (`rths_app::identify::identify_step`: the excitation's request through
/// `ctl`'s supervisor to `rig`, the tick's record queued), then `next_tick` (on the virtual rig,
/// advance the plant; on a board, wait for the tick), until the identification `id` (started,
/// with `ctl`'s supervisor running: `rths_app::identify::begin_with`) ends. `observe` sees every
/// tick's record and whether the excitation was still playing before it (`false` after its end or
/// a trip). Its outcome is then `id.outcome()`.
pub fn identify<R, A, T>(
    ctl: &mut Controller,
    rig: &mut R,
    id: &mut Identification,
    tables: &T,
    mut next_tick: impl FnMut(&mut R),
    mut observe: impl FnMut(&TelemetryRecord, bool),
) where
    R: Daq<Error = A> + Actuator<Error = A>,
    A: Error,
    T: Tables,
{
    // The board's telemetry queue; the host takes each tick's record at once.
    let mut queue: Queue<TelemetryRecord, 4> = Queue::new();
    let (mut producer, mut consumer) = queue.split();
    loop {
        let playing = id.phase() == Some(IdentifyPhase::Excite);
        let tick = identify_step(id, ctl, rig, &mut producer, tables, false);
        while let Some(rec) = consumer.dequeue() {
            observe(&rec, playing);
        }
        if tick.ticked {
            next_tick(rig);
        }
        if tick.ended || !tick.ticked {
            return;
        }
    }
}

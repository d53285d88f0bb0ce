//! rths firmware: the RTHS controller as one RTIC 2 application for every board
//! (docs/design.md §8). The board is chosen by feature (`board-qemu`, the default emulated
//! Cortex-M4, `board-stm32f4`, or the Cortex-M7 boards `board-mps2-an500` (emulated) and
//! `board-stm32h743`, built with `cargo build-m7`); everything else comes from `rths-app` and the
//! board crate.
//!
//! Tasks, highest priority first:
//! - `control` (the board's tick timer, TIM2, priority 3, `CONTROL_RATE_HZ`): E-stop, DAQ read,
//!   `Controller::tick`, command write, one telemetry record: the measured section. Then, outside
//!   it, the board's harness (on QEMU: the reference response, the NRMSE sums, the plant's advance).
//! - `supervisor` (UART4, pended, priority 2): starts an autonomous run, ends an emulated run (at
//!   `Done` or a settled fault) and reports it.
//! - `telemetry` (USART3, pended every tick, priority 1): drains the record queue to the link
//!   (`link`) or the defmt log.
//!
//! The two lower tasks are bound to spare interrupt vectors and pended by hand rather than being
//! RTIC 2 async software tasks: an async task compiles to a state machine whose resume-after-end arm
//! calls a panic, which `panic-check.sh` (rightly) finds reachable; these tasks stay provably
//! panic-free.
//! - `link_rx` (`link`; the link UART's receive interrupt, USART2, priority 1): the host's requests.
//! - `idle`: `wfi`.
//!
//! What the image runs is data, not a feature: any model kind uploaded over the link, or its
//! compiled-in default (`RTHS_MODEL`, `RTHS_STRUCTURE`: build.rs), installed at boot through the
//! path an upload takes (`analytical.rs`). `fault-inject` injects the fault `RTHS_FAULT` names at
//! build time into the emulated plant (see `build.rs`).
#![no_std]
#![no_main]

// Exactly one board.
const _: () = assert!(
    cfg!(feature = "board-qemu") as u8
        + cfg!(feature = "board-stm32f4") as u8
        + cfg!(feature = "board-mps2-an500") as u8
        + cfg!(feature = "board-stm32h743") as u8
        == 1,
    "enable exactly one board feature: `board-qemu`, `board-stm32f4`, `board-mps2-an500` or \
     `board-stm32h743`"
);
// A default model that does not fit the board's tick is refused by build.rs (with the measured
// estimate), as an upload is refused `TickBudget`.
#[cfg(feature = "board-mps2-an500")]
use rths_board_mps2_an500 as board;
#[cfg(feature = "board-qemu")]
use rths_board_qemu as board;
#[cfg(feature = "board-stm32f4")]
use rths_board_stm32f4 as board;
#[cfg(feature = "board-stm32h743")]
use rths_board_stm32h743 as board;

mod analytical;
mod gen {
    #![allow(
        dead_code,
        clippy::all,
        clippy::unreadable_literal,
        clippy::excessive_precision
    )]
    include!(concat!(env!("OUT_DIR"), "/gen.rs"));
}
mod motion;
mod stack;

#[cfg(feature = "link")]
use core::sync::atomic::AtomicU32;
use core::sync::atomic::{AtomicBool, Ordering};

use rths_app::board::{Board, CounterCalibration as _};
use rths_app::report::{as_expected, write_result, ReportInfo};
use rths_app::Run;
use rths_core::supervisor::{Limits, State};

/// The board this build is for.
type B = board::ThisBoard;

/// A run is under way (from its start to its end); the record plays meanwhile.
static RUNNING: AtomicBool = AtomicBool::new(false);
/// The emulated run is over and reported (set by `supervisor`); its plant does not run again.
static FINISHED: AtomicBool = AtomicBool::new(false);
/// The record has been played to its end and the ramp-down began (set by `control`, logged by
/// `supervisor`).
static RECORD_END: AtomicBool = AtomicBool::new(false);
/// `link`: the run ended; `telemetry` sends `RunEnded` after its last record.
static RUN_ENDED: AtomicBool = AtomicBool::new(false);
/// A site's step is under way, its supervisor running (set by `control` after each tick): its
/// records wait in the telemetry task's outbox for its end (`rths_app::site::Outbox`).
static SITE_STEP_OPEN: AtomicBool = AtomicBool::new(false);
/// `link`: an identification is under way (`rths link ... identify`): the control task plays the
/// excitation instead of the record (set by `link_rx`, cleared by `control` at its end).
static IDENTIFYING: AtomicBool = AtomicBool::new(false);
/// The identification excitation's tables, in flash (`build.rs`; empty without `identify`).
static EXCITATION: rths_app::identify::FlashTables = rths_app::identify::FlashTables::new(
    gen::EXCITATION_UNIT,
    gen::EXCITATION_RAMP,
    gen::EXCITATION_PEAK,
    gen::EXCITATION_PEAK_RATE,
);
/// `link`: the control task's free-running tick count (the clock of the host's silence).
#[cfg(feature = "link")]
static TICK_COUNT: AtomicU32 = AtomicU32::new(0);
/// `link`: [`TICK_COUNT`] at the last valid frame from the host.
#[cfg(feature = "link")]
static LAST_HEARD: AtomicU32 = AtomicU32::new(0);
/// `link`: the run ramps down if the host falls silent (`LinkLoss::RampDown`, chosen at arm time).
#[cfg(feature = "link")]
static LINK_LOSS_RAMP: AtomicBool = AtomicBool::new(false);
/// The supervisor task's interrupt (pended on a fault, a settled fault, the end of the record or
/// `Done`).
const SUPERVISOR_IRQ: board::pac::Interrupt = board::pac::Interrupt::UART4;
/// The telemetry task's interrupt (pended every tick).
const TELEMETRY_IRQ: board::pac::Interrupt = board::pac::Interrupt::USART3;

/// Telemetry queue depth (records): the telemetry task's outbox holds as many.
const QUEUE: usize = rths_app::site::OUTBOX_RECORDS;
/// A site's step-end queue depth (one per step; drained with the telemetry).
const STEP_QUEUE: usize = 16;

/// Stop at boot with a message (init errors): nothing was started.
fn die(msg: &str) -> ! {
    let mut l = heapless::String::<96>::new();
    let _ = core::fmt::Write::write_fmt(&mut l, format_args!("ERROR {msg}"));
    defmt::error!("halted: {=str}", msg);
    B::host_line(&l);
    B::exit(false)
}

/// The injected overrun of tick `k` (`fault-inject` with `RTHS_FAULT=overrun@...`).
fn injected_overrun(k: u32) -> bool {
    #[cfg(feature = "fault-inject")]
    {
        gen::FAULT_OVERRUN && u64::from(k).wrapping_sub(gen::FAULT_START) < gen::FAULT_TICKS
    }
    #[cfg(not(feature = "fault-inject"))]
    {
        let _ = k;
        false
    }
}

/// The injected stall of tick `k` (`fault-inject` with `RTHS_FAULT=stall@...`): the control task
/// never returns, for the watchdog to catch.
fn injected_stall(k: u32) -> bool {
    #[cfg(feature = "fault-inject")]
    {
        gen::FAULT_STALL && u64::from(k) >= gen::FAULT_START
    }
    #[cfg(not(feature = "fault-inject"))]
    {
        let _ = k;
        false
    }
}

/// The fault plan `RTHS_FAULT` named at build time (`fault-inject`).
#[cfg(feature = "fault-inject")]
fn faults() -> rths_hal_sim::FaultPlan {
    use rths_hal_sim::{Fault, FaultPlan};
    match gen::FAULT_KIND {
        Some(kind) => match Fault::new(kind, gen::FAULT_START, gen::FAULT_TICKS)
            .and_then(|f| FaultPlan::none().with(f))
        {
            Ok(p) => p,
            Err(_) => die("RTHS_FAULT: invalid fault"),
        },
        None => FaultPlan::none(),
    }
}

/// The injected fault spec, if any.
fn fault_spec() -> Option<&'static str> {
    #[cfg(feature = "fault-inject")]
    {
        Some(gen::FAULT_SPEC)
    }
    #[cfg(not(feature = "fault-inject"))]
    None
}

/// What the run's RESULT line names: the analytical part in force (compiled in, or uploaded
/// since boot) and where its model came from.
struct InForce {
    scenario: (&'static str, Option<usize>),
    model: &'static str,
}

/// Print the CALIB and RESULT lines; whether the run went as this build expects. `record_ticks`:
/// the ticks of the record played (the compiled-in one's, or an uploaded one's).
fn report(
    r: &Run,
    end: State,
    calib: &<B as Board>::CounterCalibration,
    daq_errors: u32,
    held_samples: u32,
    record_ticks: u32,
    in_force: &InForce,
) -> bool {
    let mut c = heapless::String::<256>::new();
    let _ = calib.write_line(&mut c);
    B::host_line(&c);
    let info = ReportInfo {
        scenario: in_force.scenario.0,
        scenario_suffix: in_force.scenario.1,
        record_ticks,
        model: in_force.model,
        fault_spec: fault_spec(),
        stack: stack::high_water(),
        daq_errors,
        held_samples,
        log_frames_cut: B::log_frames_cut(),
        limits: Limits::paper_actuator(),
    };
    let mut l = heapless::String::<1024>::new();
    let fits = write_result(&mut l, r, end, &info).is_ok();
    B::host_line(&l);
    if !fits {
        B::host_line("ERROR the RESULT line did not fit its buffer");
    }
    fits && as_expected(
        r,
        end,
        &info.limits,
        record_ticks,
        cfg!(feature = "fault-inject"),
    )
}

#[rtic::app(device = crate::board::pac, peripherals = true)]
mod app {
    use super::*;
    use core::mem::MaybeUninit;
    use heapless::spsc::{Consumer, Producer, Queue};
    use rths_app::board::{EStop, Harness, InstrCounter, TickTimer, Watchdog};
    use rths_app::record::RecordStore;
    use rths_app::run::TickFacts;
    use rths_app::site::Outbox;
    use rths_app::{control_step, TelemetryRecord};
    use rths_core::control::Controller;

    /// The link port and the session (the stream's numbering, the model in force). Without `link`
    /// the port is idle.
    pub struct Link {
        port: <B as Board>::Link,
        session: rths_app::link::Session<'static>,
    }

    #[shared]
    struct Shared {
        /// The controller, where `init` built it (its `controller` local).
        ctl: &'static mut Controller,
        timer: <B as Board>::Timer,
        run: Run,
        link: Link,
        /// The ground-motion record in force (compiled in or uploaded) and the upload in progress.
        store: RecordStore<'static>,
        /// `link`: the identification in progress.
        ident: rths_app::identify::Identification,
    }

    #[local]
    struct Local {
        rig: <B as Board>::Rig,
        counter: <B as Board>::Counter,
        estop: <B as Board>::EStop,
        harness: <B as Board>::Harness,
        calibration: <B as Board>::CounterCalibration,
        watchdog: <B as Board>::Watchdog,
        producer: Producer<'static, TelemetryRecord>,
        consumer: Consumer<'static, TelemetryRecord>,
        /// A site's step ends, control task → telemetry task (sent after their tick's record).
        step_ends: Producer<'static, rths_app::site::StepEnd>,
        step_ends_rx: Consumer<'static, rths_app::site::StepEnd>,
        /// ü_g for the coming tick of a run, mm/s².
        ag: f64,
        /// The instruction counter's own overhead, subtracted from each tick's count.
        overhead_instr: u32,
        /// `link`: the frame reader of the host's requests.
        #[cfg(feature = "link")]
        reader: rths_link::FrameReader<{ rths_link::MAX_FRAME }>,
    }

    #[init(local = [queue: Queue<TelemetryRecord, QUEUE> = Queue::new(),
                    step_queue: Queue<rths_app::site::StepEnd, STEP_QUEUE> = Queue::new(),
                    staging: [f64; analytical::STAGING] = [0.0; analytical::STAGING],
                    controller: MaybeUninit<Controller> = MaybeUninit::uninit()])]
    fn init(cx: init::Context) -> (Shared, Local) {
        stack::paint();
        #[allow(unused_mut)] // `fault-inject` changes the rig
        let mut parts = match board::init(cx.device, cx.core) {
            Ok(p) => p,
            Err(e) => {
                defmt::error!("board: {}", defmt::Debug2Format(&e));
                die("board bring-up")
            }
        };
        #[cfg(feature = "fault-inject")]
        parts.rig.inject(faults());
        let store = motion::store();
        // The structure budget's image runs it here and ends the emulation.
        if analytical::BUDGET {
            analytical::structure_budget(
                &mut *cx.local.controller,
                &parts.counter,
                rths_app::board::CounterCalibration::counter_overhead_instr(&parts.calibration),
                |k| store.accel_mm_s2(k),
                store.ticks(),
            );
        }
        let ag0 = store.accel_mm_s2(0);
        <<B as Board>::Harness as Harness<<B as Board>::Rig>>::reset(&mut parts.harness, ag0);
        // The default model, installed as an upload is; the staging area waits for uploads.
        let staging: &'static mut [f64] = cx.local.staging;
        let (ctl, boot) = match analytical::controller(cx.local.controller) {
            Ok(c) => c,
            Err(e) => die(e),
        };
        let (producer, consumer) = cx.local.queue.split();
        let (step_ends, step_ends_rx) = cx.local.step_queue.split();
        defmt::info!(
            "rths firmware: {=str}, model {=str}, {=u32} ticks, tick {=f64} Hz",
            ctl.scenario_name().0,
            gen::MODEL_SOURCE,
            gen::RECORD_TICKS,
            B::tick_rate_hz()
        );
        // An autonomous run: `supervisor` arms, starts and starts the timer. With the link the host
        // does, and the timer runs from now on: a real rig's interlocks watch it whenever a test is
        // armed, and in QEMU a guest that waits in `wfi` with no timer deadline stops its virtual
        // clock from being advanced after the host's `Start`, and the run crawls.
        let mut timer = parts.timer;
        if cfg!(feature = "link") {
            TickTimer::start(&mut timer);
        } else {
            rtic::pend(SUPERVISOR_IRQ);
        }
        (
            Shared {
                ctl,
                timer,
                run: Run::new(),
                link: Link {
                    port: parts.link,
                    session: rths_app::link::Session::new(
                        boot.checksum,
                        analytical::TICK_BUDGET,
                        if B::EMULATED_PLANT {
                            rths_app::link::Rearm::OncePerPowerUp
                        } else {
                            rths_app::link::Rearm::AtMeasured
                        },
                        boot.kind,
                        staging,
                    )
                    .with_excitation(EXCITATION)
                    .with_build_id(analytical::build_id()),
                },
                store,
                ident: rths_app::identify::Identification::new(),
            },
            Local {
                rig: parts.rig,
                counter: parts.counter,
                estop: parts.estop,
                harness: parts.harness,
                calibration: parts.calibration,
                watchdog: parts.watchdog,
                producer,
                consumer,
                step_ends,
                step_ends_rx,
                ag: ag0,
                overhead_instr: parts.calibration.counter_overhead_instr(),
                #[cfg(feature = "link")]
                reader: rths_link::FrameReader::new(),
            },
        )
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        loop {
            // With QEMU's sleep=off, wfi jumps virtual time to the next tick.
            cortex_m::asm::wfi();
        }
    }

    /// The controller tick, `CONTROL_RATE_HZ` (2048 Hz), highest priority.
    ///
    /// Deadline: the next timer update, one tick = 1/2048 s = 488.3 µs after this one fired
    /// (82 031 cycles at 168 MHz). The controller's work (measured) must fit in 10% of it; the whole
    /// task, harness and plant included, must end before the next update, else the next tick is told
    /// it overran, which the run counts and the supervisor sees (4 in a row trip it).
    #[task(binds = TIM2, priority = 3, shared = [ctl, timer, run, store, ident],
           local = [rig, counter, estop, harness, producer, ag, overhead_instr, watchdog,
                    step_ends, k: u32 = 0, overrun: bool = false, watching: bool = false,
                    site_steps: u32 = 0])]
    fn control(mut cx: control::Context) {
        cx.shared.timer.lock(TickTimer::clear);
        feed_watchdog(cx.local.watchdog, cx.local.watching);
        if IDENTIFYING.load(Ordering::Acquire) {
            // An identification (`rths link ... identify`): the excitation instead of the record,
            // through the supervisor as in a test; the plant (emulated boards) moves with it.
            #[cfg(feature = "link")]
            let _ = link_silent();
            if EStop::asserted(cx.local.estop) {
                cx.shared.ctl.lock(|c| c.supervisor_mut().emergency_stop());
            }
            let overrun = *cx.local.overrun;
            let rig = cx.local.rig;
            let producer = cx.local.producer;
            let ctl = &mut cx.shared.ctl;
            let tick = cx.shared.ident.lock(|id| {
                ctl.lock(|c| {
                    rths_app::identify::identify_step(id, c, rig, producer, &EXCITATION, overrun)
                })
            });
            if tick.ticked {
                let _ = Harness::after_tick(cx.local.harness, rig, 0, false, 0.0, f64::NAN);
            }
            if tick.ended {
                IDENTIFYING.store(false, Ordering::Release);
                if B::EMULATED_PLANT {
                    // The emulated plant has run: it plays once per power-up.
                    FINISHED.store(true, Ordering::Release);
                }
                RUN_ENDED.store(true, Ordering::Release);
            }
            rtic::pend(TELEMETRY_IRQ);
            *cx.local.overrun = cx.shared.timer.lock(|t| TickTimer::pending(t));
            return;
        }
        let running = RUNNING.load(Ordering::Acquire);
        // The emulated plant moves only during its run (it must match the host simulation's).
        if !running && B::EMULATED_PLANT {
            return;
        }
        if running && B::EMULATED_PLANT && cx.shared.ctl.lock(|c| rths_app::site::waits(c)) {
            // A site between two targets: the emulated plant holds, as the host's virtual rig
            // waits for its client (a real rig's predictor runs instead).
            return;
        }
        let k = if running { *cx.local.k } else { 0 };
        let record_ticks = cx.shared.store.lock(|s| s.ticks());
        if cfg!(feature = "link") && B::EMULATED_PLANT && running && k == 0 {
            // The record may have been uploaded after boot: the emulated structure starts at rest
            // under its first sample (as `init` did for the compiled-in one).
            let ag0 = cx.shared.store.lock(|s| s.accel_mm_s2(0));
            *cx.local.ag = ag0;
            <<B as Board>::Harness as Harness<<B as Board>::Rig>>::reset(cx.local.harness, ag0);
        }
        let ag = if running { *cx.local.ag } else { 0.0 };
        let overrun = *cx.local.overrun || injected_overrun(k);
        if running && injected_stall(k) {
            defmt::warn!("fault-inject: the control task stalls at tick {=u32}", k);
            loop {
                cortex_m::asm::nop();
            }
        }
        #[cfg(feature = "link")]
        if link_silent() && running {
            // The host fell silent and the run's policy is to ramp down: an abort (a no-op once
            // ramping).
            cx.shared.ctl.lock(|c| c.supervisor_mut().abort());
        }
        if EStop::asserted(cx.local.estop) {
            // Ramps the command to the safe position, whatever the state.
            cx.shared.ctl.lock(|c| c.supervisor_mut().emergency_stop());
        }

        // ---- measured section: the controller's work ----
        let counter = cx.local.counter;
        let rig = cx.local.rig;
        let producer = cx.local.producer;
        let t0 = InstrCounter::now(counter);
        let step = cx
            .shared
            .ctl
            .lock(|c| control_step(c, rig, producer, k, ag, overrun, running));
        let t1 = InstrCounter::now(counter);
        // ---- end of the measured section ----

        let instr =
            InstrCounter::instructions(counter, t0, t1).saturating_sub(*cx.local.overhead_instr);
        let in_record = k < record_ticks;
        let row = Harness::after_tick(cx.local.harness, rig, k, in_record, ag, step.out.target_mm);
        let next_k = if running { k.saturating_add(1) } else { 0 };
        // ü_g for the next tick, interpolated in the slack of this one (docs/design.md §8 counts
        // only the DAQ read, the control step, the command write and the log record).
        let state = step.out.state;
        let site_steps = cx.local.site_steps;
        let (site, step_end, step_open) = cx.shared.ctl.lock(|c| {
            let progress = c.site_progress();
            (
                progress.is_some(),
                rths_app::site::step_ended(c, k, site_steps),
                matches!(progress, Some((true, _))) && state == State::Running,
            )
        });
        SITE_STEP_OPEN.store(step_open, Ordering::Release);
        // A run that plays the record moves through it (a streamed one's ring releases what the
        // run has passed, and a tick whose samples have not arrived is an underrun); at rest, and
        // in a site's run (its client integrates the ground motion), the record is only read.
        let played = cx.shared.store.lock(|s| {
            if running && !site {
                s.play(next_k)
            } else {
                rths_app::record::Played {
                    accel_mm_s2: s.accel_mm_s2(next_k),
                    underrun: false,
                }
            }
        });
        *cx.local.ag = played.accel_mm_s2;
        #[cfg(feature = "link")]
        if played.underrun && LINK_LOSS_RAMP.load(Ordering::Acquire) {
            // A streamed record's samples did not arrive in time, and the run's policy for a lost
            // link is to ramp down (under `Complete` the tick plays 0 g and is counted).
            cx.shared.ctl.lock(|c| c.supervisor_mut().abort());
        }
        if let Some(e) = step_end {
            // Full only if the telemetry task stalls: the host then misses the step and stops.
            let _ = cx.local.step_ends.enqueue(e);
        }
        // A site's test ends when its client's analysis does, not with the record.
        let record_end = running && !site && next_k >= record_ticks && state == State::Running;
        let ended = cx.shared.ctl.lock(|c| {
            if record_end {
                let _ = c.supervisor_mut().finish();
            }
            // A real rig's run ends at `Done`, or in a fault once the command is at rest.
            !B::EMULATED_PLANT
                && running
                && (state == State::Done
                    || (matches!(state, State::Fault(_)) && c.supervisor().at_rest()))
        });
        let facts = TickFacts {
            k,
            counted: if B::EMULATED_PLANT {
                in_record
            } else {
                running
            },
            row,
            instr,
            command_mm: step.out.command_mm,
            measured_mm: step.measured_mm,
            state,
            overrun,
            queued: step.queued,
        };
        let notify = cx.shared.run.lock(|r| r.after_tick(&facts));
        *cx.local.k = next_k;
        if ended {
            RUNNING.store(false, Ordering::Release);
            RUN_ENDED.store(true, Ordering::Release);
        }
        if record_end {
            RECORD_END.store(true, Ordering::Release);
        }
        if notify || record_end {
            rtic::pend(SUPERVISOR_IRQ);
        }
        rtic::pend(TELEMETRY_IRQ);
        // The next update already fired: this tick overran its deadline.
        *cx.local.overrun = cx.shared.timer.lock(|t| TickTimer::pending(t));
    }

    /// `link`: count this tick; the host has been silent for longer than the link timeout and the
    /// run's policy is to ramp down.
    #[cfg(feature = "link")]
    fn link_silent() -> bool {
        let now = TICK_COUNT.fetch_add(1, Ordering::AcqRel).wrapping_add(1);
        let policy = if LINK_LOSS_RAMP.load(Ordering::Acquire) {
            rths_link::LinkLoss::RampDown
        } else {
            rths_link::LinkLoss::Complete
        };
        rths_app::link::link_lost(policy, now, LAST_HEARD.load(Ordering::Acquire))
    }

    /// The watchdog runs from the first tick on; every tick feeds it. Out of line, so that the
    /// control task's measured section compiles as it did without it.
    #[inline(never)]
    fn feed_watchdog(w: &mut <B as Board>::Watchdog, watching: &mut bool) {
        if !*watching {
            *watching = true;
            Watchdog::start(w);
        }
        Watchdog::feed(w);
    }

    /// The supervisor: starts an autonomous run; stops an emulated run on a settled fault or at
    /// `Done`, and reports it.
    #[task(binds = UART4, priority = 2, shared = [ctl, timer, run, store, link],
           local = [calibration, started: bool = cfg!(feature = "link")])]
    fn supervisor(mut cx: supervisor::Context) {
        if !*cx.local.started {
            *cx.local.started = true;
            let ok = cx.shared.ctl.lock(|c| {
                let s = c.supervisor_mut();
                s.arm().is_ok() && s.start().is_ok()
            });
            if !ok {
                die("supervisor would not arm");
            }
            defmt::info!("supervisor: armed, running");
            RUNNING.store(true, Ordering::Release);
            cx.shared.timer.lock(TickTimer::start);
            return;
        }
        if RECORD_END.swap(false, Ordering::AcqRel) {
            defmt::info!("supervisor: end of record, ramp-down");
        }
        let state = cx.shared.ctl.lock(|c| c.supervisor().state());
        let run = cx.shared.run.lock(|r| *r);
        let stop = B::EMULATED_PLANT
            && match state {
                State::Done => true,
                State::Fault(_) => run.fault_settled(),
                _ => false,
            };
        if let (State::Fault(reason), Some(t)) = (state, run.fault_tick) {
            if !stop {
                defmt::warn!("supervisor: fault {=str} at tick {=u32}", reason.name(), t);
            }
        }
        if stop && !FINISHED.swap(true, Ordering::AcqRel) {
            cx.shared.timer.lock(TickTimer::stop);
            let (daq_errors, held, part) = cx.shared.ctl.lock(|c| {
                (
                    c.supervisor().total_daq_errors(),
                    c.held_samples(),
                    c.scenario_name(),
                )
            });
            let record_ticks = cx.shared.store.lock(|s| s.ticks());
            let uploaded = cx
                .shared
                .link
                .lock(|l| l.session.model_source == rths_link::RecordSource::Uploaded);
            let in_force = InForce {
                scenario: part,
                model: if uploaded {
                    "uploaded over the link"
                } else {
                    gen::MODEL_SOURCE
                },
            };
            let ok = report(
                &run,
                state,
                cx.local.calibration,
                daq_errors,
                held,
                record_ticks,
                &in_force,
            );
            if cfg!(feature = "link") {
                // The board stays up for the host (status, the telemetry's end).
                RUN_ENDED.store(true, Ordering::Release);
                rtic::pend(TELEMETRY_IRQ);
            } else {
                B::exit(ok);
            }
        }
    }

    /// Drains the telemetry queue at the lowest priority. With `link` it streams every `every`-th
    /// record to the host, numbered, and after the run's last record `RunEnded`; without, it logs
    /// one record per second of test time.
    #[task(binds = USART3, priority = 1, shared = [link, run, ident],
           local = [consumer, step_ends_rx, outbox: Outbox = Outbox::new()])]
    fn telemetry(mut cx: telemetry::Context) {
        use rths_app::link::send;
        let consumer = cx.local.consumer;
        let steps = cx.local.step_ends_rx;
        let outbox = cx.local.outbox;
        if !cfg!(feature = "link") {
            while let Some(r) = consumer.dequeue() {
                if r.tick % rths_app::ONE_SECOND_TICKS == 0 {
                    defmt::info!(
                        "t={=u32} state={=u8} cmd={=f64} mm target={=f64} mm meas={=f64} mm F={=f64} kN",
                        r.tick,
                        state_code(r.state),
                        r.command_mm,
                        r.target_mm,
                        r.measured_mm,
                        r.force_kn
                    );
                }
            }
            return;
        }
        cx.shared
            .link
            .lock(|l| send_outbox(l, consumer, steps, outbox, false));
        if RUN_ENDED.swap(false, Ordering::AcqRel) {
            let run = cx.shared.run.lock(|r| *r);
            let id = cx.shared.ident.lock(|i| *i);
            cx.shared.link.lock(|l| {
                // Records queued after the drain above (before the end was seen) go first.
                send_outbox(l, consumer, steps, outbox, true);
                let end = if l.session.identifying {
                    l.session.identify_ended(&id)
                } else {
                    l.session.run_ended(&run)
                };
                send(&mut l.port, &end);
            });
        }
    }

    /// Send what the outbox gives, records taken from the telemetry queue as room allows: each
    /// record's telemetry, and a site's step ends (`SiteStep`, its reading) before the step's
    /// records (`rths_app::site::Outbox`); `flush` at the run's end.
    fn send_outbox(
        l: &mut Link,
        queue: &mut Consumer<'static, TelemetryRecord>,
        steps: &mut Consumer<'static, rths_app::site::StepEnd>,
        outbox: &mut Outbox,
        flush: bool,
    ) {
        use rths_app::link::send;
        use rths_app::site::Outgoing;
        loop {
            while !outbox.is_full() {
                match queue.dequeue().map(|r| outbox.push(r)) {
                    Some(Ok(())) => {}
                    // Not full: a push cannot fail; and a record is never dropped here.
                    Some(Err(_)) | None => break,
                }
            }
            let open = SITE_STEP_OPEN.load(Ordering::Acquire);
            match outbox.next(steps.peek().copied(), open, flush) {
                Some(Outgoing::Record(r)) => {
                    if let Some(m) = l.session.telemetry(&r) {
                        send(&mut l.port, &m);
                    }
                }
                Some(Outgoing::StepEnd(m)) => {
                    let _ = steps.dequeue();
                    send(&mut l.port, &m);
                }
                None => break,
            }
        }
    }

    /// The emulated board's watchdog (QEMU models no IWDG; the real board's IWDG resets the MCU in
    /// hardware): TIM5 (on the Cortex-M7 twin, CMSDK TIMER1), above the control task, every 2 ms; no tick in that time while the tick
    /// timer should run (a stalled control task) ends the emulation with a `WATCHDOG` line and a
    /// failure status, what a reset is to the real board's run.
    #[cfg(any(feature = "board-qemu", feature = "board-mps2-an500"))]
    #[task(binds = TIM5, priority = 4)]
    fn watchdog(_: watchdog::Context) {
        if board::watchdog_expired() && !FINISHED.load(Ordering::Acquire) {
            B::host_line("WATCHDOG the control task stalled (no tick for 2 ms): safe state");
            B::exit(false);
        }
    }

    /// `link`: the host's requests, one answer each (the link UART's receive interrupt, lowest
    /// priority).
    #[cfg(feature = "link")]
    #[task(binds = USART2, priority = 1, shared = [ctl, run, link, store, ident], local = [reader])]
    fn link_rx(mut cx: link_rx::Context) {
        use rths_app::board::LinkPort;
        use rths_app::link::{handle, send, Effect};
        use rths_link::HostMsg;
        while let Some(byte) = cx.shared.link.lock(|l| LinkPort::read_byte(&mut l.port)) {
            let msg = match cx.local.reader.push::<HostMsg>(byte) {
                None => continue,
                Some(Err(_)) => {
                    cx.shared
                        .link
                        .lock(|l| l.session.bad_frames = l.session.bad_frames.saturating_add(1));
                    continue;
                }
                Some(Ok(m)) => m,
            };
            LAST_HEARD.store(TICK_COUNT.load(Ordering::Acquire), Ordering::Release);
            let finished = FINISHED.load(Ordering::Acquire);
            let ctl = &mut cx.shared.ctl;
            let run = &mut cx.shared.run;
            let store = &mut cx.shared.store;
            let ident = &mut cx.shared.ident;
            let (answer, effect) = cx.shared.link.lock(|l| {
                ctl.lock(|c| {
                    run.lock(|r| {
                        store.lock(|st| {
                            ident.lock(|id| {
                                let (a, e) = handle(msg, c, r, st, &mut l.session, finished);
                                if let Effect::Identify(player) = e {
                                    // Under the controller's lock: the control task's next tick
                                    // is the identification's first.
                                    id.start(player);
                                    IDENTIFYING.store(true, Ordering::Release);
                                }
                                (a, e)
                            })
                        })
                    })
                })
            });
            let ramp = cx
                .shared
                .link
                .lock(|l| l.session.link_loss == rths_link::LinkLoss::RampDown);
            LINK_LOSS_RAMP.store(ramp, Ordering::Release);
            if let Effect::Identify(_) = effect {
                defmt::info!("link: identifying");
            }
            if effect == Effect::Started {
                defmt::info!("link: running");
                RUNNING.store(true, Ordering::Release);
            }
            cx.shared.link.lock(|l| send(&mut l.port, &answer));
        }
    }
}

/// A state's number in the log.
fn state_code(s: State) -> u8 {
    match s {
        State::Idle => 0,
        State::Armed => 1,
        State::Running => 2,
        State::RampDown => 3,
        State::Done => 4,
        State::Fault(_) => 5,
    }
}

//! rths firmware: the RTHS controller as an RTIC 2 application (DESIGN §8).
//!
//! Tasks, highest priority first:
//! - `control` (TIM2 update, priority 3, 2048 Hz): DAQ read, `Controller::tick`, command write, one
//!   telemetry record: the measured section. Then, outside it, the qemu board's test harness: the
//!   reference response, the NRMSE sums and the plant's advance to the next tick.
//! - `supervisor` (priority 2, pended on events): drives the state machine of the controller's
//!   supervisor (idle → armed → running → ramp-down → done, or fault), stops the test, reports.
//! - `telemetry` (priority 1, pended every tick): drains the record queue, logs with defmt.
//! - `idle`: `wfi`.
//!
//! The analytical part is chosen by feature: `model-lr` (default, `lr-online`), `model-rnn`
//! (`rnn-online-H`), `fe-ats` (`fe-online-ats`), `model-lrx` (`lrx-online`). `fault-inject` injects
//! the fault `RTHS_FAULT` names at build time (default: a NaN on the LVDT from 10 s on; see
//! `build.rs`).
#![no_std]
#![no_main]

mod gen {
    #![allow(
        dead_code,
        clippy::all,
        clippy::unreadable_literal,
        clippy::excessive_precision
    )]
    include!(concat!(env!("OUT_DIR"), "/gen.rs"));
}
#[cfg(feature = "link")]
mod link;
mod logger;
mod motion;
mod stack;

use core::sync::atomic::{AtomicBool, Ordering};

use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use rths_core::params::{Prototype, SpecimenScale, DT_S};
use rths_core::supervisor::{Limits, State};

/// The run is over: stop ticking (set by `supervisor`).
static FINISHED: AtomicBool = AtomicBool::new(false);
/// The record has been played to its end (set by `control`).
static RECORD_END: AtomicBool = AtomicBool::new(false);
/// `link`: the run is over and reported; `telemetry_link` sends `RunEnded` after the last record.
#[cfg(feature = "link")]
static RUN_ENDED: AtomicBool = AtomicBool::new(false);
/// `link`: the host started the run; until then the tick only acknowledges the timer. (The timer
/// runs from boot: in QEMU a guest that waits in `wfi` with no timer deadline stops its virtual clock
/// from being advanced after the host's `Start`, and the run crawls.)
#[cfg(feature = "link")]
static LINK_RUNNING: AtomicBool = AtomicBool::new(false);

/// Ticks the fault hold must be steady before the run is stopped (1 s).
const FAULT_SETTLE_TICKS: u32 = 2048;
/// The end-of-test ramp rate of `Limits::paper_actuator()`, mm/s (core has no accessor for it; only
/// reported, for the ramp check of the integration test).
pub const END_RAMP_RATE_MM_S: f64 = 10.0;
/// Telemetry decimation for the defmt log (one record per second of test time).
#[cfg_attr(feature = "link", allow(dead_code))]
const LOG_EVERY: u32 = 2048;

#[cfg(feature = "model-rnn")]
const SCENARIO_PREFIX: &str = "rnn-online-";
#[cfg(all(feature = "fe-ats", not(feature = "model-rnn")))]
const SCENARIO_PREFIX: &str = "fe-online-ats";
#[cfg(all(
    feature = "model-lrx",
    not(any(feature = "model-rnn", feature = "fe-ats"))
))]
const SCENARIO_PREFIX: &str = "lrx-online";
#[cfg(not(any(feature = "model-rnn", feature = "fe-ats", feature = "model-lrx")))]
const SCENARIO_PREFIX: &str = "lr-online";

/// One telemetry record (what the controller did at a tick).
#[derive(Debug, Clone, Copy)]
pub struct Record {
    tick: u32,
    command_mm: f64,
    target_mm: f64,
    measured_mm: f64,
    force_kn: f64,
    state: State,
}

/// Statistics of the run, written by `control`, read by `supervisor` at the end.
#[derive(Debug, Clone, Copy)]
pub struct Run {
    /// Record ticks done.
    ticks: u32,
    /// Σ (target − reference)² over the rows, mm².
    sum_sq: f64,
    /// max |reference|, mm.
    peak_ref_mm: f64,
    instr_min: u32,
    instr_max: u32,
    instr_sum: u64,
    instr_n: u32,
    overruns: u32,
    telemetry_dropped: u32,
    /// Supervisor state after the last tick.
    state: State,
    /// Tick of the first fault.
    fault_tick: Option<u32>,
    /// Command before the trip, mm.
    cmd_before_fault_mm: f64,
    /// Largest |Δcommand| per tick from the trip on, mm.
    max_step_after_fault_mm: f64,
    /// Ticks after the trip on which the command moved (the fault ramp).
    fault_ramp_ticks: u32,
    /// Ticks the command has not moved while in fault.
    fault_steady_ticks: u32,
    /// Ticks from `finish()` to `Done`.
    ramp_ticks: u32,
    /// Largest |Δcommand| per tick in the end ramp, mm.
    max_ramp_step_mm: f64,
    /// Last command, mm.
    last_cmd_mm: f64,
    /// Largest |Δcommand| per tick over the whole run, mm.
    max_step_mm: f64,
    /// Largest |command|, mm.
    peak_cmd_mm: f64,
}

impl Run {
    const fn new() -> Self {
        Self {
            ticks: 0,
            sum_sq: 0.0,
            peak_ref_mm: 0.0,
            instr_min: u32::MAX,
            instr_max: 0,
            instr_sum: 0,
            instr_n: 0,
            overruns: 0,
            telemetry_dropped: 0,
            state: State::Idle,
            fault_tick: None,
            cmd_before_fault_mm: 0.0,
            max_step_after_fault_mm: 0.0,
            fault_ramp_ticks: 0,
            fault_steady_ticks: 0,
            ramp_ticks: 0,
            max_ramp_step_mm: 0.0,
            last_cmd_mm: 0.0,
            max_step_mm: 0.0,
            peak_cmd_mm: 0.0,
        }
    }
}

fn config() -> Result<ControlConfig, &'static str> {
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

#[cfg(all(
    feature = "model-lrx",
    not(any(feature = "model-rnn", feature = "fe-ats"))
))]
fn analytical() -> Result<(Analytical, Compensator), &'static str> {
    use rths_core::compensator::{Lead, LeadParams};
    use rths_core::metamodel::{Lrx, LrxParams};
    let p = LrxParams::new(gen::LRX_COEFFS, gen::LRX_K_CORR, gen::LRX_K_ADAPT)
        .map_err(|_| "LRX model")?;
    let lead = LeadParams::new(gen::LRX_LEAD, gen::LRX_LEAD_STRIDE).map_err(|_| "LRX lead")?;
    Ok((
        Analytical::Lrx(Lrx::new(p)),
        Compensator::Lead(Lead::new(lead)),
    ))
}

#[cfg(not(any(feature = "model-rnn", feature = "fe-ats", feature = "model-lrx")))]
fn analytical() -> Result<(Analytical, Compensator), &'static str> {
    use rths_core::metamodel::{Lr, LrParams};
    let p = LrParams::new(gen::LR_THETA).map_err(|_| "LR model")?;
    Ok((Analytical::Lr(Lr::new(p)), Compensator::None))
}

#[cfg(feature = "model-rnn")]
fn analytical() -> Result<(Analytical, Compensator), &'static str> {
    use rths_core::metamodel::{Rnn, RnnParams, RnnScaling, RnnWeights};
    let w = RnnWeights {
        w_ih: &gen::RNN_W_IH,
        w_hh: &gen::RNN_W_HH,
        b_h: &gen::RNN_B_H,
        w_ho: &gen::RNN_W_HO,
        b_o: gen::RNN_B_O,
    };
    let s = RnnScaling {
        input_mean: gen::RNN_IN_MEAN,
        input_std: gen::RNN_IN_STD,
        output_mean: gen::RNN_OUT_MEAN,
        output_std: gen::RNN_OUT_STD,
    };
    let p = RnnParams::new(w, s).map_err(|_| "RNN model")?;
    Ok((Analytical::Rnn(Rnn::new(p)), Compensator::None))
}

#[cfg(all(feature = "fe-ats", not(feature = "model-rnn")))]
fn analytical() -> Result<(Analytical, Compensator), &'static str> {
    use rths_core::compensator::{Ats, AtsConfig, AtsParams};
    use rths_core::control::FeModel;
    use rths_core::params::PAPER_DELAY_STEPS;
    let fe = FeModel::new(Prototype::paper(), DT_S).map_err(|_| "FE model")?;
    let delay_s = PAPER_DELAY_STEPS as f64 * DT_S;
    let ats = AtsParams::new(AtsConfig::paper(DT_S, delay_s)).map_err(|_| "ATS")?;
    Ok((Analytical::Fe(fe), Compensator::Ats(Ats::new(ats))))
}

fn faults() -> rths_hal_sim::FaultPlan {
    #[cfg(feature = "fault-inject")]
    {
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
    #[cfg(not(feature = "fault-inject"))]
    rths_hal_sim::FaultPlan::none()
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

#[cfg_attr(feature = "link", allow(dead_code))]
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

/// Stop with a message (init errors).
fn die(msg: &str) -> ! {
    let mut l = logger::Line::<96>::new();
    l.put(format_args!("ERROR {msg}"));
    logger::host_line(&l.0);
    rths_board_qemu::exit(false)
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    logger::host_line("PANIC");
    rths_board_qemu::exit(false)
}

/// The test harness half of the qemu board: the reference response of the same structure (pure FE,
/// Chang, as `rths::analysis::pure_response`), computed along the run.
pub struct Harness {
    reference: rths_core::integrator::Chang<1>,
    proto: Prototype,
    /// target(k) as the host's history row k holds it (produced at tick k−1).
    target_row_mm: f64,
}

#[rtic::app(device = stm32f4::stm32f405, peripherals = true)]
mod app {
    use super::*;
    use heapless::spsc::{Consumer, Producer, Queue};
    use rths_board_qemu::{InstrCounter, Plant, TickTimer};
    use rths_core::integrator::{Chang, ExplicitIntegrator};
    use rths_core::structure::{LinearStructure, Vector};
    use stm32f4::stm32f405::Interrupt;

    /// Telemetry queue depth (records).
    const QUEUE: usize = 64;
    /// The telemetry task's interrupt (the link's streaming task with `link`).
    #[cfg(not(feature = "link"))]
    const TELEMETRY_IRQ: Interrupt = Interrupt::USART3;
    #[cfg(feature = "link")]
    const TELEMETRY_IRQ: Interrupt = Interrupt::UART5;

    #[shared]
    struct Shared {
        ctl: Controller,
        timer: TickTimer,
        run: Run,
        /// `link`: the port and the telemetry stream's state (nothing without `link`).
        link: LinkPort,
    }

    #[local]
    struct Local {
        rig: Plant,
        counter: InstrCounter,
        producer: Producer<'static, Record>,
        #[cfg(not(feature = "link"))]
        consumer: Consumer<'static, Record>,
        #[cfg(feature = "link")]
        link_consumer: Consumer<'static, Record>,
        harness: Harness,
        overhead_instr: u32,
        /// ü_g for the coming tick, mm/s².
        ag: f64,
        calib: rths_board_qemu::Calibration,
        /// `link`: the active model's checksum.
        #[cfg(feature = "link")]
        model_checksum: u32,
        /// `link`: the frame reader of the host's requests.
        #[cfg(feature = "link")]
        reader: LinkReader,
    }

    #[init(local = [queue: Queue<Record, QUEUE> = Queue::new()])]
    fn init(cx: init::Context) -> (Shared, Local) {
        stack::paint();
        let dp = cx.device;
        let counter = InstrCounter::new(cx.core.SYST);
        let mut timer = TickTimer::new(dp.TIM2, &dp.RCC);
        let calib = rths_board_qemu::calibrate(&counter, &mut timer, 100_000);
        let (analytical, compensator) = match analytical() {
            Ok(a) => a,
            Err(e) => die(e),
        };
        let cfg = match config() {
            Ok(c) => c,
            Err(e) => die(e),
        };
        let ctl = Controller::new(cfg, analytical, compensator);
        let rig = match Plant::new(1, faults()) {
            Some(r) => r,
            None => die("plant configuration"),
        };
        let proto = Prototype::paper();
        let mut reference =
            match LinearStructure::prototype_pure(&proto).and_then(|s| Chang::new(s, DT_S)) {
                Ok(c) => c,
                Err(_) => die("reference structure"),
            };
        reference.reset(motion::ground_accel_mm_s2(0));
        let (producer, consumer) = cx.local.queue.split();
        defmt::info!(
            "rths firmware: {=str}, model {=str}, {=u32} ticks",
            SCENARIO_PREFIX,
            gen::MODEL_SOURCE,
            gen::RECORD_TICKS
        );
        // Autonomous run: the supervisor arms and starts at once. With `link` the host does, and the
        // timer runs from now on (see `LINK_RUNNING`).
        #[cfg(not(feature = "link"))]
        rtic::pend(Interrupt::UART4);
        #[cfg(feature = "link")]
        timer.start();
        (
            Shared {
                ctl,
                timer,
                run: Run::new(),
                link: LinkPort::new(dp.USART1, &dp.RCC),
            },
            Local {
                rig,
                counter,
                producer,
                #[cfg(not(feature = "link"))]
                consumer,
                #[cfg(feature = "link")]
                link_consumer: consumer,
                harness: Harness {
                    reference,
                    proto,
                    target_row_mm: 0.0,
                },
                overhead_instr: calib.overhead_instructions,
                ag: motion::ground_accel_mm_s2(0),
                calib,
                #[cfg(feature = "link")]
                model_checksum: link::compiled_model_checksum(&gen::LR_THETA),
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

    /// The controller tick, 2048 Hz, highest priority.
    ///
    /// Deadline: the next TIM2 update, one tick = 1/2048 s = 488.3 µs after this one fired
    /// (82 031 cycles at 168 MHz). The controller's work (measured) must fit in 10% of it; the whole
    /// task, harness and plant included, must end before the next update, else that tick is counted as
    /// an overrun and passed to the supervisor (4 in a row trip it).
    #[task(binds = TIM2, priority = 3, shared = [ctl, timer, run],
           local = [rig, counter, producer, harness, overhead_instr, ag,
                    k: u32 = 0, overrun: bool = false, prev_state: State = State::Idle])]
    fn control(mut cx: control::Context) {
        cx.shared.timer.lock(|t| t.clear());
        #[cfg(feature = "link")]
        if !LINK_RUNNING.load(Ordering::Acquire) {
            return;
        }
        let k = *cx.local.k;
        let rig = cx.local.rig;
        let overrun = *cx.local.overrun || injected_overrun(k);

        // ---- measured section: the controller's work ----
        let t0 = cx.local.counter.now();
        let ag = *cx.local.ag;
        let producer = cx.local.producer;
        let (out, queued) = cx
            .shared
            .ctl
            .lock(|c| control_step(c, rig, producer, k, ag, overrun));
        let t1 = cx.local.counter.now();
        // ---- end of the measured section ----

        let instr = InstrCounter::ticks_to_instructions(InstrCounter::elapsed_ticks(t0, t1))
            .saturating_sub(*cx.local.overhead_instr);

        // The harness: host history row k (reference and the target produced at tick k−1).
        let h = cx.local.harness;
        let in_record = k < gen::RECORD_TICKS;
        let mut row_err_sq = 0.0;
        let mut ref_abs = 0.0;
        if in_record {
            let reference_mm = if k == 0 {
                h.proto.brace_disp_mm(0.0)
            } else {
                h.reference.advance(ag, &Vector::<1>::zeros());
                h.proto.brace_disp_mm(h.reference.state().disp.x)
            };
            let e = h.target_row_mm - reference_mm;
            row_err_sq = e * e;
            ref_abs = libm::fabs(reference_mm);
        }
        if out.target_mm.is_finite() {
            h.target_row_mm = out.target_mm;
        }
        // The plant converts the command and moves to the next tick (on a real rig: the DAC and the
        // physical world). A clip cannot happen: the supervisor keeps the command within the stroke.
        let _ = rig.advance();
        // ü_g for the next tick, interpolated in the slack of this one (DESIGN §8 counts only the DAQ
        // read, the control step, the command write and the log record).
        *cx.local.ag = motion::ground_accel_mm_s2(k.saturating_add(1));

        let prev_state = *cx.local.prev_state;
        let notify = cx.shared.run.lock(|r| {
            let step = libm::fabs(out.command_mm - r.last_cmd_mm);
            r.max_step_mm = r.max_step_mm.max(step);
            r.peak_cmd_mm = r.peak_cmd_mm.max(libm::fabs(out.command_mm));
            if in_record {
                r.ticks = k + 1;
                r.sum_sq += row_err_sq;
                r.peak_ref_mm = r.peak_ref_mm.max(ref_abs);
                r.instr_min = r.instr_min.min(instr);
                r.instr_max = r.instr_max.max(instr);
                r.instr_sum += instr as u64;
                r.instr_n += 1;
            }
            if overrun {
                r.overruns = r.overruns.saturating_add(1);
            }
            if !queued {
                r.telemetry_dropped = r.telemetry_dropped.saturating_add(1);
            }
            let mut notify = false;
            match out.state {
                State::Fault(_) => {
                    if r.fault_tick.is_none() {
                        r.fault_tick = Some(k);
                        r.cmd_before_fault_mm = r.last_cmd_mm;
                        notify = true;
                    }
                    r.max_step_after_fault_mm = r.max_step_after_fault_mm.max(step);
                    if step > 0.0 {
                        r.fault_ramp_ticks = r.fault_ramp_ticks.saturating_add(1);
                    }
                    r.fault_steady_ticks = if step == 0.0 {
                        r.fault_steady_ticks.saturating_add(1)
                    } else {
                        0
                    };
                    notify |= r.fault_steady_ticks == FAULT_SETTLE_TICKS;
                }
                State::RampDown | State::Done => {
                    r.ramp_ticks = r.ramp_ticks.saturating_add(1);
                    r.max_ramp_step_mm = r.max_ramp_step_mm.max(step);
                    notify |= out.state == State::Done && prev_state != State::Done;
                }
                _ => {}
            }
            r.last_cmd_mm = out.command_mm;
            r.state = out.state;
            notify
        });
        *cx.local.prev_state = out.state;
        *cx.local.k = k.saturating_add(1);
        if k + 1 == gen::RECORD_TICKS {
            RECORD_END.store(true, Ordering::Release);
            rtic::pend(Interrupt::UART4);
        }
        if notify {
            rtic::pend(Interrupt::UART4);
        }
        rtic::pend(TELEMETRY_IRQ);
        // The next update already fired: this tick overran its deadline.
        *cx.local.overrun = cx.shared.timer.lock(|t| t.pending());
    }

    /// The supervisor: starts the test, ends it at the end of the record (ramp-down), stops on a
    /// settled fault or at `Done`, and reports.
    #[task(binds = UART4, priority = 2, shared = [ctl, timer, run],
           local = [calib, started: bool = cfg!(feature = "link")])]
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
            cx.shared.timer.lock(|t| t.start());
            return;
        }
        let state = cx.shared.ctl.lock(|c| c.supervisor().state());
        if RECORD_END.load(Ordering::Acquire) && state == State::Running {
            let _ = cx.shared.ctl.lock(|c| c.supervisor_mut().finish());
            defmt::info!("supervisor: end of record, ramp-down");
            return;
        }
        let run = cx.shared.run.lock(|r| *r);
        let stop = match state {
            State::Done => true,
            State::Fault(_) => run.fault_steady_ticks >= FAULT_SETTLE_TICKS,
            _ => false,
        };
        if let (State::Fault(reason), Some(t)) = (state, run.fault_tick) {
            if !stop {
                defmt::warn!(
                    "supervisor: fault {=str} at tick {=u32}",
                    reason_str(reason),
                    t
                );
            }
        }
        if stop && !FINISHED.swap(true, Ordering::AcqRel) {
            cx.shared.timer.lock(|t| t.stop());
            let (daq_errors, held) = cx
                .shared
                .ctl
                .lock(|c| (c.supervisor().total_daq_errors(), c.held_samples()));
            let ok = report(&run, state, cx.local.calib, daq_errors, held);
            // With `link` the board stays up for the host (status, the telemetry's end).
            #[cfg(feature = "link")]
            {
                let _ = ok;
                RUN_ENDED.store(true, Ordering::Release);
                rtic::pend(TELEMETRY_IRQ);
            }
            #[cfg(not(feature = "link"))]
            rths_board_qemu::exit(ok);
        }
    }

    /// Drains the telemetry queue at the lowest priority; logs one record per second of test time.
    #[cfg(not(feature = "link"))]
    #[task(binds = USART3, priority = 1, local = [consumer, received: u32 = 0])]
    fn telemetry(cx: telemetry::Context) {
        while let Some(r) = cx.local.consumer.dequeue() {
            *cx.local.received = cx.local.received.wrapping_add(1);
            if r.tick % LOG_EVERY == 0 {
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
    }

    /// `link`: drains the telemetry queue and streams every `every`-th record to the host, numbered;
    /// after the run's last record, `RunEnded`.
    #[cfg(feature = "link")]
    #[task(binds = UART5, priority = 1, shared = [link, run], local = [link_consumer])]
    fn telemetry_link(mut cx: telemetry_link::Context) {
        use rths_link::{DeviceMsg, Telemetry};
        let consumer = cx.local.link_consumer;
        cx.shared.link.lock(|l| {
            while let Some(r) = consumer.dequeue() {
                if r.tick % l.every != 0 {
                    continue;
                }
                let seq = l.seq;
                l.seq = l.seq.wrapping_add(1);
                l.send(&DeviceMsg::Telemetry(Telemetry {
                    seq,
                    tick: r.tick,
                    state: link::run_state(r.state),
                    command_mm: r.command_mm,
                    target_mm: r.target_mm,
                    measured_mm: r.measured_mm,
                    force_kn: r.force_kn,
                }));
            }
        });
        if RUN_ENDED.swap(false, Ordering::AcqRel) {
            let run = cx.shared.run.lock(|r| *r);
            cx.shared.link.lock(|l| {
                l.send(&DeviceMsg::RunEnded {
                    state: link::run_state(run.state),
                    ticks: run.ticks,
                    records_sent: l.seq,
                    records_dropped: run.telemetry_dropped,
                })
            });
        }
    }

    /// `link`: the host's requests, one answer each (USART1 receive interrupt, lowest priority).
    #[cfg(feature = "link")]
    #[task(binds = USART1, priority = 1, shared = [ctl, timer, run, link],
           local = [model_checksum, reader])]
    fn link_rx(mut cx: link_rx::Context) {
        use rths_link::{DeviceMsg, HostMsg, NackReason};
        while let Some(byte) = cx.shared.link.lock(|l| l.uart.read_byte()) {
            let msg = match cx.local.reader.push::<HostMsg>(byte) {
                None => continue,
                Some(Err(_)) => {
                    cx.shared
                        .link
                        .lock(|l| l.bad_frames = l.bad_frames.saturating_add(1));
                    continue;
                }
                Some(Ok(m)) => m,
            };
            let req = msg.request();
            let result: Result<(), NackReason> = match msg {
                HostMsg::Status => {
                    let (tick, dropped) = cx.shared.run.lock(|r| (r.ticks, r.telemetry_dropped));
                    let crc = *cx.local.model_checksum;
                    let (sent, bad) = cx.shared.link.lock(|l| (l.seq, l.bad_frames));
                    let st = cx
                        .shared
                        .ctl
                        .lock(|c| link::status(c, crc, tick, sent, dropped, bad));
                    cx.shared.link.lock(|l| l.send(&DeviceMsg::Status(st)));
                    continue;
                }
                HostMsg::UploadLr {
                    features,
                    theta,
                    delay_steps,
                    checksum,
                } => {
                    #[cfg(not(any(feature = "model-rnn", feature = "fe-ats")))]
                    {
                        let r = cx
                            .shared
                            .ctl
                            .lock(|c| link::upload_lr(c, features, &theta, delay_steps, checksum));
                        r.map(|crc| *cx.local.model_checksum = crc)
                    }
                    #[cfg(any(feature = "model-rnn", feature = "fe-ats"))]
                    {
                        let _ = (features, theta, delay_steps, checksum);
                        Err(NackReason::Unsupported)
                    }
                }
                HostMsg::SetLimits {
                    stroke_mm,
                    velocity_mm_s,
                    force_kn,
                } => cx
                    .shared
                    .ctl
                    .lock(|c| link::set_limits(c, stroke_mm, velocity_mm_s, force_kn)),
                HostMsg::Arm { telemetry_every } => {
                    if telemetry_every == 0 {
                        Err(NackReason::OutOfRange)
                    } else if FINISHED.load(Ordering::Acquire) {
                        // The emulated plant and the record play once per power-up.
                        Err(NackReason::Unsupported)
                    } else {
                        // The emulated plant starts exactly at rest at 0 mm, as the host
                        // simulation's does: arm there (a real board arms at its measured position).
                        let r = cx.shared.ctl.lock(|c| {
                            c.supervisor_mut()
                                .arm()
                                .map_err(|_| NackReason::InvalidState)
                        });
                        if r.is_ok() {
                            cx.shared.link.lock(|l| {
                                l.every = u32::from(telemetry_every);
                                l.seq = 0;
                            });
                        }
                        r
                    }
                }
                HostMsg::Start => {
                    let r = cx.shared.ctl.lock(|c| {
                        c.supervisor_mut()
                            .start()
                            .map_err(|_| NackReason::InvalidState)
                    });
                    if r.is_ok() {
                        defmt::info!("link: running");
                        LINK_RUNNING.store(true, Ordering::Release);
                    }
                    r
                }
                HostMsg::Abort => {
                    cx.shared.ctl.lock(|c| c.supervisor_mut().abort());
                    Ok(())
                }
            };
            let answer = match result {
                Ok(()) => DeviceMsg::Ack(req),
                Err(n) => DeviceMsg::Nack(req, n),
            };
            cx.shared.link.lock(|l| l.send(&answer));
        }
    }
}

/// The frame reader of the host's requests.
#[cfg(feature = "link")]
pub type LinkReader = rths_link::FrameReader<{ rths_link::MAX_FRAME }>;
/// Without `link`: none.
#[cfg(not(feature = "link"))]
pub type LinkReader = ();

/// `link`: the port and the telemetry stream's state.
#[cfg(feature = "link")]
pub struct LinkPort {
    uart: rths_board_qemu::LinkUart,
    /// Telemetry decimation (≥ 1).
    every: u32,
    /// Next telemetry sequence number (= records sent in this run).
    seq: u32,
    /// Frames that failed COBS, CRC or decoding.
    bad_frames: u32,
}

/// Without `link`: no port (USART1 stays off).
#[cfg(not(feature = "link"))]
pub struct LinkPort;

#[cfg(not(feature = "link"))]
impl LinkPort {
    fn new(_: stm32f4::stm32f405::USART1, _: &stm32f4::stm32f405::RCC) -> Self {
        Self
    }
}

#[cfg(feature = "link")]
impl LinkPort {
    fn new(usart: stm32f4::stm32f405::USART1, rcc: &stm32f4::stm32f405::RCC) -> Self {
        Self {
            uart: rths_board_qemu::LinkUart::new(usart, rcc),
            every: 1,
            seq: 0,
            bad_frames: 0,
        }
    }

    fn send(&mut self, msg: &rths_link::DeviceMsg) {
        let mut buf = [0u8; rths_link::MAX_FRAME + 1];
        if let Ok(n) = rths_link::encode(msg, &mut buf) {
            if let Some(frame) = buf.get(..n) {
                self.uart.write_all(frame);
            }
        }
    }
}

/// The controller's work in one tick, the measured section: DAQ read, control step, command write,
/// log record. Kept out of line so that `panic-check.sh` can walk its call graph.
#[inline(never)]
fn control_step<D, A>(
    ctl: &mut Controller,
    daq_act: &mut D,
    producer: &mut heapless::spsc::Producer<'static, Record>,
    k: u32,
    ag: f64,
    overrun: bool,
) -> (rths_core::control::TickOutput, bool)
where
    D: rths_core::hal::Daq<Error = A> + rths_core::hal::Actuator<Error = A>,
    A: rths_core::hal::Error,
{
    let sample = daq_act.read().map_err(|e| e.kind());
    let out = ctl.tick(ag, sample, overrun);
    // The supervisor's command is finite and within the stroke; a refusal would hold the last one.
    let _ = daq_act.command(out.command_mm);
    let (m, f) = match sample {
        Ok(s) => (s.disp_mm, s.force_kn),
        Err(_) => (f64::NAN, f64::NAN),
    };
    let queued = producer
        .enqueue(Record {
            tick: k,
            command_mm: out.command_mm,
            target_mm: out.target_mm,
            measured_mm: m,
            force_kn: f,
            state: out.state,
        })
        .is_ok();
    (out, queued)
}

fn reason_str(r: rths_core::supervisor::FaultReason) -> &'static str {
    use rths_core::supervisor::FaultReason as F;
    match r {
        F::MeasuredStroke => "MeasuredStroke",
        F::CommandStroke => "CommandStroke",
        F::CommandVelocity => "CommandVelocity",
        F::Force => "Force",
        F::NonFiniteCommand => "NonFiniteCommand",
        F::NonFiniteSample => "NonFiniteSample",
        F::SensorTimeout => "SensorTimeout",
        F::Overrun => "Overrun",
        F::EmergencyStop => "EmergencyStop",
        F::FollowingError => "FollowingError",
        F::ImplausibleMotion => "ImplausibleMotion",
        F::FrozenSensor => "FrozenSensor",
    }
}

/// Print the CALIB and RESULT lines; whether the run went as this build expects.
fn report(
    r: &Run,
    end: State,
    calib: &rths_board_qemu::Calibration,
    daq_errors: u32,
    held_samples: u32,
) -> bool {
    let lim = Limits::paper_actuator();
    let mut c = logger::Line::<256>::new();
    c.put(format_args!(
        "CALIB {{\"loop_instr\":{},\"systick_instr\":{},\"tim2_counts\":{},\"read_overhead_instr\":{},\"tick_hz\":{:?}}}",
        calib.loop_instructions,
        calib.measured_instructions,
        calib.timer_counts,
        calib.overhead_instructions,
        rths_board_qemu::tick_rate_hz()
    ));
    logger::host_line(&c.0);

    let completed = r.fault_tick.is_none() && r.ticks == gen::RECORD_TICKS;
    let nrmse = if completed && r.peak_ref_mm > 0.0 && r.ticks > 0 {
        Some(100.0 * libm::sqrt(r.sum_sq / r.ticks as f64) / r.peak_ref_mm)
    } else {
        None
    };
    let faults = u32::from(r.fault_tick.is_some());
    let mean = if r.instr_n > 0 {
        r.instr_sum as f64 / r.instr_n as f64
    } else {
        0.0
    };
    let mut l = logger::Line::<1024>::new();
    let mut ok = true;
    ok &= l.put(format_args!("RESULT {{\"scenario\":\"{SCENARIO_PREFIX}"));
    #[cfg(feature = "model-rnn")]
    {
        ok &= l.put(format_args!("{}", gen::RNN_HIDDEN));
    }
    ok &= l.put(format_args!("\",\"ticks\":{},\"nrmse_pct\":", r.ticks));
    ok &= match nrmse {
        Some(x) => l.put(format_args!("{x:?}")),
        None => l.put(format_args!("null")),
    };
    ok &= l.put(format_args!(
        ",\"overruns\":{},\"faults\":{},\"instr_per_tick\":{{\"min\":{},\"mean\":{:.1},\"max\":{}}}",
        r.overruns, faults, r.instr_min, mean, r.instr_max
    ));
    ok &= l.put(format_args!(
        ",\"model\":\"{}\",\"end_state\":\"{}\",\"ramp_ticks\":{},\"max_ramp_step_mm\":{:?},\"final_cmd_mm\":{:?}",
        gen::MODEL_SOURCE,
        match end {
            State::Done => "done",
            State::Fault(_) => "fault",
            _ => "other",
        },
        r.ramp_ticks,
        r.max_ramp_step_mm,
        r.last_cmd_mm
    ));
    if let (State::Fault(reason), Some(t)) = (end, r.fault_tick) {
        ok &= l.put(format_args!(
            ",\"fault_reason\":\"{}\",\"fault_tick\":{},\"cmd_before_fault_mm\":{:?},\"max_step_after_fault_mm\":{:?},\"fault_ramp_ticks\":{}",
            reason_str(reason),
            t,
            r.cmd_before_fault_mm,
            r.max_step_after_fault_mm,
            r.fault_ramp_ticks
        ));
    }
    ok &= l.put(format_args!(
        ",\"max_step_mm\":{:?},\"peak_cmd_mm\":{:?}",
        r.max_step_mm, r.peak_cmd_mm
    ));
    #[cfg(feature = "fault-inject")]
    {
        ok &= l.put(format_args!(",\"fault\":\"{}\"", gen::FAULT_SPEC));
    }
    let (stack_used, stack_size) = stack::high_water();
    ok &= l.put(format_args!(
        ",\"stack_bytes\":{stack_used},\"stack_avail_bytes\":{stack_size}"
    ));
    ok &= l.put(format_args!(
        ",\"daq_errors\":{},\"held_samples\":{},\"telemetry_dropped\":{},\"log_frames_cut\":{},\"step_limits_mm\":{{\"fault\":{:?},\"end\":{:?}}}}}",
        daq_errors,
        held_samples,
        r.telemetry_dropped,
        logger::truncated_frames(),
        lim.fault_step_mm(),
        END_RAMP_RATE_MM_S * DT_S,
    ));
    logger::host_line(&l.0);
    if !ok {
        logger::host_line("ERROR the RESULT line did not fit its buffer");
    }
    // A normal build must finish the record without a fault or an overrun. A fault-injection build
    // that trips must ramp, never jumping, to the safe position (where the test was armed: 0 mm); one
    // whose fault is tolerated must finish like a normal build (the test says which is expected).
    // Either way no command ever leaves the envelope.
    let envelope =
        r.max_step_mm <= lim.max_step_mm() * (1.0 + 1e-9) && r.peak_cmd_mm <= lim.stroke_mm();
    let expected = if cfg!(feature = "fault-inject") {
        envelope
            && match end {
                State::Fault(_) => {
                    r.max_step_after_fault_mm <= lim.fault_step_mm() * (1.0 + 1e-9)
                        && r.last_cmd_mm == 0.0
                }
                _ => completed && end == State::Done && r.last_cmd_mm == 0.0,
            }
    } else {
        completed && end == State::Done && r.overruns == 0 && r.last_cmd_mm == 0.0
    };
    ok && expected
}

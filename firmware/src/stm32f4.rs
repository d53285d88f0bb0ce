//! rths firmware for the real board (`--features board-stm32f4`): the STM32F407 wired to the
//! servo-controller through the AD7606 ADC and the AD5754R DAC (`boards/stm32f4`), driven from the
//! desktop over the command link (`rths link --port ...`). defmt logs over RTT (probe-rs).
//!
//! Tasks, highest priority first:
//! - `control` (TIM2, priority 3, 2048 Hz from boot): the E-stop input (asserted → the supervisor's
//!   `emergency_stop()`, which ramps the command to the safe position), the DAQ read, `Controller::tick`
//!   with El Centro's ü_g while a run plays, the DAC write, one telemetry record. While idle the
//!   supervisor holds the command where it is; the interlocks watch the rig whenever a test is armed.
//! - `telemetry` (priority 1): streams the records (decimated as the host asked), then `RunEnded`.
//! - `link_rx` (USART2 receive, priority 1): the host's requests (`rths_link`).
//! - `idle`: `wfi`.
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
#[path = "link.rs"]
mod link;
mod motion;

use core::sync::atomic::{AtomicBool, Ordering};

use defmt_rtt as _;
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use rths_core::metamodel::{Lr, LrParams};
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::{Limits, State};

/// The end-of-test ramp rate of `Limits::paper_actuator()`, mm/s (for `link::set_limits`).
pub const END_RAMP_RATE_MM_S: f64 = 10.0;

/// A run is under way (from the host's `Start` to its end); the record plays meanwhile.
static RUNNING: AtomicBool = AtomicBool::new(false);
/// The run ended; `telemetry` sends `RunEnded` after its last record.
static RUN_ENDED: AtomicBool = AtomicBool::new(false);

/// One telemetry record.
#[derive(Debug, Clone, Copy)]
pub struct Record {
    tick: u32,
    command_mm: f64,
    target_mm: f64,
    measured_mm: f64,
    force_kn: f64,
    state: State,
}

/// The current run, as `control` sees it.
#[derive(Debug, Clone, Copy)]
pub struct RunInfo {
    /// Ticks since `Start`.
    ticks: u32,
    /// Records the queue dropped.
    dropped: u32,
    /// Last measured displacement, mm (the arm position).
    last_disp_mm: f64,
    /// State after the last tick.
    state: State,
}

/// The link port and the stream's state.
pub struct LinkPort {
    uart: rths_board_stm32f4::LinkSerial,
    every: u32,
    seq: u32,
    bad_frames: u32,
}

impl LinkPort {
    fn send(&mut self, msg: &rths_link::DeviceMsg) {
        let mut buf = [0u8; rths_link::MAX_FRAME + 1];
        if let Ok(n) = rths_link::encode(msg, &mut buf) {
            if let Some(frame) = buf.get(..n) {
                self.uart.write_all(frame);
            }
        }
    }
}

fn controller() -> Option<Controller> {
    let proto = Prototype::paper();
    let cfg = ControlConfig::new(
        proto,
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .ok()?;
    let lr = LrParams::new(gen::LR_THETA).ok()?;
    Some(Controller::new(
        cfg,
        Analytical::Lr(Lr::new(lr)),
        Compensator::None,
    ))
}

/// Stop at boot with a message: nothing was started, the DAC (if it came up) holds 0 V.
fn halt(msg: &str) -> ! {
    defmt::error!("halted: {=str}", msg);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    // The DAC holds its last output; the servo-controller's own limits and its E-stop chain are the
    // protection from here on (notes/hardware.md).
    defmt::error!("PANIC");
    loop {
        cortex_m::asm::wfi();
    }
}

#[rtic::app(device = rths_board_stm32f4::pac, peripherals = true)]
mod app {
    use super::*;
    use heapless::spsc::{Consumer, Producer, Queue};
    use rths_board_drivers::{Calibration, CalibrationConfig};
    use rths_board_stm32f4::pac::Interrupt;
    use rths_board_stm32f4::{Board, BoardEStop, BoardRig, TickTimer};

    const QUEUE: usize = 64;

    #[shared]
    struct Shared {
        ctl: Controller,
        timer: TickTimer,
        run: RunInfo,
        link: LinkPort,
    }

    #[local]
    struct Local {
        rig: BoardRig,
        estop: BoardEStop,
        producer: Producer<'static, Record>,
        consumer: Consumer<'static, Record>,
        reader: rths_link::FrameReader<{ rths_link::MAX_FRAME }>,
        model_checksum: u32,
    }

    #[init(local = [queue: Queue<Record, QUEUE> = Queue::new()])]
    fn init(cx: init::Context) -> (Shared, Local) {
        // The lab's calibration goes here (notes/hardware.md); the default is the paper actuator's.
        let Ok(cal) = Calibration::new(CalibrationConfig::paper_actuator()) else {
            halt("calibration")
        };
        let board = match Board::init(cx.device, cal) {
            Ok(b) => b,
            Err(e) => {
                defmt::error!("board: {}", defmt::Debug2Format(&e));
                halt("board bring-up")
            }
        };
        let Some(ctl) = controller() else {
            halt("controller configuration")
        };
        let Board {
            mut timer,
            rig,
            estop,
            link,
        } = board;
        timer.start();
        defmt::info!(
            "rths stm32f4: tick {=f64} Hz ({=f64} ppm), model {=str}",
            rths_board_stm32f4::tick_rate_hz(),
            rths_board_stm32f4::tick_rate_error_ppm(),
            gen::MODEL_SOURCE
        );
        let (producer, consumer) = cx.local.queue.split();
        (
            Shared {
                ctl,
                timer,
                run: RunInfo {
                    ticks: 0,
                    dropped: 0,
                    last_disp_mm: 0.0,
                    state: State::Idle,
                },
                link: LinkPort {
                    uart: link,
                    every: 1,
                    seq: 0,
                    bad_frames: 0,
                },
            },
            Local {
                rig,
                estop,
                producer,
                consumer,
                reader: rths_link::FrameReader::new(),
                model_checksum: link::compiled_model_checksum(&gen::LR_THETA),
            },
        )
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// The controller tick, 2048 Hz. Deadline: the next TIM2 update, 488.3 µs later; an overrun is
    /// passed to the supervisor (4 in a row trip it).
    #[task(binds = TIM2, priority = 3, shared = [ctl, timer, run],
           local = [rig, estop, producer, k: u32 = 0, overrun: bool = false])]
    fn control(mut cx: control::Context) {
        cx.shared.timer.lock(|t| t.clear());
        let running = RUNNING.load(Ordering::Acquire);
        let k = if running { *cx.local.k } else { 0 };
        let ag = if running {
            motion::ground_accel_mm_s2(k)
        } else {
            0.0
        };
        let overrun = *cx.local.overrun;
        let estop = cx.local.estop;
        let rig = cx.local.rig;
        let producer = cx.local.producer;
        let (out, queued, disp, ended) = cx.shared.ctl.lock(|c| {
            rths_board_drivers::check_estop(estop, c.supervisor_mut());
            let (out, queued, disp) = control_step(c, rig, producer, k, ag, overrun, running);
            if running && k + 1 >= gen::RECORD_TICKS && out.state == State::Running {
                let _ = c.supervisor_mut().finish();
            }
            let ended = running
                && (out.state == State::Done
                    || (matches!(out.state, State::Fault(_)) && c.supervisor().at_rest()));
            (out, queued, disp, ended)
        });
        cx.shared.run.lock(|r| {
            if running {
                r.ticks = k + 1;
            }
            if !queued {
                r.dropped = r.dropped.saturating_add(1);
            }
            if disp.is_finite() {
                r.last_disp_mm = disp;
            }
            r.state = out.state;
        });
        *cx.local.k = if running { k.saturating_add(1) } else { 0 };
        if ended {
            RUNNING.store(false, Ordering::Release);
            RUN_ENDED.store(true, Ordering::Release);
        }
        rtic::pend(Interrupt::USART3);
        *cx.local.overrun = cx.shared.timer.lock(|t| t.pending());
    }

    /// Streams the records of a run (every `every`-th), then `RunEnded`.
    #[task(binds = USART3, priority = 1, shared = [link, run], local = [consumer])]
    fn telemetry(mut cx: telemetry::Context) {
        use rths_link::{DeviceMsg, Telemetry};
        let consumer = cx.local.consumer;
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
                    records_dropped: run.dropped,
                })
            });
        }
    }

    /// The host's requests, one answer each.
    #[task(binds = USART2, priority = 1, shared = [ctl, run, link], local = [reader, model_checksum])]
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
                    let run = cx.shared.run.lock(|r| *r);
                    let crc = *cx.local.model_checksum;
                    let (sent, bad) = cx.shared.link.lock(|l| (l.seq, l.bad_frames));
                    let st = cx
                        .shared
                        .ctl
                        .lock(|c| link::status(c, crc, run.ticks, sent, run.dropped, bad));
                    cx.shared.link.lock(|l| l.send(&DeviceMsg::Status(st)));
                    continue;
                }
                HostMsg::UploadLr {
                    features,
                    theta,
                    delay_steps,
                    checksum,
                } => cx
                    .shared
                    .ctl
                    .lock(|c| link::upload_lr(c, features, &theta, delay_steps, checksum))
                    .map(|crc| *cx.local.model_checksum = crc),
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
                    } else {
                        let at = cx.shared.run.lock(|r| r.last_disp_mm);
                        // After a finished run, back to idle first (refused unless at rest); then arm
                        // at the measured position so the first command does not step.
                        let r = cx.shared.ctl.lock(|c| {
                            if matches!(c.supervisor().state(), State::Done | State::Fault(_)) {
                                c.reset().map_err(|_| NackReason::Busy)?;
                            }
                            c.supervisor_mut()
                                .arm_at(at)
                                .map_err(|_| NackReason::InvalidState)
                        });
                        if r.is_ok() {
                            cx.shared.link.lock(|l| {
                                l.every = u32::from(telemetry_every);
                                l.seq = 0;
                            });
                            cx.shared.run.lock(|r| {
                                r.ticks = 0;
                                r.dropped = 0;
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
                        RUNNING.store(true, Ordering::Release);
                        defmt::info!("link: running");
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

/// The controller's work in one tick: DAQ read, control step, DAC write, and (during a run) one
/// telemetry record. Returns the tick's output, whether the record was queued, and the measured
/// displacement (NaN on a DAQ error).
#[inline(never)]
fn control_step<D, A>(
    ctl: &mut Controller,
    daq_act: &mut D,
    producer: &mut heapless::spsc::Producer<'static, Record>,
    k: u32,
    ag: f64,
    overrun: bool,
    record: bool,
) -> (rths_core::control::TickOutput, bool, f64)
where
    D: rths_core::hal::Daq<Error = A> + rths_core::hal::Actuator<Error = A>,
    A: rths_core::hal::Error,
{
    let sample = daq_act.read().map_err(|e| e.kind());
    let out = ctl.tick(ag, sample, overrun);
    // A refusal (non-finite) or a clip is reported by the DAC driver; the supervisor's command is
    // finite and within the stroke, so neither happens with a sane calibration.
    let _ = daq_act.command(out.command_mm);
    let (m, f) = match sample {
        Ok(s) => (s.disp_mm, s.force_kn),
        Err(_) => (f64::NAN, f64::NAN),
    };
    let queued = !record
        || producer
            .enqueue(Record {
                tick: k,
                command_mm: out.command_mm,
                target_mm: out.target_mm,
                measured_mm: m,
                force_kn: f,
                state: out.state,
            })
            .is_ok();
    (out, queued, m)
}

//! What a board provides to the firmware: traits shaped like embedded-hal's (no registers in the
//! API), implemented by each `boards/*` crate. The DAQ and the actuator are `rths_core::hal`'s
//! [`Daq`] and [`Actuator`].

use rths_core::hal::{Actuator, Daq};

/// The controller's tick: a periodic timer at `rths_core::params::CONTROL_RATE_HZ` whose update
/// interrupt the control task is bound to.
pub trait TickTimer {
    /// Start counting: the first tick fires one period from now.
    fn start(&mut self);
    /// Stop counting and clear a pending update.
    fn stop(&mut self);
    /// Acknowledge the update interrupt.
    fn clear(&mut self);
    /// The next update already happened (the tick in progress ran past its deadline).
    fn pending(&self) -> bool;
}

/// The command link's byte port (a UART). Infallible by design: a byte lost to an overrun or a
/// framing error makes its frame fail the CRC, which the link counts as a bad frame.
pub trait LinkPort {
    /// A received byte, if one is waiting.
    fn read_byte(&mut self) -> Option<u8>;
    /// Send `bytes` (blocking).
    fn write_all(&mut self, bytes: &[u8]);
}

/// A free-running counter of the core's work, read around the measured section.
pub trait InstrCounter {
    /// The raw counter.
    fn now(&self) -> u32;
    /// Instructions from reading `start` to reading `end` (less than one wrap apart), the counter's
    /// own overhead included.
    fn instructions(&self, start: u32, end: u32) -> u32;
}

/// The watchdog of the control task: started once the tick timer runs, fed at every tick. If the
/// control task stalls (a tick not run for the watchdog's period), it forces the safe state: a
/// reset of the MCU, whose start-up latches the actuator command at its safe position (the real
/// board's IWDG), or, on the emulated board, the end of the emulation with a `WATCHDOG` line.
pub trait Watchdog {
    /// Start it (it cannot be stopped on a real board: the tick must run from then on).
    fn start(&mut self);
    /// The control task ran a tick.
    fn feed(&mut self);
}

/// The hardware emergency-stop input.
pub trait EStop {
    /// The stop is asserted (a broken wire reads as asserted).
    fn asserted(&mut self) -> bool;
}

/// A board that never has an E-stop input (the emulated one).
#[derive(Debug, Clone, Copy, Default)]
pub struct NoEStop;

impl EStop for NoEStop {
    fn asserted(&mut self) -> bool {
        false
    }
}

/// What a board runs after each tick, outside the measured section: on the emulated board the
/// reference response (for the NRMSE) and the plant's advance; nothing on a real rig.
pub trait Harness<R> {
    /// After tick `k` (`in_record`: a row of the record) with ground acceleration `ag_mm_s2` and
    /// the controller's target `target_mm`: the row's ((target − reference)², |reference|), mm², mm,
    /// if the board has a reference.
    fn after_tick(
        &mut self,
        rig: &mut R,
        k: u32,
        in_record: bool,
        ag_mm_s2: f64,
        target_mm: f64,
    ) -> Option<(f64, f64)>;
    /// Back to rest under the ground acceleration of tick 0, mm/s² (before the first tick).
    fn reset(&mut self, ag0_mm_s2: f64);
}

/// The board's calibration of its instruction counter, measured at boot.
pub trait CounterCalibration {
    /// The calibration line (`CALIB {...}`) printed before the report; nothing if the board has none.
    fn write_line<W: core::fmt::Write>(&self, w: &mut W) -> core::fmt::Result;
    /// Instructions the counter itself takes between two readings (subtracted from each tick's).
    fn counter_overhead_instr(&self) -> u32;
}

/// No calibration.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoCounterCalibration;

impl CounterCalibration for NoCounterCalibration {
    fn write_line<W: core::fmt::Write>(&self, _: &mut W) -> core::fmt::Result {
        Ok(())
    }
    fn counter_overhead_instr(&self) -> u32 {
        0
    }
}

/// A board with nothing to do between ticks (a real rig: the world moves by itself).
#[derive(Debug, Clone, Copy, Default)]
pub struct NoHarness;

impl<R> Harness<R> for NoHarness {
    fn after_tick(&mut self, _: &mut R, _: u32, _: bool, _: f64, _: f64) -> Option<(f64, f64)> {
        None
    }
    fn reset(&mut self, _: f64) {}
}

/// One board: its parts' types and what sets it apart.
pub trait Board {
    /// The tick timer.
    type Timer: TickTimer;
    /// The link port.
    type Link: LinkPort;
    /// The rig's converters (or the emulated plant), the error type of both sides.
    type RigError: rths_core::hal::Error;
    /// The DAQ and the actuator.
    type Rig: Daq<Error = Self::RigError> + Actuator<Error = Self::RigError>;
    /// The instruction counter.
    type Counter: InstrCounter;
    /// The E-stop input.
    type EStop: EStop;
    /// What runs between ticks.
    type Harness: Harness<Self::Rig>;
    /// The instruction counter's calibration.
    type CounterCalibration: CounterCalibration + Copy;
    /// The control task's watchdog.
    type Watchdog: Watchdog;
    /// The plant runs inside the MCU (QEMU): the record plays once per power-up from rest at 0 mm,
    /// the controller ticks only during that run, the board advances the plant after each tick and
    /// the run ends with the `RESULT` report. A real rig instead ticks from boot (the interlocks
    /// watch it whenever a test is armed), arms at the measured position and can run again.
    const EMULATED_PLANT: bool;

    /// The tick's actual rate, Hz (the timer's period is rounded to whole counts).
    fn tick_rate_hz() -> f64;
    /// Print a line for the user (the emulated board's stdout; the log on a real one).
    fn host_line(line: &str);
    /// End the program: the emulated board exits with `success` as its status; a real one halts
    /// (the DAC holds its output; the servo-controller's own limits protect the rig).
    fn exit(success: bool) -> !;
    /// Log frames cut or lost so far.
    fn log_frames_cut() -> u32;
}

/// The board's parts, as the firmware takes them over at boot.
pub struct Parts<B: Board> {
    /// The tick timer (stopped).
    pub timer: B::Timer,
    /// The link port.
    pub link: B::Link,
    /// DAQ and actuator.
    pub rig: B::Rig,
    /// The instruction counter.
    pub counter: B::Counter,
    /// The E-stop input.
    pub estop: B::EStop,
    /// What runs between ticks.
    pub harness: B::Harness,
    /// The instruction counter's calibration.
    pub calibration: B::CounterCalibration,
    /// The control task's watchdog (stopped).
    pub watchdog: B::Watchdog,
}

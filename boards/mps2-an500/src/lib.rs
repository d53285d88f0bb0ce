//! The emulated Cortex-M7 board: QEMU `mps2-an500` (Arm MPS2 with the AN500 FPGA image) with the
//! virtual plant inside the MCU, the double-precision twin of the `netduinoplus2` (Cortex-M4) board.
//! What every emulated board shares (the plant, the harness, the instruction counter, the logger)
//! lives in `rths-board-emulated`; this crate adds the machine's registers.
//!
//! - The Cortex-M7 of QEMU has the FPv5-D16 FPU (double precision); the firmware is built for it with
//!   `-C target-cpu=cortex-m7` (`cargo build-m7`, firmware/.cargo/config.toml), so its `f64` is
//!   hardware `vadd.f64`/`vmul.f64`/`vdiv.f64` instead of the M4's software routines.
//! - The controller tick is CMSDK TIMER0's interrupt: a down-counter on the [`PCLK_HZ`] (25 MHz)
//!   peripheral clock, reloaded every [`TICK_PERIOD_COUNTS`] counts ([`tick_rate_hz`]).
//! - SysTick counts the core clock, [`SYSCLK_HZ`] (25 MHz in QEMU: the MPS2's FPGA clock, not a real
//!   H7's 480 MHz). Under `-icount shift=3` ([`ICOUNT_NS_PER_INSTR`] = 8 ns per instruction) one
//!   SysTick count is 5 instructions: the resolution of the per-tick counts (shift=0 would give 40).
//! - The link is CMSDK UART1, QEMU's second `-serial`, on the firmware's `USART2` vector ([`pac`]).
#![no_std]
#![deny(missing_docs)]

pub mod pac;

pub use rths_board_emulated::logger;
use rths_board_emulated::CountingTimer;
pub use rths_board_emulated::{
    calibrate, exit, BoardError, Harness, Plant, SysTickCounterCalibration,
};
use rths_hal_sim::SimError;

/// The MPS2's core and peripheral clock in QEMU (`SYSCLK_FRQ`), Hz.
pub const SYSCLK_HZ: u32 = 25_000_000;

/// The CMSDK timers' and UARTs' clock, Hz (the same 25 MHz).
pub const PCLK_HZ: u32 = SYSCLK_HZ;

/// The instruction counter: SysTick at [`SYSCLK_HZ`], [`ICOUNT_NS_PER_INSTR`] ns per instruction.
pub type Counter = rths_board_emulated::InstrCounter<SYSCLK_HZ, ICOUNT_NS_PER_INSTR>;

/// Virtual nanoseconds per instruction: the runner's `-icount shift=3`.
pub const ICOUNT_NS_PER_INSTR: u32 = 8;

/// The controller rate the tick aims at, Hz (`rths_core::params::CONTROL_RATE_HZ`).
pub const TARGET_TICK_HZ: u32 = rths_core::params::CONTROL_RATE_HZ;

/// Timer counts per tick: `round(PCLK_HZ / rate)` (12 207 at 2048 Hz; exact: 12 207.03).
pub const TICK_PERIOD_COUNTS: u32 = (PCLK_HZ + TARGET_TICK_HZ / 2) / TARGET_TICK_HZ;

/// The actual tick rate, Hz (2048.005 Hz at 2048 Hz: +2.6 ppm; the controller's Δt stays nominal).
pub fn tick_rate_hz() -> f64 {
    PCLK_HZ as f64 / TICK_PERIOD_COUNTS as f64
}

/// Calibration loop iterations: 2 instructions each, 160 µs of virtual time at 8 ns per instruction,
/// well inside one tick period (the timer must not wrap during the calibration).
const CALIBRATION_ITERATIONS: u32 = 10_000;

/// CTRL bits of the CMSDK timer.
const TIMER_ENABLE: u32 = 1 << 0;
const TIMER_IRQ_ENABLE: u32 = 1 << 3;

/// The tick timer (CMSDK TIMER0).
pub struct TickTimer {
    tim: pac::TIMER0,
}

impl TickTimer {
    /// Configure TIMER0 for [`TICK_PERIOD_COUNTS`], stopped, its interrupt flag clear.
    pub fn new(tim: pac::TIMER0) -> Self {
        tim.ctrl().write(0);
        // QEMU's CMSDK timer counts RELOAD..0 and reloads: RELOAD + 1 counts per period.
        tim.reload().write(TICK_PERIOD_COUNTS - 1);
        tim.value().write(TICK_PERIOD_COUNTS - 1);
        tim.int().write(1);
        Self { tim }
    }
}

impl rths_app::board::TickTimer for TickTimer {
    fn start(&mut self) {
        self.tim.value().write(TICK_PERIOD_COUNTS - 1);
        self.tim.ctrl().write(TIMER_ENABLE | TIMER_IRQ_ENABLE);
    }
    fn stop(&mut self) {
        self.tim.ctrl().write(0);
        self.clear();
    }
    fn clear(&mut self) {
        self.tim.int().write(1);
    }
    fn pending(&self) -> bool {
        self.tim.int().read() & 1 != 0
    }
}

impl CountingTimer for TickTimer {
    /// Counts since the last start (the counter runs down from `TICK_PERIOD_COUNTS − 1`).
    fn count(&self) -> u32 {
        (TICK_PERIOD_COUNTS - 1).wrapping_sub(self.tim.value().read())
    }
    fn tick_rate_hz() -> f64 {
        tick_rate_hz()
    }
}

/// STATE bits of the CMSDK UART.
const UART_TX_FULL: u32 = 1 << 0;
const UART_RX_FULL: u32 = 1 << 1;
/// CTRL bits: transmitter, receiver, receive interrupt.
const UART_TX_ENABLE: u32 = 1 << 0;
const UART_RX_ENABLE: u32 = 1 << 1;
const UART_RX_IRQ_ENABLE: u32 = 1 << 3;
/// INTSTATUS / INTCLEAR: a byte was received.
const UART_RX_IRQ: u32 = 1 << 1;

/// CMSDK UART1, the link port: QEMU maps the machine's second `-serial` to it (`-serial null -serial
/// tcp:...` for the host's `rths link`).
pub struct LinkUart {
    uart: pac::UART1,
}

impl LinkUart {
    /// Enable UART1: transmitter and receiver on, the receive interrupt on, 115 200 Bd.
    pub fn new(uart: pac::UART1) -> Self {
        uart.bauddiv().write(PCLK_HZ / 115_200);
        uart.int().write(UART_RX_IRQ);
        uart.ctrl()
            .write(UART_TX_ENABLE | UART_RX_ENABLE | UART_RX_IRQ_ENABLE);
        Self { uart }
    }
}

impl rths_app::board::LinkPort for LinkUart {
    fn read_byte(&mut self) -> Option<u8> {
        if self.uart.state().read() & UART_RX_FULL == 0 {
            return None;
        }
        let b = self.uart.data().read() as u8;
        // The receive interrupt is a level until cleared.
        self.uart.int().write(UART_RX_IRQ);
        Some(b)
    }
    /// Polls TX-full.
    fn write_all(&mut self, bytes: &[u8]) {
        for &b in bytes {
            while self.uart.state().read() & UART_TX_FULL != 0 {}
            self.uart.data().write(u32::from(b));
        }
    }
}

/// The emulated Cortex-M7 board.
#[derive(Debug, Clone, Copy)]
pub struct Mps2An500;

/// The board this crate is (the firmware's `board::ThisBoard`).
pub type ThisBoard = Mps2An500;

impl rths_app::board::Board for Mps2An500 {
    type Timer = TickTimer;
    type Link = LinkUart;
    type RigError = SimError;
    type Rig = Plant;
    type Counter = Counter;
    type EStop = rths_app::board::NoEStop;
    type Harness = Harness;
    type CounterCalibration = SysTickCounterCalibration;
    type Watchdog = TimerWatchdog;
    const EMULATED_PLANT: bool = true;

    fn tick_rate_hz() -> f64 {
        tick_rate_hz()
    }

    fn host_line(line: &str) {
        logger::host_line(line);
    }

    fn exit(success: bool) -> ! {
        exit(success)
    }

    fn log_frames_cut() -> u32 {
        logger::truncated_frames()
    }
}

/// Bring the board up: SysTick as the instruction counter (calibrated against TIMER0), TIMER0
/// stopped, the plant at rest with no faults, UART1, and the harness (reset it before the first
/// tick).
pub fn init(
    dp: pac::Peripherals,
    core: cortex_m::Peripherals,
) -> Result<rths_app::board::Parts<Mps2An500>, BoardError> {
    // Before SysTick starts: see `calibrate`.
    let fpu_mvfr0 = core.FPU.mvfr[0].read();
    let counter = Counter::new(core.SYST);
    let mut timer = TickTimer::new(dp.TIMER0);
    let calib = calibrate(&counter, &mut timer, CALIBRATION_ITERATIONS, fpu_mvfr0);
    let (rig, harness) = rths_board_emulated::plant_and_harness()?;
    Ok(rths_app::board::Parts {
        timer,
        link: LinkUart::new(dp.UART1),
        rig,
        counter,
        estop: rths_app::board::NoEStop,
        harness,
        calibration: calib,
        watchdog: TimerWatchdog::new(dp.TIMER1),
    })
}

/// The ground-motion record buffer (address, bytes) for uploads over the link: the 64 KiB after the
/// 128 KiB the linker uses in the 4 MiB of SSRAM2/3 (`memory.x`), the size of the STM32 boards'.
pub const RECORD_BUFFER: (usize, usize) = (0x2002_0000, 64 * 1024);

/// The watchdog period, PCLK counts: 4 tick periods (1.95 ms; the real boards' IWDG: 2 ms or more).
pub const WATCHDOG_PERIOD_COUNTS: u32 = 4 * TICK_PERIOD_COUNTS;

/// How long before a tick the watchdog's check fires, PCLK counts (1 µs): it runs (above the control
/// task) before the tick rather than inside its measured section, whose count it would inflate.
pub const WATCHDOG_LEAD_COUNTS: u32 = 25;

/// The emulated watchdog: CMSDK TIMER1 on its own interrupt (the firmware's `TIM5` task, above the
/// control task) asks [`watchdog_expired`] every [`WATCHDOG_PERIOD_COUNTS`]; the counting is
/// `rths_board_emulated::watchdog`'s, shared with the Cortex-M4 twin.
pub struct TimerWatchdog {
    tim: pac::TIMER1,
}

impl TimerWatchdog {
    fn new(tim: pac::TIMER1) -> Self {
        tim.ctrl().write(0);
        tim.reload().write(WATCHDOG_PERIOD_COUNTS - 1);
        tim.value().write(WATCHDOG_PERIOD_COUNTS - 1);
        tim.int().write(1);
        Self { tim }
    }
}

impl rths_app::board::Watchdog for TimerWatchdog {
    fn start(&mut self) {
        rths_board_emulated::watchdog::arm();
        // Both timers count down on PCLK; TIMER0 reaches 0 at a tick. Phase TIMER1 to reach 0
        // WATCHDOG_LEAD_COUNTS before one.
        // SAFETY: a read of TIMER0's VALUE, which nothing writes while it runs.
        let to_tick = unsafe { pac::Peripherals::steal() }.TIMER0.value().read();
        let v = (to_tick + WATCHDOG_PERIOD_COUNTS - WATCHDOG_LEAD_COUNTS) % WATCHDOG_PERIOD_COUNTS;
        self.tim.value().write(v);
        self.tim.ctrl().write(TIMER_ENABLE | TIMER_IRQ_ENABLE);
    }
    fn feed(&mut self) {
        rths_board_emulated::watchdog::feed();
    }
}

/// The watchdog's check (its `TIM5` task): acknowledge the interrupt; `true` if no tick fed it since
/// the last check.
pub fn watchdog_expired() -> bool {
    // SAFETY: only this task touches TIMER1's INTCLEAR once the watchdog runs.
    unsafe { pac::Peripherals::steal() }.TIMER1.int().write(1);
    rths_board_emulated::watchdog::starved()
}

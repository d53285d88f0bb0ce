//! The emulated board: QEMU `netduinoplus2` (STM32F405, Cortex-M4) with the virtual plant inside the
//! MCU. What every emulated board shares (the plant, the harness, the instruction counter, the
//! logger) lives in `rths-board-emulated`; this crate adds the machine's registers.
//!
//! - The controller tick is TIM2's update interrupt. QEMU's `stm32f2xx_timer` counts at
//!   [`TIM_CLOCK_HZ`] of virtual time (it ignores the RCC prescalers); 2048 Hz does not divide it, so
//!   the tick period is rounded to [`TICK_PERIOD_COUNTS`] counts ([`tick_rate_hz`] gives the rate).
//! - QEMU does not emulate the RCC clock-ready flags: nothing here polls them. The RCC enable bit of
//!   TIM2 is set (harmless in QEMU, needed on silicon) and the core is assumed to run at
//!   [`SYSCLK_HZ`]; SysTick counts instructions on it under `-icount shift=0`
//!   ([`ICOUNT_NS_PER_INSTR`]).
//! - The link is USART2, QEMU's second `-serial` (the real board's link UART too, so that the
//!   firmware binds the same interrupt on both).
#![no_std]
#![deny(missing_docs)]

pub use rths_board_emulated::logger;

use rths_board_emulated::CountingTimer;
pub use rths_board_emulated::{
    calibrate, exit, BoardError, Harness, Plant, SysTickCounterCalibration,
};
use rths_hal_sim::SimError;
/// The device crate (STM32F405) the firmware's RTIC app is built on.
pub use stm32f4::stm32f405 as pac;

/// Core clock QEMU's netduinoplus2 machine gives the Cortex-M4 (and SysTick with CLKSOURCE = core), Hz.
pub const SYSCLK_HZ: u32 = 168_000_000;

/// The instruction counter: SysTick at [`SYSCLK_HZ`], [`ICOUNT_NS_PER_INSTR`] ns per instruction.
pub type Counter = rths_board_emulated::InstrCounter<SYSCLK_HZ, ICOUNT_NS_PER_INSTR>;

/// Virtual nanoseconds per instruction: the runner's `-icount shift=0`.
pub const ICOUNT_NS_PER_INSTR: u32 = 1;

/// The ground-motion record buffer (address, bytes) for uploads over the link: QEMU maps 192 KiB of
/// SRAM at 0x2000_0000 where the STM32F405 has 128 KiB plus a 64 KiB CCM that QEMU does not model;
/// `memory.x` gives the linker the first 128 KiB, and the last 64 KiB stand for the real board's
/// CCM (the STM32F407 board crate's `RECORD_BUFFER`): the same size on both boards.
pub const RECORD_BUFFER: (usize, usize) = (0x2002_0000, 64 * 1024);

/// Counting clock of QEMU's STM32F2xx/F4xx timer model, Hz (its `clock-frequency` default: 1 GHz of
/// virtual time, whatever the RCC says).
pub const TIM_CLOCK_HZ: u32 = 1_000_000_000;

/// The controller rate the tick aims at, Hz (`rths_core::params::CONTROL_RATE_HZ`).
pub const TARGET_TICK_HZ: u32 = rths_core::params::CONTROL_RATE_HZ;

/// Timer counts per tick: `round(TIM_CLOCK_HZ / 2048)` = 488 281 (the exact value is 488 281.25).
pub const TICK_PERIOD_COUNTS: u32 = (TIM_CLOCK_HZ + TARGET_TICK_HZ / 2) / TARGET_TICK_HZ;

/// The actual tick rate, Hz: 2048.001 Hz, a rate error of +0.5 ppm (the test's clock runs 20 µs fast
/// over 40 s; the controller's Δt stays the nominal 1/2048 s).
pub fn tick_rate_hz() -> f64 {
    TIM_CLOCK_HZ as f64 / TICK_PERIOD_COUNTS as f64
}

/// The tick timer (TIM2).
pub struct TickTimer {
    tim: pac::TIM2,
}

impl TickTimer {
    /// Configure TIM2 for [`TICK_PERIOD_COUNTS`] with its update interrupt enabled, counter stopped.
    pub fn new(tim: pac::TIM2, rcc: &pac::RCC) -> Self {
        rcc.apb1enr.modify(|_, w| w.tim2en().set_bit());
        tim.cr1.write(|w| w.cen().clear_bit());
        tim.psc.write(|w| w.psc().bits(0));
        tim.arr.write(|w| w.bits(TICK_PERIOD_COUNTS - 1));
        tim.cnt.reset();
        tim.sr.write(|w| w.uif().clear_bit());
        tim.dier.write(|w| w.uie().set_bit());
        Self { tim }
    }

    /// The counter, timer counts since the last update.
    pub fn count(&self) -> u32 {
        self.tim.cnt.read().bits()
    }
}

/// USART2, the link port: QEMU maps the machine's second `-serial` to it (`-serial null -serial
/// tcp:...` for the host's `rths link`). QEMU's USART model ignores the baud rate, sends a written
/// byte at once (TXE stays set) and holds one received byte in DR (RXNE) until it is read.
pub struct LinkUart {
    usart: pac::USART2,
}

impl LinkUart {
    /// Enable USART2: 8N1, transmitter and receiver on, the RXNE interrupt on. BRR is set for
    /// 115 200 Bd at a 42 MHz APB1 (what the silicon would need; QEMU ignores it).
    pub fn new(usart: pac::USART2, rcc: &pac::RCC) -> Self {
        rcc.apb1enr.modify(|_, w| w.usart2en().set_bit());
        usart.brr.write(|w| brr_div(w, 42_000_000 / 115_200));
        usart.cr1.write(|w| {
            w.ue()
                .set_bit()
                .te()
                .set_bit()
                .re()
                .set_bit()
                .rxneie()
                .set_bit()
        });
        Self { usart }
    }
}

fn brr_div(w: &mut pac::usart1::brr::W, div: u32) -> &mut pac::usart1::brr::W {
    w.div_mantissa()
        .bits((div >> 4) as u16)
        .div_fraction()
        .bits((div & 0xF) as u8)
}

impl CountingTimer for TickTimer {
    fn count(&self) -> u32 {
        TickTimer::count(self)
    }
    fn tick_rate_hz() -> f64 {
        tick_rate_hz()
    }
}

impl rths_app::board::TickTimer for TickTimer {
    fn start(&mut self) {
        self.tim.cnt.reset();
        self.tim.cr1.modify(|_, w| w.cen().set_bit());
    }
    fn stop(&mut self) {
        self.tim.cr1.modify(|_, w| w.cen().clear_bit());
        self.clear();
    }
    fn clear(&mut self) {
        self.tim.sr.write(|w| w.uif().clear_bit());
    }
    fn pending(&self) -> bool {
        self.tim.sr.read().uif().bit_is_set()
    }
}

impl rths_app::board::LinkPort for LinkUart {
    fn read_byte(&mut self) -> Option<u8> {
        let sr = self.usart.sr.read();
        if sr.rxne().bit_is_set() {
            Some(self.usart.dr.read().dr().bits() as u8)
        } else {
            None
        }
    }
    /// Polls TXE.
    fn write_all(&mut self, bytes: &[u8]) {
        for &b in bytes {
            while self.usart.sr.read().txe().bit_is_clear() {}
            self.usart.dr.write(|w| w.dr().bits(u16::from(b)));
        }
    }
}

/// The emulated board.
#[derive(Debug, Clone, Copy)]
pub struct Qemu;

/// The board this crate is (the firmware's `board::ThisBoard`).
pub type ThisBoard = Qemu;

impl rths_app::board::Board for Qemu {
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

/// Bring the board up: SysTick as the instruction counter (calibrated against TIM2), TIM2 stopped,
/// the plant at rest with no faults, USART2, and the harness (reset it before the first tick).
pub fn init(
    dp: pac::Peripherals,
    core: cortex_m::Peripherals,
) -> Result<rths_app::board::Parts<Qemu>, BoardError> {
    // Before SysTick starts: see `calibrate`.
    let fpu_mvfr0 = core.FPU.mvfr[0].read();
    let counter = Counter::new(core.SYST);
    let mut timer = TickTimer::new(dp.TIM2, &dp.RCC);
    let calib = calibrate(&counter, &mut timer, 100_000, fpu_mvfr0);
    let (rig, harness) = rths_board_emulated::plant_and_harness()?;
    let watchdog = TimerWatchdog::new(dp.TIM5, &dp.RCC);
    Ok(rths_app::board::Parts {
        timer,
        link: LinkUart::new(dp.USART2, &dp.RCC),
        rig,
        counter,
        estop: rths_app::board::NoEStop,
        harness,
        calibration: calib,
        watchdog,
    })
}

/// The watchdog period, virtual ns: 4 tick periods (1.95 ms; the real board's IWDG: 2 ms).
pub const WATCHDOG_PERIOD_COUNTS: u32 = 4 * TICK_PERIOD_COUNTS;

/// How long before a tick the watchdog's check fires, virtual ns: it runs (above the control task)
/// before the tick rather than in the middle of its measured section, whose instruction count it
/// would otherwise inflate.
pub const WATCHDOG_LEAD_COUNTS: u32 = 1000;

/// The emulated board's watchdog (QEMU models no IWDG): TIM5, a 32-bit timer on its own interrupt,
/// at a priority above the control task's; every [`WATCHDOG_PERIOD_COUNTS`] its task asks
/// [`watchdog_expired`], which is true when no tick fed it in the period. The firmware's bite ends
/// the emulation (what the real board's reset is to its run).
pub struct TimerWatchdog {
    tim: pac::TIM5,
}

impl TimerWatchdog {
    fn new(tim: pac::TIM5, rcc: &pac::RCC) -> Self {
        rcc.apb1enr.modify(|_, w| w.tim5en().set_bit());
        tim.cr1.write(|w| w.cen().clear_bit());
        tim.psc.write(|w| w.psc().bits(0));
        tim.arr.write(|w| w.bits(WATCHDOG_PERIOD_COUNTS - 1));
        tim.cnt.reset();
        tim.sr.write(|w| w.uif().clear_bit());
        tim.dier.write(|w| w.uie().set_bit());
        Self { tim }
    }
}

impl rths_app::board::Watchdog for TimerWatchdog {
    fn start(&mut self) {
        rths_board_emulated::watchdog::arm();
        // In phase with the tick timer (same clock), WATCHDOG_LEAD_COUNTS ahead of its update.
        // SAFETY: a read of TIM2's counter, which nothing else writes while it runs.
        #[allow(unsafe_code)]
        let phase = unsafe { &*pac::TIM2::ptr() }.cnt.read().bits();
        self.tim
            .cnt
            .write(|w| w.bits((phase + WATCHDOG_LEAD_COUNTS) % WATCHDOG_PERIOD_COUNTS));
        self.tim.cr1.modify(|_, w| w.cen().set_bit());
    }
    fn feed(&mut self) {
        rths_board_emulated::watchdog::feed();
    }
}

/// The watchdog's check (its TIM5 task): acknowledge the interrupt; `true` if no tick fed it since
/// the last check.
pub fn watchdog_expired() -> bool {
    // SAFETY: TIM5's register block is always mapped; this task is the only one that touches its
    // status register (the `TimerWatchdog` only starts the counter, before this task can run).
    #[allow(unsafe_code)]
    let tim = unsafe { &*pac::TIM5::ptr() };
    tim.sr.write(|w| w.uif().clear_bit());
    rths_board_emulated::watchdog::starved()
}

//! The emulated board: QEMU `netduinoplus2` (STM32F405) with the virtual plant inside the MCU.
//!
//! - The controller tick is TIM2's update interrupt. QEMU's `stm32f2xx_timer` counts at
//!   [`TIM_CLOCK_HZ`] of virtual time (it ignores the RCC prescalers); 2048 Hz does not divide it, so
//!   the tick period is rounded to [`TICK_PERIOD_COUNTS`] counts ([`tick_rate_hz`] gives the rate).
//! - QEMU does not emulate the RCC clock-ready flags: nothing here polls them. The RCC enable bit of
//!   TIM2 is set (harmless in QEMU, needed on silicon) and the core is assumed to run at
//!   [`SYSCLK_HZ`].
//! - Instructions are counted with SysTick on the core clock: under `-icount shift=0` one instruction
//!   takes 1 ns of virtual time, so `instructions = ticks / (f_systick · 1 ns)` (docs/design.md §8). DWT's cycle
//!   counter reads 0 in QEMU. [`calibrate`] checks the conversion against a loop of known length.
//! - The plant is `rths-hal-sim`'s [`VirtualRig`], advanced by the firmware once per tick outside the
//!   measured section.
//! - The run ends with a semihosting exit carrying the status code; text lines (`RESULT`) go to the
//!   host's stdout and defmt frames to the host file `defmt.bin` ([`logger`]), both by semihosting.
//! - The link is USART2, QEMU's second `-serial` (the real board's link UART too, so that the
//!   firmware binds the same interrupt on both).
#![no_std]
#![deny(missing_docs)]

pub mod logger;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use rths_app::board::TickTimer as _;
use rths_core::hal::{Actuator, Daq, Sample};
use rths_core::params::{Prototype, DT_S};
use rths_core::reference::Reference;
use rths_hal_sim::{FaultPlan, Preset, RigConfig, SimError, Specimen, VirtualRig};
/// The device crate (STM32F405) the firmware's RTIC app is built on.
pub use stm32f4::stm32f405 as pac;

/// Core clock QEMU's netduinoplus2 machine gives the Cortex-M4 (and SysTick with CLKSOURCE = core), Hz.
pub const SYSCLK_HZ: u32 = 168_000_000;

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

/// SysTick reload: the whole 24-bit range (100 ms at 168 MHz, far longer than a tick).
const SYST_RELOAD: u32 = 0x00FF_FFFF;

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

/// SysTick as a free-running down-counter on the core clock: the instruction counter.
pub struct InstrCounter {
    syst: SYST,
}

impl InstrCounter {
    /// Start SysTick on the core clock over its full 24-bit range, no interrupt.
    pub fn new(mut syst: SYST) -> Self {
        syst.disable_interrupt();
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(SYST_RELOAD);
        syst.clear_current();
        syst.enable_counter();
        Self { syst }
    }

    /// The raw counter (counts down).
    #[inline(always)]
    pub fn now(&self) -> u32 {
        SYST::get_current()
    }

    /// SysTick ticks elapsed from `start` to `end` (two [`Self::now`] readings less than one wrap
    /// apart).
    #[inline(always)]
    pub fn elapsed_ticks(start: u32, end: u32) -> u32 {
        start.wrapping_sub(end) & SYST_RELOAD
    }

    /// Instructions for `ticks` SysTick ticks under `-icount shift=0` (1 ns per instruction):
    /// `ticks / (f_systick · 1 ns)`, rounded.
    pub fn ticks_to_instructions(ticks: u32) -> u32 {
        ((ticks as u64 * 1_000_000_000 + SYSCLK_HZ as u64 / 2) / SYSCLK_HZ as u64) as u32
    }

    /// Release SysTick.
    pub fn free(self) -> SYST {
        self.syst
    }
}

/// A calibration of the instruction counter against a loop of known length.
#[derive(Debug, Clone, Copy)]
pub struct Calibration {
    /// Instructions the loop executes (2 per iteration: `subs`, `bne`).
    pub loop_instructions: u32,
    /// Instructions measured by SysTick.
    pub measured_instructions: u32,
    /// TIM2 counts over the same loop (1 per ns at 1 GHz).
    pub timer_counts: u32,
    /// Instructions measured around an empty section (the counter's own overhead).
    pub overhead_instructions: u32,
}

/// Run a `subs`/`bne` loop of `iterations` (2 instructions each) and measure it with SysTick and TIM2;
/// also measure the overhead of two back-to-back SysTick reads. TIM2 must be stopped (it is started
/// and stopped here, interrupt masked by the caller's priority or not yet enabled).
pub fn calibrate(counter: &InstrCounter, timer: &mut TickTimer, iterations: u32) -> Calibration {
    let a = counter.now();
    let b = counter.now();
    let overhead = InstrCounter::ticks_to_instructions(InstrCounter::elapsed_ticks(a, b));
    timer.tim.cnt.reset();
    timer.tim.cr1.modify(|_, w| w.cen().set_bit());
    let c0 = timer.count();
    let s0 = counter.now();
    spin(iterations);
    let s1 = counter.now();
    let c1 = timer.count();
    timer.stop();
    timer.tim.cnt.reset();
    Calibration {
        loop_instructions: iterations.saturating_mul(2),
        measured_instructions: InstrCounter::ticks_to_instructions(InstrCounter::elapsed_ticks(
            s0, s1,
        )),
        timer_counts: c1.wrapping_sub(c0),
        overhead_instructions: overhead,
    }
}

/// Exactly `2·n` instructions (plus a couple of setup ones): `subs`, `bne` per iteration.
#[inline(never)]
fn spin(n: u32) {
    if n == 0 {
        return;
    }
    // SAFETY: a register-only countdown loop; touches no memory.
    #[allow(unsafe_code)]
    unsafe {
        core::arch::asm!(
            "2:",
            "subs {0}, {0}, #1",
            "bne 2b",
            inout(reg) n => _,
            options(nomem, nostack)
        );
    }
}

/// The virtual rig as the MCU sees it: the DAQ is the rig's sensors; the actuator is a DAC register.
///
/// Writing a command latches it, as writing a DAC's data register does; the conversion (clip to the
/// stroke, 16-bit quantization) is the DAC's physics and is simulated with the plant in
/// [`Plant::advance`], outside the controller's measured section. The sequence seen by the plant is
/// exactly the host loop's: `read`, `command(u)`, `advance_tick`.
pub struct Plant {
    rig: VirtualRig,
    dac_mm: f64,
}

impl Plant {
    /// The plant of the study's default runs (`rths reproduce`): the `unr-compact` preset, a linear
    /// specimen at the paper's stiffness, `seed`, with `faults`. `None` if the configuration is
    /// invalid.
    pub fn new(seed: u64, faults: FaultPlan) -> Option<Self> {
        let mut c = RigConfig::new(Preset::UnrCompact);
        c.specimen = Specimen::Linear;
        c.seed = seed;
        c.build().ok().map(|p| Self {
            rig: VirtualRig::with_faults(p, faults),
            dac_mm: 0.0,
        })
    }

    /// Convert the latched command and move the plant one tick (the physical world between ticks).
    /// The error reports a clip or a refused command (the rig then holds the previous one).
    pub fn advance(&mut self) -> Result<(), SimError> {
        let r = self.rig.command(self.dac_mm);
        self.rig.advance_tick();
        r
    }

    /// The simulated rig.
    pub fn rig(&self) -> &VirtualRig {
        &self.rig
    }
}

impl Daq for Plant {
    type Error = SimError;
    fn read(&mut self) -> Result<Sample, SimError> {
        self.rig.read()
    }
}

impl Actuator for Plant {
    type Error = SimError;
    /// Latch the command in the DAC register.
    fn command(&mut self, disp_mm: f64) -> Result<(), SimError> {
        self.dac_mm = disp_mm;
        Ok(())
    }
}

/// End the QEMU run with `success` as the exit status (0 or 1).
pub fn exit(success: bool) -> ! {
    use cortex_m_semihosting::debug;
    debug::exit(if success {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::wfi();
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

impl rths_app::board::InstrCounter for InstrCounter {
    #[inline(always)]
    fn now(&self) -> u32 {
        InstrCounter::now(self)
    }
    #[inline(always)]
    fn instructions(&self, start: u32, end: u32) -> u32 {
        InstrCounter::ticks_to_instructions(InstrCounter::elapsed_ticks(start, end))
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

impl Plant {
    /// Replace the fault plan (at boot, before the first tick: the plant starts over at rest).
    pub fn inject(&mut self, faults: FaultPlan) {
        self.rig = VirtualRig::with_faults(*self.rig.params(), faults);
    }
}

/// The test harness half of the board: the reference response of the same structure (pure FE,
/// `rths_core::reference::Reference`, the one the host analysis uses), computed along the run, then the
/// plant's advance.
pub struct Harness {
    reference: Reference,
    /// target(k) as the host's history row k holds it (produced at tick k−1).
    target_row_mm: f64,
}

impl rths_app::board::Harness<Plant> for Harness {
    fn after_tick(
        &mut self,
        rig: &mut Plant,
        k: u32,
        in_record: bool,
        ag_mm_s2: f64,
        target_mm: f64,
    ) -> Option<(f64, f64)> {
        // The host history's row k: the reference and the target produced at tick k−1.
        let mut row = None;
        if in_record {
            let reference_mm = if k == 0 {
                self.reference.brace_disp_mm()
            } else {
                self.reference.advance(ag_mm_s2)
            };
            let e = self.target_row_mm - reference_mm;
            row = Some((e * e, libm::fabs(reference_mm)));
        }
        if target_mm.is_finite() {
            self.target_row_mm = target_mm;
        }
        // The plant converts the command and moves to the next tick (on a real rig: the DAC and the
        // physical world). A clip cannot happen: the supervisor keeps the command within the stroke.
        let _ = rig.advance();
        row
    }

    fn reset(&mut self, ag0_mm_s2: f64) {
        self.reference.reset(ag0_mm_s2);
        self.target_row_mm = 0.0;
    }
}

impl rths_app::board::Calibration for Calibration {
    fn write_line<W: core::fmt::Write>(&self, w: &mut W) -> core::fmt::Result {
        w.write_fmt(format_args!(
            "CALIB {{\"loop_instr\":{},\"systick_instr\":{},\"tim2_counts\":{},\"read_overhead_instr\":{},\"tick_hz\":{:?}}}",
            self.loop_instructions,
            self.measured_instructions,
            self.timer_counts,
            self.overhead_instructions,
            tick_rate_hz()
        ))
    }

    fn counter_overhead_instr(&self) -> u32 {
        self.overhead_instructions
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
    type Counter = InstrCounter;
    type EStop = rths_app::board::NoEStop;
    type Harness = Harness;
    type Calibration = Calibration;
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

/// What can fail while bringing the board up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoardError {
    /// The plant's configuration.
    Plant,
    /// The reference structure.
    Reference,
}

/// Bring the board up: SysTick as the instruction counter (calibrated against TIM2), TIM2 stopped,
/// the plant at rest with no faults, USART2, and the harness (reset it before the first tick).
pub fn init(
    dp: pac::Peripherals,
    core: cortex_m::Peripherals,
) -> Result<rths_app::board::Parts<Qemu>, BoardError> {
    let counter = InstrCounter::new(core.SYST);
    let mut timer = TickTimer::new(dp.TIM2, &dp.RCC);
    let calib = calibrate(&counter, &mut timer, 100_000);
    let watchdog = TimerWatchdog::new(dp.TIM5, &dp.RCC);
    let rig = Plant::new(1, FaultPlan::none()).ok_or(BoardError::Plant)?;
    // Reset with the record's first ü_g before the first tick (`Harness::reset`).
    let reference =
        Reference::new(&Prototype::paper(), DT_S, 0.0).map_err(|_| BoardError::Reference)?;
    Ok(rths_app::board::Parts {
        timer,
        link: LinkUart::new(dp.USART2, &dp.RCC),
        rig,
        counter,
        estop: rths_app::board::NoEStop,
        harness: Harness {
            reference,
            target_row_mm: 0.0,
        },
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

/// Control ticks since the watchdog last looked (fed by the control task).
static FEEDS: core::sync::atomic::AtomicU32 = core::sync::atomic::AtomicU32::new(0);

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
        FEEDS.store(1, core::sync::atomic::Ordering::Release);
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
        FEEDS.fetch_add(1, core::sync::atomic::Ordering::AcqRel);
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
    FEEDS.swap(0, core::sync::atomic::Ordering::AcqRel) == 0
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    logger::host_line("PANIC");
    exit(false)
}

//! The emulated board: QEMU `netduinoplus2` (STM32F405) with the virtual plant inside the MCU.
//!
//! - The controller tick is TIM2's update interrupt. QEMU's `stm32f2xx_timer` counts at
//!   [`TIM_CLOCK_HZ`] of virtual time (it ignores the RCC prescalers); 2048 Hz does not divide it, so
//!   the tick period is rounded to [`TICK_PERIOD_COUNTS`] counts ([`tick_rate_hz`] gives the rate).
//! - QEMU does not emulate the RCC clock-ready flags: nothing here polls them. The RCC enable bit of
//!   TIM2 is set (harmless in QEMU, needed on silicon) and the core is assumed to run at
//!   [`SYSCLK_HZ`].
//! - Instructions are counted with SysTick on the core clock: under `-icount shift=0` one instruction
//!   takes 1 ns of virtual time, so `instructions = ticks / (f_systick · 1 ns)` (DESIGN §8). DWT's cycle
//!   counter reads 0 in QEMU. [`calibrate`] checks the conversion against a loop of known length.
//! - The plant is `rths-hal-sim`'s [`VirtualRig`], advanced by the firmware once per tick outside the
//!   measured section.
//! - The run ends with a semihosting exit carrying the status code.
#![no_std]
#![deny(missing_docs)]

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use rths_core::hal::{Actuator, Daq, Sample};
use rths_hal_sim::{FaultPlan, Preset, RigConfig, SimError, Specimen, VirtualRig};
use stm32f4::stm32f405 as pac;

/// Core clock QEMU's netduinoplus2 machine gives the Cortex-M4 (and SysTick with CLKSOURCE = core), Hz.
pub const SYSCLK_HZ: u32 = 168_000_000;

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

    /// Start counting: the first tick fires one period from now.
    pub fn start(&mut self) {
        self.tim.cnt.reset();
        self.tim.cr1.modify(|_, w| w.cen().set_bit());
    }

    /// Stop counting and clear a pending update.
    pub fn stop(&mut self) {
        self.tim.cr1.modify(|_, w| w.cen().clear_bit());
        self.clear();
    }

    /// Acknowledge the update interrupt.
    pub fn clear(&mut self) {
        self.tim.sr.write(|w| w.uif().clear_bit());
    }

    /// The next update already happened (the tick in progress ran past its deadline).
    pub fn pending(&self) -> bool {
        self.tim.sr.read().uif().bit_is_set()
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

/// USART1, the link port: QEMU maps the machine's first `-serial` to it (`-serial tcp:...` for the
/// host's `rths link`). QEMU's USART model ignores the baud rate, sends a written byte at once (TXE
/// stays set) and holds one received byte in DR (RXNE) until it is read.
pub struct LinkUart {
    usart: pac::USART1,
}

impl LinkUart {
    /// Enable USART1: 8N1, transmitter and receiver on, the RXNE interrupt on. BRR is set for
    /// 115 200 Bd at an 84 MHz APB2 (what the silicon would need; QEMU ignores it).
    pub fn new(usart: pac::USART1, rcc: &pac::RCC) -> Self {
        rcc.apb2enr.modify(|_, w| w.usart1en().set_bit());
        usart.brr.write(|w| brr_div(w, 84_000_000 / 115_200));
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

    /// A received byte, if one is waiting.
    pub fn read_byte(&mut self) -> Option<u8> {
        let sr = self.usart.sr.read();
        if sr.rxne().bit_is_set() {
            Some(self.usart.dr.read().dr().bits() as u8)
        } else {
            None
        }
    }

    /// Send `bytes`, polling TXE.
    pub fn write_all(&mut self, bytes: &[u8]) {
        for &b in bytes {
            while self.usart.sr.read().txe().bit_is_clear() {}
            self.usart.dr.write(|w| w.dr().bits(u16::from(b)));
        }
    }
}

fn brr_div(w: &mut pac::usart1::brr::W, div: u32) -> &mut pac::usart1::brr::W {
    w.div_mantissa()
        .bits((div >> 4) as u16)
        .div_fraction()
        .bits((div & 0xF) as u8)
}

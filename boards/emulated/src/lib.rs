//! What every emulated board shares (QEMU `netduinoplus2`, Cortex-M4, and `mps2-an500`, Cortex-M7):
//! the virtual plant inside the MCU, the test harness, the instruction counter and its calibration,
//! the semihosting logger, exit and panic handler. The board crates add only their machine's
//! registers (tick timer, link UART, device crate).
//!
//! - Instructions are counted with SysTick on the core clock: under `-icount shift=S` one instruction
//!   takes 2^S ns of virtual time, so `instructions = ticks / (f_systick · 2^S ns)`
//!   (docs/design.md §8). DWT's cycle counter reads 0 in QEMU. [`calibrate`] checks the conversion
//!   against a loop of known length.
//! - The plant is `rths-hal-sim`'s [`VirtualRig`], advanced by the firmware once per tick outside the
//!   measured section.
//! - The run ends with a semihosting exit carrying the status code; text lines (`RESULT`) go to the
//!   host's stdout and defmt frames to the host file `defmt.bin` ([`logger`]), both by semihosting.
#![no_std]
#![deny(missing_docs)]

pub mod logger;
pub mod watchdog;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use rths_app::board::TickTimer;
use rths_core::hal::{Actuator, Daq, Sample};
use rths_core::params::{Prototype, DT_S};
use rths_core::reference::Reference;
use rths_hal_sim::{FaultPlan, Preset, RigConfig, SimError, Specimen, VirtualRig};

/// SysTick reload: the whole 24-bit range (far longer than a tick on every emulated board).
const SYST_RELOAD: u32 = 0x00FF_FFFF;

/// SysTick as a free-running down-counter on the core clock: the instruction counter, for a
/// machine whose core clock is `SYSCLK_HZ` under `-icount shift=S` (`NS_PER_INSTR` = 2^S virtual
/// nanoseconds per instruction). Compile-time constants, so that converting a count loads nothing
/// the compiler could hoist into the measured section.
pub struct InstrCounter<const SYSCLK_HZ: u32, const NS_PER_INSTR: u32> {
    syst: SYST,
}

impl<const SYSCLK_HZ: u32, const NS_PER_INSTR: u32> InstrCounter<SYSCLK_HZ, NS_PER_INSTR> {
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

    /// Instructions for `ticks` SysTick ticks: `ticks / (f_systick · NS_PER_INSTR · 1 ns)`,
    /// rounded.
    pub fn ticks_to_instructions(ticks: u32) -> u32 {
        let per_s = SYSCLK_HZ as u64 * NS_PER_INSTR.max(1) as u64;
        ((ticks as u64 * 1_000_000_000 + per_s / 2) / per_s.max(1)) as u32
    }

    /// Release SysTick.
    pub fn free(self) -> SYST {
        self.syst
    }
}

impl<const SYSCLK_HZ: u32, const NS_PER_INSTR: u32> rths_app::board::InstrCounter
    for InstrCounter<SYSCLK_HZ, NS_PER_INSTR>
{
    #[inline(always)]
    fn now(&self) -> u32 {
        InstrCounter::now(self)
    }
    #[inline(always)]
    fn instructions(&self, start: u32, end: u32) -> u32 {
        Self::ticks_to_instructions(Self::elapsed_ticks(start, end))
    }
}

/// A tick timer whose counter can be read (the calibration's second clock).
pub trait CountingTimer: TickTimer {
    /// Timer counts since the last [`TickTimer::start`].
    fn count(&self) -> u32;
    /// The timer's actual tick rate, Hz (its period is rounded to whole counts).
    fn tick_rate_hz() -> f64;
}

/// A calibration of the instruction counter against a loop of known length.
#[derive(Debug, Clone, Copy)]
pub struct SysTickCounterCalibration {
    /// Instructions the loop executes (2 per iteration: `subs`, `bne`).
    pub loop_instructions: u32,
    /// Instructions measured by SysTick.
    pub measured_instructions: u32,
    /// Tick-timer counts over the same loop (the `tim2_counts` of the CALIB line).
    pub timer_counts: u32,
    /// Instructions measured around an empty section (the counter's own overhead).
    pub overhead_instructions: u32,
    /// The tick timer's actual rate, Hz (computed when printed: an f64 division here, in software
    /// on the M4, would shift SysTick's phase as `calibrate` explains).
    pub tick_hz: fn() -> f64,
    /// The FPU's media and VFP feature register 0 (MVFR0) as the core reports it: bits 11:8 say
    /// whether double precision is implemented (2) or not (0): the M7's `f64` in hardware, checked
    /// on the emulated core itself.
    pub fpu_mvfr0: u32,
}

impl SysTickCounterCalibration {
    /// The FPU executes double precision (MVFR0 bits 11:8 = 2).
    pub fn fpu_f64(&self) -> bool {
        (self.fpu_mvfr0 >> 8) & 0xF == 2
    }
}

/// Run a `subs`/`bne` loop of `iterations` (2 instructions each) and measure it with SysTick and the
/// tick timer; also measure the overhead of two back-to-back SysTick reads. `fpu_mvfr0` is the FPU's
/// feature register, read by the board before it started SysTick (reading it later would shift
/// SysTick's phase against the tick timer, and with it every per-tick count by up to one SysTick
/// count). The timer must be stopped with its interrupt not yet enabled in the NVIC; it is stopped
/// again at the end.
pub fn calibrate<T: CountingTimer, const SYSCLK_HZ: u32, const NS_PER_INSTR: u32>(
    counter: &InstrCounter<SYSCLK_HZ, NS_PER_INSTR>,
    timer: &mut T,
    iterations: u32,
    fpu_mvfr0: u32,
) -> SysTickCounterCalibration {
    let to_instr = |a: u32, b: u32| {
        InstrCounter::<SYSCLK_HZ, NS_PER_INSTR>::ticks_to_instructions(InstrCounter::<
            SYSCLK_HZ,
            NS_PER_INSTR,
        >::elapsed_ticks(
            a, b
        ))
    };
    let a = counter.now();
    let b = counter.now();
    let overhead = to_instr(a, b);
    timer.start();
    let c0 = timer.count();
    let s0 = counter.now();
    spin(iterations);
    let s1 = counter.now();
    let c1 = timer.count();
    timer.stop();
    SysTickCounterCalibration {
        loop_instructions: iterations.saturating_mul(2),
        measured_instructions: to_instr(s0, s1),
        timer_counts: c1.wrapping_sub(c0),
        overhead_instructions: overhead,
        tick_hz: T::tick_rate_hz,
        fpu_mvfr0,
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

impl rths_app::board::CounterCalibration for SysTickCounterCalibration {
    fn write_line<W: core::fmt::Write>(&self, w: &mut W) -> core::fmt::Result {
        w.write_fmt(format_args!(
            "CALIB {{\"loop_instr\":{},\"systick_instr\":{},\"tim2_counts\":{},\"read_overhead_instr\":{},\"tick_hz\":{:?},\"fpu_mvfr0\":\"{:#010x}\",\"fpu_f64\":{}}}",
            self.loop_instructions,
            self.measured_instructions,
            self.timer_counts,
            self.overhead_instructions,
            (self.tick_hz)(),
            self.fpu_mvfr0,
            self.fpu_f64()
        ))
    }

    fn counter_overhead_instr(&self) -> u32 {
        self.overhead_instructions
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

    /// Replace the fault plan (at boot, before the first tick: the plant starts over at rest).
    pub fn inject(&mut self, faults: FaultPlan) {
        self.rig = VirtualRig::with_faults(*self.rig.params(), faults);
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

/// What can fail while bringing an emulated board up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoardError {
    /// The plant's configuration.
    Plant,
    /// The reference structure.
    Reference,
}

/// The plant at rest with no faults and the harness (reset it before the first tick).
pub fn plant_and_harness() -> Result<(Plant, Harness), BoardError> {
    let rig = Plant::new(1, FaultPlan::none()).ok_or(BoardError::Plant)?;
    // Reset with the record's first ü_g before the first tick (`Harness::reset`).
    let reference =
        Reference::new(&Prototype::paper(), DT_S, 0.0).map_err(|_| BoardError::Reference)?;
    Ok((
        rig,
        Harness {
            reference,
            target_row_mm: 0.0,
        },
    ))
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    logger::host_line("PANIC");
    exit(false)
}

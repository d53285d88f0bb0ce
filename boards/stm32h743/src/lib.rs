//! The real Cortex-M7 board: an STM32H743 (e.g. STM32H743VIT6, revision V) wired to the
//! servo-controller exactly as the STM32F407 board (`boards/stm32f4`): the same AD7606 ADC and
//! AD5754R DAC drivers (`rths-board-drivers`), the same pins (the LQFP100 packages share the
//! assignment), the hardware E-stop input and the command link on USART2. Its Cortex-M7 runs the
//! controller's `f64` in hardware (FPv5-D16): build with `cargo build-m7` (firmware/.cargo/config.toml).
//! Pins, wiring and bring-up: `docs/hardware.md`.
//!
//! - **Clocks**: HSE 8 MHz crystal → PLL1 → SYSCLK 480 MHz (voltage scale 0), AHB 240 MHz, APB1
//!   120 MHz (its timers 240 MHz); PLL1_Q 80 MHz for the SPI kernels; flash wait states set by the HAL.
//! - **Tick**: TIM2 on the 240 MHz APB1 timer clock, prescaler 1, period [`TICK_PERIOD_COUNTS`] =
//!   round(240 MHz / rate) = 117 188 at 2048 Hz (exact: 117 187.5): 2047.996 Hz, −4.3 ppm.
//! - **Converters**: AD7606 on SPI2 (PB13/14/15, CS PB12), AD5754R on SPI1 (PB3/4/5, SYNC PD0), both
//!   at 10 MHz (80 MHz / 8), mode 2.
//! - **Link**: USART2 (PA2 TX, PA3 RX) at 2 Mbaud (120 MHz / 60, exact), 8N1.
//! - **Watchdog**: the IWDG ([`Watchdog`], on the 32 kHz LSI), the app's `Watchdog`: started by the
//!   control task at its first tick and fed every tick (not by [`init`]: a started IWDG cannot be
//!   stopped).
//! - **Instruction counter**: the DWT cycle counter (cycles: an upper bound of the instructions).
//!
//! The HAL (`stm32h7xx-hal`) implements embedded-hal 0.2; [`eh1`] adapts its SPI buses and pins to
//! the embedded-hal 1.0 traits the drivers take.
#![no_std]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod eh1;

use defmt_rtt as _;
use eh1::{Eh1Pin, Eh1Spi};
use embedded_hal::delay::DelayNs;
use embedded_hal_bus::spi::{ExclusiveDevice, NoDelay};
use rths_board_drivers::ad5754::{Ad5754, Ad5754Error};
use rths_board_drivers::ad7606::{Ad7606, Ad7606Config, Ad7606Error};
use rths_board_drivers::{
    ActiveLevel, ConverterCalibration, ConverterCalibrationConfig, EStop, Rig,
};
use stm32h7xx_hal::gpio::{Input, Output, Pin, PushPull};
use stm32h7xx_hal::independent_watchdog::IndependentWatchdog;
pub use stm32h7xx_hal::pac;
use stm32h7xx_hal::prelude::*;
use stm32h7xx_hal::rcc::rec::ResetEnable;
use stm32h7xx_hal::serial::{Rx, Tx};
use stm32h7xx_hal::spi::{Enabled, Mode, Phase, Polarity, Spi};

/// The crystal, Hz.
pub const HSE_HZ: u32 = 8_000_000;
/// Core clock, Hz.
pub const SYSCLK_HZ: u32 = 480_000_000;
/// AHB clock, Hz (240 MHz at most on the H743).
pub const HCLK_HZ: u32 = 240_000_000;
/// APB1 clock, Hz (USART2's kernel clock).
pub const PCLK1_HZ: u32 = 120_000_000;
/// TIM2's counting clock (APB1 doubled for the timers, its prescaler being 2), Hz.
pub const TIM2_CLOCK_HZ: u32 = 240_000_000;
/// PLL1_Q, the SPI kernels' clock, Hz.
pub const SPI_KERNEL_HZ: u32 = 80_000_000;
/// The controller rate the tick aims at, Hz.
pub const TARGET_TICK_HZ: u32 = rths_core::params::CONTROL_RATE_HZ;
/// Timer counts per tick: round(240 MHz / rate) (117 188 at 2048 Hz).
pub const TICK_PERIOD_COUNTS: u32 = (TIM2_CLOCK_HZ + TARGET_TICK_HZ / 2) / TARGET_TICK_HZ;
/// The link's baud rate.
pub const LINK_BAUD: u32 = 2_000_000;
/// SPI clock of both converters, Hz (AD7606: ≤ 23.5 MHz; AD5754R: ≤ 30 MHz): 80 MHz / 8.
pub const SPI_HZ: u32 = 10_000_000;
/// The ground-motion record buffer (address, bytes) for uploads over the link: the first 64 KiB of
/// the 512 KiB AXI SRAM, which no linker region uses (`memory.x`); the size of the other boards'.
pub const RECORD_BUFFER: (usize, usize) = (0x2400_0000, 64 * 1024);

/// The watchdog's timeout, ms: ~20 ticks at 2048 Hz, far above a tick, far below a rig's reaction.
pub const WATCHDOG_TIMEOUT_MS: u32 = 10;

/// The actual tick rate, Hz: 2047.996 Hz at 2048 Hz.
pub fn tick_rate_hz() -> f64 {
    TIM2_CLOCK_HZ as f64 / TICK_PERIOD_COUNTS as f64
}

/// The tick's rate error, ppm (−4.3 at 2048 Hz).
pub fn tick_rate_error_ppm() -> f64 {
    (tick_rate_hz() / TARGET_TICK_HZ as f64 - 1.0) * 1e6
}

/// SPI mode 2 (CPOL = 1, data sampled on the falling edge): both converters.
pub const SPI_MODE: Mode = Mode {
    polarity: Polarity::IdleHigh,
    phase: Phase::CaptureOnFirstTransition,
};

/// Busy-wait delays from the core clock (the drivers' few-µs waits).
#[derive(Debug, Clone, Copy, Default)]
pub struct CycleDelay;

impl DelayNs for CycleDelay {
    fn delay_ns(&mut self, ns: u32) {
        // 480 cycles per µs; at least one cycle.
        let cycles = (ns as u64 * (SYSCLK_HZ / 1_000_000) as u64).div_ceil(1000);
        cortex_m::asm::delay(cycles.min(u32::MAX as u64).max(1) as u32);
    }
}

/// A push-pull output pin, as the drivers see it.
type Out<const P: char, const N: u8> = Eh1Pin<Pin<P, N, Output<PushPull>>>;
/// An input pin, as the drivers see it.
type In<const P: char, const N: u8> = Eh1Pin<Pin<P, N, Input>>;

/// The ADC's SPI device (SPI2, CS on PB12).
pub type AdcSpi = ExclusiveDevice<Eh1Spi<Spi<pac::SPI2, Enabled, u8>>, Out<'B', 12>, NoDelay>;
/// The DAC's SPI device (SPI1 on PB3/PB4/PB5, SYNC on PD0).
pub type DacSpi = ExclusiveDevice<Eh1Spi<Spi<pac::SPI1, Enabled, u8>>, Out<'D', 0>, NoDelay>;
/// The calibrated rig: AD7606 (CONVST PB0, BUSY PB1, RESET PC4) and AD5754R (LDAC PD1).
pub type BoardRig =
    Rig<AdcSpi, Out<'B', 0>, In<'B', 1>, Out<'C', 4>, CycleDelay, DacSpi, Out<'D', 1>, CycleDelay>;
/// The E-stop input (PC5, pull-up, a normally-closed contact to ground: high = stop).
pub type BoardEStop = EStop<In<'C', 5>>;

/// What can fail while bringing the board up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoardError {
    /// The clock tree did not come out as planned (the tick's period assumes it).
    Clocks,
    /// The ADC configuration or its reset.
    Adc(Ad7606Error),
    /// The DAC: its range did not read back (wiring, power) or the bus failed.
    Dac(Ad5754Error),
    /// The link UART configuration.
    Serial,
    /// The rig's calibration.
    Calibration,
}

/// The tick timer (TIM2).
pub struct TickTimer {
    tim: pac::TIM2,
}

impl TickTimer {
    /// TIM2 at [`TICK_PERIOD_COUNTS`], update interrupt on, stopped. Its clock is enabled by [`init`].
    fn new(tim: pac::TIM2) -> Self {
        tim.cr1.write(|w| w.cen().clear_bit());
        tim.psc.write(|w| w.psc().bits(0));
        tim.arr.write(|w| w.arr().bits(TICK_PERIOD_COUNTS - 1));
        tim.cnt.reset();
        tim.egr.write(|w| w.ug().set_bit());
        tim.sr.write(|w| w.uif().clear_bit());
        tim.dier.write(|w| w.uie().set_bit());
        Self { tim }
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

/// The link port: USART2, receive interrupt on.
pub struct LinkSerial {
    tx: Tx<pac::USART2>,
    rx: Rx<pac::USART2>,
}

impl rths_app::board::LinkPort for LinkSerial {
    /// An overrun or framing error drops the byte; the frame's CRC then rejects the frame.
    fn read_byte(&mut self) -> Option<u8> {
        use embedded_hal_02::serial::Read;
        self.rx.read().ok()
    }
    /// Blocks on TXE; 5 µs a byte at 2 Mbaud.
    fn write_all(&mut self, bytes: &[u8]) {
        use embedded_hal_02::serial::Write;
        for &b in bytes {
            let _ = nb::block!(self.tx.write(b));
        }
    }
}

/// The E-stop input as the firmware sees it.
pub struct EStopInput(pub BoardEStop);

impl rths_app::board::EStop for EStopInput {
    fn asserted(&mut self) -> bool {
        self.0.is_active()
    }
}

/// The independent watchdog (IWDG): once started it resets the MCU unless fed within
/// [`WATCHDOG_TIMEOUT_MS`]; the DAC's output then returns to 0 V at its power-on reset.
pub struct Watchdog(IndependentWatchdog);

impl rths_app::board::Watchdog for Watchdog {
    fn start(&mut self) {
        self.0.start(WATCHDOG_TIMEOUT_MS.millis());
    }
    fn feed(&mut self) {
        self.0.feed();
    }
}

/// The DWT cycle counter: on silicon the work is counted in core cycles (an upper bound of the
/// instructions).
pub struct CycleCounter;

impl rths_app::board::InstrCounter for CycleCounter {
    #[inline(always)]
    fn now(&self) -> u32 {
        cortex_m::peripheral::DWT::cycle_count()
    }
    #[inline(always)]
    fn instructions(&self, start: u32, end: u32) -> u32 {
        end.wrapping_sub(start)
    }
}

/// The board, brought up.
pub struct Board {
    /// The controller's tick.
    pub timer: TickTimer,
    /// ADC + DAC behind the calibration.
    pub rig: BoardRig,
    /// The hardware E-stop.
    pub estop: BoardEStop,
    /// The command link.
    pub link: LinkSerial,
    /// The watchdog (not started).
    pub watchdog: Watchdog,
}

impl Board {
    /// Power and clocks, pins, converters (ADC reset, DAC range set and read back, output latched at
    /// 0 V), E-stop, link UART, the tick timer (stopped) and the watchdog (not started).
    pub fn init(dp: pac::Peripherals, cal: ConverterCalibration) -> Result<Self, BoardError> {
        // 480 MHz needs voltage scale 0 (revision V silicon).
        let pwrcfg = dp.PWR.constrain().vos0(&dp.SYSCFG).freeze();
        let ccdr = dp
            .RCC
            .constrain()
            .use_hse(HSE_HZ.Hz())
            .sys_ck(SYSCLK_HZ.Hz())
            .hclk(HCLK_HZ.Hz())
            .pclk1(PCLK1_HZ.Hz())
            .pll1_q_ck(SPI_KERNEL_HZ.Hz())
            .freeze(pwrcfg, &dp.SYSCFG);
        let clocks = ccdr.clocks;
        if clocks.sys_ck().raw() != SYSCLK_HZ || clocks.timx_ker_ck().raw() != TIM2_CLOCK_HZ {
            return Err(BoardError::Clocks);
        }
        let gpioa = dp.GPIOA.split(ccdr.peripheral.GPIOA);
        let gpiob = dp.GPIOB.split(ccdr.peripheral.GPIOB);
        let gpioc = dp.GPIOC.split(ccdr.peripheral.GPIOC);
        let gpiod = dp.GPIOD.split(ccdr.peripheral.GPIOD);

        // AD7606 on SPI2.
        let adc_bus: Spi<pac::SPI2, Enabled, u8> = dp.SPI2.spi(
            (
                gpiob.pb13.into_alternate::<5>(),
                gpiob.pb14.into_alternate::<5>(),
                gpiob.pb15.into_alternate::<5>(),
            ),
            SPI_MODE,
            SPI_HZ.Hz(),
            ccdr.peripheral.SPI2,
            &clocks,
        );
        let adc_cs = Eh1Pin(gpiob.pb12.into_push_pull_output_in_state(true.into()));
        let adc_spi = ExclusiveDevice::new_no_delay(Eh1Spi(adc_bus), adc_cs).map_err(|_| {
            BoardError::Adc(Ad7606Error::Pin(embedded_hal::digital::ErrorKind::Other))
        })?;
        let convst = Eh1Pin(gpiob.pb0.into_push_pull_output_in_state(true.into()));
        let busy = Eh1Pin(gpiob.pb1.into_pull_down_input());
        let reset = Eh1Pin(gpioc.pc4.into_push_pull_output());
        let mut adc = Ad7606::new(
            adc_spi,
            convst,
            busy,
            reset,
            CycleDelay,
            Ad7606Config::new(cal.channels_to_read() as u8),
        )
        .map_err(BoardError::Adc)?;
        adc.init().map_err(BoardError::Adc)?;

        // AD5754R on SPI1 (PB3 SCK, PB4 MISO = SDO, PB5 MOSI = SDIN).
        let dac_bus: Spi<pac::SPI1, Enabled, u8> = dp.SPI1.spi(
            (
                gpiob.pb3.into_alternate::<5>(),
                gpiob.pb4.into_alternate::<5>(),
                gpiob.pb5.into_alternate::<5>(),
            ),
            SPI_MODE,
            SPI_HZ.Hz(),
            ccdr.peripheral.SPI1,
            &clocks,
        );
        let dac_cs = Eh1Pin(gpiod.pd0.into_push_pull_output_in_state(true.into()));
        let dac_spi = ExclusiveDevice::new_no_delay(Eh1Spi(dac_bus), dac_cs).map_err(|_| {
            BoardError::Dac(Ad5754Error::Pin(embedded_hal::digital::ErrorKind::Other))
        })?;
        let ldac = Eh1Pin(gpiod.pd1.into_push_pull_output_in_state(true.into()));
        let mut dac = Ad5754::new(dac_spi, ldac, CycleDelay, 0).map_err(BoardError::Dac)?;
        dac.init().map_err(BoardError::Dac)?;

        let estop = EStop::new(Eh1Pin(gpioc.pc5.into_pull_up_input()), ActiveLevel::High);

        let mut serial = dp
            .USART2
            .serial(
                (
                    gpioa.pa2.into_alternate::<7>(),
                    gpioa.pa3.into_alternate::<7>(),
                ),
                LINK_BAUD.bps(),
                ccdr.peripheral.USART2,
                &clocks,
            )
            .map_err(|_| BoardError::Serial)?;
        serial.listen(stm32h7xx_hal::serial::Event::Rxne);
        let (tx, rx) = serial.split();

        // TIM2's clock, through the HAL's peripheral record (enable and reset).
        ccdr.peripheral.TIM2.enable().reset();
        Ok(Self {
            timer: TickTimer::new(dp.TIM2),
            rig: Rig::new(adc, dac, cal),
            estop,
            link: LinkSerial { tx, rx },
            watchdog: Watchdog(IndependentWatchdog::new(dp.IWDG)),
        })
    }
}

/// The real Cortex-M7 board.
#[derive(Debug, Clone, Copy)]
pub struct Stm32h743;

/// The board this crate is (the firmware's `board::ThisBoard`).
pub type ThisBoard = Stm32h743;

impl rths_app::board::Board for Stm32h743 {
    type Timer = TickTimer;
    type Link = LinkSerial;
    type RigError = rths_board_drivers::RigError;
    type Rig = BoardRig;
    type Counter = CycleCounter;
    type EStop = EStopInput;
    type Harness = rths_app::board::NoHarness;
    type CounterCalibration = rths_app::board::NoCounterCalibration;
    type Watchdog = Watchdog;
    const EMULATED_PLANT: bool = false;

    fn tick_rate_hz() -> f64 {
        tick_rate_hz()
    }

    fn host_line(line: &str) {
        defmt::info!("{=str}", line);
    }

    fn exit(_success: bool) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    fn log_frames_cut() -> u32 {
        0
    }
}

/// Bring the board up with the paper actuator's calibration (the lab's goes here): power, clocks,
/// pins, converters, E-stop, link UART, the DWT cycle counter, and the tick timer (stopped).
pub fn init(
    dp: pac::Peripherals,
    mut core: cortex_m::Peripherals,
) -> Result<rths_app::board::Parts<Stm32h743>, BoardError> {
    let cal = ConverterCalibration::new(ConverterCalibrationConfig::paper_actuator())
        .map_err(|_| BoardError::Calibration)?;
    // The M7's caches: the instruction cache speeds flash execution; the data cache stays off (the
    // statics and the stack are in DTCM, which it does not serve, and the SPI buffers need no
    // maintenance).
    core.SCB.enable_icache();
    let b = Board::init(dp, cal)?;
    core.DCB.enable_trace();
    core.DWT.enable_cycle_counter();
    Ok(rths_app::board::Parts {
        timer: b.timer,
        link: b.link,
        rig: b.rig,
        counter: CycleCounter,
        estop: EStopInput(b.estop),
        harness: rths_app::board::NoHarness,
        calibration: rths_app::board::NoCounterCalibration,
        watchdog: b.watchdog,
    })
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    // The DAC holds its last output; the servo-controller's own limits and its E-stop chain are the
    // protection from here on.
    defmt::error!("PANIC");
    loop {
        cortex_m::asm::wfi();
    }
}

//! The real board: an STM32F407 (e.g. STM32F407VGT6) wired to the servo-controller through an
//! AD7606 ADC and an AD5754R DAC (`rths-board-drivers`), with a hardware E-stop input and the command
//! link on USART2. Pins and wiring: `docs/hardware.md`.
//!
//! - **Clocks**: HSE 8 MHz crystal → PLL (M = 8, N = 336, P = 2, Q = 7) → SYSCLK 168 MHz; AHB 168 MHz,
//!   APB1 42 MHz (its timers 84 MHz), APB2 84 MHz; flash 5 wait states (the HAL sets them).
//! - **Tick**: TIM2 on the 84 MHz APB1 timer clock, prescaler 1, period [`TICK_PERIOD_COUNTS`] =
//!   round(84 MHz / 2048) = 41 016 (exact: 41 015.625): 2047.981 Hz, a rate error of **−9.1 ppm**
//!   (0.37 ms over El Centro's 40 s; the controller keeps the nominal Δt = 1/2048 s). The HSE crystal's
//!   own tolerance (typically ±20-50 ppm) is larger than that.
//! - **Converters**: AD7606 on SPI2 (10.5 MHz, mode 2), AD5754R on SPI1 (10.5 MHz, mode 2), each with
//!   its own chip select, so the two never share a bus transaction.
//! - **Link**: USART2 (PA2 TX, PA3 RX) at 2 Mbaud (exact at 42 MHz: USARTDIV = 1.3125), 8N1.
#![no_std]
#![deny(missing_docs)]
#![forbid(unsafe_code)]

use defmt_rtt as _;
use embedded_hal::delay::DelayNs;
use embedded_hal_bus::spi::{ExclusiveDevice, NoDelay};
use rths_board_drivers::ad5754::{Ad5754, Ad5754Error};
use rths_board_drivers::ad7606::{Ad7606, Ad7606Config, Ad7606Error};
use rths_board_drivers::{
    ActiveLevel, ConverterCalibration, ConverterCalibrationConfig, EStop, Rig,
};
use stm32f4xx_hal::gpio::{Input, Output, PushPull, PB0, PB1, PB12, PC4, PC5, PD0, PD1};
pub use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::Config;
use stm32f4xx_hal::serial::{Rx, Serial, Tx};
use stm32f4xx_hal::spi::{Mode, Phase, Polarity, Spi};

/// The crystal, Hz.
pub const HSE_HZ: u32 = 8_000_000;
/// Core clock, Hz.
pub const SYSCLK_HZ: u32 = 168_000_000;

/// The ground-motion record buffer (address, bytes) for uploads over the link: the 64 KiB CCM RAM
/// (core-coupled, not reachable by DMA, which the record does not need), outside `memory.x`, so the
/// statics and the stack keep the whole 128 KiB of main SRAM.
pub const RECORD_BUFFER: (usize, usize) = (0x1000_0000, 64 * 1024);
/// TIM2's counting clock (APB1 = 42 MHz, doubled for the timers since its prescaler is not 1), Hz.
pub const TIM2_CLOCK_HZ: u32 = 84_000_000;
/// The controller rate the tick aims at, Hz.
pub const TARGET_TICK_HZ: u32 = rths_core::params::CONTROL_RATE_HZ;
/// Timer counts per tick: round(84 MHz / 2048) = 41 016.
pub const TICK_PERIOD_COUNTS: u32 = (TIM2_CLOCK_HZ + TARGET_TICK_HZ / 2) / TARGET_TICK_HZ;
/// The link's baud rate.
pub const LINK_BAUD: u32 = 2_000_000;
/// SPI clock of both converters, Hz (AD7606: ≤ 23.5 MHz; AD5754R: ≤ 30 MHz).
pub const SPI_HZ: u32 = 10_500_000;

/// The actual tick rate, Hz: 2047.981 Hz.
pub fn tick_rate_hz() -> f64 {
    TIM2_CLOCK_HZ as f64 / TICK_PERIOD_COUNTS as f64
}

/// The tick's rate error, ppm (−9.14).
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
        // 168 cycles per µs; at least one cycle.
        let cycles = (ns as u64 * (SYSCLK_HZ / 1_000_000) as u64).div_ceil(1000);
        cortex_m::asm::delay(cycles.min(u32::MAX as u64).max(1) as u32);
    }
}

/// The ADC's SPI device (SPI2, CS on PB12).
pub type AdcSpi = ExclusiveDevice<Spi<pac::SPI2>, PB12<Output<PushPull>>, NoDelay>;
/// The DAC's SPI device (SPI1 on PB3/PB4/PB5, SYNC on PD0).
pub type DacSpi = ExclusiveDevice<Spi<pac::SPI1>, PD0<Output<PushPull>>, NoDelay>;
/// The calibrated rig: AD7606 (CONVST PB0, BUSY PB1, RESET PC4) and AD5754R (LDAC PD1).
pub type BoardRig = Rig<
    AdcSpi,
    PB0<Output<PushPull>>,
    PB1<Input>,
    PC4<Output<PushPull>>,
    CycleDelay,
    DacSpi,
    PD1<Output<PushPull>>,
    CycleDelay,
>;
/// The E-stop input (PC5, pull-up, a normally-closed contact to ground: high = stop).
pub type BoardEStop = EStop<PC5<Input>>;

/// What can fail while bringing the board up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BoardError {
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
    /// TIM2 at [`TICK_PERIOD_COUNTS`], update interrupt on, stopped. The clock is enabled by
    /// [`Board::init`].
    fn new(tim: pac::TIM2) -> Self {
        tim.cr1().write(|w| w.cen().clear_bit());
        tim.psc().write(|w| w.psc().set(0));
        tim.arr().write(|w| w.arr().set(TICK_PERIOD_COUNTS - 1));
        tim.cnt().reset();
        tim.egr().write(|w| w.ug().set_bit());
        tim.sr().write(|w| w.uif().clear_bit());
        tim.dier().write(|w| w.uie().set_bit());
        Self { tim }
    }
}

/// The link port: USART2, receive interrupt on.
pub struct LinkSerial {
    tx: Tx<pac::USART2>,
    rx: Rx<pac::USART2>,
}

/// The board, brought up.
pub struct Board {
    /// The 2048 Hz tick.
    pub timer: TickTimer,
    /// ADC + DAC behind the calibration.
    pub rig: BoardRig,
    /// The hardware E-stop.
    pub estop: BoardEStop,
    /// The command link.
    pub link: LinkSerial,
    /// The control task's watchdog (stopped).
    pub watchdog: Iwdg,
}

impl Board {
    /// Clocks, pins, converters (ADC reset, DAC range set and read back, output latched at 0 V), E-stop,
    /// link UART, and the tick timer (stopped).
    pub fn init(dp: pac::Peripherals, cal: ConverterCalibration) -> Result<Self, BoardError> {
        let watchdog = Iwdg(stm32f4xx_hal::watchdog::IndependentWatchdog::new(dp.IWDG));
        let mut rcc = dp.RCC.freeze(
            Config::hse(HSE_HZ.Hz())
                .sysclk(SYSCLK_HZ.Hz())
                .hclk(SYSCLK_HZ.Hz())
                .pclk1(42.MHz())
                .pclk2(84.MHz()),
        );
        let gpioa = dp.GPIOA.split(&mut rcc);
        let gpiob = dp.GPIOB.split(&mut rcc);
        let gpioc = dp.GPIOC.split(&mut rcc);
        let gpiod = dp.GPIOD.split(&mut rcc);

        // AD7606 on SPI2.
        let adc_bus = dp.SPI2.spi(
            (Some(gpiob.pb13), Some(gpiob.pb14), Some(gpiob.pb15)),
            SPI_MODE,
            SPI_HZ.Hz(),
            &mut rcc,
        );
        let adc_cs = gpiob.pb12.into_push_pull_output_in_state(true.into());
        let adc_spi = match ExclusiveDevice::new_no_delay(adc_bus, adc_cs) {
            Ok(d) => d,
            Err(e) => match e {},
        };
        let convst = gpiob.pb0.into_push_pull_output_in_state(true.into());
        let busy = gpiob.pb1.into_pull_down_input();
        let reset = gpioc.pc4.into_push_pull_output();
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
        let dac_bus = dp.SPI1.spi(
            (
                Some(gpiob.pb3.into_floating_input()),
                Some(gpiob.pb4.into_floating_input()),
                Some(gpiob.pb5),
            ),
            SPI_MODE,
            SPI_HZ.Hz(),
            &mut rcc,
        );
        let dac_cs = gpiod.pd0.into_push_pull_output_in_state(true.into());
        let dac_spi = match ExclusiveDevice::new_no_delay(dac_bus, dac_cs) {
            Ok(d) => d,
            Err(e) => match e {},
        };
        let ldac = gpiod.pd1.into_push_pull_output_in_state(true.into());
        let mut dac = Ad5754::new(dac_spi, ldac, CycleDelay, 0).map_err(BoardError::Dac)?;
        dac.init().map_err(BoardError::Dac)?;

        let estop = EStop::new(gpioc.pc5.into_pull_up_input(), ActiveLevel::High);

        let mut serial: Serial<pac::USART2> = dp
            .USART2
            .serial(
                (gpioa.pa2, gpioa.pa3),
                stm32f4xx_hal::serial::config::Config::default().baudrate(LINK_BAUD.bps()),
                &mut rcc,
            )
            .map_err(|_| BoardError::Serial)?;
        serial.listen(stm32f4xx_hal::serial::Event::RxNotEmpty);
        let (tx, rx) = serial.split();

        // TIM2's clock, through the HAL's RCC enable and reset.
        let tim = dp.TIM2;
        {
            use stm32f4xx_hal::rcc::{Enable, Reset};
            pac::TIM2::enable(&mut rcc);
            pac::TIM2::reset(&mut rcc);
        }
        Ok(Self {
            timer: TickTimer::new(tim),
            rig: Rig::new(adc, dac, cal),
            estop,
            link: LinkSerial { tx, rx },
            watchdog,
        })
    }
}

impl rths_app::board::TickTimer for TickTimer {
    fn start(&mut self) {
        self.tim.cnt().reset();
        self.tim.cr1().modify(|_, w| w.cen().set_bit());
    }
    fn stop(&mut self) {
        self.tim.cr1().modify(|_, w| w.cen().clear_bit());
        self.clear();
    }
    fn clear(&mut self) {
        self.tim.sr().write(|w| w.uif().clear_bit());
    }
    fn pending(&self) -> bool {
        self.tim.sr().read().uif().bit_is_set()
    }
}

impl rths_app::board::LinkPort for LinkSerial {
    /// An overrun or framing error drops the byte; the frame's CRC then rejects the frame.
    fn read_byte(&mut self) -> Option<u8> {
        use embedded_hal_nb::serial::Read;
        self.rx.read().ok()
    }
    /// Blocks on TXE; 5 µs a byte at 2 Mbaud.
    fn write_all(&mut self, bytes: &[u8]) {
        use embedded_hal_nb::serial::Write;
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

/// The real board.
#[derive(Debug, Clone, Copy)]
pub struct Stm32f4;

/// The board this crate is (the firmware's `board::ThisBoard`).
pub type ThisBoard = Stm32f4;

impl rths_app::board::Board for Stm32f4 {
    type Timer = TickTimer;
    type Link = LinkSerial;
    type RigError = rths_board_drivers::RigError;
    type Rig = BoardRig;
    type Counter = CycleCounter;
    type EStop = EStopInput;
    type Harness = rths_app::board::NoHarness;
    type CounterCalibration = rths_app::board::NoCounterCalibration;
    type Watchdog = Iwdg;
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

/// Bring the board up with the paper actuator's calibration (the lab's goes here): clocks, pins,
/// converters, E-stop, link UART, the DWT cycle counter, and the tick timer (stopped).
pub fn init(
    dp: pac::Peripherals,
    mut core: cortex_m::Peripherals,
) -> Result<rths_app::board::Parts<Stm32f4>, BoardError> {
    let cal = ConverterCalibration::new(ConverterCalibrationConfig::paper_actuator())
        .map_err(|_| BoardError::Calibration)?;
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

/// The control task's watchdog period, ms: 4 ticks at 2048 Hz (IWDG on the ~32 kHz LSI, whose
/// spread, 17-47 kHz, makes the real timeout 1.4-3.8 ms; never shorter than 2 ticks).
pub const WATCHDOG_MS: u32 = 2;

/// The independent watchdog: on its own clock (LSI), it resets the MCU if the control task does
/// not feed it within [`WATCHDOG_MS`]; the start-up then latches the DAC at 0 V (`Board::init`),
/// the safe command.
pub struct Iwdg(stm32f4xx_hal::watchdog::IndependentWatchdog);

impl rths_app::board::Watchdog for Iwdg {
    fn start(&mut self) {
        self.0.start(WATCHDOG_MS.millis());
    }
    fn feed(&mut self) {
        self.0.feed();
    }
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

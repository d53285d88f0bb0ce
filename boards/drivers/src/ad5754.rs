//! AD5754R: quad 16-bit DAC with bipolar outputs (Analog Devices), here in its ±10 V range with the
//! internal 2.5 V reference, BIN/2sCOMP tied high (two's-complement coding), LDAC driven by the MCU.
//!
//! Why this part and not a DAC8563: the servo-controller's command input is ±10 V. The AD5754R makes
//! ±10 V itself (±12 to ±16.5 V supplies, output range set by a register, readable back to check the
//! wiring), while the DAC8563 gives 0-5 V and needs an external op-amp stage for the offset and the
//! gain (more parts, more drift, an extra calibration). The AD5754R also clamps its outputs to 0 V at
//! power-up until the range is set, which is the safe start for a servo command.
//!
//! Frames are 24 bits, MSB first: `R/W̄ | 0 | REG2..0 | A2..0 | D15..0`. SPI: data sampled on the
//! falling edge of SCLK (mode 2 here, as the ADC), up to 30 MHz. With LDAC high the DAC registers
//! update on an LDAC low pulse, so the new command takes effect at a known instant.
//!
//! Coding (±10 V, two's complement): `code = round(volts · 32768 / 10)`, clipped to
//! −32 768..=32 767 (−10 V .. +10 V − 1 LSB), LSB = 305.2 µV.

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::OutputPin;
use embedded_hal::spi::SpiDevice;

use crate::calibration::FULL_SCALE_V;

/// Volts per code in the ±10 V range.
pub const DAC_VOLTS_PER_CODE: f64 = FULL_SCALE_V / 32768.0;

/// Register select (REG2..0).
const REG_DAC: u8 = 0b000;
const REG_RANGE: u8 = 0b001;
const REG_POWER: u8 = 0b010;
const REG_CONTROL: u8 = 0b011;
/// Read bit of the first byte.
const READ: u8 = 0x80;
/// Address 0b100: all four channels (range and DAC registers).
const ADDR_ALL: u8 = 0b100;
/// Output range code of ±10 V.
pub const RANGE_PM10V: u16 = 0b100;
/// Power control: all four channels and the internal reference up (PU_A..PU_D, PU_REF).
pub const POWER_ALL_UP: u16 = 0b0010_1111;

/// The first byte of a frame.
pub fn command_byte(read: bool, reg: u8, addr: u8) -> u8 {
    (if read { READ } else { 0 }) | ((reg & 0b111) << 3) | (addr & 0b111)
}

/// A 24-bit frame.
pub fn frame(read: bool, reg: u8, addr: u8, data: u16) -> [u8; 3] {
    let [hi, lo] = data.to_be_bytes();
    [command_byte(read, reg, addr), hi, lo]
}

/// The NOP frame (control register, address 000) that clocks a readback out of SDO.
pub const NOP: [u8; 3] = [(REG_CONTROL << 3), 0, 0];

/// DAC code for `volts`, and whether it had to be clipped to the ±10 V range (a NaN gives 0 V and
/// `true`).
pub fn volts_to_code(volts: f64) -> (i16, bool) {
    if volts.is_nan() {
        return (0, true);
    }
    let x = volts / DAC_VOLTS_PER_CODE;
    // Round half away from zero without std (no libm needed: the range check comes first).
    if x >= 32767.0 {
        return (i16::MAX, x > 32767.5);
    }
    if x <= -32768.0 {
        return (i16::MIN, x < -32768.5);
    }
    let r = if x >= 0.0 { x + 0.5 } else { x - 0.5 };
    (r as i16, false)
}

/// Volts a code produces.
pub fn code_to_volts(code: i16) -> f64 {
    code as f64 * DAC_VOLTS_PER_CODE
}

/// What can go wrong with the AD5754R.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ad5754Error {
    /// The SPI transfer failed.
    Spi(embedded_hal::spi::ErrorKind),
    /// The LDAC pin failed.
    Pin(embedded_hal::digital::ErrorKind),
    /// The range register read back something else than ±10 V (SDO not wired, wrong part, no power).
    RangeReadback(u16),
    /// A channel outside 0..4.
    Channel(u8),
}

impl rths_core::hal::Error for Ad5754Error {
    fn kind(&self) -> rths_core::hal::ErrorKind {
        use rths_core::hal::ErrorKind;
        match self {
            Self::Spi(_) | Self::Pin(_) | Self::RangeReadback(_) => ErrorKind::Bus,
            Self::Channel(_) => ErrorKind::Other,
        }
    }
}

fn spi<E: embedded_hal::spi::Error>(e: E) -> Ad5754Error {
    Ad5754Error::Spi(e.kind())
}

fn pin<E: embedded_hal::digital::Error>(e: E) -> Ad5754Error {
    Ad5754Error::Pin(e.kind())
}

/// The AD5754R on an SPI device (SYNC = the device's CS), with LDAC.
pub struct Ad5754<SPI, LDAC, D> {
    spi: SPI,
    ldac: LDAC,
    delay: D,
    channel: u8,
}

impl<SPI, LDAC, D> Ad5754<SPI, LDAC, D>
where
    SPI: SpiDevice,
    LDAC: OutputPin,
    D: DelayNs,
{
    /// The DAC driving the servo command on `channel` (0 = DAC A .. 3 = DAC D).
    pub fn new(spi: SPI, ldac: LDAC, delay: D, channel: u8) -> Result<Self, Ad5754Error> {
        if channel > 3 {
            return Err(Ad5754Error::Channel(channel));
        }
        Ok(Self {
            spi,
            ldac,
            delay,
            channel,
        })
    }

    /// Power-up: LDAC high, all outputs to 0 V (code 0 written before the range, so the output
    /// leaves its power-on clamp at 0 V), range ±10 V on all channels, read the range back, then power
    /// up the channels and the internal reference, and latch 0 V.
    pub fn init(&mut self) -> Result<(), Ad5754Error> {
        self.ldac.set_high().map_err(pin)?;
        self.spi
            .write(&frame(false, REG_DAC, ADDR_ALL, 0))
            .map_err(spi)?;
        self.spi
            .write(&frame(false, REG_RANGE, ADDR_ALL, RANGE_PM10V))
            .map_err(spi)?;
        // Read back the range of our channel: the read frame, then a NOP that clocks the data out.
        self.spi
            .write(&frame(true, REG_RANGE, self.channel, 0))
            .map_err(spi)?;
        let mut rx = [0u8; 3];
        self.spi.transfer(&mut rx, &NOP).map_err(spi)?;
        let [_, hi, lo] = rx;
        let range = u16::from_be_bytes([hi, lo]) & 0b111;
        if range != RANGE_PM10V {
            return Err(Ad5754Error::RangeReadback(range));
        }
        self.spi
            .write(&frame(false, REG_POWER, 0, POWER_ALL_UP))
            .map_err(spi)?;
        // Power-up of the reference and outputs: 10 µs (data sheet t_PU), then latch 0 V.
        self.delay.delay_us(10);
        self.load()
    }

    /// Write `code` to the command channel and latch it (LDAC pulse).
    pub fn write_code(&mut self, code: i16) -> Result<(), Ad5754Error> {
        self.spi
            .write(&frame(false, REG_DAC, self.channel, code as u16))
            .map_err(spi)?;
        self.load()
    }

    /// LDAC low ≥ 10 ns then high: the DAC registers take the input registers.
    fn load(&mut self) -> Result<(), Ad5754Error> {
        self.ldac.set_low().map_err(pin)?;
        self.delay.delay_ns(20);
        self.ldac.set_high().map_err(pin)
    }

    /// Give the bus and pins back.
    pub fn release(self) -> (SPI, LDAC, D) {
        (self.spi, self.ldac, self.delay)
    }
}

#[cfg(test)]
mod tests;

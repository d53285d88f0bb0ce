//! AD7606: 8-channel, 16-bit, simultaneous-sampling ADC (Analog Devices), here in its ±10 V range
//! (RANGE pin high), no oversampling (OS pins low), serial interface (PAR/SER/BYTE SEL high), CONVST A
//! and B tied together, all data on DOUTA.
//!
//! One conversion: CONVST pulses low then high (the rising edge samples all 8 channels at the same
//! instant); BUSY goes high within 40 ns and falls when the results are ready (t_CONV ≤ 4.15 µs at
//! OS = 0, data sheet); the results are then read over SPI as 16-bit two's-complement words, MSB
//! first, V1 first. Only the first `n` channels are clocked out (a read may stop early by raising CS).
//! SPI: CPOL = 1, data sampled on the falling edge (mode 2), up to 23.5 MHz for VDRIVE ≥ 3.3 V.
//!
//! Coding (±10 V range): `volts = code · 10 / 32768`, LSB = 305.2 µV.

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal::spi::SpiDevice;

use crate::calibration::{ADC_CHANNELS, FULL_SCALE_V};

/// Volts of one code (LSB) in the ±10 V range: 20 V / 65 536.
pub const ADC_VOLTS_PER_CODE: f64 = FULL_SCALE_V / 32768.0;

/// Convert a 16-bit two's-complement result to volts.
pub fn code_to_volts(code: i16) -> f64 {
    code as f64 * ADC_VOLTS_PER_CODE
}

/// Timing of the BUSY wait.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ad7606Config {
    /// Channels clocked out per read (1..=8; V1 first).
    pub channels: u8,
    /// Time between two BUSY polls, ns.
    pub busy_poll_ns: u32,
    /// Polls before a conversion is declared lost (timeout = polls × poll time; the conversion takes
    /// ≤ 4.15 µs, so 10 polls of 1 µs leave more than 2× margin and still fit the 488 µs tick).
    pub busy_timeout_polls: u32,
}

impl Ad7606Config {
    /// `channels` channels, BUSY polled every 1 µs up to 10 µs.
    pub fn new(channels: u8) -> Self {
        Self {
            channels,
            busy_poll_ns: 1000,
            busy_timeout_polls: 10,
        }
    }
}

/// What can go wrong with the AD7606.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ad7606Error {
    /// The SPI transfer failed.
    Spi(embedded_hal::spi::ErrorKind),
    /// A GPIO (CONVST, BUSY, RESET) failed.
    Pin(embedded_hal::digital::ErrorKind),
    /// BUSY was already high before the conversion started (a conversion stuck or BUSY shorted high).
    BusyStuck,
    /// BUSY never rose after CONVST (CONVST or BUSY not connected, or the ADC not powered).
    NoConversion,
    /// BUSY did not fall within the timeout.
    Timeout,
    /// An invalid configuration (channel count outside 1..=8, zero timeout).
    Config,
}

impl rths_core::hal::Error for Ad7606Error {
    fn kind(&self) -> rths_core::hal::ErrorKind {
        use rths_core::hal::ErrorKind;
        match self {
            Self::Spi(_) | Self::Pin(_) | Self::NoConversion => ErrorKind::Bus,
            Self::BusyStuck | Self::Timeout => ErrorKind::Timeout,
            Self::Config => ErrorKind::Other,
        }
    }
}

fn pin<E: embedded_hal::digital::Error>(e: E) -> Ad7606Error {
    Ad7606Error::Pin(e.kind())
}

fn spi<E: embedded_hal::spi::Error>(e: E) -> Ad7606Error {
    Ad7606Error::Spi(e.kind())
}

/// One conversion's results (the first `channels` channels; the rest are 0).
pub type Codes = [i16; ADC_CHANNELS as usize];

/// The AD7606 on an SPI device (its CS managed by the `SpiDevice`), with CONVST, BUSY and RESET.
pub struct Ad7606<SPI, CONVST, BUSY, RESET, D> {
    spi: SPI,
    convst: CONVST,
    busy: BUSY,
    reset: RESET,
    delay: D,
    cfg: Ad7606Config,
}

impl<SPI, CONVST, BUSY, RESET, D> Ad7606<SPI, CONVST, BUSY, RESET, D>
where
    SPI: SpiDevice,
    CONVST: OutputPin,
    BUSY: InputPin,
    RESET: OutputPin,
    D: DelayNs,
{
    /// Take the bus and pins; validate the configuration. Call [`Self::init`] before converting.
    pub fn new(
        spi: SPI,
        convst: CONVST,
        busy: BUSY,
        reset: RESET,
        delay: D,
        cfg: Ad7606Config,
    ) -> Result<Self, Ad7606Error> {
        if cfg.channels == 0 || cfg.channels > ADC_CHANNELS || cfg.busy_timeout_polls == 0 {
            return Err(Ad7606Error::Config);
        }
        Ok(Self {
            spi,
            convst,
            busy,
            reset,
            delay,
            cfg,
        })
    }

    /// Power-up sequence: CONVST idles high, a RESET pulse of 1 µs (data sheet: ≥ 50 ns), then 1 µs
    /// before the first conversion.
    pub fn init(&mut self) -> Result<(), Ad7606Error> {
        self.convst.set_high().map_err(pin)?;
        self.reset.set_high().map_err(pin)?;
        self.delay.delay_ns(1000);
        self.reset.set_low().map_err(pin)?;
        self.delay.delay_ns(1000);
        Ok(())
    }

    /// Sample all channels at once, wait for BUSY, read the first `channels` results.
    pub fn convert(&mut self) -> Result<Codes, Ad7606Error> {
        if self.busy.is_high().map_err(pin)? {
            return Err(Ad7606Error::BusyStuck);
        }
        // CONVST low ≥ 25 ns, then the rising edge starts the conversion.
        self.convst.set_low().map_err(pin)?;
        self.delay.delay_ns(100);
        self.convst.set_high().map_err(pin)?;
        // BUSY rises within 40 ns of the edge.
        self.delay.delay_ns(100);
        if self.busy.is_low().map_err(pin)? {
            return Err(Ad7606Error::NoConversion);
        }
        let mut done = false;
        for _ in 0..self.cfg.busy_timeout_polls {
            self.delay.delay_ns(self.cfg.busy_poll_ns);
            if self.busy.is_low().map_err(pin)? {
                done = true;
                break;
            }
        }
        if !done {
            return Err(Ad7606Error::Timeout);
        }
        let mut buf = [0u8; 2 * ADC_CHANNELS as usize];
        let n = 2 * self.cfg.channels as usize;
        let bytes = buf.get_mut(..n).ok_or(Ad7606Error::Config)?;
        self.spi.read(bytes).map_err(spi)?;
        let mut codes: Codes = [0; ADC_CHANNELS as usize];
        for (c, w) in codes.iter_mut().zip(bytes.chunks_exact(2)) {
            if let [hi, lo] = *w {
                *c = i16::from_be_bytes([hi, lo]);
            }
        }
        Ok(codes)
    }

    /// Give the bus and pins back.
    pub fn release(self) -> (SPI, CONVST, BUSY, RESET, D) {
        (self.spi, self.convst, self.busy, self.reset, self.delay)
    }
}

#[cfg(test)]
mod tests;

//! embedded-hal 1.0 over the HAL's embedded-hal 0.2: the SPI bus ([`Eh1Spi`], for
//! `embedded_hal_bus::spi::ExclusiveDevice`) and GPIO pins ([`Eh1Pin`]) the drivers take.

use embedded_hal::digital::{ErrorKind as PinErrorKind, ErrorType as PinErrorType};
use embedded_hal::spi::{ErrorKind as SpiErrorKind, ErrorType as SpiErrorType};
use embedded_hal_02::digital::v2::{InputPin as InputPin02, OutputPin as OutputPin02};
use embedded_hal_02::spi::FullDuplex;

/// An embedded-hal 0.2 pin seen as an embedded-hal 1.0 pin.
pub struct Eh1Pin<P>(pub P);

/// A pin error (the HAL's pins cannot fail: their 0.2 error type is `Infallible`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PinError;

impl embedded_hal::digital::Error for PinError {
    fn kind(&self) -> PinErrorKind {
        PinErrorKind::Other
    }
}

impl<P> PinErrorType for Eh1Pin<P> {
    type Error = PinError;
}

impl<P: OutputPin02> embedded_hal::digital::OutputPin for Eh1Pin<P> {
    fn set_low(&mut self) -> Result<(), PinError> {
        self.0.set_low().map_err(|_| PinError)
    }
    fn set_high(&mut self) -> Result<(), PinError> {
        self.0.set_high().map_err(|_| PinError)
    }
}

impl<P: InputPin02> embedded_hal::digital::InputPin for Eh1Pin<P> {
    fn is_high(&mut self) -> Result<bool, PinError> {
        self.0.is_high().map_err(|_| PinError)
    }
    fn is_low(&mut self) -> Result<bool, PinError> {
        self.0.is_low().map_err(|_| PinError)
    }
}

/// An embedded-hal 0.2 full-duplex SPI bus (8-bit words) seen as an embedded-hal 1.0 `SpiBus`.
///
/// Word by word through `FullDuplex` (send one, read one): the HAL's blocking `Transfer`/`Write`
/// fill its FIFO with `unwrap` and slice indexing, which `panic-check.sh` finds reachable from the
/// control step; this path has none. The converters' frames are 3 and 4 bytes: the FIFO would save
/// well under a microsecond per tick.
pub struct Eh1Spi<S>(pub S);

/// An SPI bus error (overrun, mode fault, ...: the HAL's error, by kind).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpiError;

impl embedded_hal::spi::Error for SpiError {
    fn kind(&self) -> SpiErrorKind {
        SpiErrorKind::Other
    }
}

impl<S> SpiErrorType for Eh1Spi<S> {
    type Error = SpiError;
}

impl<S: FullDuplex<u8>> Eh1Spi<S> {
    /// Send `word`, return the word clocked in meanwhile.
    fn exchange(&mut self, word: u8) -> Result<u8, SpiError> {
        nb::block!(self.0.send(word)).map_err(|_| SpiError)?;
        nb::block!(self.0.read()).map_err(|_| SpiError)
    }
}

impl<S: FullDuplex<u8>> embedded_hal::spi::SpiBus<u8> for Eh1Spi<S> {
    fn read(&mut self, words: &mut [u8]) -> Result<(), SpiError> {
        // Clock out zeros, keep what comes in.
        for w in words.iter_mut() {
            *w = self.exchange(0)?;
        }
        Ok(())
    }
    fn write(&mut self, words: &[u8]) -> Result<(), SpiError> {
        for &w in words {
            self.exchange(w)?;
        }
        Ok(())
    }
    /// `read` and `write` may differ in length (embedded-hal 1.0): the longer sets the transfer's
    /// length, the shorter write side is padded with zeros and extra read bytes are dropped.
    fn transfer(&mut self, read: &mut [u8], write: &[u8]) -> Result<(), SpiError> {
        for i in 0..read.len().max(write.len()) {
            let b = self.exchange(write.get(i).copied().unwrap_or(0))?;
            if let Some(r) = read.get_mut(i) {
                *r = b;
            }
        }
        Ok(())
    }
    fn transfer_in_place(&mut self, words: &mut [u8]) -> Result<(), SpiError> {
        for w in words.iter_mut() {
            *w = self.exchange(*w)?;
        }
        Ok(())
    }
    /// Every word was read back: the bus is idle.
    fn flush(&mut self) -> Result<(), SpiError> {
        Ok(())
    }
}

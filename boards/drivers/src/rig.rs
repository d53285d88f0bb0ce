//! The real rig as the controller sees it: the AD7606 and the AD5754R behind a [`ConverterCalibration`], as
//! `rths_core::hal::{Daq, Actuator}`, and the hardware E-stop input.

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};
use embedded_hal::spi::SpiDevice;
use rths_core::hal::{Actuator, Daq, ErrorKind, Sample};

use crate::ad5754::{self, Ad5754, Ad5754Error};
use crate::ad7606::{self, Ad7606, Ad7606Error};
use crate::calibration::ConverterCalibration;

/// A failure of the rig's I/O.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RigError {
    /// The ADC failed.
    Adc(Ad7606Error),
    /// The DAC failed.
    Dac(Ad5754Error),
    /// A non-finite command was refused (the DAC keeps the previous one).
    NotFinite,
    /// The command needed more than ±10 V: the clipped value was written.
    OutOfRange,
}

impl rths_core::hal::Error for RigError {
    fn kind(&self) -> ErrorKind {
        match self {
            Self::Adc(e) => e.kind(),
            Self::Dac(e) => e.kind(),
            Self::NotFinite => ErrorKind::NotFinite,
            Self::OutOfRange => ErrorKind::OutOfRange,
        }
    }
}

/// The converters of the rig, calibrated.
pub struct Rig<ASPI, CONVST, BUSY, RESET, AD, DSPI, LDAC, DD> {
    adc: Ad7606<ASPI, CONVST, BUSY, RESET, AD>,
    dac: Ad5754<DSPI, LDAC, DD>,
    cal: ConverterCalibration,
    last_code: i16,
}

impl<ASPI, CONVST, BUSY, RESET, AD, DSPI, LDAC, DD>
    Rig<ASPI, CONVST, BUSY, RESET, AD, DSPI, LDAC, DD>
where
    ASPI: SpiDevice,
    CONVST: OutputPin,
    BUSY: InputPin,
    RESET: OutputPin,
    AD: DelayNs,
    DSPI: SpiDevice,
    LDAC: OutputPin,
    DD: DelayNs,
{
    /// The rig from its initialized converters. The ADC must clock out at least
    /// [`ConverterCalibration::channels_to_read`] channels (checked by the caller's configuration).
    pub fn new(
        adc: Ad7606<ASPI, CONVST, BUSY, RESET, AD>,
        dac: Ad5754<DSPI, LDAC, DD>,
        cal: ConverterCalibration,
    ) -> Self {
        Self {
            adc,
            dac,
            cal,
            last_code: 0,
        }
    }

    /// The calibration in use.
    pub fn calibration(&self) -> &ConverterCalibration {
        &self.cal
    }

    /// The last code written to the DAC.
    pub fn last_code(&self) -> i16 {
        self.last_code
    }
}

impl<ASPI, CONVST, BUSY, RESET, AD, DSPI, LDAC, DD> Daq
    for Rig<ASPI, CONVST, BUSY, RESET, AD, DSPI, LDAC, DD>
where
    ASPI: SpiDevice,
    CONVST: OutputPin,
    BUSY: InputPin,
    RESET: OutputPin,
    AD: DelayNs,
    DSPI: SpiDevice,
    LDAC: OutputPin,
    DD: DelayNs,
{
    type Error = RigError;

    /// One simultaneous conversion; displacement and force in mm and kN through the calibration.
    fn read(&mut self) -> Result<Sample, RigError> {
        let codes = self.adc.convert().map_err(RigError::Adc)?;
        let c = self.cal.config();
        let code = |ch: u8| codes.get(ch as usize).copied().unwrap_or(0);
        Ok(Sample {
            disp_mm: c.disp.to_unit(ad7606::code_to_volts(code(c.disp_channel))),
            force_kn: c
                .force
                .to_unit(ad7606::code_to_volts(code(c.force_channel))),
        })
    }
}

impl<ASPI, CONVST, BUSY, RESET, AD, DSPI, LDAC, DD> Actuator
    for Rig<ASPI, CONVST, BUSY, RESET, AD, DSPI, LDAC, DD>
where
    ASPI: SpiDevice,
    CONVST: OutputPin,
    BUSY: InputPin,
    RESET: OutputPin,
    AD: DelayNs,
    DSPI: SpiDevice,
    LDAC: OutputPin,
    DD: DelayNs,
{
    type Error = RigError;

    /// The command in volts through the calibration, to the DAC and latched. A non-finite command is
    /// refused (previous output held); one beyond ±10 V is clipped, written, and reported.
    fn command(&mut self, disp_mm: f64) -> Result<(), RigError> {
        if !disp_mm.is_finite() {
            return Err(RigError::NotFinite);
        }
        let volts = self.cal.config().command.to_volts(disp_mm);
        let (code, clipped) = ad5754::volts_to_code(volts);
        self.dac.write_code(code).map_err(RigError::Dac)?;
        self.last_code = code;
        if clipped {
            Err(RigError::OutOfRange)
        } else {
            Ok(())
        }
    }
}

/// Which level of the E-stop input means "stop".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ActiveLevel {
    /// Stop when the input reads high (fail-safe wiring: a normally-closed contact to ground with a
    /// pull-up; a pressed button or a broken wire reads high).
    High,
    /// Stop when the input reads low.
    Low,
}

/// The hardware E-stop input. A read error counts as a stop (fail-safe).
pub struct EStop<P> {
    pin: P,
    active: ActiveLevel,
}

impl<P: InputPin> EStop<P> {
    /// The input and its active level.
    pub fn new(pin: P, active: ActiveLevel) -> Self {
        Self { pin, active }
    }

    /// Whether the E-stop is asserted (or cannot be read).
    pub fn is_active(&mut self) -> bool {
        let r = match self.active {
            ActiveLevel::High => self.pin.is_high(),
            ActiveLevel::Low => self.pin.is_low(),
        };
        r.unwrap_or(true)
    }
}

/// Poll the E-stop and, if it is asserted, trip the supervisor (it then ramps the command to the safe
/// position). Returns whether it was asserted. Call once per tick before `Controller::tick`.
pub fn check_estop<P: InputPin>(
    estop: &mut EStop<P>,
    supervisor: &mut rths_core::supervisor::Supervisor,
) -> bool {
    let active = estop.is_active();
    if active {
        supervisor.emergency_stop();
    }
    active
}

#[cfg(test)]
mod tests;

//! The abstract hardware of an RTHS test, shaped like `embedded-hal`: an [`Actuator`] that takes a
//! displacement command and a [`Daq`] that returns the measured displacement and force.
//!
//! Units are those of the specimen side of the rig: the actuator stroke in mm and the load-cell force
//! in kN (see [`crate::params::SpecimenScale`] for the prototype mapping). The simulator (`rths-hal-sim`)
//! and the boards implement these traits; the control step only sees them.

/// What kind of failure a HAL error is, independent of the implementation (like `embedded_hal`'s
/// `ErrorKind`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// No new sample arrived in time (sensor dropout, ADC busy stuck).
    Timeout,
    /// A value was NaN or infinite.
    NotFinite,
    /// A value was outside the converter's or the actuator's range (it was clipped).
    OutOfRange,
    /// The bus (SPI, GPIO) reported a fault.
    Bus,
    /// Anything else.
    Other,
}

/// A HAL error: implementations keep their own detail and map it to an [`ErrorKind`].
pub trait Error: core::fmt::Debug {
    /// The generic kind of this error.
    fn kind(&self) -> ErrorKind;
}

impl Error for ErrorKind {
    fn kind(&self) -> ErrorKind {
        *self
    }
}

/// One simultaneous sample of the specimen sensors.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    /// Measured actuator (specimen) displacement, mm (LVDT).
    pub disp_mm: f64,
    /// Measured specimen force, kN (load cell).
    pub force_kn: f64,
}

/// The data-acquisition side: reads the displacement and force sensors.
pub trait Daq {
    /// The implementation's error.
    type Error: Error;
    /// Read the latest simultaneous sample. Called once per controller tick.
    fn read(&mut self) -> Result<Sample, Self::Error>;
}

/// The actuator side: the servo-controller's displacement set-point.
pub trait Actuator {
    /// The implementation's error.
    type Error: Error;
    /// Send a displacement command, mm. Called once per controller tick.
    fn command(&mut self, disp_mm: f64) -> Result<(), Self::Error>;
}

impl<T: Daq + ?Sized> Daq for &mut T {
    type Error = T::Error;
    fn read(&mut self) -> Result<Sample, Self::Error> {
        T::read(self)
    }
}

impl<T: Actuator + ?Sized> Actuator for &mut T {
    type Error = T::Error;
    fn command(&mut self, disp_mm: f64) -> Result<(), Self::Error> {
        T::command(self, disp_mm)
    }
}

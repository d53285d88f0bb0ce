//! The rig's calibration: which ADC channel carries which sensor, volts per engineering unit and
//! offsets of each sensor, and the volts per mm of the servo-controller's command input. Validated at
//! construction ([`ConverterCalibration::new`]); the drivers never hold a scale constant of their own.
//!
//! Conventions (all at the converter pins, after the servo-controller's conditioning):
//! - sensor: `volts = volts_per_unit · value + offset_v`, so `value = (volts − offset_v) / volts_per_unit`;
//! - command: `volts = volts_per_mm · disp_mm + offset_v`.
//!
//! A negative `volts_per_unit` is allowed: it flips a sensor (or the command) whose sign is opposite
//! to the controller's convention (extension positive, tension positive).

/// Full scale of the converters, ±V (AD7606 in its ±10 V range, AD5754R in its ±10 V range).
pub const FULL_SCALE_V: f64 = 10.0;

/// Number of AD7606 channels (V1..V8, numbered 0..8 here).
pub const ADC_CHANNELS: u8 = 8;

/// The linear map between one signal and its voltage.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scale {
    /// Volts per engineering unit (V/mm, V/kN); finite, non-zero.
    pub volts_per_unit: f64,
    /// Volts at zero engineering value (the sensor's or the servo input's offset); finite,
    /// |offset| < full scale.
    pub offset_v: f64,
}

impl Scale {
    /// Engineering value of `volts`.
    pub fn to_unit(&self, volts: f64) -> f64 {
        (volts - self.offset_v) / self.volts_per_unit
    }

    /// Volts for an engineering value.
    pub fn to_volts(&self, value: f64) -> f64 {
        value * self.volts_per_unit + self.offset_v
    }

    /// The engineering value at ±full scale: the smaller |value| the converter can represent.
    pub fn span_units(&self) -> f64 {
        let a = libm_abs((FULL_SCALE_V - self.offset_v) / self.volts_per_unit);
        let b = libm_abs((-FULL_SCALE_V - self.offset_v) / self.volts_per_unit);
        if a < b {
            a
        } else {
            b
        }
    }

    fn check(&self, what: &'static str) -> Result<(), ConverterCalibrationError> {
        if !self.volts_per_unit.is_finite() || self.volts_per_unit == 0.0 {
            return Err(ConverterCalibrationError::Scale(what));
        }
        if !self.offset_v.is_finite() || libm_abs(self.offset_v) >= FULL_SCALE_V {
            return Err(ConverterCalibrationError::Offset(what));
        }
        Ok(())
    }
}

fn libm_abs(x: f64) -> f64 {
    if x < 0.0 {
        -x
    } else {
        x
    }
}

/// What a calibration may get wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConverterCalibrationError {
    /// A volts-per-unit that is zero or not finite (which signal).
    Scale(&'static str),
    /// An offset that is not finite or not within ±full scale (which signal).
    Offset(&'static str),
    /// A channel number outside 0..8.
    Channel(u8),
    /// Displacement and force on the same channel.
    SameChannel,
}

impl core::fmt::Display for ConverterCalibrationError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Scale(w) => write!(f, "{w}: volts per unit must be finite and non-zero"),
            Self::Offset(w) => write!(f, "{w}: offset must be finite and within ±{FULL_SCALE_V} V"),
            Self::Channel(c) => write!(f, "ADC channel {c} does not exist (0..{ADC_CHANNELS})"),
            Self::SameChannel => write!(f, "displacement and force on the same ADC channel"),
        }
    }
}

/// The fields of a calibration, before validation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConverterCalibrationConfig {
    /// AD7606 channel of the displacement (LVDT) signal, 0..8 (0 = V1).
    pub disp_channel: u8,
    /// AD7606 channel of the force (load-cell) signal, 0..8.
    pub force_channel: u8,
    /// Displacement: V/mm and offset.
    pub disp: Scale,
    /// Force: V/kN and offset.
    pub force: Scale,
    /// Servo-controller command input: V/mm and offset.
    pub command: Scale,
}

impl ConverterCalibrationConfig {
    /// The paper's actuator as its servo-controller conditions it, **a default to be replaced by the
    /// lab's own measurement** (see `docs/hardware.md`): displacement ±25.4 mm ↔ ±10 V (0.3937 V/mm)
    /// on V1, force ±31.14 kN ↔ ±10 V (0.3211 V/kN) on V2, command ±25.4 mm ↔ ±10 V, no offsets.
    /// Source of the full scales: the paper's actuator (±25.4 mm stroke, 31.14 kN;
    /// `rths_core::params`), each mapped to the ±10 V of the converters.
    pub fn paper_actuator() -> Self {
        let disp = Scale {
            volts_per_unit: FULL_SCALE_V / 25.4,
            offset_v: 0.0,
        };
        Self {
            disp_channel: 0,
            force_channel: 1,
            disp,
            force: Scale {
                volts_per_unit: FULL_SCALE_V / 31.14,
                offset_v: 0.0,
            },
            command: disp,
        }
    }
}

/// A validated calibration (immutable).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConverterCalibration {
    cfg: ConverterCalibrationConfig,
}

impl ConverterCalibration {
    /// Validate: finite non-zero scales, finite offsets within full scale, channels in 0..8 and
    /// distinct.
    pub fn new(cfg: ConverterCalibrationConfig) -> Result<Self, ConverterCalibrationError> {
        for c in [cfg.disp_channel, cfg.force_channel] {
            if c >= ADC_CHANNELS {
                return Err(ConverterCalibrationError::Channel(c));
            }
        }
        if cfg.disp_channel == cfg.force_channel {
            return Err(ConverterCalibrationError::SameChannel);
        }
        cfg.disp.check("displacement")?;
        cfg.force.check("force")?;
        cfg.command.check("command")?;
        Ok(Self { cfg })
    }

    /// The fields.
    pub fn config(&self) -> &ConverterCalibrationConfig {
        &self.cfg
    }

    /// How many AD7606 channels a read must clock out to reach both sensors (channels come out in
    /// order V1, V2, …).
    pub fn channels_to_read(&self) -> usize {
        let m = if self.cfg.disp_channel > self.cfg.force_channel {
            self.cfg.disp_channel
        } else {
            self.cfg.force_channel
        };
        m as usize + 1
    }
}

#[cfg(test)]
mod tests;

//! The virtual rig: the plant behind a 16-bit DAC, an LVDT and a load cell behind a 16-bit ADC,
//! with sensor noise and fault injection. Implements the core HAL traits.
//!
//! Per controller tick the loop does `rig.read()` → controller → `rig.command(u)` →
//! `rig.advance_tick()`. The sample `read()` returns was taken at the end of the last
//! `advance_tick()`.

use rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;
use rths_core::hal::{Actuator, Daq, Error, ErrorKind, Sample};

use crate::fault::{FaultKind, FaultPlan};
use crate::params::PlantParams;
use crate::plant::{self, Modifiers, PlantState};
use crate::zoh::Zoh;

/// Full-scale voltage of the converters, ±V.
pub const CONVERTER_FULL_SCALE_V: f64 = 10.0;
/// Converter resolution, bits.
pub const CONVERTER_BITS: u32 = 16;

/// An error of the virtual rig.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimError {
    /// No sample this tick (injected dropout).
    Dropout,
    /// The command was NaN or infinite; the previous command is held.
    NotFinite,
    /// The command was beyond the stroke; it was clipped.
    OutOfRange,
}

impl Error for SimError {
    fn kind(&self) -> ErrorKind {
        match self {
            SimError::Dropout => ErrorKind::Timeout,
            SimError::NotFinite => ErrorKind::NotFinite,
            SimError::OutOfRange => ErrorKind::OutOfRange,
        }
    }
}

impl core::fmt::Display for SimError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SimError::Dropout => write!(f, "sensor dropout: no sample"),
            SimError::NotFinite => write!(f, "command is not finite"),
            SimError::OutOfRange => write!(f, "command beyond the stroke (clipped)"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for SimError {}
#[cfg(feature = "std")]
extern crate std;

/// Round `value` to a 16-bit bipolar converter of full scale `±full_scale` (value units ↔ ±10 V).
pub fn quantize(value: f64, full_scale: f64) -> f64 {
    quantize_bits(value, full_scale, CONVERTER_BITS)
}

/// Round `value` to a `bits`-bit bipolar converter of full scale `±full_scale` (2 ≤ `bits` ≤ 31;
/// outside, the value passes unchanged). The vRTHS benchmark's converters have 18 bits.
pub fn quantize_bits(value: f64, full_scale: f64, bits: u32) -> f64 {
    if !(2..=31).contains(&bits) {
        return value;
    }
    let half = f64::from(1u32 << (bits - 1));
    let code = libm::round(value / full_scale * half).clamp(-half, half - 1.0);
    code * full_scale / half
}

/// The simulated test rig.
#[derive(Debug, Clone)]
pub struct VirtualRig {
    params: PlantParams,
    faults: FaultPlan,
    state: PlantState,
    rng: Xoshiro256PlusPlus,
    tick: u64,
    command_mm: f64,
    /// The sample the sensors took at the end of the last tick (before faults).
    fresh: Sample,
    /// The last sample `read()` returned, per channel, for stuck and lost-tick faults.
    last_read: Sample,
    /// The plan holds at least one fault (without, the per-tick fault scans are skipped).
    has_faults: bool,
    /// The exact tick at a faulted stiffness factor, computed when that factor first applies (a
    /// pure function of the parameters and the factor, so `reset()` keeps it).
    zoh_faulted: Option<(f64, Zoh)>,
    /// Ticks taken by the exact linear step since the last reset.
    exact_ticks: u64,
}

impl VirtualRig {
    /// A rig at rest with no faults.
    pub fn new(params: PlantParams) -> Self {
        Self::with_faults(params, FaultPlan::none())
    }

    /// A rig at rest with a fault plan.
    pub fn with_faults(params: PlantParams, faults: FaultPlan) -> Self {
        let mut rig = Self {
            params,
            faults,
            state: PlantState::default(),
            rng: noise_rng(params.seed()),
            tick: 0,
            command_mm: 0.0,
            fresh: Sample::default(),
            last_read: Sample::default(),
            has_faults: faults.iter().next().is_some(),
            zoh_faulted: None,
            exact_ticks: 0,
        };
        rig.reset();
        rig
    }

    /// Back to rest at tick 0, with the noise generator re-seeded (runs reproduce bit for bit).
    pub fn reset(&mut self) {
        self.state.reset();
        self.rng = noise_rng(self.params.seed());
        self.tick = 0;
        self.exact_ticks = 0;
        self.command_mm = 0.0;
        self.fresh = self.sense();
        self.last_read = self.fresh;
    }

    /// The parameters.
    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// The fault plan.
    pub fn faults(&self) -> &FaultPlan {
        &self.faults
    }

    /// Ticks advanced since the last reset.
    pub fn tick(&self) -> u64 {
        self.tick
    }

    /// Ticks since the last reset that the plant advanced by the exact linear step (the others took
    /// RK4 with sub-steps: Bouc–Wen, [`crate::Integration::Rk4`], or near a saturation).
    pub fn exact_ticks(&self) -> u64 {
        self.exact_ticks
    }

    /// The command the servo-controller is holding (after the DAC), mm.
    pub fn held_command_mm(&self) -> f64 {
        self.command_mm
    }

    /// True (noise-free, unquantized) actuator displacement, mm.
    pub fn true_disp_mm(&self) -> f64 {
        self.state.disp_m() * 1e3
    }

    /// True actuator velocity, mm/s.
    pub fn true_vel_mm_s(&self) -> f64 {
        self.state.vel_m_s() * 1e3
    }

    /// True force on the specimen (what the load cell between rod and specimen carries), kN.
    pub fn true_force_kn(&self) -> f64 {
        self.state.force_n() * 1e-3
    }

    /// True restoring force of the specimen alone (without its inertia and damping), kN.
    pub fn true_restoring_force_kn(&self) -> f64 {
        plant::restoring_force_n(&self.params, &self.state, self.modifiers()) * 1e-3
    }

    /// Valve flow as a fraction of its rated flow (1: the valve is fully open).
    pub fn valve_flow_fraction(&self) -> f64 {
        self.state.flow() / self.params.rated_flow()
    }

    fn modifiers(&self) -> Modifiers {
        let mut m = Modifiers::default();
        if !self.has_faults {
            return m;
        }
        for f in self.faults.active(self.tick) {
            match f.kind {
                FaultKind::ValveSaturation(frac) => m.valve_factor *= frac,
                FaultKind::StiffnessChange(k) => m.stiffness_factor *= k,
                _ => {}
            }
        }
        m
    }

    fn lost(&self) -> bool {
        self.has_faults
            && self
                .faults
                .active(self.tick)
                .any(|f| matches!(f.kind, FaultKind::LostTicks))
    }

    /// Move the plant one controller step holding the last command (ZOH), then sample the sensors.
    pub fn advance_tick(&mut self) {
        let m = self.modifiers();
        let zoh = match self.params.zoh.as_ref() {
            Some(z) if m.stiffness_factor == 1.0 => Some(z),
            Some(_) => {
                let factor = m.stiffness_factor;
                if self.zoh_faulted.map(|(f, _)| f) != Some(factor) {
                    self.zoh_faulted = Some((factor, self.params.zoh_at(factor)));
                }
                self.zoh_faulted.as_ref().map(|(_, z)| z)
            }
            None => None,
        };
        if plant::advance(
            &self.params,
            &mut self.state,
            self.command_mm * 1e-3,
            m,
            zoh,
        ) {
            self.exact_ticks += 1;
        }
        self.tick = self.tick.saturating_add(1);
        self.fresh = self.sense();
    }

    /// Sensor readings of the current state: noise, then the 16-bit ADC.
    fn sense(&mut self) -> Sample {
        let s = self.params.sensors();
        let (mut disp, mut force) = (self.true_disp_mm(), self.true_force_kn());
        // The stream serves only the sensor noise: without noise the draws change nothing.
        if s.disp_noise_mm != 0.0 || s.force_noise_kn != 0.0 {
            let nd: f64 = StandardNormal.sample(&mut self.rng);
            let nf: f64 = StandardNormal.sample(&mut self.rng);
            disp += s.disp_noise_mm * nd;
            force += s.force_noise_kn * nf;
        }
        if s.quantize {
            Sample {
                disp_mm: quantize(disp, self.params.stroke_mm()),
                force_kn: quantize(force, self.params.capacity_kn()),
            }
        } else {
            Sample {
                disp_mm: disp,
                force_kn: force,
            }
        }
    }
}

fn noise_rng(seed: u64) -> Xoshiro256PlusPlus {
    // A stream separate from the parameter draw of `RigConfig::build` (same seed).
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    rng.jump();
    rng
}

impl Daq for VirtualRig {
    type Error = SimError;

    fn read(&mut self) -> Result<Sample, SimError> {
        let mut out = self.fresh;
        if self.lost() {
            return Ok(self.last_read);
        }
        // Most plans are empty: skip the scan.
        if self.has_faults {
            for f in self.faults.active(self.tick) {
                match f.kind {
                    FaultKind::Dropout => return Err(SimError::Dropout),
                    FaultKind::Stuck(ch) => {
                        if ch.disp() {
                            out.disp_mm = self.last_read.disp_mm;
                        }
                        if ch.force() {
                            out.force_kn = self.last_read.force_kn;
                        }
                    }
                    FaultKind::NaN(ch) => {
                        if ch.disp() {
                            out.disp_mm = f64::NAN;
                        }
                        if ch.force() {
                            out.force_kn = f64::NAN;
                        }
                    }
                    FaultKind::Spike(ch, m) => {
                        if ch.disp() {
                            out.disp_mm += m;
                        }
                        if ch.force() {
                            out.force_kn += m;
                        }
                    }
                    _ => {}
                }
            }
        }
        // Keep the last finite reading per channel for stuck channels.
        if out.disp_mm.is_finite() {
            self.last_read.disp_mm = out.disp_mm;
        }
        if out.force_kn.is_finite() {
            self.last_read.force_kn = out.force_kn;
        }
        Ok(out)
    }
}

impl Actuator for VirtualRig {
    type Error = SimError;

    /// Through the DAC (16 bits, ±10 V over ±stroke). A non-finite command is refused (the previous
    /// one is held); one beyond the stroke is clipped and reported.
    fn command(&mut self, disp_mm: f64) -> Result<(), SimError> {
        if self.lost() {
            return Ok(());
        }
        if !disp_mm.is_finite() {
            return Err(SimError::NotFinite);
        }
        let stroke = self.params.stroke_mm();
        let clipped = disp_mm.clamp(-stroke, stroke);
        self.command_mm = if self.params.sensors().quantize {
            quantize(clipped, stroke)
        } else {
            clipped
        };
        if clipped == disp_mm {
            Ok(())
        } else {
            Err(SimError::OutOfRange)
        }
    }
}

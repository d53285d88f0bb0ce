//! Physical constants and validated parameters of the prototype structure, the specimen scale and the
//! actuator. This is the one place where numbers with units are defined; everything else refers here.
//!
//! Units: mm, kN, s. Mass is in kN·s²/mm so that `m·a` (mm/s²) is in kN.
//!
//! Sources: Bas, Moustafa, Feil-Seifer, Blankenburg, "Using a Machine Learning Approach for
//! Computational Substructure in Real-Time Hybrid Simulation" (UNR) for the prototype, the actuator and
//! the controller rate; `docs/design.md` §2 and §4 for the derivations noted below.

use libm::sqrt;

/// Standard gravity in mm/s² (CGPM 1901), to convert ground motions recorded in g.
pub const G_MM_S2: f64 = 9806.65;

/// The controller rates a build can choose, Hz: the paper's 2048 Hz real-time controller, and the
/// vRTHS benchmark's 4096 Hz (feature `rate-4096`).
pub const CONTROL_RATES_HZ: [u32; 2] = [2048, 4096];

/// Controller (and hybrid simulation) rate in Hz: 2048, or 4096 with the `rate-4096` feature (a
/// build-time choice: the plant's discretization, the trained models and the boards' tick timers
/// all follow it). Every other rate constant derives from it (Δt, the boards' tick timers, the
/// firmware's 1 s counts, [`PAPER_DELAY_STEPS`]).
pub const CONTROL_RATE_HZ: u32 = if cfg!(feature = "rate-4096") {
    CONTROL_RATES_HZ[1]
} else {
    CONTROL_RATES_HZ[0]
};

/// [`CONTROL_RATE_HZ`] as a float.
pub const CONTROLLER_RATE_HZ: f64 = CONTROL_RATE_HZ as f64;

/// The controller step at `rate_hz`, s.
pub const fn dt_s(rate_hz: u32) -> f64 {
    1.0 / rate_hz as f64
}

/// Controller step in s (1/2048 s ≈ 488 µs; 1/4096 s ≈ 244 µs with `rate-4096`).
pub const DT_S: f64 = dt_s(CONTROL_RATE_HZ);

/// Seismic mass of the one-story prototype, kN·s²/mm (paper).
pub const MASS_KN_S2_PER_MM: f64 = 1.75;

/// Lateral stiffness of the moment frame (analytical part), kN/mm (paper).
pub const FRAME_STIFFNESS_KN_PER_MM: f64 = 176.75;

/// Axial stiffness of the steel brace (experimental part), kN/mm (paper).
pub const BRACE_AXIAL_STIFFNESS_KN_PER_MM: f64 = 1224.1;

/// cos²θ of the brace angle. Back-computed so that the brace's lateral stiffness
/// `k_b·cos²θ = 622.54 kN/mm` and the period is the paper's 0.294 s (θ ≈ 44.51°).
pub const BRACE_COS2_THETA: f64 = 0.50857;

/// Inherent viscous damping ratio of the prototype (paper: 2%).
pub const DAMPING_RATIO: f64 = 0.02;

/// Force scale between prototype and specimen: prototype force = `FORCE_SCALE` × load-cell force.
/// The specimen is a small-scale brace of stiffness `k_b / 1000 = 1.2241 kN/mm` (docs/design.md §4).
pub const FORCE_SCALE: f64 = 1000.0;

/// Displacement scale between prototype brace deformation and actuator stroke (1: full scale).
pub const DISP_SCALE: f64 = 1.0;

/// Actuator stroke, ±mm (paper's actuator: ±1 in).
pub const ACTUATOR_STROKE_MM: f64 = 25.4;

/// Actuator force capacity, kN (paper: 7 kip ≈ 31.14 kN).
pub const ACTUATOR_CAPACITY_KN: f64 = 31.14;

/// Actuator no-load velocity, mm/s (paper).
pub const ACTUATOR_VELOCITY_MM_S: f64 = 338.84;

/// Delay of the paper's actuator loop in controller steps (13.7 ms: 28 steps at 2048 Hz, 56 at
/// 4096 Hz).
pub const PAPER_DELAY_STEPS: usize = 28 * CONTROL_RATE_HZ as usize / CONTROL_RATES_HZ[0] as usize;

/// A parameter that failed validation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamError {
    /// A value was NaN or infinite.
    NotFinite(&'static str),
    /// A value that must be strictly positive was not.
    NotPositive(&'static str),
    /// A value was outside its admissible range.
    OutOfRange(&'static str),
    /// A matrix that must be invertible was singular.
    Singular(&'static str),
}

impl core::fmt::Display for ParamError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ParamError::NotFinite(what) => write!(f, "{what} is not finite"),
            ParamError::NotPositive(what) => write!(f, "{what} must be > 0"),
            ParamError::OutOfRange(what) => write!(f, "{what} is out of range"),
            ParamError::Singular(what) => write!(f, "{what} is singular"),
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for ParamError {}

/// Check that `value` is finite and strictly positive.
pub(crate) fn positive(value: f64, what: &'static str) -> Result<f64, ParamError> {
    if !value.is_finite() {
        Err(ParamError::NotFinite(what))
    } else if value <= 0.0 {
        Err(ParamError::NotPositive(what))
    } else {
        Ok(value)
    }
}

/// The one-bay one-story concentrically braced prototype frame reduced to one DOF (story drift).
///
/// Immutable once validated. Brace kinematics: axial deformation `d = x·cosθ`, axial force `N = k_b·d`,
/// story force `R_e = N·cosθ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Prototype {
    mass: f64,
    frame_k: f64,
    brace_k: f64,
    cos_theta: f64,
    damping_ratio: f64,
}

impl Prototype {
    /// The paper's frame (docs/design.md §2).
    pub fn paper() -> Self {
        Self {
            mass: MASS_KN_S2_PER_MM,
            frame_k: FRAME_STIFFNESS_KN_PER_MM,
            brace_k: BRACE_AXIAL_STIFFNESS_KN_PER_MM,
            cos_theta: sqrt(BRACE_COS2_THETA),
            damping_ratio: DAMPING_RATIO,
        }
    }

    /// A validated prototype: mass kN·s²/mm, frame and brace axial stiffness kN/mm, brace `cos²θ` in
    /// (0, 1], damping ratio in [0, 1).
    pub fn new(
        mass_kn_s2_per_mm: f64,
        frame_k_kn_per_mm: f64,
        brace_k_kn_per_mm: f64,
        cos2_theta: f64,
        damping_ratio: f64,
    ) -> Result<Self, ParamError> {
        let mass = positive(mass_kn_s2_per_mm, "mass")?;
        let frame_k = positive(frame_k_kn_per_mm, "frame stiffness")?;
        let brace_k = positive(brace_k_kn_per_mm, "brace stiffness")?;
        let cos2 = positive(cos2_theta, "cos²θ")?;
        if cos2 > 1.0 {
            return Err(ParamError::OutOfRange("cos²θ"));
        }
        if !damping_ratio.is_finite() {
            return Err(ParamError::NotFinite("damping ratio"));
        }
        if !(0.0..1.0).contains(&damping_ratio) {
            return Err(ParamError::OutOfRange("damping ratio"));
        }
        Ok(Self {
            mass,
            frame_k,
            brace_k,
            cos_theta: sqrt(cos2),
            damping_ratio,
        })
    }

    /// The same frame with the brace stiffness multiplied by `factor` (a softer or stiffer specimen).
    pub fn with_brace_factor(&self, factor: f64) -> Result<Self, ParamError> {
        let brace_k = positive(self.brace_k * factor, "brace stiffness factor")?;
        Ok(Self { brace_k, ..*self })
    }

    /// Seismic mass, kN·s²/mm.
    pub fn mass_kn_s2_per_mm(&self) -> f64 {
        self.mass
    }
    /// Frame lateral stiffness, kN/mm.
    pub fn frame_stiffness_kn_per_mm(&self) -> f64 {
        self.frame_k
    }
    /// Brace axial stiffness, kN/mm.
    pub fn brace_axial_stiffness_kn_per_mm(&self) -> f64 {
        self.brace_k
    }
    /// cos θ of the brace.
    pub fn cos_theta(&self) -> f64 {
        self.cos_theta
    }
    /// Damping ratio.
    pub fn damping_ratio(&self) -> f64 {
        self.damping_ratio
    }
    /// Brace contribution to the lateral stiffness, `k_e = k_b·cos²θ`, kN/mm.
    pub fn brace_lateral_stiffness_kn_per_mm(&self) -> f64 {
        self.brace_k * self.cos_theta * self.cos_theta
    }
    /// Total lateral stiffness `k_a + k_e`, kN/mm.
    pub fn total_stiffness_kn_per_mm(&self) -> f64 {
        self.frame_k + self.brace_lateral_stiffness_kn_per_mm()
    }
    /// Natural circular frequency, rad/s.
    pub fn omega_rad_s(&self) -> f64 {
        sqrt(self.total_stiffness_kn_per_mm() / self.mass)
    }
    /// Natural period, s (paper: 0.294 s).
    pub fn period_s(&self) -> f64 {
        2.0 * core::f64::consts::PI / self.omega_rad_s()
    }
    /// Viscous damping coefficient `c = 2ζmω`, kN·s/mm (1.496 for the paper's frame).
    pub fn damping_kn_s_per_mm(&self) -> f64 {
        2.0 * self.damping_ratio * self.mass * self.omega_rad_s()
    }
    /// Brace axial deformation (= actuator stroke at displacement scale 1) from story drift, mm.
    pub fn brace_disp_mm(&self, story_disp_mm: f64) -> f64 {
        story_disp_mm * self.cos_theta
    }
    /// Story drift from brace axial deformation, mm.
    pub fn story_disp_mm(&self, brace_disp_mm: f64) -> f64 {
        brace_disp_mm / self.cos_theta
    }
    /// Brace axial force of the linear prototype brace at deformation `brace_disp_mm`, kN.
    pub fn brace_force_kn(&self, brace_disp_mm: f64) -> f64 {
        self.brace_k * brace_disp_mm
    }
    /// Story (lateral) force from the brace axial force, kN.
    pub fn story_force_kn(&self, brace_force_kn: f64) -> f64 {
        brace_force_kn * self.cos_theta
    }
}

/// Scale between the prototype brace and the small-scale specimen (docs/design.md §4): displacement scale 1,
/// force scale 1000. The single place where specimen and prototype quantities are converted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpecimenScale {
    disp: f64,
    force: f64,
    // Reciprocals, derived once: the MCU does f64 division in software.
    inv_disp: f64,
    inv_force: f64,
    // Displacement scale exactly 1 (full-scale stroke): no multiplication at all.
    unit_disp: bool,
}

impl Default for SpecimenScale {
    fn default() -> Self {
        Self {
            disp: DISP_SCALE,
            force: FORCE_SCALE,
            inv_disp: 1.0 / DISP_SCALE,
            inv_force: 1.0 / FORCE_SCALE,
            unit_disp: DISP_SCALE == 1.0,
        }
    }
}

impl SpecimenScale {
    /// A validated scale: prototype = `disp_scale` × specimen displacement,
    /// prototype = `force_scale` × specimen force.
    pub fn new(disp_scale: f64, force_scale: f64) -> Result<Self, ParamError> {
        let disp = positive(disp_scale, "displacement scale")?;
        let force = positive(force_scale, "force scale")?;
        Ok(Self {
            disp,
            force,
            inv_disp: 1.0 / disp,
            inv_force: 1.0 / force,
            unit_disp: disp == 1.0,
        })
    }
    /// Actuator (specimen) displacement for a prototype brace deformation, mm.
    pub fn specimen_disp_mm(&self, prototype_brace_disp_mm: f64) -> f64 {
        if self.unit_disp {
            prototype_brace_disp_mm
        } else {
            prototype_brace_disp_mm * self.inv_disp
        }
    }
    /// Prototype brace deformation from a measured specimen displacement, mm.
    pub fn prototype_disp_mm(&self, specimen_disp_mm: f64) -> f64 {
        if self.unit_disp {
            specimen_disp_mm
        } else {
            specimen_disp_mm * self.disp
        }
    }
    /// Prototype brace axial force from a load-cell force, kN.
    pub fn prototype_force_kn(&self, specimen_force_kn: f64) -> f64 {
        specimen_force_kn * self.force
    }
    /// Load-cell force for a prototype brace axial force, kN.
    pub fn specimen_force_kn(&self, prototype_force_kn: f64) -> f64 {
        prototype_force_kn * self.inv_force
    }
    /// The displacement scale: prototype over specimen.
    pub fn disp_scale(&self) -> f64 {
        self.disp
    }
    /// The force scale: prototype over specimen.
    pub fn force_scale(&self) -> f64 {
        self.force
    }
    /// Specimen stiffness that stands for a prototype brace of axial stiffness `brace_k`, kN/mm.
    pub fn specimen_stiffness_kn_per_mm(&self, prototype_brace_k_kn_per_mm: f64) -> f64 {
        prototype_brace_k_kn_per_mm * self.disp / self.force
    }
}

#[cfg(test)]
mod tests;

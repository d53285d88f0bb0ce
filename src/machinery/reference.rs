//! The evaluation's reference: the response of the structure with the specimen a run's plant
//! really has (the paper's frame, its brace scaled, linear or Bouc–Wen), computed from the truth
//! that only the evaluation may know. Studies, the sweep, `rths report`, the fault and soak runs
//! score against it; the controller never sees it.
//!
//! Here too what the studies and training build their runs from: the paper's frame with another
//! brace ([`specimen_prototype`]), a study's plant ([`rig_config`]), and the error of a pure FE
//! analysis ([`AnalysisError`], `rths analyze`'s).

use std::path::PathBuf;

use rths_core::params::{ParamError, Prototype, SpecimenScale, DT_S};
use rths_core::reference::Reference;
use rths_hal_sim::Preset;
use rths_hal_sim::{RigConfig, Specimen};
use serde::Serialize;

/// The reference brace deformation: pure FE of the paper's frame with the brace scaled by `factor`
/// (the frame's damping coefficient unchanged: [`specimen_prototype`]).
pub fn reference_mm(ag_mm_s2: &[f64], factor: f64) -> anyhow::Result<Vec<f64>> {
    let proto = specimen_prototype(factor)?;
    // The brace deformation of `pure_response(.., Method::Chang)`: core's one reference stepper,
    // without the five other histories nobody reads here.
    let ag0 = *ag_mm_s2.first().ok_or(AnalysisError::EmptyMotion)?;
    if let Some(index) = ag_mm_s2.iter().position(|a| !a.is_finite()) {
        return Err(AnalysisError::NonFiniteMotion { index }.into());
    }
    let mut pure = Reference::new(&proto, DT_S, ag0).map_err(AnalysisError::from)?;
    let mut out = Vec::with_capacity(ag_mm_s2.len());
    out.push(proto.brace_disp_mm(0.0));
    out.extend(ag_mm_s2.iter().skip(1).map(|&ag| pure.advance(ag)));
    match out.iter().position(|d| !d.is_finite()) {
        Some(step) => Err(AnalysisError::Diverged { step }.into()),
        None => Ok(out),
    }
}

/// The reference brace deformation for a specimen model: linear → [`reference_mm`]; Bouc–Wen → the
/// frame integrated by Chang's method with the brace force of a Bouc–Wen brace of the same parameters
/// as the virtual specimen (at prototype scale: force × 1000), driven by the displacement path
/// (`dz/dx = (A − |z|ⁿ·(β·sgn(dx·z) + γ))/x_y`, 8 RK4 sub-steps per tick).
pub fn reference_for(
    ag_mm_s2: &[f64],
    specimen: Specimen,
    factor: f64,
) -> anyhow::Result<Vec<f64>> {
    use rths_core::integrator::{Chang, ExplicitIntegrator};
    use rths_core::structure::{LinearStructure, Vector};
    let bw = match specimen {
        Specimen::Linear => return reference_mm(ag_mm_s2, factor),
        Specimen::BoucWen(bw) => bw,
    };
    let proto = specimen_prototype(factor)?;
    let scale = SpecimenScale::default();
    let k_spec = scale.specimen_stiffness_kn_per_mm(proto.brace_axial_stiffness_kn_per_mm());
    let mut ch = Chang::new(LinearStructure::prototype_hybrid(&proto)?, DT_S)?;
    let Some(&ag0) = ag_mm_s2.first() else {
        anyhow::bail!("the ground motion is empty");
    };
    ch.reset(ag0);
    let dz_dx = |z: f64, dx: f64| {
        let sgn = if dx * z > 0.0 {
            1.0
        } else if dx * z < 0.0 {
            -1.0
        } else {
            0.0
        };
        (bw.a - z.abs().powf(bw.n) * (bw.beta * sgn + bw.gamma)) / bw.yield_disp_mm
    };
    const SUB: usize = 8;
    let (mut z, mut d_prev) = (0.0_f64, 0.0_f64);
    let mut out = Vec::with_capacity(ag_mm_s2.len());
    out.push(0.0);
    for &ag in &ag_mm_s2[1..] {
        let d = proto.brace_disp_mm(ch.next_displacement()[0]);
        let h = (d - d_prev) / SUB as f64;
        for _ in 0..SUB {
            let k1 = dz_dx(z, h);
            let k2 = dz_dx(z + 0.5 * h * k1, h);
            let k3 = dz_dx(z + 0.5 * h * k2, h);
            let k4 = dz_dx(z + h * k3, h);
            z += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        d_prev = d;
        let alpha = bw.post_yield_ratio;
        let r_spec = alpha * k_spec * d + (1.0 - alpha) * k_spec * bw.yield_disp_mm * z;
        let n = scale.prototype_force_kn(r_spec);
        ch.advance(ag, &Vector::<1>::new(proto.story_force_kn(n)));
        out.push(d);
    }
    Ok(out)
}

/// What the plant of a run really has (drawn with `uncertainty`, else nominal): the report's `plant`
/// object. Known to the evaluation (the fair reference), never to the controller.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DrawnPlant {
    /// The parameters were drawn from the benchmark's uncertainty.
    pub uncertainty: bool,
    /// The seed of the draw (and of the sensor noise).
    pub seed: u64,
    /// Servo-valve damping term β1 at the benchmark's time scale (the plant's is × r), 1/s.
    pub beta1: f64,
    /// Servo-valve stiffness term β2 at the benchmark's time scale (the plant's is × r²), 1/s².
    pub beta2: f64,
    /// Actuator leakage pole a3 at the benchmark's time scale (the plant's is × r), 1/s.
    pub a3: f64,
    /// The specimen's (initial) stiffness, N/m.
    pub specimen_stiffness_n_per_m: f64,
    /// The effective specimen stiffness factor: the configured F × drawn k / configured k; the
    /// reference is the structure with this brace.
    pub specimen_stiffness_factor: f64,
}

impl DrawnPlant {
    /// Build the plant of `rig` (configured with stiffness factor `factor`) and read what it has.
    pub fn of(rig: &RigConfig, factor: f64) -> anyhow::Result<Self> {
        // The same draw (same seed, same order) at time scale 1 gives the drawn values exactly, at
        // the benchmark's scale where its σ are published (dividing the plant's by r would round).
        let mut unscaled = *rig;
        unscaled.time_scale = 1.0;
        let p = unscaled
            .build()
            .map_err(|e| anyhow::anyhow!("invalid plant configuration: {e}"))?;
        // Without a draw the ratio is exactly 1 (same product), so nominal runs keep F bit for bit.
        let k_ratio = p.specimen_stiffness_n_per_m() / (rig.specimen_stiffness_kn_per_mm * 1.0e6);
        Ok(Self {
            uncertainty: rig.uncertainty,
            seed: rig.seed,
            beta1: p.beta1(),
            beta2: p.beta2(),
            a3: p.a3(),
            specimen_stiffness_n_per_m: p.specimen_stiffness_n_per_m(),
            specimen_stiffness_factor: factor * k_ratio,
        })
    }
}

/// The fair reference of a run on the plant `rig` (configured with specimen stiffness factor
/// `factor`): the structure with the specimen the plant really has, i.e. [`reference_for`] at the
/// effective factor of [`DrawnPlant::of`] (the Bouc–Wen shape is not drawn). Every run whose plant may
/// be drawn takes its reference here, so a drawn specimen is never judged against the nominal one.
/// Returns the reference and the draw (for the report).
pub fn reference_for_rig(
    ag_mm_s2: &[f64],
    rig: &RigConfig,
    factor: f64,
) -> anyhow::Result<(Vec<f64>, DrawnPlant)> {
    let draw = DrawnPlant::of(rig, factor)?;
    let reference = reference_for(ag_mm_s2, rig.specimen, draw.specimen_stiffness_factor)?;
    Ok((reference, draw))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machinery::motion::GroundMotion;
    use crate::studies::analysis::{pure_response, Method};

    #[test]
    fn reference_is_the_brace_deformation_of_the_pure_response_bit_for_bit() {
        let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
        let ag = &ag[..20_000];
        for factor in [0.6, 1.0, 1.4] {
            let proto = specimen_prototype(factor).unwrap();
            let full = pure_response(&proto, ag, DT_S, Method::Chang).unwrap();
            let slim = reference_mm(ag, factor).unwrap();
            assert_eq!(slim.len(), full.brace_disp_mm.len());
            assert!(slim
                .iter()
                .zip(&full.brace_disp_mm)
                .all(|(a, b)| a.to_bits() == b.to_bits()));
        }
        assert!(reference_mm(&[], 1.0).is_err());
        assert!(reference_mm(&[0.0, f64::NAN], 1.0).is_err());
    }
}

/// Why an analysis could not run or its result could not be written.
#[derive(Debug, thiserror::Error)]
pub enum AnalysisError {
    /// No ground-acceleration samples.
    #[error("the ground motion has no samples")]
    EmptyMotion,
    /// A ground-acceleration sample is NaN or infinite.
    #[error("ground acceleration sample {index} is not finite")]
    NonFiniteMotion {
        /// Index of the sample.
        index: usize,
    },
    /// Bad model parameters or time step.
    #[error("model: {0}")]
    Param(#[from] ParamError),
    /// The response blew up (NaN or infinity).
    #[error("the response became non-finite at step {step}")]
    Diverged {
        /// The step.
        step: usize,
    },
    /// The CSV could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
}

/// The paper's frame with its brace (specimen) stiffness scaled by `factor`, the frame's damping
/// coefficient c = 1.496 kN·s/mm unchanged: the damping belongs to the analytical substructure,
/// which does not change when another specimen is installed (the hybrid split computes exactly that
/// structure). [`Prototype::with_brace_factor`] alone would keep the damping *ratio* at 2% instead,
/// i.e. give the frame a damping that depends on the specimen (c ∝ √(k_a + F·k_e): −11% at F = 0.6,
/// +10% at F = 1.4), which no hybrid test of that frame can reproduce.
pub fn specimen_prototype(factor: f64) -> Result<Prototype, ParamError> {
    let paper = Prototype::paper();
    let p = paper.with_brace_factor(factor)?;
    let zeta = paper.damping_kn_s_per_mm() / (2.0 * p.mass_kn_s2_per_mm() * p.omega_rad_s());
    Prototype::new(
        p.mass_kn_s2_per_mm(),
        p.frame_stiffness_kn_per_mm(),
        p.brace_axial_stiffness_kn_per_mm(),
        p.cos_theta() * p.cos_theta(),
        zeta,
    )
}

/// The plant of the study's runs: `preset`, a `specimen` of `stiffness_factor` × the paper's brace at
/// specimen scale, default sensors, `seed`.
pub fn rig_config(
    preset: Preset,
    specimen: Specimen,
    stiffness_factor: f64,
    seed: u64,
) -> RigConfig {
    let mut c = RigConfig::new(preset);
    c.specimen = specimen;
    c.specimen_stiffness_kn_per_mm *= stiffness_factor;
    c.seed = seed;
    c
}

//! The compensation of a structure's hybrid runs: what a lab identifies of its rig before testing a
//! structure's specimen (`rths identify`'s procedure on the virtual plant, or a rig file it wrote),
//! and nothing else. `fe-online-ats` takes the ATS start; `nl-online` takes the lead filter with
//! its online gain-and-delay correction and the identified specimen for the force correction
//! (docs/nonlinear.md, "Scenarios").

use anyhow::Context;
use rths_core::compensator::{LeadAdaptParams, LeadParams};
use rths_files::structure_file::Structure;
use rths_hal_sim::{FaultPlan, Preset};
use serde::Serialize;

use super::scenario::{rig_specimen_factor, structure_rig};
use crate::identify::estimate::SpecimenFit;
use crate::identify::{identify_virtual, IdentifyConfig, RigFile};

/// The force a model is fed in the hybrid loop, corrected to the model's own displacement with the
/// identified specimen (LRX's correction of a rig-trained model, docs/design.md §5.3, at the rig):
/// `F̃ = F_m + k̂·(d̂ − x_m) − m̂·d̂'' − ĉ·d̂'`, d̂ the displacement the rig was to be at, its
/// derivatives by central differences one tick back. The spring term removes the rig's tracking
/// error from the force; the mass and damping terms remove what the rig's specimen has and the
/// structure file's (a spring) does not.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ForceCorrection {
    /// k̂, kN/mm (0: none).
    pub k_kn_per_mm: f64,
    /// ĉ, kN·s/mm.
    pub c_kn_s_per_mm: f64,
    /// m̂, kN·s²/mm.
    pub m_kn_s2_per_mm: f64,
}

impl ForceCorrection {
    /// No correction: the measured force as is.
    pub const NONE: Self = Self {
        k_kn_per_mm: 0.0,
        c_kn_s_per_mm: 0.0,
        m_kn_s2_per_mm: 0.0,
    };

    /// From identified values: refused unless finite and ≥ 0.
    pub fn new(k_kn_per_mm: f64, c_kn_s_per_mm: f64, m_kn_s2_per_mm: f64) -> anyhow::Result<Self> {
        for (what, v) in [
            ("stiffness", k_kn_per_mm),
            ("damping", c_kn_s_per_mm),
            ("mass", m_kn_s2_per_mm),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                anyhow::bail!("the identified specimen {what} {v} is not usable (finite, ≥ 0)");
            }
        }
        Ok(Self {
            k_kn_per_mm,
            c_kn_s_per_mm,
            m_kn_s2_per_mm,
        })
    }

    /// `F̃` from the measured force and displacement and the rig's targets `d = [d̂_k, d̂_{k−1},
    /// d̂_{k−2}]` (mm), at step `dt_s`.
    pub fn force_kn(&self, force_kn: f64, disp_mm: f64, d: [f64; 3], dt_s: f64) -> f64 {
        let accel = (d[0] - 2.0 * d[1] + d[2]) / (dt_s * dt_s);
        let vel = (d[0] - d[2]) / (2.0 * dt_s);
        force_kn + self.k_kn_per_mm * (d[0] - disp_mm)
            - self.m_kn_s2_per_mm * accel
            - self.c_kn_s_per_mm * vel
    }
}

/// The compensation of `nl-online`: the identified lead filter in front of the rig, the force
/// fed to the learned model corrected with the identified specimen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrectedLead {
    /// The lead filter, with its online gain-and-delay correction.
    pub lead: LeadParams,
    /// The force correction.
    pub correction: ForceCorrection,
}

/// What was identified of the rig a structure is tested on: the compensation of its hybrid runs.
#[derive(Debug, Clone, Serialize)]
pub struct RigCompensation {
    /// The structure whose specimen the rig carries.
    pub structure: String,
    /// Where it comes from: `identified` (on the virtual plant, before the runs) or the rig file.
    pub source: String,
    /// The rig's specimen stiffness over the paper's brace ([`rig_specimen_factor`]).
    pub specimen_stiffness_factor: f64,
    /// The identified delay, ms.
    pub delay_ms: f64,
    /// The identified static gain.
    pub gain: f64,
    /// The identified specimen stiffness at the actuator, kN/mm (the force correction's).
    pub specimen_k_kn_per_mm: f64,
    /// The lead filter's compensated residual over the band, %.
    pub lead_residual_pct: f64,
    /// `fe-online-ats`'s ATS start `[a0, a1 (s), a2 (s²)]`.
    pub ats_initial: [f64; 3],
    /// `nl-online`'s lead and force correction.
    #[serde(skip)]
    pub corrected_lead: CorrectedLead,
}

/// The lead's online correction of a rig-identified lead: the time constant `rths train lrx --rig`
/// gives it ([`crate::train::lrx::RIG_LEAD_ADAPT_TICKS`]).
fn adapted(lead: LeadParams) -> anyhow::Result<LeadParams> {
    Ok(lead.with_adaptation(Some(
        LeadAdaptParams::new(crate::train::lrx::RIG_LEAD_ADAPT_TICKS)
            .map_err(|e| anyhow::anyhow!("the lead's online correction: {e:?}"))?,
    )))
}

fn corrected(lead: LeadParams, fit: &SpecimenFit) -> anyhow::Result<CorrectedLead> {
    Ok(CorrectedLead {
        lead: adapted(lead)?,
        correction: ForceCorrection::new(
            fit.stiffness_kn_per_mm,
            fit.damping_kn_s_per_mm,
            fit.mass_kn_s2_per_mm,
        )?,
    })
}

/// Identify the rig `structure` is tested on, as a lab does before its test (`rths identify`: the
/// excitation through the DAQ under the supervisor, nothing of the simulator read): the virtual
/// plant of `preset` with the structure's specimen ([`structure_rig`]) and sensor noise `seed`.
pub fn identify(
    structure: &Structure,
    preset: Preset,
    seed: u64,
) -> anyhow::Result<RigCompensation> {
    let rig = structure_rig(structure, preset, seed);
    let o = identify_virtual(&rig, FaultPlan::none(), &IdentifyConfig::default())
        .with_context(|| format!("identifying the rig of {}", structure.name()))?;
    let id = &o.identification;
    let lead = LeadParams::new(id.lead_weights, id.lead_stride)
        .map_err(|e| anyhow::anyhow!("the identified lead of {}: {e:?}", structure.name()))?;
    Ok(RigCompensation {
        structure: structure.name().to_string(),
        source: "identified".to_string(),
        specimen_stiffness_factor: rig_specimen_factor(structure),
        delay_ms: id.delay_s * 1e3,
        gain: id.model.gain,
        specimen_k_kn_per_mm: id.specimen.stiffness_kn_per_mm,
        lead_residual_pct: id.lead_residual_pct,
        ats_initial: id.ats_initial,
        corrected_lead: corrected(lead, &id.specimen)?,
    })
}

/// The compensation of a rig file for `structure` (checked against the run's plant by the caller).
pub fn from_rig_file(
    structure: &Structure,
    file: &RigFile,
    source: &str,
) -> anyhow::Result<RigCompensation> {
    let k = file.specimen_fit.stiffness_kn_per_mm;
    Ok(RigCompensation {
        structure: structure.name().to_string(),
        source: source.to_string(),
        specimen_stiffness_factor: file.specimen_stiffness_factor,
        delay_ms: file.actuator.delay_ms,
        gain: file.actuator.gain,
        specimen_k_kn_per_mm: k,
        lead_residual_pct: file.quality.lead_residual_pct,
        ats_initial: file.compensation.ats_initial,
        corrected_lead: corrected(file.lead_params()?, &file.specimen_fit)?,
    })
}

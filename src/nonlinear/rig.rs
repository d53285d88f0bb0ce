//! The compensation of a structure's hybrid runs: what a lab identifies of its rig before testing a
//! structure's specimen (`rths identify`'s procedure on the virtual plant, or a rig file it wrote),
//! and nothing else. `fe-online-ats` takes the ATS start; `nl-online` takes the lead filter with
//! its online gain-and-delay correction and the identified specimen stiffness for the force
//! correction (docs/nonlinear.md, "Scenarios").

use anyhow::Context;
use rths_core::compensator::{LeadAdaptParams, LeadParams};
use rths_files::structure_file::Structure;
use rths_hal_sim::{FaultPlan, Preset};
use serde::Serialize;

use super::scenario::{rig_specimen_factor, structure_rig};
use crate::identify::{identify_virtual, IdentifyConfig, RigFile};

/// The compensation of `nl-online`: the learned model is fed the measured force corrected to its
/// own displacement, `F̃ = F_m + k̂·(d̂ − x_m)` (LRX's force correction, docs/design.md §5.3, at the
/// rig), and its target goes through the lead filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CorrectedLead {
    /// The lead filter, with its online gain-and-delay correction.
    pub lead: LeadParams,
    /// The force correction's stiffness at the rig, kN/mm (the identified specimen's; 0: the
    /// measured force as is).
    pub k_corr_kn_per_mm: f64,
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

fn corrected(lead: LeadParams, k_kn_per_mm: f64) -> anyhow::Result<CorrectedLead> {
    if !(k_kn_per_mm.is_finite() && k_kn_per_mm >= 0.0) {
        anyhow::bail!("the identified specimen stiffness {k_kn_per_mm} kN/mm is not usable");
    }
    Ok(CorrectedLead {
        lead: adapted(lead)?,
        k_corr_kn_per_mm: k_kn_per_mm,
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
        corrected_lead: corrected(lead, id.specimen.stiffness_kn_per_mm)?,
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
        corrected_lead: corrected(file.lead_params()?, k)?,
    })
}

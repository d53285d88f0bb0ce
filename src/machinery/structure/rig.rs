//! The rig of a structure's hybrid runs: the virtual plant and specimen a structure is tested on
//! ([`structure_rig`], [`is_paper_frame`]), and its compensation, what a lab identifies of its rig
//! before testing a structure's specimen (`rths identify`'s procedure on the virtual plant, or a
//! rig file it wrote), and nothing else. `fe-online-ats` takes the ATS start; `nl-online` takes the lead filter with
//! its online gain-and-delay correction and the identified specimen for the force correction
//! (docs/nonlinear.md, "Scenarios").

use anyhow::Context;
use rths_core::compensator::{LeadAdaptParams, LeadParams};
use rths_core::params::{Prototype, BRACE_AXIAL_STIFFNESS_KN_PER_MM, DT_S};
use rths_files::structure_file::Structure;
use rths_hal_sim::{FaultPlan, Preset, RigConfig, Specimen};
use serde::Serialize;

use crate::machinery::identify::estimate::SpecimenFit;
use crate::machinery::identify::{identify_virtual, IdentifyConfig, RigFile};

/// The force a model is fed in the hybrid loop, corrected to the model's own displacement with the
/// identified specimen: a parameter of the core controller (LRX's correction of a rig-trained
/// model, docs/design.md §5.3, at the rig).
pub use rths_core::control::ForceCorrection;

/// Relative tolerance on the paper frame's parameters for [`is_paper_frame`]: the shipped file
/// gives them to 9 significant digits.
pub const PAPER_FRAME_TOLERANCE: f64 = 1e-9;

/// The rig's specimen stiffness over the paper's brace for a structure: 1 for the paper's frame
/// (its brace); along the DOF (cos θ = 1) the structure's lateral spring at force scale 1000. The
/// same at every length scale (the structure scenarios' `LengthScale`).
pub fn rig_specimen_factor(structure: &Structure) -> f64 {
    if is_paper_frame(structure) {
        1.0
    } else {
        structure.specimen().1 / BRACE_AXIAL_STIFFNESS_KN_PER_MM
    }
}

/// The virtual plant a structure is tested on: `preset` with the structure's specimen at specimen
/// scale ([`rig_specimen_factor`]), sensor noise `seed`.
pub fn structure_rig(structure: &Structure, preset: Preset, seed: u64) -> RigConfig {
    crate::machinery::reference::rig_config(
        preset,
        Specimen::Linear,
        rig_specimen_factor(structure),
        seed,
    )
}

/// Is `s` the paper's frame (one DOF, the prototype's mass, stiffnesses and damping within
/// [`PAPER_FRAME_TOLERANCE`], a massless undamped specimen)? Such a file is tested with the paper's
/// brace, and a linear one *is* `rths simulate` without `--structure`.
pub fn is_paper_frame(s: &Structure) -> bool {
    let p = Prototype::paper();
    let close = |a: f64, b: f64| (a - b).abs() <= PAPER_FRAME_TOLERANCE * b.abs();
    let (m_e, k_e, c_e) = s.specimen();
    s.dofs() == 1
        && s.specimen_dof() == 0
        && m_e == 0.0
        && c_e == 0.0
        && close(s.mass()[(0, 0)], p.mass_kn_s2_per_mm())
        && close(s.stiffness()[(0, 0)], p.total_stiffness_kn_per_mm())
        && close(k_e, p.brace_lateral_stiffness_kn_per_mm())
        && close(s.damping()[(0, 0)], p.damping_kn_s_per_mm())
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
/// gives it ([`crate::machinery::train::lrx::RIG_LEAD_ADAPT_TICKS`]).
fn adapted(lead: LeadParams) -> anyhow::Result<LeadParams> {
    Ok(lead.with_adaptation(Some(
        LeadAdaptParams::new(crate::machinery::train::lrx::RIG_LEAD_ADAPT_TICKS)
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
            DT_S,
        )
        .map_err(|e| anyhow::anyhow!("the identified specimen is not usable: {e}"))?,
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
    identify_rig(structure.name(), &rig, rig_specimen_factor(structure))
}

/// Identify the virtual plant `rig` (its specimen stiffness factor `factor`) that structure
/// `name`'s specimen is on, as [`identify`] does; `rig` may be a draw of the uncertainty (the
/// lab identifies the rig it has).
pub fn identify_rig(name: &str, rig: &RigConfig, factor: f64) -> anyhow::Result<RigCompensation> {
    let o = identify_virtual(rig, FaultPlan::none(), &IdentifyConfig::default())
        .with_context(|| format!("identifying the rig of {name}"))?;
    let id = &o.identification;
    let lead = LeadParams::new(id.lead_weights, id.lead_stride)
        .map_err(|e| anyhow::anyhow!("the identified lead of {name}: {e:?}"))?;
    Ok(RigCompensation {
        structure: name.to_string(),
        source: "identified".to_string(),
        specimen_stiffness_factor: factor,
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
    from_rig_file_named(structure.name(), file, source)
}

/// [`from_rig_file`] for structure `name` (any structure file, an imported one too).
pub fn from_rig_file_named(
    name: &str,
    file: &RigFile,
    source: &str,
) -> anyhow::Result<RigCompensation> {
    let k = file.specimen_fit.stiffness_kn_per_mm;
    Ok(RigCompensation {
        structure: name.to_string(),
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

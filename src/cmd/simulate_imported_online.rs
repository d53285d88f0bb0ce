//! `rths simulate --structure S.json --scenario meta-online|fe-online-ats` for an imported
//! structure: its analytical part (the reduced model, or the host FE by operator splitting) in the
//! hybrid loop on the virtual rig ([`crate::studies::imported_hybrid`]), scored against the whole
//! model with the rig's true specimen.

use std::path::Path;

use anyhow::Context;
use rths_core::compensator::{Compensator, Lead};
use rths_core::control::{Analytical, ForceCorrection, StructureHost, StructureReduced};
use rths_core::params::DT_S;
use rths_hal_sim::Preset;
use serde::Serialize;

use crate::cmd::plant::{PresetArg, SpecimenArg};
use crate::cmd::simulate_args::Args;
use crate::machinery::identify::rig_file::VIRTUAL_BOARD;
use crate::machinery::identify::RigFile;
use crate::machinery::imported::reduced::ReducedModelFile;
use crate::machinery::imported::split::{self, OperatorSplitting};
use crate::machinery::imported::ImportedStructure;
use crate::machinery::reference::DrawnPlant;
use crate::machinery::structure::rig::{self, RigCompensation};
use crate::studies::imported_hybrid::{self as hybrid, Compensation, OnlineScore};
use crate::studies::nonlinear::scenario::{paper_ats, SimScenario};
use crate::studies::scenario::ScenarioId;

/// The JSON of an imported structure's hybrid run.
#[derive(Debug, Serialize)]
struct OnlineJson {
    structure: String,
    scenario: String,
    motion: String,
    preset: String,
    seed: u64,
    dofs: usize,
    mass_dofs: usize,
    steps: usize,
    dt_s: f64,
    /// What the plant really had (evaluation only).
    plant: DrawnPlant,
    /// What was identified of the rig (the rig file's, or identified before the run; `null`:
    /// `fe-online-ats` without a rig file, the paper's ATS start).
    compensation: Option<RigCompensation>,
    /// `fe-online-ats`: the specimen stiffness in the host FE's `K̂` (the lab's estimate), kN/mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    specimen_estimate_kn_per_mm: Option<f64>,
    /// `fe-online-ats`: the low-pass cutoff of the measured force's departure from the estimate
    /// (the structure's fundamental frequency, at most 2 Hz), Hz.
    #[serde(skip_serializing_if = "Option::is_none")]
    departure_cutoff_hz: Option<f64>,
    /// `fe-online-ats`: the host FE's mean wall time per controller tick, s (this host).
    #[serde(skip_serializing_if = "Option::is_none")]
    fe_s_per_step: Option<f64>,
    /// The reference's specimen stiffness (the plant's, at the prototype's scale), kN/mm.
    true_specimen_k_kn_per_mm: f64,
    /// The nominal specimen (the imported `--specimen-stiffness`), kN/mm.
    nominal_specimen_k_kn_per_mm: f64,
    /// The figures.
    score: OnlineScore,
}

/// Refuse the flags a hybrid run of an imported structure does not take.
fn refuse_flags(args: &Args) -> anyhow::Result<()> {
    let refuse = |flag: &str, why: &str| {
        anyhow::anyhow!("{flag} does not apply to {}: {why}", args.scenario)
    };
    if args.drift != 0.0 {
        return Err(refuse(
            "--drift",
            "the imported structure's runs have no drift study",
        ));
    }
    if args.length_scale != 1.0 {
        return Err(refuse(
            "--length-scale",
            "the rig carries the structure's own specimen",
        ));
    }
    if args.specimen_stiffness_factor != 1.0 {
        return Err(refuse(
            "--specimen-stiffness-factor",
            "the specimen is the imported --specimen-stiffness (--uncertainty draws another)",
        ));
    }
    if !matches!(args.specimen, SpecimenArg::Linear) {
        return Err(refuse(
            "--specimen bouc-wen",
            "the imported model is linear",
        ));
    }
    Ok(())
}

/// The rig file's compensation for `s`, checked against the run's plant (`None` without
/// `--rig`).
fn rig_file_compensation(
    args: &Args,
    s: &ImportedStructure,
    preset: Preset,
    rig_config: &rths_hal_sim::RigConfig,
    factor: f64,
) -> anyhow::Result<Option<RigCompensation>> {
    let Some(p) = &args.rig else {
        return Ok(None);
    };
    let file = RigFile::load(p).with_context(|| format!("rig file {}", p.display()))?;
    file.check(preset.name(), VIRTUAL_BOARD)
        .with_context(|| format!("rig file {} refused", p.display()))?;
    file.check_plant(rig_config, factor)
        .with_context(|| format!("rig file {} refused", p.display()))?;
    Ok(Some(rig::from_rig_file_named(
        s.name(),
        &file,
        &p.display().to_string(),
    )?))
}

/// Run `meta-online` or `fe-online-ats` on the imported structure `s` (from `path`) under `ag`
/// (at `DT_S`).
pub fn run(
    args: &Args,
    path: &Path,
    s: &ImportedStructure,
    ag_mm_s2: &[f64],
    motion_label: &str,
) -> anyhow::Result<()> {
    refuse_flags(args)?;
    let sc = args.scenario;
    let preset = match args.preset {
        PresetArg::Benchmark => Preset::Benchmark,
        PresetArg::UnrCompact => Preset::UnrCompact,
    };
    let (rig_config, factor) = hybrid::rig_of(preset, args.seed, args.uncertainty);
    let scale = hybrid::specimen_scale(s)?;
    let from_file = rig_file_compensation(args, s, preset, &rig_config, factor)?;
    let mut departure_cutoff_hz = None;
    let (analytical, columns, compensation, comp, estimate, timer) = match sc {
        SimScenario::MetaOnline => {
            let Some(m) = &args.model else {
                anyhow::bail!(
                    "meta-online needs the structure's reduced model: --model M.json from `rths \
                     train meta --structure {}`",
                    path.display()
                );
            };
            let file = ReducedModelFile::load(m)
                .with_context(|| format!("reduced model file {}", m.display()))?;
            let params = crate::machinery::imported::reduced::hybrid_params(&file, s, DT_S)
                .with_context(|| format!("reduced model file {}", m.display()))?;
            // The compensation: the rig file's, else the rig identified first on this virtual
            // plant (`rths identify`'s procedure: what a lab does before testing).
            let comp = match from_file {
                Some(c) => c,
                None => rig::identify_rig(s.name(), &rig_config, factor)?,
            };
            let c = comp.corrected_lead;
            (
                Analytical::StructureReduced(StructureReduced::new(params)),
                file.outputs.clone(),
                Compensation {
                    compensator: Compensator::Lead(Lead::new(c.lead)),
                    correction: c.correction,
                },
                Some(comp),
                None,
                None,
            )
        }
        SimScenario::Study(ScenarioId::FeOnlineAts) => {
            if let Some(m) = &args.model {
                anyhow::bail!(
                    "--model {} does not apply to fe-online-ats: its analytical part is the host \
                     FE of the whole model",
                    m.display()
                );
            }
            // The lab's estimate of its specimen: the rig file's identified one at the
            // structure's scale, else the imported --specimen-stiffness; never the drawn one.
            let estimate = from_file
                .as_ref()
                .map_or(s.specimen_stiffness_kn_per_mm(), |c| {
                    c.specimen_k_kn_per_mm * scale.force_scale() / scale.disp_scale()
                });
            // The departure holds the load cell's noise and the rig's inertia and tracking error;
            // loading the model with it as is, the ATS amplified it into a 76 Hz oscillation
            // that tripped every run (docs/opensees.md): it is low-passed at the fundamental,
            // at most 2 Hz.
            let cutoff = split::departure_cutoff_hz(s, estimate)
                .with_context(|| format!("the fundamental frequency of {}", path.display()))?;
            let part = OperatorSplitting::new(s, estimate, DT_S)
                .and_then(|p| p.with_departure_cutoff_hz(cutoff))
                .with_context(|| format!("the host FE of {}", path.display()))?;
            departure_cutoff_hz = Some(cutoff);
            let timer = part.timer();
            // The shear structures' fe-online-ats: the paper's ATS (the rig file's start); the
            // measured force corrected with the rig file's identified specimen, as meta-online
            // corrects it (without a rig file: as measured).
            let compensator = paper_ats(from_file.as_ref().map(|c| c.ats_initial))?;
            (
                Analytical::StructureHost(StructureHost::new(Box::new(part))),
                s.outputs().iter().map(|o| o.column()).collect(),
                Compensation {
                    compensator,
                    correction: from_file
                        .as_ref()
                        .map_or(ForceCorrection::NONE, |c| c.corrected_lead.correction),
                },
                from_file,
                Some(estimate),
                Some(timer),
            )
        }
        _ => anyhow::bail!("{sc} is not a hybrid scenario of an imported structure"),
    };
    let (run, stop) = hybrid::run_online(
        scale,
        analytical,
        compensation,
        &rig_config,
        ag_mm_s2,
        columns,
    )?;
    let (reference, plant) = hybrid::reference(s, &rig_config, factor, ag_mm_s2)
        .with_context(|| format!("the reference of {}", path.display()))?;
    let score = hybrid::score(&sc.to_string(), &run, &reference, stop);
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let csv = dir.join("history.csv");
        run.write_csv(&csv)
            .with_context(|| format!("writing {}", csv.display()))?;
    }
    let json = OnlineJson {
        structure: s.name().to_string(),
        scenario: sc.to_string(),
        motion: motion_label.to_string(),
        preset: preset.name().to_string(),
        seed: args.seed,
        dofs: s.equations().len(),
        mass_dofs: s.mass_dofs(),
        steps: ag_mm_s2.len().saturating_sub(1),
        dt_s: DT_S,
        true_specimen_k_kn_per_mm: s.specimen_stiffness_kn_per_mm()
            * plant.specimen_stiffness_factor
            / factor,
        nominal_specimen_k_kn_per_mm: s.specimen_stiffness_kn_per_mm(),
        plant,
        compensation: comp,
        specimen_estimate_kn_per_mm: estimate,
        departure_cutoff_hz,
        fe_s_per_step: timer.and_then(|t| t.s_per_step()),
        score,
    };
    if args.json {
        crate::outln!("{}", serde_json::to_string(&json)?);
        return Ok(());
    }
    print(&json);
    if let Some(dir) = &args.out {
        crate::outln!("wrote {}", dir.join("history.csv").display());
    }
    Ok(())
}

fn print(j: &OnlineJson) {
    let o = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.4}"));
    crate::outln!(
        "scenario            {} ({}, imported structure {}: {} DOFs, {} with mass, {}, seed {})",
        j.scenario,
        j.motion,
        j.structure,
        j.dofs,
        j.mass_dofs,
        j.preset,
        j.seed
    );
    crate::outln!(
        "plant               {}: specimen {:.3} kN/mm at the prototype's scale (nominal {:.3})",
        if j.plant.uncertainty {
            format!("drawn with seed {}", j.plant.seed)
        } else {
            "nominal".to_string()
        },
        j.true_specimen_k_kn_per_mm,
        j.nominal_specimen_k_kn_per_mm
    );
    match &j.compensation {
        Some(c) => crate::outln!(
            "compensation        {}: delay {:.2} ms, gain {:.4}, lead residual {:.1} %, specimen {:.5} kN/mm at the rig",
            c.source,
            c.delay_ms,
            c.gain,
            c.lead_residual_pct,
            c.specimen_k_kn_per_mm
        ),
        None => crate::outln!("compensation        the paper's ATS start (no rig file)"),
    }
    if let Some(k) = j.specimen_estimate_kn_per_mm {
        crate::outln!(
            "host FE             operator splitting, specimen estimate {k:.3} kN/mm in K̂, its departure low-passed at {:.3} Hz{}",
            j.departure_cutoff_hz.unwrap_or(f64::NAN),
            j.fe_s_per_step
                .map_or(String::new(), |t| format!(", {:.1} µs per step", t * 1e6))
        );
    }
    let r = &j.score.report;
    match (&r.stop_reason, r.stop_time_s) {
        (Some(why), Some(t)) => {
            crate::outln!("stable              no: stopped at {t:.2} s ({why})")
        }
        _ => crate::outln!("stable              yes"),
    }
    crate::outln!(
        "interface           NRMSE target {} %, measured {} %, model {} %",
        o(r.nrmse_pct),
        o(r.nrmse_measured_pct),
        o(j.score.interface_model_nrmse_pct)
    );
    crate::outln!(
        "J1-J5               J1 {} ms, J2 {} %, J3 {} %, J4 {} %, J5 {} %",
        o(r.j1_ms),
        o(r.j2_pct),
        o(r.j3_pct),
        o(r.j4_pct),
        o(r.j5_pct)
    );
    for out in &j.score.outputs {
        crate::outln!(
            "{:<19} NRMSE {} %, std error (J4's form) {} %, peak error (J5's form) {} %",
            out.column,
            o(out.nrmse_pct),
            o(out.std_error_pct),
            o(out.peak_error_pct)
        );
    }
}

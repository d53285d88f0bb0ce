//! `rths simulate --structure S.json --scenario meta-online` for an imported structure: its
//! analytical part in the hybrid loop on the virtual rig ([`crate::studies::imported_hybrid`]), scored
//! against the whole model with the rig's true specimen.

use std::path::Path;

use anyhow::Context;
use rths_core::compensator::{Compensator, Lead};
use rths_core::control::{Analytical, StructureReduced};
use rths_core::params::DT_S;
use rths_hal_sim::Preset;
use serde::Serialize;

use crate::cmd::plant::{PresetArg, SpecimenArg};
use crate::cmd::simulate_args::Args;
use crate::machinery::identify::rig_file::VIRTUAL_BOARD;
use crate::machinery::identify::RigFile;
use crate::machinery::imported::reduced::ReducedModelFile;
use crate::machinery::imported::ImportedStructure;
use crate::machinery::reference::DrawnPlant;
use crate::machinery::structure::rig::{self, RigCompensation};
use crate::studies::imported_hybrid::{self as hybrid, Compensation, OnlineScore, ReducedReadOut};
use crate::studies::nonlinear::scenario::SimScenario;

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
    /// The compensation the controller was given (identified, or the rig file's).
    compensation: RigCompensation,
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

/// Run `meta-online` on the imported structure `s` (from `path`) under `ag` (at `DT_S`).
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
    let (analytical, columns) = match sc {
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
            (
                Analytical::StructureReduced(StructureReduced::new(params)),
                file.outputs.clone(),
            )
        }
        _ => anyhow::bail!("{sc} is not a hybrid scenario of an imported structure"),
    };
    let (rig_config, factor) = hybrid::rig_of(preset, args.seed, args.uncertainty);
    // The compensation: the rig file's, else the rig identified first on this virtual plant
    // (`rths identify`'s procedure: what a lab does before testing).
    let comp = match &args.rig {
        Some(p) => {
            let file = RigFile::load(p).with_context(|| format!("rig file {}", p.display()))?;
            file.check(preset.name(), VIRTUAL_BOARD)
                .with_context(|| format!("rig file {} refused", p.display()))?;
            file.check_plant(&rig_config, factor)
                .with_context(|| format!("rig file {} refused", p.display()))?;
            rig::from_rig_file_named(s.name(), &file, &p.display().to_string())?
        }
        None => rig::identify_rig(s.name(), &rig_config, factor)?,
    };
    let c = comp.corrected_lead;
    let (run, stop) = hybrid::run_online(
        hybrid::specimen_scale(s)?,
        analytical,
        Compensation {
            compensator: Compensator::Lead(Lead::new(c.lead)),
            correction: c.correction,
        },
        &rig_config,
        ag_mm_s2,
        columns,
        &ReducedReadOut,
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
    let c = &j.compensation;
    crate::outln!(
        "compensation        {}: delay {:.2} ms, gain {:.4}, lead residual {:.1} %, specimen {:.5} kN/mm at the rig",
        c.source,
        c.delay_ms,
        c.gain,
        c.lead_residual_pct,
        c.specimen_k_kn_per_mm
    );
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

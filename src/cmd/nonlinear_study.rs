//! `rths nonlinear-study`: the scoring study of the nonlinear scenarios (docs/nonlinear.md).

use std::path::PathBuf;

use anyhow::Context;
use rths_files::structure_file::Structure;
use rths_hal_sim::Preset;

use crate::cmd::plant::PresetArg;
use crate::nonlinear::study::{self, StudyConfig, RECORDS, TARGET_DUCTILITIES};
use crate::scenario::ScenarioId;

/// The shipped yielding structures, scored by default.
const SHIPPED: [(&str, &str); 2] = [
    (
        "data/structures/paper-frame-yielding.json",
        include_str!("../../data/structures/paper-frame-yielding.json"),
    ),
    (
        "data/structures/shear3-yielding.json",
        include_str!("../../data/structures/shear3-yielding.json"),
    ),
];

/// Arguments of `rths nonlinear-study`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Structure files with yielding stories (repeatable). Default: the shipped
    /// `data/structures/paper-frame-yielding.json` and `shear3-yielding.json`.
    #[arg(long, value_name = "FILE.json")]
    pub structure: Vec<PathBuf>,
    /// Scoring records (repeatable; embedded names, or `morgan` for the vRTHS benchmark's Morgan
    /// Hill). Default: el-centro, kobe, morgan.
    #[arg(long, value_name = "NAME")]
    pub record: Vec<String>,
    /// Peak ductilities of the intensities (repeatable). Default: 0.8, 2, 4.5.
    #[arg(long, value_name = "MU")]
    pub ductility: Vec<f64>,
    /// Plant preset of the hybrid runs.
    #[arg(long, value_enum, default_value = "unr-compact")]
    pub preset: PresetArg,
    /// Seed of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write `nonlinear-study.json` and `nonlinear-study.md` here.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print the study as one JSON object on stdout and nothing else.
    #[arg(long)]
    pub json: bool,
}

/// Run `rths nonlinear-study`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let structures = if args.structure.is_empty() {
        SHIPPED
            .iter()
            .map(|(p, t)| Structure::from_json(t).with_context(|| format!("shipped {p}")))
            .collect::<anyhow::Result<Vec<_>>>()?
    } else {
        args.structure
            .iter()
            .map(|p| Structure::load(p).with_context(|| format!("structure file {}", p.display())))
            .collect::<anyhow::Result<Vec<_>>>()?
    };
    for s in &structures {
        if s.story_laws().is_none() {
            anyhow::bail!(
                "structure {} is linear (no hysteresis section): the study scores yielding \
                 structures",
                s.name()
            );
        }
    }
    if let Some(mu) = args
        .ductility
        .iter()
        .find(|m| !(m.is_finite() && **m > 0.0))
    {
        anyhow::bail!("--ductility must be a positive number, got {mu}");
    }
    let records = if args.record.is_empty() {
        RECORDS.iter().map(|r| r.to_string()).collect()
    } else {
        args.record.clone()
    };
    for r in &records {
        study::record(r)?;
    }
    let preset = match args.preset {
        PresetArg::Benchmark => Preset::Benchmark,
        PresetArg::UnrCompact => Preset::UnrCompact,
    };
    let lr = crate::cmd::simulate::study_models(None, ScenarioId::LrOnline, preset, None)?;
    let lrx = crate::cmd::simulate::study_models(None, ScenarioId::LrxOnline, preset, None)?;
    let no_model = |_: &Structure| Ok(None);
    let cfg = StudyConfig {
        structures,
        models: &no_model,
        lr: lr.lr,
        lrx: lrx.lrx,
        delay_steps: lr.delay,
        lead: Some(crate::cmd::simulate::shipped_lrx_lead()?),
        preset,
        seed: args.seed,
        records,
        ductilities: if args.ductility.is_empty() {
            TARGET_DUCTILITIES.to_vec()
        } else {
            args.ductility.clone()
        },
    };
    let report = study::run(&cfg)?;
    let md = study::markdown(&report);
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let j = dir.join("nonlinear-study.json");
        std::fs::write(&j, serde_json::to_string_pretty(&report)?)
            .with_context(|| format!("writing {}", j.display()))?;
        let m = dir.join("nonlinear-study.md");
        std::fs::write(&m, &md).with_context(|| format!("writing {}", m.display()))?;
        if !args.json {
            println!("wrote {}", j.display());
            println!("wrote {}", m.display());
        }
    }
    if args.json {
        println!("{}", serde_json::to_string(&report)?);
    } else {
        print!("{md}");
    }
    Ok(())
}

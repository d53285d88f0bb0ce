//! `rths nonlinear-study`: the scoring study of the nonlinear scenarios (docs/nonlinear.md).

use std::path::PathBuf;

use anyhow::Context;
use rths_core::control::Analytical;
use rths_files::structure_file::Structure;
use rths_hal_sim::Preset;

use crate::cmd::plant::PresetArg;
use crate::machinery::structure::model;
use crate::studies::nonlinear::study::{self, NonlinearStudyConfig, RECORDS, TARGET_DUCTILITIES};
use crate::studies::scenario::ScenarioId;
use rths_files::nl_model_file::NlModelFile;

/// The shipped yielding structures, scored by default.
const SHIPPED: [(&str, &str); 3] = [
    (
        "data/structures/paper-frame-yielding.json",
        include_str!("../../data/structures/paper-frame-yielding.json"),
    ),
    (
        "data/structures/shear3-yielding.json",
        include_str!("../../data/structures/shear3-yielding.json"),
    ),
    (
        "data/structures/shear8-yielding.json",
        include_str!("../../data/structures/shear8-yielding.json"),
    ),
];

/// Arguments of `rths nonlinear-study`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Structure files with yielding stories (repeatable). Default: the shipped
    /// `data/structures/paper-frame-yielding.json`, `shear3-yielding.json` and
    /// `shear8-yielding.json`.
    #[arg(long, value_name = "FILE.json")]
    pub structure: Vec<PathBuf>,
    /// Learned models (`rths train nonlinear`) for nl-pure / nl-online (repeatable), each for the
    /// structure it names. Default: the shipped `data/models/nl-S.json` of each structure S,
    /// where there is one.
    #[arg(long, value_name = "M.json")]
    pub model: Vec<PathBuf>,
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
    if let Some(dir) = &args.out {
        crate::machinery::output::writable_dir(dir)?;
    }
    // Each structure with its file's text (a learned model is checked against its checksum).
    let texts: Vec<(String, String)> = if args.structure.is_empty() {
        SHIPPED
            .iter()
            .map(|(p, t)| (p.to_string(), t.to_string()))
            .collect()
    } else {
        args.structure
            .iter()
            .map(|p| {
                let t = std::fs::read_to_string(p)
                    .with_context(|| format!("reading structure file {}", p.display()))?;
                Ok((p.display().to_string(), t))
            })
            .collect::<anyhow::Result<Vec<_>>>()?
    };
    let structures = texts
        .iter()
        .map(|(p, t)| Structure::from_json(t).with_context(|| format!("structure file {p}")))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let files = args
        .model
        .iter()
        .map(|p| {
            NlModelFile::load(p)
                .with_context(|| format!("model {}", p.display()))
                .map(|f| (p.clone(), f))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    for (p, f) in &files {
        if !structures.iter().any(|s| s.name() == f.structure.name) {
            anyhow::bail!(
                "model {} was trained for structure {}, which is not in this study",
                p.display(),
                f.structure.name
            );
        }
    }
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
        anyhow::bail!(
            "--ductility must be a positive number, got {}",
            rths_files::readable(*mu)
        );
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
    let text_of: Vec<(String, &str)> = structures
        .iter()
        .zip(&texts)
        .map(|(s, (_, t))| (s.name().to_string(), t.as_str()))
        .collect();
    // A given model for the structure, else the shipped one, else none (its rows are skipped
    // with the reason); a model for another version of the structure is refused.
    let models = |s: &Structure| -> anyhow::Result<Option<Analytical>> {
        let text = text_of
            .iter()
            .find(|(n, _)| n == s.name())
            .map(|(_, t)| *t)
            .unwrap_or_default();
        if let Some((p, f)) = files.iter().find(|(_, f)| f.structure.name == s.name()) {
            let m = model::learned_model(f, text)
                .with_context(|| format!("model {} refused", p.display()))?;
            return Ok(Some(Analytical::StructureModal(m)));
        }
        if model::SHIPPED.iter().any(|(n, _)| *n == s.name()) {
            return Ok(Some(model::for_structure(None, s.name(), text)?));
        }
        Ok(None)
    };
    let cfg = NonlinearStudyConfig {
        structures,
        models: &models,
        lr: lr.lr,
        lrx: lrx.lrx,
        delay_steps: lr.delay,
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
            crate::outln!("wrote {}", j.display());
            crate::outln!("wrote {}", m.display());
        }
    }
    if args.json {
        crate::outln!("{}", serde_json::to_string(&report)?);
    } else {
        crate::out!("{md}");
    }
    Ok(())
}

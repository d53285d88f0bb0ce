//! `rths simulate --structure S.json` for an imported structure (`rths import opensees`):
//! `fe-pure`, the host FE of the whole model coupled with the numerical stand-in specimen.

use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use rths_core::params::DT_S;

use crate::cmd::simulate_args::Args;
use crate::machinery::imported::fe;
use crate::machinery::imported::reduced::{self, ReducedModelFile};
use crate::machinery::imported::ImportedStructure;
use crate::studies::nonlinear::scenario::SimScenario;
use crate::studies::scenario::ScenarioId;

/// The JSON of an imported structure's run.
#[derive(Debug, serde::Serialize)]
struct ImportedJson {
    structure: String,
    scenario: String,
    motion: String,
    dofs: usize,
    mass_dofs: usize,
    steps: usize,
    dt_s: f64,
    peak_interface_mm: f64,
    peak_outputs_mm: Vec<(String, f64)>,
    fe_s_per_step: f64,
    /// `meta-pure`: the reduced model's time per step, s.
    #[serde(skip_serializing_if = "Option::is_none")]
    meta_s_per_step: Option<f64>,
    /// `meta-pure`: its modes.
    #[serde(skip_serializing_if = "Option::is_none")]
    meta_modes: Option<usize>,
    /// `meta-pure`: its NRMSE against the host FE of the same record, % (interface, largest output).
    #[serde(skip_serializing_if = "Option::is_none")]
    meta_nrmse_pct: Option<(f64, f64)>,
}

fn peak(v: impl Iterator<Item = f64>) -> f64 {
    v.fold(0.0, |m: f64, x| m.max(x.abs()))
}

/// Run an imported structure's scenario (`text` is the file at `path`, `ag` the record at `DT_S`).
pub fn run(
    args: &Args,
    path: &Path,
    text: &str,
    ag_mm_s2: &[f64],
    motion_label: &str,
) -> anyhow::Result<()> {
    let sc = args.scenario;
    if matches!(sc, SimScenario::NlPure | SimScenario::NlOnline) {
        return crate::cmd::simulate_nl_floors::run(args, path, text, ag_mm_s2, motion_label);
    }
    if matches!(
        sc,
        SimScenario::MetaOnline | SimScenario::Study(ScenarioId::FeOnlineAts)
    ) {
        let s = ImportedStructure::from_json(text)
            .with_context(|| format!("structure file {}", path.display()))?;
        return crate::cmd::simulate_imported_online::run(args, path, &s, ag_mm_s2, motion_label);
    }
    let meta = match sc {
        SimScenario::Study(ScenarioId::FePure) => false,
        SimScenario::MetaPure => true,
        _ => anyhow::bail!(
            "{sc} is not available for an imported structure ({}): run fe-pure, fe-online-ats, meta-pure or meta-online",
            path.display()
        ),
    };
    let refuse = |flag: &str| {
        anyhow::anyhow!("{flag} does not apply to fe-pure of an imported structure (no rig)")
    };
    if args.uncertainty {
        return Err(refuse("--uncertainty"));
    }
    if args.rig.is_some() {
        return Err(refuse("--rig"));
    }
    if args.drift != 0.0 {
        return Err(refuse("--drift"));
    }
    if args.length_scale != 1.0 {
        return Err(refuse("--length-scale"));
    }
    if args.specimen_stiffness_factor != 1.0 {
        return Err(refuse(
            "--specimen-stiffness-factor (the stand-in is the imported --specimen-stiffness)",
        ));
    }
    if args.model.is_some() && !meta {
        return Err(refuse("--model"));
    }
    let s = ImportedStructure::from_json(text)
        .with_context(|| format!("structure file {}", path.display()))?;
    let reduced = match (&args.model, meta) {
        (Some(m), true) => {
            let file = ReducedModelFile::load(m)
                .with_context(|| format!("reduced model file {}", m.display()))?;
            let arrays = file
                .arrays_for(&s, DT_S)
                .with_context(|| format!("reduced model file {}", m.display()))?;
            Some((arrays.spec().params(DT_S)?, file.outputs.clone()))
        }
        (None, true) => anyhow::bail!(
            "meta-pure needs the structure's reduced model: --model M.json from `rths train meta \
             --structure {}`",
            path.display()
        ),
        _ => None,
    };
    let bar = crate::machinery::progress::styled(
        ag_mm_s2.len() as u64,
        "{bar:30} {pos}/{len} steps [{elapsed}]",
        args.json,
    );
    let start = Instant::now();
    let history = fe::run_pure(&s, ag_mm_s2, DT_S, |k| bar.set_position(k as u64))
        .with_context(|| format!("the host FE of {}", path.display()))?;
    let steps = ag_mm_s2.len().saturating_sub(1);
    let per_step = start.elapsed().as_secs_f64() / steps.max(1) as f64;
    bar.finish_and_clear();
    // meta-pure: the reduced model's pure loop, scored against the host FE's run just made.
    let mut meta_figures = None;
    let history = match reduced {
        Some((params, columns)) => {
            let start = Instant::now();
            let run = reduced::run_pure(params, columns, ag_mm_s2)?;
            let meta_per_step = start.elapsed().as_secs_f64() / steps.max(1) as f64;
            meta_figures = Some((
                meta_per_step,
                params.modes(),
                reduced::history_nrmse_pct(&run, &history),
            ));
            run
        }
        None => history,
    };
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let csv = dir.join("history.csv");
        history
            .write_csv(&csv)
            .with_context(|| format!("writing {}", csv.display()))?;
    }
    let peak_outputs_mm: Vec<(String, f64)> = history
        .output_columns
        .iter()
        .enumerate()
        .map(|(i, c)| {
            (
                c.clone(),
                peak(history.outputs_mm.iter().filter_map(|r| r.get(i).copied())),
            )
        })
        .collect();
    let json = ImportedJson {
        structure: s.name().to_string(),
        scenario: sc.to_string(),
        motion: motion_label.to_string(),
        dofs: s.equations().len(),
        mass_dofs: s.mass_dofs(),
        steps,
        dt_s: DT_S,
        peak_interface_mm: peak(history.interface_mm.iter().copied()),
        peak_outputs_mm,
        fe_s_per_step: per_step,
        meta_s_per_step: meta_figures.map(|m| m.0),
        meta_modes: meta_figures.map(|m| m.1),
        meta_nrmse_pct: meta_figures.map(|m| m.2),
    };
    if args.json {
        crate::outln!("{}", serde_json::to_string(&json)?);
        return Ok(());
    }
    crate::outln!(
        "scenario            {sc} ({motion_label}, imported structure {}: {} DOFs, {} with mass)",
        json.structure,
        json.dofs,
        json.mass_dofs
    );
    crate::outln!(
        "specimen            numerical stand-in, {} kN/mm at {}",
        s.specimen_stiffness_kn_per_mm(),
        s.specimen()
    );
    crate::outln!("peak interface      {:.4} mm", json.peak_interface_mm);
    for (c, p) in &json.peak_outputs_mm {
        crate::outln!("peak {c:<14} {p:.4} mm");
    }
    crate::outln!(
        "host FE             {:.2} us per step ({steps} steps of {:.6} s)",
        per_step * 1e6,
        DT_S
    );
    if let Some((t, r, (ni, no))) = meta_figures {
        crate::outln!(
            "reduced model       {:.3} us per step ({r} modes; {:.1}x faster than the host FE)",
            t * 1e6,
            per_step / t.max(f64::MIN_POSITIVE)
        );
        crate::outln!("NRMSE vs host FE    interface {ni:.4} %, largest output {no:.4} %");
    }
    if let Some(dir) = &args.out {
        crate::outln!("wrote {}", dir.join("history.csv").display());
    }
    Ok(())
}

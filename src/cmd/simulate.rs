//! `rths simulate`: one hybrid-simulation scenario in closed loop against the virtual plant.

use anyhow::Context;
use rths_core::params::{DT_S, PAPER_DELAY_STEPS};
use rths_hal_sim::{BoucWen, Preset, Specimen};

use crate::cmd::analyze::load_motion;
use crate::cmd::plant::{PresetArg, SpecimenArg};
use crate::cmd::simulate_args::Args;
use crate::machinery::identify::rig_file::VIRTUAL_BOARD;
use crate::machinery::identify::RigFile;
use crate::machinery::model_file::{ModelFile, ModelKind};
use crate::machinery::models;
use crate::studies::nonlinear::scenario::{
    self as nl, is_paper_frame, LengthScale, SimScenario, StructureCase, StructureReport,
};
use crate::studies::scenario::{self, ScenarioId, ScenarioSetup};
use crate::studies::study::{self, DrawnPlant, StudyJson};
use rths_files::structure_file::Structure;

/// The LR model `rths reproduce` trained on El Centro (phase 2), shipped as the default.
const DEFAULT_LR: &str = include_str!("../../data/models/lr.json");
/// The shipped LRX model (`rths train lrx`: trained on Northridge × 0.5 and Loma Prieta).
const DEFAULT_LRX: &str = include_str!("../../data/models/lrx.json");
/// The shipped RNN models (`rths train rnn --hidden H`), by hidden size.
const DEFAULT_RNN: [(usize, &str); 3] = [
    (5, include_str!("../../data/models/rnn-5.json")),
    (10, include_str!("../../data/models/rnn-10.json")),
    (20, include_str!("../../data/models/rnn-20.json")),
];

/// The JSON of `rths simulate`: the study's object and the plant the run really had.
#[derive(Debug, serde::Serialize)]
struct SimulateJson {
    #[serde(flatten)]
    study: StudyJson,
    /// What the plant had (drawn or nominal); `null` for a pure run (no plant in the loop).
    plant: Option<DrawnPlant>,
    /// The ATS's initial [a0, a1 (s), a2 (s²)] taken from `--rig` (fe-online-ats only).
    #[serde(skip_serializing_if = "Option::is_none")]
    ats_initial: Option<[f64; 3]>,
}

/// Refuse a model trained on another rig than the run's: its compensation (the LRX lead filter
/// taken from a rig file) was fitted to that rig's actuator. `training.rig` is `"PRESET VIRTUAL_BOARD
/// CHECKSUM"` (`rths train lrx --rig`); `rig_checksum` is that of the `--rig` file, if given.
fn check_model_rig(
    file: &ModelFile,
    preset: Preset,
    rig_checksum: Option<&str>,
) -> anyhow::Result<()> {
    let Some(named) = &file.training.rig else {
        return Ok(());
    };
    let mut it = named.split_whitespace();
    let (m_preset, m_board, m_sum) = (it.next(), it.next(), it.next());
    if m_preset != Some(preset.name()) || m_board != Some(VIRTUAL_BOARD) {
        anyhow::bail!(
            "the model was trained for the rig `{named}` (preset, board, checksum), this run is \
             preset {} on board {VIRTUAL_BOARD}: its compensation does not fit this plant; train one for \
             it (`rths train lrx --preset {}`)",
            preset.name(),
            preset.name()
        );
    }
    if let (Some(run), Some(model)) = (rig_checksum, m_sum) {
        if run != model {
            anyhow::bail!(
                "the model was trained with the rig file of checksum {model}, --rig has {run}: \
                 another identification of the rig"
            );
        }
    }
    Ok(())
}

fn load_model(
    model: Option<&std::path::Path>,
    id: ScenarioId,
    kind: ModelKind,
) -> anyhow::Result<ModelFile> {
    let file = match (model, kind) {
        (Some(p), _) => ModelFile::load(p).with_context(|| format!("model {}", p.display()))?,
        (None, ModelKind::Lr) => {
            ModelFile::from_json(DEFAULT_LR).context("the shipped data/models/lr.json")?
        }
        (None, ModelKind::Rnn) => {
            let h = id.rnn_hidden().unwrap_or(10);
            let text = DEFAULT_RNN
                .iter()
                .find(|(k, _)| *k == h)
                .map(|(_, t)| *t)
                .with_context(|| {
                    format!("no shipped RNN of hidden size {h} (5, 10, 20): give --model")
                })?;
            ModelFile::from_json(text)
                .with_context(|| format!("the shipped data/models/rnn-{h}.json"))?
        }
        (None, ModelKind::Lrx) => {
            ModelFile::from_json(DEFAULT_LRX).context("the shipped data/models/lrx.json")?
        }
    };
    file.expect_kind(kind)?;
    Ok(file)
}

/// Print a run's figures (stability, NRMSE, J1-J5, peak command): `rths simulate`'s lines, which
/// `rths report` prints for a recording too.
pub fn print_figures(r: &crate::studies::scenario::ScenarioReport) {
    let o = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.4}"));
    match (&r.stop_reason, r.stop_time_s) {
        (Some(why), Some(t)) => {
            crate::outln!("stable              no: the supervisor stopped it ({why} at {t:.3} s)")
        }
        _ => crate::outln!("stable              yes"),
    }
    crate::outln!("NRMSE command       {} %", o(r.nrmse_pct));
    crate::outln!("NRMSE measured      {} %", o(r.nrmse_measured_pct));
    crate::outln!("J1 delay            {} ms", o(r.j1_ms));
    crate::outln!("J2 / J3             {} / {} %", o(r.j2_pct), o(r.j3_pct));
    crate::outln!("J4 / J5             {} / {} %", o(r.j4_pct), o(r.j5_pct));
    crate::outln!("peak command        {} mm", o(r.peak_disp_mm));
}

/// The metamodels a study scenario runs (none for the FE scenarios), from `--model` or shipped.
pub struct StudyModels {
    /// The LR model.
    pub lr: Option<rths_core::metamodel::LrParams>,
    /// The RNN model.
    pub rnn: Option<rths_core::metamodel::RnnParams>,
    /// The model file's feedback delay, ticks.
    pub delay: usize,
    /// The LR coefficients.
    pub coeffs: Vec<f64>,
    /// The LR condition number.
    pub cond: Option<f64>,
    /// The LRX model and its lead filter.
    pub lrx: Option<(
        rths_core::metamodel::LrxParams,
        rths_core::compensator::LeadParams,
    )>,
}

/// Load and check the model of scenario `id` (`--model` or the shipped one), refused if it was
/// trained for another rig (`check_model_rig`).
pub fn study_models(
    model: Option<&std::path::Path>,
    id: ScenarioId,
    preset: Preset,
    rig_checksum: Option<&str>,
) -> anyhow::Result<StudyModels> {
    let load = |kind: ModelKind| -> anyhow::Result<ModelFile> {
        let m = load_model(model, id, kind)?;
        check_model_rig(&m, preset, rig_checksum)?;
        Ok(m)
    };
    let (mut lr, mut rnn, mut delay, mut coeffs, mut cond) = (None, None, 28, Vec::new(), None);
    let mut lrx = None;
    if id == ScenarioId::LrxOnline {
        let m = load(ModelKind::Lrx)?;
        lrx = Some(models::lrx_params(&m)?);
        delay = m.delay_steps;
    } else if id.uses_lr() {
        let m = load(ModelKind::Lr)?;
        let p = models::lr_params(&m)?;
        coeffs = p.theta().to_vec();
        cond = m.scores.lr_condition_number;
        delay = m.delay_steps;
        lr = Some(p);
    } else if let Some(h) = id.rnn_hidden() {
        let m = load(ModelKind::Rnn)?;
        let p = models::rnn_params(&m)?;
        if p.hidden() != h {
            anyhow::bail!(
                "scenario {id} needs hidden size {h}, the model has {}",
                p.hidden()
            );
        }
        delay = m.delay_steps;
        rnn = Some(p);
    }
    Ok(StudyModels {
        lr,
        rnn,
        delay,
        coeffs,
        cond,
        lrx,
    })
}

/// The JSON of `rths simulate --structure` (a yielding or non-paper structure).
#[derive(Debug, serde::Serialize)]
struct StructureJson {
    /// The structure file's name.
    structure: String,
    /// The record and its scale.
    motion: String,
    /// The run's figures (the study's, plus ductility, residual drift and start-up).
    scenarios: Vec<StructureReport>,
    /// Why the reference is beyond the actuator (stroke or velocity), if it is.
    beyond_rig: Option<String>,
    /// The hybrid run's compensation (fe-online-ats: its ATS start; nl-online: its lead and
    /// force correction): `--rig`'s, else identified on the virtual plant before the run.
    #[serde(skip_serializing_if = "Option::is_none")]
    compensation: Option<crate::machinery::structure::rig::RigCompensation>,
}

/// `rths simulate --structure FILE` for a structure that is not the paper's linear frame.
fn run_structure(
    args: &Args,
    structure: Structure,
    structure_json: &str,
    ag: &[f64],
    motion_label: &str,
    preset: Preset,
) -> anyhow::Result<()> {
    let name = structure.name().to_string();
    let refuse = |flag: &str| {
        anyhow::anyhow!(
            "{flag} is not supported with --structure (the structure file's specimen is linear \
             and nominal; the reference is that structure)"
        )
    };
    if args.uncertainty {
        return Err(refuse("--uncertainty"));
    }
    if !matches!(args.specimen, SpecimenArg::Linear) {
        return Err(refuse("--specimen bouc-wen"));
    }
    if args.specimen_stiffness_factor != 1.0 {
        return Err(refuse("--specimen-stiffness-factor"));
    }
    if args.drift != 0.0 {
        return Err(refuse("--drift"));
    }
    let sc = args.scenario;
    // A story file without laws: its yielding is the lab's, learned from the lab's runs; the
    // model runs through its floors as an imported structure's does (no reference here).
    if matches!(sc, SimScenario::NlPure | SimScenario::NlOnline) && structure.story_laws().is_none()
    {
        let path = args
            .structure
            .as_deref()
            .unwrap_or(std::path::Path::new(""));
        return crate::cmd::simulate_nl_floors::run(args, path, structure_json, ag, motion_label);
    }
    nl::check_applies(sc, &structure)?;
    let uses_model = matches!(
        sc,
        SimScenario::NlPure
            | SimScenario::NlOnline
            | SimScenario::Study(ScenarioId::LrOnline | ScenarioId::LrxOnline)
    );
    if let (Some(m), false) = (&args.model, uses_model) {
        anyhow::bail!(
            "--model {}: scenario {sc} runs no metamodel with --structure (the model scenarios: \
             nl-pure, nl-online, lr-online, lrx-online); drop --model",
            m.display()
        );
    }
    let length = LengthScale::new(args.length_scale)?;
    if length != LengthScale::unit() && !sc.uses_rig() {
        anyhow::bail!("--length-scale scales the rig's specimen; {sc} runs without a rig");
    }
    let case = StructureCase::new(structure, ag)?.with_length_scale(length);
    let rig = case.rig(preset, args.seed);
    // The compensation: the rig file's, else the rig identified first on this virtual plant
    // (`rths identify`'s procedure: what a lab does before testing a structure's specimen).
    let mut rig_checksum = None;
    let comp = match &args.rig {
        Some(path) => {
            let file =
                RigFile::load(path).with_context(|| format!("rig file {}", path.display()))?;
            file.check(preset.name(), VIRTUAL_BOARD)
                .with_context(|| format!("rig file {} refused", path.display()))?;
            file.check_plant(&rig, case.rig_specimen_factor())
                .with_context(|| format!("rig file {} refused", path.display()))?;
            let bytes =
                std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
            rig_checksum = Some(crate::machinery::identify::rig_file::checksum_hex(&bytes));
            Some(crate::machinery::structure::rig::from_rig_file(
                &case.structure,
                &file,
                &path.display().to_string(),
            )?)
        }
        None if matches!(
            sc,
            SimScenario::NlOnline
                | SimScenario::FeOnlineLead
                | SimScenario::Study(ScenarioId::FeOnlineAts)
        ) =>
        {
            Some(crate::machinery::structure::rig::identify(
                &case.structure,
                preset,
                args.seed,
            )?)
        }
        None => None,
    };
    let ats_initial = match sc {
        SimScenario::Study(ScenarioId::FeOnlineAts) => comp.as_ref().map(|c| c.ats_initial),
        _ => None,
    };
    let models = match sc {
        SimScenario::Study(id @ (ScenarioId::LrOnline | ScenarioId::LrxOnline)) => Some(
            study_models(args.model.as_deref(), id, preset, rig_checksum.as_deref())?,
        ),
        _ => None,
    };
    let corrected_lead = match sc {
        SimScenario::NlOnline | SimScenario::FeOnlineLead => {
            comp.as_ref().map(|c| c.corrected_lead)
        }
        _ => None,
    };
    if let (SimScenario::NlPure | SimScenario::NlOnline, Some(p)) = (sc, args.model.as_deref()) {
        crate::machinery::train::nonlinear::floors::check_model_file_elastic(p, structure_json)?;
    }
    let learned = match sc {
        SimScenario::NlPure | SimScenario::NlOnline => {
            Some(crate::machinery::structure::model::for_structure(
                args.model.as_deref(),
                &name,
                structure_json,
            )?)
        }
        _ => None,
    };
    let (report, series) = nl::run_scenario(
        &case,
        sc,
        nl::ScenarioInputs {
            preset,
            seed: args.seed,
            ats_initial,
            corrected_lead,
            lr: models.as_ref().and_then(|m| m.lr),
            lrx: models.as_ref().and_then(|m| m.lrx),
            delay_steps: models.as_ref().map_or(PAPER_DELAY_STEPS, |m| m.delay),
            nl_model: learned.as_ref(),
        },
    )?;
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let run = scenario::ScenarioRun {
            report: report.report.clone(),
            history: nl::history(&case, &series),
        };
        run.history.write_csv(&dir.join("history.csv"))?;
        study::plot_run(
            &run,
            &dir.join(format!("{sc}.png")),
            &format!("{sc} ({motion_label}, structure {name}, {})", preset.name()),
        )?;
    }
    let beyond_rig = if sc.uses_rig() {
        case.beyond_rig()
    } else {
        None
    };
    if args.json {
        let json = StructureJson {
            structure: name,
            motion: motion_label.to_string(),
            scenarios: vec![report],
            beyond_rig,
            compensation: comp,
        };
        crate::outln!("{}", serde_json::to_string(&json)?);
        return crate::cmd::RunStopped::check(&json.scenarios[0].report);
    }
    let o = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.4}"));
    crate::outln!(
        "scenario            {sc} ({motion_label}, structure {name}, {}, seed {})",
        preset.name(),
        args.seed
    );
    if let Some(why) = &beyond_rig {
        crate::outln!("beyond the rig      {why}");
    }
    if let Some(l) = report.length_scale.filter(|l| *l != 1.0) {
        crate::outln!(
            "length scale        L = {l}: the rig imposes the structure's displacement / {l} (its \
             sensor noise is {l} × larger relative to the signal)"
        );
    }
    print_figures(&report.report);
    let f = &report.figures;
    crate::outln!(
        "peak ductility      {} reference, {} run (all stories); specimen story {} reference",
        o(f.peak_ductility),
        o(f.peak_ductility_model),
        o(f.peak_ductility_specimen_story)
    );
    match f.residual_drift_mm {
        Some(r) => crate::outln!(
            "residual drift      story {}: {:.4} mm reference, {:.4} mm run (error {} %)",
            r.story,
            r.reference,
            r.model,
            o(f.residual_drift_error_pct)
        ),
        None => crate::outln!("residual drift      —"),
    }
    crate::outln!(
        "start-up ratio      {} (RMS error first 2 s / after)",
        o(f.startup_error_ratio)
    );
    if let Some(dir) = &args.out {
        crate::outln!("wrote {}", dir.join("history.csv").display());
        crate::outln!("wrote {}", dir.join(format!("{sc}.png")).display());
    }
    crate::cmd::RunStopped::check(&report.report)
}

/// Run `rths simulate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let f = args.specimen_stiffness_factor;
    if !(f.is_finite() && f > 0.0) {
        anyhow::bail!(
            "--specimen-stiffness-factor must be a positive number, got {}",
            rths_files::readable(f)
        );
    }
    if !(args.scale.is_finite() && args.scale > 0.0) {
        anyhow::bail!(
            "--scale must be a positive number, got {}",
            rths_files::readable(args.scale)
        );
    }
    let motion = load_motion(args.motion.as_deref())?;
    let ag = motion.scaled(args.scale).resample_mm_s2(DT_S);
    let motion_label = if args.scale == 1.0 {
        motion.name.clone()
    } else {
        format!("{} × {}", motion.name, rths_files::readable(args.scale))
    };
    let preset = match args.preset {
        PresetArg::Benchmark => Preset::Benchmark,
        PresetArg::UnrCompact => Preset::UnrCompact,
    };
    let specimen = match args.specimen {
        SpecimenArg::Linear => Specimen::Linear,
        SpecimenArg::BoucWen => Specimen::BoucWen(BoucWen::default()),
    };
    let structure = match &args.structure {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("reading structure file {}", p.display()))?;
            // An imported (OpenSees) structure: its own host FE (`simulate_imported`).
            if crate::machinery::imported::file::is_imported(&text) {
                return crate::cmd::simulate_imported::run(&args, p, &text, &ag, &motion_label);
            }
            let s = Structure::from_json(&text)
                .with_context(|| format!("structure file {}", p.display()))?;
            Some((s, text))
        }
        None => None,
    };
    LengthScale::new(args.length_scale)?;
    let id = match (args.scenario, structure) {
        // The paper's linear frame *is* the study's structure: the same run, bit for bit.
        (SimScenario::Study(id), Some((s, _)))
            if is_paper_frame(&s) && s.story_laws().is_none() && args.length_scale == 1.0 =>
        {
            id
        }
        (_, Some((s, text))) => return run_structure(&args, s, &text, &ag, &motion_label, preset),
        (SimScenario::Study(_), None) if args.length_scale != 1.0 => anyhow::bail!(
            "--length-scale needs --structure FILE (the scale of that structure's specimen on the rig)"
        ),
        (SimScenario::Study(id), None) => id,
        (other, None) => anyhow::bail!(
            "{other} runs the learned model of a structure's numerical part: give --structure \
             FILE (a structure with yielding stories) and --model M.json"
        ),
    };
    let uses_model = id == ScenarioId::LrxOnline || id.uses_lr() || id.rnn_hidden().is_some();
    if let (Some(m), false) = (&args.model, uses_model) {
        anyhow::bail!(
            "--model {}: scenario {id} runs no metamodel (the model scenarios: lr-pure, \
             lr-offline, lr-online, rnn-pure-H, rnn-online-H, lrx-online); drop --model",
            m.display()
        );
    }
    let mut rig = crate::machinery::reference::rig_config(preset, specimen, f, args.seed);
    rig.uncertainty = args.uncertainty;
    rig.drift = rths_hal_sim::Drift::over(args.drift, ag.len() as u64);
    let mut rig_checksum = None;
    let mut ats_initial = None;
    if let Some(path) = &args.rig {
        let file = RigFile::load(path).with_context(|| format!("rig file {}", path.display()))?;
        file.check(preset.name(), VIRTUAL_BOARD)
            .with_context(|| format!("rig file {} refused", path.display()))?;
        file.check_plant(&rig, f)
            .with_context(|| format!("rig file {} refused", path.display()))?;
        let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        rig_checksum = Some(crate::machinery::identify::rig_file::checksum_hex(&bytes));
        if id == ScenarioId::FeOnlineAts {
            ats_initial = Some(file.compensation.ats_initial);
        }
    }
    let StudyModels {
        lr,
        rnn,
        delay,
        coeffs,
        cond,
        lrx,
    } = study_models(args.model.as_deref(), id, preset, rig_checksum.as_deref())?;
    // The evaluation knows the specimen the plant really has; a pure run has no plant, so its
    // reference stays the configured structure. The analytical parts keep F (`fe-pure` and
    // `fe-offline` are analyses of the structure as configured: nobody knows the draw before the test).
    let (reference, plant) = if id.uses_rig() {
        let (r, d) = study::reference_for_rig(&ag, &rig, f)?;
        (r, Some(d))
    } else {
        (study::reference_for(&ag, specimen, f)?, None)
    };
    let setup = ScenarioSetup {
        id,
        ground_accel_mm_s2: &ag,
        reference_mm: &reference,
        rig,
        stiffness_factor: f,
        lr,
        rnn,
        delay_steps: delay,
        lrx,
    };
    // Only `--out` writes the history; the figures alone need a third of it.
    let run = match &args.out {
        Some(_) => Some(scenario::run_with_ats_start(&setup, ats_initial)?),
        None => None,
    };
    let report = match &run {
        Some(run) => run.report.clone(),
        None => scenario::report_with_ats_start(&setup, ats_initial)?,
    };
    if let (Some(dir), Some(run)) = (&args.out, &run) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        run.history.write_csv(&dir.join("history.csv"))?;
        study::plot_run(
            run,
            &dir.join(format!("{id}.png")),
            &format!(
                "{id} ({}, {}, {}, F = {f})",
                motion_label,
                preset.name(),
                specimen.name()
            ),
        )?;
    }
    let json = SimulateJson {
        study: StudyJson {
            scenarios: vec![report.clone()],
            lr_coefficients: coeffs,
            lr_condition_number: cond,
            specimen_sweep: None,
        },
        plant,
        ats_initial,
    };
    if args.json {
        crate::outln!("{}", serde_json::to_string(&json)?);
        return crate::cmd::RunStopped::check(&report);
    }
    let r = &report;
    crate::outln!(
        "scenario            {id} ({}, {}, {}, F = {f}, seed {})",
        motion_label,
        preset.name(),
        specimen.name(),
        args.seed
    );
    match &plant {
        Some(d) => crate::outln!(
            "plant               {}: beta1 {:.3} 1/s, beta2 {:.5e} 1/s^2, a3 {:.4} 1/s, specimen k {:.1} N/m (effective F = {:.4})",
            if d.uncertainty {
                format!("drawn with seed {}", d.seed)
            } else {
                "nominal".to_string()
            },
            d.beta1,
            d.beta2,
            d.a3,
            d.specimen_stiffness_n_per_m,
            d.specimen_stiffness_factor
        ),
        None => crate::outln!("plant               none in the loop (pure run)"),
    }
    if let Some([a0, a1, a2]) = ats_initial {
        crate::outln!(
            "ATS start           from the rig file: a0 {a0:.4}, a1 {a1:.5} s, a2 {a2:.3e} s^2"
        );
    }
    print_figures(r);
    if let Some(dir) = &args.out {
        crate::outln!("wrote {}", dir.join("history.csv").display());
        crate::outln!("wrote {}", dir.join(format!("{id}.png")).display());
    }
    crate::cmd::RunStopped::check(r)
}

//! `rths train lr|rnn|lrx`: fit a metamodel and write its model file (LR and RNN on the pure response
//! of the prototype; LRX on frame runs with independent brace forces and on plant runs).

use std::path::PathBuf;

use anyhow::Context;
use rths_core::params::{Prototype, DT_S};

use crate::machinery::model_file::{ModelFile, Scores, Training};
use crate::machinery::train::{data, lr, rnn};

/// Which metamodel to train.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// Linear regression (paper Eq. 6), SVD least squares.
    Lr,
    /// Elman RNN, truncated BPTT with Adam.
    Rnn,
    /// Specimen-faithful LRX: frame ARX with the measured force as an input, and a learned lead
    /// filter.
    Lrx,
    /// The structure metamodel of a structure file's numerical part (`--structure`): a delta-form
    /// ARX of order 6 at the specimen's DOF, constant cost per tick whatever N is.
    Meta,
    /// Nonlinear (modal-hysteretic) metamodel of a yielding structure (`--structure`): each spring
    /// fitted to its story's force–drift history, then CMA-ES on the whole model's pure loop, on
    /// FE runs of northridge and loma-prieta at peak ductility 0.7, 2, 4, 6 (never El Centro,
    /// Kobe or Morgan Hill, the scoring records). docs/nonlinear.md.
    Nonlinear,
}

/// RNN initialization.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RnnInitArg {
    /// Least-squares ARX model realized as the RNN.
    Arx,
    /// Seeded random weights.
    Random,
}

/// A switch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    /// On.
    On,
    /// Off.
    Off,
}

/// The nonlinear metamodel's form.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum NlFormArg {
    /// Train both forms where both apply (a story structure with 3 or more histories) and keep the
    /// one with the lower loss on the held-out histories.
    Auto,
    /// One latent spring per story on the elastic modes.
    ModalHysteretic,
    /// The elastic floors plus play operators on the drifts (any structure, from histories).
    FloorHysteron,
}

/// The nonlinear metamodel's spring family.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum NlLawArg {
    /// Train bilinear and Bouc–Wen springs, and each story's own better family where they
    /// differ; keep the lowest validation loss (training loss without validation histories).
    Auto,
    /// Bilinear kinematic hardening.
    Bilinear,
    /// Bouc–Wen.
    BoucWen,
}

/// Arguments of `rths train`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model kind.
    #[arg(value_enum)]
    pub kind: Kind,
    /// Ground-motion record (AT2); default: El Centro NS (IELC180).
    #[arg(long)]
    pub motion: Option<PathBuf>,
    /// RNN hidden size (1..=32).
    #[arg(long, default_value_t = 10)]
    pub hidden: usize,
    /// Feedback delay, controller steps.
    #[arg(long, default_value_t = rths_core::params::PAPER_DELAY_STEPS)]
    pub delay_steps: usize,
    /// Seed: the RNN's initial weights; nonlinear, the springs' random start (modal-hysteretic)
    /// and the free fit's search (`--free-fit`). The same seed and inputs give the same bytes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// RNN maximum epochs of fine-tuning/training (the help's defaults: [`epochs_help`]).
    #[arg(long, help = epochs_help())]
    pub epochs: Option<usize>,
    /// RNN truncated-BPTT window, steps. Default 8192 (arx) or 1024 (random).
    #[arg(long)]
    pub window: Option<usize>,
    /// RNN Adam learning rate. Default 1e-9, relative to each weight's magnitude (arx), or 1e-3
    /// (random).
    #[arg(long)]
    pub learning_rate: Option<f64>,
    /// RNN early-stopping patience, epochs. Default 40 (arx) or 60 (random).
    #[arg(long)]
    pub patience: Option<usize>,
    /// RNN: epochs of teacher forcing before training on its own delayed prediction as feedback.
    #[arg(long)]
    pub teacher_epochs: Option<usize>,
    /// RNN initial weights: `arx` (least-squares ARX model realized as the RNN, then fine-tuned) or
    /// `random` (seeded, IRNN-like).
    #[arg(long, value_enum, default_value_t = RnnInitArg::Arx)]
    pub init: RnnInitArg,
    /// RNN ARX initialization: hidden-state scale ε (tanh's near-linear range).
    #[arg(long, default_value_t = rnn::DEFAULT_ARX_STATE_SCALE)]
    pub state_scale: f64,
    /// LR relative singular-value cut-off.
    #[arg(long, default_value_t = lr::DEFAULT_RCOND)]
    pub rcond: f64,
    /// LRX training motions, `NAME:SCALE` (embedded record, or a file path), repeatable. Default:
    /// northridge:0.5 and loma-prieta:1 (El Centro and Kobe are kept for testing).
    #[arg(long = "lrx-motion", value_name = "NAME:SCALE")]
    pub lrx_motions: Vec<String>,
    /// LRX lead-filter tap spacing, ticks (1..=8).
    #[arg(long, default_value_t = 6)]
    pub lead_stride: usize,
    /// LRX time constant of the online specimen-stiffness estimate, ticks (0: fixed at the
    /// paper's brace).
    #[arg(long, default_value_t = 2048.0)]
    pub k_adapt_ticks: f64,
    /// LRX time constant of the lead's online gain-and-delay correction, ticks (0: fixed lead;
    /// else 32..=1e7). Default: 4096 (2 s) with --rig, else 0 (the shipped model's fixed lead).
    /// docs/lrx.md, "Online adaptation of the lead".
    #[arg(long)]
    pub lead_adapt_ticks: Option<f64>,
    /// LRX relative singular-value cut-off of both least-squares fits (it drops the frame fit's
    /// least-determined direction, which the closed recursion does not tolerate well).
    #[arg(long, default_value_t = 1e-9)]
    pub lrx_rcond: f64,
    /// LRX band-limited force perturbation, RMS as a fraction of the RMS brace force.
    #[arg(long, default_value_t = 0.3)]
    pub perturbation: f64,
    /// LRX: plant preset of the lead fit on the simulator (default unr-compact); with --rig, the
    /// rig file must be of this preset (default: the rig file's).
    #[arg(long, value_enum)]
    pub preset: Option<crate::cmd::plant::PresetArg>,
    /// LRX: take the lead filter from this rig file (`rths identify`) instead of fitting it on the
    /// simulated plant; the model records the rig (preset, board, checksum).
    #[arg(long, value_name = "RIG.json")]
    pub rig: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// `meta`: the structure file whose numerical part the metamodel stands for; `nonlinear`:
    /// the structure file with yielding stories.
    #[arg(long, value_name = "FILE")]
    pub structure: Option<PathBuf>,
    /// `meta`: the controller rate it runs at, Hz (2048 or 4096; default: this build's).
    #[arg(long, value_name = "HZ")]
    pub rate: Option<u32>,
    /// Nonlinear: training records (embedded name or file), repeatable; default northridge and
    /// loma-prieta. Scoring records are refused.
    #[arg(long = "records", value_name = "NAME")]
    pub nl_records: Vec<String>,
    /// Nonlinear: train on these time histories of the lab's FE runs instead of rths's FE runs of
    /// the training records (a CSV file or an OpenSees recorder directory each; taken by file
    /// name, and with 3 or more every third held out of the fit; a history given twice is
    /// refused; docs/opensees-nonlinear.md).
    #[arg(long = "histories", value_name = "FILE", num_args = 1.., conflicts_with = "nl_records")]
    pub histories: Vec<PathBuf>,
    /// Nonlinear: CMA-ES generations of stage 2 (the whole model on the runs).
    #[arg(long, default_value_t = 20)]
    pub generations: usize,
    /// Nonlinear: CMA-ES generations of stage 1, per spring (its law on its story's force–drift
    /// history from the FE training runs).
    #[arg(long, default_value_t = 100)]
    pub stage1_generations: usize,
    /// Nonlinear: the specimen force of the training's pure loop as the lab's DAQ reads it (load
    /// cell noise and 16-bit converter, fixed seeded sequence per run) or exact.
    #[arg(long, value_enum, default_value_t = OnOff::On)]
    pub force_noise: OnOff,
    /// Nonlinear: the latent springs' law family (`auto`: train both, and each story's own
    /// better one where they differ; keep the lowest loss).
    #[arg(long, value_enum, default_value_t = NlLawArg::Auto)]
    pub law: NlLawArg,
    /// Nonlinear: the model's form (`auto`: with 3 or more histories of a story structure, both
    /// forms are trained and the one with the lower loss on the held-out histories is kept; an
    /// imported structure takes the floor-hysteron form).
    #[arg(long, value_enum, default_value_t = NlFormArg::Auto)]
    pub form: NlFormArg,
    /// Nonlinear, floor-hysteron form: Levenberg–Marquardt steps of the refinement on the
    /// simulation error after the least-squares fit, at most (0: the least-squares fit alone); it
    /// stops earlier on the validation histories (every third by file name held out of the fit),
    /// and does not run with fewer than 3 histories (none held out to stop on).
    #[arg(long, default_value_t = crate::machinery::train::nonlinear::refine::RefineConfig::default().max_iterations)]
    pub refine_steps: usize,
    /// Nonlinear, floor-hysteron form: before the refinement, move each refined candidate's
    /// thresholds and Menegotto–Pinto shape off the least squares' grid to lower the same force
    /// residual (CMA-ES; the weights refitted at every point), kept where it lowers the loss on
    /// the validation histories. Some 20 s a candidate on two cores (the fiber frame's runs).
    #[arg(long)]
    pub free_fit: bool,
    /// Nonlinear `--evaluate --histories`: score the hybrid loop too (the virtual rig, identified
    /// compensation, force correction: `nl-online`) against each held-out history.
    #[arg(long)]
    pub hybrid: bool,
    /// Nonlinear: modes kept (default: as many as the structure's DOFs). `meta` on an imported
    /// structure: the reduced model's order, exactly R modes, the lowest (default: the fewest
    /// within the 0.1 % target); its error bound is printed. At most 32 (what core holds) and the
    /// structure's DOFs with mass.
    #[arg(long, value_name = "R")]
    pub modes: Option<usize>,
    /// Nonlinear: do not train; evaluate the model file at --out. With --histories, against
    /// those held-out runs of the lab's FE program (e.g. OpenSees's own run of a record the
    /// training never read): interface NRMSE and residual drift per run, the pure loop (and the
    /// hybrid loop with --hybrid). Without, against the structure's own yielding FE on the
    /// scoring records (El Centro, Kobe, Morgan Hill) at peak ductility 0.8, 2 and 4.5.
    #[arg(long)]
    pub evaluate: bool,
    /// Output model file (JSON).
    #[arg(long)]
    pub out: PathBuf,
}

/// `--epochs`'s help, its defaults from the training's own (never a number typed twice).
fn epochs_help() -> String {
    format!(
        "RNN maximum epochs of fine-tuning/training (early stopping may end sooner; 0: ARX \
         initialization only). Default {} (`--init arx`) or {} (`--init random`)",
        crate::machinery::train::rnn::ARX_FINE_TUNE_EPOCHS,
        crate::machinery::train::rnn::RnnConfig::random_init(1).max_epochs
    )
}

/// Largest `--perturbation` (RMS force perturbation / RMS brace force): beyond 2 the runs are
/// mostly perturbation, no longer the frame's response.
const MAX_PERTURBATION: f64 = 2.0;

/// Refuse the flags `kind` does not use (they would be silently ignored) and a `--delay-steps` the
/// controller cannot run, before any training.
fn check_flags(args: &Args) -> anyhow::Result<()> {
    let build_hz = rths_core::params::CONTROL_RATE_HZ;
    if let (Some(rate), false) = (args.rate, args.kind == Kind::Meta) {
        if rate != build_hz {
            anyhow::bail!(
                "--rate {rate}: `rths train {}` trains at this build's controller rate, {build_hz} \
                 Hz (`--rate` chooses the rate of `rths train meta` only); for 4096 Hz build with \
                 `cargo build --release --features rate-4096`",
                kind_name(args.kind)
            );
        }
    }
    if matches!(args.kind, Kind::Lr | Kind::Rnn) {
        crate::machinery::model_file::check_delay_steps(args.delay_steps)
            .map_err(|e| anyhow::anyhow!("--delay-steps: {e}"))?;
    }
    if args.modes.is_some() && !matches!(args.kind, Kind::Nonlinear | Kind::Meta) {
        anyhow::bail!(
            "--modes applies to `rths train nonlinear` and `rths train meta` (an imported \
             structure's reduced model) only"
        );
    }
    Ok(())
}

fn kind_name(kind: Kind) -> &'static str {
    match kind {
        Kind::Lr => "lr",
        Kind::Rnn => "rnn",
        Kind::Lrx => "lrx",
        Kind::Meta => "meta",
        Kind::Nonlinear => "nonlinear",
    }
}

fn fmt_opt(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

fn train_lrx(args: &Args) -> anyhow::Result<()> {
    let mut cfg = crate::machinery::train::lrx::LrxConfig::new()?;
    if !args.lrx_motions.is_empty() {
        cfg.motions = args
            .lrx_motions
            .iter()
            .map(|spec| {
                let (name, scale) = match spec.rsplit_once(':') {
                    Some((n, s)) => (
                        n,
                        s.parse::<f64>()
                            .with_context(|| format!("scale in {spec}"))?,
                    ),
                    None => (spec.as_str(), 1.0),
                };
                anyhow::ensure!(
                    scale.is_finite() && scale > 0.0,
                    "scale in {spec} must be positive"
                );
                Ok((crate::cmd::analyze::load_motion(Some(name))?, scale))
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
    }
    cfg.lead_stride = args.lead_stride;
    cfg.k_adapt_ticks = args.k_adapt_ticks;
    cfg.lead_adapt_ticks = args.lead_adapt_ticks.unwrap_or(if args.rig.is_some() {
        crate::machinery::train::lrx::RIG_LEAD_ADAPT_TICKS
    } else {
        0.0
    });
    anyhow::ensure!(
        args.perturbation.is_finite() && (0.0..=MAX_PERTURBATION).contains(&args.perturbation),
        "--perturbation {}: the RMS force perturbation is a fraction of the RMS brace force, \
         0..={MAX_PERTURBATION}",
        args.perturbation
    );
    cfg.perturbation = args.perturbation;
    anyhow::ensure!(
        args.lrx_rcond.is_finite() && args.lrx_rcond > 0.0 && args.lrx_rcond < 1.0,
        "--lrx-rcond must be in (0, 1)"
    );
    cfg.rcond = args.lrx_rcond;
    cfg.seed = args.seed;
    if let Some(p) = args.preset {
        cfg.preset = match p {
            crate::cmd::plant::PresetArg::Benchmark => rths_hal_sim::Preset::Benchmark,
            crate::cmd::plant::PresetArg::UnrCompact => rths_hal_sim::Preset::UnrCompact,
        };
    }
    let mut rig_identity = None;
    if let Some(path) = &args.rig {
        let rig = crate::machinery::identify::RigFile::load(path)
            .with_context(|| format!("rig file {}", path.display()))?;
        if args.preset.is_some() {
            rig.check(cfg.preset.name(), &rig.board)
                .with_context(|| format!("rig file {}", path.display()))?;
        }
        let lead = rig.lead_params()?;
        cfg.given_lead = Some(crate::machinery::train::lrx::GivenLead {
            weights: *lead.weights(),
            stride: lead.stride(),
            fit_nrmse_pct: rig.quality.lead_fit_nrmse_pct,
        });
        cfg.specimen_dynamics = Some(crate::machinery::train::lrx::prototype_dynamics(
            &rig.specimen_fit,
        ));
        let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
        rig_identity = Some(format!(
            "{} {} {}",
            rig.preset,
            rig.board,
            crate::machinery::identify::rig_file::checksum_hex(&bytes)
        ));
        crate::outln!(
            "lead filter from rig file {} ({} on {}, stride {})",
            path.display(),
            rig.preset,
            rig.board,
            lead.stride()
        );
    }
    let mut t = crate::machinery::train::lrx::train(&cfg)?;
    t.file.training.rig = rig_identity;
    crate::outln!("LRX fit on {} (seed {})", t.file.training.motion, cfg.seed);
    for (name, c) in crate::machinery::model_file::LRX_FEATURES
        .iter()
        .zip(&t.coeffs)
    {
        crate::outln!("  {name:<24} {c:+.10e}");
    }
    crate::outln!(
        "  frame fit: one-step NRMSE {:.3e}%, condition number {:.3e}",
        t.frame_fit_nrmse_pct,
        t.frame_condition
    );
    crate::outln!(
        "  lead filter (stride {}): {:?}",
        cfg.given_lead.map_or(cfg.lead_stride, |g| g.stride),
        t.lead_weights
    );
    crate::outln!(
        "  lead fit: NRMSE {:.3}%, condition number {:.3e}",
        t.lead_fit_nrmse_pct,
        t.lead_condition
    );
    for (m, e) in &t.pure_nrmse_pct {
        crate::outln!("  lrx-pure NRMSE on {m}: {e:.3e}%");
    }
    // Generalization of the frame model: lrx-pure on every shipped record.
    let (frame, _) = crate::machinery::models::lrx_params(&t.file)?;
    crate::outln!("  lrx-pure NRMSE on the shipped records:");
    for name in crate::machinery::motion::GroundMotion::embedded_names() {
        let m = crate::machinery::motion::GroundMotion::try_embedded(name)?;
        let e = crate::machinery::train::lrx::pure_nrmse_pct(frame, &m.resample_mm_s2(DT_S))?;
        crate::outln!("    {name:<16} {e:.3e}%");
    }
    t.file
        .save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    crate::outln!("wrote {}", args.out.display());
    Ok(())
}

/// Run `rths train`.
pub fn run(args: Args) -> anyhow::Result<()> {
    check_flags(&args)?;
    if args.kind == Kind::Meta {
        return train_meta(&args);
    }
    if args.kind == Kind::Nonlinear {
        return train_nonlinear(&args);
    }
    let prototype = Prototype::paper();
    let k_b = prototype.brace_axial_stiffness_kn_per_mm();
    let motion = match &args.motion {
        Some(p) => crate::machinery::motion::GroundMotion::from_path(p)
            .with_context(|| format!("reading ground motion {}", p.display()))?,
        None => crate::machinery::motion::GroundMotion::try_el_centro()?,
    };
    let motion_name = motion.name.clone();
    let ag = motion.resample_mm_s2(DT_S);
    anyhow::ensure!(!ag.is_empty(), "ground motion {motion_name} is empty");
    let response = data::pure_response(&prototype, &ag, DT_S)?;
    let mut file = match args.kind {
        Kind::Lr => {
            let fit = lr::fit_pure(&response, args.delay_steps, k_b, args.rcond)?;
            let s = &fit.solution;
            crate::outln!(
                "LR fit on {motion_name} ({} steps, delay {} steps)",
                response.len(),
                args.delay_steps
            );
            for (name, t) in crate::machinery::model_file::LR_FEATURES
                .iter()
                .zip(&s.theta)
            {
                crate::outln!("  {name:<20} {t:+.10e}");
            }
            crate::outln!(
                "  condition number (normalized, before cut-off): {:.3e}",
                s.condition_number
            );
            crate::outln!(
                "  effective rank: {} of {} (rcond {:e})",
                s.effective_rank,
                s.theta.len(),
                args.rcond
            );
            crate::outln!("  train NRMSE (one step): {:.3e}%", fit.train_nrmse_pct);
            crate::outln!("  lr-pure NRMSE: {:.4}% (paper 0.15%)", fit.pure_nrmse_pct);
            let mut f = ModelFile::new_lr(s.theta.to_vec(), args.delay_steps, DT_S);
            f.training = Training {
                motion: motion_name,
                records: response.len(),
                phase: 1,
                method: "svd-least-squares".into(),
                svd_rcond: Some(args.rcond),
                ..Training::default()
            };
            f.scores = Scores {
                train_nrmse_pct: Some(fit.train_nrmse_pct),
                pure_nrmse_pct: Some(fit.pure_nrmse_pct),
                lr_condition_number: fmt_opt(s.condition_number),
                lr_effective_rank: Some(s.effective_rank),
                ..Scores::default()
            };
            f
        }
        Kind::Rnn => {
            let mut cfg = match args.init {
                RnnInitArg::Arx => rnn::RnnConfig::new(args.hidden),
                RnnInitArg::Random => rnn::RnnConfig::random_init(args.hidden),
            };
            cfg.delay_steps = args.delay_steps;
            cfg.seed = args.seed;
            cfg.quiet = args.quiet;
            if let Some(e) = args.epochs {
                cfg.max_epochs = e;
            }
            if let Some(w) = args.window {
                cfg.window_steps = w;
            }
            if let Some(l) = args.learning_rate {
                cfg.learning_rate = l;
            }
            if let Some(t) = args.teacher_epochs {
                cfg.teacher_epochs = t;
            }
            if let Some(p) = args.patience {
                cfg.patience = p;
            }
            cfg.arx_state_scale = args.state_scale;
            cfg.arx_rcond = args.rcond;
            let t = rnn::train(&response, k_b, &cfg)?;
            crate::outln!(
                "RNN H={} on {motion_name} ({} steps, delay {} steps, seed {})",
                args.hidden,
                response.len(),
                args.delay_steps,
                args.seed
            );
            crate::outln!(
                "  epochs: {} (best {}), best validation loss {:.4e}",
                t.epochs,
                t.best_epoch,
                t.best_validation_loss
            );
            crate::outln!("  train NRMSE (teacher forcing): {:.3}%", t.train_nrmse_pct);
            crate::outln!(
                "  rnn-pure NRMSE: initial weights {:.4}%, trained {:.4}%",
                t.init_pure_nrmse_pct,
                t.pure_nrmse_pct
            );
            crate::outln!("  wall time: {:.1} s", t.wall_time_s);
            // Generalization: the same closed loop on every shipped record (ms each).
            crate::outln!("  rnn-pure NRMSE on the shipped records (generalization):");
            for name in crate::machinery::motion::GroundMotion::embedded_names() {
                let m = crate::machinery::motion::GroundMotion::try_embedded(name)?;
                let r = data::pure_response(&prototype, &m.resample_mm_s2(DT_S), DT_S)?;
                let e = rnn::rnn_pure_nrmse_pct(&t.model, &r, args.delay_steps, k_b)?;
                crate::outln!("    {name:<16} {e:.4}%");
            }
            rnn::model_file(&t, &cfg, motion_name, response.len())
        }
        Kind::Lrx => return train_lrx(&args),
        Kind::Meta => return train_meta(&args),
        Kind::Nonlinear => return train_nonlinear(&args),
    };
    file.training.records = response.len();
    file.save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    crate::outln!("wrote {}", args.out.display());
    Ok(())
}

/// `rths train meta`: the benchmark's metamodel training ([`crate::studies::benchmark::meta`]) on any
/// structure file, at the rate asked, into a structure-metamodel file
/// ([`rths_files::structure_meta`]: the structure's name and checksum, so a model trained for
/// another structure is refused).
fn train_meta(args: &Args) -> anyhow::Result<()> {
    use rths_files::structure_meta::{MetaFile, MetaTraining};
    let path = args
        .structure
        .as_ref()
        .context("`rths train meta` needs --structure FILE")?;
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading structure file {}", path.display()))?;
    if crate::machinery::imported::file::is_imported(&text) {
        return train_reduced(args, path, &text);
    }
    if let Some(r) = args.modes {
        anyhow::bail!(
            "--modes {r}: {} is not an imported structure; its structure metamodel (delta-ARX) has \
             no modes (--modes sets the order of an imported structure's reduced model)",
            path.display()
        );
    }
    let structure = rths_files::structure_file::Structure::load(path)?;
    let rate = args.rate.unwrap_or(rths_core::params::CONTROL_RATE_HZ);
    anyhow::ensure!(
        rths_core::params::CONTROL_RATES_HZ.contains(&rate),
        "--rate must be one of {:?} Hz, got {rate}",
        rths_core::params::CONTROL_RATES_HZ
    );
    let dt_s = rths_core::params::dt_s(rate);
    let intensity = crate::studies::benchmark::DEFAULT_INTENSITY;
    let meta = crate::studies::benchmark::meta::train_at(&structure, intensity, dt_s)?;
    let file = MetaFile::new(
        &structure,
        meta.params(),
        dt_s,
        MetaTraining {
            records: crate::studies::benchmark::meta::TRAINING_RECORDS
                .iter()
                .map(|r| r.to_string())
                .collect(),
            intensity,
            method: "svd-least-squares (column-scaled), delta-form ARX".into(),
            force_correction_ratio: crate::studies::benchmark::meta::META_FORCE_CORRECTION,
        },
    );
    std::fs::write(&args.out, file.to_json()?)
        .with_context(|| format!("writing {}", args.out.display()))?;
    crate::outln!(
        "structure metamodel of {} ({} DOFs, specimen at DOF {}) at {rate} Hz: wrote {}",
        structure.name(),
        structure.dofs(),
        structure.specimen_dof() + 1,
        args.out.display()
    );
    Ok(())
}

// ---- `rths train nonlinear` (issue 16) ----

fn train_nonlinear(args: &Args) -> anyhow::Result<()> {
    use crate::machinery::train::nonlinear::choose::{train_form, Form, TrainedForm};
    use crate::machinery::train::nonlinear::{families_label, NlTrainConfig, SpringLaw};
    let t0 = std::time::Instant::now();
    let path = args
        .structure
        .as_ref()
        .context("rths train nonlinear needs --structure FILE.json")?;
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    if args.evaluate {
        return evaluate_nonlinear(args, path, &text);
    }
    let mut cfg = NlTrainConfig::new(args.seed)?;
    if !args.nl_records.is_empty() {
        cfg.records = args
            .nl_records
            .iter()
            .map(|n| crate::cmd::analyze::load_motion(Some(n)))
            .collect::<anyhow::Result<Vec<_>>>()?;
    }
    // By file name, a history given twice refused before any is read (the training orders them
    // so too: this only makes the notes below come in that order).
    cfg.histories = crate::machinery::train::nonlinear::histories::in_name_order(&args.histories)?;
    for h in &cfg.histories {
        let swinging = crate::machinery::train::nonlinear::refine::still_swinging(h, DT_S)?;
        if let Some((column, residual_mm, swing_mm)) = swinging.first() {
            crate::outln!(
                "note: {}: {column} still swings {swing_mm:.2} mm at the end (mean {residual_mm:.2} \
                 mm over the last {} s; {} output(s) so): its free vibration is too short for the \
                 residual drift the training fits; write the run with a longer one \
                 (write_histories.py --free-s, rths analyze --free-s)",
                h.display(),
                crate::machinery::structure::RESIDUAL_WINDOW_S,
                swinging.len(),
            );
        }
    }
    cfg.refine.max_iterations = args.refine_steps;
    cfg.refine.free_fit = args.free_fit;
    cfg.generations = args.generations;
    cfg.stage1_generations = args.stage1_generations;
    cfg.force_noise = args.force_noise == OnOff::On;
    cfg.modes = args.modes;
    cfg.laws = match args.law {
        NlLawArg::Auto => vec![SpringLaw::Bilinear, SpringLaw::BoucWen],
        NlLawArg::Bilinear => vec![SpringLaw::Bilinear],
        NlLawArg::BoucWen => vec![SpringLaw::BoucWen],
    };
    let bar = crate::machinery::progress::styled(
        0,
        "{elapsed_precise} [{bar:40}] {pos}/{len} (modal-hysteretic: generations of stage 1 per \
         spring, then stage 2; floor-hysteron: refinement steps) {msg}",
        args.quiet,
    );
    let form = match args.form {
        NlFormArg::Auto => Form::Auto,
        NlFormArg::ModalHysteretic => Form::Modal,
        NlFormArg::FloorHysteron => Form::Hysteron,
    };
    let (trained, choice) = train_form(&text, &cfg, form, |g, total, what| {
        bar.set_length(total as u64);
        bar.set_position(g as u64);
        bar.set_message(what);
    })?;
    bar.finish_and_clear();
    if let Some(c) = &choice {
        if c.losses_pct.is_empty() {
            crate::outln!("form: {}", c.reason);
        } else {
            let l: Vec<String> = c
                .losses_pct
                .iter()
                .map(|(f, v)| format!("{f} {v:.3}%"))
                .collect();
            crate::outln!(
                "form chosen on the held-out histories {}: {}; kept the {} form ({})",
                c.held_out.join(", "),
                l.join(", "),
                match &trained {
                    TrainedForm::Modal(_) => "modal-hysteretic",
                    TrainedForm::Hysteron(_) => "floor-hysteron",
                },
                c.reason
            );
        }
    }
    let t = match trained {
        TrainedForm::Hysteron(f) => return report_hysteron(args, &f, t0),
        TrainedForm::Modal(t) => t,
    };
    let tr = &t.file.training;
    crate::outln!(
        "modal-hysteretic model of {} ({} modes, {} springs), seed {}: stage 1 {} generations \
         per spring, stage 2 CMA-ES {} generations × {}; specimen force {}",
        t.file.structure.name,
        t.file.modes.len(),
        t.file.springs.len(),
        tr.seed,
        cfg.stage1_generations,
        tr.generations,
        tr.population,
        if cfg.force_noise {
            "as the lab's DAQ reads it"
        } else {
            "exact"
        }
    );
    crate::outln!(
        "  {} springs; loss (mean floor NRMSE over the runs): initial {:.3}%, after stage 1 \
         {:.3}%, trained {:.3}%",
        families_label(t.file.springs.iter().map(|s| s.law.as_str())),
        tr.initial_loss_pct,
        t.stage1_loss_pct,
        tr.final_loss_pct
    );
    for (label, mu, e) in &t.runs {
        if mu.is_finite() {
            crate::outln!("  {label:<24} ductility {mu:5.2}  specimen-DOF pure-loop NRMSE {e:.3}%");
        } else {
            crate::outln!("  {label:<24} history          specimen-DOF pure-loop NRMSE {e:.3}%");
        }
    }
    if let Some(v) = &t.validation {
        let (held, scores) = (&v.held_out, &v.losses_pct);
        let scores: Vec<String> = scores.iter().map(|(l, v)| format!("{l} {v:.3}%")).collect();
        crate::outln!(
            "  validation on {} (held out of the fit): {}; kept the lowest",
            held.join(", "),
            scores.join(", ")
        );
    }
    for (k, s) in t.file.springs.iter().enumerate() {
        crate::outln!(
            "  spring {}: fy {:.1} kN, k0 {:.2} kN/mm, α {:.3}, n {:.2}, β {:.3}, γ {:.3}",
            k + 1,
            s.yield_force_kn,
            s.k0_kn_per_mm,
            s.post_yield_ratio,
            s.exponent,
            s.beta,
            s.gamma
        );
    }
    crate::outln!("  wall time: {:.1} s", t.wall_time_s);
    t.file
        .save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    crate::outln!("wrote {}", args.out.display());
    Ok(())
}

/// Print and write a trained floor-hysteron model.
fn report_hysteron(
    args: &Args,
    f: &rths_files::hysteron_model_file::HysteronModelFile,
    t0: std::time::Instant,
) -> anyhow::Result<()> {
    let t = &f.training;
    crate::outln!(
        "floor-hysteron model of {} ({} floors: {}; {} directions, {} hysterons with weight; \
         operator: {})",
        f.structure.name,
        f.floors.len(),
        f.floors.join(", "),
        f.directions.len(),
        f.hysterons.len(),
        f.operator.describe()
    );
    if !t.operators_tried.is_empty() {
        let best = t
            .operators_tried
            .iter()
            .map(|(_, l)| *l)
            .fold(f64::INFINITY, f64::min);
        let play = t
            .operators_tried
            .iter()
            .filter(|(d, _)| d.starts_with("play,"))
            .map(|(_, l)| *l)
            .fold(None, |m: Option<f64>, l| Some(m.map_or(l, |m| m.min(l))))
            .map(|l| ((), l))
            .map_or(f64::NAN, |(_, l)| l);
        let judged_on = if t.validation_loss_pct.is_some() {
            "validation"
        } else {
            "training (no validation histories: fewer than 3 given)"
        };
        crate::outln!(
            "  basis chosen among {} (operator, threshold range) after least squares on the \
             {judged_on} histories (the best play {play:.3}%, the best {best:.3}%), then the {} \
             best refined and the lowest loss there kept",
            t.operators_tried.len(),
            crate::machinery::train::nonlinear::choose::REFINED_CANDIDATES
        );
    }
    crate::outln!(
        "  restoring-force fit residual {:.2}% (RMS, of the recovered force); tangent scale {:.4}",
        t.force_fit_pct,
        t.stability_scale,
    );
    for f in &t.free_fit {
        crate::outln!("  free fit of the thresholds and the shape: {f}");
    }
    let pct = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.3}%"));
    match &t.refinement {
        Some(r) => crate::outln!(
            "  refined on the simulation error: {} Levenberg–Marquardt steps, kept step {} ({}); \
             stiffness × {:.4}, damping × {:.4}",
            r.steps,
            r.kept_step,
            r.stopped,
            r.stiffness_scale,
            r.damping_scale
        ),
        None if t.validation_loss_pct.is_none() => crate::outln!(
            "  not refined: no validation histories to stop on (fewer than 3 given, or \
             --refine-steps 0)"
        ),
        None => crate::outln!("  not refined (--refine-steps 0)"),
    }
    crate::outln!(
        "  mean floor NRMSE of the pure loop: training {} after least squares, {:.3}% kept; \
         validation {}",
        pct(t.least_squares_loss_pct),
        t.train_loss_pct,
        pct(t.validation_loss_pct)
    );
    for r in &t.runs {
        crate::outln!("  trained on {r}");
    }
    crate::outln!("  wall time: {:.1} s", t0.elapsed().as_secs_f64());
    f.save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    crate::outln!("wrote {}", args.out.display());
    Ok(())
}

/// `rths train meta` on an imported structure: its reduced-order modal model
/// ([`crate::machinery::imported::reduced`]), the mode count chosen on the training records, the error bound
/// printed.
fn train_reduced(args: &Args, path: &std::path::Path, text: &str) -> anyhow::Result<()> {
    use crate::machinery::imported::reduced;
    let structure = crate::machinery::imported::ImportedStructure::from_json(text)
        .with_context(|| format!("structure file {}", path.display()))?;
    let rate = args.rate.unwrap_or(rths_core::params::CONTROL_RATE_HZ);
    anyhow::ensure!(
        rths_core::params::CONTROL_RATES_HZ.contains(&rate),
        "--rate must be one of {:?} Hz, got {rate}",
        rths_core::params::CONTROL_RATES_HZ
    );
    let dt_s = rths_core::params::dt_s(rate);
    let records = reduced::training_records(dt_s)?;
    let bar =
        crate::machinery::progress::styled(1, "{msg:40} {bar:30} {pos}/{len} [{elapsed}]", false);
    let start = std::time::Instant::now();
    let choice = args
        .modes
        .map_or(reduced::ModeChoice::ForTarget, reduced::ModeChoice::Fixed);
    let (file, reference) =
        reduced::train_choosing(&structure, &records, dt_s, choice, |stage, done, total| {
            bar.set_message(stage.to_string());
            bar.set_length(total);
            bar.set_position(done);
        })
        .with_context(|| format!("training the reduced model of {}", path.display()))?;
    bar.finish_and_clear();
    std::fs::write(&args.out, file.to_json()?)
        .with_context(|| format!("writing {}", args.out.display()))?;
    let t = &file.training;
    crate::outln!(
        "reduced model of {} ({} DOFs, {} with mass) at {rate} Hz: {} of {} modes kept{} \
         (highest {:.2} Hz, lowest left out {}), static correction at the interface and {} outputs",
        structure.name(),
        file.dofs,
        file.mass_dofs,
        file.modes.len(),
        t.total_modes,
        if args.modes.is_some() {
            " (--modes)"
        } else {
            ""
        },
        file.modes.last().map_or(0.0, |m| m.frequency_hz),
        t.lowest_truncated_hz
            .map_or("none".to_string(), |f| format!("{f:.2} Hz")),
        file.outputs.len()
    );
    crate::outln!("  the training records' runs: {reference}");
    for r in &t.per_record {
        crate::outln!(
            "  {:<12} pure loop vs host FE: interface {:.4} %, largest output {:.4} %",
            r.record,
            r.interface_nrmse_pct,
            r.max_output_nrmse_pct
        );
    }
    crate::outln!(
        "error bound {:.4} % NRMSE (the largest on the training records; target {} %){}; \
         damping coupling {:.2e}; {:.1} s",
        t.error_bound_pct,
        t.target_nrmse_pct,
        match (t.error_bound_pct <= t.target_nrmse_pct, args.modes) {
            (true, _) => String::new(),
            (false, None) => ": TARGET NOT MET with the modes the controller holds".into(),
            (false, Some(r)) => format!(": TARGET NOT MET with the {r} modes asked (--modes)"),
        },
        t.damping_coupling,
        start.elapsed().as_secs_f64()
    );
    crate::outln!("wrote {}", args.out.display());
    Ok(())
}

/// The scoring records of the nonlinear metamodel, as the nonlinear study finds them (embedded in
/// the program, so `--evaluate` runs from any working directory).
const NL_SCORING: [&str; 3] = ["el-centro", "kobe", "morgan"];
/// The peak ductilities it is scored at.
const NL_SCORING_DUCTILITIES: [f64; 3] = [0.8, 2.0, 4.5];

fn evaluate_nonlinear(args: &Args, path: &std::path::Path, text: &str) -> anyhow::Result<()> {
    use rayon::prelude::*;
    use rths_files::hysteron_model_file::AnyNlModel;
    let any =
        AnyNlModel::load(&args.out).with_context(|| format!("model {}", args.out.display()))?;
    let for_structure = || format!("model {} for {}", args.out.display(), path.display());
    any.check_structure(text).with_context(for_structure)?;
    crate::machinery::train::nonlinear::floors::check_model_elastic(&any, text)
        .with_context(for_structure)?;
    let imported = crate::machinery::imported::file::is_imported(text);
    let modal_story = matches!(any, AnyNlModel::Modal(_)) && !imported && !args.hybrid;
    if !modal_story {
        return evaluate_floors(args, path, text, &any);
    }
    let AnyNlModel::Modal(file) = any else {
        anyhow::bail!("unreachable: a modal-hysteretic model expected");
    };
    let s = rths_files::structure_file::Structure::from_json(text)?;
    if !args.histories.is_empty() {
        // Held-out runs of the lab's FE program (e.g. OpenSees's own run of a held-out record):
        // read here, by the scoring, and never by the training. A run given twice would count
        // twice in the median.
        let ordered =
            crate::machinery::train::nonlinear::histories::in_name_order(&args.histories)?;
        let paths: Vec<&std::path::Path> = ordered.iter().map(|p| p.as_path()).collect();
        let units = rths_files::structure_file::StructureFile::parse(text)?.units;
        let runs = crate::machinery::train::nonlinear::histories::read_runs(
            &s,
            &paths,
            crate::machinery::train::nonlinear::histories::recorder_units(units),
            DT_S,
        )?;
        let rows = runs
            .par_iter()
            .map(|r| crate::machinery::train::nonlinear::eval::evaluate_run(&file, &s, r, DT_S))
            .collect::<Result<Vec<_>, _>>()?;
        return print_nl_rows(args, &s, "held-out histories", &rows);
    }
    let motions = NL_SCORING
        .iter()
        .map(|n| crate::studies::nonlinear::study::record(n))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let jobs: Vec<(&crate::machinery::motion::GroundMotion, f64)> = motions
        .iter()
        .flat_map(|m| NL_SCORING_DUCTILITIES.iter().map(move |d| (m, *d)))
        .collect();
    let rows = jobs
        .par_iter()
        .map(|(m, d)| {
            let scale =
                crate::machinery::train::nonlinear::runs::scale_for_ductility(&s, m, *d, DT_S)?;
            crate::machinery::train::nonlinear::eval::evaluate(&file, &s, m, scale, DT_S)
        })
        .collect::<Result<Vec<_>, _>>()?;
    print_nl_rows(args, &s, "FE reference", &rows)
}

/// `--evaluate` of either form in the floors' coordinates (a floor-hysteron model, an imported
/// structure, or `--hybrid`): the pure loop, and with `--hybrid` the hybrid loop, against the
/// held-out histories (or, for a story structure without them, its FE reference on the scoring
/// records at peak ductility 0.8, 2 and 4.5).
fn evaluate_floors(
    args: &Args,
    path: &std::path::Path,
    text: &str,
    any: &rths_files::hysteron_model_file::AnyNlModel,
) -> anyhow::Result<()> {
    use crate::machinery::train::nonlinear::floors::{read_runs, FloorModel, FloorRun};
    use crate::machinery::train::nonlinear::score::Learned;
    use crate::machinery::train::nonlinear::score::LoopScore;
    use crate::studies::nonlinear::held_out::{score_run, HybridRig, ResidualJudgement, RunScore};
    use rayon::prelude::*;
    let fm = FloorModel::from_json(text)?;
    let runs: Vec<FloorRun> = if args.histories.is_empty() {
        anyhow::ensure!(
            fm.stories,
            "--evaluate of {} needs the held-out histories: --histories FILE...",
            path.display()
        );
        let s = rths_files::structure_file::Structure::from_json(text)?;
        anyhow::ensure!(
            s.story_laws().is_some(),
            "--evaluate of {} without --histories needs the structure's own yielding stories \
             (its FE is the reference): give the held-out histories",
            path.display()
        );
        let motions = NL_SCORING
            .iter()
            .map(|n| crate::studies::nonlinear::study::record(n))
            .collect::<anyhow::Result<Vec<_>>>()?;
        let jobs: Vec<(&crate::machinery::motion::GroundMotion, f64)> = motions
            .iter()
            .flat_map(|m| NL_SCORING_DUCTILITIES.iter().map(move |d| (m, *d)))
            .collect();
        jobs.par_iter()
            .map(|(m, d)| -> anyhow::Result<FloorRun> {
                let scale =
                    crate::machinery::train::nonlinear::runs::scale_for_ductility(&s, m, *d, DT_S)?;
                let r = crate::machinery::train::nonlinear::runs::fe_run(&s, m, scale, DT_S)?;
                Ok(FloorRun {
                    label: r.label,
                    specimen_force_kn: Vec::new(),
                    ground_accel_mm_s2: r.ground_accel_mm_s2,
                    floor_disp_mm: r.floor_disp_mm,
                })
            })
            .collect::<anyhow::Result<Vec<_>>>()?
    } else {
        let ordered =
            crate::machinery::train::nonlinear::histories::in_name_order(&args.histories)?;
        let paths: Vec<&std::path::Path> = ordered.iter().map(|p| p.as_path()).collect();
        read_runs(&fm, &paths, DT_S)?
    };
    let model = Learned::of(any, DT_S)?;
    let k_e = fm.specimen_k_kn_per_mm;
    let rig = if args.hybrid {
        Some(HybridRig::identified(
            &fm.name,
            rths_hal_sim::Preset::UnrCompact,
            args.seed,
        )?)
    } else {
        None
    };
    let rows = runs
        .par_iter()
        .map(|r| score_run(&model, k_e, r, rig.as_ref()))
        .collect::<anyhow::Result<Vec<_>>>()?;
    crate::outln!(
        "{} model {} of {} against {} ({} Hz); NRMSE at the interface ({}), residual drift at \
         the story with the largest reference residual:",
        model.form(),
        args.out.display(),
        fm.name,
        if args.histories.is_empty() {
            "the FE reference"
        } else {
            "the held-out histories"
        },
        (1.0 / DT_S).round(),
        fm.columns[fm.specimen_floor]
    );
    crate::outln!("| run | peak interface (mm) | pure NRMSE (%) | pure floors (%) | pure residual error (%) | hybrid NRMSE, measured (%) | hybrid NRMSE, model (%) | hybrid residual error (%) | hybrid / pure | length scale |");
    crate::outln!("|---|---|---|---|---|---|---|---|---|---|");
    let f = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.3}"));
    // Where judged, the story and both residuals too: an error of 100 % is a model at rest at 0
    // or at twice the residual, which a lab reads differently.
    let judged = |j: ResidualJudgement, r: &RunScore, l: &LoopScore| match j {
        ResidualJudgement::Judged(p) => {
            let k = ResidualJudgement::story(&r.residual_ref_mm).unwrap_or(0);
            format!(
                "{p:.3} (story {}: {:.2} mm, model {:.2} mm)",
                k + 1,
                r.residual_ref_mm.get(k).copied().unwrap_or(f64::NAN),
                l.residual_mm.get(k).copied().unwrap_or(f64::NAN)
            )
        }
        ResidualJudgement::Small => "— (under 0.1 mm)".into(),
        ResidualJudgement::NotAtRest {
            residual_mm,
            swing_mm,
        } => format!("not at rest ({residual_mm:.2} mm, swinging {swing_mm:.2} mm)"),
    };
    let (mut pure, mut hyb, mut res_p, mut res_h, mut ratio) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut not_at_rest = 0;
    for r in &rows {
        let floors: Vec<String> = r.pure.floor_nrmse_pct.iter().map(|v| f(*v)).collect();
        let jp = r.residual_error(&r.pure);
        if matches!(jp, ResidualJudgement::NotAtRest { .. }) {
            not_at_rest += 1;
        }
        let rp = jp.pct();
        let (hn, jh) = match &r.hybrid {
            Some(h) if h.stopped.is_none() => (h.interface_nrmse_pct, Some(r.residual_error(h))),
            _ => (None, None),
        };
        let rh = jh.and_then(|j| j.pct());
        let q = match (hn, r.pure.interface_nrmse_pct) {
            (Some(a), Some(b)) if b > 0.0 => Some(a / b),
            _ => None,
        };
        crate::outln!(
            "| {} | {:.1} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.label,
            r.peak_interface_mm,
            f(r.pure.interface_nrmse_pct),
            floors.join(" / "),
            judged(jp, r, &r.pure),
            match &r.hybrid {
                Some(h) => match &h.stopped {
                    Some(why) => format!("stopped ({why})"),
                    None => f(hn),
                },
                None => "—".into(),
            },
            f(r.hybrid.as_ref().and_then(|h| h.model_interface_nrmse_pct)),
            match (jh, &r.hybrid) {
                (Some(j), Some(h)) => judged(j, r, h),
                _ => "—".to_string(),
            },
            f(q),
            r.length_scale
        );
        pure.extend(r.pure.interface_nrmse_pct);
        hyb.extend(hn);
        res_p.extend(rp);
        res_h.extend(rh);
        ratio.extend(q);
    }
    let stat = |v: &mut Vec<f64>| -> String {
        if v.is_empty() {
            return "—".into();
        }
        let med = rths_core::metrics::median(v).unwrap_or(f64::NAN);
        format!("median {med:.3}%, max {:.3}%", v[v.len() - 1])
    };
    crate::outln!(
        "pure loop: NRMSE {}; residual drift error {} ({} of {} runs at rest with a residual of \
         0.1 mm or more{})",
        stat(&mut pure),
        stat(&mut res_p),
        res_p.len(),
        rows.len(),
        if not_at_rest > 0 {
            format!(
                "; {not_at_rest} not at rest: their histories' free vibration is too short for a \
                 residual drift"
            )
        } else {
            String::new()
        }
    );
    if args.hybrid {
        let worst = ratio.iter().copied().fold(f64::NAN, f64::max);
        crate::outln!(
            "hybrid loop (the measured interface): NRMSE {}; residual drift error {}; hybrid / pure \
             at most {worst:.2}",
            stat(&mut hyb),
            stat(&mut res_h)
        );
    }
    Ok(())
}

/// The evaluation table of `rows`, their NRMSE median and max and the worst residual-drift error.
fn print_nl_rows(
    args: &Args,
    s: &rths_files::structure_file::Structure,
    against: &str,
    rows: &[crate::machinery::train::nonlinear::eval::EvalRow],
) -> anyhow::Result<()> {
    crate::outln!(
        "pure loop of {} on {} ({against}, {} Hz):",
        args.out.display(),
        s.name(),
        (1.0 / DT_S).round()
    );
    crate::outln!("| run | ductility FE / model | NRMSE (%) | residual drift FE / model (mm) | first 2 s / rest RMS error (%) |");
    crate::outln!("|---|---|---|---|---|");
    let mut e: Vec<f64> = Vec::new();
    let mut residual_err_pct: f64 = 0.0;
    let (mut judged, mut not_at_rest) = (0, 0);
    for r in rows {
        // The residual drift is judged as the held-out scoring judges it.
        match crate::machinery::structure::ResidualJudgement::of(
            &r.residual_ref_mm,
            &r.residual_ref_swing_mm,
            &r.residual_model_mm,
        ) {
            crate::machinery::structure::ResidualJudgement::Judged(p) => {
                residual_err_pct = residual_err_pct.max(p);
                judged += 1;
            }
            crate::machinery::structure::ResidualJudgement::NotAtRest { .. } => not_at_rest += 1,
            crate::machinery::structure::ResidualJudgement::Small => {}
        }
        let res = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.3}"))
                .collect::<Vec<_>>()
                .join(" / ")
        };
        crate::outln!(
            "| {} | {:.2} / {:.2} | {:.3} | {} vs {} | {:.3} / {:.3} |",
            r.label,
            r.ductility_ref,
            r.ductility_model,
            r.nrmse_pct,
            res(&r.residual_ref_mm),
            res(&r.residual_model_mm),
            r.startup_rms_pct,
            r.rest_rms_pct
        );
        e.push(r.nrmse_pct);
    }
    let med = rths_core::metrics::median(&mut e).unwrap_or(f64::NAN);
    crate::outln!(
        "NRMSE median {:.3}%, max {:.3}%; residual drift error max {residual_err_pct:.1}% \
         ({judged} of {} runs at rest with a residual of 0.1 mm or more{})",
        med,
        e.last().copied().unwrap_or(f64::NAN),
        rows.len(),
        if not_at_rest > 0 {
            format!("; {not_at_rest} not at rest: free vibration too short for a residual drift")
        } else {
            String::new()
        }
    );
    Ok(())
}

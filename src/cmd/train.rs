//! `rths train lr|rnn`: fit a metamodel on the pure response of the prototype and write its model file.

use std::path::PathBuf;

use anyhow::Context;
use rths_core::params::{Prototype, DT_S};

use crate::model_file::{ModelFile, Scores, Training};
use crate::train::{data, lr, rnn};

/// Which metamodel to train.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// Linear regression (paper Eq. 6), SVD least squares.
    Lr,
    /// Elman RNN, truncated BPTT with Adam.
    Rnn,
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
    /// RNN initial-weight seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// RNN maximum epochs (early stopping may end sooner).
    #[arg(long)]
    pub epochs: Option<usize>,
    /// RNN truncated-BPTT window, steps.
    #[arg(long)]
    pub window: Option<usize>,
    /// RNN Adam learning rate.
    #[arg(long)]
    pub learning_rate: Option<f64>,
    /// RNN early-stopping patience, epochs.
    #[arg(long)]
    pub patience: Option<usize>,
    /// RNN: epochs of teacher forcing before training on its own delayed prediction as feedback.
    #[arg(long)]
    pub teacher_epochs: Option<usize>,
    /// LR relative singular-value cut-off.
    #[arg(long, default_value_t = lr::DEFAULT_RCOND)]
    pub rcond: f64,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Output model file (JSON).
    #[arg(long)]
    pub out: PathBuf,
}

fn fmt_opt(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// Run `rths train`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let prototype = Prototype::paper();
    let k_b = prototype.brace_axial_stiffness_kn_per_mm();
    let motion = match &args.motion {
        Some(p) => crate::motion::GroundMotion::from_path(p)
            .with_context(|| format!("reading ground motion {}", p.display()))?,
        None => crate::motion::GroundMotion::try_el_centro()?,
    };
    let motion_name = motion.name.clone();
    let ag = motion.resample_mm_s2(DT_S);
    anyhow::ensure!(!ag.is_empty(), "ground motion {motion_name} is empty");
    let response = data::pure_response(&prototype, &ag, DT_S)?;
    let mut file = match args.kind {
        Kind::Lr => {
            let fit = lr::fit_pure(&response, args.delay_steps, k_b, args.rcond)?;
            let s = &fit.solution;
            println!(
                "LR fit on {motion_name} ({} steps, delay {} steps)",
                response.len(),
                args.delay_steps
            );
            for (name, t) in crate::model_file::LR_FEATURES.iter().zip(&s.theta) {
                println!("  {name:<20} {t:+.10e}");
            }
            println!(
                "  condition number (normalized, before cut-off): {:.3e}",
                s.condition_number
            );
            println!(
                "  effective rank: {} of {} (rcond {:e})",
                s.effective_rank,
                s.theta.len(),
                args.rcond
            );
            println!("  train NRMSE (one step): {:.3e}%", fit.train_nrmse_pct);
            println!("  lr-pure NRMSE: {:.4}% (paper 0.15%)", fit.pure_nrmse_pct);
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
            let mut cfg = rnn::RnnConfig::new(args.hidden);
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
            let t = rnn::train(&response, k_b, &cfg)?;
            println!(
                "RNN H={} on {motion_name} ({} steps, delay {} steps, seed {})",
                args.hidden,
                response.len(),
                args.delay_steps,
                args.seed
            );
            println!(
                "  epochs: {} (best {}), best validation loss {:.4e}",
                t.epochs, t.best_epoch, t.best_validation_loss
            );
            println!("  train NRMSE (teacher forcing): {:.3}%", t.train_nrmse_pct);
            println!("  rnn-pure NRMSE: {:.3}%", t.pure_nrmse_pct);
            println!("  wall time: {:.1} s", t.wall_time_s);
            let mut f = ModelFile::new_rnn(t.model.to_weights(), args.delay_steps, DT_S);
            f.training = Training {
                motion: motion_name,
                records: response.len(),
                phase: 1,
                method: "tbptt-adam".into(),
                seed: Some(args.seed),
                epochs: Some(t.epochs),
                best_epoch: Some(t.best_epoch),
                window_steps: Some(cfg.window_steps),
                learning_rate: Some(cfg.learning_rate),
                ..Training::default()
            };
            f.scores = Scores {
                train_nrmse_pct: Some(t.train_nrmse_pct),
                pure_nrmse_pct: Some(t.pure_nrmse_pct),
                best_validation_loss: Some(t.best_validation_loss),
                ..Scores::default()
            };
            f
        }
    };
    file.training.records = response.len();
    file.save(&args.out)
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!("wrote {}", args.out.display());
    Ok(())
}

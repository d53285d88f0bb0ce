//! `rths check-model FILE`: validate a model file the way the controller will load it, and say why it
//! is rejected (exit status 1) or summarize it (exit status 0).

use std::fmt::Write as _;
use std::path::PathBuf;

use crate::model_file::{ModelFile, ModelKind};
use crate::models;

/// A model kind on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModelKindArg {
    /// Linear regression.
    Lr,
    /// Elman RNN.
    Rnn,
    /// Specimen-faithful frame metamodel.
    Lrx,
}

impl From<ModelKindArg> for ModelKind {
    fn from(k: ModelKindArg) -> Self {
        match k {
            ModelKindArg::Lr => ModelKind::Lr,
            ModelKindArg::Rnn => ModelKind::Rnn,
            ModelKindArg::Lrx => ModelKind::Lrx,
        }
    }
}

/// Arguments of `rths check-model`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The model file (JSON, `rths train` output).
    pub file: PathBuf,
    /// Also require this kind of model.
    #[arg(long, value_enum)]
    pub kind: Option<ModelKindArg>,
}

/// Why a model file is rejected: the file and the loader's reason.
#[derive(Debug, thiserror::Error)]
#[error("{path}: rejected: {reason}")]
pub struct Rejected {
    /// The file.
    pub path: String,
    /// The reason, as the loader gives it.
    pub reason: String,
}

/// Validate `path` as a model file (format, version, features, shapes, finite weights, and the
/// controller's own parameter checks); a summary of the model if it is accepted.
pub fn check(path: &std::path::Path, kind: Option<ModelKind>) -> Result<String, Rejected> {
    let reject = |reason: String| Rejected {
        path: path.display().to_string(),
        reason,
    };
    let m = ModelFile::load(path).map_err(|e| reject(e.to_string()))?;
    if let Some(k) = kind {
        m.expect_kind(k).map_err(|e| reject(e.to_string()))?;
    }
    if m.delay_steps > rths_core::control::MAX_DELAY_STEPS {
        return Err(reject(format!(
            "delay_steps {} exceeds the controller's maximum {}",
            m.delay_steps,
            rths_core::control::MAX_DELAY_STEPS
        )));
    }
    let mut s = String::new();
    let _ = writeln!(s, "{}: valid rths model file", path.display());
    let _ = writeln!(s, "format / version  {} / {}", m.format, m.version);
    let _ = writeln!(s, "kind              {}", m.kind);
    let _ = writeln!(s, "features          {}", m.features.join(", "));
    let _ = writeln!(s, "delay_steps       {}", m.delay_steps);
    let _ = writeln!(s, "dt_s              {:e}", m.dt_s);
    match m.kind {
        ModelKind::Lr => {
            models::lr_params(&m).map_err(|e| reject(e.to_string()))?;
            if let Some(w) = &m.lr {
                let _ = writeln!(s, "theta             {:?}", w.theta);
            }
        }
        ModelKind::Rnn => {
            models::rnn_params(&m).map_err(|e| reject(e.to_string()))?;
            if let Some(w) = &m.rnn {
                let _ = writeln!(s, "hidden            {}", w.hidden);
            }
        }
        ModelKind::Lrx => {
            models::lrx_params(&m).map_err(|e| reject(e.to_string()))?;
            if let Some(w) = &m.lrx {
                let _ = writeln!(s, "frame ARX         {:?}", w.coeffs);
                let _ = writeln!(
                    s,
                    "lead filter       {} taps every {} ticks",
                    w.lead_weights.len(),
                    w.lead_stride
                );
            }
        }
    }
    let t = &m.training;
    let _ = writeln!(
        s,
        "training          {} ({} records), phase {}, {}",
        t.motion, t.records, t.phase, t.method
    );
    let opt = |x: Option<f64>| x.map_or("—".to_string(), |v| format!("{v:.4} %"));
    let _ = writeln!(
        s,
        "scores            train NRMSE {}, pure NRMSE {}",
        opt(m.scores.train_nrmse_pct),
        opt(m.scores.pure_nrmse_pct)
    );
    Ok(s)
}

/// Print the summary, or fail with the reason.
pub fn run(args: Args) -> anyhow::Result<()> {
    let summary = check(&args.file, args.kind.map(ModelKind::from))?;
    crate::out!("{summary}");
    Ok(())
}

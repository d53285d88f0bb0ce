//! `rths check-model FILE`: validate a model file of any kind (LR, RNN, LRX, the structure
//! metamodel of `rths train meta`, the nonlinear model of `rths train nonlinear`) the way the
//! controller will load it, and say why it is rejected (exit status 1) or summarize it (exit 0).

use std::fmt::Write as _;
use std::path::PathBuf;

use crate::machinery::model_file::{ModelFile, ModelKind};
use crate::machinery::models;

/// A model kind on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModelKindArg {
    /// Linear regression.
    Lr,
    /// Elman RNN.
    Rnn,
    /// Specimen-faithful frame metamodel.
    Lrx,
    /// Structure metamodel (`rths train meta`).
    Meta,
    /// Nonlinear modal-hysteretic metamodel (`rths train nonlinear`).
    Nonlinear,
    /// Nonlinear floor-hysteron metamodel (`rths train nonlinear`, `--form floor-hysteron`).
    FloorHysteron,
}

impl ModelKindArg {
    /// The kind as the file names it (`lr`, `rnn`, `lrx`, `structure-meta`, `modal-hysteretic`).
    pub fn file_kind(self) -> &'static str {
        match self {
            ModelKindArg::Lr => "lr",
            ModelKindArg::Rnn => "rnn",
            ModelKindArg::Lrx => "lrx",
            ModelKindArg::Meta => rths_files::structure_meta::META_KIND,
            ModelKindArg::Nonlinear => rths_files::nl_model_file::NL_KIND,
            ModelKindArg::FloorHysteron => rths_files::hysteron_model_file::HYSTERON_KIND,
        }
    }
}

/// The `format` and `kind` tags of any model file, read first to pick its reader.
#[derive(serde::Deserialize)]
struct Tags {
    format: Option<String>,
    kind: Option<String>,
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

/// The lines every learned (nonlinear) model's summary starts with.
fn learned_header(
    s: &mut String,
    format: &str,
    version: u64,
    kind: &str,
    structure: &rths_files::nl_model_file::NlStructureId,
    dt_s: f64,
) {
    let _ = writeln!(s, "format / version  {format} / {version}");
    let _ = writeln!(s, "kind              {kind}");
    let _ = writeln!(
        s,
        "structure         {} ({})",
        structure.name, structure.checksum
    );
    let _ = writeln!(s, "dt_s              {dt_s:e}");
}

/// Validate `path` as a model file of any kind (its `format` and `kind` tags pick the reader; the
/// same checks as the commands that run it: [`models::check_for_controller`] for LR, RNN and LRX,
/// [`crate::machinery::structure::model::check_rate`] for the nonlinear model); a summary if it is accepted.
pub fn check(path: &std::path::Path, kind: Option<ModelKindArg>) -> Result<String, Rejected> {
    let reject = |reason: String| Rejected {
        path: path.display().to_string(),
        reason,
    };
    let text = std::fs::read_to_string(path)
        .map_err(|e| reject(format!("cannot access model file: {e}")))?;
    let tags: Tags =
        serde_json::from_str(&text).map_err(|e| reject(format!("malformed model file: {e}")))?;
    if rths_files::reduced_model_file::ReducedModelFile::is_reduced(&text) {
        return check_reduced(path, &text, kind).map_err(reject);
    }
    let file_kind = tags.kind.unwrap_or_default();
    if let Some(k) = kind {
        if file_kind != k.file_kind() {
            return Err(reject(format!(
                "wrong model kind: expected {}, file holds {file_kind}",
                k.file_kind()
            )));
        }
    }
    let mut s = String::new();
    let _ = writeln!(s, "{}: valid rths model file", path.display());
    match (tags.format.as_deref(), file_kind.as_str()) {
        (
            Some(rths_files::nl_model_file::NL_FORMAT),
            rths_files::hysteron_model_file::HYSTERON_KIND,
        ) => {
            let m = rths_files::hysteron_model_file::HysteronModelFile::from_json(&text)
                .map_err(|e| reject(e.to_string()))?;
            rths_files::rate::check_dt(
                "the nonlinear model",
                m.dt_s,
                rths_core::params::DT_S,
                &format!(
                    "rths train nonlinear --structure {}.json --histories ... --out FILE",
                    m.structure.name
                ),
            )
            .map_err(|e| reject(e.to_string()))?;
            learned_header(&mut s, &m.format, m.version, &m.kind, &m.structure, m.dt_s);
            let _ = writeln!(
                s,
                "floors / directions / hysterons   {} / {} / {}",
                m.floors.len(),
                m.directions.len(),
                m.hysterons.len()
            );
            return Ok(s);
        }
        (Some(rths_files::nl_model_file::NL_FORMAT), _) => {
            let m = rths_files::nl_model_file::NlModelFile::from_json(&text)
                .map_err(|e| reject(e.to_string()))?;
            crate::machinery::structure::model::check_rate(&m)
                .map_err(|e| reject(e.to_string()))?;
            learned_header(&mut s, &m.format, m.version, &m.kind, &m.structure, m.dt_s);
            let _ = writeln!(
                s,
                "modes / springs   {} / {}",
                m.modes.len(),
                m.springs.len()
            );
            return Ok(s);
        }
        (
            Some(crate::machinery::model_file::MODEL_FORMAT),
            rths_files::structure_meta::META_KIND,
        ) => {
            let m = rths_files::structure_meta::MetaFile::from_json(&text)
                .map_err(|e| reject(e.to_string()))?;
            m.params().map_err(|e| reject(e.to_string()))?;
            m.check_rate(rths_core::params::DT_S)
                .map_err(|e| reject(e.to_string()))?;
            let _ = writeln!(s, "format / version  {} / {}", m.format, m.version);
            let _ = writeln!(s, "kind              {}", m.kind);
            let _ = writeln!(
                s,
                "structure         {} ({}); run with that structure file only",
                m.structure.name, m.structure.checksum
            );
            let _ = writeln!(s, "dt_s              {:e} ({:.0} Hz)", m.dt_s, 1.0 / m.dt_s);
            let _ = writeln!(s, "order             {}", m.order);
            return Ok(s);
        }
        _ => {}
    }
    let m = ModelFile::from_json(&text).map_err(|e| reject(e.to_string()))?;
    models::check_for_controller(&m).map_err(|e| reject(e.to_string()))?;
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

/// The reduced-order model `rths train meta` writes for an imported structure: its arrays, checked
/// as the controller builds them at its step (the structure's checksum needs the structure file:
/// `rths simulate --structure S --scenario meta-pure --model FILE` checks it too).
fn check_reduced(
    path: &std::path::Path,
    text: &str,
    kind: Option<ModelKindArg>,
) -> Result<String, String> {
    use rths_files::reduced_model_file::ReducedModelFile;
    if let Some(k) = kind.filter(|k| *k != ModelKindArg::Meta) {
        return Err(format!(
            "wrong model kind: expected {}, file holds a reduced model (meta)",
            k.file_kind()
        ));
    }
    let m = ReducedModelFile::from_json(text).map_err(|e| e.to_string())?;
    m.check_rate(rths_core::params::DT_S)
        .map_err(|e| e.to_string())?;
    let a = m.arrays().map_err(|e| e.to_string())?;
    a.spec()
        .params(rths_core::params::DT_S)
        .map_err(|e| format!("the reduced model's parameters: {e}"))?;
    let mut s = String::new();
    let _ = writeln!(s, "{}: valid rths model file", path.display());
    let _ = writeln!(s, "format / version  {} / {}", m.format, m.version);
    let _ = writeln!(
        s,
        "structure         {} ({}); run with that structure file only",
        m.structure, m.structure_checksum
    );
    let _ = writeln!(
        s,
        "modes / outputs   {} / {}",
        m.modes.len(),
        m.outputs.len()
    );
    Ok(s)
}

/// Print the summary, or fail with the reason.
pub fn run(args: Args) -> anyhow::Result<()> {
    let summary = check(&args.file, args.kind)?;
    crate::out!("{summary}");
    Ok(())
}

//! Trained metamodel files: versioned JSON, validated on load.
//!
//! ```json
//! {"format": "rths-model", "version": 1, "kind": "lr" | "rnn" | "lrx", "features": [...],
//!  "delay_steps": 28, "dt_s": 0.00048828125,
//!  "lr": {"theta": [6 numbers]}            (kind "lr")
//!  "rnn": {"hidden": H, "w_ih": [[2]; H], "w_hh": [[H]; H], "b_h": [H], "w_ho": [H], "b_o": x,
//!          "input_mean": [2], "input_std": [2], "output_mean": x, "output_std": x}   (kind "rnn")
//!  "lrx": {"coeffs": [9], "k_corr_kn_per_mm": x, "k_adapt_ticks": x, "lead_weights": [8],
//!          "lead_stride": s, ["lead_adapt_ticks": x, "specimen_mass_kn_s2_per_mm": x,
//!          "specimen_damping_kn_s_per_mm": x]}                                         (kind "lrx")
//!  "training": {...provenance...}, "scores": {...}}
//! ```
//!
//! `features` names the coefficients (or inputs) in order; the names are `rths_core`'s
//! ([`LR_FEATURES`], [`RNN_FEATURES`], [`LRX_FEATURES`]) and every loader checks them.
//!
//! [`ModelFile::load`] checks the format tag and version first (so a future file gives a version
//! error, not a confusing field error), then every shape and every weight, and returns a
//! [`ModelFileError`] that names the field.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// The `format` tag of every model file.
pub const MODEL_FORMAT: &str = "rths-model";
/// The model-file version this code reads and writes.
pub const MODEL_VERSION: u64 = 1;
/// Largest RNN hidden size accepted (the `no_std` inference uses fixed-capacity buffers).
pub const MAX_HIDDEN: usize = rths_core::metamodel::RNN_MAX_HIDDEN;

// The name lists are core's: the order the `no_std` inference takes its coefficients in is the
// one truth, so a file written by `rths train` and checked by every loader names exactly it.

/// Feature order of the LR model (paper Eq. 6 with a bias), the order of `theta`
/// (`rths_core::metamodel::LR_FEATURE_NAMES`).
pub const LR_FEATURES: [&str; 6] = rths_core::metamodel::LR_FEATURE_NAMES;
/// Input order of the RNN, the columns of `w_ih`, `input_mean`, `input_std`
/// (`rths_core::metamodel::RNN_INPUT_NAMES`).
pub const RNN_FEATURES: [&str; 2] = rths_core::metamodel::RNN_INPUT_NAMES;
/// Coefficient order of the LRX model, the order of `lrx.coeffs`
/// (`rths_core::metamodel::LRX_FEATURE_NAMES`).
pub const LRX_FEATURES: [&str; 9] = rths_core::metamodel::LRX_FEATURE_NAMES;
/// Taps of the LRX lead filter.
pub const LRX_LEAD_TAPS: usize = rths_core::compensator::LEAD_TAPS;
/// Largest lead-filter tap spacing, ticks.
pub const LRX_MAX_STRIDE: usize = rths_core::compensator::LEAD_MAX_STRIDE;

/// The feature names a model file of `kind` must carry, in order.
pub fn feature_names(kind: ModelKind) -> &'static [&'static str] {
    match kind {
        ModelKind::Lr => &LR_FEATURES,
        ModelKind::Rnn => &RNN_FEATURES,
        ModelKind::Lrx => &LRX_FEATURES,
    }
}

/// The kinds of metamodel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// Linear regression (paper Eq. 6).
    Lr,
    /// Elman recurrent network.
    Rnn,
    /// Specimen-faithful linear metamodel of the frame alone, with a learned lead filter.
    Lrx,
}

impl std::fmt::Display for ModelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ModelKind::Lr => "lr",
            ModelKind::Rnn => "rnn",
            ModelKind::Lrx => "lrx",
        })
    }
}

/// LR coefficients, in [`LR_FEATURES`] order: `x̂(i+1) = θ·[1, ü_g(i), x_fb(i), F_fb(i), x̂(i), x̂(i−1)]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LrWeights {
    /// θ0..θ5.
    pub theta: Vec<f64>,
}

/// Elman RNN weights and scaling. With `in_k = (raw_k − input_mean[k]) / input_std[k]`:
/// `h_j ← tanh(w_ih[j]·in + w_hh[j]·h + b_h[j])`, all `h_j` from the previous `h`;
/// `y = w_ho·h + b_o`; `x̂(i+1) = y·output_std + output_mean` (mm). Order of operations (so that
/// every implementation gives the same bits, as `rths_core::metamodel::Rnn` does): pre-activation
/// `(Σ_k w_ih[j][k]·in_k + Σ_k w_hh[j][k]·h_k) + b_h[j]`, each sum in index order, `tanh` is
/// `libm::tanh`; output `(Σ_j w_ho[j]·h_j) + b_o`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RnnWeights {
    /// Hidden size H.
    pub hidden: usize,
    /// Input weights, H rows of 2.
    pub w_ih: Vec<Vec<f64>>,
    /// Recurrent weights, H × H.
    pub w_hh: Vec<Vec<f64>>,
    /// Hidden bias, H.
    pub b_h: Vec<f64>,
    /// Output weights, H.
    pub w_ho: Vec<f64>,
    /// Output bias.
    pub b_o: f64,
    /// Input means (ü_g mm/s², F_fb kN).
    pub input_mean: Vec<f64>,
    /// Input standard deviations (positive).
    pub input_std: Vec<f64>,
    /// Output mean, mm.
    pub output_mean: f64,
    /// Output standard deviation, mm (positive).
    pub output_std: f64,
}

/// LRX weights. Frame ARX (coefficients in [`LRX_FEATURES`] order):
/// `d̂(i+1) = Σ_j a_j·d̂(i−j) + Σ_j b_j·ü_g(i−j) + Σ_j c_j·F̃(i−j)` with the corrected force
/// `F̃(i) = F_fb(i) + k_corr·(d̂(i) − x_fb(i))`; lead filter (the command, specimen scale):
/// `u = Σ_i lead_weights[i]·x_t(k − i·lead_stride)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LrxWeights {
    /// a0..a2, b0..b2, c0..c2.
    pub coeffs: Vec<f64>,
    /// Nominal force-correction stiffness, kN/mm (prototype brace axial; ≥ 0).
    pub k_corr_kn_per_mm: f64,
    /// Time constant of the online stiffness estimate, ticks (0: fixed at nominal; else ≥ 1).
    pub k_adapt_ticks: f64,
    /// Lead-filter weights, newest tap first.
    pub lead_weights: Vec<f64>,
    /// Lead-filter tap spacing, ticks (1..=8).
    pub lead_stride: usize,
    /// Time constant of the lead's online gain-and-delay correction, ticks (0 or absent: the lead is
    /// fixed, as in files written before the adaptation; else 32..=1e7). Absent fields are not
    /// written, so a model trained without adaptation keeps its old file byte for byte.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lead_adapt_ticks: Option<f64>,
    /// The specimen's own moving mass removed from the measured force, prototype scale, kN·s²/mm
    /// (≥ 0; absent: 0, the force as measured). From `rths identify`'s specimen fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub specimen_mass_kn_s2_per_mm: Option<f64>,
    /// The specimen's own damping removed from the measured force, prototype scale, kN·s/mm (≥ 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub specimen_damping_kn_s_per_mm: Option<f64>,
}

impl LrxWeights {
    /// Check shapes, finiteness and ranges.
    pub fn validate(&self) -> Result<(), ModelFileError> {
        shape("lrx.coeffs", LRX_FEATURES.len(), self.coeffs.len())?;
        finite("lrx.coeffs", &self.coeffs)?;
        finite("lrx.k_corr_kn_per_mm", &[self.k_corr_kn_per_mm])?;
        if self.k_corr_kn_per_mm < 0.0 {
            return Err(ModelFileError::NonPositive {
                field: "lrx.k_corr_kn_per_mm".into(),
                value: self.k_corr_kn_per_mm,
            });
        }
        finite("lrx.k_adapt_ticks", &[self.k_adapt_ticks])?;
        if self.k_adapt_ticks != 0.0 && self.k_adapt_ticks < 1.0 {
            return Err(ModelFileError::NonPositive {
                field: "lrx.k_adapt_ticks (0 or >= 1)".into(),
                value: self.k_adapt_ticks,
            });
        }
        shape("lrx.lead_weights", LRX_LEAD_TAPS, self.lead_weights.len())?;
        finite("lrx.lead_weights", &self.lead_weights)?;
        if !(1..=LRX_MAX_STRIDE).contains(&self.lead_stride) {
            return Err(ModelFileError::WrongShape {
                field: "lrx.lead_stride (1..=8)".into(),
                expected: LRX_MAX_STRIDE,
                found: self.lead_stride,
            });
        }
        for (field, v) in [
            (
                "lrx.specimen_mass_kn_s2_per_mm",
                self.specimen_mass_kn_s2_per_mm,
            ),
            (
                "lrx.specimen_damping_kn_s_per_mm",
                self.specimen_damping_kn_s_per_mm,
            ),
        ] {
            if let Some(v) = v {
                finite(field, &[v])?;
                if v < 0.0 {
                    return Err(ModelFileError::NonPositive {
                        field: format!("{field} (>= 0)"),
                        value: v,
                    });
                }
            }
        }
        if let Some(t) = self.lead_adapt_ticks {
            finite("lrx.lead_adapt_ticks", &[t])?;
            if t != 0.0 && !(32.0..=1.0e7).contains(&t) {
                return Err(ModelFileError::NonPositive {
                    field: "lrx.lead_adapt_ticks (0 or 32..=1e7)".into(),
                    value: t,
                });
            }
        }
        Ok(())
    }
}

/// Where a model came from (no dates, so a retrain with the same inputs gives the same file).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Training {
    /// Ground motion used (file name or "el-centro").
    pub motion: String,
    /// Number of time steps in the training record.
    pub records: usize,
    /// Training phase (1: synthetic delayed feedback from the pure model; 2: recorded feedback).
    pub phase: u32,
    /// Fitting method, e.g. "svd-least-squares" or "tbptt-adam".
    pub method: String,
    /// RNG seed (RNN).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Epochs run (RNN).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub epochs: Option<usize>,
    /// Epoch of the best validation loss, whose weights were kept (RNN).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub best_epoch: Option<usize>,
    /// Truncated-BPTT window, steps (RNN).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window_steps: Option<usize>,
    /// Adam learning rate (RNN).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub learning_rate: Option<f64>,
    /// Relative singular-value cut-off of the LR least squares.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub svd_rcond: Option<f64>,
    /// The rig file the LRX lead filter was taken from (`rths identify`): preset, board and a
    /// checksum of the file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rig: Option<String>,
}

/// Fit quality. `null` where not applicable or not finite (JSON has no infinity).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Scores {
    /// NRMSE (%) of one-step predictions on the training data (teacher forcing).
    #[serde(default)]
    pub train_nrmse_pct: Option<f64>,
    /// NRMSE (%) of the model run on its own delayed predictions (`lr-pure` / `rnn-pure`).
    #[serde(default)]
    pub pure_nrmse_pct: Option<f64>,
    /// Condition number of the column-normalized LR design matrix, before the cut-off.
    #[serde(default)]
    pub lr_condition_number: Option<f64>,
    /// Effective rank kept by the cut-off.
    #[serde(default)]
    pub lr_effective_rank: Option<usize>,
    /// Best validation loss (normalized MSE) of the RNN.
    #[serde(default)]
    pub best_validation_loss: Option<f64>,
}

/// A whole model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelFile {
    /// Always [`MODEL_FORMAT`].
    pub format: String,
    /// Always [`MODEL_VERSION`].
    pub version: u64,
    /// Which model.
    pub kind: ModelKind,
    /// Input feature names ([`LR_FEATURES`] or [`RNN_FEATURES`]).
    pub features: Vec<String>,
    /// Delay of the feedback, steps.
    pub delay_steps: usize,
    /// Time step the model runs at, s.
    pub dt_s: f64,
    /// LR coefficients (kind "lr").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lr: Option<LrWeights>,
    /// RNN weights (kind "rnn").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rnn: Option<RnnWeights>,
    /// LRX weights (kind "lrx").
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lrx: Option<LrxWeights>,
    /// Provenance.
    #[serde(default)]
    pub training: Training,
    /// Scores.
    #[serde(default)]
    pub scores: Scores,
}

/// The one check of a feedback delay, ticks (model files, `rths train --delay-steps`): at most
/// [`rths_core::control::MAX_DELAY_STEPS`], what the controller's ring holds.
pub fn check_delay_steps(delay_steps: usize) -> Result<(), ModelFileError> {
    let max = rths_core::control::MAX_DELAY_STEPS;
    if delay_steps > max {
        return Err(ModelFileError::DelayTooLong {
            found: delay_steps,
            max,
        });
    }
    Ok(())
}

/// Why a model file was rejected.
#[derive(Debug, thiserror::Error)]
pub enum ModelFileError {
    /// Reading or writing failed.
    #[error("cannot access model file {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Not JSON, or not the expected structure (serde's message carries line and column).
    #[error("malformed model file: {0}")]
    Json(#[from] serde_json::Error),
    /// `format` is not "rths-model".
    #[error("unknown model format {found:?} (expected \"{MODEL_FORMAT}\")")]
    UnknownFormat {
        /// The tag found (empty if absent).
        found: String,
    },
    /// `version` is not supported.
    #[error("unsupported model file version {found} (this build reads version {MODEL_VERSION})")]
    UnsupportedVersion {
        /// The version found.
        found: u64,
    },
    /// The file holds another kind of model than asked for.
    #[error("wrong model kind: expected {expected}, file holds {found}")]
    WrongKind {
        /// Kind asked for.
        expected: ModelKind,
        /// Kind in the file.
        found: ModelKind,
    },
    /// The weights section of the declared kind is missing.
    #[error("model kind {kind} but the \"{kind}\" section is missing")]
    MissingSection {
        /// The declared kind.
        kind: ModelKind,
    },
    /// An array has the wrong length.
    #[error("wrong shape of {field}: expected {expected}, found {found}")]
    WrongShape {
        /// Field path, e.g. `rnn.w_hh[3]`.
        field: String,
        /// Expected length.
        expected: usize,
        /// Length found.
        found: usize,
    },
    /// The RNN hidden size is out of range.
    #[error("rnn.hidden must be in 1..={MAX_HIDDEN}, found {0}")]
    BadHidden(usize),
    /// A weight or scale is NaN or infinite.
    #[error("non-finite value in {field} at index {index}")]
    NonFinite {
        /// Field path.
        field: String,
        /// Flat index within the field.
        index: usize,
    },
    /// A scale (standard deviation) or the time step is not positive.
    #[error("{field} must be positive, found {value}")]
    NonPositive {
        /// Field path.
        field: String,
        /// Value found.
        value: f64,
    },
    /// The feedback delay is longer than the controller's ring holds.
    #[error(
        "delay_steps {found} exceeds the controller's maximum {max} (rths_core::control::\
         MAX_DELAY_STEPS)"
    )]
    DelayTooLong {
        /// The file's delay, ticks.
        found: usize,
        /// [`rths_core::control::MAX_DELAY_STEPS`].
        max: usize,
    },
    /// The feature list differs from what the kind requires.
    #[error(
        "feature names of a {kind} model: expected {expected:?} (the order rths-core's inference \
         takes), found {found:?}"
    )]
    FeatureMismatch {
        /// The model kind.
        kind: ModelKind,
        /// Required features.
        expected: Vec<String>,
        /// Features in the file.
        found: Vec<String>,
    },
}

#[derive(Deserialize)]
struct Header {
    #[serde(default)]
    format: Option<String>,
    #[serde(default)]
    version: Option<u64>,
}

fn shape(field: &str, expected: usize, found: usize) -> Result<(), ModelFileError> {
    if expected == found {
        Ok(())
    } else {
        Err(ModelFileError::WrongShape {
            field: field.to_string(),
            expected,
            found,
        })
    }
}

fn finite(field: &str, values: &[f64]) -> Result<(), ModelFileError> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(index) => Err(ModelFileError::NonFinite {
            field: field.to_string(),
            index,
        }),
    }
}

fn positive(field: &str, values: &[f64]) -> Result<(), ModelFileError> {
    finite(field, values)?;
    match values.iter().find(|v| **v <= 0.0) {
        None => Ok(()),
        Some(&value) => Err(ModelFileError::NonPositive {
            field: field.to_string(),
            value,
        }),
    }
}

/// Check the `features` list of a `kind` model against [`feature_names`].
pub fn check_features(kind: ModelKind, found: &[String]) -> Result<(), ModelFileError> {
    let expected = feature_names(kind);
    if expected.len() == found.len() && expected.iter().zip(found).all(|(a, b)| a == b) {
        Ok(())
    } else {
        Err(ModelFileError::FeatureMismatch {
            kind,
            expected: expected.iter().map(|s| s.to_string()).collect(),
            found: found.to_vec(),
        })
    }
}

impl LrWeights {
    /// Check shape and finiteness.
    pub fn validate(&self) -> Result<(), ModelFileError> {
        shape("lr.theta", LR_FEATURES.len(), self.theta.len())?;
        finite("lr.theta", &self.theta)
    }
}

impl RnnWeights {
    /// Check every shape, finiteness and positive scales.
    pub fn validate(&self) -> Result<(), ModelFileError> {
        let h = self.hidden;
        if h == 0 || h > MAX_HIDDEN {
            return Err(ModelFileError::BadHidden(h));
        }
        let n_in = RNN_FEATURES.len();
        shape("rnn.w_ih", h, self.w_ih.len())?;
        for (j, row) in self.w_ih.iter().enumerate() {
            let f = format!("rnn.w_ih[{j}]");
            shape(&f, n_in, row.len())?;
            finite(&f, row)?;
        }
        shape("rnn.w_hh", h, self.w_hh.len())?;
        for (j, row) in self.w_hh.iter().enumerate() {
            let f = format!("rnn.w_hh[{j}]");
            shape(&f, h, row.len())?;
            finite(&f, row)?;
        }
        shape("rnn.b_h", h, self.b_h.len())?;
        finite("rnn.b_h", &self.b_h)?;
        shape("rnn.w_ho", h, self.w_ho.len())?;
        finite("rnn.w_ho", &self.w_ho)?;
        finite("rnn.b_o", &[self.b_o])?;
        shape("rnn.input_mean", n_in, self.input_mean.len())?;
        finite("rnn.input_mean", &self.input_mean)?;
        shape("rnn.input_std", n_in, self.input_std.len())?;
        positive("rnn.input_std", &self.input_std)?;
        finite("rnn.output_mean", &[self.output_mean])?;
        positive("rnn.output_std", &[self.output_std])
    }
}

impl ModelFile {
    /// A new LR model file (format and version filled in).
    pub fn new_lr(theta: Vec<f64>, delay_steps: usize, dt_s: f64) -> Self {
        Self::new(
            ModelKind::Lr,
            delay_steps,
            dt_s,
            Some(LrWeights { theta }),
            None,
        )
    }

    /// A new RNN model file (format and version filled in).
    pub fn new_rnn(weights: RnnWeights, delay_steps: usize, dt_s: f64) -> Self {
        Self::new(ModelKind::Rnn, delay_steps, dt_s, None, Some(weights))
    }

    /// A new LRX model file (format and version filled in).
    pub fn new_lrx(weights: LrxWeights, delay_steps: usize, dt_s: f64) -> Self {
        let mut m = Self::new(ModelKind::Lrx, delay_steps, dt_s, None, None);
        m.lrx = Some(weights);
        m
    }

    fn new(
        kind: ModelKind,
        delay_steps: usize,
        dt_s: f64,
        lr: Option<LrWeights>,
        rnn: Option<RnnWeights>,
    ) -> Self {
        let names = feature_names(kind);
        Self {
            format: MODEL_FORMAT.to_string(),
            version: MODEL_VERSION,
            kind,
            features: names.iter().map(|s| s.to_string()).collect(),
            delay_steps,
            dt_s,
            lr,
            rnn,
            lrx: None,
            training: Training::default(),
            scores: Scores::default(),
        }
    }

    /// Check the whole file: format, version, features, time step and the weights of its kind.
    pub fn validate(&self) -> Result<(), ModelFileError> {
        if self.format != MODEL_FORMAT {
            return Err(ModelFileError::UnknownFormat {
                found: self.format.clone(),
            });
        }
        if self.version != MODEL_VERSION {
            return Err(ModelFileError::UnsupportedVersion {
                found: self.version,
            });
        }
        positive("dt_s", &[self.dt_s])?;
        check_delay_steps(self.delay_steps)?;
        check_features(self.kind, &self.features)?;
        match self.kind {
            ModelKind::Lr => self
                .lr
                .as_ref()
                .ok_or(ModelFileError::MissingSection { kind: self.kind })?
                .validate(),
            ModelKind::Rnn => self
                .rnn
                .as_ref()
                .ok_or(ModelFileError::MissingSection { kind: self.kind })?
                .validate(),
            ModelKind::Lrx => self
                .lrx
                .as_ref()
                .ok_or(ModelFileError::MissingSection { kind: self.kind })?
                .validate(),
        }
    }

    /// Parse and validate a model from JSON text.
    pub fn from_json(text: &str) -> Result<Self, ModelFileError> {
        // Format and version first: a newer file must say so, not fail on a renamed field.
        let header: Header = serde_json::from_str(text)?;
        let format = header.format.unwrap_or_default();
        if format != MODEL_FORMAT {
            return Err(ModelFileError::UnknownFormat { found: format });
        }
        let version = header.version.unwrap_or(0);
        if version != MODEL_VERSION {
            return Err(ModelFileError::UnsupportedVersion { found: version });
        }
        let model: ModelFile = serde_json::from_str(text)?;
        model.validate()?;
        Ok(model)
    }

    /// Pretty JSON of a validated model.
    pub fn to_json(&self) -> Result<String, ModelFileError> {
        self.validate()?;
        Ok(serde_json::to_string_pretty(self)?)
    }

    /// Read and validate a model file of any kind.
    pub fn load(path: &Path) -> Result<Self, ModelFileError> {
        let text = std::fs::read_to_string(path).map_err(|source| ModelFileError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::from_json(&text)
    }

    /// Read a model file that must hold `kind`.
    pub fn load_kind(path: &Path, kind: ModelKind) -> Result<Self, ModelFileError> {
        let model = Self::load(path)?;
        model.expect_kind(kind)?;
        Ok(model)
    }

    /// Error unless this is a `kind` model.
    pub fn expect_kind(&self, kind: ModelKind) -> Result<(), ModelFileError> {
        if self.kind == kind {
            Ok(())
        } else {
            Err(ModelFileError::WrongKind {
                expected: kind,
                found: self.kind,
            })
        }
    }

    /// Validate and write pretty JSON (with a final newline).
    pub fn save(&self, path: &Path) -> Result<(), ModelFileError> {
        let mut text = self.to_json()?;
        text.push('\n');
        std::fs::write(path, text).map_err(|source| ModelFileError::Io {
            path: path.to_path_buf(),
            source,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lr() -> ModelFile {
        let mut m = ModelFile::new_lr(vec![0.0, 1e-7, 1e-4, 1e-7, 1.99, -0.99], 28, 1.0 / 2048.0);
        m.training.motion = "el-centro".into();
        m.scores.lr_condition_number = Some(1e16);
        m
    }

    fn rnn(h: usize) -> ModelFile {
        let w = RnnWeights {
            hidden: h,
            w_ih: (0..h).map(|j| vec![0.1 * j as f64, -0.2]).collect(),
            w_hh: (0..h)
                .map(|j| (0..h).map(|k| 0.01 * (j + k) as f64).collect())
                .collect(),
            b_h: vec![0.05; h],
            w_ho: vec![0.3; h],
            b_o: -0.1,
            input_mean: vec![0.0, 1.0],
            input_std: vec![900.0, 5000.0],
            output_mean: 0.01,
            output_std: 3.0,
        };
        let mut m = ModelFile::new_rnn(w, 28, 1.0 / 2048.0);
        m.training.seed = Some(7);
        m
    }

    fn edit(m: &ModelFile, f: impl FnOnce(&mut serde_json::Value)) -> String {
        let mut v = serde_json::to_value(m).unwrap();
        f(&mut v);
        serde_json::to_string_pretty(&v).unwrap()
    }

    #[test]
    fn round_trip_both_kinds_through_a_file() {
        let dir = tempfile::tempdir().unwrap();
        for m in [lr(), rnn(5), rnn(20)] {
            let p = dir.path().join("m.json");
            m.save(&p).unwrap();
            let back = ModelFile::load_kind(&p, m.kind).unwrap();
            assert_eq!(back, m);
        }
    }

    #[test]
    fn wrong_kind_is_reported() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.json");
        rnn(5).save(&p).unwrap();
        let e = ModelFile::load_kind(&p, ModelKind::Lr).unwrap_err();
        assert!(matches!(
            e,
            ModelFileError::WrongKind {
                expected: ModelKind::Lr,
                found: ModelKind::Rnn
            }
        ));
        assert!(e.to_string().contains("expected lr"), "{e}");
    }

    #[test]
    fn unknown_format_and_version() {
        let t = edit(&lr(), |v| v["format"] = "onnx".into());
        assert!(matches!(
            ModelFile::from_json(&t),
            Err(ModelFileError::UnknownFormat { found }) if found == "onnx"
        ));
        // A future version with other fields still reports the version.
        let t = edit(&lr(), |v| {
            v["version"] = 2.into();
            v.as_object_mut().unwrap().remove("lr");
            v["kind"] = "transformer".into();
        });
        assert!(matches!(
            ModelFile::from_json(&t),
            Err(ModelFileError::UnsupportedVersion { found: 2 })
        ));
    }

    #[test]
    fn malformed_json_carries_line_and_column() {
        let t = lr()
            .to_json()
            .unwrap()
            .replacen("\"kind\"", "\"kind\" ::", 1);
        let e = ModelFile::from_json(&t).unwrap_err();
        assert!(matches!(e, ModelFileError::Json(_)));
        assert!(e.to_string().contains("line 4"), "{e}");
        let e = ModelFile::from_json(&edit(&lr(), |v| v["kind"] = "cnn".into())).unwrap_err();
        assert!(e.to_string().contains("unknown variant `cnn`"), "{e}");
    }

    #[test]
    fn wrong_shapes_name_field_and_sizes() {
        let t = edit(&lr(), |v| v["lr"]["theta"] = serde_json::json!([1.0, 2.0]));
        let e = ModelFile::from_json(&t).unwrap_err();
        assert!(
            matches!(&e, ModelFileError::WrongShape { field, expected: 6, found: 2 } if field == "lr.theta")
        );
        let t = edit(&rnn(5), |v| {
            v["rnn"]["w_hh"][3] = serde_json::json!(vec![0.0; 4])
        });
        let e = ModelFile::from_json(&t).unwrap_err();
        assert!(
            matches!(&e, ModelFileError::WrongShape { field, expected: 5, found: 4 } if field == "rnn.w_hh[3]")
        );
        assert_eq!(
            e.to_string(),
            "wrong shape of rnn.w_hh[3]: expected 5, found 4"
        );
        let t = edit(&rnn(5), |v| {
            v["rnn"]["w_ih"][0] = serde_json::json!(vec![0.0; 3])
        });
        assert!(matches!(
            ModelFile::from_json(&t),
            Err(ModelFileError::WrongShape {
                expected: 2,
                found: 3,
                ..
            })
        ));
        let t = edit(&rnn(5), |v| {
            v["rnn"]["b_h"] = serde_json::json!(vec![0.0; 6])
        });
        assert!(matches!(
            ModelFile::from_json(&t),
            Err(ModelFileError::WrongShape {
                expected: 5,
                found: 6,
                ..
            })
        ));
        let t = edit(&rnn(5), |v| {
            v["rnn"]["input_std"] = serde_json::json!([1.0])
        });
        assert!(matches!(
            ModelFile::from_json(&t),
            Err(ModelFileError::WrongShape {
                expected: 2,
                found: 1,
                ..
            })
        ));
        let t = edit(&rnn(5), |v| v["rnn"]["hidden"] = 33.into());
        assert!(matches!(
            ModelFile::from_json(&t),
            Err(ModelFileError::BadHidden(33))
        ));
        let t = edit(&lr(), |v| {
            v.as_object_mut().unwrap().remove("lr");
        });
        assert!(matches!(
            ModelFile::from_json(&t),
            Err(ModelFileError::MissingSection {
                kind: ModelKind::Lr
            })
        ));
    }

    #[test]
    fn non_finite_and_non_positive_values() {
        // JSON cannot spell NaN; a model built in code can hold one, and huge literals overflow to inf.
        let mut m = rnn(5);
        if let Some(w) = m.rnn.as_mut() {
            w.w_hh[2][4] = f64::NAN;
        }
        let e = m.to_json().unwrap_err();
        assert!(
            matches!(&e, ModelFileError::NonFinite { field, index: 4 } if field == "rnn.w_hh[2]"),
            "{e}"
        );
        let t = lr().to_json().unwrap();
        let t = t.replacen("1.99", "1e999", 1);
        let e = ModelFile::from_json(&t);
        // serde_json rejects an overflowing literal itself; either way the file is refused.
        assert!(e.is_err());
        let mut m = lr();
        if let Some(w) = m.lr.as_mut() {
            w.theta[5] = f64::INFINITY;
        }
        assert!(matches!(
            m.validate(),
            Err(ModelFileError::NonFinite { index: 5, .. })
        ));
        let t = edit(&rnn(5), |v| v["rnn"]["input_std"][1] = 0.0.into());
        assert!(
            matches!(ModelFile::from_json(&t), Err(ModelFileError::NonPositive { field, .. }) if field == "rnn.input_std")
        );
        let t = edit(&rnn(5), |v| v["rnn"]["b_o"] = serde_json::Value::Null);
        assert!(matches!(
            ModelFile::from_json(&t),
            Err(ModelFileError::Json(_))
        ));
    }

    #[test]
    fn feature_list_must_match_the_kind() {
        let t = edit(&lr(), |v| v["features"][2] = "force_fb_kn".into());
        let e = ModelFile::from_json(&t).unwrap_err();
        assert!(matches!(e, ModelFileError::FeatureMismatch { .. }));
        let t = edit(&rnn(5), |v| v["features"] = serde_json::json!(LR_FEATURES));
        assert!(matches!(
            ModelFile::from_json(&t),
            Err(ModelFileError::FeatureMismatch { .. })
        ));
    }

    /// The names are core's; a file with the old (pre-core) LR names is refused, saying which
    /// names were expected and which were found.
    #[test]
    fn a_wrong_feature_name_is_refused_with_the_reason() {
        assert_eq!(LR_FEATURES, rths_core::metamodel::LR_FEATURE_NAMES);
        assert_eq!(RNN_FEATURES, rths_core::metamodel::RNN_INPUT_NAMES);
        assert_eq!(LRX_FEATURES, rths_core::metamodel::LRX_FEATURE_NAMES);
        let t = edit(&lr(), |v| v["features"][2] = "disp_fb_mm".into());
        let e = ModelFile::from_json(&t).unwrap_err();
        assert!(
            matches!(&e, ModelFileError::FeatureMismatch { kind: ModelKind::Lr, found, .. } if found[2] == "disp_fb_mm")
        );
        let msg = e.to_string();
        assert!(msg.contains("\"brace_disp_fb_mm\""), "{msg}");
        assert!(msg.contains("\"disp_fb_mm\""), "{msg}");
        assert!(
            msg.starts_with("feature names of a lr model: expected"),
            "{msg}"
        );
        let t = edit(&rnn(5), |v| v["features"][1] = "force_fb_kn".into());
        assert!(matches!(
            ModelFile::from_json(&t),
            Err(ModelFileError::FeatureMismatch {
                kind: ModelKind::Rnn,
                ..
            })
        ));
    }
}

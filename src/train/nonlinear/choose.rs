//! `rths train nonlinear`'s choice of the form (docs/nonlinear.md "Which form the training
//! chooses"): with a lab's histories of a story structure, both forms are trained on the same
//! histories with every third one (the 3rd, 6th, ...) held out, and the one whose pure loop misses
//! the held-out histories' floors by less is kept. The scoring records are never among them: they
//! are not given to the training at all. An imported structure (yielding spread over members) has
//! no stories for the modal-hysteretic form's springs: the floor-hysteron form is the only one.

use std::path::{Path, PathBuf};

use rths_files::hysteron_model_file::{HysteronModelFile, HysteronTraining};
use rths_files::nl_model_file::{structure_checksum, StructureId};

use super::floors::{read_runs, FloorModel, FloorRun};
use super::hysteron::{self, HYSTERON_METHOD, RIDGE};
use super::score::{validation_loss, Learned};
use super::{NlTrainConfig, NlTrained};
use crate::train::TrainError;

/// The forms `--form` chooses among.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    /// Train both where both apply, keep the lower validation loss.
    Auto,
    /// The modal-hysteretic form (story structures).
    Modal,
    /// The floor-hysteron form.
    Hysteron,
}

/// What the training produced.
#[derive(Debug, Clone)]
pub enum TrainedForm {
    /// The modal-hysteretic model and its training's figures.
    Modal(Box<NlTrained>),
    /// The floor-hysteron model file.
    Hysteron(Box<HysteronModelFile>),
}

/// How the form was chosen.
#[derive(Debug, Clone)]
pub struct Choice {
    /// The histories held out of the fit to choose on (empty: no validation).
    pub held_out: Vec<String>,
    /// Each form's validation loss (mean floor NRMSE of the pure loop on them), %.
    pub losses_pct: Vec<(&'static str, f64)>,
    /// Why the kept form was kept.
    pub reason: String,
}

/// Fit the floor-hysteron form on `runs`.
pub fn fit_hysteron(
    fm: &FloorModel,
    runs: &[FloorRun],
    structure: StructureId,
    seed: u64,
    dt_s: f64,
) -> Result<HysteronModelFile, TrainError> {
    let fit = hysteron::fit(fm, runs, dt_s)?;
    let p = hysteron::params(fm, &fit, dt_s)?;
    let loss = validation_loss(&Learned::Hysteron(p), fm.specimen_k_kn_per_mm, runs);
    Ok(hysteron::model_file(
        fm,
        &fit,
        structure,
        dt_s,
        HysteronTraining {
            method: HYSTERON_METHOD.into(),
            seed,
            runs: runs
                .iter()
                .map(|r| format!("{} (history)", r.label))
                .collect(),
            ridge: RIDGE,
            stability_scale: fit.stability_scale,
            force_fit_pct: fit.force_fit_pct,
            train_loss_pct: loss,
            choice: String::new(),
        },
    ))
}

fn is_validation(i: usize) -> bool {
    i % 3 == 2
}

/// Train the form `form` (or choose it) for the structure file `json` from `cfg`.
/// `on_progress(done, total, what)` reports the steps.
pub fn train_form(
    json: &str,
    cfg: &NlTrainConfig,
    form: Form,
    mut on_progress: impl FnMut(usize, usize, String),
) -> Result<(TrainedForm, Option<Choice>), TrainError> {
    let fm = FloorModel::from_json(json)?;
    let structure = StructureId {
        name: fm.name.clone(),
        checksum: structure_checksum(json)
            .map_err(|e| TrainError::Setting(format!("structure file: {e}")))?,
    };
    let story = fm.stories;
    if !story && form == Form::Modal {
        return Err(TrainError::Setting(format!(
            "structure {} is imported (its yielding is not story by story): the \
             modal-hysteretic form needs a story structure file; use --form floor-hysteron or \
             auto",
            fm.name
        )));
    }
    if cfg.histories.is_empty() {
        if !story || form == Form::Hysteron {
            return Err(TrainError::Setting(
                "the floor-hysteron form trains on the lab's time histories: give --histories \
                 FILE..."
                    .into(),
            ));
        }
        let t = super::train(json, cfg, |g, n, l| on_progress(g, n, format!("{l:.3}%")))?;
        return Ok((TrainedForm::Modal(Box::new(t)), None));
    }
    let paths: Vec<&Path> = cfg.histories.iter().map(PathBuf::as_path).collect();
    on_progress(0, 1, "reading the histories".into());
    let runs = read_runs(&fm, &paths, cfg.dt_s)?;
    let only_hysteron = !story || form == Form::Hysteron;
    if only_hysteron || runs.len() < 3 {
        if form == Form::Modal {
            let t = super::train(json, cfg, |g, n, l| on_progress(g, n, format!("{l:.3}%")))?;
            return Ok((TrainedForm::Modal(Box::new(t)), None));
        }
        on_progress(0, 1, "fitting the hysterons".into());
        let mut f = fit_hysteron(&fm, &runs, structure, cfg.seed, cfg.dt_s)?;
        let reason = if !story {
            "the structure is imported: its yielding is spread over members, and the \
             modal-hysteretic form needs story springs"
        } else if form == Form::Hysteron {
            "--form floor-hysteron"
        } else {
            "fewer than 3 histories: none to hold out for a choice; the floor-hysteron form \
             trains in seconds"
        };
        f.training.choice = format!("floor-hysteron: {reason}");
        on_progress(1, 1, "done".into());
        return Ok((
            TrainedForm::Hysteron(Box::new(f)),
            Some(Choice {
                held_out: Vec::new(),
                losses_pct: Vec::new(),
                reason: reason.into(),
            }),
        ));
    }
    if form == Form::Modal {
        let t = super::train(json, cfg, |g, n, l| on_progress(g, n, format!("{l:.3}%")))?;
        return Ok((TrainedForm::Modal(Box::new(t)), None));
    }
    // Both forms on the same histories, every third held out.
    let pick = |want: bool| -> Vec<FloorRun> {
        runs.iter()
            .enumerate()
            .filter(|(i, _)| is_validation(*i) == want)
            .map(|(_, r)| r.clone())
            .collect()
    };
    let (fit_runs, val_runs) = (pick(false), pick(true));
    let k_e = fm.specimen_k_kn_per_mm;
    let h = fit_hysteron(&fm, &fit_runs, structure.clone(), cfg.seed, cfg.dt_s)?;
    let h_loss = validation_loss(
        &Learned::Hysteron(
            h.params(cfg.dt_s)
                .map_err(|e| TrainError::Setting(e.to_string()))?,
        ),
        k_e,
        &val_runs,
    );
    let mut modal_cfg = cfg.clone();
    modal_cfg.histories = cfg
        .histories
        .iter()
        .enumerate()
        .filter(|(i, _)| !is_validation(*i))
        .map(|(_, p)| p.clone())
        .collect();
    let modal = super::train(json, &modal_cfg, |g, n, l| {
        on_progress(g, n, format!("modal-hysteretic {l:.3}%"))
    })?;
    let m_loss = validation_loss(
        &Learned::Modal(
            modal
                .file
                .params(cfg.dt_s)
                .map_err(|e| TrainError::Setting(e.to_string()))?,
        ),
        k_e,
        &val_runs,
    );
    let held_out: Vec<String> = val_runs.iter().map(|r| r.label.clone()).collect();
    let losses_pct = vec![("floor-hysteron", h_loss), ("modal-hysteretic", m_loss)];
    // Strictly lower wins; a tie keeps the floor-hysteron form (seconds to train, no search).
    if h_loss <= m_loss {
        let reason = format!(
            "lower validation loss on {} ({h_loss:.3} % against {m_loss:.3} %); refitted on \
             every history",
            held_out.join(", ")
        );
        let mut f = fit_hysteron(&fm, &runs, structure, cfg.seed, cfg.dt_s)?;
        f.training.choice = format!("floor-hysteron: {reason}");
        Ok((
            TrainedForm::Hysteron(Box::new(f)),
            Some(Choice {
                held_out,
                losses_pct,
                reason,
            }),
        ))
    } else {
        let reason = format!(
            "lower validation loss on {} ({m_loss:.3} % against {h_loss:.3} %)",
            held_out.join(", ")
        );
        Ok((
            TrainedForm::Modal(Box::new(modal)),
            Some(Choice {
                held_out,
                losses_pct,
                reason,
            }),
        ))
    }
}

//! The arguments of `rths simulate`, which its imported-structure runs (`simulate_imported`,
//! `simulate_imported_online`) read too.

use std::path::PathBuf;

use crate::cmd::plant::{PresetArg, SpecimenArg};
use crate::studies::nonlinear::scenario::SimScenario;
use crate::studies::scenario::ScenarioId;

/// Arguments of `rths simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario (the help lists them: [`scenario_help`]).
    #[arg(long, help = scenario_help())]
    pub scenario: SimScenario,
    /// Structure file (`data/structures/`): run the scenario on this structure and judge it
    /// against the structure's FE reference (the whole yielding structure for a file with a
    /// `hysteresis` section, with 10 s of free vibration; docs/nonlinear.md). A file that is the
    /// paper's linear frame runs exactly as without --structure.
    #[arg(long, value_name = "FILE.json")]
    pub structure: Option<PathBuf>,
    /// Length (displacement) scale L ≥ 1 of a hybrid run with --structure (similitude): the
    /// actuator imposes the structure's specimen displacement / L on a rig specimen L times
    /// stiffer, so the measured force × the force scale is still the structure's specimen force.
    /// The DAQ's noise stays at the rig's scale. Default 1 (the structure's own specimen).
    #[arg(long, default_value_t = 1.0, value_name = "L")]
    pub length_scale: f64,
    /// Ground motion: an AT2/CSV file or an embedded record name (default El Centro).
    #[arg(long, value_name = "PATH|NAME")]
    pub motion: Option<String>,
    /// Multiplies the ground acceleration (e.g. El Centro × 0.85 keeps the faithful response of every
    /// specimen of the sweep within the actuator's velocity interlock).
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    pub scale: f64,
    /// Model file for metamodel scenarios: LR, RNN or LRX (default: the shipped
    /// `data/models/lr.json`, `data/models/rnn-H.json` (H = 5, 10, 20) or `data/models/lrx.json`,
    /// compiled into the binary); with --structure, the nonlinear model of nl-pure and nl-online
    /// (`rths train nonlinear`) or the reduced model of meta-pure and meta-online (`rths train
    /// meta`).
    #[arg(long, value_name = "MODEL.json")]
    pub model: Option<PathBuf>,
    /// Plant preset.
    #[arg(long, value_enum, default_value = "unr-compact")]
    pub preset: PresetArg,
    /// Specimen model.
    #[arg(long, value_enum, default_value = "linear")]
    pub specimen: SpecimenArg,
    /// Scales the physical specimen's stiffness only; the reference is then the pure FE response of
    /// the structure with that specimen (with --uncertainty, the specimen as drawn).
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    pub specimen_stiffness_factor: f64,
    /// Seed of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also draw the plant parameters (β1, β2, a3, specimen stiffness) from the benchmark's
    /// uncertainty with the seed. The reference is the structure with the specimen drawn; the
    /// controller still knows only the nominal one.
    #[arg(long)]
    pub uncertainty: bool,
    /// Slow the actuator's dynamics down by this fraction (0..0.9), linearly over the record: a
    /// drifting actuator (`rths_hal_sim::Drift`; its delay grows by about 1/(1 − F)). Default 0.
    #[arg(long, default_value_t = 0.0, value_name = "F")]
    pub drift: f64,
    /// Rig file (`rths identify`) of this run's rig: refused if it was identified on another preset,
    /// board, specimen or uncertainty draw, or if the model names another rig file. With
    /// fe-online-ats, the ATS starts from the rig file's identified initial values (and, on an
    /// imported structure, the host FE and the force correction take its identified specimen).
    #[arg(long, value_name = "RIG.json")]
    pub rig: Option<PathBuf>,
    /// Output directory for `history.csv` and the figure.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Print one JSON object on stdout and nothing else.
    #[arg(long)]
    pub json: bool,
}

/// `--scenario`'s help, from the scenario lists themselves (a new scenario is named at once).
fn scenario_help() -> String {
    let study: Vec<String> = ScenarioId::ALL.iter().map(|s| s.to_string()).collect();
    let structure: Vec<String> = crate::studies::nonlinear::scenario::STRUCTURE_SCENARIOS
        .iter()
        .map(|s| s.to_string())
        .collect();
    format!(
        "Scenario: {} (rnn-pure-H / rnn-online-H for another hidden size H); with --structure: {}; \
         with an imported structure: fe-pure, fe-online-ats, meta-pure, meta-online, nl-pure, \
         nl-online (nl-pure and nl-online of a structure whose yielding rths does not model, an \
         imported one or a story file without laws: the lab's learned model, no reference)",
        study.join(", "),
        structure.join(", ")
    )
}

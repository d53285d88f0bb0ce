//! The hybrid-simulation scenarios of the study (docs/design.md §7), run in closed loop against the virtual
//! plant with the same [`Controller`] the firmware runs.
//!
//! Per tick `k` (time `k·Δt`): the rig's sample (taken at `k·Δt`) → `Controller::tick(ü_g(k), ...)`
//! → the command for `(k+1)·Δt` → the rig holds it for one tick. A row of the history is time `k·Δt`:
//! the command and target in force then (produced at tick `k−1`), what the sensors measured, and the
//! reference (the pure FE response of the structure with the same specimen).

use std::fmt;
use std::str::FromStr;

use rths_core::compensator::{Ats, Compensator, LeadParams};
use rths_core::control::{ControlConfig, Controller, FeedbackSource};
use rths_core::metamodel::{LrParams, LrxParams, ModelError, RnnParams};
use rths_core::metrics;
use rths_core::model::Model;
use rths_core::params::{ParamError, Prototype, SpecimenScale, DT_S, PAPER_DELAY_STEPS};

use crate::machinery::reference::specimen_prototype;
use rths_core::supervisor::{Limits, State};
use rths_hal_sim::{FaultPlan, RigConfig, VirtualRig};
use serde::Serialize;

use crate::machinery::drive;

/// The scenarios of docs/design.md §7 (plus `fe-online` and `rnn-online-H`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ScenarioId {
    /// Pure FE: the reference (no actuator).
    FePure,
    /// FE commands the actuator; the brace force is the model's (command × stiffness).
    FeOffline,
    /// FE with the measured force fed back, no delay compensation (expected to go unstable).
    FeOnline,
    /// FE with the measured force fed back and the ATS compensator.
    FeOnlineAts,
    /// LR on its own 28-step delayed prediction (no actuator).
    LrPure,
    /// LR on its own delayed prediction; the actuator follows, not fed back.
    LrOffline,
    /// LR with the measured displacement and force fed back.
    LrOnline,
    /// RNN of hidden size H on its own delayed prediction (no actuator).
    RnnPure(usize),
    /// RNN of hidden size H with the measured force fed back.
    RnnOnline(usize),
    /// The specimen-faithful LRX metamodel (frame alone, measured force corrected to its own
    /// displacement) with its learned lead filter.
    LrxOnline,
}

impl ScenarioId {
    /// Every scenario `rths reproduce` runs, in report order.
    pub const ALL: [ScenarioId; 12] = [
        ScenarioId::FePure,
        ScenarioId::FeOffline,
        ScenarioId::FeOnline,
        ScenarioId::FeOnlineAts,
        ScenarioId::LrPure,
        ScenarioId::LrOffline,
        ScenarioId::LrOnline,
        ScenarioId::RnnPure(5),
        ScenarioId::RnnPure(10),
        ScenarioId::RnnPure(20),
        ScenarioId::RnnOnline(10),
        ScenarioId::LrxOnline,
    ];

    /// Does the actuator take part?
    pub fn uses_rig(self) -> bool {
        !matches!(
            self,
            ScenarioId::FePure | ScenarioId::LrPure | ScenarioId::RnnPure(_)
        )
    }

    /// The RNN hidden size this scenario needs, if any.
    pub fn rnn_hidden(self) -> Option<usize> {
        match self {
            ScenarioId::RnnPure(h) | ScenarioId::RnnOnline(h) => Some(h),
            _ => None,
        }
    }

    /// Needs the LR model.
    pub fn uses_lr(self) -> bool {
        matches!(
            self,
            ScenarioId::LrPure | ScenarioId::LrOffline | ScenarioId::LrOnline
        )
    }

    /// The paper's NRMSE for this scenario, %, where it gives one.
    pub fn paper_nrmse_pct(self) -> Option<f64> {
        match self {
            ScenarioId::FePure => Some(0.0),
            ScenarioId::FeOffline => Some(5.4),
            ScenarioId::FeOnlineAts => Some(9.4),
            ScenarioId::LrPure => Some(0.15),
            ScenarioId::LrOnline => Some(0.066),
            ScenarioId::RnnPure(5) => Some(4.23),
            ScenarioId::RnnPure(10) => Some(3.74),
            ScenarioId::RnnPure(20) => Some(3.88),
            _ => None,
        }
    }
}

impl fmt::Display for ScenarioId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ScenarioId::FePure => f.write_str("fe-pure"),
            ScenarioId::FeOffline => f.write_str("fe-offline"),
            ScenarioId::FeOnline => f.write_str("fe-online"),
            ScenarioId::FeOnlineAts => f.write_str("fe-online-ats"),
            ScenarioId::LrPure => f.write_str("lr-pure"),
            ScenarioId::LrOffline => f.write_str("lr-offline"),
            ScenarioId::LrOnline => f.write_str("lr-online"),
            ScenarioId::RnnPure(h) => write!(f, "rnn-pure-{h}"),
            ScenarioId::RnnOnline(h) => write!(f, "rnn-online-{h}"),
            ScenarioId::LrxOnline => f.write_str("lrx-online"),
        }
    }
}

/// An unknown scenario name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown scenario `{0}` (fe-pure, fe-offline, fe-online, fe-online-ats, lr-pure, lr-offline, lr-online, rnn-pure-H, rnn-online-H with H in 1..=32, lrx-online)")]
pub struct UnknownScenario(pub String);

impl FromStr for ScenarioId {
    type Err = UnknownScenario;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let hidden = |rest: &str| {
            rest.parse::<usize>()
                .ok()
                .filter(|h| (1..=rths_core::metamodel::RNN_MAX_HIDDEN).contains(h))
        };
        Ok(match s {
            "fe-pure" => ScenarioId::FePure,
            "fe-offline" => ScenarioId::FeOffline,
            "fe-online" => ScenarioId::FeOnline,
            "fe-online-ats" => ScenarioId::FeOnlineAts,
            "lr-pure" => ScenarioId::LrPure,
            "lr-offline" => ScenarioId::LrOffline,
            "lr-online" => ScenarioId::LrOnline,
            "lrx-online" => ScenarioId::LrxOnline,
            _ => {
                if let Some(h) = s.strip_prefix("rnn-pure-").and_then(hidden) {
                    ScenarioId::RnnPure(h)
                } else if let Some(h) = s.strip_prefix("rnn-online-").and_then(hidden) {
                    ScenarioId::RnnOnline(h)
                } else {
                    return Err(UnknownScenario(s.to_string()));
                }
            }
        })
    }
}

/// Why a scenario could not run (before any tick).
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// The scenario needs a model that was not given.
    #[error("scenario {0} needs {1}")]
    MissingModel(ScenarioId, &'static str),
    /// A parameter was invalid.
    #[error("invalid parameter: {0}")]
    Param(#[from] ParamError),
    /// The model's weights were refused by the controller.
    #[error("model rejected by the controller: {0}")]
    Model(ModelError),
    /// The plant configuration was invalid.
    #[error("invalid plant configuration: {0}")]
    Plant(#[from] rths_hal_sim::ConfigError),
    /// The ground motion is empty.
    #[error("the ground motion is empty")]
    EmptyMotion,
    /// The reference response is missing or has the wrong length.
    #[error("the reference has {found} steps, the motion {expected}")]
    Reference {
        /// Steps of the motion.
        expected: usize,
        /// Steps of the reference.
        found: usize,
    },
}

/// Everything a scenario run needs.
#[derive(Debug, Clone)]
pub struct ScenarioSetup<'a> {
    /// Which scenario.
    pub id: ScenarioId,
    /// Ground acceleration at every controller tick, mm/s².
    pub ground_accel_mm_s2: &'a [f64],
    /// The reference brace deformation at every tick, mm (pure FE with the same specimen).
    pub reference_mm: &'a [f64],
    /// The plant.
    pub rig: RigConfig,
    /// Specimen stiffness relative to the paper's brace. The physical specimen (the rig) always has
    /// it; of the analytical parts only `fe-pure` and `fe-offline`, which stand for the FE analysis of
    /// that structure, know it; every other analytical part is built for the paper's brace (1.0).
    pub stiffness_factor: f64,
    /// The LR model, for LR scenarios.
    pub lr: Option<LrParams>,
    /// The RNN model of the scenario's hidden size, for RNN scenarios.
    pub rnn: Option<RnnParams>,
    /// Feedback delay of the pure runs, ticks (the model file's).
    pub delay_steps: usize,
    /// The LRX frame model and its lead filter, for `lrx-online`.
    pub lrx: Option<(LrxParams, LeadParams)>,
}

/// One row per tick.
#[derive(Debug, Clone, Default)]
pub struct RunHistory {
    /// Time, s.
    pub time_s: Vec<f64>,
    /// Ground acceleration, mm/s².
    pub ground_accel_mm_s2: Vec<f64>,
    /// Reference brace deformation, mm.
    pub reference_mm: Vec<f64>,
    /// Target brace deformation from the analytical part, mm.
    pub target_mm: Vec<f64>,
    /// Command sent to the actuator, mm.
    pub command_mm: Vec<f64>,
    /// Measured actuator displacement, mm (NaN in runs without the actuator).
    pub measured_mm: Vec<f64>,
    /// Measured specimen force (load cell), kN (NaN in runs without the actuator).
    pub measured_force_kn: Vec<f64>,
}

impl RunHistory {
    fn with_capacity(n: usize) -> Self {
        let v = || Vec::with_capacity(n);
        Self {
            time_s: v(),
            ground_accel_mm_s2: v(),
            reference_mm: v(),
            target_mm: v(),
            command_mm: v(),
            measured_mm: v(),
            measured_force_kn: v(),
        }
    }

    fn push(&mut self, r: &TickRow) {
        self.time_s.push(r.time_s);
        self.ground_accel_mm_s2.push(r.ground_accel_mm_s2);
        self.reference_mm.push(r.reference_mm);
        self.target_mm.push(r.target_mm);
        self.command_mm.push(r.command_mm);
        self.measured_mm.push(r.measured_mm);
        self.measured_force_kn.push(r.measured_force_kn);
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.time_s.len()
    }
    /// No rows.
    pub fn is_empty(&self) -> bool {
        self.time_s.is_empty()
    }

    /// Write as CSV: `time_s,ground_accel_mm_s2,reference_mm,target_mm,command_mm,measured_mm,
    /// measured_force_kn`.
    pub fn write_csv(&self, path: &std::path::Path) -> std::io::Result<()> {
        use std::io::Write;
        let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
        writeln!(
            w,
            "time_s,ground_accel_mm_s2,reference_mm,target_mm,command_mm,measured_mm,measured_force_kn"
        )?;
        for i in 0..self.len() {
            writeln!(
                w,
                "{:.6},{:.4},{:.6},{:.6},{:.6},{:.6},{:.6}",
                self.time_s[i],
                self.ground_accel_mm_s2[i],
                self.reference_mm[i],
                self.target_mm[i],
                self.command_mm[i],
                self.measured_mm[i],
                self.measured_force_kn[i]
            )?;
        }
        w.flush()
    }
}

/// The figures of one run (docs/design.md §7). `None` figures: the run was stopped, or had no actuator.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ScenarioReport {
    /// Scenario id.
    pub id: String,
    /// The supervisor never tripped.
    pub stable: bool,
    /// Why the supervisor stopped the run, if it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop_reason: Option<String>,
    /// Time of the trip, s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stop_time_s: Option<f64>,
    /// NRMSE of the command (target) vs the reference, % (the paper's figure).
    pub nrmse_pct: Option<f64>,
    /// NRMSE of the measured displacement vs the reference, %.
    pub nrmse_measured_pct: Option<f64>,
    /// J1: delay of measured behind command, ms.
    pub j1_ms: Option<f64>,
    /// J2: normalized RMS tracking error, %.
    pub j2_pct: Option<f64>,
    /// J3: normalized peak tracking error, %.
    pub j3_pct: Option<f64>,
    /// J4: normalized RMS error of measured vs reference, %.
    pub j4_pct: Option<f64>,
    /// J5: normalized peak error of measured vs reference, %.
    pub j5_pct: Option<f64>,
    /// Peak command (brace deformation asked of the specimen), mm.
    pub peak_disp_mm: Option<f64>,
    /// J1 of measured against the *target* (before compensation), ms, signed: negative when the
    /// actuator leads the target (over-compensation). Equal to `j1_ms` without a compensator.
    pub j1_target_ms: Option<f64>,
    /// J2 of measured against the target, %: how well the compensated actuator tracks.
    pub j2_target_pct: Option<f64>,
    /// J3 of measured against the target, %.
    pub j3_target_pct: Option<f64>,
}

/// A finished run: figures and history.
#[derive(Debug, Clone)]
pub struct ScenarioRun {
    /// The figures.
    pub report: ScenarioReport,
    /// Per-tick history.
    pub history: RunHistory,
}

/// Largest lag searched for J1, ticks (0.1 s: far beyond any plant here).
const J1_MAX_LAG: usize = 205;

/// The model a scenario runs (its analytical part and compensator), from the setup's validated
/// parameters; [`Model::assemble`] builds it the way the firmware does.
fn model(setup: &ScenarioSetup<'_>) -> Result<Model, ScenarioError> {
    let id = setup.id;
    Ok(if id == ScenarioId::LrxOnline {
        let (frame, lead) = setup
            .lrx
            .ok_or(ScenarioError::MissingModel(id, "an LRX model"))?;
        Model::Lrx(frame, lead)
    } else if id.uses_lr() {
        Model::Lr(
            setup
                .lr
                .ok_or(ScenarioError::MissingModel(id, "an LR model"))?,
        )
    } else if id.rnn_hidden().is_some() {
        Model::Rnn(
            setup
                .rnn
                .ok_or(ScenarioError::MissingModel(id, "an RNN model"))?,
        )
    } else if id == ScenarioId::FeOnlineAts {
        Model::FeAts {
            expected_delay_s: PAPER_DELAY_STEPS as f64 * DT_S,
        }
    } else {
        Model::Fe
    })
}

/// Run one scenario to the end of the record and compute its figures.
pub fn run(setup: &ScenarioSetup<'_>) -> Result<ScenarioRun, ScenarioError> {
    run_with_ats_start(setup, None)
}

/// [`run`], the ATS of `fe-online-ats` starting from `ats_initial` = [a0, a1 (s), a2 (s²)] if
/// given (a rig file's identified values, `rths identify`) instead of the paper's
/// [1, 28 ticks, …]. The other scenarios have no ATS and ignore it.
pub fn run_with_ats_start(
    setup: &ScenarioSetup<'_>,
    ats_initial: Option<[f64; 3]>,
) -> Result<ScenarioRun, ScenarioError> {
    let mut h = RunHistory::with_capacity(setup.ground_accel_mm_s2.len());
    let stop = closed_loop(setup, &Injection::default(), ats_initial, |r| h.push(r))?;
    let report = figures(setup.id, &h, stop);
    Ok(ScenarioRun { report, history: h })
}

/// The figures of [`run`] without its history: the loop keeps only the series the figures read
/// (target, command, measured), a third of the memory the whole history would touch.
pub fn report(setup: &ScenarioSetup<'_>) -> Result<ScenarioReport, ScenarioError> {
    report_with_ats_start(setup, None)
}

/// [`report`] with the ATS start of [`run_with_ats_start`].
pub fn report_with_ats_start(
    setup: &ScenarioSetup<'_>,
    ats_initial: Option<[f64; 3]>,
) -> Result<ScenarioReport, ScenarioError> {
    let n = setup.ground_accel_mm_s2.len();
    let (mut target, mut command) = (Vec::with_capacity(n), Vec::with_capacity(n));
    // Runs without the actuator measure nothing; their figures never read it.
    let mut measured = Vec::with_capacity(if setup.id.uses_rig() { n } else { 0 });
    let stop = closed_loop(setup, &Injection::default(), ats_initial, |r| {
        target.push(r.target_mm);
        command.push(r.command_mm);
        if setup.id.uses_rig() {
            measured.push(r.measured_mm);
        }
    })?;
    let series = Series {
        target_mm: &target,
        command_mm: &command,
        measured_mm: &measured,
        reference_mm: setup.reference_mm,
    };
    Ok(figures_of(setup.id, &series, stop))
}

pub use crate::machinery::drive::Stop;

/// Faults injected into a closed-loop run: the virtual rig's fault plan and the controller's
/// `overrun` input (a control tick that missed its deadline). Default: none.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Injection {
    /// Faults of the virtual rig (ignored by runs without the actuator).
    pub faults: FaultPlan,
    /// Ticks on which the controller is told the previous tick overran: (first tick, count).
    pub overruns: Option<(u64, u64)>,
}

/// One tick of a closed-loop run, as [`simulate_observed`] reports it (a row of [`RunHistory`], plus
/// the supervisor's state after the tick and the command it produced for the next one).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickRow {
    /// Tick index k.
    pub k: usize,
    /// Time k·Δt, s.
    pub time_s: f64,
    /// Ground acceleration, mm/s².
    pub ground_accel_mm_s2: f64,
    /// Reference brace deformation, mm.
    pub reference_mm: f64,
    /// Target in force at k (produced at tick k−1), mm.
    pub target_mm: f64,
    /// Command in force at k (produced at tick k−1), mm.
    pub command_mm: f64,
    /// Measured displacement at k, mm (NaN without an actuator or on a DAQ error).
    pub measured_mm: f64,
    /// Measured force at k, kN (NaN without an actuator or on a DAQ error).
    pub measured_force_kn: f64,
    /// The command the controller produced at k for k+1, mm.
    pub next_command_mm: f64,
    /// The supervisor's state after tick k.
    pub state: State,
    /// The true (noise-free) actuator displacement at k, mm (NaN without an actuator).
    pub true_disp_mm: f64,
    /// The true force on the specimen at k, kN (NaN without an actuator).
    pub true_force_kn: f64,
    /// The command the servo-controller holds during tick k (what reached it, after the DAC), mm
    /// (NaN without an actuator). Differs from `command_mm` when the link lost ticks.
    pub servo_command_mm: f64,
}

/// The closed loop alone: run one scenario to the end of the record, returning the history and the
/// supervisor's stop (reason, time), if any.
pub fn simulate(setup: &ScenarioSetup<'_>) -> Result<(RunHistory, Stop), ScenarioError> {
    let mut h = RunHistory::with_capacity(setup.ground_accel_mm_s2.len());
    let stop = simulate_observed(setup, &Injection::default(), |r| h.push(r))?;
    Ok((h, stop))
}

/// The closed loop with injected faults, streaming: `observe` sees every tick (nothing is stored,
/// so a run can be as long as its slices). Returns the supervisor's stop (reason, time), if any.
pub fn simulate_observed(
    setup: &ScenarioSetup<'_>,
    injection: &Injection,
    observe: impl FnMut(&TickRow),
) -> Result<Stop, ScenarioError> {
    closed_loop(setup, injection, None, observe)
}

/// [`simulate_observed`] with the ATS start of [`run_with_ats_start`].
fn closed_loop(
    setup: &ScenarioSetup<'_>,
    injection: &Injection,
    ats_initial: Option<[f64; 3]>,
    mut observe: impl FnMut(&TickRow),
) -> Result<Stop, ScenarioError> {
    let n = setup.ground_accel_mm_s2.len();
    if n == 0 {
        return Err(ScenarioError::EmptyMotion);
    }
    if setup.reference_mm.len() != n {
        return Err(ScenarioError::Reference {
            expected: n,
            found: setup.reference_mm.len(),
        });
    }
    let id = setup.id;
    let proto = match id {
        ScenarioId::FePure | ScenarioId::FeOffline => specimen_prototype(setup.stiffness_factor)?,
        _ => Prototype::paper(),
    };
    let feedback = match id {
        ScenarioId::FePure | ScenarioId::FeOffline => FeedbackSource::OwnDelayed { delay_steps: 0 },
        ScenarioId::LrPure | ScenarioId::LrOffline | ScenarioId::RnnPure(_) => {
            FeedbackSource::OwnDelayed {
                delay_steps: setup.delay_steps,
            }
        }
        ScenarioId::FeOnline
        | ScenarioId::FeOnlineAts
        | ScenarioId::LrOnline
        | ScenarioId::RnnOnline(_)
        | ScenarioId::LrxOnline => FeedbackSource::Measured,
    };
    let config = ControlConfig::new(
        proto,
        SpecimenScale::default(),
        feedback,
        // A run without the actuator has nothing physical to protect (and no sensor to follow).
        if id.uses_rig() {
            Limits::paper_actuator()
        } else {
            Limits::unbounded()
        },
    )?;
    let (analytical, mut compensator) =
        model(setup)?.assemble(proto, DT_S).map_err(|e| match e {
            ModelError::Param(e) => ScenarioError::Param(e),
            // The setup's parameters are validated already; only the FE build or ATS can fail.
            other => ScenarioError::Model(other),
        })?;
    if let (Some(initial), Compensator::Ats(ats)) = (ats_initial, &compensator) {
        // The model's ATS (its bounds, window, filter), only starting elsewhere.
        compensator = Compensator::Ats(Ats::new(ats.params().with_initial(initial)?));
    }
    let mut ctl = Controller::new(config, analytical, compensator);
    let mut rig = if id.uses_rig() {
        Some(VirtualRig::with_faults(
            setup.rig.build()?,
            injection.faults,
        ))
    } else {
        None
    };
    Ok(drive::run(
        &mut ctl,
        rig.as_mut(),
        setup.ground_accel_mm_s2,
        injection.overruns,
        DT_S,
        |st, _, _| {
            observe(&TickRow {
                k: st.k,
                time_s: st.k as f64 * DT_S,
                ground_accel_mm_s2: st.ground_accel_mm_s2,
                reference_mm: setup.reference_mm.get(st.k).copied().unwrap_or(f64::NAN),
                target_mm: st.target_mm,
                command_mm: st.command_mm,
                measured_mm: st.measured_mm,
                measured_force_kn: st.measured_force_kn,
                next_command_mm: st.out.command_mm,
                state: st.out.state,
                true_disp_mm: st.true_disp_mm,
                true_force_kn: st.true_force_kn,
                servo_command_mm: st.servo_command_mm,
            });
            std::ops::ControlFlow::Continue(())
        },
    ))
}

/// The figures of a finished run (docs/design.md §7).
pub fn figures(id: ScenarioId, h: &RunHistory, stop: Stop) -> ScenarioReport {
    let series = Series {
        target_mm: &h.target_mm,
        command_mm: &h.command_mm,
        measured_mm: &h.measured_mm,
        reference_mm: &h.reference_mm,
    };
    figures_of(id, &series, stop)
}

/// The per-tick series the figures read (`measured_mm` may be empty in runs without the actuator).
struct Series<'a> {
    target_mm: &'a [f64],
    command_mm: &'a [f64],
    measured_mm: &'a [f64],
    reference_mm: &'a [f64],
}

/// [`figures`] of the series alone.
fn figures_of(id: ScenarioId, h: &Series<'_>, stop: Stop) -> ScenarioReport {
    figures_named(id.to_string(), id.uses_rig(), h, stop)
}

/// The figures of a run of another scenario family (`rths simulate --structure`, docs/nonlinear.md)
/// from its per-tick series: the same figures as [`figures`], under the name `id`; `measured_mm`
/// is read only when `uses_rig` (the actuator took part).
pub fn figures_of_series(
    id: &str,
    uses_rig: bool,
    target_mm: &[f64],
    command_mm: &[f64],
    measured_mm: &[f64],
    reference_mm: &[f64],
    stop: Stop,
) -> ScenarioReport {
    let series = Series {
        target_mm,
        command_mm,
        measured_mm,
        reference_mm,
    };
    figures_named(id.to_string(), uses_rig, &series, stop)
}

/// [`figures_of`] under any name.
fn figures_named(id: String, uses_rig: bool, h: &Series<'_>, stop: Stop) -> ScenarioReport {
    let mut r = ScenarioReport {
        id,
        stable: stop.is_none(),
        stop_reason: stop.as_ref().map(|s| s.0.clone()),
        stop_time_s: stop.as_ref().map(|s| s.1),
        ..ScenarioReport::default()
    };
    if stop.is_some() {
        return r;
    }
    r.nrmse_pct = metrics::nrmse_pct(h.target_mm, h.reference_mm).ok();
    r.peak_disp_mm = Some(metrics::peak_abs(h.command_mm));
    if uses_rig {
        r.nrmse_measured_pct = metrics::nrmse_pct(h.measured_mm, h.reference_mm).ok();
        let (m, c, t) = (h.measured_mm, h.command_mm, h.target_mm);
        // Without a compensator the command is the target: the figures against the target are
        // those against the command, and one search gives both delays.
        let same = c.len() == t.len() && c.iter().zip(t).all(|(a, b)| a.to_bits() == b.to_bits());
        let (tracking, j1_target) = if same {
            let delays = metrics::delay_steps_both(m, c, J1_MAX_LAG);
            let tracking =
                delays.and_then(|(j1, _)| metrics::tracking_with_delay(j1, m, c, h.reference_mm));
            (tracking, delays.map(|(_, signed)| signed))
        } else {
            (
                metrics::tracking(m, c, h.reference_mm, J1_MAX_LAG),
                metrics::delay_steps_signed(m, t, J1_MAX_LAG),
            )
        };
        if let Ok(tr) = tracking {
            r.j1_ms = Some(tr.j1_steps as f64 * DT_S * 1e3);
            r.j2_pct = Some(tr.j2_pct);
            r.j3_pct = Some(tr.j3_pct);
            r.j4_pct = Some(tr.j4_pct);
            r.j5_pct = Some(tr.j5_pct);
        }
        r.j1_target_ms = j1_target.ok().map(|k| k as f64 * DT_S * 1e3);
        (r.j2_target_pct, r.j3_target_pct) = match tracking {
            Ok(tr) if same => (Some(tr.j2_pct), Some(tr.j3_pct)),
            _ => (
                metrics::normalized_std_error_pct(m, t).ok(),
                metrics::normalized_peak_error_pct(m, t).ok(),
            ),
        };
    }
    r
}

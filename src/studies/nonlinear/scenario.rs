//! `rths simulate --structure FILE`: the hybrid-simulation scenarios of a structure file, judged
//! against that structure's FE reference (the whole nonlinear structure for a file with yielding
//! stories; docs/nonlinear.md, "Scenarios").
//!
//! - `fe-pure`, `fe-online-ats`: the structure's own numerical part ([`numerical_fe`]: the core
//!   controller's `StructureNl` for a yielding file, its `StructureFe` for a linear one) takes the
//!   specimen force at the specimen DOF each tick; pure (the linear specimen at the model's own
//!   displacement, no plant) or on the virtual plant with the paper's ATS.
//!
//! Every run is `rths_core::control::Controller`, the firmware's controller, driven by the host's
//! one control step ([`crate::machinery::drive::run`]): the numerical part is its analytical part.
//! - `nl-pure`, `nl-online`: a learned model of the numerical part (core's `StructureModal`,
//!   [`crate::machinery::structure::model`]) in the same two loops; online with a lead filter (the rig file's, or the shipped LRX's).
//! - `lr-online`, `lrx-online`: the shipped *linear* metamodels of the paper's frame, run exactly as
//!   `rths simulate` runs them, only judged against the nonlinear reference (they must fail
//!   visibly once the frame yields). Only for a file that *is* the paper's frame.
//!
//! What the controller sees: ground acceleration, measured (noisy, quantized) displacement and
//! force. The reference (whole structure, noise-free) is used only by the scoring ([`score`]).
//!
//! Coordinates: the series (`target_mm`, `reference_mm`, ...) are actuator displacements. A file
//! that is the paper's frame ([`is_paper_frame`]) is tested with the paper's brace (axial: the DOF's
//! displacement × cos θ, the same rig as `rths simulate` without `--structure`); any other file's
//! specimen is tested along its DOF (cos θ = 1).
//!
//! Length scale ([`LengthScale`], `--length-scale L`, similitude): the actuator imposes the
//! structure's specimen displacement / L on the same rig specimen, whose force is then / L too;
//! displacement and force scale both × L, so the structure still sees its own specimen. The
//! series stay in the structure's (prototype) actuator coordinates: the rig's displacements × L.

use std::fmt;
use std::str::FromStr;

use std::ops::ControlFlow;

use anyhow::Context;
use rths_core::compensator::{Ats, Compensator, Lead, LeadParams};
pub use rths_core::control::CompensatorTarget;
use rths_core::control::{
    self as core_control, Analytical, ControlConfig, Controller, FeedbackSource, ForceCorrection,
};
use rths_core::metamodel::{LrParams, LrxParams};
use rths_core::metrics;
use rths_core::model::Model;
use rths_core::params::{
    Prototype, SpecimenScale, DISP_SCALE, DT_S, FORCE_SCALE, PAPER_DELAY_STEPS,
};
use rths_core::supervisor::Limits;
use rths_files::structure_file::Structure;
use rths_hal_sim::{Preset, RigConfig, VirtualRig};
use serde::Serialize;

use crate::machinery::drive::{self, Stop};
use crate::machinery::structure::rig::CorrectedLead;
pub use crate::machinery::structure::rig::{
    is_paper_frame, rig_specimen_factor, structure_rig, PAPER_FRAME_TOLERANCE,
};
use crate::machinery::structure::{elastic_drifts, fe_reference, NlResponse, FREE_VIBRATION_S};
use crate::studies::scenario::{self, ScenarioId, ScenarioReport, ScenarioSetup};

/// The start-up window of [`StructureFigures::startup_error_ratio`], s (the "first 2 s").
pub const STARTUP_WINDOW_S: f64 = 2.0;

/// A length (displacement) scale of a hybrid test, L ≥ 1 (similitude, as labs scale a test to
/// their actuator): the rig's specimen displacement is the structure's / L. The rig's specimen
/// keeps its stiffness and the force scale grows × L with the displacement scale, so the
/// measured force (/ L) × the force scale is still the structure's specimen force. The force
/// scale must grow with L: the actuator's force capacity binds at the same displacement as its
/// stroke on the paper's brace (29.6 kN / 1.224 kN/mm = 24.2 mm), so a stiffer rig specimen at
/// the same force scale would trip the force interlock instead. The rig (actuator and specimen)
/// is the same at every L, so its identification and compensation still fit. L = 1 is the
/// project's [`SpecimenScale::default`] exactly. The DAQ's noise stays at the rig's scale: at L
/// its share of the signal is L times larger.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LengthScale {
    length: f64,
    scale: SpecimenScale,
}

/// A length scale that is not a number ≥ 1.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error(
    "the length scale must be a finite number ≥ 1 (the rig imposes the structure's specimen \
     displacement / L), got {0}"
)]
pub struct BadLengthScale(pub f64);

impl LengthScale {
    /// L = 1: the rig's specimen is the structure's (today's runs, bit for bit).
    pub fn unit() -> Self {
        Self {
            length: 1.0,
            scale: SpecimenScale::default(),
        }
    }

    /// L, refused unless finite and ≥ 1.
    pub fn new(length: f64) -> Result<Self, BadLengthScale> {
        if !(length.is_finite() && length >= 1.0) {
            return Err(BadLengthScale(length));
        }
        if length == 1.0 {
            return Ok(Self::unit());
        }
        let scale = SpecimenScale::new(DISP_SCALE * length, FORCE_SCALE * length)
            .map_err(|_| BadLengthScale(length))?;
        Ok(Self { length, scale })
    }

    /// L.
    pub fn get(self) -> f64 {
        self.length
    }

    /// The prototype ↔ rig conversion of a run at this scale (the one home of the length scale's
    /// conversion): displacement and force scales × L.
    pub fn specimen_scale(self) -> SpecimenScale {
        self.scale
    }

    /// The controller's prototype ↔ rig conversion of a run at this scale whose actuator is at
    /// `cos_theta` to the analytical part's DOF (the paper's brace; 1 along the DOF): the rig's
    /// displacement is the DOF's × cos θ / L, the DOF's force the rig's × L × cos θ. At cos θ = 1
    /// exactly [`Self::specimen_scale`].
    pub fn dof_scale(self, cos_theta: f64) -> Result<SpecimenScale, BadLengthScale> {
        if cos_theta == 1.0 {
            return Ok(self.scale);
        }
        SpecimenScale::new(
            DISP_SCALE * self.length / cos_theta,
            FORCE_SCALE * self.length * cos_theta,
        )
        .map_err(|_| BadLengthScale(self.length))
    }
}

impl Default for LengthScale {
    fn default() -> Self {
        Self::unit()
    }
}

/// What a series of actuator displacements (prototype coordinates, mm, one per tick) asks of the
/// actuator at length scale `length`: its peak |displacement| and peak |velocity| at the rig's
/// scale, (mm, mm/s).
pub fn rig_demand(series_mm: &[f64], length: LengthScale) -> (f64, f64) {
    let scale = length.specimen_scale();
    let peak = scale.specimen_disp_mm(metrics::peak_abs(series_mm));
    let vel = series_mm
        .windows(2)
        .map(|w| scale.specimen_disp_mm((w[1] - w[0]).abs()) / DT_S)
        .fold(0.0, f64::max);
    (peak, vel)
}

/// A scenario of `rths simulate`: one of the study's, or a learned model of a structure file's
/// numerical part (`nl-pure`, `nl-online`; `--structure` only).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SimScenario {
    /// A scenario of the study (docs/design.md §7).
    Study(ScenarioId),
    /// The structure's learned model alone (the linear specimen at its own displacement).
    NlPure,
    /// The structure's learned model in the hybrid loop on the virtual plant.
    NlOnline,
    /// The structure's own FE in the hybrid loop with `nl-online`'s compensation (the identified
    /// lead and force correction): the learned model's twin with the exact numerical part.
    FeOnlineLead,
    /// An imported structure's reduced model alone, coupled with the numerical stand-in specimen.
    MetaPure,
    /// An imported structure's reduced model in the hybrid loop on the virtual plant.
    MetaOnline,
}

impl SimScenario {
    /// Does the actuator take part?
    pub fn uses_rig(self) -> bool {
        match self {
            SimScenario::Study(id) => id.uses_rig(),
            SimScenario::NlPure | SimScenario::MetaPure => false,
            SimScenario::NlOnline | SimScenario::FeOnlineLead | SimScenario::MetaOnline => true,
        }
    }
}

impl fmt::Display for SimScenario {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimScenario::Study(id) => id.fmt(f),
            SimScenario::NlPure => f.write_str("nl-pure"),
            SimScenario::NlOnline => f.write_str("nl-online"),
            SimScenario::FeOnlineLead => f.write_str("fe-online-lead"),
            SimScenario::MetaPure => f.write_str("meta-pure"),
            SimScenario::MetaOnline => f.write_str("meta-online"),
        }
    }
}

/// An unknown scenario name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "{0}; with --structure also nl-pure, nl-online, fe-online-lead (an imported structure: meta-pure, meta-online)"
)]
pub struct UnknownSimScenario(scenario::UnknownScenario);

impl FromStr for SimScenario {
    type Err = UnknownSimScenario;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "nl-pure" => Ok(SimScenario::NlPure),
            "nl-online" => Ok(SimScenario::NlOnline),
            "fe-online-lead" => Ok(SimScenario::FeOnlineLead),
            "meta-pure" => Ok(SimScenario::MetaPure),
            "meta-online" => Ok(SimScenario::MetaOnline),
            _ => ScenarioId::from_str(s)
                .map(SimScenario::Study)
                .map_err(UnknownSimScenario),
        }
    }
}

/// The scenarios `--structure` runs (docs/nonlinear.md), in report order.
pub const STRUCTURE_SCENARIOS: [SimScenario; 7] = [
    SimScenario::NlPure,
    SimScenario::NlOnline,
    SimScenario::Study(ScenarioId::FePure),
    SimScenario::Study(ScenarioId::FeOnlineAts),
    SimScenario::FeOnlineLead,
    SimScenario::Study(ScenarioId::LrOnline),
    SimScenario::Study(ScenarioId::LrxOnline),
];

/// The finite elements of a structure file's numerical part at the controller's step, as the core
/// controller's analytical part: `rths_core::control::StructureNl` for yielding stories,
/// `rths_core::control::StructureFe` for a linear one. Like every numerical part of a structure
/// run (this, or a learned model of it: [`crate::machinery::structure::model`]), it takes the specimen's force at the
/// specimen DOF (kN, prototype, along the DOF) each tick and gives the next displacement there,
/// mm; its story drifts are read from the controller.
pub fn numerical_fe(structure: &Structure) -> anyhow::Result<Analytical> {
    let dof = structure.specimen_dof();
    Ok(if structure.story_laws().is_some() {
        Analytical::StructureNl(core_control::StructureNl::new(
            structure.nonlinear_numerical(DT_S)?,
            dof,
        )?)
    } else {
        Analytical::StructureFe(core_control::StructureFe::new(
            structure.numerical()?,
            dof,
            DT_S,
        )?)
    })
}

/// A structure, a record and its reference: what every scenario of one row shares.
#[derive(Debug, Clone)]
pub struct StructureCase {
    /// The validated structure.
    pub structure: Structure,
    /// The paper's frame ([`is_paper_frame`]).
    pub paper: bool,
    /// cos θ between the specimen DOF and the actuator (the paper's brace, or 1).
    pub cos_theta: f64,
    /// Ground acceleration at every tick, the record then [`FREE_VIBRATION_S`] of zeros, mm/s².
    pub ground_accel_mm_s2: Vec<f64>,
    /// The whole structure's response (noise-free; evaluation only).
    pub reference: NlResponse,
    /// The reference at the specimen DOF in actuator coordinates, mm (evaluation only).
    pub reference_mm: Vec<f64>,
    /// The hybrid runs' length scale (default 1).
    pub length: LengthScale,
}

impl StructureCase {
    /// The structure under `record_mm_s2` (sampled at the controller's step) and its reference.
    pub fn new(structure: Structure, record_mm_s2: &[f64]) -> anyhow::Result<Self> {
        if record_mm_s2.is_empty() {
            anyhow::bail!("the ground motion is empty");
        }
        let paper = is_paper_frame(&structure);
        let cos_theta = if paper {
            Prototype::paper().cos_theta()
        } else {
            1.0
        };
        let reference = if structure.story_laws().is_some() {
            fe_reference(&structure, record_mm_s2, DT_S)?
        } else {
            linear_reference(&structure, record_mm_s2)?
        };
        let mut ag = record_mm_s2.to_vec();
        ag.resize(reference.time_s.len(), 0.0);
        let dof = structure.specimen_dof();
        let reference_mm = (0..ag.len())
            .map(|k| {
                let floor: f64 = reference.story_drift_mm[..=dof].iter().map(|d| d[k]).sum();
                floor * cos_theta
            })
            .collect();
        Ok(Self {
            structure,
            paper,
            cos_theta,
            ground_accel_mm_s2: ag,
            reference,
            reference_mm,
            length: LengthScale::unit(),
        })
    }

    /// The same case with the hybrid runs at length scale `length`.
    pub fn with_length_scale(self, length: LengthScale) -> Self {
        Self { length, ..self }
    }

    /// The specimen's lateral stiffness at its DOF, kN/mm.
    fn specimen_k_kn_per_mm(&self) -> f64 {
        self.structure.specimen().1
    }

    /// The virtual plant of a hybrid run: `preset` with this structure's specimen at specimen
    /// scale (the paper's brace for the paper's frame, exactly `rths simulate`'s rig), sensor
    /// noise `seed`.
    pub fn rig(&self, preset: Preset, seed: u64) -> RigConfig {
        structure_rig(&self.structure, preset, seed)
    }

    /// The rig's specimen stiffness over the paper's brace: 1 for the paper's frame; along the
    /// DOF (cos θ = 1) the structure's lateral spring. The same at every length scale
    /// ([`LengthScale`]).
    pub fn rig_specimen_factor(&self) -> f64 {
        rig_specimen_factor(&self.structure)
    }

    /// Why the reference is beyond what the rig can do (stroke, velocity) at the case's length
    /// scale, if it is: its hybrid runs will be stopped by the supervisor.
    pub fn beyond_rig(&self) -> Option<String> {
        let lim = Limits::paper_actuator();
        let (peak, vel) = rig_demand(&self.reference_mm, self.length);
        if peak > lim.stroke_mm() {
            Some(format!(
                "the reference asks {peak:.1} mm of the actuator, its stroke is ±{:.1} mm",
                lim.stroke_mm()
            ))
        } else if vel > lim.velocity_mm_s() {
            Some(format!(
                "the reference asks {vel:.0} mm/s of the actuator, its limit is {:.0} mm/s",
                lim.velocity_mm_s()
            ))
        } else {
            None
        }
    }
}

/// The linear whole structure's response (Chang, as [`elastic_drifts`]) over the record and the
/// free vibration: the reference of a linear file.
fn linear_reference(structure: &Structure, record_mm_s2: &[f64]) -> anyhow::Result<NlResponse> {
    let free = (FREE_VIBRATION_S / DT_S) as usize;
    let total = record_mm_s2.len() + free;
    let mut r = NlResponse {
        time_s: (0..total).map(|i| i as f64 * DT_S).collect(),
        ground_accel_mm_s2: (0..total)
            .map(|i| record_mm_s2.get(i).copied().unwrap_or(0.0))
            .collect(),
        story_drift_mm: Vec::new(),
        story_force_kn: Vec::new(),
        yield_drift_mm: Vec::new(),
        record_steps: record_mm_s2.len(),
    };
    r.story_drift_mm = elastic_drifts(structure, &r, DT_S)?;
    Ok(r)
}

/// The per-tick series of a structure run, actuator coordinates, mm.
#[derive(Debug, Clone, Default)]
pub struct StructureSeries {
    /// Target (the numerical part's).
    pub target_mm: Vec<f64>,
    /// Command.
    pub command_mm: Vec<f64>,
    /// Measured (empty for a pure run).
    pub measured_mm: Vec<f64>,
    /// Measured force on the specimen, kN, specimen scale (empty for a pure run).
    pub measured_force_kn: Vec<f64>,
    /// The model's story drifts at the target's step, `story_drift_mm[story][k]` (empty if the
    /// model has none).
    pub story_drift_mm: Vec<Vec<f64>>,
}

impl StructureSeries {
    /// Record the controller's story drifts (the structure's `n` stories), if its analytical part
    /// has them.
    fn push_drifts(&mut self, ctl: &Controller, n: usize) {
        if let Some(d) = ctl.analytical().story_drift_mm() {
            self.story_drift_mm.resize_with(n, Vec::new);
            for (s, v) in self.story_drift_mm.iter_mut().zip(d) {
                s.push(v);
            }
        }
    }
}

/// The pure loop: `model` in the controller with the structure's linear specimen at the model's
/// own displacement (no delay, no plant, [`FeedbackSource::OwnLinearSpecimen`]). Stopped at the
/// first step the model refuses.
pub fn run_pure(case: &StructureCase, model: &Analytical) -> (StructureSeries, Stop) {
    let n = case.ground_accel_mm_s2.len();
    let mut s = StructureSeries {
        target_mm: Vec::with_capacity(n),
        command_mm: Vec::with_capacity(n),
        ..StructureSeries::default()
    };
    let config = SpecimenScale::new(1.0, 1.0).and_then(|unit| {
        ControlConfig::new(
            Prototype::paper(),
            unit,
            FeedbackSource::OwnLinearSpecimen {
                stiffness_kn_per_mm: case.specimen_k_kn_per_mm(),
            },
            Limits::unbounded(),
        )
    });
    let config = match config {
        Ok(c) => c,
        Err(e) => return (s, Some((format!("{e}"), 0.0))),
    };
    let mut ctl = Controller::new(config, model.clone(), Compensator::None);
    let stories = case.structure.dofs();
    // A pure run measures nothing: the rows are the target in force at each tick (the command
    // is the target), until the first step the model refuses.
    let stop = drive::run::<VirtualRig>(
        &mut ctl,
        None,
        &case.ground_accel_mm_s2,
        None,
        DT_S,
        |st, ctl, _| {
            s.target_mm.push(st.target_mm * case.cos_theta);
            s.command_mm.push(st.target_mm * case.cos_theta);
            if st.out.target_mm.is_finite() {
                s.push_drifts(ctl, stories);
                ControlFlow::Continue(())
            } else {
                ControlFlow::Break(())
            }
        },
    );
    (s, stop)
}

/// The hybrid loop on the virtual plant `rig`: `model` in the core controller (the firmware's
/// tick, [`drive::run`]) with the measured force corrected by `correction` (at the rig, then
/// prototype, along the DOF), the compensator given the target of `timing`, the paper
/// actuator's supervisor, the command held for one tick.
pub fn run_hybrid(
    case: &StructureCase,
    model: &Analytical,
    compensator: Compensator,
    rig: &RigConfig,
    timing: CompensatorTarget,
    correction: &ForceCorrection,
) -> anyhow::Result<(StructureSeries, Stop)> {
    let scale = case.length.specimen_scale();
    let config = ControlConfig::new(
        Prototype::paper(),
        case.length.dof_scale(case.cos_theta)?,
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .context("the controller of the structure's hybrid run")?
    .with_force_correction(*correction)
    .with_compensator_target(timing);
    let mut ctl = Controller::new(config, model.clone(), compensator);
    let mut plant = VirtualRig::new(rig.build().context("the virtual plant")?);
    let n = case.ground_accel_mm_s2.len();
    let mut s = StructureSeries {
        target_mm: Vec::with_capacity(n),
        command_mm: Vec::with_capacity(n),
        measured_mm: Vec::with_capacity(n),
        measured_force_kn: Vec::with_capacity(n),
        story_drift_mm: Vec::new(),
    };
    let stories = case.structure.dofs();
    let stop = drive::run(
        &mut ctl,
        Some(&mut plant),
        &case.ground_accel_mm_s2,
        None,
        DT_S,
        |st, ctl, _| {
            // The series in the structure's actuator coordinates (the rig's × L; identity at
            // L = 1).
            s.target_mm.push(st.target_mm * case.cos_theta);
            s.command_mm.push(scale.prototype_disp_mm(st.command_mm));
            s.measured_mm.push(scale.prototype_disp_mm(st.measured_mm));
            s.measured_force_kn.push(st.measured_force_kn);
            if st.out.target_mm.is_finite() {
                s.push_drifts(ctl, stories);
            }
            ControlFlow::Continue(())
        },
    );
    Ok((s, stop))
}

/// The paper's ATS (as `fe-online-ats` builds it), starting from `initial` if given (a rig
/// file's identified values).
pub fn paper_ats(initial: Option<[f64; 3]>) -> anyhow::Result<Compensator> {
    let (_, ats) = Model::FeAts {
        expected_delay_s: PAPER_DELAY_STEPS as f64 * DT_S,
    }
    .assemble(Prototype::paper(), DT_S)
    .map_err(|e| anyhow::anyhow!("the paper's ATS: {e}"))?;
    Ok(match (initial, ats) {
        (Some(a), Compensator::Ats(ats)) => Compensator::Ats(Ats::new(
            ats.params()
                .with_initial(a)
                .map_err(|e| anyhow::anyhow!("the rig file's ATS start {a:?}: {e:?}"))?,
        )),
        (_, c) => c,
    })
}

/// Run one of the study's scenarios of the paper's frame (`lr-online`, `lrx-online`) exactly as
/// `rths simulate` does, over the case's record and free vibration, against the case's reference.
pub fn run_paper_scenario(
    case: &StructureCase,
    setup: ScenarioSetup<'_>,
) -> anyhow::Result<(StructureSeries, Stop)> {
    if !case.paper {
        anyhow::bail!(
            "{} runs the shipped model of the paper's frame; {} is another structure",
            setup.id,
            case.structure.name()
        );
    }
    if case.length != LengthScale::unit() {
        anyhow::bail!(
            "{} runs exactly as `rths simulate` without --structure, at length scale 1; got {}",
            setup.id,
            case.length.get()
        );
    }
    let setup = ScenarioSetup {
        ground_accel_mm_s2: &case.ground_accel_mm_s2,
        reference_mm: &case.reference_mm,
        stiffness_factor: 1.0,
        ..setup
    };
    let (h, stop) = scenario::simulate(&setup)?;
    Ok((
        StructureSeries {
            target_mm: h.target_mm,
            command_mm: h.command_mm,
            measured_mm: if setup.id.uses_rig() {
                h.measured_mm
            } else {
                Vec::new()
            },
            measured_force_kn: if setup.id.uses_rig() {
                h.measured_force_kn
            } else {
                Vec::new()
            },
            story_drift_mm: Vec::new(),
        },
        stop,
    ))
}

/// Residual drift of the reference and of the model at one story, mm.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ResidualDrift {
    /// The story (1-based): of the stories the model gives, the one with the largest reference
    /// residual drift.
    pub story: usize,
    /// The reference's.
    pub reference: f64,
    /// The run's (its target).
    pub model: f64,
}

/// The figures of a structure run beyond the study's: ductility, residual drift, start-up.
#[derive(Debug, Clone, Serialize)]
pub struct StructureFigures {
    /// Peak ductility of the reference over all stories (`null`: a linear structure).
    pub peak_ductility: Option<f64>,
    /// Peak ductility of the reference at the specimen's story.
    pub peak_ductility_specimen_story: Option<f64>,
    /// Peak ductility of the run over the stories its model gives (all for the FE; the
    /// specimen's story from the target alone otherwise).
    pub peak_ductility_model: Option<f64>,
    /// Residual drift (the mean over the last [`crate::machinery::structure::RESIDUAL_WINDOW_S`] of the free
    /// vibration) at the story of [`ResidualDrift::story`].
    pub residual_drift_mm: Option<ResidualDrift>,
    /// `|model − reference| / |reference|` of the residual drift, % (`null` when the reference
    /// has none).
    pub residual_drift_error_pct: Option<f64>,
    /// RMS of the target's error in the first [`STARTUP_WINDOW_S`] over its RMS after.
    pub startup_error_ratio: Option<f64>,
}

/// A scored structure run: the study's figures and the structure's.
#[derive(Debug, Clone, Serialize)]
pub struct StructureReport {
    /// The study's figures (NRMSE, J1-J5, ...) against the structure's reference.
    #[serde(flatten)]
    pub report: ScenarioReport,
    /// Ductility, residual drift, start-up.
    #[serde(flatten)]
    pub figures: StructureFigures,
    /// The hybrid run's length scale L (`null`: a pure run, no rig).
    pub length_scale: Option<f64>,
    /// Why the reference is beyond the rig at that scale, if it is (hybrid runs only): the
    /// supervisor stops such a run.
    pub beyond_rig: Option<String>,
}

/// Score a finished run against the case's reference (evaluation: the only place the reference
/// is read).
pub fn score(
    case: &StructureCase,
    name: SimScenario,
    series: &StructureSeries,
    stop: Stop,
) -> StructureReport {
    let report = scenario::figures_of_series(
        &name.to_string(),
        name.uses_rig(),
        &series.target_mm,
        &series.command_mm,
        &series.measured_mm,
        &case.reference_mm,
        stop.clone(),
    );
    let r = &case.reference;
    let nonlinear = !r.yield_drift_mm.is_empty();
    let dof = case.structure.specimen_dof();
    let (peak_ductility, peak_ductility_specimen_story) = reference_ductility(case);
    let mut f = StructureFigures {
        peak_ductility,
        peak_ductility_specimen_story,
        peak_ductility_model: None,
        residual_drift_mm: None,
        residual_drift_error_pct: None,
        startup_error_ratio: None,
    };
    let (length_scale, beyond_rig) = if name.uses_rig() {
        (Some(case.length.get()), case.beyond_rig())
    } else {
        (None, None)
    };
    let out = |figures| StructureReport {
        report,
        figures,
        length_scale,
        beyond_rig,
    };
    if stop.is_some() || series.target_mm.len() != case.reference_mm.len() {
        return out(f);
    }
    // The run's stories: the model's own, else the target as the specimen's story (the
    // specimen sits on DOF 1 of a yielding file).
    let n = series.target_mm.len();
    let model_stories: Vec<(usize, Vec<f64>)> = if !series.story_drift_mm.is_empty()
        && series.story_drift_mm.iter().all(|d| d.len() == n)
    {
        series.story_drift_mm.iter().cloned().enumerate().collect()
    } else {
        let x = series
            .target_mm
            .iter()
            .map(|x| x / case.cos_theta)
            .collect();
        vec![(dof, x)]
    };
    if nonlinear {
        f.peak_ductility_model = model_stories
            .iter()
            .filter_map(|(i, d)| Some(metrics::peak_abs(d) / r.yield_drift_mm.get(*i)?))
            .reduce(f64::max);
    }
    let w = ((crate::machinery::structure::RESIDUAL_WINDOW_S / DT_S) as usize).clamp(1, n.max(1));
    let tail_mean = |x: &[f64]| x[x.len().saturating_sub(w)..].iter().sum::<f64>() / w as f64;
    f.residual_drift_mm = model_stories
        .iter()
        .filter_map(|(i, d)| {
            Some(ResidualDrift {
                story: i + 1,
                reference: tail_mean(r.story_drift_mm.get(*i)?),
                model: tail_mean(d),
            })
        })
        .max_by(|a, b| a.reference.abs().total_cmp(&b.reference.abs()));
    f.residual_drift_error_pct = f
        .residual_drift_mm
        .filter(|d| d.reference != 0.0)
        .map(|d| 100.0 * (d.model - d.reference).abs() / d.reference.abs());
    let err: Vec<f64> = series
        .target_mm
        .iter()
        .zip(&case.reference_mm)
        .map(|(a, b)| a - b)
        .collect();
    let k0 = ((STARTUP_WINDOW_S / DT_S) as usize).min(err.len());
    let (first, rest) = err.split_at(k0);
    let rest_rms = metrics::rms(rest);
    f.startup_error_ratio = (rest_rms > 0.0).then(|| metrics::rms(first) / rest_rms);
    out(f)
}

/// The reference's peak ductility over all stories and at the specimen's story (`None`: a linear
/// structure): [`StructureFigures::peak_ductility`] and
/// [`StructureFigures::peak_ductility_specimen_story`], which need no run.
pub fn reference_ductility(case: &StructureCase) -> (Option<f64>, Option<f64>) {
    let r = &case.reference;
    let dof = case.structure.specimen_dof();
    let all = (!r.yield_drift_mm.is_empty()).then(|| r.peak_ductility());
    let specimen = r
        .yield_drift_mm
        .get(dof)
        .and_then(|uy| Some(metrics::peak_abs(r.story_drift_mm.get(dof)?) / uy));
    (all, specimen)
}

/// What a structure scenario runs with besides its case.
pub struct ScenarioInputs<'a> {
    /// Plant preset of the hybrid runs.
    pub preset: Preset,
    /// Sensor-noise seed.
    pub seed: u64,
    /// The ATS start of `fe-online-ats` (a rig file's), else the paper's.
    pub ats_initial: Option<[f64; 3]>,
    /// The lead filter and force correction of `nl-online` (a rig file's, or identified on the
    /// virtual rig: [`crate::machinery::structure::rig`]).
    pub corrected_lead: Option<CorrectedLead>,
    /// The LR model of `lr-online`.
    pub lr: Option<LrParams>,
    /// The LRX model and lead of `lrx-online`.
    pub lrx: Option<(LrxParams, LeadParams)>,
    /// The LR/LRX model's feedback delay, ticks.
    pub delay_steps: usize,
    /// The learned model of `nl-pure` and `nl-online` (core's `StructureModal`).
    pub nl_model: Option<&'a Analytical>,
}

/// Does scenario `sc` apply to `structure`? `Err` says why not.
pub fn check_applies(sc: SimScenario, structure: &Structure) -> anyhow::Result<()> {
    let ok = match sc {
        SimScenario::NlPure | SimScenario::NlOnline => structure.story_laws().is_some(),
        SimScenario::Study(ScenarioId::FePure | ScenarioId::FeOnlineAts)
        | SimScenario::FeOnlineLead => true,
        SimScenario::Study(ScenarioId::LrOnline | ScenarioId::LrxOnline) => {
            is_paper_frame(structure)
        }
        // Imported structures only (`rths import opensees`).
        SimScenario::Study(_) | SimScenario::MetaPure | SimScenario::MetaOnline => false,
    };
    if ok {
        return Ok(());
    }
    anyhow::bail!(
        "scenario {sc} does not apply to structure {}: with --structure, nl-pure and nl-online \
         are scored here against the structure's own yielding FE, which needs yielding stories \
         (a hysteresis section; the learned model of a structure without them runs in `rths \
         simulate` and is scored by `rths train nonlinear --evaluate --histories`), lr-online and lrx-online the paper's \
         frame (their shipped models are of that frame), fe-pure, fe-online-ats and \
         fe-online-lead run any \
         structure, meta-pure and meta-online an imported one (`rths import opensees`), and the \
         other study scenarios run without --structure",
        structure.name()
    )
}

/// Run scenario `sc` on `case` and score it: its figures and its series.
pub fn run_scenario(
    case: &StructureCase,
    sc: SimScenario,
    inputs: ScenarioInputs<'_>,
) -> anyhow::Result<(StructureReport, StructureSeries)> {
    check_applies(sc, &case.structure)?;
    let rig = case.rig(inputs.preset, inputs.seed);
    let missing = || {
        anyhow::anyhow!(
            "{sc} needs the structure's learned model (--model M.json, `rths train nonlinear \
             --structure FILE`)"
        )
    };
    let (series, stop) = match sc {
        SimScenario::MetaPure | SimScenario::MetaOnline => {
            anyhow::bail!("{sc} runs an imported structure (`rths import opensees`)")
        }
        SimScenario::Study(ScenarioId::FePure) => run_pure(case, &numerical_fe(&case.structure)?),
        SimScenario::Study(ScenarioId::FeOnlineAts) => run_hybrid(
            case,
            &numerical_fe(&case.structure)?,
            paper_ats(inputs.ats_initial)?,
            &rig,
            CompensatorTarget::Current,
            &ForceCorrection::NONE,
        )?,
        SimScenario::Study(id) => {
            let setup = ScenarioSetup {
                id,
                ground_accel_mm_s2: &case.ground_accel_mm_s2,
                reference_mm: &case.reference_mm,
                rig,
                stiffness_factor: 1.0,
                lr: inputs.lr,
                rnn: None,
                delay_steps: inputs.delay_steps,
                lrx: inputs.lrx,
            };
            run_paper_scenario(case, setup)?
        }
        SimScenario::NlPure => run_pure(case, inputs.nl_model.ok_or_else(missing)?),
        SimScenario::NlOnline | SimScenario::FeOnlineLead => {
            let c = inputs.corrected_lead.ok_or_else(|| {
                anyhow::anyhow!(
                    "{sc} needs the rig's identified lead and specimen (a rig file's, or \
                     identified on the virtual rig)"
                )
            })?;
            let fe;
            let model = if sc == SimScenario::NlOnline {
                inputs.nl_model.ok_or_else(missing)?
            } else {
                fe = numerical_fe(&case.structure)?;
                &fe
            };
            run_hybrid(
                case,
                model,
                Compensator::Lead(Lead::new(c.lead)),
                &rig,
                CompensatorTarget::Current,
                &c.correction,
            )?
        }
    };
    Ok((score(case, sc, &series, stop), series))
}

/// A run's series as `rths simulate`'s history (time, ground acceleration, reference, target,
/// command, measured displacement and force; NaN where the run has none), for its CSV and figure.
pub fn history(case: &StructureCase, series: &StructureSeries) -> scenario::RunHistory {
    let n = series.target_mm.len();
    let or_nan = |v: &[f64]| -> Vec<f64> {
        (0..n)
            .map(|k| v.get(k).copied().unwrap_or(f64::NAN))
            .collect()
    };
    scenario::RunHistory {
        time_s: (0..n).map(|k| k as f64 * DT_S).collect(),
        ground_accel_mm_s2: case.ground_accel_mm_s2[..n.min(case.ground_accel_mm_s2.len())]
            .to_vec(),
        reference_mm: case.reference_mm[..n.min(case.reference_mm.len())].to_vec(),
        target_mm: series.target_mm.clone(),
        command_mm: series.command_mm.clone(),
        measured_mm: or_nan(&series.measured_mm),
        measured_force_kn: or_nan(&series.measured_force_kn),
    }
}

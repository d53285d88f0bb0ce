//! The control step: one controller tick of the hybrid loop, the code the firmware runs at 2048 Hz.
//!
//! Per tick `k` a [`Controller`] takes the ground acceleration `ü_g(k)` and the DAQ sample of tick `k`
//! (measured actuator displacement and load-cell force), and returns the actuator command for tick
//! `k+1`:
//!
//! 1. feedback: the brace deformation and brace force the analytical part sees at `k`: measured
//!    (mapped to the prototype by [`SpecimenScale`]), or the model's own target `delay_steps` ago with
//!    the linear brace force `k_b·x` (the paper's "pure" runs, no actuator in the loop);
//! 2. the analytical part ([`Analytical`]: finite elements, or the LR, RNN or LRX metamodel) gives the target
//!    brace deformation for `k+1`;
//! 3. an optional delay [`Compensator`] turns the target into the command;
//! 4. the [`Supervisor`] checks everything and rate-limits the command.
//!
//! Two parameters of a test change steps 1 and 3 (both off by default, the firmware's default):
//! a [`ForceCorrection`] brings the measured force to the displacement the rig was to be at, with
//! the identified specimen; and [`CompensatorTarget`] says which target the compensator is given.
//!
//! A DAQ error or a non-finite sample is never fed to the model: the last good sample is held for the
//! model (and counted), while the supervisor sees the raw result and trips on a non-finite value or a
//! sensor timeout. Nothing here allocates or panics.

use crate::compensator::Compensator;
use crate::hal::{ErrorKind, Sample};
use crate::integrator::{Chang, ExplicitIntegrator};
use crate::metamodel::{DeltaArx, Features, Lr, Lrx, LrxInputs, Rnn, RnnInputs};
use crate::params::{ParamError, Prototype, SpecimenScale};
use crate::predictor_corrector::{PcError, PcParams, PredictorCorrector};
use crate::structure::{LinearStructure, Vector};
use crate::supervisor::{Busy, Decision, Limits, State, Supervisor};

/// Why a controller refused to replace its analytical part's or compensator's parameters (nothing
/// changed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplaceError {
    /// The supervisor is not at rest: parameters never change under a test.
    Busy(Busy),
    /// The controller's analytical part or compensator is not of the kind the parameters are for.
    Kind,
    /// The parameters failed the model's validation.
    Model(crate::metamodel::ModelError),
}

impl From<Busy> for ReplaceError {
    fn from(b: Busy) -> Self {
        Self::Busy(b)
    }
}

impl From<crate::metamodel::ModelError> for ReplaceError {
    fn from(e: crate::metamodel::ModelError) -> Self {
        Self::Model(e)
    }
}

impl From<ParamError> for ReplaceError {
    fn from(e: ParamError) -> Self {
        Self::Model(e.into())
    }
}

/// Why a site's target was refused (nothing changed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SiteError {
    /// The controller's analytical part is not a site.
    NotASite,
    /// The supervisor is not running (armed, ramping or stopped).
    NotRunning,
    /// The predictor-corrector refused it.
    Target(PcError),
}

/// Longest feedback delay a controller can hold, ticks (the paper's is 28).
pub const MAX_DELAY_STEPS: usize = 64;

/// Where the analytical part's feedback comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FeedbackSource {
    /// The DAQ: measured displacement and force (an online hybrid test).
    Measured,
    /// The model's own target `delay_steps` ticks ago and the linear prototype brace force for it
    /// (pure runs: the paper's "28-step delayed prediction"; 0 with FE is the pure FE model).
    OwnDelayed {
        /// Delay in ticks, ≤ [`MAX_DELAY_STEPS`].
        delay_steps: usize,
    },
    /// The model's own target in force (no delay) and a linear specimen's force for it: the pure
    /// runs of a structure file, whose specimen is not the prototype's brace.
    OwnLinearSpecimen {
        /// The specimen's stiffness at the analytical part's DOF, kN/mm (finite, ≥ 0).
        stiffness_kn_per_mm: f64,
    },
}

/// The feedback seen by the analytical part at one tick, prototype units.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Feedback {
    /// Brace deformation, mm.
    pub brace_disp_mm: f64,
    /// Brace axial force, kN.
    pub brace_force_kn: f64,
}

/// Why the analytical part could not produce a target.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepError {
    /// The ground acceleration was NaN or infinite.
    NonFiniteGroundAccel,
    /// The model produced a non-finite value (its state was left as it was).
    NonFiniteOutput,
}

/// The finite-element analytical part: frame and mass integrated by Chang's explicit method, with the
/// brace force from the feedback.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeModel {
    proto: Prototype,
    integrator: Chang<1>,
    started: bool,
}

impl FeModel {
    /// The hybrid split of `proto` (frame analytical, brace external) at step `dt_s`.
    pub fn new(proto: Prototype, dt_s: f64) -> Result<Self, ParamError> {
        let integrator = Chang::new(LinearStructure::prototype_hybrid(&proto)?, dt_s)?;
        Ok(Self {
            proto,
            integrator,
            started: false,
        })
    }

    /// The target brace deformation the model holds for the coming step, mm.
    pub fn pending_target_mm(&self) -> f64 {
        self.proto
            .brace_disp_mm(self.integrator.next_displacement()[0])
    }

    /// Tick k: complete step k with `ü_g(k)` and the brace force measured at `d_k`, return `d_{k+1}`.
    /// At tick 0 the structure is at rest: step 0 is the initial condition (acceleration from
    /// `ü_g(0)`), exactly as in the Newmark reference.
    fn next_target(&mut self, ag_mm_s2: f64, fb: &Feedback) -> f64 {
        if self.started {
            let r = self.proto.story_force_kn(fb.brace_force_kn);
            self.integrator.advance(ag_mm_s2, &Vector::<1>::new(r));
        } else {
            self.integrator.reset(ag_mm_s2);
            self.started = true;
        }
        self.pending_target_mm()
    }

    fn reset(&mut self) {
        self.integrator.reset(0.0);
        self.started = false;
    }
}

/// The analytical substructure of the hybrid loop.
// No allocator on the MCU, so the ~9 KiB RNN cannot be boxed; the controller is a static resource.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Analytical {
    /// Finite elements (Chang).
    Fe(FeModel),
    /// The paper's linear-regression metamodel.
    Lr(Lr),
    /// An Elman recurrent network metamodel.
    Rnn(Rnn),
    /// The specimen-faithful linear metamodel of the frame alone (measured force as an input).
    Lrx(Lrx),
    /// An experimental site (docs/site.md): the targets come from an outside integrator
    /// ([`Controller::site_target`]), one per integration step, and the predictor-corrector turns
    /// them into a target at every tick; the ground motion and the feedback are the outside
    /// analysis's business.
    Site(PredictorCorrector),
    // ---- structure files (issues 15, 16): the feedback is the specimen's measured displacement
    // and force at the structure's specimen DOF (a unit [`SpecimenScale`]), the target the
    // displacement there.
    /// Finite elements (Chang) of an N-DOF linear numerical substructure.
    StructureFe(StructureFe),
    /// Finite elements (Chang) of an N-story numerical substructure whose stories yield.
    StructureNl(StructureNl),
    /// The structure metamodel (delta ARX) of an N-DOF numerical substructure: constant cost per
    /// tick whatever N is.
    StructureMeta(DeltaArx),
    /// The learned modal-hysteretic metamodel of a yielding numerical substructure (issue 16).
    StructureModal(StructureModal),
    /// The learned floor-hysteron metamodel of a yielding numerical substructure (issue 25): the
    /// elastic floors plus play operators on drifts; its cost depends on floors and hysterons only.
    StructureHysteron(StructureHysteron),
    /// The reduced-order modal model of a large linear numerical substructure (an imported
    /// OpenSees model): constant cost per tick whatever its DOF count.
    StructureReduced(StructureReduced),
    /// A numerical substructure the host computes (the host build only: core's `std` feature),
    /// e.g. an imported OpenSees model's sparse finite elements: core knows its trait alone.
    #[cfg(feature = "std")]
    StructureHost(StructureHost),
}

impl Analytical {
    /// The scenario name of a run of this part, and its suffix (an RNN's hidden size:
    /// `rnn-online-10`); the finite elements' name depends on their compensator too
    /// ([`Controller::scenario_name`]).
    pub fn scenario_name(&self) -> (&'static str, Option<usize>) {
        match self {
            Analytical::Fe(_) => ("fe-online", None),
            Analytical::Lr(_) => ("lr-online", None),
            Analytical::Rnn(m) => ("rnn-online-", Some(m.params().hidden())),
            Analytical::Lrx(_) => ("lrx-online", None),
            Analytical::Site(_) => ("site", None),
            Analytical::StructureFe(_) => ("structure-fe", None),
            Analytical::StructureNl(_) => ("structure-nl", None),
            Analytical::StructureMeta(_) => ("structure-meta", None),
            Analytical::StructureModal(_) => ("structure-modal", None),
            Analytical::StructureHysteron(_) => ("structure-hysteron", None),
            Analytical::StructureReduced(_) => ("structure-reduced", None),
            #[cfg(feature = "std")]
            Analytical::StructureHost(_) => ("structure-host", None),
        }
    }

    /// A structure file's part (the feedback is its specimen's at its DOF).
    pub fn is_structure(&self) -> bool {
        matches!(
            self,
            Analytical::StructureFe(_)
                | Analytical::StructureNl(_)
                | Analytical::StructureMeta(_)
                | Analytical::StructureModal(_)
                | Analytical::StructureHysteron(_)
                | Analytical::StructureReduced(_)
        ) || self.is_host()
    }

    /// A host numerical substructure (`StructureHost`, the host build only; never on the firmware).
    pub fn is_host(&self) -> bool {
        #[cfg(feature = "std")]
        if let Analytical::StructureHost(_) = self {
            return true;
        }
        false
    }

    fn next_target(&mut self, ag_mm_s2: f64, fb: &Feedback) -> Result<f64, StepError> {
        let y = match self {
            Analytical::Fe(m) => m.next_target(ag_mm_s2, fb),
            Analytical::Lr(m) => m
                .predict(Features {
                    ground_accel_mm_s2: ag_mm_s2,
                    brace_disp_fb_mm: fb.brace_disp_mm,
                    brace_force_fb_kn: fb.brace_force_kn,
                })
                .map_err(|_| StepError::NonFiniteOutput)?,
            Analytical::Rnn(m) => m
                .predict(RnnInputs {
                    ground_accel_mm_s2: ag_mm_s2,
                    brace_force_fb_kn: fb.brace_force_kn,
                })
                .map_err(|_| StepError::NonFiniteOutput)?,
            Analytical::Lrx(m) => m
                .predict(LrxInputs {
                    ground_accel_mm_s2: ag_mm_s2,
                    brace_disp_fb_mm: fb.brace_disp_mm,
                    brace_force_fb_kn: fb.brace_force_kn,
                })
                .map_err(|_| StepError::NonFiniteOutput)?,
            Analytical::Site(pc) => pc.tick().command_mm,
            Analytical::StructureFe(m) => m.next_target(ag_mm_s2, fb.brace_force_kn)?,
            Analytical::StructureNl(m) => m.next_target(ag_mm_s2, fb.brace_force_kn)?,
            Analytical::StructureMeta(m) => m
                .predict(ag_mm_s2, fb.brace_disp_mm, fb.brace_force_kn)
                .map_err(|_| StepError::NonFiniteOutput)?,
            Analytical::StructureModal(m) => m.next_target(ag_mm_s2, fb.brace_force_kn)?,
            Analytical::StructureHysteron(m) => m.next_target(ag_mm_s2, fb.brace_force_kn)?,
            Analytical::StructureReduced(m) => m.next_target(ag_mm_s2, fb.brace_force_kn)?,
            #[cfg(feature = "std")]
            Analytical::StructureHost(m) => {
                m.part_mut().next_target(ag_mm_s2, fb.brace_force_kn)?
            }
        };
        if y.is_finite() {
            Ok(y)
        } else {
            Err(StepError::NonFiniteOutput)
        }
    }

    /// Story drifts at the last completed step (after the tick of k: at d_k), mm, of the
    /// analytical parts that have stories (the structure files'); `None` for the others.
    pub fn story_drift_mm(&self) -> Option<crate::structure_n::Dofs> {
        // A learned model's drift of each of its stories.
        fn per_story(n: usize, drift: impl Fn(usize) -> f64) -> crate::structure_n::Dofs {
            let mut d = [0.0; crate::structure_n::MAX_DOF];
            for (i, di) in d.iter_mut().enumerate().take(n) {
                *di = drift(i);
            }
            d
        }
        match self {
            Analytical::StructureFe(m) => {
                let c = m.chang();
                Some(crate::structure_n::story_drifts_mm(
                    c.disp(),
                    c.model().dofs(),
                ))
            }
            Analytical::StructureNl(m) => Some(m.frame().story_drift_mm()),
            Analytical::StructureModal(m) => {
                let model = m.model();
                Some(per_story(model.params().floors(), |i| {
                    model.story_drift_mm(i)
                }))
            }
            Analytical::StructureHysteron(m) => {
                let model = m.model();
                Some(per_story(model.params().floors(), |i| {
                    model.story_drift_mm(i)
                }))
            }
            _ => None,
        }
    }

    /// The interface's (the specimen DOF's) displacement at the last completed step (after the
    /// tick of k: at d_k), mm, of a structure part that holds its DOFs' state; `None` for the
    /// others (the paper frame's parts, a site, the structure metamodel's ARX).
    pub fn interface_disp_mm(&self) -> Option<f64> {
        match self {
            Analytical::StructureFe(m) => m.chang().disp().get(m.specimen_dof()).copied(),
            Analytical::StructureNl(m) => m.frame().chang().disp().get(m.specimen_dof()).copied(),
            Analytical::StructureModal(m) => {
                let model = m.model();
                Some(model.floor_disp_mm(model.params().specimen_dof()))
            }
            Analytical::StructureHysteron(m) => {
                let model = m.model();
                Some(model.floor_disp_mm(model.params().specimen_floor()))
            }
            Analytical::StructureReduced(m) => Some(m.model().interface_mm()),
            #[cfg(feature = "std")]
            Analytical::StructureHost(m) => Some(m.part().interface_disp_mm()),
            _ => None,
        }
    }

    /// How many displacement read-outs [`Self::output_disp_mm`] gives: a structure file's DOFs
    /// (its floors) for its FE parts, its modal-hysteretic and its floor-hysteron models, an imported structure's
    /// outputs (the lab's `--output` DOFs) for its reduced model; 0 for the other parts.
    pub fn output_count(&self) -> usize {
        match self {
            Analytical::StructureFe(m) => m.chang().model().dofs(),
            Analytical::StructureNl(m) => m.frame().dofs(),
            Analytical::StructureModal(m) => m.model().params().floors(),
            Analytical::StructureHysteron(m) => m.model().params().floors(),
            Analytical::StructureReduced(m) => m.model().params().outputs(),
            #[cfg(feature = "std")]
            Analytical::StructureHost(m) => m.part().output_count(),
            _ => 0,
        }
    }

    /// Read-out `i`'s displacement at the last completed step (after the tick of k: at d_k), mm
    /// ([`Self::output_count`] says what the read-outs are); `None` past them. What a study's
    /// history records beside the target (a pure loop's floors and outputs), read from the part
    /// the controller steps.
    pub fn output_disp_mm(&self, i: usize) -> Option<f64> {
        if i >= self.output_count() {
            return None;
        }
        match self {
            Analytical::StructureFe(m) => m.chang().disp().get(i).copied(),
            Analytical::StructureNl(m) => m.frame().chang().disp().get(i).copied(),
            Analytical::StructureModal(m) => Some(m.model().floor_disp_mm(i)),
            Analytical::StructureHysteron(m) => Some(m.model().floor_disp_mm(i)),
            Analytical::StructureReduced(m) => Some(m.model().output_mm(i)),
            #[cfg(feature = "std")]
            Analytical::StructureHost(m) => m.part().output_disp_mm(i),
            _ => None,
        }
    }

    fn reset(&mut self) {
        match self {
            Analytical::Fe(m) => m.reset(),
            Analytical::Lr(m) => m.reset(),
            Analytical::Rnn(m) => m.reset(),
            Analytical::Lrx(m) => m.reset(),
            Analytical::Site(pc) => pc.reset(),
            Analytical::StructureFe(m) => m.reset(),
            Analytical::StructureNl(m) => m.reset(),
            Analytical::StructureMeta(m) => m.reset(),
            Analytical::StructureModal(m) => m.reset(),
            Analytical::StructureHysteron(m) => m.reset(),
            Analytical::StructureReduced(m) => m.reset(),
            #[cfg(feature = "std")]
            Analytical::StructureHost(m) => m.part_mut().reset(),
        }
    }
}

/// The last targets, a power-of-two ring indexed with a mask: O(1), and no index can panic.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TargetRing {
    buf: [f64; RING_LEN],
    /// Index of the newest entry.
    newest: usize,
}

/// Ring length: a power of two above [`MAX_DELAY_STEPS`].
const RING_LEN: usize = (MAX_DELAY_STEPS + 1).next_power_of_two();

impl Default for TargetRing {
    /// Full of zeros: the structure was at rest before the test.
    fn default() -> Self {
        Self {
            buf: [0.0; RING_LEN],
            newest: 0,
        }
    }
}

impl TargetRing {
    fn push(&mut self, x: f64) {
        self.newest = (self.newest + 1) & (RING_LEN - 1);
        if let Some(slot) = self.buf.get_mut(self.newest) {
            *slot = x;
        }
    }

    /// The target `delay` pushes ago (0: the newest); `delay` ≤ [`MAX_DELAY_STEPS`] (validated).
    fn delayed(&self, delay: usize) -> f64 {
        let i = self.newest.wrapping_sub(delay) & (RING_LEN - 1);
        self.buf.get(i).copied().unwrap_or(0.0)
    }
}

/// Which target of the analytical part the compensator is given at tick k.
///
/// The ATS is fitted on the command and the measurement of the same tick, so the one-tick hold
/// of the command is part of the delay it compensates (and the lead filters are fitted the same
/// way): the rig reaches what the compensator was given at tick k by the sample of tick k + 1 +
/// the delay. Given d_{k+1}, the rig is at d_{k+1} when the model reads the force it needs at
/// d_k: the specimen's force leads by one tick, which acts as added damping (measured on the
/// yielding paper frame: every hybrid peak 3-4 % low, its residual drift off by up to 75 %,
/// docs/nonlinear.md). Given d_k, the rig is at d_k when its force is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CompensatorTarget {
    /// d_{k+1}, the target the model has just produced (the paper's loop, docs/design.md §7).
    #[default]
    Next,
    /// d_k, the target in force at tick k, whose force the model reads (the structure
    /// scenarios').
    Current,
}

/// Everything about a controller that is fixed for a test, validated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlConfig {
    proto: Prototype,
    scale: SpecimenScale,
    feedback: FeedbackSource,
    limits: Limits,
    /// `None`: the measured force as is.
    correction: Option<ForceCorrection>,
    compensator_target: CompensatorTarget,
}

impl ControlConfig {
    /// Validate a configuration: the own-feedback delay must fit [`MAX_DELAY_STEPS`].
    pub fn new(
        proto: Prototype,
        scale: SpecimenScale,
        feedback: FeedbackSource,
        limits: Limits,
    ) -> Result<Self, ParamError> {
        match feedback {
            FeedbackSource::OwnDelayed { delay_steps } if delay_steps > MAX_DELAY_STEPS => {
                return Err(ParamError::OutOfRange("feedback delay steps"));
            }
            FeedbackSource::OwnLinearSpecimen {
                stiffness_kn_per_mm: k,
            } if !(k.is_finite() && k >= 0.0) => {
                return Err(ParamError::OutOfRange("own-feedback specimen stiffness"));
            }
            _ => {}
        }
        Ok(Self {
            proto,
            scale,
            feedback,
            limits,
            correction: None,
            compensator_target: CompensatorTarget::Next,
        })
    }
    /// The same configuration with the measured force corrected by `correction` before the
    /// analytical part sees it ([`FeedbackSource::Measured`] only; [`ForceCorrection::NONE`]:
    /// no correction, no term at all).
    pub fn with_force_correction(self, correction: ForceCorrection) -> Self {
        Self {
            correction: (!correction.is_none()).then_some(correction),
            ..self
        }
    }
    /// The same configuration with the compensator given `target`.
    pub fn with_compensator_target(self, target: CompensatorTarget) -> Self {
        Self {
            compensator_target: target,
            ..self
        }
    }
    /// The force correction, if any.
    pub fn force_correction(&self) -> Option<&ForceCorrection> {
        self.correction.as_ref()
    }
    /// Which target the compensator is given.
    pub fn compensator_target(&self) -> CompensatorTarget {
        self.compensator_target
    }
    /// The supervisor's limits.
    pub fn limits(&self) -> &Limits {
        &self.limits
    }
    /// The prototype the analytical part stands for.
    pub fn prototype(&self) -> &Prototype {
        &self.proto
    }
    /// The specimen scale.
    pub fn scale(&self) -> &SpecimenScale {
        &self.scale
    }
    /// The feedback source.
    pub fn feedback(&self) -> FeedbackSource {
        self.feedback
    }
}

/// The outcome of one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickOutput {
    /// The command sent to the actuator, mm (after compensation and the supervisor).
    pub command_mm: f64,
    /// The analytical part's target brace deformation for the next tick, mm (NaN if it failed).
    pub target_mm: f64,
    /// The command the control law asked for before the supervisor, mm.
    pub requested_mm: f64,
    /// The supervisor's state after this tick.
    pub state: State,
    /// The model used a held sample this tick (the DAQ failed or gave a non-finite value).
    pub sample_held: bool,
}

/// One hybrid controller: configuration, analytical part, compensator, supervisor and the small
/// state between ticks. `tick` is the whole work of a controller tick.
#[derive(Debug, Clone)]
pub struct Controller {
    config: ControlConfig,
    /// The configuration the controller was made with: a new analytical part starts from its
    /// specimen scale, force correction and compensator target ([`Self::set_structure_rig`]
    /// replaces them for a structure part).
    base: ControlConfig,
    analytical: Analytical,
    compensator: Compensator,
    supervisor: Supervisor,
    /// Targets by tick: target(k) was produced at tick k−1.
    targets: TargetRing,
    last_good: Sample,
    held_samples: u32,
    step_errors: u32,
}

impl Controller {
    /// A controller at rest, supervisor `Idle`.
    pub fn new(config: ControlConfig, analytical: Analytical, compensator: Compensator) -> Self {
        let mut c = Self {
            config,
            base: config,
            analytical,
            compensator,
            supervisor: Supervisor::new(config.limits),
            targets: TargetRing::default(),
            last_good: Sample::default(),
            held_samples: 0,
            step_errors: 0,
        };
        c.clear();
        c
    }

    /// A controller at rest with a placeholder analytical part (all-zero LR) and no compensator,
    /// written into `slot` (e.g. a `static`), and returned there: the firmware then builds its
    /// parts in place ([`crate::model::assemble_in`]) instead of moving a ~44 KiB value (the
    /// ATS's 33 KiB) through the stack.
    pub fn init_in(slot: &mut core::mem::MaybeUninit<Self>, config: ControlConfig) -> &mut Self {
        // A struct literal written straight into the slot, cleared there: `new`'s clear on a local
        // made the compiler build the ~44 KiB value on the stack and copy it (48 KiB of init
        // stack once every image held the structure parts).
        let c = slot.write(Self {
            config,
            base: config,
            analytical: Analytical::Lr(Lr::PARKED),
            compensator: Compensator::None,
            supervisor: Supervisor::new(config.limits),
            targets: TargetRing::default(),
            last_good: Sample::default(),
            held_samples: 0,
            step_errors: 0,
        });
        c.clear();
        c
    }

    /// Make the analytical part the LR model of `params` and drop any compensator, in place; only
    /// at rest, then start over.
    pub fn install_lr(&mut self, params: crate::metamodel::LrParams) -> Result<(), ReplaceError> {
        self.check_at_rest()?;
        self.analytical = Analytical::Lr(Lr::new(params));
        self.compensator = Compensator::None;
        self.config = self.base;
        self.start_over()
    }

    /// Make the analytical part an RNN of `weights` and `scaling` (validated first: refused,
    /// nothing changes) and drop any compensator, built in place (the ~9 kB RNN is never a value
    /// on the stack); only at rest, then start over.
    pub fn install_rnn(
        &mut self,
        weights: crate::metamodel::RnnWeights<'_>,
        scaling: crate::metamodel::RnnScaling,
    ) -> Result<(), ReplaceError> {
        self.check_at_rest()?;
        crate::metamodel::RnnParams::check(&weights, &scaling)?;
        self.analytical = Analytical::Rnn(Rnn::PARKED);
        self.compensator = Compensator::None;
        self.config = self.base;
        self.load_rnn(weights, scaling)
    }

    /// Make the analytical part the FE model `fe` with no compensator; only at rest, then start
    /// over.
    pub fn install_fe(&mut self, fe: FeModel) -> Result<(), ReplaceError> {
        self.check_at_rest()?;
        self.analytical = Analytical::Fe(fe);
        self.compensator = Compensator::None;
        self.config = self.base;
        self.start_over()
    }

    /// Make the analytical part `analytical` with no compensator (the structure-file parts, a few
    /// KiB: built by value); only at rest, then start over.
    pub fn install_plain(&mut self, analytical: Analytical) -> Result<(), ReplaceError> {
        self.check_at_rest()?;
        self.analytical = analytical;
        self.compensator = Compensator::None;
        self.config = self.base;
        self.start_over()
    }

    /// Make the compensator the ATS of `params`, built in place (its 33 KiB are never a value on
    /// the stack); only at rest, then start over.
    pub fn install_ats(
        &mut self,
        params: crate::compensator::AtsParams,
    ) -> Result<(), ReplaceError> {
        self.check_at_rest()?;
        self.compensator = Compensator::Ats(crate::compensator::Ats::PARKED);
        if let Compensator::Ats(a) = &mut self.compensator {
            a.configure(params);
        }
        self.start_over()
    }

    /// Make the controller an experimental site: the analytical part the predictor-corrector of
    /// `pc`, the compensator the rig's identified `lead` (`None`: none); only at rest, then start
    /// over. Targets then come from [`Self::site_target`].
    pub fn install_site(
        &mut self,
        pc: PcParams,
        lead: Option<crate::compensator::LeadParams>,
    ) -> Result<(), ReplaceError> {
        self.check_at_rest()?;
        self.analytical = Analytical::Site(PredictorCorrector::new(pc));
        self.config = self.base;
        self.compensator = match lead {
            Some(l) => Compensator::Lead(crate::compensator::Lead::new(l)),
            None => Compensator::None,
        };
        self.start_over()
    }

    /// A site's next target (the analytical part's coordinates, mm), for the step under way.
    /// Refused (nothing changes): not a site, not running, a non-finite target or one already
    /// pending.
    pub fn site_target(&mut self, target_mm: f64) -> Result<(), SiteError> {
        if self.supervisor.state() != State::Running {
            return Err(SiteError::NotRunning);
        }
        let Analytical::Site(pc) = &mut self.analytical else {
            return Err(SiteError::NotASite);
        };
        pc.set_target(target_mm).map_err(SiteError::Target)
    }

    /// A site's progress: (a target is pending, steps ended since the start); `None` if the
    /// controller is not a site.
    pub fn site_progress(&self) -> Option<(bool, u32)> {
        match &self.analytical {
            Analytical::Site(pc) => Some((pc.is_pending(), pc.steps_done())),
            _ => None,
        }
    }

    /// Back to rest: model, compensator and supervisor state cleared, parameters kept, the command
    /// held where it is (a reset never moves the actuator). Refused unless the supervisor is at rest
    /// (idle, done, or faulted with its ramp finished).
    pub fn reset(&mut self) -> Result<(), Busy> {
        self.supervisor.reset()?;
        self.clear();
        Ok(())
    }

    fn clear(&mut self) {
        self.analytical.reset();
        self.compensator.reset();
        self.targets = TargetRing::default();
        self.last_good = Sample::default();
        self.held_samples = 0;
        self.step_errors = 0;
    }

    /// Swap in a new analytical part (whole) and reset. Refused unless the supervisor is at rest:
    /// parameters never change under a running test or a moving fault ramp.
    pub fn set_analytical(&mut self, analytical: Analytical) -> Result<(), Busy> {
        self.supervisor.reset()?;
        self.analytical = analytical;
        self.clear();
        Ok(())
    }

    /// Swap in an LRX model and its lead filter (a model upload), built in place; like
    /// [`Self::set_analytical`], only at rest, and the controller starts over.
    pub fn set_lrx(
        &mut self,
        frame: crate::metamodel::LrxParams,
        lead: crate::compensator::LeadParams,
    ) -> Result<(), Busy> {
        self.supervisor.reset()?;
        self.analytical = Analytical::Lrx(Lrx::new(frame));
        self.compensator = Compensator::Lead(crate::compensator::Lead::new(lead));
        self.config = self.base;
        self.clear();
        Ok(())
    }

    /// Load new RNN weights into the RNN analytical part, in place (an upload: no ~9 kB value on
    /// the stack), and start over; only at rest. Refused (busy, not an RNN, invalid weights):
    /// nothing changes.
    pub fn load_rnn(
        &mut self,
        weights: crate::metamodel::RnnWeights<'_>,
        scaling: crate::metamodel::RnnScaling,
    ) -> Result<(), ReplaceError> {
        self.check_at_rest()?;
        let Analytical::Rnn(m) = &mut self.analytical else {
            return Err(ReplaceError::Kind);
        };
        m.load(weights, scaling)?;
        self.start_over()
    }

    /// Start the ATS compensator from `initial` = [a0, a1 (s), a2 (s²)] (a rig's identified
    /// values, within the ATS's bounds), in place, and start over; only at rest. Refused: nothing
    /// changes.
    pub fn set_ats_initial(&mut self, initial: [f64; 3]) -> Result<(), ReplaceError> {
        self.check_at_rest()?;
        let Compensator::Ats(a) = &mut self.compensator else {
            return Err(ReplaceError::Kind);
        };
        a.set_initial(initial)?;
        self.start_over()
    }

    /// Replace the LRX model's rig compensation: its lead filter `lead` and the specimen's moving
    /// mass and damping `[kN·s²/mm, kN·s/mm]` removed from the measured force (the frame model is
    /// kept), and start over; only at rest. Refused: nothing changes.
    pub fn set_lrx_rig(
        &mut self,
        lead: crate::compensator::LeadParams,
        [mass, damping]: [f64; 2],
    ) -> Result<(), ReplaceError> {
        self.check_at_rest()?;
        let Analytical::Lrx(m) = &self.analytical else {
            return Err(ReplaceError::Kind);
        };
        if !matches!(self.compensator, Compensator::Lead(_)) {
            return Err(ReplaceError::Kind);
        }
        // The frame ARX runs at the controller's tick: its derivatives use that step.
        let frame = m
            .params()
            .with_specimen_dynamics(mass, damping, crate::params::DT_S)?;
        self.analytical = Analytical::Lrx(Lrx::new(frame));
        self.compensator = Compensator::Lead(crate::compensator::Lead::new(lead));
        self.start_over()
    }

    /// Give a structure-file part the rig's compensation, as the host's hybrid runs of a structure
    /// give it (`nl-online`, `meta-online`, `fe-online-lead`): the identified `lead` in front of
    /// the rig, the measured force corrected with the identified specimen (`correction`), the
    /// compensator given the target in force ([`CompensatorTarget::Current`]), and `scale`, how
    /// the rig's specimen stands for the structure's (prototype over rig, displacement and force);
    /// a reduced model as a hybrid loop runs it
    /// ([`crate::metamodel::ReducedModalParams::for_hybrid_loop`]).
    /// Only at rest and for a structure part; then start over. Refused: nothing changes. A new
    /// analytical part (an `install_*`) starts from the controller's own configuration again.
    pub fn set_structure_rig(
        &mut self,
        lead: crate::compensator::LeadParams,
        correction: ForceCorrection,
        scale: SpecimenScale,
    ) -> Result<(), ReplaceError> {
        self.check_at_rest()?;
        if !self.analytical.is_structure() {
            return Err(ReplaceError::Kind);
        }
        self.reduced_for_hybrid_loop()?;
        self.config = ControlConfig {
            scale,
            ..self.config
        }
        .with_force_correction(correction)
        .with_compensator_target(CompensatorTarget::Current);
        self.compensator = Compensator::Lead(crate::compensator::Lead::new(lead));
        self.start_over()
    }

    /// A reduced model on a rig low-passes its static term's force deviation (the rig's noise and
    /// tracking error would reach the target in the same tick, through the lead); another part is
    /// left as it is. Out of line: the rebuilt model's frame is only this call's.
    #[inline(never)]
    fn reduced_for_hybrid_loop(&mut self) -> Result<(), ReplaceError> {
        if let Analytical::StructureReduced(m) = &self.analytical {
            let p = m.model().params().for_hybrid_loop()?;
            self.analytical = Analytical::StructureReduced(StructureReduced::new(p));
        }
        Ok(())
    }

    fn check_at_rest(&self) -> Result<(), Busy> {
        if self.supervisor.at_rest() {
            Ok(())
        } else {
            Err(Busy {
                state: self.supervisor.state(),
            })
        }
    }

    /// After new parameters (at rest, checked): the supervisor back to idle, the state cleared.
    fn start_over(&mut self) -> Result<(), ReplaceError> {
        self.supervisor.reset()?;
        self.clear();
        Ok(())
    }

    /// The compensator.
    pub fn compensator(&self) -> &Compensator {
        &self.compensator
    }

    /// The supervisor (to arm, start, finish, abort, read counters).
    pub fn supervisor(&self) -> &Supervisor {
        &self.supervisor
    }
    /// The supervisor, mutably (state transitions).
    pub fn supervisor_mut(&mut self) -> &mut Supervisor {
        &mut self.supervisor
    }
    /// The configuration.
    pub fn config(&self) -> &ControlConfig {
        &self.config
    }
    /// The scenario name a board's `RESULT` line gives a run of the part in force (compiled in or
    /// uploaded), and its suffix: [`Analytical::scenario_name`], with the finite elements named
    /// by their compensator (`fe-online-ats`).
    pub fn scenario_name(&self) -> (&'static str, Option<usize>) {
        match (&self.analytical, &self.compensator) {
            (Analytical::Fe(_), Compensator::Ats(_)) => ("fe-online-ats", None),
            // The host's finite elements of an imported structure with the ATS.
            #[cfg(feature = "std")]
            (Analytical::StructureHost(_), Compensator::Ats(_)) => ("fe-online-ats", None),
            // A structure's part with the rig's identified lead (and force correction): the host's
            // hybrid scenarios of a structure file (`rths simulate --structure`).
            (
                Analytical::StructureModal(_) | Analytical::StructureHysteron(_),
                Compensator::Lead(_),
            ) => ("nl-online", None),
            (
                Analytical::StructureReduced(_) | Analytical::StructureMeta(_),
                Compensator::Lead(_),
            ) => ("meta-online", None),
            (Analytical::StructureFe(_) | Analytical::StructureNl(_), Compensator::Lead(_)) => {
                ("fe-online-lead", None)
            }
            (a, _) => a.scenario_name(),
        }
    }
    /// The analytical part.
    pub fn analytical(&self) -> &Analytical {
        &self.analytical
    }
    /// Ticks on which the model used a held sample.
    pub fn held_samples(&self) -> u32 {
        self.held_samples
    }
    /// Ticks on which the analytical part failed (non-finite input or output).
    pub fn step_errors(&self) -> u32 {
        self.step_errors
    }

    /// One controller tick `k`: ground acceleration `ü_g(k)` (mm/s²), the DAQ result of tick `k`, and
    /// whether the previous tick overran. Returns the command for tick `k+1`.
    ///
    /// The analytical part is stepped only while the supervisor is `Running`, so a test starts from
    /// rest at `start()` and stops evolving on a fault.
    pub fn tick(
        &mut self,
        ground_accel_mm_s2: f64,
        sample: Result<Sample, ErrorKind>,
        overrun: bool,
    ) -> TickOutput {
        let good = match sample {
            Ok(s) if s.disp_mm.is_finite() && s.force_kn.is_finite() => Some(s),
            _ => None,
        };
        let sample_held = good.is_none();
        if let Some(s) = good {
            self.last_good = s;
        } else {
            self.held_samples = self.held_samples.saturating_add(1);
        }
        let (mut requested, mut target) = (self.supervisor.output_mm(), f64::NAN);
        if self.supervisor.state() == State::Running {
            match self.law(ground_accel_mm_s2) {
                Ok((t, u)) => (target, requested) = (t, u),
                Err(_) => {
                    self.step_errors = self.step_errors.saturating_add(1);
                    requested = f64::NAN; // the supervisor trips on it
                }
            }
        }
        let Decision { command_mm, state } = self.supervisor.tick(requested, sample, overrun);
        TickOutput {
            command_mm,
            target_mm: target,
            requested_mm: requested,
            state,
            sample_held,
        }
    }

    /// Feedback, model and compensator: (target, requested command).
    fn law(&mut self, ag_mm_s2: f64) -> Result<(f64, f64), StepError> {
        if !ag_mm_s2.is_finite() {
            return Err(StepError::NonFiniteGroundAccel);
        }
        let cfg = &self.config;
        let fb = match cfg.feedback {
            FeedbackSource::Measured => Feedback {
                brace_disp_mm: cfg.scale.prototype_disp_mm(self.last_good.disp_mm),
                brace_force_kn: cfg.scale.prototype_force_kn(match &cfg.correction {
                    None => self.last_good.force_kn,
                    Some(c) => {
                        // The rig's targets d̂_k, d̂_{k−1}, d̂_{k−2}: the ring before this tick's push.
                        let d = |i| cfg.scale.specimen_disp_mm(self.targets.delayed(i));
                        c.force_kn(
                            self.last_good.force_kn,
                            self.last_good.disp_mm,
                            [d(0), d(1), d(2)],
                        )
                    }
                }),
            },
            FeedbackSource::OwnDelayed { delay_steps } => {
                let x = self.targets.delayed(delay_steps);
                Feedback {
                    brace_disp_mm: x,
                    brace_force_kn: cfg.proto.brace_force_kn(x),
                }
            }
            FeedbackSource::OwnLinearSpecimen {
                stiffness_kn_per_mm,
            } => {
                let x = self.targets.delayed(0);
                Feedback {
                    brace_disp_mm: x,
                    brace_force_kn: stiffness_kn_per_mm * x,
                }
            }
        };
        let target = self.analytical.next_target(ag_mm_s2, &fb)?;
        let given = match cfg.compensator_target {
            CompensatorTarget::Next => target,
            CompensatorTarget::Current => self.targets.delayed(0),
        };
        self.targets.push(target);
        let target_specimen = cfg.scale.specimen_disp_mm(given);
        let command = self
            .compensator
            .compensate(target_specimen, self.last_good.disp_mm)
            .map_err(|_| StepError::NonFiniteOutput)?;
        Ok((target, command))
    }
}

mod correction;
#[cfg(feature = "std")]
mod host;
mod structure;
pub use correction::ForceCorrection;
#[cfg(feature = "std")]
pub use host::{HostNumerical, StructureHost};
pub use structure::{
    AtSpecimenDof, DofIntegrator, FloorHysteronSpec, ModalSpec, PartStep, ReducedSpec,
    StoryLawSpec, StructureFe, StructureHysteron, StructureModal, StructureNl, StructurePart,
    StructureReduced, StructureSpec, HYSTERON_VALUES,
};

#[cfg(test)]
mod tests;

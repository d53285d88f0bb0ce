//! The analytical parts of a structure-file test: an N-DOF numerical substructure (linear, or with
//! yielding stories) integrated by Chang's explicit method, fed the measured specimen force at the
//! specimen's DOF and giving the target displacement there (docs/benchmark.md, docs/nonlinear.md).
//! The structure metamodel of the same substructure is [`crate::metamodel::DeltaArx`]; the learned
//! nonlinear metamodel of a yielding one is [`StructureModal`] ([`crate::metamodel::ModalHyst`]).
//!
//! Each step is the vRTHS benchmark loop's (`src/studies/benchmark/run.rs`): at tick 0 the structure is at
//! rest under `ü_g(0)` (the initial condition); at tick k > 0 the step completes with `ü_g(k)` and
//! the measured force as the specimen's restoring force at its DOF; the target is the next
//! displacement at that DOF. A non-finite input is refused before it touches the state.

use crate::hysteresis::Law;
use crate::metamodel::{
    FloorHysteron, FloorHysteronParams, FloorStructure, Hysteron, HysteronOperator, ModalHyst,
    ModalHystParams, ModalMode, ModelError, ReducedModal, ReducedModalParams, ReducedMode,
    StaticCorrection, HYST_MAX_DIRECTIONS, HYST_MAX_HYSTERONS, MODAL_MAX_SPRINGS,
};
use crate::params::ParamError;
use crate::structure_n::{ChangN, Dofs, StructureN, MAX_DOF};
use crate::structure_nl::NonlinearFrame;

/// An N-DOF structure as a structure file describes its numerical part, raw (row-major `dofs ×
/// dofs` matrices; validated by [`Self::linear`] and [`Self::yielding`]). Firmware keeps one in a
/// `const` over its generated `&'static` arrays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StructureSpec<'a> {
    /// DOFs, 1..=[`MAX_DOF`].
    pub dofs: usize,
    /// Numerical mass, kN·s²/mm.
    pub mass: &'a [f64],
    /// Numerical damping, kN·s/mm.
    pub damping: &'a [f64],
    /// Numerical linear stiffness, kN/mm (zero for a yielding frame: its stories carry it).
    pub stiffness: &'a [f64],
    /// Whole-structure initial stiffness (Chang's coefficients), kN/mm.
    pub initial_stiffness: &'a [f64],
    /// Whole-structure `M·ι`, kN·s²/mm.
    pub ground_mass: &'a [f64],
    /// The specimen's DOF, 0-based.
    pub specimen_dof: usize,
    /// The stories' laws from the ground up (empty: linear).
    pub laws: &'a [StoryLawSpec],
}

/// A story's hysteresis law, raw: [`Law::bilinear`] or, with `bouc_wen = Some([n, β, γ])`,
/// [`Law::bouc_wen`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StoryLawSpec {
    /// Initial stiffness, kN/mm.
    pub k0_kn_per_mm: f64,
    /// Yield force, kN.
    pub yield_force_kn: f64,
    /// Post-yield stiffness ratio.
    pub post_yield_ratio: f64,
    /// Bouc–Wen's `[n, β, γ]`; `None`: bilinear.
    pub bouc_wen: Option<[f64; 3]>,
}

impl StoryLawSpec {
    /// The raw form of a validated law (rebuilt exactly by [`Self::validate`]).
    pub fn of(law: &Law) -> Self {
        Self {
            k0_kn_per_mm: law.k0_kn_per_mm(),
            yield_force_kn: law.yield_force_kn(),
            post_yield_ratio: law.post_yield_ratio(),
            bouc_wen: law.bouc_wen_shape(),
        }
    }

    /// The validated law.
    pub fn validate(&self) -> Result<Law, ParamError> {
        match self.bouc_wen {
            None => Law::bilinear(
                self.k0_kn_per_mm,
                self.yield_force_kn,
                self.post_yield_ratio,
            ),
            Some([n, beta, gamma]) => Law::bouc_wen(
                self.k0_kn_per_mm,
                self.yield_force_kn,
                self.post_yield_ratio,
                n,
                beta,
                gamma,
            ),
        }
    }
}

impl StructureSpec<'_> {
    /// The validated numerical substructure (the specimen's DOF checked against it).
    pub fn numerical(&self) -> Result<StructureN, ParamError> {
        let m = StructureN::new(
            self.dofs,
            self.mass,
            self.damping,
            self.stiffness,
            self.initial_stiffness,
            self.ground_mass,
        )?;
        specimen_dof_within(self.specimen_dof, m.dofs())?;
        Ok(m)
    }

    /// The validated story laws, one per DOF (entries past the DOFs repeat the first and are
    /// unused).
    pub fn story_laws(&self) -> Result<[Law; MAX_DOF], ParamError> {
        if self.laws.len() != self.dofs {
            return Err(ParamError::OutOfRange("one story law per DOF"));
        }
        let first = self
            .laws
            .first()
            .ok_or(ParamError::OutOfRange("one story law per DOF"))?
            .validate()?;
        let mut laws = [first; MAX_DOF];
        for (l, s) in laws.iter_mut().zip(self.laws) {
            *l = s.validate()?;
        }
        Ok(laws)
    }

    /// The linear FE part at step `dt_s` (refused if the spec has story laws).
    pub fn linear(&self, dt_s: f64) -> Result<StructureFe, ParamError> {
        if !self.laws.is_empty() {
            return Err(ParamError::OutOfRange(
                "a yielding structure (story laws) as a linear one",
            ));
        }
        StructureFe::new(self.numerical()?, self.specimen_dof, dt_s)
    }

    /// The yielding FE part at step `dt_s` (one law per DOF).
    pub fn yielding(&self, dt_s: f64) -> Result<StructureNl, ParamError> {
        StructureNl::build(
            self.numerical()?,
            &self.story_laws()?,
            self.specimen_dof,
            dt_s,
        )
    }
}

/// Refuse a specimen DOF (0-based) past a structure's `dofs`.
fn specimen_dof_within(specimen_dof: usize, dofs: usize) -> Result<(), ParamError> {
    if specimen_dof >= dofs {
        Err(ParamError::OutOfRange(
            "specimen DOF (beyond the structure)",
        ))
    } else {
        Ok(())
    }
}

/// What differs between the kinds of a structure file's analytical part: how each rests, steps
/// and resets (an integrator at the specimen's DOF, or a learned or reduced model). The tick
/// around it is [`StructurePart`]'s, the same for every kind.
pub trait PartStep {
    /// Put the part at rest under `ü_g(0)` (the initial condition) and return the first target,
    /// mm.
    fn rest_under(&mut self, ag_mm_s2: f64) -> f64;
    /// Complete the step at the last target with `ü_g(k)` and the specimen's measured force: the
    /// next target, mm. A step the part refuses leaves its state unchanged.
    fn complete_step(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, super::StepError>;
    /// Back to rest under no ground motion, every spring or story virgin.
    fn back_to_rest(&mut self);
}

/// A structure file's analytical part as the controller steps it, whatever its kind: tick 0 rests
/// it under `ü_g(0)`, each later tick completes the step with `ü_g(k)` and the measured force at
/// the specimen's DOF. A non-finite input is refused before it touches the state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StructurePart<M> {
    model: M,
    started: bool,
}

impl<M: PartStep> StructurePart<M> {
    /// `model`, at rest.
    fn at_rest(mut model: M) -> Self {
        model.back_to_rest();
        Self {
            model,
            started: false,
        }
    }

    /// The part's own model, its state and read-outs (for the FE parts, the integrator at the
    /// specimen's DOF).
    pub fn model(&self) -> &M {
        &self.model
    }

    /// Tick k: complete step k with `ü_g(k)` and the specimen's measured force, return the target
    /// displacement at the specimen's DOF for k+1, mm. A non-finite `ü_g` is refused first
    /// ([`super::StepError::NonFiniteGroundAccel`]), then a non-finite force
    /// ([`super::StepError::NonFiniteOutput`]), the state untouched either way.
    #[inline]
    pub fn next_target(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, super::StepError> {
        if !ag_mm_s2.is_finite() {
            return Err(super::StepError::NonFiniteGroundAccel);
        }
        if !force_kn.is_finite() {
            return Err(super::StepError::NonFiniteOutput);
        }
        if self.started {
            self.model.complete_step(ag_mm_s2, force_kn)
        } else {
            self.started = true;
            Ok(self.model.rest_under(ag_mm_s2))
        }
    }

    /// Back to rest, every spring or story virgin.
    pub fn reset(&mut self) {
        self.model.back_to_rest();
        self.started = false;
    }
}

/// An N-DOF integrator driven by the physical part's force at each DOF: Chang's linear [`ChangN`]
/// or the yielding [`NonlinearFrame`] ([`AtSpecimenDof`] puts the specimen at one of them).
pub trait DofIntegrator {
    /// Number of DOFs.
    fn dofs(&self) -> usize;
    /// The displacement of the next step, mm.
    fn next_displacement(&self) -> &Dofs;
    /// Complete the step with `ü_g` and the physical part's force at each DOF.
    fn advance(&mut self, ag_mm_s2: f64, r_ext_kn: &Dofs);
    /// Back to rest with the acceleration due to `ü_g` at t = 0.
    fn reset(&mut self, ag_mm_s2: f64);
}

impl DofIntegrator for ChangN {
    fn dofs(&self) -> usize {
        self.model().dofs()
    }
    #[inline]
    fn next_displacement(&self) -> &Dofs {
        ChangN::next_displacement(self)
    }
    #[inline]
    fn advance(&mut self, ag_mm_s2: f64, r_ext_kn: &Dofs) {
        ChangN::advance(self, ag_mm_s2, r_ext_kn);
    }
    fn reset(&mut self, ag_mm_s2: f64) {
        ChangN::reset(self, ag_mm_s2);
    }
}

impl DofIntegrator for NonlinearFrame {
    fn dofs(&self) -> usize {
        NonlinearFrame::dofs(self)
    }
    #[inline]
    fn next_displacement(&self) -> &Dofs {
        NonlinearFrame::next_displacement(self)
    }
    #[inline]
    fn advance(&mut self, ag_mm_s2: f64, r_ext_kn: &Dofs) {
        NonlinearFrame::advance(self, ag_mm_s2, r_ext_kn);
    }
    fn reset(&mut self, ag_mm_s2: f64) {
        NonlinearFrame::reset(self, ag_mm_s2);
    }
}

/// An integrator with the specimen at one of its DOFs: the measured force acts there, the target
/// is the displacement there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AtSpecimenDof<I> {
    integrator: I,
    dof: usize,
}

impl<I: DofIntegrator> AtSpecimenDof<I> {
    /// `integrator` with the specimen at `specimen_dof` (0-based).
    fn new(integrator: I, specimen_dof: usize) -> Result<Self, ParamError> {
        specimen_dof_within(specimen_dof, integrator.dofs())?;
        Ok(Self {
            integrator,
            dof: specimen_dof,
        })
    }

    /// The integrator (every floor's state).
    pub fn integrator(&self) -> &I {
        &self.integrator
    }

    /// The specimen's DOF, 0-based.
    pub fn specimen_dof(&self) -> usize {
        self.dof
    }

    /// The target: the next displacement at the specimen's DOF, mm.
    #[inline]
    fn target_mm(&self) -> f64 {
        self.integrator
            .next_displacement()
            .get(self.dof)
            .copied()
            .unwrap_or(f64::NAN)
    }
}

impl<I: DofIntegrator> PartStep for AtSpecimenDof<I> {
    fn rest_under(&mut self, ag_mm_s2: f64) -> f64 {
        self.integrator.reset(ag_mm_s2);
        self.target_mm()
    }

    #[inline]
    fn complete_step(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, super::StepError> {
        let mut r = [0.0; MAX_DOF];
        if let Some(x) = r.get_mut(self.dof) {
            *x = force_kn;
        }
        self.integrator.advance(ag_mm_s2, &r);
        Ok(self.target_mm())
    }

    fn back_to_rest(&mut self) {
        self.integrator.reset(0.0);
    }
}

/// A linear N-DOF numerical substructure integrated by [`ChangN`].
pub type StructureFe = StructurePart<AtSpecimenDof<ChangN>>;

impl StructureFe {
    /// `model` at step `dt_s`, the specimen at `specimen_dof` (0-based), at rest.
    pub fn new(model: StructureN, specimen_dof: usize, dt_s: f64) -> Result<Self, ParamError> {
        // The DOF first: a bad DOF is the error whatever the step.
        specimen_dof_within(specimen_dof, model.dofs())?;
        Ok(Self::at_rest(AtSpecimenDof::new(
            ChangN::new(model, dt_s)?,
            specimen_dof,
        )?))
    }

    /// The integrator (every floor's state).
    pub fn chang(&self) -> &ChangN {
        self.model.integrator()
    }

    /// The specimen's DOF, 0-based.
    pub fn specimen_dof(&self) -> usize {
        self.model.specimen_dof()
    }
}

/// A yielding N-story numerical substructure ([`NonlinearFrame`]: Chang, story forces evaluated
/// once per step).
pub type StructureNl = StructurePart<AtSpecimenDof<NonlinearFrame>>;

impl StructureNl {
    /// `frame`, the specimen at `specimen_dof` (0-based), at rest, every story virgin.
    pub fn new(frame: NonlinearFrame, specimen_dof: usize) -> Result<Self, ParamError> {
        Ok(Self::at_rest(AtSpecimenDof::new(frame, specimen_dof)?))
    }

    /// `model` with `laws` (the first `model.dofs()` are used) at step `dt_s`, the specimen at
    /// `specimen_dof`.
    pub fn build(
        model: StructureN,
        laws: &[Law; MAX_DOF],
        specimen_dof: usize,
        dt_s: f64,
    ) -> Result<Self, ParamError> {
        let n = model.dofs();
        let frame = NonlinearFrame::new(model, laws.get(..n).unwrap_or(&[]), dt_s)?;
        Self::new(frame, specimen_dof)
    }

    /// The frame (every floor's and story's state).
    pub fn frame(&self) -> &NonlinearFrame {
        self.model.integrator()
    }

    /// The specimen's DOF, 0-based.
    pub fn specimen_dof(&self) -> usize {
        self.model.specimen_dof()
    }
}

/// A learned or reduced model's step in the controller's terms: its own refusal (a step that would
/// overflow, the state unchanged) is a non-finite output.
macro_rules! metamodel_part_step {
    ($($model:ty),+) => {$(
        impl PartStep for $model {
            fn rest_under(&mut self, ag_mm_s2: f64) -> f64 {
                self.reset_at(ag_mm_s2);
                self.target_mm()
            }
            #[inline]
            fn complete_step(
                &mut self,
                ag_mm_s2: f64,
                force_kn: f64,
            ) -> Result<f64, super::StepError> {
                self.step(ag_mm_s2, force_kn)
                    .map_err(|_| super::StepError::NonFiniteOutput)
            }
            fn back_to_rest(&mut self) {
                self.reset();
            }
        }
    )+};
}
metamodel_part_step!(ModalHyst, FloorHysteron, ReducedModal);

/// The modal-hysteretic metamodel of a yielding structure (an `rths-nl-model` file), raw: the
/// arrays the file stores (validated by [`Self::params`]). Firmware keeps one in a `const` over its
/// generated `&'static` arrays. The modes are continuous-time (frequencies, damping) and the laws
/// rate-independent, so a model trained at one control rate runs at any other: the step is the
/// controller's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModalSpec<'a> {
    /// The modes.
    pub modes: &'a [ModalMode],
    /// Mode shapes, floors × modes, row-major.
    pub shape: &'a [f64],
    /// The specimen's DOF, 0-based.
    pub specimen_dof: usize,
    /// The specimen's stiffness the modes include, kN/mm.
    pub specimen_k_kn_per_mm: f64,
    /// The latent springs' laws, 1..=[`MODAL_MAX_SPRINGS`].
    pub laws: &'a [StoryLawSpec],
    /// The springs' drift per unit of each mode, springs × modes, row-major.
    pub drift: &'a [f64],
}

impl ModalSpec<'_> {
    /// The validated parameters at control step `dt_s`.
    pub fn params(&self, dt_s: f64) -> Result<ModalHystParams, ModelError> {
        let m = self.laws.len();
        if m == 0 || m > MODAL_MAX_SPRINGS {
            return Err(ParamError::OutOfRange("number of latent springs (1..=8)").into());
        }
        let mut laws = [Law::bilinear(1.0, 1.0, 0.0)?; MODAL_MAX_SPRINGS];
        for (l, s) in laws.iter_mut().zip(self.laws) {
            *l = s.validate()?;
        }
        ModalHystParams::new(
            dt_s,
            self.modes,
            self.shape,
            self.specimen_dof,
            self.specimen_k_kn_per_mm,
            laws.get(..m).unwrap_or(&[]),
            self.drift,
        )
    }
}

/// The modal-hysteretic metamodel ([`ModalHyst`]) as the controller steps it.
pub type StructureModal = StructurePart<ModalHyst>;

impl StructureModal {
    /// The model of `params`, at rest.
    pub fn new(params: ModalHystParams) -> Self {
        Self::at_rest(ModalHyst::new(params))
    }
}

/// Values of one hysteron in [`FloorHysteronSpec::hysterons`]: its direction's index (a whole
/// number), threshold (mm) and weight (kN/mm).
pub const HYSTERON_VALUES: usize = 3;

/// The floor-hysteron metamodel's arrays, raw, as a model file or an upload carries them (the
/// floors' matrices row-major; validated by [`Self::params`]). Its parameters are continuous-time
/// matrices and rate-independent operators: the step is the controller's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorHysteronSpec<'a> {
    /// The elastic floors.
    pub floors: FloorStructure<'a>,
    /// The directions, directions × floors, row-major (1..=[`HYST_MAX_DIRECTIONS`]).
    pub directions: &'a [f64],
    /// The hysterons, [`HYSTERON_VALUES`] each (1..=[`HYST_MAX_HYSTERONS`]).
    pub hysterons: &'a [f64],
    /// Every hysteron's operator.
    pub operator: HysteronOperator,
}

impl FloorHysteronSpec<'_> {
    /// The validated parameters at control step `dt_s`.
    pub fn params(&self, dt_s: f64) -> Result<FloorHysteronParams, ModelError> {
        let len = self.hysterons.len();
        let h = len / HYSTERON_VALUES;
        if h == 0 || h > HYST_MAX_HYSTERONS || h * HYSTERON_VALUES != len {
            return Err(ModelError::Shape {
                what: "hysterons (1..=64, 3 values each)",
                expected: HYSTERON_VALUES * h.clamp(1, HYST_MAX_HYSTERONS),
                got: len,
            });
        }
        let mut hs = [Hysteron {
            direction: 0,
            threshold_mm: 1.0,
            weight_kn_per_mm: 0.0,
        }; HYST_MAX_HYSTERONS];
        for (dst, v) in hs
            .iter_mut()
            .zip(self.hysterons.chunks_exact(HYSTERON_VALUES))
        {
            let &[direction, threshold_mm, weight_kn_per_mm] = v else {
                return Err(ParamError::OutOfRange("hysteron (3 values)").into());
            };
            // In range first: then the cast is exact, and a fraction does not survive it.
            let whole = direction >= 0.0
                && direction < HYST_MAX_DIRECTIONS as f64
                && (direction as usize) as f64 == direction;
            if !whole {
                return Err(
                    ParamError::OutOfRange("hysteron direction (no such direction)").into(),
                );
            }
            *dst = Hysteron {
                direction: direction as usize,
                threshold_mm,
                weight_kn_per_mm,
            };
        }
        FloorHysteronParams::new(
            dt_s,
            &self.floors,
            self.directions,
            hs.get(..h).unwrap_or(&[]),
        )?
        .with_operator(self.operator)
    }
}

/// The floor-hysteron metamodel ([`FloorHysteron`]) as the controller steps it.
pub type StructureHysteron = StructurePart<FloorHysteron>;

impl StructureHysteron {
    /// The model of `params`, at rest.
    pub fn new(params: FloorHysteronParams) -> Self {
        Self::at_rest(FloorHysteron::new(params))
    }
}

/// The reduced-order modal model of a large linear structure (an `rths-reduced-model` file), raw:
/// the arrays the file stores (validated by [`Self::params`]). The modes are continuous-time, so the
/// step is the controller's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReducedSpec<'a> {
    /// The retained modes.
    pub modes: &'a [ReducedMode],
    /// The outputs' mode shapes, outputs × modes, row-major.
    pub output_shape: &'a [f64],
    /// The interface's static correction.
    pub interface_static: StaticCorrection,
    /// The outputs' static corrections.
    pub output_static: &'a [StaticCorrection],
    /// The specimen's stiffness the modes include, kN/mm.
    pub specimen_k_kn_per_mm: f64,
}

impl ReducedSpec<'_> {
    /// The validated parameters at control step `dt_s`.
    pub fn params(&self, dt_s: f64) -> Result<ReducedModalParams, ModelError> {
        ReducedModalParams::new(
            dt_s,
            self.modes,
            self.output_shape,
            self.interface_static,
            self.output_static,
            self.specimen_k_kn_per_mm,
        )
    }
}

/// The reduced-order modal model ([`ReducedModal`]) as the controller steps it.
pub type StructureReduced = StructurePart<ReducedModal>;

impl StructureReduced {
    /// The model of `params`, at rest.
    pub fn new(params: ReducedModalParams) -> Self {
        Self::at_rest(ReducedModal::new(params))
    }
}

#[cfg(test)]
mod tests;

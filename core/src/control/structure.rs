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
use crate::structure_n::{ChangN, StructureN, MAX_DOF};
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
        if self.specimen_dof >= m.dofs() {
            return Err(ParamError::OutOfRange(
                "specimen DOF (beyond the structure)",
            ));
        }
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

/// Refuse a non-finite ground acceleration or force (the state is not touched).
fn finite_inputs(ag_mm_s2: f64, force_kn: f64) -> Result<(), super::StepError> {
    if !ag_mm_s2.is_finite() {
        Err(super::StepError::NonFiniteGroundAccel)
    } else if !force_kn.is_finite() {
        Err(super::StepError::NonFiniteOutput)
    } else {
        Ok(())
    }
}

/// A linear N-DOF numerical substructure integrated by [`ChangN`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StructureFe {
    chang: ChangN,
    dof: usize,
    started: bool,
}

impl StructureFe {
    /// `model` at step `dt_s`, the specimen at `specimen_dof` (0-based), at rest.
    pub fn new(model: StructureN, specimen_dof: usize, dt_s: f64) -> Result<Self, ParamError> {
        if specimen_dof >= model.dofs() {
            return Err(ParamError::OutOfRange(
                "specimen DOF (beyond the structure)",
            ));
        }
        Ok(Self {
            chang: ChangN::new(model, dt_s)?,
            dof: specimen_dof,
            started: false,
        })
    }

    /// The integrator (every floor's state).
    pub fn chang(&self) -> &ChangN {
        &self.chang
    }

    /// The specimen's DOF, 0-based.
    pub fn specimen_dof(&self) -> usize {
        self.dof
    }

    /// Tick k: complete step k with `ü_g(k)` and the specimen's measured force, return the target
    /// displacement at the specimen's DOF for k+1, mm.
    #[inline]
    pub fn next_target(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, super::StepError> {
        finite_inputs(ag_mm_s2, force_kn)?;
        if self.started {
            let mut r = [0.0; MAX_DOF];
            if let Some(x) = r.get_mut(self.dof) {
                *x = force_kn;
            }
            self.chang.advance(ag_mm_s2, &r);
        } else {
            self.chang.reset(ag_mm_s2);
            self.started = true;
        }
        Ok(self
            .chang
            .next_displacement()
            .get(self.dof)
            .copied()
            .unwrap_or(f64::NAN))
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.chang.reset(0.0);
        self.started = false;
    }
}

/// A yielding N-story numerical substructure ([`NonlinearFrame`]: Chang, story forces evaluated
/// once per step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StructureNl {
    frame: NonlinearFrame,
    dof: usize,
    started: bool,
}

impl StructureNl {
    /// `frame`, the specimen at `specimen_dof` (0-based), at rest.
    pub fn new(frame: NonlinearFrame, specimen_dof: usize) -> Result<Self, ParamError> {
        if specimen_dof >= frame.dofs() {
            return Err(ParamError::OutOfRange(
                "specimen DOF (beyond the structure)",
            ));
        }
        let mut s = Self {
            frame,
            dof: specimen_dof,
            started: false,
        };
        s.reset();
        Ok(s)
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
        &self.frame
    }

    /// The specimen's DOF, 0-based.
    pub fn specimen_dof(&self) -> usize {
        self.dof
    }

    /// As [`StructureFe::next_target`].
    #[inline]
    pub fn next_target(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, super::StepError> {
        finite_inputs(ag_mm_s2, force_kn)?;
        if self.started {
            let mut r = [0.0; MAX_DOF];
            if let Some(x) = r.get_mut(self.dof) {
                *x = force_kn;
            }
            self.frame.advance(ag_mm_s2, &r);
        } else {
            self.frame.reset(ag_mm_s2);
            self.started = true;
        }
        Ok(self
            .frame
            .next_displacement()
            .get(self.dof)
            .copied()
            .unwrap_or(f64::NAN))
    }

    /// Back to rest, every story virgin.
    pub fn reset(&mut self) {
        self.frame.reset(0.0);
        self.started = false;
    }
}

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

/// The modal-hysteretic metamodel ([`ModalHyst`]) as the controller steps it: tick 0 rests it
/// under `ü_g(0)`, each later tick completes the step with `ü_g(k)` and the measured force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StructureModal {
    model: ModalHyst,
    started: bool,
}

impl StructureModal {
    /// The model of `params`, at rest.
    pub fn new(params: ModalHystParams) -> Self {
        Self {
            model: ModalHyst::new(params),
            started: false,
        }
    }

    /// The model (its modes' and springs' state).
    pub fn model(&self) -> &ModalHyst {
        &self.model
    }

    /// As [`StructureFe::next_target`]; a step that would overflow is refused (state unchanged).
    #[inline]
    pub fn next_target(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, super::StepError> {
        finite_inputs(ag_mm_s2, force_kn)?;
        if self.started {
            self.model
                .step(ag_mm_s2, force_kn)
                .map_err(|_| super::StepError::NonFiniteOutput)
        } else {
            self.model.reset_at(ag_mm_s2);
            self.started = true;
            Ok(self.model.target_mm())
        }
    }

    /// Back to rest, every spring virgin.
    pub fn reset(&mut self) {
        self.model.reset();
        self.started = false;
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

/// The floor-hysteron metamodel ([`FloorHysteron`]) as the controller steps it: tick 0 rests it
/// under `ü_g(0)`, each later tick completes the step with `ü_g(k)` and the measured force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StructureHysteron {
    model: FloorHysteron,
    started: bool,
}

impl StructureHysteron {
    /// The model of `params`, at rest.
    pub fn new(params: FloorHysteronParams) -> Self {
        Self {
            model: FloorHysteron::new(params),
            started: false,
        }
    }

    /// The model (its floors' and hysterons' state).
    pub fn model(&self) -> &FloorHysteron {
        &self.model
    }

    /// As [`StructureFe::next_target`]; a step that would overflow is refused (state unchanged).
    #[inline]
    pub fn next_target(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, super::StepError> {
        finite_inputs(ag_mm_s2, force_kn)?;
        if self.started {
            self.model
                .step(ag_mm_s2, force_kn)
                .map_err(|_| super::StepError::NonFiniteOutput)
        } else {
            self.model.reset_at(ag_mm_s2);
            self.started = true;
            Ok(self.model.target_mm())
        }
    }

    /// Back to rest, every hysteron virgin.
    pub fn reset(&mut self) {
        self.model.reset();
        self.started = false;
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

/// The reduced-order modal model ([`ReducedModal`]) as the controller steps it: tick 0 rests it
/// under `ü_g(0)`, each later tick completes the step with `ü_g(k)` and the measured force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StructureReduced {
    model: ReducedModal,
    started: bool,
}

impl StructureReduced {
    /// The model of `params`, at rest.
    pub fn new(params: ReducedModalParams) -> Self {
        Self {
            model: ReducedModal::new(params),
            started: false,
        }
    }

    /// The model (its modes' state and read-outs).
    pub fn model(&self) -> &ReducedModal {
        &self.model
    }

    /// As [`StructureFe::next_target`]; a step that would overflow is refused (state unchanged).
    #[inline]
    pub fn next_target(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, super::StepError> {
        finite_inputs(ag_mm_s2, force_kn)?;
        if self.started {
            self.model
                .step(ag_mm_s2, force_kn)
                .map_err(|_| super::StepError::NonFiniteOutput)
        } else {
            self.model.reset_at(ag_mm_s2);
            self.started = true;
            Ok(self.model.target_mm())
        }
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.model.reset();
        self.started = false;
    }
}

#[cfg(test)]
mod tests;

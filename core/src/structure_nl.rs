//! A nonlinear N-story shear frame (1 ≤ N ≤ [`MAX_DOF`]) whose stories follow hysteretic laws
//! ([`crate::hysteresis`]), stepped by the same explicit Chang integrator as the linear structure
//! ([`ChangN`], docs/design.md §3.2).
//!
//! Chang's method predicts the next displacement explicitly from the last state, so the story
//! forces at that displacement are evaluated once per step and enter the equilibrium as a known
//! restoring force: `(M + ½ΔtC)·a₁ = −Mι·ü_g − K_lin·d₁ − R_h(d₁) − r_ext − C·(v₀ + ½Δt·a₀)`. The
//! integrator's coefficients use the whole structure's *initial* stiffness, which keeps the method
//! stable for any softening of the stories (their tangent stays at or below `k0`).
//!
//! `K_lin` is the linear part the integrator already carries ([`StructureN::stiffness`]): zero for
//! the numerical part of a test, the specimen's stiffness at its DOF for the whole structure (the
//! reference). Story `i` (0-based) joins floor `i−1` (the ground for `i = 0`) to floor `i`; its
//! drift is `x_i − x_{i−1}` and its force `f_i` pulls floor `i` back by `f_i` and floor `i−1`
//! forward by `f_i`.

use crate::hysteresis::{Law, Story};
use crate::params::ParamError;
use crate::structure_n::{story_drifts_mm, ChangN, Dofs, StructureN, MAX_DOF};

/// A nonlinear shear frame and its state, integrated by Chang's explicit method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonlinearFrame {
    chang: ChangN,
    stories: [Option<Story>; MAX_DOF],
    /// Story forces at the last completed step, kN.
    story_force: Dofs,
}

impl NonlinearFrame {
    /// `model` carries the mass, damping, linear stiffness (see the module docs), initial stiffness
    /// and ground mass; `laws` one law per story, from the ground up (as many as DOFs).
    pub fn new(model: StructureN, laws: &[Law], dt_s: f64) -> Result<Self, ParamError> {
        if laws.len() != model.dofs() {
            return Err(ParamError::OutOfRange("one story law per DOF"));
        }
        let mut stories = [None; MAX_DOF];
        for (s, law) in stories.iter_mut().zip(laws) {
            *s = Some(Story::new(*law));
        }
        let mut f = Self {
            chang: ChangN::new(model, dt_s)?,
            stories,
            story_force: [0.0; MAX_DOF],
        };
        f.reset(0.0);
        Ok(f)
    }

    /// The integrator (displacement, velocity, acceleration of the last step).
    pub fn chang(&self) -> &ChangN {
        &self.chang
    }

    /// Number of DOFs (= stories).
    pub fn dofs(&self) -> usize {
        self.chang.model().dofs()
    }

    /// The stories, from the ground up (the first [`Self::dofs`] are `Some`).
    pub fn stories(&self) -> &[Option<Story>; MAX_DOF] {
        &self.stories
    }

    /// The displacement of the next step, mm.
    pub fn next_displacement(&self) -> &Dofs {
        self.chang.next_displacement()
    }

    /// Story forces at the last completed step, kN.
    pub fn story_force_kn(&self) -> &Dofs {
        &self.story_force
    }

    /// Story drifts at the last completed step, mm.
    pub fn story_drift_mm(&self) -> Dofs {
        story_drifts_mm(self.chang.disp(), self.dofs())
    }

    /// Complete the step at [`Self::next_displacement`]: the stories move there (their state is
    /// committed: an explicit step is never re-tried), then Chang's equilibrium with `ü_g` and the
    /// physical part's force `r_ext_kn` at each DOF.
    #[inline]
    pub fn advance(&mut self, ground_accel_mm_s2: f64, r_ext_kn: &Dofs) {
        let n = self.dofs();
        let d = story_drifts_mm(self.chang.next_displacement(), n);
        for ((f, s), u) in self.story_force.iter_mut().zip(&mut self.stories).zip(d) {
            if let Some(s) = s {
                *f = s.update(u);
            }
        }
        let mut r = *r_ext_kn;
        for i in 0..n {
            let above = self.story_force.get(i + 1).copied().unwrap_or(0.0);
            let here = self.story_force.get(i).copied().unwrap_or(0.0);
            if let Some(ri) = r.get_mut(i) {
                // The story above is zero past the top (entries beyond N stay zero).
                *ri += here - if i + 1 < n { above } else { 0.0 };
            }
        }
        self.chang.advance(ground_accel_mm_s2, &r);
    }

    /// Back to rest, every story virgin, with the acceleration due to `ground_accel_mm_s2` at t = 0.
    pub fn reset(&mut self, ground_accel_mm_s2: f64) {
        for s in self.stories.iter_mut().flatten() {
            s.reset();
        }
        self.story_force = [0.0; MAX_DOF];
        self.chang.reset(ground_accel_mm_s2);
    }
}

#[cfg(test)]
mod tests;

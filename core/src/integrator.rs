//! Time integrators for the analytical substructure, stepping one controller tick at a time.
//!
//! The hybrid loop needs integrators that are *explicit in displacement*: the displacement of step
//! `i+1` (the actuator command) is known before the restoring force at that displacement is measured.
//! Two are provided, both unconditionally stable for linear systems whose stiffness does not exceed
//! the initial stiffness `K0` used for their coefficients:
//!
//! - [`Chang`] (Chang 2002): `d₁ = d₀ + β1·Δt·v₀ + β2·Δt²·a₀`, `v₁ = v₀ + Δt/2·(a₀ + a₁)`, with
//!   `D = M + ½ΔtC + ¼Δt²K0`, `β1 = D⁻¹(M + ½ΔtC)`, `β2 = D⁻¹(½M)`.
//! - [`ChenRicles`] (Chen & Ricles 2008, "CR"): `v₁ = v₀ + Δt·α·a₀`, `d₁ = d₀ + Δt·v₀ + Δt²·α·a₀`,
//!   with `α = D⁻¹M`.
//!
//! Then equilibrium `M·a₁ + C·v₁ + K·d₁ + r_ext = −M·ι·ü_g` gives `a₁`. `r_ext` is the measured
//! restoring force of the experimental substructure (the hook a hybrid run feeds; zero in a pure run).
//!
//! [`Newmark`] average acceleration (implicit, linear only) is the reference solution.

use crate::params::{positive, ParamError};
use crate::structure::{LinearStructure, Mat, Vector};

/// Displacement, velocity and acceleration of the structure at one step (mm, mm/s, mm/s²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Kinematics<const N: usize> {
    /// Displacement, mm.
    pub disp: Vector<N>,
    /// Velocity, mm/s.
    pub vel: Vector<N>,
    /// Acceleration (relative to the ground), mm/s².
    pub accel: Vector<N>,
}

impl<const N: usize> Default for Kinematics<N> {
    fn default() -> Self {
        Self {
            disp: Vector::<N>::zeros(),
            vel: Vector::<N>::zeros(),
            accel: Vector::<N>::zeros(),
        }
    }
}

/// An integrator that is explicit in displacement, stepped once per controller tick.
pub trait ExplicitIntegrator<const N: usize> {
    /// The displacement of the next step, mm: the command to impose before the force is measured.
    fn next_displacement(&self) -> &Vector<N>;
    /// Complete the step at [`Self::next_displacement`]: `ground_accel_mm_s2` is `ü_g` at that step and
    /// `r_ext_kn` the restoring force of the experimental part there (zero in a pure analysis).
    fn advance(&mut self, ground_accel_mm_s2: f64, r_ext_kn: &Vector<N>);
    /// The state at the last completed step.
    fn state(&self) -> &Kinematics<N>;
    /// Back to rest (zero displacement and velocity) with the acceleration due to `ground_accel_mm_s2`
    /// at t = 0.
    fn reset(&mut self, ground_accel_mm_s2: f64);
}

/// Coefficients common to the explicit schemes.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Common<const N: usize> {
    model: LinearStructure<N>,
    dt_s: f64,
    /// `(M + ½ΔtC)⁻¹` (Chang) or `M⁻¹` (CR), used to solve for the new acceleration.
    solve: Mat<N>,
}

fn validate_dt(dt_s: f64) -> Result<f64, ParamError> {
    positive(dt_s, "time step")
}

fn d_matrix<const N: usize>(model: &LinearStructure<N>, dt: f64) -> Mat<N> {
    model.mass() + model.damping() * (0.5 * dt) + model.initial_stiffness() * (0.25 * dt * dt)
}

fn invert<const N: usize>(m: Mat<N>, what: &'static str) -> Result<Mat<N>, ParamError> {
    let inv = m.try_inverse().ok_or(ParamError::Singular(what))?;
    if inv.iter().all(|v| v.is_finite()) {
        Ok(inv)
    } else {
        Err(ParamError::Singular(what))
    }
}

/// Chang's explicit method (2002 form). Parameters are fixed at construction; the state is reset by
/// [`ExplicitIntegrator::reset`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chang<const N: usize> {
    common: Common<N>,
    /// `Δt·β1`
    b1_dt: Mat<N>,
    /// `Δt²·β2`
    b2_dt2: Mat<N>,
    state: Kinematics<N>,
    next: Vector<N>,
}

impl<const N: usize> Chang<N> {
    /// Build for a model and a step `dt_s`, at rest.
    pub fn new(model: LinearStructure<N>, dt_s: f64) -> Result<Self, ParamError> {
        let dt = validate_dt(dt_s)?;
        let d_inv = invert(d_matrix(&model, dt), "Chang D matrix")?;
        let b1 = d_inv * (model.mass() + model.damping() * (0.5 * dt));
        let b2 = d_inv * (model.mass() * 0.5);
        let solve = invert(model.mass() + model.damping() * (0.5 * dt), "M + Δt/2·C")?;
        let mut s = Self {
            common: Common {
                model,
                dt_s: dt,
                solve,
            },
            b1_dt: b1 * dt,
            b2_dt2: b2 * (dt * dt),
            state: Kinematics::default(),
            next: Vector::<N>::zeros(),
        };
        s.reset(0.0);
        Ok(s)
    }

    /// The time step, s.
    pub fn dt_s(&self) -> f64 {
        self.common.dt_s
    }

    fn predict(&mut self) {
        let k = &self.state;
        self.next = k.disp + self.b1_dt * k.vel + self.b2_dt2 * k.accel;
    }
}

impl<const N: usize> ExplicitIntegrator<N> for Chang<N> {
    fn next_displacement(&self) -> &Vector<N> {
        &self.next
    }

    fn advance(&mut self, ground_accel_mm_s2: f64, r_ext_kn: &Vector<N>) {
        let m = &self.common.model;
        let half_dt = 0.5 * self.common.dt_s;
        let d1 = self.next;
        let v_pred = self.state.vel + self.state.accel * half_dt;
        let rhs = m.ground_force(ground_accel_mm_s2)
            - m.stiffness() * d1
            - r_ext_kn
            - m.damping() * v_pred;
        let a1 = self.common.solve * rhs;
        self.state = Kinematics {
            disp: d1,
            vel: v_pred + a1 * half_dt,
            accel: a1,
        };
        self.predict();
    }

    fn state(&self) -> &Kinematics<N> {
        &self.state
    }

    fn reset(&mut self, ground_accel_mm_s2: f64) {
        let m = &self.common.model;
        // At rest: M·a₀ = f₀. M is SPD (validated), so its inverse exists.
        let a0 = m
            .mass()
            .try_inverse()
            .map(|mi| mi * m.ground_force(ground_accel_mm_s2))
            .unwrap_or_else(Vector::<N>::zeros);
        self.state = Kinematics {
            accel: a0,
            ..Kinematics::default()
        };
        self.predict();
    }
}

/// The CR explicit method (Chen & Ricles 2008).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChenRicles<const N: usize> {
    common: Common<N>,
    /// `Δt·α`
    a_dt: Mat<N>,
    /// `Δt²·α`
    a_dt2: Mat<N>,
    state: Kinematics<N>,
    next: Vector<N>,
    next_vel: Vector<N>,
}

impl<const N: usize> ChenRicles<N> {
    /// Build for a model and a step `dt_s`, at rest.
    pub fn new(model: LinearStructure<N>, dt_s: f64) -> Result<Self, ParamError> {
        let dt = validate_dt(dt_s)?;
        let alpha = invert(d_matrix(&model, dt), "CR D matrix")? * model.mass();
        let solve = invert(*model.mass(), "mass matrix")?;
        let mut s = Self {
            common: Common {
                model,
                dt_s: dt,
                solve,
            },
            a_dt: alpha * dt,
            a_dt2: alpha * (dt * dt),
            state: Kinematics::default(),
            next: Vector::<N>::zeros(),
            next_vel: Vector::<N>::zeros(),
        };
        s.reset(0.0);
        Ok(s)
    }

    fn predict(&mut self) {
        let k = &self.state;
        self.next_vel = k.vel + self.a_dt * k.accel;
        self.next = k.disp + k.vel * self.common.dt_s + self.a_dt2 * k.accel;
    }
}

impl<const N: usize> ExplicitIntegrator<N> for ChenRicles<N> {
    fn next_displacement(&self) -> &Vector<N> {
        &self.next
    }

    fn advance(&mut self, ground_accel_mm_s2: f64, r_ext_kn: &Vector<N>) {
        let m = &self.common.model;
        let (d1, v1) = (self.next, self.next_vel);
        let rhs =
            m.ground_force(ground_accel_mm_s2) - m.stiffness() * d1 - r_ext_kn - m.damping() * v1;
        self.state = Kinematics {
            disp: d1,
            vel: v1,
            accel: self.common.solve * rhs,
        };
        self.predict();
    }

    fn state(&self) -> &Kinematics<N> {
        &self.state
    }

    fn reset(&mut self, ground_accel_mm_s2: f64) {
        let m = &self.common.model;
        self.state = Kinematics {
            accel: self.common.solve * m.ground_force(ground_accel_mm_s2),
            ..Kinematics::default()
        };
        self.predict();
    }
}

/// Newmark average acceleration (γ = ½, β = ¼), implicit: the reference solution of a *linear*
/// structure (its `stiffness` must be the whole structure's; there is no external force hook).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Newmark<const N: usize> {
    model: LinearStructure<N>,
    dt_s: f64,
    k_hat_inv: Mat<N>,
    state: Kinematics<N>,
}

impl<const N: usize> Newmark<N> {
    /// Build for a model and a step `dt_s`, at rest.
    pub fn new(model: LinearStructure<N>, dt_s: f64) -> Result<Self, ParamError> {
        let dt = validate_dt(dt_s)?;
        let k_hat =
            model.stiffness() + model.damping() * (2.0 / dt) + model.mass() * (4.0 / (dt * dt));
        let k_hat_inv = invert(k_hat, "Newmark effective stiffness")?;
        let mut s = Self {
            model,
            dt_s: dt,
            k_hat_inv,
            state: Kinematics::default(),
        };
        s.reset(0.0);
        Ok(s)
    }

    /// Back to rest with the acceleration due to `ground_accel_mm_s2` at t = 0.
    pub fn reset(&mut self, ground_accel_mm_s2: f64) {
        let m = &self.model;
        let a0 = m
            .mass()
            .try_inverse()
            .map(|mi| mi * m.ground_force(ground_accel_mm_s2))
            .unwrap_or_else(Vector::<N>::zeros);
        self.state = Kinematics {
            accel: a0,
            ..Kinematics::default()
        };
    }

    /// One step to ground acceleration `ground_accel_mm_s2` at the new time.
    pub fn step(&mut self, ground_accel_mm_s2: f64) -> &Kinematics<N> {
        let (m, dt) = (&self.model, self.dt_s);
        let Kinematics {
            disp: d,
            vel: v,
            accel: a,
        } = self.state;
        let rhs = m.ground_force(ground_accel_mm_s2)
            + m.mass() * (d * (4.0 / (dt * dt)) + v * (4.0 / dt) + a)
            + m.damping() * (d * (2.0 / dt) + v);
        let d1 = self.k_hat_inv * rhs;
        let v1 = (d1 - d) * (2.0 / dt) - v;
        let a1 = (d1 - d) * (4.0 / (dt * dt)) - v * (4.0 / dt) - a;
        self.state = Kinematics {
            disp: d1,
            vel: v1,
            accel: a1,
        };
        &self.state
    }

    /// The state at the last step.
    pub fn state(&self) -> &Kinematics<N> {
        &self.state
    }
}

#[cfg(test)]
mod tests;

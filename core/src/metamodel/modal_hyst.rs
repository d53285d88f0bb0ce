//! Modal-hysteretic metamodel of a yielding numerical substructure (docs/design.md §5.5,
//! docs/nonlinear.md): `r` elastic modal oscillators of the whole structure, driven by the ground
//! acceleration and by the measured specimen force, with `m` hysteretic latent springs whose
//! deviation from elasticity feeds back into the modes.
//!
//! Per mode `j` (mass-normalized shape `φ_j`, participation `Γ_j = φ_jᵀMι`):
//! `q̈_j + 2ζ_jω_j·q̇_j + ω_j²·q_j = −Γ_j·ü_g − φ_sj·(F − k_e·u_s) − Σ_k D_kj·h_k`, with the spring
//! drifts `δ_k = Σ_j D_kj·q_j`, their deviation from elasticity `h_k = f_k(δ_k) − k0_k·δ_k`
//! (`f_k` a Bouc–Wen or bilinear law, [`crate::hysteresis`]), the specimen DOF's displacement
//! `u_s = Σ_j φ_sj·q_j` and the measured force `F`. The coupling is one matrix `D` both ways, so
//! the springs do no work the modes do not see (the assembly is the drift map's transpose).
//!
//! The modes are stepped by Chang's explicit method (the integrator of the FE,
//! [`crate::structure_n::ChangN`]), each on its own scalar equation: the next target displacement is
//! known before the force at it is measured, and the step costs `O(r + r·m)` plus the springs'
//! laws, independent of the structure's DOF count. With `r = N` modes and the stories as springs
//! it is the FE itself written in modal coordinates (a test checks the equality).
//!
//! `no_std`, allocation-free, panic-free; a non-finite input or an overflowing step is refused with
//! [`ModelError`] and the state is left as it was.

use super::modal_chang::{predict, time_step, ModeStep};
use super::{all_finite, shape, ModelError};
use crate::hysteresis::{Law, StoryState};
use crate::params::ParamError;

/// Largest number of modes of the model.
pub const MODAL_MAX_MODES: usize = 8;
/// Largest number of latent hysteretic springs.
pub const MODAL_MAX_SPRINGS: usize = 8;
/// Largest number of floors the read-out covers (the structure's DOFs).
pub const MODAL_MAX_FLOORS: usize = crate::structure_n::MAX_DOF;

/// One elastic mode of the whole structure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModalMode {
    /// Natural circular frequency, rad/s.
    pub omega_rad_s: f64,
    /// Modal damping ratio.
    pub damping_ratio: f64,
    /// Ground participation `Γ = φᵀMι` of the mass-normalized mode, kN·s²/mm per √(kN·s²/mm).
    pub ground_participation: f64,
}

/// Validated parameters of the modal-hysteretic model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModalHystParams {
    dt_s: f64,
    modes: usize,
    mode: [ModalMode; MODAL_MAX_MODES],
    floors: usize,
    /// `shape[i][j]`: mode `j` at floor `i`.
    shape: [[f64; MODAL_MAX_MODES]; MODAL_MAX_FLOORS],
    specimen_dof: usize,
    specimen_k_kn_per_mm: f64,
    springs: usize,
    law: [Option<Law>; MODAL_MAX_SPRINGS],
    /// `drift[k][j]`: spring `k`'s drift per unit of mode `j`.
    drift: [[f64; MODAL_MAX_MODES]; MODAL_MAX_SPRINGS],
}

impl ModalHystParams {
    /// Validate and build. `modes`: 1..=[`MODAL_MAX_MODES`], each `ω > 0`, `0 ≤ ζ < 1`, `Γ`
    /// finite. `shape_row_major`: floors × modes (floors 1..=[`MODAL_MAX_FLOORS`]).
    /// `specimen_dof` < floors, `specimen_k_kn_per_mm ≥ 0` (the specimen's stiffness the modes
    /// include). `laws`: 1..=[`MODAL_MAX_SPRINGS`] springs, `drift_row_major`: springs × modes.
    /// `dt_s > 0`.
    pub fn new(
        dt_s: f64,
        modes: &[ModalMode],
        shape_row_major: &[f64],
        specimen_dof: usize,
        specimen_k_kn_per_mm: f64,
        laws: &[Law],
        drift_row_major: &[f64],
    ) -> Result<Self, ModelError> {
        let dt_s = time_step(dt_s)?;
        let r = modes.len();
        if r == 0 || r > MODAL_MAX_MODES {
            return Err(ParamError::OutOfRange("number of modes (1..=8)").into());
        }
        let mut mode = [ModalMode {
            omega_rad_s: 1.0,
            damping_ratio: 0.0,
            ground_participation: 0.0,
        }; MODAL_MAX_MODES];
        for (dst, m) in mode.iter_mut().zip(modes) {
            all_finite(
                &[m.omega_rad_s, m.damping_ratio, m.ground_participation],
                "modal frequency, damping or participation",
            )?;
            if m.omega_rad_s <= 0.0 {
                return Err(ParamError::NotPositive("modal frequency").into());
            }
            if !(0.0..1.0).contains(&m.damping_ratio) {
                return Err(ParamError::OutOfRange("modal damping ratio (0 ≤ ζ < 1)").into());
            }
            *dst = *m;
        }
        if shape_row_major.is_empty() || shape_row_major.len() % r != 0 {
            return Err(ModelError::Shape {
                what: "mode shapes (floors × modes)",
                expected: r,
                got: shape_row_major.len(),
            });
        }
        let floors = shape_row_major.len() / r;
        if floors > MODAL_MAX_FLOORS {
            return Err(ParamError::OutOfRange("number of floors (1..=8)").into());
        }
        all_finite(shape_row_major, "mode shapes")?;
        let mut shape_m = [[0.0; MODAL_MAX_MODES]; MODAL_MAX_FLOORS];
        for (row, src) in shape_m.iter_mut().zip(shape_row_major.chunks_exact(r)) {
            for (d, s) in row.iter_mut().zip(src) {
                *d = *s;
            }
        }
        if specimen_dof >= floors {
            return Err(ParamError::OutOfRange("specimen DOF (beyond the floors)").into());
        }
        if !specimen_k_kn_per_mm.is_finite() {
            return Err(ParamError::NotFinite("specimen stiffness").into());
        }
        if specimen_k_kn_per_mm < 0.0 {
            return Err(ParamError::OutOfRange("specimen stiffness (≥ 0)").into());
        }
        let m = laws.len();
        if m == 0 || m > MODAL_MAX_SPRINGS {
            return Err(ParamError::OutOfRange("number of latent springs (1..=8)").into());
        }
        shape(
            drift_row_major,
            m * r,
            "spring drift coefficients (springs × modes)",
        )?;
        all_finite(drift_row_major, "spring drift coefficients")?;
        let mut drift = [[0.0; MODAL_MAX_MODES]; MODAL_MAX_SPRINGS];
        for (row, src) in drift.iter_mut().zip(drift_row_major.chunks_exact(r)) {
            for (d, s) in row.iter_mut().zip(src) {
                *d = *s;
            }
        }
        let mut law = [None; MODAL_MAX_SPRINGS];
        for (d, l) in law.iter_mut().zip(laws) {
            *d = Some(*l);
        }
        Ok(Self {
            dt_s,
            modes: r,
            mode,
            floors,
            shape: shape_m,
            specimen_dof,
            specimen_k_kn_per_mm,
            springs: m,
            law,
            drift,
        })
    }

    /// The same model at control step `dt_s`: the modes are continuous-time and the laws
    /// rate-independent, so a model trained at one rate runs at another.
    pub fn at_dt_s(self, dt_s: f64) -> Result<Self, ModelError> {
        Ok(Self {
            dt_s: time_step(dt_s)?,
            ..self
        })
    }

    /// The time step, s.
    pub fn dt_s(&self) -> f64 {
        self.dt_s
    }
    /// Number of modes.
    pub fn modes(&self) -> usize {
        self.modes
    }
    /// Number of floors of the read-out.
    pub fn floors(&self) -> usize {
        self.floors
    }
    /// Number of latent springs.
    pub fn springs(&self) -> usize {
        self.springs
    }
    /// The specimen's DOF (0-based).
    pub fn specimen_dof(&self) -> usize {
        self.specimen_dof
    }
    /// The modes in use.
    pub fn mode_list(&self) -> &[ModalMode] {
        self.mode.get(..self.modes).unwrap_or(&[])
    }
    /// The springs' laws (the first [`Self::springs`] are `Some`).
    pub fn laws(&self) -> &[Option<Law>; MODAL_MAX_SPRINGS] {
        &self.law
    }
}

/// The modal-hysteretic model and its state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModalHyst {
    p: ModalHystParams,
    step: [ModeStep; MODAL_MAX_MODES],
    /// The springs' small states (their laws stay in the parameters: a step copies 16 B each).
    states: [StoryState; MODAL_MAX_SPRINGS],
    disp: [f64; MODAL_MAX_MODES],
    vel: [f64; MODAL_MAX_MODES],
    accel: [f64; MODAL_MAX_MODES],
    next: [f64; MODAL_MAX_MODES],
    /// The specimen DOF's displacement at `next` (the target given; the next step's `u_s`).
    target: f64,
}

impl ModalHyst {
    /// A model at rest.
    pub fn new(p: ModalHystParams) -> Self {
        let dt = p.dt_s;
        let mut step = [ModeStep::default(); MODAL_MAX_MODES];
        for (s, m) in step.iter_mut().zip(p.mode_list()) {
            *s = ModeStep::new(m.omega_rad_s, m.damping_ratio, dt);
        }
        let mut me = Self {
            p,
            step,
            states: [StoryState::REST; MODAL_MAX_SPRINGS],
            disp: [0.0; MODAL_MAX_MODES],
            vel: [0.0; MODAL_MAX_MODES],
            accel: [0.0; MODAL_MAX_MODES],
            next: [0.0; MODAL_MAX_MODES],
            target: 0.0,
        };
        me.reset();
        me
    }

    /// The parameters.
    pub fn params(&self) -> &ModalHystParams {
        &self.p
    }

    /// Back to rest, every spring virgin, zero ground acceleration.
    pub fn reset(&mut self) {
        self.reset_at(0.0);
    }

    /// Back to rest with the acceleration due to `ground_accel_mm_s2` at t = 0 (as the FE's
    /// `reset`); a non-finite value counts as 0.
    pub fn reset_at(&mut self, ground_accel_mm_s2: f64) {
        let ag = super::start_accel_mm_s2(ground_accel_mm_s2);
        self.states = [StoryState::REST; MODAL_MAX_SPRINGS];
        self.disp = [0.0; MODAL_MAX_MODES];
        self.vel = [0.0; MODAL_MAX_MODES];
        for (a, m) in self.accel.iter_mut().zip(self.p.mode_list()) {
            *a = -m.ground_participation * ag;
        }
        let (next, _) = predict(&self.step, &self.disp, &self.vel, &self.accel, self.p.modes);
        self.next = next;
        self.target = self.floor_of(&self.next, self.p.specimen_dof);
    }

    /// The target displacement of the specimen's DOF for the coming step, mm.
    pub fn target_mm(&self) -> f64 {
        self.target
    }

    /// Displacement of floor `i` (0-based) at the last completed step, mm (0 past the floors).
    pub fn floor_disp_mm(&self, i: usize) -> f64 {
        if i < self.p.floors {
            self.floor_of(&self.disp, i)
        } else {
            0.0
        }
    }

    /// Drift of story `i` (floor `i` minus floor `i−1`, the ground for `i = 0`) at the last
    /// completed step, mm.
    pub fn story_drift_mm(&self, i: usize) -> f64 {
        let below = if i == 0 {
            0.0
        } else {
            self.floor_disp_mm(i - 1)
        };
        self.floor_disp_mm(i) - below
    }

    /// Drift of latent spring `k` at the last completed step, mm (0 past the springs).
    pub fn spring_drift_mm(&self, k: usize) -> f64 {
        self.states.get(k).map_or(0.0, |s| s.drift_mm())
    }

    #[inline]
    fn floor_of(&self, q: &[f64; MODAL_MAX_MODES], i: usize) -> f64 {
        self.p.shape.get(i).map_or(0.0, |row| {
            row.iter()
                .zip(q)
                .take(self.p.modes)
                .map(|(a, b)| a * b)
                .sum()
        })
    }

    /// Complete the step at the last target with the ground acceleration there and the specimen's
    /// measured force (kN, at the specimen's DOF); return the next target displacement of the
    /// specimen's DOF, mm. A non-finite input or result is refused and the state is unchanged.
    #[inline]
    pub fn step(
        &mut self,
        ground_accel_mm_s2: f64,
        specimen_force_kn: f64,
    ) -> Result<f64, ModelError> {
        if !ground_accel_mm_s2.is_finite() || !specimen_force_kn.is_finite() {
            return Err(ParamError::NotFinite("ground acceleration or specimen force").into());
        }
        let r = self.p.modes;
        let d1 = self.next;
        // The specimen DOF's displacement at `d1`: the last target, computed then.
        let unbalanced = specimen_force_kn - self.p.specimen_k_kn_per_mm * self.target;
        // Modal restoring force beyond the elastic modes: the specimen's unbalance, then each
        // spring's deviation from elasticity through the same drift map.
        let mut rq = [0.0; MODAL_MAX_MODES];
        if let Some(row) = self.p.shape.get(self.p.specimen_dof) {
            for (x, phi) in rq.iter_mut().zip(row).take(r) {
                *x = phi * unbalanced;
            }
        }
        // The springs' states move on a copy, committed only if the step is finite.
        let m = self.p.springs;
        let mut states = self.states;
        for ((s, law), row) in states
            .iter_mut()
            .zip(&self.p.law)
            .zip(&self.p.drift)
            .take(m)
        {
            if let Some(law) = law {
                let mut delta = 0.0;
                for (a, b) in row.iter().zip(&d1).take(r) {
                    delta += a * b;
                }
                let h = law.update(s, delta) - law.k0_kn_per_mm() * delta;
                for (x, dk) in rq.iter_mut().zip(row).take(r) {
                    *x += dk * h;
                }
            }
        }
        let half_dt = 0.5 * self.p.dt_s;
        let mut v1 = [0.0; MODAL_MAX_MODES];
        let mut a1 = [0.0; MODAL_MAX_MODES];
        // Zipped fixed arrays: no index to check.
        for (((((((st, m), v0), a0), d), x), vo), ao) in self
            .step
            .iter()
            .zip(&self.p.mode)
            .zip(&self.vel)
            .zip(&self.accel)
            .zip(&d1)
            .zip(&rq)
            .zip(v1.iter_mut())
            .zip(a1.iter_mut())
            .take(r)
        {
            let vp = v0 + a0 * half_dt;
            let a = (-m.ground_participation * ground_accel_mm_s2 - st.k * d - x - st.c * vp)
                * st.solve;
            *vo = vp + a * half_dt;
            *ao = a;
        }
        let (next, ok) = predict(&self.step, &d1, &v1, &a1, r);
        let target = self.floor_of(&next, self.p.specimen_dof);
        if !ok || !target.is_finite() {
            return Err(ParamError::NotFinite("model state (the step overflowed)").into());
        }
        self.states = states;
        self.disp = d1;
        self.vel = v1;
        self.accel = a1;
        self.next = next;
        self.target = target;
        Ok(target)
    }
}

#[cfg(test)]
mod tests;

//! Reduced-order model of a large linear numerical substructure (an imported OpenSees model,
//! docs/opensees.md "The reduced model"): the `r` lowest modes of the whole structure (numerical
//! part plus the specimen's nominal stiffness `k_e`), each stepped by Chang's explicit method, and a
//! static correction for the modes left out.
//!
//! Per retained mode `j` (mass-normalized shape `φ_j`, participation `Γ_j = φ_jᵀMι`):
//! `q̈_j + 2ζ_jω_j·q̇_j + ω_j²·q_j = −Γ_j·ü_g − φ_sj·ΔF`, with `ΔF = F − k_e·u_s` the measured
//! specimen force's deviation from the nominal specimen at the last target `u_s`. A read-out
//! (the interface and each output DOF) is `u = Σ_j φ_j·q_j − h·ü_g − g·ΔF`, where `h` and `g` are
//! the truncated modes' quasi-static share of the response to the ground and to the interface
//! force (the whole structure's static response minus the retained modes' static share; the
//! truncated modes are far above the excitation's band, so they respond statically).
//!
//! The next target is known before the force at it is measured (Chang's displacement is explicit);
//! the static terms use the last tick's ground acceleration and force deviation, a one-tick lag on
//! the small residual. A step costs `O(r·(1 + outputs))` whatever the structure's DOF count.
//!
//! `no_std`, allocation-free, panic-free; a non-finite input or an overflowing step is refused with
//! [`ModelError`] and the state is left as it was.

use super::modal_chang::{predict, time_step, ModeStep};
use super::{all_finite, ModelError};
use crate::params::ParamError;

/// Largest number of retained modes.
pub const REDUCED_MAX_MODES: usize = 32;
/// Largest number of read-outs besides the interface.
pub const REDUCED_MAX_OUTPUTS: usize = 16;

/// One retained mode of the whole structure, with its shape at the interface and the outputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReducedMode {
    /// Natural circular frequency, rad/s.
    pub omega_rad_s: f64,
    /// Modal damping ratio (`φᵀCφ / 2ω`).
    pub damping_ratio: f64,
    /// Ground participation `Γ = φᵀMι` of the mass-normalized mode.
    pub ground_participation: f64,
    /// The mass-normalized shape at the interface (specimen) DOF.
    pub interface_shape: f64,
}

/// A read-out's static correction: the truncated modes' share of its static response.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StaticCorrection {
    /// Response to a unit ground acceleration left out by the modes, mm per mm/s² (`h`).
    pub ground_mm_per_mm_s2: f64,
    /// Response to a unit interface force left out by the modes, mm/kN (`g`).
    pub force_mm_per_kn: f64,
}

/// Validated parameters of the reduced model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReducedModalParams {
    dt_s: f64,
    modes: usize,
    mode: [ReducedMode; REDUCED_MAX_MODES],
    outputs: usize,
    /// `output_shape[o][j]`: mode `j` at output `o`.
    output_shape: [[f64; REDUCED_MAX_MODES]; REDUCED_MAX_OUTPUTS],
    interface_static: StaticCorrection,
    output_static: [StaticCorrection; REDUCED_MAX_OUTPUTS],
    specimen_k_kn_per_mm: f64,
    /// The static force term's low-pass cutoff, Hz (`None`: the force deviation as is).
    static_force_cutoff_hz: Option<f64>,
}

impl ReducedModalParams {
    /// Validate and build. `modes`: 1..=[`REDUCED_MAX_MODES`], each `ω > 0`, `0 ≤ ζ < 1`, the rest
    /// finite. `output_shape_row_major`: outputs × modes (0..=[`REDUCED_MAX_OUTPUTS`] outputs);
    /// `output_static`: one per output. `specimen_k_kn_per_mm ≥ 0` is the specimen stiffness the
    /// modes include. `dt_s > 0`.
    pub fn new(
        dt_s: f64,
        modes: &[ReducedMode],
        output_shape_row_major: &[f64],
        interface_static: StaticCorrection,
        output_static: &[StaticCorrection],
        specimen_k_kn_per_mm: f64,
    ) -> Result<Self, ModelError> {
        let dt_s = time_step(dt_s)?;
        let r = modes.len();
        if r == 0 || r > REDUCED_MAX_MODES {
            return Err(ParamError::OutOfRange("number of modes (1..=32)").into());
        }
        let mut mode = [ReducedMode {
            omega_rad_s: 1.0,
            damping_ratio: 0.0,
            ground_participation: 0.0,
            interface_shape: 0.0,
        }; REDUCED_MAX_MODES];
        for (dst, m) in mode.iter_mut().zip(modes) {
            all_finite(
                &[
                    m.omega_rad_s,
                    m.damping_ratio,
                    m.ground_participation,
                    m.interface_shape,
                ],
                "modal frequency, damping, participation or interface shape",
            )?;
            if m.omega_rad_s <= 0.0 {
                return Err(ParamError::NotPositive("modal frequency").into());
            }
            if !(0.0..1.0).contains(&m.damping_ratio) {
                return Err(ParamError::OutOfRange("modal damping ratio (0 ≤ ζ < 1)").into());
            }
            *dst = *m;
        }
        let n_out = output_static.len();
        if n_out > REDUCED_MAX_OUTPUTS {
            return Err(ParamError::OutOfRange("number of outputs (0..=16)").into());
        }
        if output_shape_row_major.len() != n_out * r {
            return Err(ModelError::Shape {
                what: "output mode shapes (outputs × modes)",
                expected: n_out * r,
                got: output_shape_row_major.len(),
            });
        }
        all_finite(output_shape_row_major, "output mode shapes")?;
        let mut output_shape = [[0.0; REDUCED_MAX_MODES]; REDUCED_MAX_OUTPUTS];
        for (row, src) in output_shape
            .iter_mut()
            .zip(output_shape_row_major.chunks_exact(r))
        {
            for (d, s) in row.iter_mut().zip(src) {
                *d = *s;
            }
        }
        let mut out_static = [StaticCorrection::default(); REDUCED_MAX_OUTPUTS];
        for (d, s) in out_static.iter_mut().zip(output_static) {
            *d = *s;
        }
        for s in core::iter::once(&interface_static).chain(output_static) {
            all_finite(
                &[s.ground_mm_per_mm_s2, s.force_mm_per_kn],
                "static correction",
            )?;
        }
        if !specimen_k_kn_per_mm.is_finite() {
            return Err(ParamError::NotFinite("specimen stiffness").into());
        }
        if specimen_k_kn_per_mm < 0.0 {
            return Err(ParamError::OutOfRange("specimen stiffness (≥ 0)").into());
        }
        // The lagged static term feeds the force deviation back through `g`: with a specimen
        // stiffer than its nominal by Δk it is stable for |g·Δk| < 1, and for the nominal one it
        // is exact. A residual flexibility beyond the specimen's own means the modes miss the
        // interface: refused.
        if specimen_k_kn_per_mm > 0.0
            && interface_static.force_mm_per_kn.abs() * specimen_k_kn_per_mm >= 1.0
        {
            return Err(ParamError::OutOfRange(
                "interface residual flexibility (|g|·k_e < 1: retain more modes)",
            )
            .into());
        }
        Ok(Self {
            dt_s,
            modes: r,
            mode,
            outputs: n_out,
            output_shape,
            interface_static,
            output_static: out_static,
            specimen_k_kn_per_mm,
            static_force_cutoff_hz: None,
        })
    }

    /// The same model with the force deviation of the static term low-passed (first order) at
    /// `cutoff_hz` (finite, > 0). A measured force's noise and tracking error would otherwise
    /// reach the target in the same tick, undamped, and a lead compensator amplifies them. The
    /// caller chooses the cutoff: the hybrid loop uses the lowest retained mode's frequency (at the
    /// lowest truncated mode's the loop still tripped, docs/opensees.md). In the pure loop the
    /// deviation is zero and nothing changes.
    pub fn with_static_force_cutoff_hz(self, cutoff_hz: f64) -> Result<Self, ModelError> {
        if !cutoff_hz.is_finite() {
            return Err(ParamError::NotFinite("static force cutoff").into());
        }
        if cutoff_hz <= 0.0 {
            return Err(ParamError::NotPositive("static force cutoff").into());
        }
        Ok(Self {
            static_force_cutoff_hz: Some(cutoff_hz),
            ..self
        })
    }

    /// The same model as a hybrid loop on a rig runs it: the static term's force deviation
    /// low-passed at the lowest retained mode's frequency ([`Self::with_static_force_cutoff_hz`];
    /// the host's `meta-online` and a board's part given a rig compensation alike).
    pub fn for_hybrid_loop(self) -> Result<Self, ModelError> {
        let lowest = self
            .mode_list()
            .first()
            .map_or(0.0, |m| m.omega_rad_s / (2.0 * core::f64::consts::PI));
        self.with_static_force_cutoff_hz(lowest)
    }

    /// The static force term's low-pass cutoff, Hz (`None`: none).
    pub fn static_force_cutoff_hz(&self) -> Option<f64> {
        self.static_force_cutoff_hz
    }

    /// The same model at control step `dt_s` (the modes are continuous-time).
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
    /// Number of retained modes.
    pub fn modes(&self) -> usize {
        self.modes
    }
    /// Number of outputs besides the interface.
    pub fn outputs(&self) -> usize {
        self.outputs
    }
    /// The retained modes.
    pub fn mode_list(&self) -> &[ReducedMode] {
        self.mode.get(..self.modes).unwrap_or(&[])
    }
    /// The specimen stiffness the modes include, kN/mm.
    pub fn specimen_k_kn_per_mm(&self) -> f64 {
        self.specimen_k_kn_per_mm
    }
}

/// The reduced model and its state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReducedModal {
    p: ReducedModalParams,
    step: [ModeStep; REDUCED_MAX_MODES],
    disp: [f64; REDUCED_MAX_MODES],
    vel: [f64; REDUCED_MAX_MODES],
    accel: [f64; REDUCED_MAX_MODES],
    next: [f64; REDUCED_MAX_MODES],
    /// The static force term's low-pass gain per step (1: none).
    static_force_gain: f64,
    /// The interface's target for the coming step, static correction included.
    target: f64,
    /// The static terms' inputs of the last completed step: `ü_g`, `ΔF` (low-passed, if so
    /// configured).
    last_ag_mm_s2: f64,
    last_unbalance_kn: f64,
}

impl ReducedModal {
    /// A model at rest.
    pub fn new(p: ReducedModalParams) -> Self {
        let dt = p.dt_s;
        let mut step = [ModeStep::default(); REDUCED_MAX_MODES];
        for (s, m) in step.iter_mut().zip(p.mode_list()) {
            *s = ModeStep::new(m.omega_rad_s, m.damping_ratio, dt);
        }
        let static_force_gain = p.static_force_cutoff_hz.map_or(1.0, |f| {
            1.0 - libm::exp(-2.0 * core::f64::consts::PI * f * dt)
        });
        let mut me = Self {
            p,
            step,
            static_force_gain,
            disp: [0.0; REDUCED_MAX_MODES],
            vel: [0.0; REDUCED_MAX_MODES],
            accel: [0.0; REDUCED_MAX_MODES],
            next: [0.0; REDUCED_MAX_MODES],
            target: 0.0,
            last_ag_mm_s2: 0.0,
            last_unbalance_kn: 0.0,
        };
        me.reset();
        me
    }

    /// The parameters.
    pub fn params(&self) -> &ReducedModalParams {
        &self.p
    }

    /// Back to rest under zero ground acceleration.
    pub fn reset(&mut self) {
        self.reset_at(0.0);
    }

    /// Back to rest with the acceleration due to `ground_accel_mm_s2` at t = 0; a non-finite value
    /// counts as 0.
    pub fn reset_at(&mut self, ground_accel_mm_s2: f64) {
        let ag = super::start_accel_mm_s2(ground_accel_mm_s2);
        self.disp = [0.0; REDUCED_MAX_MODES];
        self.vel = [0.0; REDUCED_MAX_MODES];
        for (a, m) in self.accel.iter_mut().zip(self.p.mode_list()) {
            *a = -m.ground_participation * ag;
        }
        self.last_ag_mm_s2 = ag;
        self.last_unbalance_kn = 0.0;
        let (next, _) = predict(&self.step, &self.disp, &self.vel, &self.accel, self.p.modes);
        self.next = next;
        self.target = self.interface_of(&self.next, ag, 0.0);
    }

    /// The interface's target displacement for the coming step, mm.
    pub fn target_mm(&self) -> f64 {
        self.target
    }

    /// The interface's displacement at the last completed step, mm.
    pub fn interface_mm(&self) -> f64 {
        self.interface_of(&self.disp, self.last_ag_mm_s2, self.last_unbalance_kn)
    }

    /// Output `o`'s displacement at the last completed step, mm (0 past the outputs).
    pub fn output_mm(&self, o: usize) -> f64 {
        if o >= self.p.outputs {
            return 0.0;
        }
        let (Some(row), Some(s)) = (self.p.output_shape.get(o), self.p.output_static.get(o)) else {
            return 0.0;
        };
        let modal: f64 = row
            .iter()
            .zip(&self.disp)
            .take(self.p.modes)
            .map(|(a, b)| a * b)
            .sum();
        modal
            - s.ground_mm_per_mm_s2 * self.last_ag_mm_s2
            - s.force_mm_per_kn * self.last_unbalance_kn
    }

    #[inline]
    fn interface_of(&self, q: &[f64; REDUCED_MAX_MODES], ag: f64, unbalance: f64) -> f64 {
        let modal: f64 = self
            .p
            .mode
            .iter()
            .zip(q)
            .take(self.p.modes)
            .map(|(m, x)| m.interface_shape * x)
            .sum();
        let s = &self.p.interface_static;
        modal - s.ground_mm_per_mm_s2 * ag - s.force_mm_per_kn * unbalance
    }

    /// Complete the step at the last target with the ground acceleration there and the specimen's
    /// measured force (kN, at the interface); return the next target displacement of the
    /// interface, mm. A non-finite input or result is refused and the state is unchanged.
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
        let unbalance = specimen_force_kn - self.p.specimen_k_kn_per_mm * self.target;
        let half_dt = 0.5 * self.p.dt_s;
        let mut v1 = [0.0; REDUCED_MAX_MODES];
        let mut a1 = [0.0; REDUCED_MAX_MODES];
        for ((((((st, m), v0), a0), d), vo), ao) in self
            .step
            .iter()
            .zip(&self.p.mode)
            .zip(&self.vel)
            .zip(&self.accel)
            .zip(&d1)
            .zip(v1.iter_mut())
            .zip(a1.iter_mut())
            .take(r)
        {
            let vp = v0 + a0 * half_dt;
            let a = (-m.ground_participation * ground_accel_mm_s2
                - m.interface_shape * unbalance
                - st.k * d
                - st.c * vp)
                * st.solve;
            *vo = vp + a * half_dt;
            *ao = a;
        }
        let (next, ok) = predict(&self.step, &d1, &v1, &a1, r);
        // The modes take the deviation as is (they integrate it); the static term its low-pass.
        let static_unbalance = if self.p.static_force_cutoff_hz.is_some() {
            self.last_unbalance_kn + self.static_force_gain * (unbalance - self.last_unbalance_kn)
        } else {
            unbalance
        };
        let target = self.interface_of(&next, ground_accel_mm_s2, static_unbalance);
        if !ok || !target.is_finite() {
            return Err(ParamError::NotFinite("model state (the step overflowed)").into());
        }
        self.disp = d1;
        self.vel = v1;
        self.accel = a1;
        self.next = next;
        self.target = target;
        self.last_ag_mm_s2 = ground_accel_mm_s2;
        self.last_unbalance_kn = static_unbalance;
        Ok(target)
    }
}

#[cfg(test)]
mod tests;

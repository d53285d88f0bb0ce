//! Floor-hysteron metamodel of a yielding numerical substructure (docs/opensees-nonlinear.md, "The
//! floor-hysteron form"): the structure's elastic model reduced to the floors a lab records (mass,
//! damping and stiffness, `n ≤ 8` floors), plus a learned restoring-force deviation that is a sum
//! of play (backlash) operators of several thresholds on linear combinations of the floors (story
//! drifts and cross-story combinations): an Iwan / Prandtl–Ishlinskii basis.
//!
//! `M·ẍ + C·ẋ + K·x − Σ_h w_h·a_h·p_h(a_hᵀx) + e·F = −M·ι·ü_g`, with `p_h` the play operator of
//! threshold `r_h` (its output `y` follows the input `δ` within `|δ − y| ≤ r_h`, starting at 0),
//! `w_h ≥ 0` and `a_h` one of the model's directions. `δ − p_h(δ)` is an elastic–perfectly-plastic
//! element of unit stiffness yielding at `r_h`, so each hysteron is an Iwan element in parallel with
//! the elastic structure: the tangent stiffness is `K` while `|δ| < r_h` and `K − w_h·a_h·a_hᵀ`
//! once it slides. With [`HysteronOperator::MenegottoPinto`] every hysteron is instead the
//! Menegotto–Pinto play ([`mp_play`]): the same element with its reversals rounded by the previous
//! excursion (steel's Bauschinger effect, outside Masing's rule that binds the plays), at most
//! [`HYST_MAX_MP`] of them; its tangent stays between the same bounds. The parameters are refused unless the fully yielded tangent `K − Σ w_h·a_h·a_hᵀ`
//! is positive definite, so the model is passive (it dissipates, never creates energy) and Chang's
//! explicit method, whose coefficients use the initial stiffness, stays stable.
//!
//! The elastic part is [`ChangN`], the FE's own integrator; the hysterons' forces enter as the
//! restoring force at the explicitly predicted displacement, as the yielding FE's stories do. A
//! step costs `O(n²)` for the structure plus `O(d·n + H)` for `d` directions and `H` hysterons,
//! independent of the elements and fibers of the lab's model.
//!
//! `no_std`, allocation-free, panic-free; a non-finite input is refused before the state is
//! touched, and a step whose result is not finite is refused with the state left as it was.

// Validation loops over the floors in use (n ≤ MAX_DOF, checked first) index fixed arrays; the
// tick (`step`) iterates with zips only.
#![allow(clippy::needless_range_loop)]

use super::mp_play::{mp_play, MpShape, MpState};
use super::ModelError;
use crate::params::ParamError;
use crate::structure_n::{ChangN, Dofs, StructureN, MAX_DOF};

/// Largest number of directions (linear combinations of the floors) the hysterons act along.
pub const HYST_MAX_DIRECTIONS: usize = 16;
/// Largest number of hysterons (64: with 128 the model was the controller's largest part, 2.1 KiB
/// over the RNN's, and the emulated boards closed the link as its run started; at 64 it runs. A
/// 3-floor structure's basis, 6 directions of 10 plays, is within it).
pub const HYST_MAX_HYSTERONS: usize = 64;
/// Largest number of Menegotto–Pinto hysterons (each carries a branch state and costs two `pow`
/// per step).
pub const HYST_MAX_MP: usize = 32;

/// The operator every hysteron of a model is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HysteronOperator {
    /// The play (Masing's rule).
    Play,
    /// The Menegotto–Pinto play of this shape ([`mp_play`]).
    MenegottoPinto(MpShape),
}

/// One play operator: its direction (an index into the model's directions), threshold and weight.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hysteron {
    /// Index of the direction it acts along.
    pub direction: usize,
    /// Threshold `r`, mm (of the direction's coordinate).
    pub threshold_mm: f64,
    /// Weight `w ≥ 0`, kN/mm: the stiffness it takes off the direction once it slides.
    pub weight_kn_per_mm: f64,
}

/// Validated parameters of the floor-hysteron model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorHysteronParams {
    chang: ChangN,
    specimen_floor: usize,
    specimen_k_kn_per_mm: f64,
    directions: usize,
    dir: [[f64; MAX_DOF]; HYST_MAX_DIRECTIONS],
    count: usize,
    hyst: [Hysteron; HYST_MAX_HYSTERONS],
    operator: HysteronOperator,
}

/// The elastic floors of the model, raw (row-major `floors × floors`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorStructure<'a> {
    /// Floors, 1..=[`MAX_DOF`].
    pub floors: usize,
    /// Mass, kN·s²/mm.
    pub mass: &'a [f64],
    /// Damping, kN·s/mm.
    pub damping: &'a [f64],
    /// The numerical part's elastic stiffness (the specimen's taken out), kN/mm.
    pub stiffness: &'a [f64],
    /// `M·ι`, kN·s²/mm.
    pub ground_mass: &'a [f64],
    /// The specimen's floor, 0-based.
    pub specimen_floor: usize,
    /// The specimen's nominal stiffness, kN/mm (Chang's initial stiffness includes it).
    pub specimen_k_kn_per_mm: f64,
}

impl FloorHysteronParams {
    /// Validate and build at step `dt_s`: the floors (mass positive definite, stiffness symmetric),
    /// `directions_row_major` (directions × floors, 1..=[`HYST_MAX_DIRECTIONS`], finite, none all
    /// zero), `hysterons` (1..=[`HYST_MAX_HYSTERONS`]: a direction that exists, threshold > 0,
    /// weight ≥ 0, finite), and the fully yielded tangent `K − Σ w·a·aᵀ` positive definite.
    pub fn new(
        dt_s: f64,
        s: &FloorStructure<'_>,
        directions_row_major: &[f64],
        hysterons: &[Hysteron],
    ) -> Result<Self, ModelError> {
        let n = s.floors;
        if n == 0 || n > MAX_DOF {
            return Err(ParamError::OutOfRange("number of floors (1..=8)").into());
        }
        super::shape(s.stiffness, n * n, "stiffness (floors × floors)")?;
        super::all_finite(s.stiffness, "stiffness")?;
        if s.specimen_floor >= n {
            return Err(ParamError::OutOfRange("specimen floor (beyond the floors)").into());
        }
        if !s.specimen_k_kn_per_mm.is_finite() {
            return Err(ParamError::NotFinite("specimen stiffness").into());
        }
        if s.specimen_k_kn_per_mm < 0.0 {
            return Err(ParamError::OutOfRange("specimen stiffness (≥ 0)").into());
        }
        let mut k = [[0.0; MAX_DOF]; MAX_DOF];
        for (i, row) in k.iter_mut().enumerate().take(n) {
            for (j, v) in row.iter_mut().enumerate().take(n) {
                *v = s.stiffness.get(i * n + j).copied().unwrap_or(f64::NAN);
            }
        }
        let scale = k.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
        for i in 0..n {
            for j in 0..i {
                if (k[i][j] - k[j][i]).abs() > 1e-9 * scale.max(f64::MIN_POSITIVE) {
                    return Err(ParamError::OutOfRange("stiffness (not symmetric)").into());
                }
            }
        }
        let mut k0 = [0.0; MAX_DOF * MAX_DOF];
        for i in 0..n {
            for j in 0..n {
                if let Some(v) = k0.get_mut(i * n + j) {
                    *v = k[i][j]
                        + if i == j && i == s.specimen_floor {
                            s.specimen_k_kn_per_mm
                        } else {
                            0.0
                        };
                }
            }
        }
        let structure = StructureN::new(
            n,
            s.mass,
            s.damping,
            s.stiffness,
            k0.get(..n * n).unwrap_or(&[]),
            s.ground_mass,
        )?;
        let chang = ChangN::new(structure, dt_s)?;
        let d = directions_row_major.len().checked_div(n).unwrap_or(0);
        if d == 0 || d > HYST_MAX_DIRECTIONS || d * n != directions_row_major.len() {
            return Err(ModelError::Shape {
                what: "directions (1..=16, each one number per floor)",
                expected: n * d.clamp(1, HYST_MAX_DIRECTIONS),
                got: directions_row_major.len(),
            });
        }
        super::all_finite(directions_row_major, "directions")?;
        let mut dir = [[0.0; MAX_DOF]; HYST_MAX_DIRECTIONS];
        for (row, src) in dir.iter_mut().zip(directions_row_major.chunks_exact(n)) {
            if src.iter().all(|v| *v == 0.0) {
                return Err(ParamError::OutOfRange("direction (all zero)").into());
            }
            for (a, b) in row.iter_mut().zip(src) {
                *a = *b;
            }
        }
        if hysterons.is_empty() || hysterons.len() > HYST_MAX_HYSTERONS {
            return Err(ParamError::OutOfRange("number of hysterons (1..=64)").into());
        }
        let mut hyst = [Hysteron {
            direction: 0,
            threshold_mm: 1.0,
            weight_kn_per_mm: 0.0,
        }; HYST_MAX_HYSTERONS];
        // The fully yielded tangent K − Σ w·a·aᵀ.
        let mut kt = k;
        for (dst, h) in hyst.iter_mut().zip(hysterons) {
            if h.direction >= d {
                return Err(
                    ParamError::OutOfRange("hysteron direction (no such direction)").into(),
                );
            }
            if !h.threshold_mm.is_finite() || !h.weight_kn_per_mm.is_finite() {
                return Err(ParamError::NotFinite("hysteron threshold or weight").into());
            }
            if h.threshold_mm <= 0.0 {
                return Err(ParamError::NotPositive("hysteron threshold").into());
            }
            if h.weight_kn_per_mm < 0.0 {
                return Err(ParamError::OutOfRange("hysteron weight (≥ 0)").into());
            }
            if let Some(a) = dir.get(h.direction) {
                for (i, row) in kt.iter_mut().enumerate().take(n) {
                    for (j, v) in row.iter_mut().enumerate().take(n) {
                        *v -= h.weight_kn_per_mm * a[i] * a[j];
                    }
                }
            }
            *dst = *h;
        }
        if !positive_definite(&kt, n) {
            return Err(ParamError::OutOfRange(
                "hysteron weights (the fully yielded tangent K − Σ w·a·aᵀ is not positive definite)",
            )
            .into());
        }
        Ok(Self {
            chang,
            specimen_floor: s.specimen_floor,
            specimen_k_kn_per_mm: s.specimen_k_kn_per_mm,
            directions: d,
            dir,
            count: hysterons.len(),
            hyst,
            operator: HysteronOperator::Play,
        })
    }

    /// The same model with every hysteron the operator `op` (a Menegotto–Pinto model has at most
    /// [`HYST_MAX_MP`] hysterons).
    pub fn with_operator(mut self, op: HysteronOperator) -> Result<Self, ModelError> {
        if matches!(op, HysteronOperator::MenegottoPinto(_)) && self.count > HYST_MAX_MP {
            return Err(
                ParamError::OutOfRange("number of Menegotto–Pinto hysterons (1..=32)").into(),
            );
        }
        self.operator = op;
        Ok(self)
    }

    /// The hysterons' operator.
    pub fn operator(&self) -> HysteronOperator {
        self.operator
    }

    /// The time step, s.
    pub fn dt_s(&self) -> f64 {
        self.chang.dt_s()
    }
    /// Number of floors.
    pub fn floors(&self) -> usize {
        self.chang.model().dofs()
    }
    /// The specimen's floor (0-based).
    pub fn specimen_floor(&self) -> usize {
        self.specimen_floor
    }
    /// The specimen's nominal stiffness, kN/mm.
    pub fn specimen_k_kn_per_mm(&self) -> f64 {
        self.specimen_k_kn_per_mm
    }
    /// Number of directions.
    pub fn directions(&self) -> usize {
        self.directions
    }
    /// The hysterons in use.
    pub fn hysterons(&self) -> &[Hysteron] {
        self.hyst.get(..self.count).unwrap_or(&[])
    }
}

/// Whether the leading `n×n` block of `a` is positive definite (Cholesky without square roots of
/// non-positive pivots).
fn positive_definite(a: &[[f64; MAX_DOF]; MAX_DOF], n: usize) -> bool {
    // Every access checked (an upload's commit builds this on the board: no panic path).
    let mut l = [[0.0; MAX_DOF]; MAX_DOF];
    for i in 0..n.min(MAX_DOF) {
        for j in 0..=i {
            let (Some(li), Some(lj)) = (l.get(i).copied(), l.get(j).copied()) else {
                return false;
            };
            let mut s = a.get(i).and_then(|r| r.get(j)).copied().unwrap_or(f64::NAN);
            for (x, y) in li.iter().zip(lj.iter()).take(j) {
                s -= x * y;
            }
            let v = if i == j {
                if !s.is_finite() || s <= 0.0 || s.is_nan() {
                    return false;
                }
                libm::sqrt(s)
            } else {
                s / lj.get(j).copied().unwrap_or(f64::NAN)
            };
            match l.get_mut(i).and_then(|r| r.get_mut(j)) {
                Some(x) => *x = v,
                None => return false,
            }
        }
    }
    true
}

/// The floor-hysteron model and its state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorHysteron {
    p: FloorHysteronParams,
    /// Each play operator's output, mm.
    play: [f64; HYST_MAX_HYSTERONS],
    /// Each Menegotto–Pinto play's state.
    mp: [MpState; HYST_MAX_MP],
}

impl FloorHysteron {
    /// A model at rest.
    pub fn new(p: FloorHysteronParams) -> Self {
        let mut me = Self {
            p,
            play: [0.0; HYST_MAX_HYSTERONS],
            mp: [MpState::REST; HYST_MAX_MP],
        };
        me.reset();
        me
    }

    /// The parameters.
    pub fn params(&self) -> &FloorHysteronParams {
        &self.p
    }

    /// Back to rest, every hysteron virgin, zero ground acceleration.
    pub fn reset(&mut self) {
        self.reset_at(0.0);
    }

    /// Back to rest with the acceleration due to `ground_accel_mm_s2` at t = 0; a non-finite
    /// value counts as 0.
    pub fn reset_at(&mut self, ground_accel_mm_s2: f64) {
        let ag = super::start_accel_mm_s2(ground_accel_mm_s2);
        self.play = [0.0; HYST_MAX_HYSTERONS];
        self.mp = [MpState::REST; HYST_MAX_MP];
        self.p.chang.reset(ag);
    }

    /// The target displacement of the specimen's floor for the coming step, mm.
    pub fn target_mm(&self) -> f64 {
        self.p
            .chang
            .next_displacement()
            .get(self.p.specimen_floor)
            .copied()
            .unwrap_or(f64::NAN)
    }

    /// Displacement of floor `i` (0-based) at the last completed step, mm (0 past the floors).
    pub fn floor_disp_mm(&self, i: usize) -> f64 {
        if i < self.p.floors() {
            self.p.chang.disp().get(i).copied().unwrap_or(0.0)
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

    /// Complete the step at the last target with the ground acceleration there and the specimen's
    /// measured force (kN, at the specimen's floor); return the next target displacement of the
    /// specimen's floor, mm. A non-finite input or result is refused and the state is unchanged.
    #[inline]
    pub fn step(
        &mut self,
        ground_accel_mm_s2: f64,
        specimen_force_kn: f64,
    ) -> Result<f64, ModelError> {
        if !ground_accel_mm_s2.is_finite() || !specimen_force_kn.is_finite() {
            return Err(ParamError::NotFinite("ground acceleration or specimen force").into());
        }
        let n = self.p.floors();
        // Each direction's coordinate at the predicted displacement.
        let mut delta = [0.0; HYST_MAX_DIRECTIONS];
        let x = self.p.chang.next_displacement();
        for (dv, a) in delta.iter_mut().zip(&self.p.dir).take(self.p.directions) {
            let mut s = 0.0;
            for (ai, xi) in a.iter().zip(x).take(n) {
                s += ai * xi;
            }
            *dv = s;
        }
        // The operators' states change only if the step is finite (the plays' new outputs wait
        // in a scratch, the Menegotto–Pinto states' old ones are kept; the integrator keeps its
        // own small state to rewind: copying it whole each tick, coefficients and all, was most
        // of the tick's cost on the board); each adds its force −w·p along its direction.
        let mut g = [0.0; HYST_MAX_DIRECTIONS];
        let count = self.p.count;
        match self.p.operator {
            HysteronOperator::Play => {
                let mut play = [0.0; HYST_MAX_HYSTERONS];
                for ((h, y), old) in self
                    .p
                    .hyst
                    .iter()
                    .zip(play.iter_mut())
                    .zip(&self.play)
                    .take(count)
                {
                    let (Some(dv), Some(gd)) = (delta.get(h.direction), g.get_mut(h.direction))
                    else {
                        *y = *old;
                        continue;
                    };
                    let lo = dv - h.threshold_mm;
                    let hi = dv + h.threshold_mm;
                    *y = if *old < lo {
                        lo
                    } else if *old > hi {
                        hi
                    } else {
                        *old
                    };
                    *gd -= h.weight_kn_per_mm * *y;
                }
                if !self.advance(ground_accel_mm_s2, specimen_force_kn, &g) {
                    return Err(ParamError::NotFinite("model state (the step overflowed)").into());
                }
                for (dst, y) in self.play.iter_mut().zip(&play).take(count) {
                    *dst = *y;
                }
            }
            HysteronOperator::MenegottoPinto(shape) => {
                // Stepped in place; the states before the step are kept for the hysterons in use
                // only (an empty slot costs its tag, where a scratch of states would be 2 KB to
                // clear) and put back if the step overflows.
                let mut before = [None; HYST_MAX_MP];
                for ((h, st), old) in self
                    .p
                    .hyst
                    .iter()
                    .zip(self.mp.iter_mut())
                    .zip(before.iter_mut())
                    .take(count)
                {
                    *old = Some(*st);
                    let (Some(dv), Some(gd)) = (delta.get(h.direction), g.get_mut(h.direction))
                    else {
                        continue;
                    };
                    *gd -= h.weight_kn_per_mm * mp_play(&shape, h.threshold_mm, st, *dv);
                }
                if !self.advance(ground_accel_mm_s2, specimen_force_kn, &g) {
                    for (st, old) in self.mp.iter_mut().zip(&before) {
                        if let Some(o) = old {
                            *st = *o;
                        }
                    }
                    return Err(ParamError::NotFinite("model state (the step overflowed)").into());
                }
            }
        }
        Ok(self.target_mm())
    }

    /// The floors' step with the hysterons' forces `g` along the directions and the specimen's
    /// force; false (the integrator as it was) if the force or the result is not finite.
    #[inline]
    fn advance(
        &mut self,
        ground_accel_mm_s2: f64,
        specimen_force_kn: f64,
        g: &[f64; HYST_MAX_DIRECTIONS],
    ) -> bool {
        let n = self.p.floors();
        let mut r: Dofs = [0.0; MAX_DOF];
        for (gd, a) in g.iter().zip(&self.p.dir).take(self.p.directions) {
            for (ri, ai) in r.iter_mut().zip(a).take(n) {
                *ri += gd * ai;
            }
        }
        if let Some(rs) = r.get_mut(self.p.specimen_floor) {
            *rs += specimen_force_kn;
        }
        if !r.iter().all(|v| v.is_finite()) {
            return false;
        }
        let before = self.p.chang.motion();
        self.p.chang.advance(ground_accel_mm_s2, &r);
        if !self.target_mm().is_finite() || !self.p.chang.disp().iter().all(|v| v.is_finite()) {
            self.p.chang.rewind(&before);
            return false;
        }
        true
    }
}

#[cfg(test)]
mod tests;

//! The servo-hydraulic plant as an ODE in SI units, integrated by RK4 with sub-steps.
//!
//! State `[q, q̇, f, x, ẋ, z]`:
//! - servo-valve and inner loop `q̈ + β1·q̇ + β2·q = a1β0·e`, `e = gain·u − x` (u: DAC command, m);
//!   this is `Gs = a1β0/(s² + β1 s + β2)` from the error to the (scaled) valve flow `q`;
//! - actuator with control-structure interaction `ḟ + a3·f = q − a2·ẋ` (`Ga = 1/(s + a3)`, the
//!   `a2·ẋ` term is the flow taken by the moving piston: the CSI of `G0 = GaGe/(1 + a2 s GaGe)`);
//! - specimen `m_e·ẍ + c_e·ẋ + R(x, z) = f` (`Ge = 1/(m_e s² + c_e s + k_e)` when linear), with
//!   Bouc–Wen's `z` when hysteretic.
//!
//! Closing `e = gain·u − x` around `Gs·G0` gives the benchmark `x/u = gain·GsG0/(1 + GsG0)`.
//!
//! Saturations: the valve flow `|q| ≤ (a2 + k_e)·v_max` (see [`PlantParams::rated_flow`]), the
//! piston velocity `|ẋ| ≤ v_max`, the actuator force `|f| ≤ capacity`, and the stroke end stops
//! `|x| ≤ stroke` (the piston stops).

use libm::{fabs, pow};

use crate::params::{PlantParams, Specimen};

const N: usize = 6;

/// The plant's mutable state (SI). `reset()` returns it to rest.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct PlantState {
    pub(crate) y: [f64; N],
}

impl PlantState {
    pub(crate) fn reset(&mut self) {
        self.y = [0.0; N];
    }
    pub(crate) fn disp_m(&self) -> f64 {
        self.y[3]
    }
    pub(crate) fn vel_m_s(&self) -> f64 {
        self.y[4]
    }
    pub(crate) fn force_n(&self) -> f64 {
        self.y[2]
    }
    pub(crate) fn flow(&self) -> f64 {
        self.y[0]
    }
}

/// Per-tick modifiers that faults apply to the plant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Modifiers {
    /// Fraction of the rated valve flow available (1: healthy).
    pub(crate) valve_factor: f64,
    /// Specimen stiffness factor (1: healthy).
    pub(crate) stiffness_factor: f64,
}

impl Default for Modifiers {
    fn default() -> Self {
        Self {
            valve_factor: 1.0,
            stiffness_factor: 1.0,
        }
    }
}

struct Ctx<'a> {
    p: &'a PlantParams,
    r_m: f64,
    q_max: f64,
    k: f64,
}

fn clamp(v: f64, lim: f64) -> f64 {
    v.clamp(-lim, lim)
}

/// Specimen restoring force, N.
fn restoring_force(c: &Ctx<'_>, x: f64, z: f64) -> f64 {
    match c.p.specimen {
        Specimen::Linear => c.k * x,
        Specimen::BoucWen(bw) => {
            let xy = bw.yield_disp_mm * 1e-3;
            let a = bw.post_yield_ratio;
            a * c.k * x + (1.0 - a) * c.k * xy * z
        }
    }
}

fn deriv(c: &Ctx<'_>, y: &[f64; N]) -> [f64; N] {
    let [q, qd, f, x, v, z] = *y;
    let p = c.p;
    let e = c.r_m - x;
    let qdd = p.a1_beta0 * e - p.beta1 * qd - p.beta2 * q;
    let flow = clamp(q, c.q_max);
    let fd = flow - p.a3 * f - p.a2 * v;
    let mut vd = (f - p.damping_n_s_per_m * v - restoring_force(c, x, z)) / p.mass_kg;
    // Flow limit at the piston: it cannot accelerate beyond the rated velocity.
    if (v >= p.velocity_m_s && vd > 0.0) || (v <= -p.velocity_m_s && vd < 0.0) {
        vd = 0.0;
    }
    let zd = match p.specimen {
        Specimen::Linear => 0.0,
        Specimen::BoucWen(bw) => {
            let xy = bw.yield_disp_mm * 1e-3;
            let sgn = if v * z >= 0.0 { 1.0 } else { -1.0 };
            (v / xy) * (bw.a - pow(fabs(z), bw.n) * (bw.beta * sgn + bw.gamma))
        }
    };
    [qd, qdd, fd, v, vd, zd]
}

fn axpy(y: &[f64; N], h: f64, k: &[f64; N]) -> [f64; N] {
    let mut out = *y;
    for (o, d) in out.iter_mut().zip(k) {
        *o += h * d;
    }
    out
}

/// Advance the plant by one controller tick holding the command `u_m` (ZOH), with `substeps` RK4
/// steps and the saturations applied after each.
pub(crate) fn advance(p: &PlantParams, s: &mut PlantState, u_m: f64, m: Modifiers) {
    let c = Ctx {
        p,
        r_m: p.gain * u_m,
        q_max: p.rated_flow() * m.valve_factor,
        k: p.stiffness_n_per_m * m.stiffness_factor,
    };
    let h = p.dt_s / f64::from(p.substeps);
    for _ in 0..p.substeps {
        let y = s.y;
        let k1 = deriv(&c, &y);
        let k2 = deriv(&c, &axpy(&y, 0.5 * h, &k1));
        let k3 = deriv(&c, &axpy(&y, 0.5 * h, &k2));
        let k4 = deriv(&c, &axpy(&y, h, &k3));
        let mut next = y;
        let slopes = k1.iter().zip(&k2).zip(&k3).zip(&k4);
        for (n, (((a, b), cc), d)) in next.iter_mut().zip(slopes) {
            *n += h / 6.0 * (a + 2.0 * b + 2.0 * cc + d);
        }
        saturate(&c, &mut next);
        s.y = next;
    }
}

fn saturate(c: &Ctx<'_>, y: &mut [f64; N]) {
    let p = c.p;
    // Valve spool at its stop: no wind-up beyond the rated flow.
    if fabs(y[0]) > c.q_max {
        y[0] = clamp(y[0], c.q_max);
        if y[0] * y[1] > 0.0 {
            y[1] = 0.0;
        }
    }
    // Relief valves: actuator force capacity.
    y[2] = clamp(y[2], p.capacity_n);
    // Flow limit at the piston.
    y[4] = clamp(y[4], p.velocity_m_s);
    // End stops: the piston stops at the stroke.
    if fabs(y[3]) >= p.stroke_m {
        y[3] = clamp(y[3], p.stroke_m);
        if y[3] * y[4] > 0.0 {
            y[4] = 0.0;
        }
    }
}

/// Specimen restoring force for the current state, N.
pub(crate) fn restoring_force_n(p: &PlantParams, s: &PlantState, m: Modifiers) -> f64 {
    let c = Ctx {
        p,
        r_m: 0.0,
        q_max: 0.0,
        k: p.stiffness_n_per_m * m.stiffness_factor,
    };
    restoring_force(&c, s.y[3], s.y[5])
}

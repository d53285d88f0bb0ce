//! The servo-hydraulic plant as an ODE in SI units.
//!
//! Integration: while the dynamics are linear (linear specimen, no saturation anywhere in the tick)
//! a whole controller tick is the exact zero-order-hold map `y ← Φ·y + Γ·r` ([`Zoh`], computed once
//! per parameter set); otherwise (Bouc–Wen, or a tick that could touch a saturation) RK4 with
//! sub-steps and the saturations applied after each sub-step.
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
use crate::zoh::Zoh;

const N: usize = 6;

/// The plant's mutable state (SI). `reset()` returns it to rest.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct PlantState {
    pub(crate) y: [f64; N],
    /// Ticks advanced since rest (the clock of a [`crate::params::Drift`]).
    pub(crate) ticks: u64,
}

impl PlantState {
    pub(crate) fn reset(&mut self) {
        self.y = [0.0; N];
        self.ticks = 0;
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

/// Advance the plant by one controller tick holding the command `u_m` (ZOH). With `zoh` (the
/// exact map of the linear plant at the active stiffness factor) the tick is one exact step unless
/// it could engage a saturation; otherwise, and for Bouc–Wen, `substeps` RK4 steps with the
/// saturations applied after each. Returns whether the exact step was taken.
pub(crate) fn advance(
    p: &PlantParams,
    s: &mut PlantState,
    u_m: f64,
    m: Modifiers,
    zoh: Option<&Zoh>,
) -> bool {
    let drifted;
    let p = if p.drift.is_active() {
        drifted = p.with_actuator_speed(p.drift.speed_at(s.ticks));
        &drifted
    } else {
        p
    };
    s.ticks = s.ticks.saturating_add(1);
    let c = Ctx {
        p,
        r_m: p.gain * u_m,
        q_max: p.rated_flow() * m.valve_factor,
        k: p.stiffness_n_per_m * m.stiffness_factor,
    };
    if let Some(z) = zoh {
        if exact_step(&c, z, s) {
            return true;
        }
    }
    rk4(&c, s);
    false
}

/// Relative margin kept from every limit (valve flow, force, velocity, stroke) by the exact step.
/// It covers the interpolation bound's remainder (≤ 6e-5 of a mode's amplitude at the fastest
/// pole, |λ·dt| = 0.38), RK4's stage points off the trajectory (≈ (λh)²/8 ≤ 1.2e-3 of a mode's
/// amplitude at 4 sub-steps) and its 1e-7 error, so a tick taken exactly is one RK4 would not
/// have clipped (test `exact_ticks_are_ticks_rk4_does_not_clip`).
const LIMIT_MARGIN: f64 = 0.02;

/// The exact tick, if it provably stays clear of every saturation; `false` leaves `s` untouched.
///
/// Within a tick the linear state is smooth, so a component is bounded by the cubic Hermite
/// interpolant of its end values `y0, y1` and slopes `ẏ0, ẏ1` (whose excess over the ends is at
/// most `4/27·dt·(|ẏ0| + |ẏ1|)`, taken as `dt/4·…`) plus the margin.
fn exact_step(c: &Ctx<'_>, z: &Zoh, s: &mut PlantState) -> bool {
    let p = c.p;
    let [q0, qd0, f0, x0, v0, _] = s.y;
    let y0 = [q0, qd0, f0, x0, v0];
    let mut y1 = [0.0; 5];
    for ((o, row), g) in y1.iter_mut().zip(&z.phi).zip(&z.gamma) {
        *o = row
            .iter()
            .zip(&y0)
            .fold(g * c.r_m, |acc, (a, b)| acc + a * b);
    }
    let [q1, qd1, f1, x1, v1] = y1;
    let fd = |q: f64, f: f64, v: f64| q - p.a3 * f - p.a2 * v;
    let vd = |f: f64, v: f64, x: f64| (f - p.damping_n_s_per_m * v - c.k * x) / p.mass_kg;
    let slack = 0.25 * p.dt_s;
    let keep = 1.0 - LIMIT_MARGIN;
    // `!(a <= b)` so that a NaN fails too.
    let clear = |a: f64, b: f64, da: f64, db: f64, lim: f64| {
        fabs(a).max(fabs(b)) + slack * (fabs(da) + fabs(db)) <= keep * lim
    };
    if !(clear(q0, q1, qd0, qd1, c.q_max)
        && clear(f0, f1, fd(q0, f0, v0), fd(q1, f1, v1), p.capacity_n)
        && clear(x0, x1, v0, v1, p.stroke_m)
        && clear(v0, v1, vd(f0, v0, x0), vd(f1, v1, x1), p.velocity_m_s))
    {
        return false;
    }
    s.y = [q1, qd1, f1, x1, v1, s.y[5]];
    true
}

fn rk4(c: &Ctx<'_>, s: &mut PlantState) {
    let p = c.p;
    let h = p.dt_s / f64::from(p.substeps);
    for _ in 0..p.substeps {
        let y = s.y;
        let k1 = deriv(c, &y);
        let k2 = deriv(c, &axpy(&y, 0.5 * h, &k1));
        let k3 = deriv(c, &axpy(&y, 0.5 * h, &k2));
        let k4 = deriv(c, &axpy(&y, h, &k3));
        let mut next = y;
        let slopes = k1.iter().zip(&k2).zip(&k3).zip(&k4);
        for (n, (((a, b), cc), d)) in next.iter_mut().zip(slopes) {
            *n += h / 6.0 * (a + 2.0 * b + 2.0 * cc + d);
        }
        saturate(c, &mut next);
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

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::params::{Preset, RigConfig};
    use rand_core::{RngCore, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;

    fn uniform(rng: &mut Xoshiro256PlusPlus) -> f64 {
        (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Random steps (±30 mm, beyond the stroke), random valve and stiffness faults, on a nominal,
    /// a soft (velocity-limited) and a stiff (force-limited) specimen: every tick the exact step
    /// takes is one that RK4 from the same state does not clip (RK4 with and without the limits
    /// agree bit for bit), and there the two agree to RK4's accuracy.
    #[test]
    fn exact_ticks_are_ticks_rk4_does_not_clip() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        let (mut exact, mut clipped, mut declined, mut total) = (0u64, 0u64, 0u64, 0u64);
        let mut worst = [0.0f64; 5];
        for preset in [Preset::Benchmark, Preset::UnrCompact] {
            for k_factor in [1.0, 0.01, 4.0] {
                let mut cfg = RigConfig::new(preset);
                cfg.specimen_stiffness_kn_per_mm *= k_factor;
                let p = cfg.build().unwrap();
                let mut free = p;
                free.capacity_n = f64::INFINITY;
                free.stroke_m = f64::INFINITY;
                free.velocity_m_s = f64::INFINITY;
                let stiffness = [1.0, 0.5, 2.0];
                let maps = stiffness.map(|f| p.zoh_at(f));
                let limits = [
                    p.rated_flow(),
                    0.0,
                    p.capacity_n,
                    p.stroke_m,
                    p.velocity_m_s,
                ];
                let mut s = PlantState::default();
                let (mut u, mut m, mut map, mut hold) = (0.0, Modifiers::default(), &maps[0], 0);
                for _ in 0..60_000 {
                    if hold == 0 {
                        hold = 1 + (uniform(&mut rng) * 600.0) as u32;
                        u = (uniform(&mut rng) * 2.0 - 1.0) * 0.030;
                        let r = uniform(&mut rng);
                        m.valve_factor = if r < 0.6 { 1.0 } else { 0.1 + r };
                        let i = (uniform(&mut rng) * 3.0) as usize % 3;
                        m.stiffness_factor = stiffness[i];
                        map = &maps[i];
                    }
                    hold -= 1;
                    let (mut a, mut b, mut c) = (s, s, s);
                    let took = advance(&p, &mut a, u, m, Some(map));
                    advance(&p, &mut b, u, m, None);
                    advance(&free, &mut c, u, m, None);
                    let clips = b != c;
                    total += 1;
                    clipped += u64::from(clips);
                    if took {
                        exact += 1;
                        assert!(!clips, "exact tick where RK4 clips: {s:?} u = {u} {m:?}");
                        for (i, (w, lim)) in worst.iter_mut().zip(limits).enumerate() {
                            if lim > 0.0 {
                                *w = w.max(fabs(a.y[i] - b.y[i]) / lim);
                            }
                        }
                    } else if !clips {
                        declined += 1;
                    }
                    s = a;
                }
            }
        }
        std::println!(
            "{total} ticks: {exact} exact, {clipped} clipped by RK4, {declined} declined without \
             a clip; worst exact − RK4 per limit {worst:?}"
        );
        // The stress reaches every regime...
        assert!(
            clipped > total / 10 && exact > total / 4,
            "{clipped} {exact}"
        );
        // ...and where the exact step is taken it is RK4's tick to the 4-sub-step RK4's own local
        // error on these violent steps (measured ≤ 3.5e-6 of the velocity limit, ≤ 1.2e-7 of the
        // others).
        assert!(worst.iter().all(|&w| w < 1e-5), "{worst:?}");
    }

    #[test]
    fn exact_map_is_the_matrix_exponential() {
        // Φ and Γ against RK4 with 4096 sub-steps of the unsaturated plant (error ~1e-16).
        let mut p = RigConfig::new(Preset::UnrCompact).build().unwrap();
        p.capacity_n = f64::INFINITY;
        p.stroke_m = f64::INFINITY;
        p.velocity_m_s = f64::INFINITY;
        p.substeps = 4096;
        let z = p.zoh_at(1.0);
        let m = Modifiers::default();
        for j in 0..6 {
            let mut s = PlantState::default();
            let u = if j == 5 { 1.0 / p.gain } else { 0.0 };
            if let Some(v) = s.y.get_mut(j) {
                *v = if j < 5 { 1.0 } else { 0.0 };
            }
            advance(&p, &mut s, u, m, None);
            let col: [f64; 5] =
                core::array::from_fn(|i| if j < 5 { z.phi[i][j] } else { z.gamma[i] });
            for (i, (rk, ex)) in s.y.iter().zip(col).enumerate() {
                let scale = fabs(*rk).max(1e-300);
                assert!(
                    fabs(rk - ex) <= 1e-10 * scale + 1e-300,
                    "column {j} row {i}: RK4 {rk} vs exact {ex}"
                );
            }
        }
    }
}

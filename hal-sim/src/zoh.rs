//! The exact zero-order-hold map of the linear plant over one controller tick (`y ← Φ·y + Γ·r`),
//! computed once per parameter set: what `plant`'s exact tick applies while the dynamics are
//! linear. It knows only the linear plant's coefficients ([`LinearPlant`]); the plant's
//! parameters (`crate::params`) hold the map of the healthy plant.

/// The exact zero-order-hold discretization of the linear plant (state `[q, q̇, f, x, ẋ]`, `z` is
/// idle) over one controller tick: `y(t + dt) = Φ·y(t) + Γ·r` for a reference `r` held over the
/// tick, no saturation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Zoh {
    /// Φ = e^{A·dt}.
    pub(crate) phi: [[f64; 5]; 5],
    /// Γ = ∫₀^dt e^{A·s}ds·B.
    pub(crate) gamma: [f64; 5],
}

/// The linear plant's coefficients a [`Zoh`] is computed from (`crate::params::PlantParams`'s,
/// the specimen stiffness already scaled).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LinearPlant {
    /// Controller tick, s.
    pub(crate) dt_s: f64,
    /// Servo-valve loop `q̈ + β1·q̇ + β2·q = a1β0·e`.
    pub(crate) beta1: f64,
    /// See `beta1`.
    pub(crate) beta2: f64,
    /// See `beta1`.
    pub(crate) a1_beta0: f64,
    /// Actuator `ḟ + a3·f = q − a2·ẋ`.
    pub(crate) a2: f64,
    /// See `a2`.
    pub(crate) a3: f64,
    /// Specimen mass, kg.
    pub(crate) mass_kg: f64,
    /// Specimen damping, N·s/m.
    pub(crate) damping_n_s_per_m: f64,
    /// Specimen stiffness, N/m.
    pub(crate) stiffness_n_per_m: f64,
}

type Mat6 = [[f64; 6]; 6];

fn matmul(a: &Mat6, b: &Mat6) -> Mat6 {
    let mut out = [[0.0; 6]; 6];
    for (orow, arow) in out.iter_mut().zip(a) {
        for (aik, brow) in arow.iter().zip(b) {
            for (o, bkj) in orow.iter_mut().zip(brow) {
                *o += aik * bkj;
            }
        }
    }
    out
}

/// Scaling and squaring: `e^{M·dt} = (e^{M·dt/2^s})^{2^s}`, each factor a Taylor series. The
/// fastest mode is |λ| ≤ 783 rad/s and the other couplings are of the same order, so with
/// `dt/64` the scaled matrix has a spectral radius ≈ 0.006 and order 12 truncates below 1e-30.
const ZOH_SQUARINGS: u32 = 6;
const ZOH_TAYLOR_ORDER: u32 = 12;

impl Zoh {
    /// `Φ = e^{A·dt}` and `Γ = ∫₀^dt e^{A·s}ds·B` from the exponential of the augmented matrix
    /// `[[A, B], [0, 0]]` (its top-right column is Γ).
    pub(crate) fn new(p: &LinearPlant) -> Self {
        let k = p.stiffness_n_per_m;
        let h = p.dt_s / f64::from(1u32 << ZOH_SQUARINGS);
        let (m, c) = (p.mass_kg, p.damping_n_s_per_m);
        // Rows: q̇, q̈, ḟ, ẋ, ẍ, ṙ = 0 (same equations as `deriv` without the saturations).
        let a: Mat6 = [
            [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
            [-p.beta2, -p.beta1, 0.0, -p.a1_beta0, 0.0, p.a1_beta0],
            [1.0, 0.0, -p.a3, 0.0, -p.a2, 0.0],
            [0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0 / m, -k / m, -c / m, 0.0],
            [0.0; 6],
        ];
        let mut ah = a;
        for v in ah.iter_mut().flatten() {
            *v *= h;
        }
        let mut ident = [[0.0; 6]; 6];
        for (i, row) in ident.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = if i == j { 1.0 } else { 0.0 };
            }
        }
        // Horner: I + M(I + M/2(I + … (I + M/n))).
        let mut e = ident;
        for j in (1..=ZOH_TAYLOR_ORDER).rev() {
            let me = matmul(&ah, &e);
            let inv = 1.0 / f64::from(j);
            for ((er, mr), ir) in e.iter_mut().zip(&me).zip(&ident) {
                for ((ev, mv), iv) in er.iter_mut().zip(mr).zip(ir) {
                    *ev = iv + mv * inv;
                }
            }
        }
        for _ in 0..ZOH_SQUARINGS {
            e = matmul(&e, &e);
        }
        let mut z = Zoh {
            phi: [[0.0; 5]; 5],
            gamma: [0.0; 5],
        };
        for ((prow, g), erow) in z.phi.iter_mut().zip(z.gamma.iter_mut()).zip(&e) {
            for (pv, ev) in prow.iter_mut().zip(erow) {
                *pv = *ev;
            }
            *g = erow[5];
        }
        z
    }
}

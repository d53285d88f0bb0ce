//! ATS: the adaptive time-series compensator (Chae, Kazemibidokhti, Ricles, EESD 2013).
//! `u_c = a0·x_t + a1·ẋ_t + a2·ẍ_t`, target derivatives by backward differences. Every `update_period`
//! samples the coefficients are re-fitted by least squares over the last `window` samples of
//! `u_f(j) ≈ a0·x_f(j) + a1·ẋ_f(j) + a2·ẍ_f(j)`, where `x_f` is the Butterworth-filtered measured
//! displacement (derivatives by backward differences of `x_f`) and `u_f` the equally filtered command
//! (same filter, so the filter's phase cancels). For a plant `g·e^{−sτ}/(1 + sT)` the inverse is
//! `(1/g)·(1 + s(τ+T) + s²(τ²/2 + τT) + …)`, so a1 ≈ (τ+T)/g is the effective delay.
//!
//! Memory: the 128 KiB MCU cannot hold the four 2048-long regressor/response arrays (64 KiB). We keep two
//! rings only (filtered x_m, window + 3 long, and filtered command, window + 1 long: ≈ 32.8 KiB in all)
//! and running sums of the 3×3 normal matrix and right-hand side. Each tick adds the newest sample's
//! outer product and subtracts the leaving sample's, whose derivatives are recomputed from the ring.
//!
//! Drift guard: add/subtract sums lose accuracy (catastrophically after a large spike leaves the window).
//! A full re-sum at update time would cost ~2048 × 12 soft-float f64 operations in one tick on the
//! Cortex-M4F (its FPU is single precision), too much for a 488 µs tick. Instead a *shadow* sum
//! accumulates only additions from the start of each window period; after exactly `window` samples it
//! equals the exact sum over the current window and replaces the running sum. Cost: 12 extra adds per
//! tick; the running sums are thus re-anchored to an exact (addition-only) value every `window` ticks,
//! so any drift or spike residue lives at most one window.
//!
//! Condition guard: the normal matrix is Jacobi-scaled to unit diagonal (x, ẋ, ẍ differ by ~10⁴ in
//! scale); its determinant `det ∈ (0, 1]` then bounds the condition number, `cond ≤ 27/det` (all
//! eigenvalues ≤ trace = 3). An update is skipped (and counted) when `det < 27/max_condition`, e.g. a
//! pure sine (sampled: ẍ is a combination of x and ẋ, exactly collinear). A window whose filtered
//! velocity RMS is below `min_velocity_rms_mm_s` is skipped too (a motionless actuator).

use super::input;
use crate::filter::{finite, Butterworth, ButterworthParams, InputError};
use crate::params::{positive, ParamError};
use nalgebra::{Matrix3, Vector3};

/// Largest ATS window in samples (1 s at 2048 Hz); the rings are sized for it.
pub const ATS_MAX_WINDOW: usize = 2048;

pub(super) const X_RING: usize = ATS_MAX_WINDOW + 3;
pub(super) const U_RING: usize = ATS_MAX_WINDOW + 1;

/// A fixed-capacity ring of the most recent samples (initially all zero: the rig starts at rest).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Ring<const N: usize> {
    buf: [f64; N],
    newest: usize,
}

impl<const N: usize> Ring<N> {
    const fn new() -> Self {
        Self {
            buf: [0.0; N],
            newest: 0,
        }
    }

    fn clear(&mut self) {
        self.buf.iter_mut().for_each(|v| *v = 0.0);
        self.newest = 0;
    }

    fn push(&mut self, v: f64) {
        self.newest = (self.newest + 1) % N;
        if let Some(slot) = self.buf.get_mut(self.newest) {
            *slot = v;
        }
    }

    /// The k-th most recent sample (0 = newest); 0 for k ≥ N (never asked for by construction).
    pub(super) fn back(&self, k: usize) -> f64 {
        if k >= N {
            return 0.0;
        }
        self.buf
            .get((self.newest + N - k) % N)
            .copied()
            .unwrap_or(0.0)
    }
}

/// Raw ATS settings, validated into [`AtsParams`]. [`AtsConfig::paper`] gives docs/design.md §6's values.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AtsConfig {
    /// Controller step, s.
    pub dt_s: f64,
    /// Expected actuator delay, s: initial a1 (initial a0 = 1, a2 = a1²/2).
    pub expected_delay_s: f64,
    /// Lower bounds of [a0, a1 (s), a2 (s²)].
    pub lower: [f64; 3],
    /// Upper bounds of [a0, a1 (s), a2 (s²)].
    pub upper: [f64; 3],
    /// Largest |Δa| per update, [a0, a1 (s), a2 (s²)].
    pub max_step: [f64; 3],
    /// Least-squares window, samples (≤ [`ATS_MAX_WINDOW`]).
    pub window: usize,
    /// Samples between coefficient updates.
    pub update_period: usize,
    /// Order of the Butterworth applied to measured and command (even).
    pub filter_order: usize,
    /// Cutoff of that filter, Hz.
    pub filter_cutoff_hz: f64,
    /// Adaptation starts (latched) once |filtered x_m| exceeds this, mm.
    pub start_threshold_mm: f64,
    /// Largest admissible condition number of the scaled normal matrix; worse fits are skipped.
    pub max_condition: f64,
    /// Smallest RMS of the filtered measured velocity over the window, mm/s; quieter windows are
    /// skipped (Jacobi scaling makes the condition test blind to *absolute* excitation, so a motionless
    /// actuator would otherwise be fitted to round-off and noise).
    pub min_velocity_rms_mm_s: f64,
}

impl AtsConfig {
    /// docs/design.md §6 / Chae et al. 2013: 1 s window, update every 16th sample, 6th-order 20 Hz Butterworth,
    /// start at 0.25 mm, |Δa| ≤ [2, 0.05, 0.001]/10, a0 ∈ [0.7, 1.3], a1 ∈ [0, 0.08] s,
    /// a2 ∈ [0, 0.0032] s². The window is `round(1 s / dt_s)` capped at [`ATS_MAX_WINDOW`]
    /// (2048 at 2048 Hz). `max_condition` = 1e8 and `min_velocity_rms_mm_s` = 0.5 mm/s are our choices
    /// (the paper states neither; 0.5 mm/s is a 0.25 mm-threshold motion at ~0.45 Hz).
    pub fn paper(dt_s: f64, expected_delay_s: f64) -> Self {
        let per_second = if dt_s.is_finite() && dt_s > 0.0 {
            libm::round(1.0 / dt_s)
        } else {
            0.0
        };
        let window = if per_second >= ATS_MAX_WINDOW as f64 {
            ATS_MAX_WINDOW
        } else {
            per_second as usize
        };
        Self {
            dt_s,
            expected_delay_s,
            lower: [0.7, 0.0, 0.0],
            upper: [1.3, 0.08, 0.0032],
            max_step: [0.2, 0.005, 0.0001],
            window,
            update_period: 16,
            filter_order: 6,
            filter_cutoff_hz: 20.0,
            start_threshold_mm: 0.25,
            max_condition: 1.0e8,
            min_velocity_rms_mm_s: 0.5,
        }
    }
}

/// Validated ATS parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AtsParams {
    config: AtsConfig,
    initial: [f64; 3],
    filter: ButterworthParams,
    min_det: f64,
    min_vel_sq_sum: f64,
}

impl AtsParams {
    /// Validate: dt > 0; finite bounds with lower ≤ upper; initial [1, delay, delay²/2] within the
    /// bounds; step limits > 0; 3 ≤ window ≤ [`ATS_MAX_WINDOW`]; 1 ≤ update period ≤ window; a valid
    /// Butterworth (0 < fc < fs/2); threshold ≥ 0; max condition > 1.
    pub fn new(config: AtsConfig) -> Result<Self, ParamError> {
        let dt = positive(config.dt_s, "ATS dt_s")?;
        for ((lo, hi), step) in config.lower.iter().zip(&config.upper).zip(&config.max_step) {
            if !lo.is_finite() || !hi.is_finite() {
                return Err(ParamError::NotFinite("ATS coefficient bound"));
            }
            if lo > hi {
                return Err(ParamError::OutOfRange("ATS bounds (lower > upper)"));
            }
            positive(*step, "ATS per-update limit")?;
        }
        let delay = config.expected_delay_s;
        if !delay.is_finite() {
            return Err(ParamError::NotFinite("ATS expected delay"));
        }
        let initial = [1.0, delay, 0.5 * delay * delay];
        let inside = initial
            .iter()
            .zip(config.lower.iter().zip(&config.upper))
            .all(|(a, (lo, hi))| a >= lo && a <= hi);
        if !inside {
            return Err(ParamError::OutOfRange(
                "ATS initial coefficients (outside bounds)",
            ));
        }
        if config.window < 3 || config.window > ATS_MAX_WINDOW {
            return Err(ParamError::OutOfRange("ATS window (3..=2048 samples)"));
        }
        if config.update_period == 0 || config.update_period > config.window {
            return Err(ParamError::OutOfRange("ATS update period (1..=window)"));
        }
        let filter =
            ButterworthParams::new(config.filter_order, config.filter_cutoff_hz, 1.0 / dt)?;
        if !config.start_threshold_mm.is_finite() {
            return Err(ParamError::NotFinite("ATS start threshold"));
        }
        if config.start_threshold_mm < 0.0 {
            return Err(ParamError::OutOfRange("ATS start threshold (must be >= 0)"));
        }
        let cond = positive(config.max_condition, "ATS max condition")?;
        if cond <= 1.0 {
            return Err(ParamError::OutOfRange("ATS max condition (must be > 1)"));
        }
        let v_min = config.min_velocity_rms_mm_s;
        if !v_min.is_finite() {
            return Err(ParamError::NotFinite("ATS min velocity RMS"));
        }
        if v_min < 0.0 {
            return Err(ParamError::OutOfRange(
                "ATS min velocity RMS (must be >= 0)",
            ));
        }
        Ok(Self {
            config,
            initial,
            filter,
            min_det: 27.0 / cond,
            min_vel_sq_sum: v_min * v_min * config.window as f64,
        })
    }

    /// The settings.
    pub fn config(&self) -> &AtsConfig {
        &self.config
    }

    /// Initial coefficients: [1, delay, delay²/2], or those of [`AtsParams::with_initial`].
    pub fn initial(&self) -> [f64; 3] {
        self.initial
    }

    /// The same parameters starting from `initial` = [a0, a1 (s), a2 (s²)] instead of
    /// [1, delay, delay²/2]: e.g. the values identified on the rig (`(1/g)·[1, τ+T, τ²/2 + τT]`
    /// of the measured actuator), which a lab would start from. Refused if not finite or outside
    /// the bounds, as [`AtsParams::new`] refuses its own.
    pub fn with_initial(self, initial: [f64; 3]) -> Result<Self, ParamError> {
        if initial.iter().any(|a| !a.is_finite()) {
            return Err(ParamError::NotFinite("ATS initial coefficients"));
        }
        let inside = initial
            .iter()
            .zip(self.config.lower.iter().zip(&self.config.upper))
            .all(|(a, (lo, hi))| a >= lo && a <= hi);
        if !inside {
            return Err(ParamError::OutOfRange(
                "ATS initial coefficients (outside bounds)",
            ));
        }
        Ok(Self { initial, ..self })
    }
}

/// Running sums of the normal equations `Σφφᵀ`, `Σφ·u`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Normal {
    pub(super) a: [[f64; 3]; 3],
    b: [f64; 3],
}

impl Normal {
    const ZERO: Self = Self {
        a: [[0.0; 3]; 3],
        b: [0.0; 3],
    };

    pub(super) fn add(&mut self, phi: &[f64; 3], y: f64, sign: f64) {
        for (row, (bi, pi)) in self.a.iter_mut().zip(self.b.iter_mut().zip(phi)) {
            *bi += sign * pi * y;
            for (aij, pj) in row.iter_mut().zip(phi) {
                *aij += sign * pi * pj;
            }
        }
    }
}

/// Mutable state of the ATS compensator.
#[derive(Debug, Clone, PartialEq)]
pub struct AtsState {
    coeffs: [f64; 3],
    target_hist: [f64; 2],
    filt_x: Butterworth,
    filt_u: Butterworth,
    pub(super) xf: Ring<X_RING>,
    pub(super) uf: Ring<U_RING>,
    pub(super) sums: Normal,
    shadow: Normal,
    shadow_count: usize,
    count: usize,
    since_update: usize,
    adapting: bool,
    updates: u32,
    skipped: u32,
}

impl AtsState {
    /// At rest, with the initial coefficients of `params`.
    pub fn new(params: &AtsParams) -> Self {
        let filt = Butterworth::new(params.filter);
        Self {
            coeffs: params.initial,
            target_hist: [0.0; 2],
            filt_x: filt,
            filt_u: filt,
            xf: Ring::new(),
            uf: Ring::new(),
            sums: Normal::default(),
            shadow: Normal::default(),
            shadow_count: 0,
            count: 0,
            since_update: 0,
            adapting: false,
            updates: 0,
            skipped: 0,
        }
    }

    /// Back to rest with the initial coefficients (in place: no 33 KiB temporary on the stack).
    pub fn reset(&mut self, params: &AtsParams) {
        self.coeffs = params.initial;
        self.target_hist = [0.0; 2];
        self.filt_x.reset();
        self.filt_u.reset();
        self.xf.clear();
        self.uf.clear();
        self.sums = Normal::default();
        self.shadow = Normal::default();
        self.shadow_count = 0;
        self.count = 0;
        self.since_update = 0;
        self.adapting = false;
        self.updates = 0;
        self.skipped = 0;
    }
}

/// ATS compensator: parameters plus state.
#[derive(Debug, Clone, PartialEq)]
pub struct Ats {
    params: AtsParams,
    pub(super) state: AtsState,
}

impl Ats {
    /// Every byte zero: not a usable compensator, a placeholder that reserves its ~33 KiB where it
    /// will live (a zero constant is written as a memset, no copy on the stack or in flash);
    /// [`Self::configure`] makes it [`Self::new`]'s.
    pub(crate) const PARKED: Self = Self {
        params: AtsParams {
            config: AtsConfig {
                dt_s: 0.0,
                expected_delay_s: 0.0,
                lower: [0.0; 3],
                upper: [0.0; 3],
                max_step: [0.0; 3],
                window: 0,
                update_period: 0,
                filter_order: 0,
                filter_cutoff_hz: 0.0,
                start_threshold_mm: 0.0,
                max_condition: 0.0,
                min_velocity_rms_mm_s: 0.0,
            },
            initial: [0.0; 3],
            filter: ButterworthParams::PARKED,
            min_det: 0.0,
            min_vel_sq_sum: 0.0,
        },
        state: AtsState {
            coeffs: [0.0; 3],
            target_hist: [0.0; 2],
            filt_x: Butterworth::PARKED,
            filt_u: Butterworth::PARKED,
            xf: Ring::new(),
            uf: Ring::new(),
            sums: Normal::ZERO,
            shadow: Normal::ZERO,
            shadow_count: 0,
            count: 0,
            since_update: 0,
            adapting: false,
            updates: 0,
            skipped: 0,
        },
    };

    /// Become `Self::new(params)` in place (a compensator built where it lives: no 33 KiB value
    /// on the stack).
    pub fn configure(&mut self, params: AtsParams) {
        self.params = params;
        self.state.filt_x = Butterworth::new(params.filter);
        self.state.filt_u = Butterworth::new(params.filter);
        self.state.reset(&self.params);
    }

    /// A compensator at rest with the initial coefficients.
    pub fn new(params: AtsParams) -> Self {
        Self {
            state: AtsState::new(&params),
            params,
        }
    }

    /// The parameters.
    pub fn params(&self) -> &AtsParams {
        &self.params
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        self.state.reset(&self.params);
    }

    /// Start from `initial` = [a0, a1 (s), a2 (s²)] from now on (a rig's identified values),
    /// validated as [`AtsParams::with_initial`] does, and back to rest; in place (the ATS's state
    /// is ~33 KiB). Refused: nothing changes.
    pub fn set_initial(&mut self, initial: [f64; 3]) -> Result<(), ParamError> {
        self.params = self.params.with_initial(initial)?;
        self.reset();
        Ok(())
    }

    /// Current [a0, a1 (s), a2 (s²)].
    pub fn coefficients(&self) -> [f64; 3] {
        self.state.coeffs
    }

    /// Whether adaptation has started (|filtered x_m| exceeded the threshold once).
    pub fn is_adapting(&self) -> bool {
        self.state.adapting
    }

    /// Coefficient updates applied so far.
    pub fn updates(&self) -> u32 {
        self.state.updates
    }

    /// Updates skipped by the excitation or condition guard (or a failed factorization).
    pub fn skipped_updates(&self) -> u32 {
        self.state.skipped
    }

    /// One tick: command `u_c` (mm) from the target and the measured displacement (mm).
    pub fn compensate(&mut self, target_mm: f64, measured_mm: f64) -> Result<f64, InputError> {
        let xt = input(target_mm, "target_mm")?;
        let xm = input(measured_mm, "measured_mm")?;
        let s = &mut self.state;
        let dt = self.params.config.dt_s;
        let [t1, t2] = s.target_hist;
        let vel = (xt - t1) / dt;
        let acc = (xt - 2.0 * t1 + t2) / (dt * dt);
        let [a0, a1, a2] = s.coeffs;
        let u = finite(a0 * xt + a1 * vel + a2 * acc, "ATS command")?;
        // Filter on copies so that a refusal leaves everything untouched.
        let (mut fx, mut fu) = (s.filt_x, s.filt_u);
        let x_f = fx.step(xm)?;
        let u_f = fu.step(u)?;

        // Commit.
        s.filt_x = fx;
        s.filt_u = fu;
        s.target_hist = [xt, t1];
        s.xf.push(x_f);
        s.uf.push(u_f);
        let window = self.params.config.window;
        let phi_new = regressor(&s.xf, 0, dt);
        s.sums.add(&phi_new, u_f, 1.0);
        s.shadow.add(&phi_new, u_f, 1.0);
        if s.count >= window {
            let phi_old = regressor(&s.xf, window, dt);
            s.sums.add(&phi_old, s.uf.back(window), -1.0);
        } else {
            s.count += 1;
        }
        s.shadow_count += 1;
        if s.shadow_count >= window {
            // The shadow holds exactly the current window, built by additions only.
            s.sums = s.shadow;
            s.shadow = Normal::default();
            s.shadow_count = 0;
        }
        if x_f.abs() > self.params.config.start_threshold_mm {
            s.adapting = true;
        }
        s.since_update += 1;
        if s.since_update >= self.params.config.update_period {
            s.since_update = 0;
            if s.adapting && s.count >= window {
                self.update();
            }
        }
        Ok(u)
    }

    /// Least-squares refit with the condition guard, per-update rate limits and bounds.
    fn update(&mut self) {
        let cfg = &self.params.config;
        let s = &mut self.state;
        let excited = s
            .sums
            .a
            .get(1)
            .and_then(|r| r.get(1))
            .is_some_and(|v| *v >= self.params.min_vel_sq_sum);
        let fit = if excited {
            solve(&s.sums, self.params.min_det)
        } else {
            None
        };
        match fit {
            Some(fit) => {
                for ((((c, f), step), lo), hi) in s
                    .coeffs
                    .iter_mut()
                    .zip(fit)
                    .zip(cfg.max_step)
                    .zip(cfg.lower)
                    .zip(cfg.upper)
                {
                    let delta = (f - *c).max(-step).min(step);
                    *c = (*c + delta).max(lo).min(hi);
                }
                s.updates = s.updates.saturating_add(1);
            }
            None => s.skipped = s.skipped.saturating_add(1),
        }
    }
}

/// [x_f, ẋ_f, ẍ_f] of the sample `k` steps back, derivatives by backward differences.
pub(super) fn regressor<const N: usize>(ring: &Ring<N>, k: usize, dt: f64) -> [f64; 3] {
    let (x0, x1, x2) = (ring.back(k), ring.back(k + 1), ring.back(k + 2));
    [x0, (x0 - x1) / dt, (x0 - 2.0 * x1 + x2) / (dt * dt)]
}

/// Solve the normal equations after Jacobi scaling; `None` when ill-conditioned or non-finite.
fn solve(n: &Normal, min_det: f64) -> Option<[f64; 3]> {
    let a = Matrix3::from_fn(|i, j| {
        n.a.get(i)
            .and_then(|r| r.get(j))
            .copied()
            .unwrap_or(f64::NAN)
    });
    let b = Vector3::from_fn(|i, _| n.b.get(i).copied().unwrap_or(f64::NAN));
    let d = a.diagonal();
    if !d.iter().all(|v| v.is_finite() && *v > 0.0) || !b.iter().all(|v| v.is_finite()) {
        return None;
    }
    let inv = d.map(|v| 1.0 / libm::sqrt(v));
    let scaled = a.component_mul(&(inv * inv.transpose()));
    let det = scaled.determinant();
    if det.is_nan() || det < min_det {
        return None;
    }
    let z = scaled.cholesky()?.solve(&b.component_mul(&inv));
    let x = z.component_mul(&inv);
    x.iter().all(|v| v.is_finite()).then_some([x.x, x.y, x.z])
}

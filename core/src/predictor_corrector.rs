//! The predictor-corrector of an experimental site: the targets of an outside integrator (one per
//! integration step, docs/site.md) turned into a command at every controller tick.
//!
//! The integration step is a whole number `N` of controller ticks. During a step the command moves
//! from the last target `d_i` (reached at the end of the previous step) toward the new one `d_{i+1}`:
//!
//! - **predictor**: while the new target has not arrived, the command follows the Lagrange
//!   polynomial through the last `order + 1` targets (at `x = 0, −1, −2, …`, `x` the time in steps),
//!   extrapolated to `x = j/N` at tick `j`; past the step's end it holds;
//! - **corrector**: once the new target arrives (at tick `j₀`, the command then `u₀`), the command is
//!   the polynomial through the new target (at `x = 1`) and the last `order` targets, interpolated
//!   at `x = j/N`, plus the gap `u₀ − p(x₀)` fading linearly to zero at `x = 1`: continuous at the
//!   arrival and exactly on the target at the step's end. A target that arrives after the step's end
//!   starts a corrector over a whole new step from where the command holds.
//!
//! When every target arrives at the step's start (a simulated site, which waits for its client),
//! only the corrector runs: the command interpolates the targets exactly.
//!
//! Parameters ([`PcParams`]) are validated and immutable; [`PredictorCorrector::reset`] returns the
//! state to rest. Nothing here allocates or panics.

use crate::params::ParamError;

/// Highest polynomial order (3: cubic, as the usual xPC predictor-correctors use).
pub const PC_MAX_ORDER: usize = 3;

/// The order an experimental site uses (cubic), on the host's virtual rig and on the board.
pub const SITE_ORDER: usize = 3;

/// Largest integration step, controller ticks.
pub const PC_MAX_TICKS_PER_STEP: u32 = 1 << 20;

/// The predictor-corrector's parameters, validated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PcParams {
    ticks_per_step: u32,
    order: usize,
}

impl PcParams {
    /// `ticks_per_step` in 1..=[`PC_MAX_TICKS_PER_STEP`], `order` in 1..=[`PC_MAX_ORDER`].
    pub fn new(ticks_per_step: u32, order: usize) -> Result<Self, ParamError> {
        if ticks_per_step == 0 || ticks_per_step > PC_MAX_TICKS_PER_STEP {
            return Err(ParamError::OutOfRange("ticks per integration step"));
        }
        if order == 0 || order > PC_MAX_ORDER {
            return Err(ParamError::OutOfRange("predictor-corrector order (1..=3)"));
        }
        Ok(Self {
            ticks_per_step,
            order,
        })
    }
    /// Controller ticks per integration step.
    pub fn ticks_per_step(&self) -> u32 {
        self.ticks_per_step
    }
    /// Polynomial order.
    pub fn order(&self) -> usize {
        self.order
    }
}

/// Why a target was refused (nothing changed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PcError {
    /// The target is NaN or infinite.
    NonFinite,
    /// A target is already pending: the step it belongs to has not ended.
    Pending,
}

/// One tick's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcTick {
    /// The command for this tick, mm.
    pub command_mm: f64,
    /// This tick ended the step: the command is the new target.
    pub step_done: bool,
    /// The command was predicted (the target had not arrived).
    pub predicted: bool,
}

/// The predictor-corrector: parameters and a small state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PredictorCorrector {
    params: PcParams,
    /// Reached targets, newest first (`d_i, d_{i−1}, …`); zeros at rest.
    targets: [f64; PC_MAX_ORDER + 1],
    /// The new target, once it has arrived.
    pending: Option<f64>,
    /// Ticks into the current step.
    tick: u32,
    /// Where the corrector started: (x₀, u₀ − p(x₀)).
    arrival: (f64, f64),
    /// The last command, mm.
    last_mm: f64,
    /// Steps ended since rest (a site reports each one's measurement).
    steps_done: u32,
}

/// Lagrange polynomial through `(xs[i], ys[i])`, `i < n`, evaluated at `x`. Iterators, not
/// slices: the firmware's control task must reach no bounds-check panic.
fn lagrange(xs: &[f64], ys: &[f64], n: usize, x: f64) -> f64 {
    let mut sum = 0.0;
    for (i, (&xi, &yi)) in xs.iter().zip(ys).take(n).enumerate() {
        let mut w = 1.0;
        for (j, &xj) in xs.iter().take(n).enumerate() {
            if j != i {
                w *= (x - xj) / (xi - xj);
            }
        }
        sum += w * yi;
    }
    sum
}

/// The abscissae of the predictor (0, −1, −2, −3) and corrector (1, 0, −1, −2).
const X_PRED: [f64; PC_MAX_ORDER + 1] = [0.0, -1.0, -2.0, -3.0];
const X_CORR: [f64; PC_MAX_ORDER + 1] = [1.0, 0.0, -1.0, -2.0];

impl PredictorCorrector {
    /// At rest at zero.
    pub fn new(params: PcParams) -> Self {
        Self {
            params,
            targets: [0.0; PC_MAX_ORDER + 1],
            pending: None,
            tick: 0,
            arrival: (0.0, 0.0),
            last_mm: 0.0,
            steps_done: 0,
        }
    }

    /// Back to rest at zero, parameters kept.
    pub fn reset(&mut self) {
        *self = Self::new(self.params);
    }

    /// The parameters.
    pub fn params(&self) -> &PcParams {
        &self.params
    }

    /// The last command, mm.
    pub fn last_mm(&self) -> f64 {
        self.last_mm
    }

    /// The last target reached, mm.
    pub fn reached_mm(&self) -> f64 {
        self.targets[0]
    }

    /// A new target is pending (its step has not ended).
    pub fn is_pending(&self) -> bool {
        self.pending.is_some()
    }

    /// Steps ended since rest (wrapping).
    pub fn steps_done(&self) -> u32 {
        self.steps_done
    }

    fn corrector_poly(&self, target_mm: f64, x: f64) -> f64 {
        let ys = Self::shifted(target_mm, &self.targets);
        lagrange(&X_CORR, &ys, self.params.order + 1, x)
    }

    /// `[newest, targets[0], targets[1], …]`: the targets once `newest` is reached.
    fn shifted(newest: f64, targets: &[f64; PC_MAX_ORDER + 1]) -> [f64; PC_MAX_ORDER + 1] {
        let mut ys = [newest; PC_MAX_ORDER + 1];
        for (y, t) in ys.iter_mut().skip(1).zip(targets) {
            *y = *t;
        }
        ys
    }

    fn x_of(&self, tick: u32) -> f64 {
        f64::from(tick) / f64::from(self.params.ticks_per_step)
    }

    /// The target of the step under way, arrived now (before the next [`Self::tick`]).
    pub fn set_target(&mut self, target_mm: f64) -> Result<(), PcError> {
        if !target_mm.is_finite() {
            return Err(PcError::NonFinite);
        }
        if self.pending.is_some() {
            return Err(PcError::Pending);
        }
        if self.tick >= self.params.ticks_per_step {
            // Late: the step is over, the command holds; a whole new step from here.
            self.tick = 0;
        }
        let x0 = self.x_of(self.tick);
        let gap = if self.tick == 0 {
            self.last_mm - self.targets[0]
        } else {
            self.last_mm - self.corrector_poly(target_mm, x0)
        };
        self.arrival = (x0, gap);
        self.pending = Some(target_mm);
        Ok(())
    }

    /// One controller tick: the command for it.
    pub fn tick(&mut self) -> PcTick {
        let n_ticks = self.params.ticks_per_step;
        let Some(target) = self.pending else {
            // Predictor, then hold past the step's end.
            if self.tick < n_ticks {
                self.tick += 1;
                let x = self.x_of(self.tick);
                let u = lagrange(&X_PRED, &self.targets, self.params.order + 1, x);
                if u.is_finite() {
                    self.last_mm = u;
                }
            }
            return PcTick {
                command_mm: self.last_mm,
                step_done: false,
                predicted: true,
            };
        };
        self.tick = self.tick.saturating_add(1).min(n_ticks);
        let step_done = self.tick == n_ticks;
        let u = if step_done {
            target
        } else {
            let x = self.x_of(self.tick);
            let (x0, gap) = self.arrival;
            self.corrector_poly(target, x) + gap * (1.0 - x) / (1.0 - x0)
        };
        if u.is_finite() {
            self.last_mm = u;
        }
        if step_done {
            self.targets = Self::shifted(target, &self.targets);
            self.pending = None;
            self.tick = 0;
            self.steps_done = self.steps_done.wrapping_add(1);
        }
        PcTick {
            command_mm: self.last_mm,
            step_done,
            predicted: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn pc(n: u32, order: usize) -> PredictorCorrector {
        PredictorCorrector::new(PcParams::new(n, order).unwrap())
    }

    #[test]
    fn parameters_are_validated() {
        assert!(PcParams::new(0, 3).is_err());
        assert!(PcParams::new(4, 0).is_err());
        assert!(PcParams::new(4, 4).is_err());
        assert!(PcParams::new(PC_MAX_TICKS_PER_STEP + 1, 1).is_err());
        assert!(PcParams::new(1, 1).is_ok());
    }

    #[test]
    fn refuses_nan_and_a_second_target_within_a_step() {
        let mut p = pc(4, 3);
        assert_eq!(p.set_target(f64::NAN), Err(PcError::NonFinite));
        p.set_target(1.0).unwrap();
        assert_eq!(p.set_target(2.0), Err(PcError::Pending));
        for _ in 0..3 {
            assert!(!p.tick().step_done);
        }
        let t = p.tick();
        assert!(t.step_done);
        assert_eq!(t.command_mm, 1.0);
        p.set_target(2.0).unwrap();
    }

    #[test]
    fn a_late_target_is_reached_a_whole_step_after_it_arrives() {
        let mut p = pc(4, 1);
        for _ in 0..10 {
            let t = p.tick();
            assert!(t.predicted);
            assert_eq!(t.command_mm, 0.0);
        }
        p.set_target(2.0).unwrap();
        let cmds: [f64; 4] = core::array::from_fn(|_| p.tick().command_mm);
        assert_eq!(cmds, [0.5, 1.0, 1.5, 2.0]);
    }

    proptest! {
        /// Targets on a polynomial of degree ≤ order, each arriving at its step's start: the
        /// commands are that polynomial at every tick (after the first `order` steps from rest).
        #[test]
        fn interpolates_a_polynomial_exactly(
            c in proptest::collection::vec(-10.0f64..10.0, 4),
            n in 1u32..40,
            order in 1usize..=3,
        ) {
            let poly = |s: f64| (0..=order).map(|k| c[k] * s.powi(k as i32)).sum::<f64>();
            let mut p = pc(n, order);
            // Start on the polynomial: feed the first `order + 1` targets.
            for i in 0..=order {
                p.set_target(poly(i as f64)).unwrap();
                for _ in 0..n { p.tick(); }
            }
            for i in (order + 1)..(order + 6) {
                p.set_target(poly(i as f64)).unwrap();
                for j in 1..=n {
                    let s = (i - 1) as f64 + f64::from(j) / f64::from(n);
                    let t = p.tick();
                    let want = poly(s);
                    prop_assert!((t.command_mm - want).abs() <= 1e-7 * (1.0 + want.abs()),
                        "{} vs {}", t.command_mm, want);
                    prop_assert_eq!(t.step_done, j == n);
                }
            }
        }

        /// Wherever targets arrive (any tick, late or not), every step ends exactly on its
        /// target, the command is finite, and the command is continuous at each arrival (the
        /// first corrected command is one tick's move from the predicted one).
        #[test]
        fn every_step_ends_on_its_target(
            targets in proptest::collection::vec(-20.0f64..20.0, 1..12),
            delays in proptest::collection::vec(0u32..20, 12),
            n in 1u32..16,
            order in 1usize..=3,
        ) {
            let mut p = pc(n, order);
            for (d, &wait) in targets.iter().zip(&delays) {
                for _ in 0..wait {
                    prop_assert!(p.tick().command_mm.is_finite());
                }
                p.set_target(*d).unwrap();
                let mut done = false;
                for _ in 0..n {
                    let t = p.tick();
                    prop_assert!(t.command_mm.is_finite());
                    if t.step_done {
                        prop_assert_eq!(t.command_mm, *d);
                        done = true;
                        break;
                    }
                }
                prop_assert!(done);
                prop_assert_eq!(p.reached_mm(), *d);
            }
        }

        /// `reset` is a fresh predictor-corrector.
        #[test]
        fn reset_is_fresh(targets in proptest::collection::vec(-5.0f64..5.0, 1..5)) {
            let mut p = pc(3, 3);
            for d in targets {
                p.set_target(d).unwrap();
                for _ in 0..3 { p.tick(); }
            }
            p.reset();
            prop_assert_eq!(p, pc(3, 3));
        }
    }
}

//! The fault-injection matrix: every fault of the virtual rig (and a control-tick overrun), at
//! several times of the El Centro `lr-online` run (and on `fe-online-ats`), against the closed loop
//! with the same [`rths_core::control::Controller`] the firmware runs.
//!
//! For each case: whether the supervisor tripped and why, the time from the fault to the trip, the
//! largest command change in one tick over the whole run (what the controller sent, and what reached
//! the servo-controller), and whether the command stayed within the stroke and velocity envelope.
//!
//! Which conditions are *unsafe* (must trip) and which are not (must not trip) is decided per case
//! ([`Expect`]) and explained in its `why`; see `docs/reliability.md`.

use rths_core::params::DT_S;
use rths_core::supervisor::{FaultReason, Limits, State};
use rths_hal_sim::{Channel, Fault, FaultKind, FaultPlan, Preset, Specimen};
use serde::Serialize;

use crate::machinery::model_file::ModelFile;
use crate::machinery::motion::GroundMotion;
use crate::studies::scenario::{self, Injection, ScenarioId, ScenarioSetup, TickRow};

/// The shipped phase-2 LR model (the one `lr-online` runs by default).
const SHIPPED_LR: &str = include_str!("../../data/models/lr.json");

/// Tick at `t_s` seconds.
fn tick(t_s: f64) -> u64 {
    (t_s / DT_S).round() as u64
}

/// The outcome a case must have.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Expect {
    /// Unsafe: the supervisor must trip, for one of these reasons.
    Trip(&'static [FaultReason]),
    /// Tolerated or not a fault of the rig: the supervisor must not trip.
    NoTrip,
    /// Not a fault in itself, unsafe only if it drives the rig past a limit: judged against the
    /// simulation's ground truth (noise-free). Must trip (following error, force or stroke) if the
    /// true following error, force or displacement went beyond its limit by more than the sensor
    /// noise can explain ([`ORACLE_MARGIN`]); must not trip if all stayed below by that margin.
    IffLimitHit,
    /// May trip (for one of these reasons) or not, depending on the motion at the time; the
    /// envelope is what is asserted. Used for short link losses (see the notes).
    Either(&'static [FaultReason]),
}

/// Margin of the ground-truth oracle, in limit units (mm or kN): ~25 σ of the sensor noise.
pub const ORACLE_MARGIN: f64 = 0.05;

impl Expect {
    fn label(self) -> String {
        match self {
            Expect::Trip(rs) => {
                let names: Vec<String> = rs.iter().map(|r| format!("{r:?}")).collect();
                format!("trip ({})", names.join("/"))
            }
            Expect::NoTrip => "no trip".to_string(),
            Expect::IffLimitHit => "trip iff a limit is hit".to_string(),
            Expect::Either(rs) => {
                let names: Vec<String> = rs.iter().map(|r| format!("{r:?}")).collect();
                format!("either (or {})", names.join("/"))
            }
        }
    }
}

/// One case of the matrix.
#[derive(Debug, Clone)]
pub struct FaultCase {
    /// Short name, e.g. `dropout 8 ticks`.
    pub name: String,
    /// The scenario it runs.
    pub scenario: ScenarioId,
    /// When the fault starts, s.
    pub start_s: f64,
    /// What is injected.
    pub injection: Injection,
    /// What must happen.
    pub expect: Expect,
    /// Why that is the right outcome.
    pub why: &'static str,
}

/// The measured outcome of one case.
#[derive(Debug, Clone, Serialize)]
pub struct CaseResult {
    /// Case name.
    pub case: String,
    /// Scenario id.
    pub scenario: String,
    /// Fault start, s.
    pub start_s: f64,
    /// The expected outcome, as text.
    pub expected: String,
    /// The supervisor tripped.
    pub detected: bool,
    /// Why it tripped.
    pub reason: Option<String>,
    /// Time from the fault's start to the trip, ms.
    pub time_to_trip_ms: Option<f64>,
    /// Largest |Δcommand| in one tick the controller sent over the whole run, mm.
    pub peak_jump_mm: f64,
    /// Largest |Δcommand| in one tick that reached the servo-controller, mm (larger than
    /// `peak_jump_mm` only when the link lost commands).
    pub peak_servo_jump_mm: f64,
    /// Largest |command|, mm.
    pub peak_command_mm: f64,
    /// Every command within the stroke limit and within one velocity-limited step of the last.
    pub envelope_kept: bool,
    /// After a trip, the command ramped (never faster than the fault ramp) to the safe position
    /// and ended there; `true` when there was no trip.
    pub ramp_ok: bool,
    /// Ground truth: the largest excess of the true following error, force or displacement over its
    /// limit between the fault and the trip (negative: that far below), mm or kN.
    pub truth_excess: f64,
    /// The outcome matches the expectation, the envelope was kept and the ramp was clean.
    pub pass: bool,
    /// Why the expectation is what it is.
    pub why: String,
}

/// The whole matrix with the limits it was checked against.
#[derive(Debug, Clone, Serialize)]
pub struct Matrix {
    /// Stroke limit, ±mm.
    pub stroke_limit_mm: f64,
    /// Rate limit: the largest command change per tick, mm (velocity limit × Δt).
    pub rate_limit_mm: f64,
    /// Fault ramp step per tick, mm.
    pub fault_step_mm: f64,
    /// One row per case.
    pub cases: Vec<CaseResult>,
}

impl Matrix {
    /// Every row passes.
    pub fn all_pass(&self) -> bool {
        self.cases.iter().all(|c| c.pass)
    }

    /// The table as Markdown.
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "Limits: stroke ±{:.2} mm, rate limit {:.4} mm/tick ({:.1} mm/s), fault ramp {:.4} mm/tick.\n\n",
            self.stroke_limit_mm,
            self.rate_limit_mm,
            self.rate_limit_mm / DT_S,
            self.fault_step_mm
        );
        s.push_str("| scenario | fault | at s | expected | detected (reason) | time to trip ms | max jump mm (servo) | peak cmd mm | envelope kept | pass |\n");
        s.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
        for c in &self.cases {
            let detected = match &c.reason {
                Some(r) => format!("yes ({r})"),
                None => "no".to_string(),
            };
            let ttt = c
                .time_to_trip_ms
                .map_or("—".to_string(), |t| format!("{t:.1}"));
            s.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {:.4} ({:.4}) | {:.2} | {} | {} |\n",
                c.scenario,
                c.case,
                c.start_s,
                c.expected,
                detected,
                ttt,
                c.peak_jump_mm,
                c.peak_servo_jump_mm,
                c.peak_command_mm,
                if c.envelope_kept { "yes" } else { "**no**" },
                if c.pass { "yes" } else { "**FAIL**" },
            ));
        }
        s
    }
}

/// Why building or running the matrix failed (not a failing row: those are results).
#[derive(Debug, thiserror::Error)]
pub enum FaultsError {
    /// A fault of the plan was invalid.
    #[error("invalid fault: {0:?}")]
    Fault(rths_hal_sim::ConfigError),
    /// The shipped model could not be read.
    #[error("shipped LR model: {0}")]
    Model(String),
    /// The reference response failed.
    #[error("reference response: {0}")]
    Reference(String),
    /// The scenario could not run.
    #[error(transparent)]
    Scenario(#[from] scenario::ScenarioError),
}

fn plan(kind: FaultKind, start: u64, ticks: u64) -> Result<Injection, FaultsError> {
    let f = Fault::new(kind, start, ticks).map_err(FaultsError::Fault)?;
    Ok(Injection {
        faults: FaultPlan::none().with(f).map_err(FaultsError::Fault)?,
        overruns: None,
    })
}

const FOREVER: u64 = u64::MAX;
use FaultReason as R;

/// The cases of the matrix: every fault kind at 2.5 s (strong motion, near the peak brace
/// velocity), 10 s and 25 s (weak motion) of `lr-online`, and a set on `fe-online-ats` at 10 s.
pub fn cases() -> Result<Vec<FaultCase>, FaultsError> {
    let mut v = Vec::new();
    for &t in &[2.5, 10.0, 25.0] {
        lr_cases(&mut v, ScenarioId::LrOnline, t)?;
    }
    fe_cases(&mut v, 10.0)?;
    Ok(v)
}

fn push(
    v: &mut Vec<FaultCase>,
    scenario: ScenarioId,
    start_s: f64,
    name: &str,
    injection: Injection,
    expect: Expect,
    why: &'static str,
) {
    v.push(FaultCase {
        name: name.to_string(),
        scenario,
        start_s,
        injection,
        expect,
        why,
    });
}

fn lr_cases(v: &mut Vec<FaultCase>, id: ScenarioId, t: f64) -> Result<(), FaultsError> {
    let k = tick(t);
    let trip = Expect::Trip;
    push(
        v,
        id,
        t,
        "dropout 4 ticks",
        plan(FaultKind::Dropout, k, 4)?,
        Expect::NoTrip,
        "short DAQ gap (2 ms) tolerated by design: last good sample held, < 8 ticks",
    );
    push(
        v,
        id,
        t,
        "dropout 7 ticks",
        plan(FaultKind::Dropout, k, 7)?,
        Expect::NoTrip,
        "edge of the sensor timeout: 7 consecutive errors are tolerated",
    );
    push(
        v,
        id,
        t,
        "dropout 8 ticks",
        plan(FaultKind::Dropout, k, 8)?,
        trip(&[R::SensorTimeout]),
        "edge: the 8th consecutive error (3.9 ms blind) trips",
    );
    push(
        v,
        id,
        t,
        "dropout permanent",
        plan(FaultKind::Dropout, k, FOREVER)?,
        trip(&[R::SensorTimeout]),
        "DAQ dead: the actuator runs blind",
    );
    push(
        v,
        id,
        t,
        "LVDT stuck",
        plan(FaultKind::Stuck(Channel::Disp), k, FOREVER)?,
        trip(&[R::FrozenSensor, R::FollowingError]),
        "position unknown: the reading no longer follows a moving command",
    );
    push(v, id, t, "load cell stuck", plan(FaultKind::Stuck(Channel::Force), k, FOREVER)?,
        Expect::NoTrip,
        "data fault, not a safety fault: the actuator's position is still measured and kept in the envelope (see notes)");
    push(
        v,
        id,
        t,
        "NaN LVDT 1 tick",
        plan(FaultKind::NaN(Channel::Disp), k, 1)?,
        trip(&[R::NonFiniteSample]),
        "a non-finite reading is never plausible",
    );
    push(
        v,
        id,
        t,
        "NaN load cell 1 tick",
        plan(FaultKind::NaN(Channel::Force), k, 1)?,
        trip(&[R::NonFiniteSample]),
        "a non-finite reading is never plausible",
    );
    push(
        v,
        id,
        t,
        "spike LVDT +5 mm 1 tick",
        plan(FaultKind::Spike(Channel::Disp, 5.0), k, 1)?,
        trip(&[R::ImplausibleMotion, R::FollowingError]),
        "a 5 mm step in 0.49 ms is 30× what the actuator can do (or 5 mm off the command)",
    );
    push(
        v,
        id,
        t,
        "spike LVDT +0.1 mm 1 tick",
        plan(FaultKind::Spike(Channel::Disp, 0.1), k, 1)?,
        Expect::NoTrip,
        "below the 0.24 mm/tick plausibility bound: indistinguishable from motion, harmless",
    );
    push(
        v,
        id,
        t,
        "spike load cell +40 kN 1 tick",
        plan(FaultKind::Spike(Channel::Force, 40.0), k, 1)?,
        trip(&[R::Force]),
        "beyond the 29.6 kN force limit: an overload is unsafe whatever its cause",
    );
    push(
        v,
        id,
        t,
        "valve at 2% flow",
        plan(FaultKind::ValveSaturation(0.02), k, FOREVER)?,
        Expect::IffLimitHit,
        "the actuator lags: unsafe only if the lag exceeds the following-error limit",
    );
    push(
        v,
        id,
        t,
        "valve at 50% flow",
        plan(FaultKind::ValveSaturation(0.5), k, FOREVER)?,
        Expect::IffLimitHit,
        "half the rated flow: the actuator lags a little more",
    );
    push(
        v,
        id,
        t,
        "specimen 50% softer",
        plan(FaultKind::StiffnessChange(0.5), k, FOREVER)?,
        Expect::IffLimitHit,
        "a change of the specimen is what the test measures, not a rig fault",
    );
    push(
        v,
        id,
        t,
        "specimen 2× stiffer",
        plan(FaultKind::StiffnessChange(2.0), k, FOREVER)?,
        Expect::IffLimitHit,
        "a change of the specimen is what the test measures, not a rig fault",
    );
    push(v, id, t, "lost ticks 2", plan(FaultKind::LostTicks, k, 2)?,
        Expect::Either(&[R::ImplausibleMotion]),
        "two commands lost: the servo catches up with a 3-step move; the stale-then-fresh reading trips only at speed");
    push(
        v,
        id,
        t,
        "lost ticks permanent",
        plan(FaultKind::LostTicks, k, FOREVER)?,
        trip(&[R::FrozenSensor, R::FollowingError]),
        "link dead: the reading freezes while the command moves",
    );
    let over = |n| Injection {
        faults: FaultPlan::none(),
        overruns: Some((k, n)),
    };
    push(
        v,
        id,
        t,
        "overrun 3 ticks",
        over(3),
        Expect::NoTrip,
        "3 consecutive late ticks are tolerated by design",
    );
    push(
        v,
        id,
        t,
        "overrun 4 ticks",
        over(4),
        trip(&[R::Overrun]),
        "the 4th consecutive missed deadline trips",
    );
    Ok(())
}

fn fe_cases(v: &mut Vec<FaultCase>, t: f64) -> Result<(), FaultsError> {
    let id = ScenarioId::FeOnlineAts;
    let k = tick(t);
    push(
        v,
        id,
        t,
        "dropout 7 ticks",
        plan(FaultKind::Dropout, k, 7)?,
        Expect::NoTrip,
        "tolerated; the FE model sees the held force",
    );
    push(
        v,
        id,
        t,
        "dropout permanent",
        plan(FaultKind::Dropout, k, FOREVER)?,
        Expect::Trip(&[R::SensorTimeout]),
        "DAQ dead",
    );
    push(
        v,
        id,
        t,
        "NaN load cell 1 tick",
        plan(FaultKind::NaN(Channel::Force), k, 1)?,
        Expect::Trip(&[R::NonFiniteSample]),
        "never fed to the FE model; trips",
    );
    push(v, id, t, "spike load cell +5 kN 1 tick", plan(FaultKind::Spike(Channel::Force, 5.0), k, 1)?,
        Expect::Trip(&[R::CommandVelocity]),
        "the FE model answers a 5 MN prototype kick with a command step no actuator may make: refused");
    push(
        v,
        id,
        t,
        "spike load cell +0.5 kN 1 tick",
        plan(FaultKind::Spike(Channel::Force, 0.5), k, 1)?,
        Expect::NoTrip,
        "a small glitch: the FE model absorbs it within the velocity limit",
    );
    push(
        v,
        id,
        t,
        "LVDT stuck",
        plan(FaultKind::Stuck(Channel::Disp), k, FOREVER)?,
        Expect::Trip(&[R::FrozenSensor, R::FollowingError]),
        "position unknown",
    );
    push(
        v,
        id,
        t,
        "valve at 2% flow",
        plan(FaultKind::ValveSaturation(0.02), k, FOREVER)?,
        Expect::IffLimitHit,
        "the actuator lags",
    );
    push(
        v,
        id,
        t,
        "specimen 50% softer",
        plan(FaultKind::StiffnessChange(0.5), k, FOREVER)?,
        Expect::IffLimitHit,
        "the specimen changes; FE + ATS follows it",
    );
    push(
        v,
        id,
        t,
        "overrun 4 ticks",
        Injection {
            faults: FaultPlan::none(),
            overruns: Some((k, 4)),
        },
        Expect::Trip(&[R::Overrun]),
        "missed deadlines",
    );
    Ok(())
}

/// Everything the runs share: the record, the references, the model.
pub struct Bench {
    ag: Vec<f64>,
    reference: Vec<f64>,
    lr: rths_core::metamodel::LrParams,
    delay_steps: usize,
}

impl Bench {
    /// El Centro at 2048 Hz, its pure FE reference and the shipped LR model.
    pub fn el_centro() -> Result<Self, FaultsError> {
        let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
        let reference = crate::studies::study::reference_mm(&ag, 1.0)
            .map_err(|e| FaultsError::Reference(e.to_string()))?;
        let model =
            ModelFile::from_json(SHIPPED_LR).map_err(|e| FaultsError::Model(e.to_string()))?;
        let lr = crate::machinery::models::lr_params(&model)
            .map_err(|e| FaultsError::Model(e.to_string()))?;
        Ok(Self {
            ag,
            reference,
            lr,
            delay_steps: model.delay_steps,
        })
    }

    fn setup(&self, id: ScenarioId) -> ScenarioSetup<'_> {
        ScenarioSetup {
            id,
            ground_accel_mm_s2: &self.ag,
            reference_mm: &self.reference,
            rig: crate::machinery::reference::rig_config(
                Preset::UnrCompact,
                Specimen::Linear,
                1.0,
                1,
            ),
            stiffness_factor: 1.0,
            lr: Some(self.lr),
            rnn: None,
            lrx: None,
            delay_steps: self.delay_steps,
        }
    }

    /// Run one case.
    pub fn run_case(&self, case: &FaultCase) -> Result<CaseResult, FaultsError> {
        let lim = Limits::paper_actuator();
        let step_tol = lim.max_step_mm() * (1.0 + 1e-9);
        let fault_tol = lim.fault_step_mm() * (1.0 + 1e-9);
        let mut prev_cmd = 0.0_f64;
        let mut prev_servo = 0.0_f64;
        let (mut peak_jump, mut peak_servo_jump, mut peak_cmd) = (0.0_f64, 0.0_f64, 0.0_f64);
        let mut envelope = true;
        let mut ramp_ok = true;
        let mut tripped_at: Option<usize> = None;
        let mut last_cmd = 0.0;
        let start_k = tick(case.start_s) as usize;
        // Ground truth up to the trip: the largest excess over each limit (negative: below it).
        let mut excess = f64::NEG_INFINITY;
        let stop = scenario::simulate_observed(
            &self.setup(case.scenario),
            &case.injection,
            |r: &TickRow| {
                if r.k >= start_k && tripped_at.is_none() && r.true_disp_mm.is_finite() {
                    let fe = (r.true_disp_mm - r.command_mm).abs() - lim.following_error_mm();
                    let force = r.true_force_kn.abs() - lim.force_kn();
                    let stroke = r.true_disp_mm.abs() - lim.stroke_mm();
                    excess = excess.max(fe).max(force).max(stroke);
                }
                let c = r.next_command_mm;
                let d = (c - prev_cmd).abs();
                peak_jump = peak_jump.max(d);
                peak_cmd = peak_cmd.max(c.abs());
                if !(c.is_finite() && c.abs() <= lim.stroke_mm() && d <= step_tol) {
                    envelope = false;
                }
                if r.servo_command_mm.is_finite() {
                    peak_servo_jump = peak_servo_jump.max((r.servo_command_mm - prev_servo).abs());
                    prev_servo = r.servo_command_mm;
                }
                if let State::Fault(_) = r.state {
                    if tripped_at.is_none() {
                        tripped_at = Some(r.k);
                    }
                    if d > fault_tol {
                        ramp_ok = false;
                    }
                }
                prev_cmd = c;
                last_cmd = c;
            },
        )?;
        // After a trip the command must end at the safe position (0 mm, where the test was armed):
        // every case leaves at least 15 s after the fault, far more than the longest ramp (~1.3 s).
        if tripped_at.is_some() && last_cmd != 0.0 {
            ramp_ok = false;
        }
        let reason = stop.as_ref().map(|s| s.0.clone());
        let detected = stop.is_some();
        let time_to_trip_ms = stop.as_ref().map(|s| (s.1 - case.start_s) * 1e3);
        let outcome_ok = match case.expect {
            Expect::NoTrip => !detected,
            Expect::Either(rs) => reason
                .as_deref()
                .is_none_or(|r| rs.iter().any(|x| format!("{x:?}") == r)),
            Expect::IffLimitHit => {
                let limit_reason = reason.as_deref().is_some_and(|r| {
                    [R::FollowingError, R::Force, R::MeasuredStroke]
                        .iter()
                        .any(|x| format!("{x:?}") == r)
                });
                if excess > ORACLE_MARGIN {
                    limit_reason
                } else if excess < -ORACLE_MARGIN {
                    !detected
                } else {
                    !detected || limit_reason
                }
            }
            Expect::Trip(rs) => reason
                .as_deref()
                .is_some_and(|r| rs.iter().any(|x| format!("{x:?}") == r)),
        };
        Ok(CaseResult {
            case: case.name.clone(),
            scenario: case.scenario.to_string(),
            start_s: case.start_s,
            expected: case.expect.label(),
            detected,
            reason,
            time_to_trip_ms,
            peak_jump_mm: peak_jump,
            peak_servo_jump_mm: peak_servo_jump,
            peak_command_mm: peak_cmd,
            envelope_kept: envelope,
            ramp_ok,
            truth_excess: excess,
            pass: outcome_ok && envelope && ramp_ok,
            why: case.why.to_string(),
        })
    }
}

/// Build and run the whole matrix.
pub fn run_matrix() -> Result<Matrix, FaultsError> {
    let bench = Bench::el_centro()?;
    let lim = Limits::paper_actuator();
    let cases = cases()?
        .iter()
        .map(|c| bench.run_case(c))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Matrix {
        stroke_limit_mm: lim.stroke_mm(),
        rate_limit_mm: lim.max_step_mm(),
        fault_step_mm: lim.fault_step_mm(),
        cases,
    })
}

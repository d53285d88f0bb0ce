//! Tests of [`crate::supervisor`].

use super::*;

fn ok(d: f64, f: f64) -> Result<Sample, ErrorKind> {
    Ok(Sample {
        disp_mm: d,
        force_kn: f,
    })
}

fn running() -> Supervisor {
    let mut s = Supervisor::new(Limits::paper_actuator());
    s.arm().unwrap();
    s.start().unwrap();
    s
}

#[test]
fn lifecycle_and_end_ramp() {
    let mut s = Supervisor::new(Limits::paper_actuator());
    assert_eq!(s.start(), Err(InvalidTransition { from: State::Idle }));
    s.arm().unwrap();
    s.start().unwrap();
    let mut x = 0.0;
    for i in 0..2000 {
        x = 5.0 * libm::sin(i as f64 * 0.01);
        let d = s.tick(x, ok(x, 1.0), false);
        assert_eq!(d.command_mm, x);
    }
    s.finish().unwrap();
    let step = 10.0 * DT_S;
    let mut prev = s.output_mm();
    let mut n = 0;
    while s.state() == State::RampDown {
        // The actuator follows the command; the request is ignored while ramping down.
        let d = s.tick(123.0, ok(prev, 0.0), false);
        assert!((d.command_mm - prev).abs() <= step * (1.0 + 1e-12));
        prev = d.command_mm;
        n += 1;
    }
    assert_eq!(s.state(), State::Done);
    assert_eq!(s.output_mm(), 0.0);
    assert!(n as f64 >= x.abs() / step - 1.0);
}

#[test]
fn every_interlock_trips_and_ramps_to_the_safe_position() {
    type Case = (fn(&mut Supervisor) -> Decision, FaultReason);
    let cases: [Case; 7] = [
        (
            |s| s.tick(f64::NAN, ok(2.0, 0.0), false),
            FaultReason::NonFiniteCommand,
        ),
        (
            |s| s.tick(2.0, ok(f64::INFINITY, 0.0), false),
            FaultReason::NonFiniteSample,
        ),
        (
            |s| s.tick(2.0, ok(30.0, 0.0), false),
            FaultReason::MeasuredStroke,
        ),
        (|s| s.tick(2.0, ok(2.0, 40.0), false), FaultReason::Force),
        (
            |s| s.tick(30.0, ok(2.0, 0.0), false),
            FaultReason::CommandStroke,
        ),
        (
            |s| s.tick(3.0, ok(2.0, 0.0), false),
            FaultReason::CommandVelocity,
        ),
        (
            |s| {
                let mut d = s.tick(2.0, Err(ErrorKind::Timeout), false);
                for _ in 0..10 {
                    d = s.tick(2.0, Err(ErrorKind::Timeout), false);
                }
                d
            },
            FaultReason::SensorTimeout,
        ),
    ];
    for (f, reason) in cases {
        let mut s = running();
        // Walk to 2 mm safely.
        let mut x: f64 = 0.0;
        while x < 2.0 {
            x = (x + 0.1).min(2.0);
            s.tick(x, ok(x, 0.0), false);
        }
        let d = f(&mut s);
        assert_eq!(d.state, State::Fault(reason));
        let step = s.limits().fault_step_mm();
        // (The sensor-timeout case trips on its 8th error and has ramped 3 ticks by its 11th.)
        assert!(
            d.command_mm <= 2.0 && 2.0 - d.command_mm <= 4.0 * step,
            "{reason:?}"
        );
        // A smooth, monotonic ramp at the fault rate back to where the test was armed (0 mm),
        // whatever the sensors say meanwhile; it takes 2 mm / (20 mm/s) = 0.1 s.
        let mut prev = d.command_mm;
        let mut ticks = 0;
        for _ in 0..5000 {
            let d = s.tick(f64::NAN, ok(f64::NAN, 0.0), false);
            assert!(d.command_mm.is_finite());
            assert!(d.command_mm <= prev && prev - d.command_mm <= step * (1.0 + 1e-12));
            if d.command_mm != prev {
                ticks += 1;
            }
            prev = d.command_mm;
        }
        assert_eq!(s.output_mm(), s.safe_position_mm(), "{reason:?}");
        assert_eq!(s.safe_position_mm(), 0.0);
        assert!(
            (200..=206).contains(&ticks),
            "{reason:?}: ramp of {ticks} ticks"
        );
    }
}

#[test]
fn overruns_counted_and_trip_after_n_consecutive() {
    let mut s = running();
    for _ in 0..3 {
        s.tick(0.0, ok(0.0, 0.0), true);
    }
    s.tick(0.0, ok(0.0, 0.0), false);
    assert_eq!(s.state(), State::Running);
    assert_eq!(s.total_overruns(), 3);
    for _ in 0..4 {
        s.tick(0.0, ok(0.0, 0.0), true);
    }
    assert_eq!(s.state(), State::Fault(FaultReason::Overrun));
}

#[test]
fn emergency_stop_and_abort() {
    let mut s = running();
    s.emergency_stop();
    assert_eq!(s.state(), State::Fault(FaultReason::EmergencyStop));
    s.abort();
    assert_eq!(s.state(), State::Fault(FaultReason::EmergencyStop));
    let mut s = running();
    s.abort();
    assert_eq!(s.state(), State::RampDown);
}

#[test]
fn limits_validation() {
    let d = DT_S;
    assert!(Limits::new(25.0, 300.0, 30.0, 8, 4, 20.0, 10.0, d).is_ok());
    assert!(Limits::new(25.0, 300.0, 30.0, 0, 4, 20.0, 10.0, d).is_err());
    assert!(Limits::new(25.0, 300.0, 30.0, 8, 4, 400.0, 10.0, d).is_err());
    assert!(Limits::new(f64::NAN, 300.0, 30.0, 8, 4, 20.0, 10.0, d).is_err());
}

proptest::proptest! {
    /// Whatever the inputs, the output is finite, within the stroke limit and never jumps.
    #[test]
    fn output_never_jumps(
        reqs in proptest::collection::vec(
            proptest::prop_oneof![-40.0..40.0f64, proptest::strategy::Just(f64::NAN),
                proptest::strategy::Just(f64::INFINITY)], 1..400),
        errs in proptest::collection::vec(proptest::bool::weighted(0.1), 400),
    ) {
        let mut s = running();
        let mut prev = 0.0;
        for (i, r) in reqs.iter().enumerate() {
            let sample = if errs[i] { Err(ErrorKind::Timeout) } else { ok(*r * 0.5, 1.0) };
            let d = s.tick(*r, sample, false);
            proptest::prop_assert!(d.command_mm.is_finite());
            proptest::prop_assert!(d.command_mm.abs() <= s.limits().stroke_mm());
            proptest::prop_assert!((d.command_mm - prev).abs() <= s.limits().max_step_mm() * (1.0 + 1e-12));
            prev = d.command_mm;
        }
    }
}

#[test]
fn following_error_and_implausible_motion_trip() {
    // The actuator does not follow (stuck at 0 while the command walks away; the live sensor's
    // reading still flickers by one code, so it is not a frozen sensor).
    let mut s = running();
    let lim = *s.limits();
    let mut x: f64 = 0.0;
    let mut tripped = None;
    for i in 0..1000 {
        x += 0.1;
        let flicker = if i % 2 == 0 { 0.0 } else { 0.001 };
        let d = s.tick(x, ok(flicker, 0.0), false);
        if let State::Fault(r) = d.state {
            tripped = Some((r, x));
            break;
        }
    }
    let (reason, at) = tripped.unwrap();
    assert_eq!(reason, FaultReason::FollowingError);
    // Checked against the command in force (sent last tick): trips within two 0.1 mm steps.
    assert!(
        at > lim.following_error_mm() && at <= lim.following_error_mm() + 0.2 + 1e-9,
        "tripped at {at}"
    );

    // A reading that jumps 1 mm in one tick: no actuator does that.
    let mut s = running();
    s.tick(0.0, ok(0.0, 0.0), false);
    let d = s.tick(0.0, ok(1.0, 0.0), false);
    assert_eq!(d.state, State::Fault(FaultReason::ImplausibleMotion));

    // After a dropout gap the next sample is not compared across the gap.
    let mut s = running();
    s.tick(0.0, ok(0.0, 0.0), false);
    for _ in 0..5 {
        s.tick(0.0, Err(ErrorKind::Timeout), false);
    }
    let d = s.tick(0.0, ok(0.5, 0.0), false);
    assert_eq!(d.state, State::Running);
}

#[test]
fn arm_at_the_measured_position_and_guarded_reset() {
    let mut s = Supervisor::new(Limits::paper_actuator());
    assert!(s.arm_at(f64::NAN).is_err());
    assert!(s.arm_at(30.0).is_err());
    assert_eq!(s.state(), State::Idle);
    s.arm_at(3.0).unwrap();
    assert_eq!((s.output_mm(), s.safe_position_mm()), (3.0, 3.0));
    // Armed at 3 mm with the actuator there: holds 3 mm, no step.
    assert_eq!(s.tick(0.0, ok(3.0, 0.0), false).command_mm, 3.0);
    assert_eq!(
        s.reset(),
        Err(Busy {
            state: State::Armed
        })
    );
    s.start().unwrap();
    s.tick(3.1, ok(3.0, 0.0), false);
    s.emergency_stop();
    assert!(s.reset().is_err(), "the fault ramp is still moving");
    while !s.at_rest() {
        s.tick(0.0, ok(s.output_mm(), 0.0), false);
    }
    assert_eq!(s.output_mm(), 3.0, "ramped back to where it was armed");
    assert_eq!(s.reset(), Ok(()));
    assert_eq!(
        (s.state(), s.output_mm()),
        (State::Idle, 3.0),
        "a reset never moves the actuator"
    );
}

#[test]
fn bit_pattern_compare_matches_float_compare() {
    let lims = [1e-9, 0.157, 24.13, 1e9];
    let xs = [
        0.0,
        -0.0,
        1e-12,
        0.157,
        -0.157,
        0.1570001,
        24.13,
        -24.2,
        1e300,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for l in lims {
        for x in xs {
            assert_eq!(super::beyond(x, l), x.abs() > l, "{x} vs {l}");
        }
        assert!(super::beyond(f64::NAN, l));
    }
}

#[test]
fn frozen_lvdt_trips_once_the_command_moved_half_a_millimetre() {
    let lim = Limits::paper_actuator();
    assert_eq!(lim.frozen_sensor_mm(), FROZEN_SENSOR_MM);
    // The actuator follows a ramp at 0.1 mm/tick; then the LVDT sticks at its last value.
    let mut s = running();
    let mut cmd = 0.0;
    for _ in 0..20 {
        cmd += 0.1;
        let d = s.tick(cmd, ok(cmd - 0.05, 0.0), false);
        assert_eq!(d.state, State::Running);
    }
    let stuck = cmd - 0.05;
    // The command in force when the reading last changed (the last ramp tick's, before its step).
    let at_stick = s.output_mm() - 0.1;
    let mut tripped = None;
    for _ in 0..40 {
        cmd += 0.1;
        let in_force = s.output_mm();
        let d = s.tick(cmd, ok(stuck, 0.0), false);
        if let State::Fault(r) = d.state {
            tripped = Some((r, in_force));
            break;
        }
    }
    let (reason, out) = tripped.unwrap();
    assert_eq!(reason, FaultReason::FrozenSensor);
    // Trips on the first tick the command in force is more than 0.5 mm from the one in force when
    // the reading last changed.
    let moved = out - at_stick;
    assert!(moved > 0.5 && moved <= 0.5 + 0.1 + 1e-6, "moved {moved}");
}

#[test]
fn an_unchanged_reading_with_a_still_command_is_not_frozen() {
    // At rest (or holding), a constant reading is what a healthy sensor without noise gives.
    let mut s = running();
    for _ in 0..10_000 {
        let d = s.tick(1.0e-3, ok(0.0, 0.0), false);
        assert_eq!(d.state, State::Running);
    }
    // A command creeping by less than the limit in all while the reading stays: no trip either.
    let mut s = running();
    let mut cmd = 0.0;
    for _ in 0..4_000 {
        cmd += 1e-4;
        let d = s.tick(cmd, ok(0.0, 0.0), false);
        assert_eq!(d.state, State::Running);
    }
    // Unbounded limits (pure runs: the sample is a constant placeholder) never see a frozen sensor.
    let mut s = Supervisor::new(Limits::unbounded());
    s.arm().unwrap();
    s.start().unwrap();
    for i in 0..2_000 {
        let d = s.tick(i as f64, ok(0.0, 0.0), false);
        assert_eq!(d.state, State::Running);
    }
}

#[test]
fn fault_reason_table_round_trips_with_unique_codes_and_names() {
    for (reason, code, name) in FaultReason::ALL {
        assert_eq!(reason.code(), code);
        assert_eq!(reason.name(), name);
        assert_eq!(FaultReason::from_code(code), Some(reason));
    }
    for (i, (a, ca, na)) in FaultReason::ALL.iter().enumerate() {
        for (b, cb, nb) in &FaultReason::ALL[i + 1..] {
            assert_ne!(a, b);
            assert_ne!(ca, cb);
            assert_ne!(na, nb);
        }
    }
    // The wire codes of the link's first release (never renumbered).
    assert_eq!(FaultReason::MeasuredStroke.code(), 0);
    assert_eq!(FaultReason::EmergencyStop.code(), 8);
    assert_eq!(FaultReason::FrozenSensor.code(), 11);
    assert_eq!(FaultReason::from_code(12), None);
}

#[test]
fn paper_actuator_end_ramp_rate() {
    assert_eq!(Limits::paper_actuator().end_ramp_rate_mm_s(), 10.0);
}

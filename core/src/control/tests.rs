//! Tests of [`crate::control`].

use super::*;
use crate::integrator::Newmark;
use crate::metamodel::LrParams;
use crate::params::DT_S;

fn config(feedback: FeedbackSource) -> ControlConfig {
    ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        feedback,
        Limits::paper_actuator(),
    )
    .unwrap()
}

fn fe(feedback: FeedbackSource) -> Controller {
    let a = Analytical::Fe(FeModel::new(Prototype::paper(), DT_S).unwrap());
    let mut c = Controller::new(config(feedback), a, Compensator::None);
    c.supervisor_mut().arm().unwrap();
    c.supervisor_mut().start().unwrap();
    c
}

/// The sample of a perfect actuator standing at the command in force (a live sensor: with a
/// constant placeholder the supervisor would see a frozen LVDT under a moving command).
fn at_command(c: &Controller) -> Result<Sample, ErrorKind> {
    Ok(Sample {
        disp_mm: c.supervisor().output_mm(),
        force_kn: 0.0,
    })
}

fn ground(k: usize) -> f64 {
    let t = k as f64 * DT_S;
    2000.0 * libm::sin(2.0 * core::f64::consts::PI * 1.3 * t) * (1.0 - libm::exp(-t))
}

#[test]
fn fe_with_own_feedback_is_the_pure_model() {
    // target(k+1) from tick k must equal the pure model's response at step k+1: exactly (Chang on
    // the whole structure) and to integration accuracy (Newmark).
    let p = Prototype::paper();
    let mut c = fe(FeedbackSource::OwnDelayed { delay_steps: 0 });
    let pure = LinearStructure::prototype_pure(&p).unwrap();
    let mut nm = Newmark::new(pure, DT_S).unwrap();
    let mut ch = Chang::new(pure, DT_S).unwrap();
    nm.reset(ground(0));
    ch.reset(ground(0));
    let (mut worst_ch, mut worst_nm): (f64, f64) = (0.0, 0.0);
    for k in 0..6000 {
        let out = c.tick(ground(k), at_command(&c), false);
        let x_nm = nm.step(ground(k + 1)).disp[0];
        let x_ch = ch.next_displacement()[0];
        ch.advance(ground(k + 1), &Vector::<1>::zeros());
        worst_ch = worst_ch.max((out.target_mm - p.brace_disp_mm(x_ch)).abs());
        worst_nm = worst_nm.max((out.target_mm - p.brace_disp_mm(x_nm)).abs());
        assert_eq!(out.state, State::Running);
        assert_eq!(out.command_mm, out.target_mm);
    }
    assert!(worst_ch < 1e-9, "vs Chang {worst_ch}");
    assert!(worst_nm < 1e-4, "vs Newmark {worst_nm}");
}

#[test]
fn lr_uses_its_own_prediction_delayed() {
    // θ2 = 1 only: x̂(k+1) = x_fb(k) = x̂(k−3) plus a bias θ0 = 0.01.
    let lr = Lr::new(LrParams::new([0.01, 0.0, 1.0, 0.0, 0.0, 0.0]).unwrap());
    let mut c = Controller::new(
        config(FeedbackSource::OwnDelayed { delay_steps: 3 }),
        Analytical::Lr(lr),
        Compensator::None,
    );
    c.supervisor_mut().arm().unwrap();
    c.supervisor_mut().start().unwrap();
    let outs: [f64; 9] = core::array::from_fn(|_| c.tick(0.0, at_command(&c), false).target_mm);
    // x_fb(k) = x̂(k−3): ticks 0..3 see x̂(−3..=0) = 0, ticks 4..7 see x̂(1..=4) = 0.01, ...
    let expect = [0.01, 0.01, 0.01, 0.01, 0.02, 0.02, 0.02, 0.02, 0.03];
    for (o, e) in outs.iter().zip(expect) {
        assert!((o - e).abs() < 1e-12, "{outs:?}");
    }
}

#[test]
fn measured_feedback_is_scaled_to_the_prototype() {
    // θ3 = 1e-3: x̂ = F_fb/1000 = the load-cell force in kN (force scale 1000).
    let lr = Lr::new(LrParams::new([0.0, 0.0, 0.0, 1e-3, 0.0, 0.0]).unwrap());
    let mut c = Controller::new(
        config(FeedbackSource::Measured),
        Analytical::Lr(lr),
        Compensator::None,
    );
    c.supervisor_mut().arm().unwrap();
    c.supervisor_mut().start().unwrap();
    let s = Sample {
        disp_mm: 0.0,
        force_kn: 0.05,
    };
    let out = c.tick(0.0, Ok(s), false);
    assert!((out.target_mm - 0.05).abs() < 1e-12);
}

#[test]
fn bad_inputs_trip_safely_and_hold_the_sample() {
    let mut c = fe(FeedbackSource::Measured);
    for k in 0..500 {
        c.tick(ground(k), at_command(&c), false);
    }
    let before = c.supervisor().output_mm();
    let out = c.tick(f64::NAN, at_command(&c), false);
    assert!(matches!(out.state, State::Fault(_)));
    assert!((out.command_mm - before).abs() <= c.supervisor().limits().max_step_mm());

    let mut c = fe(FeedbackSource::Measured);
    let out = c.tick(
        1.0,
        Ok(Sample {
            disp_mm: f64::NAN,
            force_kn: 0.0,
        }),
        false,
    );
    assert!(out.sample_held);
    assert_eq!(c.held_samples(), 1);
    assert!(matches!(
        out.state,
        State::Fault(crate::supervisor::FaultReason::NonFiniteSample)
    ));
}

#[test]
fn parameters_swap_only_at_rest_and_never_move_the_actuator() {
    use crate::supervisor::Busy;
    let lr = || Analytical::Lr(Lr::new(LrParams::new([0.0; 6]).unwrap()));
    let mut c = fe(FeedbackSource::OwnDelayed { delay_steps: 0 });
    // Run until the structure has moved well away from zero.
    let mut k = 0;
    while c.supervisor().output_mm().abs() < 3.0 {
        c.tick(ground(k) * 5.0, at_command(&c), false);
        k += 1;
    }
    assert_eq!(
        c.set_analytical(lr()),
        Err(Busy {
            state: State::Running
        })
    );
    assert_eq!(
        c.reset(),
        Err(Busy {
            state: State::Running
        })
    );
    c.supervisor_mut().emergency_stop();
    let mut prev = c.supervisor().output_mm();
    // Mid fault ramp: refused, and the ramp goes on undisturbed.
    let out = c.tick(0.0, at_command(&c), false);
    assert!(matches!(
        c.set_analytical(lr()),
        Err(Busy {
            state: State::Fault(_)
        })
    ));
    assert!(
        (out.command_mm - prev).abs() <= c.supervisor().limits().fault_step_mm() * (1.0 + 1e-12)
    );
    prev = out.command_mm;
    while !c.supervisor().at_rest() {
        let out = c.tick(0.0, at_command(&c), false);
        assert!(
            (out.command_mm - prev).abs()
                <= c.supervisor().limits().fault_step_mm() * (1.0 + 1e-12)
        );
        prev = out.command_mm;
    }
    // At rest at the safe position: the swap is allowed and holds the command where it is.
    assert_eq!(c.set_analytical(lr()), Ok(()));
    assert_eq!(c.supervisor().state(), State::Idle);
    assert_eq!(c.supervisor().output_mm(), prev);
    assert_eq!(c.reset(), Ok(()));
    assert!(ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::OwnDelayed {
            delay_steps: MAX_DELAY_STEPS + 1
        },
        Limits::paper_actuator()
    )
    .is_err());
}

proptest::proptest! {
    /// Any ground acceleration and sensor values, NaN and infinities included: no panic, and the
    /// command is finite, within the stroke and never jumps.
    #[test]
    fn never_panics_never_jumps(
        inputs in proptest::collection::vec(
            (proptest::prop_oneof![-1e5..1e5f64, proptest::strategy::Just(f64::NAN),
                proptest::strategy::Just(f64::NEG_INFINITY)],
             proptest::prop_oneof![-30.0..30.0f64, proptest::strategy::Just(f64::NAN)],
             proptest::prop_oneof![-40.0..40.0f64, proptest::strategy::Just(f64::INFINITY)],
             proptest::bool::weighted(0.05)),
            1..300),
    ) {
        let mut c = fe(FeedbackSource::Measured);
        let mut prev = 0.0;
        for (ag, d, f, err) in inputs {
            let sample = if err { Err(ErrorKind::Timeout) } else { Ok(Sample { disp_mm: d, force_kn: f }) };
            let out = c.tick(ag, sample, false);
            let lim = c.supervisor().limits();
            proptest::prop_assert!(out.command_mm.is_finite());
            proptest::prop_assert!(out.command_mm.abs() <= lim.stroke_mm());
            proptest::prop_assert!((out.command_mm - prev).abs() <= lim.max_step_mm() * (1.0 + 1e-12));
            prev = out.command_mm;
        }
    }
}

fn measured_fe(config: ControlConfig) -> Controller {
    let a = Analytical::Fe(FeModel::new(Prototype::paper(), DT_S).unwrap());
    let mut c = Controller::new(config, a, Compensator::None);
    c.supervisor_mut().arm().unwrap();
    c.supervisor_mut().start().unwrap();
    c
}

#[test]
fn by_default_no_force_correction_and_the_next_target() {
    let c = config(FeedbackSource::Measured);
    assert!(c.force_correction().is_none());
    assert_eq!(c.compensator_target(), CompensatorTarget::Next);
    // No correction given as all zeros is no term at all.
    assert!(c
        .with_force_correction(ForceCorrection::NONE)
        .force_correction()
        .is_none());
}

#[test]
fn the_compensator_is_given_the_target_of_its_timing() {
    let mut next = measured_fe(config(FeedbackSource::Measured));
    let mut current = measured_fe(
        config(FeedbackSource::Measured).with_compensator_target(CompensatorTarget::Current),
    );
    // The target in force at k: the one produced at k − 1 (0 at rest).
    let mut in_force = 0.0_f64;
    let mut moved = false;
    for k in 0..3000 {
        // A perfect actuator at the command in force, the specimen the prototype's brace.
        let spring = |c: &Controller| {
            let x = c.supervisor().output_mm();
            Ok(Sample {
                disp_mm: x,
                force_kn: SpecimenScale::default()
                    .specimen_force_kn(Prototype::paper().brace_force_kn(x)),
            })
        };
        let a = next.tick(ground(k), spring(&next), false);
        let b = current.tick(ground(k), spring(&current), false);
        assert_eq!(a.state, State::Running);
        assert_eq!(b.state, State::Running);
        assert_eq!(a.command_mm.to_bits(), a.target_mm.to_bits());
        assert_eq!(b.command_mm.to_bits(), in_force.to_bits(), "tick {k}");
        moved |= b.target_mm != in_force;
        in_force = b.target_mm;
    }
    assert!(moved);
}

#[test]
fn the_force_correction_feeds_the_model_the_corrected_force() {
    let corr = ForceCorrection::new(1.2, 0.01, 1e-5, DT_S).unwrap();
    let measured = config(FeedbackSource::Measured);
    let mut with = measured_fe(measured.with_force_correction(corr));
    let mut by_hand = measured_fe(measured);
    let scale = SpecimenScale::default();
    // d̂_k, d̂_{k−1}, d̂_{k−2} at the rig.
    let mut d = [0.0; 3];
    let mut differs = false;
    for k in 0..3000 {
        // A rig that falls short of the command, the specimen a spring.
        let x = 0.98 * with.supervisor().output_mm();
        let f = 1.2 * x;
        let a = with.tick(
            ground(k),
            Ok(Sample {
                disp_mm: x,
                force_kn: f,
            }),
            false,
        );
        let f_corr = corr.force_kn(f, x, d);
        differs |= f_corr != f;
        let b = by_hand.tick(
            ground(k),
            Ok(Sample {
                disp_mm: x,
                force_kn: f_corr,
            }),
            false,
        );
        assert_eq!(a.state, State::Running);
        assert_eq!(a.target_mm.to_bits(), b.target_mm.to_bits(), "tick {k}");
        d = [scale.specimen_disp_mm(a.target_mm), d[0], d[1]];
    }
    assert!(differs);
}

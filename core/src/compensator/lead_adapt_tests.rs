//! The lead's online correction: it converges on a residual gain and delay, holds its bounds and
//! its state under bad or frozen sensor input, and leaves a fixed lead exactly as it was.

use super::*;
use proptest::prelude::*;

/// Lead = identity (u = v), so the "compensated actuator" is the plant itself.
fn identity_lead(adapt: Option<LeadAdaptParams>) -> Lead {
    let mut w = [0.0; LEAD_TAPS];
    w[0] = 1.0;
    Lead::new(LeadParams::new(w, 1).unwrap().with_adaptation(adapt))
}

/// Target: three sines, 0.7-2.9 Hz, ~5 mm, at 2048 Hz.
fn target(k: usize) -> f64 {
    let t = k as f64 / 2048.0;
    let tau = core::f64::consts::TAU;
    3.0 * libm::sin(tau * 0.7 * t)
        + 1.5 * libm::sin(tau * 1.9 * t + 1.0)
        + 0.8 * libm::sin(tau * 2.9 * t + 2.0)
}

/// Run `ticks` against x_m(k+1) = g·u(k − delay); RMS of x_m(k+1) − x_t(k) over the last 4 s.
fn track(lead: &mut Lead, g: f64, delay: usize, ticks: usize) -> f64 {
    let mut u_hist = std::vec![0.0; ticks + delay + 2];
    let (mut xm, mut sq, mut n) = (0.0, 0.0, 0usize);
    let mut pending_target = 0.0;
    for k in 0..ticks {
        // x_m(k) answers u(k − 1 − delay).
        xm = if k > delay {
            g * u_hist[k - 1 - delay]
        } else {
            0.0
        };
        if k + 4 * 2048 >= ticks && k > 0 {
            sq += (xm - pending_target) * (xm - pending_target);
            n += 1;
        }
        let xt = target(k);
        u_hist[k] = lead.step(xt, xm).unwrap();
        pending_target = xt;
    }
    let _ = xm;
    libm::sqrt(sq / n as f64)
}

#[test]
fn adaptation_converges_on_a_residual_gain_and_delay() {
    let (g, delay) = (0.93, 4);
    let mut fixed = identity_lead(None);
    let mut adaptive = identity_lead(Some(LeadAdaptParams::new(4096.0).unwrap()));
    let ticks = 30 * 2048;
    let e_fixed = track(&mut fixed, g, delay, ticks);
    let e_adapt = track(&mut adaptive, g, delay, ticks);
    let s = adaptive.adaptation_state();
    // The first-order inverse of g·e^{−sδ}: b0 = 1/g, b1 = δ/g (ticks).
    assert!((f64::from(s.gain) - 1.0 / g).abs() < 0.01 / g, "{s:?}");
    assert!(
        (f64::from(s.delay_ticks) - delay as f64 / g).abs() < 0.1 * delay as f64 / g,
        "{s:?}"
    );
    assert!(
        e_adapt < 0.1 * e_fixed,
        "tracking RMS {e_adapt} mm vs fixed {e_fixed} mm"
    );
    // Without adaptation the state never moves.
    assert_eq!(*fixed.adaptation_state(), LeadAdaptState::default());
}

#[test]
fn a_fixed_lead_steps_exactly_as_it_compensates() {
    let mut w = [0.0; LEAD_TAPS];
    w[0] = 1.7;
    w[1] = -0.9;
    w[5] = 0.2;
    let p = LeadParams::new(w, 3).unwrap();
    let (mut a, mut b) = (Lead::new(p), Lead::new(p));
    for k in 0..500 {
        let x = target(k);
        assert_eq!(
            a.step(x, 0.3 * x).unwrap().to_bits(),
            b.compensate(x).unwrap().to_bits()
        );
    }
}

#[test]
fn bad_input_is_refused_and_a_frozen_sensor_freezes_the_fit() {
    let mut l = identity_lead(Some(LeadAdaptParams::new(2048.0).unwrap()));
    track(&mut l, 0.95, 3, 10 * 2048);
    let before = l;
    for (t, m) in [
        (f64::NAN, 0.0),
        (0.0, f64::NAN),
        (f64::INFINITY, 0.0),
        (0.0, 2.0 * MAX_ABS_INPUT_MM),
    ] {
        assert!(l.step(t, m).is_err());
        assert_eq!(l, before);
    }
    // The LVDT sticks while the target keeps moving: the velocity sum decays below the threshold
    // and the coefficients stop moving, inside their bounds, the command finite.
    let stuck = 2.5;
    let mut last = *l.adaptation_state();
    let mut frozen_from = None;
    for k in 0..20 * 2048 {
        let u = l.step(target(k), stuck).unwrap();
        assert!(u.is_finite());
        let s = *l.adaptation_state();
        assert!((LEAD_ADAPT_GAIN_BOUNDS[0]..=LEAD_ADAPT_GAIN_BOUNDS[1]).contains(&s.gain));
        let [lo, hi] = LEAD_ADAPT_DELAY_BOUNDS_TICKS;
        assert!((lo..=hi).contains(&s.delay_ticks));
        if s.updates == last.updates && frozen_from.is_none() {
            frozen_from = Some(k);
        }
        if frozen_from.is_some() && k > 12 * 2048 {
            assert_eq!(s.updates, last.updates, "still adapting at tick {k}");
        }
        last = s;
    }
    l.reset();
    assert_eq!(*l.adaptation_state(), LeadAdaptState::default());
}

#[test]
fn settings_are_validated() {
    assert!(LeadAdaptParams::new(f64::NAN).is_err());
    assert!(LeadAdaptParams::new(31.0).is_err());
    assert!(LeadAdaptParams::new(2.0e7).is_err());
    assert_eq!(LeadAdaptParams::new(4096.0).unwrap().ticks(), 4096.0);
}

fn any_input() -> impl Strategy<Value = f64> {
    prop_oneof![
        -30.0f64..30.0,
        Just(f64::NAN),
        Just(f64::INFINITY),
        -2.0e6f64..2.0e6,
        Just(0.0),
    ]
}

proptest! {
    /// Whatever the sensor and the target do, the command is finite or refused (state kept), and
    /// each coefficient stays inside its bounds and moves at most its step per tick.
    #[test]
    fn the_bounds_hold(ticks in 32.0f64..10_000.0,
                       seq in proptest::collection::vec((any_input(), any_input()), 1..400)) {
        let mut l = identity_lead(Some(LeadAdaptParams::new(ticks).unwrap()));
        for (t, m) in seq {
            let before = l;
            match l.step(t, m) {
                Ok(u) => prop_assert!(u.is_finite()),
                Err(_) => prop_assert_eq!(l, before),
            }
            let (s, p) = (l.adaptation_state(), before.adaptation_state());
            prop_assert!(s.gain >= LEAD_ADAPT_GAIN_BOUNDS[0] && s.gain <= LEAD_ADAPT_GAIN_BOUNDS[1]);
            prop_assert!(s.delay_ticks >= LEAD_ADAPT_DELAY_BOUNDS_TICKS[0]
                && s.delay_ticks <= LEAD_ADAPT_DELAY_BOUNDS_TICKS[1]);
            // The step is taken in f32: allow the rounding of the sum (a few ulps of the value).
            let ulps = |v: f32| 4.0 * f32::EPSILON * v.abs().max(1.0);
            prop_assert!((s.gain - p.gain).abs() <= LEAD_ADAPT_MAX_STEP[0] + ulps(s.gain));
            prop_assert!((s.delay_ticks - p.delay_ticks).abs()
                <= LEAD_ADAPT_MAX_STEP[1] + ulps(s.delay_ticks));
        }
    }
}

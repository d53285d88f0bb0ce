extern crate std;

use super::*;
// The tests check the ATS's internal sums against an exact re-sum.
use super::ats::{regressor, Normal, U_RING, X_RING};
use proptest::prelude::*;
use std::{println, vec::Vec};

const DT: f64 = 1.0 / 2048.0;

/// Synthetic actuator: gain g, pure delay of `delay_steps` ticks (ring buffer), then an exactly
/// discretized first-order lag with time constant `lag_s`. The caller feeds the command of tick k and
/// reads the measurement at tick k+1, which adds one more tick: total pure delay = delay_steps + 1.
struct Plant {
    ring: Vec<f64>,
    pos: usize,
    y: f64,
    e: f64,
    gain: f64,
}

impl Plant {
    fn new(delay_steps: usize, lag_s: f64, gain: f64) -> Self {
        Plant {
            ring: std::vec![0.0; delay_steps.max(1)],
            pos: 0,
            y: 0.0,
            e: libm::exp(-DT / lag_s),
            gain,
        }
    }
    fn step(&mut self, u: f64) -> f64 {
        let delayed = self.ring[self.pos];
        self.ring[self.pos] = u;
        self.pos = (self.pos + 1) % self.ring.len();
        self.y = self.e * self.y + (1.0 - self.e) * self.gain * delayed;
        self.y
    }
}

fn target(k: usize) -> f64 {
    let t = k as f64 * DT;
    let w = 2.0 * core::f64::consts::PI;
    4.0 * libm::sin(w * 0.7 * t)
        + 3.0 * libm::sin(w * 1.9 * t + 0.4)
        + 2.0 * libm::sin(w * 3.4 * t + 1.1)
}

/// Deterministic uniform noise in [−a, a] (LCG), standing in for LVDT noise.
struct Noise(u64);
impl Noise {
    fn next(&mut self, a: f64) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * a
    }
}

struct Run {
    rms_err_tail: f64,
    coeffs: [f64; 3],
    updates: u32,
    skipped: u32,
}

/// 30 s closed loop; tracking error RMS over the last 10 s.
fn run(mut comp: Compensator, delay_steps: usize, lag_s: f64, gain: f64) -> Run {
    let mut plant = Plant::new(delay_steps, lag_s, gain);
    let mut noise = Noise(7);
    let n = 30 * 2048;
    let (mut xm, mut se, mut cnt) = (0.0, 0.0, 0);
    for k in 0..n {
        let xt = target(k);
        if k >= 20 * 2048 {
            se += (xm - target(k - 1)) * (xm - target(k - 1));
            cnt += 1;
        }
        let u = comp.compensate(xt, xm + noise.next(0.01)).unwrap();
        // Measured at the next tick; compare it with the target it should follow (this tick's).
        xm = plant.step(u);
    }
    let (coeffs, updates, skipped) = match &comp {
        Compensator::Ats(a) => (a.coefficients(), a.updates(), a.skipped_updates()),
        _ => ([1.0, 0.0, 0.0], 0, 0),
    };
    Run {
        rms_err_tail: libm::sqrt(se / cnt as f64),
        coeffs,
        updates,
        skipped,
    }
}

fn paper_ats(expected_delay_s: f64) -> Ats {
    Ats::new(AtsParams::new(AtsConfig::paper(DT, expected_delay_s)).unwrap())
}

#[test]
fn ats_converges_to_plant_delay_and_cuts_tracking_error() {
    // 27 + 1 = 28 ticks = 13.67 ms pure delay (the paper's), 2 ms lag, gain 0.95.
    let (d, lag, g) = (27, 0.002, 0.95);
    let tau = (d + 1) as f64 * DT;
    let none = run(Compensator::None, d, lag, g);
    // Start from a wrong delay guess (5 ms) to show adaptation.
    let ats = run(Compensator::Ats(paper_ats(0.005)), d, lag, g);
    let ratio = ats.rms_err_tail / none.rms_err_tail;
    // Inverse plant (1/g)(1 + s(τ+T) + ...): a0 ≈ 1/g, a1 ≈ (τ+T)/g.
    let a1_expected = (tau + lag) / g;
    println!(
        "ATS: coeffs {:?} (a0 want {:.4}, a1 want {:.5} s), updates {}, skipped {}; \
         rms err none {:.4} mm, ats {:.4} mm, ratio {:.4}",
        ats.coeffs,
        1.0 / g,
        a1_expected,
        ats.updates,
        ats.skipped,
        none.rms_err_tail,
        ats.rms_err_tail,
        ratio
    );
    assert!(
        (ats.coeffs[0] - 1.0 / g).abs() < 0.02 / g,
        "a0 {:?}",
        ats.coeffs
    );
    assert!(
        (ats.coeffs[1] - a1_expected).abs() < 0.05 * a1_expected,
        "a1 {:?}",
        ats.coeffs
    );
    assert!(ratio < 0.1, "ratio {ratio}");
    assert!(ats.updates > 1000);
}

#[test]
fn ats_state_size_fits_the_mcu() {
    let size = core::mem::size_of::<Ats>();
    println!(
        "size_of: Ats {} B, AtsState {} B, Horiuchi {} B, Compensator {} B",
        size,
        core::mem::size_of::<AtsState>(),
        core::mem::size_of::<Horiuchi>(),
        core::mem::size_of::<Compensator>()
    );
    // Two rings (2051 + 2049 f64 = 32.8 KiB) plus filters and sums: well under 34 KiB of the 128 KiB.
    assert!(size < 34 * 1024, "{size}");
    assert!(size > (X_RING + U_RING) * 8);
}

#[test]
fn running_sums_reanchor_after_a_spike() {
    // A huge measured spike enters and leaves the window. A naive add/subtract running sum (kept here,
    // mirroring the implementation minus the shadow) keeps the cancellation residue; the ATS sums are
    // re-anchored to an addition-only sum and must match an exact re-sum of the window afterwards.
    let window = 256;
    let cfg = AtsConfig {
        window,
        ..AtsConfig::paper(DT, 0.01)
    };
    let mut ats = Ats::new(AtsParams::new(cfg).unwrap());
    let exact = |a: &Ats| {
        let mut n = Normal::default();
        for k in 0..window {
            n.add(&regressor(&a.state.xf, k, DT), a.state.uf.back(k), 1.0);
        }
        n
    };
    // Error of each entry relative to sqrt(E_ii·E_jj) of the exact sums (scale-free).
    let rel = |x: &Normal, e: &Normal| {
        let mut worst = 0.0_f64;
        for i in 0..3 {
            for j in 0..3 {
                let scale = libm::sqrt(e.a[i][i] * e.a[j][j]);
                worst = worst.max((x.a[i][j] - e.a[i][j]).abs() / scale);
            }
        }
        worst
    };
    let mut naive = Normal::default();
    let spike_at = 300;
    let (mut worst_ats, mut worst_naive) = (0.0_f64, 0.0_f64);
    for k in 0..4000 {
        let spike = if k == spike_at {
            0.9 * MAX_ABS_INPUT_MM
        } else {
            0.0
        };
        ats.compensate(target(k), target(k) * 0.9 + spike).unwrap();
        naive.add(&regressor(&ats.state.xf, 0, DT), ats.state.uf.back(0), 1.0);
        if k >= window {
            naive.add(
                &regressor(&ats.state.xf, window, DT),
                ats.state.uf.back(window),
                -1.0,
            );
        }
        // The filtered spike rings for < 0.3 s; after it has left, plus one re-anchoring period:
        if k >= spike_at + 600 + 2 * window {
            let e = exact(&ats);
            worst_ats = worst_ats.max(rel(&ats.state.sums, &e));
            worst_naive = worst_naive.max(rel(&naive, &e));
        }
    }
    println!("running sums after a spike: naive add/subtract error {worst_naive:.3e}, re-anchored {worst_ats:.3e}");
    assert!(worst_ats < 1e-9, "{worst_ats}");
    assert!(
        worst_naive > 1e3 * worst_ats,
        "naive {worst_naive} vs {worst_ats}"
    );
}

#[test]
fn condition_guard_skips_pure_sine() {
    // A sampled sine makes the backward-difference ẍ an exact combination of x and ẋ: rank 2.
    let cfg = AtsConfig {
        window: 512,
        ..AtsConfig::paper(DT, 0.01)
    };
    let mut ats = Ats::new(AtsParams::new(cfg).unwrap());
    let w = 2.0 * core::f64::consts::PI * 2.0 * DT;
    for k in 0..(8 * 2048) {
        let x = 5.0 * libm::sin(w * k as f64);
        ats.compensate(x, x).unwrap();
    }
    assert!(ats.is_adapting());
    println!(
        "pure sine: updates {}, skipped {}",
        ats.updates(),
        ats.skipped_updates()
    );
    // Only the filter's start-up transient (well-conditioned, gone after ~0.3 s) may be fitted.
    assert!(ats.skipped_updates() > 800, "{}", ats.skipped_updates());
    assert!(ats.updates() < 60, "{}", ats.updates());
}

#[test]
fn excitation_guard_skips_motionless_fit() {
    // Measured holds at 1 mm (above the threshold): ẋ = ẍ = 0, the normal matrix is singular.
    let cfg = AtsConfig {
        window: 64,
        ..AtsConfig::paper(DT, 0.01)
    };
    let mut ats = Ats::new(AtsParams::new(cfg).unwrap());
    // The 0 -> 1 mm step is a real (filtered) motion for ~0.1 s; let it pass the window.
    for _ in 0..500 {
        ats.compensate(1.0, 1.0).unwrap();
    }
    assert!(ats.is_adapting());
    let (updates, skipped, coeffs) = (ats.updates(), ats.skipped_updates(), ats.coefficients());
    for _ in 0..2000 {
        ats.compensate(1.0, 1.0).unwrap();
    }
    assert_eq!(ats.updates(), updates);
    assert_eq!(ats.skipped_updates() - skipped, 2000 / 16);
    assert_eq!(ats.coefficients(), coeffs);
}

#[test]
fn no_adaptation_below_threshold() {
    let mut ats = paper_ats(0.01);
    for k in 0..8000 {
        ats.compensate(0.01 * target(k), 0.01 * target(k)).unwrap();
    }
    assert!(!ats.is_adapting());
    assert_eq!(ats.updates() + ats.skipped_updates(), 0);
}

#[test]
fn ats_initial_command_and_reset() {
    let mut ats = paper_ats(0.0137);
    let [a0, a1, a2] = ats.coefficients();
    assert_eq!([a0, a1, a2], [1.0, 0.0137, 0.5 * 0.0137 * 0.0137]);
    let u = ats.compensate(0.5, 0.0).unwrap();
    let want = a0 * 0.5 + a1 * 0.5 / DT + a2 * 0.5 / (DT * DT);
    assert!((u - want).abs() < 1e-12 * want.abs());
    let fresh = ats.clone();
    for k in 0..5000 {
        ats.compensate(target(k), 0.9 * target(k)).unwrap();
    }
    ats.reset();
    let mut fresh = fresh;
    fresh.reset();
    assert_eq!(ats, fresh);
    assert_eq!(ats, paper_ats(0.0137));
}

#[test]
fn ats_starts_from_given_initial_values_within_bounds() -> Result<(), crate::params::ParamError> {
    let params = AtsParams::new(AtsConfig::paper(DT, 0.0137))?;
    let given = [1.01, 0.0237, 1.06e-4];
    let mut ats = Ats::new(params.with_initial(given)?);
    assert_eq!(ats.coefficients(), given);
    for k in 0..5000 {
        let _ = ats.compensate(target(k), 0.9 * target(k));
    }
    ats.reset();
    assert_eq!(ats.coefficients(), given);
    for bad in [
        [f64::NAN, 0.01, 0.0],
        [1.5, 0.01, 0.0],
        [1.0, -0.001, 0.0],
        [1.0, 0.01, 0.01],
    ] {
        assert!(params.with_initial(bad).is_err(), "{bad:?}");
    }
    Ok(())
}

#[test]
fn ats_param_validation() {
    let ok = AtsConfig::paper(DT, 0.0137);
    assert_eq!(ok.window, 2048);
    assert!(AtsParams::new(ok).is_ok());
    let bad = [
        AtsConfig { dt_s: 0.0, ..ok },
        AtsConfig {
            expected_delay_s: 0.09,
            ..ok
        },
        AtsConfig {
            expected_delay_s: f64::NAN,
            ..ok
        },
        AtsConfig {
            lower: [1.4, 0.0, 0.0],
            ..ok
        },
        AtsConfig {
            upper: [1.3, f64::INFINITY, 0.0032],
            ..ok
        },
        AtsConfig {
            max_step: [0.2, 0.0, 0.0001],
            ..ok
        },
        AtsConfig { window: 4096, ..ok },
        AtsConfig { window: 2, ..ok },
        AtsConfig {
            update_period: 0,
            ..ok
        },
        AtsConfig {
            filter_order: 5,
            ..ok
        },
        AtsConfig {
            filter_cutoff_hz: 1024.0,
            ..ok
        },
        AtsConfig {
            start_threshold_mm: -1.0,
            ..ok
        },
        AtsConfig {
            max_condition: 1.0,
            ..ok
        },
        // a2 = a1²/2 must also lie inside its bounds.
        AtsConfig {
            upper: [1.3, 0.08, 1e-5],
            ..ok
        },
        AtsConfig {
            min_velocity_rms_mm_s: f64::NAN,
            ..ok
        },
    ];
    for (i, c) in bad.iter().enumerate() {
        assert!(AtsParams::new(*c).is_err(), "case {i}");
    }
}

#[test]
fn refusals_leave_state_untouched() {
    let mut ats = paper_ats(0.0137);
    for k in 0..3000 {
        ats.compensate(target(k), 0.9 * target(k)).unwrap();
    }
    let before = ats.clone();
    for (t, m) in [
        (f64::NAN, 0.0),
        (0.0, f64::NAN),
        (f64::INFINITY, 0.0),
        (0.0, f64::NEG_INFINITY),
        (2e6, 0.0),
        (0.0, -2e6),
    ] {
        assert!(ats.compensate(t, m).is_err());
        assert_eq!(ats, before);
    }
    assert_eq!(
        ats.compensate(f64::NAN, 0.0),
        Err(InputError::NotFinite("target_mm"))
    );
    assert_eq!(
        ats.compensate(0.0, 2e6),
        Err(InputError::OutOfRange("measured_mm"))
    );
}

// ---------------------------------------------------------------------------------------------------
// Horiuchi
// ---------------------------------------------------------------------------------------------------

#[test]
fn horiuchi_exact_for_polynomials_up_to_its_order() {
    let delay = 0.0137;
    for order in 1..=3 {
        let mut h = Horiuchi::new(HoriuchiParams::new(order, delay, DT).unwrap());
        for deg in 0..=order {
            h.reset();
            let p = |t: f64| {
                (0..=deg)
                    .map(|i| (0.7 + i as f64) * libm::pow(t * 10.0, i as f64))
                    .sum::<f64>()
            };
            for k in 0..200 {
                let t = k as f64 * DT;
                let u = h.compensate(p(t)).unwrap();
                if k >= order {
                    let want = p(t + delay);
                    assert!(
                        (u - want).abs() < 1e-9 * want.abs().max(1.0),
                        "n={order} deg={deg} k={k}: {u} vs {want}"
                    );
                }
            }
        }
        // One degree higher is not exact.
        h.reset();
        let q = |t: f64| libm::pow(t * 10.0, (order + 1) as f64);
        let mut err = 0.0_f64;
        for k in 0..200 {
            let t = k as f64 * DT;
            err = err.max((h.compensate(q(t)).unwrap() - q(t + delay)).abs());
        }
        assert!(err > 1e-6, "n={order}: {err}");
    }
}

#[test]
fn horiuchi_sine_error_matches_closed_form() {
    // For x = sin(ωt) the extrapolator's output is Im(G·e^{jωt}) with G = Σ w_j e^{−jωjΔt}, so the
    // steady error amplitude is |G − e^{jωτ}| exactly; the Lagrange remainder bounds it by
    // ω^{n+1}/(n+1)! · Π_j (τ + jΔt).
    let (delay, f) = (0.0137, 3.4);
    let w = 2.0 * core::f64::consts::PI * f;
    for order in 1..=3 {
        let p = HoriuchiParams::new(order, delay, DT).unwrap();
        let (mut gr, mut gi) = (0.0, 0.0);
        for (j, wj) in p.weights().iter().enumerate() {
            gr += wj * libm::cos(w * j as f64 * DT);
            gi -= wj * libm::sin(w * j as f64 * DT);
        }
        let closed = libm::hypot(gr - libm::cos(w * delay), gi - libm::sin(w * delay));
        let mut fact = 1.0;
        let mut bound = libm::pow(w, (order + 1) as f64);
        for j in 0..=order {
            fact *= (j + 1) as f64;
            bound *= delay + j as f64 * DT;
        }
        bound /= fact;
        let mut h = Horiuchi::new(p);
        let mut err = 0.0_f64;
        for k in 0..(4 * 2048) {
            let t = k as f64 * DT;
            let u = h.compensate(libm::sin(w * t)).unwrap();
            if k > 10 {
                err = err.max((u - libm::sin(w * (t + delay))).abs());
            }
        }
        println!("Horiuchi n={order}: max err {err:.3e}, closed form {closed:.3e}, remainder bound {bound:.3e}");
        assert!(
            (err - closed).abs() < 1e-3 * closed + 1e-12,
            "n={order}: {err} vs {closed}"
        );
        assert!(err <= bound * (1.0 + 1e-9), "n={order}: {err} > {bound}");
    }
}

#[test]
fn horiuchi_validation_and_refusal() {
    assert!(HoriuchiParams::new(0, 0.01, DT).is_err());
    assert!(HoriuchiParams::new(4, 0.01, DT).is_err());
    assert!(HoriuchiParams::new(2, -0.01, DT).is_err());
    assert!(HoriuchiParams::new(2, 2.0, DT).is_err());
    assert!(HoriuchiParams::new(2, f64::NAN, DT).is_err());
    assert!(HoriuchiParams::new(2, 0.01, 0.0).is_err());
    // Zero delay: the command is the target.
    let mut h = Horiuchi::new(HoriuchiParams::new(3, 0.0, DT).unwrap());
    assert_eq!(h.compensate(2.5), Ok(2.5));
    let before = h;
    assert!(h.compensate(f64::NAN).is_err());
    assert!(h.compensate(f64::INFINITY).is_err());
    assert_eq!(h, before);
}

#[test]
fn compensator_enum_dispatch() {
    let mut none = Compensator::None;
    assert_eq!(none.compensate(1.5, 0.3), Ok(1.5));
    assert!(none.compensate(1.5, f64::NAN).is_err());
    let hp = HoriuchiParams::new(2, 0.0137, DT).unwrap();
    let mut a = Compensator::Horiuchi(Horiuchi::new(hp));
    let mut b = Horiuchi::new(hp);
    for k in 0..100 {
        assert_eq!(a.compensate(target(k), 0.0), b.compensate(target(k)));
    }
    assert!(a.compensate(1.0, f64::INFINITY).is_err());
    a.reset();
    assert_eq!(a, Compensator::Horiuchi(Horiuchi::new(hp)));
    let mut c = Compensator::Ats(paper_ats(0.0137));
    let mut d = paper_ats(0.0137);
    for k in 0..100 {
        assert_eq!(c.compensate(target(k), 0.5), d.compensate(target(k), 0.5));
    }
}

fn any_input() -> impl Strategy<Value = f64> {
    prop_oneof![
        20 => -20.0f64..20.0,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => -1e7f64..1e7,
        1 => Just(MAX_ABS_INPUT_MM),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn ats_bounds_and_rate_limits_hold(
        window in 8usize..200,
        period in 1usize..16,
        seq in proptest::collection::vec((any_input(), any_input()), 1..1500),
    ) {
        let cfg = AtsConfig { window, update_period: period.min(window), ..AtsConfig::paper(DT, 0.0137) };
        let p = AtsParams::new(cfg).unwrap();
        let mut ats = Ats::new(p);
        for (t, m) in seq {
            let before = ats.coefficients();
            let n_before = ats.updates() + ats.skipped_updates();
            match ats.compensate(t, m) {
                Ok(u) => {
                    prop_assert!(u.is_finite());
                    prop_assert!(t.is_finite() && m.is_finite());
                }
                Err(_) => {
                    prop_assert!(!(t.is_finite() && m.is_finite()) || t.abs() > MAX_ABS_INPUT_MM || m.abs() > MAX_ABS_INPUT_MM);
                    prop_assert_eq!(ats.coefficients(), before);
                    prop_assert_eq!(ats.updates() + ats.skipped_updates(), n_before);
                }
            }
            let after = ats.coefficients();
            for i in 0..3 {
                prop_assert!(after[i] >= cfg.lower[i] && after[i] <= cfg.upper[i], "{:?}", after);
                prop_assert!((after[i] - before[i]).abs() <= cfg.max_step[i] * (1.0 + 1e-12));
            }
        }
    }

    #[test]
    fn horiuchi_finite_or_refused(order in 1usize..=3, seq in proptest::collection::vec(any_input(), 1..300)) {
        let mut h = Horiuchi::new(HoriuchiParams::new(order, 0.0137, DT).unwrap());
        for t in seq {
            let before = h;
            match h.compensate(t) {
                Ok(u) => prop_assert!(u.is_finite() && t.abs() <= MAX_ABS_INPUT_MM),
                Err(_) => prop_assert_eq!(h, before),
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------------
// Learned lead filter
// ---------------------------------------------------------------------------------------------------

#[test]
fn lead_is_a_strided_fir_of_the_targets() {
    // u(k) = 2·x(k) − x(k − s): linear extrapolation s ticks ahead, exact on a ramp.
    for stride in 1..=LEAD_MAX_STRIDE {
        let mut w = [0.0; LEAD_TAPS];
        w[0] = 2.0;
        w[1] = -1.0;
        let mut l = Lead::new(LeadParams::new(w, stride).unwrap());
        for k in 0..100 {
            let x = 0.25 * k as f64;
            let u = l.compensate(x).unwrap();
            let expected = if k >= stride {
                x + 0.25 * stride as f64
            } else {
                2.0 * x
            };
            assert!(
                (u - expected).abs() < 1e-5,
                "stride {stride} k {k}: {u} vs {expected}"
            );
        }
    }
    // The last tap reaches (taps − 1)·stride back.
    let mut w = [0.0; LEAD_TAPS];
    w[LEAD_TAPS - 1] = 1.0;
    let mut l = Lead::new(LeadParams::new(w, 3).unwrap());
    let lag = (LEAD_TAPS - 1) * 3;
    for k in 0..60 {
        let u = l.compensate(k as f64).unwrap();
        let expected = if k >= lag { (k - lag) as f64 } else { 0.0 };
        assert_eq!(u, expected, "k {k}");
    }
}

#[test]
fn lead_refuses_bad_targets_keeps_history_and_resets() {
    let mut w = [0.0; LEAD_TAPS];
    w[0] = 1.5;
    w[1] = -0.5;
    let mut l = Lead::new(LeadParams::new(w, 2).unwrap());
    for k in 0..10 {
        l.compensate(k as f64).unwrap();
    }
    let before = l;
    for bad in [f64::NAN, f64::INFINITY, 2.0 * MAX_ABS_INPUT_MM] {
        assert!(l.compensate(bad).is_err());
        assert_eq!(l, before);
    }
    let mut c = Compensator::Lead(l);
    assert!(c.compensate(1.0, f64::NAN).is_err());
    c.reset();
    assert_eq!(c.compensate(2.0, 0.0).unwrap(), 3.0);
    assert!(LeadParams::new(w, 0).is_err());
    assert!(LeadParams::new(w, LEAD_MAX_STRIDE + 1).is_err());
    w[3] = f64::NAN;
    assert!(LeadParams::new(w, 1).is_err());
}

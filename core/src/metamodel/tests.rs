//! Tests of [`crate::metamodel`].

extern crate std;
use super::*;
use proptest::prelude::*;
use std::{vec, vec::Vec};

fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => -1e4f64..1e4,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(f64::MAX),
        1 => Just(-f64::MAX),
    ]
}

#[test]
fn lr_recurrence_matches_hand_computation() {
    let th = [0.5, 1e-3, -0.2, 0.01, 1.9, -0.95];
    let mut lr = Lr::new(LrParams::new(th).unwrap());
    let (mut p0, mut p1) = (0.0, 0.0);
    for i in 0..50 {
        let f = Features {
            ground_accel_mm_s2: 100.0 * libm::sin(i as f64 * 0.3),
            brace_disp_fb_mm: 0.1 * i as f64,
            brace_force_fb_kn: -3.0 + 0.2 * i as f64,
        };
        let want = th[0]
            + th[1] * f.ground_accel_mm_s2
            + th[2] * f.brace_disp_fb_mm
            + th[3] * f.brace_force_fb_kn
            + th[4] * p0
            + th[5] * p1;
        let got = lr.predict(f).unwrap();
        assert!((got - want).abs() <= 1e-12 * want.abs().max(1.0), "{i}");
        p1 = p0;
        p0 = want;
    }
    lr.reset();
    assert_eq!(*lr.state(), LrState::default());
}

#[test]
fn lr_arx_oscillator_is_undamped_sine() {
    // θ4 = 2cos(ωΔt), θ5 = −1 is an exact discrete oscillator: from x̂(0)=0, x̂(1)=sin(ωΔt) it
    // must reproduce sin(ωΔt·k) (docs/design.md §5 expects the fit to be ARX of this kind).
    let w = 0.01;
    let mut lr = Lr::new(LrParams::new([0.0, 0.0, 0.0, 0.0, 2.0 * libm::cos(w), -1.0]).unwrap());
    lr.state = LrState {
        pred_mm: libm::sin(w),
        prev_pred_mm: 0.0,
    };
    for k in 2..2000 {
        let y = lr.predict(Features::default()).unwrap();
        assert!((y - libm::sin(w * k as f64)).abs() < 1e-9, "{k}");
    }
}

#[test]
fn lr_validation() {
    assert!(LrParams::new([0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0]).is_err());
    assert_eq!(
        LrParams::from_slice(&[1.0; 5]),
        Err(ModelError::Shape {
            what: "LR coefficients",
            expected: 6,
            got: 5
        })
    );
    assert!(LrParams::from_slice(&[1.0; 7]).is_err());
    assert_eq!(LrParams::from_slice(&[2.0; 6]).unwrap().theta(), &[2.0; 6]);
    assert_eq!(LR_FEATURE_NAMES.len(), LR_COEFFS);
}

#[test]
fn lr_refuses_non_finite_and_keeps_state() {
    let mut lr = Lr::new(LrParams::new([0.1, 1e-3, 0.2, 0.01, 1.5, -0.6]).unwrap());
    let ok = Features {
        ground_accel_mm_s2: 50.0,
        brace_disp_fb_mm: 1.0,
        brace_force_fb_kn: 10.0,
    };
    lr.predict(ok).unwrap();
    lr.predict(ok).unwrap();
    let before = lr;
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        for which in 0..3 {
            let mut f = ok;
            match which {
                0 => f.ground_accel_mm_s2 = bad,
                1 => f.brace_disp_fb_mm = bad,
                _ => f.brace_force_fb_kn = bad,
            }
            assert!(matches!(lr.predict(f), Err(InputError::NotFinite(_))));
            assert_eq!(lr, before);
        }
    }
    // Overflowing prediction from finite inputs: refused too.
    let huge = Features {
        ground_accel_mm_s2: f64::MAX,
        brace_disp_fb_mm: f64::MAX,
        brace_force_fb_kn: f64::MAX,
    };
    let mut big = Lr::new(LrParams::new([0.0, 1.0, 1.0, 1.0, 0.0, 0.0]).unwrap());
    let big_before = big;
    assert_eq!(
        big.predict(huge),
        Err(InputError::NotFinite("LR prediction"))
    );
    assert_eq!(big, big_before);
    // And it continues from the last good state.
    let mut fresh = before;
    assert_eq!(lr.predict(ok), fresh.predict(ok));
}

/// A tiny H-unit network with deterministic weights, and the same network evaluated naively.
struct Ref {
    h: usize,
    w_ih: Vec<f64>,
    w_hh: Vec<f64>,
    b_h: Vec<f64>,
    w_ho: Vec<f64>,
    b_o: f64,
    sc: RnnScaling,
}

impl Ref {
    fn new(h: usize) -> Self {
        let g = |k: usize, s: f64| libm::sin(1.7 * k as f64 + s) * 0.6;
        Ref {
            h,
            w_ih: (0..h * 2).map(|k| g(k, 0.1)).collect(),
            w_hh: (0..h * h)
                .map(|k| g(k, 0.7) / libm::sqrt(h as f64))
                .collect(),
            b_h: (0..h).map(|k| g(k, 1.3) * 0.2).collect(),
            w_ho: (0..h).map(|k| g(k, 2.1)).collect(),
            b_o: 0.05,
            sc: RnnScaling {
                input_mean: [1.0, -2.0],
                input_std: [500.0, 300.0],
                output_mean: 0.3,
                output_std: 4.0,
            },
        }
    }
    fn params(&self) -> Result<RnnParams, ModelError> {
        RnnParams::new(
            RnnWeights {
                w_ih: &self.w_ih,
                w_hh: &self.w_hh,
                b_h: &self.b_h,
                w_ho: &self.w_ho,
                b_o: self.b_o,
            },
            self.sc,
        )
    }
    // Deliberately naive index loops: an independent reference for the iterator code.
    #[allow(clippy::needless_range_loop)]
    fn run(&self, inputs: &[[f64; 2]]) -> Vec<f64> {
        let h = self.h;
        let mut hid = vec![0.0; h];
        let mut out = Vec::new();
        for u in inputs {
            let un = [
                (u[0] - self.sc.input_mean[0]) / self.sc.input_std[0],
                (u[1] - self.sc.input_mean[1]) / self.sc.input_std[1],
            ];
            let mut nh = vec![0.0; h];
            for j in 0..h {
                let mut a = self.b_h[j];
                for k in 0..2 {
                    a += self.w_ih[j * 2 + k] * un[k];
                }
                for l in 0..h {
                    a += self.w_hh[j * h + l] * hid[l];
                }
                nh[j] = a.tanh();
            }
            hid = nh;
            let yn: f64 = (0..h).map(|j| self.w_ho[j] * hid[j]).sum::<f64>() + self.b_o;
            out.push(yn * self.sc.output_std + self.sc.output_mean);
        }
        out
    }
}

#[test]
fn rnn_matches_naive_reference_for_all_paper_sizes() {
    let inputs: Vec<[f64; 2]> = (0..500)
        .map(|i| {
            let t = i as f64 / 2048.0;
            [3000.0 * libm::sin(20.0 * t), 800.0 * libm::cos(13.0 * t)]
        })
        .collect();
    for h in [1, 5, 10, 20, 32] {
        let r = Ref::new(h);
        let want = r.run(&inputs);
        let mut rnn = Rnn::new(r.params().unwrap());
        assert_eq!(rnn.params().hidden(), h);
        for (k, (u, w)) in inputs.iter().zip(&want).enumerate() {
            let got = rnn
                .predict(RnnInputs {
                    ground_accel_mm_s2: u[0],
                    brace_force_fb_kn: u[1],
                })
                .unwrap();
            assert!((got - w).abs() < 1e-12, "H={h} k={k}: {got} vs {w}");
        }
        rnn.reset();
        assert_eq!(*rnn.state(), RnnState::default());
    }
}

#[test]
fn rnn_shape_and_value_validation() {
    let mut r = Ref::new(5);
    r.w_hh.pop();
    assert_eq!(
        r.params(),
        Err(ModelError::Shape {
            what: "RNN W_hh",
            expected: 25,
            got: 24
        })
    );
    let mut r = Ref::new(5);
    r.w_ih.push(0.0);
    assert!(matches!(
        r.params(),
        Err(ModelError::Shape {
            what: "RNN W_ih",
            ..
        })
    ));
    let mut r = Ref::new(5);
    r.w_ho.pop();
    assert!(matches!(
        r.params(),
        Err(ModelError::Shape {
            what: "RNN W_ho",
            ..
        })
    ));
    let r = Ref::new(33);
    assert_eq!(r.params(), Err(ModelError::HiddenSize(33)));
    let mut r = Ref::new(5);
    r.b_h.clear();
    assert_eq!(r.params(), Err(ModelError::HiddenSize(0)));
    let mut r = Ref::new(5);
    r.w_hh[3] = f64::NAN;
    assert!(matches!(
        r.params(),
        Err(ModelError::Param(ParamError::NotFinite(_)))
    ));
    let mut r = Ref::new(5);
    r.b_o = f64::INFINITY;
    assert!(r.params().is_err());
    let mut r = Ref::new(5);
    r.sc.input_std[1] = 0.0;
    assert!(matches!(
        r.params(),
        Err(ModelError::Param(ParamError::NotPositive(_)))
    ));
    let mut r = Ref::new(5);
    r.sc.output_std = -1.0;
    assert!(r.params().is_err());
    let mut r = Ref::new(5);
    r.sc.input_mean[0] = f64::NAN;
    assert!(r.params().is_err());
}

/// `RnnParams::weights` gives back exactly the slices it was built from, and `elman_step` on them
/// is `Rnn::predict` between normalization and de-normalization, bit for bit, with the hidden
/// state it leaves behind.
#[test]
fn elman_step_is_the_predict_step() {
    for h in [1, 7, 32] {
        let r = Ref::new(h);
        let params = r.params().unwrap();
        let w = params.weights();
        assert_eq!(w.w_ih, &r.w_ih[..]);
        assert_eq!(w.w_hh, &r.w_hh[..]);
        assert_eq!(w.b_h, &r.b_h[..]);
        assert_eq!(w.w_ho, &r.w_ho[..]);
        assert_eq!(w.b_o.to_bits(), r.b_o.to_bits());
        let mut rnn = Rnn::new(params);
        let (mut hid, mut next) = (vec![0.0; h], vec![0.0; h]);
        for i in 0..200 {
            let u = [
                2500.0 * libm::sin(0.05 * i as f64),
                -700.0 * libm::cos(0.03 * i as f64),
            ];
            let got = rnn
                .predict(RnnInputs {
                    ground_accel_mm_s2: u[0],
                    brace_force_fb_kn: u[1],
                })
                .unwrap();
            let x = [
                (u[0] - r.sc.input_mean[0]) / r.sc.input_std[0],
                (u[1] - r.sc.input_mean[1]) / r.sc.input_std[1],
            ];
            let y = elman_step(&w, &hid, &x, &mut next);
            hid.copy_from_slice(&next);
            let want = y * r.sc.output_std + r.sc.output_mean;
            assert_eq!(got.to_bits(), want.to_bits(), "H={h} step {i}");
            assert_eq!(&rnn.state().hidden[..h], &hid[..]);
        }
    }
}

/// Unchecked shapes shorten the sums; they never panic (H = 0 included).
#[test]
fn elman_step_never_panics_on_odd_shapes() {
    let empty = RnnWeights {
        w_ih: &[],
        w_hh: &[],
        b_h: &[],
        w_ho: &[],
        b_o: 0.5,
    };
    assert_eq!(elman_step(&empty, &[], &[1.0, 2.0], &mut []), 0.5);
    let short = RnnWeights {
        w_ih: &[1.0, 1.0, 1.0],
        w_hh: &[0.5; 3],
        b_h: &[0.0, 0.0],
        w_ho: &[1.0, 1.0],
        b_o: 0.0,
    };
    let mut next = [0.0; 1];
    let y = elman_step(&short, &[0.1], &[0.2, 0.3], &mut next);
    assert!(y.is_finite() && next[0].is_finite());
}

#[test]
fn rnn_refuses_non_finite_and_keeps_state() {
    let mut rnn = Rnn::new(Ref::new(10).params().unwrap());
    let ok = RnnInputs {
        ground_accel_mm_s2: 1000.0,
        brace_force_fb_kn: 200.0,
    };
    rnn.predict(ok).unwrap();
    let before = rnn;
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let a = RnnInputs {
            ground_accel_mm_s2: bad,
            ..ok
        };
        let b = RnnInputs {
            brace_force_fb_kn: bad,
            ..ok
        };
        assert!(matches!(rnn.predict(a), Err(InputError::NotFinite(_))));
        assert!(matches!(rnn.predict(b), Err(InputError::NotFinite(_))));
        assert_eq!(rnn, before);
    }
}

#[test]
fn state_sizes() {
    use core::mem::size_of;
    std::println!(
        "size_of: Lr {} B, LrState {} B, Rnn {} B, RnnParams {} B, RnnState {} B",
        size_of::<Lr>(),
        size_of::<LrState>(),
        size_of::<Rnn>(),
        size_of::<RnnParams>(),
        size_of::<RnnState>()
    );
    assert_eq!(size_of::<LrState>(), 16);
    assert_eq!(size_of::<RnnState>(), 8 * RNN_MAX_HIDDEN);
    // W_hh dominates: 32×32 f64 = 8 KiB; the whole RNN (params + state) stays under 10 KiB.
    assert!(size_of::<Rnn>() < 10 * 1024);
}

proptest! {
    #[test]
    fn lr_finite_or_refused(seq in proptest::collection::vec((any_f64(), any_f64(), any_f64()), 1..200)) {
        let mut lr = Lr::new(LrParams::new([0.1, 1e-4, 0.02, 1e-3, 1.99, -0.995]).unwrap());
        for (a, d, f) in seq {
            let before = lr;
            match lr.predict(Features { ground_accel_mm_s2: a, brace_disp_fb_mm: d, brace_force_fb_kn: f }) {
                Ok(y) => {
                    prop_assert!(y.is_finite());
                    prop_assert!(lr.state().pred_mm.is_finite() && lr.state().prev_pred_mm.is_finite());
                }
                Err(_) => prop_assert_eq!(lr, before),
            }
        }
    }

    #[test]
    fn rnn_finite_or_refused(h in 1usize..=32, seq in proptest::collection::vec((any_f64(), any_f64()), 1..100)) {
        let mut rnn = Rnn::new(Ref::new(h).params().unwrap());
        for (a, f) in seq {
            let before = rnn;
            match rnn.predict(RnnInputs { ground_accel_mm_s2: a, brace_force_fb_kn: f }) {
                Ok(y) => {
                    prop_assert!(a.is_finite() && f.is_finite() && y.is_finite());
                    prop_assert!(rnn.state().hidden.iter().all(|v| v.abs() <= 1.0));
                }
                Err(_) => prop_assert_eq!(rnn, before),
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------------
// LRX
// ---------------------------------------------------------------------------------------------------

const LRX_TEST_COEFFS: [f64; LRX_COEFFS] = [1.9, -0.95, 0.04, 1e-4, -2e-5, 3e-6, -4e-5, 2e-5, 1e-6];

#[test]
fn lrx_matches_a_naive_recursion_without_adaptation() {
    let k_c = 1000.0;
    let mut m = Lrx::new(LrxParams::new(LRX_TEST_COEFFS, k_c, 0.0).unwrap());
    let (mut d, mut g, mut f): (Vec<f64>, Vec<f64>, Vec<f64>) =
        (vec![0.0; 3], vec![0.0; 3], vec![0.0; 3]);
    let c = LRX_TEST_COEFFS;
    for i in 0..500 {
        let t = i as f64 * 0.01;
        let (ag, x_fb, f_fb) = (
            libm::sin(t) * 1000.0,
            libm::cos(1.3 * t),
            900.0 * libm::sin(0.7 * t),
        );
        let ft = f_fb + k_c * (d[0] - x_fb);
        g.insert(0, ag);
        f.insert(0, ft);
        let y = (0..3)
            .map(|j| c[j] * d[j] + c[3 + j] * g[j] + c[6 + j] * f[j])
            .sum::<f64>();
        d.insert(0, y);
        let got = m
            .predict(LrxInputs {
                ground_accel_mm_s2: ag,
                brace_disp_fb_mm: x_fb,
                brace_force_fb_kn: f_fb,
            })
            .unwrap();
        assert!(
            (got - y).abs() <= 1e-9 * y.abs().max(1.0),
            "step {i}: {got} vs {y}"
        );
    }
}

#[test]
fn lrx_correction_vanishes_when_the_actuator_is_exact() {
    // Measured displacement = the model's own target: F̃ = F, whatever k_c.
    let run = |k_c: f64| {
        let mut m = Lrx::new(LrxParams::new(LRX_TEST_COEFFS, k_c, 0.0).unwrap());
        let mut d = 0.0;
        let mut out = Vec::new();
        for i in 0..300 {
            let ag = 500.0 * libm::sin(i as f64 * 0.05);
            d = m
                .predict(LrxInputs {
                    ground_accel_mm_s2: ag,
                    brace_disp_fb_mm: d,
                    brace_force_fb_kn: 700.0 * d,
                })
                .unwrap();
            out.push(d);
        }
        out
    };
    assert_eq!(run(0.0), run(1224.1));
}

#[test]
fn lrx_estimates_the_specimen_stiffness_and_holds_it() {
    let k_nom = 1224.1;
    let mut m = Lrx::new(LrxParams::new(LRX_TEST_COEFFS, k_nom, 2048.0).unwrap());
    let k_true = 0.6 * k_nom;
    let step = |m: &mut Lrx, x: f64| {
        m.predict(LrxInputs {
            ground_accel_mm_s2: 0.0,
            brace_disp_fb_mm: x,
            brace_force_fb_kn: k_true * x,
        })
        .unwrap();
    };
    // Below the excitation threshold the nominal stiffness is used.
    step(&mut m, 0.01);
    assert_eq!(m.state().k_est_kn_per_mm, k_nom);
    for i in 0..8192 {
        step(&mut m, 5.0 * libm::sin(i as f64 * 0.02));
    }
    let k = m.state().k_est_kn_per_mm;
    assert!((k / k_true - 1.0).abs() < 1e-5, "{k} vs {k_true}");
    // The motion stops: the estimate holds instead of falling back to the nominal.
    for _ in 0..40_000 {
        step(&mut m, 0.0);
    }
    assert!((m.state().k_est_kn_per_mm / k_true - 1.0).abs() < 1e-5);
    // Bounded to 0.25..4 × nominal.
    let mut m = Lrx::new(LrxParams::new(LRX_TEST_COEFFS, k_nom, 100.0).unwrap());
    for i in 0..2000 {
        let x = 5.0 * libm::sin(i as f64 * 0.05);
        m.predict(LrxInputs {
            ground_accel_mm_s2: 0.0,
            brace_disp_fb_mm: x,
            brace_force_fb_kn: -x * k_nom,
        })
        .unwrap();
    }
    assert!((m.state().k_est_kn_per_mm - 0.25 * k_nom).abs() < 1e-3);
    m.reset();
    assert_eq!(*m.state(), LrxState::default());
}

#[test]
fn lrx_refuses_bad_inputs_and_keeps_its_state() {
    let mut m = Lrx::new(LrxParams::new(LRX_TEST_COEFFS, 1224.1, 2048.0).unwrap());
    for i in 0..50 {
        m.predict(LrxInputs {
            ground_accel_mm_s2: 100.0 * i as f64,
            brace_disp_fb_mm: 0.1,
            brace_force_fb_kn: 100.0,
        })
        .unwrap();
    }
    let before = *m.state();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        for inp in [
            LrxInputs {
                ground_accel_mm_s2: bad,
                ..LrxInputs::default()
            },
            LrxInputs {
                brace_disp_fb_mm: bad,
                ..LrxInputs::default()
            },
            LrxInputs {
                brace_force_fb_kn: bad,
                ..LrxInputs::default()
            },
        ] {
            assert!(m.predict(inp).is_err());
            assert_eq!(*m.state(), before);
        }
    }
    // A value f32 cannot hold (the stiffness sums) is refused too.
    assert!(m
        .predict(LrxInputs {
            brace_disp_fb_mm: 1e300,
            ..LrxInputs::default()
        })
        .is_err());
    assert_eq!(*m.state(), before);
}

#[test]
fn lrx_parameters_are_validated() {
    assert!(LrxParams::new(LRX_TEST_COEFFS, -1.0, 0.0).is_err());
    assert!(LrxParams::new(LRX_TEST_COEFFS, f64::NAN, 0.0).is_err());
    assert!(LrxParams::new(LRX_TEST_COEFFS, 1.0, 0.5).is_err());
    assert!(LrxParams::new(LRX_TEST_COEFFS, 1.0, f64::INFINITY).is_err());
    let mut c = LRX_TEST_COEFFS;
    c[4] = f64::NAN;
    assert!(LrxParams::new(c, 1.0, 0.0).is_err());
    assert!(matches!(
        LrxParams::from_slice(&[0.0; 8], 1.0, 0.0),
        Err(ModelError::Shape {
            expected: 9,
            got: 8,
            ..
        })
    ));
    assert!(LrxParams::from_slice(&LRX_TEST_COEFFS, 1.0, 2048.0).is_ok());
}

proptest! {
    #[test]
    fn lrx_output_is_finite_or_refused(
        inputs in proptest::collection::vec((any_f64(), any_f64(), any_f64()), 1..200)
    ) {
        let mut m = Lrx::new(LrxParams::new(LRX_TEST_COEFFS, 1224.1, 2048.0).unwrap());
        for (ag, x, f) in inputs {
            let before = *m.state();
            match m.predict(LrxInputs { ground_accel_mm_s2: ag, brace_disp_fb_mm: x, brace_force_fb_kn: f }) {
                Ok(y) => prop_assert!(y.is_finite()),
                Err(_) => prop_assert_eq!(*m.state(), before),
            }
        }
    }
}

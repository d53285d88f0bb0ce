//! Tests of the RNN trainer: gradient, round trips, bit-identity with `rths-core`, training runs
//! and the shipped models.

use super::*;
use crate::machinery::train::data::{pure_response, TrainingResponse};
use rths_core::metrics::nrmse_pct;
use rths_core::params::{Prototype, DT_S};

fn scaling() -> Scaling {
    Scaling {
        input_mean: [0.0, 0.0],
        input_std: [1.0, 1.0],
        output_mean: 0.0,
        output_std: 1.0,
    }
}

/// The analytic BPTT gradient agrees with central finite differences of the window loss.
#[test]
fn gradient_check() {
    let mut model = TrainableRnn::random(4, scaling(), 11, &RnnInit::default()).unwrap();
    // Non-zero biases so every term is exercised.
    let (bh, bo) = (model.off_bh(), model.off_bo());
    for j in 0..4 {
        model.params[bh + j] = 0.1 * j as f64 - 0.15;
    }
    model.params[bo] = 0.2;
    let h0 = [0.3, -0.2, 0.1, 0.05];
    let inputs: Vec<[f64; 2]> = (0..25)
        .map(|t| [(0.3 * t as f64).sin(), (0.17 * t as f64).cos()])
        .collect();
    let targets: Vec<f64> = (0..25).map(|t| 0.5 * (0.21 * t as f64).sin()).collect();
    let mut grad = vec![0.0; model.params.len()];
    let mut hs = Vec::new();
    let mut inp = inputs.clone();
    model.window_grad(&h0, &mut inp, &targets, &mut grad, &mut hs, None);
    let mut scratch = vec![0.0; model.params.len()];
    let loss = |m: &TrainableRnn, s: &mut Vec<f64>| {
        let mut hs = Vec::new();
        let mut inp = inputs.clone();
        m.window_grad(&h0, &mut inp, &targets, s, &mut hs, None)
    };
    let eps = 1e-6;
    let mut worst: f64 = 0.0;
    for (i, g) in grad.iter().enumerate() {
        let mut plus = model.clone();
        plus.params[i] += eps;
        let mut minus = model.clone();
        minus.params[i] -= eps;
        let fd = (loss(&plus, &mut scratch) - loss(&minus, &mut scratch)) / (2.0 * eps);
        let err = (fd - g).abs() / (fd.abs() + g.abs()).max(1e-6);
        worst = worst.max(err);
    }
    assert!(worst < 1e-6, "worst relative gradient error {worst}");
}

#[test]
fn weights_round_trip_and_physical_step_matches_normalized() {
    let mut m = TrainableRnn::random(5, scaling(), 2, &RnnInit::default()).unwrap();
    m.scaling = Scaling {
        input_mean: [1.0, -2.0],
        input_std: [100.0, 3.0],
        output_mean: 0.5,
        output_std: 2.0,
    };
    let back = TrainableRnn::from_weights(&m.to_weights()).unwrap();
    assert_eq!(back, m);
    let (mut h, mut s) = (vec![0.0; 5], vec![0.0; 5]);
    let x = m.step(&mut h, &mut s, 201.0, 1.0);
    let mut h2 = vec![0.0; 5];
    let y = m.step_normalized(&[0.0; 5], [2.0, 1.0], &mut h2);
    assert_eq!(x, y * 2.0 + 0.5);
    assert_eq!(h, h2);
}

/// The same weights in `rths-core`'s `no_std` inference give the same bits, step after step.
#[test]
fn bit_identical_to_core_inference() {
    use rths_core::metamodel as core_mm;
    let mut m = TrainableRnn::random(7, scaling(), 5, &RnnInit::default()).unwrap();
    m.scaling = Scaling {
        input_mean: [3.0, -40.0],
        input_std: [900.0, 4000.0],
        output_mean: 0.02,
        output_std: 3.3,
    };
    // The trainer's step is core's `elman_step` now, so this guards the plumbing around it: the
    // weight slices, the scaling, the normalization and the state hand-over.
    let core_params = core_mm::RnnParams::new(m.core_weights(), *m.scaling()).unwrap();
    let mut core_rnn = core_mm::Rnn::new(core_params);
    let (mut h, mut s) = (vec![0.0; 7], vec![0.0; 7]);
    for i in 0..500 {
        let ag = 2000.0 * (0.013 * i as f64).sin();
        let f = 8000.0 * (0.007 * i as f64).cos();
        let ours = m.step(&mut h, &mut s, ag, f);
        let theirs = core_rnn
            .predict(core_mm::RnnInputs {
                ground_accel_mm_s2: ag,
                brace_force_fb_kn: f,
            })
            .unwrap();
        assert_eq!(ours.to_bits(), theirs.to_bits(), "step {i}");
    }
}

fn short_response() -> TrainingResponse {
    // The strong first 6 s of El Centro.
    let ag = crate::machinery::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
    pure_response(&Prototype::paper(), &ag[..6 * 2048], DT_S).unwrap()
}

#[test]
fn training_reduces_validation_loss_and_is_seed_reproducible() {
    let r = short_response();
    let k_b = Prototype::paper().brace_axial_stiffness_kn_per_mm();
    let mut cfg = RnnConfig::random_init(5);
    cfg.max_epochs = 8;
    cfg.quiet = true;
    let a = train(&r, k_b, &cfg).unwrap();
    let first = a.history[0].1;
    assert!(a.best_validation_loss < 0.5 * first, "{:?}", a.history);
    let b = train(&r, k_b, &cfg).unwrap();
    assert_eq!(a.model, b.model);
    assert_eq!(a.history, b.history);
    cfg.seed = 2;
    let c = train(&r, k_b, &cfg).unwrap();
    assert_ne!(a.model, c.model);
}

fn el_centro_response() -> TrainingResponse {
    let ag = crate::machinery::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
    pure_response(&Prototype::paper(), &ag, DT_S).unwrap()
}

/// With a tiny state scale, the ARX realization reproduces the linear model's own closed loop
/// (`lr-pure`, an independent implementation) to rounding; with the default scale the tanh
/// curvature costs a little accuracy, and it grows as ε² (the error is the cubic term).
#[test]
fn arx_realization_matches_the_linear_model() {
    let r = short_response();
    let p = Prototype::paper();
    let k_b = p.brace_axial_stiffness_kn_per_mm();
    let fit = crate::machinery::train::lr::fit_pure(
        &r,
        28,
        k_b,
        crate::machinery::train::lr::DEFAULT_RCOND,
    )
    .unwrap();
    let scaling = Scaling {
        input_mean: [10.0, -3.0],
        input_std: [1500.0, 4000.0],
        output_mean: 0.01,
        output_std: 3.0,
    };
    let lr_loop = &fit.pure_prediction_mm;
    let err = |eps: f64| {
        let m = TrainableRnn::from_arx(6, scaling, &fit.solution.theta, k_b, eps, 3).unwrap();
        let x = pure_prediction(&m, &r.ground_accel_mm_s2, 28, k_b).unwrap();
        nrmse_pct(&x, lr_loop).unwrap()
    };
    let (tiny, small, dflt) = (err(1e-6), err(1e-4), err(1e-3));
    assert!(tiny < 1e-5, "ε = 1e-6: {tiny}%");
    // Cubic term: 10× smaller ε, ~100× smaller error.
    assert!(
        small < dflt / 50.0 && dflt < 0.5,
        "ε=1e-4: {small}%, 1e-3: {dflt}%"
    );
    assert!(TrainableRnn::from_arx(1, scaling, &fit.solution.theta, k_b, 1e-3, 3).is_err());
}

/// The target: `rnn-pure` (the RNN fed its own prediction 28 steps earlier) on El Centro
/// for H = 10 at or below the paper's 3.74 % NRMSE; fine-tuning keeps or improves the
/// initialization on held-out windows, and the run is reproducible.
#[test]
fn rnn_pure_el_centro_h10_meets_paper() {
    let r = el_centro_response();
    let k_b = Prototype::paper().brace_axial_stiffness_kn_per_mm();
    let mut cfg = RnnConfig::new(10);
    cfg.quiet = true;
    let t = train(&r, k_b, &cfg).unwrap();
    assert!(
        t.pure_nrmse_pct <= 3.74,
        "rnn-pure NRMSE {}%",
        t.pure_nrmse_pct
    );
    assert!(
        t.init_pure_nrmse_pct <= 3.74,
        "init {}%",
        t.init_pure_nrmse_pct
    );
    assert!(t.best_validation_loss <= t.history[0].1);
    // Recomputed independently of the training code's own figure: the `rnn-pure-10` scenario
    // (`rths simulate`'s) of the trained model.
    let file = model_file(&t, &cfg, "el-centro".into(), r.len());
    let setup = crate::studies::scenario::ScenarioSetup {
        id: crate::studies::scenario::ScenarioId::RnnPure(10),
        ground_accel_mm_s2: &r.ground_accel_mm_s2,
        reference_mm: &r.brace_disp_mm,
        rig: rths_hal_sim::RigConfig::new(rths_hal_sim::Preset::UnrCompact),
        stiffness_factor: 1.0,
        lr: None,
        rnn: Some(crate::machinery::models::rnn_params(&file).unwrap()),
        delay_steps: 28,
        lrx: None,
    };
    let scenario = crate::studies::scenario::report(&setup)
        .unwrap()
        .nrmse_pct
        .unwrap();
    assert_eq!(scenario, t.pure_nrmse_pct);
    cfg.max_epochs = 3;
    let a = train(&r, k_b, &cfg).unwrap();
    let b = train(&r, k_b, &cfg).unwrap();
    assert_eq!(a.model, b.model);
}

/// The shipped defaults `data/models/rnn-{5,10,20}.json` load, and run in the core's `no_std`
/// inference on their own delayed prediction they meet the paper's `rnn-pure` figures on El
/// Centro (4.23 / 3.74 / 3.88 %).
#[test]
fn shipped_models_meet_paper_in_core_closed_loop() {
    use crate::machinery::model_file::{ModelFile, ModelKind};
    use rths_core::metamodel as core_mm;
    let r = el_centro_response();
    let k_b = Prototype::paper().brace_axial_stiffness_kn_per_mm();
    for (h, paper) in [(5, 4.23), (10, 3.74), (20, 3.88)] {
        let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join(format!("data/models/rnn-{h}.json"));
        let f = ModelFile::load_kind(&path, ModelKind::Rnn).unwrap();
        let m = TrainableRnn::from_weights(f.rnn.as_ref().unwrap()).unwrap();
        assert_eq!(m.hidden(), h);
        let params = core_mm::RnnParams::new(m.core_weights(), *m.scaling()).unwrap();
        let mut net = core_mm::Rnn::new(params);
        let mut x = vec![0.0];
        for i in 0..r.len() - 1 {
            let fb = if i >= 28 { x[i - 28] } else { 0.0 };
            let next = net
                .predict(core_mm::RnnInputs {
                    ground_accel_mm_s2: r.ground_accel_mm_s2[i],
                    brace_force_fb_kn: k_b * fb,
                })
                .unwrap();
            x.push(next);
        }
        let e = nrmse_pct(&x, &r.brace_disp_mm).unwrap();
        assert!(e <= paper, "H = {h}: rnn-pure {e}% > paper {paper}%");
    }
}

//! Cost of the control step (ns per `Controller::tick`) for the LR, RNN-10, FE+ATS and LRX (shipped
//! model, with its lead filter) analytical parts, and the wall time of a whole El Centro `lr-online` run against the virtual plant
//! (compare with the record's 40 s of test time).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use rths::machinery::motion::GroundMotion;
use rths::studies::scenario::{self, ScenarioId, ScenarioSetup};
use rths::studies::study;
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use rths_core::hal::Sample;
use rths_core::metamodel::{LrParams, RnnParams, RnnScaling, RnnWeights};
use rths_core::model::Model;
use rths_core::params::{Prototype, SpecimenScale, DT_S, PAPER_DELAY_STEPS};
use rths_core::supervisor::{Limits, State};
use rths_hal_sim::{Preset, Specimen};

fn controller(analytical: Analytical, compensator: Compensator) -> Controller {
    let cfg = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .expect("valid config");
    let mut c = Controller::new(cfg, analytical, compensator);
    c.supervisor_mut().arm().expect("idle");
    c.supervisor_mut().start().expect("armed");
    c
}

fn lr() -> LrParams {
    LrParams::new([0.0, -1.7e-7, 0.0, 0.0, 1.999_474, -0.999_583]).expect("finite")
}

/// A deterministic RNN of hidden size 10 with small weights (the cost does not depend on the values).
fn rnn10() -> RnnParams {
    const H: usize = 10;
    let f = |i: usize| ((i * 7919 % 1000) as f64 / 1000.0 - 0.5) * 0.2;
    let w_ih: Vec<f64> = (0..H * 2).map(f).collect();
    let w_hh: Vec<f64> = (0..H * H).map(|i| f(i + 100)).collect();
    let b_h: Vec<f64> = (0..H).map(|i| f(i + 300)).collect();
    let w_ho: Vec<f64> = (0..H).map(|i| f(i + 400)).collect();
    RnnParams::new(
        RnnWeights {
            w_ih: &w_ih,
            w_hh: &w_hh,
            b_h: &b_h,
            w_ho: &w_ho,
            b_o: 0.0,
        },
        RnnScaling {
            input_mean: [0.0, 0.0],
            input_std: [1000.0, 5000.0],
            output_mean: 0.0,
            output_std: 5.0,
        },
    )
    .expect("valid RNN")
}

fn bench_steps(c: &mut Criterion) {
    let mut g = c.benchmark_group("control_tick");
    let lrx_file = rths::machinery::model_file::ModelFile::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models/lrx.json"),
    )
    .expect("shipped LRX model");
    let (lrx, lead) = rths::machinery::models::lrx_params(&lrx_file).expect("valid LRX model");
    // Assembled as the scenarios and the firmware assemble them.
    let cases = [
        ("lr", Model::Lr(lr())),
        ("lrx", Model::Lrx(lrx, lead)),
        ("rnn-10", Model::Rnn(rnn10())),
        (
            "fe-ats",
            Model::FeAts {
                expected_delay_s: PAPER_DELAY_STEPS as f64 * DT_S,
            },
        ),
    ]
    .map(|(name, model)| {
        let (analytical, comp) = model
            .assemble(Prototype::paper(), DT_S)
            .expect("valid model");
        (name, analytical, comp)
    });
    for (name, analytical, comp) in cases {
        let mut ctl = controller(analytical.clone(), comp.clone());
        let (mut k, mut restarts, mut ticks, mut cmd) = (0u64, 0u64, 0u64, 0.0f64);
        g.bench_function(name, |b| {
            b.iter(|| {
                // An ideal rig (the specimen is where it was told to be, a linear spring) under a
                // 1 Hz ground motion keeps every state moving. A tick after a trip would skip the
                // model and flatter the figure, so a tripped controller is rebuilt (and counted).
                k += 1;
                ticks += 1;
                let ag = 2000.0 * (k as f64 * 2.0 * std::f64::consts::PI / 2048.0).sin();
                let s = Sample {
                    disp_mm: cmd,
                    force_kn: 1.2241 * cmd,
                };
                let out = ctl.tick(black_box(ag), Ok(s), false);
                cmd = out.command_mm;
                if out.state != State::Running {
                    restarts += 1;
                    ctl = controller(analytical.clone(), comp.clone());
                    cmd = 0.0;
                }
                black_box(out)
            })
        });
        eprintln!("{name}: {restarts} restarts in {ticks} ticks");
        assert!(
            restarts * 1000 <= ticks,
            "{name}: the controller trips too often to be timed"
        );
    }
    g.finish();
}

fn bench_run(c: &mut Criterion) {
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    let reference = study::reference_mm(&ag, 1.0).expect("reference");
    let setup = ScenarioSetup {
        id: ScenarioId::LrOnline,
        ground_accel_mm_s2: &ag,
        reference_mm: &reference,
        rig: rths::machinery::reference::rig_config(Preset::UnrCompact, Specimen::Linear, 1.0, 1),
        stiffness_factor: 1.0,
        lr: Some(lr()),
        rnn: None,
        delay_steps: PAPER_DELAY_STEPS,
        lrx: None,
    };
    let mut g = c.benchmark_group("whole_run");
    g.sample_size(10);
    // The closed loop alone (controller + virtual plant + history), then with the figures (NRMSE,
    // J1's 206-lag cross-correlation, J2-J5) computed after it.
    g.bench_function("el_centro_lr_online_40s_loop", |b| {
        b.iter(|| black_box(scenario::simulate(&setup).expect("run")))
    });
    g.bench_function("el_centro_lr_online_40s_with_figures", |b| {
        b.iter(|| black_box(scenario::run(&setup).expect("run")))
    });
    g.finish();
}

criterion_group!(benches, bench_steps, bench_run);
criterion_main!(benches);

//! ns per tick of the virtual rig (`command` + `advance_tick` + `read`, one 1/2048 s controller
//! step) for both presets and both specimens: the linear specimen takes the exact zero-order-hold
//! step, Bouc–Wen RK4 with 4 sub-steps; `rk4` rows force RK4 on the linear specimen for comparison.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use rths_core::hal::{Actuator, Daq};
use rths_hal_sim::{BoucWen, Integration, Preset, RigConfig, Specimen, VirtualRig};

fn plant_tick(c: &mut Criterion) {
    let mut group = c.benchmark_group("plant_tick");
    // A 2 Hz, 10 mm sine keeps the plant (and Bouc–Wen) busy; precomputed so that only the rig
    // is timed.
    let command: Vec<f64> = (0..1024)
        .map(|k| 10.0 * (k as f64 * std::f64::consts::TAU * 2.0 / 2048.0).sin())
        .collect();
    let cases = [
        (Specimen::Linear, Integration::ExactLinear, ""),
        (Specimen::Linear, Integration::Rk4, "/rk4"),
        (
            Specimen::BoucWen(BoucWen::default()),
            Integration::ExactLinear,
            "",
        ),
    ];
    for preset in [Preset::Benchmark, Preset::UnrCompact] {
        for (specimen, integration, tag) in cases {
            let mut cfg = RigConfig::new(preset);
            cfg.specimen = specimen;
            cfg.integration = integration;
            let Ok(params) = cfg.build() else {
                continue;
            };
            let mut rig = VirtualRig::new(params);
            let mut k = 0usize;
            let name = format!("{}/{}{tag}", preset.name(), specimen.name());
            group.bench_function(name, |b| {
                b.iter(|| {
                    k = (k + 1) % command.len();
                    let u = command.get(k).copied().unwrap_or(0.0);
                    let _ = rig.command(black_box(u));
                    rig.advance_tick();
                    black_box(rig.read())
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, plant_tick);
criterion_main!(benches);

//! ns per `advance_tick` of the virtual plant (one 1/2048 s controller step, 4 RK4 sub-steps),
//! for both presets and both specimens.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use rths_core::hal::{Actuator, Daq};
use rths_hal_sim::{BoucWen, Preset, RigConfig, Specimen, VirtualRig};

fn plant_tick(c: &mut Criterion) {
    let mut group = c.benchmark_group("plant_tick");
    for preset in [Preset::Benchmark, Preset::UnrCompact] {
        for specimen in [Specimen::Linear, Specimen::BoucWen(BoucWen::default())] {
            let mut cfg = RigConfig::new(preset);
            cfg.specimen = specimen;
            let Ok(params) = cfg.build() else {
                continue;
            };
            let mut rig = VirtualRig::new(params);
            let mut k = 0u64;
            group.bench_function(format!("{}/{}", preset.name(), specimen.name()), |b| {
                b.iter(|| {
                    // A 2 Hz, 10 mm sine keeps the plant (and Bouc–Wen) busy.
                    k = k.wrapping_add(1);
                    let u = 10.0 * (k as f64 * std::f64::consts::TAU * 2.0 / 2048.0).sin();
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

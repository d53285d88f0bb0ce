//! Cost of one step of the host FE of an imported OpenSees structure (`SparseNewmark::step`:
//! Newmark's average acceleration on the whole sparse model, factorized once) for the shipped
//! frames, 72 and 1,404 DOFs (docs/opensees.md). OpenSees's own time per step for the same models
//! is measured by `scripts/opensees/transient.py` (printed by `tests/opensees.rs`).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use rths::imported::fe::SparseNewmark;
use rths::imported::ImportedStructure;

const DT_4096_S: f64 = 1.0 / 4096.0;

fn frames(c: &mut Criterion) {
    let mut g = c.benchmark_group("imported_fe");
    for (name, file) in [
        ("frame_2x3_72dof", "data/structures/opensees-frame-2x3.json"),
        (
            "frame_5x12_1404dof",
            "data/structures/opensees-frame-5x12.json",
        ),
    ] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
        let s = ImportedStructure::load(&path).expect("the shipped frame loads");
        let mut fe = SparseNewmark::new(&s, DT_4096_S).expect("the host FE builds");
        let mut k = 0u32;
        g.bench_function(name, |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                fe.step(black_box(f64::from(k % 64) - 32.0));
                black_box(fe.interface_mm())
            })
        });
    }
    g.finish();
}

criterion_group!(benches, frames);
criterion_main!(benches);

//! Cost of one step of the run-time sized N-DOF analytical part (`ChangN::advance`: Chang's
//! method, the FE path of a structure file) for N = 1, 3, 8 shear buildings, ns per tick, beside
//! the compile-time sized `Chang<N>` and the fixed-order metamodel `meta-ats` uses (trained on
//! each building), whose cost does not depend on N (`docs/benchmark.md`).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use rths_core::integrator::{Chang, ExplicitIntegrator};
use rths_core::structure::{LinearStructure, ShearBuilding, Vector};
use rths_core::structure_n::{ChangN, StructureN, MAX_DOF};

const DT_4096_S: f64 = 1.0 / 4096.0;

fn building<const N: usize>() -> LinearStructure<N> {
    ShearBuilding::<N>::uniform(1.0, 30.0, 0.05)
        .model()
        .expect("valid building")
}

/// The same step with the compile-time sized `Chang<N>` (nalgebra static matrices), under the same
/// machine load: the reference the run-time sized one is compared with.
fn fixed<const N: usize>(g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>) {
    let mut integ = Chang::new(building::<N>(), DT_4096_S).expect("valid step");
    let mut k = 0u32;
    g.bench_function(format!("fixed_n{N}"), |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let ag = f64::from(k % 64) - 32.0;
            let mut r = Vector::<N>::zeros();
            r[0] = 0.01 * integ.next_displacement()[0];
            integ.advance(black_box(ag), black_box(&r));
            black_box(integ.next_displacement()[0])
        })
    });
}

fn model<const N: usize>() -> StructureN {
    let b = building::<N>();
    let flat = |m: &rths_core::structure::Mat<N>| -> Vec<f64> {
        (0..N * N).map(|k| m[(k / N, k % N)]).collect()
    };
    let gm = b.mass() * Vector::<N>::repeat(1.0);
    StructureN::new(
        N,
        &flat(b.mass()),
        &flat(b.damping()),
        &flat(b.stiffness()),
        &flat(b.initial_stiffness()),
        gm.as_slice(),
    )
    .expect("valid model")
}

/// The metamodel of an N-story building (as a structure file), trained as `meta-ats` trains it.
fn meta<const N: usize>(g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>) {
    let json = format!(
        r#"{{"format": "rths-structure", "version": 1, "name": "b{N}", "units": "mm-kn",
        "stories": {{"floor_mass": {m:?}, "story_stiffness": {k:?}, "damping_ratio": 0.05}},
        "specimen": {{"dof": 1, "mass": 0, "stiffness": 3.0, "damping": 0}}}}"#,
        m = vec![1.0; N],
        k = vec![30.0; N]
    );
    let s = rths_files::structure_file::Structure::from_json(&json).expect("valid building");
    let mut m = rths::studies::benchmark::meta::train(&s, 0.4).expect("trained");
    let mut k = 0u32;
    g.bench_function(format!("meta_n{N}"), |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let ag = f64::from(k % 64) - 32.0;
            let f = 0.01 * m.current_mm();
            black_box(m.step(black_box(ag), black_box(f)))
        })
    });
}

fn step(c: &mut Criterion) {
    let mut g = c.benchmark_group("chang_n_tick");
    for (n, m) in [(1, model::<1>()), (3, model::<3>()), (8, model::<8>())] {
        let mut integ = ChangN::new(m, DT_4096_S).expect("valid step");
        let mut k = 0u32;
        g.bench_function(format!("n{n}"), |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let ag = f64::from(k % 64) - 32.0;
                let mut r = [0.0; MAX_DOF];
                r[0] = 0.01 * integ.next_displacement()[0];
                integ.advance(black_box(ag), black_box(&r));
                black_box(integ.next_displacement()[0])
            })
        });
    }
    fixed::<1>(&mut g);
    fixed::<3>(&mut g);
    fixed::<8>(&mut g);
    meta::<1>(&mut g);
    meta::<3>(&mut g);
    meta::<8>(&mut g);
    g.finish();
}

criterion_group!(benches, step);
criterion_main!(benches);

//! Cost of one step of the nonlinear N-story frame (`NonlinearFrame::advance`: Chang's step with
//! every story's hysteresis evaluated) for N = 1, 3, 8, bilinear and Bouc–Wen, beside the linear
//! `ChangN` step of the same building, and the structure metamodel's step (`DeltaArx`, whose
//! cost does not depend on N), ns per tick (`docs/nonlinear.md`, `docs/benchmark.md`).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use rths_core::hysteresis::Law;
use rths_core::metamodel::{DeltaArx, DeltaArxParams, DELTA_ARX_COEFFS};
use rths_core::structure::{LinearStructure, ShearBuilding, Vector};
use rths_core::structure_n::{ChangN, StructureN, MAX_DOF};
use rths_core::structure_nl::NonlinearFrame;

const DT_S: f64 = 1.0 / 4096.0;
const K_STORY: f64 = 30.0;

fn building<const N: usize>() -> LinearStructure<N> {
    ShearBuilding::<N>::uniform(1.0, K_STORY, 0.05)
        .model()
        .expect("valid building")
}

/// The building as a `StructureN`, with its linear stiffness (`linear`) or none (the stories
/// carry it).
fn model<const N: usize>(linear: bool) -> StructureN {
    let b = building::<N>();
    let flat = |m: &rths_core::structure::Mat<N>| -> Vec<f64> {
        (0..N * N).map(|k| m[(k / N, k % N)]).collect()
    };
    let gm = b.mass() * Vector::<N>::repeat(1.0);
    let k_lin = if linear {
        flat(b.stiffness())
    } else {
        vec![0.0; N * N]
    };
    StructureN::new(
        N,
        &flat(b.mass()),
        &flat(b.damping()),
        &k_lin,
        &flat(b.initial_stiffness()),
        gm.as_slice(),
    )
    .expect("valid model")
}

fn step(c: &mut Criterion) {
    let mut g = c.benchmark_group("nonlinear_tick");
    let bilinear = Law::bilinear(K_STORY, 5.0, 0.05).expect("valid law");
    let bouc_wen = Law::bouc_wen(K_STORY, 5.0, 0.05, 2.0, 0.5, 0.5).expect("valid law");
    let cases: [(usize, StructureN, StructureN); 3] = [
        (1, model::<1>(false), model::<1>(true)),
        (3, model::<3>(false), model::<3>(true)),
        (8, model::<8>(false), model::<8>(true)),
    ];
    for (n, nl, lin) in cases {
        // A ground motion strong enough to keep the stories yielding.
        let ag = |k: u32| 400.0 * (f64::from(k % 64) - 32.0);
        for (name, law) in [("bilinear", bilinear), ("bouc_wen", bouc_wen)] {
            let mut f = NonlinearFrame::new(nl, &vec![law; n], DT_S).expect("valid frame");
            let mut k = 0u32;
            g.bench_function(format!("{name}_n{n}"), |b| {
                b.iter(|| {
                    k = k.wrapping_add(1);
                    let mut r = [0.0; MAX_DOF];
                    r[0] = 0.01 * f.next_displacement()[0];
                    f.advance(black_box(ag(k)), black_box(&r));
                    black_box(f.next_displacement()[0])
                })
            });
        }
        let mut integ = ChangN::new(lin, DT_S).expect("valid step");
        let mut k = 0u32;
        g.bench_function(format!("linear_n{n}"), |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let mut r = [0.0; MAX_DOF];
                r[0] = 0.01 * integ.next_displacement()[0];
                integ.advance(black_box(ag(k)), black_box(&r));
                black_box(integ.next_displacement()[0])
            })
        });
    }
    // The structure metamodel: nothing in its step depends on N (the same histories and
    // coefficients for any structure), so one row stands for N = 1, 3, 8.
    let ag = |k: u32| 400.0 * (f64::from(k % 64) - 32.0);
    // The metamodel's cost is that of its fixed order: any stable coefficients measure it
    // (a trained model's are no cheaper or dearer: the same 18 multiply-adds).
    let mut theta = [0.0; DELTA_ARX_COEFFS];
    theta[1] = 0.9;
    theta[6] = 1e-9;
    theta[12] = -1e-6;
    let mut meta = DeltaArx::new(DeltaArxParams::from_slice(&theta, 1.0).expect("valid"));
    let mut k = 0u32;
    g.bench_function("meta_any_n", |b| {
        b.iter(|| {
            k = k.wrapping_add(1);
            let x = meta.current_mm();
            black_box(meta.predict(black_box(ag(k)), black_box(x), black_box(0.01 * x)))
        })
    });
    g.finish();
}

criterion_group!(benches, step);
criterion_main!(benches);

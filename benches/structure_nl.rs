//! Cost of one step of the nonlinear N-story frame (`NonlinearFrame::advance`: Chang's step with
//! every story's hysteresis evaluated) for N = 1, 3, 8, bilinear and Bouc–Wen, beside the linear
//! `ChangN` step of the same building, and the structure metamodel's step (`DeltaArx`, whose
//! cost does not depend on N), ns per tick (`docs/nonlinear.md`, `docs/benchmark.md`);
//! and one step of the modal-hysteretic
//! metamodel of the same building (every mode, one Bouc–Wen or bilinear spring per story:
//! `ModalHyst::step`), the learned model's cost (`docs/nonlinear.md`); and the shipped
//! floor-hysteron model of the fiber frame (`FloorHysteron::step`).

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use rths::machinery::motion::GroundMotion;
use rths::machinery::train::nonlinear::modal::elastic_modes;
use rths_core::hysteresis::Law;
use rths_core::metamodel::{DeltaArx, DeltaArxParams, DELTA_ARX_COEFFS};
use rths_core::metamodel::{FloorHysteron, ModalHyst, ModalHystParams, ModalMode};
use rths_core::structure::{LinearStructure, ShearBuilding, Vector};
use rths_core::structure_n::{ChangN, StructureN, MAX_DOF};
use rths_core::structure_nl::NonlinearFrame;

const DT_4096_S: f64 = 1.0 / 4096.0;
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
            let mut f = NonlinearFrame::new(nl, &vec![law; n], DT_4096_S).expect("valid frame");
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
        let mut integ = ChangN::new(lin, DT_4096_S).expect("valid step");
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

/// The modal-hysteretic model of the uniform N-story building (story 1 holding a specimen of
/// `0.01` kN/mm, as the FE rows' external spring), every mode, one spring per story.
fn modal_model(n: usize, law: &str) -> ModalHyst {
    let json = format!(
        r#"{{"format": "rths-structure", "version": 1, "name": "bench", "units": "mm-kn",
            "stories": {{"floor_mass": {m:?}, "story_stiffness": {k:?}, "damping_ratio": 0.05}},
            "specimen": {{"dof": 1, "mass": 0.0, "stiffness": 0.01, "damping": 0.0}}}}"#,
        m = vec![1.0; n],
        k = vec![K_STORY; n],
    );
    let s = rths_files::structure_file::Structure::from_json(&json).expect("valid structure");
    let modes = elastic_modes(&s, n).expect("modes");
    let laws: Vec<Law> = modes
        .story_k0_kn_per_mm
        .iter()
        .map(|k0| match law {
            "bilinear" => Law::bilinear(*k0, 5.0, 0.05),
            _ => Law::bouc_wen(*k0, 5.0, 0.05, 2.0, 0.5, 0.5),
        })
        .collect::<Result<_, _>>()
        .expect("valid laws");
    let mm: Vec<ModalMode> = (0..n)
        .map(|j| ModalMode {
            omega_rad_s: modes.omega_rad_s[j],
            damping_ratio: modes.damping_ratio[j],
            ground_participation: modes.ground_participation[j],
        })
        .collect();
    let shape: Vec<f64> = modes.shape.iter().flatten().copied().collect();
    let drift: Vec<f64> = modes.drift.iter().flatten().copied().collect();
    ModalHyst::new(
        ModalHystParams::new(DT_4096_S, &mm, &shape, 0, 0.01, &laws, &drift).expect("valid model"),
    )
}

fn metamodel_step(c: &mut Criterion) {
    let mut g = c.benchmark_group("nonlinear_metamodel_tick");
    for n in [1, 3, 8] {
        for law in ["bilinear", "bouc_wen"] {
            let mut m = modal_model(n, law);
            let ag = |k: u32| 400.0 * (f64::from(k % 64) - 32.0);
            let mut k = 0u32;
            let mut target = 0.0;
            g.bench_function(format!("modal_{law}_n{n}"), |b| {
                b.iter(|| {
                    k = k.wrapping_add(1);
                    target = m
                        .step(black_box(ag(k)), black_box(0.01 * target))
                        .unwrap_or(0.0);
                    black_box(target)
                })
            });
        }
    }
    g.finish();
}

/// The FE numerical part of a shipped yielding structure and its modal-hysteretic model with every
/// mode and the structure's own laws (a trained model has the same cost: the same laws, other
/// numbers), both in the pure loop under El Centro × 2 (looped): the cost on a real record.
fn shipped(c: &mut Criterion) {
    let mut g = c.benchmark_group("nonlinear_shipped_tick");
    let ag = GroundMotion::try_el_centro()
        .expect("embedded record")
        .scaled(2.0)
        .resample_mm_s2(DT_4096_S);
    for file in ["paper-frame-yielding", "shear3-yielding"] {
        let path = format!("{}/data/structures/{file}.json", env!("CARGO_MANIFEST_DIR"));
        let s = rths_files::structure_file::Structure::load(std::path::Path::new(&path))
            .expect("shipped structure");
        let k_e = s.specimen().1;
        let mut fe = s
            .nonlinear_numerical(DT_4096_S)
            .expect("nonlinear structure");
        let mut k = 0usize;
        g.bench_function(format!("fe_{file}"), |b| {
            b.iter(|| {
                k = (k + 1) % ag.len();
                let mut r = [0.0; MAX_DOF];
                r[0] = k_e * fe.next_displacement()[0];
                fe.advance(black_box(ag[k]), black_box(&r));
                black_box(fe.next_displacement()[0])
            })
        });
        let n = s.dofs();
        let modes = elastic_modes(&s, n).expect("modes");
        let laws = s.story_laws().expect("yielding stories");
        let mm: Vec<ModalMode> = (0..n)
            .map(|j| ModalMode {
                omega_rad_s: modes.omega_rad_s[j],
                damping_ratio: modes.damping_ratio[j],
                ground_participation: modes.ground_participation[j],
            })
            .collect();
        let shape: Vec<f64> = modes.shape.iter().flatten().copied().collect();
        let drift: Vec<f64> = modes.drift.iter().flatten().copied().collect();
        let mut m = ModalHyst::new(
            ModalHystParams::new(DT_4096_S, &mm, &shape, 0, k_e, laws, &drift)
                .expect("valid model"),
        );
        step_through(&mut g, &format!("modal_{file}"), &ag, k_e, |a, f| {
            m.step(a, f).ok()
        });
    }
    // The floor-hysteron model learned from OpenSees runs of the fiber-section frame (issue 25):
    // its cost is its floors and hysterons, nothing of the frame's elements or fibers.
    let path = format!(
        "{}/data/models/nl-fiber-frame-hysteron.json",
        env!("CARGO_MANIFEST_DIR")
    );
    let file =
        rths_files::hysteron_model_file::HysteronModelFile::load(std::path::Path::new(&path))
            .expect("shipped model");
    let k_e = file.specimen_stiffness_kn_per_mm;
    let mut m = FloorHysteron::new(file.params(DT_4096_S).expect("valid model"));
    step_through(&mut g, "hysteron_nl-fiber-frame", &ag, k_e, |a, f| {
        m.step(a, f).ok()
    });
    g.finish();
}

/// One tick of a learned model per iteration, along the record `ag` (mm/s²), the specimen's
/// force `k_e` times the last target fed back.
fn step_through(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    ag: &[f64],
    k_e: f64,
    mut step: impl FnMut(f64, f64) -> Option<f64>,
) {
    let (mut k, mut target) = (0usize, 0.0);
    g.bench_function(name, |b| {
        b.iter(|| {
            k = (k + 1) % ag.len();
            target = step(black_box(ag[k]), black_box(k_e * target)).unwrap_or(0.0);
            black_box(target)
        })
    });
}

criterion_group!(benches, step, metamodel_step, shipped);
criterion_main!(benches);

//! Cost of one step of an imported OpenSees structure, side by side, for the shipped frames (72
//! and 1,404 DOFs, docs/opensees.md): OpenSees's own transient analysis of the same model
//! (`scripts/opensees/transient.py` on 2 s of El Centro, printed before the timings; a loud
//! `SKIPPED:` line without openseespy), the host FE's step (`SparseNewmark::step`: Newmark on the
//! whole sparse model, factorized once) and the reduced model's (`StructureReduced::next_target`,
//! the analytical part core's controller steps; trained as `rths train meta` trains it, which
//! takes about 16 s for the large frame before its timing starts).

use std::ffi::OsString;
use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use rths::machinery::imported::fe::SparseNewmark;
use rths::machinery::imported::{export, reduced, ImportedStructure};
use rths_core::control::StructureReduced;
use rths_files::motion::GroundMotion;

const DT_4096_S: f64 = 1.0 / 4096.0;

const FRAMES: [(&str, &str, &str); 2] = [
    (
        "frame_2x3_72dof",
        "data/structures/opensees-frame-2x3.json",
        "frame-2x3.py",
    ),
    (
        "frame_5x12_1404dof",
        "data/structures/opensees-frame-5x12.json",
        "frame-5x12.py",
    ),
];

/// OpenSees's time per step on `script` under 2 s of El Centro at `DT_4096_S`, s; `Err` says why not.
fn opensees_per_step(script: &str) -> Result<f64, String> {
    export::python_command().map_err(|e| e.to_string())?;
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    let ag = GroundMotion::embedded("el-centro")
        .ok_or("El Centro is embedded")?
        .resample_mm_s2(DT_4096_S);
    let text: String = ag
        .iter()
        .take((2.0 / DT_4096_S) as usize)
        .map(|v| format!("{v:e}\n"))
        .collect();
    let record = dir.path().join("ag.txt");
    std::fs::write(&record, text).map_err(|e| e.to_string())?;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let args: Vec<OsString> = vec![
        root.join("data/structures/opensees").join(script).into(),
        "--record".into(),
        record.into(),
        "--dt".into(),
        format!("{DT_4096_S:e}").into(),
        "--dofs".into(),
        "1:1".into(),
        "--out".into(),
        dir.path().join("out.csv").into(),
    ];
    let stdout = export::run_script(export::TRANSIENT, "transient.py", dir.path(), &args)
        .map_err(|e| e.to_string())?;
    let timing: serde_json::Value =
        serde_json::from_str(stdout.trim()).map_err(|e| e.to_string())?;
    timing["per_step_s"]
        .as_f64()
        .ok_or_else(|| "no per_step_s".to_string())
}

fn frames(c: &mut Criterion) {
    let mut g = c.benchmark_group("imported_fe");
    for (name, file, script) in FRAMES {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(file);
        let s = ImportedStructure::load(&path).expect("the shipped frame loads");
        match opensees_per_step(script) {
            Ok(t) => println!("{name}/opensees: {:.1} us per step (transient.py)", t * 1e6),
            Err(e) => println!("SKIPPED: openseespy ({name}: {e})"),
        }
        let mut fe = SparseNewmark::new(&s, DT_4096_S).expect("the host FE builds");
        let mut k = 0u32;
        g.bench_function(format!("{name}/host_fe"), |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                fe.step(black_box(f64::from(k % 64) - 32.0));
                black_box(fe.interface_mm())
            })
        });
        let records = reduced::training_records(DT_4096_S).expect("embedded training records");
        let file = reduced::train(&s, &records, DT_4096_S, |_, _, _| {}).expect("training");
        let params = reduced::hybrid_params(&file, &s, DT_4096_S).expect("the frame's model");
        println!("{name}/reduced: {} modes", params.modes());
        let mut part = StructureReduced::new(params);
        let k_e = s.specimen_stiffness_kn_per_mm();
        let mut target = 0.0;
        g.bench_function(format!("{name}/reduced"), |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let ag = black_box(f64::from(k % 64) - 32.0);
                target = part.next_target(ag, k_e * target).unwrap_or(0.0);
                black_box(target)
            })
        });
    }
    g.finish();
}

criterion_group!(benches, frames);
criterion_main!(benches);

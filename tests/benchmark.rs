//! The vRTHS benchmark: structure files (shipped ones agree with their sources; bad ones are refused
//! with the reason), the N-DOF path on the paper's frame, records that do not match, benchmark runs
//! (stable, finite J's), a 5-story file under the benchmark plant, and the identified controller.

use std::path::Path;

use rths::cmd::benchmark::history_columns;
use rths::studies::benchmark::plant::PlantDraw;
use rths::studies::benchmark::run::{check_record, run, run_on, ControllerKind, RunConfig};
use rths::studies::benchmark::{case_structure, BenchmarkRecord};
use rths_core::integrator::{Chang, ExplicitIntegrator};
use rths_core::params::{Prototype, DT_S};
use rths_core::structure::{LinearStructure, Vector};
use rths_core::structure_n::{ChangN, MAX_DOF};
use rths_files::motion::parse_csv;
use rths_files::structure_file::{Structure, SI_TO_MM_KN};
use rths_hal_sim::params::{
    BENCHMARK_SPECIMEN_STIFFNESS_N_PER_M, NOMINAL_SPECIMEN_DAMPING_RATIO, NOMINAL_SPECIMEN_MASS_KG,
};

fn root(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

#[test]
fn shipped_case_files_equal_the_benchmark_data() {
    let text = std::fs::read_to_string(root("data/vrths_benchmark/structure_cases.json")).unwrap();
    let src: serde_json::Value = serde_json::from_str(&text).unwrap();
    for case in 1..=4u8 {
        let s = case_structure(case).unwrap();
        let on_disk =
            Structure::load(&root(&format!("data/structures/vrths-case{case}.json"))).unwrap();
        assert_eq!(s, on_disk, "embedded and data/structures agree");
        let c = &src["cases"][format!("case_{case}")];
        for (key, m) in [
            ("mass_kg", s.mass()),
            ("stiffness_n_per_m", s.stiffness()),
            ("damping_n_s_per_m", s.damping()),
        ] {
            for i in 0..3 {
                for j in 0..3 {
                    let v = c[key][i][j].as_f64().unwrap();
                    assert_eq!(m[(i, j)], v * SI_TO_MM_KN, "case {case} {key}[{i}][{j}]");
                }
            }
        }
        // The specimen subtracted is the benchmark plant's.
        let (m_e, k_e, c_e) = s.specimen();
        assert_eq!(s.specimen_dof(), 0);
        assert_eq!(m_e, NOMINAL_SPECIMEN_MASS_KG * SI_TO_MM_KN);
        assert_eq!(k_e, BENCHMARK_SPECIMEN_STIFFNESS_N_PER_M * SI_TO_MM_KN);
        let c_expected = 2.0
            * NOMINAL_SPECIMEN_DAMPING_RATIO
            * (NOMINAL_SPECIMEN_MASS_KG * BENCHMARK_SPECIMEN_STIFFNESS_N_PER_M).sqrt()
            * SI_TO_MM_KN;
        assert!((c_e - c_expected).abs() < 1e-12 * c_expected);
    }
    // The data README's frequencies of case 1.
    let f = case_structure(1).unwrap().natural_frequencies_hz();
    for (got, want) in f.iter().zip([3.612, 15.997, 38.086]) {
        assert!((got - want).abs() < 1e-3, "{f:?}");
    }
}

#[test]
fn paper_frame_file_is_the_prototype_and_integrates_as_the_fe_path() {
    let s = Structure::load(&root("data/structures/paper-frame.json")).unwrap();
    let p = Prototype::paper();
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
    assert!(close(s.mass()[(0, 0)], p.mass_kn_s2_per_mm()));
    assert!(close(s.stiffness()[(0, 0)], p.total_stiffness_kn_per_mm()));
    assert!(close(s.damping()[(0, 0)], p.damping_kn_s_per_mm()));
    let (m_n, k_n, c_n) = s.numerical_matrices();
    assert!(close(m_n[(0, 0)], p.mass_kn_s2_per_mm()));
    assert!(close(k_n[(0, 0)], p.frame_stiffness_kn_per_mm()));
    assert!(close(c_n[(0, 0)], p.damping_kn_s_per_mm()));
    // El Centro through both: the file's N-DOF path and the compiled-in FE path.
    let ag = rths::machinery::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
    let mut fe = Chang::new(LinearStructure::prototype_hybrid(&p).unwrap(), DT_S).unwrap();
    let mut nd = ChangN::new(s.numerical().unwrap(), DT_S).unwrap();
    fe.reset(ag[0]);
    nd.reset(ag[0]);
    let (mut worst, mut peak) = (0.0_f64, 0.0_f64);
    for &a in &ag[1..] {
        let r = p.brace_lateral_stiffness_kn_per_mm() * fe.next_displacement()[0];
        fe.advance(a, &Vector::<1>::new(r));
        let mut ext = [0.0; MAX_DOF];
        ext[0] = p.brace_lateral_stiffness_kn_per_mm() * nd.next_displacement()[0];
        nd.advance(a, &ext);
        worst = worst.max((fe.state().disp[0] - nd.disp()[0]).abs());
        peak = peak.max(fe.state().disp[0].abs());
    }
    assert!(peak > 10.0, "El Centro drives the frame: {peak} mm");
    assert!(worst < 1e-9 * peak, "file path vs FE path: {worst} mm");
}

fn refusal(json: &str) -> String {
    match Structure::from_json(json) {
        Ok(_) => panic!("accepted: {json}"),
        Err(e) => e.to_string(),
    }
}

fn case1_with(edit: impl Fn(&mut serde_json::Value)) -> String {
    let mut v: serde_json::Value =
        serde_json::from_str(rths::studies::benchmark::case_text(1).unwrap()).unwrap();
    edit(&mut v);
    v.to_string()
}

#[test]
fn bad_structure_files_are_refused_with_the_reason() {
    let e = refusal(&case1_with(|v| {
        v["matrices"]["stiffness"][0][1] = 1.0e6.into()
    }));
    assert!(e.contains("stiffness is not symmetric: entry (1,2)"), "{e}");
    let e = refusal(&case1_with(|v| v["matrices"]["mass"][2][2] = (-1.0).into()));
    assert!(e.contains("mass is not positive definite"), "{e}");
    let e = refusal(&case1_with(|v| {
        v["matrices"]["stiffness"] = serde_json::json!([[1, 0, 0], [0, -1, 0], [0, 0, 1]])
    }));
    assert!(e.contains("stiffness is not positive definite"), "{e}");
    let e = refusal(&case1_with(|v| v["specimen"]["dof"] = 4.into()));
    assert!(
        e.contains("specimen is on DOF 4, but the structure has DOFs 1..=3"),
        "{e}"
    );
    let e = refusal(&case1_with(|v| v["specimen"]["mass"] = 2000.0.into()));
    assert!(e.contains("numerical mass"), "{e}");
    let e = refusal(&case1_with(|v| {
        v["matrices"]["damping"][1] = serde_json::json!([1, 2])
    }));
    assert!(
        e.contains("damping: expected 3 entries in row 2, found 2"),
        "{e}"
    );
    let e = refusal(&case1_with(|v| v["version"] = 7.into()));
    assert!(e.contains("version 7"), "{e}");
    let nine = serde_json::json!({"format": "rths-structure", "version": 1, "name": "tall",
        "units": "mm-kn", "stories": {"floor_mass": vec![1.0; 9], "story_stiffness": vec![100.0; 9],
        "damping_ratio": 0.02}, "specimen": {"dof": 1, "mass": 0, "stiffness": 1, "damping": 0}});
    let e = refusal(&nine.to_string());
    assert!(e.contains("9 DOFs; 1..=8"), "{e}");
    let e = refusal(&case1_with(|v| {
        v["stories"] = serde_json::json!({"floor_mass": [1.0], "story_stiffness": [1.0],
            "damping_ratio": 0.02})
    }));
    assert!(
        e.contains("exactly one of \"matrices\" and \"stories\""),
        "{e}"
    );
    // A record that does not match the two-column uniform format is refused with its line.
    let bad = "time_s,accel_g\n0,0\n0.02,0.1\n0.05,0.2\n0.07,0.1\n";
    let e = parse_csv(bad, "bad").unwrap_err().to_string();
    assert!(e.contains("line 4"), "{e}");
    // Damping that feeds energy in, and a specimen stiffer than the structure at its DOF.
    let e = refusal(&case1_with(|v| {
        v["matrices"]["damping"] = serde_json::json!([[1, 0, 0], [0, -1, 0], [0, 0, 1]])
    }));
    assert!(e.contains("damping is not positive semi-definite"), "{e}");
    let e = refusal(&case1_with(|v| v["specimen"]["stiffness"] = 1.0e9.into()));
    assert!(
        e.contains("numerical stiffness (whole stiffness minus the specimen's) is not positive semi-definite"),
        "{e}"
    );
}

/// A CSV record at `dt_s` lasting `duration_s`.
fn csv_record(dt_s: f64, duration_s: f64) -> String {
    let n = (duration_s / dt_s).round() as usize;
    let mut s = String::from("time_s,accel_g\n");
    for k in 0..=n {
        let t = k as f64 * dt_s;
        s.push_str(&format!(
            "{t},{}\n",
            0.1 * (2.0 * std::f64::consts::PI * 2.0 * t).sin()
        ));
    }
    s
}

#[test]
fn records_that_do_not_match_the_benchmark_are_refused() {
    // Rate: finer than the benchmark's 4096 Hz tick.
    let fine = parse_csv(&csv_record(1.0 / 8192.0, 3.0), "fine").unwrap();
    let e = check_record(&fine).unwrap_err().to_string();
    assert!(
        e.contains("8192.0 Hz, above the benchmark's 4096 Hz"),
        "{e}"
    );
    // Length: shorter than 2 s.
    let short = parse_csv(&csv_record(0.01, 1.0), "short").unwrap();
    let e = check_record(&short).unwrap_err().to_string();
    assert!(e.contains("1.000 s long"), "{e}");
    // At the benchmark's rate, 3 s: accepted.
    check_record(&parse_csv(&csv_record(1.0 / 4096.0, 3.0), "ok").unwrap()).unwrap();
    // And a run refuses it before anything runs.
    let cfg = RunConfig {
        case: 0,
        record: BenchmarkRecord::ElCentro,
        intensity: 0.4,
        plant: PlantDraw::Nominal,
        controller: ControllerKind::FeAts,
    };
    let e = run_on(&case_structure(1).unwrap(), &short, &cfg)
        .unwrap_err()
        .to_string();
    assert!(e.contains("1.000 s long"), "{e}");
}

/// A 5-story shear building with the specimen on floor 2: the N-DOF path of `--structure`
/// (numerical part, reference, history columns, J's) on a structure that is not the benchmark's.
#[test]
fn a_five_story_structure_file_runs_under_the_benchmark_plant() {
    let json = serde_json::json!({"format": "rths-structure", "version": 1, "name": "shear5",
        "units": "si", "stories": {"floor_mass": [2000.0, 1800.0, 1800.0, 1600.0, 1500.0],
        "story_stiffness": [16.0e6, 14.0e6, 12.0e6, 10.0e6, 8.0e6], "damping_ratio": 0.02},
        "specimen": {"dof": 2, "mass": 29.13, "stiffness": 1.19e6, "damping_ratio": 0.0097}});
    let s = Structure::from_json(&json.to_string()).unwrap();
    assert_eq!((s.dofs(), s.specimen_dof()), (5, 1));
    let cfg = RunConfig {
        case: 0,
        record: BenchmarkRecord::ElCentro,
        intensity: 0.4,
        plant: PlantDraw::Nominal,
        controller: ControllerKind::FeAts,
    };
    let r = run_on(&s, &BenchmarkRecord::ElCentro.motion().unwrap(), &cfg).unwrap();
    assert!(r.unstable.is_none(), "{:?}", r.unstable);
    let h = &r.history;
    assert_eq!((h.floors_mm.len(), h.reference_mm.len()), (5, 5));
    assert!(h.reference_mm.iter().all(|f| f.len() == h.time_s.len()));
    // Stiff enough that the specimen's force stays inside the load cell's ±8900 N.
    assert_eq!(r.clipped_force_ticks, 0);
    let j = r.criteria.unwrap();
    println!("{j:?}");
    assert!(j.as_array().iter().all(|v| v.is_finite()), "{j:?}");
    // The measured floor 2 follows the reference (measured: J4 2.48 %, J6/J7 1.04/0.97 %).
    assert!(j.j4_pct < 3.0 && j.j6_pct < 1.5 && j.j7_pct < 1.5, "{j:?}");
    assert_eq!(
        history_columns(5, 1).join(","),
        "time_s,x2_mm,target2_mm,x1_mm,x3_mm,x4_mm,x5_mm,r1_mm,r2_mm,r3_mm,r4_mm,r5_mm"
    );
    // The benchmark's own 3 stories keep the columns.
    assert_eq!(
        history_columns(3, 0).join(","),
        "time_s,x1_mm,target1_mm,x2_mm,x3_mm,r1_mm,r2_mm,r3_mm"
    );
}

/// The identified controller: the rig identified at 4096 Hz through the converters (lead, its
/// online correction, the specimen's stiffness for the force correction), then the metamodel.
#[test]
fn the_identified_metamodel_meets_j4_on_case_1_el_centro() {
    let r = run(&RunConfig {
        case: 1,
        record: BenchmarkRecord::ElCentro,
        intensity: 0.4,
        plant: PlantDraw::Nominal,
        controller: ControllerKind::MetaId,
    })
    .unwrap();
    assert!(r.unstable.is_none(), "{:?}", r.unstable);
    let id = r.identification.as_ref().unwrap();
    // The identified specimen (measured data only) against the benchmark's 1.19 kN/mm, 29.13 kg.
    let k = id.specimen.stiffness_kn_per_mm;
    assert!((k - 1.19).abs() < 0.01 * 1.19, "{k}");
    assert!((id.specimen.mass_kn_s2_per_mm - 29.13e-6).abs() < 0.05 * 29.13e-6);
    assert_eq!(r.force_correction_kn_per_mm, Some(k));
    let j = r.criteria.unwrap();
    println!("{j:?}");
    // Measured: J4 3.33 %, J6/J7 2.93/2.84 % (docs/benchmark.md); the goal is J4 ≤ 4 %.
    assert!(j.j4_pct < 3.6, "{j:?}");
    assert!(j.j6_pct < 3.3 && j.j7_pct < 3.3, "{j:?}");
}

#[test]
fn a_benchmark_run_is_stable_with_finite_criteria() {
    let r = run(&RunConfig {
        case: 1,
        record: BenchmarkRecord::ElCentro,
        intensity: 0.4,
        plant: PlantDraw::Nominal,
        controller: ControllerKind::FeAts,
    })
    .unwrap();
    assert!(r.unstable.is_none(), "{:?}", r.unstable);
    let j = r.criteria.unwrap();
    println!("{j:?}");
    assert!(j.as_array().iter().all(|v| v.is_finite()));
    assert_eq!(r.history.time_s.len(), r.history.reference_mm[2].len());
    // Measured on this run: J2 2.69 %, J4 2.94 %, J6/J7 1.23 % (docs/benchmark.md); the bounds
    // leave room for round-off across platforms, not for a regression.
    assert!(j.j2_pct < 3.0 && j.j4_pct < 3.5, "{j:?}");
    assert!(j.j6_pct < 1.5 && j.j7_pct < 1.5, "{j:?}");
}

#[test]
fn the_metamodel_is_within_a_point_of_fe_ats() {
    let cfg = |controller| RunConfig {
        case: 1,
        record: BenchmarkRecord::Morgan,
        intensity: 0.4,
        plant: PlantDraw::Perturbed(1),
        controller,
    };
    let fe = run(&cfg(ControllerKind::FeAts)).unwrap().criteria.unwrap();
    let meta = run(&cfg(ControllerKind::MetaAts))
        .unwrap()
        .criteria
        .unwrap();
    println!("fe-ats {fe:?}\nmeta-ats {meta:?}");
    // Measured: J4 3.52 % (fe-ats) and 3.34 % (meta-ats) on this plant; Morgan Hill is never
    // used for training.
    assert!(meta.j4_pct <= fe.j4_pct + 1.0, "{meta:?} vs {fe:?}");
    assert!(meta.j6_pct < 2.0 && meta.j7_pct < 2.0, "{meta:?}");
}

#[test]
fn bad_benchmark_arguments_are_refused() {
    let mut cfg = RunConfig {
        case: 5,
        record: BenchmarkRecord::Kobe,
        intensity: 0.4,
        plant: PlantDraw::Nominal,
        controller: ControllerKind::Fe,
    };
    assert!(run(&cfg).unwrap_err().to_string().contains("cases 1..=4"));
    cfg.case = 1;
    cfg.intensity = f64::NAN;
    assert!(run(&cfg).unwrap_err().to_string().contains("intensity"));
}

/// The whole grid (12 cells × 21 plants, both ATS controllers):
/// `cargo test --features sim --test benchmark -- --ignored` (about 2 minutes).
#[test]
#[ignore]
fn whole_grid_is_stable() {
    for controller in [ControllerKind::FeAts, ControllerKind::MetaAts] {
        grid_meets_the_goals(controller);
    }
}

/// The identified controller over the grid: stable on every plant and J4 ≤ 8 % on every perturbed
/// one (measured max 5.09 %); its nominal J4 misses 4 % on Morgan Hill (docs/benchmark.md).
/// `cargo test --features sim --test benchmark -- --ignored` (about a minute more).
#[test]
#[ignore]
fn identified_grid_is_stable() {
    let g = rths::studies::benchmark::grid::run_grid(ControllerKind::MetaId, 0.4, 20).unwrap();
    println!("{}", g.table());
    for c in &g.cells {
        assert!(c.nominal.is_some(), "case {} {}", c.case, c.record);
        assert_eq!(c.perturbed_unstable, 0, "case {} {}", c.case, c.record);
        assert!(c.perturbed_max_j4_pct.is_some_and(|j4| j4 <= 6.0));
    }
}

fn grid_meets_the_goals(controller: ControllerKind) {
    let g = rths::studies::benchmark::grid::run_grid(controller, 0.4, 20).unwrap();
    println!("{}", g.table());
    for c in &g.cells {
        let j = c
            .nominal
            .unwrap_or_else(|| panic!("case {} {} unstable", c.case, c.record));
        assert_eq!(c.perturbed_unstable, 0, "case {} {}", c.case, c.record);
        // The goals: J4 ≤ 4 %, J6-J7 ≤ 4 % nominal; J4 ≤ 8 % on every perturbed plant.
        assert!(
            j[3] <= 4.0 && j[5] <= 4.0 && j[6] <= 4.0,
            "case {} {}: {j:?}",
            c.case,
            c.record
        );
        assert!(
            c.perturbed_max_j4_pct.is_some_and(|j4| j4 <= 8.0),
            "case {} {}",
            c.case,
            c.record
        );
    }
}

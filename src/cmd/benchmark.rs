//! `rths benchmark`: the vRTHS benchmark problem (Silva et al. 2020): one case × record with J1-J9,
//! its history and figure, or (with neither `--case` nor `--record`) the whole grid and its table.
//! See `docs/benchmark.md`.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::machinery::plot::{self, Panel};
use crate::studies::benchmark::grid::run_grid;
use crate::studies::benchmark::plant::PlantDraw;
use crate::studies::benchmark::run::{
    run as run_one, run_on, BenchmarkRun, ControllerKind, RunConfig,
};
use crate::studies::benchmark::{BenchmarkRecord, DEFAULT_INTENSITY, PERTURBED_PLANTS};

/// Arguments of `rths benchmark`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Partitioning case, 1..4 (with --record; neither: the whole grid).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=4))]
    pub case: Option<u8>,
    /// Ground-motion record (with --case or --structure).
    #[arg(long, value_enum)]
    pub record: Option<BenchmarkRecord>,
    /// Run this structure file (N ≤ 8 DOFs, the specimen on its DOF) instead of a case, with
    /// --record or --record-file.
    #[arg(long, value_name = "FILE", conflicts_with = "case")]
    pub structure: Option<PathBuf>,
    /// A two-column CSV record `time_s,accel_g` (with --structure): uniform step no finer than
    /// 1/4096 s, 2..=600 s long.
    #[arg(
        long,
        value_name = "CSV",
        requires = "structure",
        conflicts_with = "record"
    )]
    pub record_file: Option<PathBuf>,
    /// Factor on the ground acceleration.
    #[arg(long, default_value_t = DEFAULT_INTENSITY)]
    pub intensity: f64,
    /// Run on a plant drawn from the benchmark's uncertainty (with --seed); the number of perturbed
    /// plants per cell in the grid (default 20).
    #[arg(long, value_name = "N")]
    pub perturbed: Option<u64>,
    /// Seed of the perturbed plant of a single run.
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,
    /// Controller.
    #[arg(long, value_enum, default_value = "fe-ats")]
    pub controller: ControllerKind,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
    /// Write history.csv and benchmark.png (single run) or table.md (grid) into this directory.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// Run `rths benchmark`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(dir) = &args.out {
        crate::machinery::output::writable_dir(dir)?;
    }
    if let Some(path) = &args.structure {
        return structure_run(&args, path);
    }
    match (args.case, args.record) {
        (Some(case), Some(record)) => single(&args, case, record),
        (None, None) => grid(&args),
        _ => anyhow::bail!("give both --case and --record (one run), or neither (the whole grid)"),
    }
}

fn plant_of(args: &Args) -> anyhow::Result<PlantDraw> {
    Ok(match (args.perturbed, args.seed) {
        (None, None) => PlantDraw::Nominal,
        (Some(_), Some(seed)) | (None, Some(seed)) => PlantDraw::Perturbed(seed),
        (Some(n), None) => {
            anyhow::bail!("--perturbed {n} on one run needs --seed S (the plant to draw)")
        }
    })
}

/// `--structure FILE`: one run of a structure file under the benchmark plant.
fn structure_run(args: &Args, path: &Path) -> anyhow::Result<()> {
    let structure = rths_files::structure_file::Structure::load(path)
        .with_context(|| format!("structure file {}", path.display()))?;
    let (record, motion) = match (&args.record_file, args.record) {
        (Some(csv), None) => (
            BenchmarkRecord::ElCentro,
            crate::machinery::motion::GroundMotion::from_path(csv)
                .with_context(|| format!("record {}", csv.display()))?,
        ),
        (None, Some(r)) => (r, r.motion()?),
        _ => anyhow::bail!("--structure needs --record NAME or --record-file CSV"),
    };
    let cfg = RunConfig {
        // Not one of the four cases: the label 0, and the metamodel is trained for this file.
        case: 0,
        record,
        intensity: args.intensity,
        plant: plant_of(args)?,
        controller: args.controller,
    };
    finish_single(args, &run_on(&structure, &motion, &cfg)?)
}

fn single(args: &Args, case: u8, record: BenchmarkRecord) -> anyhow::Result<()> {
    let cfg = RunConfig {
        case,
        record,
        intensity: args.intensity,
        plant: plant_of(args)?,
        controller: args.controller,
    };
    finish_single(args, &run_one(&cfg)?)
}

fn finish_single(args: &Args, r: &BenchmarkRun) -> anyhow::Result<()> {
    if args.json {
        crate::outln!("{}", serde_json::to_string_pretty(&single_json(r))?);
    } else {
        print_single(r);
    }
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let csv = dir.join("history.csv");
        write_history(r, &csv)?;
        let png = dir.join("benchmark.png");
        draw(r, &png)?;
        if !args.json {
            crate::outln!("wrote {} and {}", csv.display(), png.display());
        }
    }
    if let Some(why) = &r.unstable {
        return Err(crate::cmd::RunStopped(why.clone()).into());
    }
    Ok(())
}

fn single_json(r: &BenchmarkRun) -> serde_json::Value {
    serde_json::json!({
        "case": r.config.case,
        "structure": r.structure_name,
        "record": r.record_name,
        "intensity": r.config.intensity,
        "plant": r.config.plant,
        "controller": r.config.controller,
        "specimen_stiffness_n_per_m": r.specimen_stiffness_n_per_m,
        "ticks": r.history.time_s.len(),
        "clipped_force_ticks": r.clipped_force_ticks,
        "unstable": r.unstable,
        "ats_coefficients": r.ats_coefficients,
        "lead_adaptation": r.lead_adaptation.map(|[g, d]| serde_json::json!({"gain": g, "delay_s": d})),
        "force_correction_kn_per_mm": r.force_correction_kn_per_mm,
        "identification": r.identification.as_ref().map(|id| serde_json::json!({
            "delay_s": id.delay_s, "gain": id.gain, "lead_residual_pct": id.lead_residual_pct,
            "specimen_stiffness_kn_per_mm": id.specimen.stiffness_kn_per_mm,
            "specimen_damping_kn_s_per_mm": id.specimen.damping_kn_s_per_mm,
            "specimen_mass_kn_s2_per_mm": id.specimen.mass_kn_s2_per_mm,
            "specimen_r2": id.specimen.r2, "wall_s": id.wall_s,
        })),
        "j2_noise_free_pct": r.j2_noise_free_pct,
        "criteria": r.criteria.map(|j| serde_json::json!({
            "j1_ms": j.j1_ms, "j2_pct": j.j2_pct, "j3_pct": j.j3_pct, "j4_pct": j.j4_pct,
            "j5_pct": j.j5_pct, "j6_pct": j.j6_pct, "j7_pct": j.j7_pct, "j8_pct": j.j8_pct,
            "j9_pct": j.j9_pct,
        })),
    })
}

fn print_single(r: &BenchmarkRun) {
    let c = &r.config;
    crate::outln!(
        "vRTHS benchmark: {}, {} ×{}, {:?} plant (k_e {:.0} N/m), controller {}, {} ticks at 4096 Hz",
        r.structure_name,
        r.record_name,
        c.intensity,
        c.plant,
        r.specimen_stiffness_n_per_m,
        c.controller.name(),
        r.history.time_s.len()
    );
    if let Some(a) = r.ats_coefficients {
        crate::outln!(
            "ATS coefficients at the end: a0 {:.4}, a1 {:.2} ms, a2 {:.3e} s²",
            a[0],
            a[1] * 1e3,
            a[2]
        );
    }
    if let Some(id) = &r.identification {
        crate::outln!(
            "identified rig: delay {:.2} ms, gain {:.4}, lead residual {:.1} %, specimen k {:.4} kN/mm \
             c {:.3e} kN·s/mm m {:.3e} kN·s²/mm (R² {:.4}); {:.1} s to identify",
            id.delay_s * 1e3,
            id.gain,
            id.lead_residual_pct,
            id.specimen.stiffness_kn_per_mm,
            id.specimen.damping_kn_s_per_mm,
            id.specimen.mass_kn_s2_per_mm,
            id.specimen.r2,
            id.wall_s
        );
    }
    if let Some([g, d]) = r.lead_adaptation {
        crate::outln!(
            "lead correction at the end: gain {g:.4}, delay {:.3} ms",
            d * 1e3
        );
    }
    if r.clipped_force_ticks > 0 {
        crate::outln!(
            "WARNING: the load cell clipped at its ±8900 N range on {} ticks: the force fed back \
             is wrong there (the specimen moves more than the benchmark's actuator can load)",
            r.clipped_force_ticks
        );
    }
    if let Some(k) = r.force_correction_kn_per_mm {
        crate::outln!("force correction stiffness {k:.4} kN/mm");
    }
    match (&r.criteria, &r.unstable) {
        (Some(j), _) => {
            // The specimen's floor and the two others J6-J9 are on (floors 1; 2, 3 for the cases).
            let d = r.specimen_dof + 1;
            let others: Vec<String> = (1..=r.history.floors_mm.len())
                .filter(|&f| f != d)
                .take(2)
                .map(|f| f.to_string())
                .collect();
            let others = others.join(", ");
            crate::outln!("J1 {:.2} ms (delay)", j.j1_ms);
            crate::outln!(
                "J2 {:.2} %  J3 {:.2} %  (tracking, floor {d})",
                j.j2_pct,
                j.j3_pct
            );
            if let Some(j2) = r.j2_noise_free_pct {
                crate::outln!("   J2 of the noise-free displacement {j2:.2} % (evaluation only)");
            }
            crate::outln!(
                "J4 {:.2} %  J5 {:.2} %  (floor {d} vs reference)",
                j.j4_pct,
                j.j5_pct
            );
            crate::outln!(
                "J6 {:.2} %  J7 {:.2} %  (floors {others} vs reference)",
                j.j6_pct,
                j.j7_pct
            );
            crate::outln!(
                "J8 {:.2} %  J9 {:.2} %  (floors {others} peak vs reference)",
                j.j8_pct,
                j.j9_pct
            );
        }
        (None, Some(why)) => crate::outln!("UNSTABLE: {why}"),
        (None, None) => {}
    }
}

/// The columns of `history.csv` for `dofs` floors with the specimen on floor `dof` (0-based):
/// time, the measured specimen floor and its target, the other (numerical) floors in order, the
/// reference floors 1..N, each named by its floor. With the specimen on floor 1 this is
/// `time_s,x1_mm,target1_mm,x2_mm..xN_mm,r1_mm..rN_mm`: for the benchmark's 3 stories
/// `time_s,x1_mm,target1_mm,x2_mm,x3_mm,r1_mm,r2_mm,r3_mm`.
pub fn history_columns(dofs: usize, dof: usize) -> Vec<String> {
    let mut c = vec![
        "time_s".to_string(),
        format!("x{}_mm", dof + 1),
        format!("target{}_mm", dof + 1),
    ];
    c.extend(
        (0..dofs)
            .filter(|&j| j != dof)
            .map(|j| format!("x{}_mm", j + 1)),
    );
    c.extend((1..=dofs).map(|j| format!("r{j}_mm")));
    c
}

/// Write [`history_columns`] of a run.
fn write_history(r: &BenchmarkRun, path: &Path) -> anyhow::Result<()> {
    let h = &r.history;
    let (dofs, dof) = (h.floors_mm.len(), r.specimen_dof);
    let others: Vec<usize> = (0..dofs).filter(|&j| j != dof).collect();
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    writeln!(w, "{}", history_columns(dofs, dof).join(","))?;
    for k in 0..h.time_s.len() {
        let v = |s: &Vec<f64>| s.get(k).copied().unwrap_or(f64::NAN);
        let mut row = vec![h.time_s[k], h.measured_mm[k], h.target_mm[k]];
        row.extend(others.iter().map(|&j| v(&h.floors_mm[j])));
        row.extend(h.reference_mm.iter().map(v));
        let line: Vec<String> = row.iter().map(|x| x.to_string()).collect();
        writeln!(w, "{}", line.join(","))?;
    }
    w.flush()?;
    Ok(())
}

/// What [`draw`] draws of a run: per floor the error against the reference, the zoom window on
/// the specimen floor's strongest motion and, for a stopped run, where it stopped (its histories
/// end there; the reference is cut to them).
#[derive(Debug, Clone, PartialEq)]
struct BenchmarkFigure {
    /// Samples drawn (the run's, up to its stop).
    samples: usize,
    /// Per floor: (measured or numerical) − reference, mm.
    error_mm: Vec<Vec<f64>>,
    /// The zoom window around the specimen floor's reference peak, s.
    zoom_s: Option<(f64, f64)>,
    /// The stop, marked.
    trip: Option<plot::Marker>,
}

impl BenchmarkFigure {
    fn of(r: &BenchmarkRun) -> Self {
        let h = &r.history;
        let samples = h.time_s.len().min(h.measured_mm.len());
        let cut = |v: &[f64]| v[..samples.min(v.len())].to_vec();
        let error_mm = (0..h.reference_mm.len())
            .map(|j| plot::difference(&cut(floor_values(r, j)), &cut(&h.reference_mm[j])))
            .collect();
        let zoom_s = h.reference_mm.get(r.specimen_dof).and_then(|x| {
            plot::peak_window_s(&h.time_s[..samples], &cut(x), plot::ZOOM_HALF_WIDTH_S)
        });
        let trip = r.unstable.as_ref().and_then(|_| {
            h.time_s[..samples].last().map(|&time_s| plot::Marker {
                time_s,
                label: format!("stopped at {time_s:.3} s"),
            })
        });
        Self {
            samples,
            error_mm,
            zoom_s,
            trip,
        }
    }

    /// Every floor against its reference, the floors' errors, and the specimen floor zoomed on
    /// its strongest motion.
    fn panels<'a>(&'a self, r: &'a BenchmarkRun) -> Vec<Panel<'a>> {
        let h = &r.history;
        let n = self.samples;
        let cut = |v: &'a [f64]| &v[..n.min(v.len())];
        let t = cut(&h.time_s);
        let label = |j: usize| {
            if j == r.specimen_dof {
                "measured"
            } else {
                "numerical"
            }
        };
        let floors: Vec<Panel> = h
            .reference_mm
            .iter()
            .enumerate()
            .map(|(j, reference)| {
                Panel::new(format!("Floor {} (mm)", j + 1))
                    .with_line("reference", t, cut(reference), plot::LineStyle::Reference)
                    .with(label(j), t, cut(floor_values(r, j)))
            })
            .collect();
        let mut error = Panel::new("Error vs reference (mm)");
        for (j, e) in self.error_mm.iter().enumerate() {
            error = error.with(format!("floor {}: {} − reference", j + 1, label(j)), t, e);
        }
        let zoom = match (self.zoom_s, floors.get(r.specimen_dof)) {
            (Some(w), Some(p)) => Some(
                p.clone()
                    .zoomed(format!("Floor {}, zoom (mm)", r.specimen_dof + 1), w),
            ),
            _ => None,
        };
        floors.into_iter().chain([error]).chain(zoom).collect()
    }
}

/// Floor `j`'s displacement of the run: the specimen's measured, the others numerical.
fn floor_values(r: &BenchmarkRun, j: usize) -> &[f64] {
    if j == r.specimen_dof {
        &r.history.measured_mm
    } else {
        r.history.floors_mm.get(j).map_or(&[], |x| x.as_slice())
    }
}

/// Every floor against the reference, the errors and a zoom ([`BenchmarkFigure`]).
fn draw(r: &BenchmarkRun, path: &Path) -> anyhow::Result<()> {
    let c = &r.config;
    let title = match &r.criteria {
        Some(j) => format!(
            "vRTHS {}, {} x{}, {}: J4 {:.2} %, J6 {:.2} %, J7 {:.2} %",
            r.structure_name,
            r.record_name,
            c.intensity,
            c.controller.name(),
            j.j4_pct,
            j.j6_pct,
            j.j7_pct
        ),
        None => format!("vRTHS {}, {}: unstable", r.structure_name, r.record_name),
    };
    let fig = BenchmarkFigure::of(r);
    plot::draw(
        path,
        &plot::Figure {
            title,
            panels: fig.panels(r),
            marker: fig.trip.clone(),
            time_span_s: None,
        },
    )
}

fn grid(args: &Args) -> anyhow::Result<()> {
    if args.seed.is_some() {
        anyhow::bail!(
            "--seed selects the plant of one run; the grid draws seeds 1..=N (--perturbed N)"
        );
    }
    let n = args.perturbed.unwrap_or(PERTURBED_PLANTS);
    let start = std::time::Instant::now();
    let g = run_grid(args.controller, args.intensity, n)?;
    let table = g.table();
    if args.json {
        crate::outln!("{}", serde_json::to_string_pretty(&g)?);
    } else {
        crate::outln!("{table}");
        crate::outln!(
            "({} runs in {:.1} s)",
            12 * (n + 1),
            start.elapsed().as_secs_f64()
        );
    }
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let path = dir.join("table.md");
        std::fs::write(&path, &table).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::studies::benchmark::run::BenchmarkHistory;

    /// A 3-floor run of 200 ticks at 0.01 s, the specimen on floor 1: each floor's reference a
    /// sine, the run `j + 1` × 0.01 mm above it; stopped after `ticks` if fewer than 200.
    fn result(ticks: usize) -> BenchmarkRun {
        let time_s: Vec<f64> = (0..200).map(|k| k as f64 * 0.01).collect();
        let reference_mm: Vec<Vec<f64>> = (0..3)
            .map(|j| time_s.iter().map(|t| (j as f64 + 1.0) * t.sin()).collect())
            .collect();
        let off = |j: usize| -> Vec<f64> {
            reference_mm[j][..ticks]
                .iter()
                .map(|r| r + (j as f64 + 1.0) * 0.01)
                .collect()
        };
        let history = BenchmarkHistory {
            time_s: time_s[..ticks].to_vec(),
            measured_mm: off(0),
            target_mm: off(0),
            floors_mm: (0..3).map(off).collect(),
            reference_mm: reference_mm.clone(),
            true_disp_mm: off(0),
        };
        BenchmarkRun {
            config: RunConfig {
                case: 1,
                record: BenchmarkRecord::ElCentro,
                intensity: 0.4,
                plant: PlantDraw::Nominal,
                controller: ControllerKind::FeAts,
            },
            criteria: None,
            unstable: (ticks < 200).then(|| "stroke".to_string()),
            history,
            ats_coefficients: None,
            identification: None,
            lead_adaptation: None,
            force_correction_kn_per_mm: None,
            specimen_stiffness_n_per_m: 0.0,
            structure_name: "test".into(),
            specimen_dof: 0,
            clipped_force_ticks: 0,
            record_name: "el-centro".into(),
            j2_noise_free_pct: None,
        }
    }

    #[test]
    fn benchmark_figure_has_floors_errors_and_a_zoom() {
        let r = result(200);
        let fig = BenchmarkFigure::of(&r);
        assert!(fig.trip.is_none());
        let panels = fig.panels(&r);
        let names: Vec<&str> = panels.iter().map(|p| p.y_label.as_str()).collect();
        assert_eq!(
            names,
            [
                "Floor 1 (mm)",
                "Floor 2 (mm)",
                "Floor 3 (mm)",
                "Error vs reference (mm)",
                "Floor 1, zoom (mm)"
            ]
        );
        assert_eq!(panels[0].series[0].label, "reference");
        assert_eq!(panels[0].series[0].line, plot::LineStyle::Reference);
        assert_eq!(panels[0].series[1].label, "measured");
        assert_eq!(panels[1].series[1].label, "numerical");
        let error = &panels[3];
        let labels: Vec<&str> = error.series.iter().map(|s| s.label.as_str()).collect();
        assert_eq!(
            labels,
            [
                "floor 1: measured − reference",
                "floor 2: numerical − reference",
                "floor 3: numerical − reference"
            ]
        );
        let h = &r.history;
        for (k, e) in error.series[0].values.iter().enumerate() {
            assert_eq!(*e, h.measured_mm[k] - h.reference_mm[0][k]);
        }
        for (k, e) in error.series[2].values.iter().enumerate() {
            assert_eq!(*e, h.floors_mm[2][k] - h.reference_mm[2][k]);
        }
        // sin peaks at π/2 s: the window ±1.5 s around it is kept inside the 1.99 s record.
        assert_eq!(panels[4].zoom_s, Some((0.0, 1.99)));
    }

    #[test]
    fn stopped_benchmark_figure_ends_where_the_run_stopped() {
        let r = result(120);
        let fig = BenchmarkFigure::of(&r);
        assert_eq!(fig.samples, 120);
        let trip = fig.trip.as_ref().unwrap();
        assert!((trip.time_s - 1.19).abs() < 1e-12);
        assert!(trip.label.contains("1.190 s"), "{}", trip.label);
        for p in fig.panels(&r) {
            for s in &p.series {
                assert_eq!(s.values.len(), 120, "{} / {}", p.y_label, s.label);
            }
        }
    }
}

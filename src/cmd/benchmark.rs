//! `rths benchmark`: the vRTHS benchmark problem (Silva et al. 2020): one case × record with J1-J9,
//! its history and figure, or (with neither `--case` nor `--record`) the whole grid and its table.
//! See `docs/benchmark.md`.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::benchmark::grid::run_grid;
use crate::benchmark::run::{run as run_one, ControllerKind, PlantDraw, RunConfig, RunResult};
use crate::benchmark::{Record, DEFAULT_INTENSITY, PERTURBED_PLANTS};
use crate::plot::{self, Panel};

/// Arguments of `rths benchmark`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Partitioning case, 1..4 (with --record; neither: the whole grid).
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=4))]
    pub case: Option<u8>,
    /// Ground-motion record (with --case).
    #[arg(long, value_enum)]
    pub record: Option<Record>,
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
    match (args.case, args.record) {
        (Some(case), Some(record)) => single(&args, case, record),
        (None, None) => grid(&args),
        _ => anyhow::bail!("give both --case and --record (one run), or neither (the whole grid)"),
    }
}

fn single(args: &Args, case: u8, record: Record) -> anyhow::Result<()> {
    let plant = match (args.perturbed, args.seed) {
        (None, None) => PlantDraw::Nominal,
        (Some(_), Some(seed)) | (None, Some(seed)) => PlantDraw::Perturbed(seed),
        (Some(n), None) => {
            anyhow::bail!("--perturbed {n} on one run needs --seed S (the plant to draw)")
        }
    };
    let cfg = RunConfig {
        case,
        record,
        intensity: args.intensity,
        plant,
        controller: args.controller,
    };
    let r = run_one(&cfg)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&single_json(&r))?);
    } else {
        print_single(&r);
    }
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let csv = dir.join("history.csv");
        write_history(&r, &csv)?;
        let png = dir.join("benchmark.png");
        draw(&r, &png)?;
        if !args.json {
            println!("wrote {} and {}", csv.display(), png.display());
        }
    }
    if let Some(why) = &r.unstable {
        anyhow::bail!("the run went unstable: {why}");
    }
    Ok(())
}

fn single_json(r: &RunResult) -> serde_json::Value {
    serde_json::json!({
        "case": r.config.case,
        "record": r.config.record,
        "intensity": r.config.intensity,
        "plant": r.config.plant,
        "controller": r.config.controller,
        "specimen_stiffness_n_per_m": r.specimen_stiffness_n_per_m,
        "ticks": r.history.time_s.len(),
        "unstable": r.unstable,
        "ats_coefficients": r.ats_coefficients,
        "j2_noise_free_pct": r.j2_noise_free_pct,
        "criteria": r.criteria.map(|j| serde_json::json!({
            "j1_ms": j.j1_ms, "j2_pct": j.j2_pct, "j3_pct": j.j3_pct, "j4_pct": j.j4_pct,
            "j5_pct": j.j5_pct, "j6_pct": j.j6_pct, "j7_pct": j.j7_pct, "j8_pct": j.j8_pct,
            "j9_pct": j.j9_pct,
        })),
    })
}

fn print_single(r: &RunResult) {
    let c = &r.config;
    println!(
        "vRTHS benchmark: case {}, {} ×{}, {:?} plant (k_e {:.0} N/m), controller {}, {} ticks at 4096 Hz",
        c.case,
        c.record,
        c.intensity,
        c.plant,
        r.specimen_stiffness_n_per_m,
        c.controller.name(),
        r.history.time_s.len()
    );
    if let Some(a) = r.ats_coefficients {
        println!(
            "ATS coefficients at the end: a0 {:.4}, a1 {:.2} ms, a2 {:.3e} s²",
            a[0],
            a[1] * 1e3,
            a[2]
        );
    }
    match (&r.criteria, &r.unstable) {
        (Some(j), _) => {
            println!("J1 {:.2} ms (delay)", j.j1_ms);
            println!(
                "J2 {:.2} %  J3 {:.2} %  (tracking, floor 1)",
                j.j2_pct, j.j3_pct
            );
            if let Some(j2) = r.j2_noise_free_pct {
                println!("   J2 of the noise-free displacement {j2:.2} % (evaluation only)");
            }
            println!(
                "J4 {:.2} %  J5 {:.2} %  (floor 1 vs reference)",
                j.j4_pct, j.j5_pct
            );
            println!(
                "J6 {:.2} %  J7 {:.2} %  (floors 2, 3 vs reference)",
                j.j6_pct, j.j7_pct
            );
            println!(
                "J8 {:.2} %  J9 {:.2} %  (floors 2, 3 peak vs reference)",
                j.j8_pct, j.j9_pct
            );
        }
        (None, Some(why)) => println!("UNSTABLE: {why}"),
        (None, None) => {}
    }
}

/// `time_s,x1_mm,target1_mm,x2_mm,x3_mm,r1_mm,r2_mm,r3_mm`.
fn write_history(r: &RunResult, path: &Path) -> anyhow::Result<()> {
    let h = &r.history;
    let file =
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    writeln!(w, "time_s,x1_mm,target1_mm,x2_mm,x3_mm,r1_mm,r2_mm,r3_mm")?;
    for k in 0..h.time_s.len() {
        let v = |s: &Vec<f64>| s.get(k).copied().unwrap_or(f64::NAN);
        writeln!(
            w,
            "{},{},{},{},{},{},{},{}",
            h.time_s[k],
            h.measured_mm[k],
            h.target_mm[k],
            v(&h.floors_mm[1]),
            v(&h.floors_mm[2]),
            v(&h.reference_mm[0]),
            v(&h.reference_mm[1]),
            v(&h.reference_mm[2]),
        )?;
    }
    w.flush()?;
    Ok(())
}

/// Every floor against the reference.
fn draw(r: &RunResult, path: &Path) -> anyhow::Result<()> {
    let h = &r.history;
    let c = &r.config;
    let title = match &r.criteria {
        Some(j) => format!(
            "vRTHS case {}, {} x{}, {}: J4 {:.2} %, J6 {:.2} %, J7 {:.2} %",
            c.case,
            c.record,
            c.intensity,
            c.controller.name(),
            j.j4_pct,
            j.j6_pct,
            j.j7_pct
        ),
        None => format!("vRTHS case {}, {}: unstable", c.case, c.record),
    };
    plot::stacked_time_series(
        path,
        &title,
        &[
            floor(
                "Floor 1 (mm)",
                &h.time_s,
                &h.reference_mm[0],
                "measured",
                &h.measured_mm,
            ),
            floor(
                "Floor 2 (mm)",
                &h.time_s,
                &h.reference_mm[1],
                "numerical",
                &h.floors_mm[1],
            ),
            floor(
                "Floor 3 (mm)",
                &h.time_s,
                &h.reference_mm[2],
                "numerical",
                &h.floors_mm[2],
            ),
        ],
    )
}

fn floor<'a>(
    y_label: &str,
    time_s: &'a [f64],
    reference: &'a [f64],
    label: &str,
    values: &'a [f64],
) -> Panel<'a> {
    Panel {
        y_label: y_label.to_string(),
        series: Vec::new(),
    }
    .with("reference", time_s, reference)
    .with(label, time_s, values)
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
        println!("{}", serde_json::to_string_pretty(&g)?);
    } else {
        println!("{table}");
        println!(
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

//! The benchmark's grid: every case × record, on the nominal plant and on `PERTURBED_PLANTS`
//! perturbed ones, run on every core (rayon), summarized in the benchmark's table.

use std::sync::Arc;

use rayon::prelude::*;
use rths_core::metrics::BenchmarkCriteria;

use super::ident::RigIdentification;
use super::plant::PlantDraw;
use super::run::{run, ControllerKind, RunConfig};
use super::BenchmarkRecord;

/// One case × record of the grid.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Cell {
    /// Partitioning case.
    pub case: u8,
    /// Record.
    pub record: BenchmarkRecord,
    /// J1..J9 on the nominal plant (`None`: unstable).
    pub nominal: Option<[f64; 9]>,
    /// J2 of the noise-free displacement on the nominal plant, % (evaluation only).
    pub nominal_j2_noise_free_pct: Option<f64>,
    /// Largest J4 over the stable perturbed plants, % (`None`: none stable, or none run).
    pub perturbed_max_j4_pct: Option<f64>,
    /// Mean J4 over the stable perturbed plants, %.
    pub perturbed_mean_j4_pct: Option<f64>,
    /// Perturbed plants whose run went unstable.
    pub perturbed_unstable: usize,
}

/// The grid's outcome.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Grid {
    /// Controller.
    pub controller: ControllerKind,
    /// Intensity.
    pub intensity: f64,
    /// Perturbed plants per cell.
    pub perturbed_plants: u64,
    /// Cells, case-major.
    pub cells: Vec<Cell>,
    /// The `*-id` controllers: the rig identifications' total wall-clock time, s (one per plant
    /// draw, shared by every case × record on it; run in parallel with the grid's runs).
    pub identification_s: Option<f64>,
    /// The `*-id` controllers: the identified specimen stiffness over the plant draws, kN/mm
    /// [min, max].
    pub identified_stiffness_kn_per_mm: Option<[f64; 2]>,
}

/// Run the grid (`perturbed` plants per cell, seeds 1..=perturbed) on every core.
pub fn run_grid(
    controller: ControllerKind,
    intensity: f64,
    perturbed: u64,
) -> anyhow::Result<Grid> {
    let mut configs = Vec::new();
    for case in 1..=4u8 {
        for record in BenchmarkRecord::ALL {
            let plants = std::iter::once(PlantDraw::Nominal)
                .chain((1..=perturbed).map(PlantDraw::Perturbed));
            for plant in plants {
                configs.push(RunConfig {
                    case,
                    record,
                    intensity,
                    plant,
                    controller,
                });
            }
        }
    }
    // Keep only the figures: the histories of 252 runs would not fit comfortably in memory.
    type Kept = (
        (RunConfig, Option<BenchmarkCriteria>, Option<f64>),
        Option<Arc<RigIdentification>>,
    );
    let bar = crate::machinery::progress::bar(configs.len() as u64, "benchmark runs", false);
    let kept: Vec<Kept> = configs
        .par_iter()
        .map(|c| {
            let kept = run(c).map(|r| {
                (
                    (r.config, r.criteria, r.j2_noise_free_pct),
                    r.identification,
                )
            });
            bar.inc(1);
            kept
        })
        .collect::<anyhow::Result<_>>()?;
    bar.finish_and_clear();
    // One identification per plant draw (the cache hands every run of a draw the same one).
    let mut ids: Vec<(PlantDraw, Arc<RigIdentification>)> = Vec::new();
    for ((c, _, _), id) in &kept {
        if let Some(id) = id {
            if !ids.iter().any(|(p, _)| *p == c.plant) {
                ids.push((c.plant, id.clone()));
            }
        }
    }
    let identification_s = (!ids.is_empty()).then(|| ids.iter().map(|(_, i)| i.wall_s).sum());
    let stiffness: Vec<f64> = ids
        .iter()
        .map(|(_, i)| i.specimen.stiffness_kn_per_mm)
        .collect();
    let identified_stiffness_kn_per_mm = (!stiffness.is_empty()).then(|| {
        [
            stiffness.iter().copied().fold(f64::INFINITY, f64::min),
            stiffness.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        ]
    });
    let results: Vec<(RunConfig, Option<BenchmarkCriteria>, Option<f64>)> =
        kept.into_iter().map(|(r, _)| r).collect();
    let mut cells = Vec::new();
    for case in 1..=4u8 {
        for record in BenchmarkRecord::ALL {
            let of_cell = results
                .iter()
                .filter(|(c, _, _)| c.case == case && c.record == record);
            let nominal_run = of_cell
                .clone()
                .find(|(c, _, _)| c.plant == PlantDraw::Nominal);
            let nominal = nominal_run.and_then(|(_, j, _)| j.map(|j| j.as_array()));
            let nominal_j2_noise_free_pct = nominal_run.and_then(|(_, _, j2)| *j2);
            let perturbed: Vec<&Option<BenchmarkCriteria>> = of_cell
                .filter(|(c, _, _)| c.plant != PlantDraw::Nominal)
                .map(|(_, j, _)| j)
                .collect();
            let j4: Vec<f64> = perturbed
                .iter()
                .filter_map(|j| j.map(|j| j.j4_pct))
                .collect();
            cells.push(Cell {
                case,
                record,
                nominal,
                nominal_j2_noise_free_pct,
                perturbed_max_j4_pct: j4.iter().copied().reduce(f64::max),
                perturbed_mean_j4_pct: (!j4.is_empty())
                    .then(|| j4.iter().sum::<f64>() / j4.len() as f64),
                perturbed_unstable: perturbed.iter().filter(|j| j.is_none()).count(),
            });
        }
    }
    Ok(Grid {
        controller,
        intensity,
        perturbed_plants: perturbed,
        cells,
        identification_s,
        identified_stiffness_kn_per_mm,
    })
}

impl Grid {
    /// The benchmark's table, Markdown: J1 (ms) and J2-J9 (%) on the nominal plant, and J4 over the
    /// perturbed plants.
    pub fn table(&self) -> String {
        let mut s = format!(
            "controller {}, intensity {}, {} perturbed plants per cell\n\n\
             | case | record | J1 ms | J2 % | J3 % | J4 % | J5 % | J6 % | J7 % | J8 % | J9 % | \
             J2 noise-free % | J4 max (pert.) % | J4 mean (pert.) % | unstable (pert.) |\n\
             |---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
            self.controller.name(),
            self.intensity,
            self.perturbed_plants
        );
        for c in &self.cells {
            let js = match c.nominal {
                Some(j) => j
                    .iter()
                    .map(|v| format!("{v:.2}"))
                    .collect::<Vec<_>>()
                    .join(" | "),
                None => ["unstable"; 9].join(" | "),
            };
            let opt = |v: Option<f64>| v.map_or("n/a".to_string(), |v| format!("{v:.2}"));
            s.push_str(&format!(
                "| {} | {} | {js} | {} | {} | {} | {} |\n",
                c.case,
                c.record,
                opt(c.nominal_j2_noise_free_pct),
                opt(c.perturbed_max_j4_pct),
                opt(c.perturbed_mean_j4_pct),
                c.perturbed_unstable
            ));
        }
        if let (Some(t), Some([lo, hi])) =
            (self.identification_s, self.identified_stiffness_kn_per_mm)
        {
            s.push_str(&format!(
                "\n{} rig identifications (one per plant draw): {t:.1} s of compute in all; \
                 identified specimen stiffness {lo:.4}..{hi:.4} kN/mm\n",
                self.perturbed_plants + 1
            ));
        }
        s
    }
}

//! The vRTHS benchmark problem (Silva, Gomez, Maghareh, Dyke, Spencer 2020) run against rths's
//! controllers: its four partitioning cases of the 3-story frame (the files
//! `data/structures/vrths-case1.json` to `-case4.json`), its three records, its plant, sensors and
//! converters at 4096 Hz, and its criteria J1-J9 (`docs/benchmark.md`).
//!
//! - [`plant`]: the benchmark's plant, nominal or drawn, and its sensors.
//! - [`ident`]: the rig identified through the benchmark's converters (`*-id` controllers).
//! - [`meta`]: the metamodel of a case's numerical substructure (`meta-*` controllers).
//! - [`run`]: one run (case × record × plant × controller) and its reference.
//! - [`grid`]: every case × record on the nominal and the perturbed plants, on every core.
//!
//! The records and the structure files are embedded at build time (`include_str!`), so the
//! command works from any directory; the same files are in the repository's `data/`.

pub mod grid;
pub mod ident;
pub mod meta;
pub mod plant;
pub mod run;

use anyhow::Context;
use rths_files::motion::{parse_csv, GroundMotion};
use rths_files::structure_file::Structure;

/// The benchmark's control and sampling rate, Hz.
pub const BENCHMARK_RATE_HZ: f64 = 4096.0;
/// The benchmark's step, s.
pub const BENCHMARK_DT_S: f64 = 1.0 / BENCHMARK_RATE_HZ;
/// Default intensity: the factor on the records' ground acceleration.
pub const DEFAULT_INTENSITY: f64 = 0.4;
/// Noise power of the displacement sensor's band-limited white noise, m² (benchmark).
pub const DISP_NOISE_POWER_M2: f64 = 6.25e-14;
/// Noise power of the force sensor's band-limited white noise, N² (benchmark).
pub const FORCE_NOISE_POWER_N2: f64 = 1.16e-3;
/// Resolution of the benchmark's converters, bits.
pub const BENCHMARK_CONVERTER_BITS: u32 = 18;
/// The benchmark actuator's force capacity, N: the load cell's full scale here.
pub const ACTUATOR_CAPACITY_N: f64 = 8900.0;
/// Perturbed plants of the grid (seeds 1..=20), as the benchmark evaluates robustness.
pub const PERTURBED_PLANTS: u64 = 20;

/// A band-limited white noise of power `p` sampled every `dt_s` has variance `p/dt_s` (the
/// Simulink block the benchmark uses): its σ.
pub fn noise_sigma(power: f64, dt_s: f64) -> f64 {
    (power / dt_s).sqrt()
}

/// The benchmark's three records.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum BenchmarkRecord {
    /// 1940 El Centro (0.02 s).
    ElCentro,
    /// 1995 Kobe (0.01 s).
    Kobe,
    /// 1984 Morgan Hill (0.005 s).
    Morgan,
}

impl BenchmarkRecord {
    /// All three, in the benchmark's order.
    pub const ALL: [BenchmarkRecord; 3] = [
        BenchmarkRecord::ElCentro,
        BenchmarkRecord::Kobe,
        BenchmarkRecord::Morgan,
    ];

    /// The CLI name.
    pub fn name(self) -> &'static str {
        match self {
            BenchmarkRecord::ElCentro => "el-centro",
            BenchmarkRecord::Kobe => "kobe",
            BenchmarkRecord::Morgan => "morgan",
        }
    }

    fn text(self) -> &'static str {
        match self {
            BenchmarkRecord::ElCentro => {
                include_str!("../../../data/vrths_benchmark/el_centro.csv")
            }
            BenchmarkRecord::Kobe => include_str!("../../../data/vrths_benchmark/kobe.csv"),
            BenchmarkRecord::Morgan => include_str!("../../../data/vrths_benchmark/morgan.csv"),
        }
    }

    /// The record as shipped (unscaled, in g), validated by the CSV reader.
    pub fn motion(self) -> anyhow::Result<GroundMotion> {
        let m = parse_csv(self.text(), self.name())
            .with_context(|| format!("benchmark record {}", self.name()))?;
        m.validate()
            .with_context(|| format!("benchmark record {}", self.name()))?;
        Ok(m)
    }
}

impl std::fmt::Display for BenchmarkRecord {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The structure file of partitioning case `case` (1..=4), embedded.
pub fn case_text(case: u8) -> anyhow::Result<&'static str> {
    Ok(match case {
        1 => include_str!("../../../data/structures/vrths-case1.json"),
        2 => include_str!("../../../data/structures/vrths-case2.json"),
        3 => include_str!("../../../data/structures/vrths-case3.json"),
        4 => include_str!("../../../data/structures/vrths-case4.json"),
        _ => anyhow::bail!("--case {case}: the benchmark has cases 1..=4"),
    })
}

/// Partitioning case `case` (1..=4), validated.
pub fn case_structure(case: u8) -> anyhow::Result<Structure> {
    Structure::from_json(case_text(case)?)
        .with_context(|| format!("structure file of benchmark case {case}"))
}

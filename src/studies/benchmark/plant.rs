//! The vRTHS benchmark's plant at 4096 Hz: nominal or drawn from the benchmark's uncertainty,
//! with its sensors' noise (the 18-bit converters are [`super::ident::Converters`]). What a run,
//! an identification and the grid share of the rig.

use rths_hal_sim::{PlantParams, Preset, RigConfig, Sensors};

use super::{noise_sigma, BENCHMARK_DT_S, DISP_NOISE_POWER_M2, FORCE_NOISE_POWER_N2};

/// The plant of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PlantDraw {
    /// The nominal benchmark plant (sensor noise seed 0).
    Nominal,
    /// The benchmark's uncertainty drawn from this seed (β1, β2, a3, k_e; and the noise).
    Perturbed(u64),
}

/// The benchmark plant of a run at 4096 Hz holding a specimen of stiffness `specimen_kn_per_mm`
/// (the structure file's; the benchmark's mass and damping ratio), its noise (quantization at 18
/// bits is the [`Converters`]').
pub fn plant_params(plant: PlantDraw, specimen_kn_per_mm: f64) -> anyhow::Result<PlantParams> {
    rig_config(plant, specimen_kn_per_mm)
        .build()
        .map_err(|e| anyhow::anyhow!("benchmark plant: {e}"))
}

/// The configuration of [`plant_params`].
pub fn rig_config(plant: PlantDraw, specimen_kn_per_mm: f64) -> RigConfig {
    let mut cfg = RigConfig::new(Preset::Benchmark);
    cfg.dt_s = BENCHMARK_DT_S;
    cfg.specimen_stiffness_kn_per_mm = specimen_kn_per_mm;
    cfg.sensors = Sensors {
        disp_noise_mm: noise_sigma(DISP_NOISE_POWER_M2, BENCHMARK_DT_S) * 1e3,
        force_noise_kn: noise_sigma(FORCE_NOISE_POWER_N2, BENCHMARK_DT_S) * 1e-3,
        quantize: false,
    };
    match plant {
        PlantDraw::Nominal => {}
        PlantDraw::Perturbed(seed) => {
            cfg.uncertainty = true;
            cfg.seed = seed;
        }
    }
    cfg
}

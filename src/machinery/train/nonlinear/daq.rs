//! The specimen force as the lab's DAQ gives it, for the training's pure loop: the load cell's
//! noise and its 16-bit converter, at specimen scale, carried to the structure's force along the
//! specimen DOF as the hybrid scenario does (`SpecimenScale`'s force scale, and the paper brace's
//! cos θ for the paper's frame). The noise is a fixed sequence drawn from a seed per run, so the
//! training loss stays a deterministic function of θ.

use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rths_core::params::{Prototype, SpecimenScale, ACTUATOR_CAPACITY_KN};
use rths_files::structure_file::Structure;
use rths_hal_sim::rig::quantize;
use rths_hal_sim::Sensors;

use crate::machinery::structure::rig::is_paper_frame;

/// What the training's pure loop feeds the model as the measured specimen force.
#[derive(Debug, Clone)]
pub struct ForceDaq {
    /// Structure force along the specimen DOF per load-cell kN.
    structure_kn_per_cell_kn: f64,
    /// Load-cell noise, one draw per step, kN at the cell (empty: ideal sensor).
    noise_cell_kn: Vec<f64>,
    /// Converter full scale at the cell, kN (`None`: not quantized).
    full_scale_cell_kn: Option<f64>,
}

impl ForceDaq {
    /// The exact force (no noise, no converter).
    pub fn ideal() -> Self {
        Self {
            structure_kn_per_cell_kn: 1.0,
            noise_cell_kn: Vec::new(),
            full_scale_cell_kn: None,
        }
    }

    /// The default rig's load cell (hal-sim's default sensors, the actuator's capacity as the
    /// converter's full scale) on the specimen of `structure`, `steps` noise draws from `seed`.
    pub fn lab(structure: &Structure, steps: usize, seed: u64) -> Self {
        let sensors = Sensors::default();
        let mut rng = StdRng::seed_from_u64(seed);
        let noise_cell_kn = (0..steps)
            .map(|_| {
                let n: f64 = StandardNormal.sample(&mut rng);
                sensors.force_noise_kn * n
            })
            .collect();
        Self {
            structure_kn_per_cell_kn: structure_kn_per_cell_kn(structure),
            noise_cell_kn,
            full_scale_cell_kn: sensors.quantize.then_some(ACTUATOR_CAPACITY_KN),
        }
    }

    /// Whether this is [`Self::ideal`].
    pub fn is_ideal(&self) -> bool {
        self.noise_cell_kn.is_empty() && self.full_scale_cell_kn.is_none()
    }

    /// One load-cell noise σ in structure force units, kN (0 for the ideal sensor).
    pub fn noise_sigma_kn(&self) -> f64 {
        if self.noise_cell_kn.is_empty() {
            0.0
        } else {
            Sensors::default().force_noise_kn * self.structure_kn_per_cell_kn
        }
    }

    /// The measured force at step `k` when the specimen carries `force_kn` (structure units).
    #[inline]
    pub fn measure(&self, k: usize, force_kn: f64) -> f64 {
        if self.is_ideal() {
            return force_kn;
        }
        let s = self.structure_kn_per_cell_kn;
        let cell = force_kn / s + self.noise_cell_kn.get(k).copied().unwrap_or(0.0);
        let read = match self.full_scale_cell_kn {
            Some(fs) => on_grid(cell, fs),
            None => cell,
        };
        read * s
    }
}

/// `cell` on the converter's grid (full scale `fs`), not clipped at ±`fs`: the training runs at
/// ductility 6 ask more of the load cell than the actuator's capacity (the paper's frame: some
/// 46 kN of 31.14), runs a rig would stop, and a clipped force would teach the model a wrong
/// specimen. Whole full scales are carried past the converter (`fs` is a whole number of codes).
fn on_grid(cell: f64, fs: f64) -> f64 {
    let whole = (cell / fs).trunc() * fs;
    whole + quantize(cell - whole, fs)
}

/// Structure force along the specimen DOF per load-cell kN: the specimen scale's force scale,
/// times cos θ of the paper's brace for the paper's frame (its specimen is the inclined brace);
/// other structures' specimens act along their DOF.
pub fn structure_kn_per_cell_kn(structure: &Structure) -> f64 {
    let cos_theta = if is_paper_frame(structure) {
        Prototype::paper().cos_theta()
    } else {
        1.0
    };
    SpecimenScale::default().prototype_force_kn(1.0) * cos_theta
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shear3() -> Structure {
        let p = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/data/structures/shear3-yielding.json"
        );
        Structure::load(std::path::Path::new(p)).expect("shear3")
    }

    #[test]
    fn the_lab_force_is_noisy_quantized_and_repeatable() {
        let s = shear3();
        let a = ForceDaq::lab(&s, 1000, 3);
        let b = ForceDaq::lab(&s, 1000, 3);
        let c = ForceDaq::lab(&s, 1000, 4);
        assert!(ForceDaq::ideal().is_ideal() && !a.is_ideal());
        assert_eq!(ForceDaq::ideal().measure(5, 1234.5), 1234.5);
        let f = 2000.0;
        let (ma, mb, mc) = (a.measure(7, f), b.measure(7, f), c.measure(7, f));
        assert_eq!(ma, mb);
        assert_ne!(ma, mc);
        // σ at the cell 0.003 kN × force scale 1000: a few kN around 2000 kN.
        let sigma = a.noise_sigma_kn();
        assert!((sigma - 3.0).abs() < 1e-9, "{sigma}");
        let err: Vec<f64> = (0..1000).map(|k| a.measure(k, f) - f).collect();
        let rms = (err.iter().map(|e| e * e).sum::<f64>() / 1000.0).sqrt();
        assert!(rms > 0.7 * sigma && rms < 1.3 * sigma, "{rms}");
        // The converter: readings sit on its grid (full scale / 2¹⁵ at the cell).
        let lsb = ACTUATOR_CAPACITY_KN / 32768.0 * 1000.0;
        let q = a.measure(11, f) / lsb;
        assert!((q - q.round()).abs() < 1e-6, "{q}");
        // Past the full scale the reading is not clipped, and stays on the grid.
        let big = 2.5 * ACTUATOR_CAPACITY_KN * 1000.0;
        let q = a.measure(12, big) / lsb;
        assert!(
            (a.measure(12, big) - big).abs() < 5.0 * sigma,
            "{}",
            a.measure(12, big)
        );
        assert!((q - q.round()).abs() < 1e-6, "{q}");
    }
}

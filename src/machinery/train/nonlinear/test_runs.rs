//! Synthetic training runs for the floor-hysteron form's tests: a known model's pure loop under a
//! synthetic ground motion, written as a lab's history would carry it.

use nalgebra::{DMatrix, DVector};
use rths_core::metamodel::{FloorHysteronParams, FloorStructure, Hysteron, HysteronOperator};
use rths_core::params::DT_S;
use rths_files::history::RecorderUnits;

use super::floors::{FloorModel, FloorRun, Reduction};
use super::hysteron::pure_loop;

/// One floor: 0.6 kN·s²/mm on a 200 kN/mm story, 2 % damping, a 100 kN/mm specimen.
pub(crate) fn one_floor() -> FloorModel {
    let (m, k, k_e): (f64, f64, f64) = (0.6, 200.0, 100.0);
    let c = 2.0 * 0.02 * ((k + k_e) * m).sqrt();
    FloorModel {
        name: "one-floor".into(),
        columns: vec!["out_1_1_mm".into()],
        mass: DMatrix::from_element(1, 1, m),
        damping: DMatrix::from_element(1, 1, c),
        stiffness: DMatrix::from_element(1, 1, k),
        ground_mass: DVector::from_element(1, m),
        specimen_floor: 0,
        specimen_k_kn_per_mm: k_e,
        units: RecorderUnits::MM_KN,
        stories: true,
        reduction: Reduction::None,
    }
}

/// The model of `fm` with `hysterons` of the operator `op` (directions: the floor alone).
pub(crate) fn truth(
    fm: &FloorModel,
    hysterons: &[(f64, f64)],
    op: HysteronOperator,
) -> FloorHysteronParams {
    let hs: Vec<Hysteron> = hysterons
        .iter()
        .map(|&(r, w)| Hysteron {
            direction: 0,
            threshold_mm: r,
            weight_kn_per_mm: w,
        })
        .collect();
    FloorHysteronParams::new(
        DT_S,
        &FloorStructure {
            floors: 1,
            mass: fm.mass.as_slice(),
            damping: fm.damping.as_slice(),
            stiffness: fm.stiffness.as_slice(),
            ground_mass: fm.ground_mass.as_slice(),
            specimen_floor: 0,
            specimen_k_kn_per_mm: fm.specimen_k_kn_per_mm,
        },
        &[1.0],
        &hs,
    )
    .and_then(|p| p.with_operator(op))
    .expect("a valid synthetic model")
}

/// A ground motion of `seconds` (two frequencies under a rising and falling envelope) and 2 s at
/// rest, scaled to `peak_mm_s2`.
pub(crate) fn ground(seconds: f64, peak_mm_s2: f64, phase: f64) -> Vec<f64> {
    let n = (seconds / DT_S) as usize;
    let rest = (2.0 / DT_S) as usize;
    (0..n + rest)
        .map(|k| {
            if k >= n {
                return 0.0;
            }
            let t = k as f64 * DT_S;
            let env = (std::f64::consts::PI * t / seconds).sin();
            peak_mm_s2
                * env
                * (0.7 * (9.0 * t + phase).sin() + 0.3 * (23.0 * t + 2.0 * phase).sin())
        })
        .collect()
}

/// The run of `p` under `ag`, as a history carries it.
pub(crate) fn run_of(p: FloorHysteronParams, ag: Vec<f64>, label: &str) -> FloorRun {
    let floors = pure_loop(p, &ag).expect("a finite synthetic run");
    let k_e = p.specimen_k_kn_per_mm();
    FloorRun {
        label: label.into(),
        specimen_force_kn: floors[0].iter().map(|x| k_e * x).collect(),
        ground_accel_mm_s2: ag,
        floor_disp_mm: floors,
    }
}

/// The runs of `p` under [`ground`] motions of `seconds`, one per `(peak mm/s², phase)`, labelled
/// by their peak.
pub(crate) fn runs_of(
    p: FloorHysteronParams,
    seconds: f64,
    motions: &[(f64, f64)],
) -> Vec<FloorRun> {
    motions
        .iter()
        .map(|&(a, ph)| run_of(p, ground(seconds, a, ph), &format!("run-{a}")))
        .collect()
}

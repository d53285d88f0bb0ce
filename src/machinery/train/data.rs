//! Training data, phase 1: the pure finite-element response of the prototype with synthetic
//! delayed feedback.
//!
//! The prototype (frame + brace) is integrated with Chang's method at the controller step: the
//! reference response [`Reference`] of `rths_core`, the same the analysis and the firmware use. The brace deformation `d = x·cosθ` and force `N = k_b·d` are the
//! signals the metamodels predict and feed back; the feedback is the signal `delay_steps` earlier
//! (zero before the start, where the structure is at rest).

use rths_core::params::Prototype;
use rths_core::reference::Reference;

use super::TrainError;

/// The pure response sampled at `k·dt_s`, k = 0..n.
#[derive(Debug, Clone, PartialEq)]
pub struct TrainingResponse {
    /// Ground acceleration ü_g, mm/s².
    pub ground_accel_mm_s2: Vec<f64>,
    /// Brace axial deformation d, mm.
    pub brace_disp_mm: Vec<f64>,
    /// Prototype brace axial force N = k_b·d, kN.
    pub brace_force_kn: Vec<f64>,
    /// Time step, s.
    pub dt_s: f64,
}

impl TrainingResponse {
    /// Number of steps.
    pub fn len(&self) -> usize {
        self.brace_disp_mm.len()
    }

    /// True for an empty record.
    pub fn is_empty(&self) -> bool {
        self.brace_disp_mm.is_empty()
    }
}

/// Integrate the whole prototype under `ground_accel_mm_s2` (ü_g at `k·dt_s`), from rest.
pub fn pure_response(
    prototype: &Prototype,
    ground_accel_mm_s2: &[f64],
    dt_s: f64,
) -> Result<TrainingResponse, TrainError> {
    if let Some(i) = ground_accel_mm_s2.iter().position(|a| !a.is_finite()) {
        return Err(TrainError::NonFiniteInput(i));
    }
    let first = *ground_accel_mm_s2.first().ok_or(TrainError::TooShort {
        found: 0,
        needed: 1,
    })?;
    let mut reference = Reference::new(prototype, dt_s, first)?;
    let mut disp = Vec::with_capacity(ground_accel_mm_s2.len());
    disp.push(reference.brace_disp_mm());
    disp.extend(
        ground_accel_mm_s2[1..]
            .iter()
            .map(|&ag| reference.advance(ag)),
    );
    let force = disp.iter().map(|&d| prototype.brace_force_kn(d)).collect();
    Ok(TrainingResponse {
        ground_accel_mm_s2: ground_accel_mm_s2.to_vec(),
        brace_disp_mm: disp,
        brace_force_kn: force,
        dt_s,
    })
}

/// `x` delayed by `delay` steps: `y(i) = x(i − delay)`, zero before the start.
pub fn delayed(x: &[f64], delay: usize) -> Vec<f64> {
    let n = x.len();
    let zeros = delay.min(n);
    let mut y = vec![0.0; zeros];
    y.extend_from_slice(&x[..n - zeros]);
    y
}

#[cfg(test)]
mod tests {
    use super::*;
    use rths_core::params::DT_S;

    #[test]
    fn delay_shifts_and_zero_fills() {
        assert_eq!(delayed(&[1.0, 2.0, 3.0, 4.0], 2), vec![0.0, 0.0, 1.0, 2.0]);
        assert_eq!(delayed(&[1.0, 2.0], 5), vec![0.0, 0.0]);
        assert_eq!(delayed(&[1.0, 2.0], 0), vec![1.0, 2.0]);
    }

    #[test]
    fn el_centro_pure_peak_matches_design() {
        let ag = crate::machinery::motion::GroundMotion::el_centro().resample_mm_s2(DT_S);
        assert_eq!(ag.len(), 81_900);
        let r = pure_response(&Prototype::paper(), &ag, DT_S).unwrap();
        let peak = rths_core::metrics::peak_abs(&r.brace_disp_mm);
        // docs/design.md §2: Newmark reference peak brace deformation ≈ 12.67 mm.
        assert!((peak - 12.67).abs() < 0.05, "peak d = {peak}");
        let k_b = Prototype::paper().brace_axial_stiffness_kn_per_mm();
        assert!((r.brace_force_kn[5000] - k_b * r.brace_disp_mm[5000]).abs() < 1e-9);
    }
}

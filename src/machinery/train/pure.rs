//! The pure scores training records and prints (`lr-pure`, `rnn-pure`, `lrx-pure`): the trained
//! model as the analytical part of core's controller (`rths_core::control::Controller`, the tick
//! the firmware runs), fed its own target `delay_steps` ticks ago and the linear brace force for it
//! (`FeedbackSource::OwnDelayed`, the feedback of the `lr-pure` and `rnn-pure-H` scenarios), with
//! no actuator, run over the record by the host's driver ([`crate::machinery::drive::run_pure`]). A score is
//! therefore the figure `rths simulate --scenario lr-pure` gives the same model, not that of a
//! loop of training's own.

use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use rths_core::metrics::nrmse_pct;
use rths_core::params::{Prototype, SpecimenScale, DT_S};
use rths_core::supervisor::Limits;

use super::TrainError;

/// The paper's frame with a brace of `brace_k_kn_per_mm`: the structure whose linear brace force
/// a pure run feeds back (`k_b·x̂`); only that force depends on it.
pub fn brace_prototype(brace_k_kn_per_mm: f64) -> Result<Prototype, TrainError> {
    let p = Prototype::paper();
    Ok(Prototype::new(
        p.mass_kn_s2_per_mm(),
        p.frame_stiffness_kn_per_mm(),
        brace_k_kn_per_mm,
        p.cos_theta() * p.cos_theta(),
        p.damping_ratio(),
    )?)
}

/// The pure run of `analytical` on `proto`'s brace over `ground_accel_mm_s2` (mm/s² per tick):
/// the target in force at every tick, `x̂(k)` (produced at tick k−1; `x̂(0) = 0`, at rest), as
/// the scenarios record it. `name` labels a stop: a model whose output stops being finite trips
/// the supervisor, and the run is refused with the time of the trip.
pub fn prediction(
    name: &str,
    analytical: Analytical,
    proto: Prototype,
    delay_steps: usize,
    ground_accel_mm_s2: &[f64],
) -> Result<Vec<f64>, TrainError> {
    let config = ControlConfig::new(
        proto,
        SpecimenScale::default(),
        FeedbackSource::OwnDelayed { delay_steps },
        // No actuator: nothing physical to protect, only non-finite values trip.
        Limits::unbounded(),
    )?;
    let mut ctl = Controller::new(config, analytical, Compensator::None);
    let mut x = Vec::with_capacity(ground_accel_mm_s2.len());
    let stop = crate::machinery::drive::run_pure(&mut ctl, ground_accel_mm_s2, DT_S, |st, _| {
        x.push(st.target_mm);
        std::ops::ControlFlow::Continue(())
    });
    match stop {
        None => Ok(x),
        Some((reason, time_s)) => Err(TrainError::Diverged(format!(
            "{name}: the controller stopped ({reason}) at {time_s:.3} s"
        ))),
    }
}

/// NRMSE (%) of [`prediction`] against `reference_mm` (the pure brace deformation).
pub fn nrmse(
    name: &str,
    analytical: Analytical,
    proto: Prototype,
    delay_steps: usize,
    ground_accel_mm_s2: &[f64],
    reference_mm: &[f64],
) -> Result<f64, TrainError> {
    let x = prediction(name, analytical, proto, delay_steps, ground_accel_mm_s2)?;
    Ok(nrmse_pct(&x, reference_mm)?)
}

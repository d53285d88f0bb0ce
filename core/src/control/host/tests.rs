//! Tests of [`super`]: a host part in the controller.

use std::boxed::Box;

use super::*;
use crate::compensator::Compensator;
use crate::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use crate::hal::Sample;
use crate::params::{Prototype, SpecimenScale};
use crate::supervisor::{Limits, State};

/// A one-DOF stand-in: the target is the ground acceleration times a gain plus the force.
#[derive(Debug, Clone, Default)]
struct Toy {
    last: f64,
}

impl HostNumerical for Toy {
    fn next_target(&mut self, ag_mm_s2: f64, force_kn: f64) -> Result<f64, StepError> {
        if !(ag_mm_s2.is_finite() && force_kn.is_finite()) {
            return Err(StepError::NonFiniteOutput);
        }
        self.last = 1e-4 * ag_mm_s2 + 1e-3 * force_kn;
        Ok(self.last)
    }
    fn interface_disp_mm(&self) -> f64 {
        self.last
    }
    fn output_count(&self) -> usize {
        1
    }
    fn output_disp_mm(&self, i: usize) -> Option<f64> {
        (i == 0).then_some(2.0 * self.last)
    }
    fn reset(&mut self) {
        self.last = 0.0;
    }
    fn boxed_clone(&self) -> Box<dyn HostNumerical> {
        Box::new(self.clone())
    }
}

fn controller() -> Controller {
    let config = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::unbounded(),
    )
    .unwrap();
    let part = Analytical::StructureHost(StructureHost::new(Box::new(Toy::default())));
    let mut c = Controller::new(config, part, Compensator::None);
    c.supervisor_mut().arm().unwrap();
    c.supervisor_mut().start().unwrap();
    c
}

#[test]
fn a_host_part_steps_in_the_controller_and_reads_out() {
    let mut c = controller();
    assert!(c.analytical().is_structure() && c.analytical().is_host());
    let out = c.tick(1000.0, Ok(Sample::default()), false);
    assert_eq!(out.target_mm, 0.1);
    assert_eq!(c.analytical().interface_disp_mm(), Some(0.1));
    assert_eq!(c.analytical().output_count(), 1);
    assert_eq!(c.analytical().output_disp_mm(0), Some(0.2));
    assert_eq!(c.analytical().output_disp_mm(1), None);
    // A clone is its own part: stepping it leaves the original as it was.
    let mut d = c.clone();
    assert_ne!(c.analytical(), d.analytical());
    d.tick(2000.0, Ok(Sample::default()), false);
    assert_eq!(c.analytical().interface_disp_mm(), Some(0.1));
    assert_eq!(d.analytical().interface_disp_mm(), Some(0.2));
    assert_eq!(c.analytical(), c.analytical());
}

#[test]
fn a_nan_force_stops_a_host_part_safely() {
    let mut c = controller();
    c.tick(1000.0, Ok(Sample::default()), false);
    let bad = Sample {
        disp_mm: 0.0,
        force_kn: f64::NAN,
    };
    let out = c.tick(1000.0, Ok(bad), false);
    assert!(out.sample_held);
    assert!(matches!(out.state, State::Fault(_)), "{out:?}");
    // A non-finite ground acceleration reaches the part's refusal, never a panic.
    let mut c = controller();
    let out = c.tick(f64::NAN, Ok(Sample::default()), false);
    assert!(out.target_mm.is_nan());
    assert_eq!(c.step_errors(), 1);
}

#[test]
fn a_host_part_with_the_ats_is_fe_online_ats() {
    let config = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::unbounded(),
    )
    .unwrap();
    let part = Analytical::StructureHost(StructureHost::new(Box::new(Toy::default())));
    let mut c = Controller::new(config, part, Compensator::None);
    assert_eq!(c.scenario_name(), ("structure-host", None));
    let dt = crate::params::DT_S;
    let ats =
        crate::compensator::AtsParams::new(crate::compensator::AtsConfig::paper(dt, 28.0 * dt))
            .unwrap();
    c.install_ats(ats).unwrap();
    assert_eq!(c.scenario_name(), ("fe-online-ats", None));
}

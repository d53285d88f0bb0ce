//! The reference response: the whole prototype (frame + brace, all numerical) integrated with
//! Chang's method from rest, one controller tick at a time.
//!
//! This is the `fe-pure` brace deformation every figure is measured against and the training target
//! of the metamodels, so it has exactly one implementation: the host analysis, the trainer and the
//! firmware's test harness all step this struct, and therefore agree bit for bit.

use crate::integrator::{Chang, ExplicitIntegrator, Kinematics};
use crate::params::{ParamError, Prototype};
use crate::structure::{LinearStructure, Vector};

/// The pure prototype stepped with Chang's method; see the module docs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reference {
    proto: Prototype,
    chang: Chang<1>,
}

impl Reference {
    /// At rest at t = 0 under the ground acceleration `ag0_mm_s2` (the record's first tick), with
    /// step `dt_s`.
    pub fn new(proto: &Prototype, dt_s: f64, ag0_mm_s2: f64) -> Result<Self, ParamError> {
        let mut chang = Chang::new(LinearStructure::prototype_pure(proto)?, dt_s)?;
        chang.reset(ag0_mm_s2);
        Ok(Self {
            proto: *proto,
            chang,
        })
    }

    /// Back to rest at t = 0 under the ground acceleration `ag0_mm_s2` (a new run of the same record).
    pub fn reset(&mut self, ag0_mm_s2: f64) {
        self.chang.reset(ag0_mm_s2);
    }

    /// Step to the next tick under the ground acceleration `ag_mm_s2` there; returns the brace
    /// axial deformation at that tick, mm.
    pub fn advance(&mut self, ag_mm_s2: f64) -> f64 {
        // A pure analysis: the brace is part of the numerical model, no external restoring force.
        self.chang.advance(ag_mm_s2, &Vector::<1>::zeros());
        self.brace_disp_mm()
    }

    /// Brace axial deformation d = x·cosθ at the current tick, mm.
    pub fn brace_disp_mm(&self) -> f64 {
        self.proto.brace_disp_mm(self.chang.state().disp[0])
    }

    /// Story drift x, story velocity and relative acceleration at the current tick (mm, mm/s, mm/s²).
    pub fn state(&self) -> &Kinematics<1> {
        self.chang.state()
    }

    /// The prototype being integrated.
    pub fn prototype(&self) -> &Prototype {
        &self.proto
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::DT_S;

    /// The struct is exactly the Chang integrator on the pure model (the bit-identity the host,
    /// trainer and firmware rely on).
    #[test]
    fn matches_a_bare_chang_integrator_bit_for_bit() -> Result<(), ParamError> {
        let p = Prototype::paper();
        let ag = |k: usize| 2500.0 * libm::sin(k as f64 * 0.031) + 40.0 * k as f64 % 7.0;
        let mut r = Reference::new(&p, DT_S, ag(0))?;
        let mut c = Chang::new(LinearStructure::prototype_pure(&p)?, DT_S)?;
        c.reset(ag(0));
        assert_eq!(r.brace_disp_mm(), 0.0);
        for k in 1..3000 {
            c.advance(ag(k), &Vector::<1>::zeros());
            let d = r.advance(ag(k));
            assert_eq!(d.to_bits(), p.brace_disp_mm(c.state().disp[0]).to_bits());
            assert_eq!(r.state(), c.state());
        }
        Ok(())
    }

    #[test]
    fn bad_step_is_refused() {
        assert!(Reference::new(&Prototype::paper(), 0.0, 0.0).is_err());
    }
}

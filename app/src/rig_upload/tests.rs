//! Tests of [`crate::rig_upload`]: a rig compensation swaps in whole; bad ones are refused and the
//! controller keeps what it had.

use super::*;
use rths_core::control::{ControlConfig, FeedbackSource};
use rths_core::model::{assemble, ModelSpec};
use rths_core::params::{Prototype, SpecimenScale, DT_S, PAPER_DELAY_STEPS};
use rths_core::supervisor::Limits;

fn controller(spec: &ModelSpec<'_>) -> Controller {
    let cfg = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let (a, c) = assemble(spec, Prototype::paper(), DT_S).unwrap();
    Controller::new(cfg, a, c)
}

fn fe_ats() -> Controller {
    controller(&ModelSpec::FeAts {
        expected_delay_s: PAPER_DELAY_STEPS as f64 * DT_S,
    })
}

const COEFFS: [f64; 9] = [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.9, -0.9, 0.0];
const LEAD: [f64; 8] = [1.2, -0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];

fn lrx() -> Controller {
    controller(&ModelSpec::Lrx {
        coeffs: &COEFFS,
        k_corr_kn_per_mm: 12.0,
        k_adapt_ticks: 0.0,
        lead_weights: &LEAD,
        lead_stride: 2,
        lead_adapt_ticks: 0.0,
        specimen_dynamics: [0.0; 2],
    })
}

fn frame(v: &[f64]) -> [f64; RECORD_CHUNK] {
    let mut f = [0.0; RECORD_CHUNK];
    f[..v.len()].copy_from_slice(v);
    f
}

fn up(
    ctl: &mut Controller,
    build: ModelKind,
    kind: ModelKind,
    v: &[f64],
) -> Result<u32, NackReason> {
    let c = rths_link::rig_checksum(kind, v);
    upload_rig(ctl, build, kind, v.len() as u8, &frame(v), c)
}

#[test]
fn an_ats_start_is_uploaded_and_reported() {
    let mut ctl = fe_ats();
    let Compensator::Ats(a) = ctl.compensator() else {
        panic!("not an ATS")
    };
    let compiled = a.params().initial();
    assert_eq!(
        rig_checksum_of(&ctl),
        rths_link::rig_checksum(ModelKind::FeAts, &compiled)
    );
    let new = [compiled[0] * 1.05, compiled[1] * 1.1, compiled[2]];
    let c = up(&mut ctl, ModelKind::FeAts, ModelKind::FeAts, &new).unwrap();
    assert_eq!(c, rths_link::rig_checksum(ModelKind::FeAts, &new));
    assert_eq!(rig_checksum_of(&ctl), c);
    let Compensator::Ats(a) = ctl.compensator() else {
        panic!("not an ATS")
    };
    assert_eq!(a.params().initial(), new);
    assert_eq!(a.coefficients(), new, "it starts from them");
}

#[test]
fn an_lrx_rig_replaces_the_lead_and_the_specimen_dynamics_only() {
    let mut ctl = lrx();
    let Analytical::Lrx(m) = ctl.analytical() else {
        panic!("not an LRX")
    };
    let coeffs = *m.params().coeffs();
    let v = rths_link::rig_values(
        &[1.3, -0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        3,
        4096.0,
        [1e-5, 2e-3],
    )
    .unwrap();
    let c = up(&mut ctl, ModelKind::Lrx, ModelKind::Lrx, &v).unwrap();
    assert_eq!(rig_checksum_of(&ctl), c);
    let Analytical::Lrx(m) = ctl.analytical() else {
        panic!("not an LRX")
    };
    assert_eq!(*m.params().coeffs(), coeffs, "the frame model stays");
    assert_eq!(m.params().specimen_dynamics(), (1e-5, 2e-3));
    let Compensator::Lead(l) = ctl.compensator() else {
        panic!("not a lead")
    };
    assert_eq!(l.params().stride(), 3);
    assert_eq!(l.params().adaptation().map(|a| a.ticks()), Some(4096.0));
}

#[test]
fn bad_rig_uploads_are_refused_with_their_reason_and_nothing_changes() {
    let mut ctl = fe_ats();
    let before = (ctl.analytical().clone(), ctl.compensator().clone());
    let Compensator::Ats(a) = ctl.compensator() else {
        panic!("not an ATS")
    };
    let ok = a.params().initial();
    let (fe, lx) = (ModelKind::FeAts, ModelKind::Lrx);
    // Another build's kind, a kind without rig compensation, a wrong count.
    assert_eq!(
        up(&mut ctl, fe, lx, &[0.0; 12]),
        Err(NackReason::Unsupported)
    );
    assert_eq!(
        up(&mut ctl, ModelKind::Rnn, ModelKind::Rnn, &ok),
        Err(NackReason::Unsupported)
    );
    assert_eq!(up(&mut ctl, fe, fe, &ok[..2]), Err(NackReason::Shape));
    // A NaN, a corrupted value (checksum), outside the ATS's bounds.
    assert_eq!(
        up(&mut ctl, fe, fe, &[f64::NAN, ok[1], ok[2]]),
        Err(NackReason::NotFinite)
    );
    let c = rths_link::rig_checksum(fe, &ok);
    let mut bad = frame(&ok);
    bad[1] *= 2.0;
    assert_eq!(
        upload_rig(&mut ctl, fe, fe, 3, &bad, c),
        Err(NackReason::Checksum)
    );
    assert_eq!(
        up(&mut ctl, fe, fe, &[1e6, ok[1], ok[2]]),
        Err(NackReason::OutOfRange)
    );
    assert_eq!(
        (ctl.analytical().clone(), ctl.compensator().clone()),
        before
    );
    // Under a test.
    ctl.supervisor_mut().arm().unwrap();
    assert_eq!(up(&mut ctl, fe, fe, &ok), Err(NackReason::Busy));
    // The LRX's own checks: a fractional stride, a negative mass, a bad adaptation constant.
    let mut ctl = lrx();
    let before = (ctl.analytical().clone(), ctl.compensator().clone());
    let good = rths_link::rig_values(&LEAD, 2, 0.0, [0.0; 2]).unwrap();
    for (i, x) in [(8, 2.5), (10, -1.0), (9, -5.0)] {
        let mut v = good;
        v[i] = x;
        assert_eq!(up(&mut ctl, lx, lx, &v), Err(NackReason::OutOfRange), "{i}");
    }
    assert_eq!(
        (ctl.analytical().clone(), ctl.compensator().clone()),
        before
    );
}

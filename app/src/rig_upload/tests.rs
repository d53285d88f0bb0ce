//! Tests of [`crate::rig_upload`]: a rig compensation swaps in whole; bad ones are refused and the
//! controller keeps what it had.

use super::*;
use rths_core::control::{ControlConfig, FeedbackSource};
use rths_core::model::{assemble, ModelSpec};
use rths_core::params::{Prototype, SpecimenScale, DT_S, PAPER_DELAY_STEPS};
use rths_core::supervisor::Limits;
use rths_link::layout::Dims;

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

/// The part in force: `build`, on the M7's tick at 2048 Hz.
fn part(build: ModelKind) -> InForce {
    InForce {
        kind: build,
        dims: Dims::default(),
        budget: Some(TickBudget::cortex_m7_480mhz(2048.0)),
    }
}

fn up(
    ctl: &mut Controller,
    build: ModelKind,
    kind: ModelKind,
    v: &[f64],
) -> Result<u32, NackReason> {
    let c = rths_link::rig_checksum(kind, v);
    upload_rig(ctl, &part(build), kind, v.len() as u8, &frame(v), c)
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
        upload_rig(&mut ctl, &part(fe), fe, 3, &bad, c),
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

/// A 2-mode, 2-spring modal-hysteretic model (not trained: only the upload is tested).
fn modal() -> Controller {
    use rths_core::control::{ModalSpec, StoryLawSpec};
    use rths_core::metamodel::ModalMode;
    let modes = [
        ModalMode {
            omega_rad_s: 20.0,
            damping_ratio: 0.02,
            ground_participation: 1.0,
        },
        ModalMode {
            omega_rad_s: 60.0,
            damping_ratio: 0.03,
            ground_participation: 0.3,
        },
    ];
    let law = StoryLawSpec {
        k0_kn_per_mm: 40.0,
        yield_force_kn: 20.0,
        post_yield_ratio: 0.05,
        bouc_wen: None,
    };
    controller(&ModelSpec::StructureModal {
        model: ModalSpec {
            modes: &modes,
            shape: &[0.5, 0.2, 0.9, -0.4],
            specimen_dof: 0,
            specimen_k_kn_per_mm: 50.0,
            laws: &[law, law],
            drift: &[0.5, 0.2, 0.4, -0.6],
        },
    })
}

/// `values` sent in chunks and committed.
fn chunked(
    st: &mut RigStaging,
    ctl: &mut Controller,
    p: &InForce,
    kind: ModelKind,
    v: &[f64],
    checksum: u32,
) -> Result<u32, NackReason> {
    st.begin(p.kind, kind, v.len() as u8, checksum, true)?;
    for (i, ch) in v.chunks(RECORD_CHUNK).enumerate() {
        st.chunk(i as u32, ch.len() as u8, &frame(ch), true)?;
    }
    st.commit(ctl, p)
}

#[test]
fn a_structure_part_takes_the_rig_s_lead_force_correction_and_scale_in_chunks() {
    use rths_core::control::CompensatorTarget;
    let sm = ModelKind::StructureModal;
    let mut ctl = modal();
    let p = InForce {
        kind: sm,
        dims: dims_of(&ctl),
        budget: Some(TickBudget::cortex_m7_480mhz(2048.0)),
    };
    assert_eq!((p.dims.modes, p.dims.springs, p.dims.dofs), (2, 2, 2));
    assert_eq!(rig_checksum_of(&ctl), 0, "no compensation yet");
    let v = rths_link::layout::structure_rig_values(
        &LEAD,
        2,
        4096.0,
        [0.05, 1e-4, 1e-6],
        [2.0, 1500.0],
    )
    .unwrap();
    let c = rths_link::rig_checksum(sm, &v);
    // One frame holds 12 values: a structure part's 15 go in chunks.
    assert_eq!(up(&mut ctl, sm, sm, &v[..12]), Err(NackReason::Shape));
    let mut st = RigStaging::new();
    assert_eq!(chunked(&mut st, &mut ctl, &p, sm, &v, c), Ok(c));
    assert_eq!(ctl.scenario_name(), ("nl-online", None));
    assert_eq!(rig_checksum_of(&ctl), c, "reported as uploaded");
    let cfg = ctl.config();
    assert_eq!(cfg.compensator_target(), CompensatorTarget::Current);
    assert_eq!(cfg.scale().force_scale(), 1500.0);
    assert_eq!(cfg.force_correction().unwrap().k_kn_per_mm(), 0.05);
    let Compensator::Lead(l) = ctl.compensator() else {
        panic!("not a lead")
    };
    assert_eq!(l.params().adaptation().map(|a| a.ticks()), Some(4096.0));
}

#[test]
fn bad_structure_rig_compensations_are_refused_and_nothing_changes() {
    let sm = ModelKind::StructureModal;
    let mut ctl = modal();
    let good =
        rths_link::layout::structure_rig_values(&LEAD, 2, 0.0, [0.05, 0.0, 0.0], [1.0, 1000.0])
            .unwrap();
    let p = InForce {
        kind: sm,
        dims: dims_of(&ctl),
        budget: Some(TickBudget::cortex_m7_480mhz(2048.0)),
    };
    let before = (ctl.analytical().clone(), ctl.compensator().clone());
    let mut st = RigStaging::new();
    // Another kind than the part in force, another count.
    assert_eq!(
        st.begin(sm, ModelKind::Lrx, 12, 0, true),
        Err(NackReason::Unsupported)
    );
    assert_eq!(st.begin(sm, sm, 14, 0, true), Err(NackReason::Shape));
    assert_eq!(st.begin(sm, sm, 15, 0, false), Err(NackReason::Busy));
    // Out of order, a NaN, short, a wrong checksum.
    st.begin(sm, sm, 15, 0, true).unwrap();
    assert_eq!(
        st.chunk(1, 3, &frame(&good[12..]), true),
        Err(NackReason::Sequence)
    );
    let mut nan = good;
    nan[13] = f64::NAN;
    st.begin(sm, sm, 15, 0, true).unwrap();
    assert_eq!(
        st.chunk(0, 12, &frame(&nan[..12]), true)
            .and_then(|()| st.chunk(1, 3, &frame(&nan[12..]), true)),
        Err(NackReason::NotFinite)
    );
    st.begin(sm, sm, 15, 0, true).unwrap();
    st.chunk(0, 12, &frame(&good[..12]), true).unwrap();
    assert_eq!(st.commit(&mut ctl, &p), Err(NackReason::Incomplete));
    let c = rths_link::rig_checksum(sm, &good);
    assert_eq!(
        chunked(&mut st, &mut ctl, &p, sm, &good, c ^ 1),
        Err(NackReason::Checksum)
    );
    // Core's bounds: a fractional stride, a negative stiffness, a zero force scale.
    for (i, x) in [(8, 2.5), (10, -1.0), (14, 0.0)] {
        let mut v = good;
        v[i] = x;
        let c = rths_link::rig_checksum(sm, &v);
        assert_eq!(
            chunked(&mut st, &mut ctl, &p, sm, &v, c),
            Err(NackReason::OutOfRange),
            "{i}"
        );
    }
    // A tick too short for the part with its compensation: refused for the tick.
    let slow = InForce {
        budget: Some(TickBudget {
            clock_hz: 1e6,
            ..TickBudget::cortex_m7_480mhz(2048.0)
        }),
        ..p
    };
    assert_eq!(
        chunked(&mut st, &mut ctl, &slow, sm, &good, c),
        Err(NackReason::TickBudget)
    );
    assert_eq!(
        (ctl.analytical().clone(), ctl.compensator().clone()),
        before
    );
    assert_eq!(ctl.scenario_name(), ("structure-modal", None));
}

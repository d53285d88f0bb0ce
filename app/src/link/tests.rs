//! Tests of [`crate::link`]: request handling against a controller, telemetry numbering.

extern crate std;

use super::*;
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, FeedbackSource};
use rths_core::metamodel::{Lr, LrParams};
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::FaultReason;
use rths_link::Request;

const THETA: [f64; LR_COEFFS] = [0.0, 0.5, 0.1, 0.0, 0.0, 0.0];

fn controller() -> Controller {
    let cfg = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let lr = LrParams::new(THETA).unwrap();
    Controller::new(cfg, Analytical::Lr(Lr::new(lr)), Compensator::None)
}

fn session(rearm: Rearm) -> Session<'static> {
    Session::new(
        compiled_model_checksum(&THETA),
        TickBudget::cortex_m4_168mhz(2048.0),
        rearm,
        ModelKind::Lr,
        &mut [],
    )
}

/// A compiled-in record of 3 samples and no upload buffer (the requests these tests send do not
/// touch the record).
fn store() -> RecordStore<'static> {
    RecordStore::new(&[0.0, 0.1, 0.0], 0.01, 41, &mut [])
}

fn ack(r: Request) -> (DeviceMsg, Effect) {
    (DeviceMsg::Ack(r), Effect::None)
}

#[test]
fn arm_start_abort_and_refusals() {
    let mut ctl = controller();
    let mut run = Run::new();
    let mut s = session(Rearm::OncePerPowerUp);
    let (m, _) = handle(
        HostMsg::Start,
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    assert_eq!(
        m,
        DeviceMsg::Nack(Request::Start, NackReason::InvalidState),
        "start before arm"
    );
    let (m, _) = handle(
        HostMsg::Arm { telemetry_every: 0 },
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    assert_eq!(m, DeviceMsg::Nack(Request::Arm, NackReason::OutOfRange));
    assert_eq!(
        handle(
            HostMsg::Arm { telemetry_every: 4 },
            &mut ctl,
            &mut run,
            &mut store(),
            &mut s,
            false
        ),
        ack(Request::Arm)
    );
    assert_eq!(s.every, 4);
    assert_eq!(
        handle(
            HostMsg::Start,
            &mut ctl,
            &mut run,
            &mut store(),
            &mut s,
            false
        ),
        (DeviceMsg::Ack(Request::Start), Effect::Started)
    );
    assert_eq!(ctl.supervisor().state(), State::Running);
    assert_eq!(
        handle(
            HostMsg::Abort,
            &mut ctl,
            &mut run,
            &mut store(),
            &mut s,
            false
        ),
        ack(Request::Abort)
    );
    assert_eq!(ctl.supervisor().state(), State::RampDown);
    // The emulated plant plays once per power-up.
    let (m, _) = handle(
        HostMsg::Arm { telemetry_every: 1 },
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        true,
    );
    assert_eq!(m, DeviceMsg::Nack(Request::Arm, NackReason::Unsupported));
}

#[test]
fn a_real_rig_rearms_after_a_run_at_the_measured_position() {
    let mut ctl = controller();
    let mut run = Run::new();
    let mut s = session(Rearm::AtMeasured);
    handle(
        HostMsg::Arm { telemetry_every: 1 },
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    handle(
        HostMsg::Abort,
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    // Ramp the aborted run down to Done (it was armed at 0 mm and never moved).
    for _ in 0..10 {
        ctl.tick(0.0, Ok(rths_core::hal::Sample::default()), false);
    }
    assert_eq!(ctl.supervisor().state(), State::Done);
    run.telemetry_dropped = 5;
    assert_eq!(
        handle(
            HostMsg::Arm { telemetry_every: 2 },
            &mut ctl,
            &mut run,
            &mut store(),
            &mut s,
            true
        ),
        ack(Request::Arm)
    );
    assert_eq!(ctl.supervisor().state(), State::Armed);
    assert_eq!(run.telemetry_dropped, 0, "a new run's counts");
}

#[test]
fn upload_lr_refusals_and_swap() {
    let mut ctl = controller();
    let mut run = Run::new();
    let theta = [0.0, 0.4, 0.1, 0.0, 0.0, 0.0];
    let crc = rths_link::model_checksum(&theta, 28);
    let up = |features, theta: [f64; LR_COEFFS], checksum| HostMsg::UploadLr {
        features,
        theta,
        delay_steps: 28,
        checksum,
    };
    // An image whose compiled-in part is FE + ATS takes it too: the LR runs without the ATS, as
    // the host's `lr-online` does, and the status reports the new kind.
    {
        let mut fe_ctl = std::boxed::Box::new(controller());
        let spec = rths_core::model::ModelSpec::FeAts {
            expected_delay_s: 0.0137,
        };
        rths_core::model::assemble_in(&mut fe_ctl, &spec, Prototype::paper(), DT_S).unwrap();
        let mut fe = Session::new(
            0,
            TickBudget::cortex_m4_168mhz(2048.0),
            Rearm::OncePerPowerUp,
            ModelKind::FeAts,
            &mut [],
        );
        let (m, _) = handle(
            up(6, theta, crc),
            &mut fe_ctl,
            &mut run,
            &mut store(),
            &mut fe,
            false,
        );
        assert_eq!(m, DeviceMsg::Ack(Request::UploadLr));
        assert!(matches!(fe_ctl.analytical(), Analytical::Lr(_)));
        assert_eq!(*fe_ctl.compensator(), Compensator::None);
        assert_eq!(
            (fe.model_kind, fe.model_checksum, fe.model_source),
            (ModelKind::Lr, crc, RecordSource::Uploaded)
        );
    }
    let mut s = session(Rearm::OncePerPowerUp);
    let nack = |n| DeviceMsg::Nack(Request::UploadLr, n);
    assert_eq!(
        handle(
            up(5, theta, crc),
            &mut ctl,
            &mut run,
            &mut store(),
            &mut s,
            false
        )
        .0,
        nack(NackReason::Shape)
    );
    let mut bad = theta;
    bad[1] = f64::NAN;
    assert_eq!(
        handle(
            up(6, bad, crc),
            &mut ctl,
            &mut run,
            &mut store(),
            &mut s,
            false
        )
        .0,
        nack(NackReason::NotFinite)
    );
    assert_eq!(
        handle(
            up(6, theta, crc ^ 1),
            &mut ctl,
            &mut run,
            &mut store(),
            &mut s,
            false
        )
        .0,
        nack(NackReason::Checksum)
    );
    assert_eq!(
        handle(
            up(6, theta, crc),
            &mut ctl,
            &mut run,
            &mut store(),
            &mut s,
            false
        ),
        ack(Request::UploadLr)
    );
    assert_eq!(s.model_checksum, crc);
    let (st, _) = handle(
        HostMsg::Status,
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    match st {
        DeviceMsg::Status(st) => {
            assert_eq!(st.model_checksum, crc);
            assert_eq!(st.state, RunState::Idle);
        }
        other => panic!("{other:?}"),
    }
    // Busy while running.
    handle(
        HostMsg::Arm { telemetry_every: 1 },
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    handle(
        HostMsg::Start,
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    assert_eq!(
        handle(
            up(6, theta, crc),
            &mut ctl,
            &mut run,
            &mut store(),
            &mut s,
            false
        )
        .0,
        nack(NackReason::Busy)
    );
    let (m, _) = handle(
        HostMsg::SetLimits {
            stroke_mm: 10.0,
            velocity_mm_s: 100.0,
            force_kn: 5.0,
        },
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    assert_eq!(m, DeviceMsg::Nack(Request::SetLimits, NackReason::Busy));
}

#[test]
fn telemetry_decimation_and_sequence_numbers() {
    let mut s = session(Rearm::OncePerPowerUp);
    s.every = 3;
    let rec = |tick| TelemetryRecord {
        tick,
        command_mm: 1.0,
        target_mm: 2.0,
        measured_mm: 3.0,
        force_kn: 4.0,
        state: State::Fault(FaultReason::FrozenSensor),
    };
    let sent: heapless::Vec<(u32, u32), 8> = (0..10)
        .filter_map(|k| match s.telemetry(&rec(k)) {
            Some(DeviceMsg::Telemetry(t)) => {
                assert_eq!(t.state, RunState::Fault(11));
                Some((t.seq, t.tick))
            }
            _ => None,
        })
        .collect();
    assert_eq!(sent.as_slice(), &[(0, 0), (1, 3), (2, 6), (3, 9)]);
    let mut run = Run::new();
    run.ticks = 10;
    run.telemetry_dropped = 1;
    assert_eq!(
        s.run_ended(&run),
        DeviceMsg::RunEnded {
            state: RunState::Idle,
            ticks: 10,
            records_sent: 4,
            records_dropped: 1
        }
    );
}

#[test]
fn send_writes_one_frame() {
    struct Port(heapless::Vec<u8, 512>);
    impl LinkPort for Port {
        fn read_byte(&mut self) -> Option<u8> {
            None
        }
        fn write_all(&mut self, bytes: &[u8]) {
            self.0.extend_from_slice(bytes).unwrap();
        }
    }
    let mut p = Port(heapless::Vec::new());
    send(&mut p, &DeviceMsg::Ack(Request::Abort));
    let mut r = rths_link::FrameReader::<{ rths_link::MAX_FRAME }>::new();
    let got: heapless::Vec<DeviceMsg, 2> =
        p.0.iter()
            .filter_map(|&b| r.push::<DeviceMsg>(b))
            .map(|m| m.unwrap())
            .collect();
    assert_eq!(got.as_slice(), &[DeviceMsg::Ack(Request::Abort)]);
}

#[test]
fn a_record_upload_over_handle_is_reported_and_refused_under_a_test() {
    extern crate std;
    use rths_link::{record_checksum, RecordSource, RECORD_CHUNK};
    use std::vec::Vec;
    let mut ctl = controller();
    let mut run = Run::new();
    let mut s = session(Rearm::AtMeasured);
    let mut buf = [0.0; 64];
    let compiled = [0.0, 0.1, 0.0];
    let mut store = RecordStore::new(&compiled, 0.01, 41, &mut buf);
    let motion: Vec<f64> = (0..20).map(|i| i as f64 * 0.01).collect();
    let c = record_checksum(&motion, 0.02);
    let chunk = |i: usize| {
        let ch = motion.chunks(RECORD_CHUNK).nth(i).unwrap();
        let mut values = [0.0; RECORD_CHUNK];
        values[..ch.len()].copy_from_slice(ch);
        HostMsg::RecordChunk {
            seq: i as u32,
            count: ch.len() as u8,
            values,
        }
    };
    let begin = HostMsg::RecordBegin {
        samples: 20,
        dt_s: 0.02,
        scale: 0.5,
        checksum: c,
    };
    let mut h = |m: HostMsg, ctl: &mut Controller, store: &mut RecordStore<'_>| {
        handle(m, ctl, &mut run, store, &mut s, false).0
    };
    // Armed: every record request is refused Busy, nothing changes.
    assert_eq!(
        h(HostMsg::Arm { telemetry_every: 1 }, &mut ctl, &mut store),
        DeviceMsg::Ack(Request::Arm)
    );
    assert_eq!(
        h(begin, &mut ctl, &mut store),
        DeviceMsg::Nack(Request::RecordBegin, NackReason::Busy)
    );
    assert_eq!(store.info().source, RecordSource::Compiled);
    // At rest (a fresh controller): the upload goes through.
    let mut ctl = controller();
    assert_eq!(
        h(begin, &mut ctl, &mut store),
        DeviceMsg::Ack(Request::RecordBegin)
    );
    assert_eq!(
        h(chunk(1), &mut ctl, &mut store),
        DeviceMsg::Nack(Request::RecordChunk, NackReason::Sequence),
        "reordered"
    );
    assert_eq!(
        h(begin, &mut ctl, &mut store),
        DeviceMsg::Ack(Request::RecordBegin)
    );
    assert_eq!(
        h(chunk(0), &mut ctl, &mut store),
        DeviceMsg::Ack(Request::RecordChunk)
    );
    assert_eq!(
        h(chunk(1), &mut ctl, &mut store),
        DeviceMsg::Ack(Request::RecordChunk)
    );
    assert_eq!(
        h(HostMsg::RecordCommit, &mut ctl, &mut store),
        DeviceMsg::Ack(Request::RecordCommit)
    );
    let DeviceMsg::Status(st) = h(HostMsg::Status, &mut ctl, &mut store) else {
        panic!("status")
    };
    assert_eq!(st.record.source, RecordSource::Uploaded);
    assert_eq!(st.record.checksum, c);
    assert_eq!(st.record.samples, 20);
    assert_eq!(st.record.scale, 0.5);
    assert_eq!(st.record_capacity, 32);
    assert_eq!(st.model_kind, ModelKind::Lr);
}

#[test]
fn the_link_loss_policy_is_chosen_at_arm_time() {
    use rths_link::{LinkLoss, LINK_TIMEOUT_TICKS};
    let mut ctl = controller();
    let mut run = Run::new();
    let mut s = session(Rearm::OncePerPowerUp);
    assert_eq!(s.link_loss, LinkLoss::Complete);
    let (m, _) = handle(
        HostMsg::ArmWith {
            telemetry_every: 0,
            on_link_loss: LinkLoss::RampDown,
            owner: 7,
        },
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    assert_eq!(m, DeviceMsg::Nack(Request::Arm, NackReason::OutOfRange));
    assert_eq!(
        s.link_loss,
        LinkLoss::Complete,
        "a refused arm changes nothing"
    );
    let (m, _) = handle(
        HostMsg::ArmWith {
            telemetry_every: 2,
            on_link_loss: LinkLoss::RampDown,
            owner: 7,
        },
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    assert_eq!(m, DeviceMsg::Ack(Request::Arm));
    assert_eq!((s.link_loss, s.every), (LinkLoss::RampDown, 2));
    // Another host cannot start it (a plain Start or another token); its owner can; an abort
    // from anyone is obeyed.
    for m in [HostMsg::Start, HostMsg::StartAs { owner: 8 }] {
        let (a, _) = handle(m, &mut ctl, &mut run, &mut store(), &mut s, false);
        assert_eq!(a, DeviceMsg::Nack(Request::Start, NackReason::NotOwner));
    }
    let (a, e) = handle(
        HostMsg::StartAs { owner: 7 },
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    assert_eq!((a, e), (DeviceMsg::Ack(Request::Start), Effect::Started));
    let (a, _) = handle(
        HostMsg::Abort,
        &mut ctl,
        &mut run,
        &mut store(),
        &mut s,
        false,
    );
    assert_eq!(a, DeviceMsg::Ack(Request::Abort));
    // Lost after more than the timeout of silence, and only with RampDown; the tick count wraps.
    assert!(!link_lost(
        LinkLoss::RampDown,
        100 + LINK_TIMEOUT_TICKS,
        100
    ));
    assert!(link_lost(LinkLoss::RampDown, 101 + LINK_TIMEOUT_TICKS, 100));
    assert!(link_lost(
        LinkLoss::RampDown,
        5,
        u32::MAX - LINK_TIMEOUT_TICKS
    ));
    assert!(!link_lost(LinkLoss::Complete, 1_000_000, 0));
}

#[test]
fn holdings_report_the_model_and_rig_origin_and_uploads_change_them() {
    let mut ctl = controller();
    let mut run = Run::new();
    let mut s = session(Rearm::OncePerPowerUp).with_build_id(0xB111_D000);
    let mut st = store();
    let h = |ctl: &mut Controller, run: &mut Run, st: &mut RecordStore<'_>, s: &mut Session<'_>| {
        match handle(HostMsg::Holdings, ctl, run, st, s, false).0 {
            DeviceMsg::Holdings(h) => h,
            other => panic!("{other:?}"),
        }
    };
    let h0 = h(&mut ctl, &mut run, &mut st, &mut s);
    assert_eq!(h0.model_kind, ModelKind::Lr);
    assert_eq!(h0.model_source, RecordSource::Compiled);
    assert_eq!(h0.model_checksum, compiled_model_checksum(&THETA));
    assert_eq!(
        (h0.rig_source, h0.rig_checksum),
        (RecordSource::Compiled, 0)
    );
    assert_eq!(h0.rate_hz, rths_core::params::CONTROL_RATE_HZ);
    assert_eq!(h0.build_id, 0xB111_D000);
    // An LR build has no rig compensation: refused, nothing changes.
    let rig = HostMsg::UploadRig {
        kind: ModelKind::Lr,
        count: 0,
        values: [0.0; rths_link::RECORD_CHUNK],
        checksum: rths_link::rig_checksum(ModelKind::Lr, &[]),
    };
    assert_eq!(
        handle(rig, &mut ctl, &mut run, &mut st, &mut s, false).0,
        DeviceMsg::Nack(Request::UploadRig, NackReason::Unsupported)
    );
    assert_eq!(h(&mut ctl, &mut run, &mut st, &mut s), h0);
    let theta = [0.0, 0.4, 0.1, 0.0, 0.0, 0.0];
    let checksum = rths_link::model_checksum(&theta, 28);
    let up = HostMsg::UploadLr {
        features: 6,
        theta,
        delay_steps: 28,
        checksum,
    };
    assert_eq!(
        handle(up, &mut ctl, &mut run, &mut st, &mut s, false).0,
        DeviceMsg::Ack(Request::UploadLr)
    );
    let h1 = h(&mut ctl, &mut run, &mut st, &mut s);
    assert_eq!(
        (h1.model_source, h1.model_checksum),
        (RecordSource::Uploaded, checksum)
    );
}

/// A structure part uploaded over `handle` (the modal model of a 1-story structure, in chunks),
/// then its rig compensation in chunks: the holdings report the kind, the uploads' checksums, and
/// an `UploadRig` frame cannot carry a structure part's 15 values.
#[test]
fn a_structure_part_and_its_rig_compensation_go_in_chunks_over_handle() {
    use rths_core::control::{ModalSpec, StoryLawSpec};
    use rths_core::metamodel::ModalMode;
    use rths_core::model::ModelSpec;
    use rths_link::RECORD_CHUNK;
    let spec = ModelSpec::StructureModal {
        model: ModalSpec {
            modes: &[ModalMode {
                omega_rad_s: 20.0,
                damping_ratio: 0.02,
                ground_participation: 1.0,
            }],
            shape: &[0.7],
            specimen_dof: 0,
            specimen_k_kn_per_mm: 50.0,
            laws: &[StoryLawSpec {
                k0_kn_per_mm: 40.0,
                yield_force_kn: 20.0,
                post_yield_ratio: 0.05,
                bouc_wen: None,
            }],
            drift: &[0.7],
        },
    };
    let mut v = std::vec![0.0; rths_link::MODEL_MAX_VALUES];
    let (kind, n) = rths_link::layout::lay_out(&spec, &mut v).unwrap();
    v.truncate(n);
    let mut ctl = controller();
    let mut run = Run::new();
    let mut area = std::vec![0.0; rths_link::MODEL_MAX_VALUES];
    let mut s = Session::new(
        compiled_model_checksum(&THETA),
        TickBudget::cortex_m7_480mhz(2048.0),
        Rearm::OncePerPowerUp,
        ModelKind::Lr,
        &mut area,
    );
    let frame = |xs: &[f64]| {
        let mut f = [0.0; RECORD_CHUNK];
        f[..xs.len()].copy_from_slice(xs);
        f
    };
    let mut send = |m: HostMsg, ctl: &mut Controller, s: &mut Session<'_>| {
        handle(m, ctl, &mut run, &mut store(), s, false).0
    };
    let c = rths_link::model_values_checksum(kind, &v, 0);
    let r = send(
        HostMsg::ModelBegin {
            kind,
            values: n as u16,
            delay_steps: 0,
            checksum: c,
        },
        &mut ctl,
        &mut s,
    );
    assert_eq!(r, DeviceMsg::Ack(Request::ModelBegin));
    for (i, ch) in v.chunks(RECORD_CHUNK).enumerate() {
        let m = HostMsg::ModelChunk {
            seq: i as u32,
            count: ch.len() as u8,
            values: frame(ch),
        };
        assert_eq!(
            send(m, &mut ctl, &mut s),
            DeviceMsg::Ack(Request::ModelChunk)
        );
    }
    assert_eq!(
        send(HostMsg::ModelCommit, &mut ctl, &mut s),
        DeviceMsg::Ack(Request::ModelCommit)
    );
    let h = holdings(&ctl, &s);
    assert_eq!((h.model_kind, h.model_checksum), (kind, c));
    assert_eq!(h.rig_checksum, 0, "no compensation yet");
    let lead = [1.2, -0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let rig = rths_link::layout::structure_rig_values(
        &lead,
        2,
        4096.0,
        [0.05, 1e-4, 1e-6],
        [2.0, 1500.0],
    )
    .unwrap();
    let rc = rths_link::rig_checksum(kind, &rig);
    // One frame holds 12: refused for its shape, nothing changes.
    let r = send(
        HostMsg::UploadRig {
            kind,
            count: 12,
            values: frame(&rig[..12]),
            checksum: rc,
        },
        &mut ctl,
        &mut s,
    );
    assert_eq!(r, DeviceMsg::Nack(Request::UploadRig, NackReason::Shape));
    let r = send(
        HostMsg::RigBegin {
            kind,
            values: rig.len() as u8,
            checksum: rc,
        },
        &mut ctl,
        &mut s,
    );
    assert_eq!(r, DeviceMsg::Ack(Request::RigBegin));
    for (i, ch) in rig.chunks(RECORD_CHUNK).enumerate() {
        let m = HostMsg::RigChunk {
            seq: i as u32,
            count: ch.len() as u8,
            values: frame(ch),
        };
        assert_eq!(send(m, &mut ctl, &mut s), DeviceMsg::Ack(Request::RigChunk));
    }
    assert_eq!(
        send(HostMsg::RigCommit, &mut ctl, &mut s),
        DeviceMsg::Ack(Request::RigCommit)
    );
    let h = holdings(&ctl, &s);
    assert_eq!((h.rig_source, h.rig_checksum), (RecordSource::Uploaded, rc));
    assert_eq!(ctl.scenario_name(), ("nl-online", None));
    // A commit with nothing staged: out of sequence.
    assert_eq!(
        send(HostMsg::RigCommit, &mut ctl, &mut s),
        DeviceMsg::Nack(Request::RigCommit, NackReason::Sequence)
    );
}

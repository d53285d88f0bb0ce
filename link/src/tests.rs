use super::*;
use proptest::prelude::*;

fn any_state() -> impl Strategy<Value = RunState> {
    prop_oneof![
        Just(RunState::Idle),
        Just(RunState::Armed),
        Just(RunState::Running),
        Just(RunState::RampDown),
        Just(RunState::Done),
        any::<u8>().prop_map(RunState::Fault),
    ]
}

fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>(),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(-0.0)
    ]
}

fn any_host() -> impl Strategy<Value = HostMsg> {
    prop_oneof![
        Just(HostMsg::Status),
        (
            any::<u8>(),
            prop::array::uniform6(any_f64()),
            any::<u16>(),
            any::<u32>()
        )
            .prop_map(
                |(features, theta, delay_steps, checksum)| HostMsg::UploadLr {
                    features,
                    theta,
                    delay_steps,
                    checksum
                }
            ),
        (any_f64(), any_f64(), any_f64()).prop_map(|(a, b, c)| HostMsg::SetLimits {
            stroke_mm: a,
            velocity_mm_s: b,
            force_kn: c
        }),
        any::<u16>().prop_map(|telemetry_every| HostMsg::Arm { telemetry_every }),
        (
            any::<u16>(),
            prop_oneof![Just(LinkLoss::Complete), Just(LinkLoss::RampDown)],
            any::<u32>()
        )
            .prop_map(|(telemetry_every, on_link_loss, owner)| HostMsg::ArmWith {
                telemetry_every,
                on_link_loss,
                owner
            }),
        any::<u32>().prop_map(|owner| HostMsg::StartAs { owner }),
        Just(HostMsg::Start),
        Just(HostMsg::Abort),
        (any::<u32>(), any_f64(), any_f64(), any::<u32>()).prop_map(
            |(samples, dt_s, scale, checksum)| HostMsg::RecordBegin {
                samples,
                dt_s,
                scale,
                checksum
            }
        ),
        (
            any::<u32>(),
            any::<u8>(),
            prop::collection::vec(any_f64(), RECORD_CHUNK)
        )
            .prop_map(|(seq, count, v)| HostMsg::RecordChunk {
                seq,
                count,
                values: v.try_into().unwrap(),
            }),
        Just(HostMsg::RecordCommit),
        (any_kind(), any::<u16>(), any::<u16>(), any::<u32>()).prop_map(
            |(kind, values, delay_steps, checksum)| HostMsg::ModelBegin {
                kind,
                values,
                delay_steps,
                checksum
            }
        ),
        (
            any::<u32>(),
            any::<u8>(),
            prop::collection::vec(any_f64(), RECORD_CHUNK)
        )
            .prop_map(|(seq, count, v)| HostMsg::ModelChunk {
                seq,
                count,
                values: v.try_into().unwrap(),
            }),
        Just(HostMsg::ModelCommit),
        any_f64().prop_map(|amplitude_mm| HostMsg::Identify { amplitude_mm }),
        Just(HostMsg::Holdings),
        (
            any_kind(),
            any::<u8>(),
            prop::collection::vec(any_f64(), RECORD_CHUNK),
            any::<u32>()
        )
            .prop_map(|(kind, count, v, checksum)| HostMsg::UploadRig {
                kind,
                count,
                values: v.try_into().unwrap(),
                checksum,
            }),
        (
            any::<u32>(),
            prop::collection::vec(any_f64(), 8),
            any::<u16>()
        )
            .prop_map(|(ticks_per_step, w, lead_stride)| HostMsg::SiteBegin {
                ticks_per_step,
                lead_weights: w.try_into().unwrap(),
                lead_stride,
            }),
        (any::<u32>(), any_f64())
            .prop_map(|(step, target_mm)| HostMsg::SiteTarget { step, target_mm }),
        any::<bool>().prop_map(|fault| HostMsg::SiteEnd { fault }),
        (any::<u32>(), any_f64(), any_f64(), any::<u32>()).prop_map(
            |(samples, dt_s, scale, checksum)| HostMsg::StreamBegin {
                samples,
                dt_s,
                scale,
                checksum
            }
        ),
        (
            any::<u32>(),
            any::<u8>(),
            prop::collection::vec(any_f64(), RECORD_CHUNK)
        )
            .prop_map(|(seq, count, v)| HostMsg::StreamChunk {
                seq,
                count,
                values: v.try_into().unwrap(),
            }),
        Just(HostMsg::StreamStatus),
        (any_kind(), any::<u8>(), any::<u32>()).prop_map(|(kind, values, checksum)| {
            HostMsg::RigBegin {
                kind,
                values,
                checksum,
            }
        }),
        (
            any::<u32>(),
            any::<u8>(),
            prop::collection::vec(any_f64(), RECORD_CHUNK)
        )
            .prop_map(|(seq, count, v)| HostMsg::RigChunk {
                seq,
                count,
                values: v.try_into().unwrap(),
            }),
        Just(HostMsg::RigCommit),
    ]
}

fn any_kind() -> impl Strategy<Value = ModelKind> {
    prop_oneof![
        Just(ModelKind::Lr),
        Just(ModelKind::Lrx),
        Just(ModelKind::Rnn),
        Just(ModelKind::FeAts),
        Just(ModelKind::StructureFe),
        Just(ModelKind::StructureNl),
        Just(ModelKind::StructureMeta),
        Just(ModelKind::StructureModal),
        Just(ModelKind::StructureReduced),
        Just(ModelKind::StructureHysteron),
    ]
}

fn any_record_info() -> impl Strategy<Value = RecordInfo> {
    (
        prop_oneof![
            Just(RecordSource::Compiled),
            Just(RecordSource::Uploaded),
            Just(RecordSource::Streamed)
        ],
        any::<[u32; 3]>(),
        any_f64(),
        any_f64(),
    )
        .prop_map(|(source, u, dt_s, scale)| RecordInfo {
            source,
            samples: u[0],
            dt_s,
            scale,
            ticks: u[1],
            checksum: u[2],
        })
}

fn any_device() -> impl Strategy<Value = DeviceMsg> {
    let req = prop_oneof![
        Just(Request::Status),
        Just(Request::UploadLr),
        Just(Request::SetLimits),
        Just(Request::Arm),
        Just(Request::Start),
        Just(Request::Abort),
        Just(Request::RecordBegin),
        Just(Request::RecordChunk),
        Just(Request::RecordCommit),
        Just(Request::ModelBegin),
        Just(Request::ModelChunk),
        Just(Request::ModelCommit),
        Just(Request::Holdings),
        Just(Request::UploadRig),
        Just(Request::SiteBegin),
        Just(Request::SiteTarget),
        Just(Request::SiteEnd),
        Just(Request::StreamBegin),
        Just(Request::StreamChunk),
        Just(Request::StreamStatus),
        Just(Request::RigBegin),
        Just(Request::RigChunk),
        Just(Request::RigCommit),
    ];
    let reason = prop_oneof![
        Just(NackReason::Shape),
        Just(NackReason::NotFinite),
        Just(NackReason::Checksum),
        Just(NackReason::OutOfRange),
        Just(NackReason::Busy),
        Just(NackReason::InvalidState),
        Just(NackReason::Unsupported),
        Just(NackReason::Sequence),
        Just(NackReason::Incomplete),
        Just(NackReason::TooLong),
        Just(NackReason::Rate),
        Just(NackReason::NotOwner),
        Just(NackReason::TickBudget),
    ];
    let kind = any_kind();
    prop_oneof![
        req.clone().prop_map(DeviceMsg::Ack),
        (req, reason).prop_map(|(r, n)| DeviceMsg::Nack(r, n)),
        (
            any_state(),
            any::<[u32; 5]>(),
            (any_f64(), any_f64(), any_f64()),
            (kind, any_record_info(), any::<u32>()),
        )
            .prop_map(
                |(state, u, (a, b, c), (model_kind, record, record_capacity))| DeviceMsg::Status(
                    Status {
                        state,
                        model_checksum: u[0],
                        tick: u[1],
                        records_sent: u[2],
                        records_dropped: u[3],
                        stroke_mm: a,
                        velocity_mm_s: b,
                        force_kn: c,
                        bad_frames: u[4],
                        model_kind,
                        record,
                        record_capacity,
                    }
                )
            ),
        (
            any::<u32>(),
            any::<u32>(),
            any_state(),
            prop::array::uniform4(any_f64())
        )
            .prop_map(|(seq, tick, state, v)| DeviceMsg::Telemetry(Telemetry {
                seq,
                tick,
                state,
                command_mm: v[0],
                target_mm: v[1],
                measured_mm: v[2],
                force_kn: v[3],
            })),
        (any_state(), any::<[u32; 3]>()).prop_map(|(state, u)| DeviceMsg::RunEnded {
            state,
            ticks: u[0],
            records_sent: u[1],
            records_dropped: u[2],
        }),
        (any::<u32>(), prop::array::uniform3(any_f64())).prop_map(|(seq, v)| {
            DeviceMsg::IdentifySample(IdentifySample {
                seq,
                command_mm: v[0],
                measured_mm: v[1],
                force_kn: v[2],
            })
        }),
        (any_state(), any::<[u32; 3]>()).prop_map(|(state, u)| DeviceMsg::IdentifyEnded {
            state,
            ticks: u[0],
            samples_sent: u[1],
            samples_dropped: u[2],
        }),
        (
            any_kind(),
            any_kind(),
            any::<[u32; 4]>(),
            any::<[bool; 2]>()
        )
            .prop_map(|(model_kind, _, u, b)| {
                let src = |x: bool| {
                    if x {
                        RecordSource::Uploaded
                    } else {
                        RecordSource::Compiled
                    }
                };
                DeviceMsg::Holdings(Holdings {
                    model_kind,
                    model_source: src(b[0]),
                    model_checksum: u[0],
                    rig_source: src(b[1]),
                    rig_checksum: u[1],
                    rate_hz: u[2],
                    build_id: u[3],
                })
            }),
        (any::<[u32; 2]>(), any_f64(), any_f64()).prop_map(|(u, measured_mm, force_kn)| {
            DeviceMsg::SiteStep {
                step: u[0],
                tick: u[1],
                measured_mm,
                force_kn,
            }
        }),
        any::<[u32; 3]>().prop_map(|u| DeviceMsg::StreamAck {
            seq: u[0],
            next_seq: u[1],
            free: u[2],
        }),
        (
            any::<[u32; 4]>(),
            any::<bool>(),
            any::<Option<u32>>(),
            any::<Option<bool>>()
        )
            .prop_map(|(u, in_force, first_underrun_tick, checksum_ok)| {
                DeviceMsg::StreamStatus(StreamStatus {
                    in_force,
                    next_seq: u[0],
                    received: u[1],
                    free: u[2],
                    underrun_ticks: u[3],
                    first_underrun_tick,
                    checksum_ok,
                })
            }),
    ]
}

/// Bit-level equality (NaN == NaN with the same payload): postcard sends the IEEE bytes.
fn same<T: Serialize>(a: &T, b: &T) -> bool {
    let mut x = [0u8; MAX_FRAME];
    let mut y = [0u8; MAX_FRAME];
    postcard::to_slice(a, &mut x).unwrap() == postcard::to_slice(b, &mut y).unwrap()
}

fn round_trip<T: Serialize + for<'de> Deserialize<'de> + core::fmt::Debug>(m: &T) -> T {
    let mut buf = [0u8; MAX_FRAME + 1];
    let n = encode(m, &mut buf).unwrap();
    assert_eq!(buf[n - 1], 0, "ends with the delimiter");
    assert!(
        buf[..n - 1].iter().all(|b| *b != 0),
        "no zero inside a frame"
    );
    decode(&mut buf[..n - 1]).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn host_messages_round_trip(m in any_host()) {
        let d: HostMsg = round_trip(&m);
        prop_assert!(same(&d, &m), "{:?} vs {:?}", d, m);
    }

    #[test]
    fn device_messages_round_trip(m in any_device()) {
        let d: DeviceMsg = round_trip(&m);
        prop_assert!(same(&d, &m), "{:?} vs {:?}", d, m);
    }

    /// The receive path's COBS decoding (the crate's state machine, in place) gives what the
    /// crate's own `decode_in_place` gives on every frame body a reader can collect (no zero
    /// inside), and the same bytes.
    #[test]
    fn cobs_decoding_agrees_with_the_crates(bytes in prop::collection::vec(1u8..=255, 0..600)) {
        let mut ours = bytes.clone();
        let mut theirs = bytes.clone();
        let a = crate::cobs_decode_in_place(&mut ours).ok();
        let b = cobs::decode_in_place(&mut theirs).ok();
        match (a, b) {
            (Some(n), Some(m)) => prop_assert!(n == m && ours[..n] == theirs[..m]),
            (None, Some(m)) => prop_assert!(false, "refused what the crate decodes to {m} bytes"),
            (Some(n), None) => prop_assert!(false, "decoded {n} bytes the crate refuses"),
            (None, None) => {}
        }
    }

    /// Every payload (never empty: a frame holds at least its CRC), zeros and 254-byte runs
    /// included, comes back from its encoding.
    #[test]
    fn cobs_decoding_inverts_the_encoding(payload in prop::collection::vec(any::<u8>(), 1..700)) {
        let mut enc = vec![0u8; cobs::max_encoding_length(payload.len())];
        let m = cobs::encode(&payload, &mut enc);
        let n = crate::cobs_decode_in_place(&mut enc[..m]);
        prop_assert_eq!(n.ok(), Some(payload.len()));
        prop_assert_eq!(&enc[..payload.len()], &payload[..]);
    }

    #[test]
    fn arbitrary_bytes_never_panic_the_decoder(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let mut b = bytes.clone();
        let _ = decode::<HostMsg>(&mut b);
        let mut b = bytes.clone();
        let _ = decode::<DeviceMsg>(&mut b);
        let mut r = FrameReader::<{ MAX_FRAME }>::new();
        for x in bytes {
            let _ = r.push::<DeviceMsg>(x);
        }
    }

    #[test]
    fn a_corrupted_frame_is_rejected(m in any_host(), pos in any::<prop::sample::Index>(), flip in 1u8..=255) {
        let mut buf = [0u8; MAX_FRAME + 1];
        let n = encode(&m, &mut buf).unwrap();
        let body = &mut buf[..n - 1];
        let i = pos.index(body.len());
        body[i] ^= flip;
        // Any change of the body is caught: by COBS, the CRC, or a zero that splits it.
        if body.contains(&0) {
            // The stream reader sees two shorter frames: neither can be the message.
            let mut r = FrameReader::<{ MAX_FRAME }>::new();
            for &b in body.iter().chain([&0u8]) {
                if let Some(res) = r.push::<HostMsg>(b) {
                    prop_assert!(res.is_err() || !same(&res.unwrap(), &m));
                }
            }
        } else {
            let r = decode::<HostMsg>(body);
            prop_assert!(r.is_err(), "accepted a corrupted frame: {:?}", r);
        }
    }

    #[test]
    fn a_stream_of_frames_decodes_in_order(ms in prop::collection::vec(any_device(), 1..20), noise in prop::collection::vec(1u8..=255, 0..10)) {
        // Noise before the first delimiter is one bad frame; then every message comes through.
        let mut stream = noise.clone();
        stream.push(0);
        for m in &ms {
            let mut buf = [0u8; MAX_FRAME + 1];
            let n = encode(m, &mut buf).unwrap();
            stream.extend_from_slice(&buf[..n]);
        }
        let mut r = FrameReader::<{ MAX_FRAME }>::new();
        let mut got = Vec::new();
        let mut errors = 0;
        for b in stream {
            match r.push::<DeviceMsg>(b) {
                Some(Ok(m)) => got.push(m),
                Some(Err(_)) => errors += 1,
                None => {}
            }
        }
        prop_assert_eq!(got.len(), ms.len());
        for (a, b) in got.iter().zip(&ms) {
            prop_assert!(same(a, b));
        }
        prop_assert!(errors <= 1);
    }
}

#[test]
fn the_largest_messages_fit_a_frame() {
    let t = DeviceMsg::Telemetry(Telemetry {
        seq: u32::MAX,
        tick: u32::MAX,
        state: RunState::Fault(255),
        command_mm: f64::MAX,
        target_mm: f64::MAX,
        measured_mm: f64::MAX,
        force_kn: f64::MAX,
    });
    let mut buf = [0u8; MAX_FRAME + 1];
    let n = encode(&t, &mut buf).unwrap();
    println!("largest telemetry frame: {n} bytes");
    assert!(n <= 50, "{n}");
    let u = HostMsg::UploadLr {
        features: 6,
        theta: [f64::MAX; 6],
        delay_steps: u16::MAX,
        checksum: u32::MAX,
    };
    assert!(encode(&u, &mut buf).unwrap() <= MAX_FRAME);
    let c = HostMsg::RecordChunk {
        seq: u32::MAX,
        count: u8::MAX,
        values: [f64::MAX; RECORD_CHUNK],
    };
    let n = encode(&c, &mut buf).unwrap();
    println!("largest record chunk frame: {n} bytes");
    assert!(n <= MAX_FRAME + 1, "{n}");
    let info = RecordInfo {
        source: RecordSource::Uploaded,
        samples: u32::MAX,
        dt_s: f64::MAX,
        scale: f64::MAX,
        ticks: u32::MAX,
        checksum: u32::MAX,
    };
    let st = DeviceMsg::Status(Status {
        state: RunState::Fault(255),
        model_checksum: u32::MAX,
        tick: u32::MAX,
        records_sent: u32::MAX,
        records_dropped: u32::MAX,
        stroke_mm: f64::MAX,
        velocity_mm_s: f64::MAX,
        force_kn: f64::MAX,
        bad_frames: u32::MAX,
        model_kind: ModelKind::FeAts,
        record: info,
        record_capacity: u32::MAX,
    });
    let n = encode(&st, &mut buf).unwrap();
    println!("largest status frame: {n} bytes");
    assert!(n <= MAX_FRAME + 1, "{n}");
}

#[test]
fn record_checksum_covers_every_sample_its_order_and_the_step() {
    let a = [0.01, -0.02, 0.5, 1e-9, -0.0];
    let c = record_checksum(&a, 0.01);
    // Fed in chunks of any size, the running digest gives the same checksum.
    let mut d = RecordDigest::new();
    d.update(&a[..2]);
    d.update(&a[2..]);
    assert_eq!(d.finalize(0.01), c);
    assert_ne!(record_checksum(&a, 0.02), c, "the step counts");
    for i in 0..a.len() {
        let mut b = a;
        b[i] = f64::from_bits(b[i].to_bits() ^ 1);
        assert_ne!(record_checksum(&b, 0.01), c, "sample {i}");
    }
    let mut swapped = a;
    swapped.swap(0, 1);
    assert_ne!(record_checksum(&swapped, 0.01), c, "the order counts");
    assert_ne!(record_checksum(&a[..4], 0.01), c, "the length counts");
}

#[test]
fn a_too_small_buffer_and_an_overlong_frame_are_errors() {
    let mut small = [0u8; 8];
    assert_eq!(
        encode(
            &HostMsg::SetLimits {
                stroke_mm: 1.0,
                velocity_mm_s: 2.0,
                force_kn: 3.0
            },
            &mut small
        ),
        Err(LinkError::TooLong)
    );
    let mut r = FrameReader::<4>::new();
    for b in [1, 2, 3, 4, 5, 6] {
        assert!(r.push::<HostMsg>(b).is_none());
    }
    assert_eq!(r.push::<HostMsg>(0), Some(Err(LinkError::TooLong)));
    // The reader is usable again after the overlong frame.
    let mut buf = [0u8; MAX_FRAME + 1];
    let n = encode(&HostMsg::Start, &mut buf).unwrap();
    let mut r2 = FrameReader::<{ MAX_FRAME }>::new();
    let got: Vec<_> = buf[..n]
        .iter()
        .filter_map(|b| r2.push::<HostMsg>(*b))
        .collect();
    assert_eq!(got, vec![Ok(HostMsg::Start)]);
}

#[test]
fn crc_and_message_errors_are_told_apart() {
    // A valid CRC over bytes that are no message.
    let payload = [0xFFu8, 0xFF, 0xFF];
    let crc = FRAME_CRC.checksum(&payload).to_le_bytes();
    let raw = [payload[0], payload[1], payload[2], crc[0], crc[1]];
    let mut body = [0u8; 16];
    let n = cobs::encode(&raw, &mut body);
    assert_eq!(decode::<HostMsg>(&mut body[..n]), Err(LinkError::Message));
    let mut short = [0x02u8, 0x01];
    assert_eq!(decode::<HostMsg>(&mut short), Err(LinkError::Crc));
    assert_eq!(LinkError::Crc.to_string(), "CRC mismatch");
}

#[test]
fn model_checksum_covers_every_coefficient_and_the_delay() {
    let theta = [
        0.0,
        1e-7,
        2e-8,
        1e-11,
        1.9994749475973028,
        -0.9995838569968694,
    ];
    let c = model_checksum(&theta, 28);
    assert_ne!(c, model_checksum(&theta, 27));
    for i in 0..6 {
        let mut t = theta;
        t[i] = f64::from_bits(t[i].to_bits() ^ 1);
        assert_ne!(c, model_checksum(&t, 28), "coefficient {i}");
    }
    // CRC-32/ISO-HDLC check value.
    assert_eq!(MODEL_CRC.checksum(b"123456789"), 0xCBF4_3926);
}

#[test]
fn seq_check_reports_gaps_and_counts_the_missing() {
    let mut s = SeqCheck::new();
    assert_eq!(s.observe(0), Ok(()));
    assert_eq!(s.observe(1), Ok(()));
    assert_eq!(
        s.observe(5),
        Err(Gap {
            expected: 2,
            got: 5
        })
    );
    assert_eq!(s.observe(6), Ok(()));
    assert_eq!(s.missing(), 3);
    assert!(s.observe(6).is_err(), "a repeat is not silent either");
    let mut mid = SeqCheck::starting_at(512);
    assert_eq!(mid.observe(512), Ok(()));
    let mut late = SeqCheck::new();
    assert_eq!(
        late.observe(3),
        Err(Gap {
            expected: 0,
            got: 3
        })
    );
}

#[test]
fn lrx_values_order_and_their_checksum() {
    let coeffs: [f64; 9] = core::array::from_fn(|i| i as f64);
    let lead: [f64; 8] = core::array::from_fn(|i| 10.0 + i as f64);
    let v = lrx_values(&coeffs, 100.0, 200.0, &lead, 3).unwrap();
    assert_eq!(&v[..9], &coeffs);
    assert_eq!((v[9], v[10]), (100.0, 200.0));
    assert_eq!(&v[11..19], &lead);
    assert_eq!(v[19], 3.0);
    assert!(lrx_values(&coeffs[..8], 1.0, 0.0, &lead, 3).is_none());
    assert!(lrx_values(&coeffs, 1.0, 0.0, &lead[..7], 3).is_none());
    let c = model_values_checksum(ModelKind::Lrx, &v, 28);
    assert_ne!(
        model_values_checksum(ModelKind::Rnn, &v, 28),
        c,
        "the kind counts"
    );
    assert_ne!(
        model_values_checksum(ModelKind::Lrx, &v, 29),
        c,
        "the delay counts"
    );
    let mut w = v;
    w[19] = 4.0;
    assert_ne!(model_values_checksum(ModelKind::Lrx, &w, 28), c);
}

#[test]
fn an_identification_sample_is_32_bytes_on_the_wire() {
    // 56 s at 2048 Hz (or 4096 Hz): seq < 2^21, a 3-byte varint; the stream rate in `IdentifySample`'s
    // docs follows from this size.
    let mut buf = [0u8; MAX_FRAME + 1];
    let worst = DeviceMsg::IdentifySample(IdentifySample {
        seq: (1 << 21) - 1,
        command_mm: -2.5,
        measured_mm: f64::MAX,
        force_kn: -f64::MAX,
    });
    let n = encode(&worst, &mut buf).unwrap();
    assert_eq!(n, 32, "{n}");
    assert!(same(&round_trip(&worst), &worst));
}

#[test]
fn rig_values_layout_checksum_and_frame() {
    let lead: [f64; 8] = core::array::from_fn(|i| 1.0 + i as f64);
    let v = rig_values(&lead, 3, 4096.0, [0.5, 0.25]).unwrap();
    assert_eq!(&v[..8], &lead);
    assert_eq!(&v[8..12], &[3.0, 4096.0, 0.5, 0.25]);
    assert!(rig_values(&lead[..7], 3, 0.0, [0.0; 2]).is_none());
    assert_eq!(rig_value_count(ModelKind::Lrx), Some(12));
    assert_eq!(rig_value_count(ModelKind::FeAts), Some(3));
    assert_eq!(rig_value_count(ModelKind::Rnn), None);
    let c = rig_checksum(ModelKind::Lrx, &v);
    assert_ne!(rig_checksum(ModelKind::FeAts, &v), c, "the kind counts");
    let mut w = v;
    w[11] = 0.5;
    assert_ne!(rig_checksum(ModelKind::Lrx, &w), c);
    let mut buf = [0u8; MAX_FRAME + 1];
    let m = HostMsg::UploadRig {
        kind: ModelKind::FeAts,
        count: u8::MAX,
        values: [f64::MAX; RECORD_CHUNK],
        checksum: u32::MAX,
    };
    let n = encode(&m, &mut buf).unwrap();
    assert!(n <= MAX_FRAME + 1, "{n}");
    let h = DeviceMsg::Holdings(Holdings {
        model_kind: ModelKind::FeAts,
        model_source: RecordSource::Uploaded,
        model_checksum: u32::MAX,
        rig_source: RecordSource::Uploaded,
        rig_checksum: u32::MAX,
        rate_hz: u32::MAX,
        build_id: u32::MAX,
    });
    assert!(encode(&h, &mut buf).unwrap() <= MAX_FRAME + 1);
    let b = HostMsg::SiteBegin {
        ticks_per_step: u32::MAX,
        lead_weights: [f64::MAX; 8],
        lead_stride: u16::MAX,
    };
    assert!(encode(&b, &mut buf).unwrap() <= MAX_FRAME + 1);
}

#[test]
fn rnn_value_count_and_its_inverse() {
    assert_eq!(rnn_value_count(10), 20 + 100 + 10 + 10 + 1 + 6);
    for h in [1, 5, 10, 20, 32] {
        assert_eq!(rnn_hidden_of(rnn_value_count(h)), Some(h));
    }
    assert_eq!(rnn_hidden_of(rnn_value_count(10) + 1), None);
    assert!(rnn_value_count(32) <= usize::from(u16::MAX));
}

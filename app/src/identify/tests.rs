//! Tests of [`crate::identify`]: refusals, and a whole identification on an ideal rig.

extern crate std;
use std::boxed::Box;
use std::vec::Vec;

use super::*;
use crate::tick_cost::TickBudget;
use heapless::spsc::Queue;
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, FeedbackSource};
use rths_core::hal::{ErrorKind, Sample};
use rths_core::identify_excitation::{ramp_cos, unit_cos, Libm, Multisine};
use rths_core::metamodel::{Lr, LrParams};
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::{FaultReason, Limits};

fn controller() -> Controller {
    let cfg = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let lr = LrParams::new([0.0, 0.5, 0.1, 0.0, 0.0, 0.0]).unwrap();
    Controller::new(cfg, Analytical::Lr(Lr::new(lr)), Compensator::None)
}

/// The default excitation's tables (the `libm` crate's cosines: the firmware's come from std's, as
/// the host's; the logic under test is the same).
fn tables() -> FlashTables {
    let cfg = ExcitationConfig::new(DT_S);
    let ms = Multisine::new::<Libm>(&cfg).unwrap();
    let n = ms.period_ticks();
    let cos: Vec<f64> = (0..n).map(|i| unit_cos::<Libm>(i, n)).collect();
    let unit: Vec<f64> = (0..n).map(|t| ms.unit_at(t, |i| cos[i])).collect();
    let stats = UnitStats::of(n, DT_S, |i| unit[i]);
    let ramp = cfg.ramp_settle_ticks().0;
    let rc: Vec<f64> = (0..ramp).map(|j| ramp_cos::<Libm>(j, ramp)).collect();
    let bytes = |v: &[f64]| -> &'static [u8] {
        Box::leak(
            v.iter()
                .flat_map(|x| x.to_le_bytes())
                .collect::<Vec<u8>>()
                .into_boxed_slice(),
        )
    };
    FlashTables::new(bytes(&unit), bytes(&rc), stats.peak, stats.peak_rate_per_s)
}

/// A rig that follows its command exactly, one tick late; `nan_at`: the displacement reads NaN
/// from that tick on.
struct Ideal {
    pos_mm: f64,
    cmd_mm: f64,
    tick: u32,
    nan_at: u32,
}

impl Daq for Ideal {
    type Error = ErrorKind;
    fn read(&mut self) -> Result<Sample, ErrorKind> {
        let disp_mm = if self.tick >= self.nan_at {
            f64::NAN
        } else {
            self.pos_mm
        };
        Ok(Sample {
            disp_mm,
            force_kn: 1.2 * self.pos_mm,
        })
    }
}

impl Actuator for Ideal {
    type Error = ErrorKind;
    fn command(&mut self, disp_mm: f64) -> Result<(), ErrorKind> {
        self.cmd_mm = disp_mm;
        Ok(())
    }
}

impl Ideal {
    fn advance(&mut self) {
        self.pos_mm = self.cmd_mm;
        self.tick += 1;
    }
}

/// Run an identification to its end; the records and the final state.
fn run(nan_at: u32) -> (Vec<TelemetryRecord>, Identification, Controller) {
    let t = tables();
    let mut ctl = controller();
    let player = begin(&mut ctl, &t, 2.0, true, None).unwrap();
    let mut id = Identification::new();
    id.start(player);
    let mut q: Queue<TelemetryRecord, 8> = Queue::new();
    let (mut p, mut c) = q.split();
    let mut rig = Ideal {
        pos_mm: 0.0,
        cmd_mm: 0.0,
        tick: 0,
        nan_at,
    };
    let mut recs = Vec::new();
    for _ in 0..200_000 {
        let s = identify_step(&mut id, &mut ctl, &mut rig, &mut p, &t, false);
        if s.ticked {
            rig.advance();
        }
        while let Some(r) = c.dequeue() {
            recs.push(r);
        }
        if s.ended {
            break;
        }
    }
    (recs, id, ctl)
}

#[test]
fn an_identification_plays_the_whole_excitation_and_ends_done() {
    let (recs, id, ctl) = run(u32::MAX);
    let t = tables();
    let s = t.schedule(2.0).unwrap();
    assert_eq!(id.phase(), Some(IdentifyPhase::Ended));
    assert_eq!(id.state, State::Done);
    assert_eq!(ctl.supervisor().state(), State::Done);
    assert_eq!(id.dropped, 0);
    assert_eq!(recs.len() as u32, id.ticks);
    assert!(recs.len() > s.ticks(), "{} ticks", recs.len());
    // The supervisor passes the excitation through unchanged (it is far inside the limits), and
    // the record's request is the player's, tick by tick.
    let mut p = Player::new(s);
    for (k, r) in recs.iter().enumerate() {
        assert_eq!(r.tick as usize, k);
        let want = p.next(&t).unwrap_or(0.0);
        assert_eq!(r.target_mm.to_bits(), want.to_bits(), "tick {k}");
        assert_eq!(r.command_mm.to_bits(), want.to_bits(), "tick {k}");
    }
    let peak = recs.iter().fold(0.0f64, |m, r| m.max(r.command_mm.abs()));
    assert!(peak > 0.5 && peak <= 2.0, "{peak}");
}

#[test]
fn a_nan_trips_the_supervisor_and_the_identification_ends_at_rest() {
    let (recs, id, ctl) = run(30_000);
    assert_eq!(id.phase(), Some(IdentifyPhase::Ended));
    assert!(
        matches!(id.state, State::Fault(FaultReason::NonFiniteSample)),
        "{:?}",
        id.state
    );
    assert!(ctl.supervisor().at_rest());
    assert!(recs.len() < 40_000 + 60 * 2048, "{}", recs.len());
}

#[test]
fn refusals() {
    let t = tables();
    let mut ctl = controller();
    assert_eq!(
        begin(&mut ctl, &t, f64::NAN, true, None).err(),
        Some(NackReason::NotFinite)
    );
    assert_eq!(
        begin(&mut ctl, &t, 3.0, true, None).err(),
        Some(NackReason::OutOfRange),
        "more than 10% of the stroke"
    );
    assert_eq!(
        begin(&mut ctl, &t, 2.0, false, None).err(),
        Some(NackReason::Unsupported),
        "the emulated plant has run"
    );
    let empty = FlashTables::new(&[], &[], 0.0, 0.0);
    assert_eq!(
        begin(&mut ctl, &empty, 2.0, true, None).err(),
        Some(NackReason::Unsupported)
    );
    ctl.supervisor_mut().arm().unwrap();
    assert_eq!(
        begin(&mut ctl, &t, 2.0, true, None).err(),
        Some(NackReason::Busy),
        "armed"
    );
    ctl.supervisor_mut().start().unwrap();
    assert_eq!(
        begin(&mut ctl, &t, 2.0, true, None).err(),
        Some(NackReason::Busy),
        "running"
    );
}

#[test]
fn the_link_request_starts_an_identification_and_numbers_its_samples() {
    use crate::link::{handle, Effect, Rearm, Session};
    use crate::record::RecordStore;
    use crate::Run;
    use rths_link::{DeviceMsg, HostMsg, ModelKind, Request};
    let mut ctl = controller();
    let mut run = Run::new();
    let mut store = RecordStore::new(&[0.0, 0.1, 0.0], 0.01, 41, &mut []);
    let msg = HostMsg::Identify { amplitude_mm: 2.0 };
    // A build without the tables refuses.
    let mut s = Session::new(
        0,
        TickBudget::cortex_m4_168mhz(2048.0),
        Rearm::OncePerPowerUp,
        ModelKind::Lr,
        &mut [],
    );
    let (a, e) = handle(msg, &mut ctl, &mut run, &mut store, &mut s, false);
    assert_eq!(
        a,
        DeviceMsg::Nack(Request::Identify, NackReason::Unsupported)
    );
    assert_eq!(e, Effect::None);
    // The emulated plant after its run refuses.
    let mut s = s.with_excitation(tables());
    let (a, _) = handle(msg, &mut ctl, &mut run, &mut store, &mut s, true);
    assert_eq!(
        a,
        DeviceMsg::Nack(Request::Identify, NackReason::Unsupported)
    );
    // Accepted: the supervisor runs, the stream is the identification's, from seq 0.
    let (a, e) = handle(msg, &mut ctl, &mut run, &mut store, &mut s, false);
    assert_eq!(a, DeviceMsg::Ack(Request::Identify));
    assert!(matches!(e, Effect::Identify(_)));
    assert!(s.identifying);
    assert_eq!(ctl.supervisor().state(), State::Running);
    let r = TelemetryRecord {
        tick: 0,
        command_mm: 0.25,
        target_mm: 0.25,
        measured_mm: 0.125,
        force_kn: 0.5,
        state: State::Running,
    };
    for seq in 0..3 {
        match s.telemetry(&r) {
            Some(DeviceMsg::IdentifySample(t)) => {
                assert_eq!(t.seq, seq);
                assert_eq!(
                    (t.command_mm, t.measured_mm, t.force_kn),
                    (0.25, 0.125, 0.5)
                );
            }
            m => panic!("{m:?}"),
        }
    }
    // A second one, and an arm, while it runs: refused.
    let (a, _) = handle(msg, &mut ctl, &mut run, &mut store, &mut s, false);
    assert_eq!(a, DeviceMsg::Nack(Request::Identify, NackReason::Busy));
    let (a, _) = handle(
        HostMsg::Arm { telemetry_every: 1 },
        &mut ctl,
        &mut run,
        &mut store,
        &mut s,
        false,
    );
    assert!(matches!(a, DeviceMsg::Nack(Request::Arm, _)), "{a:?}");
    let id = Identification {
        ticks: 3,
        ..Identification::new()
    };
    assert_eq!(
        s.identify_ended(&id),
        DeviceMsg::IdentifyEnded {
            state: rths_link::RunState::Idle,
            ticks: 3,
            samples_sent: 3,
            samples_dropped: 0
        }
    );
}

//! Tests of [`crate::identify_session`]: a whole run on an ideal rig, a trip, the ramp bound.

extern crate std;
use std::vec::Vec;

use super::*;
use crate::identify_excitation::{ExcitationConfig, StdTables};
use crate::params::DT_S;
use crate::supervisor::Limits;

/// A rig that follows its command one tick late; its displacement reads NaN from `nan_at` on.
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

/// Run to the end with the ramp bound of `bound_dt_s`: the records, the session, the tables.
fn run(nan_at: u32, bound_dt_s: f64) -> (Vec<IdentifyTickRecord>, IdentifySession, StdTables) {
    let tables = StdTables::new(&ExcitationConfig::new(DT_S)).unwrap();
    let mut sup = Supervisor::new(Limits::paper_actuator());
    sup.arm().unwrap();
    sup.start().unwrap();
    let mut s = IdentifySession::new(Player::new(tables.schedule), bound_dt_s);
    let mut rig = Ideal {
        pos_mm: 0.0,
        cmd_mm: 0.0,
        tick: 0,
        nan_at,
    };
    let mut recs = Vec::new();
    while let Some(r) = s.step(&mut sup, &mut rig, &tables, false) {
        rig.pos_mm = rig.cmd_mm;
        rig.tick += 1;
        recs.push(r);
        assert!(recs.len() < 1_000_000, "the run must end");
    }
    // Over means over: nothing more is read or written.
    assert!(s.step(&mut sup, &mut rig, &tables, false).is_none());
    (recs, s, tables)
}

#[test]
fn a_run_plays_the_whole_excitation_and_ends_done() {
    let (recs, s, tables) = run(u32::MAX, DT_S);
    assert_eq!(s.outcome(), Some(IdentifyOutcome::Done));
    assert_eq!(s.phase(), IdentifyPhase::Ended);
    assert_eq!(recs.len() as u32, s.ticks());
    assert!(recs.len() > tables.schedule.ticks());
    // Far inside the limits, the supervisor passes the player's requests through bit for bit.
    let mut p = Player::new(tables.schedule);
    for (k, r) in recs.iter().enumerate() {
        assert_eq!(r.tick as usize, k);
        let want = p.next(&tables).unwrap_or(0.0);
        assert_eq!(r.requested_mm.to_bits(), want.to_bits(), "tick {k}");
        assert_eq!(r.command_mm.to_bits(), want.to_bits(), "tick {k}");
        assert_eq!(r.daq_error, None);
    }
    assert_eq!(recs.last().map(|r| r.state), Some(State::Done));
}

#[test]
fn a_trip_stops_the_excitation_and_ramps_to_rest() {
    let (recs, s, tables) = run(5_000, DT_S);
    let Some(IdentifyOutcome::Tripped { reason, tick }) = s.outcome() else {
        panic!("{:?}", s.outcome());
    };
    assert_eq!(reason, FaultReason::NonFiniteSample);
    // The trip comes within the sensor timeout of the first NaN, long before the excitation's end.
    assert!((5_000..5_000 + 16).contains(&tick), "tick {tick}");
    assert!(recs.len() < tables.schedule.ticks());
    // After the trip every request is 0 and the run ends at the safe position.
    for r in recs.iter().skip(tick as usize + 1) {
        assert_eq!(r.requested_mm, 0.0);
    }
    assert!(matches!(
        recs.last().map(|r| r.state),
        Some(State::Fault(_))
    ));
}

#[test]
fn a_ramp_that_outlasts_the_bound_ends_unsettled() {
    // A bound of 3 ticks: the trip's ramp from the excitation's amplitude takes far longer.
    let (recs, s, _) = run(40_000, MAX_RAMP_S / 3.0);
    assert!(
        matches!(
            s.outcome(),
            Some(IdentifyOutcome::Unsettled {
                state: State::Fault(_)
            })
        ),
        "{:?}",
        s.outcome()
    );
    let trip = recs
        .iter()
        .position(|r| matches!(r.state, State::Fault(_)))
        .unwrap();
    assert_eq!(recs.len(), trip + 1 + 3);
}

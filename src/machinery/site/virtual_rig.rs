//! The virtual rig as an element's experimental side: core's controller as a site
//! (`Controller::install_site`) ticked through the host's one driver (`crate::machinery::drive::Driver`)
//! against the simulated plant, in simulated time (the rig waits for its client) or paced to the
//! wall clock (`--real-time`: the rig never waits, the predictor runs while the client computes).

use std::time::{Duration, Instant};

use rths_core::compensator::{Compensator, LeadParams};
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use rths_core::metamodel::Lr;
use rths_core::params::{Prototype, SpecimenScale, DT_S};
use rths_core::predictor_corrector::{PcParams, SITE_ORDER};
use rths_core::supervisor::{Limits, State};
use rths_hal_sim::{RigConfig, VirtualRig};
use rths_link::RunState;

use super::experiment::{Experiment, ExperimentError, PacingStats, Reading, SiteRow};
use crate::machinery::drive::Driver;

/// The ticks of a whole stroke ramped at the slowest rate fit well inside (the supervisor's
/// settle bound).
const SETTLE_TICKS: usize = (120.0 / DT_S) as usize;

/// Spin (rather than sleep) for this last part of a wait: a sleep overshoots by tens of µs.
const SPIN: Duration = Duration::from_micros(150);

/// The wall clock of a paced rig.
#[derive(Debug, Clone)]
struct Pacer {
    start: Instant,
    ticks: u64,
    sum_sq_s2: f64,
    late_max_s: f64,
    last: Instant,
}

impl Pacer {
    fn new() -> Self {
        let now = Instant::now();
        Self {
            start: now,
            ticks: 0,
            sum_sq_s2: 0.0,
            late_max_s: 0.0,
            last: now,
        }
    }

    fn deadline(&self) -> Instant {
        self.start + Duration::from_secs_f64(self.ticks as f64 * DT_S)
    }

    /// Wait for the next tick's deadline; note how late it starts.
    fn wait(&mut self) {
        let dl = self.deadline();
        let now = Instant::now();
        if dl > now + SPIN {
            std::thread::sleep(dl - now - SPIN);
        }
        while Instant::now() < dl {
            std::hint::spin_loop();
        }
        let now = Instant::now();
        let late = now.duration_since(dl).as_secs_f64();
        self.sum_sq_s2 += late * late;
        self.late_max_s = self.late_max_s.max(late);
        self.ticks += 1;
        self.last = now;
    }

    fn stats(&self) -> PacingStats {
        let span = self.last.duration_since(self.start).as_secs_f64();
        PacingStats {
            ticks: self.ticks,
            rate_hz: if span > 0.0 {
                (self.ticks.saturating_sub(1)) as f64 / span
            } else {
                0.0
            },
            jitter_rms_s: (self.sum_sq_s2 / self.ticks.max(1) as f64).sqrt(),
            late_max_s: self.late_max_s,
        }
    }
}

/// One element's virtual rig and controller.
pub struct VirtualExperiment {
    rig: VirtualRig,
    ctl: Controller,
    lead: LeadParams,
    driver: Option<Driver>,
    rows: Vec<SiteRow>,
    real_time: bool,
    pacer: Option<Pacer>,
}

impl VirtualExperiment {
    /// The rig of `cfg` with the identified `lead` in front of it; `real_time`: paced to the
    /// wall clock.
    pub fn new(cfg: &RigConfig, lead: LeadParams, real_time: bool) -> anyhow::Result<Self> {
        let config = ControlConfig::new(
            Prototype::paper(),
            SpecimenScale::default(),
            FeedbackSource::Measured,
            Limits::paper_actuator(),
        )
        .map_err(|e| anyhow::anyhow!("the site's controller: {e:?}"))?;
        Ok(Self {
            rig: VirtualRig::new(cfg.build()?),
            ctl: Controller::new(config, Analytical::Lr(Lr::PARKED), Compensator::None),
            lead,
            driver: None,
            rows: Vec::new(),
            real_time,
            pacer: None,
        })
    }

    /// One controller tick (paced if asked), recorded.
    fn tick(&mut self) {
        let Some(d) = self.driver.as_mut() else {
            return;
        };
        if let Some(p) = self.pacer.as_mut() {
            p.wait();
        }
        // A site's targets come from its client: the ground motion is the client's business.
        let s = d.tick(&mut self.ctl, Some(&mut self.rig), 0.0, false);
        self.rows.push(SiteRow {
            tick: u32::try_from(s.k).unwrap_or(u32::MAX),
            state: super::experiment::run_state(s.out.state),
            command_mm: s.out.command_mm,
            target_mm: s.out.target_mm,
            measured_mm: s.measured_mm,
            force_kn: s.measured_force_kn,
        });
        d.actuate(Some(&mut self.rig));
    }

    /// Tick until the supervisor is at rest (bounded).
    fn settle(&mut self) {
        for _ in 0..SETTLE_TICKS {
            if self.ctl.supervisor().at_rest() {
                break;
            }
            self.tick();
        }
    }

    fn tripped(&self) -> Option<ExperimentError> {
        match self.ctl.supervisor().state() {
            State::Fault(r) => Some(ExperimentError::Supervisor(r.name().into())),
            _ => None,
        }
    }
}

impl Experiment for VirtualExperiment {
    fn begin(&mut self, ticks_per_step: u32) -> Result<(), ExperimentError> {
        let pc = PcParams::new(ticks_per_step, SITE_ORDER)
            .map_err(|e| ExperimentError::Controller(format!("predictor-corrector: {e:?}")))?;
        self.ctl
            .install_site(pc, Some(self.lead))
            .map_err(|e| ExperimentError::Controller(format!("{e:?}")))?;
        self.driver = Some(Driver::start(&mut self.ctl, DT_S));
        if self.real_time {
            self.pacer = Some(Pacer::new());
        }
        Ok(())
    }

    fn step(&mut self, target_mm: f64) -> Result<Reading, ExperimentError> {
        // A paced rig may have tripped while it waited for this target.
        if let Some(e) = self.tripped() {
            return Err(e);
        }
        let (_, done0) = self
            .ctl
            .site_progress()
            .ok_or_else(|| ExperimentError::Controller("not a site".into()))?;
        self.ctl
            .site_target(target_mm)
            .map_err(|e| ExperimentError::Controller(format!("the target was refused: {e:?}")))?;
        loop {
            self.tick();
            if let Some(e) = self.tripped() {
                return Err(e);
            }
            if self.ctl.site_progress().map(|(_, n)| n) != Some(done0) {
                let r = self.rows.last().copied();
                return Ok(Reading {
                    measured_mm: r.map_or(f64::NAN, |r| r.measured_mm),
                    force_kn: r.map_or(f64::NAN, |r| r.force_kn),
                });
            }
        }
    }

    fn idle_deadline(&self) -> Option<Instant> {
        self.pacer.as_ref().map(Pacer::deadline)
    }

    fn idle_tick(&mut self) {
        self.tick();
    }

    fn safe_stop(&mut self) {
        self.ctl.supervisor_mut().emergency_stop();
        self.settle();
    }

    fn finish(&mut self) {
        let _ = self.ctl.supervisor_mut().finish();
        self.settle();
    }

    fn state(&self) -> RunState {
        super::experiment::run_state(self.ctl.supervisor().state())
    }

    fn take_rows(&mut self) -> Vec<SiteRow> {
        std::mem::take(&mut self.rows)
    }

    fn pacing(&self) -> Option<PacingStats> {
        self.pacer.as_ref().map(Pacer::stats)
    }
}

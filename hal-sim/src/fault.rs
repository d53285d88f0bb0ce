//! Fault injection: what can go wrong on a rig, when, for how long.

use crate::params::ConfigError;

/// Which sensor a sensor fault affects.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Channel {
    /// The LVDT (displacement).
    Disp,
    /// The load cell (force).
    Force,
    /// Both.
    Both,
}

impl Channel {
    pub(crate) fn disp(self) -> bool {
        matches!(self, Channel::Disp | Channel::Both)
    }
    pub(crate) fn force(self) -> bool {
        matches!(self, Channel::Force | Channel::Both)
    }
}

/// What a fault does while it is active.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FaultKind {
    /// No sample arrives: `read()` returns an error of kind `Timeout`.
    Dropout,
    /// The channel repeats the last value it read before the fault.
    Stuck(Channel),
    /// The channel reads NaN (the controller must catch it).
    NaN(Channel),
    /// The reading is offset by `magnitude` (mm on `Disp`, kN on `Force`, both on `Both`).
    Spike(Channel, f64),
    /// The valve delivers only this fraction (0..=1) of its rated flow.
    ValveSaturation(f64),
    /// The specimen stiffness is multiplied by this factor (> 0), e.g. a cracked brace.
    StiffnessChange(f64),
    /// The link between controller and rig loses ticks: the command sent in these ticks never
    /// reaches the servo-controller (it holds the previous one) and `read()` returns the stale
    /// sample of the last good tick.
    LostTicks,
}

/// One fault: kind, first tick (counted by `advance_tick`), duration in ticks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fault {
    /// What happens.
    pub kind: FaultKind,
    /// First tick at which it is active.
    pub start_tick: u64,
    /// Number of ticks it stays active (`u64::MAX`: for ever).
    pub duration_ticks: u64,
}

impl Fault {
    /// A validated fault.
    pub fn new(kind: FaultKind, start_tick: u64, duration_ticks: u64) -> Result<Self, ConfigError> {
        match kind {
            FaultKind::Spike(_, m) if !m.is_finite() => {
                return Err(ConfigError::NotFinite("spike magnitude"))
            }
            FaultKind::ValveSaturation(f) if !(0.0..=1.0).contains(&f) => {
                return Err(ConfigError::OutOfRange("valve flow fraction (0..=1)"))
            }
            FaultKind::StiffnessChange(f) if !(f.is_finite() && f > 0.0) => {
                return Err(ConfigError::NotPositive("stiffness factor"))
            }
            _ => {}
        }
        Ok(Self {
            kind,
            start_tick,
            duration_ticks,
        })
    }

    /// Whether the fault is active at `tick`.
    pub fn active(&self, tick: u64) -> bool {
        tick >= self.start_tick && tick - self.start_tick < self.duration_ticks
    }
}

/// Most faults a plan holds.
pub const MAX_FAULTS: usize = 8;

/// A fixed-capacity set of faults (allocation-free).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FaultPlan {
    faults: [Option<Fault>; MAX_FAULTS],
}

impl FaultPlan {
    /// No faults.
    pub fn none() -> Self {
        Self::default()
    }

    /// This plan with one more fault.
    pub fn with(mut self, fault: Fault) -> Result<Self, ConfigError> {
        let slot = self
            .faults
            .iter_mut()
            .find(|f| f.is_none())
            .ok_or(ConfigError::TooManyFaults)?;
        *slot = Some(fault);
        Ok(self)
    }

    /// The faults active at `tick`.
    pub fn active(&self, tick: u64) -> impl Iterator<Item = &Fault> {
        self.faults.iter().flatten().filter(move |f| f.active(tick))
    }

    /// All faults in the plan.
    pub fn iter(&self) -> impl Iterator<Item = &Fault> {
        self.faults.iter().flatten()
    }
}

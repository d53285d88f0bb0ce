//! Can the board's tick run an uploaded model? An estimate of the model's instructions per tick
//! against what the core does in one tick, from the firmware budget's measured rows
//! (`firmware/budget.sh`, docs/firmware.md "the budget"): a model that cannot meet the tick is
//! refused at upload ([`rths_link::NackReason::TickBudget`]) instead of overrunning every tick of a
//! test.

use rths_link::ModelKind;

/// Cycles per instruction the budget assumes (QEMU counts instructions, not cycles; the same
/// figure as the budget report's `cycles_per_instr`).
pub const CYCLES_PER_INSTR: f64 = 1.5;

/// The measured cost of one controller tick of each path on one core, instructions per tick (the
/// budget report's `instr/tick max`, 2048 Hz; the 4096 Hz rows differ by < 0.2 %).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathCost {
    /// The LR path: the controller with the cheapest analytical part (the base of the RNN's cost).
    pub lr: f64,
    /// The LRX path.
    pub lrx: f64,
    /// The FE + ATS path.
    pub fe_ats: f64,
    /// An RNN's cost per unit of h² + 4h (h hidden units: 2h input and h² recurrent
    /// multiply-adds, h output weights and h `tanh` calls, each about the same cost on a core):
    /// (RNN-10's max − LR's max) / 140, rounded up.
    pub rnn_per_term: f64,
}

impl PathCost {
    /// The Cortex-M4 (software f64): LR 1,875, LRX 3,333, FE + ATS 31,196, RNN-10 56,768
    /// instructions per tick max, so (56,768 − 1,875) / 140 = 392.1 → 393 per term.
    pub const CORTEX_M4: Self = Self {
        lr: 1_875.0,
        lrx: 3_333.0,
        fe_ats: 31_196.0,
        rnn_per_term: 393.0,
    };
    /// The Cortex-M7 (hardware f64): LR 375, LRX 535, FE + ATS 3,165, RNN-10 2,445, so
    /// (2,445 − 375) / 140 = 14.8 → 15 per term.
    pub const CORTEX_M7: Self = Self {
        lr: 375.0,
        lrx: 535.0,
        fe_ats: 3_165.0,
        rnn_per_term: 15.0,
    };
}

/// A board's tick: its core's measured costs, its clock and the controller's rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickBudget {
    /// The core's measured path costs.
    pub cost: PathCost,
    /// The core clock, Hz.
    pub clock_hz: f64,
    /// The controller's rate, Hz.
    pub rate_hz: f64,
}

impl TickBudget {
    /// A Cortex-M4 at 168 MHz (the STM32F407, the emulated STM32F405) at `rate_hz`.
    pub const fn cortex_m4_168mhz(rate_hz: f64) -> Self {
        Self {
            cost: PathCost::CORTEX_M4,
            clock_hz: 168e6,
            rate_hz,
        }
    }

    /// A Cortex-M7 at 480 MHz (the STM32H743, the emulated mps2-an500) at `rate_hz`.
    pub const fn cortex_m7_480mhz(rate_hz: f64) -> Self {
        Self {
            cost: PathCost::CORTEX_M7,
            clock_hz: 480e6,
            rate_hz,
        }
    }

    /// Instructions the core runs in one tick at [`CYCLES_PER_INSTR`].
    pub fn instr_per_tick(&self) -> f64 {
        self.clock_hz / self.rate_hz / CYCLES_PER_INSTR
    }

    /// The estimated instructions per tick of an RNN of `hidden` units: the LR path's plus
    /// `rnn_per_term` × (h² + 4h).
    pub fn rnn_instr(&self, hidden: usize) -> f64 {
        let h = hidden as f64;
        self.cost.lr + self.cost.rnn_per_term * (h * h + 4.0 * h)
    }

    /// The estimated instructions per tick of a `kind` model (`rnn_hidden`: an RNN's hidden size).
    pub fn instr(&self, kind: ModelKind, rnn_hidden: usize) -> f64 {
        match kind {
            ModelKind::Lr => self.cost.lr,
            ModelKind::Lrx => self.cost.lrx,
            ModelKind::FeAts => self.cost.fe_ats,
            ModelKind::Rnn => self.rnn_instr(rnn_hidden),
        }
    }

    /// The estimate as a share of the tick, % (over 100: the model cannot meet the tick).
    pub fn pct_of_tick(&self, kind: ModelKind, rnn_hidden: usize) -> f64 {
        100.0 * self.instr(kind, rnn_hidden) / self.instr_per_tick()
    }

    /// The tick can run a `kind` model.
    pub fn fits(&self, kind: ModelKind, rnn_hidden: usize) -> bool {
        self.instr(kind, rnn_hidden) <= self.instr_per_tick()
    }
}

#[cfg(test)]
mod tests;

//! Can the board's tick run an uploaded model? An estimate of the model's instructions per tick
//! against what the core does in one tick, from the firmware budget's measured rows
//! (`firmware/budget.sh`, docs/firmware.md "the budget"): a model that cannot meet the tick is
//! refused at upload ([`rths_link::NackReason::TickBudget`]) instead of overrunning every tick of a
//! test. The structure parts' costs are the structure budget's rows (`budget.sh`, the ideal rig):
//! their sizes (DOFs, yielding stories, modes, springs) come from the values
//! ([`rths_link::layout::Dims`]).

use rths_link::layout::Dims;
use rths_link::ModelKind;

/// Cycles per instruction the budget assumes (QEMU counts instructions, not cycles; the same
/// figure as the budget report's `cycles_per_instr`).
pub const CYCLES_PER_INSTR: f64 = 1.5;

/// The share of a tick a learned structure model may take with its rig compensation on the
/// fastest board at the highest rate (the Cortex-M7 at 4096 Hz): the learned nonlinear model's
/// goal, "within 10 % of the tick". The training keeps its models within it
/// ([`TickBudget::max_hysterons`]).
pub const LEARNED_TICK_SHARE: f64 = 0.10;

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
    /// The structure parts (`None`: not measured on this core, and refused).
    pub structure: Option<StructureCost>,
}

/// The measured cost of the structure parts on one core, instructions per tick (the structure
/// budget's `instr max`, `budget.sh`: the Cortex-M7 at 4096 Hz, the Cortex-M4 at 2048 Hz; the
/// count per tick does not depend on the rate). The estimate equals a measured row at its sizes
/// and laws (rounded up) and is interpolated between them; a Bouc–Wen law costs more than a
/// bilinear one, so the laws count apart.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StructureCost {
    /// The linear finite elements at N = 1, 3, 8 DOFs: a dense Chang step is O(N²), the estimate
    /// the quadratic through them.
    pub fe: [f64; 3],
    /// What a yielding story adds to the linear FE of its N: bilinear (the N = 1 and 8 rows),
    /// Bouc–Wen (the N = 3 row), the largest (FE yielding − FE linear) / N measured.
    pub per_story: [f64; 2],
    /// The structure metamodel (its cost does not grow with N: the largest measured).
    pub meta: f64,
    /// The modal-hysteretic model at 1 mode and 1 bilinear spring, each further mode or bilinear
    /// spring (the 8-mode, 8-spring row), and what a Bouc–Wen spring adds to a bilinear one (the
    /// 3-mode, 3-spring Bouc–Wen row).
    pub modal: [f64; 3],
    /// The reduced model at `reduced_modes` modes, and the largest measured cost of each further
    /// mode (its cost grows with the modes, not the DOFs).
    pub reduced: [f64; 2],
    /// The modes of the reduced model's base row.
    pub reduced_modes: f64,
    /// The floor-hysteron model's cost beyond the linear FE of its floors, its plays and
    /// directions costed as bilinear stories and its Menegotto–Pinto plays at `hysteron_mp`: the
    /// M7's from its measured play row (3 floors, 6 directions, 6 plays, `nl-online`: 2,810
    /// max); infinite where not measured (refused).
    pub hysteron_base: f64,
    /// A Menegotto–Pinto hysteron (two `pow` a step): the M7's from its measured row (the
    /// trained fiber-frame model: 3 floors, 6 directions, 6 of them, `nl-online`: 6,105 max)
    /// less the play row, per hysteron, plus a play's share; infinite where not measured.
    pub hysteron_mp: f64,
    /// What the rig compensation of a structure part adds (the lead with its adaptation and the
    /// force correction): the largest measured (compensated − uncompensated) row.
    pub rig: f64,
}

impl StructureCost {
    /// The linear FE of N DOFs: the quadratic through the N = 1, 3, 8 rows.
    fn fe_instr(&self, n: f64) -> f64 {
        let [a, b, c] = self.fe;
        a * (n - 3.0) * (n - 8.0) / 14.0 - b * (n - 1.0) * (n - 8.0) / 10.0
            + c * (n - 1.0) * (n - 3.0) / 35.0
    }

    /// A structure part of `kind` and sizes `dims`, without its rig compensation.
    pub fn instr(&self, kind: ModelKind, dims: &Dims) -> f64 {
        let n = dims.dofs as f64;
        let bw = dims.bouc_wen.min(dims.springs) as f64;
        let bilinear = dims.springs as f64 - bw;
        match kind {
            ModelKind::StructureFe => self.fe_instr(n),
            ModelKind::StructureNl => {
                self.fe_instr(n) + self.per_story[0] * bilinear + self.per_story[1] * bw
            }
            ModelKind::StructureMeta => self.meta,
            ModelKind::StructureModal => {
                let units = (dims.modes + dims.springs).saturating_sub(2) as f64;
                self.modal[0] + self.modal[1] * units + self.modal[2] * bw
            }
            ModelKind::StructureReduced => {
                let more = (dims.modes as f64 - self.reduced_modes).max(0.0);
                self.reduced[0] + self.reduced[1] * more
            }
            // Two measured rows (the M7): the floors are the linear FE's Chang step; each play and
            // each direction is costed as a bilinear story (a play is one compare and a clamp, a
            // direction n multiply-adds each way, both cheaper than a story's law), each
            // Menegotto–Pinto play at its own measured cost, plus the measured rest.
            ModelKind::StructureHysteron => {
                let mp = dims.bouc_wen.min(dims.hysterons) as f64;
                let plays = dims.hysterons as f64 - mp;
                self.fe_instr(n)
                    + self.per_story[0] * (plays + dims.directions as f64)
                    + self.hysteron_mp * mp
                    + self.hysteron_base
            }
            ModelKind::Lr | ModelKind::Lrx | ModelKind::Rnn | ModelKind::FeAts => 0.0,
        }
    }
}

impl PathCost {
    /// The Cortex-M4 (software f64): LR 1,875, LRX 3,333, FE + ATS 31,196, RNN-10 56,768
    /// instructions per tick max, so (56,768 − 1,875) / 140 = 392.1 → 393 per term.
    pub const CORTEX_M4: Self = Self {
        lr: 1_875.0,
        lrx: 3_333.0,
        fe_ats: 31_196.0,
        rnn_per_term: 393.0,
        // The structure budget on the emulated M4 at 2048 Hz: FE 3,226 / 13,000 / 65,726 (N = 1,
        // 3, 8); FE yielding 4,458 / 24,393 (Bouc–Wen) / 75,220; metamodel 10,583 at most; modal
        // 4,982 (1, 1), 22,869 (3, 3, Bouc–Wen), 52,565 (8, 8); reduced 6,845 / 19,982 /
        // 63,060 (2, 9, 32 modes); a rig compensation at most +2,780 (nl-online, meta-online).
        structure: Some(StructureCost {
            fe: [3_226.0, 13_000.0, 65_726.0],
            per_story: [1_232.0, 3_798.0],
            meta: 10_583.0,
            modal: [4_982.0, 3_399.0, 1_431.0],
            reduced: [6_845.0, 1_877.0],
            reduced_modes: 2.0,
            hysteron_base: f64::INFINITY,
            hysteron_mp: f64::INFINITY,
            rig: 2_780.0,
        }),
    };
    /// The Cortex-M7 (hardware f64): LR 375, LRX 535, FE + ATS 3,165, RNN-10 2,445, so
    /// (2,445 − 375) / 140 = 14.8 → 15 per term.
    pub const CORTEX_M7: Self = Self {
        lr: 375.0,
        lrx: 535.0,
        fe_ats: 3_165.0,
        rnn_per_term: 15.0,
        // The structure budget on the emulated M7 at 4096 Hz: FE 830 / 1,145 / 2,590 (N = 1, 3,
        // 8); FE yielding 935 / 1,750 (Bouc–Wen) / 3,160; metamodel 735 at most; modal 870
        // (1, 1), 1,585 (3, 3, Bouc–Wen), 2,485 (8, 8); reduced 2,055 / 2,400 / 3,455 (2, 9, 32
        // modes); a rig compensation at most +395 (nl-online, meta-online).
        structure: Some(StructureCost {
            fe: [830.0, 1_145.0, 2_590.0],
            per_story: [105.0, 202.0],
            meta: 735.0,
            modal: [870.0, 116.0, 84.0],
            reduced: [2_055.0, 50.0],
            reduced_modes: 2.0,
            // 2,810 (measured, nl-online, 6 plays) − 395 (rig) − 1,145 (FE, N = 3) − 12 × 105.
            hysteron_base: 10.0,
            // The larger of the two measured rows' cost per Menegotto–Pinto play, rounded up:
            // (6,105 (nl-online, 6 of them on 6 directions) − 2,810) / 6 + 105 = 655, and
            // (4,690 (nl-online at 4096 Hz, 4 of them on 3 directions) − 395 − 1,145 − 3 × 105
            // − 10) / 4 = 706.25.
            hysteron_mp: 707.0,
            rig: 395.0,
        }),
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

    /// The estimated instructions per tick of a `kind` model (`rnn_hidden`: an RNN's hidden size;
    /// a structure part of the smallest size: [`Self::instr_dims`] for its own).
    pub fn instr(&self, kind: ModelKind, rnn_hidden: usize) -> f64 {
        self.instr_dims(
            kind,
            &Dims {
                rnn_hidden,
                dofs: 1,
                modes: 1,
                springs: 1,
                ..Dims::default()
            },
        )
    }

    /// The estimated instructions per tick of a `kind` model of sizes `dims`, without a rig
    /// compensation (infinite: a structure part on a core whose costs were not measured).
    pub fn instr_dims(&self, kind: ModelKind, dims: &Dims) -> f64 {
        match kind {
            ModelKind::Lr => self.cost.lr,
            ModelKind::Lrx => self.cost.lrx,
            ModelKind::FeAts => self.cost.fe_ats,
            ModelKind::Rnn => self.rnn_instr(dims.rnn_hidden),
            _ => self
                .cost
                .structure
                .map_or(f64::INFINITY, |s| s.instr(kind, dims)),
        }
    }

    /// The estimate of a structure part of sizes `dims` with its rig compensation (the lead and
    /// the force correction).
    pub fn instr_with_rig(&self, kind: ModelKind, dims: &Dims) -> f64 {
        self.instr_dims(kind, dims) + self.cost.structure.map_or(f64::INFINITY, |s| s.rig)
    }

    /// [`Self::instr_dims`] as a share of the tick, % (over 100: the model cannot meet the tick).
    pub fn pct_of_tick_dims(&self, kind: ModelKind, dims: &Dims) -> f64 {
        100.0 * self.instr_dims(kind, dims) / self.instr_per_tick()
    }

    /// The tick can run a `kind` model of sizes `dims` (without a rig compensation).
    pub fn fits_dims(&self, kind: ModelKind, dims: &Dims) -> bool {
        self.instr_dims(kind, dims) <= self.instr_per_tick()
    }

    /// The most hysterons a floor-hysteron model of `floors` floors and `directions` directions
    /// may keep (`menegotto_pinto`: of that operator, else plays) for its estimate with the rig
    /// compensation to stay within `share` of the tick (0: not even one; a core whose costs were
    /// not measured gives 0).
    pub fn max_hysterons(
        &self,
        floors: usize,
        directions: usize,
        menegotto_pinto: bool,
        share: f64,
    ) -> usize {
        let limit = share * self.instr_per_tick();
        let cost = |h: usize| {
            self.instr_with_rig(
                ModelKind::StructureHysteron,
                &Dims {
                    dofs: floors,
                    directions,
                    hysterons: h,
                    bouc_wen: if menegotto_pinto { h } else { 0 },
                    ..Dims::default()
                },
            )
        };
        // The cost grows with each hysteron; the controller holds at most 64 of them.
        (1..=64)
            .take_while(|h| cost(*h) <= limit)
            .last()
            .unwrap_or(0)
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

//! The rig compensation upload (`HostMsg::UploadRig` in one frame, `RigBegin`/`RigChunk`/
//! `RigCommit` in chunks): what a rig file (`rths identify`) gives the controller's analytical part
//! in force, validated on the device and swapped in whole, or refused with the reason and the
//! compensation in force kept. The values' layout is `rths_link::rig_value_count`'s:
//! - FE + ATS: the ATS's initial [a0, a1, a2] (checked against the ATS's own bounds,
//!   `AtsParams::with_initial`);
//! - LRX: its lead filter (weights, stride, adaptation time constant) and the specimen's moving mass
//!   and damping (checked by `rths_core::model::lead_params` and
//!   `LrxParams::with_specimen_dynamics`, the model file's own checks);
//! - a structure part (`nl-online`, `meta-online`, `fe-online-lead`): the identified lead with its
//!   adaptation, the identified specimen that corrects the measured force
//!   (`rths_core::control::ForceCorrection`), and the specimen scale (prototype over rig), which
//!   the controller takes with the compensator given the target in force
//!   (`Controller::set_structure_rig`); the board's tick must run the part with it
//!   (`TickBudget`).

use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, Controller, ForceCorrection};
use rths_core::metamodel::HysteronOperator;
use rths_core::params::{SpecimenScale, DT_S};
use rths_link::layout::{Dims, RIG_UPLOAD_MAX_VALUES};
use rths_link::{ModelKind, NackReason, RECORD_CHUNK};

use crate::chunks::Chunks;
use crate::model_upload::{replace_nack, stride_of};
use crate::tick_cost::TickBudget;

/// A structure kind (its rig compensation is [`rths_link::layout::structure_rig_values`]').
pub fn is_structure(kind: ModelKind) -> bool {
    matches!(
        kind,
        ModelKind::StructureFe
            | ModelKind::StructureNl
            | ModelKind::StructureMeta
            | ModelKind::StructureModal
            | ModelKind::StructureReduced
            | ModelKind::StructureHysteron
    )
}

/// The board's part in force, as a rig compensation needs it: its kind, its sizes (a structure
/// part's cost with the compensation), and the board's tick.
#[derive(Debug, Clone, Copy)]
pub struct InForce {
    /// The analytical kind in force.
    pub kind: ModelKind,
    /// Its sizes.
    pub dims: Dims,
    /// The board's tick (`None`: not checked, the structure budget that measures the costs the
    /// check estimates from).
    pub budget: Option<TickBudget>,
}

/// Validate the rig compensation `v` (the kind's [`rths_link::rig_value_count`] values) of a
/// `kind` part against the part in force and swap it in whole (only at rest). Refused (another
/// kind `Unsupported`, another count `Shape`, a NaN `NotFinite`, out of core's bounds
/// `OutOfRange`, a structure part the tick cannot run with its compensation `TickBudget`):
/// nothing changes.
pub fn install_rig(
    ctl: &mut Controller,
    part: &InForce,
    kind: ModelKind,
    v: &[f64],
) -> Result<(), NackReason> {
    if !ctl.supervisor().at_rest() {
        return Err(NackReason::Busy);
    }
    if kind != part.kind {
        return Err(NackReason::Unsupported);
    }
    let expected = rths_link::rig_value_count(kind).ok_or(NackReason::Unsupported)?;
    if v.len() != expected {
        return Err(NackReason::Shape);
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err(NackReason::NotFinite);
    }
    match (kind, v) {
        (ModelKind::FeAts, &[a0, a1, a2]) => ctl.set_ats_initial([a0, a1, a2]),
        (ModelKind::Lrx, &[w0, w1, w2, w3, w4, w5, w6, w7, stride, adapt, mass, damping]) => {
            let lead = rths_core::model::lead_params(
                &[w0, w1, w2, w3, w4, w5, w6, w7],
                stride_of(stride)?,
                adapt,
            )
            .map_err(|_| NackReason::OutOfRange)?;
            ctl.set_lrx_rig(lead, [mass, damping])
        }
        (k, &[w0, w1, w2, w3, w4, w5, w6, w7, stride, adapt, k_kn_per_mm, c, m, disp, force])
            if is_structure(k) =>
        {
            if let Some(b) = &part.budget {
                if b.instr_with_rig(kind, &part.dims) > b.instr_per_tick() {
                    return Err(NackReason::TickBudget);
                }
            }
            let lead = rths_core::model::lead_params(
                &[w0, w1, w2, w3, w4, w5, w6, w7],
                stride_of(stride)?,
                adapt,
            )
            .map_err(|_| NackReason::OutOfRange)?;
            let correction = ForceCorrection::new(k_kn_per_mm, c, m, DT_S)
                .map_err(|_| NackReason::OutOfRange)?;
            let scale = SpecimenScale::new(disp, force).map_err(|_| NackReason::OutOfRange)?;
            ctl.set_structure_rig(lead, correction, scale)
        }
        _ => return Err(NackReason::Unsupported),
    }
    .map_err(replace_nack)
}

/// Validate an uploaded rig compensation in one frame (`HostMsg::UploadRig`) and swap it in whole
/// (only at rest); its [`rths_link::rig_checksum`]. Refused (as [`install_rig`], and a wrong
/// checksum `Checksum`): nothing changes.
pub fn upload_rig(
    ctl: &mut Controller,
    part: &InForce,
    kind: ModelKind,
    count: u8,
    values: &[f64; RECORD_CHUNK],
    checksum: u32,
) -> Result<u32, NackReason> {
    if !ctl.supervisor().at_rest() {
        return Err(NackReason::Busy);
    }
    if kind != part.kind {
        return Err(NackReason::Unsupported);
    }
    let expected = rths_link::rig_value_count(kind).ok_or(NackReason::Unsupported)?;
    if usize::from(count) != expected {
        return Err(NackReason::Shape);
    }
    let v = values.get(..expected).ok_or(NackReason::Shape)?;
    if v.iter().any(|x| !x.is_finite()) {
        return Err(NackReason::NotFinite);
    }
    if rths_link::rig_checksum(kind, v) != checksum {
        return Err(NackReason::Checksum);
    }
    install_rig(ctl, part, kind, v)?;
    Ok(checksum)
}

/// A rig compensation uploaded in chunks (a structure part's has more values than a frame holds).
#[derive(Debug, Clone)]
pub struct RigStaging {
    staged: Option<(ModelKind, u32, Chunks)>,
    area: [f64; RIG_UPLOAD_MAX_VALUES],
}

impl Default for RigStaging {
    fn default() -> Self {
        Self::new()
    }
}

impl RigStaging {
    /// Nothing staged.
    pub const fn new() -> Self {
        Self {
            staged: None,
            area: [0.0; RIG_UPLOAD_MAX_VALUES],
        }
    }

    /// Begin an upload of the `kind` part's compensation of `values` values (replaces one in
    /// progress): at rest, for the kind in force, of its count.
    pub fn begin(
        &mut self,
        part: ModelKind,
        kind: ModelKind,
        values: u8,
        checksum: u32,
        at_rest: bool,
    ) -> Result<(), NackReason> {
        self.staged = None;
        if !at_rest {
            return Err(NackReason::Busy);
        }
        if kind != part {
            return Err(NackReason::Unsupported);
        }
        let expected = rths_link::rig_value_count(kind).ok_or(NackReason::Unsupported)?;
        if usize::from(values) != expected || expected > self.area.len() {
            return Err(NackReason::Shape);
        }
        self.staged = Some((kind, checksum, Chunks::new(expected)));
        Ok(())
    }

    /// The next chunk: out of order, duplicated, a bad count or a non-finite value drops the upload.
    pub fn chunk(
        &mut self,
        seq: u32,
        count: u8,
        values: &[f64; RECORD_CHUNK],
        at_rest: bool,
    ) -> Result<(), NackReason> {
        if !at_rest {
            return Err(NackReason::Busy);
        }
        let (kind, checksum, mut chunks) = self.staged.take().ok_or(NackReason::Sequence)?;
        let vals = chunks.check(seq, count, values)?;
        let at = chunks.written();
        self.area
            .get_mut(at..at + vals.len())
            .ok_or(NackReason::TooLong)?
            .copy_from_slice(vals);
        chunks.advance(vals.len());
        self.staged = Some((kind, checksum, chunks));
        Ok(())
    }

    /// Check the compensation (every value arrived, its checksum) and swap it in whole
    /// ([`install_rig`]); its checksum. Refused: the upload is dropped, nothing changes.
    pub fn commit(&mut self, ctl: &mut Controller, part: &InForce) -> Result<u32, NackReason> {
        if !ctl.supervisor().at_rest() {
            return Err(NackReason::Busy);
        }
        let (kind, checksum, chunks) = self.staged.take().ok_or(NackReason::Sequence)?;
        if !chunks.complete() {
            return Err(NackReason::Incomplete);
        }
        let v = self.area.get(..chunks.total()).ok_or(NackReason::Shape)?;
        if rths_link::rig_checksum(kind, v) != checksum {
            return Err(NackReason::Checksum);
        }
        install_rig(ctl, part, kind, v)?;
        Ok(checksum)
    }
}

/// The link kind of the controller's analytical part (`None`: one no upload makes, a site or the
/// plain finite elements).
pub fn kind_of(ctl: &Controller) -> Option<ModelKind> {
    Some(match (ctl.analytical(), ctl.compensator()) {
        (Analytical::Lr(_), _) => ModelKind::Lr,
        (Analytical::Lrx(_), _) => ModelKind::Lrx,
        (Analytical::Rnn(_), _) => ModelKind::Rnn,
        (Analytical::Fe(_), Compensator::Ats(_)) => ModelKind::FeAts,
        (Analytical::StructureFe(_), _) => ModelKind::StructureFe,
        (Analytical::StructureNl(_), _) => ModelKind::StructureNl,
        (Analytical::StructureMeta(_), _) => ModelKind::StructureMeta,
        (Analytical::StructureModal(_), _) => ModelKind::StructureModal,
        (Analytical::StructureReduced(_), _) => ModelKind::StructureReduced,
        (Analytical::StructureHysteron(_), _) => ModelKind::StructureHysteron,
        _ => return None,
    })
}

/// The sizes of the controller's analytical part, as `rths_link::layout::dims` reads them from its
/// values (what a structure part's cost depends on).
pub fn dims_of(ctl: &Controller) -> Dims {
    let d = Dims::default();
    match ctl.analytical() {
        Analytical::Rnn(m) => Dims {
            rnn_hidden: m.params().hidden(),
            ..d
        },
        Analytical::StructureFe(m) => Dims {
            dofs: m.chang().model().dofs(),
            ..d
        },
        Analytical::StructureNl(m) => Dims {
            dofs: m.frame().dofs(),
            springs: m.frame().dofs(),
            bouc_wen: m
                .frame()
                .stories()
                .iter()
                .flatten()
                .filter(|s| s.law().bouc_wen_shape().is_some())
                .count(),
            ..d
        },
        Analytical::StructureModal(m) => {
            let p = m.model().params();
            Dims {
                dofs: p.floors(),
                modes: p.modes(),
                springs: p.springs(),
                bouc_wen: p
                    .laws()
                    .iter()
                    .flatten()
                    .filter(|l| l.bouc_wen_shape().is_some())
                    .count(),
                ..d
            }
        }
        Analytical::StructureReduced(m) => {
            let p = m.model().params();
            Dims {
                modes: p.modes(),
                outputs: p.outputs(),
                ..d
            }
        }
        Analytical::StructureHysteron(m) => {
            let p = m.model().params();
            let h = p.hysterons().len();
            Dims {
                dofs: p.floors(),
                directions: p.directions(),
                hysterons: h,
                bouc_wen: if p.operator() == HysteronOperator::Play {
                    0
                } else {
                    h
                },
                ..d
            }
        }
        _ => d,
    }
}

/// The rig compensation `ctl` holds, as an upload would send it ([`rths_link::rig_value_count`]'s
/// layout), and its kind; `None` for a controller without one.
pub fn rig_of(ctl: &Controller) -> Option<(ModelKind, [f64; RIG_UPLOAD_MAX_VALUES], usize)> {
    let mut v = [0.0; RIG_UPLOAD_MAX_VALUES];
    match (ctl.analytical(), ctl.compensator()) {
        (_, Compensator::Ats(a)) => {
            let init = a.params().initial();
            v.get_mut(..init.len())?.copy_from_slice(&init);
            Some((ModelKind::FeAts, v, init.len()))
        }
        (Analytical::Lrx(m), Compensator::Lead(l)) => {
            let p = l.params();
            let adapt = p.adaptation().map_or(0.0, |a| a.ticks());
            let (mass, damping) = m.params().specimen_dynamics();
            let r = rths_link::rig_values(p.weights(), p.stride(), adapt, [mass, damping])?;
            v.get_mut(..r.len())?.copy_from_slice(&r);
            Some((ModelKind::Lrx, v, r.len()))
        }
        (a, Compensator::Lead(l)) if a.is_structure() => {
            let p = l.params();
            let adapt = p.adaptation().map_or(0.0, |a| a.ticks());
            let cfg = ctl.config();
            let c = cfg
                .force_correction()
                .copied()
                .unwrap_or(ForceCorrection::NONE);
            let s = cfg.scale();
            let r = rths_link::layout::structure_rig_values(
                p.weights(),
                p.stride(),
                adapt,
                [c.k_kn_per_mm(), c.c_kn_s_per_mm(), c.m_kn_s2_per_mm()],
                [s.disp_scale(), s.force_scale()],
            )?;
            v.get_mut(..r.len())?.copy_from_slice(&r);
            Some((kind_of(ctl)?, v, r.len()))
        }
        _ => None,
    }
}

/// [`rths_link::rig_checksum`] of the rig compensation `ctl` holds (0: none).
pub fn rig_checksum_of(ctl: &Controller) -> u32 {
    rig_of(ctl).map_or(0, |(kind, v, n)| {
        v.get(..n).map_or(0, |v| rths_link::rig_checksum(kind, v))
    })
}

#[cfg(test)]
mod tests;

//! The rig compensation upload (`HostMsg::UploadRig`): what a rig file (`rths identify`) gives the
//! build's controller, validated on the device and swapped in whole, or refused with the reason
//! and the compensation in force kept. The FE + ATS build takes the ATS's initial [a0, a1, a2]
//! (checked against the ATS's own bounds, `AtsParams::with_initial`); the LRX build takes its lead
//! filter (weights, stride, adaptation time constant) and the specimen's moving mass and damping
//! (checked by `rths_core::model::lead_params` and `LrxParams::with_specimen_dynamics`, the model
//! file's own checks). The values' layout is `rths_link::rig_value_count`'s.

use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, Controller};
use rths_link::{ModelKind, NackReason, RECORD_CHUNK, RIG_MAX_VALUES};

use crate::model_upload::{replace_nack, stride_of};

/// Validate an uploaded rig compensation for a `build` controller and swap it in whole (only at
/// rest); its [`rths_link::rig_checksum`]. Refused: nothing changes.
pub fn upload_rig(
    ctl: &mut Controller,
    build: ModelKind,
    kind: ModelKind,
    count: u8,
    values: &[f64; RECORD_CHUNK],
    checksum: u32,
) -> Result<u32, NackReason> {
    if !ctl.supervisor().at_rest() {
        return Err(NackReason::Busy);
    }
    if kind != build {
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
        _ => return Err(NackReason::Unsupported),
    }
    .map_err(replace_nack)?;
    Ok(checksum)
}

/// The rig compensation `ctl` holds, as an upload would send it ([`rths_link::rig_value_count`]'s
/// layout), and its kind; `None` for a controller without one.
pub fn rig_of(ctl: &Controller) -> Option<(ModelKind, [f64; RIG_MAX_VALUES], usize)> {
    match (ctl.analytical(), ctl.compensator()) {
        (_, Compensator::Ats(a)) => {
            let mut v = [0.0; RIG_MAX_VALUES];
            let init = a.params().initial();
            v.get_mut(..init.len())?.copy_from_slice(&init);
            Some((ModelKind::FeAts, v, init.len()))
        }
        (Analytical::Lrx(m), Compensator::Lead(l)) => {
            let p = l.params();
            let adapt = p.adaptation().map_or(0.0, |a| a.ticks());
            let (mass, damping) = m.params().specimen_dynamics();
            let v = rths_link::rig_values(p.weights(), p.stride(), adapt, [mass, damping])?;
            Some((
                ModelKind::Lrx,
                v,
                rths_link::rig_value_count(ModelKind::Lrx)?,
            ))
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

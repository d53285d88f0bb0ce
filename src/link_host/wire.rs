//! The wire layout of what the host uploads (an LR model in one frame, other models of any kind and
//! ground-motion records in chunks, a rig compensation in one frame or, a structure part's, in
//! chunks), and the names of what the device reports (model kinds, record sources, run states,
//! fault codes). The models' values are `rths_link::layout`'s, read from a lab's files by
//! `rths_files::upload`, the reader the firmware's build script uses for its default.

use rths_link::{
    HostMsg, ModelKind as WireModelKind, RecordSource, RunState, LR_COEFFS, RECORD_CHUNK,
};

use super::error::LinkHostError;
use crate::machinery::model_file::{ModelFile, ModelKind};
use rths_core::supervisor::FaultReason;
use rths_files::upload::LaidOut;

/// The upload message of an LR model file (validated here too: kind, 6 coefficients, finite).
pub fn upload_message(model: &ModelFile) -> Result<HostMsg, LinkHostError> {
    if model.kind != ModelKind::Lr {
        return Err(LinkHostError::Model(
            "only LR models can be uploaded over the link".into(),
        ));
    }
    let theta: [f64; LR_COEFFS] = model
        .lr
        .as_ref()
        .and_then(|w| w.theta.clone().try_into().ok())
        .ok_or_else(|| LinkHostError::Model(format!("lr.theta must have {LR_COEFFS} values")))?;
    let delay = u16::try_from(model.delay_steps)
        .map_err(|_| LinkHostError::Model("delay_steps does not fit 16 bits".into()))?;
    Ok(HostMsg::UploadLr {
        features: LR_COEFFS as u8,
        theta,
        delay_steps: delay,
        checksum: rths_link::model_checksum(&theta, delay),
    })
}

/// The messages of a record upload: `RecordBegin`, one `RecordChunk` per [`RECORD_CHUNK`] samples
/// (numbered from 0), `RecordCommit`. Checked here too (≥ 2 finite samples, a finite step and scale)
/// so that a bad file fails before anything is sent; the device checks again.
pub fn record_messages(
    samples_g: &[f64],
    dt_s: f64,
    scale: f64,
) -> Result<Vec<HostMsg>, LinkHostError> {
    let samples = checked_record(samples_g, dt_s, scale)?;
    let mut out = Vec::with_capacity(samples_g.len() / RECORD_CHUNK + 3);
    out.push(HostMsg::RecordBegin {
        samples,
        dt_s,
        scale,
        checksum: rths_link::record_checksum(samples_g, dt_s),
    });
    out.extend(
        chunks(samples_g).map(|(seq, count, values)| HostMsg::RecordChunk { seq, count, values }),
    );
    out.push(HostMsg::RecordCommit);
    Ok(out)
}

/// The messages of a streamed record: its `StreamBegin` and its `StreamChunk`s (numbered from 0),
/// checked as [`record_messages`]; the `RecordCommit` goes once the ring is full.
pub fn stream_messages(
    samples_g: &[f64],
    dt_s: f64,
    scale: f64,
) -> Result<(HostMsg, Vec<HostMsg>), LinkHostError> {
    let samples = checked_record(samples_g, dt_s, scale)?;
    let begin = HostMsg::StreamBegin {
        samples,
        dt_s,
        scale,
        checksum: rths_link::record_checksum(samples_g, dt_s),
    };
    let chunks = chunks(samples_g)
        .map(|(seq, count, values)| HostMsg::StreamChunk { seq, count, values })
        .collect();
    Ok((begin, chunks))
}

/// A record's checks before anything is sent; its sample count.
fn checked_record(samples_g: &[f64], dt_s: f64, scale: f64) -> Result<u32, LinkHostError> {
    if samples_g.len() < 2 {
        return Err(LinkHostError::Motion("fewer than 2 samples".into()));
    }
    if let Some(i) = samples_g.iter().position(|v| !v.is_finite()) {
        return Err(LinkHostError::Motion(format!("sample {i} is not finite")));
    }
    if !(dt_s.is_finite() && dt_s > 0.0 && scale.is_finite()) {
        return Err(LinkHostError::Motion(format!(
            "step {dt_s} s or scale {scale} is not a finite positive number"
        )));
    }
    u32::try_from(samples_g.len())
        .map_err(|_| LinkHostError::Motion("more than 2^32 samples".into()))
}

/// `values` in frames of [`RECORD_CHUNK`]: each chunk's number (from 0), its count, and its
/// values padded with 0.
fn chunks(values: &[f64]) -> impl Iterator<Item = (u32, u8, [f64; RECORD_CHUNK])> + '_ {
    values.chunks(RECORD_CHUNK).enumerate().map(|(i, ch)| {
        let mut padded = [0.0; RECORD_CHUNK];
        for (d, s) in padded.iter_mut().zip(ch) {
            *d = *s;
        }
        (i as u32, ch.len() as u8, padded)
    })
}

/// The flat values of a model file for a chunked upload, and its wire kind
/// (`rths_link::layout`: LRX in `rths_link::lrx_values`' order, an RNN in
/// `rths_link::rnn_value_count`'s; any image takes an RNN of up to
/// `rths_link::RNN_UPLOAD_MAX_HIDDEN` units that its tick can run).
pub fn model_values(model: &ModelFile) -> Result<(WireModelKind, Vec<f64>), LinkHostError> {
    if model.kind == ModelKind::Lr {
        return Err(LinkHostError::Model(
            "an LR model goes in one UploadLr".into(),
        ));
    }
    let laid = rths_files::upload::lay_out_model_file(model, std::path::Path::new("model"))
        .map_err(|e| LinkHostError::Model(e.to_string()))?;
    Ok((laid.kind, laid.values))
}

/// The messages of a chunked upload of a model laid out from a lab's files
/// (`rths_files::upload::lay_out_files`: a structure's finite elements or one of its models).
pub fn laid_out_messages(laid: &LaidOut) -> Result<Vec<HostMsg>, LinkHostError> {
    chunked_messages(laid.kind, &laid.values, laid.delay_steps)
}

/// The rig-compensation values that carry an LRX model's optional lead adaptation and specimen
/// dynamics (`rths train lrx --rig`), in `rths_link::rig_values`' layout (0: absent, as the device
/// reads them), or `None` for a model without them (or not LRX).
pub fn lrx_rig_extras(model: &ModelFile) -> Result<Option<Vec<f64>>, LinkHostError> {
    let Some(x) = model.lrx.as_ref().filter(|_| model.kind == ModelKind::Lrx) else {
        return Ok(None);
    };
    let extras = [
        x.lead_adapt_ticks,
        x.specimen_mass_kn_s2_per_mm,
        x.specimen_damping_kn_s_per_mm,
    ];
    if extras.iter().all(Option::is_none) {
        return Ok(None);
    }
    let [adapt, mass, damping] = extras.map(|v| v.unwrap_or(0.0));
    rths_link::rig_values(&x.lead_weights, x.lead_stride, adapt, [mass, damping])
        .map(|v| Some(v.to_vec()))
        .ok_or_else(|| LinkHostError::Model("lrx: 8 lead weights".into()))
}

/// The messages of a chunked model upload: `ModelBegin`, the chunks of [`RECORD_CHUNK`] values,
/// `ModelCommit`.
pub fn model_messages(model: &ModelFile) -> Result<Vec<HostMsg>, LinkHostError> {
    let (kind, v) = model_values(model)?;
    let delay_steps = u16::try_from(model.delay_steps)
        .map_err(|_| LinkHostError::Model("delay_steps does not fit 16 bits".into()))?;
    chunked_messages(kind, &v, delay_steps)
}

/// The messages of a chunked upload that makes the device's analytical part its own finite
/// elements with the ATS starting from `expected_delay_s` (`rths_link::FE_ATS_VALUES`: the one
/// value), as `rths simulate --scenario fe-online-ats` runs them.
pub fn fe_ats_messages(expected_delay_s: f64) -> Result<Vec<HostMsg>, LinkHostError> {
    chunked_messages(WireModelKind::FeAts, &[expected_delay_s], 0)
}

/// `ModelBegin`, the chunks of `v`, `ModelCommit`, for a `kind` upload.
fn chunked_messages(
    kind: WireModelKind,
    v: &[f64],
    delay_steps: u16,
) -> Result<Vec<HostMsg>, LinkHostError> {
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(LinkHostError::Model(format!("value {i} is not finite")));
    }
    let values = u16::try_from(v.len())
        .map_err(|_| LinkHostError::Model("more than 65535 values".into()))?;
    let mut out = vec![HostMsg::ModelBegin {
        kind,
        values,
        delay_steps,
        checksum: rths_link::model_values_checksum(kind, v, delay_steps),
    }];
    out.extend(chunks(v).map(|(seq, count, values)| HostMsg::ModelChunk { seq, count, values }));
    out.push(HostMsg::ModelCommit);
    Ok(out)
}

/// The rig compensation a rig file (`rths identify`) gives a device's analytical part `kind`, in
/// `rths_link::rig_value_count`'s layout: FE + ATS: the ATS's identified initial [a0, a1, a2] (as
/// `rths simulate fe-online-ats --rig` starts from); LRX: the identified lead filter, the lead's
/// adaptation time constant `lead_adapt_ticks`, and the specimen's moving mass and damping at the
/// prototype's scale (as `rths train lrx --rig` writes them into a model). Another kind has none.
pub fn rig_values(
    rig: &crate::machinery::identify::RigFile,
    kind: WireModelKind,
    lead_adapt_ticks: f64,
) -> Result<Vec<f64>, LinkHostError> {
    match kind {
        WireModelKind::FeAts => Ok(rig.compensation.ats_initial.to_vec()),
        WireModelKind::Lrx => {
            let lead = rig
                .lead_params()
                .map_err(|e| LinkHostError::Model(format!("rig file: {e}")))?;
            let dynamics = crate::machinery::train::lrx::prototype_dynamics(&rig.specimen_fit);
            let v =
                rths_link::rig_values(lead.weights(), lead.stride(), lead_adapt_ticks, dynamics)
                    .ok_or_else(|| LinkHostError::Model("rig file: 8 lead weights".into()))?;
            Ok(v.to_vec())
        }
        WireModelKind::Lr | WireModelKind::Rnn => Err(LinkHostError::Model(format!(
            "the device runs {}, which has no rig compensation to upload",
            model_kind_name(kind)
        ))),
        _ => Err(LinkHostError::Model(format!(
            "the device runs {}, a structure part: its rig compensation needs the structure's \
             files (--structure, and --model for its model) to map the rig's specimen to the \
             structure's",
            model_kind_name(kind)
        ))),
    }
}

/// The rig compensation a rig file gives a structure part (`rths_link::layout::
/// structure_rig_values`), as the host's hybrid runs of a structure give it (`nl-online`,
/// `meta-online`, `fe-online-lead`): the identified lead with its adaptation `lead_adapt_ticks`,
/// the identified specimen (stiffness, damping, mass at the rig) that corrects the measured force,
/// and the specimen scale by which the rig's specimen stands for the structure's of
/// `specimen_k_kn_per_mm` (prototype, along its DOF): displacement `length_scale`, force
/// `k_structure × length_scale / k_rig` with the rig file's identified stiffness `k_rig`.
pub fn structure_rig_values(
    rig: &crate::machinery::identify::RigFile,
    specimen_k_kn_per_mm: f64,
    length_scale: f64,
    lead_adapt_ticks: f64,
) -> Result<Vec<f64>, LinkHostError> {
    let lead = rig
        .lead_params()
        .map_err(|e| LinkHostError::Model(format!("rig file: {e}")))?;
    let fit = &rig.specimen_fit;
    let k_rig = fit.stiffness_kn_per_mm;
    let force_scale = specimen_k_kn_per_mm * length_scale / k_rig;
    if !(force_scale.is_finite()
        && force_scale > 0.0
        && length_scale.is_finite()
        && length_scale > 0.0)
    {
        return Err(LinkHostError::Model(format!(
            "no specimen scale maps the rig's specimen ({} kN/mm identified) to the structure's \
             ({} kN/mm) at length scale {}",
            rths_files::readable(k_rig),
            rths_files::readable(specimen_k_kn_per_mm),
            rths_files::readable(length_scale)
        )));
    }
    rths_link::layout::structure_rig_values(
        lead.weights(),
        lead.stride(),
        lead_adapt_ticks,
        [
            fit.stiffness_kn_per_mm,
            fit.damping_kn_s_per_mm,
            fit.mass_kn_s2_per_mm,
        ],
        [length_scale, force_scale],
    )
    .map(|v| v.to_vec())
    .ok_or_else(|| LinkHostError::Model("rig file: 8 lead weights".into()))
}

/// The messages of a rig compensation for `kind`: one `UploadRig` frame for up to
/// `rths_link::RIG_MAX_VALUES` values, else `RigBegin`, its chunks and `RigCommit` (a structure
/// part's).
pub fn rig_messages(kind: WireModelKind, values: &[f64]) -> Result<Vec<HostMsg>, LinkHostError> {
    if values.len() <= rths_link::RIG_MAX_VALUES {
        return Ok(vec![rig_message(kind, values)?]);
    }
    if let Some(i) = values.iter().position(|x| !x.is_finite()) {
        return Err(LinkHostError::Model(format!("rig value {i} is not finite")));
    }
    let n = u8::try_from(values.len())
        .map_err(|_| LinkHostError::Model("more than 255 rig values".into()))?;
    let mut out = vec![HostMsg::RigBegin {
        kind,
        values: n,
        checksum: rths_link::rig_checksum(kind, values),
    }];
    out.extend(chunks(values).map(|(seq, count, values)| HostMsg::RigChunk { seq, count, values }));
    out.push(HostMsg::RigCommit);
    Ok(out)
}

/// The `UploadRig` message of a rig compensation for `kind` (its values, one frame).
pub fn rig_message(kind: WireModelKind, values: &[f64]) -> Result<HostMsg, LinkHostError> {
    if values.len() > rths_link::RIG_MAX_VALUES {
        return Err(LinkHostError::Model(format!(
            "{} rig values, a frame holds {}",
            values.len(),
            rths_link::RIG_MAX_VALUES
        )));
    }
    let mut v = [0.0; RECORD_CHUNK];
    v.get_mut(..values.len())
        .ok_or_else(|| LinkHostError::Model("rig values".into()))?
        .copy_from_slice(values);
    Ok(HostMsg::UploadRig {
        kind,
        count: values.len() as u8,
        values: v,
        checksum: rths_link::rig_checksum(kind, values),
    })
}

/// The name of a model kind as the device reports it.
pub fn model_kind_name(k: WireModelKind) -> &'static str {
    match k {
        WireModelKind::Lr => "lr",
        WireModelKind::Lrx => "lrx",
        WireModelKind::Rnn => "rnn",
        WireModelKind::FeAts => "fe-ats",
        WireModelKind::StructureFe => "structure-fe",
        WireModelKind::StructureNl => "structure-nl",
        WireModelKind::StructureMeta => "structure-meta",
        WireModelKind::StructureModal => "structure-modal",
        WireModelKind::StructureReduced => "structure-reduced",
        WireModelKind::StructureHysteron => "structure-hysteron",
    }
}

/// The name of a record's source as the device reports it.
pub fn record_source_name(s: RecordSource) -> &'static str {
    match s {
        RecordSource::Compiled => "compiled in",
        RecordSource::Uploaded => "uploaded",
        RecordSource::Streamed => "streamed during the run",
    }
}

/// A state's name in the CSV and the status print.
pub fn state_name(s: RunState) -> String {
    match s {
        RunState::Idle => "idle".into(),
        RunState::Armed => "armed".into(),
        RunState::Running => "running".into(),
        RunState::RampDown => "ramp-down".into(),
        RunState::Done => "done".into(),
        RunState::Fault(c) => format!("fault-{}", fault_name(c)),
    }
}

/// The name of a fault code (`rths_core::supervisor::FaultReason`'s table); "Unknown" for a code
/// this host does not know (a newer firmware's).
pub fn fault_name(code: u8) -> &'static str {
    FaultReason::from_code(code).map_or("Unknown", FaultReason::name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn record_and_model_messages_chunk_and_check_their_input() {
        let samples: Vec<f64> = (0..25).map(|i| i as f64 * 0.01).collect();
        let m = record_messages(&samples, 0.02, 1.0).unwrap();
        assert_eq!(m.len(), 1 + 3 + 1, "begin, 12 + 12 + 1, commit");
        match m[3] {
            HostMsg::RecordChunk { seq, count, .. } => assert_eq!((seq, count), (2, 1)),
            _ => panic!("{:?}", m[3]),
        }
        let values = |msg: &HostMsg| match msg {
            HostMsg::RecordChunk { values, .. } => *values,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            values(&m[1])[..],
            samples[..RECORD_CHUNK],
            "the first chunk"
        );
        let mut last = [0.0; RECORD_CHUNK];
        last[0] = samples[24];
        assert_eq!(values(&m[3]), last, "the last chunk, padded with 0");
        assert!(record_messages(&samples[..1], 0.02, 1.0).is_err());
        assert!(record_messages(&[0.0, f64::NAN], 0.02, 1.0).is_err());
        assert!(record_messages(&samples, 0.0, 1.0).is_err());
        assert!(record_messages(&samples, 0.02, f64::INFINITY).is_err());
        let lrx = ModelFile::from_json(include_str!("../../data/models/lrx.json")).unwrap();
        let m = model_messages(&lrx).unwrap();
        assert_eq!(m.len(), 1 + 2 + 1, "begin, 12 + 8 values, commit");
        let lr = ModelFile::from_json(include_str!("../../data/models/lr.json")).unwrap();
        assert!(model_messages(&lr).is_err(), "LR goes in one UploadLr");
    }
}

//! Tests of [`crate::model_upload`]: an LRX upload swaps the model whole; bad ones are refused.

use super::*;
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, FeedbackSource};
use rths_core::metamodel::{Lr, LrParams};
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::Limits;
use rths_link::lrx_values;

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

fn lrx() -> [f64; LRX_VALUES] {
    let coeffs = [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.9, -0.9, 0.0];
    let lead = [1.2, -0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    lrx_values(&coeffs, 12.0, 0.0, &lead, 2).unwrap()
}

fn send(st: &mut ModelStaging, v: &[f64], at_rest: bool) -> Result<(), NackReason> {
    for (i, ch) in v.chunks(RECORD_CHUNK).enumerate() {
        let mut c = [0.0; RECORD_CHUNK];
        c[..ch.len()].copy_from_slice(ch);
        st.chunk(i as u32, ch.len() as u8, &c, at_rest)?;
    }
    Ok(())
}

#[test]
fn an_lrx_upload_swaps_the_model_and_its_lead_filter() {
    let mut ctl = controller();
    let mut st = ModelStaging::new();
    let v = lrx();
    let c = rths_link::model_values_checksum(ModelKind::Lrx, &v, 28);
    st.begin(
        ModelKind::Lrx,
        LRX_VALUES as u16,
        28,
        c,
        ModelKind::Lrx,
        true,
    )
    .unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Ok(c));
    assert!(!st.uploading());
}

#[test]
fn bad_model_uploads_are_refused_whole() {
    let mut ctl = controller();
    let mut st = ModelStaging::new();
    let v = lrx();
    let c = rths_link::model_values_checksum(ModelKind::Lrx, &v, 28);
    let n = LRX_VALUES as u16;
    // A kind the build does not run, a kind that cannot be uploaded in chunks, a wrong count.
    assert_eq!(
        st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lr, true),
        Err(NackReason::Unsupported)
    );
    assert_eq!(
        st.begin(ModelKind::Rnn, 147, 28, c, ModelKind::Rnn, true),
        Err(NackReason::Unsupported)
    );
    assert_eq!(
        st.begin(ModelKind::Lrx, n - 1, 28, c, ModelKind::Lrx, true),
        Err(NackReason::Shape)
    );
    assert_eq!(
        st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lrx, false),
        Err(NackReason::Busy)
    );
    // Truncated, reordered, a wrong checksum, a NaN, a bad stride, under a test.
    st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lrx, true)
        .unwrap();
    send(&mut st, &v[..12], true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Err(NackReason::Incomplete));
    st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lrx, true)
        .unwrap();
    let mut c1 = [0.0; RECORD_CHUNK];
    c1[..8].copy_from_slice(&v[12..]);
    assert_eq!(st.chunk(1, 8, &c1, true), Err(NackReason::Sequence));
    st.begin(ModelKind::Lrx, n, 28, c ^ 1, ModelKind::Lrx, true)
        .unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Err(NackReason::Checksum));
    let mut nan = v;
    nan[4] = f64::NAN;
    st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lrx, true)
        .unwrap();
    assert_eq!(send(&mut st, &nan, true), Err(NackReason::NotFinite));
    let mut bad = v;
    bad[19] = 2.5;
    let cb = rths_link::model_values_checksum(ModelKind::Lrx, &bad, 28);
    st.begin(ModelKind::Lrx, n, 28, cb, ModelKind::Lrx, true)
        .unwrap();
    send(&mut st, &bad, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Err(NackReason::OutOfRange));
    bad[19] = 9.0; // a whole number outside the lead filter's 1..=8: the model's own check
    let cb = rths_link::model_values_checksum(ModelKind::Lrx, &bad, 28);
    st.begin(ModelKind::Lrx, n, 28, cb, ModelKind::Lrx, true)
        .unwrap();
    send(&mut st, &bad, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Err(NackReason::OutOfRange));
    st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lrx, true)
        .unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, false), Err(NackReason::Busy));
}

//! Tests of [`crate::model_upload`]: an LRX upload swaps the model whole; bad ones are refused.

extern crate std;
use std::{boxed::Box, vec, vec::Vec};

use super::*;
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, FeedbackSource};
use rths_core::metamodel::{Lr, LrParams};
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::Limits;
use rths_link::{lrx_values, MODEL_MAX_VALUES};

/// A staging area of `n` values for a test (leaked: the device's is a static).
fn area(n: usize) -> &'static mut [f64] {
    Box::leak(vec![0.0; n].into_boxed_slice())
}

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
    let mut st = ModelStaging::new(area(MODEL_MAX_VALUES));
    let v = lrx();
    let c = rths_link::model_values_checksum(ModelKind::Lrx, &v, 28);
    st.begin(
        ModelKind::Lrx,
        LRX_VALUES as u16,
        28,
        c,
        ModelKind::Lrx,
        0,
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
    let mut st = ModelStaging::new(area(MODEL_MAX_VALUES));
    let v = lrx();
    let c = rths_link::model_values_checksum(ModelKind::Lrx, &v, 28);
    let n = LRX_VALUES as u16;
    // A kind the build does not run, a kind that cannot be uploaded in chunks, a wrong count.
    assert_eq!(
        st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lr, 0, true),
        Err(NackReason::Unsupported)
    );
    assert_eq!(
        st.begin(ModelKind::Rnn, 147, 28, c, ModelKind::Rnn, 0, true),
        Err(NackReason::Unsupported)
    );
    assert_eq!(
        st.begin(ModelKind::Lrx, n - 1, 28, c, ModelKind::Lrx, 0, true),
        Err(NackReason::Shape)
    );
    assert_eq!(
        st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lrx, 0, false),
        Err(NackReason::Busy)
    );
    // Truncated, reordered, a wrong checksum, a NaN, a bad stride, under a test.
    st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lrx, 0, true)
        .unwrap();
    send(&mut st, &v[..12], true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Err(NackReason::Incomplete));
    st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lrx, 0, true)
        .unwrap();
    let mut c1 = [0.0; RECORD_CHUNK];
    c1[..8].copy_from_slice(&v[12..]);
    assert_eq!(st.chunk(1, 8, &c1, true), Err(NackReason::Sequence));
    st.begin(ModelKind::Lrx, n, 28, c ^ 1, ModelKind::Lrx, 0, true)
        .unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Err(NackReason::Checksum));
    let mut nan = v;
    nan[4] = f64::NAN;
    st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lrx, 0, true)
        .unwrap();
    assert_eq!(send(&mut st, &nan, true), Err(NackReason::NotFinite));
    let mut bad = v;
    bad[19] = 2.5;
    let cb = rths_link::model_values_checksum(ModelKind::Lrx, &bad, 28);
    st.begin(ModelKind::Lrx, n, 28, cb, ModelKind::Lrx, 0, true)
        .unwrap();
    send(&mut st, &bad, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Err(NackReason::OutOfRange));
    bad[19] = 9.0; // a whole number outside the lead filter's 1..=8: the model's own check
    let cb = rths_link::model_values_checksum(ModelKind::Lrx, &bad, 28);
    st.begin(ModelKind::Lrx, n, 28, cb, ModelKind::Lrx, 0, true)
        .unwrap();
    send(&mut st, &bad, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Err(NackReason::OutOfRange));
    st.begin(ModelKind::Lrx, n, 28, c, ModelKind::Lrx, 0, true)
        .unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, false), Err(NackReason::Busy));
}

/// An RNN of `h` units with distinct finite weights (not trained: only the upload is tested).
fn rnn_model(h: usize, seed: f64) -> (Vec<f64>, RnnScaling) {
    let n = h * 2 + h * h + h + h + 1;
    let w: Vec<f64> = (0..n).map(|i| seed * ((i as f64) * 0.37).sin()).collect();
    let s = RnnScaling {
        input_mean: [0.1, -0.2],
        input_std: [2.0, 3.0],
        output_mean: 0.5,
        output_std: 4.0,
    };
    (w, s)
}

fn weights(h: usize, w: &[f64]) -> RnnWeights<'_> {
    let (w_ih, r) = w.split_at(2 * h);
    let (w_hh, r) = r.split_at(h * h);
    let (b_h, r) = r.split_at(h);
    let (w_ho, r) = r.split_at(h);
    RnnWeights {
        w_ih,
        w_hh,
        b_h,
        w_ho,
        b_o: r[0],
    }
}

fn rnn_controller(h: usize) -> Controller {
    use rths_core::metamodel::{Rnn, RnnParams};
    let (w, s) = rnn_model(h, 0.1);
    let p = RnnParams::new(weights(h, &w), s).unwrap();
    let mut c = controller();
    c.set_analytical(Analytical::Rnn(Rnn::new(p))).unwrap();
    c
}

#[test]
fn an_rnn_upload_loads_the_weights_in_place_as_new_would_build_them() {
    use rths_core::metamodel::RnnParams;
    let h = 5;
    let mut ctl = rnn_controller(h);
    let (w, s) = rnn_model(h, 0.3);
    let mut v = vec![0.0; rths_link::rnn_value_count(h)];
    let n = rnn_values(&weights(h, &w), &s, &mut v).unwrap();
    assert_eq!(n, v.len());
    let c = rths_link::model_values_checksum(ModelKind::Rnn, &v, 28);
    assert_eq!(rnn_checksum(&weights(h, &w), &s, 28, &mut [0.0; 64]), c);
    let mut st = ModelStaging::new(area(n));
    st.begin(ModelKind::Rnn, n as u16, 28, c, ModelKind::Rnn, h, true)
        .unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Ok(c));
    let Analytical::Rnn(m) = ctl.analytical() else {
        panic!("not an RNN")
    };
    assert_eq!(*m.params(), RnnParams::new(weights(h, &w), s).unwrap());
}

#[test]
fn bad_rnn_uploads_are_refused_whole_and_the_model_in_force_stays() {
    let h = 5;
    let mut ctl = rnn_controller(h);
    let before = ctl.analytical().clone();
    let (w, s) = rnn_model(h, 0.3);
    let n = rths_link::rnn_value_count(h);
    let mut v = vec![0.0; n];
    rnn_values(&weights(h, &w), &s, &mut v).unwrap();
    let c = rths_link::model_values_checksum(ModelKind::Rnn, &v, 28);
    let mut st = ModelStaging::new(area(n));
    // Another hidden size than the build's; a build without an RNN; a staging area too small.
    let n6 = rths_link::rnn_value_count(6) as u16;
    assert_eq!(
        st.begin(ModelKind::Rnn, n6, 28, c, ModelKind::Rnn, h, true),
        Err(NackReason::Shape)
    );
    assert_eq!(
        st.begin(ModelKind::Rnn, n as u16, 28, c, ModelKind::Lrx, 0, true),
        Err(NackReason::Unsupported)
    );
    assert_eq!(
        ModelStaging::new(area(n - 1)).begin(
            ModelKind::Rnn,
            n as u16,
            28,
            c,
            ModelKind::Rnn,
            h,
            true
        ),
        Err(NackReason::TooLong)
    );
    // A duplicated chunk, a NaN, a wrong checksum, a non-positive std (the model's own check).
    st.begin(ModelKind::Rnn, n as u16, 28, c, ModelKind::Rnn, h, true)
        .unwrap();
    let mut c0 = [0.0; RECORD_CHUNK];
    c0.copy_from_slice(&v[..RECORD_CHUNK]);
    st.chunk(0, RECORD_CHUNK as u8, &c0, true).unwrap();
    assert_eq!(
        st.chunk(0, RECORD_CHUNK as u8, &c0, true),
        Err(NackReason::Sequence)
    );
    assert!(!st.uploading());
    let mut nan = v.clone();
    nan[n - 3] = f64::NAN;
    st.begin(ModelKind::Rnn, n as u16, 28, c, ModelKind::Rnn, h, true)
        .unwrap();
    assert_eq!(send(&mut st, &nan, true), Err(NackReason::NotFinite));
    st.begin(ModelKind::Rnn, n as u16, 28, c ^ 1, ModelKind::Rnn, h, true)
        .unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Err(NackReason::Checksum));
    let mut bad = v.clone();
    bad[n - 1] = 0.0; // output std
    let cb = rths_link::model_values_checksum(ModelKind::Rnn, &bad, 28);
    st.begin(ModelKind::Rnn, n as u16, 28, cb, ModelKind::Rnn, h, true)
        .unwrap();
    send(&mut st, &bad, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true), Err(NackReason::OutOfRange));
    // Under a test.
    st.begin(ModelKind::Rnn, n as u16, 28, c, ModelKind::Rnn, h, true)
        .unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, false), Err(NackReason::Busy));
    assert_eq!(*ctl.analytical(), before, "the model in force stays");
}

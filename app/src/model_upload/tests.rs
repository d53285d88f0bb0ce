//! Tests of [`crate::model_upload`]: an LRX upload swaps the model whole; bad ones are refused.

extern crate std;
use std::{boxed::Box, vec, vec::Vec};

use super::*;
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, FeedbackSource};
use rths_core::metamodel::{Lr, LrParams};
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::supervisor::Limits;
use rths_link::{lrx_values, LRX_VALUES, MODEL_MAX_VALUES};

/// A board whose tick runs every model of these tests.
const M7: TickBudget = TickBudget::cortex_m7_480mhz(2048.0);
/// The F407's tick at 2048 Hz: no RNN-10.
const M4: TickBudget = TickBudget::cortex_m4_168mhz(2048.0);

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
    st.begin(ModelKind::Lrx, LRX_VALUES as u16, 28, c, true)
        .unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true, &M7), Ok((ModelKind::Lrx, c)));
    assert!(!st.uploading());
}

#[test]
fn bad_model_uploads_are_refused_whole() {
    let mut ctl = controller();
    let mut st = ModelStaging::new(area(MODEL_MAX_VALUES));
    let v = lrx();
    let c = rths_link::model_values_checksum(ModelKind::Lrx, &v, 28);
    let n = LRX_VALUES as u16;
    // A kind that cannot be uploaded in chunks, counts no kind has, too many for the area.
    assert_eq!(
        st.begin(ModelKind::Lr, 6, 28, c, true),
        Err(NackReason::Unsupported)
    );
    for (kind, bad) in [
        (ModelKind::Rnn, 146), // RNN-10 has 147
        (ModelKind::Lrx, 19),
        (ModelKind::Rnn, rths_link::rnn_value_count(33) as u16),
        (ModelKind::FeAts, 2),
        (ModelKind::FeAts, 0),
    ] {
        assert_eq!(
            st.begin(kind, bad, 28, c, true),
            Err(NackReason::Shape),
            "{kind:?} {bad}"
        );
    }
    assert_eq!(
        ModelStaging::new(area(100)).begin(ModelKind::Rnn, 147, 28, c, true),
        Err(NackReason::TooLong)
    );
    assert_eq!(
        st.begin(ModelKind::Lrx, n - 1, 28, c, true),
        Err(NackReason::Shape)
    );
    assert_eq!(
        st.begin(ModelKind::Lrx, n, 28, c, false),
        Err(NackReason::Busy)
    );
    // Truncated, reordered, a wrong checksum, a NaN, a bad stride, under a test.
    st.begin(ModelKind::Lrx, n, 28, c, true).unwrap();
    send(&mut st, &v[..12], true).unwrap();
    assert_eq!(st.commit(&mut ctl, true, &M7), Err(NackReason::Incomplete));
    st.begin(ModelKind::Lrx, n, 28, c, true).unwrap();
    let mut c1 = [0.0; RECORD_CHUNK];
    c1[..8].copy_from_slice(&v[12..]);
    assert_eq!(st.chunk(1, 8, &c1, true), Err(NackReason::Sequence));
    st.begin(ModelKind::Lrx, n, 28, c ^ 1, true).unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true, &M7), Err(NackReason::Checksum));
    let mut nan = v;
    nan[4] = f64::NAN;
    st.begin(ModelKind::Lrx, n, 28, c, true).unwrap();
    assert_eq!(send(&mut st, &nan, true), Err(NackReason::NotFinite));
    let mut bad = v;
    bad[19] = 2.5;
    let cb = rths_link::model_values_checksum(ModelKind::Lrx, &bad, 28);
    st.begin(ModelKind::Lrx, n, 28, cb, true).unwrap();
    send(&mut st, &bad, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true, &M7), Err(NackReason::OutOfRange));
    bad[19] = 9.0; // a whole number outside the lead filter's 1..=8: the model's own check
    let cb = rths_link::model_values_checksum(ModelKind::Lrx, &bad, 28);
    st.begin(ModelKind::Lrx, n, 28, cb, true).unwrap();
    send(&mut st, &bad, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true, &M7), Err(NackReason::OutOfRange));
    st.begin(ModelKind::Lrx, n, 28, c, true).unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, false, &M7), Err(NackReason::Busy));
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
    st.begin(ModelKind::Rnn, n as u16, 28, c, true).unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true, &M7), Ok((ModelKind::Rnn, c)));
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
    // A count that is no RNN's; a staging area too small.
    assert_eq!(
        st.begin(ModelKind::Rnn, n as u16 + 1, 28, c, true),
        Err(NackReason::Shape)
    );
    assert_eq!(
        ModelStaging::new(area(n - 1)).begin(ModelKind::Rnn, n as u16, 28, c, true),
        Err(NackReason::TooLong)
    );
    // A duplicated chunk, a NaN, a wrong checksum, a non-positive std (the model's own check).
    st.begin(ModelKind::Rnn, n as u16, 28, c, true).unwrap();
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
    st.begin(ModelKind::Rnn, n as u16, 28, c, true).unwrap();
    assert_eq!(send(&mut st, &nan, true), Err(NackReason::NotFinite));
    st.begin(ModelKind::Rnn, n as u16, 28, c ^ 1, true).unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true, &M7), Err(NackReason::Checksum));
    let mut bad = v.clone();
    bad[n - 1] = 0.0; // output std
    let cb = rths_link::model_values_checksum(ModelKind::Rnn, &bad, 28);
    st.begin(ModelKind::Rnn, n as u16, 28, cb, true).unwrap();
    send(&mut st, &bad, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true, &M7), Err(NackReason::OutOfRange));
    // Under a test.
    st.begin(ModelKind::Rnn, n as u16, 28, c, true).unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, false, &M7), Err(NackReason::Busy));
    assert_eq!(*ctl.analytical(), before, "the model in force stays");
}

#[test]
fn any_image_takes_an_rnn_of_any_size_its_tick_runs_and_the_m4_refuses_an_rnn_10() {
    // An LR image (no RNN compiled in) takes an RNN-5 and an RNN-20 on the M7's tick.
    for h in [5, 20] {
        let mut ctl = controller();
        let (w, s) = rnn_model(h, 0.3);
        let mut v = vec![0.0; rths_link::rnn_value_count(h)];
        let n = rnn_values(&weights(h, &w), &s, &mut v).unwrap();
        let c = rths_link::model_values_checksum(ModelKind::Rnn, &v, 28);
        let mut st = ModelStaging::new(area(MODEL_MAX_VALUES));
        st.begin(ModelKind::Rnn, n as u16, 28, c, true).unwrap();
        send(&mut st, &v, true).unwrap();
        assert_eq!(st.commit(&mut ctl, true, &M7), Ok((ModelKind::Rnn, c)));
        let Analytical::Rnn(m) = ctl.analytical() else {
            panic!("not an RNN")
        };
        assert_eq!(m.params().hidden(), h);
    }
    // The F407's tick: RNN-10 refused (104 %), the LR model in force stays; RNN-9 taken.
    for (h, want) in [(10, Err(NackReason::TickBudget)), (9, Ok(()))] {
        let mut ctl = controller();
        let before = ctl.analytical().clone();
        let (w, s) = rnn_model(h, 0.3);
        let mut v = vec![0.0; rths_link::rnn_value_count(h)];
        let n = rnn_values(&weights(h, &w), &s, &mut v).unwrap();
        let c = rths_link::model_values_checksum(ModelKind::Rnn, &v, 28);
        let mut st = ModelStaging::new(area(MODEL_MAX_VALUES));
        st.begin(ModelKind::Rnn, n as u16, 28, c, true).unwrap();
        send(&mut st, &v, true).unwrap();
        let got = st.commit(&mut ctl, true, &M4).map(|_| ());
        assert_eq!(got, want, "RNN-{h}");
        if want.is_err() {
            assert_eq!(*ctl.analytical(), before, "the model in force stays");
        }
    }
}

#[test]
fn an_fe_ats_upload_makes_the_controller_the_host_s_fe_online_ats_and_bad_delays_are_refused() {
    use rths_core::model::{assemble, ModelSpec};
    let delay_s = 0.0137;
    let v = [delay_s];
    let c = rths_link::model_values_checksum(ModelKind::FeAts, &v, 28);
    let mut ctl = Box::new(controller());
    let mut st = ModelStaging::new(area(MODEL_MAX_VALUES));
    st.begin(ModelKind::FeAts, 1, 28, c, true).unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(st.commit(&mut ctl, true, &M4), Ok((ModelKind::FeAts, c)));
    let (fe, ats) = assemble(
        &ModelSpec::FeAts {
            expected_delay_s: delay_s,
        },
        Prototype::paper(),
        DT_S,
    )
    .unwrap();
    assert_eq!(*ctl.analytical(), fe);
    assert_eq!(*ctl.compensator(), ats);
    // A negative delay, or one beyond the ATS's bounds (0..=0.08 s); the model stays.
    for bad in [-0.01, 0.09, 1e9] {
        let v = [bad];
        let c = rths_link::model_values_checksum(ModelKind::FeAts, &v, 28);
        st.begin(ModelKind::FeAts, 1, 28, c, true).unwrap();
        send(&mut st, &v, true).unwrap();
        assert_eq!(
            st.commit(&mut ctl, true, &M4),
            Err(NackReason::OutOfRange),
            "{bad}"
        );
        assert_eq!(*ctl.analytical(), fe);
    }
    // FE + ATS at 4096 Hz on the M4 (114 % of the tick).
    let m4_4096 = TickBudget::cortex_m4_168mhz(4096.0);
    let mut ctl = Box::new(controller());
    st.begin(ModelKind::FeAts, 1, 28, c_of(delay_s), true)
        .unwrap();
    send(&mut st, &[delay_s], true).unwrap();
    assert_eq!(
        st.commit(&mut ctl, true, &m4_4096),
        Err(NackReason::TickBudget)
    );
}

fn c_of(delay_s: f64) -> u32 {
    rths_link::model_values_checksum(ModelKind::FeAts, &[delay_s], 28)
}

/// A structure's finite elements (N = 2, linear), its modal-hysteretic and its floor-hysteron
/// model (plays, Menegotto–Pinto), uploaded to an LR
/// image: built as core's assembly builds them; a part the tick cannot run refused `TickBudget`,
/// values that announce other sizes than they have `Shape`.
#[test]
fn any_image_takes_a_structure_part_built_as_core_assembles_it() {
    use rths_core::control::{ModalSpec, StoryLawSpec, StructureSpec};
    use rths_core::metamodel::ModalMode;
    use rths_core::model::{assemble, ModelSpec};
    let (m, c, k, gm) = (
        [1.0, 0.0, 0.0, 1.0],
        [0.1, 0.0, 0.0, 0.1],
        [300.0, -150.0, -150.0, 150.0],
        [1.0, 1.0],
    );
    let fe = ModelSpec::StructureFe {
        structure: StructureSpec {
            dofs: 2,
            mass: &m,
            damping: &c,
            stiffness: &k,
            initial_stiffness: &k,
            ground_mass: &gm,
            specimen_dof: 0,
            laws: &[],
        },
    };
    let modes = [ModalMode {
        omega_rad_s: 20.0,
        damping_ratio: 0.02,
        ground_participation: 1.0,
    }];
    let law = StoryLawSpec {
        k0_kn_per_mm: 40.0,
        yield_force_kn: 20.0,
        post_yield_ratio: 0.05,
        bouc_wen: Some([2.0, 0.5, 0.5]),
    };
    let modal = ModelSpec::StructureModal {
        model: ModalSpec {
            modes: &modes,
            shape: &[0.7],
            specimen_dof: 0,
            specimen_k_kn_per_mm: 50.0,
            laws: &[law],
            drift: &[0.7],
        },
    };
    // The floor-hysteron model of the same floors: its story drifts, 3 plays and 1 Menegotto–Pinto
    // model of the same hysterons.
    let dirs = [1.0, 0.0, -1.0, 1.0];
    let hyst = [0.0, 1.0, 40.0, 1.0, 2.0, 30.0, 0.0, 4.0, 20.0];
    let floors = rths_core::metamodel::FloorStructure {
        floors: 2,
        mass: &m,
        damping: &c,
        stiffness: &k,
        ground_mass: &gm,
        specimen_floor: 0,
        specimen_k_kn_per_mm: 50.0,
    };
    let hysteron = |operator| ModelSpec::StructureHysteron {
        model: rths_core::control::FloorHysteronSpec {
            floors,
            directions: &dirs,
            hysterons: &hyst,
            operator,
        },
    };
    let mp = rths_core::metamodel::MpShape::new(20.0, 0.925, 0.15).unwrap();
    for spec in [
        fe,
        modal,
        hysteron(rths_core::metamodel::HysteronOperator::Play),
        hysteron(rths_core::metamodel::HysteronOperator::MenegottoPinto(mp)),
    ] {
        let mut v = vec![0.0; MODEL_MAX_VALUES];
        let (kind, n) = rths_link::layout::lay_out(&spec, &mut v).unwrap();
        v.truncate(n);
        let c = rths_link::model_values_checksum(kind, &v, 0);
        let mut ctl = Box::new(controller());
        let mut st = ModelStaging::new(area(MODEL_MAX_VALUES));
        st.begin(kind, n as u16, 0, c, true).unwrap();
        send(&mut st, &v, true).unwrap();
        assert_eq!(st.commit(&mut ctl, true, &M7), Ok((kind, c)), "{kind:?}");
        let (a, comp) = assemble(&spec, Prototype::paper(), DT_S).unwrap();
        assert_eq!(*ctl.analytical(), a, "{kind:?}");
        assert_eq!(*ctl.compensator(), comp);
        // A tick too short for it: refused, the model in force stays.
        let slow = TickBudget {
            clock_hz: 1e6,
            ..M7
        };
        let mut lr = controller();
        let before = lr.analytical().clone();
        st.begin(kind, n as u16, 0, c, true).unwrap();
        send(&mut st, &v, true).unwrap();
        assert_eq!(
            st.commit(&mut lr, true, &slow),
            Err(NackReason::TickBudget),
            "{kind:?}"
        );
        assert_eq!(*lr.analytical(), before);
    }
    // Two DOFs announced, the values of one: refused at the commit.
    let n = rths_link::layout::structure_value_count(2, 0);
    let mut v = vec![0.5; n];
    v[..3].copy_from_slice(&[1.0, 0.0, 0.0]);
    let c = rths_link::model_values_checksum(ModelKind::StructureFe, &v, 0);
    let mut st = ModelStaging::new(area(MODEL_MAX_VALUES));
    st.begin(ModelKind::StructureFe, n as u16, 0, c, true)
        .unwrap();
    send(&mut st, &v, true).unwrap();
    assert_eq!(
        st.commit(&mut controller(), true, &M7),
        Err(NackReason::Shape)
    );
    // A count no structure's FE has: refused at the begin.
    assert_eq!(
        st.begin(ModelKind::StructureFe, n as u16 + 1, 0, c, true),
        Err(NackReason::Shape)
    );
}

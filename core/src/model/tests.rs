//! Tests of controller assembly: validation, and the same controller by value and in place.

use super::*;

const THETA: [f64; 6] = [0.0, 1e-7, 0.0, 0.0, 1.99, -0.99];
/// Firmware keeps its spec in a `const` over `&'static` arrays.
const LR: ModelSpec<'static> = ModelSpec::Lr { theta: &THETA };

#[test]
fn each_spec_assembles_its_parts() -> Result<(), ModelError> {
    let p = Prototype::paper();
    let (a, c) = assemble(&LR, p, DT_S)?;
    assert!(matches!((a, c), (Analytical::Lr(_), Compensator::None)));
    let lead = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let coeffs = [0.0; 9];
    let lrx = ModelSpec::Lrx {
        coeffs: &coeffs,
        k_corr_kn_per_mm: 1.0,
        k_adapt_ticks: 0.0,
        lead_weights: &lead,
        lead_stride: 2,
        lead_adapt_ticks: 0.0,
        specimen_dynamics: [0.0; 2],
    };
    let (a, c) = assemble(&lrx, p, DT_S)?;
    assert!(matches!((a, c), (Analytical::Lrx(_), Compensator::Lead(_))));
    let (a, c) = assemble(&ModelSpec::Fe, p, DT_S)?;
    assert!(matches!((a, c), (Analytical::Fe(_), Compensator::None)));
    let ats = ModelSpec::FeAts {
        expected_delay_s: 28.0 * DT_S,
    };
    let (a, c) = assemble(&ats, p, DT_S)?;
    assert!(matches!((a, c), (Analytical::Fe(_), Compensator::Ats(_))));
    let h = 2;
    let w = [0.1; 4];
    let rnn = ModelSpec::Rnn {
        weights: RnnWeights {
            w_ih: &w,
            w_hh: &w,
            b_h: &w[..h],
            w_ho: &w[..h],
            b_o: 0.0,
        },
        scaling: RnnScaling {
            input_mean: [0.0; 2],
            input_std: [1.0; 2],
            output_mean: 0.0,
            output_std: 1.0,
        },
    };
    let (a, c) = assemble(&rnn, p, DT_S)?;
    assert!(matches!((a, c), (Analytical::Rnn(_), Compensator::None)));
    Ok(())
}

/// The name a board's RESULT line gives the part in force: the kind, the finite elements'
/// compensator, and an RNN's own size.
#[test]
fn scenario_names_follow_the_part_in_force() -> Result<(), ModelError> {
    use crate::control::{ControlConfig, Controller, FeedbackSource};
    use crate::params::SpecimenScale;
    use crate::supervisor::Limits;
    let p = Prototype::paper();
    let cfg = ControlConfig::new(
        p,
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let name = |spec: &ModelSpec<'_>| -> Result<_, ModelError> {
        let (a, c) = assemble(spec, p, DT_S)?;
        Ok(Controller::new(cfg, a, c).scenario_name())
    };
    assert_eq!(name(&LR)?, ("lr-online", None));
    assert_eq!(name(&ModelSpec::Fe)?, ("fe-online", None));
    let ats = ModelSpec::FeAts {
        expected_delay_s: 28.0 * DT_S,
    };
    assert_eq!(name(&ats)?, ("fe-online-ats", None));
    let w = [0.1; 4];
    let rnn = ModelSpec::Rnn {
        weights: RnnWeights {
            w_ih: &w,
            w_hh: &w,
            b_h: &w[..2],
            w_ho: &w[..2],
            b_o: 0.0,
        },
        scaling: RnnScaling {
            input_mean: [0.0; 2],
            input_std: [1.0; 2],
            output_mean: 0.0,
            output_std: 1.0,
        },
    };
    assert_eq!(name(&rnn)?, ("rnn-online-", Some(2)));
    Ok(())
}

/// `assemble_in` builds exactly the parts `Controller::new` gets from `assemble`, for every
/// kind, and they run the same.
#[test]
fn assemble_in_builds_the_same_controller_in_place() {
    use crate::control::{ControlConfig, FeedbackSource};
    use crate::hal::Sample;
    use crate::params::SpecimenScale;
    use crate::supervisor::Limits;
    let p = Prototype::paper();
    let cfg = ControlConfig::new(
        p,
        SpecimenScale::default(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let lead = [1.2, -0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let coeffs = [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.9, -0.9, 0.0];
    let w = [0.1, -0.2, 0.3, 0.05];
    let specs = [
        LR,
        ModelSpec::Lrx {
            coeffs: &coeffs,
            k_corr_kn_per_mm: 12.0,
            k_adapt_ticks: 4096.0,
            lead_weights: &lead,
            lead_stride: 2,
            lead_adapt_ticks: 4096.0,
            specimen_dynamics: [1e-5, 2e-3],
        },
        ModelSpec::Rnn {
            weights: RnnWeights {
                w_ih: &w,
                w_hh: &w,
                b_h: &w[..2],
                w_ho: &w[2..],
                b_o: 0.1,
            },
            scaling: RnnScaling {
                input_mean: [0.5, -0.5],
                input_std: [100.0, 10.0],
                output_mean: 0.0,
                output_std: 2.0,
            },
        },
        ModelSpec::Fe,
        ModelSpec::FeAts {
            expected_delay_s: 28.0 * DT_S,
        },
    ];
    for spec in &specs {
        let (a, c) = assemble(spec, p, DT_S).unwrap();
        let mut by_value = Controller::new(cfg, a, c);
        let mut slot = core::mem::MaybeUninit::uninit();
        let in_place = Controller::init_in(&mut slot, cfg);
        assemble_in(in_place, spec, p, DT_S).unwrap();
        assert_eq!(in_place.analytical(), by_value.analytical(), "{spec:?}");
        assert_eq!(in_place.compensator(), by_value.compensator(), "{spec:?}");
        for ctl in [&mut by_value, &mut *in_place] {
            ctl.supervisor_mut().arm().unwrap();
            ctl.supervisor_mut().start().unwrap();
        }
        for k in 0..400 {
            let ag = 1000.0 * libm::sin(k as f64 * 0.05);
            let s = Sample {
                disp_mm: 0.01 * libm::sin(k as f64 * 0.05),
                force_kn: 0.2 * libm::cos(k as f64 * 0.05),
            };
            let x = by_value.tick(ag, Ok(s), false);
            let y = in_place.tick(ag, Ok(s), false);
            let bits = |o: crate::control::TickOutput| {
                (
                    [o.command_mm, o.target_mm, o.requested_mm].map(f64::to_bits),
                    o.state,
                    o.sample_held,
                )
            };
            assert_eq!(bits(x), bits(y), "{spec:?} tick {k}");
        }
    }
    // Refused: bad weights.
    let mut slot = core::mem::MaybeUninit::uninit();
    let ctl = Controller::init_in(&mut slot, cfg);
    let bad = ModelSpec::Lr { theta: &[0.0; 5] };
    assert!(assemble_in(ctl, &bad, p, DT_S).is_err());
}

#[test]
fn bad_weights_are_refused() {
    let short = [0.0; 5];
    assert!(matches!(
        assemble(&ModelSpec::Lr { theta: &short }, Prototype::paper(), DT_S),
        Err(ModelError::Shape { .. })
    ));
    let lrx = ModelSpec::Lrx {
        coeffs: &[0.0; 9],
        k_corr_kn_per_mm: 1.0,
        k_adapt_ticks: 0.0,
        lead_weights: &[1.0; 7],
        lead_stride: 1,
        lead_adapt_ticks: 0.0,
        specimen_dynamics: [0.0; 2],
    };
    assert!(matches!(
        lrx.validate(),
        Err(ModelError::Shape {
            expected: 8,
            got: 7,
            ..
        })
    ));
    assert!(assemble(&ModelSpec::Fe, Prototype::paper(), 0.0).is_err());
}

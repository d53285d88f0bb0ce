//! Tests of the structure-file analytical parts: the controller's command stream is the direct
//! stepping of the integrator (or the metamodel) bit for bit, and non-finite feedback is refused.

use proptest::prelude::*;

use super::*;
use crate::control::{
    Analytical, CompensatorTarget, ControlConfig, Controller, FeedbackSource, ForceCorrection,
    ReplaceError,
};
use crate::hal::{ErrorKind, Sample};
use crate::metamodel::{DeltaArx, DeltaArxParams, ModalHyst, ModalMode, DELTA_ARX_COEFFS};
use crate::model::{assemble, ModelSpec};
use crate::params::{Prototype, SpecimenScale, DT_S};
use crate::supervisor::{Limits, State};

/// A 3-story shear frame (masses 0.6/0.6/0.5 kN·s²/mm, stories 300/250/200 kN/mm), the specimen a
/// 100 kN/mm spring at DOF 0: whole K, numerical K (specimen taken off), damping, `M·ι`.
const MASS: [f64; 9] = [0.6, 0.0, 0.0, 0.0, 0.6, 0.0, 0.0, 0.0, 0.5];
const K_WHOLE: [f64; 9] = [
    550.0, -250.0, 0.0, -250.0, 450.0, -200.0, 0.0, -200.0, 200.0,
];
const K_NUM: [f64; 9] = [
    450.0, -250.0, 0.0, -250.0, 450.0, -200.0, 0.0, -200.0, 200.0,
];
const DAMPING: [f64; 9] = [1.1, -0.5, 0.0, -0.5, 0.9, -0.4, 0.0, -0.4, 0.4];
const GROUND_MASS: [f64; 3] = [0.6, 0.6, 0.5];
const K_SPECIMEN: f64 = 100.0;
/// Stories 1..3 yield at 3, 2.5, 1.5 kN (story 1 without the specimen: 200 kN/mm).
const LAWS: [StoryLawSpec; 3] = [
    StoryLawSpec {
        k0_kn_per_mm: 200.0,
        yield_force_kn: 3.0,
        post_yield_ratio: 0.05,
        bouc_wen: None,
    },
    StoryLawSpec {
        k0_kn_per_mm: 250.0,
        yield_force_kn: 2.5,
        post_yield_ratio: 0.05,
        bouc_wen: Some([2.0, 0.5, 0.5]),
    },
    StoryLawSpec {
        k0_kn_per_mm: 200.0,
        yield_force_kn: 1.5,
        post_yield_ratio: 0.05,
        bouc_wen: None,
    },
];
const ZERO: [f64; 9] = [0.0; 9];

fn linear_spec() -> StructureSpec<'static> {
    StructureSpec {
        dofs: 3,
        mass: &MASS,
        damping: &DAMPING,
        stiffness: &K_NUM,
        initial_stiffness: &K_WHOLE,
        ground_mass: &GROUND_MASS,
        specimen_dof: 0,
        laws: &[],
    }
}

fn yielding_spec() -> StructureSpec<'static> {
    StructureSpec {
        stiffness: &ZERO,
        laws: &LAWS,
        ..linear_spec()
    }
}

/// A two-mode, two-floor modal-hysteretic model with a bilinear and a Bouc–Wen spring that yield
/// at drifts of 5 µm: the ground motion below drives both well past it.
const MODES: [ModalMode; 2] = [
    ModalMode {
        omega_rad_s: 15.0,
        damping_ratio: 0.03,
        ground_participation: 1.0,
    },
    ModalMode {
        omega_rad_s: 40.0,
        damping_ratio: 0.05,
        ground_participation: 0.3,
    },
];
const MODAL_SHAPE: [f64; 4] = [0.8, 0.5, 1.0, -0.6];
const MODAL_LAWS: [StoryLawSpec; 2] = [
    StoryLawSpec {
        k0_kn_per_mm: 200.0,
        yield_force_kn: 1.0,
        post_yield_ratio: 0.05,
        bouc_wen: None,
    },
    StoryLawSpec {
        k0_kn_per_mm: 150.0,
        yield_force_kn: 0.75,
        post_yield_ratio: 0.05,
        bouc_wen: Some([2.0, 0.5, 0.5]),
    },
];
const MODAL_DRIFT: [f64; 4] = [0.8, 0.5, 0.2, -1.1];

fn modal_spec() -> ModalSpec<'static> {
    ModalSpec {
        modes: &MODES,
        shape: &MODAL_SHAPE,
        specimen_dof: 0,
        specimen_k_kn_per_mm: K_SPECIMEN,
        laws: &MODAL_LAWS,
        drift: &MODAL_DRIFT,
    }
}

fn theta() -> [f64; DELTA_ARX_COEFFS] {
    // A stable, arbitrary model: a small pull toward rest and small input gains.
    let mut t = [0.0; DELTA_ARX_COEFFS];
    t[0] = -1e-3;
    t[1] = 0.9;
    t[6] = -1e-7;
    t[12] = -1e-4;
    t[13] = 2e-4;
    t
}

fn ground(k: usize) -> f64 {
    let t = k as f64 * DT_S;
    500.0 * libm::sin(2.0 * core::f64::consts::PI * 2.1 * t) * (1.0 - libm::exp(-2.0 * t))
}

/// Prototype force = 1000 × load cell (the paper's scale): the structure's forces stay within the
/// load cell's range the supervisor checks.
fn scale() -> SpecimenScale {
    SpecimenScale::new(1.0, 1000.0).unwrap()
}

fn controller(spec: &ModelSpec<'_>) -> Controller {
    let cfg = ControlConfig::new(
        Prototype::paper(),
        scale(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let (a, comp) = assemble(spec, Prototype::paper(), DT_S).unwrap();
    let mut c = Controller::new(cfg, a, comp);
    c.supervisor_mut().arm().unwrap();
    c.supervisor_mut().start().unwrap();
    c
}

/// Run `spec` in the controller against a perfect actuator holding a linear specimen; the inputs
/// each tick saw (ü_g, x_m, F_m at prototype scale) and the targets.
fn run(spec: &ModelSpec<'_>, ticks: usize) -> (std::vec::Vec<[f64; 3]>, std::vec::Vec<f64>) {
    let mut c = controller(spec);
    let (mut inputs, mut targets) = (std::vec::Vec::new(), std::vec::Vec::new());
    for k in 0..ticks {
        let x = c.supervisor().output_mm();
        let s = Sample {
            disp_mm: x,
            force_kn: K_SPECIMEN * x / 1000.0,
        };
        let out = c.tick(ground(k), Ok(s), false);
        assert_eq!(out.state, State::Running, "tick {k}");
        // No compensator: the request is the target.
        assert_eq!(out.requested_mm.to_bits(), out.target_mm.to_bits());
        inputs.push([ground(k), s.disp_mm, scale().prototype_force_kn(s.force_kn)]);
        targets.push(out.target_mm);
    }
    (inputs, targets)
}

extern crate std;

#[test]
fn the_fe_variant_is_chang_bit_for_bit() {
    let (inputs, targets) = run(
        &ModelSpec::StructureFe {
            structure: linear_spec(),
        },
        4000,
    );
    let mut ch = crate::structure_n::ChangN::new(linear_spec().numerical().unwrap(), DT_S).unwrap();
    for (k, ([ag, _, f], t)) in inputs.iter().zip(&targets).enumerate() {
        if k == 0 {
            ch.reset(*ag);
        } else {
            let mut r = [0.0; MAX_DOF];
            r[0] = *f;
            ch.advance(*ag, &r);
        }
        assert_eq!(t.to_bits(), ch.next_displacement()[0].to_bits(), "tick {k}");
    }
    assert!(
        targets.iter().any(|t| t.abs() > 0.01),
        "the structure moved"
    );
}

#[test]
fn the_yielding_variant_is_the_nonlinear_frame_bit_for_bit() {
    let spec = yielding_spec();
    let (inputs, targets) = run(&ModelSpec::StructureNl { structure: spec }, 4000);
    let laws = spec.story_laws().unwrap();
    let mut nl = NonlinearFrame::new(spec.numerical().unwrap(), &laws[..3], DT_S).unwrap();
    let mut yielded = false;
    for (k, ([ag, _, f], t)) in inputs.iter().zip(&targets).enumerate() {
        if k == 0 {
            nl.reset(*ag);
        } else {
            let mut r = [0.0; MAX_DOF];
            r[0] = *f;
            nl.advance(*ag, &r);
        }
        assert_eq!(t.to_bits(), nl.next_displacement()[0].to_bits(), "tick {k}");
        yielded |= nl
            .story_force_kn()
            .iter()
            .zip(&LAWS)
            .any(|(f, l)| f.abs() > 0.9 * l.yield_force_kn);
    }
    assert!(yielded, "a story reached its yield force");
}

#[test]
fn the_metamodel_variant_is_the_delta_arx_bit_for_bit() {
    let th = theta();
    let (inputs, targets) = run(
        &ModelSpec::StructureMeta {
            theta: &th,
            k_corr_kn_per_mm: 50.0,
        },
        4000,
    );
    let mut m = DeltaArx::new(DeltaArxParams::from_slice(&th, 50.0).unwrap());
    for (k, ([ag, x, f], t)) in inputs.iter().zip(&targets).enumerate() {
        // The correction written out: F̃ = F_m + k_c·(d̂(k) − x_m).
        let d_k = m.current_mm();
        let y = m.step(*ag, f + 50.0 * (d_k - x)).unwrap();
        assert_eq!(t.to_bits(), y.to_bits(), "tick {k}");
    }
    assert!(targets.iter().any(|t| t.abs() > 1e-3), "the model moved");
}

#[test]
fn the_modal_variant_is_the_modal_hysteretic_model_bit_for_bit() {
    let spec = modal_spec();
    let (inputs, targets) = run(&ModelSpec::StructureModal { model: spec }, 4000);
    let mut m = ModalHyst::new(spec.params(DT_S).unwrap());
    let mut peak_drift: f64 = 0.0;
    for (k, ([ag, _, f], t)) in inputs.iter().zip(&targets).enumerate() {
        let y = if k == 0 {
            m.reset_at(*ag);
            m.target_mm()
        } else {
            m.step(*ag, *f).unwrap()
        };
        assert_eq!(t.to_bits(), y.to_bits(), "tick {k}");
        peak_drift = peak_drift.max(m.spring_drift_mm(0).abs());
    }
    // Spring 0 yields at 1/200 mm.
    assert!(peak_drift > 10.0 * 1.0 / 200.0, "peak drift {peak_drift}");
}

#[test]
fn a_modal_spec_runs_at_the_step_it_is_given_and_bad_ones_are_refused() {
    let spec = modal_spec();
    let at = |dt: f64| spec.params(dt).unwrap();
    assert_eq!(at(DT_S / 2.0).dt_s(), DT_S / 2.0);
    assert_eq!(at(DT_S).at_dt_s(DT_S / 2.0).unwrap(), at(DT_S / 2.0));
    assert!(at(DT_S).at_dt_s(0.0).is_err());
    assert!(ModalSpec { laws: &[], ..spec }.params(DT_S).is_err());
    let nine = [MODAL_LAWS[0]; 9];
    assert!(ModalSpec {
        laws: &nine,
        ..spec
    }
    .params(DT_S)
    .is_err());
    let bad_law = [StoryLawSpec {
        yield_force_kn: -1.0,
        ..MODAL_LAWS[0]
    }; 2];
    assert!(ModalSpec {
        laws: &bad_law,
        ..spec
    }
    .params(DT_S)
    .is_err());
    assert!(ModalSpec {
        drift: &MODAL_DRIFT[..3],
        ..spec
    }
    .params(DT_S)
    .is_err());
    assert!(ModalSpec {
        specimen_dof: 2,
        ..spec
    }
    .params(DT_S)
    .is_err());
}

#[test]
fn a_yielding_spec_is_not_a_linear_one_and_bad_specs_are_refused() {
    assert!(yielding_spec().linear(DT_S).is_err());
    assert!(linear_spec().yielding(DT_S).is_err());
    let beyond = StructureSpec {
        specimen_dof: 3,
        ..linear_spec()
    };
    assert!(beyond.linear(DT_S).is_err());
    // A DOF past the structure is the error whatever else is wrong (a step of 0 here), for both
    // FE parts.
    let dof_error = Err(ParamError::OutOfRange(
        "specimen DOF (beyond the structure)",
    ));
    let model = linear_spec().numerical().unwrap();
    assert_eq!(StructureFe::new(model, 3, 0.0).map(|_| ()), dof_error);
    let laws = yielding_spec().story_laws().unwrap();
    let frame = yielding_spec().numerical().unwrap();
    assert_eq!(
        StructureNl::build(frame, &laws, 3, DT_S).map(|_| ()),
        dof_error
    );
    let short = StructureSpec {
        mass: &MASS[..8],
        ..linear_spec()
    };
    assert!(short.numerical().is_err());
    let nan = [f64::NAN; 9];
    let bad = StructureSpec {
        damping: &nan,
        ..linear_spec()
    };
    assert!(bad.linear(DT_S).is_err());
    let bad_law = [StoryLawSpec {
        yield_force_kn: -1.0,
        ..LAWS[0]
    }; 3];
    let bad = StructureSpec {
        laws: &bad_law,
        ..yielding_spec()
    };
    assert!(bad.yielding(DT_S).is_err());
    assert!(DeltaArxParams::from_slice(&theta()[..17], 1.0).is_err());
    assert!(DeltaArxParams::from_slice(&theta(), f64::NAN).is_err());
    assert!(DeltaArxParams::from_slice(&theta(), -1.0).is_err());
    let mut th = theta();
    th[3] = f64::INFINITY;
    assert!(DeltaArxParams::from_slice(&th, 1.0).is_err());
}

#[test]
fn a_law_round_trips_through_its_raw_form() {
    for l in LAWS {
        let law = l.validate().unwrap();
        assert_eq!(StoryLawSpec::of(&law), l);
    }
}

/// A value that is sometimes NaN or infinite.
fn maybe_bad(x: f64, pick: u8) -> f64 {
    match pick % 8 {
        0 => f64::NAN,
        1 => f64::INFINITY,
        _ => x,
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// NaN or infinite feedback or ground acceleration gives a safe refusal (a held sample, a
    /// step error, the supervisor's trip), never a panic, and a finite command; the parts
    /// themselves refuse it with their state untouched.
    #[test]
    fn non_finite_feedback_is_refused_never_a_panic(
        which in 0u8..4,
        picks in proptest::collection::vec((any::<u8>(), any::<u8>(), any::<u8>(), -5.0f64..5.0), 1..200),
    ) {
        let th = theta();
        let spec = match which {
            0 => ModelSpec::StructureFe { structure: linear_spec() },
            1 => ModelSpec::StructureNl { structure: yielding_spec() },
            2 => ModelSpec::StructureModal { model: modal_spec() },
            _ => ModelSpec::StructureMeta { theta: &th, k_corr_kn_per_mm: 50.0 },
        };
        let mut c = controller(&spec);
        for (k, (pa, px, pf, x)) in picks.iter().enumerate() {
            let s: Result<Sample, ErrorKind> = Ok(Sample {
                disp_mm: maybe_bad(*x, *px),
                force_kn: maybe_bad(K_SPECIMEN * x / 1000.0, *pf),
            });
            let out = c.tick(maybe_bad(ground(k), *pa), s, false);
            prop_assert!(out.command_mm.is_finite());
        }
        // The parts refuse directly, state untouched.
        let (mut a, _) = assemble(&spec, Prototype::paper(), DT_S).unwrap();
        let before = a.clone();
        let r = match &mut a {
            Analytical::StructureFe(m) => m.next_target(f64::NAN, 1.0).map(|_| ()),
            Analytical::StructureNl(m) => m.next_target(1.0, f64::NAN).map(|_| ()),
            Analytical::StructureModal(m) => m.next_target(f64::INFINITY, 1.0).map(|_| ()),
            Analytical::StructureMeta(m) => m.predict(1.0, 0.0, f64::INFINITY).map(|_| ()).map_err(|_| super::super::StepError::NonFiniteOutput),
            _ => Ok(()),
        };
        prop_assert!(r.is_err());
        prop_assert_eq!(a, before);
    }
}

#[test]
fn validated_models_assemble_the_same_parts() {
    let th = theta();
    for spec in [
        ModelSpec::StructureFe {
            structure: linear_spec(),
        },
        ModelSpec::StructureNl {
            structure: yielding_spec(),
        },
        ModelSpec::StructureMeta {
            theta: &th,
            k_corr_kn_per_mm: 50.0,
        },
        ModelSpec::StructureModal {
            model: modal_spec(),
        },
    ] {
        let direct = assemble(&spec, Prototype::paper(), DT_S).unwrap();
        let via_model = spec
            .validate()
            .unwrap()
            .assemble(Prototype::paper(), DT_S)
            .unwrap();
        assert_eq!(direct, via_model);
    }
    let bad = ModelSpec::StructureFe {
        structure: yielding_spec(),
    };
    assert!(bad.validate().is_err());
}

#[test]
fn a_structure_part_takes_the_rig_s_compensation_and_is_named_by_it() {
    use crate::compensator::LeadParams;
    let lead = LeadParams::new([1.2, -0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0], 2).unwrap();
    let correction = ForceCorrection::new(0.05, 1e-4, 1e-6, DT_S).unwrap();
    let rig_scale = SpecimenScale::new(2.0, 1500.0).unwrap();
    // Not a structure part: refused, nothing changes.
    let cfg = ControlConfig::new(
        Prototype::paper(),
        scale(),
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .unwrap();
    let (a, comp) = assemble(
        &ModelSpec::FeAts {
            expected_delay_s: 0.0137,
        },
        Prototype::paper(),
        DT_S,
    )
    .unwrap();
    let mut fe = Controller::new(cfg, a, comp);
    assert_eq!(
        fe.set_structure_rig(lead, correction, rig_scale),
        Err(ReplaceError::Kind)
    );
    assert_eq!(fe.scenario_name(), ("fe-online-ats", None));
    for (spec, uncompensated, compensated) in [
        (
            ModelSpec::StructureModal {
                model: modal_spec(),
            },
            "structure-modal",
            "nl-online",
        ),
        (
            ModelSpec::StructureMeta {
                theta: &theta(),
                k_corr_kn_per_mm: K_SPECIMEN,
            },
            "structure-meta",
            "meta-online",
        ),
        (
            ModelSpec::StructureFe {
                structure: linear_spec(),
            },
            "structure-fe",
            "fe-online-lead",
        ),
    ] {
        let mut c = controller(&spec);
        assert_eq!(c.scenario_name(), (uncompensated, None));
        // Under a test: refused.
        assert!(matches!(
            c.set_structure_rig(lead, correction, rig_scale),
            Err(ReplaceError::Busy(_))
        ));
        c.supervisor_mut().abort();
        for k in 0..200 {
            let x = c.supervisor().output_mm();
            c.tick(
                ground(k),
                Ok(Sample {
                    disp_mm: x,
                    force_kn: 0.0,
                }),
                false,
            );
        }
        assert!(c.supervisor().at_rest());
        c.set_structure_rig(lead, correction, rig_scale).unwrap();
        assert_eq!(c.scenario_name(), (compensated, None));
        assert_eq!(c.config().force_correction(), Some(&correction));
        assert_eq!(c.config().compensator_target(), CompensatorTarget::Current);
        assert_eq!(c.config().scale(), &rig_scale);
        assert_eq!(c.supervisor().state(), State::Idle);
        // A new part starts from the controller's own configuration: no correction, the next
        // target, its scale.
        crate::model::assemble_in(&mut c, &spec, Prototype::paper(), DT_S).unwrap();
        assert_eq!(c.scenario_name(), (uncompensated, None));
        assert_eq!(c.config().force_correction(), None);
        assert_eq!(c.config().compensator_target(), CompensatorTarget::Next);
        assert_eq!(c.config().scale(), &scale());
    }
}

/// The controller's read-outs of a structure part (`Analytical::interface_disp_mm`,
/// `Analytical::output_disp_mm`: what a study's history records) are the part's own state after
/// every tick: the FE parts' DOFs, the modal-hysteretic model's floors, the reduced model's
/// interface and outputs; a part without them gives none.
#[test]
fn the_read_outs_are_the_part_s_own_state_after_every_tick() {
    let reduced_modes = [
        crate::metamodel::ReducedMode {
            omega_rad_s: 15.0,
            damping_ratio: 0.02,
            ground_participation: 1.1,
            interface_shape: 0.7,
        },
        crate::metamodel::ReducedMode {
            omega_rad_s: 70.0,
            damping_ratio: 0.04,
            ground_participation: -0.2,
            interface_shape: 0.4,
        },
    ];
    let reduced_statics = [
        crate::metamodel::StaticCorrection {
            ground_mm_per_mm_s2: 2e-6,
            force_mm_per_kn: 1e-4,
        },
        crate::metamodel::StaticCorrection {
            ground_mm_per_mm_s2: -1e-6,
            force_mm_per_kn: 2e-5,
        },
    ];
    let reduced = ReducedSpec {
        modes: &reduced_modes,
        output_shape: &[0.3, -0.1, 0.9, 0.2],
        interface_static: crate::metamodel::StaticCorrection {
            ground_mm_per_mm_s2: 1e-6,
            force_mm_per_kn: 1e-4,
        },
        output_static: &reduced_statics,
        specimen_k_kn_per_mm: 5.0,
    };
    let th = theta();
    let specs = [
        ModelSpec::StructureFe {
            structure: linear_spec(),
        },
        ModelSpec::StructureNl {
            structure: yielding_spec(),
        },
        ModelSpec::StructureModal {
            model: modal_spec(),
        },
        ModelSpec::StructureReduced { model: reduced },
        ModelSpec::StructureMeta {
            theta: &th,
            k_corr_kn_per_mm: 50.0,
        },
    ];
    for spec in &specs {
        let mut c = controller(spec);
        for k in 0..2000 {
            let x = c.supervisor().output_mm();
            let s = Sample {
                disp_mm: x,
                force_kn: K_SPECIMEN * x / 1000.0,
            };
            c.tick(ground(k), Ok(s), false);
            let a = c.analytical();
            let n = a.output_count();
            let outs: std::vec::Vec<Option<f64>> = (0..=n).map(|i| a.output_disp_mm(i)).collect();
            assert_eq!(outs[n], None, "past the read-outs");
            let (iface, want): (Option<f64>, std::vec::Vec<f64>) = match a {
                Analytical::StructureFe(m) => {
                    (Some(m.chang().disp()[0]), m.chang().disp()[..3].to_vec())
                }
                Analytical::StructureNl(m) => (
                    Some(m.frame().chang().disp()[0]),
                    m.frame().chang().disp()[..3].to_vec(),
                ),
                Analytical::StructureModal(m) => (
                    Some(m.model().floor_disp_mm(0)),
                    (0..2).map(|i| m.model().floor_disp_mm(i)).collect(),
                ),
                Analytical::StructureReduced(m) => (
                    Some(m.model().interface_mm()),
                    (0..2).map(|i| m.model().output_mm(i)).collect(),
                ),
                _ => (None, std::vec::Vec::new()),
            };
            assert_eq!(
                a.interface_disp_mm().map(f64::to_bits),
                iface.map(f64::to_bits)
            );
            let got: std::vec::Vec<u64> = outs[..n].iter().map(|o| o.unwrap().to_bits()).collect();
            let want: std::vec::Vec<u64> = want.iter().map(|w| w.to_bits()).collect();
            assert_eq!(got, want, "tick {k}");
        }
        if !matches!(spec, ModelSpec::StructureMeta { .. }) {
            assert!(
                c.analytical().interface_disp_mm().unwrap().abs() > 0.0,
                "the structure moved"
            );
        }
    }
}

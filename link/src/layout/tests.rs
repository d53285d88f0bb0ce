//! Tests of [`crate::layout`]: every kind read back as laid out, bit for bit; values that are no
//! model of their kind refused; arbitrary values never panic.

extern crate std;
use std::{vec, vec::Vec};

use super::*;
use proptest::prelude::*;

const KINDS: [ModelKind; 10] = [
    ModelKind::Lr,
    ModelKind::Lrx,
    ModelKind::Rnn,
    ModelKind::FeAts,
    ModelKind::StructureFe,
    ModelKind::StructureNl,
    ModelKind::StructureMeta,
    ModelKind::StructureModal,
    ModelKind::StructureReduced,
    ModelKind::StructureHysteron,
];

/// Distinct values for every slot: a value in the wrong place shows.
fn ramp(n: usize, at: f64) -> Vec<f64> {
    (0..n).map(|i| at + i as f64 * 0.125).collect()
}

fn bilinear(k0: f64) -> StoryLawSpec {
    StoryLawSpec {
        k0_kn_per_mm: k0,
        yield_force_kn: 10.0,
        post_yield_ratio: 0.05,
        bouc_wen: None,
    }
}

fn bouc_wen(k0: f64) -> StoryLawSpec {
    StoryLawSpec {
        bouc_wen: Some([2.0, 0.5, 0.5]),
        ..bilinear(k0)
    }
}

/// Lay `spec` out, read it back and lay that out again: the same kind and values, bit for bit,
/// and the spec read back equal to the one laid out.
fn round_trip(spec: &ModelSpec<'_>) -> (ModelKind, Vec<f64>) {
    let mut out = vec![0.0; MODEL_MAX_VALUES];
    let (kind, n) = lay_out(spec, &mut out).unwrap();
    let v = out[..n].to_vec();
    let again = with_spec(kind, &v, |back| {
        assert_eq!(back, spec, "{kind:?}");
        let mut o = vec![0.0; MODEL_MAX_VALUES];
        let (k, m) = lay_out(back, &mut o).unwrap();
        (k, o[..m].to_vec())
    })
    .unwrap();
    assert_eq!(again.0, kind);
    assert_eq!(
        again.1.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        "{kind:?}"
    );
    (kind, v)
}

#[test]
fn every_kind_reads_back_as_laid_out() {
    let theta = ramp(6, 0.5);
    assert_eq!(round_trip(&ModelSpec::Lr { theta: &theta }).1.len(), 6);
    let coeffs = ramp(9, 1.0);
    let lead = ramp(8, -1.0);
    let (_, v) = round_trip(&ModelSpec::Lrx {
        coeffs: &coeffs,
        k_corr_kn_per_mm: 12.0,
        k_adapt_ticks: 2048.0,
        lead_weights: &lead,
        lead_stride: 3,
        lead_adapt_ticks: 0.0,
        specimen_dynamics: [0.0, 0.0],
    });
    assert_eq!(
        v,
        lrx_values(&coeffs, 12.0, 2048.0, &lead, 3)
            .unwrap()
            .to_vec()
    );
    let h = 3;
    let (w_ih, w_hh, b_h, w_ho) = (
        ramp(2 * h, 0.0),
        ramp(h * h, 1.0),
        ramp(h, 2.0),
        ramp(h, 3.0),
    );
    let (kind, v) = round_trip(&ModelSpec::Rnn {
        weights: RnnWeights {
            w_ih: &w_ih,
            w_hh: &w_hh,
            b_h: &b_h,
            w_ho: &w_ho,
            b_o: 0.25,
        },
        scaling: RnnScaling {
            input_mean: [1.0, 2.0],
            input_std: [3.0, 4.0],
            output_mean: 5.0,
            output_std: 6.0,
        },
    });
    assert_eq!((kind, v.len()), (ModelKind::Rnn, rnn_value_count(h)));
    assert_eq!(
        round_trip(&ModelSpec::FeAts {
            expected_delay_s: 0.0137
        })
        .1,
        vec![0.0137]
    );
    let n = 3;
    let (m, c, k, k0, gm) = (
        ramp(n * n, 1.0),
        ramp(n * n, 2.0),
        ramp(n * n, 3.0),
        ramp(n * n, 4.0),
        ramp(n, 5.0),
    );
    let linear = StructureSpec {
        dofs: n,
        mass: &m,
        damping: &c,
        stiffness: &k,
        initial_stiffness: &k0,
        ground_mass: &gm,
        specimen_dof: 1,
        laws: &[],
    };
    let (kind, v) = round_trip(&ModelSpec::StructureFe { structure: linear });
    assert_eq!(
        (kind, v.len()),
        (ModelKind::StructureFe, structure_value_count(3, 0))
    );
    let laws = [bilinear(50.0), bouc_wen(40.0), bilinear(30.0)];
    let (kind, v) = round_trip(&ModelSpec::StructureNl {
        structure: StructureSpec {
            laws: &laws,
            ..linear
        },
    });
    assert_eq!(
        (kind, v.len()),
        (ModelKind::StructureNl, structure_value_count(3, 3))
    );
    let d = dims(kind, &v).unwrap();
    assert_eq!((d.dofs, d.springs, d.bouc_wen), (3, 3, 1));
    let theta = ramp(DELTA_ARX_COEFFS, 0.0);
    assert_eq!(
        round_trip(&ModelSpec::StructureMeta {
            theta: &theta,
            k_corr_kn_per_mm: 7.0
        })
        .1
        .len(),
        STRUCTURE_META_VALUES
    );
    let modes = [
        ModalMode {
            omega_rad_s: 20.0,
            damping_ratio: 0.02,
            ground_participation: 1.5,
        },
        ModalMode {
            omega_rad_s: 55.0,
            damping_ratio: 0.03,
            ground_participation: -0.5,
        },
    ];
    let (shape, drift) = (ramp(3 * 2, 0.1), ramp(2 * 2, -0.2));
    let springs = [bouc_wen(20.0), bilinear(25.0)];
    let (kind, v) = round_trip(&ModelSpec::StructureModal {
        model: ModalSpec {
            modes: &modes,
            shape: &shape,
            specimen_dof: 2,
            specimen_k_kn_per_mm: 8.0,
            laws: &springs,
            drift: &drift,
        },
    });
    assert_eq!(
        (kind, v.len()),
        (ModelKind::StructureModal, modal_value_count(2, 3, 2))
    );
    let d = dims(kind, &v).unwrap();
    assert_eq!((d.modes, d.dofs, d.springs, d.bouc_wen), (2, 3, 2, 1));
    let rmodes = [
        ReducedMode {
            omega_rad_s: 10.0,
            damping_ratio: 0.05,
            ground_participation: 1.0,
            interface_shape: 0.5,
        },
        ReducedMode {
            omega_rad_s: 30.0,
            damping_ratio: 0.05,
            ground_participation: 0.1,
            interface_shape: -0.25,
        },
        ReducedMode {
            omega_rad_s: 90.0,
            damping_ratio: 0.06,
            ground_participation: 0.01,
            interface_shape: 0.125,
        },
    ];
    let out_shape = ramp(2 * 3, 0.3);
    let statics = [
        StaticCorrection {
            ground_mm_per_mm_s2: 1e-6,
            force_mm_per_kn: 1e-3,
        },
        StaticCorrection {
            ground_mm_per_mm_s2: -2e-6,
            force_mm_per_kn: 3e-3,
        },
    ];
    let (kind, v) = round_trip(&ModelSpec::StructureReduced {
        model: ReducedSpec {
            modes: &rmodes,
            output_shape: &out_shape,
            interface_static: StaticCorrection {
                ground_mm_per_mm_s2: 4e-6,
                force_mm_per_kn: 5e-3,
            },
            output_static: &statics,
            specimen_k_kn_per_mm: 50.0,
        },
    });
    assert_eq!(
        (kind, v.len()),
        (ModelKind::StructureReduced, reduced_value_count(3, 2))
    );
    assert_eq!(
        lay_out(&ModelSpec::Fe, &mut [0.0; 4]),
        Err(LayoutError::Kind)
    );
}

/// A floor-hysteron spec of 2 floors, 3 directions and 4 hysterons with the operator `op`.
fn hysteron_round_trip(op: rths_core::metamodel::HysteronOperator) -> (ModelKind, Vec<f64>) {
    let (m, c, k, g) = (
        [1e-3, 0.0, 0.0, 1.5e-3],
        [0.01, -0.002, -0.002, 0.02],
        [300.0, -100.0, -100.0, 100.0],
        [1e-3, 1.5e-3],
    );
    let dirs = [1.0, 0.0, -1.0, 1.0, 0.0, 1.0];
    let hyst = [0.0, 1.0, 5.0, 1.0, 2.0, 4.0, 2.0, 3.0, 3.0, 0.0, 6.0, 2.0];
    round_trip(&ModelSpec::StructureHysteron {
        model: FloorHysteronSpec {
            floors: FloorStructure {
                floors: 2,
                mass: &m,
                damping: &c,
                stiffness: &k,
                ground_mass: &g,
                specimen_floor: 1,
                specimen_k_kn_per_mm: 50.0,
            },
            directions: &dirs,
            hysterons: &hyst,
            operator: op,
        },
    })
}

#[test]
fn a_floor_hysteron_model_reads_back_as_laid_out_with_either_operator() {
    use rths_core::metamodel::HysteronOperator;
    let (kind, v) = hysteron_round_trip(HysteronOperator::Play);
    assert_eq!(
        (kind, v.len()),
        (ModelKind::StructureHysteron, hysteron_value_count(2, 3, 4))
    );
    let d = dims(kind, &v).unwrap();
    assert_eq!(
        (d.dofs, d.directions, d.hysterons, d.bouc_wen),
        (2, 3, 4, 0)
    );
    let mp = MpShape::new(20.0, 0.925, 0.15).unwrap();
    let (kind, v) = hysteron_round_trip(HysteronOperator::MenegottoPinto(mp));
    assert_eq!(kind, ModelKind::StructureHysteron);
    assert_eq!(dims(kind, &v).unwrap().bouc_wen, 4);
    // The operator's flag whole, the play's shape values 0, and a Menegotto–Pinto shape in range.
    let mut w = v.clone();
    w[5] = 0.5;
    assert_eq!(dims(kind, &w), Err(LayoutError::Value));
    w[5] = 0.0;
    assert_eq!(dims(kind, &w), Err(LayoutError::Value));
    let mut w = v.clone();
    w[6] = 1e9;
    assert_eq!(dims(kind, &w), Err(LayoutError::Value));
    // Sizes that disagree with the count; a specimen past the floors.
    let mut w = v.clone();
    w[2] = 5.0;
    assert_eq!(dims(kind, &w), Err(LayoutError::Shape));
    let mut w = v;
    w[3] = 2.0;
    assert_eq!(dims(kind, &w), Err(LayoutError::Shape));
}

#[test]
fn the_staging_area_holds_the_largest_model_of_every_kind() {
    let largest = [
        ("RNN-32", rnn_value_count(RNN_UPLOAD_MAX_HIDDEN)),
        (
            "FE yielding, N = 8",
            structure_value_count(MAX_DOF, MAX_DOF),
        ),
        (
            "modal, 8 modes, 8 floors, 8 springs",
            modal_value_count(MODAL_MAX_MODES, MODAL_MAX_FLOORS, MODAL_MAX_SPRINGS),
        ),
        (
            "reduced, 32 modes, 16 outputs",
            reduced_value_count(REDUCED_MAX_MODES, REDUCED_MAX_OUTPUTS),
        ),
        (
            "floor-hysteron, 8 floors, 16 directions, 64 hysterons",
            hysteron_value_count(MAX_DOF, HYST_MAX_DIRECTIONS, HYST_MAX_HYSTERONS),
        ),
    ];
    for (what, n) in largest {
        std::println!("{what}: {n} values, {} bytes", 8 * n);
        assert!(n <= MODEL_MAX_VALUES, "{what}");
    }
    assert_eq!(MODEL_MAX_VALUES, 1159);
    assert!(
        MODEL_MAX_VALUES <= usize::from(u16::MAX),
        "ModelBegin's count"
    );
    assert!(
        RIG_UPLOAD_MAX_VALUES <= usize::from(u8::MAX),
        "RigBegin's count"
    );
}

#[test]
fn values_that_are_no_model_of_their_kind_are_refused() {
    // Counts no model of the kind has.
    for (kind, n) in [
        (ModelKind::Lr, 5),
        (ModelKind::Lrx, 19),
        (ModelKind::Rnn, 146),
        (ModelKind::Rnn, rnn_value_count(33)),
        (ModelKind::FeAts, 2),
        (ModelKind::StructureFe, structure_value_count(3, 0) + 1),
        (ModelKind::StructureFe, structure_value_count(9, 0)),
        (ModelKind::StructureNl, structure_value_count(2, 0)),
        (ModelKind::StructureMeta, 18),
        (ModelKind::StructureModal, 3),
        (ModelKind::StructureReduced, reduced_value_count(33, 16)),
        (
            ModelKind::StructureHysteron,
            hysteron_value_count(1, 1, 1) - 1,
        ),
        (
            ModelKind::StructureHysteron,
            hysteron_value_count(8, 16, 65),
        ),
    ] {
        assert_eq!(count_fits(kind, n), Err(LayoutError::Shape), "{kind:?} {n}");
        assert_eq!(
            dims(kind, &vec![1.0; n]),
            Err(LayoutError::Shape),
            "{kind:?} {n}"
        );
        assert!(with_spec(kind, &vec![1.0; n], |_| ()).is_err(), "{kind:?}");
    }
    // A header that disagrees with the count, or with the kind.
    let n = structure_value_count(2, 0);
    let mut v = vec![0.5; n];
    v[..3].copy_from_slice(&[2.0, 0.0, 0.0]);
    assert!(dims(ModelKind::StructureFe, &v).is_ok());
    v[1] = 2.0; // the specimen's DOF past the structure
    assert_eq!(dims(ModelKind::StructureFe, &v), Err(LayoutError::Shape));
    v[1] = 0.5; // not a whole number
    assert_eq!(dims(ModelKind::StructureFe, &v), Err(LayoutError::Shape));
    v[1] = 0.0;
    v[2] = 2.0; // laws on a linear structure
    assert_eq!(dims(ModelKind::StructureFe, &v), Err(LayoutError::Shape));
    let mut r = vec![0.5; reduced_value_count(2, 1)];
    r[..2].copy_from_slice(&[2.0, 1.0]);
    assert!(dims(ModelKind::StructureReduced, &r).is_ok());
    r[1] = 2.0; // two outputs announced, one laid out
    assert_eq!(
        dims(ModelKind::StructureReduced, &r),
        Err(LayoutError::Shape)
    );
    // A stride or a law's flag that is not a whole number in its range.
    let mut lrx = lrx_values(&[0.0; 9], 1.0, 0.0, &[0.0; 8], 2).unwrap();
    lrx[19] = 2.5;
    assert_eq!(
        with_spec(ModelKind::Lrx, &lrx, |_| ()),
        Err(LayoutError::Value)
    );
    lrx[19] = 65.0;
    assert_eq!(
        with_spec(ModelKind::Lrx, &lrx, |_| ()),
        Err(LayoutError::Value)
    );
    let mut nl = vec![1.0; structure_value_count(1, 1)];
    nl[..3].copy_from_slice(&[1.0, 0.0, 1.0]);
    assert!(with_spec(ModelKind::StructureNl, &nl, |_| ()).is_ok());
    nl[3 + 4 + 1 + 3] = 0.5; // the Bouc–Wen flag
    assert_eq!(
        with_spec(ModelKind::StructureNl, &nl, |_| ()),
        Err(LayoutError::Value)
    );
}

#[test]
fn a_structure_rig_compensation_has_its_layout() {
    let lead: [f64; 8] = core::array::from_fn(|i| 1.0 + i as f64);
    let v = structure_rig_values(&lead, 3, 4096.0, [0.05, 1e-4, 1e-6], [2.0, 1500.0]).unwrap();
    assert_eq!(&v[..8], &lead);
    assert_eq!(&v[8..], &[3.0, 4096.0, 0.05, 1e-4, 1e-6, 2.0, 1500.0]);
    assert!(structure_rig_values(&lead[..7], 3, 0.0, [0.0; 3], [1.0; 2]).is_none());
    for kind in KINDS {
        let n = rig_value_count(kind);
        assert!(n.is_none_or(|n| n <= RIG_UPLOAD_MAX_VALUES), "{kind:?}");
    }
    assert_eq!(
        rig_value_count(ModelKind::StructureModal),
        Some(STRUCTURE_RIG_VALUES)
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]
    /// Arbitrary values of any count, for any kind, never panic the reader: they are a spec or a
    /// refusal, and a spec's values lay out again to the same count.
    #[test]
    fn arbitrary_values_never_panic_the_reader(
        k in 0usize..KINDS.len(),
        head in prop::collection::vec(0.0f64..40.0, 0..6),
        tail in prop::collection::vec(any::<f64>(), 0..700),
    ) {
        let kind = KINDS[k];
        let v: Vec<f64> = head.iter().map(|x| x.floor()).chain(tail).collect();
        let _ = dims(kind, &v);
        if let Ok(n) = with_spec(kind, &v, |spec| {
            let mut out = vec![0.0; MODEL_MAX_VALUES];
            lay_out(spec, &mut out).map(|(_, n)| n)
        }) {
            prop_assert_eq!(n, Ok(v.len()));
        }
    }
}

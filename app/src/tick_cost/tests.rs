use super::*;
use rths_link::layout::Dims;

const M4_2048: TickBudget = TickBudget::cortex_m4_168mhz(2048.0);
const M7_4096: TickBudget = TickBudget::cortex_m7_480mhz(4096.0);

#[test]
fn the_rnn_estimate_reproduces_the_measured_rnn_10_within_a_quarter_percent() {
    // The budget's RNN-10 rows: 56,768 (M4) and 2,445 (M7) instructions per tick max.
    assert!((M4_2048.rnn_instr(10) - 56_768.0).abs() / 56_768.0 < 0.0025);
    assert!((M7_4096.rnn_instr(10) - 2_445.0).abs() / 2_445.0 < 0.015);
    assert!(
        M4_2048.rnn_instr(10) >= 56_768.0,
        "rounded up: never below the measurement"
    );
}

#[test]
fn rnn_10_does_not_fit_the_m4_at_2048_hz_and_fits_the_m7_at_4096_hz() {
    let pct = M4_2048.pct_of_tick(ModelKind::Rnn, 10);
    assert!((103.0..105.0).contains(&pct), "{pct}");
    assert!(!M4_2048.fits(ModelKind::Rnn, 10));
    assert!(
        M4_2048.fits(ModelKind::Rnn, 9),
        "{}",
        M4_2048.pct_of_tick(ModelKind::Rnn, 9)
    );
    assert!(M7_4096.fits(ModelKind::Rnn, 10));
    assert!(M7_4096.fits(ModelKind::Rnn, rths_link::RNN_UPLOAD_MAX_HIDDEN));
}

#[test]
fn fe_ats_fits_the_m4_at_2048_hz_but_not_at_4096_hz() {
    assert!(M4_2048.fits(ModelKind::FeAts, 0));
    let m4_4096 = TickBudget {
        rate_hz: 4096.0,
        ..M4_2048
    };
    // The budget's 4096 Hz M4 FE + ATS row: 114 % of the tick.
    let pct = m4_4096.pct_of_tick(ModelKind::FeAts, 0);
    assert!((113.0..115.0).contains(&pct), "{pct}");
    assert!(!m4_4096.fits(ModelKind::FeAts, 0));
    for kind in [ModelKind::Lr, ModelKind::Lrx] {
        assert!(m4_4096.fits(kind, 0));
    }
}

#[test]
fn the_link_s_rnn_limit_is_the_controller_s_capacity() {
    assert_eq!(
        rths_link::RNN_UPLOAD_MAX_HIDDEN,
        rths_core::metamodel::RNN_MAX_HIDDEN
    );
}

/// The structure budget's measured rows (`budget.sh`: the M7 at 4096 Hz, the M4 at 2048 Hz): kind,
/// N (DOFs or floors), modes, springs (yielding stories or latent springs), Bouc–Wen laws, and the
/// measured max instructions per tick on the M7 and the M4.
const STRUCTURE_ROWS: [(ModelKind, usize, usize, usize, usize, f64, f64); 15] = [
    (ModelKind::StructureFe, 1, 0, 0, 0, 830.0, 3_226.0),
    (ModelKind::StructureFe, 3, 0, 0, 0, 1_145.0, 13_000.0),
    (ModelKind::StructureFe, 8, 0, 0, 0, 2_590.0, 65_726.0),
    (ModelKind::StructureNl, 1, 0, 1, 0, 935.0, 4_458.0),
    (ModelKind::StructureNl, 3, 0, 3, 3, 1_750.0, 24_393.0),
    (ModelKind::StructureNl, 8, 0, 8, 0, 3_160.0, 75_220.0),
    (ModelKind::StructureMeta, 1, 0, 0, 0, 730.0, 10_583.0),
    (ModelKind::StructureMeta, 3, 0, 0, 0, 730.0, 10_482.0),
    (ModelKind::StructureMeta, 8, 0, 0, 0, 735.0, 10_482.0),
    (ModelKind::StructureModal, 1, 1, 1, 0, 870.0, 4_982.0),
    (ModelKind::StructureModal, 3, 3, 3, 3, 1_585.0, 22_869.0),
    (ModelKind::StructureModal, 8, 8, 8, 0, 2_485.0, 52_565.0),
    (ModelKind::StructureReduced, 0, 2, 0, 0, 2_055.0, 6_845.0),
    (ModelKind::StructureReduced, 0, 9, 0, 0, 2_400.0, 19_982.0),
    (ModelKind::StructureReduced, 0, 32, 0, 0, 3_455.0, 63_060.0),
];

#[test]
fn the_structure_estimates_are_never_below_a_measured_row_and_close_to_it() {
    let m4 = TickBudget::cortex_m4_168mhz(2048.0);
    let m7 = TickBudget::cortex_m7_480mhz(4096.0);
    for (kind, n, modes, springs, bouc_wen, on_m7, on_m4) in STRUCTURE_ROWS {
        let d = Dims {
            dofs: n,
            modes,
            springs,
            bouc_wen,
            ..Dims::default()
        };
        for (b, measured) in [(&m7, on_m7), (&m4, on_m4)] {
            let est = b.instr_dims(kind, &d);
            assert!(
                est >= measured && est <= 1.1 * measured,
                "{kind:?} {d:?}: estimated {est}, measured {measured}"
            );
        }
    }
    // Every structure part fits the M7's 4096 Hz tick with its rig compensation (the largest, the
    // reduced model of 32 modes, ~5 %); on the M4 at 2048 Hz the 8-DOF FE (120 %) does not.
    let reduced = Dims {
        modes: 32,
        ..Dims::default()
    };
    let pct =
        100.0 * m7.instr_with_rig(ModelKind::StructureReduced, &reduced) / m7.instr_per_tick();
    assert!(pct < 10.0, "{pct}");
    let fe8 = Dims {
        dofs: 8,
        ..Dims::default()
    };
    assert!(!m4.fits_dims(ModelKind::StructureFe, &fe8));
    assert!(m4.fits_dims(
        ModelKind::StructureFe,
        &Dims {
            dofs: 3,
            ..Dims::default()
        }
    ));
}

#[test]
fn the_floor_hysteron_estimate_is_its_measured_m7_row_and_the_m4_refuses_it() {
    let k = ModelKind::StructureHysteron;
    let dims = |directions, hysterons, mp| Dims {
        dofs: 3,
        directions,
        hysterons,
        bouc_wen: mp,
        ..Dims::default()
    };
    // The measured rows, 3 floors, nl-online on the M7: 6 directions and 6 plays 2,810 max; 6
    // directions and 6 Menegotto–Pinto plays 6,105 max; 3 directions and 4 of them 4,690 max.
    // The estimate is the first and covers the others.
    assert_eq!(M7_4096.instr_with_rig(k, &dims(6, 6, 0)), 2_810.0);
    for (d, h, measured) in [(6, 6, 6_105.0), (3, 4, 4_690.0)] {
        let est = M7_4096.instr_with_rig(k, &dims(d, h, h));
        assert!((measured..measured * 1.06).contains(&est), "{d} {h}: {est}");
    }
    let (play, mp) = (
        M7_4096.instr_dims(k, &dims(6, 18, 0)),
        M7_4096.instr_dims(k, &dims(6, 18, 18)),
    );
    assert!(2_810.0 < play && play < mp, "{play} {mp}");
    assert!(M7_4096.fits_dims(k, &dims(6, 18, 0)));
    // Not measured on the M4: refused.
    assert!(!M4_2048.fits_dims(k, &dims(1, 1, 0)));
}

#[test]
fn the_hysterons_a_learned_model_may_keep_stay_within_the_share() {
    let share = LEARNED_TICK_SHARE;
    let tick = M7_4096.instr_per_tick();
    for (d, mp) in [(3, true), (3, false), (6, true)] {
        let h = M7_4096.max_hysterons(3, d, mp, share);
        assert!(h >= 1, "{d} {mp}");
        let est = |h: usize| {
            M7_4096.instr_with_rig(
                ModelKind::StructureHysteron,
                &Dims {
                    dofs: 3,
                    directions: d,
                    hysterons: h,
                    bouc_wen: if mp { h } else { 0 },
                    ..Dims::default()
                },
            )
        };
        assert!(est(h) <= share * tick);
        assert!(h == 64 || est(h + 1) > share * tick);
    }
    // The fiber frame's 3 floors and 3 directions: 8 Menegotto–Pinto plays at 4096 Hz.
    assert_eq!(M7_4096.max_hysterons(3, 3, true, share), 8);
    // Not measured on the M4: none.
    assert_eq!(M4_2048.max_hysterons(3, 3, true, share), 0);
}

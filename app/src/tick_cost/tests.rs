use super::*;

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

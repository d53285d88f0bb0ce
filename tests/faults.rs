//! The fault-injection matrix (`rths faults`): every row must pass, and the command runs it.
#![cfg(feature = "sim")]

use rths::studies::faults;

#[test]
fn every_fault_case_passes() {
    let m = faults::run_matrix().unwrap();
    println!("{}", m.to_markdown());
    assert!(m.cases.len() >= 60, "{} cases", m.cases.len());
    for c in &m.cases {
        assert!(
            c.envelope_kept,
            "{} {}: command left the envelope",
            c.scenario, c.case
        );
        assert!(
            c.peak_jump_mm <= m.rate_limit_mm * (1.0 + 1e-9),
            "{} {}: jump {} mm above the rate limit",
            c.scenario,
            c.case,
            c.peak_jump_mm
        );
        assert!(c.pass, "{c:?}");
    }
    // Both directions are exercised: cases that must trip and cases that must not.
    assert!(m.cases.iter().any(|c| c.detected));
    assert!(m.cases.iter().any(|c| !c.detected));
}

/// What reached the servo-controller: within the rate limit (plus the DAC's rounding) unless the
/// link lost commands, and then within one step per lost tick plus one.
#[test]
fn servo_side_steps_are_bounded() {
    let m = faults::run_matrix().unwrap();
    // One code of the 16-bit DAC over ±25.4 mm, twice (two roundings).
    let dac = 2.0 * 25.4 / 32768.0;
    for c in &m.cases {
        let bound = if c.case == "lost ticks 2" {
            3.0 * m.rate_limit_mm + dac
        } else {
            m.rate_limit_mm + dac
        };
        assert!(
            c.peak_servo_jump_mm <= bound,
            "{} {}: servo step {} mm > {bound}",
            c.scenario,
            c.case,
            c.peak_servo_jump_mm
        );
    }
}

//! The fault-injection matrix (`rths faults`): every row must pass, and the command runs it.
#![cfg(feature = "sim")]

use rths::faults;

#[test]
fn every_fault_case_passes() {
    let m = faults::run_matrix().unwrap();
    println!("{}", m.to_markdown());
    assert!(m.cases.len() >= 60, "{} cases", m.cases.len());
    for c in &m.cases {
        assert!(c.envelope_kept, "{} {}: command left the envelope", c.scenario, c.case);
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

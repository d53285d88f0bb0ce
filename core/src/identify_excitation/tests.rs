//! Tests of the identification excitation: its schedule, ramps and players.

use super::*;

#[test]
fn refuses_bad_settings() {
    let mut c = ExcitationConfig::new(crate::params::DT_S);
    c.amplitude_mm = 3.0;
    assert!(matches!(
        Multisine::new::<Libm>(&c),
        Err(ExcitationError::Amplitude(_))
    ));
    let mut c = ExcitationConfig::new(crate::params::DT_S);
    c.band_hi_hz = 1000.0;
    assert_eq!(Multisine::new::<Libm>(&c), Err(ExcitationError::Band));
    let mut c = ExcitationConfig::new(crate::params::DT_S);
    c.periods = 1;
    assert_eq!(Multisine::new::<Libm>(&c), Err(ExcitationError::Periods));
    let mut c = ExcitationConfig::new(crate::params::DT_S);
    c.ramp_s = f64::NAN;
    assert_eq!(Multisine::new::<Libm>(&c), Err(ExcitationError::Timing));
    let c = ExcitationConfig::new(crate::params::DT_S);
    let bad = UnitStats {
        peak: 0.0,
        peak_rate_per_s: 1.0,
    };
    assert_eq!(Schedule::new(&c, 8, bad), Err(ExcitationError::EmptyBand));
}

#[test]
fn a_player_ends_at_zero_after_every_tick() {
    let c = ExcitationConfig::new(crate::params::DT_S);
    let stats = UnitStats {
        peak: 1.0,
        peak_rate_per_s: 1.0,
    };
    let s = Schedule::new(&c, c.period_ticks(), stats).unwrap();
    struct Half;
    impl Tables for Half {
        fn unit(&self, _: usize) -> f64 {
            0.5
        }
        fn ramp_cos(&self, j: usize) -> f64 {
            ramp_cos::<Libm>(j, 4096)
        }
    }
    let mut p = Player::new(s);
    let mut last = f64::NAN;
    let mut n = 0;
    while let Some(v) = p.next(&Half) {
        last = v;
        n += 1;
    }
    assert_eq!(n, s.ticks());
    assert_eq!(last, 0.0);
    assert_eq!(p.next(&Half), None);
}

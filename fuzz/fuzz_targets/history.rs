//! Arbitrary bytes to the time-history readers (CSV and one recorder file): a history or an
//! error, never a panic; an accepted history has columns of one length, finite values.
#![no_main]
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let dt = 1.0 / 2048.0;
    if let Ok(h) = rths_files::history::parse_csv(&text, Path::new("fuzz.csv"), dt) {
        assert!(h.len() >= 2, "a history of fewer than 2 rows was accepted");
        assert_eq!(h.specimen_force_kn.len(), h.len());
        assert_eq!(h.interface_mm.len(), h.len());
        for (_, v) in &h.outputs {
            assert_eq!(v.len(), h.len());
        }
        assert!(h.ground_accel_mm_s2.iter().all(|v| v.is_finite()));
    }
    if let Ok(r) = rths_files::history::parse_recorder(&text, Path::new("fuzz.out")) {
        assert!(r.time_s.len() == r.value.len() && r.value.len() == r.line.len());
        assert!(r.time_s.iter().chain(&r.value).all(|x| x.is_finite()));
    }
});

//! Arbitrary bytes to the AT2 reader: it must return a motion or an error, never panic, and a motion
//! it accepts must be valid (finite, positive step, non-empty).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(m) = rths_files::motion::parse_at2(&text, "fuzz") {
        assert!(m.validate().is_ok(), "parse_at2 accepted an invalid motion");
    }
});

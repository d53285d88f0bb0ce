//! Arbitrary bytes to the CSV reader: a motion or an error, never a panic; accepted motions are valid.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(m) = rths_files::motion::parse_csv(&text, "fuzz") {
        assert!(m.validate().is_ok(), "parse_csv accepted an invalid motion");
    }
});

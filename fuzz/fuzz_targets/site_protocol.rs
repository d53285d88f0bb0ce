//! Arbitrary bytes to `rths site`'s element-server parser (OpenSees's genericClient protocol): the
//! first 44 bytes as a handshake, the rest as messages of its dataSize; an error or a value, never
//! a panic; an accepted setTrialResponse is finite.
#![no_main]
use libfuzzer_sys::fuzz_target;
use rths::machinery::site::protocol::{parse_handshake, parse_message, Action, HANDSHAKE_BYTES};

fuzz_target!(|data: &[u8]| {
    let (head, rest) = data.split_at(data.len().min(HANDSHAKE_BYTES));
    let Ok(hs) = parse_handshake(head) else {
        return;
    };
    assert!(hs.dofs >= 1 && hs.data_size >= 3 * hs.dofs + 2);
    for chunk in rest.chunks(hs.message_bytes()) {
        if let Ok(m) = parse_message(chunk, &hs) {
            assert_eq!(m.disp.len(), hs.dofs);
            if m.action == Action::SetTrialResponse {
                assert!(m.disp.iter().all(|x| x.is_finite()) && m.time_s.is_finite());
            }
        }
    }
});

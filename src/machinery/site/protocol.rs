//! The element-server protocol of OpenSees's `genericClient` element, as pure functions: the
//! handshake and the messages parsed from bytes, the replies encoded (docs/site.md).
//!
//! On connect the client sends 11 little-endian `i32`: `[n, n, n, 0, 1, 0, 0, 0, n, 0, dataSize]`
//! (n basic DOFs: sizes of the control displacement, velocity, acceleration, force, deformation and
//! time, then of the DAQ's; `dataSize` ≥ max(3n + 2, n²)). Every message after it is `dataSize`
//! little-endian `f64`: `[action, d(n), v(n), a(n), t, …]`; the replies of getForce and the matrix
//! requests are `dataSize` `f64` too (the force in the first n, a matrix n × n column-major).

/// Bytes of the handshake.
pub const HANDSHAKE_BYTES: usize = 11 * 4;

/// The largest `dataSize` a server accepts (f64 per message): 64 KiB messages. The client's
/// default is 256.
pub const MAX_DATA_SIZE: usize = 8192;

/// The largest number of basic DOFs of an element the handshake may announce.
pub const MAX_BASIC_DOFS: usize = 64;

/// The action codes of the protocol (the client's `RemoteTest_*` values).
const ACTIONS: [(f64, Action); 8] = [
    (3.0, Action::SetTrialResponse),
    (5.0, Action::CommitState),
    (10.0, Action::GetForce),
    (12.0, Action::GetInitialStiff),
    (13.0, Action::GetTangentStiff),
    (14.0, Action::GetDamp),
    (15.0, Action::GetMass),
    (99.0, Action::Die),
];

/// What a client asked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Action {
    /// 3: the trial response (no reply).
    SetTrialResponse,
    /// 5: commit the state (no reply).
    CommitState,
    /// 10: the resisting force (reply: dataSize f64, the force first).
    GetForce,
    /// 12: the initial stiffness (reply: n × n).
    GetInitialStiff,
    /// 13: the tangent stiffness (reply: n × n).
    GetTangentStiff,
    /// 14: the damping matrix (reply: n × n).
    GetDamp,
    /// 15: the mass matrix (reply: n × n).
    GetMass,
    /// 99: the end of the analysis.
    Die,
}

impl Action {
    /// The action of a code (the message's first f64), `None` for an unknown one.
    pub fn from_code(code: f64) -> Option<Self> {
        ACTIONS.iter().find(|(c, _)| *c == code).map(|(_, a)| *a)
    }

    /// Does the client wait for a reply?
    pub fn has_reply(self) -> bool {
        !matches!(
            self,
            Action::SetTrialResponse | Action::CommitState | Action::Die
        )
    }
}

/// Why bytes from a client were refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProtocolError {
    /// The handshake is not 44 bytes.
    #[error("handshake of {0} bytes, expected 44 (11 int32)")]
    HandshakeLength(usize),
    /// The handshake's sizes are not a genericClient's.
    #[error("handshake {0:?} is not a genericClient's [n, n, n, 0, 1, 0, 0, 0, n, 0, dataSize]")]
    HandshakeShape([i32; 11]),
    /// Too many basic DOFs.
    #[error("the element has {0} basic DOFs, at most {MAX_BASIC_DOFS} are accepted")]
    TooManyDofs(i32),
    /// dataSize too small for the element or beyond [`MAX_DATA_SIZE`].
    #[error("dataSize {got} out of range ({min}..={MAX_DATA_SIZE} for {n} DOFs)")]
    DataSize {
        /// Announced.
        got: i32,
        /// Smallest for the DOFs.
        min: usize,
        /// DOFs.
        n: usize,
    },
    /// A message of another length than dataSize f64 (malformed or oversized).
    #[error("message of {got} bytes, expected {want} (dataSize f64)")]
    MessageLength {
        /// Received.
        got: usize,
        /// Expected.
        want: usize,
    },
    /// An action code this server does not know.
    #[error("unknown action {0}")]
    UnknownAction(f64),
    /// A displacement, velocity, acceleration or time that is not finite.
    #[error("non-finite {0} in a setTrialResponse")]
    NonFinite(&'static str),
}

/// A client's handshake: its element's sizes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Handshake {
    /// Basic DOFs n.
    pub dofs: usize,
    /// f64 per message.
    pub data_size: usize,
}

impl Handshake {
    /// Bytes per message.
    pub fn message_bytes(&self) -> usize {
        self.data_size * 8
    }
}

/// Parse the handshake.
pub fn parse_handshake(bytes: &[u8]) -> Result<Handshake, ProtocolError> {
    if bytes.len() != HANDSHAKE_BYTES {
        return Err(ProtocolError::HandshakeLength(bytes.len()));
    }
    let mut v = [0i32; 11];
    for (x, c) in v.iter_mut().zip(bytes.chunks_exact(4)) {
        *x = i32::from_le_bytes([c[0], c[1], c[2], c[3]]);
    }
    let n = v[0];
    let shape = [n, n, n, 0, 1, 0, 0, 0, n, 0];
    if v[..10] != shape || n < 1 {
        return Err(ProtocolError::HandshakeShape(v));
    }
    if n as usize > MAX_BASIC_DOFS {
        return Err(ProtocolError::TooManyDofs(n));
    }
    let dofs = n as usize;
    let min = (3 * dofs + 2).max(dofs * dofs);
    let ds = v[10];
    if ds < 0 || (ds as usize) < min || ds as usize > MAX_DATA_SIZE {
        return Err(ProtocolError::DataSize {
            got: ds,
            min,
            n: dofs,
        });
    }
    Ok(Handshake {
        dofs,
        data_size: ds as usize,
    })
}

/// One message from the client.
#[derive(Debug, Clone, PartialEq)]
pub struct Message {
    /// What is asked.
    pub action: Action,
    /// Trial displacements, n.
    pub disp: Vec<f64>,
    /// Trial velocities, n.
    pub vel: Vec<f64>,
    /// Trial accelerations, n.
    pub accel: Vec<f64>,
    /// The analysis time, s.
    pub time_s: f64,
}

/// Parse one message of a client with handshake `hs`. The response of a setTrialResponse must be
/// finite; the other actions carry the last one, which is not read.
pub fn parse_message(bytes: &[u8], hs: &Handshake) -> Result<Message, ProtocolError> {
    if bytes.len() != hs.message_bytes() {
        return Err(ProtocolError::MessageLength {
            got: bytes.len(),
            want: hs.message_bytes(),
        });
    }
    let f = |i: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&bytes[8 * i..8 * i + 8]);
        f64::from_le_bytes(b)
    };
    let code = f(0);
    let action = Action::from_code(code).ok_or(ProtocolError::UnknownAction(code))?;
    let n = hs.dofs;
    let disp: Vec<f64> = (1..=n).map(f).collect();
    let vel: Vec<f64> = (n + 1..=2 * n).map(f).collect();
    let accel: Vec<f64> = (2 * n + 1..=3 * n).map(f).collect();
    let time_s = f(3 * n + 1);
    if action == Action::SetTrialResponse {
        for (what, v) in [
            ("displacement", &disp),
            ("velocity", &vel),
            ("acceleration", &accel),
        ] {
            if v.iter().any(|x| !x.is_finite()) {
                return Err(ProtocolError::NonFinite(what));
            }
        }
        if !time_s.is_finite() {
            return Err(ProtocolError::NonFinite("time"));
        }
    }
    Ok(Message {
        action,
        disp,
        vel,
        accel,
        time_s,
    })
}

/// A reply: `values` then zeros, `data_size` little-endian f64 (`values` beyond it are dropped).
pub fn encode_reply(values: &[f64], data_size: usize) -> Vec<u8> {
    let mut out = vec![0u8; data_size * 8];
    for (c, v) in out.chunks_exact_mut(8).zip(values) {
        c.copy_from_slice(&v.to_le_bytes());
    }
    out
}

/// The handshake's bytes for `dofs` and `data_size` (what a client sends; tests and fuzz seeds).
pub fn encode_handshake(dofs: i32, data_size: i32) -> Vec<u8> {
    [dofs, dofs, dofs, 0, 1, 0, 0, 0, dofs, 0, data_size]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn the_default_handshake_and_a_trial_response() {
        let hs = parse_handshake(&encode_handshake(1, 256)).unwrap();
        assert_eq!(
            hs,
            Handshake {
                dofs: 1,
                data_size: 256
            }
        );
        let mut vals = vec![0.0; 256];
        vals[..5].copy_from_slice(&[3.0, 1.5, 2.0, 3.0, 0.25]);
        let m = parse_message(&encode_reply(&vals, 256), &hs).unwrap();
        assert_eq!(m.action, Action::SetTrialResponse);
        assert_eq!(
            (m.disp[0], m.vel[0], m.accel[0], m.time_s),
            (1.5, 2.0, 3.0, 0.25)
        );
    }

    #[test]
    fn bad_handshakes_and_messages_are_refused() {
        assert!(matches!(
            parse_handshake(&[0; 43]),
            Err(ProtocolError::HandshakeLength(43))
        ));
        let mut b = encode_handshake(1, 256);
        b[12] = 7;
        assert!(matches!(
            parse_handshake(&b),
            Err(ProtocolError::HandshakeShape(_))
        ));
        assert!(parse_handshake(&encode_handshake(2, 7)).is_err());
        assert!(parse_handshake(&encode_handshake(1, 1 << 20)).is_err());
        assert!(parse_handshake(&encode_handshake(0, 256)).is_err());
        assert!(parse_handshake(&encode_handshake(-3, 256)).is_err());
        let hs = parse_handshake(&encode_handshake(1, 8)).unwrap();
        assert!(matches!(
            parse_message(&[0; 72], &hs),
            Err(ProtocolError::MessageLength { got: 72, want: 64 })
        ));
        assert!(matches!(
            parse_message(&encode_reply(&[7.0], 8), &hs),
            Err(ProtocolError::UnknownAction(_))
        ));
        assert!(matches!(
            parse_message(&encode_reply(&[3.0, f64::NAN], 8), &hs),
            Err(ProtocolError::NonFinite("displacement"))
        ));
    }

    proptest! {
        /// Any bytes: a handshake or an error, never a panic; an accepted one re-encodes to the
        /// same bytes.
        #[test]
        fn any_handshake_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            if let Ok(hs) = parse_handshake(&bytes) {
                prop_assert_eq!(encode_handshake(hs.dofs as i32, hs.data_size as i32), bytes);
            }
        }

        /// Any bytes as a message: a message or an error, never a panic; an accepted
        /// setTrialResponse is finite.
        #[test]
        fn any_message_bytes(
            bytes in proptest::collection::vec(any::<u8>(), 0..200),
            n in 1usize..4,
        ) {
            let hs = Handshake { dofs: n, data_size: (3 * n + 2).max(n * n) };
            if let Ok(m) = parse_message(&bytes, &hs) {
                prop_assert_eq!(m.disp.len(), n);
                if m.action == Action::SetTrialResponse {
                    prop_assert!(m.disp.iter().chain(&m.vel).chain(&m.accel).all(|x| x.is_finite()));
                }
            }
        }

        /// Well-formed messages of every action parse to what was sent.
        #[test]
        fn well_formed_messages_round_trip(
            code in prop::sample::select(vec![3.0, 5.0, 10.0, 12.0, 13.0, 14.0, 15.0, 99.0]),
            d in -1e3f64..1e3, t in 0.0f64..100.0,
        ) {
            let hs = Handshake { dofs: 1, data_size: 16 };
            let m = parse_message(&encode_reply(&[code, d, 0.0, 0.0, t], 16), &hs).unwrap();
            prop_assert_eq!(m.disp[0], d);
            prop_assert_eq!(m.time_s, t);
            prop_assert_eq!(m.action.has_reply(), [10.0, 12.0, 13.0, 14.0, 15.0].contains(&code));
        }
    }
}

//! The one checksum of the project's own files and command streams: FNV-1a, 64 bit (not a
//! security hash). It ties a model file to its structure file and rig file (`"fnv1a64:<16 hex>"`,
//! [`Fnv1a64Label`]), and it condenses a run's command stream into one number that a host run and
//! the firmware's must share (the bits of each `f64`, little-endian, [`Fnv1a64::write_f64`]).
//! The link's frames and uploads carry their own CRC-32 (`rths-link`), not this.

/// FNV-1a's 64-bit offset basis (the hash of no bytes).
pub const FNV1A64_OFFSET_BASIS: u64 = 0xcbf2_9ce4_8422_2325;

/// FNV-1a's 64-bit prime.
pub const FNV1A64_PRIME: u64 = 0x0000_0100_0000_01b3;

/// An FNV-1a (64 bit) hash being fed bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fnv1a64 {
    state: u64,
}

impl Default for Fnv1a64 {
    fn default() -> Self {
        Self::new()
    }
}

impl Fnv1a64 {
    /// The hash of no bytes yet.
    pub const fn new() -> Self {
        Self {
            state: FNV1A64_OFFSET_BASIS,
        }
    }

    /// Feed `bytes`, in order.
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.state = (self.state ^ u64::from(b)).wrapping_mul(FNV1A64_PRIME);
        }
    }

    /// Feed the bits of `v`, little-endian (the same value always hashes the same, NaN payloads
    /// and the sign of zero included).
    pub fn write_f64(&mut self, v: f64) {
        self.write(&v.to_bits().to_le_bytes());
    }

    /// The hash of everything fed so far.
    pub const fn finish(&self) -> u64 {
        self.state
    }
}

/// FNV-1a (64 bit) of `bytes`.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h = Fnv1a64::new();
    h.write(bytes);
    h.finish()
}

/// A hash as the files carry it: `fnv1a64:` and 16 lower-case hex digits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fnv1a64Label(pub u64);

impl core::fmt::Display for Fnv1a64Label {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "fnv1a64:{:016x}", self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The published FNV-1a 64-bit test vectors.
    #[test]
    fn the_published_vectors() {
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
    }

    #[test]
    fn fed_in_pieces_or_as_floats_it_is_the_same_hash() {
        let mut h = Fnv1a64::new();
        h.write(b"foo");
        h.write(b"bar");
        assert_eq!(h.finish(), fnv1a64(b"foobar"));
        let mut f = Fnv1a64::default();
        f.write_f64(-0.0);
        f.write_f64(1.5);
        let mut bytes = [0u8; 16];
        bytes[..8].copy_from_slice(&(-0.0f64).to_bits().to_le_bytes());
        bytes[8..].copy_from_slice(&1.5f64.to_bits().to_le_bytes());
        assert_eq!(f.finish(), fnv1a64(&bytes));
    }

    #[test]
    fn the_label_is_sixteen_hex_digits() {
        extern crate std;
        use std::string::ToString;
        assert_eq!(
            Fnv1a64Label(fnv1a64(b"")).to_string(),
            "fnv1a64:cbf29ce484222325"
        );
        assert_eq!(Fnv1a64Label(1).to_string(), "fnv1a64:0000000000000001");
    }
}

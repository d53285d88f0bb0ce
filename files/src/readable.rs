//! Numbers in messages: a value a user typed or a file holds is printed in shortest form when it is
//! of ordinary size, and in exponent form (`1e300`, `2.5e-9`) otherwise, never with hundreds of
//! digits.

use core::fmt;

/// Below this magnitude (and above [`SMALL`]) a value prints in plain shortest form.
const LARGE: f64 = 1e6;
/// Above this magnitude (and below [`LARGE`]) a value prints in plain shortest form.
const SMALL: f64 = 1e-4;

/// `v` printed readably (see the module's description).
pub fn readable(v: f64) -> Readable {
    Readable(v)
}

/// A value printed readably ([`readable`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Readable(pub f64);

impl fmt::Display for Readable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        let plain = !v.is_finite() || v == 0.0 || (SMALL..LARGE).contains(&v.abs());
        if plain {
            write!(f, "{v}")
        } else {
            write!(f, "{v:e}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::readable;

    #[test]
    fn ordinary_values_are_plain_and_huge_or_tiny_ones_in_exponent_form() {
        for (v, text) in [
            (2.0, "2"),
            (-0.5, "-0.5"),
            (0.0, "0"),
            (123456.5, "123456.5"),
            (1e300, "1e300"),
            (-1.5e7, "-1.5e7"),
            (2.5e-9, "2.5e-9"),
            (f64::NAN, "NaN"),
            (f64::INFINITY, "inf"),
        ] {
            assert_eq!(readable(v).to_string(), text);
        }
    }
}

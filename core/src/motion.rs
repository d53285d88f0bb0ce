//! A ground-motion record at controller ticks: ü_g at tick k by linear interpolation between the
//! record's samples (in g, at the record's own step), and the number of ticks the record lasts.
//!
//! The host's resampling, the firmware's per-tick motion and the firmware build script's tick count
//! all call these, so the host simulation and the MCU see the same ü_g bit for bit.

use crate::params::G_MM_S2;

/// A record borrowed as read: `accel_g[i]` is the acceleration in g at `t = i·dt_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record<'a> {
    accel_g: &'a [f64],
    dt_s: f64,
}

impl<'a> Record<'a> {
    /// A record of samples in g every `dt_s` seconds. `const` so that firmware can keep one in a
    /// `static`; a bad step or an empty record simply lasts zero ticks.
    pub const fn new(accel_g: &'a [f64], dt_s: f64) -> Self {
        Self { accel_g, dt_s }
    }

    /// Duration `(n − 1)·dt_s`, s (0 for fewer than two samples).
    pub fn duration_s(&self) -> f64 {
        self.accel_g.len().saturating_sub(1) as f64 * self.dt_s
    }

    /// Ticks of `tick_dt_s` the record covers: `k = 0..=floor(duration / tick_dt_s)`. Zero if the
    /// record is empty or either step is not finite and positive.
    pub fn ticks(&self, tick_dt_s: f64) -> usize {
        record_ticks(self.accel_g.len(), self.dt_s, tick_dt_s)
    }

    /// Ground acceleration at tick `k` of `tick_dt_s` (time `k·tick_dt_s`), mm/s², interpolated
    /// linearly between the samples; past the last sample (reachable only through the slack in
    /// [`Self::ticks`]) the last sample is held; 0 for an empty record.
    #[inline]
    pub fn accel_mm_s2(&self, k: usize, tick_dt_s: f64) -> f64 {
        accel_at_mm_s2(
            self.accel_g.len(),
            |i| self.accel_g.get(i).copied(),
            k,
            tick_dt_s,
            self.dt_s,
        )
    }
}

/// Ticks of `tick_dt_s` a record of `samples` samples every `dt_s` covers (what
/// [`Record::ticks`] counts, for a record not held whole, e.g. one streamed through a ring).
pub fn record_ticks(samples: usize, dt_s: f64, tick_dt_s: f64) -> usize {
    if samples == 0 || !positive(tick_dt_s) || !positive(dt_s) {
        return 0;
    }
    let duration_s = (samples - 1) as f64 * dt_s;
    // A hair of slack so that e.g. 39.99 s / (1/2048 s) landing a rounding error below an
    // integer still counts the last step.
    // `as` saturates a count beyond the word size; so does the `+ 1`.
    let last = libm::floor(duration_s / tick_dt_s * (1.0 + 1e-12)) as usize;
    last.saturating_add(1)
}

/// The samples tick `k` reads: the index of the first of the two it interpolates between (the
/// second is the next one, if the record has it), and its weight's complement.
#[inline]
pub fn tick_position(k: usize, tick_dt_s: f64, dt_s: f64) -> (usize, f64) {
    let pos = k as f64 * tick_dt_s / dt_s;
    let i = libm::floor(pos) as usize;
    (i, pos - i as f64)
}

/// [`Record::accel_mm_s2`] of a record of `samples` samples read through `sample_g` (sample `i`
/// in g, `None` if it does not exist): the one formula for a record held whole and one streamed.
#[inline]
pub fn accel_at_mm_s2(
    samples: usize,
    sample_g: impl Fn(usize) -> Option<f64>,
    k: usize,
    tick_dt_s: f64,
    dt_s: f64,
) -> f64 {
    let (i, frac) = tick_position(k, tick_dt_s, dt_s);
    let a = match (sample_g(i), sample_g(i.saturating_add(1))) {
        (Some(a0), Some(a1)) => a0 + frac * (a1 - a0),
        (Some(a0), None) => a0,
        _ => samples.checked_sub(1).and_then(&sample_g).unwrap_or(0.0),
    };
    a * G_MM_S2
}

fn positive(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::DT_S;

    #[test]
    fn interpolates_and_counts_ticks() {
        let g = [0.0, 1.0, -1.0];
        let r = Record::new(&g, 0.01);
        // 0.02 s at 2048 Hz: 40.96 → ticks 0..=40.
        assert_eq!(r.ticks(DT_S), 41);
        assert_eq!(r.accel_mm_s2(0, DT_S), 0.0);
        let pos = 10.0 * DT_S / 0.01;
        assert_eq!(r.accel_mm_s2(10, DT_S), pos * G_MM_S2);
        assert_eq!(r.accel_mm_s2(1000, DT_S), -G_MM_S2);
    }

    #[test]
    fn degenerate_records_last_zero_ticks() {
        assert_eq!(Record::new(&[], 0.01).ticks(DT_S), 0);
        assert_eq!(Record::new(&[1.0], 0.0).ticks(DT_S), 0);
        assert_eq!(Record::new(&[1.0], 0.01).ticks(f64::NAN), 0);
        assert_eq!(Record::new(&[1.0], 0.01).ticks(DT_S), 1);
        assert_eq!(Record::new(&[], 0.01).accel_mm_s2(3, DT_S), 0.0);
    }

    #[test]
    fn the_slack_counts_a_last_tick_a_rounding_error_short() {
        // 3999 steps of 0.01 s = 39.99 s; 39.99·2048 = 81899.52 → 81 900 ticks (the El Centro count).
        let g = [0.0; 4000];
        assert_eq!(Record::new(&g, 0.01).ticks(DT_S), 81_900);
    }
}

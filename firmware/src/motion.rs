//! The ground motion at controller ticks, computed exactly as the host's
//! `GroundMotion::resample_mm_s2(DT_S)` does (same operations in the same order, IEEE f64), so the
//! firmware and the host simulation see the same ü_g bit for bit.

use rths_core::params::{DT_S, G_MM_S2};

use crate::gen::{MOTION_DT_S, MOTION_G, RECORD_TICKS};

/// Ground acceleration at tick `k` (time `k·Δt`), mm/s²; 0 after the record.
#[inline]
pub fn ground_accel_mm_s2(k: u32) -> f64 {
    if k >= RECORD_TICKS {
        return 0.0;
    }
    let pos = k as f64 * DT_S / MOTION_DT_S;
    let i = libm::floor(pos) as usize;
    let frac = pos - i as f64;
    let a = match (MOTION_G.get(i).copied(), MOTION_G.get(i + 1).copied()) {
        (Some(a0), Some(a1)) => a0 + frac * (a1 - a0),
        (Some(a0), None) => a0,
        _ => MOTION_G.last().copied().unwrap_or(0.0),
    };
    a * G_MM_S2
}

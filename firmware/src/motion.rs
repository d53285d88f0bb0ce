//! The ground motion at controller ticks: `rths_core::motion::Record`, the interpolation the host's
//! `GroundMotion::resample_mm_s2(DT_S)` runs, so the firmware and the host simulation see the same
//! ü_g bit for bit.

use rths_core::motion::Record;
use rths_core::params::DT_S;

use crate::gen::{MOTION_DT_S, MOTION_G, RECORD_TICKS};

/// The compiled-in record (values in g at its own step).
static RECORD: Record<'static> = Record::new(&MOTION_G, MOTION_DT_S);

/// Ground acceleration at tick `k` (time `k·Δt`), mm/s²; 0 after the record.
#[inline]
pub fn ground_accel_mm_s2(k: u32) -> f64 {
    if k >= RECORD_TICKS {
        return 0.0;
    }
    RECORD.accel_mm_s2(k as usize, DT_S)
}

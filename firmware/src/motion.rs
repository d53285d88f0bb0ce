//! The ground motion at controller ticks: the compiled-in record (`gen`) and, with `link`, the
//! board's record buffer for uploaded ones, both in `rths_app::record::RecordStore`, which plays the
//! one in force with `rths_core::motion::Record`'s interpolation, the one the host's
//! `GroundMotion::resample_mm_s2(DT_S)` runs, so the firmware and the host simulation see the same
//! ü_g bit for bit.

use rths_app::record::RecordStore;

use crate::gen::{MOTION_DT_S, MOTION_G, RECORD_TICKS};

/// The record store: the compiled-in record, and the board's record buffer with `link`.
pub fn store() -> RecordStore<'static> {
    RecordStore::new(&MOTION_G, MOTION_DT_S, RECORD_TICKS, buffer())
}

/// The board's record buffer, zeroed (`link`); handed out once.
#[cfg(feature = "link")]
fn buffer() -> &'static mut [f64] {
    use core::sync::atomic::{AtomicBool, Ordering};
    static TAKEN: AtomicBool = AtomicBool::new(false);
    if TAKEN.swap(true, Ordering::AcqRel) {
        return &mut [];
    }
    let (addr, bytes) = crate::board::RECORD_BUFFER;
    let n = bytes / core::mem::size_of::<f64>();
    let p = addr as *mut f64;
    // SAFETY: the board names RAM outside every linker region (no static, no stack lives there),
    // 8-byte aligned; it is zeroed before the slice is made, and the slice is made only once
    // (`TAKEN`), so it is the one reference to that memory.
    unsafe {
        core::ptr::write_bytes(p, 0, n);
        core::slice::from_raw_parts_mut(p, n)
    }
}

/// No uploads without the link.
#[cfg(not(feature = "link"))]
fn buffer() -> &'static mut [f64] {
    &mut []
}

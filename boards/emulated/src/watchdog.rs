//! The emulated boards' watchdog counter (QEMU models no IWDG on the netduinoplus2, and the MPS2's
//! CMSDK watchdog resets the machine instead of ending the emulation with a verdict): the control
//! task feeds it every tick; a timer interrupt above the control task asks, once per watchdog
//! period, whether any tick fed it since it last asked. Each board adds only its timer.

use core::sync::atomic::{AtomicU32, Ordering};

/// Control ticks since the watchdog last looked.
static FEEDS: AtomicU32 = AtomicU32::new(0);

/// The watchdog starts: the first period counts as fed (the tick timer has just started).
pub fn arm() {
    FEEDS.store(1, Ordering::Release);
}

/// The control task ran a tick.
pub fn feed() {
    FEEDS.fetch_add(1, Ordering::AcqRel);
}

/// The watchdog's check: `true` if no tick fed it since the last check (the control task stalled).
pub fn starved() -> bool {
    FEEDS.swap(0, Ordering::AcqRel) == 0
}

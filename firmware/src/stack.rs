//! Stack high-water mark: the free RAM between the end of the statics (`_stack_end`) and the stack
//! pointer is painted at boot; at the end the lowest overwritten word gives the deepest the stack
//! went (init, every task and its interrupts share the main stack).

const PAINT: u32 = 0xA5A5_5A5A;
/// Margin below the current stack pointer left unpainted while painting, bytes.
const MARGIN: usize = 64;

extern "C" {
    static _stack_start: u32;
    static _stack_end: u32;
}

fn bounds() -> (usize, usize) {
    // Only the addresses of the linker symbols are taken.
    (
        core::ptr::addr_of!(_stack_end) as usize,
        core::ptr::addr_of!(_stack_start) as usize,
    )
}

/// Paint the unused stack (call early in `init`).
pub fn paint() {
    let (lo, _) = bounds();
    let sp = cortex_m::register::msp::read() as usize;
    let mut a = lo;
    while a + 4 <= sp.saturating_sub(MARGIN) {
        // SAFETY: [lo, sp − margin) is RAM below the live stack and above every static.
        unsafe { core::ptr::write_volatile(a as *mut u32, PAINT) };
        a += 4;
    }
}

/// Deepest stack use since `paint`, bytes, and the stack space available.
pub fn high_water() -> (usize, usize) {
    let (lo, hi) = bounds();
    let mut a = lo;
    // SAFETY: reads of RAM between the statics and the stack top.
    while a < hi && unsafe { core::ptr::read_volatile(a as *const u32) } == PAINT {
        a += 4;
    }
    (hi - a, hi - lo)
}

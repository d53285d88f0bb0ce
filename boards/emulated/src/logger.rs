//! defmt transport for QEMU: frames go to the host file `defmt.bin` through semihosting, so the
//! program's stdout carries only plain text (the RESULT line). Decode with
//! `defmt-print -e <elf> < defmt.bin`.
//!
//! One frame is buffered and written with a single semihosting call at its end (each call is a trap
//! to the host). Logging happens only at low priority (telemetry, supervisor, init), never in the
//! control task; the critical section keeps frames whole anyway.

use core::cell::RefCell;
use core::fmt::Write as _;

use cortex_m::interrupt::{self, Mutex};
use cortex_m_semihosting::hio;
use heapless::Vec;

/// Longest frame kept; a longer one is cut (and counted).
const FRAME_BYTES: usize = 256;

struct State {
    encoder: defmt::Encoder,
    frame: Vec<u8, FRAME_BYTES>,
    file: Option<usize>,
    opened: bool,
    truncated: u32,
    restore: Option<critical_section::RestoreState>,
}

static STATE: Mutex<RefCell<State>> = Mutex::new(RefCell::new(State {
    encoder: defmt::Encoder::new(),
    frame: Vec::new(),
    file: None,
    opened: false,
    truncated: 0,
    restore: None,
}));

/// Frames cut to [`FRAME_BYTES`] so far.
pub fn truncated_frames() -> u32 {
    // try_borrow: no panic path (`panic-check.sh` on the supervisor task); it cannot fail inside the
    // section.
    interrupt::free(|cs| STATE.borrow(cs).try_borrow().map_or(0, |s| s.truncated))
}

fn push(st: &mut State, bytes: &[u8]) {
    if st.frame.extend_from_slice(bytes).is_err() {
        st.truncated = st.truncated.saturating_add(1);
    }
}

#[defmt::global_logger]
struct Logger;

// SAFETY: defmt calls acquire/release in pairs and write/flush only in between; the state is only
// touched inside the critical section taken in `acquire` and given back in `release`.
unsafe impl defmt::Logger for Logger {
    fn acquire() {
        // SAFETY: paired with the release in `release`.
        let restore = unsafe { critical_section::acquire() };
        // SAFETY: interrupts are masked from here to `release`.
        let cs = unsafe { interrupt::CriticalSection::new() };
        // try_borrow_mut: no panic path. Interrupts are masked and nothing else holds the state, so
        // it cannot fail; if it ever did, the section is given back and the frame dropped.
        let Ok(mut st) = STATE.borrow(&cs).try_borrow_mut() else {
            // SAFETY: the state this `acquire` just took.
            unsafe { critical_section::release(restore) };
            return;
        };
        st.restore = Some(restore);
        st.frame.clear();
        let State { encoder, frame, .. } = &mut *st;
        encoder.start_frame(|b| {
            let _ = frame.extend_from_slice(b);
        });
    }

    unsafe fn flush() {}

    unsafe fn release() {
        // SAFETY: still inside the critical section taken in `acquire`.
        let cs = unsafe { interrupt::CriticalSection::new() };
        let restore = if let Ok(mut st) = STATE.borrow(&cs).try_borrow_mut() {
            let st = &mut *st;
            let mut tmp: Vec<u8, 16> = Vec::new();
            st.encoder.end_frame(|b| {
                let _ = tmp.extend_from_slice(b);
            });
            let tmp2 = tmp.clone();
            push(st, &tmp2);
            if !st.opened {
                st.opened = true;
                st.file = open_host_file(b"defmt.bin\0");
            }
            if let Some(fd) = st.file {
                write_host(fd, &st.frame);
            }
            st.restore.take()
        } else {
            None
        };
        if let Some(r) = restore {
            // SAFETY: the state `acquire` saved.
            unsafe { critical_section::release(r) };
        }
    }

    unsafe fn write(bytes: &[u8]) {
        // SAFETY: inside the critical section taken in `acquire`.
        let cs = unsafe { interrupt::CriticalSection::new() };
        let Ok(mut st) = STATE.borrow(&cs).try_borrow_mut() else {
            return;
        };
        let st = &mut *st;
        let mut chunk: Vec<u8, FRAME_BYTES> = Vec::new();
        st.encoder.write(bytes, |b| {
            let _ = chunk.extend_from_slice(b);
        });
        push(st, &chunk);
    }
}

/// A `core::fmt` sink into a fixed buffer (for the RESULT line).
pub struct Line<const N: usize>(pub heapless::String<N>);

impl<const N: usize> Line<N> {
    /// Empty.
    pub fn new() -> Self {
        Self(heapless::String::new())
    }
    /// Append formatted text; `false` if it did not fit.
    pub fn put(&mut self, args: core::fmt::Arguments<'_>) -> bool {
        self.0.write_fmt(args).is_ok()
    }
}

/// Print a text line on the host's stdout (semihosting).
pub fn host_line(s: &str) {
    if let Ok(mut out) = hio::hstdout() {
        let _ = out.write_all(s.as_bytes());
        let _ = out.write_all(b"\n");
    }
}

/// Open (create, truncate, binary) a host file by semihosting; `name` ends with NUL.
fn open_host_file(name: &[u8]) -> Option<usize> {
    // SAFETY: SYS_OPEN reads `name` (NUL-terminated, its length without the NUL) and nothing else.
    let fd = unsafe {
        cortex_m_semihosting::syscall!(
            OPEN,
            name.as_ptr(),
            cortex_m_semihosting::nr::open::W_TRUNC_BINARY,
            name.len().saturating_sub(1)
        )
    };
    (fd != usize::MAX).then_some(fd)
}

/// Write `bytes` to a host file opened by [`open_host_file`] (best effort).
fn write_host(fd: usize, bytes: &[u8]) {
    // SAFETY: SYS_WRITE reads `bytes` only.
    unsafe {
        cortex_m_semihosting::syscall!(WRITE, fd, bytes.as_ptr(), bytes.len());
    }
}

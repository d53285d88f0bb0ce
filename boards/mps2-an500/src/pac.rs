//! The device module the firmware's RTIC app is built on: the AN500's interrupt vector and the two
//! peripherals this board uses, written by hand (there is no svd2rust crate for the MPS2 FPGA
//! images; RTIC needs only `Interrupt`, `interrupt`, `NVIC_PRIO_BITS` and `Peripherals::steal`).
//!
//! The firmware binds its tasks to the STM32 vector names (`TIM2`, `TIM5`, `USART2`, `UART4`, `USART3`),
//! one app for every board: here those names are given to the AN500 lines that play the same roles.
#![allow(non_camel_case_types, non_snake_case, clippy::upper_case_acronyms)]

// The runtime (reset handler, exceptions, `DefaultHandler_`) this vector table sits behind: linked
// through this crate, as an svd2rust device crate links it.
use cortex_m_rt as _;

/// The AN500 interrupt lines the firmware binds, named after the role's STM32 vector.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
#[repr(u16)]
pub enum Interrupt {
    /// UART1 receive (IRQ 2): the link port's receive interrupt (the STM32 boards' USART2).
    USART2 = 2,
    /// CMSDK TIMER0 (IRQ 8): the controller tick (the STM32 boards' TIM2).
    TIM2 = 8,
    /// CMSDK TIMER1 (IRQ 9): the emulated watchdog's check (the emulated STM32's TIM5).
    TIM5 = 9,
    /// Line 30, wired to no device: the supervisor task, pended by software (the STM32's UART4).
    UART4 = 30,
    /// Line 31, wired to no device: the telemetry task, pended by software (the STM32's USART3).
    USART3 = 31,
}

// SAFETY: every variant is a valid external interrupt number of the AN500 (it has 32).
unsafe impl cortex_m::interrupt::InterruptNumber for Interrupt {
    #[inline(always)]
    fn number(self) -> u16 {
        self as u16
    }
}

/// The name RTIC checks the vector by (svd2rust's alias).
pub use self::Interrupt as interrupt;

/// Priority bits of the AN500's Cortex-M7 NVIC.
pub const NVIC_PRIO_BITS: u8 = 3;

/// Interrupt lines of the AN500.
const LINES: usize = 32;

extern "C" {
    fn USART2();
    fn TIM2();
    fn TIM5();
    fn UART4();
    fn USART3();
}

/// An entry of the interrupt vector.
#[derive(Clone, Copy)]
pub union Vector {
    handler: unsafe extern "C" fn(),
    reserved: usize,
}

const NONE: Vector = Vector { reserved: 0 };

/// The interrupt vector (after cortex-m-rt's exceptions): the bound lines, `DefaultHandler`
/// (`device.x`) unless the firmware defines them.
#[link_section = ".vector_table.interrupts"]
#[no_mangle]
pub static __INTERRUPTS: [Vector; LINES] = {
    let mut v = [NONE; LINES];
    v[Interrupt::USART2 as usize] = Vector { handler: USART2 };
    v[Interrupt::TIM2 as usize] = Vector { handler: TIM2 };
    v[Interrupt::TIM5 as usize] = Vector { handler: TIM5 };
    v[Interrupt::UART4 as usize] = Vector { handler: UART4 };
    v[Interrupt::USART3 as usize] = Vector { handler: USART3 };
    v
};

/// A CMSDK APB timer at `BASE`: a 32-bit down-counter on the 25 MHz PCLK.
pub struct CmsdkTimer<const BASE: usize> {
    _own: (),
}

/// CMSDK APB TIMER0 at 0x4000_0000: the controller tick.
pub type TIMER0 = CmsdkTimer<0x4000_0000>;

/// CMSDK APB TIMER1 at 0x4000_1000: the emulated watchdog's check.
pub type TIMER1 = CmsdkTimer<0x4000_1000>;

/// CMSDK APB UART1 at 0x4000_5000 (QEMU's second `-serial`).
pub struct UART1 {
    _own: (),
}

/// A 32-bit peripheral register at `base + offset`.
#[derive(Clone, Copy)]
pub(crate) struct Reg(usize);

impl Reg {
    #[inline(always)]
    pub(crate) fn read(self) -> u32 {
        // SAFETY: an aligned, always-mapped device register of a peripheral this crate owns.
        unsafe { core::ptr::read_volatile(self.0 as *const u32) }
    }
    #[inline(always)]
    pub(crate) fn write(self, v: u32) {
        // SAFETY: as in `read`.
        unsafe { core::ptr::write_volatile(self.0 as *mut u32, v) }
    }
}

impl<const BASE: usize> CmsdkTimer<BASE> {
    /// CTRL: bit 0 enable, bit 3 interrupt enable.
    pub(crate) fn ctrl(&self) -> Reg {
        Reg(BASE)
    }
    /// VALUE: the current count (counts down).
    pub(crate) fn value(&self) -> Reg {
        Reg(BASE + 0x4)
    }
    /// RELOAD: loaded into VALUE when it reaches 0.
    pub(crate) fn reload(&self) -> Reg {
        Reg(BASE + 0x8)
    }
    /// INTSTATUS (read) / INTCLEAR (write 1): bit 0, the count reached 0.
    pub(crate) fn int(&self) -> Reg {
        Reg(BASE + 0xC)
    }
}

impl UART1 {
    const BASE: usize = 0x4000_5000;
    /// DATA: the received byte (read) or the byte to send (write).
    pub(crate) fn data(&self) -> Reg {
        Reg(Self::BASE)
    }
    /// STATE: bit 0 TX buffer full, bit 1 RX buffer full.
    pub(crate) fn state(&self) -> Reg {
        Reg(Self::BASE + 0x4)
    }
    /// CTRL: bit 0 TX enable, bit 1 RX enable, bit 3 RX interrupt enable.
    pub(crate) fn ctrl(&self) -> Reg {
        Reg(Self::BASE + 0x8)
    }
    /// INTSTATUS (read) / INTCLEAR (write 1): bit 1, a byte was received.
    pub(crate) fn int(&self) -> Reg {
        Reg(Self::BASE + 0xC)
    }
    /// BAUDDIV: PCLK / baud (QEMU sends nothing below 16).
    pub(crate) fn bauddiv(&self) -> Reg {
        Reg(Self::BASE + 0x10)
    }
}

/// The peripherals this board uses.
pub struct Peripherals {
    /// The tick timer.
    pub TIMER0: TIMER0,
    /// The watchdog's timer.
    pub TIMER1: TIMER1,
    /// The link UART.
    pub UART1: UART1,
}

impl Peripherals {
    /// The peripherals, without checking that they were not taken before (RTIC takes them once,
    /// before `init`).
    ///
    /// # Safety
    /// Call once: two owners of a peripheral would race on its registers.
    pub unsafe fn steal() -> Self {
        Self {
            TIMER0: TIMER0 { _own: () },
            TIMER1: TIMER1 { _own: () },
            UART1: UART1 { _own: () },
        }
    }
}

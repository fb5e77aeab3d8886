//! The board's critical section: every interrupt masked but the edge
//! interrupt (`TIMER_IRQ_0`), the input interrupt (`IO_IRQ_BANK0`) and
//! UART0's interrupt (`UART0_IRQ`).
//!
//! The axes' arithmetic runs in the main loop inside critical sections
//! (the firmware core's `Mutex`es); a Smooth ramp step takes tens of
//! microseconds on the M0+. With PRIMASK, the usual single-core critical
//! section, the edge interrupt would wait that long and the step pulses
//! would stretch. Here a critical section clears the NVIC enables of
//! every interrupt but the edge interrupt, which stays live. That is
//! sound because the edge interrupt touches nothing a critical section
//! guards: only the lock-free edge queue (`edges.rs`), SIO's output
//! registers and the timer's alarm 0. The input interrupt likewise
//! touches only its own lock-free queue and flag (`inputs.rs`), the IO
//! bank's interrupt registers, the timer and SIO's input register: live
//! too, so that an input's edge is stamped with its time while the main
//! loop computes. UART0's interrupt touches only its rings' own ends
//! and UART0's registers (`uart.rs`): live too, so that no byte is lost
//! while the main loop computes and a reply that waits for room in its
//! ring drains. Core 1 (`core1.rs`) never takes a critical section and
//! touches nothing one guards: only the run-ahead slots' lock-free
//! handshake, its own end of the SIO FIFOs and its own divider.

use cortex_m::peripheral::NVIC;
use rp2040_hal::pac::Interrupt;

/// The NVIC enable bit of the interrupt a critical section leaves live.
#[cfg(not(feature = "pio"))]
const EDGE_IRQ_BIT: u32 = 1 << (Interrupt::TIMER_IRQ_0 as u32);
/// The NVIC enable bit of the interrupt a critical section leaves live:
/// with the `pio` feature, the PIO feeder's DMA interrupt (`pio.rs`),
/// which touches only the DMA channels' registers and the counts of words
/// written to the rings and handed to the channels.
#[cfg(feature = "pio")]
const EDGE_IRQ_BIT: u32 = 1 << (Interrupt::DMA_IRQ_0 as u32);

/// The input interrupt (`inputs.rs`), live as well.
const INPUT_IRQ_BIT: u32 = 1 << (Interrupt::IO_IRQ_BANK0 as u32);
/// UART0's interrupt (`uart.rs`), live as well.
const UART_IRQ_BIT: u32 = 1 << (Interrupt::UART0_IRQ as u32);
/// The interrupts a critical section leaves live.
const LIVE_BITS: u32 = EDGE_IRQ_BIT | INPUT_IRQ_BIT | UART_IRQ_BIT;

struct AllButEdges;
critical_section::set_impl!(AllButEdges);

// SAFETY: core 0 alone takes it (core 1 never does, and touches nothing
// it guards); what the still-enabled interrupts touch is never guarded
// by a critical section (see the module docs). Nested
// sections restore exactly the enables their entry found.
unsafe impl critical_section::Impl for AllButEdges {
    unsafe fn acquire() -> critical_section::RawRestoreState {
        // SAFETY: NVIC's enable registers; ICER clears only the bits written.
        let nvic = unsafe { &*NVIC::PTR };
        let enabled = nvic.iser[0].read();
        unsafe { nvic.icer[0].write(enabled & !LIVE_BITS) };
        // The masking takes effect before the guarded code runs.
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
        enabled
    }

    unsafe fn release(enabled: critical_section::RawRestoreState) {
        // SAFETY: ISER sets only the bits written: those enabled at entry.
        let nvic = unsafe { &*NVIC::PTR };
        unsafe { nvic.iser[0].write(enabled & !LIVE_BITS) };
    }
}

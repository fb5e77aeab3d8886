//! UART0's received bytes, moved by its interrupt from the 32-byte
//! hardware FIFO into a ring that the main loop reads.
//!
//! The main loop reads bytes only between its stretches of work, and a
//! stretch can outlast the FIFO: 32 bytes at 115,200 baud come in 2.8 ms,
//! while a grbl arc's first line keeps the loop busy for tens of
//! milliseconds (its chords interpreted and planned in one turn). A sender
//! that counts characters keeps up to 128 bytes in flight (grbl advertises
//! a 128-byte receive buffer, `[OPT:,31,128]`), so the FIFO overran and
//! the line that lost bytes came out garbled: streaming an arc and 14
//! lines after it, the session answered 7 `ok` and `error:21` (two lines
//! run together), then waited for lines that had lost their ends. The
//! interrupt stays live inside the board's critical sections (`cs.rs`) at
//! the lowest priority, below the edge and PIO feeder interrupts, which
//! preempt it: it touches only UART0's data and flag registers and the
//! ring's producer end.
//!
//! USB CDC needs none of this: its host waits for the device's endpoint.

use core::sync::atomic::AtomicU32;

use heapless::spsc::{Consumer, Producer, Queue};
use rp2040_hal::pac;

use crate::edges::count;

/// The interrupt's NVIC priority: the lowest, below the edge or PIO
/// feeder interrupt (0) and the input interrupt (0x40).
pub const PRIORITY: u8 = 0xC0;

/// The ring's slots (one stays empty): a grbl sender's 128 bytes in
/// flight twice over and more, and a protocol v1 host's lines.
const RING: usize = 512;

/// Received bytes lost: the ring was full, or the hardware FIFO overran
/// before the interrupt came (its OE flag). For a debugger or the
/// emulator's harness (rp2040py does not model the OE flag).
#[no_mangle]
pub static COGSTEP_UART_OVERRUNS: AtomicU32 = AtomicU32::new(0);

/// The ring's producer, the interrupt's alone once [`init`] has set it
/// (before the interrupt is unmasked).
static mut PRODUCER: Option<Producer<'static, u8>> = None;

/// Makes the ring; returns the main loop's end. Call once, before
/// unmasking `UART0_IRQ`; `None` if called twice.
pub fn init() -> Option<Consumer<'static, u8>> {
    let ring = cortex_m::singleton!(: Queue<u8, RING> = Queue::new())?;
    let (producer, consumer) = ring.split();
    // SAFETY: the interrupt is still masked; nothing else reads PRODUCER.
    unsafe { *core::ptr::addr_of_mut!(PRODUCER) = Some(producer) };
    Some(consumer)
}

/// The interrupt: every byte in the FIFO to the ring (RX at the FIFO's
/// threshold and RX timeout, both cleared as the FIFO empties).
pub fn on_interrupt() {
    // SAFETY: UART0's data and flag registers; the main loop only writes
    // (transmit) and never reads the receive side.
    let uart = unsafe { &*pac::UART0::ptr() };
    // SAFETY: the interrupt is PRODUCER's one user after `init`.
    let Some(producer) = (unsafe { (*core::ptr::addr_of_mut!(PRODUCER)).as_mut() }) else {
        uart.uartimsc()
            .modify(|_, w| w.rxim().clear_bit().rtim().clear_bit());
        return;
    };
    while uart.uartfr().read().rxfe().bit_is_clear() {
        let received = uart.uartdr().read();
        if received.oe().bit_is_set() {
            count(&COGSTEP_UART_OVERRUNS);
        }
        if producer.enqueue(received.data().bits()).is_err() {
            count(&COGSTEP_UART_OVERRUNS);
        }
    }
}

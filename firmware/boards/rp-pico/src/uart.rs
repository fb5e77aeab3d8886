//! UART0's bytes both ways through rings, moved by its interrupt.
//!
//! **Received.** The interrupt moves each byte from the 32-byte hardware
//! FIFO into a ring that the main loop reads. The main loop reads bytes
//! only between its stretches of work, and a stretch can outlast the
//! FIFO: 32 bytes at 115,200 baud come in 2.8 ms, while a grbl arc's
//! first line keeps the loop busy for tens of milliseconds (its chords
//! interpreted and planned in one turn). A sender that counts characters
//! keeps up to 128 bytes in flight (grbl advertises a 128-byte receive
//! buffer, `[OPT:,31,128]`), so the FIFO overran and the line that lost
//! bytes came out garbled: streaming an arc and 14 lines after it, the
//! session answered 7 `ok` and `error:21` (two lines run together), then
//! waited for lines that had lost their ends.
//!
//! **Sent.** The main loop puts its replies into a second ring
//! ([`Transmit`]) and sets the interrupt pending; the interrupt moves
//! them into the hardware FIFO as it has room, its transmit interrupt
//! (the FIFO down to half) on while bytes wait. The main loop used to
//! write each reply into the FIFO itself and wait for room: 32 bytes
//! each 86.8 µs at 115,200 baud, so a status line of four axes (about
//! 250 bytes) held it some 19 ms, while the axes' cores run only 4 ms
//! ahead of the pins. rp2040py sends a byte the moment it is written,
//! which hid that; its harness now sends them at 115,200 baud
//! (`firmware/pico-sim/uart_tx.py`), and the timing scenario at 6,000
//! steps/s made an edge 13.5 ms late with the old way.
//!
//! The interrupt stays live inside the board's critical sections
//! (`cs.rs`) at the lowest priority, below the edge and PIO feeder
//! interrupts, which preempt it: it touches only UART0's data, flag and
//! mask registers, the receive ring's producer end and the transmit
//! ring's consumer end. So the main loop never touches the consumer: it
//! only sets the interrupt pending.
//!
//! USB CDC needs none of this: its host waits for the device's endpoint.

use core::sync::atomic::AtomicU32;

use core::fmt;

use heapless::spsc::{Consumer, Producer, Queue};
use rp2040_hal::pac;
use rp2040_hal::pac::Interrupt;

use crate::edges::count;

/// The interrupt's NVIC priority: the lowest, below the edge or PIO
/// feeder interrupt (0) and the input interrupt (0x40).
pub const PRIORITY: u8 = 0xC0;

/// The receive ring's slots (one stays empty): a grbl sender's 128 bytes
/// in flight twice over and more, and a protocol v1 host's lines.
const RING: usize = 512;

/// The transmit ring's slots (one stays empty): a status line of four
/// axes (about 250 bytes) several times over, and grbl's settings (`$$`,
/// about 600). A reply that finds it full waits for room.
const TX_RING: usize = 2048;

/// Received bytes lost: the ring was full, or the hardware FIFO overran
/// before the interrupt came (its OE flag). For a debugger or the
/// emulator's harness (rp2040py does not model the OE flag).
#[no_mangle]
pub static COGSTEP_UART_OVERRUNS: AtomicU32 = AtomicU32::new(0);

/// The interrupt's ends of the rings: the receive ring's producer and the
/// transmit ring's consumer, the interrupt's alone once [`init`] has set
/// them (before the interrupt is unmasked).
static mut INTERRUPT_ENDS: Option<(Producer<'static, u8>, Consumer<'static, u8>)> = None;

/// The main loop's end of the transmit ring: a reply written here goes
/// out through the interrupt.
pub struct Transmit {
    ring: Producer<'static, u8>,
}

impl Transmit {
    /// Puts `bytes` into the ring and sets the interrupt pending; waits
    /// for room if the ring is full (the interrupt stays live in
    /// critical sections, so it drains).
    pub fn write(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            while self.ring.enqueue(byte).is_err() {
                pend();
                core::hint::spin_loop();
            }
        }
        pend();
    }
}

impl fmt::Write for Transmit {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        self.write(text.as_bytes());
        Ok(())
    }
}

/// Sets UART0's interrupt pending: it sends what the ring holds.
#[inline]
fn pend() {
    cortex_m::peripheral::NVIC::pend(Interrupt::UART0_IRQ);
}

/// Makes the rings; returns the main loop's ends (received bytes to read,
/// replies to send). Call once, before unmasking `UART0_IRQ`; `None` if
/// called twice.
pub fn init() -> Option<(Consumer<'static, u8>, Transmit)> {
    let received = cortex_m::singleton!(: Queue<u8, RING> = Queue::new())?;
    let sent = cortex_m::singleton!(: Queue<u8, TX_RING> = Queue::new())?;
    let (producer, consumer) = received.split();
    let (to_send, sending) = sent.split();
    // SAFETY: the interrupt is still masked; nothing else reads the ends.
    unsafe { *core::ptr::addr_of_mut!(INTERRUPT_ENDS) = Some((producer, sending)) };
    Some((consumer, Transmit { ring: to_send }))
}

/// The interrupt: every byte in the receive FIFO to the receive ring (RX
/// at the FIFO's threshold and RX timeout, both cleared as the FIFO
/// empties), then the transmit ring's bytes into the transmit FIFO while
/// it has room, its interrupt (the FIFO down to half) on while bytes
/// wait. Returns whether a byte came in.
pub fn on_interrupt() -> bool {
    // SAFETY: UART0's data, flag and mask registers: the interrupt's alone
    // once the UART is set up.
    let uart = unsafe { &*pac::UART0::ptr() };
    // SAFETY: the interrupt is the ends' one user after `init`.
    let Some((producer, sending)) =
        (unsafe { (*core::ptr::addr_of_mut!(INTERRUPT_ENDS)).as_mut() })
    else {
        uart.uartimsc()
            .modify(|_, w| w.rxim().clear_bit().rtim().clear_bit().txim().clear_bit());
        return false;
    };
    let mut received = false;
    while uart.uartfr().read().rxfe().bit_is_clear() {
        let byte = uart.uartdr().read();
        received = true;
        if byte.oe().bit_is_set() {
            count(&COGSTEP_UART_OVERRUNS);
        }
        if producer.enqueue(byte.data().bits()).is_err() {
            count(&COGSTEP_UART_OVERRUNS);
        }
    }
    while uart.uartfr().read().txff().bit_is_clear() {
        let Some(byte) = sending.dequeue() else {
            break;
        };
        // SAFETY: any byte is a valid data write.
        uart.uartdr().write(|w| unsafe { w.data().bits(byte) });
    }
    let waiting = sending.peek().is_some();
    uart.uartimsc().modify(|_, w| w.txim().bit(waiting));
    received
}

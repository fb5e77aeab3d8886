//! The receive buffer: grbl's 128-byte serial buffer, realtime bytes taken
//! out on arrival.
//!
//! A sender that streams by character counting keeps at most
//! [`RX_BUFFER_SIZE`] bytes of lines not yet answered in flight; those
//! bytes wait here (or in the line being carried out) until their `ok`.
//! The receiver never drops a byte it accepts and never reorders: a byte
//! that finds the buffer full is refused ([`GrblReceiver::push`] says so),
//! and a board that reads its UART only as far as
//! [`room`](GrblReceiver::room) allows never sees that.

use super::realtime::GrblRealtime;

/// grbl's receive buffer size, bytes (`[OPT:` reports it).
pub const RX_BUFFER_SIZE: usize = 128;

/// What one received byte amounts to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Received {
    /// A line byte, stored in the buffer.
    Stored,
    /// A realtime byte, to act on now.
    Realtime(GrblRealtime),
    /// The buffer was full: the byte was not taken.
    Full,
}

/// A ring of line bytes in arrival order.
#[derive(Clone, Debug, Default)]
pub struct GrblReceiver {
    bytes: heapless::Deque<u8, RX_BUFFER_SIZE>,
}

impl GrblReceiver {
    /// An empty buffer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one byte from the wire.
    pub fn push(&mut self, byte: u8) -> Received {
        if let Some(realtime) = GrblRealtime::from_byte(byte) {
            return Received::Realtime(realtime);
        }
        match self.bytes.push_back(byte) {
            Ok(()) => Received::Stored,
            Err(_) => Received::Full,
        }
    }

    /// The oldest line byte, taken out.
    pub fn pop(&mut self) -> Option<u8> {
        self.bytes.pop_front()
    }

    /// How many more bytes fit.
    pub fn room(&self) -> usize {
        RX_BUFFER_SIZE - self.bytes.len()
    }

    /// How many line bytes wait.
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    /// No line byte waits.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Forgets every buffered byte (a soft reset does).
    pub fn clear(&mut self) {
        self.bytes.clear();
    }
}

//! The handshake by which an axis's words reach its DMA channel: the main
//! loop writes each word into the axis's ring and counts it
//! ([`RingWriter`], [`RingCounts::publish`]); the DMA interrupt hands an
//! idle channel the words counted since it last started
//! ([`RingCounts::arm`]); the channel reads them in order, its read slot
//! telling the writer which slots are free again ([`Channel::read_slot`]).
//!
//! The board (`firmware/boards/rp-pico/src/pio.rs`) runs this very code
//! on the DMA's registers; `tests/ring_loom.rs` model-checks it with loom
//! (`RUSTFLAGS="--cfg loom"`), the channel and the interrupt as threads
//! of their own: every word reaches the channel once, in order, and no
//! slot is written while the channel may still read it.

#[cfg(loom)]
use loom::sync::atomic::{AtomicU32, Ordering};

#[cfg(not(loom))]
use core::sync::atomic::{AtomicU32, Ordering};

/// What the handshake needs of a DMA channel reading a ring of `N` slots.
pub trait Channel {
    /// Whether the channel is moving words (started and not done), read
    /// in one order with the count's store and load (see
    /// [`RingCounts::publish`]).
    fn busy(&self) -> bool;
    /// The slot the channel reads next, in `0..N`: the slots from the
    /// writer's next one up to it are free.
    fn read_slot(&self) -> usize;
    /// Starts the idle channel on the `count` words from its read slot on.
    fn start(&self, count: u32);
}

/// The counts the writer and the interrupt share: words written to the
/// ring since boot, and words handed to the channel (both wrapping).
#[derive(Debug)]
pub struct RingCounts {
    written: AtomicU32,
    armed: AtomicU32,
}

impl RingCounts {
    /// No word written, none handed out.
    #[cfg(not(loom))]
    pub const fn new() -> RingCounts {
        RingCounts {
            written: AtomicU32::new(0),
            armed: AtomicU32::new(0),
        }
    }

    /// No word written, none handed out.
    #[cfg(loom)]
    pub fn new() -> RingCounts {
        RingCounts {
            written: AtomicU32::new(0),
            armed: AtomicU32::new(0),
        }
    }

    /// The writer's count published: the words it has written (their
    /// slots stored before) are the channel's to take.
    ///
    /// Sequentially consistent, as is the read in [`RingCounts::arm`]:
    /// the writer stores the count and then looks whether the channel is
    /// busy (to raise the interrupt if it is not), while the channel's end
    /// clears busy and then the interrupt reads the count. With only
    /// release and acquire both could see the old value, and the words
    /// would wait for a start that never comes (loom finds that
    /// interleaving). On the chip the core's own accesses keep their order
    /// and the interrupt runs on the same core: one order, as here.
    #[inline(always)]
    pub fn publish<const N: usize>(&self, writer: &RingWriter<N>) {
        self.written.store(writer.written, Ordering::SeqCst);
    }

    /// The interrupt's side: if `channel` is idle, starts it on the words
    /// published since it last started (it reads on from where it
    /// stopped). Only one context calls this (the DMA interrupt; its set-up
    /// before that is unmasked).
    #[inline(always)]
    pub fn arm(&self, channel: &impl Channel) {
        if channel.busy() {
            return;
        }
        let written = self.written.load(Ordering::SeqCst);
        let count = written.wrapping_sub(self.armed.load(Ordering::Relaxed));
        if count == 0 {
            return;
        }
        self.armed.store(written, Ordering::Relaxed);
        channel.start(count);
    }
}

impl Default for RingCounts {
    fn default() -> RingCounts {
        RingCounts::new()
    }
}

/// The writer's end of a ring of `N` slots (a power of two): which slot
/// comes next and which are free. One slot stays free, so that a full
/// ring and an empty one differ.
#[derive(Clone, Debug)]
pub struct RingWriter<const N: usize = 512> {
    /// Words written since boot (wrapping).
    written: u32,
}

impl<const N: usize> RingWriter<N> {
    const POWER_OF_TWO: () = assert!(N.is_power_of_two() && N >= 2);

    /// An empty ring, its channel at slot 0.
    pub const fn new() -> RingWriter<N> {
        let () = Self::POWER_OF_TWO;
        RingWriter { written: 0 }
    }

    /// The words the ring holds at most.
    pub const fn capacity(&self) -> usize {
        N - 1
    }

    /// Words written and not yet read by `channel`.
    #[inline(always)]
    pub fn len(&self, channel: &impl Channel) -> usize {
        (self.written as usize).wrapping_sub(channel.read_slot()) & (N - 1)
    }

    /// Whether `channel` has read every word written.
    pub fn is_empty(&self, channel: &impl Channel) -> bool {
        self.len(channel) == 0
    }

    /// Free slots now (the channel only frees more).
    #[inline(always)]
    pub fn room(&self, channel: &impl Channel) -> usize {
        self.capacity() - self.len(channel)
    }

    /// The slot the next word goes to: free while [`RingWriter::room`] was
    /// not 0 since the last [`RingWriter::advance`].
    #[inline(always)]
    pub fn next_slot(&self) -> usize {
        self.written as usize & (N - 1)
    }

    /// The word is in [`RingWriter::next_slot`]: on to the next. The
    /// channel gets it once [`RingCounts::publish`] has counted it.
    #[inline(always)]
    pub fn advance(&mut self) {
        self.written = self.written.wrapping_add(1);
    }
}

impl<const N: usize> Default for RingWriter<N> {
    fn default() -> RingWriter<N> {
        RingWriter::new()
    }
}

//! The ring handshake (`cogstep_pio_steps::ring`) model-checked with loom:
//! the main loop writing words and the DMA channel reading them, each a
//! thread, and the DMA interrupt that hands the words out run whole, one
//! at a time, by whoever raises it (the main loop's kick, the channel's
//! completion), in every interleaving loom explores (a superset of what
//! the chip allows: there the interrupt stops the main loop while it
//! runs, and the channel is hardware).
//!
//!     RUSTFLAGS="--cfg loom" CARGO_TARGET_DIR=target/loom \
//!         cargo test --manifest-path firmware/Cargo.toml -p cogstep-pio-steps --release --test ring_loom
#![cfg(loom)]

use cogstep_pio_steps::ring::{Channel, RingCounts, RingWriter};
use loom::cell::UnsafeCell;
use loom::sync::atomic::{AtomicBool, AtomicU32, AtomicUsize, Ordering};
use loom::sync::{Arc, Mutex};
use loom::thread;

/// Slots of the model's ring (three words at most in it).
const N: usize = 4;
/// Words the main loop writes: more than the ring holds, so that it waits
/// for room and wraps.
const WORDS: u32 = 5;

/// The DMA channel as the handshake sees it, and the ring it reads.
struct Dma {
    slots: [UnsafeCell<u32>; N],
    busy: AtomicBool,
    read: AtomicUsize,
    remaining: AtomicU32,
    /// Words the channel has moved.
    moved: AtomicU32,
}

impl Channel for Dma {
    fn busy(&self) -> bool {
        self.busy.load(Ordering::SeqCst)
    }
    fn read_slot(&self) -> usize {
        self.read.load(Ordering::Acquire)
    }
    fn start(&self, count: u32) {
        assert!(!self.busy.load(Ordering::Relaxed), "started while busy");
        self.remaining.store(count, Ordering::Relaxed);
        self.busy.store(true, Ordering::SeqCst);
    }
}

struct Shared {
    dma: Dma,
    counts: RingCounts,
    /// The DMA interrupt runs whole, one at a time: whoever raises it
    /// (the main loop's kick, a channel done) runs it under this lock.
    interrupt: Mutex<()>,
}

impl Shared {
    /// The DMA interrupt, raised.
    fn interrupt(&self) {
        let _whole = self.interrupt.lock().unwrap();
        self.counts.arm(&self.dma);
    }
}

#[test]
fn every_word_reaches_the_channel_once_in_order_and_no_slot_is_written_while_it_may_be_read() {
    let mut builder = loom::model::Builder::new();
    builder.preemption_bound = Some(3);
    builder.max_branches = 100_000;
    builder.check(|| {
        let shared = Arc::new(Shared {
            dma: Dma {
                slots: core::array::from_fn(|_| UnsafeCell::new(0)),
                busy: AtomicBool::new(false),
                read: AtomicUsize::new(0),
                remaining: AtomicU32::new(0),
                moved: AtomicU32::new(0),
            },
            counts: RingCounts::new(),
            interrupt: Mutex::new(()),
        });

        // The channel: one word a turn while started.
        let channel = {
            let shared = Arc::clone(&shared);
            thread::spawn(move || {
                let dma = &shared.dma;
                loop {
                    let moved = dma.moved.load(Ordering::Relaxed);
                    if moved == WORDS {
                        break;
                    }
                    if !dma.busy.load(Ordering::SeqCst) {
                        thread::yield_now();
                        continue;
                    }
                    let slot = dma.read.load(Ordering::Relaxed);
                    let word = dma.slots[slot].with(|word| unsafe { *word });
                    assert_eq!(word, 100 + moved, "word {moved} out of order");
                    dma.moved.store(moved + 1, Ordering::Relaxed);
                    dma.read.store((slot + 1) % N, Ordering::Release);
                    let remaining = dma.remaining.load(Ordering::Relaxed) - 1;
                    dma.remaining.store(remaining, Ordering::Relaxed);
                    if remaining == 0 {
                        dma.busy.store(false, Ordering::SeqCst);
                        // Its completion raises the interrupt.
                        shared.interrupt();
                    }
                }
            })
        };

        // The main loop: each word into a free slot, counted, and the
        // interrupt raised if the channel is idle.
        let mut writer = RingWriter::<N>::new();
        let dma = &shared.dma;
        for word in 0..WORDS {
            while writer.room(dma) == 0 {
                thread::yield_now();
            }
            dma.slots[writer.next_slot()].with_mut(|slot| unsafe { *slot = 100 + word });
            writer.advance();
            shared.counts.publish(&writer);
            if !dma.busy() {
                shared.interrupt();
            }
        }
        channel.join().unwrap();
        assert!(writer.is_empty(dma));
    });
}

//! Watching the pins: per-cog edge rings and the sinks they drain into.
//!
//! A cog never waits on an observer. Each cog pushes its edges into its own
//! bounded lock-free ring ([`crossbeam::queue::ArrayQueue`]); the hub drains
//! the rings into the in-memory trace. With the real clock a full ring drops
//! the edge and counts it ([`Hub::trace_overflows`](crate::Hub::trace_overflows)
//! — never silent). With the virtual clock time only moves while the hub
//! drains, so a cog whose ring is full waits for room instead: the trace is
//! complete and the edges' times are unaffected.
//!
//! Sinks: the in-memory trace ([`Hub::trace`](crate::Hub::trace)), which
//! also holds the input pins' edges ([`Hub::set_input`](crate::Hub::set_input));
//! VCD files that open in GTKWave or PulseView, written whole
//! ([`Hub::write_vcd`](crate::Hub::write_vcd)) or streamed as edges come
//! ([`VcdStream`], [`Recorder`]); and the per-pin rising-edge counters
//! ([`Hub::rising_edges`](crate::Hub::rising_edges)), which are always on.
//!
//! - `waveform`: [`VcdStream`], [`Signal`] (a pin's role name and level),
//!   [`Timebase`] (CT ticks to VCD time), [`write_vcd`].
//! - `record`: [`Recorder`], a thread that streams a running hub's edges to
//!   a VCD in bounded memory.

use crossbeam::queue::ArrayQueue;

use crate::pins::Edge;
use crate::sync::{AtomicU64, Ordering};

mod record;
mod waveform;

pub use record::{RecordSummary, Recorder, RecorderOptions, LOST_MARKER_NAME};
pub use waveform::{write_vcd, Signal, Timebase, VcdError, VcdStream};

/// One cog's edge ring.
#[derive(Debug)]
pub(crate) struct EdgeTap {
    ring: Option<ArrayQueue<Edge>>,
    overflows: AtomicU64,
}

impl EdgeTap {
    /// A tap that records up to `capacity` undrained edges, or none at all.
    pub fn new(capacity: Option<usize>) -> Self {
        Self {
            ring: capacity.map(|c| ArrayQueue::new(c.max(16))),
            overflows: AtomicU64::new(0),
        }
    }

    /// Whether edges are recorded at all.
    pub fn enabled(&self) -> bool {
        self.ring.is_some()
    }

    /// Pushes an edge; on a full ring, counts it as lost.
    pub fn push_or_count(&self, edge: Edge) {
        if let Some(ring) = &self.ring {
            if ring.push(edge).is_err() {
                self.overflows.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Pushes an edge, waiting for the drainer while the ring is full.
    /// `give_up` is polled while waiting (shutdown).
    pub fn push_waiting(&self, mut edge: Edge, give_up: impl Fn() -> bool) {
        if let Some(ring) = &self.ring {
            while let Err(back) = ring.push(edge) {
                if give_up() {
                    self.overflows.fetch_add(1, Ordering::Relaxed);
                    return;
                }
                edge = back;
                std::thread::yield_now();
            }
        }
    }

    /// Moves the waiting edges into `into`.
    pub fn drain_into(&self, into: &mut Vec<Edge>) {
        if let Some(ring) = &self.ring {
            while let Some(edge) = ring.pop() {
                into.push(edge);
            }
        }
    }

    pub fn overflows(&self) -> u64 {
        self.overflows.load(Ordering::Relaxed)
    }
}

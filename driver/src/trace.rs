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
//! Sinks: the in-memory trace ([`Hub::trace`](crate::Hub::trace)), a VCD
//! file ([`write_vcd`]) that opens in GTKWave or PulseView, and the per-pin
//! rising-edge counters ([`Hub::rising_edges`](crate::Hub::rising_edges)),
//! which are always on.

use std::collections::BTreeMap;
use std::io;

use crossbeam::queue::ArrayQueue;

use crate::pins::Edge;
use crate::sync::{AtomicU64, Ordering};

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

/// Writes edges as a VCD file: one wire per pin that has an edge, named
/// `pin<N>` or by `names`, time in nanoseconds when the clock divides 1 GHz
/// evenly, else in picoseconds. The edges need not be sorted.
pub fn write_vcd<W: io::Write>(
    out: W,
    edges: &[Edge],
    clkfreq: u32,
    names: &BTreeMap<u8, String>,
) -> io::Result<()> {
    let mut sorted = edges.to_vec();
    sorted.sort_unstable();
    let (unit, per_second) = if clkfreq > 0 && 1_000_000_000 % clkfreq == 0 {
        (vcd::TimescaleUnit::NS, 1_000_000_000u128)
    } else {
        (vcd::TimescaleUnit::PS, 1_000_000_000_000u128)
    };
    let mut writer = vcd::Writer::new(out);
    writer.timescale(1, unit)?;
    writer.add_module("cogstep")?;
    let mut ids = BTreeMap::new();
    for edge in &sorted {
        if let std::collections::btree_map::Entry::Vacant(slot) = ids.entry(edge.pin) {
            let name = names
                .get(&edge.pin)
                .cloned()
                .unwrap_or_else(|| format!("pin{}", edge.pin));
            slot.insert(writer.add_wire(1, &name)?);
        }
    }
    writer.upscope()?;
    writer.enddefinitions()?;
    writer.timestamp(0)?;
    for id in ids.values() {
        writer.change_scalar(*id, vcd::Value::V0)?;
    }
    let mut last_time = 0u64;
    for edge in &sorted {
        let time = u64::try_from(u128::from(edge.ct) * per_second / u128::from(clkfreq.max(1)))
            .unwrap_or(u64::MAX);
        if time != last_time {
            writer.timestamp(time)?;
            last_time = time;
        }
        if let Some(id) = ids.get(&edge.pin) {
            let value = if edge.level {
                vcd::Value::V1
            } else {
                vcd::Value::V0
            };
            writer.change_scalar(*id, value)?;
        }
    }
    Ok(())
}

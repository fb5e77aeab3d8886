//! The edge trace: the cogs' rings drained into it (by a thread with the
//! real clock), read in time order, written as VCD, and the pins by role.

use std::sync::Arc;
use std::time::Duration;

use super::{lock, Hub, HubError};
use crate::clock::ClockMode;
use crate::cog::CogShared;
use crate::pins::Edge;
use crate::sync::Ordering;
use crate::trace::{write_vcd, Signal, VcdError};

impl Hub {
    pub(super) fn drain(&self) {
        let cogs = lock(&self.inner.cogs);
        self.drain_taps(cogs.iter().map(|slot| &*slot.shared), &mut Vec::new());
    }

    /// Moves the edges waiting in `cogs`' rings into the trace.
    pub(super) fn drain_taps<'a>(
        &self,
        cogs: impl Iterator<Item = &'a CogShared>,
        buffer: &mut Vec<Edge>,
    ) {
        for cog in cogs {
            cog.tap.drain_into(buffer);
        }
        if !buffer.is_empty() {
            lock(&self.inner.trace).append(buffer);
        }
    }

    /// Real clock with tracing: a thread drains the rings every millisecond.
    ///
    /// It holds the hub weakly and upgrades it for each drain, so the hub's
    /// last reference may go on this thread: [`HubInner`]'s drop then
    /// stops every cog from here and leaves this thread to end by itself.
    pub(super) fn start_drainer(&self) -> Result<(), HubError> {
        let weak = Arc::downgrade(&self.inner);
        let stop = Arc::clone(&self.inner.drainer_stop);
        #[cfg(all(test, not(loom)))]
        let probe = Arc::clone(&self.inner.drainer_probe);
        let thread = std::thread::Builder::new()
            .name("hub-drain".into())
            .spawn(move || {
                while !stop.load(Ordering::Acquire) {
                    match weak.upgrade() {
                        Some(inner) => {
                            let hub = Hub { inner };
                            hub.drain();
                            #[cfg(all(test, not(loom)))]
                            probe.hold_here();
                            // May be the last reference: the hub drops here.
                            drop(hub);
                        }
                        None => break,
                    }
                    std::thread::sleep(Duration::from_millis(1));
                }
                #[cfg(all(test, not(loom)))]
                probe.ended();
            })?;
        *lock(&self.inner.drainer) = Some(thread);
        Ok(())
    }

    /// Every edge recorded so far (with `trace_edges`), inputs included, in
    /// time order (one pin's edges at one CT in the order they happened).
    pub fn trace(&self) -> Vec<Edge> {
        if self.inner.config.clock == ClockMode::Real {
            self.drain();
        }
        let mut edges = lock(&self.inner.trace).clone();
        // Stable: one pin's edges at one CT (an input pulse) keep their order.
        edges.sort_by_key(|edge| (edge.ct, edge.pin));
        edges
    }

    /// Takes the recorded edges out of the hub, in time order.
    pub fn take_trace(&self) -> Vec<Edge> {
        if self.inner.config.clock == ClockMode::Real {
            self.drain();
        }
        let mut edges = std::mem::take(&mut *lock(&self.inner.trace));
        edges.sort_by_key(|edge| (edge.ct, edge.pin));
        edges
    }

    /// Edges lost because a ring was full (real clock only; never silent).
    pub fn trace_overflows(&self) -> u64 {
        lock(&self.inner.cogs)
            .iter()
            .map(|slot| slot.shared.tap.overflows())
            .sum()
    }

    /// Writes the trace as a VCD file (GTKWave, PulseView): every started
    /// axis's pins by role ([`Hub::signals`]), all low at time 0 = CT 0,
    /// then every edge (inputs included) up to now. A hub without
    /// `trace_edges` has no edges: [`VcdError::TracingOff`], nothing written.
    pub fn write_vcd<W: std::io::Write>(&self, out: W) -> Result<(), VcdError> {
        if !self.inner.config.trace_edges {
            return Err(VcdError::TracingOff);
        }
        let edges = self.trace();
        let signals: Vec<Signal> = lock(&self.inner.pin_names).values().cloned().collect();
        let end = edges.last().map_or(0, |edge| edge.ct).max(self.now());
        Ok(write_vcd(
            out,
            &edges,
            self.inner.config.clkfreq,
            &signals,
            end,
        )?)
    }

    /// Every pin of every axis started so far, by role name (`axis1_step`,
    /// `axis1_dir`, `axis1_stop`, `axis2_cw`, …; axis N is cog N − 1), with
    /// its level now.
    pub fn signals(&self) -> Vec<Signal> {
        let mut signals: Vec<Signal> = lock(&self.inner.pin_names).values().cloned().collect();
        for signal in &mut signals {
            signal.level = if signal.input {
                self.input(signal.pin)
            } else {
                self.output(signal.pin)
            };
        }
        signals
    }
}

//! The system counter: CT now, the virtual clock's epochs (every cog runs
//! to one target), and waiting for the axes to go idle.

use std::sync::Arc;
use std::time::Duration;

use super::{lock, Hub};
use crate::clock::ClockMode;
use crate::cog::CogShared;
use crate::path::PATH_SLICE_MS;
use crate::sync::Ordering;
use cogstep_motion::axis::Mode;

impl Hub {
    /// The system counter CT, in clkfreq ticks.
    pub fn now(&self) -> u64 {
        self.inner.shared.now()
    }

    /// Virtual clock: advances CT by `ticks`, every cog making the steps
    /// due until then. Returns the new CT. (With the real clock, time
    /// advances by itself: this waits `ticks` of real time instead.)
    pub fn advance(&self, ticks: u64) -> u64 {
        match self.inner.config.clock {
            ClockMode::Virtual => {
                let target = self.inner.shared.epochs.now().saturating_add(ticks);
                self.advance_virtual(target);
                target
            }
            ClockMode::Real => {
                let wait = self
                    .inner
                    .shared
                    .real
                    .until(self.now().saturating_add(ticks));
                std::thread::sleep(wait);
                self.drain();
                self.now()
            }
        }
    }

    /// Runs until every axis is idle (no step left to make, nothing it could
    /// start without an input changing), and returns the CT then: with the
    /// virtual clock, the moment the last axis became ready. With the real
    /// clock this waits for it.
    pub fn run_until_idle(&self) -> u64 {
        match self.inner.config.clock {
            ClockMode::Virtual => {
                // Paths first, slice by slice, until none has steps to make.
                while self.run_path_slice(u64::MAX) {}
                let mut epoch_cogs = lock(&self.inner.advancing);
                self.run_epoch(u64::MAX, &mut epoch_cogs);
                let now = self.inner.shared.epochs.now();
                let end = lock(&self.inner.cogs)
                    .iter()
                    .map(|slot| slot.shared.epoch_done.ct())
                    .fold(now, u64::max);
                self.inner.shared.epochs.set_now(end);
                end
            }
            ClockMode::Real => {
                while self.axes_busy() {
                    std::thread::sleep(Duration::from_millis(1));
                }
                self.drain();
                self.now()
            }
        }
    }

    /// Virtual clock: runs every cog to `target`; while a look-ahead path
    /// has steps to make, in slices of [`PATH_SLICE_MS`], the paths looking
    /// at their inputs and computing their edges before each.
    fn advance_virtual(&self, target: u64) {
        while self.inner.shared.epochs.now() < target && self.run_path_slice(target) {}
        if self.inner.shared.epochs.now() < target {
            let mut epoch_cogs = lock(&self.inner.advancing);
            self.run_epoch(target, &mut epoch_cogs);
            self.inner.shared.epochs.set_now(target);
        }
    }

    /// One slice of the active paths towards `target` (virtual clock);
    /// false when no path is active (nothing was run).
    fn run_path_slice(&self, target: u64) -> bool {
        let active: Vec<_> = self
            .live_paths()
            .into_iter()
            .filter(|path| path.is_active())
            .collect();
        if active.is_empty() {
            return false;
        }
        let mut epoch_cogs = lock(&self.inner.advancing);
        let now = self.inner.shared.epochs.now();
        let slice = u64::from(self.inner.config.clkfreq) / 1_000 * PATH_SLICE_MS;
        let to = target.min(now.saturating_add(slice.max(1)));
        for path in &active {
            path.service(now, to);
        }
        self.run_epoch(to, &mut epoch_cogs);
        self.inner.shared.epochs.set_now(to);
        true
    }

    /// Whether some axis still moves, or has a command not yet answered.
    fn axes_busy(&self) -> bool {
        lock(&self.inner.cogs).iter().any(|slot| {
            let shared = &slot.shared;
            let status = &shared.mailbox.status;
            !shared.is_shut_down()
                && (shared.mailbox.slot_in_use()
                    || Mode(status.mode.load(Ordering::Acquire)).has(Mode::MOVING))
        })
    }

    /// One virtual epoch: every cog runs to `target`, the rings are drained.
    /// `cogs` is scratch space for the list of cogs (its capacity is kept).
    fn run_epoch(&self, target: u64, cogs: &mut Vec<Arc<CogShared>>) {
        let shared = &self.inner.shared;
        cogs.clear();
        cogs.extend(
            lock(&self.inner.cogs)
                .iter()
                .map(|slot| Arc::clone(&slot.shared)),
        );
        *lock(&shared.waiter) = Some(std::thread::current());
        let epoch = shared.epochs.open(target);
        for cog in cogs.iter() {
            cog.kick();
        }
        let mut buffer = Vec::new();
        loop {
            self.drain_taps(cogs.iter().map(|cog| &**cog), &mut buffer);
            let done = cogs
                .iter()
                .all(|cog| cog.epoch_done.is_done(epoch) || cog.shutdown.load(Ordering::Acquire));
            if done {
                break;
            }
            std::thread::park_timeout(Duration::from_micros(200));
        }
        self.drain_taps(cogs.iter().map(|cog| &**cog), &mut buffer);
        *lock(&shared.waiter) = None;
        // Stopped cogs' threads end when the last handle goes.
        cogs.clear();
    }

    /// The highest step rate a cog can sustain at this clock, given the
    /// CORDIC work of a ramp step (steps/s).
    pub fn max_step_rate(&self) -> u64 {
        u64::from(self.inner.config.clkfreq) / self.inner.math_ticks.max(1)
    }
}

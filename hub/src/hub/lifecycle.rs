//! A hub's life and its cogs': the hub built, cogs started on pins, an
//! axis released, every cog stopped (on shutdown, and on the drop, wherever
//! the last reference goes).

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use super::config::step_math_ticks;
use super::{lock, CogSlot, Hub, HubConfig, HubError, HubInner};
use crate::axis::Axis;
use crate::clock::{ClockMode, Epochs, RealClock};
use crate::cog::{Cog, CogShared, HubShared};
use crate::pins::{Outputs, PinBank, PIN_COUNT};
use crate::sync::{AtomicBool, Ordering};
use crate::trace::{EdgeTap, Signal};
use cogstep_motion::axis_core::AxisCore;
use cogstep_motion::profile::scurve;

impl Hub {
    /// A hub with no cogs yet.
    pub fn new(config: HubConfig) -> Result<Self, HubError> {
        if config.clkfreq < 1_000 {
            return Err(HubError::Config("clkfreq must be at least 1,000 Hz"));
        }
        if config.pulse_ticks == 0 {
            return Err(HubError::Config("the step pulse must last at least 1 tick"));
        }
        if config.max_cogs == 0 || config.max_cogs > usize::from(PIN_COUNT) {
            return Err(HubError::Config("max_cogs must be 1 to 64"));
        }
        scurve::plan(&config.scurve(), 1, 1)?;
        let shared = Arc::new(HubShared {
            clock: config.clock,
            pins: PinBank::default(),
            real: RealClock::new(config.clkfreq),
            epochs: Epochs::default(),
            waiter: Mutex::new(None),
            realtime_priority: config.realtime_priority,
        });
        let hub = Hub {
            inner: Arc::new(HubInner {
                config,
                shared,
                cogs: Mutex::new(Vec::new()),
                claimed: Mutex::new(0),
                switch_pins: Mutex::new(0),
                advancing: Mutex::new(Vec::new()),
                trace: Mutex::new(Vec::new()),
                pin_names: Mutex::new(BTreeMap::new()),
                next_id: Mutex::new(0),
                grouping: Mutex::new(()),
                paths: Mutex::new(Vec::new()),
                math_ticks: step_math_ticks(),
                drainer_stop: Arc::new(AtomicBool::new(false)),
                drainer: Mutex::new(None),
                #[cfg(all(test, not(loom)))]
                drainer_probe: Arc::default(),
            }),
        };
        if config.clock == ClockMode::Real && config.trace_edges {
            hub.start_drainer()?;
        }
        Ok(hub)
    }

    /// The configuration the hub runs with.
    pub fn config(&self) -> &HubConfig {
        &self.inner.config
    }

    /// Starts a cog driving a step/dir (`sd`) driver.
    pub fn start_sd(&self, stop_pin: u8, step_pin: u8, dir_pin: u8) -> Result<Axis, HubError> {
        self.start(
            stop_pin,
            Outputs::StepDir {
                step: step_pin,
                dir: dir_pin,
            },
        )
    }

    /// Starts a cog driving a cw/ccw (`cc`) driver.
    pub fn start_cc(&self, stop_pin: u8, cw_pin: u8, ccw_pin: u8) -> Result<Axis, HubError> {
        self.start(
            stop_pin,
            Outputs::CwCcw {
                cw: cw_pin,
                ccw: ccw_pin,
            },
        )
    }

    /// Starts a cog on `stop_pin` and `outputs`.
    pub fn start(&self, stop_pin: u8, outputs: Outputs) -> Result<Axis, HubError> {
        let pins = [stop_pin, outputs.pins()[0], outputs.pins()[1]];
        let mut mask = 0u64;
        for pin in pins {
            if pin >= PIN_COUNT {
                return Err(HubError::PinOutOfRange(pin));
            }
            if mask & (1 << pin) != 0 {
                return Err(HubError::PinInUse(pin));
            }
            mask |= 1 << pin;
        }
        let mut cogs = lock(&self.inner.cogs);
        if cogs.len() >= self.inner.config.max_cogs {
            return Err(HubError::TooManyCogs {
                max: self.inner.config.max_cogs,
            });
        }
        let mut claimed = lock(&self.inner.claimed);
        if let Some(pin) = pins.iter().find(|p| *claimed & (1 << **p) != 0) {
            return Err(HubError::PinInUse(*pin));
        }
        let id = {
            let mut next = lock(&self.inner.next_id);
            *next += 1;
            *next - 1
        };
        let tap = EdgeTap::new(
            self.inner
                .config
                .trace_edges
                .then_some(self.inner.config.trace_ring),
        );
        let shared = Arc::new(CogShared::new(id, outputs, stop_pin, tap));
        // The offset is a hub setting: show it before the cog has run at all.
        shared
            .mailbox
            .status
            .show_offset(self.inner.config.offset_deg);
        let hub_shared = Arc::clone(&self.inner.shared);
        let start_ct = hub_shared.now();
        let mut core = AxisCore::new(self.core_config(outputs), start_ct);
        core.set_stop_pin(start_ct, hub_shared.pins.input(stop_pin));
        let cog = Cog::new(Arc::clone(&shared), hub_shared, core, start_ct);
        let thread = std::thread::Builder::new()
            .name(format!("cog{id}"))
            .spawn(move || cog.run())?;
        *lock(&shared.thread) = Some(thread.thread().clone());
        *claimed |= mask;
        cogs.push(CogSlot {
            shared: Arc::clone(&shared),
            thread: Some(thread),
        });
        drop(claimed);
        drop(cogs);
        let mut names = lock(&self.inner.pin_names);
        for signal in Signal::of_axis(id, stop_pin, outputs) {
            names.insert(signal.pin, signal);
        }
        Ok(Axis {
            hub: self.clone(),
            shared,
        })
    }

    /// Stops every cog (threads joined, pins released).
    pub fn shutdown(&self) {
        let slots: Vec<CogSlot> = lock(&self.inner.cogs).drain(..).collect();
        for mut slot in slots {
            stop_cog(&mut slot);
        }
        *lock(&self.inner.claimed) = 0;
        *lock(&self.inner.switch_pins) = 0;
    }

    pub(crate) fn release(&self, id: usize) {
        let slot = {
            let mut cogs = lock(&self.inner.cogs);
            cogs.iter()
                .position(|slot| slot.shared.id == id)
                .map(|i| cogs.remove(i))
        };
        if let Some(mut slot) = slot {
            let pins = [
                slot.shared.stop_pin,
                slot.shared.outputs.pins()[0],
                slot.shared.outputs.pins()[1],
            ];
            stop_cog(&mut slot);
            let switches = lock(&slot.shared.switches)
                .iter()
                .fold(0u64, |mask, switch| mask | (1u64 << switch.pin));
            let mut claimed = lock(&self.inner.claimed);
            for pin in pins {
                *claimed &= !(1u64 << pin);
            }
            *claimed &= !switches;
            *lock(&self.inner.switch_pins) &= !switches;
        }
    }
}

fn stop_cog(slot: &mut CogSlot) {
    slot.shared.shutdown.store(true, Ordering::Release);
    slot.shared.kick();
    if let Some(thread) = slot.thread.take() {
        let _ = thread.join();
    }
}

impl Drop for HubInner {
    /// Runs wherever the last reference goes: on a user's thread, or on
    /// the drainer's (its temporary handle can be the last). A thread
    /// cannot join itself, so the drainer is joined only from another
    /// thread; on its own it is left to end (the stop flag is set and the
    /// hub it would upgrade is gone). Every cog is stopped either way.
    fn drop(&mut self) {
        self.drainer_stop.store(true, Ordering::Release);
        if let Some(thread) = lock(&self.drainer).take() {
            if thread.thread().id() != std::thread::current().id() {
                let _ = thread.join();
            }
        }
        let slots: Vec<CogSlot> = lock(&self.cogs).drain(..).collect();
        for mut slot in slots {
            stop_cog(&mut slot);
        }
    }
}

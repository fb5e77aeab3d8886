//! What the cogs see from outside: input pins (stop pins, limits), the
//! simulated switches driven by where an axis is, the output pins, and
//! emergency stops.

use std::sync::Arc;

use super::{lock, Hub, HubError};
use crate::axis::Axis;
use crate::cog::CogShared;
use crate::pins::{Edge, PIN_COUNT};
use crate::switch::{Bounce, DemoSwitches, Switch};
use crate::sync::Ordering;
use crate::trace::Signal;
use cogstep_motion::axis::AxisError;

impl Hub {
    /// Drives an input pin (a stop pin: high = run, low = controlled stop).
    /// With `trace_edges`, a change of level is an edge in the trace at
    /// that CT. Takes effect at the CT [`Hub::now`] shows: with the virtual clock,
    /// the cog on that stop pin has seen the level when this returns, so
    /// even a pulse given between two advances is never missed.
    pub fn set_input(&self, pin: u8, level: bool) -> Result<(), HubError> {
        if pin >= PIN_COUNT {
            return Err(HubError::PinOutOfRange(pin));
        }
        if *lock(&self.inner.switch_pins) & (1 << pin) != 0 {
            return Err(HubError::SwitchPin(pin));
        }
        let was = self.inner.shared.pins.set_input(pin, level);
        if was != level && self.inner.config.trace_edges {
            let ct = self.now();
            lock(&self.inner.trace).push(Edge { ct, pin, level });
        }
        // Every axis that acts on the pin: its stop pin, a limit, a home switch.
        let watchers: Vec<Arc<CogShared>> = lock(&self.inner.cogs)
            .iter()
            .filter(|slot| {
                slot.shared.stop_pin == pin
                    || slot.shared.watched.load(Ordering::Acquire) & (1 << pin) != 0
            })
            .map(|slot| Arc::clone(&slot.shared))
            .collect();
        let mut stopped_members: Vec<Arc<CogShared>> = Vec::new();
        for cog in watchers {
            if !level && cog.stop_pin == pin {
                // A stop pin low on any member stops its whole group.
                let group = lock(&cog.group).clone();
                if let Some(group) = group.filter(|group| group.is_live()) {
                    group.stop_after(self.group_stop_ct());
                    stopped_members.extend(
                        group
                            .members
                            .iter()
                            .filter_map(std::sync::Weak::upgrade)
                            .filter(|member| member.id != cog.id),
                    );
                }
            }
            // The cog has seen the level when this returns (real time: within
            // microseconds). A cog that is gone has no axis left to stop.
            let _ = cog.refresh();
        }
        // Every member has taken the group's stop when this returns.
        for member in stopped_members {
            let _ = member.refresh();
        }
        Ok(())
    }

    /// Attaches a simulated switch to `axis`: `pin` reads `active_level`
    /// while the axis's physical position (the signed count of its own step
    /// edges since it started, whatever set_position or homing did) lies in
    /// `active`, and the other level elsewhere. The axis sees it on the
    /// exact step that changes it, in virtual and real time (see
    /// [`crate::switch`]). The pin is the switch's until the axis stops.
    pub fn attach_switch(
        &self,
        pin: u8,
        axis: &Axis,
        active: std::ops::RangeInclusive<i64>,
        active_level: bool,
    ) -> Result<(), HubError> {
        self.attach_bouncing_switch(pin, axis, active, active_level, Bounce::default())
    }

    /// Fits axis `index`'s [`DemoSwitches`]: its home switch and both
    /// hard limits attached as simulated switches, and the limits set as
    /// the axis's limit pins.
    pub fn fit_demo_switches(&self, axis: &Axis, index: usize) -> Result<DemoSwitches, HubError> {
        let switches = DemoSwitches::for_axis(index)
            .ok_or(HubError::Config("demo switches fit axes 0 to 7"))?;
        let bounce = Bounce {
            steps: 3,
            seed: index as u64,
        };
        self.attach_bouncing_switch(
            switches.home_pin,
            axis,
            i64::MIN..=switches.home_at,
            true,
            bounce,
        )?;
        self.attach_switch(switches.min_pin, axis, i64::MIN..=switches.min_at, true)?;
        self.attach_switch(switches.max_pin, axis, switches.max_at..=i64::MAX, true)?;
        axis.set_limit_pins(
            Some((switches.min_pin, true)),
            Some((switches.max_pin, true)),
        )
        .map_err(|_| HubError::NoSuchAxis)?;
        // Named by role in waveforms: axis1_home, axis1_min, axis1_max.
        let mut names = lock(&self.inner.pin_names);
        for (pin, role) in [
            (switches.home_pin, "home"),
            (switches.min_pin, "min"),
            (switches.max_pin, "max"),
        ] {
            if let Some(signal) = names.get_mut(&pin) {
                signal.name = format!("axis{}_{role}", axis.shared.id + 1);
            }
        }
        Ok(switches)
    }

    /// [`Hub::attach_switch`] with contact bounce: the level chatters
    /// within `bounce.steps` steps inside each end of the range, as a
    /// pattern seeded by `bounce.seed` (the same in every run).
    pub fn attach_bouncing_switch(
        &self,
        pin: u8,
        axis: &Axis,
        active: std::ops::RangeInclusive<i64>,
        active_level: bool,
        bounce: Bounce,
    ) -> Result<(), HubError> {
        if pin >= PIN_COUNT {
            return Err(HubError::PinOutOfRange(pin));
        }
        if active.is_empty() {
            return Err(HubError::Config("the switch's active range is empty"));
        }
        let cogs = lock(&self.inner.cogs);
        let owned = Arc::ptr_eq(&axis.hub.inner, &self.inner)
            && cogs
                .iter()
                .any(|slot| Arc::ptr_eq(&slot.shared, &axis.shared))
            && !axis.shared.is_shut_down();
        if !owned {
            return Err(HubError::NoSuchAxis);
        }
        let mut claimed = lock(&self.inner.claimed);
        if *claimed & (1 << pin) != 0 {
            return Err(HubError::PinInUse(pin));
        }
        *claimed |= 1 << pin;
        *lock(&self.inner.switch_pins) |= 1 << pin;
        lock(&axis.shared.switches).push(Switch {
            pin,
            active,
            active_level,
            bounce,
        });
        drop(claimed);
        drop(cogs);
        lock(&self.inner.pin_names).insert(
            pin,
            Signal {
                pin,
                name: format!("axis{}_switch{pin}", axis.shared.id + 1),
                input: true,
                level: false,
            },
        );
        // The cog drives the pin from now on (and has set it when this returns).
        let _ = axis.shared.refresh();
        Ok(())
    }

    /// The level of an input pin.
    pub fn input(&self, pin: u8) -> bool {
        pin < PIN_COUNT && self.inner.shared.pins.input(pin)
    }

    /// The level of an output pin. Cogs publish their pins at the end of
    /// each batch of steps: exact when [`Hub::advance`] or
    /// [`Hub::run_until_idle`] returns and while an axis is idle; with the
    /// real clock, up to one batch (at most 20 ms) behind while it moves.
    pub fn output(&self, pin: u8) -> bool {
        pin < PIN_COUNT && self.inner.shared.pins.output(pin)
    }

    /// Rising edges seen on a pin since the hub started (published as
    /// [`Hub::output`] says: exact after an advance and once STM reads 0).
    pub fn rising_edges(&self, pin: u8) -> u64 {
        if pin < PIN_COUNT {
            self.inner.shared.pins.rising_edges(pin)
        } else {
            0
        }
    }

    /// Emergency stop of every axis: no more steps, positions kept.
    pub fn emergency_stop(&self) {
        let cogs: Vec<Arc<CogShared>> = lock(&self.inner.cogs)
            .iter()
            .map(|slot| Arc::clone(&slot.shared))
            .collect();
        for cog in &cogs {
            request_estop(cog);
        }
        for cog in &cogs {
            // A cog that is gone makes no steps: nothing to wait for.
            let _ = wait_for_estop(cog);
        }
    }
}

pub(crate) fn request_estop(cog: &CogShared) {
    cog.mailbox.estop.ask();
    cog.kick();
}

/// Waits for the cog to carry out every emergency stop asked so far.
pub(crate) fn wait_for_estop(cog: &CogShared) -> Result<(), AxisError> {
    let wanted = cog.mailbox.estop.asked();
    cog.wait_until(|| cog.mailbox.estop.is_done(wanted))
}

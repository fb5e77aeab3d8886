//! The hub: shared memory, the system counter, 64 pins, and the cogs.
//!
//! ```
//! use cogstep_hub::{ClockMode, Hub, HubConfig};
//! let hub = Hub::new(HubConfig { clkfreq: 200_000_000, clock: ClockMode::Virtual, ..Default::default() })?;
//! let x = hub.start_sd(0, 1, 2)?;          // stop pin 0, step pin 1, dir pin 2
//! hub.set_input(0, true);                  // the stop pin must be high to run
//! x.move_steps(20_000, -5_000)?;           // 20,000 steps/s, 5,000 steps back
//! let ct = hub.run_until_idle();
//! assert_eq!(x.position(), -5_000);
//! assert_eq!(x.stm(), 0);
//! assert_eq!(hub.rising_edges(1), 5_000);
//! assert!(ct > 0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! With [`ClockMode::Virtual`] time moves only in [`Hub::advance`] and
//! [`Hub::run_until_idle`]; commands and inputs given between those calls
//! take effect at the CT [`Hub::now`] shows, so the same calls give the same
//! edges bit for bit, however the threads are scheduled. (A command given by
//! another thread *while* the hub advances takes effect at whatever CT its
//! cog has reached then.) With [`ClockMode::Real`] the counter follows the
//! monotonic clock and the cogs run on their own.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::axis::Axis;
use crate::clock::{ClockMode, Epochs, RealClock};
use crate::cog::{Cog, CogShared, GroupShared, HubShared};
use crate::mailbox::{Command, CommandKind};
use crate::pins::{Edge, Outputs, PinBank, PIN_COUNT};
use crate::switch::{Bounce, DemoSwitches, Switch};
use crate::sync::{AtomicBool, AtomicU64, Ordering};
use crate::trace::{write_vcd, EdgeTap, Signal, VcdError};
use cogstep_motion::axis::{AxisError, Mode};
use cogstep_motion::axis_core::{AxisCore, AxisCoreConfig};
use cogstep_motion::profile::scurve::{self, Arithmetic, ScurveConfig};
use cogstep_motion::profile::PlanError;

/// How to build a hub.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HubConfig {
    /// System clock, Hz (default 200 MHz, as the P2 usually runs).
    pub clkfreq: u32,
    /// Virtual (deterministic) or real time.
    pub clock: ClockMode,
    /// How many cogs may run at once (default 8, as the P2 has).
    pub max_cogs: usize,
    /// Step pulse width, ticks (default 1,000: the reference's 5 µs at 200 MHz).
    pub pulse_ticks: u32,
    /// Direction set-up time before the next step edge, ticks (default
    /// 1,000: 5 µs at 200 MHz, enough for common driver chips).
    pub dir_setup_ticks: u32,
    /// S-curve offset, degrees (default 40).
    pub offset_deg: u32,
    /// Acceleration divisor (default 10).
    pub accel_div: u32,
    /// Reference integer arithmetic, or the improved default.
    pub arithmetic: Arithmetic,
    /// A jog decelerates this long after its last heartbeat, ms (default 150).
    pub jog_timeout_ms: u32,
    /// Record every pin edge for [`Hub::trace`] and VCD (default off; the
    /// per-pin counters are always on).
    pub trace_edges: bool,
    /// Undrained edges each cog's ring holds (default 65,536).
    pub trace_ring: usize,
    /// A hard limit stops its axis with an emergency stop instead of the
    /// fastest controlled deceleration (default off).
    pub limit_estop: bool,
    /// With the real clock, each cog asks the kernel for the lowest
    /// real-time priority (`SCHED_FIFO` 1) where the process may have it,
    /// so that late wake-ups do not become lag (default on; a cog that is
    /// refused stays an ordinary thread). Off: cogs stay ordinary threads.
    pub realtime_priority: bool,
}

impl Default for HubConfig {
    fn default() -> Self {
        Self {
            clkfreq: 200_000_000,
            clock: ClockMode::Virtual,
            max_cogs: 8,
            pulse_ticks: 1_000,
            dir_setup_ticks: 1_000,
            offset_deg: 40,
            accel_div: 10,
            arithmetic: Arithmetic::Smooth,
            jog_timeout_ms: 150,
            trace_edges: false,
            trace_ring: 1 << 16,
            limit_estop: false,
            realtime_priority: true,
        }
    }
}

impl HubConfig {
    /// The S-curve settings every cog uses.
    pub fn scurve(&self) -> ScurveConfig {
        ScurveConfig {
            clkfreq: self.clkfreq,
            offset_deg: self.offset_deg,
            accel_div: self.accel_div,
            arithmetic: self.arithmetic,
        }
    }
}

/// Why the hub refused a request. Nothing changes when it does.
#[derive(Debug, thiserror::Error)]
pub enum HubError {
    /// All cogs are taken.
    #[error("all {max} cogs are running")]
    TooManyCogs {
        /// The limit.
        max: usize,
    },
    /// Pins are numbered 0 to 63.
    #[error("pin {0} does not exist (pins are 0 to 63)")]
    PinOutOfRange(u8),
    /// Another cog (or this one) already uses the pin.
    #[error("pin {0} is already in use")]
    PinInUse(u8),
    /// The configuration cannot work.
    #[error("bad hub configuration: {0}")]
    Config(&'static str),
    /// The S-curve settings are invalid.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The operating system would not start the cog's thread.
    #[error("could not start a cog thread: {0}")]
    Spawn(#[from] std::io::Error),
    /// A virtual-clock operation was asked of a real-clock hub.
    #[error("only a hub with the virtual clock can be advanced")]
    NotVirtual,
    /// The axis is not one of this hub's running axes.
    #[error("the axis is stopped or belongs to another hub")]
    NoSuchAxis,
    /// The pin is driven by a simulated switch ([`Hub::attach_switch`]).
    #[error("pin {0} is driven by a simulated switch")]
    SwitchPin(u8),
}

struct CogSlot {
    shared: Arc<CogShared>,
    thread: Option<JoinHandle<()>>,
}

struct HubInner {
    config: HubConfig,
    shared: Arc<HubShared>,
    cogs: Mutex<Vec<CogSlot>>,
    /// Pins claimed by running cogs and their switches (bit per pin).
    claimed: Mutex<u64>,
    /// Pins driven by simulated switches (bit per pin; also in `claimed`).
    switch_pins: Mutex<u64>,
    /// Serialises advancing the virtual clock; holds the list of cogs an
    /// epoch runs, kept so that epochs allocate nothing.
    advancing: Mutex<Vec<Arc<CogShared>>>,
    trace: Mutex<Vec<Edge>>,
    /// Every started axis's pins, by role (for VCD files).
    pin_names: Mutex<BTreeMap<u8, Signal>>,
    next_id: Mutex<usize>,
    /// Serialises group moves' admission, so that two callers never hold
    /// half of each other's axes.
    grouping: Mutex<()>,
    /// Clock ticks of CORDIC work per ramp step (QROTATE then QDIV in a cog's slot).
    math_ticks: u64,
    drainer_stop: Arc<AtomicBool>,
    drainer: Mutex<Option<JoinHandle<()>>>,
}

/// The hub: start cogs on pins, drive inputs, watch outputs, run the clock.
/// Cheap to clone: clones share one hub. The cogs stop when the last clone
/// (and every [`Axis`]) is dropped, or with [`Hub::shutdown`].
#[derive(Clone)]
pub struct Hub {
    inner: Arc<HubInner>,
}

pub(crate) fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panicking cog must not take the hub down with it.
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

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
                math_ticks: step_math_ticks(),
                drainer_stop: Arc::new(AtomicBool::new(false)),
                drainer: Mutex::new(None),
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
            .offset
            .store(self.inner.config.offset_deg, Ordering::Relaxed);
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

    /// What every cog's axis core runs with, on `outputs`.
    pub(crate) fn core_config(&self, outputs: Outputs) -> AxisCoreConfig {
        let config = &self.inner.config;
        AxisCoreConfig {
            scurve: config.scurve(),
            outputs,
            pulse_ticks: config.pulse_ticks,
            dir_setup_ticks: config.dir_setup_ticks,
            jog_timeout_ticks: u64::from(config.jog_timeout_ms) * u64::from(config.clkfreq) / 1_000,
            math_ticks: self.inner.math_ticks,
            limit_estop: config.limit_estop,
        }
    }

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
        for cog in watchers {
            if !level && cog.stop_pin == pin {
                // A stop pin low on any member stops its whole group.
                let group = lock(&cog.group).clone();
                if let Some(group) = group {
                    group.stop_after(self.group_stop_ct());
                }
            }
            // The cog has seen the level when this returns (real time: within
            // microseconds). A cog that is gone has no axis left to stop.
            let _ = cog.refresh();
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
                let mut epoch_cogs = lock(&self.inner.advancing);
                let target = self.inner.shared.epochs.now().saturating_add(ticks);
                self.run_epoch(target, &mut epoch_cogs);
                self.inner.shared.epochs.set_now(target);
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

    fn drain(&self) {
        let cogs = lock(&self.inner.cogs);
        self.drain_taps(cogs.iter().map(|slot| &*slot.shared), &mut Vec::new());
    }

    /// Moves the edges waiting in `cogs`' rings into the trace.
    fn drain_taps<'a>(&self, cogs: impl Iterator<Item = &'a CogShared>, buffer: &mut Vec<Edge>) {
        for cog in cogs {
            cog.tap.drain_into(buffer);
        }
        if !buffer.is_empty() {
            lock(&self.inner.trace).append(buffer);
        }
    }

    /// Real clock with tracing: a thread drains the rings every millisecond.
    fn start_drainer(&self) -> Result<(), HubError> {
        let weak = Arc::downgrade(&self.inner);
        let stop = Arc::clone(&self.inner.drainer_stop);
        let thread = std::thread::Builder::new()
            .name("hub-drain".into())
            .spawn(move || {
                while !stop.load(Ordering::Acquire) {
                    match weak.upgrade() {
                        Some(inner) => Hub { inner }.drain(),
                        None => return,
                    }
                    std::thread::sleep(Duration::from_millis(1));
                }
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

    /// A coordinated move: every axis's first edge on the same CT, one
    /// straight line in step space. Each `(axis, steps)` names an axis of
    /// this hub and its signed steps (0 allowed); the lead is the axis
    /// with the most steps and runs the S-curve of its move at `speed`;
    /// every other axis makes its steps along the line, so that at every
    /// edge its position is within one step of `steps · s(t)`, `s(t)` the
    /// lead's progress (see [`crate::axis_core`]'s "Coordinated moves").
    ///
    /// All or nothing: every axis is first reserved (each must be idle,
    /// its stop pin high); only when all are does the move start on all of
    /// them at one CT. Otherwise nothing moves and the first refusal is the
    /// error: [`AxisError::DuplicateAxis`], [`AxisError::Busy`],
    /// [`AxisError::StopPinLow`], [`AxisError::PositionOutOfRange`],
    /// [`AxisError::StepsOutOfRange`], a speed the lead cannot run
    /// ([`AxisError::Plan`], [`AxisError::PulseTooLong`]),
    /// [`AxisError::Unavailable`], or [`AxisError::Unsupported`] for an
    /// axis of another hub.
    ///
    /// A stop pin low on any member (or an emergency stop of any member)
    /// stops them all along the line; each axis's steps not made are in
    /// [`Axis::dropped_steps`] and its [`Axis::ledger`], and a group move of
    /// those completes the line.
    pub fn move_together(&self, moves: &[(&Axis, i32)], speed: u32) -> Result<(), AxisError> {
        for (i, (axis, steps)) in moves.iter().enumerate() {
            if !Arc::ptr_eq(&axis.hub.inner, &self.inner) {
                return Err(AxisError::Unsupported("an axis of another hub"));
            }
            axis.alive()?;
            if *steps == i32::MIN {
                return Err(AxisError::StepsOutOfRange);
            }
            if moves[..i]
                .iter()
                .any(|(other, _)| other.cog() == axis.cog())
            {
                return Err(AxisError::DuplicateAxis);
            }
        }
        let Some(lead_steps) = moves.iter().map(|(_, steps)| steps.unsigned_abs()).max() else {
            return Ok(());
        };
        if lead_steps > 0 {
            let lead = i32::try_from(lead_steps).map_err(|_| AxisError::StepsOutOfRange)?;
            let outputs = moves[0].0.outputs();
            AxisCore::check_move(&self.core_config(outputs), speed, lead)?;
        }
        let _admission = lock(&self.inner.grouping);
        let mut reserved: Vec<&Axis> = Vec::with_capacity(moves.len());
        for (axis, steps) in moves {
            let reply = axis.shared.call(Command {
                kind: CommandKind::GroupReserve,
                speed,
                steps: i64::from(*steps),
            });
            if let Err(error) = reply {
                for axis in reserved {
                    // Giving a reservation back cannot be refused; a cog
                    // that is gone holds nothing.
                    let _ = axis.shared.call(Command {
                        kind: CommandKind::GroupCancel,
                        speed: 0,
                        steps: 0,
                    });
                }
                return Err(error);
            }
            reserved.push(axis);
        }
        // The direction pins settle before the first edge (every member is
        // idle since at least now, its last pulse over).
        let setup = u64::from(self.inner.config.dir_setup_ticks);
        let start_ct = match self.inner.config.clock {
            ClockMode::Virtual => self.now() + setup,
            // The start lands a moment ahead, so each cog has it in time.
            ClockMode::Real => self.now() + setup + u64::from(self.inner.config.clkfreq) / 500,
        };
        let group = Arc::new(GroupShared {
            speed,
            lead_steps,
            start_ct,
            stop_after: AtomicU64::new(u64::MAX),
            members: moves
                .iter()
                .map(|(axis, _)| Arc::downgrade(&axis.shared))
                .collect(),
            progress: moves.iter().map(|_| AtomicU64::new(start_ct)).collect(),
        });
        for (axis, _) in moves {
            *lock(&axis.shared.group) = Some(Arc::clone(&group));
        }
        // A stop pin that went low since its member was reserved: the group
        // does not start. (A stop pin going low from here on finds the group
        // in its member's record and stops the whole line: set_input writes
        // the pin before it reads the record, this reads the pins after it
        // wrote the records, both under the records' locks.)
        let low = moves
            .iter()
            .any(|(axis, _)| !self.inner.shared.pins.input(axis.shared.stop_pin));
        if low {
            for (axis, _) in moves {
                let mut record = lock(&axis.shared.group);
                if record
                    .as_ref()
                    .is_some_and(|current| Arc::ptr_eq(current, &group))
                {
                    *record = None;
                }
                drop(record);
                let _ = axis.shared.call(Command {
                    kind: CommandKind::GroupCancel,
                    speed: 0,
                    steps: 0,
                });
            }
            return Err(AxisError::StopPinLow);
        }
        let mut outcome = Ok(());
        for (axis, steps) in moves {
            // Reserved: only a cog that died since can refuse.
            let reply = axis.shared.call(Command {
                kind: CommandKind::GroupStart,
                speed,
                steps: i64::from(*steps),
            });
            outcome = outcome.and(reply);
        }
        outcome
    }

    /// The CT a group stop asked for now acts after: now with the virtual
    /// clock (every cog stands there), a moment ahead with the real one.
    fn group_stop_ct(&self) -> u64 {
        match self.inner.config.clock {
            ClockMode::Virtual => self.now(),
            ClockMode::Real => {
                self.now()
                    + u64::from(self.inner.config.clkfreq) / 1_000 * GroupShared::REAL_STOP_LEAD_MS
            }
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

    /// The highest step rate a cog can sustain at this clock, given the
    /// CORDIC work of a ramp step (steps/s).
    pub fn max_step_rate(&self) -> u64 {
        u64::from(self.inner.config.clkfreq) / self.inner.math_ticks.max(1)
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

pub(crate) fn request_estop(cog: &CogShared) {
    cog.mailbox.estop.ask();
    cog.kick();
}

/// Waits for the cog to carry out every emergency stop asked so far.
pub(crate) fn wait_for_estop(cog: &CogShared) -> Result<(), AxisError> {
    let wanted = cog.mailbox.estop.asked();
    cog.wait_until(|| cog.mailbox.estop.is_done(wanted))
}

impl Drop for HubInner {
    fn drop(&mut self) {
        self.drainer_stop.store(true, Ordering::Release);
        if let Some(thread) = lock(&self.drainer).take() {
            let _ = thread.join();
        }
        let slots: Vec<CogSlot> = lock(&self.cogs).drain(..).collect();
        for mut slot in slots {
            stop_cog(&mut slot);
        }
    }
}

/// The CORDIC work of a ramp step on the P2, from cordic-core's pipeline
/// model: QROTATE issued in the cog's hub slot, GETQX waiting the 55 clocks
/// for its result, then QDIV in the next slot and GETQX again; the worst
/// case over where in the 8-clock slot rotation the step begins.
fn step_math_ticks() -> u64 {
    use cordic_core::pipeline::{Command, Cordic};
    (0..8u64)
        .map(|start| {
            let mut cordic = Cordic::starting_at(0, start);
            cordic.issue(Command::Rotate {
                x: 25_000,
                y: 0,
                angle: 1 << 30,
            });
            let _ = cordic.getqx();
            cordic.issue(Command::Div {
                dividend: 200_000_000,
                divisor: 25_000,
            });
            let _ = cordic.getqx();
            cordic.now() - start
        })
        .max()
        .unwrap_or(0)
}

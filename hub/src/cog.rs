//! A cog: one worker thread that owns one axis.
//!
//! The cog is a thin loop around the axis's [`AxisCore`], which decides
//! everything: it reads the mailbox and the inputs, hands them to the core
//! with the CT they arrive at, answers each command with the core's verdict,
//! drives the pins with the edges the core emits, and publishes the status:
//!
//! ```text
//! mailbox, stop pin, e-stop ─► AxisCore (admission, profile, edges) ─► pins, trace
//!                                  └─► status in the mailbox, the answer in the slot
//! ```
//!
//! Step times are exact clock ticks whatever the clock: with the virtual
//! clock the cog runs through events up to the CT the hub names; with the
//! real clock it sleeps until its steps are due and makes them in small
//! batches, each edge carrying its scheduled CT.
//!
//! The per-step path touches no shared cache line another cog writes: the
//! inputs are looked at in full only when one of them moved (a comparison of
//! three input words with what the last look saw), and the output levels
//! and rising-edge counts stay in the cog until the batch ends
//! ([`OwnPins`]). Status goes to the axis's own mailbox on every step, or
//! once per batch of plain slew steps: when nothing traces its edges and no
//! input moved, the cog makes the steps due at speed in closed form
//! ([`AxisCore::run_slew`], up to [`SLEW_BATCH_STEPS`] at a time), bit for
//! bit the steps it would make one by one (`tests/tests/slew_fast_path.rs`).
//!
//! A real-clock cog runs at the lowest real-time priority where the
//! process may have it ([`crate::clock::ask_for_realtime_priority`]).

use std::sync::{Arc, Condvar, Mutex};
use std::thread::Thread;
use std::time::Duration;

use crate::clock::{ClockMode, EpochDone, Epochs, RealClock};
use crate::mailbox::{Command, CommandKind, Mailbox};
use crate::pins::PinBank;
use crate::switch::Switch;
use crate::sync::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use crate::trace::EdgeTap;
use cogstep_motion::axis::{AxisError, Direction, HomeReport, LimitTrip};
use cogstep_motion::axis_core::{AxisCore, CoreCommand, Edge, GroupMove, GroupRequest, Outputs};

/// The hub's state that cogs read: pins, time, the epoch protocol.
#[derive(Debug)]
pub(crate) struct HubShared {
    pub clock: ClockMode,
    pub pins: PinBank,
    pub real: RealClock,
    /// Virtual clock: CT and the epochs the cogs run.
    pub epochs: Epochs,
    /// The thread waiting for an epoch to finish.
    pub waiter: Mutex<Option<Thread>>,
    /// Real-clock cogs ask for real-time priority ([`crate::HubConfig::realtime_priority`]).
    pub realtime_priority: bool,
}

impl HubShared {
    /// CT now, for inputs applied from outside.
    pub fn now(&self) -> u64 {
        match self.clock {
            ClockMode::Virtual => self.epochs.now(),
            ClockMode::Real => self.real.now(),
        }
    }

    fn wake_waiter(&self) {
        if let Ok(waiter) = self.waiter.lock() {
            if let Some(thread) = waiter.as_ref() {
                thread.unpark();
            }
        }
    }
}

/// One group move, shared by its members' cogs: what every member runs
/// (the lead's speed and steps, the start CT) and the group's stop.
///
/// The stop is one word: `stop_after` (u64::MAX = none), lowered with
/// `fetch_min` (Release) by whoever stops the group and read (Acquire) by
/// every member's cog before each of its events. A member's copy of the
/// lead curve decelerates from the first lead edge after that CT, so the
/// copies agree as long as no cog has passed that CT when the word is
/// written: with the virtual clock the hub writes it between epochs at the
/// CT every cog stands at; with the real clock it names a CT a millisecond
/// ahead of the clock ([`GroupShared::REAL_STOP_LEAD_MS`]), and cogs never
/// run events ahead of the clock.
#[derive(Debug)]
pub(crate) struct GroupShared {
    pub speed: u32,
    pub lead_steps: u32,
    pub start_ct: u64,
    pub stop_after: AtomicU64,
    /// The members (weak: the members hold this group).
    pub members: Vec<std::sync::Weak<CogShared>>,
    /// With the virtual clock, each member's progress (same order as
    /// `members`): every event of its part before this CT is done
    /// (`u64::MAX` once its part ended). A member runs an event at `t` only
    /// when every other member has reached `t`, so a stop one of them asks
    /// for at `t` (a hard limit) reaches all of them before they pass it:
    /// the members run in lockstep, and the line stays one line.
    pub progress: Vec<AtomicU64>,
}

impl GroupShared {
    /// With the real clock, how far ahead of the clock a group stop lands, ms.
    pub const REAL_STOP_LEAD_MS: u64 = 1;

    /// Stops the group along its line from the first lead edge after `ct`.
    pub fn stop_after(&self, ct: u64) {
        // AcqRel: Release publishes the stop to the members' Acquire load;
        // racing stoppers agree on the earliest CT.
        self.stop_after.fetch_min(ct, Ordering::AcqRel);
    }

    /// Publishes member `slot`'s progress (see [`GroupShared::progress`]).
    pub fn set_progress(&self, slot: usize, ct: u64) {
        if let Some(progress) = self.progress.get(slot) {
            // Release: a stop (or an e-stop request) this member made before
            // is seen by a member that reads this progress with Acquire.
            progress.store(ct, Ordering::Release);
        }
    }

    /// Whether a member still runs its part (the group has not ended).
    pub fn is_live(&self) -> bool {
        // Acquire: pairs with set_progress's Release.
        self.progress
            .iter()
            .any(|progress| progress.load(Ordering::Acquire) != u64::MAX)
    }

    /// Whether every member but `slot` has reached `t` (or is gone).
    pub fn others_reached(&self, slot: usize, t: u64) -> bool {
        self.progress.iter().enumerate().all(|(i, progress)| {
            let gone = || {
                self.members
                    .get(i)
                    .is_some_and(|member| member.upgrade().is_none_or(|m| m.is_shut_down()))
            };
            // Acquire: pairs with set_progress's Release.
            i == slot || progress.load(Ordering::Acquire) >= t || gone()
        })
    }

    /// The CT the group stops after, if a stop was asked (a member's cog
    /// reads it before each of its events).
    pub fn stop_ct(&self) -> Option<u64> {
        // Acquire: pairs with the stopper's fetch_min.
        let after = self.stop_after.load(Ordering::Acquire);
        (after != u64::MAX).then_some(after)
    }
}

/// One axis's state shared between its handles, the hub and its cog.
#[derive(Debug)]
pub(crate) struct CogShared {
    pub id: usize,
    pub mailbox: Mailbox,
    pub outputs: Outputs,
    pub stop_pin: u8,
    pub tap: EdgeTap,
    /// Set when the cog is told to stop, and by the cog itself when its
    /// thread ends for any reason (a panic included): its axis is gone.
    pub shutdown: AtomicBool,
    /// Virtual clock: the last epoch this cog finished, and its CT then.
    pub epoch_done: EpochDone,
    pub thread: Mutex<Option<Thread>>,
    /// The last group move this axis was (or is) a member of; set by the hub
    /// before it posts the group's start.
    pub group: Mutex<Option<Arc<GroupShared>>>,
    /// Simulated switches this axis drives (read by the cog when the
    /// inputs sequence moves).
    pub switches: Mutex<Vec<Switch>>,
    /// A command beyond the mailbox's (homing, limits) and its answer.
    ext: Mutex<ExtSlot>,
    /// One caller of [`CogShared::call_ext`] at a time.
    ext_call: Mutex<()>,
    /// The input pins the axis acts on (stop pin apart), published by the cog.
    pub watched: AtomicU64,
    /// The physical position (signed count of step edges), published by the cog.
    pub physical: AtomicI64,
    /// Limits and homing, published by the cog when they change.
    pub extras: Mutex<Extras>,
    /// Signalled whenever the cog answered a command or handled an input,
    /// for callers that wait for it ([`CogShared::wait_until`]).
    progress: Mutex<()>,
    progressed: Condvar,
}

impl CogShared {
    pub fn new(id: usize, outputs: Outputs, stop_pin: u8, tap: EdgeTap) -> Self {
        Self {
            id,
            mailbox: Mailbox::default(),
            outputs,
            stop_pin,
            tap,
            shutdown: AtomicBool::new(false),
            epoch_done: EpochDone::default(),
            thread: Mutex::new(None),
            group: Mutex::new(None),
            switches: Mutex::new(Vec::new()),
            ext: Mutex::new(ExtSlot::default()),
            ext_call: Mutex::new(()),
            watched: AtomicU64::new(0),
            physical: AtomicI64::new(0),
            extras: Mutex::new(Extras::default()),
            progress: Mutex::new(()),
            progressed: Condvar::new(),
        }
    }

    /// Wakes the cog's thread to look at its inputs.
    pub fn kick(&self) {
        if let Ok(thread) = self.thread.lock() {
            if let Some(thread) = thread.as_ref() {
                thread.unpark();
            }
        }
    }

    pub fn is_shut_down(&self) -> bool {
        self.shutdown.load(Ordering::Acquire)
    }

    /// Tells waiters that the cog did something they may wait for. Taking
    /// the lock orders this after the waiter's check, so no wake-up is lost.
    fn notify(&self) {
        let _guard = self.progress.lock();
        self.progressed.notify_all();
    }

    /// Waits until `done()` holds: a real wait, woken by the cog. The only
    /// way out without it is the cog being gone, which is an error.
    pub fn wait_until(&self, mut done: impl FnMut() -> bool) -> Result<(), AxisError> {
        let mut guard = self
            .progress
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        loop {
            if done() {
                return Ok(());
            }
            if self.is_shut_down() {
                return Err(AxisError::Unavailable);
            }
            // The timeout only re-checks for a cog that died without a word.
            guard = self
                .progressed
                .wait_timeout(guard, Duration::from_millis(50))
                .unwrap_or_else(|poisoned| poisoned.into_inner())
                .0;
        }
    }

    /// Posts a command and waits for the cog's answer: `Ok` means the axis
    /// took it and will carry it out.
    pub fn call(&self, command: Command) -> Result<(), AxisError> {
        if self.is_shut_down() {
            return Err(AxisError::Unavailable);
        }
        // The slot is busy only while another caller's command is answered.
        self.wait_until(|| self.mailbox.post(command).is_ok())?;
        self.kick();
        let mut reply = None;
        let waited = self.wait_until(|| {
            reply = reply.or_else(|| self.mailbox.poll_reply());
            reply.is_some()
        });
        match (reply, waited) {
            (Some(reply), _) => reply,
            (None, Err(error)) => Err(error),
            (None, Ok(())) => Err(AxisError::Unavailable),
        }
    }
}

/// A command beyond the mailbox's, and the cog's answer.
#[derive(Debug, Default)]
struct ExtSlot {
    request: Option<CoreCommand>,
    reply: Option<Result<(), AxisError>>,
}

/// The limit and homing state of an axis, as its cog last published it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Extras {
    pub home_outcome: Option<Result<HomeReport, AxisError>>,
    pub limit_trip: Option<LimitTrip>,
    pub soft_limits: Option<(i64, i64)>,
    pub limit_pins: [Option<(u8, bool)>; 2],
    pub homing: bool,
}

fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl CogShared {
    /// Hands the cog a command the mailbox has no room for (homing, limit
    /// settings) and waits for its answer: `Ok` means it was taken.
    pub fn call_ext(&self, command: CoreCommand) -> Result<(), AxisError> {
        if self.is_shut_down() {
            return Err(AxisError::Unavailable);
        }
        let _one_at_a_time = lock(&self.ext_call);
        *lock(&self.ext) = ExtSlot {
            request: Some(command),
            reply: None,
        };
        // The cog looks at the slot when the inputs sequence moves.
        self.mailbox.inputs.ask();
        self.kick();
        let mut reply = None;
        let waited = self.wait_until(|| {
            reply = lock(&self.ext).reply.take();
            reply.is_some()
        });
        match (reply, waited) {
            (Some(reply), _) => reply,
            (None, Err(error)) => {
                lock(&self.ext).request = None;
                Err(error)
            }
            (None, Ok(())) => Err(AxisError::Unavailable),
        }
    }

    /// Re-reads the switches and settings: the cog has taken them when this returns.
    pub fn refresh(&self) -> Result<(), AxisError> {
        let seq = self.mailbox.inputs.ask();
        self.kick();
        self.wait_until(|| self.mailbox.inputs.is_done(seq))
    }
}

/// Marks the axis gone when the cog's thread ends, however it ends.
struct ExitGuard(Arc<CogShared>);

impl Drop for ExitGuard {
    fn drop(&mut self) {
        self.0.shutdown.store(true, Ordering::Release);
        self.0.notify();
    }
}

/// The most slew steps a cog makes in one closed-form batch before it looks
/// at its inputs again: a batch costs about as much as one step, so this
/// bounds the wall time an input waits (a fraction of a microsecond), not
/// the CT it takes effect at.
const SLEW_BATCH_STEPS: u32 = 1 << 12;

/// The cog's own state (only its thread touches it).
pub(crate) struct Cog {
    shared: Arc<CogShared>,
    hub: Arc<HubShared>,
    core: AxisCore,
    /// All events up to this CT are done.
    ct: u64,
    estop_seen: u64,
    epoch_seen: u64,
    /// The input changes the last look saw.
    input_seq_seen: u64,
    pins: OwnPins,
    /// The group move the core runs its part of, and this member's slot in it.
    group: Option<Arc<GroupShared>>,
    group_slot: usize,
    /// The switches this axis drives (a copy of the shared list).
    switches: Vec<Switch>,
    /// The input word last given to the core.
    inputs_fed: u64,
    /// The core's limit and homing events last published.
    events_seen: u32,
}

/// The levels and rising-edge counts of a cog's output pins, kept by the
/// cog and published to the hub's [`PinBank`] at the end of each batch.
struct OwnPins {
    /// The two output pins.
    pins: [u8; 2],
    /// Their bits in the bank's words.
    mask: u64,
    /// Their levels now (bits of `mask`).
    levels: u64,
    /// The levels last published.
    published: u64,
    /// Rising edges on each pin not yet added to the bank's counters.
    rising: [u64; 2],
}

impl OwnPins {
    fn new(outputs: Outputs) -> Self {
        let pins = outputs.pins();
        Self {
            pins,
            mask: (1u64 << pins[0]) | (1u64 << pins[1]),
            levels: 0,
            published: 0,
            rising: [0; 2],
        }
    }

    #[inline]
    fn drive(&mut self, pin: u8, level: bool) {
        let bit = 1u64 << pin;
        if level {
            self.levels |= bit;
            self.rising[usize::from(pin == self.pins[1])] += 1;
        } else {
            self.levels &= !bit;
        }
    }

    /// `steps` pulses on `pin` (a rising and a falling edge each).
    #[inline]
    fn pulses(&mut self, pin: u8, steps: u32) {
        if steps > 0 {
            self.levels &= !(1u64 << pin);
            self.rising[usize::from(pin == self.pins[1])] += u64::from(steps);
        }
    }

    fn publish(&mut self, bank: &PinBank) {
        for (pin, rising) in self.pins.iter().zip(&mut self.rising) {
            if *rising != 0 {
                bank.add_rising_edges(*pin, *rising);
                *rising = 0;
            }
        }
        if self.levels != self.published {
            bank.publish_outputs(self.mask, self.levels);
            self.published = self.levels;
        }
    }
}

impl Cog {
    pub fn new(shared: Arc<CogShared>, hub: Arc<HubShared>, core: AxisCore, ct: u64) -> Self {
        let outputs = shared.outputs;
        Self {
            shared,
            hub,
            core,
            ct,
            estop_seen: 0,
            epoch_seen: 0,
            input_seq_seen: 0,
            pins: OwnPins::new(outputs),
            group: None,
            group_slot: 0,
            switches: Vec::new(),
            inputs_fed: 0,
            events_seen: u32::MAX,
        }
    }

    /// The thread's body.
    pub fn run(mut self) {
        let _exit = ExitGuard(Arc::clone(&self.shared));
        self.epoch_seen = self.hub.epochs.opened();
        self.shared.epoch_done.finish(self.epoch_seen, self.ct);
        self.publish_all();
        match self.hub.clock {
            ClockMode::Virtual => self.run_virtual(),
            ClockMode::Real => self.run_real(),
        }
    }

    fn run_virtual(&mut self) {
        while !self.shared.is_shut_down() {
            // Inputs applied between epochs take effect at the hub's CT.
            if self.core.next_event().is_none() {
                self.ct = self.ct.max(self.hub.epochs.now());
            }
            self.look_if_needed(self.ct);
            if let Some((epoch, target)) = self.hub.epochs.opened_since(self.epoch_seen) {
                self.run_until(target);
                self.epoch_seen = epoch;
                self.shared.epoch_done.finish(epoch, self.ct);
                self.hub.wake_waiter();
                continue;
            }
            std::thread::park();
        }
    }

    fn run_real(&mut self) {
        // Late wake-ups are lag: where it may, the cog goes before ordinary threads.
        if self.hub.realtime_priority {
            crate::clock::ask_for_realtime_priority();
        }
        while !self.shared.is_shut_down() {
            let now = self.hub.real.now();
            if self.core.next_event().is_none() {
                // Idle: a command found now starts now, not at the CT of
                // the last wake-up (up to a long nap ago), which would
                // make the move's first steps in one late burst.
                self.ct = self.ct.max(now);
            }
            self.run_until(now);
            match self.core.next_event() {
                Some(next) => {
                    let wait = self.hub.real.until(next);
                    // Batch: never sleep less than 300 µs while moving, so
                    // 8 fast axes cost a few thousand wake-ups a second.
                    let nap = wait.clamp(Duration::from_micros(300), Duration::from_millis(20));
                    std::thread::park_timeout(nap);
                }
                None => std::thread::park_timeout(Duration::from_millis(50)),
            }
        }
    }

    /// Processes every event up to `limit` (virtual: u64::MAX = until nothing is left).
    fn run_until(&mut self, limit: u64) {
        // Inputs are read once before the first event and then once at each
        // event's CT, before it happens: a step never takes a second look.
        self.look_if_needed(self.ct);
        while !self.shared.is_shut_down() {
            match self.core.next_event() {
                Some(t) if t <= limit => {
                    self.wait_for_group(t);
                    self.ct = self.ct.max(t);
                    self.look_if_needed(self.ct);
                    self.look_at_group();
                    // A group member's events may lie behind the cog's CT (a
                    // start CT given a moment ago): they run at their own CT.
                    let at = if self.group.is_some() { t } else { self.ct };
                    // A plain slew of an axis outside a group may be made
                    // in closed form.
                    if self.group.is_some() || !self.slew_batch(limit) {
                        self.event(at);
                    }
                    self.look_at_group();
                }
                _ => break,
            }
        }
        if limit != u64::MAX {
            self.ct = self.ct.max(limit);
        }
        // The batch's end: the edges made so far are counted in the bank.
        self.pins.publish(&self.hub.pins);
        self.publish_all();
    }

    /// A group member: passes the group's stop on to the core (before any
    /// event after it), and lets go of the group once the part is done.
    #[inline]
    fn look_at_group(&mut self) {
        let Some(group) = &self.group else {
            return;
        };
        if let Some(after) = group.stop_ct() {
            self.core.stop_group_after(after);
        }
        if self.core.in_group() {
            let next = self.core.next_event().unwrap_or(u64::MAX);
            group.set_progress(self.group_slot, next);
            return;
        }
        // The part is done. The axis stays a member (its stop pin and its
        // e-stop still stop the line) until the group ends or it takes a
        // move of its own (`leave_group_record`).
        group.set_progress(self.group_slot, u64::MAX);
        self.group = None;
    }

    /// The axis takes a move of its own: it is no longer a member of the
    /// group it last ran a part of (the others' e-stops and stop pins no
    /// longer reach it, nor its theirs). A part still running keeps it.
    fn leave_group_record(&mut self) {
        if self.group.is_none() {
            *lock(&self.shared.group) = None;
        }
    }

    /// With the virtual clock, a group member waits before its event at
    /// `t` until every other member has reached `t` (see
    /// [`GroupShared::progress`]).
    fn wait_for_group(&mut self, t: u64) {
        if self.hub.clock != ClockMode::Virtual {
            return;
        }
        let Some(group) = &self.group else {
            return;
        };
        group.set_progress(self.group_slot, t);
        while !group.others_reached(self.group_slot, t) && !self.shared.is_shut_down() {
            std::thread::yield_now();
        }
    }

    /// Passes what the core asks of its whole group (a hard limit tripped
    /// on this member) to the group: the line's stop, or an emergency stop
    /// of every member.
    fn pass_group_request(&mut self, t: u64) {
        let Some(request) = self.core.take_group_request() else {
            return;
        };
        let Some(group) = &self.group else {
            return;
        };
        match request {
            GroupRequest::StopAfter(after) => group.stop_after(after),
            GroupRequest::EmergencyStop => {
                group.stop_after(t);
                for member in group.members.iter().filter_map(std::sync::Weak::upgrade) {
                    let same = lock(&member.group)
                        .as_ref()
                        .is_some_and(|current| Arc::ptr_eq(current, group));
                    if member.id != self.shared.id && same {
                        crate::hub::request_estop(&member);
                    }
                }
            }
        }
        // The request is out before the progress says this CT is done.
        let next = self.core.next_event().unwrap_or(u64::MAX);
        group.set_progress(self.group_slot, next.max(t));
    }

    /// Makes the slew steps due up to `limit` at once, in closed form
    /// ([`AxisCore::run_slew`]), when nothing observes them one by one: no
    /// trace, no switch driven by this axis, and no input moved since the
    /// look at the first of them (an
    /// input that moves while the batch runs is seen after it, at a later
    /// CT, as it would be by a cog that had got that far). Returns whether
    /// it made any.
    #[inline]
    fn slew_batch(&mut self, limit: u64) -> bool {
        // Switches this axis drives move with each step: every step is
        // then an event of its own.
        if self.shared.tap.enabled() || !self.switches.is_empty() {
            return false;
        }
        match self.core.run_slew(self.ct, limit, SLEW_BATCH_STEPS) {
            Some(run) => {
                self.pins.pulses(run.pin, run.steps);
                self.ct = self.ct.max(self.core.last_step().ct);
                self.publish_step();
                true
            }
            None => false,
        }
    }

    /// Runs the core's event at `t`, driving the pins and the trace.
    fn event(&mut self, t: u64) {
        let Cog {
            shared,
            hub,
            core,
            pins,
            ..
        } = self;
        let before = core.physical_position();
        core.run_event(t, &mut |edge: Edge| {
            pins.drive(edge.pin, edge.level);
            if shared.tap.enabled() {
                match hub.clock {
                    ClockMode::Virtual => shared.tap.push_waiting(edge, || shared.is_shut_down()),
                    ClockMode::Real => shared.tap.push_or_count(edge),
                }
            }
        });
        if core.physical_position() != before {
            // The switches move with the step, and the core sees them
            // before its next event: on the step that changed them.
            if !self.switches.is_empty() {
                self.drive_switches(t);
            }
            if self.core.watched_pins() != 0 {
                self.feed_inputs(t);
                self.pass_group_request(t);
            }
            if self.core.events() != self.events_seen {
                self.publish_all();
            }
            self.publish_step();
        } else if !core.is_moving() {
            // The move ended: whoever sees it idle sees every edge counted.
            self.pins.publish(&self.hub.pins);
            self.publish_all();
        }
    }

    /// Looks at the inputs at CT `t` unless none of them moved.
    #[inline]
    fn look_if_needed(&mut self, t: u64) {
        let mailbox = &self.shared.mailbox;
        let quiet = mailbox.estop.asked() == self.estop_seen
            && !mailbox.has_command()
            && mailbox.inputs.asked() == self.input_seq_seen;
        if !quiet {
            self.look(t);
        }
    }

    /// The full look at the inputs, at CT `t`.
    fn look(&mut self, t: u64) {
        // Acquire: the stop pin's level read below is at least as new as
        // the change that bumped the sequence.
        let input_seq = self.shared.mailbox.inputs.asked();
        let mut progressed = false;
        // Emergency stop first: it overrides everything after it.
        let estops = self.shared.mailbox.estop.asked();
        if estops != self.estop_seen {
            self.estop_seen = estops;
            // An emergency stop is always taken.
            let _ = self.core.command(t, CoreCommand::EmergencyStop);
            self.pins.publish(&self.hub.pins);
            self.publish_all();
            self.shared.mailbox.estop.finish(estops);
            progressed = true;
        }
        let stop_pin_high = self.hub.pins.input(self.shared.stop_pin);
        if stop_pin_high != self.core.stop_pin_high() {
            self.core.set_stop_pin(t, stop_pin_high);
        }
        if input_seq != self.input_seq_seen {
            self.switches.clone_from(&lock(&self.shared.switches));
            self.drive_switches(t);
        }
        self.feed_inputs(t);
        self.pass_group_request(t);
        if let Some(command) = self.shared.mailbox.take() {
            let reply = match command.kind {
                CommandKind::GroupStart => self.start_group(t, command),
                _ => self.core.command(t, core_command(command)).map(|_| ()),
            };
            let moves = matches!(
                command.kind,
                CommandKind::Move | CommandKind::Jog | CommandKind::GroupReserve
            );
            if moves && reply.is_ok() {
                self.leave_group_record();
            }
            // The status first, then the answer: the caller sees both.
            self.publish_all();
            self.shared.mailbox.answer(reply);
            progressed = true;
        }
        if input_seq != self.input_seq_seen {
            self.input_seq_seen = input_seq;
            let request = lock(&self.shared.ext).request.take();
            if let Some(command) = request {
                let reply = self.core.command(t, command).map(|_| ());
                if matches!(command, CoreCommand::Home(_)) && reply.is_ok() {
                    self.leave_group_record();
                }
                self.publish_all();
                lock(&self.shared.ext).reply = Some(reply);
            }
            self.publish_all();
            self.shared.mailbox.inputs.finish(input_seq);
            progressed = true;
        }
        if progressed {
            self.shared.notify();
        }
    }

    /// Takes a group start: the move's parameters come from the group the
    /// hub handed this axis.
    fn start_group(&mut self, t: u64, command: Command) -> Result<(), AxisError> {
        let group = self
            .shared
            .group
            .lock()
            .ok()
            .and_then(|group| group.clone())
            .ok_or(AxisError::Fault("a group start without its group"))?;
        let part = GroupMove {
            speed: group.speed,
            lead_steps: group.lead_steps,
            steps: i32::try_from(command.steps).map_err(|_| AxisError::StepsOutOfRange)?,
            start_ct: group.start_ct,
        };
        self.core.command(t, CoreCommand::GroupStart(part))?;
        self.group_slot = group
            .members
            .iter()
            .position(|member| member.upgrade().is_some_and(|m| m.id == self.shared.id))
            .unwrap_or(usize::MAX);
        self.group = Some(group);
        self.look_at_group();
        Ok(())
    }

    /// Sets the pins of this axis's switches for where it is now (a change
    /// of level is an edge in the trace).
    fn drive_switches(&mut self, t: u64) {
        let physical = self.core.physical_position();
        for switch in &self.switches {
            let level = switch.level_at(physical);
            let was = self.hub.pins.set_input(switch.pin, level);
            if was != level && self.shared.tap.enabled() {
                let edge = Edge {
                    ct: t,
                    pin: switch.pin,
                    level,
                };
                match self.hub.clock {
                    ClockMode::Virtual => self
                        .shared
                        .tap
                        .push_waiting(edge, || self.shared.is_shut_down()),
                    ClockMode::Real => self.shared.tap.push_or_count(edge),
                }
            }
        }
    }

    /// Gives the core the input levels, when they changed since it last had them.
    fn feed_inputs(&mut self, t: u64) {
        let levels = self.hub.pins.inputs_word();
        if levels != self.inputs_fed {
            self.inputs_fed = levels;
            self.core.set_inputs(t, levels);
        }
    }

    /// What changes on every step (Release last, on steps-to-go: whoever
    /// sees it sees the position of the same step).
    fn publish_step(&self) {
        let status = &self.shared.mailbox.status;
        self.shared
            .physical
            .store(self.core.physical_position(), Ordering::Relaxed);
        let last = self.core.last_step();
        status
            .position
            .store(self.core.position(), Ordering::Relaxed);
        status.velocity.store(last.velocity, Ordering::Relaxed);
        status
            .delay_ticks
            .store(last.delay_ticks, Ordering::Relaxed);
        status.last_step_ct.store(last.ct, Ordering::Relaxed);
        status
            .mode
            .store(self.core.mode().bits(), Ordering::Relaxed);
        status
            .steps_to_go
            .store(self.core.steps_to_go(), Ordering::Release);
    }

    /// Everything the status shows.
    fn publish_all(&mut self) {
        let status = &self.shared.mailbox.status;
        let info = self.core.move_info();
        let ledger = self.core.ledger();
        status.move_speed.store(info.speed, Ordering::Relaxed);
        status
            .accel_steps
            .store(info.accel_steps, Ordering::Relaxed);
        status.slew_steps.store(info.slew_steps, Ordering::Relaxed);
        status
            .top_velocity
            .store(info.top_velocity, Ordering::Relaxed);
        status
            .max_velocity
            .store(info.max_velocity, Ordering::Relaxed);
        status.move_start_ct.store(info.start_ct, Ordering::Relaxed);
        status
            .offset
            .store(self.core.offset_deg(), Ordering::Relaxed);
        status
            .dropped_steps
            .store(self.core.dropped_steps(), Ordering::Relaxed);
        status.ledger_base.store(ledger.base, Ordering::Relaxed);
        status
            .ledger_accepted
            .store(ledger.accepted, Ordering::Relaxed);
        status
            .ledger_dropped
            .store(ledger.dropped, Ordering::Relaxed);
        status
            .ledger_dropped_total
            .store(ledger.dropped_total, Ordering::Relaxed);
        status.ledger_jogged.store(ledger.jogged, Ordering::Relaxed);
        status
            .math_overruns
            .store(self.core.math_overruns(), Ordering::Relaxed);
        if self.core.events() != self.events_seen {
            self.events_seen = self.core.events();
            *lock(&self.shared.extras) = Extras {
                home_outcome: self.core.home_outcome(),
                limit_trip: self.core.limit_trip(),
                soft_limits: self.core.soft_limits(),
                limit_pins: self.core.limit_pins(),
                homing: self.core.is_homing(),
            };
            self.shared
                .watched
                .store(self.core.watched_pins(), Ordering::Release);
        }
        self.publish_step();
    }
}

/// The core's form of a command from the slot.
fn core_command(command: Command) -> CoreCommand {
    match command.kind {
        // The producer checked the range: a Move's steps fit an i32.
        CommandKind::Move => CoreCommand::Move {
            speed: command.speed,
            steps: i32::try_from(command.steps).unwrap_or(i32::MIN),
        },
        CommandKind::SetPosition => CoreCommand::SetPosition(command.steps),
        CommandKind::Jog => CoreCommand::Jog {
            speed: command.speed,
            direction: if command.steps < 0 {
                Direction::Reverse
            } else {
                Direction::Forward
            },
        },
        CommandKind::JogRelease => CoreCommand::JogRelease,
        CommandKind::GroupReserve => CoreCommand::GroupReserve {
            steps: i32::try_from(command.steps).unwrap_or(i32::MIN),
        },
        CommandKind::GroupCancel | CommandKind::GroupStart => CoreCommand::GroupCancel,
    }
}

/// The group stop's handoff, model-checked: with the virtual clock the hub
/// stops a group between epochs (`Hub::set_input`), then starts the next
/// epoch (`epoch.fetch_add`, AcqRel); every member's cog that sees the new
/// epoch (Acquire) must see the stop before it runs an event of that epoch,
/// or the copies of the lead curve would part. A second stopper racing in
/// (another member's stop pin, from another thread) cannot make a member
/// see a later stop than the hub's.
#[cfg(all(test, loom))]
mod loom_tests {
    use super::*;
    use loom::sync::Arc;
    use loom::thread;

    fn group() -> GroupShared {
        GroupShared {
            speed: 1_000,
            lead_steps: 100,
            start_ct: 0,
            stop_after: AtomicU64::new(u64::MAX),
            members: Vec::new(),
            progress: (0..2).map(|_| AtomicU64::new(0)).collect(),
        }
    }

    /// The lockstep of a group's members with the virtual clock: a member
    /// that trips a limit at CT 5 asks for the line's stop, then says it is
    /// past CT 5; the other member, about to run its event at CT 8, waits
    /// for that and must then see the stop (or its copy of the lead curve
    /// would run past the line's end).
    #[test]
    fn a_member_sees_a_stop_asked_at_a_ct_before_it_passes_it() {
        loom::model(|| {
            let group = Arc::new(group());
            let tripper = {
                let group = Arc::clone(&group);
                thread::spawn(move || {
                    group.stop_after(5);
                    group.set_progress(0, 10);
                })
            };
            while !group.others_reached(1, 8) {
                thread::yield_now();
            }
            assert_eq!(group.stop_ct(), Some(5));
            tripper.join().unwrap();
        });
    }

    #[test]
    fn every_member_sees_the_stop_before_the_next_epoch() {
        loom::model(|| {
            let group = Arc::new(group());
            let epoch = Arc::new(AtomicU64::new(0));
            // One member: each member's cog reads the same two words alike.
            let members: Vec<_> = (0..1)
                .map(|_| {
                    let group = Arc::clone(&group);
                    let epoch = Arc::clone(&epoch);
                    thread::spawn(move || {
                        // The cog: once it sees the new epoch, it looks at
                        // the group before its first event (look_at_group).
                        // (Seeing the old epoch it would wait: no event runs.)
                        (epoch.load(Ordering::Acquire) == 1).then(|| group.stop_ct())
                    })
                })
                .collect();
            let racer = {
                let group = Arc::clone(&group);
                thread::spawn(move || group.stop_after(7_000))
            };
            // The hub: the stop at the CT every cog stands at, then the epoch.
            group.stop_after(5_000);
            epoch.fetch_add(1, Ordering::AcqRel);
            for member in members {
                if let Some(seen) = member.join().unwrap() {
                    assert_eq!(seen, Some(5_000));
                }
            }
            racer.join().unwrap();
            assert_eq!(group.stop_ct(), Some(5_000));
        });
    }
}

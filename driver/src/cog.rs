//! A cog: one worker thread that owns one axis.
//!
//! The cog reads its inputs (the mailbox, the jog heartbeat, emergency-stop
//! requests, its stop pin) at every event, asks the axis's [`Motion`] for the
//! next step, drives the pins and publishes its status in the mailbox:
//!
//! ```text
//! mailbox ─► Motion (profile) ─► step at CT t: dir edge (sd, with set-up),
//!     rising edge at t, falling edge at t + pulse ─► next step at t + delay
//! ```
//!
//! Step times are exact clock ticks whatever the clock: with the virtual
//! clock the cog runs through events up to the CT the hub names; with the
//! real clock it sleeps until its steps are due and makes them in small
//! batches, each edge carrying its scheduled CT.
//!
//! The per-step path touches no shared cache line another cog writes: the
//! inputs are looked at in full only when one of them moved (a cheap
//! comparison of the four input words with what the last look saw, which
//! gives the same result as a full look every time), and the output levels
//! and rising-edge counts stay in the cog until the batch ends
//! ([`OwnPins`]). Status goes to the axis's own mailbox on every step.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::thread::Thread;
use std::time::Duration;

use crate::axis::{Direction, Mode};
use crate::clock::{ClockMode, RealClock};
use crate::mailbox::{CommandKind, Mailbox};
use crate::pins::{Edge, Outputs, PinBank};
use crate::profile::motion::{Accepted, Motion};
use crate::profile::{Phase, Profile};
use crate::sync::{AtomicU32, AtomicU64, Ordering};
use crate::trace::EdgeTap;

/// The most steps a jog asks for at a time.
const JOG_CHUNK_MAX: u32 = 1 << 28;

/// Jog word: bit 32 = reverse, bit 33 = active, low 32 bits = speed.
pub(crate) const JOG_REVERSE: u64 = 1 << 32;
pub(crate) const JOG_ACTIVE: u64 = 1 << 33;

/// The hub's state that cogs read: pins, time, the epoch protocol.
#[derive(Debug)]
pub(crate) struct HubShared {
    pub clock: ClockMode,
    pub pins: PinBank,
    pub real: RealClock,
    /// Virtual CT: every cog has processed all events up to here.
    pub now: AtomicU64,
    /// Virtual clock: the CT the current epoch runs to (u64::MAX: until quiescent).
    pub target: AtomicU64,
    /// Virtual clock: incremented (Release) after `target` is written.
    pub epoch: AtomicU64,
    /// The thread waiting for an epoch to finish.
    pub waiter: Mutex<Option<Thread>>,
    pub pulse_ticks: u32,
    pub dir_setup_ticks: u32,
    pub jog_timeout_ticks: u64,
    /// Clock ticks of CORDIC work per ramp step (QROTATE then QDIV in the cog's slot).
    pub math_ticks: u64,
}

impl HubShared {
    /// CT now, for inputs applied from outside.
    pub fn now(&self) -> u64 {
        match self.clock {
            ClockMode::Virtual => self.now.load(Ordering::Acquire),
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

/// One axis's state shared between its handles, the hub and its cog.
#[derive(Debug)]
pub(crate) struct CogShared {
    pub id: usize,
    pub mailbox: Mailbox,
    pub outputs: Outputs,
    pub stop_pin: u8,
    pub tap: EdgeTap,
    pub shutdown: AtomicBool,
    /// Set while the cog takes a full look at its inputs. A producer that
    /// saw its command taken waits for it to clear (Acquire), and then sees
    /// the command applied (STM, mode), not just taken.
    pub looking: AtomicBool,
    /// Virtual clock: the last epoch this cog finished, and its CT then.
    pub done_epoch: AtomicU64,
    pub ct: AtomicU64,
    /// Emergency stops the cog has carried out.
    pub estop_done: AtomicU32,
    /// Incremented (Release) after each change of the stop pin.
    pub input_seq: AtomicU64,
    /// The last `input_seq` a full look has handled.
    pub input_seq_done: AtomicU64,
    /// Incremented on every jog request (heartbeat or release).
    pub jog_seq: AtomicU64,
    /// The last jog request the cog has handled.
    pub jog_seq_done: AtomicU64,
    pub thread: Mutex<Option<Thread>>,
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
            looking: AtomicBool::new(false),
            done_epoch: AtomicU64::new(0),
            ct: AtomicU64::new(0),
            estop_done: AtomicU32::new(0),
            input_seq: AtomicU64::new(0),
            input_seq_done: AtomicU64::new(0),
            jog_seq: AtomicU64::new(0),
            jog_seq_done: AtomicU64::new(0),
            thread: Mutex::new(None),
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

    fn is_shut_down(&self) -> bool {
        self.shutdown.load(std::sync::atomic::Ordering::Acquire)
    }
}

/// The cog's own state (only its thread touches it).
pub(crate) struct Cog {
    shared: Arc<CogShared>,
    hub: Arc<HubShared>,
    motion: Motion,
    /// All events up to this CT are done.
    ct: u64,
    /// When the next step is due (or the last delay ends), while moving.
    due: Option<u64>,
    /// When the axis is ready for a next first step (last step + its delay).
    ready_ct: u64,
    /// Current level of the direction pin (sd), or last direction (cc).
    dir_reverse: bool,
    /// When the last pulse ends: a direction change may not come before.
    last_fall_ct: u64,
    /// Flags that outlive a move (STOP_LATCHED, ESTOP, JOG).
    sticky: u32,
    /// A command taken while the stop pin is low, waiting for it to go high.
    held: Option<(u32, i32)>,
    /// The stop pin was low at the last look and the move was told to stop.
    stopping: bool,
    estop_seen: u32,
    jog_seq_seen: u64,
    /// Jogging: speed, direction and the CT by which the next beat must come.
    jog: Option<(u32, Direction, u64)>,
    epoch_seen: u64,
    /// `CogShared::input_seq` as the last full look at the inputs saw it.
    input_seq_seen: u64,
    /// A step changed what a full look would publish (a move ended, or a
    /// queued one began), so the next look may not be skipped.
    republish: bool,
    pins: OwnPins,
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
    pub fn new(shared: Arc<CogShared>, hub: Arc<HubShared>, motion: Motion, ct: u64) -> Self {
        let outputs = shared.outputs;
        Self {
            shared,
            hub,
            motion,
            ct,
            due: None,
            ready_ct: ct,
            dir_reverse: false,
            last_fall_ct: 0,
            sticky: 0,
            held: None,
            stopping: false,
            estop_seen: 0,
            jog_seq_seen: 0,
            jog: None,
            epoch_seen: 0,
            input_seq_seen: 0,
            republish: true,
            pins: OwnPins::new(outputs),
        }
    }

    /// The thread's body.
    pub fn run(mut self) {
        self.epoch_seen = self.hub.epoch.load(Ordering::Acquire);
        self.shared
            .done_epoch
            .store(self.epoch_seen, Ordering::Release);
        match self.hub.clock {
            ClockMode::Virtual => self.run_virtual(),
            ClockMode::Real => self.run_real(),
        }
    }

    fn run_virtual(&mut self) {
        while !self.shared.is_shut_down() {
            // Inputs applied between epochs take effect at the hub's CT.
            if self.due.is_none() {
                self.ct = self.ct.max(self.hub.now.load(Ordering::Acquire));
            }
            self.poll(self.ct);
            let epoch = self.hub.epoch.load(Ordering::Acquire);
            if epoch != self.epoch_seen {
                let target = self.hub.target.load(Ordering::Acquire);
                self.run_until(target);
                self.epoch_seen = epoch;
                self.shared.ct.store(self.ct, Ordering::Release);
                self.shared.done_epoch.store(epoch, Ordering::Release);
                self.hub.wake_waiter();
                continue;
            }
            std::thread::park();
        }
    }

    fn run_real(&mut self) {
        while !self.shared.is_shut_down() {
            let now = self.hub.real.now();
            if self.due.is_none() {
                // Idle: a command found now starts now, not at the CT of
                // the last wake-up (up to a long nap ago), which would
                // make the move's first steps in one late burst.
                self.ct = self.ct.max(now);
            }
            self.run_until(now);
            match self.next_event() {
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

    /// The next CT at which something happens without outside input.
    fn next_event(&self) -> Option<u64> {
        let jog_deadline = self.jog.map(|(_, _, deadline)| deadline);
        match (self.due, jog_deadline) {
            (Some(due), Some(deadline)) => Some(due.min(deadline)),
            (due, deadline) => due.or(deadline),
        }
    }

    /// Processes every event up to `limit` (virtual: u64::MAX = until nothing is left).
    fn run_until(&mut self, limit: u64) {
        // Inputs are read once before the first event and then once at each
        // event's CT, before it happens: a step never takes a second look.
        self.poll_if_needed(self.ct);
        while !self.shared.is_shut_down() {
            match self.next_event() {
                Some(t) if t <= limit => {
                    self.ct = self.ct.max(t);
                    self.poll_if_needed(self.ct);
                    if self.due.is_some_and(|due| due <= self.ct) {
                        self.step();
                    }
                }
                _ => break,
            }
        }
        if limit != u64::MAX {
            self.ct = self.ct.max(limit);
        }
        self.pins.publish(&self.hub.pins);
    }

    /// Reads the inputs at CT `t` unless a full look would change nothing.
    #[inline]
    fn poll_if_needed(&mut self, t: u64) {
        if !self.poll_is_noop() {
            self.poll(t);
        }
    }

    /// Whether [`Cog::poll`] would do nothing new: no input word moved since
    /// the last full look, no jog deadline or held move is pending, and no
    /// step since changed what the look publishes. Loads only: the lines
    /// stay shared, and nothing is skipped that the full look would do.
    #[inline]
    fn poll_is_noop(&self) -> bool {
        let mailbox = &self.shared.mailbox;
        !self.republish
            && self.jog.is_none()
            && self.held.is_none()
            && mailbox.estop_requests.load(Ordering::Acquire) == self.estop_seen
            && !mailbox.has_command()
            && self.shared.jog_seq.load(Ordering::Acquire) == self.jog_seq_seen
            && self.shared.input_seq.load(Ordering::Acquire) == self.input_seq_seen
    }

    /// Reads the inputs at CT `t`.
    fn poll(&mut self, t: u64) {
        // Relaxed: published by the Release with which `take` frees the slot.
        self.shared
            .looking
            .store(true, std::sync::atomic::Ordering::Relaxed);
        self.look(t);
        // Release: whoever sees the look over sees what it applied.
        self.shared
            .looking
            .store(false, std::sync::atomic::Ordering::Release);
    }

    /// The full look at the inputs (see [`Cog::poll`]).
    fn look(&mut self, t: u64) {
        self.republish = false;
        // Acquire: the stop pin's level read below is at least as new as
        // the change that bumped the sequence.
        let input_seq = self.shared.input_seq.load(Ordering::Acquire);
        self.look_inputs(t);
        self.input_seq_seen = input_seq;
        // Release: whoever sees this sees the look's effects.
        self.shared
            .input_seq_done
            .store(input_seq, Ordering::Release);
    }

    fn look_inputs(&mut self, t: u64) {
        // Emergency stop first: it overrides everything after it.
        let estops = self.shared.mailbox.estop_requests.load(Ordering::Acquire);
        if estops != self.estop_seen {
            self.estop_seen = estops;
            let dropped = self.motion.estop();
            self.shared
                .mailbox
                .dropped_steps
                .store(dropped, Ordering::Relaxed);
            self.held = None;
            self.jog = None;
            self.due = None;
            self.ready_ct = self.ready_ct.max(t);
            self.sticky = Mode::ESTOP | (self.sticky & Mode::STOP_LATCHED);
            self.pins.publish(&self.hub.pins);
            self.publish_idle();
            self.shared.estop_done.store(estops, Ordering::Release);
        }
        let stop_pin_high = self.hub.pins.input(self.shared.stop_pin);
        if let Some(command) = self.shared.mailbox.take() {
            match command.kind {
                CommandKind::Move => {
                    let steps = i32::try_from(command.steps).unwrap_or(0);
                    if stop_pin_high {
                        self.apply_move(t, command.speed, steps);
                    } else if self.held.is_none() {
                        self.held = Some((command.speed, steps));
                    } else {
                        self.shared.mailbox.refused.fetch_add(1, Ordering::Relaxed);
                    }
                }
                CommandKind::SetPosition => {
                    if self.motion.is_moving() || self.held.is_some() {
                        self.shared.mailbox.refused.fetch_add(1, Ordering::Relaxed);
                    } else {
                        self.shared
                            .mailbox
                            .position
                            .store(command.steps, Ordering::Relaxed);
                    }
                }
            }
        }
        self.poll_jog(t, stop_pin_high);
        if stop_pin_high {
            self.stopping = false;
            if let Some((speed, steps)) = self.held.take() {
                self.apply_move(t, speed, steps);
            }
        } else if !self.stopping && self.motion.is_moving() {
            // Stop pin low: decelerate at once from the current velocity.
            self.stopping = true;
            let dropped = self.motion.stop();
            self.shared
                .mailbox
                .dropped_steps
                .store(dropped, Ordering::Relaxed);
            self.jog = None;
            self.sticky = (self.sticky | Mode::STOP_LATCHED) & !Mode::JOG;
        }
        let mut mode = self.mode_now();
        if self.held.is_some() {
            mode |= Mode::HOLD;
        }
        self.shared.mailbox.mode.store(mode, Ordering::Relaxed);
        let queued = u32::from(self.motion.steps_to_go() > self.remaining_in_current());
        self.shared.mailbox.queued.store(queued, Ordering::Relaxed);
    }

    fn remaining_in_current(&self) -> u64 {
        self.motion
            .current()
            .map_or(0, |(curve, _)| u64::from(curve.remaining_steps()))
    }

    /// Jog heartbeats and their deadline.
    fn poll_jog(&mut self, t: u64, stop_pin_high: bool) {
        let seq = self.shared.jog_seq.load(Ordering::Acquire);
        if seq != self.jog_seq_seen {
            self.jog_seq_seen = seq;
            let word = self.shared.mailbox.jog.load(Ordering::Relaxed);
            let beat = self.shared.mailbox.jog_beat_ct.load(Ordering::Relaxed);
            if word & JOG_ACTIVE == 0 {
                // Released: decelerate now.
                if self.jog.take().is_some() {
                    self.motion.stop();
                    self.sticky &= !Mode::JOG;
                }
            } else if stop_pin_high {
                let speed = word as u32;
                let direction = if word & JOG_REVERSE != 0 {
                    Direction::Reverse
                } else {
                    Direction::Forward
                };
                let deadline = beat.saturating_add(self.hub.jog_timeout_ticks);
                let same = self
                    .jog
                    .is_some_and(|(s, d, _)| s == speed && d == direction);
                // Top up a long jog only on a move that already runs this way.
                let running_this_way = self
                    .motion
                    .current()
                    .is_some_and(|(curve, d)| d == direction && curve.is_running());
                let chunk = self.jog_chunk(speed);
                let low = running_this_way && self.remaining_in_current() < u64::from(chunk / 2);
                if !same || low || !self.motion.is_moving() {
                    let magnitude = i32::try_from(chunk).unwrap_or(i32::MAX);
                    let steps = if direction == Direction::Reverse {
                        -magnitude
                    } else {
                        magnitude
                    };
                    self.apply_move(t, speed, steps);
                }
                if self.motion.is_moving() {
                    self.jog = Some((speed, direction, deadline));
                    self.sticky |= Mode::JOG;
                }
            }
        }
        self.shared
            .jog_seq_done
            .store(self.jog_seq_seen, Ordering::Release);
        if let Some((_, _, deadline)) = self.jog {
            if t >= deadline {
                // No heartbeat in time: the caller is gone or let go.
                self.jog = None;
                self.motion.stop();
                self.sticky &= !Mode::JOG;
            }
        }
    }

    /// Steps a jog asks for at a time: enough to reach `speed`, run two
    /// heartbeat timeouts at it and still stop. A beat tops the jog up when
    /// fewer than half are left, so between two beats (at most one timeout
    /// apart, or the jog ends) the axis never starts slowing down by itself,
    /// and STM stays a meaningful count.
    fn jog_chunk(&self, speed: u32) -> u32 {
        let config = self.motion.config();
        let accel_steps = u64::from(speed / config.accel_div.max(1) + 2);
        let timeout_steps =
            u64::from(speed) * self.hub.jog_timeout_ticks / u64::from(config.clkfreq.max(1)) + 1;
        let chunk = 2 * (2 * accel_steps + timeout_steps) + 16;
        u32::try_from(chunk.min(u64::from(JOG_CHUNK_MAX))).unwrap_or(JOG_CHUNK_MAX)
    }

    /// Hands a move to the motion and schedules its first step.
    fn apply_move(&mut self, t: u64, speed: u32, steps: i32) {
        let mailbox = &self.shared.mailbox;
        let was_moving = self.motion.is_moving();
        match self.motion.command(speed, steps) {
            Ok(accepted) => {
                if accepted == Accepted::Started {
                    self.sticky &= !(Mode::STOP_LATCHED | Mode::ESTOP | Mode::JOG);
                    let reverse = if steps < 0 { Mode::REVERSE } else { 0 };
                    mailbox
                        .mode
                        .store(Mode::MOVING | Mode::ACCEL | reverse, Ordering::Relaxed);
                    mailbox.dropped_steps.store(0, Ordering::Relaxed);
                    mailbox.move_start_ct.store(t, Ordering::Relaxed);
                }
                if !was_moving {
                    self.due = Some(self.due.unwrap_or(t).max(t).max(self.ready_ct));
                }
                if let Some((curve, _)) = self.motion.current() {
                    let plan = curve.plan();
                    if accepted != Accepted::Queued {
                        // The speed asked for (the top speed may be lower).
                        mailbox.move_speed.store(speed, Ordering::Relaxed);
                    }
                    mailbox
                        .accel_steps
                        .store(curve.accel_steps(), Ordering::Relaxed);
                    mailbox.offset.store(plan.offset_deg, Ordering::Relaxed);
                    mailbox
                        .top_velocity
                        .store(curve.top_speed(), Ordering::Relaxed);
                    mailbox.slew_steps.store(plan.slew_steps, Ordering::Relaxed);
                }
                let stm = u32::try_from(self.motion.steps_to_go()).unwrap_or(u32::MAX);
                mailbox.stm.store(stm, Ordering::Release);
            }
            Err(_) => {
                mailbox.refused.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Makes the step that is due at `self.ct`, or ends the move.
    fn step(&mut self) {
        let mut t = self.ct;
        let Some(next) = self.motion.next_step() else {
            self.due = None;
            self.ready_ct = t;
            self.republish = true;
            // Whoever sees STM = 0 sees every edge of the move counted.
            self.pins.publish(&self.hub.pins);
            self.publish_idle();
            return;
        };
        if next.step.index == 0 {
            // A move began (perhaps a queued one): the look republishes.
            self.republish = true;
        }
        let reverse = next.direction == Direction::Reverse;
        if reverse != self.dir_reverse {
            if let Some(dir_pin) = self.shared.outputs.dir_pin() {
                // The direction must settle `dir_setup` before the step edge,
                // and may not change while the last pulse is still high.
                let setup = u64::from(self.hub.dir_setup_ticks);
                let dir_ct = t.saturating_sub(setup).max(self.last_fall_ct);
                t = t.max(dir_ct + setup);
                self.emit(Edge {
                    ct: dir_ct,
                    pin: dir_pin,
                    level: reverse,
                });
            }
            self.dir_reverse = reverse;
        }
        let pin = self.shared.outputs.pulse_pin(next.direction);
        let fall = t + u64::from(self.hub.pulse_ticks);
        self.emit(Edge {
            ct: t,
            pin,
            level: true,
        });
        self.emit(Edge {
            ct: fall,
            pin,
            level: false,
        });
        self.last_fall_ct = fall;
        let mailbox = &self.shared.mailbox;
        let delay = next.step.delay_ticks;
        if next.step.phase != Phase::Slew && u64::from(delay) < self.hub.math_ticks {
            mailbox.math_overruns.fetch_add(1, Ordering::Relaxed);
        }
        // The cog is the position's only writer (set_position goes through
        // the command slot), so a load and a store do what an atomic add
        // would, without its locked bus cycle on every step.
        let position = mailbox.position.load(Ordering::Relaxed) + next.direction.sign();
        mailbox.position.store(position, Ordering::Relaxed);
        mailbox
            .velocity
            .store(next.step.velocity_steps_per_s as u32, Ordering::Relaxed);
        mailbox.delay_ticks.store(delay, Ordering::Relaxed);
        mailbox.last_step_ct.store(t, Ordering::Relaxed);
        let mut mode = Mode::MOVING | (self.sticky & !Mode::HOLD);
        mode |= match next.step.phase {
            Phase::Accel => Mode::ACCEL,
            Phase::Slew => Mode::SLEW,
            Phase::Decel => Mode::DECEL,
        };
        if reverse {
            mode |= Mode::REVERSE;
        }
        mailbox.mode.store(mode, Ordering::Relaxed);
        let stm = u32::try_from(self.motion.steps_to_go()).unwrap_or(u32::MAX);
        // Release: whoever sees this STM also sees the position above.
        mailbox.stm.store(stm, Ordering::Release);
        self.ct = t;
        self.due = Some(t + u64::from(delay));
        self.ready_ct = t + u64::from(delay);
    }

    /// Mode bits between steps: the phase of the last step while moving,
    /// plus the flags that outlive a step.
    fn mode_now(&self) -> u32 {
        const STEP_BITS: u32 =
            Mode::MOVING | Mode::ACCEL | Mode::DECEL | Mode::SLEW | Mode::REVERSE;
        let current = self.shared.mailbox.mode.load(Ordering::Relaxed);
        if self.due.is_some() {
            (current & STEP_BITS) | self.sticky
        } else {
            let reverse = if self.dir_reverse { Mode::REVERSE } else { 0 };
            self.sticky | reverse
        }
    }

    fn publish_idle(&self) {
        let mailbox = &self.shared.mailbox;
        let reverse = if self.dir_reverse { Mode::REVERSE } else { 0 };
        mailbox
            .mode
            .store((self.sticky & !Mode::JOG) | reverse, Ordering::Relaxed);
        mailbox.velocity.store(0, Ordering::Relaxed);
        mailbox.stm.store(0, Ordering::Release);
    }

    fn emit(&mut self, edge: Edge) {
        self.pins.drive(edge.pin, edge.level);
        if self.shared.tap.enabled() {
            match self.hub.clock {
                ClockMode::Virtual => {
                    let shared = &self.shared;
                    self.shared.tap.push_waiting(edge, || shared.is_shut_down());
                }
                ClockMode::Real => self.shared.tap.push_or_count(edge),
            }
        }
    }
}

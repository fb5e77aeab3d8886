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

//!
//! What the cog shares with the hub and the handles (its mailbox, the
//! calls that wait for its answer, a group's stop) is in `cog::shared`.

use std::sync::Arc;
use std::time::Duration;

mod shared;

use shared::{lock, ExitGuard};
pub(crate) use shared::{CogShared, Extras, GroupShared, HubShared, PathSignal};

use crate::clock::ClockMode;
use crate::mailbox::{Command, CommandKind, DecodeError};
use crate::pins::PinBank;
use crate::status::{MoveStatus, StatusSnapshot, StepStatus};
use crate::switch::Switch;
use crate::sync::Ordering;
use cogstep_motion::axis::{AxisError, Direction};
use cogstep_motion::axis_core::{
    AxisCore, CoreCommand, Edge, GroupMove, GroupRequest, Outputs, PATH_QUEUE,
};

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
            self.top_up_path();
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
            self.top_up_path();
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
            self.top_up_path();
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
        // The other members see where this one stands (its next event lies
        // beyond this batch, or its part ended).
        self.look_at_group();
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

    /// A path axis: moves the path's steps from the feed into the core as
    /// it has room. A step the core refuses (a limit) ends the feed; the
    /// path's owner sees the error and stops the path.
    #[inline]
    fn top_up_path(&mut self) {
        if !self.core.on_path() {
            return;
        }
        let room = self.core.path_room();
        if room < PATH_QUEUE / 2 {
            return;
        }
        let mut feed = lock(&self.shared.path_feed);
        for _ in 0..room {
            let Some((ct, forward)) = feed.pop_front() else {
                break;
            };
            if let Err(error) = self.core.push_path_step(ct, forward) {
                feed.clear();
                self.shared.path.refuse(error);
                break;
            }
        }
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
        // A group stop (a stop pin) or an e-stop reaches the part before the
        // caller hears the cog has looked, and the other members do not
        // wait for a part an e-stop ended.
        self.look_at_group();
        if let Some(taken) = self.shared.mailbox.take() {
            let taken =
                taken
                    .map_err(DecodeError::into_axis_error)
                    .and_then(core_command)
                    .and_then(|taken| match taken {
                        // A setting's command rides in the slot's setting lock.
                        Taken::Setting => {
                            self.shared.mailbox.take_setting().map(Taken::Core).ok_or(
                                AxisError::Fault("the mailbox held a setting without its command"),
                            )
                        }
                        taken => Ok(taken),
                    });
            // A move of the axis's own: it leaves the group it last ran a part of.
            let moves = matches!(
                taken,
                Ok(Taken::Core(
                    CoreCommand::Move { .. }
                        | CoreCommand::Jog { .. }
                        | CoreCommand::GroupReserve { .. }
                        | CoreCommand::Home(_)
                        | CoreCommand::PathStart
                ))
            );
            let reply = match taken {
                Ok(Taken::Core(command)) => self.core.command(t, command).map(|_| ()),
                Ok(Taken::GroupStart { steps }) => self.start_group(t, steps),
                Ok(Taken::Setting) => Err(AxisError::Fault("a setting taken twice")),
                Err(error) => Err(error),
            };
            if moves && reply.is_ok() {
                self.leave_group_record();
            }
            self.look_at_group();
            // The status first, then the answer: the caller sees both.
            self.publish_all();
            self.shared.mailbox.answer(reply);
            progressed = true;
        }
        if input_seq != self.input_seq_seen {
            self.input_seq_seen = input_seq;
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
    fn start_group(&mut self, t: u64, steps: i32) -> Result<(), AxisError> {
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
            steps,
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

    /// What changes on every step, as one status write.
    fn publish_step(&self) {
        self.shared
            .physical
            .store(self.core.physical_position(), Ordering::Relaxed);
        self.shared.mailbox.status.publish_step(&self.step_status());
    }

    fn step_status(&self) -> StepStatus {
        let last = self.core.last_step();
        StepStatus {
            position: self.core.position(),
            steps_to_go: self.core.steps_to_go(),
            mode: self.core.mode().bits(),
            velocity: last.velocity,
            delay_ticks: last.delay_ticks,
            last_step_ct: last.ct,
        }
    }

    /// Everything the status shows, as one status write.
    fn publish_all(&mut self) {
        let info = self.core.move_info();
        let snapshot = StatusSnapshot {
            step: self.step_status(),
            moves: MoveStatus {
                move_speed: info.speed,
                accel_steps: info.accel_steps,
                slew_steps: info.slew_steps,
                top_velocity: info.top_velocity,
                max_velocity: info.max_velocity,
                move_start_ct: info.start_ct,
                offset: self.core.offset_deg(),
                dropped_steps: self.core.dropped_steps(),
                ledger: self.core.ledger(),
                math_overruns: self.core.math_overruns(),
            },
        };
        self.shared
            .physical
            .store(self.core.physical_position(), Ordering::Relaxed);
        self.shared.mailbox.status.publish_all(&snapshot);
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
        // Last: the trip is written before the word that says the core
        // left the path.
        self.shared.path.publish(
            self.core.on_path(),
            self.core.limit_trip().map(|trip| trip.side),
        );
    }
}

/// What a command from the slot asks of the cog.
#[derive(Debug)]
enum Taken {
    /// A command the core takes as it is.
    Core(CoreCommand),
    /// A group start: the rest of the move is in the axis's group
    /// ([`Cog::start_group`]).
    GroupStart { steps: i32 },
    /// A setting: its command is in the slot's setting lock.
    Setting,
}

/// The core's form of a command from the slot, one arm per kind. Steps
/// outside an i32 are refused here (the producers check them before
/// posting, so this is a second look, never a different command).
fn core_command(command: Command) -> Result<Taken, AxisError> {
    let steps_i32 = || i32::try_from(command.steps).map_err(|_| AxisError::StepsOutOfRange);
    Ok(match command.kind {
        CommandKind::Move => Taken::Core(CoreCommand::Move {
            speed: command.speed,
            steps: steps_i32()?,
        }),
        CommandKind::SetPosition => Taken::Core(CoreCommand::SetPosition(command.steps)),
        CommandKind::Jog => Taken::Core(CoreCommand::Jog {
            speed: command.speed,
            direction: if command.steps < 0 {
                Direction::Reverse
            } else {
                Direction::Forward
            },
        }),
        CommandKind::JogRelease => Taken::Core(CoreCommand::JogRelease),
        CommandKind::GroupReserve => Taken::Core(CoreCommand::GroupReserve {
            steps: steps_i32()?,
        }),
        CommandKind::GroupCancel => Taken::Core(CoreCommand::GroupCancel),
        CommandKind::GroupStart => Taken::GroupStart {
            steps: steps_i32()?,
        },
        CommandKind::Setting => Taken::Setting,
        CommandKind::PathStart => Taken::Core(CoreCommand::PathStart),
        CommandKind::PathEnd => Taken::Core(CoreCommand::PathEnd),
    })
}

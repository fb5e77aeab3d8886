//! One axis of the firmware: the driver's [`AxisCore`] (everything the axis
//! decides, time in and edges out, the same core the host's cogs run) and
//! the edges it has decided but whose time has not come yet.
//!
//! The core emits a step's edges when it makes the step: the direction
//! edge `dir_setup_ticks` *before* the rising edge, the falling edge
//! `pulse_ticks` after it. A timer interrupt cannot drive a pin in the
//! past, so the firmware's core lives [`AxisRunner::lookahead`] ticks (the
//! set-up time) ahead of the clock: a command arriving at CT `now` reaches
//! the core at `now + lookahead`, the core runs its events up to that
//! time, and the edges it decides are queued and driven each at its CT,
//! which is then never in the past. Every step and edge is the core's,
//! shifted by the set-up time (5 µs); position and mode show a step that
//! long before its rising edge.

use driver::axis::{AxisError, AxisStatus, LimitStatus, Mode};
use driver::axis_core::{
    AxisCore, AxisCoreConfig, CoreCommand, Edge, GroupLead, GroupRequest, Outputs, StepTrain,
};
use driver::profile::scurve::{SCurve, ScurveConfig};
use heapless::Deque;

use cogstep_handoff::AheadSlot;

/// Which of an axis's two output pins an edge is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    /// The step pin (`sd`) or the clockwise pin (`cc`).
    First,
    /// The direction pin (`sd`) or the counter-clockwise pin (`cc`).
    Second,
}

impl Output {
    /// 0 for [`Output::First`], 1 for [`Output::Second`].
    pub fn index(self) -> usize {
        match self {
            Output::First => 0,
            Output::Second => 1,
        }
    }

    fn of_pin(pin: u8) -> Self {
        if pin == 0 {
            Output::First
        } else {
            Output::Second
        }
    }
}

/// The two output variants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// Step and direction.
    Sd,
    /// Clockwise and counter-clockwise.
    Cc,
}

/// The core's settings for an axis of a board whose CT runs at `clkfreq`:
/// the host hub's timings (5 µs pulse and direction set-up, 150 ms jog
/// timeout), the axis's own pins numbered 0 ([`Output::First`]) and 1.
pub fn core_config(clkfreq: u32, variant: Variant) -> AxisCoreConfig {
    let micros = |us: u64| u64::from(clkfreq) * us / 1_000_000;
    let outputs = match variant {
        Variant::Sd => Outputs::StepDir { step: 0, dir: 1 },
        Variant::Cc => Outputs::CwCcw { cw: 0, ccw: 1 },
    };
    AxisCoreConfig {
        scurve: ScurveConfig {
            clkfreq,
            ..ScurveConfig::default()
        },
        outputs,
        pulse_ticks: u32::try_from(micros(5)).unwrap_or(u32::MAX).max(1),
        dir_setup_ticks: u32::try_from(micros(5)).unwrap_or(u32::MAX),
        jog_timeout_ticks: micros(150_000),
        math_ticks: 0,
        limit_estop: false,
        input_latency_ticks: 0,
    }
}

/// What one run of an axis did (for cost measurements).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Work {
    /// Ramp steps made (accelerating or decelerating).
    pub ramp_steps: u32,
    /// Slew steps made.
    pub slew_steps: u32,
    /// Edges driven.
    pub edges: u32,
}

impl Work {
    /// Adds another run's work.
    pub fn add(&mut self, other: Work) {
        self.ramp_steps += other.ramp_steps;
        self.slew_steps += other.slew_steps;
        self.edges += other.edges;
    }
}

/// Rising and falling edges driven on each output since boot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EdgeCounts {
    /// Rising edges on [`Output::First`] and [`Output::Second`].
    pub rising: [u64; 2],
    /// Falling edges on each output.
    pub falling: [u64; 2],
}

/// Edges decided and not yet driven: a step's direction, rising and
/// falling edges, for the steps inside the look-ahead (two at most while
/// the pulse fits between steps, which the core checks).
const QUEUE: usize = 8;

/// [`AxisRunner`]'s wake-up when it has nothing to wait for (and a
/// train's falling edge when it has none to drive).
pub(crate) const NEVER: u64 = u64::MAX;

/// An [`AxisCore`] run ahead of the clock, with its pending edges.
///
/// A step whose edges the core can tell before making it (the same
/// direction, no direction edge: every step of a move but its first and
/// a reversal's, see [`AxisCore::next_plain_step`]) is not made ahead:
/// the interrupt at its rising edge drives the edge and then lets the
/// core make the step, so a step costs two interrupts (rising edge and
/// decision; falling edge) instead of three. Whatever reads or changes
/// the core first brings it up to where the look-ahead would have it
/// ([`AxisRunner::sync`]), so the core sees the same inputs at the same
/// CTs and decides the same steps, and the pins get the same edges.
///
/// At speed the core hands its slew steps out ahead as a
/// [`StepTrain`] (each step's CT is one 32.32 addition from the last),
/// and on a ramp the steps its profile computed ahead (a few at a time,
/// each delay known): the interrupt then only drives edges and adds, and
/// the train goes back to the core when it ends or before anything reads
/// or changes the core.
#[derive(Clone, Debug)]
pub struct AxisRunner {
    core: AxisCore,
    pending: Deque<Edge, QUEUE>,
    edges: EdgeCounts,
    /// When the axis next needs the step interrupt ([`NEVER`]: not at
    /// all), kept up to date by everything that changes the core or the
    /// queue.
    wake: u64,
    /// Steps out of the core (slew, or ramp steps computed ahead), while
    /// it holds them.
    train: Option<Train>,
    /// When the core next needs the interrupt ([`NEVER`]: not at all), as
    /// [`AxisRunner::refresh_wake`] found it last (the core has not
    /// changed since while no train is out).
    core_wake: u64,
    /// The stop level the protocol set (`S`, `R`, `!`) and the level of
    /// the board's stop input: the core's stop pin is high while both are.
    stop_command_high: bool,
    stop_input_high: bool,
    /// The group move this axis last ran a part of, until it takes a move
    /// of its own (see [`crate::group`]).
    group: Option<GroupRecord>,
    /// An emergency stop came to this axis while it had a group record:
    /// the group's other parts stop too.
    group_estop: bool,
    /// Where another core computes this axis's next ramp run (see
    /// [`cogstep_handoff`]), if one does, and how long it would take to
    /// answer a request ([`RunAheadTicks`]).
    ahead: Option<(&'static AheadSlot<SCurve>, RunAheadTicks)>,
    /// The run (its [`AxisCore::run_end_index`]) the last request was
    /// posted for: one request a run.
    ahead_key: Option<u32>,
    /// Runs computed ahead that the core took (their prediction came
    /// true): runs it did not compute itself.
    runs_taken: u32,
}

/// A board's estimate of the ticks another core would take to answer a
/// request for an axis's next ramp run posted now: its backlog and the
/// run's cost. The axis asks only when its armed run lasts that long
/// ([`AxisCore::ramp_run_lasts`]): an answer that comes after the run is
/// used up is thrown away (the axis computed that run itself meanwhile),
/// and a helper that answers late ones falls further behind on the others.
pub type RunAheadTicks = fn() -> u64;

/// An axis's record of the group move it last ran a part of: the group's
/// number (one per `G`) and its members (bit per axis).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct GroupRecord {
    pub(crate) id: u32,
    pub(crate) members: u8,
}

/// A [`StepTrain`] in the runner's hands (or lent to the board's fast
/// path, [`crate::fast::FastTrain`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Train {
    pub(crate) steps: StepTrain,
    pub(crate) output: Output,
    /// The falling edge of the step made last ([`NEVER`]: driven).
    pub(crate) fall_ct: u64,
    /// The core's own next event (a jog's deadline) comes due: the train
    /// goes back before it, at this CT.
    pub(crate) give_back_ct: u64,
}

impl Train {
    /// When the axis next needs the step interrupt, the train running.
    fn wake(&self) -> u64 {
        self.fall_ct.min(self.steps.rise_ct).min(self.give_back_ct)
    }

    /// Drives the rising edge of the step at `steps.rise_ct`, makes the
    /// step and arms its pulse's falling edge; returns whether the train
    /// has a step after it.
    #[inline(always)]
    fn rise(
        &mut self,
        rising: &mut [u64; 2],
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
        work: &mut Work,
    ) -> bool {
        drive(self.output, true, self.steps.rise_ct);
        rising[self.output.index()] += 1;
        work.edges += 1;
        if self.steps.is_ramp() {
            work.ramp_steps += 1;
        } else {
            work.slew_steps += 1;
        }
        self.fall_ct = self.steps.rise_ct + u64::from(self.steps.pulse_ticks);
        self.steps.make_step();
        self.steps.has_step()
    }
}

/// A train's steps as an iterator of their rising edges' CTs, for
/// [`crate::Hardware::set_rises_at`]: each `next` makes the step whose
/// rising edge it returns, while the step is the train's to make ahead
/// (its rise by the run's frontier and before the train goes back to its
/// core, and a step of the train after it) and the run's count allows. A
/// step is made only when taken: a board that stops taking leaves the
/// rest in the train.
pub struct TrainRises<'a> {
    steps: &'a mut StepTrain,
    /// The last CT a step may rise at: the run's frontier, and before the
    /// train goes back.
    last_ct: u64,
    /// Steps the run may still make: its count, and all but the train's
    /// last (the core decides what follows that one).
    left: u32,
    made: u32,
}

impl<'a> TrainRises<'a> {
    /// A run of `steps` up to CT `until`, before `give_back_ct`, of at most
    /// `max` steps.
    fn new(steps: &'a mut StepTrain, until: u64, give_back_ct: u64, max: u32) -> Self {
        // A give-back at CT 0 leaves no step (none rises before it).
        let left = match give_back_ct {
            0 => 0,
            _ => max.min(steps.steps_left.saturating_sub(1)),
        };
        TrainRises {
            last_ct: until.min(give_back_ct.saturating_sub(1)),
            left,
            steps,
            made: 0,
        }
    }
}

impl Iterator for TrainRises<'_> {
    type Item = u64;

    #[inline(always)]
    fn next(&mut self) -> Option<u64> {
        let steps = &mut *self.steps;
        let ct = steps.rise_ct;
        if self.left == 0 || ct > self.last_ct {
            return None;
        }
        if steps.limit_ct != NEVER && ends_before_its_next_step(steps) {
            return None;
        }
        steps.make_step();
        self.left -= 1;
        self.made += 1;
        Some(ct)
    }
}

impl TrainRises<'_> {
    /// The run's next steps at once, as many as fit `rises` and `next`
    /// would make one by one: each one's rising CT into `rises`, in
    /// order; returns how many (0: the run is over, or `rises` is
    /// empty). The same steps and the same train as that many `next`
    /// calls (a jog's train, whose deadline `next` looks past each step
    /// for, goes one step at a time); one loop over the train's fields in
    /// registers ([`StepTrain::make_steps_into`]) where `next` is a call
    /// of the iterator each, for a board that handles the CTs a run at a
    /// time (the Pico's PIO build).
    #[inline(always)]
    pub fn fill(&mut self, rises: &mut [u64]) -> usize {
        if self.steps.limit_ct != NEVER {
            let mut count = 0;
            for slot in rises.iter_mut() {
                let Some(ct) = self.next() else { break };
                *slot = ct;
                count += 1;
            }
            return count;
        }
        let most = rises.len().min(self.left as usize);
        let count = self.steps.make_steps_into(self.last_ct, &mut rises[..most]);
        self.left -= count as u32;
        self.made += count as u32;
        count
    }
}

/// Whether a train with a deadline (a jog's) ends before the step after
/// its next one: then that next step is not the train's to make ahead.
/// Out of line: only a jog's train asks (a copy of the train), and a
/// train's run loop stays short.
#[cold]
#[inline(never)]
fn ends_before_its_next_step(steps: &StepTrain) -> bool {
    let mut after = *steps;
    after.make_step();
    !after.has_step()
}

impl AxisRunner {
    /// An idle axis at CT `ct`, its stop pin high (running allowed), as a
    /// board starts.
    pub fn new(config: AxisCoreConfig, ct: u64) -> Self {
        let mut core = AxisCore::new(config, ct);
        core.set_stop_pin(ct, true);
        AxisRunner {
            core,
            pending: Deque::new(),
            edges: EdgeCounts::default(),
            wake: NEVER,
            train: None,
            core_wake: NEVER,
            stop_command_high: true,
            stop_input_high: true,
            group: None,
            group_estop: false,
            ahead: None,
            ahead_key: None,
            runs_taken: 0,
        }
    }

    /// Lets another core compute this axis's ramp runs ahead through
    /// `slot` (see [`cogstep_handoff`]), asking only when the answer would
    /// come in time (in `answer_ticks`); this runner is the slot's owner.
    pub fn set_run_ahead(&mut self, slot: &'static AheadSlot<SCurve>, answer_ticks: RunAheadTicks) {
        self.ahead = Some((slot, answer_ticks));
        self.ahead_key = None;
    }

    /// Ramp runs computed ahead that the core took so far.
    pub fn runs_taken(&self) -> u32 {
        self.runs_taken
    }

    /// Before the core decides a step itself: if its armed ramp run is used
    /// up and the helper's answer was computed from the very state the core
    /// is in, the core takes the next run from it instead of computing it
    /// (bit for bit the same run: `SCurve::adopt_run_ahead`).
    #[inline]
    fn take_run_ahead(&mut self) {
        let (Some((slot, _)), Some(_)) = (self.ahead, self.ahead_key) else {
            return;
        };
        let core = &mut self.core;
        if slot.answer(|from, ahead| core.adopt_run_ahead(from, ahead)) == Some(true) {
            self.runs_taken += 1;
        }
    }

    /// After the core changed: if it armed a ramp run not yet asked for and
    /// the helper is free, asks it for the run that follows.
    #[inline]
    fn post_run_ahead(&mut self) {
        let Some((slot, answer_ticks)) = self.ahead else {
            return;
        };
        let key = self.core.run_end_index();
        if key.is_none() || key == self.ahead_key || !slot.idle() {
            return;
        }
        // An answer that comes after the run is used up is work thrown
        // away: the core computes that run itself meanwhile. When the
        // helper is that far behind, it is not asked (and stays free for
        // requests it can answer in time); the core computes the run as
        // it would anyway. Asked once a run either way.
        if !self.core.ramp_run_lasts(answer_ticks()) {
            self.ahead_key = key;
            return;
        }
        let core = &self.core;
        if slot.post(|from| core.run_ahead_from(from)) {
            self.ahead_key = key;
        }
    }

    /// The core's settings.
    pub fn config(&self) -> &AxisCoreConfig {
        self.core.config()
    }

    /// How far ahead of the clock the core runs: the direction set-up time.
    pub fn lookahead(&self) -> u64 {
        u64::from(self.core.config().dir_setup_ticks)
    }

    /// A command arriving at CT `now` (the core's `now + lookahead`);
    /// refused commands change nothing. Edges that fall due meanwhile (a
    /// late interrupt) go through `drive`.
    pub fn command(
        &mut self,
        now: u64,
        command: CoreCommand,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) -> Result<(), AxisError> {
        self.command_with(now, command, None, drive)
    }

    /// [`AxisRunner::command`], a `CoreCommand::GroupStart` with the lead's
    /// curve planned once for every member when `lead` is given
    /// (`AxisCore::command_with_lead`).
    pub(crate) fn command_with(
        &mut self,
        now: u64,
        command: CoreCommand,
        lead: Option<&GroupLead>,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) -> Result<(), AxisError> {
        self.catch_up(now, drive);
        let core_ct = now.saturating_add(self.lookahead());
        let moves = matches!(
            command,
            CoreCommand::Move { .. }
                | CoreCommand::Jog { .. }
                | CoreCommand::Home(_)
                | CoreCommand::PathStart
        );
        let estop = matches!(command, CoreCommand::EmergencyStop);
        let result = self
            .core
            .command_with_lead(core_ct, command, lead)
            .map(|_| ());
        if estop && self.group.is_some() {
            self.group_estop = true;
        }
        if moves && result.is_ok() && !self.core.in_group() {
            // A move of its own: the axis leaves the group it last ran a
            // part of (its stop no longer reaches the others, nor theirs it).
            self.group = None;
        }
        self.refresh_wake();
        result
    }

    /// The group move this axis last ran a part of.
    pub(crate) fn group(&self) -> Option<GroupRecord> {
        self.group
    }

    /// Records the group move this axis now runs a part of (or, `None`,
    /// forgets a group that has ended).
    pub(crate) fn set_group(&mut self, group: Option<GroupRecord>) {
        self.group = group;
        self.group_estop = false;
    }

    /// Whether the core runs a part of a group move (or is reserved for one).
    pub(crate) fn in_group(&self) -> bool {
        self.core.in_group()
    }

    /// Whether the core's stop pin is high (the protocol's level and the
    /// board's stop input both).
    pub(crate) fn stop_pin_high(&self) -> bool {
        self.core.stop_pin_high()
    }

    /// What this axis asks of its whole group since the last call: an
    /// emergency stop (one came to the axis, or its hard limit e-stops),
    /// or the line's stop (its hard limit tripped).
    pub(crate) fn take_group_request(&mut self) -> Option<GroupRequest> {
        let request = self.core.take_group_request();
        if core::mem::take(&mut self.group_estop) {
            return Some(GroupRequest::EmergencyStop);
        }
        request
    }

    /// Whether [`AxisRunner::take_group_request`] has something to give.
    pub(crate) fn has_group_request(&self) -> bool {
        self.group_estop || self.core.has_group_request()
    }

    /// Takes the lead's next edge of this axis's group part from `other`'s,
    /// a member that has just made it (`AxisCore::take_lead_edge_from`):
    /// the same edge, computed once.
    pub(crate) fn take_lead_edge_from(&mut self, other: &AxisRunner) {
        if self.core.take_lead_edge_from(&other.core) {
            self.refresh_wake();
        }
    }

    /// Stops this axis's part of a group move along the line: it
    /// decelerates from the first lead edge after the core's CT `ct`.
    pub(crate) fn stop_group_after(&mut self, ct: u64) {
        self.give_back_train();
        self.core.stop_group_after(ct);
        self.refresh_wake();
    }

    /// The stop level the protocol sets (`S`, `R`, `!`) from CT `now`
    /// (the core's `now + lookahead`). The core's stop pin is high while
    /// this and the board's stop input ([`AxisRunner::set_stop_input`])
    /// both are: either one low holds the axis.
    pub fn set_stop_pin(
        &mut self,
        now: u64,
        high: bool,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) {
        self.stop_command_high = high;
        self.apply_stop(now, drive);
    }

    /// The level of the board's stop input from CT `now` (see
    /// [`AxisRunner::set_stop_pin`]).
    pub fn set_stop_input(
        &mut self,
        now: u64,
        high: bool,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) {
        self.stop_input_high = high;
        self.apply_stop(now, drive);
    }

    fn apply_stop(&mut self, now: u64, drive: &mut (impl FnMut(Output, bool, u64) + ?Sized)) {
        self.catch_up(now, drive);
        let core_ct = now.saturating_add(self.lookahead());
        let high = self.stop_command_high && self.stop_input_high;
        self.core.set_stop_pin(core_ct, high);
        self.refresh_wake();
    }

    /// The switch inputs' levels (bit per pin) from CT `now`, which
    /// changed when the axis's physical position was `physical_then`
    /// (`None`: now). The core is told how many steps it made since, so
    /// that homing and a limit trip latch the step on which they changed
    /// (see [`crate::inputs`]).
    pub fn set_inputs(
        &mut self,
        now: u64,
        levels: u64,
        physical_then: Option<i64>,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) {
        self.catch_up(now, drive);
        let core_ct = now.saturating_add(self.lookahead());
        let late_steps =
            physical_then.map_or(0, |then| self.core.physical_position().saturating_sub(then));
        self.core.set_inputs_late(core_ct, levels, late_steps);
        self.refresh_wake();
    }

    /// The core's physical position: the signed count of the step edges
    /// it has decided (some of them may still wait for their CT).
    pub fn physical_position(&self) -> i64 {
        self.core.physical_position()
    }

    /// Whether the core is on a look-ahead path.
    pub fn on_path(&self) -> bool {
        self.core.on_path()
    }

    /// Pushes a path step (its rising edge at `ct`, forwards or not) to
    /// the core at CT `now`; refused steps change nothing (see
    /// `AxisCore::push_path_step`).
    pub fn push_path_step(
        &mut self,
        now: u64,
        ct: u64,
        forward: bool,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) -> Result<(), AxisError> {
        self.catch_up(now, drive);
        let result = self.core.push_path_step(ct, forward);
        self.refresh_wake();
        result
    }

    /// The limit and homing state (hard limits and homing only on a board
    /// that reads switch inputs, see [`crate::Hardware::switch_pins`]).
    pub fn limit_status(&self) -> LimitStatus {
        LimitStatus {
            soft_limits: self.core.soft_limits(),
            limit_pins: self.core.limit_pins(),
            trip: self.core.limit_trip(),
            homing: self.core.is_homing(),
            home_outcome: self.core.home_outcome(),
        }
    }

    /// Brings the core up to CT `now` + the look-ahead, as the step
    /// interrupt would have: makes the steps it left for their rising
    /// edges and queues their edges (the interrupt drives them).
    pub fn sync(&mut self, now: u64, drive: &mut (impl FnMut(Output, bool, u64) + ?Sized)) {
        self.catch_up(now, drive);
        self.refresh_wake();
    }

    /// [`AxisRunner::sync`] without taking a train out again: the core is
    /// the caller's to change, then `refresh_wake`.
    fn catch_up(&mut self, now: u64, drive: &mut (impl FnMut(Output, bool, u64) + ?Sized)) {
        self.give_back_train();
        let horizon = now.saturating_add(self.lookahead());
        while let Some(t) = self.core.next_event().filter(|&t| t <= horizon) {
            self.take_run_ahead();
            let (pending, edges) = (&mut self.pending, &mut self.edges);
            self.core.run_event(t, &mut |edge: Edge| {
                Self::queue(pending, edges, edge, drive)
            });
        }
    }

    /// A snapshot as the status line shows it, at CT `now`. STM is 0: a
    /// firmware takes each command before it replies.
    pub fn status(
        &mut self,
        now: u64,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) -> AxisStatus {
        self.sync(now, drive);
        AxisStatus {
            position: self.core.position(),
            stm: 0,
            steps_to_go: self.core.steps_to_go(),
            mode: self.core.mode(),
            velocity_steps_per_s: self.core.last_step().velocity,
            stop_pin_high: self.core.stop_pin_high(),
        }
    }

    /// Steps the last stop left unmade.
    pub fn dropped_steps(&self) -> u32 {
        self.core.dropped_steps()
    }

    /// The edges driven so far.
    pub fn edge_counts(&self) -> EdgeCounts {
        self.edges
    }

    /// Runs the core up to `now` + the look-ahead (a step with known edges
    /// only up to `now`: its rising edge is driven, then it is made) and
    /// drives every edge due by `now` through `drive`.
    #[inline(always)]
    pub fn advance(
        &mut self,
        now: u64,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) -> Work {
        let mut work = Work::default();
        if let Some(train) = &mut self.train {
            if Self::run_train(train, &mut self.edges, now, drive, &mut work) {
                self.wake = train.wake();
                return work;
            }
        }
        self.advance_general(now, drive, work)
    }

    /// [`AxisRunner::advance`] off the train, after giving it back.
    #[inline(never)]
    fn advance_general(
        &mut self,
        now: u64,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
        mut work: Work,
    ) -> Work {
        self.give_back_train();
        let horizon = now.saturating_add(self.lookahead());
        while let Some(t) = self.core.next_event().filter(|&t| t <= horizon) {
            self.take_run_ahead();
            let position_before = self.core.position();
            match self.core.next_plain_step() {
                // Left for the interrupt at its rising edge.
                Some((due, _)) if due > now => break,
                Some((due, pin)) => {
                    work.edges += self.drive_until(due, drive);
                    let rising = Edge {
                        ct: due,
                        pin,
                        level: true,
                    };
                    Self::drive_edge(&mut self.edges, rising, drive);
                    work.edges += 1;
                    // The core emits that edge first: it is driven already.
                    let mut first = true;
                    let (pending, edges) = (&mut self.pending, &mut self.edges);
                    self.core.run_event(t, &mut |edge: Edge| {
                        if core::mem::take(&mut first) {
                            debug_assert_eq!(edge, rising);
                        } else {
                            Self::queue(pending, edges, edge, drive);
                        }
                    });
                }
                None => {
                    let (pending, edges) = (&mut self.pending, &mut self.edges);
                    self.core.run_event(t, &mut |edge: Edge| {
                        Self::queue(pending, edges, edge, drive)
                    });
                }
            }
            if self.core.position() != position_before {
                if self.core.mode().has(Mode::SLEW) {
                    work.slew_steps += 1;
                } else {
                    work.ramp_steps += 1;
                }
            }
        }
        work.edges += self.drive_until(now, drive);
        self.refresh_wake();
        work
    }

    /// When this axis next needs the step interrupt.
    pub fn next_wake(&self) -> Option<u64> {
        (self.wake != NEVER).then_some(self.wake)
    }

    /// [`AxisRunner::next_wake`], [`u64::MAX`] for none.
    #[inline]
    pub(crate) fn wake(&self) -> u64 {
        self.wake
    }

    /// Drives the train's edges due by `now` (each step's falling edge,
    /// then the next step's rising edge, which makes the step). Returns
    /// whether the train goes on.
    #[inline(always)]
    fn run_train(
        train: &mut Train,
        edges: &mut EdgeCounts,
        now: u64,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
        work: &mut Work,
    ) -> bool {
        let index = train.output.index();
        loop {
            if train.fall_ct <= now {
                drive(train.output, false, train.fall_ct);
                edges.falling[index] += 1;
                work.edges += 1;
                train.fall_ct = NEVER;
            }
            if train.steps.rise_ct > now {
                return now < train.give_back_ct;
            }
            if !train.rise(&mut edges.rising, drive, work) {
                // What follows is the core's to decide, a look-ahead early.
                return false;
            }
        }
    }

    /// The train out of the core, if any (for the board's fast path).
    pub(crate) fn train(&self) -> Option<&Train> {
        self.train.as_ref()
    }

    /// Hands the train out of the core over to the board's fast path: the
    /// axis then waits for nothing until [`AxisRunner::take_back`].
    pub(crate) fn lend_train(&mut self) {
        self.train = None;
        self.wake = NEVER;
    }

    /// A train lent with [`AxisRunner::lend_train`], back with the steps
    /// the fast path made (`edges`: the edges it drove): the runner stands
    /// where running the train itself would have left it.
    pub(crate) fn take_back(&mut self, train: Train, edges: &EdgeCounts) {
        debug_assert!(self.train.is_none() && self.pending.is_empty());
        self.add_edges(edges);
        self.train = Some(train);
        if train.steps.has_step() {
            self.wake = train.wake();
        } else {
            // Its last step made: the core decides what follows, as
            // `advance` does when a train ends.
            self.give_back_train();
            self.refresh_wake();
        }
    }

    /// The step's falling edge, when it is the only edge queued and the
    /// core's next event comes after it: out of the queue for the board's
    /// fast path, with the CT at which the axis next needs the interrupt.
    /// The axis then waits for nothing until [`AxisRunner::take_back_fall`].
    pub(crate) fn lend_fall(&mut self) -> Option<(Edge, u64)> {
        if self.train.is_some() || self.pending.len() != 1 {
            return None;
        }
        let fall = *self.pending.front()?;
        let next = self.core_wake;
        if fall.level || next == NEVER || next <= fall.ct {
            return None;
        }
        self.pending.pop_front();
        self.wake = NEVER;
        Some((fall, next))
    }

    /// A falling edge lent with [`AxisRunner::lend_fall`], back: driven by
    /// the fast path (the axis then waits for the core, as it would after
    /// driving it), or still to drive.
    pub(crate) fn take_back_fall(&mut self, fall: Edge, driven: bool) {
        debug_assert!(self.train.is_none() && self.pending.is_empty());
        if driven {
            let mut edges = EdgeCounts::default();
            edges.falling[Output::of_pin(fall.pin).index()] = 1;
            self.add_edges(&edges);
            // The core may offer a train now (at speed, or the ramp steps
            // computed after that step).
            self.refresh_wake();
        } else {
            let _ = self.pending.push_front(fall);
            self.refresh_wake();
        }
    }

    /// The CT of the falling edge that ends the step pulse now out, when
    /// it is the axis's next edge, nothing else of the axis is queued and
    /// the axis next needs the interrupt after it. For a board that queues
    /// edges ahead of the pins ([`crate::Firmware::step_interrupt_ahead`]).
    pub(crate) fn fall_ahead(&self) -> Option<u64> {
        if let Some(train) = &self.train {
            let after = train.steps.rise_ct.min(train.give_back_ct);
            return (train.fall_ct != NEVER && train.fall_ct < after).then_some(train.fall_ct);
        }
        if self.pending.len() != 1 {
            return None;
        }
        let fall = *self.pending.front()?;
        (!fall.level && self.core_wake > fall.ct).then_some(fall.ct)
    }

    /// Drives the edge [`AxisRunner::fall_ahead`] names through `drive`
    /// (which gives it its own CT, not now's), and takes up the axis's
    /// next wake-up, as driving it at its CT would have.
    pub(crate) fn drive_fall_ahead(
        &mut self,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) {
        if let Some(train) = &mut self.train {
            debug_assert!(train.fall_ct != NEVER);
            drive(train.output, false, train.fall_ct);
            self.edges.falling[train.output.index()] += 1;
            train.fall_ct = NEVER;
            self.wake = train.wake();
            return;
        }
        let Some(fall) = self.pending.pop_front() else {
            return;
        };
        debug_assert!(!fall.level && self.pending.is_empty());
        Self::drive_edge(&mut self.edges, fall, drive);
        // The core may offer a train now.
        self.refresh_wake();
        debug_assert!(self.wake > fall.ct);
    }

    /// The CT of the train's next rising edge, when it is the axis's next
    /// edge (the last pulse has ended), comes before the train's give-back,
    /// and the train has a step after it: then driving it at that CT
    /// ([`AxisRunner::drive_rise_ahead`]) leaves the axis exactly where
    /// [`AxisRunner::advance`] at that CT would (no look at the core, no
    /// give-back). For a board that queues edges ahead of the pins
    /// ([`crate::Firmware::step_interrupt_ahead_trains`]).
    pub(crate) fn rise_ahead(&self) -> Option<u64> {
        let train = self.train.as_ref()?;
        let steps = &train.steps;
        if train.fall_ct != NEVER || steps.rise_ct >= train.give_back_ct || steps.steps_left < 2 {
            return None;
        }
        if steps.limit_ct != NEVER && ends_before_its_next_step(steps) {
            return None;
        }
        Some(steps.rise_ct)
    }

    /// Drives the rising edge [`AxisRunner::rise_ahead`] names through
    /// `drive` (which gives it its own CT) and makes its step, as
    /// [`AxisRunner::advance`] at that CT would.
    pub(crate) fn drive_rise_ahead(
        &mut self,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
        work: &mut Work,
    ) {
        let Some(train) = &mut self.train else {
            return;
        };
        debug_assert!(train.fall_ct == NEVER && train.steps.steps_left >= 2);
        let more = train.rise(&mut self.edges.rising, drive, work);
        debug_assert!(more);
        self.wake = train.wake();
    }

    /// The steps [`AxisRunner::rise_ahead`] would name one after the
    /// other, as many as rise by CT `until` (at most `max`): made at once,
    /// their rising edges handed to `rises` as a [`TrainRises`] (each
    /// edge's CT as the iterator makes its step). For a board whose
    /// hardware ends each pulse itself and whose axes' edges owe nothing
    /// to one another's order ([`crate::Hardware::rises_per_axis`]): each
    /// step's falling edge ends its pulse with it, counted and never
    /// driven. The axis is then where driving each rising edge at its CT
    /// with [`AxisRunner::drive_rise_ahead`] (and its fall) would leave
    /// it. Returns the steps made (those `rises` took).
    pub(crate) fn drive_rises_ahead(
        &mut self,
        until: u64,
        max: u32,
        rises: impl FnOnce(Output, &mut TrainRises<'_>),
        work: &mut Work,
    ) -> u32 {
        let Some(train) = &mut self.train else {
            return 0;
        };
        if train.fall_ct != NEVER {
            return 0;
        }
        let ramp = train.steps.is_ramp();
        let mut run = TrainRises::new(&mut train.steps, until, train.give_back_ct, max);
        rises(train.output, &mut run);
        let made = run.made;
        let index = train.output.index();
        self.edges.rising[index] += u64::from(made);
        self.edges.falling[index] += u64::from(made);
        work.edges += 2 * made;
        if ramp {
            work.ramp_steps += made;
        } else {
            work.slew_steps += made;
        }
        self.wake = train.wake();
        made
    }

    fn add_edges(&mut self, edges: &EdgeCounts) {
        for index in 0..2 {
            self.edges.rising[index] += edges.rising[index];
            self.edges.falling[index] += edges.falling[index];
        }
    }

    /// Hands the train (if any) back to the core; its pending falling
    /// edge joins the queue.
    fn give_back_train(&mut self) {
        if let Some(train) = self.train.take() {
            self.core.commit_train(&train.steps);
            if train.fall_ct != NEVER {
                let fall = Edge {
                    ct: train.fall_ct,
                    pin: train.steps.pin,
                    level: false,
                };
                // The queue is empty while a train runs.
                let _ = self.pending.push_back(fall);
            }
        }
    }

    /// Recomputes the wake-up, taking a train out of the core when it
    /// offers one (never while one is out: see [`AxisRunner::catch_up`]).
    fn refresh_wake(&mut self) {
        debug_assert!(self.train.is_none(), "a train is out");
        self.post_run_ahead();
        if self.pending.is_empty() {
            // A train whose first step does not come before its give-back
            // (a jog's deadline a look-ahead early) would be given back at
            // once, and taken out again, for ever: the core makes that
            // step itself.
            let train_steps = self.core.step_train().filter(|steps| {
                steps.has_step() && steps.rise_ct < steps.limit_ct.saturating_sub(self.lookahead())
            });
            if let Some(steps) = train_steps {
                let give_back_ct = steps.limit_ct.saturating_sub(self.lookahead());
                let train = Train {
                    steps,
                    output: Output::of_pin(steps.pin),
                    fall_ct: NEVER,
                    give_back_ct,
                };
                self.wake = steps.rise_ct.min(give_back_ct);
                self.train = Some(train);
                return;
            }
        }
        let core = self.core_wake();
        self.core_wake = core.unwrap_or(NEVER);
        let edge = self.pending.front().map(|edge| edge.ct);
        self.wake = match (core, edge) {
            (Some(a), Some(b)) => a.min(b),
            (a, b) => a.or(b).unwrap_or(NEVER),
        };
    }

    /// When the core next needs the interrupt: a step with known edges at
    /// its rising edge, an event that drives no edge before its CT (a
    /// group part's lead edge) at its CT, anything else a look-ahead early.
    fn core_wake(&self) -> Option<u64> {
        match self.core.next_plain_step() {
            Some((due, _)) => Some(due),
            None => self.core.next_event().map(|t| {
                if self.core.next_event_on_time() {
                    t
                } else {
                    t.saturating_sub(self.lookahead())
                }
            }),
        }
    }

    /// Drives the queued edges due by CT `limit`; returns how many.
    #[inline]
    fn drive_until(
        &mut self,
        limit: u64,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) -> u32 {
        let mut driven = 0;
        while let Some(edge) = self
            .pending
            .front()
            .copied()
            .filter(|edge| edge.ct <= limit)
        {
            self.pending.pop_front();
            Self::drive_edge(&mut self.edges, edge, drive);
            driven += 1;
        }
        driven
    }

    /// Queues an edge the core decided; never lost: a full queue drives
    /// its oldest edge now.
    #[inline]
    fn queue(
        pending: &mut Deque<Edge, QUEUE>,
        edges: &mut EdgeCounts,
        edge: Edge,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) {
        if let Err(edge) = pending.push_back(edge) {
            if let Some(oldest) = pending.pop_front() {
                Self::drive_edge(edges, oldest, drive);
            }
            let _ = pending.push_back(edge);
        }
    }

    #[inline]
    fn drive_edge(
        edges: &mut EdgeCounts,
        edge: Edge,
        drive: &mut (impl FnMut(Output, bool, u64) + ?Sized),
    ) {
        let output = Output::of_pin(edge.pin);
        if edge.level {
            edges.rising[output.index()] += 1;
        } else {
            edges.falling[output.index()] += 1;
        }
        drive(output, edge.level, edge.ct);
    }
}

//! The axis core: everything one axis decides, time in and edges out.
//!
//! `no_std`, no allocation, no threads, no atomics, no clock: the host's cog
//! thread and a microcontroller's timer interrupt both run an axis by
//! handing [`AxisCore`] its commands and inputs with the system counter (CT)
//! at which they arrive, and asking it when the next event is due:
//!
//! ```text
//! command(ct, Move | Jog | JogRelease | SetPosition | EmergencyStop) ─► Ok | AxisError
//! set_stop_pin(ct, level)
//! next_event() ─► Some(ct)          run_until(ct, |edge| drive the pin)
//! ```
//!
//! ```
//! use cogstep_motion::axis_core::{AxisCore, AxisCoreConfig, CoreCommand, Edge, Outputs};
//! let outputs = Outputs::StepDir { step: 1, dir: 2 };
//! let mut core = AxisCore::new(AxisCoreConfig::new(outputs), 0);
//! core.set_stop_pin(0, true);
//! core.command(0, CoreCommand::Move { speed: 20_000, steps: -100 })?;
//! let mut rising = 0;
//! core.run_until(u64::MAX, &mut |edge: Edge| rising += u32::from(edge.level && edge.pin == 1));
//! assert_eq!((core.position(), rising, core.steps_to_go()), (-100, 100, 0));
//! # Ok::<(), cogstep_motion::axis::AxisError>(())
//! ```
//!
//! # Admission: every `Ok` is carried out
//!
//! [`AxisCore::command`] decides, with the state the axis acts on, whether a
//! command is taken; a command it takes is carried out (run, merged, queued
//! behind a reversal, or held until the stop pin goes high), and the steps of
//! a taken command that end up not made (a stop, an emergency stop) are
//! counted in [`AxisCore::ledger`]. The rules:
//!
//! | command | refused with | when |
//! |---|---|---|
//! | any move or jog | `Plan`, `PulseTooLong`, `StepsOutOfRange` | the input cannot be run at all |
//! | move | `Jogging` | a jog owns the axis (release it first) |
//! | move | `Busy` | a reversal is queued, or a held move waits |
//! | move | `TooManySteps` | a merge would pass 2³² − 1 steps in one move |
//! | move | `PositionOutOfRange` | the move could carry the position past `i64` |
//! | jog | `StopPinLow` | the stop pin is low |
//! | jog | `Busy` | a move (not a jog) runs, is queued or held, or the beat contradicts a queued jog reversal |
//! | set position | `NotIdle` | anything moves, is queued or held |
//!
//! | group reserve / start | `Busy` | anything moves, is queued, held or reserved, or the axis is still within its last step's period |
//! | group reserve / start | `StopPinLow` | the stop pin is low |
//! | group start | `StepsOutOfRange` | the member's steps exceed the lead's |
//!
//! # Coordinated moves
//!
//! A group move runs every member on one straight line in step space. The
//! lead is the member with the most steps `L`; it runs the ordinary S-curve
//! of `L` steps at the group's speed from the shared start CT, its edges at
//! `t_1 = start_ct, t_2, …, t_L`. Every member — the lead included — runs
//! its own copy of that lead curve (same config, same integer arithmetic, so
//! the copies agree tick for tick without talking to each other) and makes
//! its own `n` steps on it: its step `j` (1-based) falls at the lead's
//! fractional edge `k = 1 + (j − 1)·(L − 1)/(n − 1)`, time-interpolated
//! between the lead's edges `t_⌊k⌋` and `t_⌊k⌋+1` and rounded down to a
//! whole tick (a one-step member steps at `t_1`). So every member's first
//! edge is at the start CT, its last on the lead's last, and at every edge
//! its position is within one step of `n · s(t)`, where `s(t)` is `k/L` at
//! the lead's `k`-th edge and linear in between. In `P2Exact` the lead's
//! edges are the reference's for a move of `L` steps (delay + pulse + the
//! cog's overhead, [`scurve::p2_period_ticks`]); the other members' edges
//! are those integer edges interpolated as above, in integer arithmetic
//! (the reference has no group move: this is the rule cogstep defines).
//!
//! A stop acts on the line, not on one member: [`AxisCore::stop_group_after`]
//! tells every member's copy to start decelerating at the first lead edge
//! after a CT, so all copies decelerate identically and each member keeps
//! following the same (shorter) line. The steps a member does not reach are
//! dropped and counted in the [`StepLedger`] (and [`AxisCore::dropped_steps`]):
//! a later group move of each member's dropped steps completes the line.
//!
//! A jog is kept alive by heartbeats: it decelerates `jog_timeout_ticks`
//! after the last one. A jog has no target, so its steps are not "dropped"
//! when it ends; the ledger counts them as made by the jog.

use crate::axis::{AxisError, Direction, Mode};
use crate::profile::motion::{Accepted, CommandError, Motion};
use crate::profile::scurve::{self, Arithmetic, SCurve, ScurveConfig};
use crate::profile::{Phase, Profile};

/// One level change on a pin, at a system counter time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Edge {
    /// The system counter (CT) when the pin changed, in clkfreq ticks.
    pub ct: u64,
    /// The pin number.
    pub pin: u8,
    /// The new level: `true` = high.
    pub level: bool,
}

/// How an axis's step outputs map onto pins: all that differs between the
/// two variants.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Outputs {
    /// Step and direction (`sd`).
    StepDir {
        /// Pulsed once per step.
        step: u8,
        /// Low for positive steps, high for negative.
        dir: u8,
    },
    /// Clockwise and counter-clockwise (`cc`).
    CwCcw {
        /// Pulsed for each positive step.
        cw: u8,
        /// Pulsed for each negative step.
        ccw: u8,
    },
}

impl Outputs {
    /// The pin pulsed for a step in `direction`.
    pub fn pulse_pin(self, direction: Direction) -> u8 {
        match (self, direction) {
            (Outputs::StepDir { step, .. }, _) => step,
            (Outputs::CwCcw { cw, .. }, Direction::Forward) => cw,
            (Outputs::CwCcw { ccw, .. }, Direction::Reverse) => ccw,
        }
    }

    /// The direction pin, for `sd`.
    pub fn dir_pin(self) -> Option<u8> {
        match self {
            Outputs::StepDir { dir, .. } => Some(dir),
            Outputs::CwCcw { .. } => None,
        }
    }

    /// Both output pins.
    pub fn pins(self) -> [u8; 2] {
        match self {
            Outputs::StepDir { step, dir } => [step, dir],
            Outputs::CwCcw { cw, ccw } => [cw, ccw],
        }
    }

    /// `"sd"` or `"cc"`.
    pub fn variant(self) -> &'static str {
        match self {
            Outputs::StepDir { .. } => "sd",
            Outputs::CwCcw { .. } => "cc",
        }
    }
}

/// How an axis runs: its profile settings, pins and timing limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisCoreConfig {
    /// The S-curve settings (clock, offset, acceleration divisor, arithmetic).
    pub scurve: ScurveConfig,
    /// The output pins.
    pub outputs: Outputs,
    /// Step pulse width, ticks (≥ 1).
    pub pulse_ticks: u32,
    /// Direction set-up time before the next step edge, ticks.
    pub dir_setup_ticks: u32,
    /// A jog decelerates this long after its last heartbeat, ticks.
    pub jog_timeout_ticks: u64,
    /// Clock ticks of CORDIC work a ramp step needs (counted as an overrun
    /// when its delay is shorter).
    pub math_ticks: u64,
}

impl AxisCoreConfig {
    /// The defaults of a P2 at 200 MHz (5 µs pulse and set-up, 150 ms jog
    /// timeout) on `outputs`.
    pub fn new(outputs: Outputs) -> Self {
        let scurve = ScurveConfig::default();
        Self {
            scurve,
            outputs,
            pulse_ticks: 1_000,
            dir_setup_ticks: 1_000,
            jog_timeout_ticks: u64::from(scurve.clkfreq) * 150 / 1_000,
            math_ticks: 0,
        }
    }
}

/// A command for one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CoreCommand {
    /// The reference `move(speed, steps)`.
    Move {
        /// Steps/s.
        speed: u32,
        /// Signed: the sign is the direction.
        steps: i32,
    },
    /// A jog heartbeat: run at `speed` in `direction` until the beats stop.
    Jog {
        /// Steps/s.
        speed: u32,
        /// Which way.
        direction: Direction,
    },
    /// End a jog at once: controlled deceleration.
    JogRelease,
    /// Set the position counter (idle only).
    SetPosition(i64),
    /// No more steps; the position is kept.
    EmergencyStop,
    /// A coordinated move's first phase: check that this member could run
    /// its part (`steps`, signed) now, and refuse every other move until
    /// [`CoreCommand::GroupStart`] or [`CoreCommand::GroupCancel`].
    GroupReserve {
        /// This member's signed steps.
        steps: i32,
    },
    /// Give a reservation back: nothing moves.
    GroupCancel,
    /// A coordinated move's second phase: run this member's part of the
    /// line. Never refused after a [`CoreCommand::GroupReserve`] that was
    /// taken (the checks were made then).
    GroupStart(GroupMove),
}

/// One member's part of a coordinated move (see [`AxisCore`]'s "Coordinated
/// moves").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GroupMove {
    /// The lead's speed, steps/s.
    pub speed: u32,
    /// The lead's steps (the longest move of the group), ≥ |`steps`|.
    pub lead_steps: u32,
    /// This member's signed steps (0 allowed: it makes none).
    pub steps: i32,
    /// The CT of every member's first edge.
    pub start_ct: u64,
}

/// What a taken command became.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Taken {
    /// A move started, merged, changed speed or was queued behind a reversal.
    Move(Accepted),
    /// The stop pin is low: the move waits for it to go high (mode HOLD).
    Held,
    /// A jog heartbeat was taken.
    Jog,
    /// Anything else (release, set position, emergency stop).
    Done,
}

/// The step accounts of an axis since it started (or since its position was
/// last set): what was asked for, what was not made, what jogs made.
///
/// Whenever the axis is idle, `position = base + accepted − dropped + jogged`,
/// all signed: no step vanishes unaccounted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepLedger {
    /// The position the accounts start from (the last set position).
    pub base: i64,
    /// Signed sum of the steps of every taken move.
    pub accepted: i64,
    /// Signed sum of the steps of taken moves that were then not made.
    pub dropped: i64,
    /// Total (unsigned) of the steps not made, stop after stop.
    pub dropped_total: u64,
    /// Signed steps made while a jog owned the axis.
    pub jogged: i64,
}

/// A jog in progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Jog {
    speed: u32,
    direction: Direction,
    /// The CT by which the next heartbeat must come.
    deadline: u64,
}

/// The state of a move's parameters as the reference driver's hub longs
/// show them (speed asked, accel steps, slew steps, top velocity, start CT).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MoveInfo {
    /// The speed the move asked for, steps/s.
    pub speed: u32,
    /// Accel steps of the ramp in use.
    pub accel_steps: u32,
    /// Steps at speed, as planned.
    pub slew_steps: u32,
    /// The top velocity the move heads for, steps/s.
    pub top_velocity: u32,
    /// CT at which the move began.
    pub start_ct: u64,
    /// The reference's "Max Velocity" long: written when deceleration
    /// starts (`_mlp5`), with the velocity of the last ramp step before it;
    /// it keeps the last move's value until then.
    pub max_velocity: u32,
}

/// What the last step did, for status displays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LastStep {
    /// Velocity of the step, steps/s.
    pub velocity: u32,
    /// The delay computed after it, ticks.
    pub delay_ticks: u32,
    /// CT of its rising edge.
    pub ct: u64,
}

/// A member's part of a coordinated move: its copy of the lead's curve and
/// where it stands on the line (see the module docs).
#[derive(Clone, Debug)]
struct Follower {
    /// The lead's S-curve (`lead_steps` at the group's speed).
    lead: SCurve,
    lead_steps: u32,
    /// This member's steps (magnitude) and direction.
    steps: u32,
    direction: Direction,
    /// Steps made so far.
    made: u32,
    /// Lead edges passed so far (`k`), the CT of the last one, and the CT
    /// its period ends (the next lead edge while the lead runs).
    lead_index: u32,
    lead_ct: u64,
    lead_period_end: u64,
    /// The lead has edges after `lead_index`.
    lead_running: bool,
    lead_velocity: f64,
    lead_delay: u32,
    lead_phase: Phase,
    /// The member's next step, once the lead edges it lies between are known.
    next_step: Option<u64>,
    /// Decelerate from the first lead edge after this CT.
    stop_after: Option<u64>,
    stopped: bool,
    /// The member is done (every step made, or the line ended short): the
    /// axis is ready at this CT.
    finish_at: Option<u64>,
}

impl Follower {
    fn next_event(&self) -> Option<u64> {
        if let Some(finish) = self.finish_at {
            return Some(finish);
        }
        let lead = self.lead_running.then_some(self.lead_period_end);
        match (lead, self.next_step) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// The lead's next edge, at `t`: the copy of the curve moves on one step
    /// (first decelerating, if a stop asked for it before `t`).
    fn lead_edge(&mut self, t: u64, period: impl Fn(u32) -> u64) {
        if !self.stopped && self.stop_after.is_some_and(|after| t > after) {
            self.stopped = true;
            self.lead.stop();
        }
        match self.lead.next() {
            Some(step) => {
                self.lead_index += 1;
                self.lead_ct = t;
                self.lead_delay = step.delay_ticks;
                self.lead_velocity = step.velocity_steps_per_s;
                self.lead_phase = step.phase;
                self.lead_period_end = t + period(step.delay_ticks);
                self.lead_running = self.lead.is_running();
            }
            None => self.lead_running = false,
        }
    }

    /// The lead's fractional edge of the member's step `j` (0-based):
    /// `1 + j·(L − 1)/(n − 1)` as whole part and remainder over `n − 1`.
    fn lead_position_of(&self, j: u32) -> (u64, u64, u64) {
        if self.steps <= 1 {
            return (1, 0, 1);
        }
        let over = u64::from(self.steps - 1);
        let numerator = u64::from(j) * u64::from(self.lead_steps - 1);
        (1 + numerator / over, numerator % over, over)
    }

    /// Schedules the next step if the lead edges around it are known, or
    /// ends the member when the line ended short of it. Returns the steps
    /// the member will not make, when it ends short.
    fn settle(&mut self) -> Option<u32> {
        if self.finish_at.is_some() || self.next_step.is_some() {
            return None;
        }
        if self.made == self.steps {
            self.finish_at = Some(self.lead_period_end.max(self.lead_ct));
            return None;
        }
        let (whole, remainder, over) = self.lead_position_of(self.made);
        let index = u64::from(self.lead_index);
        if whole < index || (whole == index && remainder == 0) {
            self.next_step = Some(self.lead_ct);
        } else if whole == index && self.lead_running {
            let span = u128::from(self.lead_period_end - self.lead_ct);
            let offset = span * u128::from(remainder) / u128::from(over);
            self.next_step = Some(self.lead_ct + offset as u64);
        } else if !self.lead_running && whole >= index {
            // The lead made its last edge before this step: the line ends here.
            self.finish_at = Some(self.lead_period_end.max(self.lead_ct));
            return Some(self.steps - self.made);
        }
        None
    }
}

/// One axis (see the module docs).
#[derive(Clone, Debug)]
pub struct AxisCore {
    config: AxisCoreConfig,
    motion: Motion,
    position: i64,
    /// When the next step is due, while moving.
    due: Option<u64>,
    /// When the axis is ready for a next first step (last step + its period).
    ready_ct: u64,
    /// Level of the direction pin (sd), or last direction (cc).
    dir_reverse: bool,
    /// When the last pulse ends: a direction change may not come before.
    last_fall_ct: u64,
    stop_pin_high: bool,
    /// The stop pin went low while moving and the move was told to stop.
    stopping: bool,
    /// A move taken while the stop pin is low.
    held: Option<(u32, i32)>,
    jog: Option<Jog>,
    /// The steps in the motion belong to a jog (until the axis is idle).
    jog_owns: bool,
    /// Flags that outlive a move (STOP_LATCHED, ESTOP).
    sticky: u32,
    /// Phase bits of the last step.
    step_bits: u32,
    ledger: StepLedger,
    /// Steps the last stop left unmade (a later move of that many reaches
    /// the original target).
    last_dropped: u32,
    move_info: MoveInfo,
    /// A reversal was queued: its first step begins a new move.
    queued_start: bool,
    last_step: LastStep,
    math_overruns: u64,
    /// A coordinated move reserved this axis (nothing else may start).
    reserved: bool,
    /// The coordinated move this axis runs its part of.
    group: Option<Follower>,
}

impl AxisCore {
    /// An idle axis at position 0, its stop pin low, at CT `ct`.
    pub fn new(config: AxisCoreConfig, ct: u64) -> Self {
        Self {
            config,
            motion: Motion::new(config.scurve),
            position: 0,
            due: None,
            ready_ct: ct,
            dir_reverse: false,
            last_fall_ct: 0,
            stop_pin_high: false,
            stopping: false,
            held: None,
            jog: None,
            jog_owns: false,
            sticky: 0,
            step_bits: 0,
            ledger: StepLedger::default(),
            last_dropped: 0,
            move_info: MoveInfo::default(),
            queued_start: false,
            last_step: LastStep::default(),
            math_overruns: 0,
            reserved: false,
            group: None,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &AxisCoreConfig {
        &self.config
    }

    /// Whether a move of `steps` at `speed` can be run at all: it plans,
    /// and the step pulse (with its falling edge) fits between two steps.
    pub fn check_move(config: &AxisCoreConfig, speed: u32, steps: i32) -> Result<(), AxisError> {
        if steps == i32::MIN {
            return Err(AxisError::StepsOutOfRange);
        }
        scurve::plan(&config.scurve, speed, steps.unsigned_abs())?;
        let shortest = config.scurve.clkfreq / speed.max(1);
        if config.pulse_ticks >= shortest.saturating_sub(1) {
            return Err(AxisError::PulseTooLong { speed });
        }
        Ok(())
    }

    /// Takes a command arriving at CT `t` (see the module docs for the
    /// rules). A refused command changes nothing.
    pub fn command(&mut self, t: u64, command: CoreCommand) -> Result<Taken, AxisError> {
        match command {
            CoreCommand::Move { speed, steps } => self.command_move(t, speed, steps),
            CoreCommand::Jog { speed, direction } => self.command_jog(t, speed, direction),
            CoreCommand::JogRelease => {
                if self.jog.take().is_some() {
                    // A jog has no target: its unmade chunk was never promised.
                    self.motion.stop();
                    self.queued_start = false;
                }
                Ok(Taken::Done)
            }
            CoreCommand::SetPosition(position) => {
                if self.is_busy() {
                    return Err(AxisError::NotIdle);
                }
                self.position = position;
                self.ledger = StepLedger {
                    base: position,
                    dropped_total: self.ledger.dropped_total,
                    ..StepLedger::default()
                };
                Ok(Taken::Done)
            }
            CoreCommand::EmergencyStop => {
                self.emergency_stop(t);
                Ok(Taken::Done)
            }
            CoreCommand::GroupReserve { steps } => {
                self.check_group(t, steps)?;
                self.reserved = true;
                Ok(Taken::Done)
            }
            CoreCommand::GroupCancel => {
                self.reserved = false;
                Ok(Taken::Done)
            }
            CoreCommand::GroupStart(group) => self.start_group(t, group),
        }
    }

    /// Whether this axis could run its part of a group move now.
    fn check_group(&self, t: u64, steps: i32) -> Result<(), AxisError> {
        if steps == i32::MIN {
            return Err(AxisError::StepsOutOfRange);
        }
        if self.reserved || self.is_busy() || self.group.is_some() || self.ready_ct > t {
            return Err(AxisError::Busy);
        }
        if !self.stop_pin_high {
            return Err(AxisError::StopPinLow);
        }
        self.check_reach(i64::from(steps))
    }

    /// Starts this member's part of a group move (see the module docs).
    fn start_group(&mut self, t: u64, group: GroupMove) -> Result<Taken, AxisError> {
        if !self.reserved {
            self.check_group(t, group.steps)?;
        }
        let steps = group.steps.unsigned_abs();
        if group.steps == i32::MIN || steps > group.lead_steps {
            return Err(AxisError::StepsOutOfRange);
        }
        self.reserved = false;
        if steps == 0 {
            return Ok(Taken::Done);
        }
        let lead = SCurve::new(self.config.scurve, group.speed, group.lead_steps)?;
        let direction = Direction::of(group.steps);
        self.sticky &= !(Mode::STOP_LATCHED | Mode::ESTOP);
        self.last_dropped = 0;
        self.ledger.accepted += i64::from(group.steps);
        let start = group.start_ct.max(t);
        self.move_info = MoveInfo {
            speed: group.speed,
            accel_steps: lead.accel_steps(),
            slew_steps: lead.plan().slew_steps,
            top_velocity: scale(lead.top_speed(), steps, group.lead_steps),
            start_ct: start,
            max_velocity: self.move_info.max_velocity,
        };
        self.step_bits = Mode::ACCEL | if group.steps < 0 { Mode::REVERSE } else { 0 };
        self.group = Some(Follower {
            lead,
            lead_steps: group.lead_steps,
            steps,
            direction,
            made: 0,
            lead_index: 0,
            lead_ct: start,
            lead_period_end: start,
            lead_running: true,
            lead_velocity: 0.0,
            lead_delay: 0,
            lead_phase: Phase::Accel,
            next_step: None,
            stop_after: None,
            stopped: false,
            finish_at: None,
        });
        Ok(Taken::Done)
    }

    /// Stops the group move this axis runs its part of along its line: every
    /// member told the same CT decelerates from the same lead edge (the
    /// first after `ct`), so all stay on the line. The steps not reached are
    /// dropped (see the module docs). Nothing happens without a group move.
    pub fn stop_group_after(&mut self, ct: u64) {
        if let Some(follower) = self.group.as_mut() {
            if follower.finish_at.is_none() {
                let after = follower.stop_after.map_or(ct, |earlier| earlier.min(ct));
                follower.stop_after = Some(after);
                self.sticky |= Mode::STOP_LATCHED;
            }
        }
    }

    /// Whether the axis runs its part of a group move (or is reserved for one).
    pub fn in_group(&self) -> bool {
        self.group.is_some() || self.reserved
    }

    fn command_move(&mut self, t: u64, speed: u32, steps: i32) -> Result<Taken, AxisError> {
        Self::check_move(&self.config, speed, steps)?;
        if self.jog_owns && self.motion.is_moving() {
            return Err(AxisError::Jogging);
        }
        if self.held.is_some() || self.in_group() {
            return Err(AxisError::Busy);
        }
        self.check_reach(i64::from(steps))?;
        if !self.stop_pin_high {
            self.held = Some((speed, steps));
            self.ledger.accepted += i64::from(steps);
            return Ok(Taken::Held);
        }
        let accepted = self.start_or_merge(t, speed, steps)?;
        self.ledger.accepted += i64::from(steps);
        Ok(Taken::Move(accepted))
    }

    /// Hands a move to the motion and schedules its first step.
    fn start_or_merge(&mut self, t: u64, speed: u32, steps: i32) -> Result<Accepted, AxisError> {
        let was_moving = self.motion.is_moving();
        let accepted = self.motion.command(speed, steps).map_err(|e| match e {
            CommandError::Plan(plan) => AxisError::Plan(plan),
            CommandError::Busy => AxisError::Busy,
            CommandError::TooManySteps => AxisError::TooManySteps,
        })?;
        if accepted == Accepted::Started {
            // A new move: a jog that just ran out no longer owns the axis.
            self.jog_owns = false;
            self.sticky &= !(Mode::STOP_LATCHED | Mode::ESTOP);
            self.last_dropped = 0;
            self.step_bits = Mode::ACCEL | if steps < 0 { Mode::REVERSE } else { 0 };
            self.move_info.start_ct = t;
        }
        if !was_moving {
            self.due = Some(self.due.unwrap_or(t).max(t).max(self.ready_ct));
        }
        if accepted == Accepted::Queued {
            self.queued_start = true;
            let cut = self.motion.take_cut_steps();
            if !self.jog_owns {
                // Turning round stops short of the earlier target.
                self.drop_steps(cut);
            }
        } else {
            self.move_info.speed = speed;
            self.refresh_move_info();
        }
        Ok(accepted)
    }

    /// The move parameters from the curve in progress.
    fn refresh_move_info(&mut self) {
        if let Some((curve, _)) = self.motion.current() {
            self.move_info.accel_steps = curve.accel_steps();
            self.move_info.slew_steps = curve.plan().slew_steps;
            self.move_info.top_velocity = curve.top_speed();
        }
    }

    fn command_jog(
        &mut self,
        t: u64,
        speed: u32,
        direction: Direction,
    ) -> Result<Taken, AxisError> {
        Self::check_move(&self.config, speed, 1)?;
        if !self.stop_pin_high {
            return Err(AxisError::StopPinLow);
        }
        let moving = self.motion.is_moving();
        if self.held.is_some() || self.in_group() || (moving && !self.jog_owns) {
            return Err(AxisError::Busy);
        }
        let deadline = t.saturating_add(self.config.jog_timeout_ticks);
        let same = self
            .jog
            .is_some_and(|jog| jog.speed == speed && jog.direction == direction);
        let running_this_way = self
            .motion
            .current()
            .is_some_and(|(curve, d)| d == direction && curve.is_running());
        let queued_this_way = moving && !running_this_way;
        let chunk = self.jog_chunk(speed);
        let low = running_this_way && self.remaining_in_current() < u64::from(chunk / 2);
        if self.motion.has_queued() {
            // A reversal is on its way: only a beat for it keeps it alive.
            if same && queued_this_way {
                self.jog = Some(Jog {
                    speed,
                    direction,
                    deadline,
                });
                return Ok(Taken::Jog);
            }
            return Err(AxisError::Busy);
        }
        if !same || low || !moving {
            let magnitude = i32::try_from(chunk).unwrap_or(i32::MAX);
            let steps = match direction {
                Direction::Forward => magnitude,
                Direction::Reverse => -magnitude,
            };
            self.check_reach(i64::from(steps))?;
            self.start_or_merge(t, speed, steps)?;
        }
        self.jog_owns = true;
        self.jog = Some(Jog {
            speed,
            direction,
            deadline,
        });
        Ok(Taken::Jog)
    }

    /// Refuses what could carry the position past the range of an `i64`:
    /// `extra` steps (signed) on top of everything the axis still has to
    /// make, which may go either way.
    fn check_reach(&self, extra: i64) -> Result<(), AxisError> {
        let pending = i128::from(self.steps_to_go());
        let position = i128::from(self.position);
        let extra = i128::from(extra);
        let highest = position + extra.max(0) + pending;
        let lowest = position + extra.min(0) - pending;
        if highest > i128::from(i64::MAX) || lowest < i128::from(i64::MIN) {
            return Err(AxisError::PositionOutOfRange);
        }
        Ok(())
    }

    /// Steps a jog asks for at a time: enough to reach `speed`, run two
    /// heartbeat timeouts at it and still stop. A beat tops the jog up when
    /// fewer than half are left, so between two beats the axis never starts
    /// slowing down by itself.
    fn jog_chunk(&self, speed: u32) -> u32 {
        const JOG_CHUNK_MAX: u64 = 1 << 28;
        let scurve = &self.config.scurve;
        let accel_steps = u64::from(speed / scurve.accel_div.max(1) + 2);
        let timeout_steps =
            u64::from(speed) * self.config.jog_timeout_ticks / u64::from(scurve.clkfreq.max(1)) + 1;
        let chunk = 2 * (2 * accel_steps + timeout_steps) + 16;
        u32::try_from(chunk.min(JOG_CHUNK_MAX)).unwrap_or(u32::MAX)
    }

    fn remaining_in_current(&self) -> u64 {
        self.motion
            .current()
            .map_or(0, |(curve, _)| u64::from(curve.remaining_steps()))
    }

    /// Anything moving, queued, held or reserved.
    fn is_busy(&self) -> bool {
        self.motion.is_moving() || self.held.is_some() || self.in_group()
    }

    /// Counts steps of taken moves that will not be made.
    fn drop_steps(&mut self, signed: i64) {
        self.ledger.dropped += signed;
        self.ledger.dropped_total = self
            .ledger
            .dropped_total
            .saturating_add(signed.unsigned_abs());
    }

    /// A stop ended what the motion still had to make: counted as dropped
    /// (and reported as the last stop's) unless a jog owned it (a jog has
    /// no target: its unmade chunk was never promised).
    fn account_stop(&mut self, dropped: i64) {
        self.last_dropped = 0;
        if !self.jog_owns {
            self.drop_steps(dropped);
            self.last_dropped = u32::try_from(dropped.unsigned_abs()).unwrap_or(u32::MAX);
        }
    }

    fn emergency_stop(&mut self, t: u64) {
        self.reserved = false;
        if let Some(follower) = self.group.take() {
            let unmade = follower.steps - follower.made;
            self.drop_steps(i64::from(unmade) * follower.direction.sign());
            self.last_dropped = unmade;
            self.ready_ct = self.ready_ct.max(t);
            self.sticky = Mode::ESTOP | (self.sticky & Mode::STOP_LATCHED);
            self.step_bits = 0;
            self.last_step.velocity = 0;
            return;
        }
        let dropped = self.motion.estop();
        self.account_stop(dropped);
        self.queued_start = false;
        if let Some((_, steps)) = self.held.take() {
            self.drop_steps(i64::from(steps));
            self.last_dropped = self.last_dropped.saturating_add(steps.unsigned_abs());
        }
        self.jog = None;
        self.jog_owns = false;
        self.stopping = false;
        self.due = None;
        self.ready_ct = self.ready_ct.max(t);
        self.sticky = Mode::ESTOP | (self.sticky & Mode::STOP_LATCHED);
        self.step_bits = 0;
    }

    /// The stop pin's level at CT `t`: low decelerates at once from the
    /// current velocity (the steps left are counted as dropped); high lets
    /// a held move run.
    pub fn set_stop_pin(&mut self, t: u64, high: bool) {
        self.stop_pin_high = high;
        if high {
            self.stopping = false;
            if let Some((speed, steps)) = self.held.take() {
                // Checked when it was taken; the motion can only be stopping
                // (or idle) now, so it runs, merges or queues. Should it
                // still be refused, its steps are counted, not lost.
                if self.start_or_merge(t, speed, steps).is_err() {
                    self.drop_steps(i64::from(steps));
                    self.last_dropped = steps.unsigned_abs();
                }
            }
        } else if !self.stopping && self.motion.is_moving() {
            self.stopping = true;
            let dropped = self.motion.stop();
            self.account_stop(dropped);
            self.queued_start = false;
            self.jog = None;
            self.sticky |= Mode::STOP_LATCHED;
        }
    }

    /// The next CT at which something happens without outside input.
    pub fn next_event(&self) -> Option<u64> {
        if let Some(follower) = &self.group {
            return follower.next_event();
        }
        let deadline = self.jog.map(|jog| jog.deadline);
        match (self.due, deadline) {
            (Some(due), Some(deadline)) => Some(due.min(deadline)),
            (due, deadline) => due.or(deadline),
        }
    }

    /// Runs every event due up to CT `limit`, passing each pin edge to `emit`
    /// in time order per pin. Returns the CT of the last event run (or
    /// `None` when nothing was due).
    pub fn run_until(&mut self, limit: u64, emit: &mut impl FnMut(Edge)) -> Option<u64> {
        let mut last = None;
        while let Some(t) = self.next_event().filter(|t| *t <= limit) {
            self.run_event(t, emit);
            last = Some(t);
        }
        last
    }

    /// Runs the event due at CT `t` (`t` ≥ [`AxisCore::next_event`]): a
    /// jog's deadline, then the step that is due.
    pub fn run_event(&mut self, t: u64, emit: &mut impl FnMut(Edge)) {
        if self.group.is_some() {
            self.run_group_event(t, emit);
            return;
        }
        if let Some(jog) = self.jog {
            if t >= jog.deadline {
                // No heartbeat in time: the caller is gone or let go.
                self.jog = None;
                self.motion.stop();
                self.queued_start = false;
            }
        }
        if self.due.is_some_and(|due| due <= t) {
            self.step(emit);
        }
    }

    /// A group member's event at `t`: the lead's edge, then its own step,
    /// then its end.
    fn run_group_event(&mut self, t: u64, emit: &mut impl FnMut(Edge)) {
        let config = self.config;
        let Some(follower) = self.group.as_mut() else {
            return;
        };
        if follower.finish_at.is_some_and(|finish| finish <= t) {
            self.group = None;
            self.finish(t);
            return;
        }
        if follower.lead_running && follower.lead_period_end <= t {
            follower.lead_edge(t, |delay| period_ticks(&config, delay));
            self.step_bits = match follower.lead_phase {
                Phase::Accel => Mode::ACCEL,
                Phase::Slew => Mode::SLEW,
                Phase::Decel => Mode::DECEL,
            } | (self.step_bits & Mode::REVERSE);
        }
        if let Some(unmade) = follower.settle() {
            let signed = i64::from(unmade) * follower.direction.sign();
            self.drop_steps(signed);
            self.last_dropped = unmade;
            return;
        }
        if follower.next_step.is_some_and(|due| due <= t) {
            let due = follower.next_step.take().unwrap_or(t);
            follower.made += 1;
            let direction = follower.direction;
            let velocity = follower.lead_velocity * f64::from(follower.steps)
                / f64::from(follower.lead_steps.max(1));
            let delay = scale(follower.lead_delay, follower.lead_steps, follower.steps);
            let dropped = follower.settle();
            self.emit_step(due, direction, emit);
            self.last_step = LastStep {
                velocity: velocity as u32,
                delay_ticks: delay,
                ct: due,
            };
            if let Some(unmade) = dropped {
                self.drop_steps(i64::from(unmade) * direction.sign());
                self.last_dropped = unmade;
            }
        }
    }

    /// Drives the pins for one step whose rising edge is due at `t` (later
    /// if the direction pin needs its set-up time); returns the CT of the
    /// rising edge.
    fn emit_step(&mut self, mut t: u64, direction: Direction, emit: &mut impl FnMut(Edge)) -> u64 {
        let reverse = direction == Direction::Reverse;
        if reverse != self.dir_reverse {
            if let Some(dir_pin) = self.config.outputs.dir_pin() {
                // The direction settles `dir_setup` before the step edge, and
                // may not change while the last pulse is still high.
                let setup = u64::from(self.config.dir_setup_ticks);
                let dir_ct = t.saturating_sub(setup).max(self.last_fall_ct);
                t = t.max(dir_ct + setup);
                emit(Edge {
                    ct: dir_ct,
                    pin: dir_pin,
                    level: reverse,
                });
            }
            self.dir_reverse = reverse;
        }
        let pin = self.config.outputs.pulse_pin(direction);
        let fall = t + u64::from(self.config.pulse_ticks);
        emit(Edge {
            ct: t,
            pin,
            level: true,
        });
        emit(Edge {
            ct: fall,
            pin,
            level: false,
        });
        self.last_fall_ct = fall;
        self.position = self.position.saturating_add(direction.sign());
        t
    }

    /// Makes the step that is due, or ends the move.
    fn step(&mut self, emit: &mut impl FnMut(Edge)) {
        let Some(t) = self.due else { return };
        let Some(next) = self.motion.next_step() else {
            self.finish(t);
            return;
        };
        if next.step.index == 0 {
            self.begin_curve(t);
        }
        let reverse = next.direction == Direction::Reverse;
        let t = self.emit_step(t, next.direction, emit);
        let delay = next.step.delay_ticks;
        if next.step.phase != Phase::Slew && u64::from(delay) < self.config.math_ticks {
            self.math_overruns += 1;
        }
        let sign = next.direction.sign();
        if self.jog_owns {
            self.ledger.jogged += sign;
        }
        if next.step.phase == Phase::Decel && self.step_bits & Mode::DECEL == 0 {
            // Deceleration starts: the reference writes Max Velocity now,
            // the velocity of the last ramp (or slew) step.
            self.move_info.max_velocity = self.last_step.velocity;
        }
        self.last_step = LastStep {
            velocity: next.step.velocity_steps_per_s as u32,
            delay_ticks: delay,
            ct: t,
        };
        self.step_bits = match next.step.phase {
            Phase::Accel => Mode::ACCEL,
            Phase::Slew => Mode::SLEW,
            Phase::Decel => Mode::DECEL,
        } | if reverse { Mode::REVERSE } else { 0 };
        let period = self.period_ticks(delay);
        self.due = Some(t + period);
        self.ready_ct = t + period;
    }

    /// Rising edge to the next rising edge after a step of `delay_ticks`:
    /// in `P2Exact` the reference cog's running target (delay + pulse + the
    /// cog's fixed overhead, [`scurve::p2_period_ticks`]), so its edges are
    /// the real board's; `Smooth` runs at the speed asked (period = delay).
    fn period_ticks(&self, delay_ticks: u32) -> u64 {
        period_ticks(&self.config, delay_ticks)
    }

    /// A curve's first step (a new move, or a queued reversal beginning):
    /// the move parameters describe it from now on.
    fn begin_curve(&mut self, t: u64) {
        if core::mem::take(&mut self.queued_start) {
            self.move_info.start_ct = t;
            if let Some((curve, _)) = self.motion.current() {
                self.move_info.speed = curve.plan().requested_speed;
            }
            self.refresh_move_info();
        }
    }

    /// The move made its last step: the axis is ready at `t`.
    fn finish(&mut self, t: u64) {
        self.due = None;
        self.ready_ct = t;
        self.jog = None;
        self.jog_owns = false;
        self.step_bits = 0;
        self.last_step.velocity = 0;
    }

    /// Steps from the origin (the sum of every step edge since the axis
    /// started, or since its position was last set).
    pub fn position(&self) -> i64 {
        self.position
    }

    /// Steps still to make (the move in progress, a queued reversal and a
    /// held move); 0 exactly when the axis is idle.
    pub fn steps_to_go(&self) -> u64 {
        let held = self
            .held
            .map_or(0, |(_, steps)| u64::from(steps.unsigned_abs()));
        let group = self.group.as_ref().map_or(0, |follower| {
            if follower.finish_at.is_some() {
                0
            } else {
                u64::from(follower.steps - follower.made)
            }
        });
        self.motion.steps_to_go() + held + group
    }

    /// Whether a step is scheduled (the axis is moving).
    pub fn is_moving(&self) -> bool {
        self.due.is_some() || self.group.is_some()
    }

    /// The mode bits now: the phase and direction of the last step while
    /// moving, plus STOP_LATCHED, ESTOP, HOLD and JOG. At the end of a move
    /// only the flags that outlive it remain (the reference keeps b5 alone:
    /// the direction bit clears).
    pub fn mode(&self) -> Mode {
        let mut bits = self.sticky;
        if self.is_moving() {
            bits |= Mode::MOVING | self.step_bits;
            // The jog bit says what admission sees: a jog with steps left.
            if self.jog_owns && self.motion.is_moving() {
                bits |= Mode::JOG;
            }
        }
        if self.held.is_some() {
            bits |= Mode::HOLD;
        }
        Mode(bits)
    }

    /// The stop pin level the core last saw.
    pub fn stop_pin_high(&self) -> bool {
        self.stop_pin_high
    }

    /// Steps the last stop (stop pin or emergency, held moves included)
    /// left unmade.
    pub fn dropped_steps(&self) -> u32 {
        self.last_dropped
    }

    /// The step accounts.
    pub fn ledger(&self) -> StepLedger {
        self.ledger
    }

    /// The parameters of the current (or last) move.
    pub fn move_info(&self) -> MoveInfo {
        self.move_info
    }

    /// What the last step did (velocity 0 when idle).
    pub fn last_step(&self) -> LastStep {
        self.last_step
    }

    /// Ramp steps whose delay was shorter than the CORDIC work they needed.
    pub fn math_overruns(&self) -> u64 {
        self.math_overruns
    }

    /// The S-curve offset, degrees.
    pub fn offset_deg(&self) -> u32 {
        self.config.scurve.offset_deg
    }
}

/// Rising edge to the next rising edge after a step of `delay_ticks` (see
/// [`AxisCore`]'s `period_ticks`).
fn period_ticks(config: &AxisCoreConfig, delay_ticks: u32) -> u64 {
    match config.scurve.arithmetic {
        Arithmetic::Smooth => u64::from(delay_ticks),
        Arithmetic::P2Exact => scurve::p2_period_ticks(delay_ticks, config.pulse_ticks),
    }
}

/// `value · numerator / denominator`, saturating (0 over 0).
fn scale(value: u32, numerator: u32, denominator: u32) -> u32 {
    if denominator == 0 {
        return 0;
    }
    let scaled = u64::from(value) * u64::from(numerator) / u64::from(denominator);
    u32::try_from(scaled).unwrap_or(u32::MAX)
}

#[cfg(test)]
mod group_tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;

    /// Three cores told the same group move, each run on its own: the
    /// firmware's view (no hub, no threads).
    fn members(steps: &[i32], start_ct: u64) -> Vec<AxisCore> {
        let lead_steps = steps.iter().map(|s| s.unsigned_abs()).max().unwrap();
        steps
            .iter()
            .enumerate()
            .map(|(i, &steps)| {
                let pin = u8::try_from(2 * i).unwrap();
                let outputs = Outputs::StepDir {
                    step: pin,
                    dir: pin + 1,
                };
                let mut core = AxisCore::new(AxisCoreConfig::new(outputs), 0);
                core.set_stop_pin(0, true);
                core.command(0, CoreCommand::GroupReserve { steps })
                    .unwrap();
                assert_eq!(
                    core.command(
                        0,
                        CoreCommand::Move {
                            speed: 100,
                            steps: 5
                        }
                    ),
                    Err(AxisError::Busy)
                );
                core.command(
                    0,
                    CoreCommand::GroupStart(GroupMove {
                        speed: 20_000,
                        lead_steps,
                        steps,
                        start_ct,
                    }),
                )
                .unwrap();
                core
            })
            .collect()
    }

    /// Each core's rising step edges, run up to `limit`.
    fn rising(core: &mut AxisCore, limit: u64) -> Vec<u64> {
        let mut edges = Vec::new();
        core.run_until(limit, &mut |edge: Edge| {
            if edge.level && edge.pin.is_multiple_of(2) {
                edges.push(edge.ct);
            }
        });
        edges
    }

    #[test]
    fn members_start_together_and_end_together_on_their_own() {
        let steps = [5_000, -1_700, 1, 0];
        let mut cores = members(&steps, 10_000);
        let edges: Vec<Vec<u64>> = cores.iter_mut().map(|c| rising(c, u64::MAX)).collect();
        for (core, steps) in cores.iter().zip(steps) {
            assert_eq!(core.position(), i64::from(steps));
            assert_eq!((core.steps_to_go(), core.is_moving()), (0, false));
        }
        assert_eq!(edges[0][0], 10_000);
        assert_eq!(edges[1][0], 10_000);
        assert_eq!(edges[2], [10_000]);
        assert!(edges[3].is_empty());
        assert_eq!(edges[1].last(), edges[0].last());
        // The lead's edges are those of the same move alone.
        let mut alone = AxisCore::new(AxisCoreConfig::new(Outputs::StepDir { step: 0, dir: 1 }), 0);
        alone.set_stop_pin(0, true);
        alone
            .command(
                10_000,
                CoreCommand::Move {
                    speed: 20_000,
                    steps: 5_000,
                },
            )
            .unwrap();
        assert_eq!(rising(&mut alone, u64::MAX), edges[0]);
    }

    #[test]
    fn a_stop_told_to_every_member_keeps_them_on_the_line() {
        let steps = [5_000, -1_700, 333];
        let mut cores = members(&steps, 0);
        let stop_ct = 20_000_000;
        let mut edges: Vec<Vec<u64>> = cores.iter_mut().map(|c| rising(c, stop_ct)).collect();
        for core in &mut cores {
            core.stop_group_after(stop_ct);
        }
        for (core, edges) in cores.iter_mut().zip(&mut edges) {
            edges.extend(rising(core, u64::MAX));
        }
        let lead_made = edges[0].len() as f64;
        assert!(lead_made < 5_000.0);
        for (core, steps) in cores.iter().zip(steps) {
            let line = f64::from(steps) * lead_made / 5_000.0;
            assert!(
                (core.position() as f64 - line).abs() <= 1.0,
                "{} vs {line}",
                core.position()
            );
            let unmade = i64::from(steps) - core.position();
            assert_eq!(u64::from(core.dropped_steps()), unmade.unsigned_abs());
            assert_eq!(core.ledger().dropped, unmade);
            assert!(core.mode().has(Mode::STOP_LATCHED));
        }
    }
}

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
//! A jog is kept alive by heartbeats: it decelerates `jog_timeout_ticks`
//! after the last one. A jog has no target, so its steps are not "dropped"
//! when it ends; the ledger counts them as made by the jog.

use crate::axis::{AxisError, Direction, Mode};
use crate::profile::motion::{Accepted, CommandError, Motion};
use crate::profile::scurve::{self, Arithmetic, ScurveConfig};
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
        }
    }

    fn command_move(&mut self, t: u64, speed: u32, steps: i32) -> Result<Taken, AxisError> {
        Self::check_move(&self.config, speed, steps)?;
        if self.jog_owns && self.motion.is_moving() {
            return Err(AxisError::Jogging);
        }
        if self.held.is_some() {
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
        if self.held.is_some() || (moving && !self.jog_owns) {
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

    /// Anything moving, queued or held.
    fn is_busy(&self) -> bool {
        self.motion.is_moving() || self.held.is_some()
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

    /// Makes the step that is due, or ends the move.
    fn step(&mut self, emit: &mut impl FnMut(Edge)) {
        let Some(mut t) = self.due else { return };
        let Some(next) = self.motion.next_step() else {
            self.finish(t);
            return;
        };
        if next.step.index == 0 {
            self.begin_curve(t);
        }
        let reverse = next.direction == Direction::Reverse;
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
        let pin = self.config.outputs.pulse_pin(next.direction);
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
        let delay = next.step.delay_ticks;
        if next.step.phase != Phase::Slew && u64::from(delay) < self.config.math_ticks {
            self.math_overruns += 1;
        }
        let sign = next.direction.sign();
        self.position = self.position.saturating_add(sign);
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
        match self.config.scurve.arithmetic {
            Arithmetic::Smooth => u64::from(delay_ticks),
            Arithmetic::P2Exact => scurve::p2_period_ticks(delay_ticks, self.config.pulse_ticks),
        }
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

    /// Steps from the origin.
    pub fn position(&self) -> i64 {
        self.position
    }

    /// Steps still to make (the move in progress, a queued reversal and a
    /// held move); 0 exactly when the axis is idle.
    pub fn steps_to_go(&self) -> u64 {
        let held = self
            .held
            .map_or(0, |(_, steps)| u64::from(steps.unsigned_abs()));
        self.motion.steps_to_go() + held
    }

    /// Whether a step is scheduled (the axis is moving).
    pub fn is_moving(&self) -> bool {
        self.due.is_some()
    }

    /// The mode bits now: the phase and direction of the last step while
    /// moving, plus STOP_LATCHED, ESTOP, HOLD and JOG. At the end of a move
    /// only the flags that outlive it remain (the reference keeps b5 alone:
    /// the direction bit clears).
    pub fn mode(&self) -> Mode {
        let mut bits = self.sticky;
        if self.due.is_some() {
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

//! The axis core: everything one axis decides, time in and edges out.
//!
//! `no_std`, no allocation, no threads, no atomics, no clock: the host's cog
//! thread and a microcontroller's timer interrupt both run an axis by
//! handing [`AxisCore`] its commands and inputs with the system counter (CT)
//! at which they arrive, and asking it when the next event is due:
//!
//! ```text
//! command(ct, Move | Jog | JogRelease | SetPosition | EmergencyStop
//!             | Home | SetSoftLimits | SetLimitPins | ClearLimitFault) ─► Ok | AxisError
//! set_stop_pin(ct, level)            set_inputs(ct, levels of pins 0–63)
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
//! | set position | `NotIdle` | anything moves, is queued or held, or homing runs |
//! | move, jog | `Homing` | homing owns the axis |
//! | move, jog | `IntoLimit(side)` | it goes towards a hard limit that tripped (until `ClearLimitFault`) or reads active |
//! | move | `BeyondSoftLimit` | where the axis ends once everything taken and this move are carried out lies beyond a soft limit |
//! | jog | `BeyondSoftLimit` | it would start (or turn round) with no room left before the soft limit |
//! | home | `Homing`, `NotIdle`, `StopPinLow`, `BadSetting`, a speed's `Plan` | homing runs; anything moves; the stop pin is low; bad switch pin, travel or back-off |
//! | home | `IntoLimit(side)` | a hard limit other than the home switch is in the way |
//! | set soft limits, set limit pins | `BadSetting` (`Homing` for limit pins while homing) | min above max; a limit pin out of range, an output, or both limits on one pin |
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
//!
//! # Inputs, homing and limits
//!
//! The core keeps a *physical position* beside the position counter: the
//! signed count of its own step edges since it started, which set_position
//! and homing leave alone. Inputs come in as levels with
//! [`AxisCore::set_inputs`]; a caller gives them after each step edge a
//! switch can see (the host's cog does so before the next event, so an
//! input that changed with a step is seen on that step, in virtual and
//! real time alike), and the core acts on the pins it watches
//! ([`AxisCore::watched_pins`]):
//!
//! - **Homing** ([`CoreCommand::Home`]) runs as stages, each a move whose
//!   steps are taken (and counted in the ledger) like any other: seek the
//!   switch for at most `max_travel` steps; on the step where it reads its
//!   active level, latch `(position, physical)` and stop (the profile's
//!   deceleration, the unmade steps dropped); back off to `backoff_steps`
//!   before the latched point; approach at `latch_speed`, latch again,
//!   stop; set the position so that the latched point is `set_position`
//!   (the ledger starts again from there). A switch pressed at the start is
//!   first left. Contact bounce after the first contact is ignored: the
//!   first reading latches. The stop pin, an emergency stop or a tripped
//!   limit end homing with an error outcome ([`AxisCore::home_outcome`]).
//! - **Hard limits** ([`CoreCommand::SetLimitPins`]): a limit pin changing
//!   to its active level while the motion heads that way trips once:
//!   controlled stop (or an emergency stop with `limit_estop`), and the
//!   trip is kept ([`AxisCore::limit_trip`]: where, and the steps still
//!   made to stop; none further) until [`CoreCommand::ClearLimitFault`].
//!   Hook for coordinated moves: a group move must stop its other members
//!   when one of them trips; [`AxisCore::events`] moves when a trip
//!   happens, and [`AxisCore::check_target`] is the admission a group move
//!   runs for each member.
//! - **Soft limits** ([`CoreCommand::SetSoftLimits`]) are admission only: a
//!   move that would end beyond them is refused; a jog's chunks are cut
//!   so that it ends exactly on the limit.

use crate::axis::{AxisError, Direction, HomeConfig, HomeReport, LimitTrip, Mode};
use crate::profile::ieee_div::f64_to_u32;
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
    /// A hard limit stops the axis with an emergency stop instead of the
    /// fastest controlled deceleration.
    pub limit_estop: bool,
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
            limit_estop: false,
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
    /// Start homing (idle only; see [`AxisCore`]'s homing section).
    Home(HomeConfig),
    /// Soft limits `(min, max)` on the position, or none.
    SetSoftLimits(Option<(i64, i64)>),
    /// The hard limit inputs: `(pin, active level)` for the min and max side.
    SetLimitPins {
        /// The limit met moving in reverse.
        min: Option<(u8, bool)>,
        /// The limit met moving forward.
        max: Option<(u8, bool)>,
    },
    /// Forget a tripped hard limit.
    ClearLimitFault,
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

/// The stages of homing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum HomePhase {
    /// The switch read active at the start: move away until it releases.
    Escape,
    /// First pass towards the switch at the seek speed.
    Seek,
    /// Back to `backoff_steps` before the switch point.
    Backoff,
    /// Second pass at the latch speed.
    Approach,
}

/// Homing in progress.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Homing {
    config: HomeConfig,
    phase: HomePhase,
    /// The switch changed in this phase (and the motion was told to stop).
    found: bool,
    /// (position, physical) at the switch step of the first pass.
    seek: Option<(i64, i64)>,
    /// (position, physical) at the switch step of the second pass.
    latch: Option<(i64, i64)>,
}

/// The index of a side's hard limit: 0 = min (met in reverse), 1 = max.
fn limit_index(side: Direction) -> usize {
    match side {
        Direction::Reverse => 0,
        Direction::Forward => 1,
    }
}

fn pin_bit(pin: u8) -> u64 {
    1u64.checked_shl(u32::from(pin)).unwrap_or(0)
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

/// Steps made at once by [`AxisCore::run_slew`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlewRun {
    /// The pin each step pulsed.
    pub pin: u8,
    /// How many steps: a rising and a falling edge each.
    pub steps: u32,
}

/// Slew steps whose edges are known before they are made, for a caller
/// that drives them without the core (a timer interrupt): from
/// [`AxisCore::slew_train`], stepped by [`SlewTrain::make_step`], handed
/// back with [`AxisCore::commit_train`]. Each step is a rising edge on
/// [`SlewTrain::pin`] at its CT and a falling edge `pulse_ticks` later,
/// the same edges [`AxisCore::run_event`] would emit; the arithmetic per
/// step is one 32.32 addition.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlewTrain {
    /// CT of the next step's rising edge.
    pub rise_ct: u64,
    /// The pin pulsed.
    pub pin: u8,
    /// Width of each pulse, ticks.
    pub pulse_ticks: u32,
    /// Steps the train may still make.
    pub steps_left: u32,
    /// No step of the train may rise at or after this CT (a jog's
    /// deadline; [`u64::MAX`] for none): the core decides what happens then.
    pub limit_ct: u64,
    delay_q32: u64,
    carry: u32,
    /// Ticks added to each delay to make the period (P2Exact's pulse and
    /// cog overhead; 0 in Smooth).
    period_extra: u32,
    made: u32,
    last_rise_ct: u64,
    last_delay_ticks: u32,
}

impl SlewTrain {
    /// Whether the step at [`SlewTrain::rise_ct`] is the train's to make.
    #[inline(always)]
    pub fn has_step(&self) -> bool {
        self.steps_left > 0 && self.rise_ct < self.limit_ct
    }

    /// Makes the step at [`SlewTrain::rise_ct`] (the caller drives its
    /// edges) and moves on to the next; call only when
    /// [`SlewTrain::has_step`].
    #[inline(always)]
    pub fn make_step(&mut self) {
        let total = self.delay_q32 + u64::from(self.carry);
        let delay_ticks = (total >> 32) as u32;
        self.carry = total as u32;
        self.last_rise_ct = self.rise_ct;
        self.last_delay_ticks = delay_ticks;
        self.rise_ct += u64::from(delay_ticks) + u64::from(self.period_extra);
        self.steps_left -= 1;
        self.made += 1;
    }

    /// Steps made so far.
    pub fn made(&self) -> u32 {
        self.made
    }

    /// Makes `steps` steps at once (at most [`SlewTrain::steps_left`]):
    /// the same train as that many calls of [`SlewTrain::make_step`], in
    /// closed form (the carry makes the sum of k delays
    /// `⌊(carry + k·delay_q32) / 2^32⌋`). For a caller that makes the
    /// steps with [`SlewTrain::delay_q32`] and [`SlewTrain::carry`] itself
    /// and hands the train back with its count.
    pub fn make_steps(&mut self, steps: u32) {
        let steps = steps.min(self.steps_left);
        if steps == 0 {
            return;
        }
        let delay_q32 = u128::from(self.delay_q32);
        let before_last = u128::from(self.carry) + delay_q32 * u128::from(steps - 1);
        let total = before_last + delay_q32;
        let extra = u64::from(self.period_extra);
        self.last_rise_ct =
            self.rise_ct + (before_last >> 32) as u64 + extra * u64::from(steps - 1);
        self.last_delay_ticks = ((total >> 32) - (before_last >> 32)) as u32;
        self.rise_ct += (total >> 32) as u64 + extra * u64::from(steps);
        self.carry = total as u32;
        self.steps_left -= steps;
        self.made += steps;
    }

    /// The delay between steps, 32.32 ticks: each step's delay in ticks
    /// is the integer part of this plus [`SlewTrain::carry`], the carry
    /// its fraction.
    pub fn delay_q32(&self) -> u64 {
        self.delay_q32
    }

    /// The fraction carried to the next step's delay (of 2^32).
    pub fn carry(&self) -> u32 {
        self.carry
    }

    /// Ticks added to each delay to make the period (P2Exact's pulse and
    /// cog overhead; 0 in Smooth).
    pub fn period_extra(&self) -> u32 {
        self.period_extra
    }
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
    sticky: Mode,
    /// Phase bits of the last step.
    step_bits: Mode,
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
    /// The signed count of the axis's own step edges since it started
    /// (set_position and homing leave it alone).
    physical: i64,
    /// Input levels as last told ([`AxisCore::set_inputs`]), bit per pin.
    inputs: u64,
    soft_limits: Option<(i64, i64)>,
    /// `(pin, active level)` of the min and max hard limits.
    limit_pins: [Option<(u8, bool)>; 2],
    limit_trip: Option<LimitTrip>,
    homing: Option<Homing>,
    home_outcome: Option<Result<HomeReport, AxisError>>,
    /// Counts changes of the limit and homing state, for publishing.
    events: u32,
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
            sticky: Mode::empty(),
            step_bits: Mode::empty(),
            ledger: StepLedger::default(),
            last_dropped: 0,
            move_info: MoveInfo::default(),
            queued_start: false,
            last_step: LastStep::default(),
            math_overruns: 0,
            reserved: false,
            group: None,
            physical: 0,
            inputs: 0,
            soft_limits: None,
            limit_pins: [None; 2],
            limit_trip: None,
            homing: None,
            home_outcome: None,
            events: 0,
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
                self.reset_position(position);
                Ok(Taken::Done)
            }
            CoreCommand::EmergencyStop => {
                self.emergency_stop(t);
                Ok(Taken::Done)
            }
            CoreCommand::Home(config) => self.command_home(t, config),
            CoreCommand::SetSoftLimits(limits) => {
                if limits.is_some_and(|(min, max)| min > max) {
                    return Err(AxisError::BadSetting("the soft min is above the soft max"));
                }
                self.soft_limits = limits;
                self.events = self.events.wrapping_add(1);
                Ok(Taken::Done)
            }
            CoreCommand::SetLimitPins { min, max } => {
                if self.homing.is_some() {
                    return Err(AxisError::Homing);
                }
                let outputs = self.config.outputs.pins();
                for (pin, _) in min.iter().chain(max.iter()) {
                    if *pin >= 64 {
                        return Err(AxisError::BadSetting("limit pins are 0 to 63"));
                    }
                    if outputs.contains(pin) {
                        return Err(AxisError::BadSetting(
                            "a limit pin is an output of the axis",
                        ));
                    }
                }
                if min.zip(max).is_some_and(|(min, max)| min.0 == max.0) {
                    return Err(AxisError::BadSetting("the min and max limits share a pin"));
                }
                self.limit_pins = [min, max];
                self.events = self.events.wrapping_add(1);
                Ok(Taken::Done)
            }
            CoreCommand::ClearLimitFault => {
                self.limit_trip = None;
                self.events = self.events.wrapping_add(1);
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
        self.step_bits = Mode::ACCEL
            | if group.steps < 0 {
                Mode::REVERSE
            } else {
                Mode::empty()
            };
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

    /// Sets the position counter; the ledger starts again from it.
    fn reset_position(&mut self, position: i64) {
        self.position = position;
        self.ledger = StepLedger {
            base: position,
            dropped_total: self.ledger.dropped_total,
            ..StepLedger::default()
        };
    }

    fn command_move(&mut self, t: u64, speed: u32, steps: i32) -> Result<Taken, AxisError> {
        Self::check_move(&self.config, speed, steps)?;
        if self.homing.is_some() {
            return Err(AxisError::Homing);
        }
        if self.jog_owns && self.motion.is_moving() {
            return Err(AxisError::Jogging);
        }
        if self.held.is_some() || self.in_group() {
            return Err(AxisError::Busy);
        }
        self.check_reach(i64::from(steps))?;
        self.check_limit(Direction::of(steps))?;
        self.check_soft_move(speed, steps)?;
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
            self.step_bits = Mode::ACCEL
                | if steps < 0 {
                    Mode::REVERSE
                } else {
                    Mode::empty()
                };
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
        if self.homing.is_some() {
            return Err(AxisError::Homing);
        }
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
            self.check_limit(direction)?;
            // A soft limit shortens the chunk so that the jog stops on it.
            let room = self.soft_room(direction, running_this_way);
            let magnitude = i32::try_from(u64::from(chunk).min(room)).unwrap_or(i32::MAX);
            if magnitude == 0 {
                if !running_this_way {
                    return Err(AxisError::BeyondSoftLimit);
                }
                // Already heading for the limit: the beat only keeps the jog alive.
            } else {
                let steps = match direction {
                    Direction::Forward => magnitude,
                    Direction::Reverse => -magnitude,
                };
                self.check_reach(i64::from(steps))?;
                self.start_or_merge(t, speed, steps)?;
            }
        }
        self.jog_owns = true;
        self.jog = Some(Jog {
            speed,
            direction,
            deadline,
        });
        Ok(Taken::Jog)
    }

    /// The limit admission of a move of `steps` at `speed` (hard limits
    /// tripped or active that way, soft limits), without taking it: what a
    /// coordinated move checks on each member before any of them starts.
    pub fn check_target(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        if self.homing.is_some() {
            return Err(AxisError::Homing);
        }
        if steps == 0 {
            // An axis that does not move in a group crosses nothing.
            return Ok(());
        }
        self.check_limit(Direction::of(steps))?;
        self.check_soft_move(speed, steps)
    }

    /// Refuses a move or jog towards a hard limit that tripped (until the
    /// fault is cleared) or reads active now.
    fn check_limit(&self, side: Direction) -> Result<(), AxisError> {
        if self.limit_trip.is_some_and(|trip| trip.side == side) || self.limit_active(side) {
            return Err(AxisError::IntoLimit(side));
        }
        Ok(())
    }

    /// Whether the hard limit of `side` reads active (a limit on the home
    /// switch's pin is the switch while homing).
    fn limit_active(&self, side: Direction) -> bool {
        self.limit_pins[limit_index(side)].is_some_and(|(pin, active)| {
            let is_home_switch = self
                .homing
                .is_some_and(|homing| homing.config.switch_pin == pin);
            !is_home_switch && self.input(pin) == active
        })
    }

    /// Refuses a move that would end beyond the soft limits (where the axis
    /// ends once this move and everything before it is carried out).
    fn check_soft_move(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        let Some((min, max)) = self.soft_limits else {
            return Ok(());
        };
        let end_offset = if self.stop_pin_high {
            let mut motion = self.motion.clone();
            match motion.command(speed, steps) {
                Ok(_) => motion.end_offset(),
                // Refused below with its own error.
                Err(_) => return Ok(()),
            }
        } else {
            // Held: it runs from where the axis stops.
            self.motion.end_offset() + i64::from(steps)
        };
        let end = i128::from(self.position) + i128::from(end_offset);
        if end < i128::from(min) || end > i128::from(max) {
            return Err(AxisError::BeyondSoftLimit);
        }
        Ok(())
    }

    /// Steps a jog in `direction` may add before it would pass the soft
    /// limit (`u64::MAX` without one): from where the motion ends now, or
    /// where it stops when it must turn round first.
    fn soft_room(&self, direction: Direction, running_this_way: bool) -> u64 {
        let Some((min, max)) = self.soft_limits else {
            return u64::MAX;
        };
        let end_offset = if running_this_way || !self.motion.is_moving() {
            self.motion.end_offset()
        } else {
            let mut motion = self.motion.clone();
            motion.stop();
            motion.end_offset()
        };
        let end = i128::from(self.position) + i128::from(end_offset);
        let room = match direction {
            Direction::Forward => i128::from(max) - end,
            Direction::Reverse => end - i128::from(min),
        };
        u64::try_from(room.max(0)).unwrap_or(u64::MAX)
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

    /// Anything moving, queued, held, reserved for a group or homing.
    fn is_busy(&self) -> bool {
        self.motion.is_moving() || self.held.is_some() || self.in_group() || self.homing.is_some()
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
            self.step_bits = Mode::empty();
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
        self.step_bits = Mode::empty();
        self.abort_homing(AxisError::HomingAborted);
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
            self.abort_homing(AxisError::HomingAborted);
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

    /// The event at CT `t` and the ones after it, up to CT `limit` and at
    /// most `max_steps` of them, when every one is a plain slew step: made
    /// at once, in closed form. The core is then bit for bit what
    /// [`AxisCore::run_event`] at each of those steps leaves; the edges are
    /// not passed one by one but summed up in the [`SlewRun`] (each step a
    /// rising and a falling edge on its pin, the pin low after the last).
    /// `None` (and nothing changed) when the event at `t` is anything else:
    /// a ramp step, a re-planned curve, a direction change, a jog deadline.
    ///
    /// The caller runs no input between those steps: it is for a caller
    /// that would find nothing new at them (nothing asked, no edge traced,
    /// no simulated switch moving with the axis). An axis that watches
    /// inputs on every step (limit pins, homing) gets `None`.
    pub fn run_slew(&mut self, t: u64, limit: u64, max_steps: u32) -> Option<SlewRun> {
        // Inputs looked at on every step (limit pins, a home switch) make
        // every step an event of its own.
        if self.watched_pins() != 0 || self.homing.is_some() {
            return None;
        }
        let first = self.due.filter(|due| *due == t && t <= limit)?;
        let (span, direction) = self.motion.slew_span()?;
        let reverse = direction == Direction::Reverse;
        if reverse != self.dir_reverse || max_steps == 0 {
            return None;
        }
        // A jog's deadline is an event of its own: the steps stop short of it.
        let mut last_allowed = limit;
        if let Some(jog) = self.jog {
            last_allowed = last_allowed.min(jog.deadline.checked_sub(1)?);
        }
        let window = last_allowed.checked_sub(first)?;
        let (due_steps, fixed_period) = match self.config.scurve.arithmetic {
            Arithmetic::Smooth => (span.steps_within(window), None),
            Arithmetic::P2Exact => {
                // The reference's slew delay is whole ticks: every period alike.
                if span.delay_q32 & 0xFFFF_FFFF != 0 {
                    return None;
                }
                let period = self.period_ticks(span.delay_ticks(0)).max(1);
                (window / period + 1, Some(period))
            }
        };
        let steps = due_steps
            .min(u64::from(span.steps))
            .min(u64::from(max_steps)) as u32;
        let last_delay = self.motion.skip_slew(steps)?;
        let before_last = u64::from(steps - 1);
        let t_last = first
            + match fixed_period {
                Some(period) => before_last * period,
                None => span.ticks_before(before_last),
            };
        let next = t_last + self.period_ticks(last_delay);
        self.settle_slew(
            direction,
            steps,
            LastStep {
                velocity: f64_to_u32(span.velocity_steps_per_s),
                delay_ticks: last_delay,
                ct: t_last,
            },
            next,
        );
        Some(SlewRun {
            pin: self.config.outputs.pulse_pin(direction),
            steps,
        })
    }

    /// The next event when it is a step whose edges are known before it is
    /// made: `(due, pin)` when the step due at `due` goes on in the current
    /// curve's direction with no direction edge before it, and no jog
    /// deadline comes first. Its first edge is then the rising edge of
    /// `pin` at `due`, and nothing the step decides happens before `due`:
    /// a caller may drive that edge at `due` and only then run the event
    /// ([`AxisCore::run_event`] emits the same edge first, with the rest).
    /// `None` says nothing about when the next event is.
    #[inline]
    pub fn next_plain_step(&self) -> Option<(u64, u8)> {
        let due = self.due?;
        if self.jog.is_some_and(|jog| jog.deadline <= due) {
            return None;
        }
        let (curve, direction) = self.motion.current()?;
        if !curve.is_running() {
            return None;
        }
        let outputs = self.config.outputs;
        let reverse = direction == Direction::Reverse;
        if reverse != self.dir_reverse && outputs.dir_pin().is_some() {
            return None;
        }
        Some((due, outputs.pulse_pin(direction)))
    }

    /// The slew steps from the next event on that need no decision: the
    /// next event is a step with known edges ([`AxisCore::next_plain_step`])
    /// and the profile's fast slew path (see
    /// [`crate::profile::scurve::SCurve::slew_span`]) makes it and those
    /// after it. `None` otherwise. While a caller holds a train it must
    /// not run the core; it hands the train back with
    /// [`AxisCore::commit_train`] before anything else touches the core.
    pub fn slew_train(&self) -> Option<SlewTrain> {
        let (due, pin) = self.next_plain_step()?;
        let (curve, _) = self.motion.current()?;
        // Inputs looked at on every step (limit pins, a home switch) make
        // every step an event of its own.
        if self.watched_pins() != 0 || self.homing.is_some() {
            return None;
        }
        let ahead = curve.slew_span()?;
        let period_extra = match self.config.scurve.arithmetic {
            Arithmetic::Smooth => 0,
            Arithmetic::P2Exact => (scurve::p2_period_ticks(0, self.config.pulse_ticks))
                .min(u64::from(u32::MAX)) as u32,
        };
        Some(SlewTrain {
            rise_ct: due,
            pin,
            pulse_ticks: self.config.pulse_ticks,
            steps_left: ahead.steps,
            limit_ct: self.jog.map_or(u64::MAX, |jog| jog.deadline),
            delay_q32: ahead.delay_q32,
            carry: ahead.carry_q32 as u32,
            period_extra,
            made: 0,
            last_rise_ct: 0,
            last_delay_ticks: 0,
        })
    }

    /// Takes back a train from [`AxisCore::slew_train`]: the core is left
    /// as if it had run the events of the steps the train made, one by
    /// one, at their CTs (same position, accounts, last step and next
    /// event).
    pub fn commit_train(&mut self, train: &SlewTrain) {
        let steps = train.made;
        let Some((span, direction)) = self.motion.slew_span().filter(|_| steps > 0) else {
            return;
        };
        let delay = self.motion.skip_slew(steps);
        debug_assert_eq!(delay, Some(train.last_delay_ticks));
        self.settle_slew(
            direction,
            steps,
            LastStep {
                velocity: f64_to_u32(span.velocity_steps_per_s),
                delay_ticks: train.last_delay_ticks,
                ct: train.last_rise_ct,
            },
            train.rise_ct,
        );
    }

    /// The core's state after `steps` slew steps made at once (by
    /// [`AxisCore::run_slew`] or a [`SlewTrain`]), the last of them `last`,
    /// the next step due at `next`: what that many calls of `step` leave.
    fn settle_slew(&mut self, direction: Direction, steps: u32, last: LastStep, next: u64) {
        let moved = direction.sign() * i64::from(steps);
        self.position = self.position.saturating_add(moved);
        self.physical = self.physical.saturating_add(moved);
        if self.jog_owns {
            self.ledger.jogged += moved;
        }
        self.last_fall_ct = last.ct + u64::from(self.config.pulse_ticks);
        self.last_step = last;
        self.step_bits = Mode::SLEW
            | if direction == Direction::Reverse {
                Mode::REVERSE
            } else {
                Mode::empty()
            };
        self.due = Some(next);
        self.ready_ct = next;
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
                velocity: f64_to_u32(velocity),
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
        self.physical = self.physical.saturating_add(direction.sign());
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
        if next.step.phase == Phase::Decel && !self.step_bits.contains(Mode::DECEL) {
            // Deceleration starts: the reference writes Max Velocity now,
            // the velocity of the last ramp (or slew) step.
            self.move_info.max_velocity = self.last_step.velocity;
        }
        self.last_step = LastStep {
            velocity: f64_to_u32(next.step.velocity_steps_per_s),
            delay_ticks: delay,
            ct: t,
        };
        self.step_bits = match next.step.phase {
            Phase::Accel => Mode::ACCEL,
            Phase::Slew => Mode::SLEW,
            Phase::Decel => Mode::DECEL,
        } | if reverse {
            Mode::REVERSE
        } else {
            Mode::empty()
        };
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

    /// The move made its last step: the axis is ready at `t` (homing goes
    /// on with its next stage).
    fn finish(&mut self, t: u64) {
        self.due = None;
        self.ready_ct = t;
        self.jog = None;
        self.jog_owns = false;
        self.step_bits = Mode::empty();
        self.last_step.velocity = 0;
        self.advance_homing(t);
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
        if self.limit_trip.is_some() {
            bits |= Mode::LIMIT;
        }
        if self.homing.is_some() {
            bits |= Mode::HOMING;
        }
        bits
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

/// Inputs, hard and soft limits, homing.
impl AxisCore {
    /// The input levels at CT `t`, bit per pin (bit n = pin n high). Give
    /// them whenever a watched pin ([`AxisCore::watched_pins`]) may have
    /// changed, and after each step edge a switch could see: a change that
    /// arrives right after a step (before the next event) is taken as the
    /// step on which it happened, so the latched position is that step's.
    pub fn set_inputs(&mut self, t: u64, levels: u64) {
        let changed = (levels ^ self.inputs) & self.watched_pins();
        self.inputs = levels;
        if changed == 0 {
            return;
        }
        if let Some(homing) = self.homing {
            if changed & pin_bit(homing.config.switch_pin) != 0 {
                self.homing_switch_changed();
            }
        }
        for side in [Direction::Reverse, Direction::Forward] {
            if let Some((pin, _)) = self.limit_pins[limit_index(side)] {
                // A bouncing limit trips once: the first contact is the trip.
                let tripped = self.limit_trip.is_some_and(|trip| trip.side == side);
                if changed & pin_bit(pin) != 0
                    && !tripped
                    && self.limit_active(side)
                    && self.moving_towards(side)
                {
                    self.trip(t, side);
                }
            }
        }
    }

    /// The input pins the axis acts on now: its hard limits and, while
    /// homing, the home switch (bit per pin).
    pub fn watched_pins(&self) -> u64 {
        let limits = self
            .limit_pins
            .iter()
            .flatten()
            .fold(0, |mask, (pin, _)| mask | pin_bit(*pin));
        let switch = self
            .homing
            .map_or(0, |homing| pin_bit(homing.config.switch_pin));
        limits | switch
    }

    /// The level of an input pin as last told.
    pub fn input(&self, pin: u8) -> bool {
        self.inputs & pin_bit(pin) != 0
    }

    /// Whether the motion heads for `side` (the move in progress or a
    /// queued reversal).
    fn moving_towards(&self, side: Direction) -> bool {
        let current = self
            .motion
            .current()
            .is_some_and(|(curve, direction)| direction == side && curve.is_running());
        current || self.motion.queued_direction() == Some(side)
    }

    /// A hard limit read active moving towards it: stop (the profile's
    /// deceleration from the current velocity, or an emergency stop) and
    /// latch the fault.
    fn trip(&mut self, t: u64, side: Direction) {
        if self.config.limit_estop {
            self.emergency_stop(t);
        } else {
            self.stop_motion();
            self.jog = None;
            self.sticky |= Mode::STOP_LATCHED;
        }
        self.abort_homing(AxisError::IntoLimit(side));
        self.limit_trip = Some(LimitTrip {
            side,
            position: self.position,
            physical: self.physical,
            stopping_steps: self.motion.steps_to_go(),
        });
        self.events = self.events.wrapping_add(1);
    }

    /// Controlled stop of the motion, its unmade steps accounted for.
    fn stop_motion(&mut self) {
        let dropped = self.motion.stop();
        self.account_stop(dropped);
        self.queued_start = false;
    }

    /// Ends homing with `error` (nothing to do when not homing).
    fn abort_homing(&mut self, error: AxisError) {
        if self.homing.take().is_some() {
            self.home_outcome = Some(Err(error));
            self.events = self.events.wrapping_add(1);
        }
    }

    fn command_home(&mut self, t: u64, config: HomeConfig) -> Result<Taken, AxisError> {
        if self.homing.is_some() {
            return Err(AxisError::Homing);
        }
        if self.is_busy() {
            return Err(AxisError::NotIdle);
        }
        if config.switch_pin >= 64 {
            return Err(AxisError::BadSetting("the switch pin must be 0 to 63"));
        }
        if self.config.outputs.pins().contains(&config.switch_pin) {
            return Err(AxisError::BadSetting(
                "the switch pin is an output of the axis",
            ));
        }
        if config.max_travel == 0 || config.max_travel > i32::MAX.unsigned_abs() {
            return Err(AxisError::BadSetting("max_travel must be 1 to 2^31 - 1"));
        }
        if config.backoff_steps == 0 || config.backoff_steps > 1 << 30 {
            return Err(AxisError::BadSetting("backoff_steps must be 1 to 2^30"));
        }
        Self::check_move(&self.config, config.seek_speed, 1)?;
        Self::check_move(&self.config, config.latch_speed, 1)?;
        if !self.stop_pin_high {
            return Err(AxisError::StopPinLow);
        }
        let pressed = self.input(config.switch_pin) == config.active_level;
        let (phase, toward) = if pressed {
            (HomePhase::Escape, config.direction.opposite())
        } else {
            (HomePhase::Seek, config.direction)
        };
        let homing = Homing {
            config,
            phase,
            found: false,
            seek: None,
            latch: None,
        };
        self.homing = Some(homing);
        // A limit on the home switch's own pin is the switch while homing;
        // any other limit the axis would run into refuses homing.
        let refused = self
            .check_limit(toward)
            .and_then(|()| {
                let trip_elsewhere = self.limit_trip.is_some_and(|trip| {
                    trip.side == config.direction
                        && self.limit_pins[limit_index(trip.side)]
                            .is_some_and(|(pin, _)| pin != config.switch_pin)
                });
                if trip_elsewhere {
                    Err(AxisError::IntoLimit(config.direction))
                } else {
                    Ok(())
                }
            })
            .and_then(|()| {
                let steps = i64::from(config.max_travel) * toward.sign();
                self.homing_move(t, config.seek_speed, steps)
            });
        if let Err(error) = refused {
            self.homing = None;
            return Err(error);
        }
        if self.limit_trip.is_some_and(|trip| trip.side == toward) {
            // Homing onto the switch that tripped: the fault is the switch.
            self.limit_trip = None;
        }
        self.home_outcome = None;
        self.events = self.events.wrapping_add(1);
        Ok(Taken::Done)
    }

    /// Runs one of homing's moves (its steps count as taken).
    fn homing_move(&mut self, t: u64, speed: u32, steps: i64) -> Result<(), AxisError> {
        let steps = i32::try_from(steps).map_err(|_| AxisError::StepsOutOfRange)?;
        Self::check_move(&self.config, speed, steps)?;
        self.check_reach(i64::from(steps))?;
        self.start_or_merge(t, speed, steps)?;
        self.ledger.accepted += i64::from(steps);
        Ok(())
    }

    /// The home switch changed while homing.
    fn homing_switch_changed(&mut self) {
        let Some(mut homing) = self.homing else {
            return;
        };
        let pressed = self.input(homing.config.switch_pin) == homing.config.active_level;
        let here = (self.position, self.physical);
        let found = match homing.phase {
            HomePhase::Seek if pressed => {
                homing.seek = Some(here);
                true
            }
            HomePhase::Approach if pressed => {
                homing.latch = Some(here);
                true
            }
            HomePhase::Escape => !pressed,
            _ => false,
        };
        if found && !homing.found {
            homing.found = true;
            self.homing = Some(homing);
            self.stop_motion();
        }
    }

    /// A homing move ended at `t`: the next stage, or the outcome.
    fn advance_homing(&mut self, t: u64) {
        let Some(mut homing) = self.homing else {
            return;
        };
        let config = homing.config;
        let sign = config.direction.sign();
        let travel = i64::from(config.max_travel);
        let backoff = i64::from(config.backoff_steps);
        let pressed = self.input(config.switch_pin) == config.active_level;
        let next = match (homing.phase, homing.found) {
            (HomePhase::Escape, true) => Ok((HomePhase::Seek, config.seek_speed, sign * travel)),
            (HomePhase::Escape, false) => Err(AxisError::HomeSwitchStuck),
            (HomePhase::Seek, true) => {
                // Back to `backoff` steps before the switch point, whatever
                // the deceleration overshot.
                let switch_physical = homing.seek.map_or(self.physical, |(_, physical)| physical);
                let overshoot = (self.physical - switch_physical) * sign;
                Ok((
                    HomePhase::Backoff,
                    config.seek_speed,
                    -sign * (overshoot.max(0) + backoff),
                ))
            }
            (HomePhase::Backoff, _) if pressed => Err(AxisError::HomeSwitchStuck),
            (HomePhase::Backoff, _) => Ok((
                HomePhase::Approach,
                config.latch_speed,
                sign * (backoff + travel).min(i64::from(i32::MAX)),
            )),
            (HomePhase::Approach, true) => {
                self.homing = None;
                let (latch_position, latch_physical) = homing.latch.unwrap_or((0, 0));
                let (seek_position, seek_physical) = homing.seek.unwrap_or((0, 0));
                let position = config
                    .set_position
                    .checked_add(self.physical - latch_physical);
                self.home_outcome = Some(match position {
                    Some(position) => {
                        self.reset_position(position);
                        Ok(HomeReport {
                            seek_position,
                            seek_physical,
                            latch_position,
                            latch_physical,
                            position,
                        })
                    }
                    None => Err(AxisError::PositionOutOfRange),
                });
                self.events = self.events.wrapping_add(1);
                return;
            }
            (HomePhase::Seek | HomePhase::Approach, false) => Err(AxisError::HomeSwitchNotFound),
        };
        let started = next.and_then(|(phase, speed, steps)| {
            homing.phase = phase;
            homing.found = false;
            self.homing = Some(homing);
            self.homing_move(t, speed, steps)
        });
        if let Err(error) = started {
            // Still homing here: the outcome is the error.
            self.abort_homing(error);
        }
    }

    /// The signed count of the axis's own step edges since it started:
    /// where the motor physically is, whatever set_position or homing did.
    pub fn physical_position(&self) -> i64 {
        self.physical
    }

    /// The soft limits `(min, max)`, if set.
    pub fn soft_limits(&self) -> Option<(i64, i64)> {
        self.soft_limits
    }

    /// The hard limit inputs `[min, max]`: `(pin, active level)`.
    pub fn limit_pins(&self) -> [Option<(u8, bool)>; 2] {
        self.limit_pins
    }

    /// The hard limit that tripped, until [`CoreCommand::ClearLimitFault`].
    pub fn limit_trip(&self) -> Option<LimitTrip> {
        self.limit_trip
    }

    /// The side whose hard limit tripped, until cleared.
    pub fn limit_fault(&self) -> Option<Direction> {
        self.limit_trip.map(|trip| trip.side)
    }

    /// How the last homing ended: `None` while homing or never homed.
    pub fn home_outcome(&self) -> Option<Result<HomeReport, AxisError>> {
        self.home_outcome
    }

    /// Whether homing is under way.
    pub fn is_homing(&self) -> bool {
        self.homing.is_some()
    }

    /// Counts changes of the limit and homing state (settings, trips,
    /// outcomes): a status publisher republishes them when it moves.
    pub fn events(&self) -> u32 {
        self.events
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

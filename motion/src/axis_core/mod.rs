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
//!                                    set_inputs_late(ct, levels, late_steps)
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
//! | set position | `NotIdle` | anything has steps left, is queued, held or reserved, or homing runs (the last step's period is idle) |
//! | move, jog, set position | `Homing` | homing owns the axis |
//! | move, jog | `IntoLimit(side)` | it goes towards a hard limit that tripped (until `ClearLimitFault`) or reads active |
//! | move | `BeyondSoftLimit` | where the axis ends once everything taken and this move are carried out lies beyond a soft limit |
//! | jog | `BeyondSoftLimit` | it would start (or turn round) with no room left before the soft limit |
//! | home | `Homing`, `NotIdle`, `StopPinLow`, `BadSetting`, a speed's `Plan` | homing runs; anything moves; the stop pin is low; bad switch pin, travel or back-off |
//! | home | `IntoLimit(side)` | a hard limit other than the home switch is in the way |
//! | home | `BeyondSoftLimit` | a soft limit leaves no room to travel towards the switch (travel is cut to the room otherwise) |
//! | set soft limits, set limit pins | `BadSetting` (`Homing` for limit pins while homing) | min above max; a limit pin out of range, an output, or both limits on one pin |
//!
//! | group reserve / start | `Busy` | anything moves, is queued, held or reserved, or the axis is still within its last step's period |
//! | group reserve / start | `StopPinLow` | the stop pin is low |
//! | group reserve / start | `IntoLimit(side)`, `BeyondSoftLimit` | as for a move of the member's steps from where it stands |
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
//! ([`AxisCore::watched_pins`]). A caller that runs the core ahead of its
//! pins (a firmware whose cores run milliseconds ahead of the timer) learns
//! of a change some steps after the core made the step on which it
//! happened: [`AxisCore::set_inputs_late`] takes that count, and homing
//! and a trip latch that step's positions as if told on time, while the
//! stop starts from where the core is (up to that many steps further than
//! on the hub; a trip's stopping steps count them):
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
//!   A group member that trips stops its part on the line at once and
//!   asks for the whole line to stop ([`AxisCore::take_group_request`]):
//!   the caller passes it to every member, so all of them stay on the line.
//!   A limit pin set while it already reads active, and the axis moves
//!   towards it, trips at once. A move held by the stop pin that heads for
//!   a limit that trips is dropped (its steps counted), and a held move is
//!   admitted again when the pin goes high.
//! - **Soft limits** ([`CoreCommand::SetSoftLimits`]) hold for every way
//!   the axis moves: a move, a merge or a group part that would end beyond
//!   them is refused, a held move that would is dropped when the pin goes
//!   high, a jog's chunks and homing's travel are cut so that they end
//!   exactly on the limit.
//!
//! # One state
//!
//! What the axis is doing is one value (`State` in `state.rs`: idle, a
//! held move, reserved, a group part, or running with the motion's owner:
//! moves, a jog or homing), so no two flags can say different things.
//! The admission table above is tested row by row on the core
//! (`admission_tests.rs`).

mod admission;
mod config;
mod group;
mod homing;
mod limits;
mod path;
mod schedule;
mod slew;
mod state;
mod stop;

#[cfg(test)]
mod admission_tests;
#[cfg(test)]
mod late_inputs_tests;
#[cfg(test)]
mod safety_tests;
#[cfg(test)]
mod test_core;

pub use config::{
    AxisCoreConfig, CoreCommand, Edge, GroupMove, LastStep, MoveInfo, Outputs, StepLedger, Taken,
};
pub use group::{GroupLead, GroupRequest};
pub use path::PATH_QUEUE;
pub use slew::{SlewRun, StepTrain, RAMP_TRAIN_STEPS};

use crate::axis::{AxisError, Direction, HomeReport, LimitTrip, Mode};
use crate::profile::motion::Motion;
use crate::profile::scurve::{self, Arithmetic};
use state::{Owner, State};

/// One axis (see the module docs).
#[derive(Clone, Debug)]
pub struct AxisCore {
    config: AxisCoreConfig,
    motion: Motion,
    /// What the axis is doing: one value (see `state.rs`).
    state: State,
    position: i64,
    /// When the axis is ready for a next first step (last step + its period).
    ready_ct: u64,
    /// Level of the direction pin (sd), or last direction (cc).
    dir_reverse: bool,
    /// When the last pulse ends: a direction change may not come before.
    last_fall_ct: u64,
    stop_pin_high: bool,
    /// Flags that outlive a move (STOP_LATCHED, ESTOP).
    sticky: Mode,
    /// Phase bits of the last step.
    step_bits: Mode,
    ledger: StepLedger,
    /// Steps the last stop left unmade (a later move of that many reaches
    /// the original target).
    last_dropped: u32,
    move_info: MoveInfo,
    last_step: LastStep,
    math_overruns: u64,
    /// The signed count of the axis's own step edges since it started
    /// (set_position and homing leave it alone).
    physical: i64,
    /// Input levels as last told ([`AxisCore::set_inputs`]), bit per pin.
    inputs: u64,
    soft_limits: Option<(i64, i64)>,
    /// `(pin, active level)` of the min and max hard limits.
    limit_pins: [Option<(u8, bool)>; 2],
    limit_trip: Option<LimitTrip>,
    home_outcome: Option<Result<HomeReport, AxisError>>,
    /// What this member asks of its whole group (a limit tripped), until
    /// the caller takes it.
    group_request: Option<GroupRequest>,
    /// Counts changes of the limit and homing state, for publishing.
    events: u32,
}

impl AxisCore {
    /// An idle axis at position 0, its stop pin low, at CT `ct`.
    pub fn new(config: AxisCoreConfig, ct: u64) -> Self {
        Self {
            config,
            motion: Motion::new(config.scurve),
            state: State::Idle,
            position: 0,
            ready_ct: ct,
            dir_reverse: false,
            last_fall_ct: 0,
            stop_pin_high: false,
            sticky: Mode::empty(),
            step_bits: Mode::empty(),
            ledger: StepLedger::default(),
            last_dropped: 0,
            move_info: MoveInfo::default(),
            last_step: LastStep::default(),
            math_overruns: 0,
            physical: 0,
            inputs: 0,
            soft_limits: None,
            limit_pins: [None; 2],
            limit_trip: None,
            home_outcome: None,
            group_request: None,
            events: 0,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &AxisCoreConfig {
        &self.config
    }

    /// Takes a command arriving at CT `t` (see the module docs for the
    /// rules). A refused command changes nothing.
    pub fn command(&mut self, t: u64, command: CoreCommand) -> Result<Taken, AxisError> {
        self.command_with_lead(t, command, None)
    }

    /// [`AxisCore::command`], a [`CoreCommand::GroupStart`] with the lead's
    /// curve planned once for every member ([`GroupLead::plan`]): the
    /// member takes a copy of it instead of planning its own, when it is the
    /// curve its own planning would give (the same S-curve settings, speed
    /// and lead steps; else it plans its own). The same outcome, for less
    /// work: a caller that starts every member in one critical section (a
    /// firmware) plans the curve once, outside it. `lead` is ignored by any
    /// other command.
    pub fn command_with_lead(
        &mut self,
        t: u64,
        command: CoreCommand,
        lead: Option<&GroupLead>,
    ) -> Result<Taken, AxisError> {
        match command {
            CoreCommand::Move { speed, steps } => self.command_move(t, speed, steps),
            CoreCommand::Jog { speed, direction } => self.command_jog(t, speed, direction),
            CoreCommand::JogRelease => {
                self.release_jog();
                Ok(Taken::Done)
            }
            CoreCommand::SetPosition(position) => {
                if self.state.homing().is_some() {
                    return Err(AxisError::Homing);
                }
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
            CoreCommand::SetSoftLimits(limits) => self.set_soft_limits(limits),
            CoreCommand::SetLimitPins { min, max } => self.set_limit_pins(t, min, max),
            CoreCommand::ClearLimitFault => {
                self.limit_trip = None;
                self.events = self.events.wrapping_add(1);
                Ok(Taken::Done)
            }
            CoreCommand::GroupReserve { steps } => {
                self.check_group(t, steps)?;
                self.state = State::Reserved;
                Ok(Taken::Done)
            }
            CoreCommand::GroupCancel => {
                if matches!(self.state, State::Reserved) {
                    self.state = State::Idle;
                }
                Ok(Taken::Done)
            }
            CoreCommand::GroupStart(group) => self.start_group_with(t, group, lead),
            CoreCommand::PathStart => self.start_path(t),
            CoreCommand::PathEnd => {
                self.end_path(t);
                Ok(Taken::Done)
            }
        }
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
            .state
            .held()
            .map_or(0, |held| u64::from(held.steps.unsigned_abs()));
        let group = self.state.follower().map_or(0, |follower| {
            if follower.finish_at.is_some() {
                0
            } else {
                u64::from(follower.steps - follower.made)
            }
        });
        let path = match &self.state {
            State::Path(part) => part.len() as u64,
            _ => 0,
        };
        self.motion.steps_to_go() + held + group + path
    }

    /// Whether a step is scheduled (the axis is moving).
    pub fn is_moving(&self) -> bool {
        match &self.state {
            State::Running(_) | State::Group(_) => true,
            State::Path(part) => part.len() > 0,
            State::Idle | State::Held(_) | State::Reserved => false,
        }
    }

    /// The mode bits now: the phase and direction of the last step while
    /// moving, plus STOP_LATCHED, ESTOP, HOLD and JOG. At the end of a move
    /// only the flags that outlive it remain (the reference keeps b5 alone:
    /// the direction bit clears).
    pub fn mode(&self) -> Mode {
        let mut bits = self.sticky;
        match &self.state {
            State::Idle | State::Reserved => {}
            State::Held(_) => bits |= Mode::HOLD,
            State::Group(_) => bits |= Mode::MOVING | self.step_bits,
            State::Path(part) => {
                if part.len() > 0 {
                    bits |= Mode::MOVING | self.step_bits;
                }
            }
            State::Running(run) => {
                bits |= Mode::MOVING | self.step_bits;
                match run.owner {
                    // The jog bit says what admission sees: a jog with steps left.
                    Owner::Jog(_) if self.motion.is_moving() => bits |= Mode::JOG,
                    Owner::Moves { held: Some(_) } => bits |= Mode::HOLD,
                    Owner::Homing(_) => bits |= Mode::HOMING,
                    Owner::Jog(_) | Owner::Moves { held: None } => {}
                }
            }
        }
        if self.limit_trip.is_some() {
            bits |= Mode::LIMIT;
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

    /// What the last step did; its velocity is 0 once nothing is left to
    /// make (idle, as [`AxisCore::steps_to_go`] and the status say, the
    /// last step's period included).
    pub fn last_step(&self) -> LastStep {
        let mut last = self.last_step;
        if self.steps_to_go() == 0 {
            last.velocity = 0;
        }
        last
    }

    /// Ramp steps whose delay was shorter than the CORDIC work they needed.
    pub fn math_overruns(&self) -> u64 {
        self.math_overruns
    }

    /// The S-curve offset, degrees.
    pub fn offset_deg(&self) -> u32 {
        self.config.scurve.offset_deg
    }

    /// Counts changes of the limit and homing state (settings, trips,
    /// outcomes): a status publisher republishes them when it moves.
    pub fn events(&self) -> u32 {
        self.events
    }

    /// Rising edge to the next rising edge after a step of `delay_ticks`:
    /// in `P2Exact` the reference cog's running target (delay + pulse + the
    /// cog's fixed overhead, [`scurve::p2_period_ticks`]), so its edges are
    /// the real board's; `Smooth` runs at the speed asked (period = delay).
    fn period_ticks(&self, delay_ticks: u32) -> u64 {
        period_ticks(&self.config, delay_ticks)
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
    let scaled = div_u64(
        u64::from(value) * u64::from(numerator),
        u64::from(denominator),
    );
    u32::try_from(scaled).unwrap_or(u32::MAX)
}

/// `n / d` (`d` > 0), by a 32-bit division where both fit: a
/// microcontroller's 32-bit divider, not a 64-bit library call.
#[inline]
fn div_u64(n: u64, d: u64) -> u64 {
    match (u32::try_from(n), u32::try_from(d)) {
        (Ok(n), Ok(d)) => u64::from(n / d),
        _ => n / d,
    }
}

/// The bit of an input pin in a word of levels (0 for pins past 63).
fn pin_bit(pin: u8) -> u64 {
    1u64.checked_shl(u32::from(pin)).unwrap_or(0)
}

/// The index of a side's hard limit: 0 = min (met in reverse), 1 = max.
fn limit_index(side: Direction) -> usize {
    match side {
        Direction::Reverse => 0,
        Direction::Forward => 1,
    }
}

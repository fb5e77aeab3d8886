//! [`Axis`]: a handle on one cog, from any thread — the commands (each
//! answered by the cog's axis core before the call returns), the status
//! the cog publishes, homing and limits, and the [`AxisContract`].

use cogstep_motion::refusal::bad_setting;
use std::sync::Arc;

use crate::cog::CogShared;
use crate::hub::{lock, request_estop, wait_for_estop, Hub};
use crate::mailbox::{Command, CommandKind};
use crate::pins::{Outputs, PIN_COUNT};
use crate::sync::Ordering;
use cogstep_motion::axis::{AxisContract, AxisError, AxisStatus, Direction, HomeConfig};
use cogstep_motion::axis::{HomeReport, LimitStatus, LimitTrip, Mode};
use cogstep_motion::axis_core::{AxisCore, CoreCommand, StepLedger};

/// One axis: a handle on a running cog. Cheap to clone; readable from any
/// thread at any time.
#[derive(Clone)]
pub struct Axis {
    pub(crate) hub: Hub,
    pub(crate) shared: Arc<CogShared>,
}

impl std::fmt::Debug for Axis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Axis")
            .field("cog", &self.shared.id)
            .field("outputs", &self.shared.outputs)
            .field("stop_pin", &self.shared.stop_pin)
            .finish()
    }
}

impl Axis {
    pub(crate) fn alive(&self) -> Result<(), AxisError> {
        if self.shared.is_shut_down() {
            Err(AxisError::Unavailable)
        } else {
            Ok(())
        }
    }

    /// The cog's number.
    pub fn cog(&self) -> usize {
        self.shared.id
    }

    /// The output pins and their variant.
    pub fn outputs(&self) -> Outputs {
        self.shared.outputs
    }

    /// The stop pin.
    pub fn stop_pin(&self) -> u8 {
        self.shared.stop_pin
    }

    /// The reference `move(sp, st)`: `speed` steps/s, `steps` signed.
    ///
    /// While the axis moves, the same direction and speed merges (the jog),
    /// another speed changes speed without stopping, and the other direction
    /// decelerates to a stop and then runs the new move. With the stop pin
    /// low the move is held until it goes high.
    ///
    /// `Ok` is a promise: the cog has taken the command and carries it out
    /// (only a stop or an emergency stop can cut it short, and then the
    /// steps not made are counted in [`Axis::dropped_steps`] and
    /// [`Axis::ledger`]). Otherwise a typed error says why, and nothing
    /// changed: bad input, [`AxisError::Busy`] (a reversal or a held move
    /// waits), [`AxisError::Jogging`], [`AxisError::TooManySteps`],
    /// [`AxisError::PositionOutOfRange`], [`AxisError::Unavailable`].
    pub fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        self.alive()?;
        AxisCore::check_move(&self.hub.core_config(self.shared.outputs), speed, steps)?;
        self.shared.call(Command {
            kind: CommandKind::Move,
            speed,
            steps: i64::from(steps),
        })
    }

    /// A jog heartbeat: run at `speed` in `direction` while heartbeats keep
    /// coming; the axis starts decelerating `jog_timeout_ms` (default
    /// 150 ms) of CT after the last one, so a caller that dies cannot leave
    /// the motor running. Refused with [`AxisError::StopPinLow`] while the
    /// stop pin is low and [`AxisError::Busy`] while a move runs.
    pub fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError> {
        self.alive()?;
        AxisCore::check_move(&self.hub.core_config(self.shared.outputs), speed, 1)?;
        self.shared.call(Command {
            kind: CommandKind::Jog,
            speed,
            steps: direction.sign(),
        })
    }

    /// Ends a jog at once (key released): controlled deceleration.
    pub fn jog_release(&self) -> Result<(), AxisError> {
        self.alive()?;
        self.shared.call(Command {
            kind: CommandKind::JogRelease,
            speed: 0,
            steps: 0,
        })
    }

    /// How long a jog runs on after its last heartbeat, in clock ticks (the
    /// hub's `jog_timeout_ms`).
    pub fn jog_timeout_ticks(&self) -> u64 {
        self.hub.core_config(self.shared.outputs).jog_timeout_ticks
    }

    /// Emergency stop of this axis: no more steps, position kept; a held
    /// move is dropped too (counted in [`Axis::dropped_steps`]).
    ///
    /// An axis running its part of a group move stops the whole group: every
    /// member is stopped at once.
    pub fn emergency_stop(&self) -> Result<(), AxisError> {
        self.alive()?;
        // The record is the group this axis ran its part of, until it takes
        // a move of its own: an e-stop reaches the other members only while
        // the group runs, and only those still in it.
        let group = lock(&self.shared.group).clone();
        let members: Vec<Arc<CogShared>> = group
            .filter(|group| group.is_live())
            .map(|group| {
                group
                    .members
                    .iter()
                    .filter_map(std::sync::Weak::upgrade)
                    // This axis is asked once, below: a second stop would
                    // find it idle and report no steps dropped.
                    .filter(|member| member.id != self.shared.id)
                    .filter(|member| {
                        lock(&member.group)
                            .as_ref()
                            .is_some_and(|current| Arc::ptr_eq(current, &group))
                    })
                    .collect()
            })
            .unwrap_or_default();
        for member in &members {
            request_estop(member);
        }
        request_estop(&self.shared);
        for member in &members {
            let _ = wait_for_estop(member);
        }
        // When this returns, the axis makes no more steps.
        wait_for_estop(&self.shared)
    }

    /// Drives this axis's stop pin.
    pub fn set_stop_pin(&self, high: bool) -> Result<(), AxisError> {
        self.alive()?;
        self.hub
            .set_input(self.shared.stop_pin, high)
            .map_err(|_| AxisError::Unavailable)
    }

    /// Sets the position counter; only while idle ([`AxisError::NotIdle`]
    /// otherwise). The step ledger starts again from here.
    pub fn set_position(&self, position: i64) -> Result<(), AxisError> {
        self.alive()?;
        self.shared.call(Command {
            kind: CommandKind::SetPosition,
            speed: 0,
            steps: position,
        })
    }

    /// Starts homing (idle only) and returns at once, like
    /// [`Axis::move_steps`]: the axis seeks the switch at `seek_speed`,
    /// latches the position at the step on which the switch changed,
    /// decelerates, backs off to `backoff_steps` before that point,
    /// approaches again at `latch_speed`, latches, stops, and sets the
    /// position so that the switch point is `set_position`. Read the
    /// outcome with [`Axis::home_outcome`] once the axis is idle.
    ///
    /// Refused with [`AxisError::NotIdle`], [`AxisError::Homing`],
    /// [`AxisError::StopPinLow`], [`AxisError::IntoLimit`] (a limit other
    /// than the switch is in the way), [`AxisError::BadSetting`] or a
    /// speed's plan error.
    pub fn home(&self, config: HomeConfig) -> Result<(), AxisError> {
        self.alive()?;
        if config.switch_pin >= PIN_COUNT {
            return Err(AxisError::BadSetting(bad_setting::SWITCH_PIN_OUT_OF_RANGE));
        }
        self.shared.call_setting(CoreCommand::Home(config))
    }

    /// How the last homing ended: `None` while homing or never homed,
    /// `Some(Err(..))` when it failed (the axis stopped under control).
    pub fn home_outcome(&self) -> Option<Result<HomeReport, AxisError>> {
        lock(&self.shared.extras).home_outcome
    }

    /// The limit and homing state, read at once.
    pub fn limit_status(&self) -> LimitStatus {
        let extras = *lock(&self.shared.extras);
        LimitStatus {
            soft_limits: extras.soft_limits,
            limit_pins: extras.limit_pins,
            trip: extras.limit_trip,
            homing: extras.homing,
            home_outcome: extras.home_outcome,
        }
    }

    /// Whether homing is under way.
    pub fn is_homing(&self) -> bool {
        lock(&self.shared.extras).homing
    }

    /// Soft limits on the position: a move that would end beyond them is
    /// refused with [`AxisError::BeyondSoftLimit`] at the call, and a jog
    /// decelerates so that it stops exactly on the limit.
    pub fn set_soft_limits(&self, min: i64, max: i64) -> Result<(), AxisError> {
        self.alive()?;
        self.shared
            .call_setting(CoreCommand::SetSoftLimits(Some((min, max))))
    }

    /// Removes the soft limits.
    pub fn clear_soft_limits(&self) -> Result<(), AxisError> {
        self.alive()?;
        self.shared.call_setting(CoreCommand::SetSoftLimits(None))
    }

    /// The soft limits `(min, max)`, if set.
    pub fn soft_limits(&self) -> Option<(i64, i64)> {
        lock(&self.shared.extras).soft_limits
    }

    /// The hard limit inputs, `(pin, active level)` for the min side (met
    /// moving in reverse) and the max side. A limit reading active in the
    /// direction of motion stops the axis (the profile's deceleration from
    /// the current velocity; an emergency stop with
    /// [`HubConfig::limit_estop`](crate::HubConfig::limit_estop)) and latches [`Axis::limit_fault`].
    pub fn set_limit_pins(
        &self,
        min: Option<(u8, bool)>,
        max: Option<(u8, bool)>,
    ) -> Result<(), AxisError> {
        self.alive()?;
        for (pin, _) in min.iter().chain(max.iter()) {
            if *pin >= PIN_COUNT {
                return Err(AxisError::BadSetting(bad_setting::LIMIT_PIN_OUT_OF_RANGE));
            }
            if *pin == self.shared.stop_pin {
                return Err(AxisError::BadSetting(bad_setting::LIMIT_PIN_IS_STOP_PIN));
            }
        }
        self.shared
            .call_setting(CoreCommand::SetLimitPins { min, max })?;
        // The hub routes the limit pins' changes to this axis from now on.
        self.shared.refresh()
    }

    /// The hard limit inputs `[min, max]`.
    pub fn limit_pins(&self) -> [Option<(u8, bool)>; 2] {
        lock(&self.shared.extras).limit_pins
    }

    /// The side whose hard limit tripped, until [`Axis::clear_limit_fault`].
    pub fn limit_fault(&self) -> Option<Direction> {
        lock(&self.shared.extras).limit_trip.map(|trip| trip.side)
    }

    /// The hard limit that tripped: where, and the steps made after it to stop.
    pub fn limit_trip(&self) -> Option<LimitTrip> {
        lock(&self.shared.extras).limit_trip
    }

    /// Forgets a tripped hard limit: moves towards it are taken again
    /// (unless the limit still reads active).
    pub fn clear_limit_fault(&self) -> Result<(), AxisError> {
        self.alive()?;
        self.shared.call_setting(CoreCommand::ClearLimitFault)
    }

    /// The physical position: the signed count of this axis's own step
    /// edges since it started (set_position and homing leave it alone).
    pub fn physical_position(&self) -> i64 {
        self.shared.physical.load(Ordering::Acquire)
    }

    /// The status words. A reader of one field loads its one atomic: with
    /// `Relaxed` where the value stands alone (speeds, counts, CTs), with
    /// `Acquire` for position, steps to go and mode, so that a caller who
    /// then reads other state sees the cog's writes before them (steps to
    /// go is stored last, with Release). Several fields together are read
    /// as one snapshot ([`Axis::status`], [`Axis::ledger`]).
    fn status_fields(&self) -> &crate::mailbox::Status {
        &self.shared.mailbox.status
    }

    /// Steps from the origin.
    pub fn position(&self) -> i64 {
        self.status_fields().position.load(Ordering::Acquire)
    }

    /// The reference's STM: the signed steps of a move command not yet
    /// taken by the cog, 0 once it has it (the move then runs, merges,
    /// queues or is held). "0" means "ready for another command".
    pub fn stm(&self) -> i32 {
        let stm = self.shared.mailbox.stm.load(Ordering::Acquire);
        i32::try_from(stm).unwrap_or(0)
    }

    /// Steps still to make (the move in progress, a queued reversal, a held
    /// move); 0 exactly when the axis is idle.
    pub fn steps_to_go(&self) -> u64 {
        self.status_fields().steps_to_go.load(Ordering::Acquire)
    }

    /// The mode bits ([`Mode::bits`] gives the reference layout).
    pub fn mode(&self) -> Mode {
        Mode(self.status_fields().mode.load(Ordering::Acquire))
    }

    /// The speed the current (or last) move asked for, steps/s (the
    /// reference's speed long; a short move's top speed may be lower: see
    /// [`Axis::top_velocity`]).
    pub fn speed(&self) -> u32 {
        self.status_fields().move_speed.load(Ordering::Relaxed)
    }

    /// Accel steps of the current (or last) move.
    pub fn accel_steps(&self) -> u32 {
        self.status_fields().accel_steps.load(Ordering::Relaxed)
    }

    /// Steps at speed of the current (or last) move, as planned.
    pub fn slew_steps(&self) -> u32 {
        self.status_fields().slew_steps.load(Ordering::Relaxed)
    }

    /// The S-curve offset, degrees.
    pub fn offset(&self) -> u32 {
        self.status_fields().offset.load(Ordering::Relaxed)
    }

    /// The top velocity of the current (or last) move, steps/s.
    pub fn top_velocity(&self) -> u32 {
        self.status_fields().top_velocity.load(Ordering::Relaxed)
    }

    /// The reference driver's "Max Velocity": written when a move starts
    /// to decelerate, with the velocity of its last step before; until then
    /// it shows the last move's (0 before any).
    pub fn max_velocity(&self) -> u32 {
        self.status_fields().max_velocity.load(Ordering::Relaxed)
    }

    /// The velocity of the last step, steps/s (0 when idle).
    pub fn velocity(&self) -> u32 {
        self.status_fields().velocity.load(Ordering::Relaxed)
    }

    /// The delay after the last step, ticks.
    pub fn delay_ticks(&self) -> u32 {
        self.status_fields().delay_ticks.load(Ordering::Relaxed)
    }

    /// Steps the last stop (stop pin or emergency, a held move included)
    /// left unmade: a later move of that many steps reaches the original
    /// target.
    pub fn dropped_steps(&self) -> u32 {
        self.status_fields().dropped_steps.load(Ordering::Relaxed)
    }

    /// The step accounts: whenever the axis is idle, `position = base +
    /// accepted − dropped + jogged` (see [`StepLedger`]).
    pub fn ledger(&self) -> StepLedger {
        // Five words of one instant: read as one snapshot.
        self.status_fields().snapshot().moves.ledger
    }

    /// CT at which the current (or last) move was taken.
    pub fn move_start_ct(&self) -> u64 {
        self.status_fields().move_start_ct.load(Ordering::Relaxed)
    }

    /// CT of the last step's rising edge.
    pub fn last_step_ct(&self) -> u64 {
        self.status_fields().last_step_ct.load(Ordering::Relaxed)
    }

    /// Ramp steps whose delay was shorter than the CORDIC work they needed.
    pub fn math_overruns(&self) -> u64 {
        self.status_fields().math_overruns.load(Ordering::Relaxed)
    }

    /// Whether the stop pin is high.
    pub fn stop_pin_high(&self) -> bool {
        self.hub.input(self.shared.stop_pin)
    }

    /// A snapshot of the axis: position, steps to go, mode and velocity
    /// are one instant's, as the cog published them together (never a mix
    /// of two steps). STM (written by the callers too) and the stop pin
    /// (an input) are read just after.
    pub fn status(&self) -> AxisStatus {
        let step = self.status_fields().snapshot().step;
        AxisStatus {
            position: step.position,
            stm: self.stm(),
            steps_to_go: step.steps_to_go,
            mode: Mode(step.mode),
            velocity_steps_per_s: step.velocity,
            stop_pin_high: self.stop_pin_high(),
        }
    }

    /// Frees the cog (the reference `stop()`): its thread is joined and its
    /// pins released. Other handles on this axis get [`AxisError::Unavailable`].
    pub fn stop(&self) {
        self.hub.release(self.shared.id);
    }
}

impl AxisContract for Axis {
    fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        Axis::move_steps(self, speed, steps)
    }

    fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError> {
        Axis::jog(self, speed, direction)
    }

    fn jog_release(&self) -> Result<(), AxisError> {
        Axis::jog_release(self)
    }

    fn set_stop_pin(&self, high: bool) -> Result<(), AxisError> {
        Axis::set_stop_pin(self, high)
    }

    fn emergency_stop(&self) -> Result<(), AxisError> {
        Axis::emergency_stop(self)
    }

    fn set_position(&self, position: i64) -> Result<(), AxisError> {
        Axis::set_position(self, position)
    }

    fn status(&self) -> Result<AxisStatus, AxisError> {
        self.alive()?;
        Ok(Axis::status(self))
    }

    fn home(&self, config: HomeConfig) -> Result<(), AxisError> {
        Axis::home(self, config)
    }

    fn set_soft_limits(&self, min: i64, max: i64) -> Result<(), AxisError> {
        Axis::set_soft_limits(self, min, max)
    }

    fn clear_soft_limits(&self) -> Result<(), AxisError> {
        Axis::clear_soft_limits(self)
    }

    fn set_limit_pins(
        &self,
        min: Option<(u8, bool)>,
        max: Option<(u8, bool)>,
    ) -> Result<(), AxisError> {
        Axis::set_limit_pins(self, min, max)
    }

    fn clear_limit_fault(&self) -> Result<(), AxisError> {
        Axis::clear_limit_fault(self)
    }

    fn limit_status(&self) -> Result<LimitStatus, AxisError> {
        self.alive()?;
        Ok(Axis::limit_status(self))
    }
}

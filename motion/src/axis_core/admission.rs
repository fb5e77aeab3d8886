//! Admission: whether a move or a jog is taken in the state the axis is
//! in, and handing what is taken to the motion (the table is in the
//! module docs; `admission_tests.rs` checks it row by row).

use super::state::{HeldMove, Jog, Owner, Run, State};
use super::{AxisCore, AxisCoreConfig, Taken};
use crate::axis::{AxisError, Direction, Mode};
use crate::profile::motion::{Accepted, CommandError};
use crate::profile::scurve;
use crate::profile::Profile;

impl AxisCore {
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

    pub(super) fn command_move(
        &mut self,
        t: u64,
        speed: u32,
        steps: i32,
    ) -> Result<Taken, AxisError> {
        Self::check_move(&self.config, speed, steps)?;
        match &self.state {
            State::Idle => {}
            State::Held(_) | State::Reserved | State::Group(_) | State::Path(_) => {
                return Err(AxisError::Busy)
            }
            State::Running(run) => match run.owner {
                Owner::Homing(_) => return Err(AxisError::Homing),
                Owner::Jog(_) if self.motion.is_moving() => return Err(AxisError::Jogging),
                Owner::Moves { held: Some(_) } => return Err(AxisError::Busy),
                // The last step's period of a jog or a move: a new move.
                Owner::Jog(_) | Owner::Moves { held: None } => {}
            },
        }
        self.check_reach(i64::from(steps))?;
        self.check_limit(Direction::of(steps))?;
        self.check_soft_move(speed, steps)?;
        if !self.stop_pin_high {
            let held = Some(HeldMove { speed, steps });
            match &mut self.state {
                State::Running(run) => run.owner = Owner::Moves { held },
                state => *state = State::Held(HeldMove { speed, steps }),
            }
            self.ledger.accepted += i64::from(steps);
            // The next move ends the alarm of an emergency stop, held or not.
            self.sticky &= !Mode::ESTOP;
            return Ok(Taken::Held);
        }
        let accepted = self.start_or_merge(t, speed, steps)?;
        self.ledger.accepted += i64::from(steps);
        Ok(Taken::Move(accepted))
    }

    /// Hands a move to the motion and schedules its first step. A move
    /// that starts belongs to moves (a jog or homing claims it after).
    pub(super) fn start_or_merge(
        &mut self,
        t: u64,
        speed: u32,
        steps: i32,
    ) -> Result<Accepted, AxisError> {
        let was_moving = self.motion.is_moving();
        let accepted = self.motion.command(speed, steps).map_err(|e| match e {
            CommandError::Plan(plan) => AxisError::Plan(plan),
            CommandError::Busy => AxisError::Busy,
            CommandError::TooManySteps => AxisError::TooManySteps,
        })?;
        let ready_ct = self.ready_ct;
        if accepted == Accepted::Started {
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
        let jog_owned = self.state.jog_owns();
        match &mut self.state {
            State::Running(run) => {
                if accepted == Accepted::Started {
                    // A new move: a jog that just ran out no longer owns the axis.
                    run.owner = Owner::Moves { held: None };
                }
                if !was_moving {
                    run.due = run.due.max(t).max(ready_ct);
                }
            }
            state => {
                *state = State::Running(Run {
                    due: t.max(ready_ct),
                    owner: Owner::Moves { held: None },
                    stopping: false,
                    queued_start: false,
                });
            }
        }
        if accepted == Accepted::Queued {
            if let Some(run) = self.state.run_mut() {
                run.queued_start = true;
            }
            let cut = self.motion.take_cut_steps();
            if !jog_owned {
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
    pub(super) fn refresh_move_info(&mut self) {
        if let Some((curve, _)) = self.motion.current() {
            self.move_info.accel_steps = curve.accel_steps();
            self.move_info.slew_steps = curve.plan().slew_steps;
            self.move_info.top_velocity = curve.top_speed();
        }
    }

    pub(super) fn command_jog(
        &mut self,
        t: u64,
        speed: u32,
        direction: Direction,
    ) -> Result<Taken, AxisError> {
        Self::check_move(&self.config, speed, 1)?;
        if self.state.homing().is_some() {
            return Err(AxisError::Homing);
        }
        if !self.stop_pin_high {
            return Err(AxisError::StopPinLow);
        }
        let moving = self.motion.is_moving();
        let busy = match &self.state {
            State::Idle => false,
            State::Held(_) | State::Reserved | State::Group(_) | State::Path(_) => true,
            State::Running(run) => match run.owner {
                Owner::Moves { held } => held.is_some() || moving,
                Owner::Jog(_) => false,
                Owner::Homing(_) => true,
            },
        };
        if busy {
            return Err(AxisError::Busy);
        }
        let deadline = t.saturating_add(self.config.jog_timeout_ticks);
        let beat = Jog {
            speed,
            direction,
            deadline,
        };
        let same = self
            .state
            .jog()
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
                self.claim_for_jog(beat);
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
        self.claim_for_jog(beat);
        Ok(Taken::Jog)
    }

    /// The running motion is the jog's, kept alive by `beat`.
    fn claim_for_jog(&mut self, beat: Jog) {
        if let Some(run) = self.state.run_mut() {
            run.owner = Owner::Jog(Some(beat));
        }
    }

    /// Ends a jog's heartbeat: controlled deceleration. A jog has no
    /// target: its unmade chunk was never promised.
    pub(super) fn release_jog(&mut self) {
        if let Some(run) = self.state.run_mut() {
            if let Owner::Jog(beat @ Some(_)) = &mut run.owner {
                *beat = None;
                run.queued_start = false;
                self.motion.stop();
            }
        }
    }

    /// Refuses what could carry the position past the range of an `i64`:
    /// `extra` steps (signed) on top of everything the axis still has to
    /// make, which may go either way.
    pub(super) fn check_reach(&self, extra: i64) -> Result<(), AxisError> {
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

    /// Anything with steps left to make (moving, queued, held), reserved
    /// for a group or homing: the axis is not idle. The last step's period
    /// is not: nothing is left to make (a new move's first step waits for
    /// it, [`AxisCore::next_event`]).
    pub(super) fn is_busy(&self) -> bool {
        match &self.state {
            State::Idle => false,
            State::Held(_) | State::Reserved | State::Group(_) | State::Path(_) => true,
            State::Running(run) => {
                self.motion.is_moving()
                    || matches!(run.owner, Owner::Homing(_) | Owner::Moves { held: Some(_) })
            }
        }
    }
}

//! Inputs, hard limits and soft limits: what the axis watches, when a
//! limit trips, and how far a move may go.

use super::group::GroupRequest;
use super::state::{Owner, State};
use super::{limit_index, pin_bit, AxisCore, Taken};
use crate::axis::{AxisError, Direction, LimitTrip, Mode};
use crate::refusal::bad_setting;

impl AxisCore {
    /// The input levels at CT `t`, bit per pin (bit n = pin n high). Give
    /// them whenever a watched pin ([`AxisCore::watched_pins`]) may have
    /// changed, and after each step edge a switch could see: a change that
    /// arrives right after a step (before the next event) is taken as the
    /// step on which it happened, so the latched position is that step's.
    pub fn set_inputs(&mut self, t: u64, levels: u64) {
        self.set_inputs_late(t, levels, 0);
    }

    /// [`AxisCore::set_inputs`] for a caller that runs the core ahead of
    /// its pins and learns of a change late: the inputs changed on the
    /// step after which the core has since made `late_steps` more (signed,
    /// as the physical position counts them; 0 is `set_inputs`). Homing
    /// and a limit trip latch the position and physical position of that
    /// step, as if the change had come on time; the stop itself starts
    /// from where the core is now, so it ends up to `late_steps` further
    /// (counted in a trip's stopping steps). A limit also trips when the
    /// axis no longer heads for it but those late steps did.
    pub fn set_inputs_late(&mut self, t: u64, levels: u64, late_steps: i64) {
        let changed = (levels ^ self.inputs) & self.watched_pins();
        self.inputs = levels;
        if changed == 0 {
            return;
        }
        if let Some(homing) = self.state.homing() {
            if changed & pin_bit(homing.config.switch_pin) != 0 {
                self.homing_switch_changed(late_steps);
            }
        }
        for side in [Direction::Reverse, Direction::Forward] {
            if let Some((pin, _)) = self.limit_pins[limit_index(side)] {
                if changed & pin_bit(pin) != 0 {
                    self.trip_if_heading(t, side, late_steps);
                }
            }
        }
    }

    /// Trips the limit of `side` if it reads active while the axis heads
    /// that way, or made its `late_steps` that way (and it has not tripped
    /// already: a bouncing limit trips once, on its first contact).
    fn trip_if_heading(&mut self, t: u64, side: Direction, late_steps: i64) {
        let tripped = self.limit_trip.is_some_and(|trip| trip.side == side);
        let heading = self.moving_towards(side) || late_steps * side.sign() > 0;
        if !tripped && self.limit_active(side) && heading {
            self.trip(t, side, late_steps);
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
            .state
            .homing()
            .map_or(0, |homing| pin_bit(homing.config.switch_pin));
        limits | switch
    }

    /// The level of an input pin as last told.
    pub fn input(&self, pin: u8) -> bool {
        self.inputs & pin_bit(pin) != 0
    }

    /// Whether the motion heads for `side` (the move in progress, a
    /// queued reversal, or this member's part of a group move).
    fn moving_towards(&self, side: Direction) -> bool {
        match &self.state {
            State::Group(follower) => follower.direction == side && follower.finish_at.is_none(),
            State::Path(part) => part.heads(side),
            State::Running(_) => {
                let current = self
                    .motion
                    .current()
                    .is_some_and(|(curve, direction)| direction == side && curve.is_running());
                current || self.motion.queued_direction() == Some(side)
            }
            State::Idle | State::Held(_) | State::Reserved => false,
        }
    }

    /// A hard limit read active moving towards it: stop (the profile's
    /// deceleration from the current velocity, or an emergency stop) and
    /// latch the fault. A group member stops its part on the line and asks
    /// the group to do the same; a held move towards the limit is dropped.
    /// `late_steps` as in [`AxisCore::set_inputs_late`].
    fn trip(&mut self, t: u64, side: Direction, late_steps: i64) {
        let in_group = matches!(self.state, State::Group(_));
        self.abort_homing(AxisError::IntoLimit(side));
        if matches!(self.state, State::Path(_)) {
            // A path stops at once, and asks for the whole path to stop.
            self.trip_path(t);
        } else if self.config.limit_estop {
            self.emergency_stop(t);
            if in_group {
                self.group_request = Some(GroupRequest::EmergencyStop);
            }
        } else if in_group {
            self.stop_group_after(t);
            if self.group_request != Some(GroupRequest::EmergencyStop) {
                self.group_request = Some(GroupRequest::StopAfter(t));
            }
        } else {
            self.stop_motion();
            let mut dropped = None;
            if let Some(run) = self.state.run_mut() {
                match &mut run.owner {
                    Owner::Jog(beat) => *beat = None,
                    Owner::Moves { held } => {
                        if held.is_some_and(|held| Direction::of(held.steps) == side) {
                            dropped = held.take();
                        }
                    }
                    Owner::Homing(_) => {}
                }
            }
            if let Some(held) = dropped {
                self.drop_held(held);
            }
            self.sticky |= Mode::STOP_LATCHED;
        }
        let stopping_steps = if matches!(self.state, State::Group(_)) {
            // The part follows the line's deceleration: play a copy out.
            let mut probe = self.clone();
            probe.run_until(u64::MAX, &mut |_| {});
            probe.physical.abs_diff(self.physical)
        } else {
            self.steps_to_go()
        };
        self.limit_trip = Some(LimitTrip {
            side,
            position: self.position - late_steps,
            physical: self.physical - late_steps,
            stopping_steps: stopping_steps + late_steps.unsigned_abs(),
        });
        self.events = self.events.wrapping_add(1);
    }

    /// What this member asks of its whole group since the last call (a
    /// hard limit tripped during a group move): the caller passes it to
    /// every member ([`AxisCore::stop_group_after`], or an emergency stop).
    pub fn take_group_request(&mut self) -> Option<GroupRequest> {
        self.group_request.take()
    }

    /// Whether [`AxisCore::take_group_request`] has something to give.
    pub fn has_group_request(&self) -> bool {
        self.group_request.is_some()
    }

    /// Refuses a move or jog towards a hard limit that tripped (until the
    /// fault is cleared) or reads active now.
    pub(super) fn check_limit(&self, side: Direction) -> Result<(), AxisError> {
        let home_switch = self.state.homing().map(|homing| homing.config.switch_pin);
        self.check_limit_with(side, home_switch)
    }

    /// [`AxisCore::check_limit`], with the home switch's pin (a limit on it
    /// is the switch while homing).
    pub(super) fn check_limit_with(
        &self,
        side: Direction,
        home_switch: Option<u8>,
    ) -> Result<(), AxisError> {
        let tripped = self.limit_trip.is_some_and(|trip| trip.side == side);
        if tripped || self.limit_active_with(side, home_switch) {
            return Err(AxisError::IntoLimit(side));
        }
        Ok(())
    }

    /// Whether the hard limit of `side` reads active (a limit on the home
    /// switch's pin is the switch while homing).
    fn limit_active(&self, side: Direction) -> bool {
        let home_switch = self.state.homing().map(|homing| homing.config.switch_pin);
        self.limit_active_with(side, home_switch)
    }

    fn limit_active_with(&self, side: Direction, home_switch: Option<u8>) -> bool {
        self.limit_pins[limit_index(side)]
            .is_some_and(|(pin, active)| home_switch != Some(pin) && self.input(pin) == active)
    }

    /// Refuses a move that would end beyond the soft limits (where the axis
    /// ends once this move and everything before it is carried out).
    pub(super) fn check_soft_move(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        if self.soft_limits.is_none() {
            return Ok(());
        }
        // Every point where the path turns or ends: the current move's end,
        // then a queued reversal's (and a held move's after them).
        let (current_end, end) = if self.stop_pin_high {
            let mut motion = self.motion.clone();
            match motion.command(speed, steps) {
                Ok(_) => (current_offset(&motion), motion.end_offset()),
                // Refused below with its own error.
                Err(_) => return Ok(()),
            }
        } else {
            // Held: it runs from where the axis stops.
            let before = self.motion.end_offset();
            self.check_soft_end(current_offset(&self.motion))?;
            (before, before + i64::from(steps))
        };
        self.check_soft_end(current_end)?;
        self.check_soft_end(end)
    }

    /// Refuses an end `end_offset` steps from the position beyond the soft
    /// limits.
    pub(super) fn check_soft_end(&self, end_offset: i64) -> Result<(), AxisError> {
        let Some((min, max)) = self.soft_limits else {
            return Ok(());
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
    pub(super) fn soft_room(&self, direction: Direction, running_this_way: bool) -> u64 {
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

    pub(super) fn set_soft_limits(
        &mut self,
        limits: Option<(i64, i64)>,
    ) -> Result<Taken, AxisError> {
        if limits.is_some_and(|(min, max)| min > max) {
            return Err(AxisError::BadSetting(bad_setting::SOFT_MIN_ABOVE_MAX));
        }
        self.soft_limits = limits;
        self.events = self.events.wrapping_add(1);
        Ok(Taken::Done)
    }

    pub(super) fn set_limit_pins(
        &mut self,
        t: u64,
        min: Option<(u8, bool)>,
        max: Option<(u8, bool)>,
    ) -> Result<Taken, AxisError> {
        if self.state.homing().is_some() {
            return Err(AxisError::Homing);
        }
        let outputs = self.config.outputs.pins();
        for (pin, _) in min.iter().chain(max.iter()) {
            if *pin >= 64 {
                return Err(AxisError::BadSetting(bad_setting::LIMIT_PIN_OUT_OF_RANGE));
            }
            if outputs.contains(pin) {
                return Err(AxisError::BadSetting(bad_setting::LIMIT_PIN_IS_OUTPUT));
            }
        }
        if min.zip(max).is_some_and(|(min, max)| min.0 == max.0) {
            return Err(AxisError::BadSetting(bad_setting::LIMITS_SHARE_A_PIN));
        }
        self.limit_pins = [min, max];
        self.events = self.events.wrapping_add(1);
        // A limit that already reads active while the axis heads for it
        // trips now, as if it had just changed.
        for side in [Direction::Reverse, Direction::Forward] {
            self.trip_if_heading(t, side, 0);
        }
        Ok(Taken::Done)
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
    ///
    /// [`CoreCommand::ClearLimitFault`]: super::CoreCommand::ClearLimitFault
    pub fn limit_trip(&self) -> Option<LimitTrip> {
        self.limit_trip
    }

    /// The side whose hard limit tripped, until cleared.
    pub fn limit_fault(&self) -> Option<Direction> {
        self.limit_trip.map(|trip| trip.side)
    }
}

/// Where the motion's current move ends, relative to the position (a
/// queued reversal turns there).
fn current_offset(motion: &crate::profile::motion::Motion) -> i64 {
    use crate::profile::Profile;
    motion.current().map_or(0, |(curve, direction)| {
        i64::from(curve.remaining_steps()) * direction.sign()
    })
}

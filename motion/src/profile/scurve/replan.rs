//! Live re-planning of a move in progress: merge, stop, emergency stop and
//! speed change ([`ReplanError`] when one is refused).

use crate::profile::PlanError;

use super::curve::SCurve;
use super::planning::plan;
use super::ramp::{slew_q32, Ramp};

/// Why a re-planning request was refused. Nothing changes when it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplanError {
    /// The steps would exceed `u32::MAX` in one move.
    #[error("the move would exceed 2^32 - 1 steps")]
    TooManySteps,
    /// The new speed cannot be planned.
    #[error(transparent)]
    Plan(#[from] PlanError),
}

impl SCurve {
    /// Adds `extra_steps` to the move (the jog merge): they run at the top
    /// speed with no deceleration in between; a move already decelerating
    /// climbs back from its current velocity. A short move whose speed the
    /// plan had lowered climbs on towards the requested speed.
    pub fn merge(&mut self, extra_steps: u32) -> Result<(), ReplanError> {
        self.settle();
        let remaining = self
            .remaining
            .checked_add(extra_steps)
            .ok_or(ReplanError::TooManySteps)?;
        // A short move ran below the requested speed; with more steps it may
        // climb towards it again (the walk still keeps room to stop).
        let requested = self.plan.requested_speed;
        self.slew_floor = u32::MAX;
        if self.top_speed() < requested {
            self.change_speed(requested)?;
        }
        self.remaining = remaining;
        self.stopping = false;
        Ok(())
    }

    /// Controlled stop: from now on decelerate from the current velocity, at
    /// once, whatever the phase. Returns the steps that will not be made (the
    /// move's total shrinks by exactly that many).
    ///
    /// No step after a stop is faster than the step before it. In P2Exact
    /// the deceleration's angles are the reference's (one ramp step nearer
    /// 180° than the mirror of the acceleration's) and its velocity is an
    /// integer `sp/2 − X`, so turning round mid-ramp could step up by one
    /// unit of `sp/2` (+4.2 % at 49 steps/s, where `sp/2` = 24) or, from
    /// the slew, onto the 180° step; such a step keeps the previous delay.
    /// A later merge or speed change lifts the rule.
    pub fn stop(&mut self) -> u32 {
        self.settle();
        self.slew_floor = u32::MAX;
        self.stopping = true;
        let needed = self.position.unwrap_or(0);
        let dropped = self.remaining.saturating_sub(needed);
        self.remaining -= dropped;
        dropped
    }

    /// Emergency stop: no more steps. Returns the steps that will not be made.
    pub fn estop(&mut self) -> u32 {
        self.settle();
        let dropped = self.remaining;
        self.remaining = 0;
        self.pending_ramp = None;
        self.slew_floor = u32::MAX;
        dropped
    }

    /// Changes the top speed without stopping. Speeding up climbs the new
    /// ramp from the current velocity; slowing down descends the current
    /// ramp until the new speed is reached, then runs on the new ramp. The
    /// acceleration stays within what either ramp allows.
    pub fn change_speed(&mut self, speed: u32) -> Result<(), ReplanError> {
        let new_plan = plan(&self.config, speed, u32::MAX)?;
        self.settle();
        self.slew_floor = u32::MAX;
        self.stopping = false;
        let new_ramp = Ramp::new(&self.config, new_plan.speed, new_plan.accel_steps);
        if slew_q32(self.config.clkfreq, new_ramp.speed) <= self.last_delay_q32 {
            self.switch_ramp(new_ramp);
        } else {
            self.pending_ramp = Some(new_ramp);
        }
        Ok(())
    }

    /// Runs on `ramp` from here, at the highest position whose velocity does
    /// not exceed the current one (whose delay is at least the current one).
    pub(super) fn switch_ramp(&mut self, ramp: Ramp) {
        let current = self.last_delay_q32;
        let mapped = self
            .position
            .map(|_| self.last_position_not_faster(ramp, current));
        self.ramp = ramp;
        self.position = mapped;
        self.pending_ramp = None;
        self.last_ramp = None;
        self.slew_q32 = slew_q32(self.config.clkfreq, ramp.speed);
        self.carry = 0;
        self.slew_floor = u32::MAX;
    }
}

//! One axis's motion: signed move commands on top of the S-curve.
//!
//! [`Motion`] is what a cog runs. It owns the move in progress (an
//! [`SCurve`]) and its direction, and decides what a new command means while
//! the axis moves:
//!
//! | axis | new command | result |
//! |---|---|---|
//! | idle | any | a new move starts |
//! | moving | same direction, same speed | **merge**: the steps join the slew, no deceleration in between (a decelerating axis climbs back) |
//! | moving | same direction, other speed | **speed change** without stopping, then the steps are added |
//! | moving | other direction | **reversal**: decelerate to a stop, then the new move starts (queued; one at a time) |
//!
//! The reference driver only merges on its last slew step and otherwise
//! finishes (and decelerates) the current move before it takes the next
//! command; cogstep takes every command at once.

use super::scurve::{RampSpan, ReplanError, SCurve, ScurveConfig, SlewSpan};
use super::{PlanError, Step};

/// The direction of a move: the sign of its steps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Positive steps (the reference's direction bit clear).
    Forward,
    /// Negative steps (the reference's direction bit set).
    Reverse,
}

impl Direction {
    /// The direction of a signed step count (`Forward` for 0).
    pub fn of(steps: i32) -> Self {
        if steps < 0 {
            Direction::Reverse
        } else {
            Direction::Forward
        }
    }

    /// The other way.
    pub fn opposite(self) -> Self {
        match self {
            Direction::Forward => Direction::Reverse,
            Direction::Reverse => Direction::Forward,
        }
    }

    /// +1 or −1.
    pub fn sign(self) -> i64 {
        match self {
            Direction::Forward => 1,
            Direction::Reverse => -1,
        }
    }
}

/// What a command did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Accepted {
    /// The axis was idle: a new move started.
    Started,
    /// Same direction and speed: the steps joined the move in progress.
    Merged,
    /// Same direction, another speed: the move changes speed without
    /// stopping and the steps were added.
    SpeedChanged,
    /// Other direction: the axis decelerates to a stop, then this move starts.
    Queued,
}

/// Why a command was refused. A refused command changes nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// The move cannot be planned.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// A reversal is already waiting for the axis to stop.
    #[error("a queued move is already waiting for the axis to stop")]
    Busy,
    /// The steps would not fit in one move.
    #[error("the move would exceed 2^32 - 1 steps")]
    TooManySteps,
}

impl From<ReplanError> for CommandError {
    fn from(error: ReplanError) -> Self {
        match error {
            ReplanError::TooManySteps => CommandError::TooManySteps,
            ReplanError::Plan(plan) => CommandError::Plan(plan),
        }
    }
}

/// A step of a [`Motion`]: the profile's step and the direction it goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionStep {
    /// The profile's view of the step.
    pub step: Step,
    /// Which way the motor turns on this step.
    pub direction: Direction,
}

/// The motion of one axis (see the module docs).
#[derive(Clone, Debug)]
pub struct Motion {
    config: ScurveConfig,
    current: Option<(SCurve, Direction, u32)>,
    queued: Option<(u32, i32)>,
    /// Signed steps of the current move that a reversal cut off, not yet
    /// collected by [`Motion::take_cut_steps`].
    cut: i64,
}

impl Motion {
    /// An idle axis whose moves use `config`.
    pub fn new(config: ScurveConfig) -> Self {
        Self {
            config,
            current: None,
            queued: None,
            cut: 0,
        }
    }

    /// The S-curve settings.
    pub fn config(&self) -> &ScurveConfig {
        &self.config
    }

    /// Takes a move command: `speed` steps/s, `steps` signed (the sign is
    /// the direction). See the module docs for what happens while moving.
    pub fn command(&mut self, speed: u32, steps: i32) -> Result<Accepted, CommandError> {
        let magnitude = steps.unsigned_abs();
        // Validate first, so that a refused command changes nothing.
        super::scurve::plan(&self.config, speed, magnitude)?;
        let direction = Direction::of(steps);
        match &mut self.current {
            Some((curve, current_direction, current_speed)) if curve.is_running() => {
                if *current_direction != direction {
                    if self.queued.is_some() {
                        return Err(CommandError::Busy);
                    }
                    self.cut += i64::from(curve.stop()) * current_direction.sign();
                    self.queued = Some((speed, steps));
                    return Ok(Accepted::Queued);
                }
                if self.queued.is_some() {
                    // Stopping for a reversal: this one joins the queue's
                    // turn only if it goes the queued way.
                    return Err(CommandError::Busy);
                }
                if *current_speed == speed {
                    curve.merge(magnitude)?;
                    Ok(Accepted::Merged)
                } else {
                    let mut changed = curve.clone();
                    changed.change_speed(speed)?;
                    changed.merge(magnitude)?;
                    *curve = changed;
                    *current_speed = speed;
                    Ok(Accepted::SpeedChanged)
                }
            }
            _ => {
                let curve = SCurve::new(self.config, speed, magnitude)?;
                self.current = Some((curve, direction, speed));
                Ok(Accepted::Started)
            }
        }
    }

    /// The next step, or `None` when the axis is idle (a queued move starts
    /// as soon as the one before it has made its last step).
    #[inline]
    pub fn next_step(&mut self) -> Option<MotionStep> {
        loop {
            if let Some((curve, direction, _)) = &mut self.current {
                if let Some(step) = curve.next() {
                    return Some(MotionStep {
                        step,
                        direction: *direction,
                    });
                }
            }
            let (speed, steps) = self.queued.take()?;
            // Validated when queued; a failure here leaves the axis idle.
            self.current = SCurve::new(self.config, speed, steps.unsigned_abs())
                .ok()
                .map(|curve| (curve, Direction::of(steps), speed));
        }
    }

    /// The slew steps the move in progress yields next in closed form, and
    /// their direction ([`SCurve::slew_span`]).
    pub fn slew_span(&self) -> Option<(SlewSpan, Direction)> {
        let (curve, direction, _) = self.current.as_ref()?;
        Some((curve.slew_span()?, *direction))
    }

    /// Makes `steps` steps of [`Motion::slew_span`] at once, exactly as
    /// many [`Motion::next_step`] calls would ([`SCurve::skip_slew`]).
    pub fn skip_slew(&mut self, steps: u32) -> Option<u32> {
        self.current.as_mut()?.0.skip_slew(steps)
    }

    /// The ramp steps computed ahead that the move in progress yields
    /// next, and their direction ([`SCurve::ramp_span`]).
    pub fn ramp_span(&self) -> Option<(RampSpan<'_>, Direction)> {
        let (curve, direction, _) = self.current.as_ref()?;
        Some((curve.ramp_span()?, *direction))
    }

    /// Makes `steps` steps of [`Motion::ramp_span`] at once, exactly as
    /// many [`Motion::next_step`] calls would ([`SCurve::skip_ramp`]).
    pub fn skip_ramp(&mut self, steps: u32) -> Option<u32> {
        self.current.as_mut()?.0.skip_ramp(steps)
    }

    /// The move's [`SCurve::run_end_index`]: when its armed run is used up.
    pub fn run_end_index(&self) -> Option<u32> {
        self.current.as_ref()?.0.run_end_index()
    }

    /// [`SCurve::run_ahead_from`] of the move in progress: its state once
    /// its armed run is used up, for another core to compute the next run
    /// from.
    pub fn run_ahead_from(&self, into: &mut Option<SCurve>) -> bool {
        self.current
            .as_ref()
            .is_some_and(|(curve, _, _)| curve.run_ahead_from(into))
    }

    /// [`SCurve::adopt_run_ahead`] on the move in progress: the next run,
    /// computed by another core from `from`, taken only when the move is
    /// `from` exactly (so its steps are the ones it would have made).
    pub fn adopt_run_ahead(&mut self, from: &SCurve, ahead: &SCurve) -> bool {
        self.current
            .as_mut()
            .is_some_and(|(curve, _, _)| curve.adopt_run_ahead(from, ahead))
    }

    /// Controlled stop: decelerate from the current velocity at once and
    /// drop a queued move. Returns the steps that will not be made, signed
    /// (the current move's in its direction, plus the queued move's): a
    /// later move of that many steps reaches the original target.
    pub fn stop(&mut self) -> i64 {
        let queued = self.queued.take().map_or(0, |(_, steps)| i64::from(steps));
        let current = self.current.as_mut().map_or(0, |(curve, direction, _)| {
            i64::from(curve.stop()) * direction.sign()
        });
        current + queued
    }

    /// Emergency stop: no more steps. Returns the steps not made, signed
    /// as for [`Motion::stop`].
    pub fn estop(&mut self) -> i64 {
        let queued = self.queued.take().map_or(0, |(_, steps)| i64::from(steps));
        let current = self.current.as_mut().map_or(0, |(curve, direction, _)| {
            i64::from(curve.estop()) * direction.sign()
        });
        current + queued
    }

    /// The signed steps of earlier moves that reversals cut off since the
    /// last call (the axis stops short of their target to turn round).
    pub fn take_cut_steps(&mut self) -> i64 {
        core::mem::take(&mut self.cut)
    }

    /// Whether a reversal waits for the axis to stop.
    pub fn has_queued(&self) -> bool {
        self.queued.is_some()
    }

    /// Whether a move (or a queued one) still has steps to make.
    pub fn is_moving(&self) -> bool {
        self.queued.is_some()
            || self
                .current
                .as_ref()
                .is_some_and(|(curve, _, _)| curve.is_running())
    }

    /// The move in progress (or the last one), with its direction.
    pub fn current(&self) -> Option<(&SCurve, Direction)> {
        self.current
            .as_ref()
            .map(|(curve, direction, _)| (curve, *direction))
    }

    /// Where the motion ends relative to where it is now, signed: the
    /// current move's remaining steps in its direction plus a queued move's.
    pub fn end_offset(&self) -> i64 {
        let current = self.current.as_ref().map_or(0, |(curve, direction, _)| {
            i64::from(super::Profile::remaining_steps(curve)) * direction.sign()
        });
        current + self.queued.map_or(0, |(_, steps)| i64::from(steps))
    }

    /// The direction of a queued reversal.
    pub fn queued_direction(&self) -> Option<Direction> {
        self.queued.map(|(_, steps)| Direction::of(steps))
    }

    /// Steps still to make in the current move, plus those of a queued one.
    pub fn steps_to_go(&self) -> u64 {
        let current = self.current.as_ref().map_or(0, |(curve, _, _)| {
            u64::from(super::Profile::remaining_steps(curve))
        });
        current
            + self
                .queued
                .map_or(0, |(_, steps)| u64::from(steps.unsigned_abs()))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use crate::profile::Phase;

    fn run(motion: &mut Motion) -> Vec<MotionStep> {
        core::iter::from_fn(|| motion.next_step()).collect()
    }

    fn net_position(steps: &[MotionStep]) -> i64 {
        steps.iter().map(|s| s.direction.sign()).sum()
    }

    #[test]
    fn a_move_runs_in_its_direction() {
        let mut motion = Motion::new(ScurveConfig::default());
        assert_eq!(motion.command(5_000, -1_234), Ok(Accepted::Started));
        let steps = run(&mut motion);
        assert_eq!(net_position(&steps), -1_234);
        assert!(!motion.is_moving());
    }

    #[test]
    fn same_direction_and_speed_merges() {
        let mut motion = Motion::new(ScurveConfig::default());
        motion.command(5_000, 2_000).unwrap();
        let mut steps: Vec<_> = (0..1_000).filter_map(|_| motion.next_step()).collect();
        assert_eq!(motion.command(5_000, 500), Ok(Accepted::Merged));
        steps.extend(run(&mut motion));
        assert_eq!(net_position(&steps), 2_500);
        let phase_changes = steps
            .windows(2)
            .filter(|w| w[0].step.phase != w[1].step.phase)
            .count();
        assert_eq!(phase_changes, 2);
    }

    #[test]
    fn other_speed_changes_speed_without_stopping() {
        let mut motion = Motion::new(ScurveConfig::default());
        motion.command(5_000, 5_000).unwrap();
        let mut steps: Vec<_> = (0..2_000).filter_map(|_| motion.next_step()).collect();
        assert_eq!(motion.command(8_000, 1_000), Ok(Accepted::SpeedChanged));
        steps.extend(run(&mut motion));
        assert_eq!(net_position(&steps), 6_000);
        assert!(steps.iter().any(|s| s.step.velocity_steps_per_s == 8_000.0));
        // Never stopped on the way: no decel step before the last ramp down.
        let first_decel = steps
            .iter()
            .position(|s| s.step.phase == Phase::Decel)
            .unwrap();
        assert!(steps[first_decel..]
            .iter()
            .all(|s| s.step.phase == Phase::Decel));
    }

    #[test]
    fn reversal_stops_then_runs_the_new_move() {
        let mut motion = Motion::new(ScurveConfig::default());
        motion.command(5_000, 5_000).unwrap();
        let mut steps: Vec<_> = (0..2_000).filter_map(|_| motion.next_step()).collect();
        assert_eq!(motion.command(5_000, -3_000), Ok(Accepted::Queued));
        assert_eq!(motion.command(5_000, -10), Err(CommandError::Busy));
        steps.extend(run(&mut motion));
        let turn = steps
            .iter()
            .position(|s| s.direction == Direction::Reverse)
            .unwrap();
        let forward = i64::try_from(turn).unwrap();
        assert_eq!(net_position(&steps), forward - 3_000);
        // It slowed down before turning: the last forward step is a decel step
        // at the ramp's floor, the first reverse one starts a new ramp.
        assert_eq!(steps[turn - 1].step.phase, Phase::Decel);
        assert_eq!(steps[turn].step.index, 0);
        assert!(steps[turn - 1].step.velocity_steps_per_s < 700.0);
    }

    #[test]
    fn a_refused_command_changes_nothing() {
        let mut motion = Motion::new(ScurveConfig::default());
        motion.command(5_000, 1_000).unwrap();
        motion.next_step();
        let before = motion.steps_to_go();
        assert!(matches!(
            motion.command(0, 10),
            Err(CommandError::Plan(PlanError::ZeroSpeed))
        ));
        assert!(matches!(
            motion.command(10, 0),
            Err(CommandError::Plan(PlanError::ZeroSteps))
        ));
        assert_eq!(motion.steps_to_go(), before);
        assert_eq!(run(&mut motion).len(), 999);
    }

    #[test]
    fn stop_and_estop_report_what_is_not_made() {
        let mut motion = Motion::new(ScurveConfig::default());
        motion.command(5_000, 10_000).unwrap();
        let made_before = (0..3_000).filter_map(|_| motion.next_step()).count();
        let dropped = motion.stop();
        let made_after = run(&mut motion).len();
        assert_eq!(made_before + made_after + dropped as usize, 10_000);
        motion
            .command(5_000, i32::try_from(dropped).unwrap())
            .unwrap();
        assert_eq!(run(&mut motion).len(), dropped as usize);

        // A queued reversal's steps are part of what a stop drops.
        motion.command(5_000, 3_000).unwrap();
        (0..1_000).for_each(|_| {
            motion.next_step();
        });
        motion.command(5_000, -700).unwrap();
        let cut = motion.take_cut_steps();
        assert!(cut > 0);
        assert_eq!(motion.stop(), -700);
        let made = run(&mut motion).len() as i64;
        assert_eq!(1_000 + made + cut, 3_000);

        motion.command(5_000, 100).unwrap();
        motion.next_step();
        assert_eq!(motion.estop(), 99);
        assert!(motion.next_step().is_none());
    }
}

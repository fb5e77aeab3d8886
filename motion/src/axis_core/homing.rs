//! Homing: seek the switch, back off, approach it slowly, set the position
//! (see the module docs' "Inputs, homing and limits").

use super::state::{Owner, State};
use super::{limit_index, AxisCore, Taken};
use crate::axis::{AxisError, Direction, HomeConfig, HomeReport};
use crate::refusal::bad_setting;

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

/// Homing in progress: the owner of the running motion while it lasts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Homing {
    pub(super) config: HomeConfig,
    phase: HomePhase,
    /// The switch changed in this phase (and the motion was told to stop).
    found: bool,
    /// (position, physical) at the switch step of the first pass.
    seek: Option<(i64, i64)>,
    /// (position, physical) at the switch step of the second pass.
    latch: Option<(i64, i64)>,
    /// The approach began with the switch still read pressed, its release
    /// not told yet (a core run ahead of its pins learns of it up to
    /// [`crate::axis_core::AxisCoreConfig::input_latency_ticks`] late):
    /// the CT by which the release must come, or homing ends
    /// `HomeSwitchStuck`.
    pub(super) release_by: Option<u64>,
}

impl AxisCore {
    /// Whether homing is under way.
    pub fn is_homing(&self) -> bool {
        self.state.homing().is_some()
    }

    /// How the last homing ended: `None` while homing or never homed.
    pub fn home_outcome(&self) -> Option<Result<HomeReport, AxisError>> {
        self.home_outcome
    }

    /// Records how homing ended.
    pub(super) fn end_homing(&mut self, outcome: Result<HomeReport, AxisError>) {
        self.home_outcome = Some(outcome);
        self.events = self.events.wrapping_add(1);
    }

    /// Ends homing with `error` (nothing to do when not homing): the
    /// motion it ran goes on as a plain move's (it is being stopped).
    pub(super) fn abort_homing(&mut self, error: AxisError) {
        if let Some(run) = self.state.run_mut() {
            if matches!(run.owner, Owner::Homing(_)) {
                run.owner = Owner::Moves { held: None };
                self.end_homing(Err(error));
            }
        }
    }

    pub(super) fn command_home(&mut self, t: u64, config: HomeConfig) -> Result<Taken, AxisError> {
        if self.state.homing().is_some() {
            return Err(AxisError::Homing);
        }
        if self.is_busy() {
            return Err(AxisError::NotIdle);
        }
        if config.switch_pin >= 64 {
            return Err(AxisError::BadSetting(bad_setting::SWITCH_PIN_OUT_OF_RANGE));
        }
        if self.config.outputs.pins().contains(&config.switch_pin) {
            return Err(AxisError::BadSetting(bad_setting::SWITCH_PIN_IS_OUTPUT));
        }
        if config.max_travel == 0 || config.max_travel > i32::MAX.unsigned_abs() {
            return Err(AxisError::BadSetting(bad_setting::MAX_TRAVEL_OUT_OF_RANGE));
        }
        if config.backoff_steps == 0 || config.backoff_steps > 1 << 30 {
            return Err(AxisError::BadSetting(bad_setting::BACKOFF_OUT_OF_RANGE));
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
            release_by: None,
        };
        // A limit on the home switch's own pin is the switch while homing;
        // any other limit the axis would run into refuses homing.
        self.check_limit_with(toward, Some(config.switch_pin))?;
        let trip_elsewhere = self.limit_trip.is_some_and(|trip| {
            trip.side == config.direction
                && self.limit_pins[limit_index(trip.side)]
                    .is_some_and(|(pin, _)| pin != config.switch_pin)
        });
        if trip_elsewhere {
            return Err(AxisError::IntoLimit(config.direction));
        }
        let steps = i64::from(config.max_travel) * toward.sign();
        self.homing_move(t, config.seek_speed, steps, homing)?;
        if self
            .limit_trip
            .is_some_and(|trip| trip.side == config.direction)
        {
            // Homing onto the switch that tripped (a trip on that side on
            // any other pin refused homing above): the fault is the switch,
            // whether homing first leaves it or seeks it.
            self.limit_trip = None;
        }
        self.home_outcome = None;
        self.events = self.events.wrapping_add(1);
        Ok(Taken::Done)
    }

    /// Runs one of homing's moves (its steps count as taken), owned by
    /// `homing`.
    fn homing_move(
        &mut self,
        t: u64,
        speed: u32,
        steps: i64,
        homing: Homing,
    ) -> Result<(), AxisError> {
        // Homing's travel stays inside the soft limits: a stage is cut to
        // the room left that way (a seek cut short ends without the switch,
        // `HomeSwitchNotFound`); no room at all is `BeyondSoftLimit`.
        let direction = if steps < 0 {
            Direction::Reverse
        } else {
            Direction::Forward
        };
        let room = self.soft_room(direction, false);
        let steps = if steps.unsigned_abs() > room {
            let room = i64::try_from(room).unwrap_or(i64::MAX);
            room * direction.sign()
        } else {
            steps
        };
        if steps == 0 {
            return Err(AxisError::BeyondSoftLimit);
        }
        let steps = i32::try_from(steps).map_err(|_| AxisError::StepsOutOfRange)?;
        Self::check_move(&self.config, speed, steps)?;
        self.check_reach(i64::from(steps))?;
        self.start_or_merge(t, speed, steps)?;
        self.ledger.accepted += i64::from(steps);
        if let Some(run) = self.state.run_mut() {
            run.owner = Owner::Homing(homing);
        }
        Ok(())
    }

    /// The home switch changed while homing, on the step `late_steps`
    /// before the core's last (see [`AxisCore::set_inputs_late`]): that
    /// step's position is latched.
    pub(super) fn homing_switch_changed(&mut self, late_steps: i64) {
        let Some(homing) = self.state.homing().copied() else {
            return;
        };
        let pressed = self.input(homing.config.switch_pin) == homing.config.active_level;
        let here = (self.position - late_steps, self.physical - late_steps);
        let mut homing = homing;
        let found = match homing.phase {
            HomePhase::Seek if pressed => {
                homing.seek = Some(here);
                true
            }
            HomePhase::Approach if pressed => {
                homing.latch = Some(here);
                true
            }
            HomePhase::Approach if homing.release_by.is_some() => {
                // The release after the backoff, told late: the approach
                // goes on to the switch.
                homing.release_by = None;
                if let Some(run) = self.state.run_mut() {
                    run.owner = Owner::Homing(homing);
                }
                false
            }
            HomePhase::Escape => !pressed,
            _ => false,
        };
        if found && !homing.found {
            homing.found = true;
            if let Some(run) = self.state.run_mut() {
                run.owner = Owner::Homing(homing);
            }
            self.stop_motion();
        }
    }

    /// A homing move ended at `t` (the axis is idle): the next stage, or
    /// the outcome.
    pub(super) fn advance_homing(&mut self, t: u64, mut homing: Homing) {
        debug_assert!(matches!(self.state, State::Idle));
        let config = homing.config;
        let sign = config.direction.sign();
        let travel = i64::from(config.max_travel);
        let backoff = i64::from(config.backoff_steps);
        let pressed = self.input(config.switch_pin) == config.active_level;
        homing.release_by = None;
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
            (HomePhase::Backoff, _) if pressed && self.config.input_latency_ticks == 0 => {
                Err(AxisError::HomeSwitchStuck)
            }
            (HomePhase::Backoff, _) => {
                if pressed {
                    // The release may not have been told yet: the approach
                    // starts, and ends homing if it is not told in time.
                    homing.release_by = Some(t.saturating_add(self.config.input_latency_ticks));
                }
                Ok((
                    HomePhase::Approach,
                    config.latch_speed,
                    sign * (backoff + travel).min(i64::from(i32::MAX)),
                ))
            }
            (HomePhase::Approach, true) => {
                let (latch_position, latch_physical) = homing.latch.unwrap_or((0, 0));
                let (seek_position, seek_physical) = homing.seek.unwrap_or((0, 0));
                let position = config
                    .set_position
                    .checked_add(self.physical - latch_physical);
                let outcome = match position {
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
                };
                self.end_homing(outcome);
                return;
            }
            (HomePhase::Seek | HomePhase::Approach, false) => Err(AxisError::HomeSwitchNotFound),
        };
        let started = next.and_then(|(phase, speed, steps)| {
            homing.phase = phase;
            homing.found = false;
            self.homing_move(t, speed, steps, homing)
        });
        if let Err(error) = started {
            self.end_homing(Err(error));
        }
    }
}

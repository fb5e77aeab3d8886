//! The schedule: when the next event is due, and running it — a jog's
//! deadline, a step's edges on the pins, the end of a move.

use super::state::{Owner, State};
use super::{AxisCore, Edge, LastStep};
use crate::axis::{AxisError, Direction, Mode};
use crate::profile::ieee_div::f64_to_u32;
use crate::profile::Phase;

impl AxisCore {
    /// The next CT at which something happens without outside input.
    pub fn next_event(&self) -> Option<u64> {
        match &self.state {
            State::Group(follower) => follower.next_event(),
            State::Path(_) => self.path_next_event(),
            State::Running(run) => Some(
                self.deadline()
                    .map_or(run.due, |deadline| deadline.min(run.due)),
            ),
            State::Idle | State::Held(_) | State::Reserved => None,
        }
    }

    /// A running motion's deadline, if it has one: a jog's heartbeat, or
    /// the switch's release an approach waits for (homing).
    pub(super) fn deadline(&self) -> Option<u64> {
        match &self.state.run()?.owner {
            Owner::Jog(jog) => jog.map(|jog| jog.deadline),
            Owner::Homing(homing) => homing.release_by,
            Owner::Moves { .. } => None,
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
        if matches!(self.state, State::Group(_)) {
            self.run_group_event(t, emit);
            return;
        }
        if matches!(self.state, State::Path(_)) {
            self.run_path_event(t, emit);
            return;
        }
        if self.state.jog().is_some_and(|jog| t >= jog.deadline) {
            // No heartbeat in time: the caller is gone or let go.
            self.release_jog();
        }
        let release_by = self.state.homing().and_then(|homing| homing.release_by);
        if release_by.is_some_and(|by| t >= by) {
            // The switch never released after the backoff.
            self.abort_homing(AxisError::HomeSwitchStuck);
            self.stop_motion();
        }
        if self.state.run().is_some_and(|run| run.due <= t) {
            self.step(emit);
        }
    }

    /// Drives the pins for one step whose rising edge is due at `t` (later
    /// if the direction pin needs its set-up time); returns the CT of the
    /// rising edge.
    pub(super) fn emit_step(
        &mut self,
        mut t: u64,
        direction: Direction,
        emit: &mut impl FnMut(Edge),
    ) -> u64 {
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
        let Some(t) = self.state.run().map(|run| run.due) else {
            return;
        };
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
        if self.state.jog_owns() {
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
        if let Some(run) = self.state.run_mut() {
            run.due = t + period;
        }
        self.ready_ct = t + period;
    }

    /// A curve's first step (a new move, or a queued reversal beginning):
    /// the move parameters describe it from now on.
    fn begin_curve(&mut self, t: u64) {
        let queued_start = self
            .state
            .run_mut()
            .is_some_and(|run| core::mem::take(&mut run.queued_start));
        if queued_start {
            self.move_info.start_ct = t;
            if let Some((curve, _)) = self.motion.current() {
                self.move_info.speed = curve.plan().requested_speed;
            }
            self.refresh_move_info();
        }
    }

    /// The move made its last step: the axis is ready at `t` (a held move
    /// waits on, homing goes on with its next stage).
    pub(super) fn finish(&mut self, t: u64) {
        let state = core::mem::replace(&mut self.state, State::Idle);
        self.ready_ct = t;
        self.step_bits = Mode::empty();
        self.last_step.velocity = 0;
        if let State::Running(run) = state {
            match run.owner {
                Owner::Moves { held: Some(held) } => self.state = State::Held(held),
                Owner::Homing(homing) => self.advance_homing(t, homing),
                Owner::Moves { held: None } | Owner::Jog(_) => {}
            }
        }
    }
}

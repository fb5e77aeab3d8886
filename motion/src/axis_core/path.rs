//! A path's part: the steps a path runner decided for this axis, made on
//! their CTs.
//!
//! A look-ahead path ([`crate::planner::PathRunner`]) decides when every
//! axis of the path steps; each axis's core then makes its own steps, in
//! the order and at the CTs given, and keeps what only it can keep: its
//! position and step accounts, its pins (the direction's set-up time and
//! the pulse), its hard limits and its soft limits.
//!
//! ```text
//! PathStart ─► Path (steps pushed with push_path_step, made at their CTs)
//!          ─► PathEnd ─► Idle once the last pushed step's pulse is over
//! ```
//!
//! While on a path the axis refuses every other motion (`Busy`, or
//! `NotIdle` to set its position or home). A step pushed towards a hard
//! limit that tripped or reads active is refused with `IntoLimit`, and a
//! limit that trips during the path stops the axis at once: its pushed
//! steps are dropped and counted, and the core asks for the whole path to
//! stop ([`AxisCore::take_group_request`] gives
//! [`GroupRequest::EmergencyStop`]). A step that would end beyond a soft
//! limit is refused with `BeyondSoftLimit` (the path's planner checks its
//! lines' ends against the soft limits before they run; this is the core's
//! second look). The stop pin does not stop a path axis by itself: the
//! path holds along the path, which its owner decides.

use super::group::GroupRequest;
use super::state::State;
use super::{AxisCore, LastStep, Taken};
use crate::axis::{AxisError, Direction, Mode};

/// How many steps a path axis holds ahead of the clock.
pub const PATH_QUEUE: usize = 32;

/// This axis's part of a path: the steps pushed and not yet made.
#[derive(Clone, Copy, Debug)]
pub(super) struct PathPart {
    /// `(CT, forward)` of each step pushed and not made, in order.
    ring: [(u64, bool); PATH_QUEUE],
    head: usize,
    len: usize,
    /// No more steps will come: the axis is idle once they are made.
    closing: bool,
    /// The CT of the last step pushed (steps come in time order).
    last_pushed: u64,
}

impl PathPart {
    fn front(&self) -> Option<(u64, bool)> {
        (self.len > 0).then(|| self.ring[self.head])
    }

    fn pop(&mut self) -> Option<(u64, bool)> {
        let front = self.front()?;
        self.head = (self.head + 1) % PATH_QUEUE;
        self.len -= 1;
        Some(front)
    }

    /// The signed sum of the steps pushed and not made.
    fn pending(&self) -> i64 {
        (0..self.len)
            .map(|i| {
                if self.ring[(self.head + i) % PATH_QUEUE].1 {
                    1
                } else {
                    -1
                }
            })
            .sum()
    }

    pub(super) fn len(&self) -> usize {
        self.len
    }

    pub(super) fn heads(&self, side: Direction) -> bool {
        (0..self.len)
            .any(|i| self.ring[(self.head + i) % PATH_QUEUE].1 == (side == Direction::Forward))
    }
}

impl AxisCore {
    /// Puts the axis on a path: idle, its stop pin high, no hard limit
    /// tripped. (From [`super::CoreCommand::PathStart`].)
    pub(super) fn start_path(&mut self, t: u64) -> Result<Taken, AxisError> {
        if self.state.homing().is_some() {
            return Err(AxisError::Homing);
        }
        if self.is_busy() || t < self.ready_ct {
            return Err(AxisError::Busy);
        }
        if !self.stop_pin_high {
            return Err(AxisError::StopPinLow);
        }
        if let Some(trip) = self.limit_trip {
            return Err(AxisError::IntoLimit(trip.side));
        }
        self.state = State::Path(PathPart {
            ring: [(0, false); PATH_QUEUE],
            head: 0,
            len: 0,
            closing: false,
            last_pushed: t,
        });
        self.last_dropped = 0;
        Ok(Taken::Done)
    }

    /// No more steps will come (from [`super::CoreCommand::PathEnd`]): the
    /// axis goes idle once the steps pushed are made. Off a path: nothing.
    pub(super) fn end_path(&mut self, t: u64) {
        if let State::Path(part) = &mut self.state {
            part.closing = true;
            if part.len == 0 {
                self.leave_path(t);
            }
        }
    }

    /// Whether the axis is on a path.
    pub fn on_path(&self) -> bool {
        matches!(self.state, State::Path(_))
    }

    /// How many more steps the path may push now.
    pub fn path_room(&self) -> usize {
        match &self.state {
            State::Path(part) if !part.closing => PATH_QUEUE - part.len,
            _ => 0,
        }
    }

    /// Pushes the path's next step for this axis: its rising edge at `ct`
    /// (no earlier than the steps pushed before), forwards or not. Refused,
    /// with nothing changed: off a path or after its end (`NotIdle`), the
    /// queue full (`Busy`), towards a hard limit that tripped or reads
    /// active (`IntoLimit`), beyond a soft limit (`BeyondSoftLimit`).
    pub fn push_path_step(&mut self, ct: u64, forward: bool) -> Result<(), AxisError> {
        let direction = if forward {
            Direction::Forward
        } else {
            Direction::Reverse
        };
        let (pending, last_pushed) = match &self.state {
            State::Path(part) if !part.closing => {
                if part.len == PATH_QUEUE {
                    return Err(AxisError::Busy);
                }
                (part.pending(), part.last_pushed)
            }
            _ => return Err(AxisError::NotIdle),
        };
        self.check_limit(direction)?;
        if let Some((min, max)) = self.soft_limits {
            let end = self.position.saturating_add(pending + direction.sign());
            if end < min || end > max {
                return Err(AxisError::BeyondSoftLimit);
            }
        }
        let ct = ct.max(last_pushed);
        if let State::Path(part) = &mut self.state {
            part.ring[(part.head + part.len) % PATH_QUEUE] = (ct, forward);
            part.len += 1;
            part.last_pushed = ct;
        }
        self.ledger.accepted += direction.sign();
        Ok(())
    }

    /// The path's next event: its next step.
    pub(super) fn path_next_event(&self) -> Option<u64> {
        match &self.state {
            State::Path(part) => part.front().map(|(ct, _)| ct),
            _ => None,
        }
    }

    /// The path's event at `t`: the step due.
    pub(super) fn run_path_event(&mut self, t: u64, emit: &mut impl FnMut(super::Edge)) {
        let State::Path(part) = &mut self.state else {
            return;
        };
        let Some((ct, forward)) = part.front().filter(|(ct, _)| *ct <= t) else {
            return;
        };
        part.pop();
        let closing_and_done = part.closing && part.len == 0;
        let direction = if forward {
            Direction::Forward
        } else {
            Direction::Reverse
        };
        let previous = self.last_step.ct;
        let rising = self.emit_step(ct, direction, emit);
        let period = rising.saturating_sub(previous).max(1);
        let clkfreq = u64::from(self.config.scurve.clkfreq);
        self.last_step = LastStep {
            // A 32-bit division where both fit (the M0+'s divider, not a
            // 64-bit library call each step).
            velocity: u32::try_from(super::div_u64(clkfreq, period)).unwrap_or(u32::MAX),
            delay_ticks: u32::try_from(period).unwrap_or(u32::MAX),
            ct: rising,
        };
        self.step_bits = Mode::SLEW
            | if forward {
                Mode::empty()
            } else {
                Mode::REVERSE
            };
        self.ready_ct = rising + u64::from(self.config.pulse_ticks);
        if closing_and_done {
            self.leave_path(self.last_fall_ct);
        }
    }

    /// The path's steps not made, dropped (an emergency stop, a limit).
    pub(super) fn drop_path(&mut self) {
        if let State::Path(part) = &mut self.state {
            let pending = part.pending();
            let unmade = part.len as u32;
            part.head = 0;
            part.len = 0;
            part.closing = true;
            self.drop_steps(pending);
            self.last_dropped = unmade;
        }
    }

    /// A hard limit tripped on the path: stop at once, ask for the path to stop.
    pub(super) fn trip_path(&mut self, t: u64) {
        self.drop_path();
        self.group_request = Some(GroupRequest::EmergencyStop);
        self.leave_path(t);
        self.sticky |= Mode::STOP_LATCHED;
    }

    fn leave_path(&mut self, t: u64) {
        self.state = State::Idle;
        self.ready_ct = t.max(self.last_fall_ct);
        self.step_bits = Mode::empty();
        self.last_step.velocity = 0;
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use crate::axis_core::{AxisCoreConfig, CoreCommand, Edge, Outputs};

    fn core() -> AxisCore {
        let mut core = AxisCore::new(AxisCoreConfig::new(Outputs::StepDir { step: 1, dir: 2 }), 0);
        core.set_stop_pin(0, true);
        core
    }

    fn rising(core: &mut AxisCore, limit: u64) -> Vec<u64> {
        let mut edges = Vec::new();
        core.run_until(limit, &mut |edge: Edge| {
            if edge.pin == 1 && edge.level {
                edges.push(edge.ct);
            }
        });
        edges
    }

    #[test]
    fn a_path_axis_makes_the_steps_pushed_on_their_cts_and_nothing_else() {
        let mut core = core();
        core.command(0, CoreCommand::PathStart).unwrap();
        for ct in [1_000, 2_000, 2_500] {
            core.push_path_step(ct, true).unwrap();
        }
        assert_eq!(core.steps_to_go(), 3);
        assert!(core.is_moving());
        // Every other motion is refused while the path owns the axis.
        assert_eq!(
            core.command(
                0,
                CoreCommand::Move {
                    speed: 1_000,
                    steps: 5
                }
            ),
            Err(AxisError::Busy)
        );
        assert_eq!(
            core.command(0, CoreCommand::SetPosition(9)),
            Err(AxisError::NotIdle)
        );
        assert_eq!(
            core.command(0, CoreCommand::GroupReserve { steps: 1 }),
            Err(AxisError::Busy)
        );
        assert_eq!(rising(&mut core, 2_000), [1_000, 2_000]);
        // A reversal: the direction pin settles first, the step waits for it.
        core.push_path_step(2_600, false).unwrap();
        core.command(2_000, CoreCommand::PathEnd).unwrap();
        assert_eq!(core.push_path_step(3_000, true), Err(AxisError::NotIdle));
        let setup = u64::from(core.config().dir_setup_ticks);
        let pulse = u64::from(core.config().pulse_ticks);
        let last = rising(&mut core, u64::MAX);
        assert_eq!(last[0], 2_500);
        assert_eq!(last[1], (2_600u64).max(2_500 + pulse + setup));
        assert_eq!(core.position(), 2);
        assert!(!core.on_path());
        let ledger = core.ledger();
        assert_eq!((ledger.accepted, ledger.dropped), (2, 0));
    }

    #[test]
    fn an_emergency_stop_drops_the_steps_pushed_and_counts_them() {
        let mut core = core();
        core.command(0, CoreCommand::PathStart).unwrap();
        for i in 1..=10 {
            core.push_path_step(i * 1_000, false).unwrap();
        }
        assert_eq!(rising(&mut core, 3_000).len(), 3);
        core.command(3_100, CoreCommand::EmergencyStop).unwrap();
        assert!(!core.on_path());
        assert_eq!(core.position(), -3);
        assert_eq!(core.dropped_steps(), 7);
        let ledger = core.ledger();
        assert_eq!(
            ledger.base + ledger.accepted - ledger.dropped,
            core.position()
        );
    }

    #[test]
    fn limits_hold_on_a_path() {
        let mut core = core();
        core.command(0, CoreCommand::SetSoftLimits(Some((-2, 2))))
            .unwrap();
        core.command(
            0,
            CoreCommand::SetLimitPins {
                min: Some((10, true)),
                max: None,
            },
        )
        .unwrap();
        core.command(0, CoreCommand::PathStart).unwrap();
        core.push_path_step(100, true).unwrap();
        core.push_path_step(200, true).unwrap();
        assert_eq!(
            core.push_path_step(300, true),
            Err(AxisError::BeyondSoftLimit)
        );
        assert_eq!(rising(&mut core, u64::MAX), [100, 200]);
        for i in 0..3 {
            core.push_path_step(300 + i * 100, false).unwrap();
        }
        rising(&mut core, 300);
        // The min switch closes while the path heads for it: stop at once.
        core.set_inputs(350, 1 << 10);
        assert!(!core.on_path());
        assert_eq!(core.position(), 1);
        assert_eq!(core.take_group_request(), Some(GroupRequest::EmergencyStop));
        assert!(core.limit_trip().is_some());
        assert_eq!(
            core.command(10_000, CoreCommand::PathStart),
            Err(AxisError::IntoLimit(Direction::Reverse))
        );
    }
}

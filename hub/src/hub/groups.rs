//! Coordinated moves: every axis of a group reserved, then started on one
//! CT, and stopped together.

use std::sync::Arc;

use super::{lock, Hub};
use crate::axis::Axis;
use crate::clock::ClockMode;
use crate::cog::GroupShared;
use crate::mailbox::{Command, CommandKind};
use crate::sync::AtomicU64;
use cogstep_motion::axis::AxisError;
use cogstep_motion::axis_core::AxisCore;

impl Hub {
    /// A coordinated move: every axis's first edge on the same CT, one
    /// straight line in step space. Each `(axis, steps)` names an axis of
    /// this hub and its signed steps (0 allowed); the lead is the axis
    /// with the most steps and runs the S-curve of its move at `speed`;
    /// every other axis makes its steps along the line, so that at every
    /// edge its position is within one step of `steps · s(t)`, `s(t)` the
    /// lead's progress (see [`cogstep_motion::axis_core`]'s "Coordinated moves").
    ///
    /// All or nothing: every axis is first reserved (each must be idle,
    /// its stop pin high); only when all are does the move start on all of
    /// them at one CT. Otherwise nothing moves and the first refusal is the
    /// error: [`AxisError::DuplicateAxis`], [`AxisError::Busy`],
    /// [`AxisError::StopPinLow`], [`AxisError::PositionOutOfRange`],
    /// [`AxisError::StepsOutOfRange`], a speed the lead cannot run
    /// ([`AxisError::Plan`], [`AxisError::PulseTooLong`]),
    /// [`AxisError::Unavailable`], or [`AxisError::Unsupported`] for an
    /// axis of another hub.
    ///
    /// A stop pin low on any member (or an emergency stop of any member)
    /// stops them all along the line; each axis's steps not made are in
    /// [`Axis::dropped_steps`] and its [`Axis::ledger`], and a group move of
    /// those completes the line.
    pub fn move_together(&self, moves: &[(&Axis, i32)], speed: u32) -> Result<(), AxisError> {
        for (i, (axis, steps)) in moves.iter().enumerate() {
            if !Arc::ptr_eq(&axis.hub.inner, &self.inner) {
                return Err(AxisError::Unsupported("an axis of another hub"));
            }
            axis.alive()?;
            if *steps == i32::MIN {
                return Err(AxisError::StepsOutOfRange);
            }
            if moves[..i]
                .iter()
                .any(|(other, _)| other.cog() == axis.cog())
            {
                return Err(AxisError::DuplicateAxis);
            }
        }
        let Some(lead_steps) = moves.iter().map(|(_, steps)| steps.unsigned_abs()).max() else {
            return Ok(());
        };
        if lead_steps > 0 {
            let lead = i32::try_from(lead_steps).map_err(|_| AxisError::StepsOutOfRange)?;
            let outputs = moves[0].0.outputs();
            AxisCore::check_move(&self.core_config(outputs), speed, lead)?;
        }
        let _admission = lock(&self.inner.grouping);
        let mut reserved: Vec<&Axis> = Vec::with_capacity(moves.len());
        for (axis, steps) in moves {
            let reply = axis.shared.call(Command {
                kind: CommandKind::GroupReserve,
                speed,
                steps: i64::from(*steps),
            });
            if let Err(error) = reply {
                for axis in reserved {
                    // Giving a reservation back cannot be refused; a cog
                    // that is gone holds nothing.
                    let _ = axis.shared.call(Command {
                        kind: CommandKind::GroupCancel,
                        speed: 0,
                        steps: 0,
                    });
                }
                return Err(error);
            }
            reserved.push(axis);
        }
        // The direction pins settle before the first edge (every member is
        // idle since at least now, its last pulse over).
        let setup = u64::from(self.inner.config.dir_setup_ticks);
        let start_ct = match self.inner.config.clock {
            ClockMode::Virtual => self.now() + setup,
            // The start lands a moment ahead, so each cog has it in time.
            ClockMode::Real => self.now() + setup + u64::from(self.inner.config.clkfreq) / 500,
        };
        let group = Arc::new(GroupShared {
            speed,
            lead_steps,
            start_ct,
            stop_after: AtomicU64::new(u64::MAX),
            members: moves
                .iter()
                .map(|(axis, _)| Arc::downgrade(&axis.shared))
                .collect(),
            progress: moves.iter().map(|_| AtomicU64::new(start_ct)).collect(),
        });
        for (axis, _) in moves {
            *lock(&axis.shared.group) = Some(Arc::clone(&group));
        }
        // A stop pin that went low since its member was reserved: the group
        // does not start. (A stop pin going low from here on finds the group
        // in its member's record and stops the whole line: set_input writes
        // the pin before it reads the record, this reads the pins after it
        // wrote the records, both under the records' locks.)
        let low = moves
            .iter()
            .any(|(axis, _)| !self.inner.shared.pins.input(axis.shared.stop_pin));
        if low {
            for (axis, _) in moves {
                let mut record = lock(&axis.shared.group);
                if record
                    .as_ref()
                    .is_some_and(|current| Arc::ptr_eq(current, &group))
                {
                    *record = None;
                }
                drop(record);
                let _ = axis.shared.call(Command {
                    kind: CommandKind::GroupCancel,
                    speed: 0,
                    steps: 0,
                });
            }
            return Err(AxisError::StopPinLow);
        }
        let mut outcome = Ok(());
        for (axis, steps) in moves {
            // Reserved: only a cog that died since can refuse.
            let reply = axis.shared.call(Command {
                kind: CommandKind::GroupStart,
                speed,
                steps: i64::from(*steps),
            });
            outcome = outcome.and(reply);
        }
        outcome
    }

    /// The CT a group stop asked for now acts after: now with the virtual
    /// clock (every cog stands there), a moment ahead with the real one.
    pub(super) fn group_stop_ct(&self) -> u64 {
        match self.inner.config.clock {
            ClockMode::Virtual => self.now(),
            ClockMode::Real => {
                self.now()
                    + u64::from(self.inner.config.clkfreq) / 1_000 * GroupShared::REAL_STOP_LEAD_MS
            }
        }
    }
}

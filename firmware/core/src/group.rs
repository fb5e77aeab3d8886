//! Coordinated moves (`G`) on the firmware: every member's first step on
//! one CT, one straight line in step space, stopped together.
//!
//! Each member's core runs its own copy of the lead's S-curve (the motion
//! crate's group follower, the same the host's cogs run); what the hub
//! does across its cog threads the firmware does across its axes, all in
//! one place:
//!
//! - **Start** ([`Firmware::start_group`], the `Board`'s `move_together`):
//!   inside one critical section every member is reserved
//!   (`CoreCommand::GroupReserve`: idle, its last pulse over, its stop pin
//!   high, within its limits); one refusal gives every reservation back
//!   and is the reply, and nothing moves. Then every member starts its
//!   part on the same CT: the CT a move commanded now would take its
//!   first step (the set-up time ahead of the clock, the direction edge at
//!   now). Each member records the group (`GroupRecord`) until it takes a
//!   move of its own.
//! - **Stop**: a member's stop pin low (`S`, `!`, or the board's stop
//!   input) or its hard limit tripping stops the whole line. The step
//!   interrupt looks at the members of a group that still runs before it
//!   runs any axis ([`Firmware::pass_group_stops`]), and tells every
//!   member the same CT (`AxisCore::stop_group_after`): every copy of the
//!   curve decelerates from the same lead edge, so all stay on the line.
//!   For a stop pin that CT is the one a command acts at (now, the set-up
//!   time ahead), for a limit the CT of the trip. The firmware looks
//!   after every protocol command and realtime byte, before the reply
//!   (`Board::after_command`: `S`, `!` and `K` reach the whole line at
//!   once), and in the step interrupt before any axis runs (the board's
//!   stop input, a switch). No member has run past that CT: a command
//!   brings an axis only up to its own CT, and the interrupt passes the
//!   stop on before it runs any axis. A hard limit that e-stops
//!   (`limit_estop`) e-stops every member.
//! - **Emergency stop**: `E` stops every axis, members included. An
//!   emergency stop of one member (`AxisContract::emergency_stop` of its
//!   axis, or a hard limit with `limit_estop`) stops every part still
//!   running at the next step interrupt, as the hub's does.
//!
//! The steps a member did not make are in its ledger and its dropped
//! steps; a `G` of them completes the line, as on the hub.

use critical_section::CriticalSection;
use driver::axis::AxisError;
use driver::axis_core::{AxisCore, CoreCommand, GroupLead, GroupMove, GroupRequest};

use crate::axis::{AxisRunner, GroupRecord, Output};
use crate::scheduler::{Firmware, Hardware};

impl<H: Hardware> Firmware<H> {
    /// A coordinated move of axes 0 to `steps.len() − 1` at `speed` (the
    /// lead's): all or nothing (see the module docs). Refused with
    /// nothing changed: `StepsOutOfRange` (a count of `i32::MIN`, or more
    /// counts than the board has axes), the lead's speed
    /// (`AxisCore::check_move`: `Plan`, `PulseTooLong`), then the first
    /// member's refusal (`Busy`, `StopPinLow`, limits).
    pub fn start_group(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
        if steps.len() > self.axis_count || steps.contains(&i32::MIN) {
            return Err(AxisError::StepsOutOfRange);
        }
        let Some(lead_steps) = steps.iter().map(|steps| steps.unsigned_abs()).max() else {
            return Ok(());
        };
        // The lead's curve, planned once for every member and outside the
        // critical section (a few hundred microseconds on an M0+; once a
        // member, inside it, they held the edge feeder back for a
        // millisecond with four).
        let planned = if lead_steps > 0 {
            let lead = i32::try_from(lead_steps).map_err(|_| AxisError::StepsOutOfRange)?;
            let config = self.axes[0].config();
            AxisCore::check_move(&config, speed, lead)?;
            Some(GroupLead::plan(&config, speed, lead_steps)?)
        } else {
            None
        };
        let members = (1u8 << steps.len()) - 1;
        let result = critical_section::with(|cs| {
            let now = self.hardware.now_ticks();
            for (index, &part) in steps.iter().enumerate() {
                let reserve = CoreCommand::GroupReserve { steps: part };
                if let Err(error) = self.on_axis(cs, index, now, reserve) {
                    for before in 0..index {
                        // Giving a reservation back cannot be refused.
                        let _ = self.on_axis(cs, before, now, CoreCommand::GroupCancel);
                    }
                    return Err(error);
                }
            }
            // Every member's first step where a move taken now would take
            // it: the core's CT (the set-up time ahead of the clock).
            let start_ct = now.saturating_add(self.axes[0].runner(cs).lookahead());
            let mut groups = self.groups.borrow(cs).get();
            let record = GroupRecord {
                id: groups.next_id,
                members,
            };
            groups.next_id = groups.next_id.wrapping_add(1);
            groups.live = true;
            self.groups.borrow(cs).set(groups);
            let mut outcome = Ok(());
            for (index, &part) in steps.iter().enumerate() {
                // A request left from an earlier group is not this one's.
                let _ = self.axes[index].runner(cs).take_group_request();
                let group = GroupMove {
                    speed,
                    lead_steps,
                    steps: part,
                    start_ct,
                };
                // Reserved and checked: the core takes it.
                let start = CoreCommand::GroupStart(group);
                let started = self.on_axis_with(cs, index, now, start, planned.as_ref());
                outcome = outcome.and(started);
                self.axes[index].runner(cs).set_group(Some(record));
            }
            outcome
        });
        self.hardware.request_step_interrupt();
        result
    }

    /// Before the step interrupt runs axis `index` (`logic`, borrowed),
    /// a member of a running group: its lead edge is taken from the
    /// member before it, which has just made the same edge, when it can be
    /// (see `AxisCore::take_lead_edge_from`), so that the members compute
    /// the lead's curve once between them, not once each.
    #[inline]
    pub(crate) fn share_lead(&self, cs: CriticalSection<'_>, index: usize, logic: &mut AxisRunner) {
        let Some(record) = logic.group() else {
            return;
        };
        if !logic.in_group() {
            return;
        }
        for earlier in self.axes[..index].iter().rev() {
            let other = earlier.logic.borrow_ref(cs);
            if other.group() == Some(record) && other.in_group() {
                logic.take_lead_edge_from(&other);
                return;
            }
        }
    }

    /// `command` to axis `index` at CT `now`, its pins driven at once.
    fn on_axis(
        &self,
        cs: CriticalSection<'_>,
        index: usize,
        now: u64,
        command: CoreCommand,
    ) -> Result<(), AxisError> {
        self.on_axis_with(cs, index, now, command, None)
    }

    /// [`Firmware::on_axis`], a group's start with its lead's curve
    /// planned once (`AxisRunner::command_with`).
    fn on_axis_with(
        &self,
        cs: CriticalSection<'_>,
        index: usize,
        now: u64,
        command: CoreCommand,
        lead: Option<&GroupLead>,
    ) -> Result<(), AxisError> {
        let hardware = &self.hardware;
        let mut drive =
            |output: Output, level: bool, ct: u64| hardware.drive_pin(index, output, level, ct);
        self.axes[index]
            .runner(cs)
            .command_with(now, command, lead, &mut drive)
    }

    /// Passes a member's stop on to its whole group (see the module docs)
    /// at CT `now`: after each protocol command (`Board::after_command`),
    /// and in the step interrupt before any axis runs (`in_interrupt`:
    /// the fast path's train is back already; elsewhere a member's is
    /// taken back before it changes). Costs one look at a flag while no
    /// group move runs, and one look at each axis while every member runs
    /// its part and none has anything to pass on.
    pub(crate) fn pass_group_stops(&self, cs: CriticalSection<'_>, now: u64, in_interrupt: bool) {
        let mut groups = self.groups.borrow(cs).get();
        if !groups.live {
            return;
        }
        let axes = self.axes();
        // The usual case, one look at each axis: every axis with a record
        // runs its part (so every group is live) and none asks anything.
        // (A member in its part has no train lent to a fast path: a
        // group part's steps go the general way.)
        let (mut recorded, mut quiet) = (false, true);
        for axis in axes {
            let runner = axis.logic.borrow_ref(cs);
            if runner.group().is_some() {
                recorded = true;
                quiet &= runner.in_group() && runner.stop_pin_high() && !runner.has_group_request();
            }
        }
        if recorded && quiet {
            return;
        }
        let mut live = false;
        for axis in axes {
            let Some(record) = axis.logic.borrow_ref(cs).group() else {
                continue;
            };
            let members = || {
                axes.iter().filter(move |member| {
                    record.members & (1 << member.index) != 0
                        && member.logic.borrow_ref(cs).group() == Some(record)
                })
            };
            if !members().any(|member| member.logic.borrow_ref(cs).in_group()) {
                // Every part is done: the group is over, and what a member
                // asked of it (an e-stop that ended the last part) with it.
                let mut runner = axis.logic.borrow_ref_mut(cs);
                let _ = runner.take_group_request();
                runner.set_group(None);
                continue;
            }
            live = true;
            let runner = |index: usize| {
                let member = &self.axes[index];
                if in_interrupt {
                    member.logic.borrow_ref_mut(cs)
                } else {
                    member.runner(cs)
                }
            };
            let (request, pin_low, core_now) = {
                let mut runner = runner(axis.index);
                let core_now = now.saturating_add(runner.lookahead());
                (
                    runner.take_group_request(),
                    !runner.stop_pin_high(),
                    core_now,
                )
            };
            let mut stop_after = pin_low.then_some(core_now);
            match request {
                Some(GroupRequest::StopAfter(ct)) => {
                    stop_after = Some(stop_after.map_or(ct, |pin| pin.min(ct)));
                }
                Some(GroupRequest::EmergencyStop) => {
                    // The parts still running: a second stop of an axis
                    // already stopped would report no steps dropped.
                    let running = members().filter(|member| {
                        member.index != axis.index && member.logic.borrow_ref(cs).in_group()
                    });
                    for member in running {
                        let hardware = &self.hardware;
                        let index = member.index;
                        let mut drive = |output: Output, level: bool, ct: u64| {
                            hardware.drive_pin(index, output, level, ct)
                        };
                        let mut runner = runner(member.index);
                        // An emergency stop is never refused.
                        let _ = runner.command(now, CoreCommand::EmergencyStop, &mut drive);
                    }
                }
                None => {}
            }
            if let Some(ct) = stop_after {
                for member in members() {
                    runner(member.index).stop_group_after(ct);
                }
            }
        }
        if !live {
            groups.live = false;
            self.groups.borrow(cs).set(groups);
        }
    }
}

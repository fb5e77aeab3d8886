//! Coordinated moves: a member's copy of the lead's curve, where it
//! stands on the line, and what it asks of the other members.

use super::state::State;
use super::{
    div_u64, period_ticks, scale, AxisCore, AxisCoreConfig, Edge, GroupMove, LastStep, MoveInfo,
    Taken,
};
use crate::axis::{AxisError, Direction, Mode};
use crate::profile::ieee_div::div_trunc;
#[cfg(any(test, target_arch = "x86_64", target_arch = "aarch64"))]
use crate::profile::ieee_div::f64_to_u32;
use crate::profile::scurve::{SCurve, ScurveConfig};
use crate::profile::Phase;

/// What a group member asks of every member of its group (the caller
/// passes it on: the core knows only its own axis).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroupRequest {
    /// Stop the line: every member decelerates from the first lead edge
    /// after this CT ([`AxisCore::stop_group_after`]).
    StopAfter(u64),
    /// Stop every member at once (an emergency stop: a hard limit with
    /// `limit_estop`).
    EmergencyStop,
}

/// A member's part of a coordinated move: its copy of the lead's curve and
/// where it stands on the line (see the module docs).
#[derive(Clone, Debug)]
pub(super) struct Follower {
    /// The lead's S-curve (`lead_steps` at the group's speed).
    lead: SCurve,
    lead_steps: u32,
    /// This member's steps (magnitude) and direction.
    pub(super) steps: u32,
    pub(super) direction: Direction,
    /// Steps made so far.
    pub(super) made: u32,
    /// The lead's fractional edge of step `made` ([`Follower::lead_position_of`]),
    /// as whole part and remainder over `n − 1`, kept as steps are made,
    /// and what each step adds to it: no division a step.
    next_whole: u64,
    next_remainder: u64,
    stride_whole: u64,
    stride_remainder: u64,
    /// Lead edges passed so far (`k`), the CT of the last one, and the CT
    /// its period ends (the next lead edge while the lead runs).
    lead_index: u32,
    lead_ct: u64,
    lead_period_end: u64,
    /// The lead has edges after `lead_index`.
    lead_running: bool,
    lead_velocity: f64,
    lead_delay: u32,
    lead_phase: Phase,
    /// The member's next step, once the lead edges it lies between are known.
    next_step: Option<u64>,
    /// The last scaled step ([`Follower::scaled_step`]): the lead's
    /// velocity (bits) and delay it was scaled from, and the result.
    scaled: Option<(u64, u32, (u32, u32))>,
    /// Decelerate from the first lead edge after this CT.
    stop_after: Option<u64>,
    stopped: bool,
    /// The member is done (every step made, or the line ended short): the
    /// axis is ready at this CT.
    pub(super) finish_at: Option<u64>,
}

impl Follower {
    pub(super) fn next_event(&self) -> Option<u64> {
        if let Some(finish) = self.finish_at {
            return Some(finish);
        }
        let lead = self.lead_running.then_some(self.lead_period_end);
        match (lead, self.next_step) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// The CT of the member's next step when it is its next event and
    /// nothing decided at that event can take it away or move it (for
    /// `AxisCore::next_plain_step`): a step already placed between two
    /// lead edges, or the step on the next lead edge when that edge is sure
    /// to come and no stop begins at it. `None` says nothing.
    #[inline(never)]
    pub(super) fn plain_step_due(&self) -> Option<u64> {
        if self.finish_at.is_some() {
            return None;
        }
        if let Some(due) = self.next_step {
            // Placed: made at `due`, whatever the lead's edge at `due` does.
            return (!self.lead_running || due <= self.lead_period_end).then_some(due);
        }
        let t = self.lead_period_end;
        let stop_begins = !self.stopped && self.stop_after.is_some_and(|after| t > after);
        (self.lead_running && !stop_begins && self.step_on_next_lead_edge()).then_some(t)
    }

    /// Whether the member's next step (none placed yet) lies on the lead's
    /// next edge.
    fn step_on_next_lead_edge(&self) -> bool {
        self.made < self.steps
            && self.next_whole == u64::from(self.lead_index) + 1
            && self.next_remainder == 0
    }

    /// Whether the member's next event drives no edge before its own CT:
    /// not its end, and no direction edge ahead of a step (see
    /// `AxisCore::next_event_on_time`). `turns`: a step now would change
    /// the direction pin.
    #[inline(never)]
    pub(super) fn event_on_time(&self, turns: bool) -> bool {
        if self.finish_at.is_some() {
            return false;
        }
        let steps_at_event = self.next_step.is_some() || self.step_on_next_lead_edge();
        !(steps_at_event && turns)
    }

    /// The member's velocity and delay at a step, scaled from the lead's
    /// last edge's ([`member_velocity`], `scale`); kept while the lead's
    /// stay the same (at speed: every step), so computed once a change.
    fn scaled_step(&mut self) -> (u32, u32) {
        let key = (self.lead_velocity.to_bits(), self.lead_delay);
        if let Some((velocity_bits, delay, scaled)) = self.scaled {
            if (velocity_bits, delay) == key {
                return scaled;
            }
        }
        let scaled = (
            member_velocity(self.lead_velocity, self.steps, self.lead_steps),
            scale(self.lead_delay, self.lead_steps, self.steps),
        );
        self.scaled = Some((key.0, key.1, scaled));
        scaled
    }

    /// The lead's next edge, at `t`: the copy of the curve moves on one step
    /// (first decelerating, if a stop asked for it before `t`).
    fn lead_edge(&mut self, t: u64, period: impl Fn(u32) -> u64) {
        if !self.stopped && self.stop_after.is_some_and(|after| t > after) {
            self.stopped = true;
            if self.lead_index == 0 {
                // Stopped before the line's first edge: nothing moves.
                self.lead_running = false;
                return;
            }
            self.lead.stop();
        }
        match self.lead.next() {
            Some(step) => {
                self.lead_index += 1;
                self.lead_ct = t;
                self.lead_delay = step.delay_ticks;
                self.lead_velocity = step.velocity_steps_per_s;
                self.lead_phase = step.phase;
                self.lead_period_end = t + period(step.delay_ticks);
                self.lead_running = self.lead.is_running();
            }
            None => self.lead_running = false,
        }
    }

    /// The lead's fractional edge of the member's step `j` (0-based):
    /// `1 + j·(L − 1)/(n − 1)` as whole part and remainder over `n − 1`.
    /// (Computed once a part; the steps then keep it, checked against
    /// this in debug builds.)
    fn lead_position_of(steps: u32, lead_steps: u32, j: u32) -> (u64, u64, u64) {
        if steps <= 1 {
            return (1, 0, 1);
        }
        let over = u64::from(steps - 1);
        let numerator = u64::from(j) * u64::from(lead_steps - 1);
        (1 + numerator / over, numerator % over, over)
    }

    /// `n − 1`, what the remainders are over.
    fn over(&self) -> u64 {
        u64::from(self.steps.max(2) - 1)
    }

    /// One more step made: its successor's lead position, by an addition.
    fn count_step(&mut self) {
        self.made += 1;
        self.next_whole += self.stride_whole;
        self.next_remainder += self.stride_remainder;
        if self.next_remainder >= self.over() {
            self.next_remainder -= self.over();
            self.next_whole += 1;
        }
        debug_assert_eq!(
            (self.next_whole, self.next_remainder, self.over()),
            Self::lead_position_of(self.steps, self.lead_steps, self.made)
        );
    }

    /// Schedules the next step if the lead edges around it are known, or
    /// ends the member when the line ended short of it. Returns the steps
    /// the member will not make, when it ends short.
    fn settle(&mut self) -> Option<u32> {
        if self.finish_at.is_some() || self.next_step.is_some() {
            return None;
        }
        if self.made == self.steps {
            self.finish_at = Some(self.lead_period_end.max(self.lead_ct));
            return None;
        }
        let (whole, remainder, over) = (self.next_whole, self.next_remainder, self.over());
        let index = u64::from(self.lead_index);
        if whole < index || (whole == index && remainder == 0) {
            self.next_step = Some(self.lead_ct);
        } else if whole == index && self.lead_running {
            let span = self.lead_period_end - self.lead_ct;
            let offset = match span.checked_mul(remainder) {
                Some(product) => div_u64(product, over),
                None => (u128::from(span) * u128::from(remainder) / u128::from(over)) as u64,
            };
            self.next_step = Some(self.lead_ct + offset);
        } else if !self.lead_running && whole >= index {
            // The lead made its last edge before this step: the line ends here.
            self.finish_at = Some(self.lead_period_end.max(self.lead_ct));
            return Some(self.steps - self.made);
        }
        None
    }
}

/// A group move's lead curve, planned once for all its members
/// ([`AxisCore::command_with_lead`]): on a microcontroller planning a
/// curve takes a few hundred microseconds, once a member.
#[derive(Clone, Debug)]
pub struct GroupLead {
    speed: u32,
    lead_steps: u32,
    curve: SCurve,
}

impl GroupLead {
    /// The lead's curve of a group move at `speed` whose longest part is
    /// `lead_steps`, planned with `config`'s S-curve settings; refused as
    /// the members would refuse it (`Plan`).
    // One copy of the planning in the firmware's flash.
    #[inline(never)]
    pub fn plan(config: &AxisCoreConfig, speed: u32, lead_steps: u32) -> Result<Self, AxisError> {
        Ok(Self {
            speed,
            lead_steps,
            curve: SCurve::new(config.scurve, speed, lead_steps)?,
        })
    }

    /// Whether this is the curve a member with `scurve` would plan for `group`.
    fn fits(&self, scurve: ScurveConfig, group: &GroupMove) -> bool {
        *self.curve.config() == scurve
            && self.speed == group.speed
            && self.lead_steps == group.lead_steps
    }
}

/// A member's velocity at its step, steps/s: the lead's, `lead_velocity`,
/// scaled by `steps / lead_steps` and truncated, as
/// `f64_to_u32(lead_velocity · steps / lead_steps)` gives it.
#[inline]
fn member_velocity(lead_velocity: f64, steps: u32, lead_steps: u32) -> u32 {
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    return f64_to_u32(lead_velocity * f64::from(steps) / f64::from(lead_steps.max(1)));
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    return member_velocity_in_integers(lead_velocity, steps, lead_steps);
}

/// [`member_velocity`] with the division in integers (`ieee_div`, the same
/// bits): on a core without an FPU, a soft-float division a step was the
/// costliest thing a group part did.
#[cfg_attr(any(target_arch = "x86_64", target_arch = "aarch64"), allow(dead_code))]
#[inline(never)]
fn member_velocity_in_integers(lead_velocity: f64, steps: u32, lead_steps: u32) -> u32 {
    // Velocities are never negative; `lead_steps` is at most 2^31 − 1 (a
    // move's steps are an `i32`'s magnitude).
    let product = lead_velocity * f64::from(steps);
    let quotient = div_trunc(product.to_bits(), lead_steps.clamp(1, 1 << 31));
    u32::try_from(quotient).unwrap_or(u32::MAX)
}

impl AxisCore {
    /// Whether this axis could run its part of a group move now.
    pub(super) fn check_group(&self, t: u64, steps: i32) -> Result<(), AxisError> {
        if steps == i32::MIN {
            return Err(AxisError::StepsOutOfRange);
        }
        // Any motion, its last step's period included: a group starts from
        // an axis whose last move has ended.
        let taken = !matches!(self.state, State::Idle);
        if taken || self.ready_ct > t {
            return Err(AxisError::Busy);
        }
        if !self.stop_pin_high {
            return Err(AxisError::StopPinLow);
        }
        self.check_reach(i64::from(steps))?;
        if steps != 0 {
            // A group part crosses limits as a move of its steps would.
            self.check_limit(Direction::of(steps))?;
            self.check_soft_end(i64::from(steps))?;
        }
        Ok(())
    }

    /// Starts this member's part of a group move (see the module docs),
    /// with the lead's curve planned once for the whole group or (`None`)
    /// planned here ([`AxisCore::command_with_lead`]).
    pub(super) fn start_group_with(
        &mut self,
        t: u64,
        group: GroupMove,
        planned: Option<&GroupLead>,
    ) -> Result<Taken, AxisError> {
        if !matches!(self.state, State::Reserved) {
            self.check_group(t, group.steps)?;
        }
        let steps = group.steps.unsigned_abs();
        if group.steps == i32::MIN || steps > group.lead_steps {
            return Err(AxisError::StepsOutOfRange);
        }
        let lead = if steps == 0 {
            None
        } else {
            match planned.filter(|lead| lead.fits(self.config.scurve, &group)) {
                Some(lead) => Some(lead.curve.clone()),
                None => Some(GroupLead::plan(&self.config, group.speed, group.lead_steps)?.curve),
            }
        };
        self.state = State::Idle;
        let Some(lead) = lead else {
            return Ok(Taken::Done);
        };
        let direction = Direction::of(group.steps);
        self.sticky &= !(Mode::STOP_LATCHED | Mode::ESTOP);
        self.last_dropped = 0;
        self.ledger.accepted += i64::from(group.steps);
        let start = group.start_ct.max(t);
        self.move_info = MoveInfo {
            speed: group.speed,
            accel_steps: lead.accel_steps(),
            slew_steps: lead.plan().slew_steps,
            top_velocity: scale(lead.top_speed(), steps, group.lead_steps),
            start_ct: start,
            max_velocity: self.move_info.max_velocity,
        };
        self.step_bits = Mode::ACCEL
            | if group.steps < 0 {
                Mode::REVERSE
            } else {
                Mode::empty()
            };
        // A part of one step stays on the lead's first edge.
        let over = u64::from(steps.max(2) - 1);
        let stride = if steps <= 1 {
            0
        } else {
            u64::from(group.lead_steps - 1)
        };
        self.state = State::Group(Follower {
            lead,
            lead_steps: group.lead_steps,
            steps,
            direction,
            made: 0,
            next_whole: 1,
            next_remainder: 0,
            stride_whole: stride / over,
            stride_remainder: stride % over,
            lead_index: 0,
            lead_ct: start,
            lead_period_end: start,
            lead_running: true,
            lead_velocity: 0.0,
            lead_delay: 0,
            lead_phase: Phase::Accel,
            next_step: None,
            scaled: None,
            stop_after: None,
            stopped: false,
            finish_at: None,
        });
        Ok(Taken::Done)
    }

    /// Stops the group move this axis runs its part of along its line: every
    /// member told the same CT decelerates from the same lead edge (the
    /// first after `ct`), so all stay on the line. The steps not reached are
    /// dropped (see the module docs). Nothing happens without a group move.
    pub fn stop_group_after(&mut self, ct: u64) {
        if let Some(follower) = self.state.follower_mut() {
            if follower.finish_at.is_none() {
                let after = follower.stop_after.map_or(ct, |earlier| earlier.min(ct));
                follower.stop_after = Some(after);
                self.sticky |= Mode::STOP_LATCHED;
            }
        }
    }

    /// Whether the next event ([`AxisCore::next_event`]) drives no edge
    /// before its own CT, so that a caller that drives edges as their CTs
    /// come may run it at its CT rather than ahead of it: a group member's
    /// lead edge that is not also a step in a new direction. `false` says
    /// nothing.
    pub fn next_event_on_time(&self) -> bool {
        let Some(follower) = self.state.follower() else {
            return false;
        };
        let reverse = follower.direction == Direction::Reverse;
        let turns = reverse != self.dir_reverse && self.config.outputs.dir_pin().is_some();
        follower.event_on_time(turns)
    }

    /// Whether the axis runs its part of a group move (or is reserved for one).
    pub fn in_group(&self) -> bool {
        matches!(self.state, State::Reserved | State::Group(_))
    }

    /// The phase bits of the lead's edge just made (or taken from another
    /// member).
    fn take_lead_phase(&mut self) {
        if let Some(follower) = self.state.follower() {
            self.step_bits = match follower.lead_phase {
                Phase::Accel => Mode::ACCEL,
                Phase::Slew => Mode::SLEW,
                Phase::Decel => Mode::DECEL,
            } | (self.step_bits & Mode::REVERSE);
        }
    }

    /// The member's next step, or the line's end: whether the line ended
    /// short of it (its unmade steps dropped).
    fn settle_part(&mut self) -> bool {
        let Some(follower) = self.state.follower_mut() else {
            return false;
        };
        let Some(unmade) = follower.settle() else {
            return false;
        };
        let signed = i64::from(unmade) * follower.direction.sign();
        self.drop_steps(signed);
        self.last_dropped = unmade;
        true
    }

    /// Takes the lead's next edge from `other`, a member of the same group
    /// move that has just made it, instead of computing it again: every
    /// member's copy of the lead's curve makes the same edges on the same
    /// CTs (see the module docs), so a caller that runs several members
    /// (a firmware's axes) computes a ramp's cosines and delays once, not
    /// once a member. Taken only when nothing can differ: `other` is one
    /// lead edge ahead, at the CT this member's next lead edge is due,
    /// with the same curve and the same stop, this member's edge one that
    /// would compute (`SCurve::next_is_precomputed`: a run's entries and
    /// slew steps cost less than the copy), and no step of this member
    /// due before it. Then this member stands exactly where making the edge
    /// itself would leave it; otherwise nothing changes. Whether it took it.
    pub fn take_lead_edge_from(&mut self, other: &AxisCore) -> bool {
        let (Some(theirs), Some(mine)) = (other.state.follower(), self.state.follower_mut()) else {
            return false;
        };
        let t = theirs.lead_ct;
        let same = theirs.lead_index == mine.lead_index + 1
            && mine.lead_running
            && mine.finish_at.is_none()
            && mine.lead_period_end == t
            && mine.next_step.is_none_or(|due| due >= t)
            && theirs.lead_steps == mine.lead_steps
            && theirs.stop_after == mine.stop_after
            && !mine.lead.next_is_precomputed()
            && theirs.lead.plan() == mine.lead.plan();
        if !same {
            return false;
        }
        mine.lead.clone_from(&theirs.lead);
        mine.lead_index = theirs.lead_index;
        mine.lead_ct = theirs.lead_ct;
        mine.lead_period_end = theirs.lead_period_end;
        mine.lead_running = theirs.lead_running;
        mine.lead_velocity = theirs.lead_velocity;
        mine.lead_delay = theirs.lead_delay;
        mine.lead_phase = theirs.lead_phase;
        mine.stopped = theirs.stopped;
        self.take_lead_phase();
        self.settle_part();
        true
    }

    /// A group member's event at `t`: the lead's edge, then its own step,
    /// then its end.
    pub(super) fn run_group_event(&mut self, t: u64, emit: &mut impl FnMut(Edge)) {
        let config = self.config;
        let Some(follower) = self.state.follower_mut() else {
            return;
        };
        if follower.finish_at.is_some_and(|finish| finish <= t) {
            self.state = State::Idle;
            self.finish(t);
            return;
        }
        if follower.lead_running && follower.lead_period_end <= t {
            follower.lead_edge(t, |delay| period_ticks(&config, delay));
            self.take_lead_phase();
        }
        if self.settle_part() {
            return;
        }
        let Some(follower) = self.state.follower_mut() else {
            return;
        };
        if follower.next_step.is_some_and(|due| due <= t) {
            let due = follower.next_step.take().unwrap_or(t);
            follower.count_step();
            let direction = follower.direction;
            let (velocity, delay) = follower.scaled_step();
            let dropped = follower.settle();
            self.emit_step(due, direction, emit);
            self.last_step = LastStep {
                velocity,
                delay_ticks: delay,
                ct: due,
            };
            if let Some(unmade) = dropped {
                self.drop_steps(i64::from(unmade) * direction.sign());
                self.last_dropped = unmade;
            }
        }
    }
}

#[cfg(test)]
mod group_tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;
    use crate::axis_core::{AxisCoreConfig, CoreCommand, Outputs};

    /// Three cores told the same group move, each run on its own: the
    /// firmware's view (no hub, no threads).
    fn members(steps: &[i32], start_ct: u64) -> Vec<AxisCore> {
        let lead_steps = steps.iter().map(|s| s.unsigned_abs()).max().unwrap();
        steps
            .iter()
            .enumerate()
            .map(|(i, &steps)| {
                let pin = u8::try_from(2 * i).unwrap();
                let outputs = Outputs::StepDir {
                    step: pin,
                    dir: pin + 1,
                };
                let mut core = AxisCore::new(AxisCoreConfig::new(outputs), 0);
                core.set_stop_pin(0, true);
                core.command(0, CoreCommand::GroupReserve { steps })
                    .unwrap();
                assert_eq!(
                    core.command(
                        0,
                        CoreCommand::Move {
                            speed: 100,
                            steps: 5
                        }
                    ),
                    Err(AxisError::Busy)
                );
                core.command(
                    0,
                    CoreCommand::GroupStart(GroupMove {
                        speed: 20_000,
                        lead_steps,
                        steps,
                        start_ct,
                    }),
                )
                .unwrap();
                core
            })
            .collect()
    }

    /// Each core's rising step edges, run up to `limit`.
    fn rising(core: &mut AxisCore, limit: u64) -> Vec<u64> {
        let mut edges = Vec::new();
        core.run_until(limit, &mut |edge: Edge| {
            if edge.level && edge.pin.is_multiple_of(2) {
                edges.push(edge.ct);
            }
        });
        edges
    }

    #[test]
    fn members_start_together_and_end_together_on_their_own() {
        let steps = [5_000, -1_700, 1, 0];
        let mut cores = members(&steps, 10_000);
        let edges: Vec<Vec<u64>> = cores.iter_mut().map(|c| rising(c, u64::MAX)).collect();
        for (core, steps) in cores.iter().zip(steps) {
            assert_eq!(core.position(), i64::from(steps));
            assert_eq!((core.steps_to_go(), core.is_moving()), (0, false));
        }
        assert_eq!(edges[0][0], 10_000);
        assert_eq!(edges[1][0], 10_000);
        assert_eq!(edges[2], [10_000]);
        assert!(edges[3].is_empty());
        assert_eq!(edges[1].last(), edges[0].last());
        // The lead's edges are those of the same move alone.
        let mut alone = AxisCore::new(AxisCoreConfig::new(Outputs::StepDir { step: 0, dir: 1 }), 0);
        alone.set_stop_pin(0, true);
        alone
            .command(
                10_000,
                CoreCommand::Move {
                    speed: 20_000,
                    steps: 5_000,
                },
            )
            .unwrap();
        assert_eq!(rising(&mut alone, u64::MAX), edges[0]);
    }

    /// A member started with a lead curve planned once for the group makes
    /// the edges of one that plans its own; a curve planned for another
    /// move is not taken.
    #[test]
    fn a_lead_planned_once_gives_every_member_its_own_edges() {
        let steps = [5_000, -1_700, 333, 0];
        let config = AxisCoreConfig::new(Outputs::StepDir { step: 0, dir: 1 });
        let right = GroupLead::plan(&config, 20_000, 5_000).unwrap();
        let other_speed = GroupLead::plan(&config, 10_000, 5_000).unwrap();
        let other_steps = GroupLead::plan(&config, 20_000, 4_000).unwrap();
        for lead in [&right, &other_speed, &other_steps] {
            let mut own = members(&steps, 7_000);
            for (index, (core, &part)) in own.iter_mut().zip(&steps).enumerate() {
                let mut planned = AxisCore::new(*core.config(), 0);
                planned.set_stop_pin(0, true);
                planned
                    .command(0, CoreCommand::GroupReserve { steps: part })
                    .unwrap();
                let group = GroupMove {
                    speed: 20_000,
                    lead_steps: 5_000,
                    steps: part,
                    start_ct: 7_000,
                };
                planned
                    .command_with_lead(0, CoreCommand::GroupStart(group), Some(lead))
                    .unwrap();
                let mut expected = Vec::new();
                core.run_until(u64::MAX, &mut |edge| expected.push(edge));
                let mut edges = Vec::new();
                planned.run_until(u64::MAX, &mut |edge| edges.push(edge));
                assert_eq!(edges, expected, "member {index}");
                assert_eq!(
                    (planned.position(), planned.last_step(), planned.mode()),
                    (core.position(), core.last_step(), core.mode())
                );
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]

        /// Whenever a member says its next event is a plain step (a
        /// firmware then drives its rising edge at `due` before running the
        /// event), the event is at `due` and its first edge is that rising
        /// edge; whenever it says the event is on time (a firmware then
        /// runs it at its CT), no edge comes before it: stops told at any
        /// CT, lines of any slope, single steps.
        #[test]
        fn a_members_plain_step_is_the_events_first_edge(
            steps in proptest::collection::vec(-900i32..=900, 1..4),
            stop_ct in proptest::option::of(0u64..40_000_000),
        ) {
            let mut cores = members(&steps, 1_000);
            let mut plain = 0;
            for core in &mut cores {
                let mut stopped = false;
                while let Some(t) = core.next_event() {
                    if let Some(ct) = stop_ct.filter(|&ct| !stopped && t > ct) {
                        core.stop_group_after(ct);
                        stopped = true;
                        continue;
                    }
                    let expected = core.next_plain_step();
                    let on_time = core.next_event_on_time();
                    let mut edges = Vec::new();
                    core.run_event(t, &mut |edge| edges.push(edge));
                    if on_time {
                        proptest::prop_assert!(edges.iter().all(|edge| edge.ct >= t), "{edges:?} before {t}");
                    }
                    if let Some((due, pin)) = expected {
                        plain += 1;
                        proptest::prop_assert_eq!(t, due);
                        proptest::prop_assert_eq!(
                            edges.first().copied(),
                            Some(Edge { ct: due, pin, level: true })
                        );
                    }
                }
            }
            let made: u64 = steps.iter().map(|s| u64::from(s.unsigned_abs())).sum();
            proptest::prop_assert!(stop_ct.is_some() || made < 3 || plain > 0);
        }
    }

    /// Members run in CT order, each taking its lead edges from the member
    /// before it where it can (as a firmware runs its axes): the same
    /// edges and the same state as members that compute every edge.
    #[test]
    fn lead_edges_taken_from_another_member_are_the_ones_it_would_make() {
        for (steps, stop_ct) in [
            (vec![5_000, -1_700, 333, 0], None),
            (vec![5_000, -1_700, 333], Some(20_000_000)),
            (vec![-700, 700, 699], Some(3_000_000)),
        ] {
            let mut alone = members(&steps, 0);
            let mut sharing = members(&steps, 0);
            let mut taken = 0;
            let mut edges: Vec<Vec<Edge>> = vec![Vec::new(); steps.len()];
            let mut stopped = false;
            loop {
                let next = sharing.iter().filter_map(AxisCore::next_event).min();
                let Some(t) = next else { break };
                if let Some(ct) = stop_ct.filter(|&ct| !stopped && t > ct) {
                    for core in &mut sharing {
                        core.stop_group_after(ct);
                    }
                    stopped = true;
                }
                for index in 0..sharing.len() {
                    if index > 0 && sharing[index].next_event() == Some(t) {
                        let (before, after) = sharing.split_at_mut(index);
                        if after[0].take_lead_edge_from(&before[index - 1]) {
                            taken += 1;
                        }
                    }
                    if sharing[index].next_event() == Some(t) {
                        sharing[index].run_event(t, &mut |edge| edges[index].push(edge));
                    }
                }
            }
            // A stop's deceleration runs on each member's ramp runs (the
            // lead's curve computed ahead): few of its edges are shared.
            let floor = if stop_ct.is_none() { 100 } else { 1 };
            assert!(taken > floor, "{taken} lead edges taken");
            for (index, core) in alone.iter_mut().enumerate() {
                let mut expected = Vec::new();
                if let Some(ct) = stop_ct {
                    core.run_until(ct, &mut |edge| expected.push(edge));
                    core.stop_group_after(ct);
                }
                core.run_until(u64::MAX, &mut |edge| expected.push(edge));
                assert_eq!(edges[index], expected, "member {index} of {steps:?}");
                let shared = &sharing[index];
                assert_eq!(
                    (
                        shared.position(),
                        shared.dropped_steps(),
                        shared.mode(),
                        shared.last_step()
                    ),
                    (
                        core.position(),
                        core.dropped_steps(),
                        core.mode(),
                        core.last_step()
                    )
                );
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(512))]

        /// A microcontroller's member velocity (integer division) is the
        /// host's (`f64` division), for lead velocities as the curve makes
        /// them (an integer times a power of two) and any line.
        #[test]
        fn a_members_velocity_in_integers_is_the_f64_one(
            units in 0u64..1 << 62,
            shift in 0i32..64,
            steps in 1u32..=i32::MAX as u32,
            lead_extra in 0u32..=i32::MAX as u32,
        ) {
            let lead_velocity = units as f64 * 2f64.powi(-shift);
            let lead_steps = steps.saturating_add(lead_extra).min(i32::MAX as u32);
            proptest::prop_assert_eq!(
                member_velocity_in_integers(lead_velocity, steps, lead_steps),
                f64_to_u32(lead_velocity * f64::from(steps) / f64::from(lead_steps))
            );
        }
    }

    #[test]
    fn a_stop_told_to_every_member_keeps_them_on_the_line() {
        let steps = [5_000, -1_700, 333];
        let mut cores = members(&steps, 0);
        let stop_ct = 20_000_000;
        let mut edges: Vec<Vec<u64>> = cores.iter_mut().map(|c| rising(c, stop_ct)).collect();
        for core in &mut cores {
            core.stop_group_after(stop_ct);
        }
        for (core, edges) in cores.iter_mut().zip(&mut edges) {
            edges.extend(rising(core, u64::MAX));
        }
        let lead_made = edges[0].len() as f64;
        assert!(lead_made < 5_000.0);
        for (core, steps) in cores.iter().zip(steps) {
            let line = f64::from(steps) * lead_made / 5_000.0;
            assert!(
                (core.position() as f64 - line).abs() <= 1.0,
                "{} vs {line}",
                core.position()
            );
            let unmade = i64::from(steps) - core.position();
            assert_eq!(u64::from(core.dropped_steps()), unmade.unsigned_abs());
            assert_eq!(core.ledger().dropped, unmade);
            assert!(core.mode().has(Mode::STOP_LATCHED));
        }
    }
}

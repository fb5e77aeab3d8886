//! The planner's queue: coordinated lines in, a plan (entry, cruise and
//! exit speed, ramp lengths) per line out, re-planned on every push from
//! the last entry that can still change ([`Planner::settled`]).
//!
//! # Units
//!
//! A line's speeds are **lead** speeds: steps/s of its longest axis, as
//! `move_together` drives its lead. The other axes follow at
//! `|steps_i|/lead_steps` of it, so axis `i`'s limits bound the lead by
//! `max_speed_i·L/|n_i|` and `max_accel_i·L/|n_i|`. A junction joins two
//! lines with different leads, so junction speeds are **path** speeds:
//! steps/s along the line in step space (its Euclidean length `E`); a
//! line's lead speed is its path speed times `r = L/E` (≤ 1).
//!
//! # The passes
//!
//! Junction `k` is the entry of line `k`; its limit is the smallest of the
//! two lines' speed limits (as path speeds), the junction deviation speed
//! and the chord bound of each line ([`super::junction`]), or 0 in exact stop and at the start of an
//! empty queue. The exit of the last line is 0: the machine can always stop
//! by the end of what is queued.
//!
//! - **Backward**, from the end: each line's highest entry is the highest
//!   speed from which its ramp reaches its exit bound within its length
//!   ([`super::ramp::max_entry_speed`]), held at the junction limit.
//! - **Forward**, from the first line that is not frozen: each line's exit
//!   is the lower of that bound and the highest speed its ramp reaches from
//!   its entry within its length.
//! - **Cruise**: the highest speed, up to the line's limit, whose entry and
//!   exit ramps ([`super::ramp::ramp_distance`], whole steps) fit together
//!   in the line.
//!
//! The passes plan with lengths `1/1024` step short, so the rounding of
//! the path-to-lead conversions (ulps) never makes a ramp one step too
//! long.
//!
//! # Frozen lines
//!
//! A line being stepped is frozen ([`Planner::freeze_front`]): its plan
//! and both its junction speeds never change again. Pushing lines only
//! raises the backward pass's bounds (more room to stop), so the first
//! unfrozen line can always leave from the frozen exit.

use core::f64::consts::PI;

use super::junction::{chord_speed, junction_deviation_speed};
use super::ramp::{max_speed_within, min_speed_within, ramp_distance, ramp_length};
use super::sqrt::sqrt;

/// The most axes a line may have.
pub const MAX_AXES: usize = 8;

/// How far short of a line's length the passes plan (steps), so that
/// rounding never makes its ramps a step too long.
const PLAN_MARGIN_STEPS: f64 = 1.0 / 1024.0;

/// A line's backward bound before the pass has run with its present
/// limits (a bound is never below 0).
const NO_BOUND: f64 = -1.0;

/// How lines are joined.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blending {
    /// Every junction at 0 (G61): each line starts and ends at rest.
    ExactStop,
    /// Junctions at the highest speed the corner rule and the limits allow
    /// (G64).
    Blend,
}

/// The machine's limits, per axis in steps, and how lines are joined.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Machine<const AXES: usize> {
    /// Each axis's top speed (steps/s, > 0).
    pub max_speed_steps_per_s: [f64; AXES],
    /// Each axis's top acceleration (steps/s², > 0).
    pub max_accel_steps_per_s2: [f64; AXES],
    /// grbl's junction deviation δ, in steps of step space (≥ 0).
    pub junction_deviation_steps: f64,
    /// Exact stop or blending.
    pub blending: Blending,
}

/// A coordinated line: every axis moves on one line in step space, the
/// lead (the longest axis) at up to `feed_steps_per_s`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line<const AXES: usize> {
    /// Signed steps per axis.
    pub steps: [i32; AXES],
    /// The lead axis's speed limit (steps/s, > 0; `f64::INFINITY` for a
    /// rapid that only the axes' limits hold).
    pub feed_steps_per_s: f64,
}

/// What a line's axis cores are to run, in lead steps and lead steps/s:
/// `accel_steps` of ramp from `entry` to `cruise`, `cruise_steps` at
/// `cruise`, `decel_steps` of ramp to `exit`; the three add up to the lead
/// steps.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Plan {
    /// Lead speed at the start (steps/s).
    pub entry_steps_per_s: f64,
    /// Lead speed between the ramps (steps/s).
    pub cruise_steps_per_s: f64,
    /// Lead speed at the end (steps/s).
    pub exit_steps_per_s: f64,
    /// Length of the entry ramp (lead steps).
    pub accel_steps: u32,
    /// Length of the cruise (lead steps).
    pub cruise_steps: u32,
    /// Length of the exit ramp (lead steps).
    pub decel_steps: u32,
}

/// A queued line with its limits and its plan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment<const AXES: usize> {
    line: Line<AXES>,
    lead_steps: u32,
    lead_per_path: f64,
    unit: [f64; AXES],
    /// The lead's limit from every axis's top speed alone (steps/s).
    axis_speed_limit: f64,
    /// The corner rule's limit at this line's start (path steps/s; 0 for
    /// the first line and in exact stop).
    corner_limit: f64,
    speed_limit: f64,
    accel_limit: f64,
    junction_limit: f64,
    junction_speed: f64,
    /// The backward pass's bound on the entry (path steps/s; [`NO_BOUND`]
    /// until the pass has run with the line's present limits).
    entry_bound: f64,
    /// The lead speeds the passes gave the line's start and end.
    entry_lead: f64,
    exit_lead: f64,
    /// The plan, worked out once the line is frozen (before, on demand).
    plan: Option<Plan>,
}

impl<const AXES: usize> Segment<AXES> {
    /// The line as pushed.
    pub fn line(&self) -> &Line<AXES> {
        &self.line
    }
    /// The lead axis's steps (the largest `|steps|`).
    pub fn lead_steps(&self) -> u32 {
        self.lead_steps
    }
    /// `r = L/E`: lead speed over path speed (0 < r ≤ 1).
    pub fn lead_per_path(&self) -> f64 {
        self.lead_per_path
    }
    /// The lead's speed limit: the feed and every axis's top speed (steps/s).
    pub fn speed_limit_steps_per_s(&self) -> f64 {
        self.speed_limit
    }
    /// The lead's acceleration limit from every axis's (steps/s²).
    pub fn accel_limit_steps_per_s2(&self) -> f64 {
        self.accel_limit
    }
    /// The limit of the junction at this line's start (path steps/s).
    pub fn junction_limit_steps_per_s(&self) -> f64 {
        self.junction_limit
    }
    /// The planned speed at this line's start (path steps/s).
    pub fn junction_speed_steps_per_s(&self) -> f64 {
        self.junction_speed
    }
    /// The plan.
    pub fn plan(&self) -> Plan {
        self.plan
            .unwrap_or_else(|| plan_line(self.entry_lead, self.exit_lead, self))
    }
}

/// A machine the planner cannot plan for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MachineError {
    /// No axes, or more than [`MAX_AXES`].
    #[error("a planner has 1 to 8 axes")]
    AxisCount,
    /// A top speed that is not a positive number.
    #[error("axis {0}'s max speed must be above 0")]
    MaxSpeed(usize),
    /// A top acceleration that is not a positive finite number.
    #[error("axis {0}'s max acceleration must be above 0 and finite")]
    MaxAccel(usize),
    /// A junction deviation below 0 or not finite.
    #[error("the junction deviation must be 0 or more and finite")]
    JunctionDeviation,
}

/// A line the planner does not take.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PushError {
    /// The queue holds its capacity already.
    #[error("the planner queue is full")]
    Full,
    /// Every axis's steps are 0.
    #[error("a line must move at least one axis")]
    NoMotion,
    /// A feed that is not above 0 (or NaN).
    #[error("a line's feed must be above 0")]
    Feed,
}

/// A fixed-capacity look-ahead planner of up to `N` lines of `AXES` axes;
/// no allocation.
#[derive(Clone, Debug)]
pub struct Planner<const N: usize, const AXES: usize> {
    machine: Machine<AXES>,
    ring: [Option<Segment<AXES>>; N],
    head: usize,
    len: usize,
    frozen: usize,
    /// Lines from the front whose entry speed is final: nothing pushed
    /// later can change it (see [`Planner::replan`]); at least 1 while a
    /// line is queued (the front's entry is the machine's speed).
    settled: usize,
    /// The path speed at the front's start once the line before it has
    /// been popped (0 at rest).
    start_speed: f64,
    /// The feed override (1 = 100 %), for the lines not frozen.
    feed_scale: f64,
    /// The rapid override (1 = 100 %), for rapids not frozen.
    rapid_scale: f64,
}

impl<const N: usize, const AXES: usize> Planner<N, AXES> {
    /// An empty planner for `machine`.
    pub fn new(machine: Machine<AXES>) -> Result<Self, MachineError> {
        if AXES == 0 || AXES > MAX_AXES {
            return Err(MachineError::AxisCount);
        }
        for axis in 0..AXES {
            let speed = machine.max_speed_steps_per_s[axis];
            if speed.is_nan() || speed <= 0.0 {
                return Err(MachineError::MaxSpeed(axis));
            }
            let accel = machine.max_accel_steps_per_s2[axis];
            if !(accel > 0.0 && accel.is_finite()) {
                return Err(MachineError::MaxAccel(axis));
            }
        }
        let deviation = machine.junction_deviation_steps;
        if !(deviation >= 0.0 && deviation.is_finite()) {
            return Err(MachineError::JunctionDeviation);
        }
        Ok(Planner {
            machine,
            ring: [None; N],
            head: 0,
            len: 0,
            frozen: 0,
            settled: 0,
            start_speed: 0.0,
            feed_scale: 1.0,
            rapid_scale: 1.0,
        })
    }

    /// Forgets every line, in place: the queue as [`Self::new`] leaves
    /// it, with the machine, the mode and the overrides kept.
    pub(crate) fn clear(&mut self) {
        for slot in &mut self.ring {
            *slot = None;
        }
        self.head = 0;
        self.len = 0;
        self.frozen = 0;
        self.settled = 0;
        self.start_speed = 0.0;
    }

    /// The machine planned for.
    pub fn machine(&self) -> &Machine<AXES> {
        &self.machine
    }

    /// Lines queued.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no line is queued.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether the queue is at its capacity.
    pub fn is_full(&self) -> bool {
        self.len == N
    }

    /// Switches between exact stop (G61) and blending (G64) for the
    /// junctions of the lines pushed from now on; queued junctions keep
    /// the mode they were pushed with.
    pub fn set_blending(&mut self, blending: Blending) {
        self.machine.blending = blending;
    }

    /// Sets the feed override (`feed_scale`, 1 = 100 %: the feed of every
    /// line that is not a rapid is multiplied by it) and the rapid override
    /// (`rapid_scale`, at most 1: a rapid's top speed from the axes' limits is
    /// multiplied by it), and re-plans every line that is not frozen. Frozen
    /// lines keep their plan: the change takes effect at the first junction
    /// not frozen, from the speed the machine has there, without a jump in
    /// speed or acceleration. When the override falls, lines may keep a
    /// speed above their new feed for as long as the machine takes to slow
    /// down within its acceleration (never above an axis's top speed or a
    /// corner's limit). Scales that are not above 0 and finite are refused
    /// (`Err(PushError::Feed)`, nothing changes).
    pub fn set_overrides(&mut self, feed_scale: f64, rapid_scale: f64) -> Result<(), PushError> {
        let valid = |scale: f64| scale > 0.0 && scale.is_finite();
        if !valid(feed_scale) || !valid(rapid_scale) {
            return Err(PushError::Feed);
        }
        self.feed_scale = feed_scale;
        self.rapid_scale = rapid_scale.min(1.0);
        for index in self.frozen..self.len {
            let segment = *self.at(index);
            let speed_limit =
                self.scaled_limit(segment.line.feed_steps_per_s, segment.axis_speed_limit);
            let junction_limit = match index.checked_sub(1).map(|prev| self.at(prev)) {
                None => 0.0,
                Some(prev) => segment
                    .corner_limit
                    .min(prev.speed_limit / prev.lead_per_path)
                    .min(speed_limit / segment.lead_per_path),
            };
            let segment = self.at_mut(index);
            segment.speed_limit = speed_limit;
            segment.junction_limit = junction_limit;
            segment.entry_bound = NO_BOUND;
        }
        // New limits: no entry after the frozen lines is final any more.
        self.settled = self.settled.min(self.frozen + 1);
        self.replan();
        Ok(())
    }

    /// The overrides in force: (feed, rapid).
    pub fn overrides(&self) -> (f64, f64) {
        (self.feed_scale, self.rapid_scale)
    }

    /// A line's lead speed limit under the overrides: its feed (scaled) and
    /// its axes' limit, or for a rapid (an infinite feed) the axes' limit
    /// scaled by the rapid override.
    fn scaled_limit(&self, feed: f64, axis_speed_limit: f64) -> f64 {
        if feed == f64::INFINITY {
            axis_speed_limit * self.rapid_scale
        } else {
            (feed * self.feed_scale).min(axis_speed_limit)
        }
    }

    /// Lines at the front whose entry speed is final (at least 1 while a
    /// line is queued): what later pushes re-plan starts at the last of
    /// them.
    pub fn settled(&self) -> usize {
        self.settled
    }

    /// Lines at the front that are frozen.
    pub fn frozen(&self) -> usize {
        self.frozen
    }

    /// The `index`-th queued line from the front.
    pub fn get(&self, index: usize) -> Option<&Segment<AXES>> {
        if index >= self.len {
            return None;
        }
        self.ring[(self.head + index) % N].as_ref()
    }

    /// The queued lines, front first.
    pub fn iter(&self) -> impl Iterator<Item = &Segment<AXES>> {
        (0..self.len).filter_map(|index| self.get(index))
    }

    /// Queues `line` and re-plans every line that is not frozen.
    pub fn push(&mut self, line: Line<AXES>) -> Result<(), PushError> {
        if self.len == N {
            return Err(PushError::Full);
        }
        if line.feed_steps_per_s.is_nan() || line.feed_steps_per_s <= 0.0 {
            return Err(PushError::Feed);
        }
        let lead_steps = line
            .steps
            .iter()
            .map(|steps| steps.unsigned_abs())
            .max()
            .unwrap_or(0);
        if lead_steps == 0 {
            return Err(PushError::NoMotion);
        }
        let lead = f64::from(lead_steps);
        let path_steps = sqrt(
            line.steps
                .iter()
                .map(|&steps| f64::from(steps) * f64::from(steps))
                .sum(),
        );
        let mut unit = [0.0; AXES];
        let mut axis_speed_limit = f64::INFINITY;
        let mut accel_limit = f64::INFINITY;
        let limits = self
            .machine
            .max_speed_steps_per_s
            .iter()
            .zip(&self.machine.max_accel_steps_per_s2);
        for ((component, &steps), (max_speed, max_accel)) in
            unit.iter_mut().zip(&line.steps).zip(limits)
        {
            *component = f64::from(steps) / path_steps;
            if steps != 0 {
                // The lead moves L/|n| steps per step of this axis.
                let lead_per_axis = lead / f64::from(steps.unsigned_abs());
                axis_speed_limit = axis_speed_limit.min(max_speed * lead_per_axis);
                accel_limit = accel_limit.min(max_accel * lead_per_axis);
            }
        }
        let lead_per_path = (lead / path_steps).min(1.0);
        let speed_limit = self.scaled_limit(line.feed_steps_per_s, axis_speed_limit);
        let corner_limit = match (self.machine.blending, self.last()) {
            (Blending::ExactStop, _) | (_, None) => 0.0,
            (Blending::Blend, Some(prev)) => {
                // Simpler than grbl's limit along u_next − u_prev: the
                // lower of the two lines' path accelerations.
                let corner_accel =
                    (prev.accel_limit / prev.lead_per_path).min(accel_limit / lead_per_path);
                let prev_path_steps = f64::from(prev.lead_steps) / prev.lead_per_path;
                junction_deviation_speed(
                    &prev.unit,
                    &unit,
                    corner_accel,
                    self.machine.junction_deviation_steps,
                )
                .min(chord_speed(
                    &prev.unit,
                    &unit,
                    prev_path_steps,
                    prev.accel_limit / prev.lead_per_path,
                ))
                .min(chord_speed(
                    &prev.unit,
                    &unit,
                    path_steps,
                    accel_limit / lead_per_path,
                ))
            }
        };
        let junction_limit = match self.last() {
            None => 0.0,
            Some(prev) => corner_limit
                .min(prev.speed_limit / prev.lead_per_path)
                .min(speed_limit / lead_per_path),
        };
        let segment = Segment {
            line,
            lead_steps,
            lead_per_path,
            unit,
            axis_speed_limit,
            corner_limit,
            speed_limit,
            accel_limit,
            junction_limit,
            junction_speed: 0.0,
            entry_bound: NO_BOUND,
            entry_lead: 0.0,
            exit_lead: 0.0,
            plan: None,
        };
        self.ring[(self.head + self.len) % N] = Some(segment);
        self.len += 1;
        self.settled = self.settled.max(1);
        self.replan();
        Ok(())
    }

    /// Freezes the first `count` lines (at most all queued): their plans
    /// and junction speeds never change again. Freezing fewer than are
    /// frozen already changes nothing.
    pub fn freeze_front(&mut self, count: usize) {
        let count = count.min(self.len);
        for index in self.frozen..count {
            let segment = self.at_mut(index);
            segment.plan = Some(segment.plan());
        }
        self.frozen = self.frozen.max(count);
    }

    /// Takes the front line off the queue (its steps are done): it was
    /// frozen, or is frozen as it goes; the next line starts from its exit.
    pub fn pop_front(&mut self) -> Option<Segment<AXES>> {
        if self.len == 0 {
            return None;
        }
        let segment = self.ring[self.head].take()?;
        self.head = (self.head + 1) % N;
        self.len -= 1;
        self.frozen = self.frozen.saturating_sub(1);
        self.settled = self
            .settled
            .saturating_sub(1)
            .max(usize::from(self.len > 0));
        self.start_speed = self.get(0).map_or(0.0, |next| next.junction_speed);
        Some(segment)
    }

    /// The same queue planned with no entry after the frozen lines taken
    /// as settled (the tests' reference for the settled economy).
    #[cfg(test)]
    pub(crate) fn replanned(&self) -> Self {
        let mut fresh = self.clone();
        fresh.settled = fresh.settled.min(fresh.frozen + 1);
        for index in fresh.frozen..fresh.len {
            fresh.at_mut(index).entry_bound = NO_BOUND;
        }
        fresh.replan();
        fresh
    }

    fn last(&self) -> Option<&Segment<AXES>> {
        self.len.checked_sub(1).and_then(|index| self.get(index))
    }

    fn at_mut(&mut self, index: usize) -> &mut Segment<AXES> {
        self.ring[(self.head + index) % N]
            .as_mut()
            .expect("a queued index")
    }

    fn at(&self, index: usize) -> &Segment<AXES> {
        self.get(index).expect("a queued index")
    }

    /// The backward and forward passes over the lines that are not frozen
    /// and not settled.
    ///
    /// grbl's "planned up to here": pushing lines only raises the backward
    /// bounds, so an entry the forward pass did not take from its backward
    /// bound (it is what the line before reaches, or the junction's own
    /// limit) is final once every entry before it is. Lines whose entry and
    /// exit are both final keep their plan; the passes start at the last
    /// line whose entry is final, so a push costs the lines after it, not
    /// the whole queue.
    ///
    /// The backward pass stops at the first bound (from the end) that
    /// comes out as it was: every bound before it depends only on it and
    /// on its line's limits. The forward pass then starts at the line that
    /// ends at the first bound that changed, from its entry as it was.
    fn replan(&mut self) {
        let settled_from = self.frozen.max(self.settled.saturating_sub(1));
        if settled_from >= self.len {
            return;
        }

        // Backward: each junction's bound (path steps/s); the end of the
        // queue is 0.
        let mut exit_bound = 0.0;
        let mut first = settled_from;
        for index in (settled_from + 1..self.len).rev() {
            let segment = self.at_mut(index);
            let exit_lead = (exit_bound * segment.lead_per_path).min(segment.speed_limit);
            let entry_lead = max_speed_within(
                exit_lead,
                plan_length(segment.lead_steps),
                segment.accel_limit,
            );
            let bound = segment
                .junction_limit
                .min(entry_lead / segment.lead_per_path);
            if bound.to_bits() == segment.entry_bound.to_bits() {
                first = index;
                break;
            }
            segment.entry_bound = bound;
            exit_bound = bound;
        }
        // The entry of the first line re-planned is fixed: the frozen or
        // settled line's entry, one the bounds did not change, or the speed
        // the machine has at the front.
        let fixed_entry = if first == 0 {
            self.start_speed
        } else {
            self.at(first).junction_speed
        };

        // Forward: each exit is the bound or what the entry reaches.
        let mut entry = fixed_entry;
        for index in first..self.len {
            let bound = if index + 1 < self.len {
                self.at(index + 1).entry_bound
            } else {
                0.0
            };
            let segment = self.at_mut(index);
            segment.junction_speed = entry;
            // An entry above the line's limit comes only from a fallen
            // override: the line then slows down as fast as it can.
            let r = segment.lead_per_path;
            let entry_lead = clamp_ulps(entry * r, segment.speed_limit);
            let length = plan_length(segment.lead_steps);
            let reach_lead = max_speed_within(entry_lead, length, segment.accel_limit);
            let lowest_lead = min_speed_within(entry_lead, length, segment.accel_limit);
            let wanted = bound.min(reach_lead / r);
            let wanted_lead = (wanted * r).min(segment.speed_limit);
            // Only a fallen override leaves a line that cannot slow down to
            // its bound; it then slows as much as it can.
            let (exit, exit_lead) = if wanted_lead < entry_lead
                && ramp_length(wanted_lead, entry_lead, segment.accel_limit) > length + 1e-6
            {
                (lowest_lead / r, lowest_lead)
            } else {
                (wanted, wanted_lead)
            };
            segment.entry_lead = entry_lead;
            segment.exit_lead = exit_lead;
            segment.plan = None;
            // The next entry is final when this one is and it was not held
            // down by the backward bound below its junction's limit.
            let next = index + 1;
            if next < self.len && next == self.settled {
                let limit = self.at(next).junction_limit;
                let slowing = exit_lead != wanted_lead;
                if !slowing && (wanted < bound || bound >= limit) {
                    self.settled = next + 1;
                }
            }
            entry = exit;
        }
    }
}

/// `speed` held at `limit` when it is above it by rounding only (a few
/// ulps of the path-to-lead conversion); a speed really above is kept.
fn clamp_ulps(speed: f64, limit: f64) -> f64 {
    if speed > limit && speed <= limit * (1.0 + 1e-12) {
        limit
    } else {
        speed
    }
}

/// The length the passes plan a line of `lead_steps` with.
fn plan_length(lead_steps: u32) -> f64 {
    f64::from(lead_steps) - PLAN_MARGIN_STEPS
}

/// The line's plan between `entry` and `exit` (lead steps/s; their ramp
/// fits in the line): the highest cruise whose two ramps fit in whole steps.
///
/// A line of one lead step between two rests has no room for a ramp (one
/// needs a step up and one down): it is a single pulse, timed as a cruise
/// at the speed a cosine ramp from rest reaches over that step (or the
/// line's limit), its edge half way through. Before, its cruise came out
/// as 0 and the edge never came: a path held or ended by such a sliver
/// (the rest of a line after a hold) never finished.
fn plan_line<const AXES: usize>(entry: f64, exit: f64, segment: &Segment<AXES>) -> Plan {
    let accel = segment.accel_limit;
    let length = segment.lead_steps;
    if length == 1 && entry == 0.0 && exit == 0.0 {
        return Plan {
            entry_steps_per_s: 0.0,
            cruise_steps_per_s: max_speed_within(0.0, 1.0, accel).min(segment.speed_limit),
            exit_steps_per_s: 0.0,
            accel_steps: 0,
            cruise_steps: 1,
            decel_steps: 0,
        };
    }
    let ramps = |cruise: f64| {
        let up = ramp_distance(entry, cruise, accel);
        let down = ramp_distance(cruise, exit, accel);
        (
            up,
            down,
            u64::from(up) + u64::from(down) <= u64::from(length),
        )
    };
    let mut low = entry.max(exit);
    let mut high = segment.speed_limit.max(low);
    let cruise = if ramps(high).2 {
        high
    } else {
        // With `A` whole steps up and `L − A` down, the highest cruise is
        // min(√(entry² + 4aA/π), √(exit² + 4a(L − A)/π)): best where the
        // two meet, at the exact lengths' split (c² = (4aL/π + entry² +
        // exit²)/2), so only the whole splits on either side of it count;
        // then a few ulps down while rounding puts the ramps over.
        let length_f = f64::from(length);
        let reach = |from: f64, steps: f64| sqrt(from * from + 4.0 * accel * steps / PI);
        let meet_sq = ((4.0 * accel * length_f / PI) + entry * entry + exit * exit) / 2.0;
        let split = (PI * (meet_sq - entry * entry) / (4.0 * accel)).clamp(0.0, length_f);
        let mut best = low;
        for up in [libm::floor(split), libm::ceil(split)] {
            let mut cruise = reach(entry, up)
                .min(reach(exit, length_f - up))
                .min(high)
                .max(low);
            let mut tries = 0;
            while cruise > low && !ramps(cruise).2 && tries < 64 {
                cruise = f64::from_bits(cruise.to_bits() - 1);
                tries += 1;
            }
            if ramps(cruise).2 && cruise > best {
                best = cruise;
            }
        }
        // Rounding beyond a few ulps: the bisection, as a last resort.
        if best == low && !ramps(low).2 {
            for _ in 0..200 {
                let mid = low + (high - low) / 2.0;
                if mid <= low || mid >= high {
                    break;
                }
                if ramps(mid).2 {
                    low = mid;
                } else {
                    high = mid;
                }
            }
            best = low;
        }
        best
    };
    let (accel_steps, decel_steps, fits) = ramps(cruise);
    debug_assert!(fits, "entry {entry} exit {exit} over {length} steps");
    Plan {
        entry_steps_per_s: entry,
        cruise_steps_per_s: cruise,
        exit_steps_per_s: exit,
        accel_steps,
        cruise_steps: length.saturating_sub(accel_steps.saturating_add(decel_steps)),
        decel_steps,
    }
}

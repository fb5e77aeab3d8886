//! Running a plan: the path's timeline, and every axis's step edges on it.
//!
//! A [`PathRunner`] owns a [`Planner`] and turns its frozen lines into
//! step edges, in time order, for every axis at once. It decides *when*
//! each step is; the axis cores that make the steps decide nothing about
//! the path (they count, check their limits and drive their pins).
//!
//! # The timeline
//!
//! Each line, once frozen, gets a start time (the end of the line before
//! it, plus any dwell) and its plan's three pieces: the entry ramp, the
//! cruise and the exit ramp ([`super::ramp`]: the seed's cosine in time).
//! A line's **progress** `s` (lead steps, 0 to `L`) is then a continuous,
//! increasing function of time, and so is the path's: the lines join at
//! speed, with zero acceleration.
//!
//! # The edges
//!
//! An axis with `n` steps in a line of `L` lead steps makes its step `i`
//! (1 to `|n|`) when the progress crosses `s = (i − ½)·L/|n|`: when the
//! line's continuous position on that axis crosses the middle between two
//! whole steps. So every axis is within half a step of the line at every
//! moment (position = the line's position rounded), the lead included,
//! every axis ends each line exactly on its target, and a corner between
//! lines with different leads needs no special case. Every axis's edges
//! come from one function of time, so they are consistent with each other
//! whatever axis is the lead. The edge CT is the start CT plus the time,
//! rounded down to a whole tick.
//!
//! # Hold, resume, cancel
//!
//! [`PathRunner::hold`] brings the path to rest **along the path**: from
//! the first point at or after the request where the plan's acceleration is
//! 0 (at once in a cruise, at the end of a ramp otherwise), a cosine ramp
//! to rest in path steps at the lowest path acceleration of the lines
//! ahead, provided it passes every junction within its limit (else from
//! the next such point). Edges already taken are never changed. Once every
//! edge up to the stop is taken, [`PathRunner::resume`] plans what is left
//! from rest — the rest of the line it stopped in (each axis's target minus
//! its position) and every line after it — so the program ends exactly
//! where it would have. [`PathRunner::cancel`] holds and then drops what is
//! queued.
//!
//! # Overrides
//!
//! [`PathRunner::set_overrides`] re-plans the lines not frozen with a
//! feed and a rapid override; the lines frozen (those being stepped)
//! keep their plans, so the change takes effect at the next junction not
//! frozen, without a jump in speed or acceleration.

use core::f64::consts::PI;

use super::queue::{Blending, Line, Machine, MachineError, Plan, Planner, PushError, Segment};
use super::ramp_time::{time_in_ramp, Ramp, Warm};
use super::sqrt::sqrt;

/// One step edge of the path: axis `axis` steps once, forwards or not,
/// with its rising edge at `ct`, in the line tagged `tag`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PathEdge {
    /// The CT of the rising edge.
    pub ct: u64,
    /// The axis (0-based, in the runner's order).
    pub axis: u8,
    /// Towards higher positions.
    pub forward: bool,
    /// The tag the line was pushed with (e.g. its G-code line number).
    pub tag: u32,
}

/// What the path is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathState {
    /// Nothing queued, nothing moving.
    Idle,
    /// Lines queued or running.
    Running,
    /// A hold is bringing the path to rest.
    Holding,
    /// At rest on the path after a hold: [`PathRunner::resume`] goes on.
    Held,
}

/// What the runner refuses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RunError {
    /// The line itself (see [`PushError`]).
    #[error(transparent)]
    Push(#[from] PushError),
    /// The line's end is beyond the range of a position (`i64`).
    #[error("the line's end is beyond the range of a position")]
    PositionOutOfRange,
    /// `resume` before the hold has come to rest, or without a hold.
    #[error("the path is not held at rest")]
    NotHeld,
    /// A dwell that is not 0 or more seconds and finite.
    #[error("a dwell must be 0 or more seconds and finite")]
    Dwell,
}

/// A queued line as the runner keeps it beside the planner.
#[derive(Clone, Copy, Debug, Default)]
struct Meta {
    tag: u32,
    blending: Option<Blending>,
    /// Dwell before this line starts (ticks).
    delay: f64,
    /// Path position at the line's start (path steps since the runner's origin).
    p0: f64,
    /// Start and end time (ticks since the origin), once timed.
    t0: f64,
    t1: f64,
    timed: bool,
    /// The plan's pieces in ticks, once timed.
    timing: Timing,
    /// Lead steps per path step, once timed (the speed of a line retired,
    /// whose segment is gone, still reads from its meta).
    lead_per_path: f64,
}

/// A frozen line's plan as its timeline uses it: the three speeds per
/// tick, the three lengths in lead steps, the three durations in ticks;
/// worked out once, when the line is timed.
#[derive(Clone, Copy, Debug, Default)]
struct Timing {
    entry: f64,
    cruise: f64,
    exit: f64,
    accel_steps: f64,
    cruise_steps: f64,
    decel_steps: f64,
    cruise_ticks: f64,
    /// The two ramps (their durations, and their constants for their
    /// inverses).
    accel_ramp: Ramp,
    decel_ramp: Ramp,
}

impl Timing {
    fn of(plan: &Plan, hz: f64) -> Self {
        let (entry, cruise, exit) = (
            plan.entry_steps_per_s / hz,
            plan.cruise_steps_per_s / hz,
            plan.exit_steps_per_s / hz,
        );
        let accel_steps = f64::from(plan.accel_steps);
        let cruise_steps = f64::from(plan.cruise_steps);
        let decel_steps = f64::from(plan.decel_steps);
        Timing {
            entry,
            cruise,
            exit,
            accel_steps,
            cruise_steps,
            decel_steps,
            cruise_ticks: if plan.cruise_steps > 0 {
                cruise_steps / cruise
            } else {
                0.0
            },
            accel_ramp: Ramp::new(accel_steps, entry, cruise),
            decel_ramp: Ramp::new(decel_steps, cruise, exit),
        }
    }

    fn duration(&self) -> f64 {
        self.accel_ramp.duration() + self.cruise_ticks + self.decel_ramp.duration()
    }
}

impl Meta {
    /// Path position and path speed (per tick) at time `t` in this line,
    /// once timed (it needs only the meta: a retired line still answers).
    fn path_state_at(&self, t: f64) -> (f64, f64) {
        let g = &self.timing;
        let tau = (t - self.t0).max(0.0);
        let (s, v) = if tau <= g.accel_ramp.duration() {
            (
                distance_in_ramp(tau, g.accel_steps, g.entry, g.cruise),
                speed_in_ramp(tau, g.accel_steps, g.entry, g.cruise),
            )
        } else if tau <= g.accel_ramp.duration() + g.cruise_ticks {
            (
                g.accel_steps + (tau - g.accel_ramp.duration()) * g.cruise,
                g.cruise,
            )
        } else {
            let x = (tau - g.accel_ramp.duration() - g.cruise_ticks).min(g.decel_ramp.duration());
            (
                g.accel_steps
                    + g.cruise_steps
                    + distance_in_ramp(x, g.decel_steps, g.cruise, g.exit),
                speed_in_ramp(x, g.decel_steps, g.cruise, g.exit),
            )
        };
        let r = self.lead_per_path;
        (self.p0 + s / r, v / r)
    }
}

/// What a resume keeps of a line not finished by a hold.
#[derive(Clone, Copy, Debug)]
struct Rest<const AXES: usize> {
    /// Its steps not made.
    line: Line<AXES>,
    tag: u32,
    blending: Option<Blending>,
    /// Its dwell (ticks; 0 once started).
    delay: f64,
}

/// One axis's next step.
#[derive(Clone, Copy, Debug, Default)]
struct Cursor {
    /// The queued line (index from the front) the next step is in; `len`
    /// when the axis has no step left in the queue.
    line: usize,
    /// The step within that line (1-based).
    step: u32,
}

/// Where an axis's last solve inside a line's ramp landed, and for which
/// step: its next step's solve in the same ramp starts from there
/// ([`Ramp::time_from`]). The chain is the same however the edges are
/// asked for (each axis's steps are solved in order, once each, and a
/// diagonal's axes share theirs), so the times are too, to the bit.
#[derive(Clone, Copy, Debug, PartialEq)]
struct AxisWarm {
    /// The line (counted from the runner's start: lines done + index).
    line: u64,
    /// The ramp down (else up).
    down: bool,
    /// The step solved (1-based, in the line).
    step: u32,
    warm: Warm,
}

/// The ramp to rest a hold runs (path coordinates).
#[derive(Clone, Copy, Debug, PartialEq)]
struct HoldRamp {
    p0: f64,
    p1: f64,
    t0: f64,
    /// Path speed at its start (path steps per tick).
    u0: f64,
}

impl HoldRamp {
    fn t1(&self) -> f64 {
        self.t0 + ramp_ticks(self.p1 - self.p0, self.u0, 0.0)
    }
}

/// Runs a stream of lines on up to `AXES` axes: `N` lines queued at most.
#[derive(Clone, Debug)]
pub struct PathRunner<const N: usize, const AXES: usize> {
    planner: Planner<N, AXES>,
    meta: [Meta; N],
    head: usize,
    cursors: [Cursor; AXES],
    /// Each axis's next edge time as last computed (`None`: to compute).
    next_cache: [Option<Option<f64>>; AXES],
    /// Where the solve of each axis's cached next edge landed, and of its
    /// edge before (the start of its next solve in the same ramp).
    next_warm: [Option<AxisWarm>; AXES],
    warm: [Option<AxisWarm>; AXES],
    /// CT of the timeline's origin.
    origin_ct: u64,
    /// Ticks per second.
    hz: f64,
    /// The time (ticks since the origin) of the latest edge taken.
    taken_t: f64,
    /// The end of the timed lines' timeline (ticks since the origin).
    timed_end: f64,
    /// Lines timed at the front of the queue.
    timed_lines: usize,
    /// Where the next pushed line starts on the path.
    next_p0: f64,
    /// A dwell pushed after the last line (ticks), for the next line.
    pending_delay: f64,
    /// The next line must start from rest (after a dwell or a pause).
    pending_stop: bool,
    blending: Blending,
    hold: Option<HoldRamp>,
    /// A hold that found no earlier point stops at the end of the queue.
    hold_at_end: bool,
    cancel: bool,
    /// Every axis's position after the edges taken.
    positions: [i64; AXES],
    /// Every axis's position after everything queued.
    targets: [i64; AXES],
    lines_done: u64,
    /// Lines dropped by a cancel or an emergency stop before any of their
    /// steps was made.
    lines_dropped: u64,
    last_tag: u32,
}

impl<const N: usize, const AXES: usize> PathRunner<N, AXES> {
    /// A runner for `machine` at rest at `positions`, its timeline starting
    /// at CT `origin_ct`, with `hz` ticks per second.
    pub fn new(
        machine: Machine<AXES>,
        positions: [i64; AXES],
        origin_ct: u64,
        hz: u32,
    ) -> Result<Self, MachineError> {
        let blending = machine.blending;
        Ok(PathRunner {
            planner: Planner::new(machine)?,
            meta: [Meta::default(); N],
            head: 0,
            cursors: [Cursor::default(); AXES],
            next_cache: [None; AXES],
            next_warm: [None; AXES],
            warm: [None; AXES],
            origin_ct,
            hz: f64::from(hz.max(1)),
            taken_t: 0.0,
            timed_end: 0.0,
            timed_lines: 0,
            next_p0: 0.0,
            pending_delay: 0.0,
            pending_stop: false,
            blending,
            hold: None,
            hold_at_end: false,
            cancel: false,
            positions,
            targets: positions,
            lines_done: 0,
            lines_dropped: 0,
            last_tag: 0,
        })
    }

    /// The CT the timeline's times count from (the start, or the last
    /// resume).
    pub fn origin_ct(&self) -> u64 {
        self.origin_ct
    }

    /// The planner (its queue and plans).
    pub fn planner(&self) -> &Planner<N, AXES> {
        &self.planner
    }

    /// Every axis's position after the edges taken so far.
    pub fn positions(&self) -> [i64; AXES] {
        self.positions
    }

    /// Every axis's position once everything queued has run.
    pub fn targets(&self) -> [i64; AXES] {
        self.targets
    }

    /// Lines queued (running ones included).
    pub fn queued(&self) -> usize {
        self.planner.len()
    }

    /// Whether a push would be refused as full.
    pub fn is_full(&self) -> bool {
        self.planner.is_full()
    }

    /// Lines whose every step has been taken, and lines a cancel or an
    /// emergency stop stopped part way.
    pub fn lines_done(&self) -> u64 {
        self.lines_done
    }

    /// Lines a cancel or an emergency stop dropped before any of their
    /// steps was made (a line stopped part way counts as done,
    /// [`Self::lines_done`]): pushed = done + queued + dropped.
    pub fn lines_dropped(&self) -> u64 {
        self.lines_dropped
    }

    /// Counts this runner's queue, about to be dropped: the lines none of
    /// whose steps has been made as dropped, those started as done.
    fn count_queue_dropped(&mut self) {
        let untouched = (0..self.planner.len())
            .filter(|&index| (0..AXES).all(|axis| self.made_in(axis, index) == 0))
            .count() as u64;
        self.lines_dropped += untouched;
        self.lines_done += self.planner.len() as u64 - untouched;
    }

    /// The tag of the line of the latest edge taken (0 before any).
    pub fn last_tag(&self) -> u32 {
        self.last_tag
    }

    /// What the path is doing.
    pub fn state(&self) -> PathState {
        if self.hold.is_some() || self.hold_at_end {
            if self.next_edge_time().is_none() {
                PathState::Held
            } else {
                PathState::Holding
            }
        } else if self.planner.is_empty() {
            PathState::Idle
        } else {
            PathState::Running
        }
    }

    /// Switches between exact stop and blending for the lines pushed from
    /// now on.
    pub fn set_blending(&mut self, blending: Blending) {
        self.blending = blending;
    }

    /// Sets the feed and rapid overrides (1 = 100 %) for the lines not
    /// frozen (see [`Planner::set_overrides`]).
    pub fn set_overrides(&mut self, feed_scale: f64, rapid_scale: f64) -> Result<(), RunError> {
        self.planner.set_overrides(feed_scale, rapid_scale)?;
        Ok(())
    }

    /// A pause of `seconds` at rest after the lines queued: the next line
    /// starts from rest that long after the last one ends.
    pub fn push_dwell(&mut self, seconds: f64) -> Result<(), RunError> {
        if !(seconds >= 0.0 && seconds.is_finite()) {
            return Err(RunError::Dwell);
        }
        self.pending_delay += seconds * self.hz;
        self.pending_stop = true;
        Ok(())
    }

    /// Queues `line`, tagged `tag`. Refused (nothing changes) when the
    /// queue is full, the line does not move, its feed is not above 0, or
    /// its end is beyond a position's range.
    pub fn push(&mut self, line: Line<AXES>, tag: u32) -> Result<(), RunError> {
        let mut targets = self.targets;
        for (target, &steps) in targets.iter_mut().zip(&line.steps) {
            *target = target
                .checked_add(i64::from(steps))
                .ok_or(RunError::PositionOutOfRange)?;
        }
        let blending = if self.pending_stop {
            Blending::ExactStop
        } else {
            self.blending
        };
        self.planner.set_blending(blending);
        self.planner.push(line)?;
        let length = sqrt(
            line.steps
                .iter()
                .map(|&steps| f64::from(steps) * f64::from(steps))
                .sum(),
        );
        let index = self.planner.len() - 1;
        self.meta[(self.head + index) % N] = Meta {
            tag,
            blending: Some(blending),
            delay: self.pending_delay,
            p0: self.next_p0,
            ..Meta::default()
        };
        self.next_p0 += length;
        self.pending_delay = 0.0;
        self.pending_stop = false;
        self.targets = targets;
        self.forget_no_next();
        // Axes with no step left in the queue find their next one here.
        for (cursor, &steps) in self.cursors.iter_mut().zip(&line.steps) {
            if cursor.line == index {
                if steps == 0 {
                    cursor.line = index + 1;
                } else {
                    cursor.step = 1;
                }
            }
        }
        Ok(())
    }

    /// [`Self::push`] for a runner on a clock: a line pushed when nothing
    /// is queued (the path ran dry, or has not started) starts from rest
    /// no earlier than `earliest_ct`, so that none of its edges is in the
    /// past (they would come in a burst to catch up). A line pushed behind
    /// others is timed as `push` times it. Refused as `push` is, with
    /// nothing changed.
    pub fn push_no_earlier_than(
        &mut self,
        line: Line<AXES>,
        tag: u32,
        earliest_ct: u64,
    ) -> Result<(), RunError> {
        let (delay, stop) = (self.pending_delay, self.pending_stop);
        if self.planner.is_empty() && self.hold.is_none() && !self.hold_at_end {
            let earliest = earliest_ct.saturating_sub(self.origin_ct) as f64;
            let gap = earliest - self.timeline_end();
            if gap > self.pending_delay {
                self.pending_delay = gap;
                self.pending_stop = true;
            }
        }
        let pushed = self.push(line, tag);
        if pushed.is_err() {
            (self.pending_delay, self.pending_stop) = (delay, stop);
        }
        pushed
    }

    /// The next edge, if it is due at or before `limit_ct`: taken (the
    /// positions count it). Lines are frozen and timed as the edges reach
    /// them, not before, so lines pushed meanwhile are still planned with.
    pub fn next_edge_until(&mut self, limit_ct: u64) -> Option<PathEdge> {
        self.next_edge_timed(limit_ct).map(|(edge, _)| edge)
    }

    /// [`Self::next_edge_until`], with the edge's exact time in ticks (the
    /// CT before it is rounded down to a whole tick).
    pub fn next_edge_timed(&mut self, limit_ct: u64) -> Option<(PathEdge, f64)> {
        self.settle_cancel();
        loop {
            let (axis, t) = match self.earliest() {
                Some(next) => next,
                None => {
                    if self.time_next_line() {
                        continue;
                    }
                    return None;
                }
            };
            // A line not yet timed may start before this edge.
            if let Some(start) = self.untimed_start() {
                if start <= t && self.time_next_line() {
                    continue;
                }
            }
            let ct = self.ct_of(t);
            if ct > limit_ct {
                return None;
            }
            return Some((self.take(axis, t, ct), self.origin_ct as f64 + t));
        }
    }

    /// The CT of the next edge, timing lines as needed (`None`: no edge is
    /// left in what is queued, or the path is held at rest).
    pub fn peek_ct(&mut self) -> Option<u64> {
        loop {
            match self.earliest() {
                Some((_, t)) => {
                    if let Some(start) = self.untimed_start() {
                        if start <= t && self.time_next_line() {
                            continue;
                        }
                    }
                    return Some(self.ct_of(t));
                }
                None => {
                    if !self.time_next_line() {
                        return None;
                    }
                }
            }
        }
    }

    /// When the path as planned comes to rest (the CT the last queued
    /// line's timeline ends, or the hold's), timing every line: for a
    /// whole program in virtual time.
    pub fn end_ct(&mut self) -> u64 {
        while self.time_next_line() {}
        if let Some(hold) = self.hold {
            return self.ct_of(hold.t1());
        }
        let end = (0..self.planner.len())
            .map(|index| self.meta_at(index).t1)
            .fold(self.taken_t, f64::max);
        self.ct_of(end)
    }

    /// Asks the path to come to rest along the path, from the first point
    /// at or after `at_ct` (and after every edge taken) where the plan's
    /// acceleration is 0. Holding or held already: nothing changes.
    pub fn hold(&mut self, at_ct: u64) {
        if self.hold.is_some() || self.hold_at_end || self.planner.is_empty() {
            return;
        }
        let from = (at_ct.saturating_sub(self.origin_ct) as f64).max(self.taken_t);
        // Time every line up to `from`.
        while self.timeline_end() < from && self.time_next_line() {}
        let lowest_accel = self.lowest_path_accel();
        let mut candidate = self.zero_accel_point(from);
        while let Some((index, t)) = candidate {
            let (p, u) = self.path_state_at(index, t);
            let distance = if u > 0.0 {
                PI * u * u / (4.0 * lowest_accel)
            } else {
                0.0
            };
            let ramp = HoldRamp {
                p0: p,
                p1: p + distance,
                t0: t,
                u0: u,
            };
            if ramp.p1 <= self.next_p0 && self.ramp_within_junctions(&ramp, index) {
                self.hold = Some(ramp);
                self.forget_all();
                return;
            }
            candidate = self.next_zero_accel_point(index, t);
        }
        // No earlier rest than the plan's own at the end of the queue.
        while self.time_next_line() {}
        self.hold_at_end = true;
    }

    /// [`Self::hold`], and an idle path (nothing queued) is held too: the
    /// lines pushed then wait for [`Self::resume`] (a feed hold in grbl's
    /// Idle state). A stop pin holds only what moves ([`Self::hold`]).
    pub fn hold_even_idle(&mut self, at_ct: u64) {
        if self.planner.is_empty() && self.hold.is_none() {
            self.hold_at_end = true;
            self.forget_all();
        } else {
            self.hold(at_ct);
        }
    }

    /// Whether the path is held at rest: every edge up to the stop taken.
    pub fn is_held(&self) -> bool {
        self.state() == PathState::Held
    }

    /// Goes on after a hold has come to rest: what is left is planned from
    /// rest, its timeline starting at `at_ct`. Refused unless held at rest.
    pub fn resume(&mut self, at_ct: u64) -> Result<(), RunError> {
        if !self.is_held() {
            return Err(RunError::NotHeld);
        }
        // Not before the path has come to rest: the hold's ramp ends after
        // its last edge, and a start from rest before that end would join
        // it with a jump in acceleration.
        let at_ct = at_ct.max(self.end_ct().saturating_add(1));
        let cancel = self.cancel;
        // What is left, kept compactly: a runner is a board's largest
        // object, and this runs on its stack beside a fresh one.
        let mut rest = [Rest {
            line: Line {
                steps: [0; AXES],
                feed_steps_per_s: 1.0,
            },
            tag: 0,
            blending: None,
            delay: 0.0,
        }; N];
        let mut count = 0;
        if !cancel {
            for index in 0..self.planner.len() {
                let segment = self.segment(index);
                let mut line = *segment.line();
                for (axis, steps) in line.steps.iter_mut().enumerate() {
                    let made = self.made_in(axis, index);
                    *steps = steps.signum() * (steps.unsigned_abs() - made) as i32;
                }
                if line.steps.iter().any(|&steps| steps != 0) {
                    let meta = self.meta_at(index);
                    rest[count] = Rest {
                        line,
                        tag: meta.tag,
                        blending: meta.blending,
                        // Started: its dwell is behind it.
                        delay: if line.steps != segment.line().steps {
                            0.0
                        } else {
                            meta.delay
                        },
                    };
                    count += 1;
                }
            }
        }
        let blending = self.blending;
        if cancel {
            self.count_queue_dropped();
        }
        self.rest_from(at_ct);
        for (index, left) in rest.iter().take(count).enumerate() {
            // The first line leaves from rest; the others keep their mode
            // and their dwells.
            self.blending = if index == 0 {
                Blending::ExactStop
            } else {
                left.blending.unwrap_or(blending)
            };
            if left.delay > 0.0 {
                self.pending_delay = left.delay;
                self.pending_stop = true;
            }
            self.push(left.line, left.tag)
                .expect("the rest of a queue fits in it");
        }
        self.blending = blending;
        Ok(())
    }

    /// Asks the path to come to rest along the path (as [`Self::hold`]) and
    /// drops every line queued once it is at rest: [`Self::resume`] then
    /// leaves the runner idle at the positions reached.
    pub fn cancel(&mut self, at_ct: u64) {
        self.hold(at_ct);
        self.cancel = true;
    }

    /// A cancelled path at rest drops what is left.
    fn settle_cancel(&mut self) {
        if self.cancel && self.is_held() {
            let at = self.ct_of(self.taken_t);
            let _ = self.resume(at);
        }
    }

    /// Stops at once: drops every line and every edge not taken (an
    /// emergency stop); the positions are those of the edges taken.
    pub fn emergency_stop(&mut self) {
        let taken_t = self.taken_t;
        self.count_queue_dropped();
        self.rest_from(self.origin_ct);
        self.taken_t = taken_t;
        self.timed_end = taken_t;
    }

    /// Empties this runner in place (a runner is a board's largest object:
    /// no second one on its stack): at rest at its positions, with its
    /// machine, overrides, mode and counts, its timeline starting at
    /// `origin_ct` — what [`Self::new`] makes of them.
    fn rest_from(&mut self, origin_ct: u64) {
        self.planner.clear();
        for meta in &mut self.meta {
            *meta = Meta::default();
        }
        self.head = 0;
        self.cursors = [Cursor::default(); AXES];
        self.forget_all();
        self.origin_ct = origin_ct;
        self.taken_t = 0.0;
        self.timed_end = 0.0;
        self.timed_lines = 0;
        self.next_p0 = 0.0;
        self.pending_delay = 0.0;
        self.pending_stop = false;
        self.hold = None;
        self.hold_at_end = false;
        self.cancel = false;
        self.targets = self.positions;
    }

    /// The path's speed at `ct` (path steps/s, in step space), for a
    /// progress display; 0 outside the timeline.
    pub fn path_speed_at(&self, ct: u64) -> f64 {
        let t = ct.saturating_sub(self.origin_ct) as f64;
        if let Some(hold) = self.hold {
            if t >= hold.t0 {
                return speed_in_ramp(t - hold.t0, hold.p1 - hold.p0, hold.u0, 0.0) * self.hz;
            }
        }
        for index in 0..self.planner.len() {
            let meta = self.meta_at(index);
            if meta.timed && t >= meta.t0 && t < meta.t1 {
                let (_, u) = self.path_state_at(index, t);
                return u * self.hz;
            }
        }
        // A line whose every edge is taken is retired while the clock is
        // still in it (the edges are computed ahead): its meta stays in its
        // slot until a push reuses it, newest first behind the head.
        for back in 1..=N - self.planner.len() {
            let meta = &self.meta[(self.head + N - back) % N];
            if !meta.timed || t >= meta.t1 {
                break;
            }
            if t >= meta.t0 {
                return meta.path_state_at(t).1 * self.hz;
            }
        }
        0.0
    }

    // ----- the timeline -----

    fn segment(&self, index: usize) -> &Segment<AXES> {
        self.planner.get(index).expect("a queued line")
    }

    fn meta_at(&self, index: usize) -> &Meta {
        &self.meta[(self.head + index) % N]
    }

    fn meta_mut(&mut self, index: usize) -> &mut Meta {
        &mut self.meta[(self.head + index) % N]
    }

    fn ct_of(&self, t: f64) -> u64 {
        // `as` saturates: a time before the origin (or NaN) is 0 ticks
        // after it, with no `f64::max` (a library call on an M0+, each
        // edge).
        self.origin_ct.saturating_add(t as u64)
    }

    /// Lines timed at the front.
    fn timed(&self) -> usize {
        self.timed_lines
    }

    /// The end of the timed lines' timeline (ticks).
    fn timeline_end(&self) -> f64 {
        self.timed_end
    }

    /// The start time the next line to time would get, unless a hold ends
    /// the timeline first.
    fn untimed_start(&self) -> Option<f64> {
        if self.hold.is_some() || self.hold_at_end {
            return None;
        }
        let timed = self.timed();
        if timed >= self.planner.len() {
            return None;
        }
        Some(self.timeline_end() + self.meta_at(timed).delay)
    }

    /// Freezes and times the next line; false when there is none (or a
    /// hold ends the timeline).
    fn time_next_line(&mut self) -> bool {
        let Some(t0) = self.untimed_start() else {
            return false;
        };
        let index = self.timed();
        self.planner.freeze_front(index + 1);
        let timing = Timing::of(&self.segment(index).plan(), self.hz);
        let lead_per_path = self.segment(index).lead_per_path();
        let duration = timing.duration();
        let meta = self.meta_mut(index);
        meta.lead_per_path = lead_per_path;
        meta.t0 = t0;
        meta.t1 = t0 + duration;
        meta.timed = true;
        meta.timing = timing;
        self.forget_no_next();
        self.timed_end = t0 + duration;
        self.timed_lines += 1;
        true
    }

    /// Time (ticks since the origin) at lead progress `s` of a timed line,
    /// a solve in one of its ramps starting from `warm` if that landed in
    /// the same ramp; and where the solve landed (ramp down or up).
    fn time_in_line(
        &self,
        index: usize,
        s: f64,
        warm: Option<&AxisWarm>,
    ) -> (f64, Option<(bool, Warm)>) {
        let meta = self.meta_at(index);
        let g = &meta.timing;
        let (a, c) = (g.accel_steps, g.cruise_steps);
        let from = |down: bool| warm.filter(|warm| warm.down == down).map(|warm| &warm.warm);
        if s <= a {
            let (tau, landed) = g.accel_ramp.time_from(s, from(false));
            return (meta.t0 + tau, landed.map(|landed| (false, landed)));
        }
        if s <= a + c {
            return (meta.t0 + g.accel_ramp.duration() + (s - a) / g.cruise, None);
        }
        let x = (s - a - c).min(g.decel_steps);
        let (tau, landed) = g.decel_ramp.time_from(x, from(true));
        (
            meta.t0 + g.accel_ramp.duration() + g.cruise_ticks + tau,
            landed.map(|landed| (true, landed)),
        )
    }

    /// Path position and path speed (per tick) at time `t` within timed
    /// line `index`.
    fn path_state_at(&self, index: usize, t: f64) -> (f64, f64) {
        self.meta_at(index).path_state_at(t)
    }

    /// The first point at or after `t` where the plan's acceleration is 0:
    /// (line, time).
    fn zero_accel_point(&self, t: f64) -> Option<(usize, f64)> {
        for index in 0..self.timed() {
            let meta = self.meta_at(index);
            if t > meta.t1 {
                continue;
            }
            for (start, end, ramp) in self.pieces(index) {
                if t <= start {
                    return Some((index, start));
                }
                if t <= end {
                    return Some((index, if ramp { end } else { t }));
                }
            }
        }
        None
    }

    /// The next point after `(index, t)` where the acceleration is 0 (a
    /// piece boundary), timing lines as needed.
    fn next_zero_accel_point(&mut self, index: usize, t: f64) -> Option<(usize, f64)> {
        let mut index = index;
        loop {
            if index >= self.timed() && !self.time_next_line() {
                return None;
            }
            for (start, end, _) in self.pieces(index) {
                if start > t {
                    return Some((index, start));
                }
                if end > t {
                    return Some((index, end));
                }
            }
            index += 1;
        }
    }

    /// A timed line's pieces: (start, end, is a ramp), times in ticks.
    fn pieces(&self, index: usize) -> [(f64, f64, bool); 3] {
        let meta = self.meta_at(index);
        let (t0, g) = (meta.t0, &meta.timing);
        let cruise_at = t0 + g.accel_ramp.duration();
        let decel_at = cruise_at + g.cruise_ticks;
        [
            (t0, cruise_at, true),
            (cruise_at, decel_at, false),
            (decel_at, meta.t1, true),
        ]
    }

    /// The tests' view of the acceleration: times every line queued and
    /// gives, for each piece of each line's plan (ramp, cruise, ramp) that
    /// lasts, in order: the path speed at its start and end, the path
    /// acceleration just inside its start and its end (a difference over a
    /// millionth of the piece), and the piece's peak acceleration from its
    /// closed form — speeds per tick, accelerations per tick².
    #[cfg(test)]
    pub(crate) fn pieces_seen(&mut self) -> Vec<[f64; 5]> {
        while self.time_next_line() {}
        let mut seen = Vec::new();
        for index in 0..self.timed() {
            let r = self.segment(index).lead_per_path();
            let g = self.meta_at(index).timing;
            let peak = |from: f64, to: f64, ticks: f64| PI * (to - from).abs() / (2.0 * ticks * r);
            let pieces = [
                (
                    g.accel_ramp.duration(),
                    peak(g.entry, g.cruise, g.accel_ramp.duration()),
                ),
                (g.cruise_ticks, 0.0),
                (
                    g.decel_ramp.duration(),
                    peak(g.cruise, g.exit, g.decel_ramp.duration()),
                ),
            ];
            for ((start, end, _), (ticks, peak)) in self.pieces(index).into_iter().zip(pieces) {
                if ticks <= 0.0 {
                    continue;
                }
                let d = (end - start) * 1e-6;
                let u = |t: f64| self.path_state_at(index, t).1;
                seen.push([
                    u(start),
                    u(end),
                    (u(start + 2.0 * d) - u(start + d)) / d,
                    (u(end - d) - u(end - 2.0 * d)) / d,
                    peak,
                ]);
            }
        }
        seen
    }

    /// The lowest path acceleration (per tick²) of the lines queued.
    fn lowest_path_accel(&self) -> f64 {
        self.planner
            .iter()
            .map(|segment| segment.accel_limit_steps_per_s2() / segment.lead_per_path())
            .fold(f64::INFINITY, f64::min)
            / (self.hz * self.hz)
    }

    /// Whether the hold's ramp passes every junction and line ahead of
    /// line `index` within its speed limits.
    fn ramp_within_junctions(&self, ramp: &HoldRamp, index: usize) -> bool {
        for next in index + 1..self.planner.len() {
            let p = self.meta_at(next).p0;
            if p >= ramp.p1 {
                break;
            }
            let segment = self.segment(next);
            let limit = segment
                .junction_limit_steps_per_s()
                .min(segment.speed_limit_steps_per_s() / segment.lead_per_path())
                / self.hz;
            let tau = time_in_ramp(p - ramp.p0, ramp.p1 - ramp.p0, ramp.u0, 0.0);
            let u = speed_in_ramp(tau, ramp.p1 - ramp.p0, ramp.u0, 0.0);
            if u > limit * (1.0 + 1e-9) {
                return false;
            }
        }
        true
    }

    // ----- the edges -----

    /// How many steps `axis` has taken in line `index`.
    fn made_in(&self, axis: usize, index: usize) -> u32 {
        let cursor = self.cursors[axis];
        let total = self.segment(index).line().steps[axis].unsigned_abs();
        match cursor.line.cmp(&index) {
            core::cmp::Ordering::Less => 0,
            core::cmp::Ordering::Equal => cursor.step - 1,
            core::cmp::Ordering::Greater => total,
        }
    }

    /// The time of `axis`'s next edge, if its line is timed (or the hold
    /// covers it); `None` past the hold's stop or the queue.
    fn axis_next_time(&self, axis: usize) -> Option<f64> {
        self.axis_next(axis).map(|(t, _)| t)
    }

    /// [`Self::axis_next_time`], and where its solve landed if it solved
    /// in a line's ramp (from where the axis's last one landed, if that was
    /// the step before in the same ramp).
    fn axis_next(&self, axis: usize) -> Option<(f64, Option<AxisWarm>)> {
        let cursor = self.cursors[axis];
        if cursor.line >= self.planner.len() {
            return None;
        }
        let segment = self.segment(cursor.line);
        let steps = segment.line().steps[axis].unsigned_abs();
        let lead = f64::from(segment.lead_steps());
        let s = (f64::from(cursor.step) - 0.5) * lead / f64::from(steps);
        let meta = self.meta_at(cursor.line);
        if let Some(hold) = self.hold {
            let p = meta.p0 + s / segment.lead_per_path();
            if p >= hold.p0 {
                if p > hold.p1 {
                    return None;
                }
                return Some((
                    hold.t0 + time_in_ramp(p - hold.p0, hold.p1 - hold.p0, hold.u0, 0.0),
                    None,
                ));
            }
        }
        if !meta.timed {
            return None;
        }
        let line = self.lines_done + cursor.line as u64;
        let warm = self.warm[axis]
            .filter(|warm| warm.line == line && warm.step.checked_add(1) == Some(cursor.step));
        let (t, landed) = self.time_in_line(cursor.line, s, warm.as_ref());
        let landed = landed.map(|(down, warm)| AxisWarm {
            line,
            down,
            step: cursor.step,
            warm,
        });
        Some((t, landed))
    }

    fn next_edge_time(&self) -> Option<f64> {
        (0..AXES)
            .filter_map(|axis| self.axis_next_time(axis))
            .reduce(f64::min)
    }

    /// [`Self::axis_next_time`], computed once per step of the axis (the
    /// cache is dropped when a hold is set or the runner starts over; a
    /// line pushed or timed drops only the axes that had no next edge:
    /// [`Self::forget_no_next`]).
    fn cached_next_time(&mut self, axis: usize) -> Option<f64> {
        if let Some(known) = self.next_cache[axis] {
            debug_assert_eq!(
                known.map(f64::to_bits),
                self.axis_next_time(axis).map(f64::to_bits),
                "axis {axis}'s cached next edge time is stale"
            );
            return known;
        }
        let next = match self.same_next_time(axis) {
            Some(known) => known,
            None => self.axis_next(axis),
        };
        self.next_cache[axis] = Some(next.map(|(t, _)| t));
        self.next_warm[axis] = next.and_then(|(_, warm)| warm);
        next.map(|(t, _)| t)
    }

    /// Drops every axis's cached next edge and the solves' landings (a
    /// hold, a fresh start).
    fn forget_all(&mut self) {
        self.next_cache = [None; AXES];
        self.next_warm = [None; AXES];
        self.warm = [None; AXES];
    }

    /// The next edge time of `axis` when another axis has it cached already
    /// for the very same progress: the same line, the same step and as many
    /// steps in the line (a diagonal's axes), so the same inputs and the
    /// same time to the bit. On a core without an FPU each time off the
    /// line's cruise is a ramp's inverse in software `f64` (most of an
    /// M0+'s work on a ramp): a 45° move of three axes solves it once per
    /// step instead of three times.
    fn same_next_time(&self, axis: usize) -> Option<Option<(f64, Option<AxisWarm>)>> {
        let cursor = self.cursors[axis];
        let other = (0..AXES).find(|&other| {
            other != axis
                && matches!(self.next_cache[other], Some(Some(_)))
                && self.cursors[other].line == cursor.line
                && self.cursors[other].step == cursor.step
        })?;
        // A cursor with a cached time is in the queue.
        let steps = self.segment(cursor.line).line().steps;
        (steps[other].unsigned_abs() == steps[axis].unsigned_abs())
            .then(|| self.next_cache[other].map(|next| next.map(|t| (t, self.next_warm[other]))))?
    }

    /// A line pushed or timed: the axes that had no next edge (their line
    /// was not timed, or not queued) may have one now. An axis's next edge
    /// in a timed line stays as it was: a timed line is frozen (its plan,
    /// its start and its timing no longer change), and pushing or timing a
    /// line after it does not move its cursor. (Each time is a ramp's
    /// inverse, `f64` trigonometry in software on the firmware's cores: a
    /// program's first lines, timed one by one, computed every axis's next
    /// edge again for each.)
    fn forget_no_next(&mut self) {
        for cached in &mut self.next_cache {
            if *cached == Some(None) {
                *cached = None;
            }
        }
    }

    /// The axis whose edge comes first (the lowest index on a tie), and when.
    fn earliest(&mut self) -> Option<(usize, f64)> {
        let mut best: Option<(usize, f64)> = None;
        for axis in 0..AXES {
            if let Some(t) = self.cached_next_time(axis) {
                if best.is_none_or(|(_, bt)| t < bt) {
                    best = Some((axis, t));
                }
            }
        }
        best
    }

    fn take(&mut self, axis: usize, t: f64, ct: u64) -> PathEdge {
        let cursor = self.cursors[axis];
        let line = *self.segment(cursor.line).line();
        let tag = self.meta_at(cursor.line).tag;
        let forward = line.steps[axis] > 0;
        self.positions[axis] += if forward { 1 } else { -1 };
        if t > self.taken_t {
            self.taken_t = t;
        }
        self.last_tag = tag;
        // On to the next step: this line's, or the next line's with a step.
        let mut next = cursor;
        next.step += 1;
        if next.step > line.steps[axis].unsigned_abs() {
            next.line += 1;
            next.step = 1;
            while next.line < self.planner.len() && self.segment(next.line).line().steps[axis] == 0
            {
                next.line += 1;
            }
        }
        self.cursors[axis] = next;
        self.next_cache[axis] = None;
        self.warm[axis] = self.next_warm[axis].take();
        self.retire();
        PathEdge {
            ct,
            axis: axis as u8,
            forward,
            tag,
        }
    }

    /// Pops the lines every axis is done with (and whose time has come).
    fn retire(&mut self) {
        while !self.planner.is_empty() && self.cursors.iter().all(|cursor| cursor.line > 0) {
            self.planner.pop_front();
            if self.meta_at(0).timed {
                self.timed_lines -= 1;
            }
            self.head = (self.head + 1) % N;
            for cursor in &mut self.cursors {
                cursor.line -= 1;
            }
            self.lines_done += 1;
        }
    }
}

/// A cosine ramp's duration over `d` from `u0` to `u1` (per tick).
fn ramp_ticks(d: f64, u0: f64, u1: f64) -> f64 {
    if d <= 0.0 {
        0.0
    } else {
        2.0 * d / (u0 + u1)
    }
}

/// Distance covered `tau` into the cosine ramp of length `d` from `u0` to
/// `u1`: `m·τ − h·(T/π)·sin(πτ/T)`.
pub(super) fn distance_in_ramp(tau: f64, d: f64, u0: f64, u1: f64) -> f64 {
    if d <= 0.0 {
        return 0.0;
    }
    let m = (u0 + u1) / 2.0;
    let h = (u1 - u0) / 2.0;
    let t = d / m;
    let w = PI / t;
    let tau = tau.clamp(0.0, t);
    m * tau - h / w * libm::sin(w * tau)
}

/// Speed `tau` into the ramp: `m − h·cos(πτ/T)`.
fn speed_in_ramp(tau: f64, d: f64, u0: f64, u1: f64) -> f64 {
    if d <= 0.0 {
        return u1;
    }
    let m = (u0 + u1) / 2.0;
    let h = (u1 - u0) / 2.0;
    let t = d / m;
    let tau = tau.clamp(0.0, t);
    m - h * libm::cos(PI * tau / t)
}

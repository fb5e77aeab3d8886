//! A grbl-style trapezoid look-ahead: the comparison for cogstep's
//! planner (`cogstep_motion::planner`).
//!
//! The same lines, the same machine and the same junction limits as
//! cogstep's planner — grbl's junction deviation with Klipper's chord
//! bound ([`junction_deviation_speed`], [`chord_speed`]), every axis's
//! speed and acceleration as a limit on the line, the machine able to stop
//! by the end of what is queued — and the same backward and forward passes
//! over a queue of the same length, but **constant-acceleration ramps**:
//! a line is a trapezoid (or a triangle) in speed, `v² = v0² + 2·a·s`.
//! Only the ramp differs, so the two total times compare the curves.
//!
//! A trapezoid's acceleration jumps by `a` at every ramp's start and end
//! (by `2a` at a triangle's peak); [`LookaheadSummary`] counts those jumps.
//! cogstep's cosine ramps have none (their acceleration is 0 at both ends
//! of every ramp), at the price of a longer ramp for the same peak (`π/2`
//! of a trapezoid's distance from rest).
//!
//! # Units
//!
//! Everything here is along the path in step space (path steps, path
//! steps/s), as the planner's junction speeds are: a line of lead `L`
//! steps and Euclidean length `E` has path limits `limit_lead · E/L`.
//!
//! # Streaming
//!
//! [`TrapezoidLookahead::push`] takes a line; when the queue is at its
//! capacity `N` the front line is run first (its plan is final then: its
//! entry was fixed when the line before it ran, its exit is the backward
//! bound of what is queued). [`TrapezoidLookahead::finish`] runs the rest.

use cogstep_motion::planner::{
    chord_speed, junction_deviation_speed, Blending, Line, Machine, MachineError, PushError,
};

/// Relative speed difference below which two speeds are the same (no
/// ramp between them).
const SAME_SPEED: f64 = 1e-9;

/// A queued line, in path units.
#[derive(Clone, Copy, Debug)]
struct Block<const AXES: usize> {
    unit: [f64; AXES],
    length: f64,
    speed_limit: f64,
    accel: f64,
    junction_limit: f64,
    /// The planned speed at the line's start.
    entry: f64,
    /// A dwell (s) at rest before the line.
    dwell_s: f64,
}

impl<const AXES: usize> Block<AXES> {
    const EMPTY: Self = Block {
        unit: [0.0; AXES],
        length: 0.0,
        speed_limit: 0.0,
        accel: 0.0,
        junction_limit: 0.0,
        entry: 0.0,
        dwell_s: 0.0,
    };
}

/// What a stream came to.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LookaheadSummary {
    /// Lines run.
    pub lines: u64,
    /// The stream's total time (s), dwells included.
    pub total_time_s: f64,
    /// Points where the path acceleration jumps (a ramp's start or end
    /// against what comes before or after it).
    pub accel_jumps: u64,
    /// The largest such jump (path steps/s²).
    pub largest_jump_steps_per_s2: f64,
}

/// A trapezoid look-ahead over at most `N` queued lines of `AXES` axes.
#[derive(Clone, Debug)]
pub struct TrapezoidLookahead<const N: usize, const AXES: usize> {
    machine: Machine<AXES>,
    queue: [Block<AXES>; N],
    head: usize,
    len: usize,
    /// The speed at the front's start (fixed once the line before it ran).
    front_entry: f64,
    /// The path acceleration at the end of what has run.
    last_accel: f64,
    pending_dwell_s: f64,
    pending_stop: bool,
    summary: LookaheadSummary,
}

impl<const N: usize, const AXES: usize> TrapezoidLookahead<N, AXES> {
    /// An empty look-ahead for `machine` (checked as the planner checks it).
    pub fn new(machine: Machine<AXES>) -> Result<Self, MachineError> {
        // The planner's checks, once.
        cogstep_motion::planner::Planner::<1, AXES>::new(machine)?;
        Ok(TrapezoidLookahead {
            machine,
            queue: [Block::EMPTY; N],
            head: 0,
            len: 0,
            front_entry: 0.0,
            last_accel: 0.0,
            pending_dwell_s: 0.0,
            pending_stop: false,
            summary: LookaheadSummary::default(),
        })
    }

    /// Exact stop or blending for the lines pushed from now on.
    pub fn set_blending(&mut self, blending: Blending) {
        self.machine.blending = blending;
    }

    /// A pause of `seconds` at rest before the next line.
    pub fn push_dwell(&mut self, seconds: f64) {
        self.pending_dwell_s += seconds.max(0.0);
        self.pending_stop = true;
    }

    /// Lines queued.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether nothing is queued.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    fn at(&self, index: usize) -> &Block<AXES> {
        &self.queue[(self.head + index) % N]
    }

    fn at_mut(&mut self, index: usize) -> &mut Block<AXES> {
        &mut self.queue[(self.head + index) % N]
    }

    /// Queues `line` (running the front line first when the queue is full)
    /// and re-plans.
    pub fn push(&mut self, line: Line<AXES>) -> Result<(), PushError> {
        if line.feed_steps_per_s.is_nan() || line.feed_steps_per_s <= 0.0 {
            return Err(PushError::Feed);
        }
        let lead = line
            .steps
            .iter()
            .map(|steps| steps.unsigned_abs())
            .max()
            .unwrap_or(0);
        if lead == 0 {
            return Err(PushError::NoMotion);
        }
        if N == 0 {
            return Err(PushError::Full);
        }
        if self.len == N {
            self.run_front();
        }
        let lead = f64::from(lead);
        let length = libm::sqrt(
            line.steps
                .iter()
                .map(|&s| f64::from(s) * f64::from(s))
                .sum::<f64>(),
        );
        let mut unit = [0.0; AXES];
        let (mut speed_lead, mut accel_lead) = (f64::INFINITY, f64::INFINITY);
        for (axis, &steps) in line.steps.iter().enumerate() {
            unit[axis] = f64::from(steps) / length;
            if steps != 0 {
                let lead_per_axis = lead / f64::from(steps.unsigned_abs());
                speed_lead =
                    speed_lead.min(self.machine.max_speed_steps_per_s[axis] * lead_per_axis);
                accel_lead =
                    accel_lead.min(self.machine.max_accel_steps_per_s2[axis] * lead_per_axis);
            }
        }
        let lead_per_path = (lead / length).min(1.0);
        let speed_limit = line.feed_steps_per_s.min(speed_lead) / lead_per_path;
        let accel = accel_lead / lead_per_path;
        let stop = self.pending_stop || self.machine.blending == Blending::ExactStop;
        let junction_limit = match self.len.checked_sub(1).map(|last| *self.at(last)) {
            Some(prev) if !stop => {
                let corner = junction_deviation_speed(
                    &prev.unit,
                    &unit,
                    prev.accel.min(accel),
                    self.machine.junction_deviation_steps,
                )
                .min(chord_speed(&prev.unit, &unit, prev.length, prev.accel))
                .min(chord_speed(&prev.unit, &unit, length, accel));
                corner.min(prev.speed_limit).min(speed_limit)
            }
            _ => 0.0,
        };
        let block = Block {
            unit,
            length,
            speed_limit,
            accel,
            junction_limit,
            entry: 0.0,
            dwell_s: self.pending_dwell_s,
        };
        let index = self.len;
        self.len += 1;
        *self.at_mut(index) = block;
        if index == 0 && stop {
            self.front_entry = 0.0;
        }
        self.pending_dwell_s = 0.0;
        self.pending_stop = false;
        self.replan();
        Ok(())
    }

    /// The backward and forward passes; the front's entry is fixed.
    fn replan(&mut self) {
        if self.len == 0 {
            return;
        }
        // Backward: each line's highest entry, from a stop at the end.
        let mut exit = 0.0f64;
        for index in (1..self.len).rev() {
            let block = self.at_mut(index);
            let entry = libm::sqrt(exit * exit + 2.0 * block.accel * block.length);
            block.entry = entry.min(block.junction_limit);
            exit = block.entry;
        }
        // Forward: what each entry reaches.
        let mut entry = self.front_entry;
        self.at_mut(0).entry = entry;
        for index in 0..self.len - 1 {
            let block = *self.at(index);
            let reach = libm::sqrt(entry * entry + 2.0 * block.accel * block.length);
            let next = self.at_mut(index + 1);
            next.entry = next.entry.min(reach);
            entry = next.entry;
        }
    }

    /// Runs the front line with its plan: time and acceleration jumps.
    fn run_front(&mut self) {
        if self.len == 0 {
            return;
        }
        let block = *self.at(0);
        let exit = if self.len > 1 { self.at(1).entry } else { 0.0 };
        let (v0, v1, a, length) = (block.entry, exit, block.accel, block.length);
        if block.dwell_s > 0.0 {
            self.summary.total_time_s += block.dwell_s;
        }
        // The highest cruise whose two ramps fit.
        let peak = libm::sqrt((2.0 * a * length + v0 * v0 + v1 * v1) / 2.0);
        let cruise = block.speed_limit.min(peak).max(v0).max(v1);
        let up = (cruise * cruise - v0 * v0).max(0.0) / (2.0 * a);
        let down = (cruise * cruise - v1 * v1).max(0.0) / (2.0 * a);
        let flat = (length - up - down).max(0.0);
        let mut time = 0.0;
        let mut pieces: [(f64, f64); 3] = [(0.0, 0.0); 3];
        let mut count = 0;
        if cruise - v0 > SAME_SPEED * cruise {
            time += (cruise - v0) / a;
            pieces[count] = (a, up);
            count += 1;
        }
        if flat > 0.0 && cruise > 0.0 {
            time += flat / cruise;
            pieces[count] = (0.0, flat);
            count += 1;
        }
        if cruise - v1 > SAME_SPEED * cruise {
            time += (cruise - v1) / a;
            pieces[count] = (-a, down);
            count += 1;
        }
        for &(accel, _) in &pieces[..count] {
            self.jump(accel);
        }
        self.summary.total_time_s += time;
        self.summary.lines += 1;
        self.head = (self.head + 1) % N;
        self.len -= 1;
        self.front_entry = exit;
        if exit == 0.0 {
            // At rest between lines: the acceleration is 0 there.
            self.jump(0.0);
        }
    }

    fn jump(&mut self, accel: f64) {
        let jump = (accel - self.last_accel).abs();
        if jump > 0.0 {
            self.summary.accel_jumps += 1;
            self.summary.largest_jump_steps_per_s2 =
                self.summary.largest_jump_steps_per_s2.max(jump);
        }
        self.last_accel = accel;
    }

    /// Runs everything queued and says what the stream came to.
    pub fn finish(mut self) -> LookaheadSummary {
        while self.len > 0 {
            self.run_front();
        }
        self.jump(0.0);
        self.summary
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn machine() -> Machine<2> {
        Machine {
            max_speed_steps_per_s: [10_000.0, 10_000.0],
            max_accel_steps_per_s2: [100_000.0, 100_000.0],
            junction_deviation_steps: 1.0,
            blending: Blending::Blend,
        }
    }

    fn line(x: i32, y: i32, feed: f64) -> Line<2> {
        Line {
            steps: [x, y],
            feed_steps_per_s: feed,
        }
    }

    #[test]
    fn one_line_is_the_closed_form_trapezoid() {
        // 10 000 steps at 5 000 steps/s and 100 000 steps/s²: ramps of
        // 0.05 s and 125 steps each, 9 750 steps at speed.
        let mut planner = TrapezoidLookahead::<8, 2>::new(machine()).unwrap();
        planner.push(line(10_000, 0, 5_000.0)).unwrap();
        let summary = planner.finish();
        let expected = 2.0 * 0.05 + 9_750.0 / 5_000.0;
        assert!(
            (summary.total_time_s - expected).abs() < 1e-9,
            "{summary:?}"
        );
        // Up at the start, off at the cruise, on at the decel, off at rest.
        assert_eq!(summary.accel_jumps, 4);
        assert_eq!(summary.largest_jump_steps_per_s2, 100_000.0);
    }

    #[test]
    fn collinear_lines_blend_and_exact_stop_is_slower() {
        let run = |blending| {
            let mut planner = TrapezoidLookahead::<16, 2>::new(machine()).unwrap();
            planner.set_blending(blending);
            for _ in 0..40 {
                planner.push(line(250, 0, 5_000.0)).unwrap();
            }
            planner.finish()
        };
        let blend = run(Blending::Blend);
        let stop = run(Blending::ExactStop);
        // One long trapezoid: the same as a single line of 10 000 steps.
        let single = 2.0 * 0.05 + 9_750.0 / 5_000.0;
        assert!((blend.total_time_s - single).abs() < 1e-6, "{blend:?}");
        assert_eq!(blend.accel_jumps, 4);
        assert!((stop.total_time_s - 40.0 * 0.1).abs() < 1e-9, "{stop:?}");
        assert_eq!(stop.lines, 40);
    }

    #[test]
    fn a_right_angle_runs_at_the_junction_limit() {
        let mut planner = TrapezoidLookahead::<8, 2>::new(machine()).unwrap();
        planner.push(line(10_000, 0, 5_000.0)).unwrap();
        planner.push(line(0, 10_000, 5_000.0)).unwrap();
        let junction = planner.at(1).entry;
        let expected = junction_deviation_speed(&[1.0, 0.0], &[0.0, 1.0], 100_000.0, 1.0);
        assert!((junction - expected).abs() < 1e-9, "{junction} {expected}");
        let summary = planner.finish();
        assert!(
            summary.total_time_s > 4.0 && summary.total_time_s < 4.2,
            "{summary:?}"
        );
    }
}

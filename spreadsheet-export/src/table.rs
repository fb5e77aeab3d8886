//! Rows of the table, from a profile's steps.
//!
//! A [`Row`] is a [`Step`] plus what the table adds:
//!
//! - `period_ticks`: from this step's rising edge to the next one, what a
//!   scope measures ([`EdgeTiming`]): the delay itself for cogstep's own
//!   arithmetic and the other profiles; for `p2-exact`, the reference cog's
//!   `delay + pulse + overhead` ([`scurve::p2_period_ticks`]), since the
//!   P2 adds its 1,000-tick pulse and a few instruction clocks to every
//!   delay (`delay_ticks` stays the computed delay, the QDIV result, as
//!   the author's spreadsheet has it);
//! - `time_ticks`: the clock tick of the step's rising edge, the sum of the
//!   earlier periods kept in integer ticks (`time_s` is converted per row,
//!   so it never drifts);
//! - `accel_steps_per_s2`: the acceleration from this step to the next, the
//!   change in the profile's velocity over the time between the middles of
//!   the two step intervals:
//!   `a_n = (v_{n+1} − v_n) / ((c_n + c_{n+1}) / 2)`, `c` in seconds.
//!   With `v = 1/c` this is Austin's Eq. 3,
//!   `2·(c_n − c_{n+1}) / (c_n·c_{n+1}·(c_n + c_{n+1}))`; using the
//!   profile's own velocity keeps the rounding of delays to whole ticks
//!   (±1 tick, which at high speed alternates) out of the acceleration.
//!   The last step has no next interval: its acceleration is 0.
//!
//! A reverse move (negative `--steps`) has negative velocity and
//! acceleration; delays, angles and times are those of the forward move.

use std::iter::Peekable;

use driver::profile::scurve::{self, P2_PULSE_TICKS};
use driver::profile::{Phase, Step};

/// How a profile's rising edges follow its delays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EdgeTiming {
    /// The period is the delay (cogstep's scheduling: each edge is placed
    /// `delay_ticks` after the one before).
    Delay,
    /// The reference P2 cog: its running target adds the step pulse and
    /// the cog's fixed instruction overhead to every delay.
    P2Cog {
        /// The step pulse, ticks (the reference's `delayh`).
        pulse_ticks: u32,
    },
}

impl EdgeTiming {
    /// The reference cog as the P2 driver ships (1,000-tick pulse).
    pub const P2_REFERENCE: Self = EdgeTiming::P2Cog {
        pulse_ticks: P2_PULSE_TICKS,
    };

    /// Ticks from a step's rising edge to the next, for a step of this delay.
    pub fn period_ticks(self, delay_ticks: u32) -> u64 {
        match self {
            EdgeTiming::Delay => u64::from(delay_ticks),
            EdgeTiming::P2Cog { pulse_ticks } => scurve::p2_period_ticks(delay_ticks, pulse_ticks),
        }
    }
}

/// One row of the table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// Step index, from 0.
    pub step: u32,
    /// Accelerating, at speed or decelerating.
    pub phase: Phase,
    /// S-curve angle, degrees (`None` for profiles without one).
    pub angle_deg: Option<f64>,
    /// Velocity the profile computed for this step, steps/s (signed).
    pub velocity_steps_per_s: f64,
    /// The delay the profile computed for this step, ticks.
    pub delay_ticks: u32,
    /// Ticks from this step's rising edge to the next (see [`EdgeTiming`]).
    pub period_ticks: u64,
    /// Tick of this step's rising edge (0 for step 0): the earlier periods.
    pub time_ticks: u64,
    /// `time_ticks / clkfreq`, seconds.
    pub time_s: f64,
    /// Acceleration from this step to the next, steps/s² (signed; 0 for the
    /// last step).
    pub accel_steps_per_s2: f64,
    /// The faster of this step's and the next step's velocity, steps/s
    /// (magnitude): where the motor's torque is read for this acceleration.
    pub peak_rate_steps_per_s: f64,
}

/// The rows of a move, streamed from its profile with one step of lookahead.
pub struct Rows<P: Iterator<Item = Step>> {
    steps: Peekable<P>,
    clkfreq: f64,
    direction: f64,
    timing: EdgeTiming,
    time_ticks: u64,
}

impl<P: Iterator<Item = Step>> Rows<P> {
    /// Rows of `profile` at `clkfreq` Hz; `direction` is +1.0 or −1.0;
    /// `timing` says how its edges follow its delays.
    pub fn new(profile: P, clkfreq: u32, direction: f64, timing: EdgeTiming) -> Self {
        Self {
            steps: profile.peekable(),
            clkfreq: f64::from(clkfreq.max(1)),
            direction,
            timing,
            time_ticks: 0,
        }
    }
}

impl<P: Iterator<Item = Step>> Iterator for Rows<P> {
    type Item = Row;

    fn next(&mut self) -> Option<Row> {
        let step = self.steps.next()?;
        let velocity = step.velocity_steps_per_s;
        let period_ticks = self.timing.period_ticks(step.delay_ticks);
        let (accel, peak) = match self.steps.peek() {
            Some(next) => {
                let next_period = self.timing.period_ticks(next.delay_ticks);
                let interval_s = (period_ticks as f64 + next_period as f64) / (2.0 * self.clkfreq);
                let next_velocity = next.velocity_steps_per_s;
                (
                    (next_velocity - velocity) / interval_s,
                    velocity.abs().max(next_velocity.abs()),
                )
            }
            None => (0.0, velocity.abs()),
        };
        let row = Row {
            step: step.index,
            phase: step.phase,
            angle_deg: step.angle_deg(),
            velocity_steps_per_s: self.direction * velocity,
            delay_ticks: step.delay_ticks,
            period_ticks,
            time_ticks: self.time_ticks,
            time_s: self.time_ticks as f64 / self.clkfreq,
            accel_steps_per_s2: self.direction * accel,
            peak_rate_steps_per_s: peak,
        };
        self.time_ticks += period_ticks;
        Some(row)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.steps.size_hint()
    }
}

/// A point of a chart or plot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplePoint {
    /// Step index.
    pub step: u32,
    /// Time of the step's rising edge, s.
    pub time_s: f64,
    /// Velocity, steps/s.
    pub velocity_steps_per_s: f64,
    /// Acceleration, steps/s².
    pub accel_steps_per_s2: f64,
}

/// Thins a move to about `max_points` chart points without losing its
/// extremes: a short move keeps every row; a long one is cut into buckets
/// of consecutive steps, and each bucket keeps its first and last row and
/// the rows with the lowest and highest velocity and acceleration (the
/// "M4" way of drawing many points on few pixels), in step order.
#[derive(Clone, Debug)]
pub struct Sampler {
    /// Steps per bucket (1: keep every row).
    stride: u32,
    bucket: Option<Bucket>,
    points: Vec<SamplePoint>,
}

/// Points a bucket keeps at most.
const POINTS_PER_BUCKET: u32 = 6;

#[derive(Clone, Copy, Debug)]
struct Bucket {
    index: u32,
    first: SamplePoint,
    last: SamplePoint,
    slowest: SamplePoint,
    fastest: SamplePoint,
    least_accel: SamplePoint,
    most_accel: SamplePoint,
}

impl Bucket {
    fn new(index: u32, point: SamplePoint) -> Self {
        Self {
            index,
            first: point,
            last: point,
            slowest: point,
            fastest: point,
            least_accel: point,
            most_accel: point,
        }
    }

    fn add(&mut self, point: SamplePoint) {
        self.last = point;
        if point.velocity_steps_per_s < self.slowest.velocity_steps_per_s {
            self.slowest = point;
        }
        if point.velocity_steps_per_s > self.fastest.velocity_steps_per_s {
            self.fastest = point;
        }
        if point.accel_steps_per_s2 < self.least_accel.accel_steps_per_s2 {
            self.least_accel = point;
        }
        if point.accel_steps_per_s2 > self.most_accel.accel_steps_per_s2 {
            self.most_accel = point;
        }
    }

    fn drain_into(self, points: &mut Vec<SamplePoint>) {
        let mut kept = [
            self.first,
            self.last,
            self.slowest,
            self.fastest,
            self.least_accel,
            self.most_accel,
        ];
        kept.sort_by_key(|point| point.step);
        for point in kept {
            if points
                .last()
                .is_none_or(|previous| previous.step != point.step)
            {
                points.push(point);
            }
        }
    }
}

impl Sampler {
    /// A sampler for a move of `total_steps` steps.
    pub fn new(total_steps: u32, max_points: u32) -> Self {
        let stride = if total_steps <= max_points {
            1
        } else {
            let buckets = (max_points / POINTS_PER_BUCKET).max(1);
            total_steps.div_ceil(buckets)
        };
        let capacity = total_steps.min(max_points.saturating_add(POINTS_PER_BUCKET));
        Self {
            stride,
            bucket: None,
            points: Vec::with_capacity(capacity as usize),
        }
    }

    /// Offers the next row.
    pub fn offer(&mut self, row: &Row) {
        let point = SamplePoint {
            step: row.step,
            time_s: row.time_s,
            velocity_steps_per_s: row.velocity_steps_per_s,
            accel_steps_per_s2: row.accel_steps_per_s2,
        };
        let index = row.step / self.stride;
        match &mut self.bucket {
            Some(bucket) if bucket.index == index => bucket.add(point),
            _ => {
                if let Some(full) = self.bucket.replace(Bucket::new(index, point)) {
                    full.drain_into(&mut self.points);
                }
            }
        }
    }

    /// The points kept, in step order.
    pub fn into_points(mut self) -> Vec<SamplePoint> {
        if let Some(last) = self.bucket.take() {
            last.drain_into(&mut self.points);
        }
        self.points
    }
}

/// What the whole move came to, gathered row by row.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Summary {
    /// Rows seen.
    pub steps: u32,
    /// Rows in each phase.
    pub accel_steps: u32,
    /// Rows at speed.
    pub slew_steps: u32,
    /// Rows decelerating.
    pub decel_steps: u32,
    /// Largest |velocity|, steps/s.
    pub top_speed_steps_per_s: f64,
    /// All periods added up, ticks: from the first rising edge until the
    /// axis is ready again.
    pub total_ticks: u64,
    /// Largest |acceleration|, steps/s², and the step where it occurs.
    pub largest_accel: Option<(u32, f64)>,
}

impl Summary {
    /// Adds a row.
    pub fn add(&mut self, row: &Row) {
        self.steps += 1;
        match row.phase {
            Phase::Accel => self.accel_steps += 1,
            Phase::Slew => self.slew_steps += 1,
            Phase::Decel => self.decel_steps += 1,
        }
        self.top_speed_steps_per_s = self
            .top_speed_steps_per_s
            .max(row.velocity_steps_per_s.abs());
        self.total_ticks += row.period_ticks;
        let accel = row.accel_steps_per_s2;
        if self
            .largest_accel
            .is_none_or(|(_, largest)| accel.abs() > largest.abs())
        {
            self.largest_accel = Some((row.step, accel));
        }
    }

    /// Total time of the move, s.
    pub fn total_time_s(&self, clkfreq: u32) -> f64 {
        self.total_ticks as f64 / f64::from(clkfreq.max(1))
    }

    /// The real average step rate, steps/s: the steps over the time they
    /// take, rising edge to rising edge (`None` before any step).
    pub fn average_rate_steps_per_s(&self, clkfreq: u32) -> Option<f64> {
        (self.total_ticks > 0)
            .then(|| f64::from(self.steps) * f64::from(clkfreq.max(1)) / self.total_ticks as f64)
    }
}

#[cfg(test)]
mod tests {
    use driver::profile::scurve::{SCurve, ScurveConfig};
    use driver::profile::Profile;

    use super::*;

    /// A constant-velocity profile, for checking the arithmetic by hand.
    struct Steady {
        index: u32,
        count: u32,
        delays: Vec<(f64, u32)>,
    }

    impl Iterator for Steady {
        type Item = Step;
        fn next(&mut self) -> Option<Step> {
            if self.index == self.count {
                return None;
            }
            let (velocity, delay_ticks) = self.delays[self.index as usize];
            let step = Step {
                index: self.index,
                phase: Phase::Slew,
                binary_angle: None,
                velocity_steps_per_s: velocity,
                delay_ticks,
            };
            self.index += 1;
            Some(step)
        }
    }

    impl Profile for Steady {
        fn remaining_steps(&self) -> u32 {
            self.count - self.index
        }
    }

    #[test]
    fn time_is_the_sum_of_earlier_delays() {
        let curve = SCurve::new(ScurveConfig::default(), 20_000, 20_000).unwrap();
        let reference: Vec<Step> = curve.clone().collect();
        let mut ticks = 0u64;
        for (row, step) in Rows::new(curve, 200_000_000, 1.0, EdgeTiming::Delay).zip(&reference) {
            assert_eq!(row.time_ticks, ticks);
            assert_eq!(row.time_s, ticks as f64 / 200e6);
            assert_eq!(row.delay_ticks, step.delay_ticks);
            assert_eq!(row.velocity_steps_per_s, step.velocity_steps_per_s);
            ticks += u64::from(step.delay_ticks);
        }
    }

    #[test]
    fn acceleration_is_the_velocity_change_over_the_interval_midpoints() {
        // 1,000 → 2,000 steps/s; intervals 1 ms and 0.5 ms at 1 MHz: the
        // midpoints are 0.75 ms apart, so a = 1,000 / 0.75e-3.
        let profile = Steady {
            index: 0,
            count: 2,
            delays: vec![(1_000.0, 1_000), (2_000.0, 500)],
        };
        let rows: Vec<Row> = Rows::new(profile, 1_000_000, 1.0, EdgeTiming::Delay).collect();
        assert!((rows[0].accel_steps_per_s2 - 1_000.0 / 0.75e-3).abs() < 1e-6);
        assert_eq!(rows[0].peak_rate_steps_per_s, 2_000.0);
        assert_eq!(rows[1].accel_steps_per_s2, 0.0);
        assert_eq!(rows[1].time_s, 1e-3);
    }

    #[test]
    fn equals_austins_eq3_when_velocity_is_one_over_delay() {
        let (c0, c1) = (1e-3_f64, 0.8e-3_f64);
        let profile = Steady {
            index: 0,
            count: 2,
            delays: vec![(1.0 / c0, 1_000), (1.0 / c1, 800)],
        };
        let row = Rows::new(profile, 1_000_000, 1.0, EdgeTiming::Delay)
            .next()
            .unwrap();
        let eq3 = 2.0 * (c0 - c1) / (c0 * c1 * (c0 + c1));
        assert!((row.accel_steps_per_s2 - eq3).abs() < 1e-6 * eq3);
    }

    #[test]
    fn reverse_negates_velocity_and_acceleration_only() {
        let forward: Vec<Row> = Rows::new(
            SCurve::new(ScurveConfig::default(), 5_000, 3_000).unwrap(),
            200_000_000,
            1.0,
            EdgeTiming::Delay,
        )
        .collect();
        let reverse: Vec<Row> = Rows::new(
            SCurve::new(ScurveConfig::default(), 5_000, 3_000).unwrap(),
            200_000_000,
            -1.0,
            EdgeTiming::Delay,
        )
        .collect();
        for (f, r) in forward.iter().zip(&reverse) {
            assert_eq!(r.velocity_steps_per_s, -f.velocity_steps_per_s);
            assert_eq!(r.accel_steps_per_s2, -f.accel_steps_per_s2);
            assert_eq!(
                (r.delay_ticks, r.time_ticks, r.angle_deg),
                (f.delay_ticks, f.time_ticks, f.angle_deg)
            );
        }
    }

    #[test]
    fn sampler_keeps_few_points_and_the_extremes() {
        let curve = SCurve::new(ScurveConfig::default(), 20_000, 1_000_001).unwrap();
        let mut sampler = Sampler::new(1_000_001, 4_000);
        let mut most_accel = (0, f64::MIN);
        let mut least_accel = (0, f64::MAX);
        for row in Rows::new(curve, 200_000_000, 1.0, EdgeTiming::Delay) {
            if row.accel_steps_per_s2 > most_accel.1 {
                most_accel = (row.step, row.accel_steps_per_s2);
            }
            if row.accel_steps_per_s2 < least_accel.1 {
                least_accel = (row.step, row.accel_steps_per_s2);
            }
            sampler.offer(&row);
        }
        let points = sampler.into_points();
        assert!(points.len() <= 4_000, "{}", points.len());
        assert_eq!(points[0].step, 0);
        assert_eq!(points.last().map(|p| p.step), Some(1_000_000));
        assert!(points.windows(2).all(|pair| pair[0].step < pair[1].step));
        for (step, accel) in [most_accel, least_accel] {
            assert!(points
                .iter()
                .any(|p| p.step == step && p.accel_steps_per_s2 == accel));
        }
    }

    #[test]
    fn sampler_keeps_every_row_of_a_short_move() {
        let curve = SCurve::new(ScurveConfig::default(), 2_000, 300).unwrap();
        let mut sampler = Sampler::new(300, 4_000);
        for row in Rows::new(curve, 200_000_000, 1.0, EdgeTiming::Delay) {
            sampler.offer(&row);
        }
        let steps: Vec<u32> = sampler.into_points().iter().map(|p| p.step).collect();
        assert_eq!(steps, (0..300).collect::<Vec<_>>());
    }

    #[test]
    fn p2_exact_edges_add_the_pulse_and_the_cogs_overhead() {
        use driver::profile::scurve::{Arithmetic, P2_STEP_OVERHEAD_TICKS};
        let config = ScurveConfig {
            arithmetic: Arithmetic::P2Exact,
            ..ScurveConfig::default()
        };
        let curve = SCurve::new(config, 20_000, 20_000).unwrap();
        let steps: Vec<Step> = curve.clone().collect();
        let rows: Vec<Row> = Rows::new(curve, 200_000_000, 1.0, EdgeTiming::P2_REFERENCE).collect();
        let mut edge = 0u64;
        for (row, step) in rows.iter().zip(&steps) {
            assert_eq!(row.delay_ticks, step.delay_ticks);
            assert_eq!(
                row.period_ticks,
                u64::from(step.delay_ticks) + 1_000 + u64::from(P2_STEP_OVERHEAD_TICKS)
            );
            assert_eq!(row.time_ticks, edge);
            edge += row.period_ticks;
        }
        // At speed: 10,000 + 1,000 + 8 ticks, 18,169 steps/s, not 20,000.
        assert_eq!(rows[10_000].period_ticks, 11_008);
        let mut summary = Summary::default();
        rows.iter().for_each(|row| summary.add(row));
        assert_eq!(summary.total_ticks, edge);
        let rate = summary.average_rate_steps_per_s(200_000_000).unwrap();
        assert_eq!(rate, 20_000.0 * 200e6 / edge as f64);
        // The ramps are slower still than the slew's 18,169 steps/s.
        assert!(rate < 18_169.0, "{rate}");
    }

    #[test]
    fn smooth_periods_are_its_delays() {
        let curve = SCurve::new(ScurveConfig::default(), 20_000, 20_000).unwrap();
        let mut summary = Summary::default();
        for row in Rows::new(curve, 200_000_000, 1.0, EdgeTiming::Delay) {
            assert_eq!(row.period_ticks, u64::from(row.delay_ticks));
            summary.add(&row);
        }
        assert_eq!(
            Summary::default().average_rate_steps_per_s(200_000_000),
            None
        );
        let rate = summary.average_rate_steps_per_s(200_000_000).unwrap();
        assert_eq!(rate, 20_000.0 * 200e6 / summary.total_ticks as f64);
    }

    #[test]
    fn summary_counts_phases_like_the_plan() {
        let curve = SCurve::new(ScurveConfig::default(), 20_000, 20_000).unwrap();
        let plan = *curve.plan();
        let mut summary = Summary::default();
        for row in Rows::new(curve, 200_000_000, 1.0, EdgeTiming::Delay) {
            summary.add(&row);
        }
        assert_eq!(summary.steps, 20_000);
        assert_eq!(summary.accel_steps, plan.accel_steps);
        assert_eq!(summary.slew_steps, plan.slew_steps);
        assert_eq!(summary.decel_steps, plan.accel_steps);
        assert_eq!(summary.top_speed_steps_per_s, f64::from(plan.speed));
        assert!(summary.largest_accel.is_some_and(|(_, a)| a > 0.0));
    }
}

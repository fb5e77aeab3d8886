//! The runner's properties over random streams of lines: exact ends, the
//! line kept at every edge, the limits, holds and overrides.

// Axes are indexed across several arrays at once.
#![allow(clippy::needless_range_loop)]

use super::*;
use crate::planner::MAX_AXES;
use proptest::prelude::*;

const AXES: usize = 3;
const CAPACITY: usize = 16;
const HZ: u32 = 1_000_000;
type Runner = PathRunner<CAPACITY, AXES>;

fn machine_strategy() -> impl Strategy<Value = Machine<AXES>> {
    (
        prop::array::uniform3(2_000.0f64..40_000.0),
        prop::array::uniform3(20_000.0f64..2e6),
        0.0f64..20.0,
    )
        .prop_map(|(speed, accel, deviation)| Machine {
            max_speed_steps_per_s: speed,
            max_accel_steps_per_s2: accel,
            junction_deviation_steps: deviation,
            blending: Blending::Blend,
        })
}

fn line_strategy() -> impl Strategy<Value = Line<AXES>> {
    (prop::array::uniform3(-400i32..=400), 500.0f64..60_000.0)
        .prop_filter("a line moves", |(steps, _)| steps.iter().any(|&s| s != 0))
        .prop_map(|(steps, feed_steps_per_s)| Line {
            steps,
            feed_steps_per_s,
        })
}

fn lines_strategy() -> impl Strategy<Value = Vec<Line<AXES>>> {
    prop::collection::vec(line_strategy(), 1..12)
}

/// An edge as the checks see it: the line it belongs to (index in the
/// program), its exact time, the step within that line.
#[derive(Clone, Copy, Debug)]
struct Seen {
    edge: PathEdge,
    t: f64,
}

fn end(lines: &[Line<AXES>]) -> [i64; AXES] {
    let mut end = [0i64; AXES];
    for line in lines {
        for (target, steps) in end.iter_mut().zip(line.steps) {
            *target += i64::from(steps);
        }
    }
    end
}

/// Pushes what fits, takes edges, pushes more: the program's every edge.
fn run_all(machine: Machine<AXES>, lines: &[Line<AXES>]) -> (Runner, Vec<Seen>) {
    let mut runner = Runner::new(machine, [0; AXES], 0, HZ).unwrap();
    let mut seen = Vec::new();
    let mut next = 0;
    loop {
        while next < lines.len() && !runner.is_full() {
            runner.push(lines[next], next as u32).unwrap();
            next += 1;
        }
        match runner.next_edge_timed(u64::MAX) {
            Some((edge, t)) => seen.push(Seen { edge, t }),
            None if next == lines.len() => break,
            None => unreachable!("a full queue has edges"),
        }
    }
    (runner, seen)
}

/// The half-step rule: the step `step` (1-based) of an axis with `n` steps
/// in a line of lead `lead` is at progress `(step − ½)·lead/|n|`.
fn progress(step: u32, n: i32, lead: u32) -> f64 {
    (f64::from(step) - 0.5) * f64::from(lead) / f64::from(n.unsigned_abs())
}

/// Every axis's steps of every line, in order, against the program: the
/// right number and direction, and in each line the edges of all axes come
/// in the order of their progress (so every axis is within half a step of
/// the line whenever any axis steps).
fn check_edges(lines: &[Line<AXES>], seen: &[Seen]) -> Result<(), TestCaseError> {
    let mut steps_in = vec![[0u32; AXES]; lines.len()];
    let mut last_time = f64::NEG_INFINITY;
    let mut last_progress = vec![f64::NEG_INFINITY; lines.len()];
    let mut last_ct = 0;
    for s in seen {
        let line = &lines[s.edge.tag as usize];
        let axis = usize::from(s.edge.axis);
        prop_assert!(s.t >= last_time, "edges in time order");
        prop_assert!(s.edge.ct >= last_ct);
        last_time = s.t;
        last_ct = s.edge.ct;
        prop_assert_eq!(s.edge.forward, line.steps[axis] > 0);
        let count = &mut steps_in[s.edge.tag as usize][axis];
        *count += 1;
        prop_assert!(*count <= line.steps[axis].unsigned_abs());
        let lead = line.steps.iter().map(|n| n.unsigned_abs()).max().unwrap();
        let p = progress(*count, line.steps[axis], lead);
        let last = &mut last_progress[s.edge.tag as usize];
        prop_assert!(
            p >= *last - 1e-9,
            "line {} axis {}: {} after {}",
            s.edge.tag,
            axis,
            p,
            last
        );
        *last = p;
    }
    for (line, made) in lines.iter().zip(&steps_in) {
        for axis in 0..AXES {
            prop_assert_eq!(made[axis], line.steps[axis].unsigned_abs());
        }
    }
    Ok(())
}

/// No axis above its top speed, and the acceleration an axis's steps show
/// (the change of its mean speed over two steps) within its limit wherever
/// the path does not turn; `slack` allows what a fallen override keeps.
fn check_limits(
    machine: &Machine<AXES>,
    lines: &[Line<AXES>],
    seen: &[Seen],
) -> Result<(), TestCaseError> {
    let hz = f64::from(HZ);
    for axis in 0..AXES {
        let edges: Vec<&Seen> = seen
            .iter()
            .filter(|s| usize::from(s.edge.axis) == axis)
            .collect();
        let max_speed = machine.max_speed_steps_per_s[axis];
        let max_accel = machine.max_accel_steps_per_s2[axis];
        for pair in edges.windows(2) {
            let period = (pair[1].t - pair[0].t) / hz;
            prop_assert!(
                1.0 / period <= max_speed * (1.0 + 1e-6),
                "axis {} at {} steps/s over {}",
                axis,
                1.0 / period,
                max_speed
            );
        }
        for triple in edges.windows(3) {
            // The same direction of travel in step space over the three
            // edges: within one line, or across lines of one direction.
            let unit = |tag: u32| {
                let steps = lines[tag as usize].steps;
                let length = steps
                    .iter()
                    .map(|&n| f64::from(n).powi(2))
                    .sum::<f64>()
                    .sqrt();
                steps.map(|n| f64::from(n) / length)
            };
            let (a, b) = (unit(triple[0].edge.tag), unit(triple[2].edge.tag));
            if a.iter().zip(&b).any(|(x, y)| (x - y).abs() > 1e-12) {
                continue;
            }
            let (p1, p2) = (
                (triple[1].t - triple[0].t) / hz,
                (triple[2].t - triple[1].t) / hz,
            );
            let accel = (1.0 / p2 - 1.0 / p1) / ((p1 + p2) / 2.0);
            prop_assert!(
                // The two-step estimate is the acceleration's mean to second
                // order: on a ramp of a few dozen steps it reads up to a few
                // 10⁻⁴ above the plan's peak (1.2·10⁻⁴ found; the plans'
                // own peaks are checked exactly in the planner's tests).
                accel.abs() <= max_accel * (1.0 + 5e-4) + 1e-3,
                "axis {}: {} steps/s² over {} at {}",
                axis,
                accel,
                max_accel,
                triple[1].t
            );
        }
    }
    Ok(())
}

/// Which step each axis stands at when the path is at rest inside line
/// `lines[tag]` is on the line: some progress lies within half a step of
/// every axis's position.
fn on_the_line(line: &Line<AXES>, made: [u32; AXES]) -> bool {
    let lead = line.steps.iter().map(|n| n.unsigned_abs()).max().unwrap();
    let (mut low, mut high) = (0.0f64, f64::from(lead));
    for axis in 0..AXES {
        let n = line.steps[axis];
        if n == 0 {
            continue;
        }
        let share = f64::from(lead) / f64::from(n.unsigned_abs());
        // Made m steps: progress in [(m − ½)·share, (m + ½)·share].
        low = low.max((f64::from(made[axis]) - 0.5) * share);
        high = high.min((f64::from(made[axis]) + 0.5) * share);
    }
    low <= high + 1e-9
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Continuous acceleration at every junction: along the path the
    /// speed never jumps, and the acceleration is 0 at both ends of every
    /// piece of every line's plan (ramp, cruise, ramp), so at every
    /// junction and every piece boundary it is 0 on both sides. (A
    /// trapezoid's ramp starts at its full acceleration.)
    #[test]
    fn the_acceleration_along_the_path_is_continuous_at_every_junction(
        machine in machine_strategy(),
        lines in lines_strategy(),
        exact in any::<bool>(),
    ) {
        let machine = Machine {
            blending: if exact { Blending::ExactStop } else { Blending::Blend },
            ..machine
        };
        let mut runner = Runner::new(machine, [0; AXES], 0, HZ).unwrap();
        for (tag, line) in lines.iter().enumerate() {
            runner.push(*line, tag as u32).unwrap();
        }
        let pieces = runner.pieces_seen();
        prop_assert!(pieces.len() >= lines.len());
        prop_assert_eq!(pieces[0][0], 0.0);
        prop_assert_eq!(pieces[pieces.len() - 1][1], 0.0);
        for pair in pieces.windows(2) {
            let (end, start) = (pair[0][1], pair[1][0]);
            prop_assert!((end - start).abs() <= 1e-9 * end.max(start) + 1e-15, "{} then {}", end, start);
        }
        for [_, _, a_start, a_end, peak] in pieces {
            // Over a millionth of the piece, a cosine's acceleration is
            // about π·10⁻⁶ of its peak.
            prop_assert!(a_start.abs() <= 1e-4 * peak + 1e-15, "{} of {}", a_start, peak);
            prop_assert!(a_end.abs() <= 1e-4 * peak + 1e-15, "{} of {}", a_end, peak);
        }
    }

    #[test]
    fn every_axis_ends_exactly_on_the_line_within_its_limits(
        machine in machine_strategy(),
        lines in lines_strategy(),
    ) {
        let (runner, seen) = run_all(machine, &lines);
        prop_assert_eq!(runner.positions(), end(&lines));
        prop_assert_eq!(runner.state(), PathState::Idle);
        prop_assert_eq!(runner.lines_done(), lines.len() as u64);
        check_edges(&lines, &seen)?;
        check_limits(&machine, &lines, &seen)?;
        // The same program, the same edges.
        let (_, again) = run_all(machine, &lines);
        prop_assert_eq!(
            seen.iter().map(|s| s.edge).collect::<Vec<_>>(),
            again.iter().map(|s| s.edge).collect::<Vec<_>>()
        );
    }

    #[test]
    fn a_hold_stops_on_the_path_and_resume_finishes_the_program(
        machine in machine_strategy(),
        lines in lines_strategy(),
        at in 0.0f64..1.0,
        pause in 0u64..100_000,
    ) {
        let (_, reference) = run_all(machine, &lines);
        let stop_at = reference.last().map_or(0, |s| (s.edge.ct as f64 * at) as u64);
        let mut runner = Runner::new(machine, [0; AXES], 0, HZ).unwrap();
        let mut next = 0;
        let mut seen = Vec::new();
        let mut held_once = false;
        let mut made = vec![[0u32; AXES]; lines.len()];
        loop {
            while next < lines.len() && !runner.is_full() {
                runner.push(lines[next], next as u32).unwrap();
                next += 1;
            }
            if !held_once {
                match runner.next_edge_timed(stop_at) {
                    Some((edge, t)) => {
                        made[edge.tag as usize][usize::from(edge.axis)] += 1;
                        seen.push(Seen { edge, t });
                        continue;
                    }
                    None => {
                        runner.hold(stop_at);
                        held_once = true;
                        // Run the hold out.
                        while let Some((edge, t)) = runner.next_edge_timed(u64::MAX) {
                            made[edge.tag as usize][usize::from(edge.axis)] += 1;
                            seen.push(Seen { edge, t });
                        }
                        prop_assert!(runner.is_held() || runner.state() == PathState::Idle);
                        // At rest on the path: in the line it stopped in, some
                        // progress is within half a step of every axis.
                        for (tag, line) in lines.iter().enumerate().take(next) {
                            prop_assert!(on_the_line(line, made[tag]), "line {} made {:?}", tag, made[tag]);
                        }
                        let rest_ct = seen.last().map_or(0, |s| s.edge.ct) + pause;
                        if runner.is_held() {
                            runner.resume(rest_ct).unwrap();
                        }
                        continue;
                    }
                }
            }
            match runner.next_edge_timed(u64::MAX) {
                Some((edge, t)) => {
                    made[edge.tag as usize][usize::from(edge.axis)] += 1;
                    seen.push(Seen { edge, t });
                }
                None if next == lines.len() => break,
                None => unreachable!("a full queue has edges"),
            }
        }
        prop_assert_eq!(runner.positions(), end(&lines));
        for (line, made) in lines.iter().zip(&made) {
            for axis in 0..AXES {
                prop_assert_eq!(made[axis], line.steps[axis].unsigned_abs());
            }
        }
        check_limits(&machine, &lines, &seen)?;
    }

    #[test]
    fn an_override_changes_the_time_not_the_end(
        machine in machine_strategy(),
        lines in lines_strategy(),
        scale in 0.1f64..2.0,
        after in 0usize..200,
    ) {
        let mut runner = Runner::new(machine, [0; AXES], 0, HZ).unwrap();
        let mut next = 0;
        let mut seen = Vec::new();
        loop {
            while next < lines.len() && !runner.is_full() {
                runner.push(lines[next], next as u32).unwrap();
                next += 1;
            }
            if seen.len() == after {
                runner.set_overrides(scale, 1.0).unwrap();
            }
            match runner.next_edge_timed(u64::MAX) {
                Some((edge, t)) => seen.push(Seen { edge, t }),
                None if next == lines.len() => break,
                None => unreachable!("a full queue has edges"),
            }
        }
        prop_assert_eq!(runner.positions(), end(&lines));
        check_edges(&lines, &seen)?;
        check_limits(&machine, &lines, &seen)?;
    }
}

/// The examples' machine: 10 000 steps/s and 100 000 steps/s² on every axis.
fn example_machine() -> Machine<AXES> {
    Machine {
        max_speed_steps_per_s: [10_000.0; AXES],
        max_accel_steps_per_s2: [100_000.0; AXES],
        junction_deviation_steps: 1.0,
        blending: Blending::Blend,
    }
}

#[test]
fn a_line_from_rest_is_the_seed_cosine_in_time() {
    let machine = example_machine();
    let line = Line {
        steps: [4_000, 0, 0],
        feed_steps_per_s: 5_000.0,
    };
    let (runner, seen) = run_all(machine, &[line]);
    assert_eq!(runner.positions(), [4_000, 0, 0]);
    let plan_ramp = ramp_distance(0.0, 5_000.0, 100_000.0);
    // The ramp: π/2 of a trapezoid's 125 steps; its time 2d/v.
    assert_eq!(plan_ramp, 197);
    let t_ramp = f64::from(HZ) * ramp_time(0.0, 5_000.0, f64::from(plan_ramp));
    // The cruise's periods are 200 µs exactly.
    let cruise: Vec<f64> = seen
        .windows(2)
        .filter(|w| w[0].t > t_ramp + 1.0 && w[1].t < seen.last().unwrap().t - t_ramp - 1.0)
        .map(|w| w[1].t - w[0].t)
        .collect();
    assert!(cruise.len() > 3_000);
    assert!(
        cruise.iter().all(|p| (p - 200.0).abs() < 1e-6),
        "{:?}",
        &cruise[..4]
    );
    // The first step (at half a step of progress) comes after a finite
    // time: s ≈ (π²/12)·v·τ³/T² near rest.
    assert!(seen[0].t > 0.0 && seen[0].t < t_ramp / 4.0);
}

#[test]
fn collinear_lines_run_through_their_junctions() {
    let machine = example_machine();
    let lines = [Line {
        steps: [300, 150, 0],
        feed_steps_per_s: 8_000.0,
    }; 10];
    let (runner, seen) = run_all(machine, &lines);
    assert_eq!(runner.positions(), [3_000, 1_500, 0]);
    // The lead's periods at the middle junctions: the cruise's 125 µs.
    let lead: Vec<&Seen> = seen.iter().filter(|s| s.edge.axis == 0).collect();
    for junction in 3..7 {
        let at = junction * 300;
        let period = lead[at].t - lead[at - 1].t;
        assert!(
            (period - 125.0).abs() < 1e-6,
            "junction {junction}: {period}"
        );
    }
}

#[test]
fn a_hold_during_a_cruise_starts_at_once_and_resumes_from_rest() {
    let machine = example_machine();
    let line = Line {
        steps: [10_000, 5_000, 0],
        feed_steps_per_s: 5_000.0,
    };
    let mut runner = Runner::new(machine, [0; AXES], 0, HZ).unwrap();
    runner.push(line, 7).unwrap();
    // Half a second in: cruising at 5 000 steps/s.
    while runner.next_edge_until(500_000).is_some() {}
    let before = runner.positions();
    runner.hold(500_000);
    assert_eq!(runner.state(), PathState::Holding);
    let mut last = 0;
    while let Some(edge) = runner.next_edge_until(u64::MAX) {
        last = edge.ct;
    }
    assert!(runner.is_held());
    // The ramp to rest: π·v²/(4a) ≈ 196 lead steps, in 2d/v ≈ 78.5 ms.
    let lead_moved = runner.positions()[0] - before[0];
    assert!((195..=198).contains(&lead_moved), "{lead_moved}");
    // Its last edge, half a step before rest, where the speed falls as
    // the square of the time left (about 9 ms before the ramp's end).
    assert!((565_000..575_000).contains(&last), "{last}");
    assert_eq!(runner.resume(1_000_000), Ok(()));
    while runner.next_edge_until(u64::MAX).is_some() {}
    assert_eq!(runner.positions(), [10_000, 5_000, 0]);
    assert_eq!(runner.resume(2_000_000), Err(RunError::NotHeld));
}

#[test]
fn cancel_stops_on_the_path_and_drops_the_rest() {
    let machine = example_machine();
    let mut runner = Runner::new(machine, [0; AXES], 0, HZ).unwrap();
    for tag in 0..4 {
        runner
            .push(
                Line {
                    steps: [2_000, -1_000, 500],
                    feed_steps_per_s: 6_000.0,
                },
                tag,
            )
            .unwrap();
    }
    while runner.next_edge_until(300_000).is_some() {}
    runner.cancel(300_000);
    while runner.next_edge_until(u64::MAX).is_some() {}
    assert_eq!(runner.state(), PathState::Idle);
    assert_eq!(runner.queued(), 0);
    let at = runner.positions();
    assert!(at[0] > 0 && at[0] < 8_000);
    assert_eq!(runner.targets(), at);
    // Every line is done or dropped: the one it stopped in is done.
    let started = (at[0] as u64).div_ceil(2_000);
    assert_eq!(runner.lines_done(), started);
    assert_eq!(runner.lines_dropped(), 4 - started);
}

/// The hub's use of a runner, mirrored: 32 lines, a 200 MHz CT, 1 ms
/// slices, every line pushed up front (a full queue runs a slice), a stop
/// pin low from `hold_at` for 200 ms then resume.
fn hub_like(
    lines: &[([i32; 3], f64)],
    hold_at_ms: Option<u64>,
    pause_ms: u64,
) -> Result<(), TestCaseError> {
    const HUB_HZ: u32 = 200_000_000;
    type HubRunner = PathRunner<32, MAX_AXES>;
    let machine = Machine {
        max_speed_steps_per_s: [20_000.0; MAX_AXES],
        max_accel_steps_per_s2: [400_000.0; MAX_AXES],
        junction_deviation_steps: 2.0,
        blending: Blending::Blend,
    };
    let mut runner = HubRunner::new(machine, [0; MAX_AXES], 0, HUB_HZ).unwrap();
    let ms = u64::from(HUB_HZ) / 1_000;
    let mut now = 0u64;
    let mut filled = 0u64;
    let mut low = false;
    let mut slices = 0u64;
    let mut slice = |runner: &mut HubRunner,
                     now: &mut u64,
                     filled: &mut u64,
                     low: bool|
     -> Result<(), TestCaseError> {
        slices += 1;
        prop_assert!(
            slices < 200_000,
            "hang at {} ms: state {:?} queued {}",
            *now / ms,
            runner.state(),
            runner.queued()
        );
        if low {
            runner.hold((*filled).max(*now));
        }
        let to = *now + ms;
        while runner.next_edge_until(to).is_some() {}
        *filled = (*filled).max(to);
        *now = to;
        Ok(())
    };
    let mut end = [0i64; 3];
    for (tag, (steps, feed)) in lines.iter().enumerate() {
        let mut line = Line {
            steps: [0; MAX_AXES],
            feed_steps_per_s: *feed,
        };
        line.steps[..3].copy_from_slice(steps);
        while runner.is_full() {
            slice(&mut runner, &mut now, &mut filled, low)?;
        }
        runner.push(line, tag as u32).unwrap();
        for (e, s) in end.iter_mut().zip(steps) {
            *e += i64::from(*s);
        }
    }
    if let Some(at) = hold_at_ms {
        while now < at * ms {
            slice(&mut runner, &mut now, &mut filled, low)?;
        }
        low = true;
        for _ in 0..200 + pause_ms {
            slice(&mut runner, &mut now, &mut filled, low)?;
        }
        low = false;
        if runner.is_held() {
            runner.resume(filled.max(now)).unwrap();
        }
    }
    while runner.state() != PathState::Idle {
        slice(&mut runner, &mut now, &mut filled, low)?;
    }
    prop_assert_eq!(&runner.positions()[..3], &end[..]);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The hub's programs (`tests/tests/path_job.rs`), on the runner alone
    /// in 1 ms slices: held at a random moment and resumed, every program
    /// ends on its end (a one-step rest of a line after a hold never ran:
    /// 1 case in about 1,200; 3,000 pass).
    #[test]
    fn a_program_held_and_resumed_as_the_hub_runs_it_ends_on_its_end(
        program in prop::collection::vec(
            (prop::array::uniform3(-600i32..=600), 2_000.0f64..20_000.0)
                .prop_filter("moves", |(steps, _)| steps.iter().any(|&s| s != 0)),
            1..40,
        ),
        hold_at_ms in prop::option::of(1u64..300),
        pause_ms in 1u64..50,
    ) {
        hub_like(&program, hold_at_ms, pause_ms)?;
    }
}

fn long_lines_strategy() -> impl Strategy<Value = Vec<Line<AXES>>> {
    prop::collection::vec(line_strategy(), 1..60)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Long streams through a small queue in slices, with holds and
    /// pauses: every program ends on its end, with no edge too many.
    #[test]
    fn a_long_stream_with_holds_in_slices_ends_on_its_end(
        machine in machine_strategy(),
        lines in long_lines_strategy(),
        holds in prop::collection::vec((0u64..400_000, 0u64..50_000), 0..4),
        slice in 200u64..5_000,
    ) {
        let mut runner = Runner::new(machine, [0; AXES], 0, HZ).unwrap();
        let total: u64 = lines.iter().map(|l| l.steps.iter().map(|s| u64::from(s.unsigned_abs())).sum::<u64>()).sum();
        let mut next = 0;
        let mut now = 0u64;
        let mut edges = 0u64;
        let mut holds = holds;
        holds.sort();
        let mut hold_i = 0;
        let mut iterations = 0u64;
        loop {
            iterations += 1;
            prop_assert!(iterations < 2_000_000, "hang: now {} edges {} of {} next {} state {:?}", now, edges, total, next, runner.state());
            while next < lines.len() && !runner.is_full() {
                runner.push(lines[next], next as u32).unwrap();
                next += 1;
            }
            if hold_i < holds.len() && now >= holds[hold_i].0 {
                runner.hold(now);
                if runner.is_held() {
                    runner.resume(now + holds[hold_i].1).unwrap();
                    hold_i += 1;
                }
            }
            while let Some(_edge) = runner.next_edge_until(now + slice) {
                edges += 1;
                prop_assert!(edges <= total, "too many edges");
            }
            now += slice;
            if next == lines.len() && runner.state() == PathState::Idle {
                break;
            }
        }
        prop_assert_eq!(runner.positions(), end(&lines));
    }
}

/// The case the property found: held in the last line, its rest is one
/// step of x and y, from rest to rest.
#[test]
fn the_one_step_rest_of_a_line_after_a_hold_is_made() {
    let program = [
        ([0, -220, 33], 19_588.403_213_079_164),
        ([599, 0, 0], 9_057.992_549_293_034),
        ([-230, -154, 75], 15_627.200_318_893_321),
        ([236, 255, -50], 9_882.252_278_113_487),
    ];
    hub_like(&program, Some(206), 1).unwrap();
}

/// A line of one step between two rests (alone, or in exact stop) is one
/// pulse, half way through its time, at the speed a cosine ramp from rest
/// reaches over one step.
#[test]
fn a_one_step_line_from_rest_to_rest_is_one_pulse() {
    let machine = example_machine();
    let mut runner = Runner::new(machine, [0; AXES], 0, HZ).unwrap();
    let line = Line {
        steps: [1, -1, 0],
        feed_steps_per_s: 5_000.0,
    };
    runner.push(line, 7).unwrap();
    let edges: Vec<_> = core::iter::from_fn(|| runner.next_edge_timed(u64::MAX)).collect();
    assert_eq!(edges.len(), 2);
    assert_eq!(runner.positions(), [1, -1, 0]);
    assert_eq!(runner.state(), PathState::Idle);
    let speed = super::ramp::max_speed_within(0.0, 1.0, 100_000.0);
    let expected = 0.5 / speed * f64::from(HZ);
    for (edge, t) in edges {
        assert_eq!(edge.tag, 7);
        assert!((t - expected).abs() < 1e-6 * expected, "{t} vs {expected}");
    }
}

/// 20,000 steps/s and 400,000 steps/s² on every axis, blending.
fn plain_machine() -> Machine<AXES> {
    Machine {
        max_speed_steps_per_s: [20_000.0; AXES],
        max_accel_steps_per_s2: [400_000.0; AXES],
        junction_deviation_steps: 2.0,
        blending: Blending::Blend,
    }
}

/// A runner that ran dry starts the next line from rest no earlier than the
/// CT it is given: the same edges as a fresh runner started then, shifted.
/// Behind other lines the CT changes nothing, and a refused line leaves no
/// delay behind.
#[test]
fn a_line_after_the_runner_ran_dry_starts_no_earlier_than_asked() {
    let machine = plain_machine();
    let line = Line {
        steps: [300, -120, 0],
        feed_steps_per_s: 10_000.0,
    };
    let edges_of = |runner: &mut Runner| {
        let mut edges = Vec::new();
        while let Some(edge) = runner.next_edge_until(u64::MAX) {
            edges.push(edge);
        }
        edges
    };
    let mut runner = Runner::new(machine, [0; AXES], 1_000, HZ).unwrap();
    runner.push(line, 1).unwrap();
    let first = edges_of(&mut runner);
    let dry_at = runner.end_ct();
    // Refused (no motion): nothing of the gap stays behind.
    let still = Line {
        steps: [0; AXES],
        feed_steps_per_s: 10_000.0,
    };
    assert!(runner
        .push_no_earlier_than(still, 2, dry_at + 5_000_000)
        .is_err());
    let later = dry_at + 250_000;
    runner.push_no_earlier_than(line, 2, later).unwrap();
    // Behind a queued line the earliest CT is not a delay.
    runner.push_no_earlier_than(line, 3, u64::MAX / 2).unwrap();
    let second = edges_of(&mut runner);
    let mut fresh = Runner::new(machine, [300, -120, 0], later, HZ).unwrap();
    fresh.push(line, 2).unwrap();
    fresh.push(line, 3).unwrap();
    let expected = edges_of(&mut fresh);
    assert_eq!(second.len(), expected.len());
    for (got, want) in second.iter().zip(&expected) {
        assert_eq!(
            (got.axis, got.forward, got.tag),
            (want.axis, want.forward, want.tag)
        );
        assert!(got.ct.abs_diff(want.ct) <= 1, "{} vs {}", got.ct, want.ct);
    }
    assert!(first.last().unwrap().ct < later);
}

/// The speed along the path reads the same once a line's edges are all
/// taken (it is retired while the clock is still in it: a board computes
/// edges ahead) as while it was queued.
#[test]
fn the_path_speed_of_a_retired_line_is_still_read() {
    let machine = plain_machine();
    let mut runner = Runner::new(machine, [0; AXES], 0, HZ).unwrap();
    for tag in 0..6 {
        let line = Line {
            steps: [120, if tag % 2 == 0 { 30 } else { -30 }, 0],
            feed_steps_per_s: 15_000.0,
        };
        runner.push(line, tag).unwrap();
    }
    let end = runner.end_ct();
    let probes: Vec<u64> = (0..200).map(|k| k * end / 200).collect();
    let before: Vec<f64> = probes.iter().map(|&ct| runner.path_speed_at(ct)).collect();
    while runner.next_edge_until(u64::MAX).is_some() {}
    assert_eq!(runner.queued(), 0);
    for (&ct, want) in probes.iter().zip(&before) {
        let got = runner.path_speed_at(ct);
        assert!(
            (got - want).abs() <= 1e-9 * want.max(1.0),
            "at {ct}: {got} vs {want}"
        );
    }
    assert!(before.iter().skip(1).all(|&speed| speed > 0.0));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Axes with as many steps in a line (a diagonal) share each step's
    /// time (`PathRunner::same_next_time`: solved once, not per axis):
    /// every axis's k-th edge of the line at the same time to the bit, and
    /// the program's end exact. (Debug builds also check every cached time
    /// against a fresh solve.)
    #[test]
    fn the_axes_of_a_diagonal_step_together(
        machine in machine_strategy(),
        lines in prop::collection::vec(
            (1i32..=300, prop::array::uniform3(prop::bool::ANY), prop::array::uniform3(prop::bool::ANY), 500.0f64..60_000.0),
            1..8,
        ),
    ) {
        let lines: Vec<Line<AXES>> = lines
            .into_iter()
            .map(|(n, moves, forwards, feed_steps_per_s)| {
                let mut steps = [0; AXES];
                for axis in 0..AXES {
                    if moves[axis] || axis == 0 {
                        steps[axis] = if forwards[axis] { n } else { -n };
                    }
                }
                Line { steps, feed_steps_per_s }
            })
            .collect();
        let (runner, seen) = run_all(machine, &lines);
        prop_assert_eq!(runner.positions(), end(&lines));
        for (index, line) in lines.iter().enumerate() {
            let times = |axis: usize| -> Vec<u64> {
                seen.iter()
                    .filter(|s| s.edge.tag == index as u32 && usize::from(s.edge.axis) == axis)
                    .map(|s| s.t.to_bits())
                    .collect()
            };
            let first = times(0);
            prop_assert_eq!(first.len() as u32, line.steps[0].unsigned_abs());
            for axis in 1..AXES {
                if line.steps[axis] != 0 {
                    prop_assert_eq!(&times(axis), &first, "line {} axis {}", index, axis);
                }
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Each axis's solves in a ramp start where its last one landed
    /// (`AxisWarm`): the times depend on that chain to their last bits, so
    /// the chain must not depend on how the edges are asked for. The same
    /// program taken edge by edge, and in slices up to random limits with
    /// looks ahead (`peek_ct`) between them, as a board's main loop does:
    /// every edge at the same time to the bit.
    #[test]
    fn the_edges_do_not_depend_on_how_they_are_asked_for(
        machine in machine_strategy(),
        lines in lines_strategy(),
        slices in prop::collection::vec((1u64..20_000, prop::bool::ANY), 1..64),
    ) {
        let (_, all) = run_all(machine, &lines);
        let mut runner = Runner::new(machine, [0; AXES], 0, HZ).unwrap();
        for (tag, line) in lines.iter().enumerate() {
            runner.push(*line, tag as u32).unwrap();
        }
        let mut sliced = Vec::new();
        let mut limit = 0u64;
        for (width, peek) in slices.iter().cycle() {
            limit += width;
            if *peek {
                runner.peek_ct();
            }
            while let Some((edge, t)) = runner.next_edge_timed(limit) {
                sliced.push((edge, t.to_bits()));
            }
            if runner.peek_ct().is_none() {
                break;
            }
        }
        let all: Vec<(PathEdge, u64)> = all.iter().map(|seen| (seen.edge, seen.t.to_bits())).collect();
        prop_assert_eq!(sliced, all);
    }
}

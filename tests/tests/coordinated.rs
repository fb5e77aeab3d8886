//! Coordinated moves (`Hub::move_together`): one start CT, one straight
//! line in step space, one finish; stops keep every axis on the line and a
//! later group move completes it. Property tests in virtual time (case
//! counts from `COGSTEP_MODEL_CASES`), the main scenario in real time.

use cogstep_test_support::edges::signed_steps;
use cogstep_test_support::hub::{start_axis, tracing_hub, Wiring};
use cogstep_test_support::props::cases;
use driver::profile::scurve::Arithmetic;
use driver::{Axis, AxisError, ClockMode, Edge, Hub, HubConfig};
use proptest::prelude::*;

/// A hub with `count` axes, their stop pins high: axis `i` is `sd` on
/// stop pin 3i, step 3i + 1, dir 3i + 2 (even `i`) or `cc` on the same
/// pins (odd `i`).
fn hub_with_axes(count: usize, clock: ClockMode, arithmetic: Arithmetic) -> (Hub, Vec<Axis>) {
    let hub = tracing_hub(HubConfig {
        clock,
        arithmetic,
        ..HubConfig::default()
    });
    let axes = (0..count)
        .map(|i| start_axis(&hub, i, Wiring::sd_if(i % 2 == 0)))
        .collect();
    (hub, axes)
}

/// Every step of one axis from the trace: (CT of the rising edge, position after it).
fn steps_of(axis: &Axis, trace: &[Edge], start: i64) -> Vec<(u64, i64)> {
    signed_steps(axis.outputs(), trace)
        .into_iter()
        .map(|(ct, count)| (ct, start + count))
        .collect()
}

/// The line's progress `s(t)`: `k / L` at the lead's `k`-th edge, linear
/// between its edges, 0 before the first, constant after the last.
fn progress(lead_edges: &[u64], lead_steps: u32, t: u64) -> f64 {
    let k = lead_edges.partition_point(|&ct| ct <= t);
    let whole = k as f64;
    let fraction = match (k.checked_sub(1).map(|i| lead_edges[i]), lead_edges.get(k)) {
        (Some(before), Some(&after)) => (t - before) as f64 / (after - before) as f64,
        _ => 0.0,
    };
    (whole + fraction) / f64::from(lead_steps)
}

/// What one group move did, read back from the trace.
struct Line {
    /// Each axis's steps (CT, position after).
    steps: Vec<Vec<(u64, i64)>>,
    /// The lead's index in the group.
    lead: usize,
}

/// Checks the line of a group move whose steps were `asked` from the
/// positions `from`: the largest deviation of any axis from
/// `from + asked · s(t)` at every edge of every axis (after every edge at
/// that CT).
fn largest_deviation(line: &Line, from: &[i64], asked: &[i32]) -> f64 {
    let lead_steps = asked[line.lead].unsigned_abs();
    let lead_edges: Vec<u64> = line.steps[line.lead].iter().map(|(ct, _)| *ct).collect();
    let mut all_cts: Vec<u64> = line.steps.iter().flatten().map(|(ct, _)| *ct).collect();
    all_cts.sort_unstable();
    all_cts.dedup();
    let mut worst = 0.0f64;
    for ct in all_cts {
        let s = progress(&lead_edges, lead_steps, ct);
        for (i, steps) in line.steps.iter().enumerate() {
            let made = steps.partition_point(|(at, _)| *at <= ct);
            let position = if made == 0 {
                from[i]
            } else {
                steps[made - 1].1
            };
            let on_line = from[i] as f64 + f64::from(asked[i]) * s;
            worst = worst.max((position as f64 - on_line).abs());
        }
    }
    worst
}

fn read_line(axes: &[Axis], trace: &[Edge], from: &[i64], asked: &[i32]) -> Line {
    let lead = (0..asked.len())
        .max_by_key(|&i| (asked[i].unsigned_abs(), std::cmp::Reverse(i)))
        .unwrap();
    Line {
        steps: axes
            .iter()
            .zip(from)
            .map(|(axis, &start)| steps_of(axis, trace, start))
            .collect(),
        lead,
    }
}

fn group_of<'a>(axes: &'a [Axis], steps: &[i32]) -> Vec<(&'a Axis, i32)> {
    axes.iter().zip(steps.iter().copied()).collect()
}

fn axis_steps() -> impl Strategy<Value = i32> {
    prop_oneof![1 => Just(0), 1 => -3..=3i32, 6 => -2_500..=2_500i32]
}

fn groups() -> impl Strategy<Value = (Vec<i32>, u32, bool)> {
    (
        prop::collection::vec(axis_steps(), 2..=8),
        500u32..=40_000,
        any::<bool>(),
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(24), ..ProptestConfig::default() })]

    /// Same start CT, on the line within one step at every edge, every
    /// axis with two or more steps finishing within one lead period of the
    /// lead, every target reached.
    #[test]
    fn a_group_runs_on_one_line((asked, speed, exact) in groups()) {
        let arithmetic = if exact { Arithmetic::P2Exact } else { Arithmetic::Smooth };
        let (hub, axes) = hub_with_axes(asked.len(), ClockMode::Virtual, arithmetic);
        hub.advance(12_345);
        let from = vec![0; asked.len()];
        hub.move_together(&group_of(&axes, &asked), speed).unwrap();
        hub.run_until_idle();
        let trace = hub.take_trace();
        let line = read_line(&axes, &trace, &from, &asked);
        for (axis, steps) in axes.iter().zip(&asked) {
            prop_assert_eq!(axis.position(), i64::from(*steps));
            prop_assert_eq!(axis.steps_to_go(), 0);
        }
        if asked[line.lead] == 0 {
            prop_assert!(trace.iter().all(|edge| !edge.level || edge.pin % 3 == 0));
            return Ok(());
        }
        let lead_steps = &line.steps[line.lead];
        let start = lead_steps[0].0;
        let end = lead_steps.last().unwrap().0;
        let last_period = if lead_steps.len() >= 2 { end - lead_steps[lead_steps.len() - 2].0 } else { 0 };
        for (steps, asked) in line.steps.iter().zip(&asked) {
            if let Some((first, _)) = steps.first() {
                prop_assert_eq!(*first, start, "first edges on one CT");
            }
            if asked.unsigned_abs() >= 2 {
                let last = steps.last().unwrap().0;
                prop_assert!(end.abs_diff(last) <= last_period, "finish: {} vs {}", last, end);
            }
        }
        let deviation = largest_deviation(&line, &from, &asked);
        prop_assert!(deviation <= 1.0, "deviation {}", deviation);
    }

    /// A stop pin low on one member mid-move: every axis decelerates on
    /// the line, its steps not made are reported, and a group move of those
    /// reaches every target.
    #[test]
    fn a_stop_keeps_the_line_and_a_resume_completes_it(
        (asked, speed, exact) in groups(),
        stopper in 0usize..8,
        when in 0.0f64..1.0,
    ) {
        let arithmetic = if exact { Arithmetic::P2Exact } else { Arithmetic::Smooth };
        let (hub, axes) = hub_with_axes(asked.len(), ClockMode::Virtual, arithmetic);
        hub.advance(1_000);
        let from = vec![0; asked.len()];
        hub.move_together(&group_of(&axes, &asked), speed).unwrap();
        // Where the whole move would end, to stop somewhere inside it.
        let lead_steps = asked.iter().map(|s| s.unsigned_abs()).max().unwrap();
        let rough_ticks = 200_000_000u64 * u64::from(lead_steps) * 3 / u64::from(speed) + 1;
        hub.advance((rough_ticks as f64 * when) as u64 / 3);
        let stopper = &axes[stopper % axes.len()];
        stopper.set_stop_pin(false).unwrap();
        hub.run_until_idle();
        let trace = hub.take_trace();
        let line = read_line(&axes, &trace, &from, &asked);
        let deviation = largest_deviation(&line, &from, &asked);
        prop_assert!(deviation <= 1.0, "deviation {} while stopping", deviation);
        let mut rest = Vec::new();
        for (axis, steps) in axes.iter().zip(&asked) {
            let left = i64::from(*steps) - axis.position();
            prop_assert_eq!(u64::from(axis.dropped_steps()), left.unsigned_abs());
            let ledger = axis.ledger();
            prop_assert_eq!(ledger.base + ledger.accepted - ledger.dropped + ledger.jogged, axis.position());
            rest.push(i32::try_from(left).unwrap());
        }
        stopper.set_stop_pin(true).unwrap();
        hub.move_together(&group_of(&axes, &rest), speed).unwrap();
        hub.run_until_idle();
        for (axis, steps) in axes.iter().zip(&asked) {
            prop_assert_eq!(axis.position(), i64::from(*steps));
        }
    }
}

#[test]
fn an_axis_twice_or_busy_moves_nothing() {
    let (hub, axes) = hub_with_axes(3, ClockMode::Virtual, Arithmetic::Smooth);
    let (x, y, z) = (&axes[0], &axes[1], &axes[2]);
    assert_eq!(
        hub.move_together(&[(x, 100), (y, 50), (x, 10)], 10_000),
        Err(AxisError::DuplicateAxis)
    );
    z.move_steps(10_000, 5_000).unwrap();
    hub.advance(1_000_000);
    assert_eq!(
        hub.move_together(&[(x, 100), (y, 50), (z, 10)], 10_000),
        Err(AxisError::Busy)
    );
    hub.run_until_idle();
    assert_eq!((x.position(), y.position(), z.position()), (0, 0, 5_000));
    // The refused group gave its reservations back: each axis moves alone.
    x.move_steps(10_000, 10).unwrap();
    y.set_stop_pin(false).unwrap();
    assert_eq!(
        hub.move_together(&[(x, 100), (y, 50)], 10_000),
        Err(AxisError::Busy)
    );
    hub.run_until_idle();
    assert_eq!(
        hub.move_together(&[(x, 100), (y, 50)], 10_000),
        Err(AxisError::StopPinLow)
    );
    assert!(matches!(
        hub.move_together(&[(x, 100), (z, 50)], 0),
        Err(AxisError::Plan(_))
    ));
    hub.run_until_idle();
    assert_eq!((x.position(), y.position(), z.position()), (10, 0, 5_000));
    assert_eq!(hub.move_together(&[], 10_000), Ok(()));
    assert_eq!(hub.move_together(&[(x, 0), (z, 0)], 10_000), Ok(()));
    // A member is busy while its part runs.
    hub.move_together(&[(x, 1_000), (z, -300)], 10_000).unwrap();
    assert_eq!(x.move_steps(10_000, 5), Err(AxisError::Busy));
    assert_eq!(z.set_position(0), Err(AxisError::NotIdle));
    hub.run_until_idle();
    assert_eq!((x.position(), z.position()), (1_010, 4_700));
}

/// In P2Exact the lead's edges are the reference's for its move alone:
/// tick for tick those of `move_steps` with the same steps and speed.
#[test]
fn p2exact_lead_edges_are_the_reference_move() {
    let (hub, axes) = hub_with_axes(3, ClockMode::Virtual, Arithmetic::P2Exact);
    hub.advance(50_000);
    hub.move_together(
        &[(&axes[0], 1_500), (&axes[1], -700), (&axes[2], 3)],
        18_000,
    )
    .unwrap();
    hub.run_until_idle();
    let group = steps_of(&axes[0], &hub.take_trace(), 0);
    hub.advance(50_000);
    axes[0].move_steps(18_000, 1_500).unwrap();
    hub.run_until_idle();
    let alone = steps_of(&axes[0], &hub.take_trace(), 1_500);
    let offsets = |steps: &[(u64, i64)]| {
        steps
            .iter()
            .map(|(ct, _)| ct - steps[0].0)
            .collect::<Vec<_>>()
    };
    assert_eq!(offsets(&group), offsets(&alone));
}

/// An emergency stop of one member stops them all on the line; the dropped
/// steps complete it.
#[test]
fn an_emergency_stop_of_one_member_stops_the_group() {
    let (hub, axes) = hub_with_axes(3, ClockMode::Virtual, Arithmetic::Smooth);
    let asked = [8_000, -3_000, 1_200];
    hub.advance(1_000);
    hub.move_together(&group_of(&axes, &asked), 20_000).unwrap();
    hub.advance(40_000_000);
    axes[2].emergency_stop().unwrap();
    hub.run_until_idle();
    let trace = hub.take_trace();
    let line = read_line(&axes, &trace, &[0; 3], &asked);
    assert!(largest_deviation(&line, &[0; 3], &asked) <= 1.0);
    let rest: Vec<i32> = axes
        .iter()
        .zip(asked)
        .map(|(axis, steps)| {
            let left = i64::from(steps) - axis.position();
            assert!(left != 0);
            assert_eq!(
                u64::from(axis.dropped_steps()),
                left.unsigned_abs(),
                "axis {} ledger {:?} mode {:?}",
                axis.cog(),
                axis.ledger(),
                axis.mode()
            );
            i32::try_from(left).unwrap()
        })
        .collect();
    hub.move_together(&group_of(&axes, &rest), 20_000).unwrap();
    hub.run_until_idle();
    let positions: Vec<i64> = axes.iter().map(Axis::position).collect();
    assert_eq!(positions, vec![8_000, -3_000, 1_200]);
}

/// The main scenario with the real clock: three axes, a stop pin mid-move,
/// the resume.
#[test]
fn real_time_group_stop_and_resume() {
    let (hub, axes) = hub_with_axes(3, ClockMode::Real, Arithmetic::Smooth);
    let asked = [12_000, -4_000, 0];
    hub.move_together(&group_of(&axes, &asked), 20_000).unwrap();
    hub.run_until_idle();
    let trace = hub.take_trace();
    let line = read_line(&axes, &trace, &[0; 3], &asked);
    assert_eq!(line.steps[0][0].0, line.steps[1][0].0);
    assert!(largest_deviation(&line, &[0; 3], &asked) <= 1.0);
    let positions: Vec<i64> = axes.iter().map(Axis::position).collect();
    assert_eq!(positions, vec![12_000, -4_000, 0]);

    let from = positions;
    let back = [-12_000, 4_000, 0];
    hub.move_together(&group_of(&axes, &back), 20_000).unwrap();
    std::thread::sleep(std::time::Duration::from_millis(300));
    axes[2].set_stop_pin(false).unwrap();
    hub.run_until_idle();
    let trace = hub.take_trace();
    let line = read_line(&axes, &trace, &from, &back);
    assert!(largest_deviation(&line, &from, &back) <= 1.0);
    let rest: Vec<i32> = axes
        .iter()
        .zip(back)
        .zip(&from)
        .map(|((axis, steps), from)| {
            i32::try_from(from + i64::from(steps) - axis.position()).unwrap()
        })
        .collect();
    assert!(rest[0] != 0, "the stop came before the end");
    axes[2].set_stop_pin(true).unwrap();
    hub.move_together(&group_of(&axes, &rest), 20_000).unwrap();
    hub.run_until_idle();
    let positions: Vec<i64> = axes.iter().map(Axis::position).collect();
    assert_eq!(positions, vec![0, 0, 0]);
}

//! The planner's properties over random streams of lines.

use super::*;
use proptest::prelude::*;

const AXES: usize = 3;
const CAPACITY: usize = 32;
type TestPlanner = Planner<CAPACITY, AXES>;

fn machine_strategy() -> impl Strategy<Value = Machine<AXES>> {
    (
        prop::array::uniform3(100.0f64..50_000.0),
        prop::array::uniform3(100.0f64..1e6),
        0.0f64..50.0,
    )
        .prop_map(
            |(max_speed_steps_per_s, max_accel_steps_per_s2, junction_deviation_steps)| Machine {
                max_speed_steps_per_s,
                max_accel_steps_per_s2,
                junction_deviation_steps,
                blending: Blending::Blend,
            },
        )
}

fn line_strategy() -> impl Strategy<Value = Line<AXES>> {
    (prop::array::uniform3(-2000i32..=2000), 10.0f64..60_000.0)
        .prop_filter("a line moves", |(steps, _)| steps.iter().any(|&s| s != 0))
        .prop_map(|(steps, feed_steps_per_s)| Line {
            steps,
            feed_steps_per_s,
        })
}

fn lines_strategy() -> impl Strategy<Value = Vec<Line<AXES>>> {
    prop::collection::vec(line_strategy(), 1..24)
}

fn plan_all(machine: Machine<AXES>, lines: &[Line<AXES>]) -> TestPlanner {
    let mut planner = TestPlanner::new(machine).unwrap();
    for line in lines {
        planner.push(*line).unwrap();
    }
    planner
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()) + 1e-9
}

/// Every property a plan keeps, whatever was pushed, frozen or popped.
fn check(planner: &TestPlanner) -> Result<(), TestCaseError> {
    let machine = planner.machine();
    let segments: Vec<_> = planner.iter().collect();
    for (index, segment) in segments.iter().enumerate() {
        let plan = segment.plan();
        let line = segment.line();
        let limit = segment.speed_limit_steps_per_s();
        let lead = f64::from(segment.lead_steps());
        // Feed and every axis's limits, on the lead.
        prop_assert!(limit <= line.feed_steps_per_s);
        for axis in 0..AXES {
            let share = f64::from(line.steps[axis].unsigned_abs()) / lead;
            prop_assert!(
                plan.cruise_steps_per_s * share
                    <= machine.max_speed_steps_per_s[axis] * (1.0 + 1e-12)
            );
            prop_assert!(
                segment.accel_limit_steps_per_s2() * share
                    <= machine.max_accel_steps_per_s2[axis] * (1.0 + 1e-12)
            );
        }
        prop_assert!(
            plan.entry_steps_per_s <= limit
                && plan.exit_steps_per_s <= limit
                && plan.cruise_steps_per_s <= limit
        );
        prop_assert!(plan.cruise_steps_per_s >= plan.entry_steps_per_s.max(plan.exit_steps_per_s));
        // The ramps fit in the line, in whole steps.
        let accel = segment.accel_limit_steps_per_s2();
        let up = ramp_distance(plan.entry_steps_per_s, plan.cruise_steps_per_s, accel);
        let down = ramp_distance(plan.cruise_steps_per_s, plan.exit_steps_per_s, accel);
        let one_pulse = segment.lead_steps() == 1
            && plan.entry_steps_per_s == 0.0
            && plan.exit_steps_per_s == 0.0;
        if one_pulse {
            // One step between two rests: one pulse, no room for a ramp.
            prop_assert_eq!(
                (plan.accel_steps, plan.cruise_steps, plan.decel_steps),
                (0, 1, 0)
            );
            prop_assert!(plan.cruise_steps_per_s > 0.0);
        } else {
            prop_assert_eq!((plan.accel_steps, plan.decel_steps), (up, down));
            prop_assert!(
                u64::from(up) + u64::from(down) <= u64::from(segment.lead_steps()),
                "line {}: {:?}",
                index,
                plan
            );
        }
        prop_assert_eq!(
            plan.accel_steps + plan.cruise_steps + plan.decel_steps,
            segment.lead_steps()
        );
        // The junction at its start: within its limit, the same path speed
        // on both sides.
        let r = segment.lead_per_path();
        let junction = segment.junction_speed_steps_per_s();
        prop_assert!(junction <= segment.junction_limit_steps_per_s() * (1.0 + 1e-12));
        prop_assert!(close(plan.entry_steps_per_s, (junction * r).min(limit)));
        if index > 0 {
            let prev = segments[index - 1];
            let prev_exit_path = prev.plan().exit_steps_per_s / prev.lead_per_path();
            prop_assert!(
                close(prev_exit_path, plan.entry_steps_per_s / r),
                "junction {}",
                index
            );
            prop_assert!(
                prev_exit_path
                    <= prev.speed_limit_steps_per_s() / prev.lead_per_path() * (1.0 + 1e-12)
            );
        }
    }
    if let Some(last) = segments.last() {
        prop_assert_eq!(last.plan().exit_steps_per_s, 0.0);
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn every_plan_keeps_the_limits(machine in machine_strategy(), lines in lines_strategy()) {
        let planner = plan_all(machine, &lines);
        check(&planner)?;
        prop_assert_eq!(planner.get(0).unwrap().plan().entry_steps_per_s, 0.0);
    }

    #[test]
    fn extreme_lines_keep_the_limits(
        max_speed in prop::array::uniform3(1.0f64..2e6),
        max_accel in prop::array::uniform3(1.0f64..1e9),
        deviation in 0.0f64..1e4,
        lines in prop::collection::vec(
            (prop::array::uniform3(-(1i32 << 30)..=1 << 30), 0.01f64..1e7, 0u32..31),
            1..8,
        ),
    ) {
        let machine = Machine {
            max_speed_steps_per_s: max_speed,
            max_accel_steps_per_s2: max_accel,
            junction_deviation_steps: deviation,
            blending: Blending::Blend,
        };
        // Lengths from 1 step to 2^30: each axis's steps scaled down by a power of two.
        let lines: Vec<_> = lines
            .iter()
            .map(|&(steps, feed_steps_per_s, shift)| Line { steps: steps.map(|s| s >> shift), feed_steps_per_s })
            .filter(|line| line.steps.iter().any(|&s| s != 0))
            .collect();
        check(&plan_all(machine, &lines))?;
    }

    #[test]
    fn exact_stop_stops_at_every_junction(machine in machine_strategy(), lines in lines_strategy()) {
        let planner = plan_all(Machine { blending: Blending::ExactStop, ..machine }, &lines);
        check(&planner)?;
        for segment in planner.iter() {
            prop_assert_eq!(segment.plan().entry_steps_per_s, 0.0);
            prop_assert_eq!(segment.plan().exit_steps_per_s, 0.0);
        }
    }

    #[test]
    fn collinear_junctions_keep_speed(
        machine in machine_strategy(),
        direction in prop::array::uniform3(-20i32..=20),
        lengths in prop::collection::vec(1i32..=60, 2..16),
        feed in 10.0f64..60_000.0,
    ) {
        prop_assume!(direction.iter().any(|&d| d != 0));
        let lines: Vec<_> = lengths
            .iter()
            .map(|&k| Line { steps: direction.map(|d| d * k), feed_steps_per_s: feed })
            .collect();
        let planner = plan_all(machine, &lines);
        check(&planner)?;
        for segment in planner.iter().skip(1) {
            // Straight on: no corner limit, only the feed and the axes.
            let limit = segment.junction_limit_steps_per_s();
            prop_assert!(close(limit, segment.speed_limit_steps_per_s() / segment.lead_per_path()), "{}", limit);
            prop_assert!(segment.junction_speed_steps_per_s() > 0.0);
        }
    }

    #[test]
    fn frozen_lines_never_change(
        machine in machine_strategy(),
        lines in lines_strategy(),
        more in lines_strategy(),
        freeze in 0usize..24,
        pops in 0usize..4,
    ) {
        let mut planner = plan_all(machine, &lines);
        planner.freeze_front(freeze);
        let frozen: Vec<_> = planner.iter().take(planner.frozen()).copied().collect();
        for line in &more {
            if planner.push(*line).is_err() {
                break;
            }
            check(&planner)?;
        }
        let now: Vec<_> = planner.iter().take(frozen.len()).copied().collect();
        prop_assert_eq!(&now, &frozen);
        // Popping what ran keeps the rest's start.
        for _ in 0..pops {
            let next_entry = planner.get(1).map(|s| s.junction_speed_steps_per_s());
            planner.pop_front();
            prop_assert_eq!(planner.get(0).map(|s| s.junction_speed_steps_per_s()), next_entry);
            if planner.push(more[0]).is_ok() {
                check(&planner)?;
            }
        }
    }

    #[test]
    fn more_lines_never_lower_a_junction(machine in machine_strategy(), lines in lines_strategy(), more in lines_strategy()) {
        // What the frozen lines rely on: a longer queue has more room to stop.
        let mut planner = plan_all(machine, &lines);
        let before: Vec<_> = planner.iter().map(|s| s.junction_speed_steps_per_s()).collect();
        for line in &more {
            if planner.push(*line).is_err() {
                break;
            }
            for (segment, &speed) in planner.iter().zip(&before) {
                prop_assert!(segment.junction_speed_steps_per_s() >= speed * (1.0 - 1e-12));
            }
        }
    }

    #[test]
    fn exact_stop_junctions_stop_in_a_blended_stream(
        machine in machine_strategy(),
        lines in lines_strategy(),
        exact in prop::collection::vec(any::<bool>(), 24),
    ) {
        let mut planner = TestPlanner::new(machine).unwrap();
        for (line, &exact) in lines.iter().zip(&exact) {
            planner.set_blending(if exact { Blending::ExactStop } else { Blending::Blend });
            planner.push(*line).unwrap();
        }
        check(&planner)?;
        for (segment, &exact) in planner.iter().zip(&exact) {
            if exact {
                prop_assert_eq!(segment.junction_speed_steps_per_s(), 0.0);
                prop_assert_eq!(segment.plan().entry_steps_per_s, 0.0);
            }
        }
    }

    #[test]
    fn planning_is_deterministic(machine in machine_strategy(), lines in lines_strategy()) {
        let a = plan_all(machine, &lines);
        let b = plan_all(machine, &lines);
        let a: Vec<_> = a.iter().copied().collect();
        let b: Vec<_> = b.iter().copied().collect();
        prop_assert_eq!(a, b);
    }
}

#[test]
fn long_collinear_lines_run_at_the_feed() {
    let machine = Machine {
        max_speed_steps_per_s: [10_000.0; AXES],
        max_accel_steps_per_s2: [100_000.0; AXES],
        junction_deviation_steps: 1.0,
        blending: Blending::Blend,
    };
    let mut planner = TestPlanner::new(machine).unwrap();
    for _ in 0..4 {
        planner
            .push(Line {
                steps: [4000, 2000, 0],
                feed_steps_per_s: 5000.0,
            })
            .unwrap();
    }
    let speeds: Vec<_> = planner.iter().map(|s| s.plan()).collect();
    for pair in speeds.windows(2) {
        assert_eq!(pair[0].exit_steps_per_s, 5000.0);
        assert_eq!(pair[1].entry_steps_per_s, 5000.0);
    }
    assert_eq!(speeds[0].accel_steps, ramp_distance(0.0, 5000.0, 100_000.0));
    assert_eq!(speeds[3].decel_steps, ramp_distance(5000.0, 0.0, 100_000.0));
}

#[test]
fn a_right_angle_slows_to_the_deviation_speed() {
    let machine = Machine {
        max_speed_steps_per_s: [10_000.0; AXES],
        max_accel_steps_per_s2: [100_000.0; AXES],
        junction_deviation_steps: 2.0,
        blending: Blending::Blend,
    };
    let mut planner = TestPlanner::new(machine).unwrap();
    planner
        .push(Line {
            steps: [20_000, 0, 0],
            feed_steps_per_s: 8000.0,
        })
        .unwrap();
    planner
        .push(Line {
            steps: [0, 20_000, 0],
            feed_steps_per_s: 8000.0,
        })
        .unwrap();
    let corner = junction_deviation_speed(&[1.0, 0.0, 0.0], &[0.0, 1.0, 0.0], 100_000.0, 2.0);
    let junction = planner.get(1).unwrap().junction_speed_steps_per_s();
    assert!(close(junction, corner), "{junction} {corner}");
    assert!(corner < 8000.0);
}

#[test]
fn refusals() {
    let machine = Machine {
        max_speed_steps_per_s: [1000.0; AXES],
        max_accel_steps_per_s2: [1000.0; AXES],
        junction_deviation_steps: 1.0,
        blending: Blending::Blend,
    };
    assert_eq!(
        TestPlanner::new(Machine {
            max_accel_steps_per_s2: [1.0, 0.0, 1.0],
            ..machine
        })
        .unwrap_err(),
        MachineError::MaxAccel(1)
    );
    assert_eq!(
        TestPlanner::new(Machine {
            junction_deviation_steps: -1.0,
            ..machine
        })
        .unwrap_err(),
        MachineError::JunctionDeviation
    );
    assert!(Planner::<4, 9>::new(Machine {
        max_speed_steps_per_s: [1.0; 9],
        max_accel_steps_per_s2: [1.0; 9],
        junction_deviation_steps: 1.0,
        blending: Blending::Blend,
    })
    .is_err());
    let mut planner = Planner::<2, AXES>::new(machine).unwrap();
    assert_eq!(
        planner.push(Line {
            steps: [0; AXES],
            feed_steps_per_s: 1.0
        }),
        Err(PushError::NoMotion)
    );
    assert_eq!(
        planner.push(Line {
            steps: [1, 0, 0],
            feed_steps_per_s: f64::NAN
        }),
        Err(PushError::Feed)
    );
    let rapid = Line {
        steps: [1, 0, 0],
        feed_steps_per_s: f64::INFINITY,
    };
    planner.push(rapid).unwrap();
    planner.push(rapid).unwrap();
    assert_eq!(planner.push(rapid), Err(PushError::Full));
    assert!(planner
        .iter()
        .all(|s| s.speed_limit_steps_per_s() == 1000.0));
}

/// One operation on a planner that runs: what the runner does to it.
#[derive(Clone, Debug)]
enum Op {
    Push(Line<AXES>),
    Freeze(usize),
    Pop,
    Overrides(f64),
}

fn op_strategy() -> impl Strategy<Value = Op> {
    prop_oneof![
        6 => line_strategy().prop_map(Op::Push),
        1 => (0usize..4).prop_map(Op::Freeze),
        2 => Just(Op::Pop),
        1 => (0.1f64..2.0).prop_map(Op::Overrides),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The settled entries (grbl's "planned up to here") are an economy,
    /// never a difference: after every push, freeze, pop and override the
    /// junction speeds and plans are bit for bit those of planning every
    /// line that is not frozen again.
    #[test]
    fn settled_entries_plan_as_a_full_replan_would(
        machine in machine_strategy(),
        ops in prop::collection::vec(op_strategy(), 1..120),
    ) {
        let mut planner = TestPlanner::new(machine).unwrap();
        for op in ops {
            match op {
                Op::Push(line) => {
                    if planner.is_full() {
                        planner.freeze_front(1);
                        planner.pop_front();
                    }
                    planner.push(line).unwrap();
                }
                Op::Freeze(count) => planner.freeze_front(planner.frozen() + count),
                Op::Pop => {
                    planner.freeze_front(1);
                    planner.pop_front();
                }
                Op::Overrides(scale) => planner.set_overrides(scale, 1.0).unwrap(),
            }
            let fresh = planner.replanned();
            for (index, (a, b)) in planner.iter().zip(fresh.iter()).enumerate() {
                prop_assert_eq!(
                    a.junction_speed_steps_per_s().to_bits(),
                    b.junction_speed_steps_per_s().to_bits(),
                    "line {}", index
                );
                prop_assert_eq!(a.plan(), b.plan(), "line {}", index);
            }
        }
    }
}

//! The hub's look-ahead path (`Hub::path`, `PathJob`): the steps on the
//! pins are the planner's, every axis ends exactly on its target, a stop
//! pin holds along the path and resume finishes it, an e-stop or a limit
//! stops every axis, soft limits refuse a line before it runs. Virtual
//! time, plus a real-clock run.

use cogstep_test_support::edges::signed_steps;
use cogstep_test_support::hub::{start_axis, tracing_hub, Wiring};
use cogstep_test_support::ledger::assert_accounted;
use driver::planner::{Blending, Line, Machine, PathRunner, PathState, MAX_AXES};
use driver::{Axis, AxisError, ClockMode, Hub, HubConfig, PathError, PathFault, PathMachine};

fn hub_with_axes(count: usize, clock: ClockMode) -> (Hub, Vec<Axis>) {
    let hub = tracing_hub(HubConfig {
        clock,
        ..HubConfig::default()
    });
    let axes = (0..count)
        .map(|i| start_axis(&hub, i, Wiring::sd_if(i % 2 == 0)))
        .collect();
    (hub, axes)
}

fn machine(count: usize) -> PathMachine {
    PathMachine {
        max_speed_steps_per_s: vec![20_000.0; count],
        max_accel_steps_per_s2: vec![400_000.0; count],
        junction_deviation_steps: 2.0,
        blending: Blending::Blend,
    }
}

/// A square with a diagonal, and a short zig-zag: corners, reversals,
/// collinear joins.
fn program() -> Vec<[i32; 3]> {
    vec![
        [4_000, 0, 100],
        [0, 3_000, 100],
        [-4_000, 0, 100],
        [0, -3_000, -300],
        [2_000, 1_500, 0],
        [2_000, 1_500, 0],
        [150, -150, 0],
        [150, 150, 0],
        [150, -150, 0],
    ]
}

/// The same program run by the planner alone, from CT `origin`.
fn runner_edges(origin: u64, clkfreq: u32, feed: f64) -> Vec<Vec<(u64, i64)>> {
    let m = Machine {
        max_speed_steps_per_s: [20_000.0; MAX_AXES],
        max_accel_steps_per_s2: [400_000.0; MAX_AXES],
        junction_deviation_steps: 2.0,
        blending: Blending::Blend,
    };
    let mut runner = PathRunner::<32, MAX_AXES>::new(m, [0; MAX_AXES], origin, clkfreq).unwrap();
    for (tag, steps) in program().iter().enumerate() {
        let mut line = Line {
            steps: [0; MAX_AXES],
            feed_steps_per_s: feed,
        };
        line.steps[..3].copy_from_slice(steps);
        runner.push(line, tag as u32).unwrap();
    }
    let mut per_axis = vec![Vec::new(); 3];
    let mut position = [0i64; 3];
    while let Some(edge) = runner.next_edge_until(u64::MAX) {
        let axis = usize::from(edge.axis);
        position[axis] += if edge.forward { 1 } else { -1 };
        per_axis[axis].push((edge.ct, position[axis]));
    }
    per_axis
}

/// With the real clock: waits (polling) until `done()` holds, failing
/// with `what` at `deadline`.
fn wait_for(deadline: std::time::Instant, what: &str, mut done: impl FnMut() -> bool) {
    while !done() {
        assert!(std::time::Instant::now() < deadline, "{what}");
        std::thread::sleep(std::time::Duration::from_micros(200));
    }
}

fn end_of_program() -> [i64; 3] {
    let mut end = [0i64; 3];
    for steps in program() {
        for (e, s) in end.iter_mut().zip(steps) {
            *e += i64::from(s);
        }
    }
    end
}

#[test]
fn the_pins_carry_the_planners_edges_and_every_axis_ends_on_its_target() {
    let (hub, axes) = hub_with_axes(3, ClockMode::Virtual);
    let refs: Vec<&Axis> = axes.iter().collect();
    let start = hub.now();
    let job = hub.path(&refs, machine(3)).unwrap();
    for (tag, steps) in program().iter().enumerate() {
        job.push(steps, 15_000.0, tag as u32).unwrap();
    }
    // While on the path the axes refuse every other motion.
    assert_eq!(axes[0].move_steps(1_000, 10), Err(AxisError::Busy));
    let done = job.finish().unwrap();
    assert_eq!(done.state, PathState::Idle);
    let end = end_of_program();
    for (axis, target) in axes.iter().zip(end) {
        assert_eq!(axis.position(), target);
        assert_accounted(axis);
    }
    // Edge for edge the planner's, from the path's origin (now + the
    // direction set-up).
    let origin = start + u64::from(hub.config().dir_setup_ticks);
    let expected = runner_edges(origin, hub.config().clkfreq, 15_000.0);
    let trace = hub.take_trace();
    for (index, axis) in axes.iter().enumerate() {
        let seen = signed_steps(axis.outputs(), &trace);
        assert_eq!(seen.len(), expected[index].len(), "axis {index}");
        for (got, want) in seen.iter().zip(&expected[index]) {
            // A reversal waits for the direction pin's set-up: never early,
            // at most the set-up late.
            assert_eq!(got.1, want.1, "axis {index} at {}", want.0);
            let late = got.0 - want.0;
            assert!(
                late <= u64::from(hub.config().dir_setup_ticks)
                    + u64::from(hub.config().pulse_ticks),
                "axis {index}: {late} ticks late at {}",
                want.0
            );
        }
    }
    // The axes are free again.
    axes[0].move_steps(1_000, 10).unwrap();
    hub.run_until_idle();
    assert_eq!(axes[0].position(), end[0] + 10);
}

/// With the virtual clock nothing but the owner moves time on: a push
/// that waits for room while the path is held at rest is refused (nothing
/// queued) instead of waiting for ever; after a resume it goes in.
#[test]
fn a_push_into_a_full_held_path_is_refused_not_left_waiting() {
    let (hub, axes) = hub_with_axes(2, ClockMode::Virtual);
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = hub.path(&refs, machine(2)).unwrap();
    job.push(&[4_000, 1_000], 15_000.0, 1).unwrap();
    hub.advance(hub.config().clkfreq as u64 / 20);
    axes[0].set_stop_pin(false).unwrap();
    let mut tag = 2;
    let refused = loop {
        match job.push(&[10, 10], 15_000.0, tag) {
            Ok(()) => tag += 1,
            Err(error) => break error,
        }
        assert!(tag < 1_000, "the queue never filled");
    };
    assert_eq!(refused, PathError::HeldFull);
    assert_eq!(job.progress().state, PathState::Held);
    let queued = job.progress().queued;
    assert_eq!(job.push(&[10, 10], 15_000.0, tag), Err(PathError::HeldFull));
    assert_eq!(job.progress().queued, queued, "nothing was queued");
    axes[0].set_stop_pin(true).unwrap();
    job.resume().unwrap();
    job.push(&[10, 10], 15_000.0, tag).unwrap();
    job.finish().unwrap();
    let lines = i64::from(tag - 1);
    assert_eq!(axes[0].position(), 4_000 + 10 * lines);
    assert_eq!(axes[1].position(), 1_000 + 10 * lines);
    for axis in &axes {
        assert_accounted(axis);
    }
}

#[test]
fn a_stop_pin_holds_along_the_path_and_resume_finishes_it_exactly() {
    let (hub, axes) = hub_with_axes(3, ClockMode::Virtual);
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = hub.path(&refs, machine(3)).unwrap();
    for (tag, steps) in program().iter().enumerate() {
        job.push(steps, 15_000.0, tag as u32).unwrap();
    }
    hub.advance(hub.config().clkfreq as u64 / 5);
    let moving = job.progress();
    assert_eq!(moving.state, PathState::Running);
    assert!(moving.speed_steps_per_s > 1_000.0);
    axes[1].set_stop_pin(false).unwrap();
    // Held within the ramp to rest (well under 100 ms at these limits).
    hub.advance(hub.config().clkfreq as u64 / 10);
    let held = job.progress();
    assert_eq!(held.state, PathState::Held);
    let positions: Vec<i64> = axes.iter().map(Axis::position).collect();
    hub.advance(hub.config().clkfreq as u64 / 10);
    assert_eq!(
        positions,
        axes.iter().map(Axis::position).collect::<Vec<_>>()
    );
    assert_eq!(
        job.resume(),
        Err(PathError::NotHeld),
        "the stop pin is still low"
    );
    axes[1].set_stop_pin(true).unwrap();
    job.resume().unwrap();
    job.finish().unwrap();
    for (axis, target) in axes.iter().zip(end_of_program()) {
        assert_eq!(axis.position(), target);
        assert_accounted(axis);
    }
}

#[test]
fn an_emergency_stop_of_one_axis_stops_the_whole_path() {
    let (hub, axes) = hub_with_axes(3, ClockMode::Virtual);
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = hub.path(&refs, machine(3)).unwrap();
    for (tag, steps) in program().iter().enumerate() {
        job.push(steps, 15_000.0, tag as u32).unwrap();
    }
    hub.advance(hub.config().clkfreq as u64 / 5);
    axes[2].emergency_stop().unwrap();
    hub.advance(hub.config().clkfreq as u64 / 100);
    assert_eq!(job.progress().fault, Some(PathFault::Stopped(2)));
    let positions: Vec<i64> = axes.iter().map(Axis::position).collect();
    hub.run_until_idle();
    assert_eq!(
        positions,
        axes.iter().map(Axis::position).collect::<Vec<_>>()
    );
    for axis in &axes {
        assert_accounted(axis);
    }
    assert_eq!(
        job.push(&[1, 1, 1], 1_000.0, 99),
        Err(PathError::Stopped(PathFault::Stopped(2)))
    );
}

#[test]
fn a_line_beyond_a_soft_limit_is_refused_before_it_runs() {
    let (hub, axes) = hub_with_axes(2, ClockMode::Virtual);
    axes[1].set_soft_limits(-100, 2_000).unwrap();
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = hub.path(&refs, machine(2)).unwrap();
    job.push(&[1_000, 1_500], 10_000.0, 1).unwrap();
    assert_eq!(
        job.push(&[1_000, 600], 10_000.0, 2),
        Err(PathError::BeyondSoftLimit { axis: 1 })
    );
    assert_eq!(
        job.push(&[1_000], 10_000.0, 3),
        Err(PathError::AxisCount(2))
    );
    job.push(&[-1_000, 500], 10_000.0, 4).unwrap();
    job.finish().unwrap();
    assert_eq!((axes[0].position(), axes[1].position()), (0, 2_000));
}

#[test]
fn a_path_refuses_axes_that_are_not_free() {
    let (hub, axes) = hub_with_axes(2, ClockMode::Virtual);
    axes[0].move_steps(1_000, 500).unwrap();
    let refs: Vec<&Axis> = axes.iter().collect();
    assert_eq!(
        hub.path(&refs, machine(2)).err(),
        Some(PathError::Axis(AxisError::Busy))
    );
    hub.run_until_idle();
    axes[1].set_stop_pin(false).unwrap();
    assert_eq!(
        hub.path(&refs, machine(2)).err(),
        Some(PathError::Axis(AxisError::StopPinLow))
    );
    // Nothing was left reserved: a move runs.
    axes[0].move_steps(1_000, 10).unwrap();
    hub.run_until_idle();
    assert_eq!(axes[0].position(), 510);
    assert_eq!(
        hub.path(&[&axes[0], &axes[0]], machine(2)).err(),
        Some(PathError::Axis(AxisError::DuplicateAxis))
    );
}

#[test]
fn a_full_queue_blocks_the_caller_until_a_line_is_done() {
    let (hub, axes) = hub_with_axes(2, ClockMode::Virtual);
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = hub.path(&refs, machine(2)).unwrap();
    // Twice the queue's length of short lines: the later pushes advance
    // the virtual clock until there is room.
    for tag in 0..64 {
        let dir = if tag % 2 == 0 { 1 } else { -1 };
        job.push(&[200, 100 * dir], 12_000.0, tag).unwrap();
        assert!(job.progress().queued <= 32);
    }
    let done = job.finish().unwrap();
    assert_eq!(done.done, 64);
    assert_eq!((axes[0].position(), axes[1].position()), (12_800, 0));
}

#[test]
fn a_path_runs_with_the_real_clock() {
    let (_hub, axes) = hub_with_axes(2, ClockMode::Real);
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = _hub.path(&refs, machine(2)).unwrap();
    for tag in 0..20 {
        job.push(&[300, if tag % 2 == 0 { 200 } else { -200 }], 10_000.0, tag)
            .unwrap();
    }
    job.finish().unwrap();
    assert_eq!((axes[0].position(), axes[1].position()), (6_000, 0));
    for axis in &axes {
        assert_accounted(axis);
    }
}

#[test]
fn a_hard_limit_during_a_path_stops_every_axis_at_once() {
    let (hub, axes) = hub_with_axes(2, ClockMode::Virtual);
    // Pin 20: active from x = 3 000 on.
    hub.attach_switch(20, &axes[0], 3_000..=i64::MAX, true)
        .unwrap();
    axes[0].set_limit_pins(None, Some((20, true))).unwrap();
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = hub.path(&refs, machine(2)).unwrap();
    job.push(&[5_000, 2_500], 10_000.0, 1).unwrap();
    assert_eq!(
        job.wait(),
        Err(PathError::Stopped(PathFault::Limit {
            axis: 0,
            side: driver::Direction::Forward
        }))
    );
    hub.run_until_idle();
    // x stopped on the step that closed the switch; y within the slice.
    assert_eq!(axes[0].position(), 3_000);
    let line = 3_000.0 * 2_500.0 / 5_000.0;
    assert!(
        (axes[1].position() as f64 - line).abs() <= 40.0,
        "{}",
        axes[1].position()
    );
    for axis in &axes {
        assert_accounted(axis);
    }
    drop(job);
    // Away from the limit after clearing the fault.
    axes[0].clear_limit_fault().unwrap();
    axes[0].move_steps(5_000, -1_000).unwrap();
    hub.run_until_idle();
    assert_eq!(axes[0].position(), 2_000);
}

mod props {
    use super::*;
    use cogstep_test_support::props::cases;
    use proptest::prelude::*;

    fn lines() -> impl Strategy<Value = Vec<([i32; 3], f64)>> {
        prop::collection::vec(
            (prop::array::uniform3(-600i32..=600), 2_000.0f64..20_000.0)
                .prop_filter("moves", |(steps, _)| steps.iter().any(|&s| s != 0)),
            1..40,
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(cases(12)))]

        /// Random programs on the hub, with a stop pin dropped and raised
        /// at random moments: a hold comes to rest and stays, resume goes
        /// on, and the axes end exactly on the program's end, their ledgers
        /// balanced (`COGSTEP_MODEL_CASES` raises the count; 300 pass).
        #[test]
        fn a_program_on_the_hub_ends_exactly_on_its_end(
            program in lines(),
            hold_at_ms in prop::option::of(1u64..300),
            pause_ms in 1u64..50,
        ) {
            let (hub, axes) = hub_with_axes(3, ClockMode::Virtual);
            let refs: Vec<&Axis> = axes.iter().collect();
            let job = hub.path(&refs, machine(3)).unwrap();
            let mut end = [0i64; 3];
            let ms = u64::from(hub.config().clkfreq) / 1_000;
            for (tag, (steps, feed)) in program.iter().enumerate() {
                job.push(steps, *feed, tag as u32).unwrap();
                for (e, s) in end.iter_mut().zip(steps) {
                    *e += i64::from(*s);
                }
            }
            if let Some(at) = hold_at_ms {
                hub.advance(at * ms);
                axes[0].set_stop_pin(false).unwrap();
                hub.advance(200 * ms);
                let state = job.progress().state;
                prop_assert!(matches!(state, PathState::Held | PathState::Idle), "{:?}", state);
                let still: Vec<i64> = axes.iter().map(Axis::position).collect();
                hub.advance(pause_ms * ms);
                prop_assert_eq!(&still, &axes.iter().map(Axis::position).collect::<Vec<_>>());
                axes[0].set_stop_pin(true).unwrap();
                if state == PathState::Held {
                    job.resume().unwrap();
                }
            }
            job.finish().unwrap();
            for (axis, target) in axes.iter().zip(end) {
                prop_assert_eq!(axis.position(), target);
                assert_accounted(axis);
            }
        }
    }
}
#[test]
fn with_the_real_clock_held_means_at_rest() {
    // The stop's last edges are computed ahead of the clock: the progress
    // says Held only once the axes have made them.
    let (_hub, axes) = hub_with_axes(2, ClockMode::Real);
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = _hub.path(&refs, machine(2)).unwrap();
    for tag in 0..20 {
        job.push(&[300, if tag % 2 == 0 { 200 } else { -200 }], 10_000.0, tag)
            .unwrap();
    }
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    wait_for(deadline, "the path never ran", || job.progress().done >= 3);
    job.hold();
    wait_for(deadline, "never held", || {
        job.progress().state == PathState::Held
    });
    let held: Vec<i64> = axes.iter().map(Axis::position).collect();
    std::thread::sleep(std::time::Duration::from_millis(30));
    assert_eq!(held, axes.iter().map(Axis::position).collect::<Vec<_>>());
    job.resume().unwrap();
    job.finish().unwrap();
    assert_eq!((axes[0].position(), axes[1].position()), (6_000, 0));
}

#[test]
fn another_thread_holds_and_resumes_a_path_whose_owner_waits_in_push() {
    let (hub, axes) = hub_with_axes(2, ClockMode::Real);
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = hub.path(&refs, machine(2)).unwrap();
    let control = job.control();
    // More lines than the queue holds: the owner waits in push for room.
    let owner = std::thread::spawn(move || {
        for tag in 0..48 {
            let dir = if tag % 2 == 0 { 1 } else { -1 };
            job.push(&[200, 100 * dir], 12_000.0, tag).unwrap();
        }
        job
    });
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    wait_for(deadline, "the path never ran", || {
        control.progress().done >= 4
    });
    control.hold();
    wait_for(deadline, "never held", || {
        control.progress().state == PathState::Held
    });
    let held: Vec<i64> = axes.iter().map(Axis::position).collect();
    std::thread::sleep(std::time::Duration::from_millis(50));
    assert_eq!(held, axes.iter().map(Axis::position).collect::<Vec<_>>());
    assert!(held[0] < 9_600, "held before the end: {held:?}");
    assert!(!owner.is_finished(), "the owner still waits for room");
    control.resume().unwrap();
    let job = owner.join().unwrap();
    job.finish().unwrap();
    assert_eq!((axes[0].position(), axes[1].position()), (9_600, 0));
    for axis in &axes {
        assert_accounted(axis);
    }
}

#[test]
fn a_cancel_refuses_the_push_that_waits_for_room_and_nothing_runs_after_it() {
    let (hub, axes) = hub_with_axes(2, ClockMode::Real);
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = hub.path(&refs, machine(2)).unwrap();
    let control = job.control();
    let owner = std::thread::spawn(move || {
        for tag in 0..48 {
            let dir = if tag % 2 == 0 { 1 } else { -1 };
            if let Err(error) = job.push(&[200, 100 * dir], 12_000.0, tag) {
                return (job, Some((tag, error)));
            }
        }
        (job, None)
    });
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    wait_for(deadline, "the path never ran", || {
        control.progress().done >= 4
    });
    control.cancel();
    let (job, refused) = owner.join().unwrap();
    let (tag, error) = refused.expect("the waiting push is refused");
    assert_eq!(error, PathError::Cancelled);
    assert!(tag >= 32, "it waited for room: {tag}");
    let done = job.wait().unwrap();
    assert_eq!(done.state, PathState::Idle);
    // What the cancel dropped is neither done nor still queued.
    assert_eq!(done.queued, 0, "{done:?}");
    assert!(done.done < u64::from(tag), "{done:?}");
    let stopped: Vec<i64> = axes.iter().map(Axis::position).collect();
    std::thread::sleep(std::time::Duration::from_millis(50));
    assert_eq!(stopped, axes.iter().map(Axis::position).collect::<Vec<_>>());
    assert!(stopped[0] < 9_600, "cancelled before the end: {stopped:?}");
    // The path takes new lines after a cancel.
    job.push(&[-stopped[0] as i32, -stopped[1] as i32], 12_000.0, 99)
        .unwrap();
    job.finish().unwrap();
    assert_eq!((axes[0].position(), axes[1].position()), (0, 0));
}

#[test]
fn a_cancel_while_a_gcode_line_queues_its_chords_refuses_the_rest_of_the_line() {
    use driver::gcode::{GcodePath, GcodePathError, MachineSpec};
    let (hub, axes) = hub_with_axes(2, ClockMode::Real);
    let spec = MachineSpec::from_toml_str(
        "[axes.x]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 100.0\nmax_accel_mm_s2 = 2000.0\n\
         [axes.y]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 100.0\nmax_accel_mm_s2 = 2000.0\n\
         [planner]\njunction_deviation_mm = 0.01\narc_tolerance_mm = 0.002\n",
    )
    .unwrap();
    let refs: Vec<&Axis> = axes.iter().collect();
    let mut program = GcodePath::new(&hub, &refs, &spec).unwrap();
    let control = program.job().control();
    program.run_line(1, "G1 X1 F3000").unwrap();
    // A full circle of 10 mm radius: far more chords than the queue holds.
    let owner = std::thread::spawn(move || {
        let outcome = program.run_line(2, "G2 X1 Y0 I10 J0");
        (program, outcome)
    });
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    wait_for(deadline, "the arc never ran", || {
        control.progress().tag == 2
    });
    control.cancel();
    let (program, outcome) = owner.join().unwrap();
    assert!(
        matches!(
            outcome,
            Err(GcodePathError::Path {
                line: 2,
                error: PathError::Cancelled
            })
        ),
        "{outcome:?}"
    );
    program.job().wait().unwrap();
    let stopped: Vec<i64> = axes.iter().map(Axis::position).collect();
    std::thread::sleep(std::time::Duration::from_millis(50));
    assert_eq!(stopped, axes.iter().map(Axis::position).collect::<Vec<_>>());
    assert_ne!(stopped, [80, 0], "stopped on the circle, not at its end");
}

/// A path that ran dry and waited (a sender slower than the machine, a
/// pause between two commands) starts its next line from rest *then*: no
/// edge of it is in the past, and its steps are spaced as a start from
/// rest, not made in a burst to catch up.
#[test]
fn a_line_pushed_after_the_path_ran_dry_starts_from_rest_then() {
    let (hub, axes) = hub_with_axes(2, ClockMode::Virtual);
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = hub.path(&refs, machine(2)).unwrap();
    job.push(&[1_000, 500], 10_000.0, 1).unwrap();
    job.wait().unwrap();
    // A second at rest.
    hub.advance(u64::from(hub.config().clkfreq));
    let _ = hub.take_trace();
    let pushed_at = hub.now();
    job.push(&[1_000, 500], 10_000.0, 2).unwrap();
    job.finish().unwrap();
    assert_eq!((axes[0].position(), axes[1].position()), (2_000, 1_000));
    let trace = hub.take_trace();
    let steps = signed_steps(axes[0].outputs(), &trace);
    assert_eq!(steps.len(), 1_000);
    assert!(
        steps[0].0 >= pushed_at,
        "the first edge at {} is before the push at {pushed_at}",
        steps[0].0
    );
    // From rest: the first interval is the longest of the ramp up.
    let first = steps[1].0 - steps[0].0;
    let cruise = steps[500].0 - steps[499].0;
    assert!(
        first > 2 * cruise,
        "first interval {first}, cruise {cruise}"
    );
}

/// A hold asked of an idle path holds it (a feed hold before the program):
/// the lines pushed then wait, nothing moves however long, and resume runs
/// them to their end exactly.
#[test]
fn a_hold_of_an_idle_path_keeps_the_lines_pushed_until_resume() {
    let (hub, axes) = hub_with_axes(2, ClockMode::Virtual);
    let refs: Vec<&Axis> = axes.iter().collect();
    let job = hub.path(&refs, machine(2)).unwrap();
    job.hold();
    assert_eq!(job.progress().state, PathState::Held);
    job.push(&[1_000, 500], 10_000.0, 1).unwrap();
    job.push(&[1_000, -500], 10_000.0, 2).unwrap();
    hub.advance(u64::from(hub.config().clkfreq) / 2);
    assert_eq!((axes[0].position(), axes[1].position()), (0, 0));
    assert_eq!(job.progress().state, PathState::Held);
    assert_eq!(job.progress().queued, 2);
    job.resume().unwrap();
    let done = job.finish().unwrap();
    assert_eq!(done.done, 2);
    assert_eq!((axes[0].position(), axes[1].position()), (2_000, 0));
    for axis in &axes {
        assert_accounted(axis);
    }
}

//! Behaviour of the hub and its cogs through the shared-memory API, as a
//! user of `driver` sees it: positions, STM, mode bits and the pin edges.

use std::collections::BTreeMap;

use cogstep_test_support::edges::rising;
use cogstep_test_support::hub::tracing_hub;
use driver::profile::scurve::{SCurve, ScurveConfig};
use driver::{AxisError, ClockMode, Direction, Edge, Hub, HubConfig, HubError, Mode};

const STOP: u8 = 0;
const STEP: u8 = 1;
const DIR: u8 = 2;

fn virtual_hub() -> Hub {
    tracing_hub(HubConfig::default())
}

fn edges_on(edges: &[Edge], pin: u8) -> Vec<Edge> {
    edges.iter().copied().filter(|e| e.pin == pin).collect()
}

/// The delays the motion core computes for a fresh move.
fn profile_delays(speed: u32, steps: u32) -> Vec<u64> {
    SCurve::new(ScurveConfig::default(), speed, steps)
        .expect("plan")
        .map(|s| u64::from(s.delay_ticks))
        .collect()
}

#[test]
fn sd_move_forward_then_back_with_exact_edges() {
    let hub = virtual_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    let start = hub.now();
    x.move_steps(20_000, 3_000).unwrap();
    assert_eq!(
        x.steps_to_go(),
        3_000,
        "STM shows the move as soon as the cog took it"
    );
    assert!(
        x.mode().has(Mode::MOVING),
        "the mode shows the move at once"
    );
    hub.run_until_idle();
    assert_eq!(x.position(), 3_000);
    assert_eq!(x.stm(), 0);
    assert!(!x.mode().has(Mode::MOVING));

    let trace = hub.take_trace();
    let rises = rising(&trace, STEP);
    assert_eq!(rises.len(), 3_000);
    assert_eq!(
        rises[0], start,
        "the first step rises at the CT the move was given"
    );
    let expected = profile_delays(20_000, 3_000);
    for (i, w) in rises.windows(2).enumerate() {
        assert_eq!(w[1] - w[0], expected[i], "interval after step {i}");
    }
    // Every pulse is exactly the configured width.
    let step_edges = edges_on(&trace, STEP);
    for pair in step_edges.chunks(2) {
        assert!(pair[0].level && !pair[1].level);
        assert_eq!(pair[1].ct - pair[0].ct, 1_000);
    }
    assert!(
        edges_on(&trace, DIR).is_empty(),
        "forward needs no direction change"
    );

    // Back: the direction pin goes high at least the set-up time before the step.
    x.move_steps(20_000, -3_000).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), 0);
    let trace = hub.take_trace();
    let dir = edges_on(&trace, DIR);
    assert_eq!(dir.len(), 1);
    assert!(dir[0].level);
    let first_back = rising(&trace, STEP)[0];
    assert!(
        first_back >= dir[0].ct + 1_000,
        "direction set-up respected"
    );
    // As the reference (`and mode, #%0100000`): at the end of a move only
    // b5 survives, so the direction bit clears; the pin keeps its level.
    assert_eq!(x.mode().reference_bits(), 0);
    assert!(hub.output(DIR));
}

#[test]
fn mode_bits_follow_the_phases() {
    let hub = virtual_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    x.move_steps(10_000, -5_000).unwrap();
    let mut seen = Vec::new();
    while x.steps_to_go() > 0 {
        hub.advance(200_000); // 1 ms
        let mode = x.mode();
        let phase = if mode.has(Mode::ACCEL) {
            "accel"
        } else if mode.has(Mode::SLEW) {
            "slew"
        } else if mode.has(Mode::DECEL) {
            "decel"
        } else {
            "none"
        };
        if seen.last() != Some(&phase) {
            seen.push(phase);
        }
        if mode.has(Mode::MOVING) {
            assert!(
                mode.has(Mode::REVERSE),
                "direction bit set for negative steps"
            );
            // Exactly one phase bit while moving.
            let phases = mode & (Mode::ACCEL | Mode::SLEW | Mode::DECEL);
            assert_eq!(phases.iter().count(), 1, "{mode:?}");
        }
    }
    hub.run_until_idle();
    assert_eq!(&seen[..3], &["accel", "slew", "decel"]);
    assert_eq!(x.position(), -5_000);
    assert!(!x.mode().contains(Mode::MOVING));
}

#[test]
fn cc_pulses_cw_for_positive_and_ccw_for_negative() {
    let hub = virtual_hub();
    let y = hub.start_cc(10, 11, 12).unwrap();
    hub.set_input(10, true).unwrap();
    y.move_steps(5_000, 700).unwrap();
    hub.run_until_idle();
    y.move_steps(5_000, -300).unwrap();
    hub.run_until_idle();
    assert_eq!(y.position(), 400);
    assert_eq!(hub.rising_edges(11), 700);
    assert_eq!(hub.rising_edges(12), 300);
    let trace = hub.trace();
    let cw = rising(&trace, 11);
    let ccw = rising(&trace, 12);
    assert!(
        cw.last() < ccw.first(),
        "all cw pulses come before the ccw ones"
    );
}

#[test]
fn merge_keeps_the_speed_with_no_dip() {
    let hub = virtual_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    x.move_steps(10_000, 4_000).unwrap();
    hub.advance(200_000_000 / 4); // 250 ms: well into the slew
    assert!(x.mode().has(Mode::SLEW));
    x.move_steps(10_000, 3_000).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), 7_000);
    let rises = rising(&hub.trace(), STEP);
    let intervals: Vec<u64> = rises.windows(2).map(|w| w[1] - w[0]).collect();
    // Shortest interval reached once, held, then a single deceleration.
    let top = *intervals.iter().min().unwrap();
    let first_top = intervals.iter().position(|d| *d <= top + 1).unwrap();
    let last_top = intervals.iter().rposition(|d| *d <= top + 1).unwrap();
    assert!(
        intervals[first_top..=last_top]
            .iter()
            .all(|d| *d <= top + 1),
        "no dip between the merged moves"
    );
    let decel = intervals.len() - last_top - 1;
    assert!(
        (990..=1_001).contains(&decel),
        "one deceleration ramp, {decel} intervals"
    );
}

#[test]
fn stop_pin_stops_under_control_from_each_phase_and_the_count_stays_exact() {
    // 0.05 s is accelerating, 0.3 s at speed, 0.63 s decelerating.
    for stop_after_ticks in [10_000_000u64, 60_000_000, 126_000_000] {
        let hub = virtual_hub();
        let x = hub.start_sd(STOP, STEP, DIR).unwrap();
        hub.set_input(STOP, true).unwrap();
        x.move_steps(10_000, 6_000).unwrap();
        hub.advance(stop_after_ticks);
        let before = x.position();
        hub.set_input(STOP, false).unwrap();
        hub.run_until_idle();
        let stopped_at = x.position();
        assert!(stopped_at >= before);
        assert!(
            x.mode().has(Mode::STOP_LATCHED),
            "the stop is latched in the mode"
        );
        let dropped = x.dropped_steps();
        assert_eq!(
            stopped_at + i64::from(dropped),
            6_000,
            "stop after {stop_after_ticks}"
        );
        // Decelerating from the stop on: intervals never shrink after it.
        let rises = rising(&hub.trace(), STEP);
        let after: Vec<u64> = rises
            .iter()
            .copied()
            .filter(|ct| *ct >= stop_after_ticks)
            .collect();
        for w in after.windows(3) {
            assert!(w[2] - w[1] >= w[1] - w[0], "stop after {stop_after_ticks}");
        }
        // Resume: the remaining steps reach the original target.
        if dropped > 0 {
            hub.set_input(STOP, true).unwrap();
            x.move_steps(10_000, i32::try_from(dropped).unwrap())
                .unwrap();
            assert!(
                !x.mode().has(Mode::STOP_LATCHED),
                "cleared by the next move"
            );
            hub.run_until_idle();
        }
        assert_eq!(x.position(), 6_000);
    }
}

#[test]
fn a_stop_pin_pulse_between_advances_is_never_missed() {
    // Low and straight back high at one CT: the cog has seen the low level
    // before `set_input` returns, however the threads are scheduled.
    for _ in 0..20 {
        let hub = virtual_hub();
        let x = hub.start_sd(STOP, STEP, DIR).unwrap();
        hub.set_input(STOP, true).unwrap();
        x.move_steps(10_000, 6_000).unwrap();
        hub.advance(60_000_000);
        hub.set_input(STOP, false).unwrap();
        hub.set_input(STOP, true).unwrap();
        hub.run_until_idle();
        assert!(x.mode().has(Mode::STOP_LATCHED));
        assert!(x.dropped_steps() > 0);
        assert_eq!(x.position() + i64::from(x.dropped_steps()), 6_000);
    }
}

#[test]
fn status_reads_after_a_command_see_it_applied() {
    for _ in 0..50 {
        let hub = virtual_hub();
        let x = hub.start_sd(STOP, STEP, DIR).unwrap();
        hub.set_input(STOP, true).unwrap();
        x.move_steps(10_000, -5_000).unwrap();
        assert_eq!(x.stm(), 0);
        assert_eq!(x.steps_to_go(), 5_000);
        assert!(x.mode().has(Mode::MOVING | Mode::REVERSE));
    }
}

#[test]
fn a_move_waits_for_the_stop_pin() {
    let hub = virtual_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    x.move_steps(1_000, 100).unwrap();
    hub.advance(20_000_000);
    assert_eq!(x.position(), 0);
    assert!(x.mode().has(Mode::HOLD));
    assert_eq!(x.move_steps(1_000, 5), Err(AxisError::Busy));
    hub.set_input(STOP, true).unwrap();
    let released = hub.now();
    hub.run_until_idle();
    assert_eq!(x.position(), 100);
    assert_eq!(rising(&hub.trace(), STEP)[0], released);
}

#[test]
fn emergency_stop_keeps_the_position() {
    let hub = virtual_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    x.move_steps(10_000, 10_000).unwrap();
    hub.advance(50_000_000);
    hub.emergency_stop();
    let at_stop = x.position();
    let edges_at_stop = hub.rising_edges(STEP);
    assert!(x.mode().has(Mode::ESTOP));
    assert_eq!(x.stm(), 0);
    hub.advance(200_000_000);
    assert_eq!(x.position(), at_stop);
    assert_eq!(hub.rising_edges(STEP), edges_at_stop);
    assert_eq!(i64::from(x.dropped_steps()) + at_stop, 10_000);
    x.move_steps(10_000, 10).unwrap();
    assert!(!x.mode().has(Mode::ESTOP));
    hub.run_until_idle();
    assert_eq!(x.position(), at_stop + 10);
}

#[test]
fn jog_runs_while_heartbeats_come_and_stops_after_the_timeout() {
    let hub = virtual_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    for _ in 0..10 {
        x.jog(5_000, Direction::Forward).unwrap();
        hub.advance(20_000_000); // 100 ms between beats
        assert!(x.mode().has(Mode::MOVING));
        assert!(x.mode().has(Mode::JOG));
    }
    let last_beat = hub.now() - 20_000_000;
    hub.run_until_idle();
    assert!(x.position() > 0);
    // Deceleration begins within 150 ms of CT of the last beat: from the
    // first step after that deadline on, intervals only grow, and no more
    // steps follow than one deceleration ramp (502 steps at 5,000 steps/s).
    let deadline = last_beat + 30_000_000;
    let rises = rising(&hub.trace(), STEP);
    let after: Vec<u64> = rises.iter().copied().filter(|ct| *ct >= deadline).collect();
    assert!(
        after.len() <= 503,
        "{} steps after the deadline",
        after.len()
    );
    let top = 200_000_000 / 5_000;
    assert!(after[1] - after[0] > top - 2);
    for w in after.windows(3) {
        assert!(w[2] - w[1] >= w[1] - w[0]);
    }
    assert!(!x.mode().has(Mode::JOG));
}

#[test]
fn jog_release_stops_at_once_and_reverse_jog_reverses() {
    let hub = virtual_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    x.jog(5_000, Direction::Forward).unwrap();
    hub.advance(20_000_000);
    x.jog_release().unwrap();
    let released = hub.now();
    hub.run_until_idle();
    let rises = rising(&hub.trace(), STEP);
    let after: Vec<u64> = rises.iter().copied().filter(|ct| *ct >= released).collect();
    for w in after.windows(3) {
        assert!(w[2] - w[1] >= w[1] - w[0]);
    }
    let forward = x.position();
    x.jog(5_000, Direction::Reverse).unwrap();
    hub.advance(20_000_000);
    hub.run_until_idle();
    assert!(x.position() < forward);
}

#[test]
fn reversal_decelerates_then_runs_back() {
    let hub = virtual_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    x.move_steps(10_000, 5_000).unwrap();
    hub.advance(60_000_000);
    let made = x.position();
    x.move_steps(10_000, -2_000).unwrap();
    hub.run_until_idle();
    let trace = hub.trace();
    let dir = edges_on(&trace, DIR);
    assert_eq!(dir.len(), 1);
    let forward_steps = rising(&trace, STEP)
        .iter()
        .filter(|ct| **ct < dir[0].ct)
        .count() as i64;
    assert!(forward_steps > made);
    assert_eq!(x.position(), forward_steps - 2_000);
}

#[test]
fn eight_axes_run_at_once_and_a_ninth_is_refused() {
    let hub = Hub::new(HubConfig::default()).unwrap();
    let axes: Vec<_> = (0..8u8)
        .map(|i| {
            let axis = if i % 2 == 0 {
                hub.start_sd(i * 3, i * 3 + 1, i * 3 + 2)
            } else {
                hub.start_cc(i * 3, i * 3 + 1, i * 3 + 2)
            }
            .unwrap();
            hub.set_input(i * 3, true).unwrap();
            axis
        })
        .collect();
    assert!(matches!(
        hub.start_sd(40, 41, 42),
        Err(HubError::TooManyCogs { max: 8 })
    ));
    for (i, axis) in axes.iter().enumerate() {
        let steps = 1_000 * (i as i32 + 1) * if i % 3 == 0 { -1 } else { 1 };
        axis.move_steps(5_000 + 1_000 * i as u32, steps).unwrap();
    }
    hub.run_until_idle();
    for (i, axis) in axes.iter().enumerate() {
        let steps = 1_000 * (i as i64 + 1) * if i % 3 == 0 { -1 } else { 1 };
        assert_eq!(axis.position(), steps);
    }
    axes[7].stop();
    assert_eq!(axes[7].move_steps(100, 1), Err(AxisError::Unavailable));
    hub.start_sd(21, 22, 23)
        .expect("a freed cog and its pins can be reused");
}

#[test]
fn bad_pins_are_typed_errors() {
    let hub = Hub::new(HubConfig::default()).unwrap();
    hub.start_sd(0, 1, 2).unwrap();
    assert!(matches!(hub.start_sd(3, 1, 4), Err(HubError::PinInUse(1))));
    assert!(matches!(hub.start_sd(5, 5, 6), Err(HubError::PinInUse(5))));
    assert!(matches!(
        hub.start_cc(7, 64, 8),
        Err(HubError::PinOutOfRange(64))
    ));
}

#[test]
fn bad_commands_change_nothing() {
    let hub = virtual_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    assert!(matches!(x.move_steps(0, 10), Err(AxisError::Plan(_))));
    assert!(matches!(x.move_steps(10, 0), Err(AxisError::Plan(_))));
    // 1,000-tick pulses leave no room at 200,000 steps/s (1,000 ticks apart).
    assert_eq!(
        x.move_steps(200_000, 10),
        Err(AxisError::PulseTooLong { speed: 200_000 })
    );
    hub.run_until_idle();
    assert_eq!(x.position(), 0);
    assert_eq!(hub.rising_edges(STEP), 0);
    x.move_steps(1_000, 10).unwrap();
    hub.advance(1_000);
    assert_eq!(x.set_position(5), Err(AxisError::NotIdle));
    hub.run_until_idle();
    x.set_position(-42).unwrap();
    assert_eq!(x.position(), -42);
}

#[test]
fn the_same_scenario_gives_the_same_edges() {
    let run = || {
        let hub = virtual_hub();
        let x = hub.start_sd(STOP, STEP, DIR).unwrap();
        let y = hub.start_cc(3, 4, 5).unwrap();
        hub.set_input(STOP, true).unwrap();
        hub.set_input(3, true).unwrap();
        x.move_steps(12_000, 3_000).unwrap();
        y.move_steps(7_000, -2_000).unwrap();
        hub.advance(30_000_000);
        x.move_steps(12_000, 500).unwrap();
        hub.set_input(3, false).unwrap();
        hub.advance(10_000_000);
        hub.set_input(3, true).unwrap();
        y.move_steps(7_000, 100).unwrap();
        hub.run_until_idle();
        let mut vcd = Vec::new();
        hub.write_vcd(&mut vcd).unwrap();
        (hub.trace(), vcd)
    };
    let (first, vcd) = run();
    let (second, _) = run();
    assert!(first.len() > 5_000);
    assert_eq!(first, second);
    let text = String::from_utf8(vcd).unwrap();
    assert!(text.contains("$timescale 1 ns $end") || text.contains("$timescale\n"));
    assert!(text.contains("axis1_step"));
    assert!(text.contains("axis2_ccw"));
}

#[test]
fn many_threads_commanding_one_axis_lose_nothing() {
    let hub = Hub::new(HubConfig {
        clock: ClockMode::Real,
        ..HubConfig::default()
    })
    .unwrap();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    let accepted: u64 = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..4)
            .map(|_| {
                let x = x.clone();
                scope.spawn(move || {
                    let mut ok = 0u64;
                    for _ in 0..200 {
                        match x.move_steps(40_000, 50) {
                            Ok(()) => ok += 1,
                            Err(AxisError::Busy) => {}
                            Err(other) => panic!("unexpected {other}"),
                        }
                        std::thread::yield_now();
                    }
                    ok
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).sum()
    });
    hub.run_until_idle();
    assert!(accepted > 0);
    // Same direction and speed: every accepted command merged or started.
    assert_eq!(x.position(), i64::try_from(accepted * 50).unwrap());
    assert_eq!(hub.rising_edges(STEP), accepted * 50);
    assert_eq!(x.ledger().accepted, i64::try_from(accepted * 50).unwrap());
}

#[test]
fn real_clock_runs_a_move_in_about_its_time() {
    let hub = Hub::new(HubConfig {
        clock: ClockMode::Real,
        trace_edges: true,
        ..HubConfig::default()
    })
    .unwrap();
    let x = hub.start_cc(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    x.move_steps(20_000, 2_000).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), 2_000);
    let rises = rising(&hub.trace(), STEP);
    assert_eq!(rises.len(), 2_000);
    let expected = profile_delays(20_000, 2_000);
    for (i, w) in rises.windows(2).enumerate() {
        assert_eq!(w[1] - w[0], expected[i]);
    }
    assert_eq!(hub.trace_overflows(), 0);
}

#[test]
fn edges_count_matches_position_on_every_axis() {
    let hub = virtual_hub();
    let mut names = BTreeMap::new();
    for i in 0..4u8 {
        let axis = hub.start_sd(i * 3, i * 3 + 1, i * 3 + 2).unwrap();
        hub.set_input(i * 3, true).unwrap();
        axis.move_steps(3_000, if i % 2 == 0 { 500 } else { -500 })
            .unwrap();
        names.insert(i, axis);
    }
    hub.run_until_idle();
    let trace = hub.trace();
    for (i, axis) in &names {
        let steps = rising(&trace, i * 3 + 1).len() as i64;
        assert_eq!(axis.position().abs(), steps);
    }
}

#[test]
fn cordic_math_bounds_the_step_rate_and_overruns_are_counted() {
    // At 200 MHz a ramp step's QROTATE + QDIV take ~128 clocks in the model.
    let hub = Hub::new(HubConfig::default()).unwrap();
    let rate = hub.max_step_rate();
    assert!((1_000_000..2_000_000).contains(&rate), "{rate}");
    // At 2 MHz and 20,000 steps/s a step lasts 100 ticks: shorter than its math.
    let slow = Hub::new(HubConfig {
        clkfreq: 2_000_000,
        pulse_ticks: 10,
        dir_setup_ticks: 10,
        ..HubConfig::default()
    })
    .unwrap();
    let x = slow.start_sd(STOP, STEP, DIR).unwrap();
    slow.set_input(STOP, true).unwrap();
    x.move_steps(20_000, 5_000).unwrap();
    slow.run_until_idle();
    assert_eq!(x.position(), 5_000);
    assert!(x.math_overruns() > 0);
    assert!(slow.max_step_rate() < 20_000);
    // The same move at 200 MHz has time to spare.
    let fast = virtual_hub();
    let y = fast.start_sd(STOP, STEP, DIR).unwrap();
    fast.set_input(STOP, true).unwrap();
    y.move_steps(20_000, 5_000).unwrap();
    fast.run_until_idle();
    assert_eq!(y.math_overruns(), 0);
}

#[test]
fn a_jog_shows_a_meaningful_steps_to_go_and_the_offset_shows_before_any_move() {
    let hub = virtual_hub();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    assert_eq!(x.offset(), 40);
    hub.set_input(STOP, true).unwrap();
    for _ in 0..20 {
        x.jog(5_000, Direction::Forward).unwrap();
        hub.advance(10_000_000); // a beat every 50 ms
                                 // Enough in hand to reach speed, ride out a timeout and stop, no more.
        let to_go = x.steps_to_go();
        assert!(to_go > 0 && to_go < 10_000, "steps to go {to_go}");
    }
    // Held for a second: at speed, never slowing between the beats.
    assert!(x.mode().has(Mode::SLEW), "{:?}", x.mode());
    hub.run_until_idle();
    assert_eq!(x.stm(), 0);
}

/// `realtime_priority: false` keeps real-clock cogs ordinary threads; the
/// axis moves the same (every step made, the position exact).
#[test]
fn real_clock_cogs_without_realtime_priority_make_every_step() {
    let hub = Hub::new(HubConfig {
        clock: ClockMode::Real,
        realtime_priority: false,
        ..HubConfig::default()
    })
    .unwrap();
    let x = hub.start_sd(STOP, STEP, DIR).unwrap();
    hub.set_input(STOP, true).unwrap();
    x.move_steps(20_000, -1_500).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), -1_500);
    assert_eq!(hub.rising_edges(STEP), 1_500);
    assert_eq!(x.steps_to_go(), 0);
}

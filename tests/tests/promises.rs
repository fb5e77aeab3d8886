//! Every `Ok` is a promise, and no step vanishes: one named regression test
//! per finding of the adversarial run (issue 11), in virtual time (and in
//! real time where the finding was a race).

use std::time::Duration;

use cogstep_test_support::hub::{start_axis, Wiring};
use cogstep_test_support::ledger::assert_accounted;
use driver::serial::sim::{BoardSim, SimConfig};
use driver::{AxisError, ClockMode, Direction, Hub, HubConfig, Mode};

fn hub_with(clock: ClockMode) -> Hub {
    Hub::new(HubConfig {
        clock,
        ..HubConfig::default()
    })
    .expect("hub")
}

/// One idle sd axis (stop pin 0, step 1, dir 2) with its stop pin high.
fn axis_on(hub: &Hub) -> driver::Axis {
    start_axis(hub, 0, Wiring::Sd)
}

const MS: u64 = 200_000;

#[test]
fn finding_1_a_move_during_a_jog_is_refused_not_cut_off() {
    let hub = hub_with(ClockMode::Virtual);
    let x = axis_on(&hub);
    x.jog(5_000, Direction::Forward).unwrap();
    hub.advance(10 * MS);
    let before = (x.position(), x.ledger(), x.steps_to_go());
    assert_eq!(x.move_steps(5_000, 100_000), Err(AxisError::Jogging));
    assert_eq!((x.position(), x.ledger(), x.steps_to_go()), before);
    // The jog times out; the axis is idle with no jog bit, no stale deadline.
    hub.run_until_idle();
    assert_accounted(&x);
    assert!(!x.mode().has(Mode::JOG));
    let from = x.position();
    x.move_steps(5_000, 100_000).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), from + 100_000);
    assert_eq!(x.dropped_steps(), 0);
    assert_accounted(&x);
}

#[test]
fn finding_1_a_stale_jog_deadline_does_not_stop_a_new_move() {
    let hub = hub_with(ClockMode::Virtual);
    let x = axis_on(&hub);
    x.jog(5_000, Direction::Forward).unwrap();
    hub.advance(10 * MS);
    x.jog_release().unwrap();
    hub.run_until_idle();
    let from = x.position();
    x.move_steps(5_000, 14_817).unwrap();
    // Well past the old jog's deadline.
    hub.advance(400 * MS);
    hub.run_until_idle();
    assert_eq!(x.position(), from + 14_817);
    assert!(!x.mode().has(Mode::JOG));
}

#[test]
fn finding_1_over_serial_a_move_during_a_jog_gets_an_error() {
    use driver::serial::host::{SerialBoard, SerialConfig};
    use driver::AxisContract;
    let (sim, path) = BoardSim::spawn_pty(SimConfig::default()).expect("sim");
    let board = SerialBoard::open(SerialConfig::new(path)).expect("board");
    let x = board.axis(0).expect("axis");
    x.jog(5_000, Direction::Forward).unwrap();
    // The hub's own refusal, carried exactly over the wire (it was `Busy`
    // before the error contract).
    assert_eq!(x.move_steps(5_000, 100_000), Err(AxisError::Jogging));
    board.close();
    sim.stop();
}

/// The held move and the HOLD bit, through a whole deceleration.
fn hold_scenario(hub: &Hub, x: &driver::Axis, wait: impl Fn()) {
    x.move_steps(20_000, 50_000).unwrap();
    wait();
    x.set_stop_pin(false).unwrap();
    x.move_steps(20_000, 1_000).unwrap(); // A: held
    for _ in 0..4 {
        wait();
        assert!(x.mode().has(Mode::HOLD), "{:?}", x.mode());
        // B: refused at the call, never Ok-then-dropped.
        assert_eq!(x.move_steps(20_000, 2_000), Err(AxisError::Busy));
    }
    x.set_stop_pin(true).unwrap();
    hub.run_until_idle();
    assert!(!x.mode().has(Mode::HOLD));
    assert_accounted(x);
}

#[test]
fn finding_2_hold_survives_the_deceleration_in_virtual_time() {
    let hub = hub_with(ClockMode::Virtual);
    let x = axis_on(&hub);
    hold_scenario(&hub, &x, || {
        hub.advance(20 * MS);
    });
}

#[test]
fn finding_2_hold_survives_the_deceleration_in_real_time() {
    let hub = hub_with(ClockMode::Real);
    let x = axis_on(&hub);
    for _ in 0..3 {
        hold_scenario(&hub, &x, || std::thread::sleep(Duration::from_millis(20)));
    }
}

#[test]
fn finding_3_a_jog_beat_while_a_reversal_is_queued_is_refused_or_honoured() {
    let hub = hub_with(ClockMode::Virtual);
    let x = axis_on(&hub);
    x.jog(8_000, Direction::Forward).unwrap();
    hub.advance(100 * MS);
    // Reverse: the jog decelerates, then turns round.
    x.jog(8_000, Direction::Reverse).unwrap();
    // A beat for the queued reversal keeps it alive; any other is refused.
    assert_eq!(x.jog(8_000, Direction::Reverse), Ok(()));
    assert_eq!(x.jog(8_000, Direction::Forward), Err(AxisError::Busy));
    assert_eq!(x.jog(4_000, Direction::Reverse), Err(AxisError::Busy));
    hub.run_until_idle();
    assert_accounted(&x);
}

#[test]
fn finding_4_a_merge_that_would_overflow_is_refused_at_the_call() {
    // The adversarial run's sequence: `M 4 580 -2147483647; M 4 13
    // -2147483647; M 4 8 -243`.
    let hub = hub_with(ClockMode::Virtual);
    let x = axis_on(&hub);
    x.move_steps(580, -2_147_483_647).unwrap();
    x.move_steps(13, -2_147_483_647).unwrap();
    let before = (x.ledger(), x.steps_to_go());
    assert_eq!(x.move_steps(8, -243), Err(AxisError::TooManySteps));
    assert_eq!((x.ledger(), x.steps_to_go()), before);
    assert_eq!(x.ledger().accepted, -2 * 2_147_483_647);
    x.emergency_stop().unwrap();
    assert_eq!(x.ledger().dropped_total, 2 * 2_147_483_647);
    assert_accounted(&x);
}

#[test]
fn finding_5_an_emergency_stop_counts_a_held_move() {
    let hub = hub_with(ClockMode::Virtual);
    let x = axis_on(&hub);
    x.set_stop_pin(false).unwrap();
    x.move_steps(1_000, 500).unwrap();
    assert_eq!(x.steps_to_go(), 500);
    x.emergency_stop().unwrap();
    assert_eq!(x.dropped_steps(), 500);
    assert_eq!(x.ledger().dropped, 500);
    assert!(!x.mode().has(Mode::HOLD));
    x.set_stop_pin(true).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), 0);
    assert_accounted(&x);
}

#[test]
fn finding_6_status_describes_the_reverse_move_while_it_runs() {
    let hub = hub_with(ClockMode::Virtual);
    let x = axis_on(&hub);
    x.move_steps(10_000, 20_000).unwrap();
    hub.advance(300 * MS);
    x.move_steps(40_000, -30_000).unwrap();
    // Run until the reverse move has begun.
    while !x.mode().has(Mode::REVERSE) {
        hub.advance(MS);
    }
    hub.advance(100 * MS);
    assert_eq!(x.speed(), 40_000);
    assert_eq!(x.accel_steps(), 40_000 / 10 + 2);
    assert_eq!(x.top_velocity(), 40_000);
    assert_eq!(x.slew_steps(), 30_000 - 2 * (40_000 / 10 + 2));
    assert!(x.move_start_ct() > 300 * MS, "{}", x.move_start_ct());
    hub.run_until_idle();
    assert_accounted(&x);
}

#[test]
fn finding_7_steps_to_go_is_right_as_soon_as_the_stop_pin_goes_low() {
    let hub = hub_with(ClockMode::Virtual);
    let x = axis_on(&hub);
    x.move_steps(20_000, 40_000).unwrap();
    hub.advance(500 * MS);
    x.set_stop_pin(false).unwrap();
    let to_go = x.steps_to_go();
    let at_stop = x.position();
    assert!(x.dropped_steps() > 0);
    assert_eq!(
        at_stop + i64::from(x.dropped_steps()) + i64::try_from(to_go).unwrap(),
        40_000
    );
    hub.run_until_idle();
    assert_eq!(x.position(), at_stop + i64::try_from(to_go).unwrap());
    assert_accounted(&x);
}

#[test]
fn finding_8_positions_never_wrap_and_a_gone_cog_is_an_error() {
    let hub = hub_with(ClockMode::Virtual);
    let x = axis_on(&hub);
    x.set_position(i64::MAX - 1).unwrap();
    assert_eq!(x.move_steps(1_000, 3), Err(AxisError::PositionOutOfRange));
    assert_eq!(
        x.jog(1_000, Direction::Forward),
        Err(AxisError::PositionOutOfRange)
    );
    // Away from the limit is fine.
    x.move_steps(1_000, -3).unwrap();
    hub.run_until_idle();
    x.move_steps(1_000, 3).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), i64::MAX - 1);
    x.move_steps(1_000, 1).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), i64::MAX);
    x.set_position(i64::MIN + 2).unwrap();
    assert_eq!(x.move_steps(1_000, -3), Err(AxisError::PositionOutOfRange));
    x.move_steps(1_000, -2).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), i64::MIN);
    assert_accounted(&x);

    x.stop();
    assert_eq!(x.move_steps(1_000, 10), Err(AxisError::Unavailable));
    assert_eq!(
        x.jog(1_000, Direction::Forward),
        Err(AxisError::Unavailable)
    );
}

#[test]
fn finding_13_a_jog_with_the_stop_pin_low_and_i32_min_steps_are_refused() {
    let hub = hub_with(ClockMode::Virtual);
    let x = axis_on(&hub);
    x.set_stop_pin(false).unwrap();
    assert_eq!(x.jog(1_000, Direction::Forward), Err(AxisError::StopPinLow));
    x.set_stop_pin(true).unwrap();
    assert_eq!(
        x.move_steps(1_000, i32::MIN),
        Err(AxisError::StepsOutOfRange)
    );
    assert_eq!(x.ledger().accepted, 0);
    assert!(matches!(
        hub.set_input(64, true),
        Err(driver::HubError::PinOutOfRange(64))
    ));
}

#[test]
fn racing_producers_in_real_time_every_ok_is_honoured() {
    let hub = hub_with(ClockMode::Real);
    let x = axis_on(&hub);
    let accepted: i64 = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..4i32)
            .map(|p| {
                let x = x.clone();
                scope.spawn(move || {
                    let mut ok = 0i64;
                    for i in 0..150i32 {
                        let steps = if (i + p) % 3 == 0 { -40 } else { 60 };
                        let speed = 30_000 + 10_000 * u32::from(i % 2 == 0);
                        match x.move_steps(speed, steps) {
                            Ok(()) => ok += i64::from(steps),
                            Err(AxisError::Busy) => {}
                            Err(other) => panic!("unexpected {other}"),
                        }
                        if i % 50 == 7 {
                            x.set_stop_pin(false).unwrap();
                            std::thread::sleep(Duration::from_micros(300));
                            x.set_stop_pin(true).unwrap();
                        }
                    }
                    ok
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).sum()
    });
    x.set_stop_pin(true).unwrap();
    hub.run_until_idle();
    // Every Ok is in the ledger, and every step is accounted for.
    assert_eq!(x.ledger().accepted, accepted);
    assert_accounted(&x);
}

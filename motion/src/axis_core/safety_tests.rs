//! The holes an outside review found in limits, e-stops and the step
//! accounts, each as the scenario that showed it, on the core alone.

extern crate std;
use std::vec::Vec;

use super::test_core::{assert_accounts, core};
use super::*;
use crate::axis::{HomeConfig, Mode};

const LIMIT_PIN: u8 = 10;

/// Runs the core to its end with a limit switch at physical `switch_at`
/// (active high on [`LIMIT_PIN`] at and beyond it, forward), feeding the
/// input after every event as the hub's cog does. Returns the rising
/// step edges' CTs.
fn run_with_switch(core: &mut AxisCore, switch_at: i64, until: u64) -> Vec<u64> {
    let mut rises = Vec::new();
    while let Some(t) = core.next_event().filter(|t| *t <= until) {
        core.run_event(t, &mut |edge: Edge| {
            if edge.level && edge.pin == 1 {
                rises.push(edge.ct);
            }
        });
        let level = core.physical_position() >= switch_at;
        core.set_inputs(t, u64::from(level) << LIMIT_PIN);
    }
    rises
}

/// `core()` with its max hard limit on [`LIMIT_PIN`], active high.
fn core_with_max_limit() -> AxisCore {
    let mut core = core();
    core.command(
        0,
        CoreCommand::SetLimitPins {
            min: None,
            max: Some((LIMIT_PIN, true)),
        },
    )
    .unwrap();
    core
}

fn group_part(
    core: &mut AxisCore,
    t: u64,
    steps: i32,
    lead_steps: u32,
    speed: u32,
) -> Result<(), AxisError> {
    core.command(t, CoreCommand::GroupReserve { steps })?;
    core.command(
        t,
        CoreCommand::GroupStart(GroupMove {
            speed,
            lead_steps,
            steps,
            start_ct: t,
        }),
    )?;
    Ok(())
}

#[test]
fn a_group_part_beyond_a_soft_limit_is_refused_like_a_move() {
    let mut x = core();
    x.command(0, CoreCommand::SetSoftLimits(Some((-1_000, 1_000))))
        .unwrap();
    assert_eq!(
        x.command(
            0,
            CoreCommand::Move {
                speed: 10_000,
                steps: 5_000
            }
        ),
        Err(AxisError::BeyondSoftLimit)
    );
    assert_eq!(
        x.command(0, CoreCommand::GroupReserve { steps: 5_000 }),
        Err(AxisError::BeyondSoftLimit)
    );
    assert_eq!(
        x.command(
            0,
            CoreCommand::GroupStart(GroupMove {
                speed: 10_000,
                lead_steps: 5_000,
                steps: 5_000,
                start_ct: 0
            })
        ),
        Err(AxisError::BeyondSoftLimit)
    );
    assert!(!x.is_moving());
    group_part(&mut x, 0, 900, 5_000, 10_000).unwrap();
}

#[test]
fn a_limit_switch_stops_a_group_part_and_asks_the_line_to_stop() {
    let mut x = core_with_max_limit();
    group_part(&mut x, 0, 5_000, 5_000, 10_000).unwrap();
    run_with_switch(&mut x, 2_000, u64::MAX);
    let trip = x.limit_trip().expect("the switch trips the group part");
    assert_eq!(trip.physical, 2_000);
    assert!(x.position() < 5_000);
    assert_eq!(x.position(), trip.position + trip.stopping_steps as i64);
    assert!(matches!(
        x.take_group_request(),
        Some(GroupRequest::StopAfter(_))
    ));
    assert_eq!(x.take_group_request(), None);
    assert_accounts(&x);
    // Towards the tripped limit nothing runs, group or not.
    let later = x.last_step().ct + 100_000_000;
    assert_eq!(
        x.command(later, CoreCommand::GroupReserve { steps: 1_000 }),
        Err(AxisError::IntoLimit(Direction::Forward))
    );
    group_part(&mut x, later, -1_000, 1_000, 10_000).unwrap();
}

#[test]
fn with_limit_estop_a_group_part_stops_at_once_and_asks_for_an_emergency_stop() {
    let mut config = AxisCoreConfig::new(Outputs::StepDir { step: 1, dir: 2 });
    config.limit_estop = true;
    let mut x = AxisCore::new(config, 0);
    x.set_stop_pin(0, true);
    x.command(
        0,
        CoreCommand::SetLimitPins {
            min: None,
            max: Some((LIMIT_PIN, true)),
        },
    )
    .unwrap();
    group_part(&mut x, 0, 5_000, 5_000, 10_000).unwrap();
    run_with_switch(&mut x, 2_000, u64::MAX);
    assert_eq!(x.physical_position(), 2_000);
    assert_eq!(x.take_group_request(), Some(GroupRequest::EmergencyStop));
    assert_accounts(&x);
}

#[test]
fn a_held_move_does_not_survive_a_trip_towards_its_limit() {
    // Switch at 3,000; the stop pin drops at 2,905 while at speed; a move
    // of 5,000 is held; the deceleration passes the switch and trips.
    let mut x = core_with_max_limit();
    x.command(
        0,
        CoreCommand::Move {
            speed: 20_000,
            steps: 20_000,
        },
    )
    .unwrap();
    while x.physical_position() < 2_905 {
        let t = x.next_event().unwrap();
        x.run_event(t, &mut |_| {});
    }
    let t = x.last_step().ct;
    x.set_stop_pin(t, false);
    assert_eq!(
        x.command(
            t,
            CoreCommand::Move {
                speed: 20_000,
                steps: 5_000
            }
        ),
        Ok(Taken::Held)
    );
    run_with_switch(&mut x, 3_000, u64::MAX);
    let trip = x.limit_trip().expect("the deceleration passes the switch");
    let allowed = trip.physical + trip.stopping_steps as i64;
    assert!(x.physical_position() <= allowed);
    x.set_stop_pin(x.last_step().ct + 1, true);
    run_with_switch(&mut x, 3_000, u64::MAX);
    assert!(
        x.physical_position() <= allowed,
        "{} > {allowed}",
        x.physical_position()
    );
    assert_accounts(&x);
}

#[test]
fn a_held_move_beyond_a_soft_limit_set_meanwhile_is_dropped_not_run() {
    let mut x = core();
    x.set_stop_pin(0, false);
    x.command(
        0,
        CoreCommand::Move {
            speed: 10_000,
            steps: 5_000,
        },
    )
    .unwrap();
    x.command(0, CoreCommand::SetSoftLimits(Some((-100, 100))))
        .unwrap();
    x.set_stop_pin(10, true);
    x.run_until(u64::MAX, &mut |_| {});
    assert_eq!(x.position(), 0);
    assert_eq!(x.dropped_steps(), 5_000);
    assert_accounts(&x);
}

#[test]
fn a_limit_pin_set_while_active_trips_an_axis_moving_towards_it() {
    let mut x = core();
    x.command(
        0,
        CoreCommand::Move {
            speed: 20_000,
            steps: 20_000,
        },
    )
    .unwrap();
    x.run_until(2_000_000, &mut |_| {});
    x.set_inputs(2_000_000, 1 << LIMIT_PIN);
    x.command(
        2_000_000,
        CoreCommand::SetLimitPins {
            min: None,
            max: Some((LIMIT_PIN, true)),
        },
    )
    .unwrap();
    assert_eq!(x.limit_fault(), Some(Direction::Forward));
    x.run_until(u64::MAX, &mut |_| {});
    assert!(x.position() < 20_000);
    assert_accounts(&x);
}

#[test]
fn an_emergency_stop_after_a_group_stop_counts_each_step_once() {
    // The line stopped short: the member's unmade steps are dropped when
    // the line ends, and an e-stop after that drops nothing more.
    let mut x = core();
    group_part(&mut x, 0, -27, 172, 56_815).unwrap();
    x.run_until(3_732_192, &mut |_| {});
    x.stop_group_after(3_732_192);
    while x.steps_to_go() > 0 {
        let t = x.next_event().unwrap();
        x.run_event(t, &mut |_| {});
    }
    let t = x.next_event().unwrap_or(4_097_064);
    x.command(t, CoreCommand::EmergencyStop).unwrap();
    assert_accounts(&x);
    assert_eq!(x.ledger().dropped, x.ledger().accepted - x.position());
}

#[test]
fn after_an_emergency_stop_the_axis_is_idle_with_no_speed() {
    let mut x = core();
    x.command(
        0,
        CoreCommand::Move {
            speed: 20_000,
            steps: 20_000,
        },
    )
    .unwrap();
    x.run_until(20_000_000, &mut |_| {});
    assert!(x.last_step().velocity > 0);
    x.command(20_000_000, CoreCommand::EmergencyStop).unwrap();
    assert_eq!(x.last_step().velocity, 0);
    assert!(!x.mode().has(Mode::MOVING));
    assert!(x.mode().has(Mode::ESTOP));
    assert_eq!(x.next_event(), None);
    assert_accounts(&x);
    // The same after a jog released and a group move.
    let mut y = core();
    y.command(
        0,
        CoreCommand::Jog {
            speed: 195,
            direction: Direction::Forward,
        },
    )
    .unwrap();
    y.command(0, CoreCommand::JogRelease).unwrap();
    y.run_until(u64::MAX, &mut |_| {});
    let t = y.last_step().ct + 200_000_000;
    y.command(t, CoreCommand::GroupReserve { steps: -1_144 })
        .unwrap();
    y.command(
        t,
        CoreCommand::GroupStart(GroupMove {
            speed: 43_300,
            lead_steps: 1_144,
            steps: -1_144,
            start_ct: t,
        }),
    )
    .unwrap();
    y.run_until(t + 1_000_000, &mut |_| {});
    y.command(t + 1_000_000, CoreCommand::EmergencyStop)
        .unwrap();
    assert_eq!(y.mode().bits() & Mode::MOVING.bits(), 0);
    assert_eq!(y.last_step().velocity, 0);
    assert_accounts(&y);
}

#[test]
fn a_move_after_an_emergency_stop_starts_at_once() {
    // A 1-step move at 100 steps/s has a long delay after its step; an
    // e-stop ends it, and the next move does not wait that delay out.
    let mut x = core();
    x.command(
        0,
        CoreCommand::Move {
            speed: 100,
            steps: 1,
        },
    )
    .unwrap();
    let mut rises = Vec::new();
    x.run_until(0, &mut |edge: Edge| {
        if edge.level && edge.pin == 1 {
            rises.push(edge.ct)
        }
    });
    assert_eq!(rises, [0]);
    assert!(
        x.next_event().unwrap() > 1_000_000,
        "the step's period is long"
    );
    x.command(5_000, CoreCommand::EmergencyStop).unwrap();
    x.command(
        5_001,
        CoreCommand::Move {
            speed: 1_000,
            steps: 5,
        },
    )
    .unwrap();
    let first = x.next_event().unwrap();
    assert!(first <= 5_001 + 2_000, "first step at {first}");
}

#[test]
fn a_held_move_after_an_emergency_stop_is_gone_and_counted() {
    let mut x = core();
    x.command(
        0,
        CoreCommand::Move {
            speed: 20_000,
            steps: 20_000,
        },
    )
    .unwrap();
    x.run_until(10_000_000, &mut |_| {});
    x.set_stop_pin(10_000_000, false);
    x.command(
        10_000_000,
        CoreCommand::Move {
            speed: 20_000,
            steps: 700,
        },
    )
    .unwrap();
    x.command(10_000_001, CoreCommand::EmergencyStop).unwrap();
    x.set_stop_pin(10_000_002, true);
    x.run_until(u64::MAX, &mut |_| {});
    assert_accounts(&x);
}

#[test]
fn a_soft_limit_holds_where_the_path_turns_not_only_where_it_ends() {
    // Found by tests/tests/safety_props.rs: a reversal queued behind a
    // move, then a new move the other way: the path turns beyond the soft
    // max although it ends on it.
    let mut y = core();
    y.command(0, CoreCommand::SetSoftLimits(Some((-6_000, 6_000))))
        .unwrap();
    y.command(
        0,
        CoreCommand::Move {
            speed: 1_000,
            steps: 1,
        },
    )
    .unwrap();
    y.command(
        0,
        CoreCommand::Move {
            speed: 1_000,
            steps: -270,
        },
    )
    .unwrap();
    let result = y.command(
        0,
        CoreCommand::Move {
            speed: 7_801,
            steps: 6_270,
        },
    );
    if result.is_ok() {
        let mut highest = 0;
        while let Some(t) = y.next_event() {
            y.run_event(t, &mut |_| {});
            highest = highest.max(y.position());
        }
        assert!(highest <= 6_000, "the path reached {highest}");
    } else {
        assert_eq!(result, Err(AxisError::BeyondSoftLimit));
    }
}

#[test]
fn homing_travels_only_inside_the_soft_limits() {
    // The switch lies beyond the soft min: the seek stops on the limit and
    // homing ends without the switch, no step past the limit.
    let mut x = core();
    x.command(0, CoreCommand::SetSoftLimits(Some((-1_000, 1_000))))
        .unwrap();
    x.command(0, CoreCommand::Home(home_on_limit_pin()))
        .unwrap();
    let mut lowest = 0;
    while let Some(t) = x.next_event() {
        x.run_event(t, &mut |_| {});
        lowest = lowest.min(x.position());
        // The switch would be pressed at -3,000 and below.
        x.set_inputs(t, u64::from(x.physical_position() <= -3_000) << LIMIT_PIN);
    }
    assert_eq!(lowest, -1_000);
    assert_eq!(x.home_outcome(), Some(Err(AxisError::HomeSwitchNotFound)));
    assert_accounts(&x);
    // At the limit already: nothing to travel, refused at the call.
    let home = home_on_limit_pin();
    let t = x.last_step().ct + 100_000_000;
    assert_eq!(
        x.command(t, CoreCommand::Home(home)),
        Err(AxisError::BeyondSoftLimit)
    );
}

/// Homing in reverse onto [`LIMIT_PIN`] (pressed high).
fn home_on_limit_pin() -> HomeConfig {
    HomeConfig {
        switch_pin: LIMIT_PIN,
        active_level: true,
        direction: Direction::Reverse,
        seek_speed: 4_000,
        latch_speed: 400,
        backoff_steps: 100,
        max_travel: 100_000,
        set_position: 0,
    }
}

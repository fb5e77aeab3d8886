//! Homing on simulated switches: the position is latched at the step on
//! which the switch changed, whatever the bounce, direction, output variant
//! or clock, and no step goes unaccounted.

use cogstep_test_support::edges::{position_from_edges, signed_steps};
use cogstep_test_support::hub::{start_axis, tracing_hub, Wiring};
use cogstep_test_support::ledger::accounted;
use cogstep_test_support::props::{cases, direction};
use driver::switch::Bounce;
use driver::{AxisError, ClockMode, Direction, HomeConfig, Hub, HubConfig};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

fn hub(clock: ClockMode) -> Hub {
    tracing_hub(HubConfig {
        clock,
        ..HubConfig::default()
    })
}

#[test]
fn homing_reverse_onto_a_switch_sets_the_switch_point() {
    let hub = hub(ClockMode::Virtual);
    let x = start_axis(&hub, 0, Wiring::Sd);
    hub.attach_switch(10, &x, i64::MIN..=-3_217, true).unwrap();
    x.set_position(5_000).unwrap();
    assert_eq!(x.home_outcome(), None);
    x.home(HomeConfig {
        switch_pin: 10,
        active_level: true,
        direction: Direction::Reverse,
        seek_speed: 8_000,
        latch_speed: 500,
        backoff_steps: 200,
        max_travel: 100_000,
        set_position: 0,
    })
    .unwrap();
    assert!(x.is_homing());
    assert_eq!(x.move_steps(1_000, 10), Err(AxisError::Homing));
    hub.run_until_idle();
    let report = x.home_outcome().expect("homed").expect("found");
    assert_eq!(
        (report.seek_physical, report.latch_physical),
        (-3_217, -3_217)
    );
    assert_eq!(report.seek_position, 5_000 - 3_217);
    assert_eq!(x.position(), x.physical_position() + 3_217);
    assert_eq!(report.position, x.position());
    assert!(hub.input(10), "it stops just past the switch point");
    assert_eq!(
        position_from_edges(x.outputs(), &hub.trace()),
        x.physical_position()
    );
}

/// One homing run on a fresh hub; checks everything a user relies on.
#[allow(clippy::too_many_arguments)]
fn check_homing(
    clock: ClockMode,
    sd: bool,
    direction: Direction,
    switch_at: i64,
    bounce: Bounce,
    start_position: i64,
    config: HomeConfig,
) -> Result<(), TestCaseError> {
    let hub = hub(clock);
    let x = start_axis(&hub, 0, Wiring::sd_if(sd));
    // The switch point is `switch_at` steps from the start, the way homing goes.
    let point = switch_at * direction.sign();
    let active = match direction {
        Direction::Forward => point..=i64::MAX,
        Direction::Reverse => i64::MIN..=point,
    };
    hub.attach_bouncing_switch(10, &x, active, config.active_level, bounce)
        .unwrap();
    x.set_position(start_position).unwrap();
    x.home(HomeConfig {
        switch_pin: 10,
        direction,
        ..config
    })
    .unwrap();
    // No step lost, throughout: at every 10 ms of virtual time the pins'
    // signed count is the physical position.
    let mut trace = Vec::new();
    if clock == ClockMode::Virtual {
        while x.is_homing() || x.steps_to_go() != 0 {
            hub.advance(2_000_000);
            trace.extend(hub.take_trace());
            prop_assert_eq!(
                position_from_edges(x.outputs(), &trace),
                x.physical_position()
            );
        }
    }
    hub.run_until_idle();
    trace.extend(hub.take_trace());
    let report = x
        .home_outcome()
        .expect("homing ended")
        .expect("switch found");
    // Both passes latch the step on which the switch changed.
    prop_assert_eq!(report.seek_physical, point);
    prop_assert_eq!(report.latch_physical, point);
    prop_assert_eq!(report.seek_position, start_position + point);
    // The switch point is now `set_position`, exactly.
    prop_assert_eq!(
        x.position() - config.set_position,
        x.physical_position() - point
    );
    prop_assert_eq!(report.position, x.position());
    prop_assert_eq!(x.steps_to_go(), 0);
    // No step lost: the pins' signed count is the physical position, and
    // the ledger accounts for every step since homing set the position.
    let steps = signed_steps(x.outputs(), &trace);
    let count = steps.last().map_or(0, |&(_, count)| count);
    prop_assert_eq!(count, x.physical_position());
    prop_assert_eq!(i128::from(x.position()), accounted(&x.ledger()));
    // The switch's first change came with the step that reached the point.
    let switch_edge = trace
        .iter()
        .find(|edge| edge.pin == 10 && edge.level == config.active_level)
        .expect("the switch changed");
    let step = steps
        .iter()
        .find(|(_, count)| *count == point)
        .expect("the point was reached");
    prop_assert_eq!(switch_edge.ct, step.0);
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(48), ..ProptestConfig::default() })]

    /// Random switch points and bounce, both directions, sd and cc.
    #[test]
    fn homing_latches_the_switch_step_exactly(
        sd in any::<bool>(),
        direction in direction(),
        switch_at in 1i64..6_000,
        bounce_steps in 0u32..12,
        seed in any::<u64>(),
        start_position in -1_000_000i64..1_000_000,
        set_position in -1_000_000i64..1_000_000,
        seek_speed in 2_000u32..30_000,
        latch_speed in 100u32..2_000,
        backoff_steps in 1u32..400,
        active_level in any::<bool>(),
    ) {
        check_homing(
            ClockMode::Virtual,
            sd,
            direction,
            switch_at,
            Bounce { steps: bounce_steps, seed },
            start_position,
            HomeConfig {
                active_level,
                seek_speed,
                latch_speed,
                backoff_steps,
                max_travel: 100_000,
                set_position,
                ..HomeConfig::default()
            },
        )?;
    }
}

#[test]
fn homing_in_real_time_latches_the_switch_step_exactly() {
    for (sd, direction) in [(true, Direction::Reverse), (false, Direction::Forward)] {
        check_homing(
            ClockMode::Real,
            sd,
            direction,
            1_500,
            Bounce { steps: 6, seed: 3 },
            250,
            HomeConfig {
                seek_speed: 20_000,
                latch_speed: 2_000,
                backoff_steps: 50,
                set_position: -40,
                ..HomeConfig::default()
            },
        )
        .unwrap();
    }
}

#[test]
fn a_switch_that_never_trips_fails_within_max_travel_under_control() {
    let hub = hub(ClockMode::Virtual);
    let x = hub.start_cc(0, 1, 2).unwrap();
    hub.set_input(0, true).unwrap();
    hub.attach_switch(10, &x, 5_000..=i64::MAX, true).unwrap();
    x.home(HomeConfig {
        switch_pin: 10,
        direction: Direction::Forward,
        max_travel: 3_000,
        ..HomeConfig::default()
    })
    .unwrap();
    hub.run_until_idle();
    assert_eq!(x.home_outcome(), Some(Err(AxisError::HomeSwitchNotFound)));
    // The seek ran its max_travel with its own deceleration, no further.
    assert_eq!((x.position(), x.steps_to_go()), (3_000, 0));
    assert_eq!(hub.rising_edges(1), 3_000);
    assert!(!x.is_homing());
    // The axis takes moves again.
    x.move_steps(8_000, -3_000).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), 0);
}

#[test]
fn homing_from_on_the_switch_first_moves_off_it() {
    let hub = hub(ClockMode::Virtual);
    let x = start_axis(&hub, 0, Wiring::Sd);
    // Pressed at the start (low-active switch).
    hub.attach_switch(10, &x, i64::MIN..=20, false).unwrap();
    assert!(!hub.input(10));
    x.home(HomeConfig {
        switch_pin: 10,
        active_level: false,
        direction: Direction::Reverse,
        ..HomeConfig::default()
    })
    .unwrap();
    hub.run_until_idle();
    let report = x.home_outcome().unwrap().unwrap();
    assert_eq!(report.latch_physical, 20);
    assert_eq!(x.position(), x.physical_position() - 20);
}

#[test]
fn bad_homing_requests_are_refused_and_change_nothing() {
    let hub = hub(ClockMode::Virtual);
    let x = hub.start_sd(0, 1, 2).unwrap();
    let home = HomeConfig {
        switch_pin: 10,
        ..HomeConfig::default()
    };
    assert_eq!(x.home(home), Err(AxisError::StopPinLow));
    hub.set_input(0, true).unwrap();
    for bad in [
        HomeConfig {
            max_travel: 0,
            ..home
        },
        HomeConfig {
            backoff_steps: 0,
            ..home
        },
        HomeConfig {
            switch_pin: 1,
            ..home
        },
        HomeConfig {
            switch_pin: 64,
            ..home
        },
    ] {
        assert!(
            matches!(x.home(bad), Err(AxisError::BadSetting(_))),
            "{bad:?}"
        );
    }
    assert!(matches!(
        x.home(HomeConfig {
            seek_speed: 0,
            ..home
        }),
        Err(AxisError::Plan(_))
    ));
    x.move_steps(1_000, 100).unwrap();
    assert_eq!(x.home(home), Err(AxisError::NotIdle));
    hub.run_until_idle();
    assert_eq!((x.position(), x.home_outcome()), (100, None));
}

#[test]
fn an_emergency_stop_or_the_stop_pin_aborts_homing() {
    let hub = hub(ClockMode::Virtual);
    let x = start_axis(&hub, 0, Wiring::Sd);
    hub.attach_switch(10, &x, i64::MIN..=-50_000, true).unwrap();
    let home = HomeConfig {
        switch_pin: 10,
        ..HomeConfig::default()
    };
    x.home(home).unwrap();
    hub.advance(20_000_000);
    x.emergency_stop().unwrap();
    hub.run_until_idle();
    assert_eq!(x.home_outcome(), Some(Err(AxisError::HomingAborted)));
    x.home(home).unwrap();
    hub.advance(20_000_000);
    hub.set_input(0, false).unwrap();
    hub.run_until_idle();
    assert_eq!(x.home_outcome(), Some(Err(AxisError::HomingAborted)));
    let ledger = x.ledger();
    assert_eq!(
        x.position(),
        ledger.base + ledger.accepted - ledger.dropped + ledger.jogged
    );
}

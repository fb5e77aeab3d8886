//! Inputs learned late ([`AxisCore::set_inputs_late`]): a core run ahead
//! of its pins, told of each switch change some steps after the step on
//! which it happened, latches what a core told on time latches.

extern crate std;
use std::vec::Vec;

use proptest::prelude::*;

use super::test_core::core;
use super::*;
use crate::axis::{AxisError, HomeConfig, HomeReport, LimitTrip};

const SWITCH_PIN: u8 = 10;

/// A switch on [`SWITCH_PIN`] that reads `pressed(physical)`, told to the
/// core `late` steps after the step on which it changed (or once the core
/// has nothing left to do, when fewer follow). `late = 0` is the hub's
/// cog: told after every event.
fn run_late(core: &mut AxisCore, late: usize, pressed: impl Fn(i64) -> bool) {
    // The steps made so far (physical after each) and the changes not told yet:
    // (index of the step it came on, level).
    let mut steps: Vec<i64> = std::vec![core.physical_position()];
    let mut untold: Vec<(usize, bool)> = Vec::new();
    let mut seen = pressed(core.physical_position());
    core.set_inputs(0, u64::from(seen) << SWITCH_PIN);
    let mut t = 0;
    loop {
        let next = core.next_event();
        if let Some(at) = next {
            t = at;
            let before = core.physical_position();
            core.run_event(t, &mut |_| {});
            if core.physical_position() != before {
                steps.push(core.physical_position());
                let level = pressed(core.physical_position());
                if level != seen {
                    seen = level;
                    untold.push((steps.len() - 1, level));
                }
            }
        }
        // Tell every change `late` steps old, or all of them at the end.
        while let Some(&(index, level)) = untold.first() {
            if next.is_some() && steps.len() - 1 < index + late {
                break;
            }
            untold.remove(0);
            let late_steps = core.physical_position() - steps[index];
            core.set_inputs_late(t, u64::from(level) << SWITCH_PIN, late_steps);
        }
        if next.is_none() && untold.is_empty() {
            return;
        }
    }
}

fn home_config(direction: Direction, seek_speed: u32, latch_speed: u32) -> HomeConfig {
    HomeConfig {
        switch_pin: SWITCH_PIN,
        active_level: true,
        direction,
        seek_speed,
        latch_speed,
        backoff_steps: 60,
        max_travel: 20_000,
        set_position: 7,
    }
}

/// Homes a fresh core onto a switch pressed at and beyond `switch_at`
/// (the home direction's side), told `late` steps late: the report and
/// where the position counter puts the physical origin.
fn home_late(config: HomeConfig, switch_at: i64, late: usize) -> (HomeReport, i64, i64) {
    let mut x = core();
    x.command(0, CoreCommand::Home(config)).unwrap();
    let sign = config.direction.sign();
    run_late(&mut x, late, |physical| physical * sign >= switch_at * sign);
    let report = match x.home_outcome() {
        Some(Ok(report)) => report,
        other => panic!("homing ended with {other:?}"),
    };
    (
        report,
        x.position() - x.physical_position(),
        x.physical_position(),
    )
}

#[test]
fn homing_told_late_latches_the_step_on_which_the_switch_changed() {
    let config = home_config(Direction::Reverse, 4_000, 400);
    let (on_time, origin, end) = home_late(config, -1_500, 0);
    assert_eq!(
        (on_time.seek_physical, on_time.latch_physical),
        (-1_500, -1_500)
    );
    let (late, late_origin, late_end) = home_late(config, -1_500, 25);
    assert_eq!(
        (
            late.seek_position,
            late.seek_physical,
            late.latch_position,
            late.latch_physical
        ),
        (
            on_time.seek_position,
            on_time.seek_physical,
            on_time.latch_position,
            on_time.latch_physical
        )
    );
    // The same place gets the same position; the stop ends further on.
    assert_eq!(late_origin, origin);
    assert!(late_end < end, "{late_end} vs {end}");
}

/// A move towards a max limit on [`SWITCH_PIN`] active at and beyond
/// `limit_at`, told `late` steps late: the trip and where the axis ends.
fn trip_late(speed: u32, steps: i32, limit_at: i64, late: usize) -> (Option<LimitTrip>, i64) {
    let mut x = core();
    x.command(
        0,
        CoreCommand::SetLimitPins {
            min: None,
            max: Some((SWITCH_PIN, true)),
        },
    )
    .unwrap();
    x.command(0, CoreCommand::Move { speed, steps }).unwrap();
    run_late(&mut x, late, |physical| physical >= limit_at);
    (x.limit_trip(), x.physical_position())
}

#[test]
fn a_limit_told_late_trips_at_its_step_and_counts_the_steps_after_it() {
    let (on_time, end) = trip_late(10_000, 5_000, 2_000, 0);
    let on_time = on_time.expect("the limit trips");
    assert_eq!((on_time.position, on_time.physical), (2_000, 2_000));
    assert_eq!(on_time.physical + on_time.stopping_steps as i64, end);
    let (late, late_end) = trip_late(10_000, 5_000, 2_000, 40);
    let late = late.expect("the limit trips");
    assert_eq!((late.position, late.physical), (2_000, 2_000));
    assert_eq!(late.physical + late.stopping_steps as i64, late_end);
    // At speed the stop is the same deceleration, 40 steps later.
    assert_eq!(late_end, end + 40);
}

#[test]
fn a_limit_hit_on_the_last_steps_trips_though_the_core_has_stopped() {
    // The move ends 10 steps past the limit; told 30 steps late, the core
    // is idle by then: it trips all the same, at the limit's step.
    let (trip, end) = trip_late(2_000, 1_010, 1_000, 30);
    assert_eq!(end, 1_010);
    let trip = trip.expect("the limit trips");
    assert_eq!(
        (trip.side, trip.physical, trip.stopping_steps),
        (Direction::Forward, 1_000, 10)
    );
}

/// Homes a fresh core whose caller promises its input changes within
/// `latency_ticks`, on a switch that reads `pressed(physical, seen)`
/// (`seen`: it has been pressed before), told `late` steps late: the
/// outcome, the origin and where the pins end.
fn home_within(
    config: HomeConfig,
    latency_ticks: u64,
    late: usize,
    pressed: impl Fn(i64, bool) -> bool,
) -> (Option<Result<HomeReport, AxisError>>, i64, i64) {
    let mut x = core();
    x.config.input_latency_ticks = latency_ticks;
    x.command(0, CoreCommand::Home(config)).unwrap();
    let seen = core::cell::Cell::new(false);
    run_late(&mut x, late, |physical| {
        let level = pressed(physical, seen.get());
        seen.set(seen.get() || level);
        level
    });
    assert!(!x.is_moving() && !x.is_homing());
    (
        x.home_outcome(),
        x.position() - x.physical_position(),
        x.physical_position(),
    )
}

/// 100 ms at the core's 200 MHz: steps told late on a slow approach from
/// rest come that late.
const LATENCY_100_MS: u64 = 20_000_000;

#[test]
fn a_backoff_that_ends_before_the_release_is_told_waits_for_it() {
    let config = HomeConfig {
        backoff_steps: 1,
        ..home_config(Direction::Reverse, 4_000, 400)
    };
    let switch = |physical: i64, _seen: bool| physical <= -1_500;
    let (on_time, origin, _) = home_within(config, 0, 0, switch);
    let on_time = on_time.unwrap().unwrap();
    // Told 2 steps late, the release comes after the backoff's end: a
    // core that is promised nothing calls the switch stuck (the hub's
    // rule, for a caller that tells on time)...
    let (stuck, _, _) = home_within(config, 0, 2, switch);
    assert_eq!(stuck, Some(Err(AxisError::HomeSwitchStuck)));
    // ...one promised the changes within 100 ms waits, and homes as on time.
    let (late, late_origin, _) = home_within(config, LATENCY_100_MS, 2, switch);
    let late = late.unwrap().unwrap();
    assert_eq!(
        (late.seek_physical, late.latch_physical, late.latch_position),
        (
            on_time.seek_physical,
            on_time.latch_physical,
            on_time.latch_position
        )
    );
    assert_eq!(late_origin, origin);
}

#[test]
fn a_switch_that_never_releases_ends_homing_once_the_latency_is_past() {
    let config = home_config(Direction::Reverse, 4_000, 400);
    // Pressed from -1,500 on, and for ever once pressed.
    let stuck = |physical: i64, seen: bool| seen || physical <= -1_500;
    let (outcome, _, end) = home_within(config, LATENCY_100_MS, 3, stuck);
    assert_eq!(outcome, Some(Err(AxisError::HomeSwitchStuck)));
    // The backoff ended 60 steps before the switch point; the approach
    // made fewer steps towards it than 100 ms at the latch speed (40),
    // its stop included (13: it starts from rest).
    let backoff_end = -1_500 + 60;
    assert!((backoff_end - 40..backoff_end).contains(&end), "{end}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Whatever the lateness, speeds and side, homing latches the same
    /// steps and gives the same place the same position as on time.
    #[test]
    fn homing_told_late_agrees_with_homing_on_time(
        late in 1usize..60,
        seek_speed in 1_000u32..12_000,
        latch_speed in 100u32..1_000,
        switch_at in 200i64..3_000,
        forward in any::<bool>(),
    ) {
        let direction = if forward { Direction::Forward } else { Direction::Reverse };
        let config = home_config(direction, seek_speed, latch_speed);
        let switch_at = switch_at * direction.sign();
        let (on_time, origin, _) = home_late(config, switch_at, 0);
        let (told_late, late_origin, _) = home_late(config, switch_at, late);
        prop_assert_eq!(told_late.seek_physical, on_time.seek_physical);
        prop_assert_eq!(told_late.latch_physical, on_time.latch_physical);
        prop_assert_eq!(told_late.latch_position, on_time.latch_position);
        prop_assert_eq!(late_origin, origin);
    }

    /// A limit told late trips at the step the on-time core trips at, and
    /// no step edge goes past its stopping steps.
    #[test]
    fn a_limit_told_late_trips_where_it_would_on_time(
        late in 1usize..80,
        speed in 500u32..20_000,
        limit_at in 1i64..4_000,
    ) {
        let (on_time, end) = trip_late(speed, 4_000, limit_at, 0);
        let (told_late, late_end) = trip_late(speed, 4_000, limit_at, late);
        let on_time = on_time.expect("the limit trips on time");
        let told_late = told_late.expect("the limit trips late");
        prop_assert_eq!((told_late.position, told_late.physical), (on_time.position, on_time.physical));
        prop_assert_eq!(told_late.physical + told_late.stopping_steps as i64, late_end);
        // The stop starts later, never earlier.
        prop_assert!(late_end >= end, "{} before {}", late_end, end);
    }
}

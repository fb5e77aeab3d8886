//! Hard limits (switches that stop an axis) and soft limits (positions no
//! move may end beyond): no edge goes past a hard limit's reported stopping
//! distance, no move crosses a soft limit, and jogs stop exactly on it.

use cogstep_test_support::edges::signed_steps;
use cogstep_test_support::hub::{start_axis, tracing_hub, Wiring};
use cogstep_test_support::props::{cases, direction};
use driver::switch::{Bounce, Switch};
use driver::{Axis, AxisError, ClockMode, Direction, Edge, Hub, HubConfig};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

fn hub(clock: ClockMode, limit_estop: bool) -> Hub {
    tracing_hub(HubConfig {
        clock,
        limit_estop,
        ..HubConfig::default()
    })
}

/// The signed position after every step, from the pins alone.
fn walk(x: &Axis, trace: &[Edge]) -> Vec<i64> {
    signed_steps(x.outputs(), trace)
        .into_iter()
        .map(|(_, position)| position)
        .collect()
}

/// Drives an axis into a hard limit at `limit_at` steps the way `side` goes.
#[allow(clippy::too_many_arguments)]
fn check_hard_limit(
    clock: ClockMode,
    sd: bool,
    side: Direction,
    limit_at: i64,
    bounce: Bounce,
    speed: u32,
    limit_estop: bool,
) -> Result<(), TestCaseError> {
    let hub = hub(clock, limit_estop);
    let x = start_axis(&hub, 0, Wiring::sd_if(sd));
    let point = limit_at * side.sign();
    let (active, pins) = match side {
        Direction::Forward => (point..=i64::MAX, (None, Some((11, true)))),
        Direction::Reverse => (i64::MIN..=point, (Some((11, true)), None)),
    };
    hub.attach_bouncing_switch(11, &x, active.clone(), true, bounce)
        .unwrap();
    x.set_limit_pins(pins.0, pins.1).unwrap();
    let far = i32::try_from(limit_at * 4 + 10_000).unwrap();
    let steps = far * i32::try_from(side.sign()).unwrap();
    x.move_steps(speed, steps).unwrap();
    hub.run_until_idle();
    prop_assert_eq!(x.limit_fault(), Some(side));
    let trip = x.limit_trip().unwrap();
    prop_assert_eq!(trip.physical, point, "tripped on the step that reached it");
    if limit_estop {
        prop_assert_eq!(trip.stopping_steps, 0);
    }
    // No edge beyond the stopping distance reported.
    let positions = walk(&x, &hub.trace());
    let furthest = positions.iter().map(|p| p * side.sign()).max().unwrap_or(0);
    prop_assert_eq!(
        furthest,
        limit_at + i64::try_from(trip.stopping_steps).unwrap()
    );
    prop_assert_eq!(*positions.last().unwrap(), x.physical_position());
    let ledger = x.ledger();
    prop_assert_eq!(
        x.position(),
        ledger.base + ledger.accepted - ledger.dropped + ledger.jogged
    );
    prop_assert_eq!(ledger.dropped, i64::from(steps) - x.position());
    // Further in: refused; away: taken.
    prop_assert_eq!(
        x.move_steps(speed, steps.signum()),
        Err(AxisError::IntoLimit(side))
    );
    prop_assert_eq!(x.jog(speed, side), Err(AxisError::IntoLimit(side)));
    x.clear_limit_fault().unwrap();
    prop_assert_eq!(x.limit_fault(), None);
    // Still on the switch: still refused. (Where the axis stopped inside
    // the bounce, the chatter may read the switch open there, as a contact
    // resting on its bounce would: the pins then say the way is clear, and
    // the move is taken. Seen once in CI: limit at 6, 5 steps of bounce,
    // 500 steps/s.)
    let switch = Switch {
        pin: 11,
        active: active.clone(),
        active_level: true,
        bounce,
    };
    if switch.pressed_at(x.physical_position()) {
        prop_assert_eq!(
            x.move_steps(speed, steps.signum()),
            Err(AxisError::IntoLimit(side))
        );
    }
    let away = -steps.signum() * i32::try_from(trip.stopping_steps + 50).unwrap();
    x.move_steps(speed, away).unwrap();
    hub.run_until_idle();
    prop_assert_eq!(x.limit_fault(), None, "moving away never trips");
    x.move_steps(speed, steps.signum() * 10).unwrap();
    hub.run_until_idle();
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(48), ..ProptestConfig::default() })]

    #[test]
    fn no_edge_beyond_a_hard_limit_after_the_stopping_distance(
        sd in any::<bool>(),
        side in direction(),
        limit_at in 1i64..5_000,
        bounce_steps in 0u32..8,
        seed in any::<u64>(),
        speed in 500u32..40_000,
        limit_estop in any::<bool>(),
    ) {
        check_hard_limit(
            ClockMode::Virtual,
            sd,
            side,
            limit_at,
            Bounce { steps: bounce_steps, seed },
            speed,
            limit_estop,
        )?;
    }
}

#[test]
fn hard_limits_in_real_time() {
    check_hard_limit(
        ClockMode::Real,
        true,
        Direction::Forward,
        2_000,
        Bounce::default(),
        20_000,
        false,
    )
    .unwrap();
    check_hard_limit(
        ClockMode::Real,
        false,
        Direction::Reverse,
        1_000,
        Bounce { steps: 5, seed: 1 },
        10_000,
        true,
    )
    .unwrap();
}

#[test]
fn a_limit_driven_from_outside_stops_a_move_and_bad_settings_are_refused() {
    let hub = hub(ClockMode::Virtual, false);
    let x = start_axis(&hub, 0, Wiring::Sd);
    assert!(matches!(
        x.set_limit_pins(Some((1, true)), None),
        Err(AxisError::BadSetting(_))
    ));
    assert!(matches!(
        x.set_limit_pins(Some((9, true)), Some((9, true))),
        Err(AxisError::BadSetting(_))
    ));
    assert!(matches!(
        x.set_soft_limits(10, -10),
        Err(AxisError::BadSetting(_))
    ));
    x.set_limit_pins(Some((11, false)), Some((12, false)))
        .unwrap();
    // Low-active limits, both released (high).
    hub.set_input(11, true).unwrap();
    hub.set_input(12, true).unwrap();
    x.move_steps(10_000, -50_000).unwrap();
    hub.advance(100_000_000);
    hub.set_input(11, false).unwrap();
    hub.run_until_idle();
    let trip = x.limit_trip().unwrap();
    assert_eq!(trip.side, Direction::Reverse);
    assert_eq!(x.position(), trip.position - trip.stopping_steps as i64);
    assert!(x.mode().has(driver::Mode::LIMIT));
    assert_eq!(
        x.move_steps(10_000, -5),
        Err(AxisError::IntoLimit(Direction::Reverse))
    );
    x.move_steps(10_000, 5).unwrap();
    hub.run_until_idle();
}

/// What the soft-limit property does to the axis.
#[derive(Clone, Debug)]
enum Op {
    Move {
        speed: u32,
        steps: i32,
    },
    Jog {
        speed: u32,
        forward: bool,
        beats: u8,
    },
    Advance {
        ms: u32,
    },
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (500u32..30_000, -20_000i32..20_000).prop_map(|(speed, steps)| Op::Move { speed, steps }),
        (500u32..30_000, any::<bool>(), 1u8..40).prop_map(|(speed, forward, beats)| Op::Jog {
            speed,
            forward,
            beats
        }),
        (1u32..400).prop_map(|ms| Op::Advance { ms }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(48), ..ProptestConfig::default() })]

    /// Random moves, jogs and waits: no step ever lands outside the soft
    /// limits; an idle axis refuses exactly the moves that would end
    /// beyond them.
    #[test]
    fn no_move_or_jog_crosses_a_soft_limit(
        sd in any::<bool>(),
        min in -15_000i64..0,
        max in 0i64..15_000,
        ops in prop::collection::vec(op(), 1..12),
    ) {
        let hub = hub(ClockMode::Virtual, false);
        let x = start_axis(&hub, 0, Wiring::sd_if(sd));
        x.set_soft_limits(min, max).unwrap();
        prop_assert_eq!(x.soft_limits(), Some((min, max)));
        for op in &ops {
            match *op {
                Op::Move { speed, steps } => {
                    let idle = x.steps_to_go() == 0;
                    let end = x.position() + i64::from(steps);
                    let result = x.move_steps(speed, steps);
                    if idle && steps != 0 && (end < min || end > max) {
                        prop_assert_eq!(result, Err(AxisError::BeyondSoftLimit));
                    }
                    if idle && steps != 0 && (min..=max).contains(&end) {
                        prop_assert!(result.is_ok(), "{:?}", result);
                    }
                }
                Op::Jog { speed, forward, beats } => {
                    let direction = if forward { Direction::Forward } else { Direction::Reverse };
                    for _ in 0..beats {
                        let _ = x.jog(speed, direction);
                        hub.advance(20_000_000);
                    }
                }
                Op::Advance { ms } => {
                    hub.advance(u64::from(ms) * 200_000);
                }
            }
        }
        hub.run_until_idle();
        for position in walk(&x, &hub.trace()) {
            prop_assert!((min..=max).contains(&position), "{} outside {}..={}", position, min, max);
        }
    }

    /// A jog held long enough stops exactly on the soft limit.
    #[test]
    fn a_jog_stops_exactly_on_the_soft_limit(
        sd in any::<bool>(),
        forward in any::<bool>(),
        limit in 1i64..3_000,
        speed in 500u32..30_000,
    ) {
        let hub = hub(ClockMode::Virtual, false);
        let x = start_axis(&hub, 0, Wiring::sd_if(sd));
        x.set_soft_limits(-limit, limit).unwrap();
        let direction = if forward { Direction::Forward } else { Direction::Reverse };
        let mut beats = 0;
        loop {
            match x.jog(speed, direction) {
                Ok(()) => {}
                Err(AxisError::BeyondSoftLimit) => break,
                Err(other) => prop_assert!(false, "{:?}", other),
            }
            hub.advance(20_000_000);
            beats += 1;
            prop_assert!(beats < 10_000, "the jog never reached the limit");
        }
        hub.run_until_idle();
        prop_assert_eq!(x.position(), limit * direction.sign());
        let positions = walk(&x, &hub.trace());
        prop_assert_eq!(positions.iter().map(|p| p.abs()).max(), Some(limit));
    }
}

#[test]
fn soft_limits_in_real_time() {
    let hub = hub(ClockMode::Real, false);
    let x = start_axis(&hub, 0, Wiring::Sd);
    x.set_soft_limits(-1_000, 2_000).unwrap();
    assert_eq!(x.move_steps(20_000, 2_001), Err(AxisError::BeyondSoftLimit));
    x.move_steps(20_000, 2_000).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), 2_000);
    for _ in 0..200 {
        match x.jog(20_000, Direction::Reverse) {
            Ok(()) => std::thread::sleep(std::time::Duration::from_millis(10)),
            Err(AxisError::BeyondSoftLimit) => break,
            Err(other) => panic!("{other:?}"),
        }
    }
    hub.run_until_idle();
    assert_eq!(x.position(), -1_000);
    x.clear_soft_limits().unwrap();
    x.move_steps(20_000, -5).unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), -1_005);
}

//! Limits that hold in every kind of motion and e-stops that reach only
//! their own axes: the scenarios an outside review found, on the hub
//! (virtual time, so each runs the same every time).

use cogstep_test_support::hub::{start_axis, Wiring};
use cogstep_test_support::ledger::assert_accounted;
use driver::{Axis, AxisError, Direction, Hub, HubConfig};

fn hub_xy() -> (Hub, Axis, Axis) {
    let hub = Hub::new(HubConfig::default()).unwrap();
    let x = start_axis(&hub, 0, Wiring::Sd);
    let y = start_axis(&hub, 1, Wiring::Sd);
    (hub, x, y)
}

#[test]
fn a_group_move_is_refused_beyond_a_soft_limit_as_a_move_is() {
    let (hub, x, y) = hub_xy();
    x.set_soft_limits(-1_000, 1_000).unwrap();
    assert_eq!(x.move_steps(10_000, 5_000), Err(AxisError::BeyondSoftLimit));
    assert_eq!(
        hub.move_together(&[(&x, 5_000), (&y, 100)], 10_000),
        Err(AxisError::BeyondSoftLimit)
    );
    hub.run_until_idle();
    assert_eq!((x.position(), y.position()), (0, 0));
    hub.move_together(&[(&x, 900), (&y, 100)], 10_000).unwrap();
    hub.run_until_idle();
    assert_eq!((x.position(), y.position()), (900, 100));
}

#[test]
fn a_limit_switch_stops_a_group_move_and_keeps_every_axis_on_the_line() {
    let (hub, x, y) = hub_xy();
    hub.attach_switch(10, &x, 2_000..=i64::MAX, true).unwrap();
    x.set_limit_pins(None, Some((10, true))).unwrap();
    // A single move trips there...
    x.move_steps(10_000, 5_000).unwrap();
    hub.run_until_idle();
    let single = x.position();
    assert!((2_000..5_000).contains(&single), "{single}");
    x.clear_limit_fault().unwrap();
    x.move_steps(10_000, -i32::try_from(single).unwrap())
        .unwrap();
    hub.run_until_idle();
    // ...and so does the same move in a group, with y on the line.
    hub.move_together(&[(&x, 5_000), (&y, 2_500)], 10_000)
        .unwrap();
    hub.run_until_idle();
    assert_eq!(x.limit_fault(), Some(Direction::Forward));
    assert!(
        x.position() < 5_000,
        "x ran through the switch to {}",
        x.position()
    );
    let line = x.position() as f64 * 2_500.0 / 5_000.0;
    assert!(
        (y.position() as f64 - line).abs() <= 1.0,
        "y {} off the line {line}",
        y.position()
    );
    assert_accounted(&x);
    assert_accounted(&y);
    // Towards the tripped limit no group move runs; away from it one does.
    assert_eq!(
        hub.move_together(&[(&x, 1_000), (&y, 10)], 10_000),
        Err(AxisError::IntoLimit(Direction::Forward))
    );
    hub.move_together(&[(&x, -1_000), (&y, 10)], 10_000)
        .unwrap();
    hub.run_until_idle();
    assert_accounted(&x);
}

#[test]
fn with_limit_estop_a_trip_in_a_group_stops_every_member_at_once() {
    let hub = Hub::new(HubConfig {
        limit_estop: true,
        ..HubConfig::default()
    })
    .unwrap();
    let x = hub.start_sd(0, 1, 2).unwrap();
    let y = hub.start_sd(3, 4, 5).unwrap();
    hub.set_input(0, true).unwrap();
    hub.set_input(3, true).unwrap();
    hub.attach_switch(10, &x, 2_000..=i64::MAX, true).unwrap();
    x.set_limit_pins(None, Some((10, true))).unwrap();
    hub.move_together(&[(&x, 5_000), (&y, 5_000)], 10_000)
        .unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), 2_000);
    assert!((y.position() - 2_000).abs() <= 1, "y at {}", y.position());
    assert_accounted(&x);
    assert_accounted(&y);
}

#[test]
fn an_axis_emergency_stop_does_not_reach_through_a_group_that_ended() {
    let (hub, x, y) = hub_xy();
    hub.move_together(&[(&x, 1), (&y, 1_000)], 10_000).unwrap();
    hub.run_until_idle();
    x.move_steps(10_000, 1_000).unwrap();
    hub.advance(2_000_000);
    y.emergency_stop().unwrap();
    hub.run_until_idle();
    assert_eq!(x.position(), 1_001, "y's e-stop dropped x's own move");
    assert_eq!(x.dropped_steps(), 0);
    y.move_steps(10_000, 10_000).unwrap();
    hub.advance(2_000_000);
    x.emergency_stop().unwrap();
    hub.run_until_idle();
    assert_eq!(
        y.position(),
        11_000,
        "x's e-stop stopped y's unrelated move"
    );
    assert_accounted(&x);
    assert_accounted(&y);
}

#[test]
fn an_emergency_stop_after_a_group_stop_counts_each_step_once() {
    let (hub, x, y) = hub_xy();
    hub.move_together(&[(&y, 172), (&x, -27)], 56_815).unwrap();
    hub.advance(3_732_192);
    y.set_stop_pin(false).unwrap();
    hub.advance(364_872);
    x.emergency_stop().unwrap();
    y.emergency_stop().unwrap();
    hub.run_until_idle();
    assert_accounted(&x);
    assert_accounted(&y);
}

#[test]
fn a_group_does_not_start_when_a_stop_pin_is_low() {
    let (hub, x, y) = hub_xy();
    y.set_stop_pin(false).unwrap();
    assert_eq!(
        hub.move_together(&[(&x, 500), (&y, 500)], 10_000),
        Err(AxisError::StopPinLow)
    );
    hub.run_until_idle();
    assert_eq!((x.position(), y.position()), (0, 0));
    assert_eq!(x.move_steps(10_000, 10), Ok(()));
}

#[test]
fn a_limit_pin_configured_while_active_stops_an_axis_heading_for_it() {
    let (hub, x, _) = hub_xy();
    x.move_steps(20_000, 20_000).unwrap();
    hub.advance(20_000_000);
    hub.set_input(11, true).unwrap();
    x.set_limit_pins(None, Some((11, true))).unwrap();
    hub.run_until_idle();
    assert_eq!(x.limit_fault(), Some(Direction::Forward));
    assert!(x.position() < 20_000, "all {} steps ran", x.position());
    assert_accounted(&x);
}

#[test]
fn after_an_emergency_stop_the_axis_reports_no_speed() {
    let (hub, x, _) = hub_xy();
    x.move_steps(20_000, 20_000).unwrap();
    hub.advance(40_000_000);
    assert!(x.status().velocity_steps_per_s > 0);
    x.emergency_stop().unwrap();
    let status = x.status();
    assert_eq!(status.velocity_steps_per_s, 0);
    assert_eq!(status.mode.bits() & driver::Mode::MOVING.bits(), 0);
}

#[test]
fn a_new_move_after_an_emergency_stop_starts_at_once() {
    // 1 step at 100 steps/s leaves a long delay after the step; the e-stop
    // ends it, and the next move does not wait it out.
    let (hub, x, _) = hub_xy();
    x.move_steps(100, 1).unwrap();
    hub.advance(40_000_000);
    x.emergency_stop().unwrap();
    x.move_steps(1_000, 20_000).unwrap();
    hub.advance(2_000_000);
    assert!(x.position() > 1, "no step 10 ms after the new move");
}

//! Homing on simulated switches: the position is latched at the step on
//! which the switch changed, whatever the bounce, direction, output variant
//! or clock, and no step goes unaccounted.

use driver::switch::Bounce;
use driver::{AxisError, ClockMode, Direction, Edge, HomeConfig, Hub, HubConfig};
use proptest::prelude::*;

fn hub(clock: ClockMode) -> Hub {
    Hub::new(HubConfig {
        clock,
        trace_edges: true,
        ..HubConfig::default()
    })
    .expect("hub")
}

/// The signed step count from the pins alone (sd: step pulses signed by
/// the direction pin; cc: cw minus ccw), and the CT of each step's rising
/// edge in order.
fn steps_from_edges(trace: &[Edge], sd: bool) -> (i64, Vec<(u64, i64)>) {
    let (mut count, mut dir_high, mut steps) = (0i64, false, Vec::new());
    for edge in trace {
        let delta = match (sd, edge.pin, edge.level) {
            (true, 2, level) => {
                dir_high = level;
                0
            }
            (true, 1, true) => {
                if dir_high {
                    -1
                } else {
                    1
                }
            }
            (false, 1, true) => 1,
            (false, 2, true) => -1,
            _ => 0,
        };
        if delta != 0 {
            count += delta;
            steps.push((edge.ct, count));
        }
    }
    (count, steps)
}

#[test]
fn homing_reverse_onto_a_switch_sets_the_switch_point() {
    let hub = hub(ClockMode::Virtual);
    let x = hub.start_sd(0, 1, 2).unwrap();
    hub.set_input(0, true).unwrap();
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
    assert_eq!((report.seek_physical, report.latch_physical), (-3_217, -3_217));
    assert_eq!(report.seek_position, 5_000 - 3_217);
    assert_eq!(x.position() - 0, x.physical_position() + 3_217);
    assert_eq!(report.position, x.position());
    assert!(hub.input(10), "it stops just past the switch point");
    let (count, _) = steps_from_edges(&hub.trace(), true);
    assert_eq!(count, x.physical_position());
}

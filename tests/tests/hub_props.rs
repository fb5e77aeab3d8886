//! Random command sequences against the hub: whatever users do, the count
//! stays exact, nothing panics or deadlocks, and virtual time is repeatable.

use driver::{AxisError, Direction, Edge, Hub, HubConfig};
use proptest::prelude::*;

#[derive(Clone, Debug)]
enum Action {
    Move {
        axis: usize,
        speed: u32,
        steps: i32,
    },
    StopPin {
        axis: usize,
        high: bool,
    },
    EmergencyStop {
        axis: usize,
    },
    Jog {
        axis: usize,
        speed: u32,
        reverse: bool,
    },
    JogRelease {
        axis: usize,
    },
    Advance {
        ticks: u64,
    },
}

fn action() -> impl Strategy<Value = Action> {
    let axis = 0usize..2;
    prop_oneof![
        4 => (axis.clone(), 500u32..60_000, -3_000i32..3_000)
            .prop_map(|(axis, speed, steps)| Action::Move { axis, speed, steps }),
        2 => (axis.clone(), any::<bool>()).prop_map(|(axis, high)| Action::StopPin { axis, high }),
        1 => axis.clone().prop_map(|axis| Action::EmergencyStop { axis }),
        1 => (axis.clone(), 500u32..20_000, any::<bool>())
            .prop_map(|(axis, speed, reverse)| Action::Jog { axis, speed, reverse }),
        1 => axis.prop_map(|axis| Action::JogRelease { axis }),
        4 => (0u64..40_000_000).prop_map(|ticks| Action::Advance { ticks }),
    ]
}

/// Runs the actions on a fresh hub with one cc and one sd axis; returns the
/// trace and the final positions.
fn run(actions: &[Action]) -> (Vec<Edge>, [i64; 2]) {
    let hub = Hub::new(HubConfig {
        trace_edges: true,
        ..HubConfig::default()
    })
    .expect("hub");
    let axes = [
        hub.start_cc(0, 1, 2).expect("cc"),
        hub.start_sd(3, 4, 5).expect("sd"),
    ];
    hub.set_input(0, true).unwrap();
    hub.set_input(3, true).unwrap();
    for action in actions {
        let result = match *action {
            Action::Move { axis, speed, steps } => axes[axis].move_steps(speed, steps),
            Action::StopPin { axis, high } => axes[axis].set_stop_pin(high),
            Action::EmergencyStop { axis } => axes[axis].emergency_stop(),
            Action::Jog {
                axis,
                speed,
                reverse,
            } => {
                let direction = if reverse {
                    Direction::Reverse
                } else {
                    Direction::Forward
                };
                axes[axis].jog(speed, direction)
            }
            Action::JogRelease { axis } => axes[axis].jog_release(),
            Action::Advance { ticks } => {
                hub.advance(ticks);
                Ok(())
            }
        };
        match result {
            Ok(())
            | Err(AxisError::Busy)
            | Err(AxisError::Jogging)
            | Err(AxisError::StopPinLow)
            | Err(AxisError::Plan(_))
            | Err(AxisError::PulseTooLong { .. }) => {}
            Err(other) => panic!("unexpected error {other}"),
        }
    }
    hub.set_input(0, true).unwrap();
    hub.set_input(3, true).unwrap();
    hub.run_until_idle();
    (hub.trace(), [axes[0].position(), axes[1].position()])
}

/// Position from the pins alone: cw minus ccw pulses for cc; step pulses
/// signed by the direction pin's level at each rising edge for sd.
fn positions_from_edges(trace: &[Edge]) -> [i64; 2] {
    let mut cc = 0i64;
    let mut sd = 0i64;
    let mut dir_high = false;
    for edge in trace {
        match (edge.pin, edge.level) {
            (1, true) => cc += 1,
            (2, true) => cc -= 1,
            (5, level) => dir_high = level,
            (4, true) => sd += if dir_high { -1 } else { 1 },
            _ => {}
        }
    }
    [cc, sd]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn position_is_the_signed_count_of_step_edges(actions in prop::collection::vec(action(), 1..24)) {
        let (trace, positions) = run(&actions);
        prop_assert_eq!(positions_from_edges(&trace), positions);
        // Pulses never overlap on one pin: rising, falling, rising...
        for pin in [1u8, 2, 4] {
            let mut high = false;
            for edge in trace.iter().filter(|e| e.pin == pin) {
                prop_assert_ne!(edge.level, high);
                high = edge.level;
            }
            prop_assert!(!high);
        }
    }

    #[test]
    fn virtual_time_is_repeatable(actions in prop::collection::vec(action(), 1..16)) {
        let first = run(&actions);
        let second = run(&actions);
        prop_assert_eq!(first, second);
    }
}

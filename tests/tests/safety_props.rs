//! Limits as an invariant, model-checked: random sequences of moves,
//! jogs, group moves, homing, stop pins, e-stops, fault clears and time on two axes
//! with soft limits and a simulated hard-limit switch each, in virtual
//! time (and, fewer cases, with the real clock). After every operation: no axis beyond a soft limit, no axis
//! further past its switch than the stop it had when it tripped, a refusal
//! changed nothing, an idle axis's accounts add up, an e-stopped axis has
//! no speed. Case counts from `COGSTEP_MODEL_CASES` (CI: 300; the long run
//! in the closing note used 20,000).

use cogstep_test_support::hub::{start_axis, Wiring};
use cogstep_test_support::ledger::accounted;
use cogstep_test_support::props::{cases, Tally};
use driver::serial::StatusLine;
use driver::{Axis, AxisError, AxisState, ClockMode, Direction, HomeConfig, Hub, HubConfig, Mode};
use proptest::prelude::*;

const SOFT: i64 = 6_000;
/// x's max switch is active at physical ≥ 3,000; y's min switch at ≤ −3,000.
const SWITCH: i64 = 3_000;
/// The most steps any move here needs to stop (20,000 steps/s: 2,002 ramp steps).
const STOP_MAX: i64 = 2_100;

#[derive(Clone, Debug)]
enum Op {
    Move {
        axis: usize,
        speed: u32,
        steps: i32,
    },
    Jog {
        axis: usize,
        speed: u32,
        forward: bool,
    },
    JogRelease {
        axis: usize,
    },
    Group {
        x: i32,
        y: i32,
        speed: u32,
    },
    StopPin {
        axis: usize,
        high: bool,
    },
    EmergencyStop {
        axis: usize,
    },
    ClearFault {
        axis: usize,
    },
    /// Home y on its min limit switch (the switch point set to its own
    /// physical position, so the position stays the physical one).
    HomeY {
        seek_speed: u32,
    },
    Advance {
        ticks: u64,
    },
}

fn op() -> impl Strategy<Value = Op> {
    let axis = 0usize..2;
    let speed = prop_oneof![1_000u32..20_000, Just(20_000u32)];
    let steps = prop_oneof![-9_000i32..9_000, -300i32..300];
    prop_oneof![
        4 => (axis.clone(), speed.clone(), steps.clone())
            .prop_map(|(axis, speed, steps)| Op::Move { axis, speed, steps }),
        2 => (axis.clone(), speed.clone(), any::<bool>())
            .prop_map(|(axis, speed, forward)| Op::Jog { axis, speed, forward }),
        1 => axis.clone().prop_map(|axis| Op::JogRelease { axis }),
        3 => (steps.clone(), steps, speed)
            .prop_map(|(x, y, speed)| Op::Group { x, y, speed }),
        2 => (axis.clone(), any::<bool>()).prop_map(|(axis, high)| Op::StopPin { axis, high }),
        1 => axis.clone().prop_map(|axis| Op::EmergencyStop { axis }),
        1 => axis.prop_map(|axis| Op::ClearFault { axis }),
        1 => (2_000u32..20_000).prop_map(|seek_speed| Op::HomeY { seek_speed }),
        5 => (1u64..80_000_000).prop_map(|ticks| Op::Advance { ticks }),
    ]
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Seen {
    position: i64,
    steps_to_go: u64,
    mode: u32,
    ledger: driver::StepLedger,
}

fn seen(axis: &Axis) -> Seen {
    Seen {
        position: axis.position(),
        steps_to_go: axis.steps_to_go(),
        mode: axis.mode().bits(),
        ledger: axis.ledger(),
    }
}

fn check_invariants(axes: &[Axis; 2]) -> Result<(), TestCaseError> {
    for (i, axis) in axes.iter().enumerate() {
        let position = axis.position();
        prop_assert!((-SOFT..=SOFT).contains(&position), "axis {i} at {position}");
        let physical = axis.physical_position();
        let past = if i == 0 {
            physical - SWITCH
        } else {
            -SWITCH - physical
        };
        prop_assert!(past <= STOP_MAX, "axis {i} {past} steps past its switch");
        if let Some(trip) = axis.limit_trip() {
            let beyond = (physical - trip.physical) * trip.side.sign();
            prop_assert!(
                beyond <= trip.stopping_steps as i64,
                "axis {i}: {beyond} steps past its trip, {} allowed",
                trip.stopping_steps
            );
        }
        let status = axis.status();
        if status.mode.has(Mode::ESTOP) {
            prop_assert_eq!(status.velocity_steps_per_s, 0);
        }
        // One definition of each state and field, as docs/protocol.md has
        // them: Idle and Alarm have nothing to make and no speed, Run has
        // steps to make, and the status line says the same.
        match status.state() {
            AxisState::Idle | AxisState::Alarm => {
                prop_assert_eq!(status.steps_to_go, 0, "axis {} {:?}", i, status);
                prop_assert_eq!(status.velocity_steps_per_s, 0, "axis {} {:?}", i, status);
            }
            AxisState::Run | AxisState::Jog => {
                prop_assert!(status.steps_to_go > 0, "axis {} {:?}", i, status)
            }
            AxisState::Hold => {}
        }
        let line = StatusLine::new(i, &status).to_string();
        let read = StatusLine::parse(&line).expect("a status line reads back");
        prop_assert_eq!(read.state, status.state());
        prop_assert_eq!(read.steps_to_go, status.steps_to_go);
        prop_assert_eq!(read.velocity_steps_per_s, status.velocity_steps_per_s);
        if axis.steps_to_go() == 0 && !axis.mode().has(Mode::MOVING) {
            let ledger = axis.ledger();
            prop_assert_eq!(
                i128::from(position),
                accounted(&ledger),
                "axis {} {:?}",
                i,
                ledger
            );
        }
    }
    Ok(())
}

fn run(ops: &[Op], clock: ClockMode) -> Result<usize, TestCaseError> {
    let real = clock == ClockMode::Real;
    let hub = Hub::new(HubConfig {
        clock,
        realtime_priority: false,
        ..HubConfig::default()
    })
    .unwrap();
    let axes = [
        start_axis(&hub, 0, Wiring::Sd),
        start_axis(&hub, 1, Wiring::Cc),
    ];
    hub.attach_switch(10, &axes[0], SWITCH..=i64::MAX, true)
        .unwrap();
    hub.attach_switch(11, &axes[1], i64::MIN..=-SWITCH, true)
        .unwrap();
    axes[0].set_limit_pins(None, Some((10, true))).unwrap();
    axes[1].set_limit_pins(Some((11, true)), None).unwrap();
    for axis in &axes {
        axis.set_soft_limits(-SOFT, SOFT).unwrap();
    }
    let stop_pins = [0u8, 3];
    for op in ops {
        let before = [seen(&axes[0]), seen(&axes[1])];
        let (result, touched): (Result<(), AxisError>, Vec<usize>) = match *op {
            Op::Move { axis, speed, steps } => (axes[axis].move_steps(speed, steps), vec![axis]),
            Op::Jog {
                axis,
                speed,
                forward,
            } => {
                let direction = if forward {
                    Direction::Forward
                } else {
                    Direction::Reverse
                };
                (axes[axis].jog(speed, direction), vec![axis])
            }
            Op::JogRelease { axis } => (axes[axis].jog_release(), vec![]),
            Op::Group { x, y, speed } => (
                hub.move_together(&[(&axes[0], x), (&axes[1], y)], speed),
                vec![0, 1],
            ),
            Op::StopPin { axis, high } => (
                hub.set_input(stop_pins[axis], high)
                    .map_err(|_| AxisError::Unavailable),
                vec![],
            ),
            Op::EmergencyStop { axis } => (axes[axis].emergency_stop(), vec![]),
            Op::ClearFault { axis } => (axes[axis].clear_limit_fault(), vec![]),
            Op::HomeY { seek_speed } => (
                axes[1].home(HomeConfig {
                    switch_pin: 11,
                    active_level: true,
                    direction: Direction::Reverse,
                    seek_speed,
                    latch_speed: 500,
                    backoff_steps: 200,
                    max_travel: 20_000,
                    set_position: -SWITCH,
                }),
                vec![1],
            ),
            Op::Advance { ticks } => {
                // Real time: at most 20 ms a step of the sequence.
                hub.advance(if real { ticks.min(4_000_000) } else { ticks });
                (Ok(()), vec![])
            }
        };
        // With the real clock the axes move between two reads: a refusal's
        // "nothing changed" is the virtual clock's to check.
        if result.is_err() && !real {
            for axis in touched {
                prop_assert_eq!(seen(&axes[axis]), before[axis], "{:?}: {:?}", op, result);
            }
        }
        check_invariants(&axes)?;
    }
    if real {
        // Real time: no waiting out long moves; an e-stop ends them.
        for axis in &axes {
            axis.emergency_stop().unwrap();
        }
    } else {
        for pin in stop_pins {
            hub.set_input(pin, true).unwrap();
        }
        for axis in &axes {
            axis.jog_release().unwrap();
        }
    }
    hub.run_until_idle();
    check_invariants(&axes)?;
    Ok(ops.len())
}

#[test]
fn limits_hold_in_every_kind_of_motion() {
    let tally = Tally::default();
    let config = ProptestConfig {
        cases: cases(300),
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    proptest!(config, |(ops in prop::collection::vec(op(), 1..40))| {
        tally.add(run(&ops, ClockMode::Virtual)?);
    });
    tally.report("limits");
}

/// The same with the real clock: the cogs run on their own while the
/// sequence goes on (an advance waits up to 20 ms). Fewer cases: each
/// takes real time.
#[test]
fn limits_hold_in_every_kind_of_motion_in_real_time() {
    let tally = Tally::default();
    let config = ProptestConfig {
        cases: cases(300) / 15,
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    proptest!(config, |(ops in prop::collection::vec(op(), 1..25))| {
        tally.add(run(&ops, ClockMode::Real)?);
    });
    tally.report("limits in real time");
}

//! Limits as an invariant over serial: random sequences of moves, group
//! moves (`G`), stop pins, e-stops, fault clears and waits sent to the
//! board simulator (a real-time hub with the demo switches: each axis's
//! min limit at physical −6,000) through `SerialBoard`, with soft limits
//! set over the wire. After every operation, read back over the wire: no
//! axis beyond a soft limit, none further past its limit switch than the
//! stop it had when it tripped, a status that agrees with itself. Few
//! cases (each takes real time); more with `COGSTEP_MODEL_CASES`.
#![cfg(all(unix, feature = "std"))]

use std::time::Duration;

use cogstep_test_support::props::{cases, Tally};
use driver::serial::host::{SerialBoard, SerialConfig};
use driver::serial::sim::{BoardSim, SimConfig};
use driver::switch::DemoSwitches;
use driver::{AxisContract, AxisState};
use proptest::prelude::*;

const SOFT: (i64, i64) = (-9_000, 5_000);
/// The most steps any move here needs to stop (20,000 steps/s: 2,002 ramp steps).
const STOP_MAX: i64 = 2_100;

#[derive(Clone, Debug)]
enum Op {
    Move { axis: usize, speed: u32, steps: i32 },
    Group { x: i32, y: i32, speed: u32 },
    StopPin { axis: usize, high: bool },
    EmergencyStop { axis: usize },
    ClearFault { axis: usize },
    Wait { ms: u64 },
}

fn op() -> impl Strategy<Value = Op> {
    let axis = 0usize..2;
    let speed = 2_000u32..=20_000;
    let steps = prop_oneof![-12_000i32..9_000, -200i32..200];
    prop_oneof![
        4 => (axis.clone(), speed.clone(), steps.clone())
            .prop_map(|(axis, speed, steps)| Op::Move { axis, speed, steps }),
        3 => (steps.clone(), steps, speed).prop_map(|(x, y, speed)| Op::Group { x, y, speed }),
        2 => (axis.clone(), any::<bool>()).prop_map(|(axis, high)| Op::StopPin { axis, high }),
        1 => axis.clone().prop_map(|axis| Op::EmergencyStop { axis }),
        1 => axis.prop_map(|axis| Op::ClearFault { axis }),
        4 => (1u64..60).prop_map(|ms| Op::Wait { ms }),
    ]
}

fn check(board: &SerialBoard) -> Result<(), TestCaseError> {
    let min_at = DemoSwitches::for_axis(0).expect("demo switches").min_at;
    for i in 0..2 {
        let axis = board.axis(i).expect("axis");
        let status = axis.status().expect("status");
        let limits = axis.limit_status().expect("limits");
        let position = status.position;
        prop_assert!(
            (SOFT.0..=SOFT.1).contains(&position),
            "axis {i} at {position}, beyond its soft limits"
        );
        prop_assert!(
            position >= min_at - STOP_MAX,
            "axis {i} at {position}: through its min limit"
        );
        if let Some(trip) = limits.trip {
            let beyond = (position - trip.physical) * trip.side.sign();
            prop_assert!(
                beyond <= trip.stopping_steps as i64,
                "axis {i}: {beyond} steps past its trip, {} allowed",
                trip.stopping_steps
            );
        }
        if matches!(status.state(), AxisState::Idle | AxisState::Alarm) {
            prop_assert_eq!(status.steps_to_go, 0, "axis {} {:?}", i, status);
            prop_assert_eq!(status.velocity_steps_per_s, 0, "axis {} {:?}", i, status);
        }
    }
    Ok(())
}

fn run(ops: &[Op]) -> Result<usize, TestCaseError> {
    let (sim, path) = BoardSim::spawn_pty(SimConfig::default()).expect("a pseudo-terminal");
    let board = SerialBoard::open(SerialConfig {
        poll_interval: Duration::from_millis(20),
        timeout: Duration::from_secs(2),
        ..SerialConfig::new(path)
    })
    .expect("the simulated board answers");
    let axes = [board.axis(0).unwrap(), board.axis(1).unwrap()];
    for axis in &axes {
        axis.set_soft_limits(SOFT.0, SOFT.1).unwrap();
    }
    for op in ops {
        // Refusals are typed errors; what matters here is where the axes go.
        let _ = match *op {
            Op::Move { axis, speed, steps } => axes[axis].move_steps(speed, steps),
            Op::Group { x, y, speed } => board.move_together(&[x, y], speed),
            Op::StopPin { axis, high } => axes[axis].set_stop_pin(high),
            Op::EmergencyStop { axis } => axes[axis].emergency_stop(),
            Op::ClearFault { axis } => axes[axis].clear_limit_fault(),
            Op::Wait { ms } => {
                std::thread::sleep(Duration::from_millis(ms));
                Ok(())
            }
        };
        check(&board)?;
    }
    for axis in &axes {
        axis.emergency_stop().unwrap();
    }
    check(&board)?;
    board.close();
    sim.stop();
    Ok(ops.len())
}

#[test]
fn limits_hold_over_serial() {
    let tally = Tally::default();
    let config = ProptestConfig {
        cases: cases(300) / 30,
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    proptest!(config, |(ops in prop::collection::vec(op(), 1..20))| {
        tally.add(run(&ops)?);
    });
    tally.report("limits over serial");
}

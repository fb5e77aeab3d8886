//! Homing and limits over the serial protocol: the simulated board (a
//! real-time hub with the demo switches on every axis) and the host
//! backend give what the local hub gives, to the step.
#![cfg(all(unix, feature = "std"))]

use std::time::{Duration, Instant};

use cogstep_test_support::status::is_done;
use driver::serial::host::{SerialBoard, SerialConfig};
use driver::serial::sim::{BoardSim, SimConfig};
use driver::switch::DemoSwitches;
use driver::{AxisContract, AxisError, ClockMode, Direction, Hub, HubConfig, LimitStatus};

const PATIENCE: Duration = Duration::from_secs(30);

fn board() -> (BoardSim, SerialBoard) {
    let (sim, path) = BoardSim::spawn_pty(SimConfig::default()).expect("a pseudo-terminal");
    let board = SerialBoard::open(SerialConfig {
        poll_interval: Duration::from_millis(20),
        timeout: Duration::from_secs(2),
        ..SerialConfig::new(path)
    })
    .expect("the simulated board answers");
    (sim, board)
}

/// Waits until the axis is idle and its homing (if any) has ended.
fn settle(axis: &impl AxisContract) -> LimitStatus {
    let start = Instant::now();
    loop {
        let status = axis.status().unwrap();
        if is_done(&status) {
            let limits = axis.limit_status().unwrap();
            if !limits.homing {
                return limits;
            }
        }
        assert!(
            start.elapsed() < PATIENCE,
            "the axis never settled: {status:?}"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The same homing on a local virtual-time hub with the same switches.
fn local_homing(index: usize) -> LimitStatus {
    let hub = Hub::new(HubConfig::default()).unwrap();
    let base = u8::try_from(index * 3).unwrap();
    let axis = if index.is_multiple_of(2) {
        hub.start_sd(base, base + 1, base + 2).unwrap()
    } else {
        hub.start_cc(base, base + 1, base + 2).unwrap()
    };
    hub.set_input(base, true).unwrap();
    let switches = hub.fit_demo_switches(&axis, index).unwrap();
    axis.home(switches.home_config()).unwrap();
    hub.run_until_idle();
    assert_eq!(hub.config().clock, ClockMode::Virtual);
    axis.limit_status()
}

#[test]
fn homing_over_serial_matches_the_local_hub() {
    let (sim, board) = board();
    for index in [0, 1] {
        let axis = board.axis(index).unwrap();
        let switches = DemoSwitches::for_axis(index).unwrap();
        axis.home(switches.home_config()).unwrap();
        let remote = settle(&axis);
        let report = remote.home_outcome.unwrap().unwrap();
        assert_eq!(report.latch_physical, switches.home_at);
        assert_eq!(remote, local_homing(index), "axis {index}");
        assert_eq!(axis.status().unwrap().position, report.position);
    }
    board.close();
    sim.stop();
}

#[test]
fn limits_over_serial() {
    let (sim, board) = board();
    let axis = board.axis(1).unwrap();
    let switches = DemoSwitches::for_axis(1).unwrap();
    // Into the min limit: it trips at its switch point and stops.
    axis.move_steps(10_000, -20_000).unwrap();
    let limits = settle(&axis);
    let trip = limits.trip.expect("tripped");
    assert_eq!(
        (trip.side, trip.physical),
        (Direction::Reverse, switches.min_at)
    );
    assert_eq!(
        axis.status().unwrap().position,
        switches.min_at - i64::try_from(trip.stopping_steps).unwrap()
    );
    assert_eq!(
        limits.limit_pins,
        [
            Some((switches.min_pin, true)),
            Some((switches.max_pin, true))
        ]
    );
    assert_eq!(
        axis.move_steps(1_000, -5),
        Err(AxisError::IntoLimit(Direction::Reverse))
    );
    axis.clear_limit_fault().unwrap();
    axis.move_steps(10_000, 5_000).unwrap();
    let limits = settle(&axis);
    assert_eq!(limits.trip, None);
    // Soft limits: refused at the call.
    let here = axis.status().unwrap().position;
    axis.set_soft_limits(here - 100, here + 100).unwrap();
    assert_eq!(axis.move_steps(1_000, 101), Err(AxisError::BeyondSoftLimit));
    assert_eq!(
        axis.limit_status().unwrap().soft_limits,
        Some((here - 100, here + 100))
    );
    axis.move_steps(1_000, 100).unwrap();
    settle(&axis);
    axis.clear_soft_limits().unwrap();
    assert_eq!(axis.limit_status().unwrap().soft_limits, None);
    // Homing while moving is refused.
    axis.move_steps(1_000, 1_000).unwrap();
    assert_eq!(axis.home(switches.home_config()), Err(AxisError::NotIdle));
    board.close();
    sim.stop();
}

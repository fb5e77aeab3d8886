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

/// A group move over serial (`G`) stops at a member's hard limit as a
/// single move does, every member on the line (it ran axis 0 through the
/// demo's limit at −6,000 before limits held in group moves).
#[test]
fn a_group_move_over_serial_stops_at_a_members_limit() {
    let (sim, board) = board();
    let x = board.axis(0).unwrap();
    let y = board.axis(1).unwrap();
    let switches = DemoSwitches::for_axis(0).unwrap();
    board.move_together(&[-10_000, 5_000], 10_000).unwrap();
    settle(&x);
    settle(&y);
    let limits = x.limit_status().unwrap();
    let trip = limits.trip.expect("axis 0 tripped at its min limit");
    assert_eq!(
        (trip.side, trip.physical),
        (Direction::Reverse, switches.min_at)
    );
    let x_at = x.status().unwrap().position;
    assert!(
        x_at > -10_000 && x_at <= switches.min_at,
        "axis 0 at {x_at}"
    );
    let y_at = y.status().unwrap().position;
    let line = -x_at as f64 * 5_000.0 / 10_000.0;
    // Real clock: a member whose cog had run past the trip's CT stops
    // from its next lead edge (docs/coordinated.md), a batch at most.
    assert!(
        (y_at as f64 - line).abs() <= 50.0,
        "axis 1 at {y_at}, the line at {line}"
    );
    // Towards the tripped limit no group runs.
    assert_eq!(
        board.move_together(&[-100, 100], 10_000),
        Err(AxisError::IntoLimit(Direction::Reverse))
    );
    board.close();
    sim.stop();
}

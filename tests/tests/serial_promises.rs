//! The promise over the wire: random command sequences sent to the board
//! simulator through a real pseudo-terminal. Every `ok` is carried out (the
//! final positions are the sum of the accepted moves), and every refusal is
//! an error at the call that changes nothing.

use std::time::{Duration, Instant};

use cogstep_test_support::status::is_done;
use driver::serial::host::{SerialBoard, SerialConfig};
use driver::serial::sim::{BoardSim, SimConfig};
use driver::{AxisContract, AxisError};
use proptest::prelude::*;

#[derive(Clone, Debug)]
enum Op {
    /// A move on an axis; axis 0 only goes forward and axis 1 only back, so
    /// that no reversal cuts a move short (that is the stop's business).
    Move { axis: usize, speed: u32, steps: u32 },
    /// Bad input: must be refused and change nothing.
    Bad { axis: usize, speed: u32, steps: i32 },
    /// Set the position, after waiting for the axis to be idle.
    SetPosition { axis: usize, position: i64 },
    /// Let time pass.
    Pause { ms: u64 },
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        5 => (0usize..2, 5_000u32..40_000, 1u32..300)
            .prop_map(|(axis, speed, steps)| Op::Move { axis, speed, steps }),
        2 => (0usize..2, prop_oneof![Just(0u32), Just(1_000_000_000)], prop_oneof![Just(0i32), Just(i32::MIN), Just(10)])
            .prop_map(|(axis, speed, steps)| Op::Bad { axis, speed, steps }),
        1 => (0usize..2, -1_000i64..1_000).prop_map(|(axis, position)| Op::SetPosition { axis, position }),
        2 => (0u64..30).prop_map(|ms| Op::Pause { ms }),
    ]
}

fn wait_idle(axis: &dyn AxisContract) {
    let start = Instant::now();
    loop {
        let status = axis.status().expect("status");
        if is_done(&status) {
            return;
        }
        assert!(start.elapsed() < Duration::from_secs(20), "never idle");
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn run(ops: &[Op]) -> Result<(), TestCaseError> {
    let (sim, path) = BoardSim::spawn_pty(SimConfig {
        axes: 2,
        ..SimConfig::default()
    })
    .expect("sim");
    let board = SerialBoard::open(SerialConfig::new(path)).expect("board");
    let axes = [
        board.axis(0).expect("axis 0"),
        board.axis(1).expect("axis 1"),
    ];
    let mut expected = [0i64; 2];
    for op in ops {
        match *op {
            Op::Move { axis, speed, steps } => {
                let signed = if axis == 0 {
                    steps as i32
                } else {
                    -(steps as i32)
                };
                match axes[axis].move_steps(speed, signed) {
                    Ok(()) => expected[axis] += i64::from(signed),
                    // A refusal is a typed error at the call.
                    Err(AxisError::Busy) => {}
                    Err(other) => return Err(TestCaseError::fail(format!("{op:?}: {other}"))),
                }
            }
            Op::Bad { axis, speed, steps } => {
                wait_idle(&axes[axis]);
                let before = axes[axis].status().expect("status");
                let result = axes[axis].move_steps(speed, steps);
                if speed == 0 || steps == 0 || steps == i32::MIN || speed == 1_000_000_000 {
                    prop_assert!(result.is_err(), "{:?} was taken", op);
                }
                if result.is_ok() {
                    expected[axis] += i64::from(steps);
                } else {
                    prop_assert_eq!(axes[axis].status().expect("status"), before);
                }
            }
            Op::SetPosition { axis, position } => {
                wait_idle(&axes[axis]);
                axes[axis].set_position(position).expect("set position");
                expected[axis] = position;
            }
            Op::Pause { ms } => std::thread::sleep(Duration::from_millis(ms)),
        }
    }
    for (axis, expected) in axes.iter().zip(expected) {
        wait_idle(axis);
        prop_assert_eq!(axis.status().expect("status").position, expected);
    }
    board.close();
    sim.stop();
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 8, max_shrink_iters: 16, ..ProptestConfig::default() })]

    #[test]
    fn every_ok_over_the_wire_is_carried_out(ops in prop::collection::vec(op(), 1..14)) {
        run(&ops)?;
    }
}

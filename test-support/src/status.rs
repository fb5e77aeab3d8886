//! Polling an axis, through the contract every backend shares, until its
//! status says what a test waits for.

use std::time::{Duration, Instant};

use cogstep_motion::axis::{AxisContract, AxisStatus, Mode};

/// The move is over: nothing left to make and not moving.
pub fn is_done(status: &AxisStatus) -> bool {
    status.steps_to_go == 0 && !status.mode.has(Mode::MOVING)
}

/// Polls `axis` until `done` holds, letting time pass with `pause` (a sleep
/// on a board, an advance of the virtual clock on a hub); a status that
/// fails to read is polled again. Fails with the last status after
/// `patience`.
pub fn wait_in(
    axis: &(impl AxisContract + ?Sized),
    patience: Duration,
    what: &str,
    pause: &dyn Fn(),
    done: impl Fn(&AxisStatus) -> bool,
) -> AxisStatus {
    let start = Instant::now();
    let mut last = None;
    while start.elapsed() < patience {
        if let Ok(status) = axis.status() {
            if done(&status) {
                return status;
            }
            last = Some(status);
        }
        pause();
    }
    panic!("waited {patience:?} for {what}; last status {last:?}");
}

/// [`wait_in`] real time, polling every 5 ms.
pub fn wait_until(
    axis: &(impl AxisContract + ?Sized),
    patience: Duration,
    what: &str,
    done: impl Fn(&AxisStatus) -> bool,
) -> AxisStatus {
    let pause = || std::thread::sleep(Duration::from_millis(5));
    wait_in(axis, patience, what, &pause, done)
}

/// Waits until the move is done at `target` and returns the final status.
pub fn finish(axis: &(impl AxisContract + ?Sized), patience: Duration, target: i64) -> AxisStatus {
    wait_until(axis, patience, &format!("position {target}"), |status| {
        is_done(status) && status.position == target
    })
}

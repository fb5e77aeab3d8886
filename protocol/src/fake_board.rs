//! A fake board for the protocol tests: it records every request its axes
//! accept, and refuses on demand.

extern crate std;
use std::cell::{Cell, RefCell};
use std::rc::Rc;
use std::string::String;
use std::vec::Vec;

use super::{Board, Session};
use cogstep_motion::axis::{AxisContract, AxisError, AxisStatus, Direction, Mode};

/// One accepted request. Refused requests are not recorded: they change
/// nothing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Call {
    Move {
        axis: usize,
        speed: u32,
        steps: i32,
    },
    Jog {
        axis: usize,
        speed: u32,
        direction: Direction,
    },
    JogRelease {
        axis: usize,
    },
    StopPin {
        axis: usize,
        high: bool,
    },
    EmergencyStop {
        axis: usize,
    },
    SetPosition {
        axis: usize,
        position: i64,
    },
}

pub struct FakeAxis {
    index: usize,
    log: Rc<RefCell<Vec<Call>>>,
    status: Cell<AxisStatus>,
    /// While set, every request but `status` is refused with this error.
    pub refusal: Cell<Option<AxisError>>,
    /// While set, `status` fails with this error.
    pub status_failure: Cell<Option<AxisError>>,
}

impl FakeAxis {
    fn accept(&self, call: Call) -> Result<(), AxisError> {
        if let Some(error) = self.refusal.get() {
            return Err(error);
        }
        self.log.borrow_mut().push(call);
        Ok(())
    }

    fn update(&self, change: impl FnOnce(&mut AxisStatus)) {
        let mut status = self.status.get();
        change(&mut status);
        self.status.set(status);
    }

    pub fn set_status(&self, status: AxisStatus) {
        self.status.set(status);
    }
}

impl AxisContract for FakeAxis {
    fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        self.accept(Call::Move {
            axis: self.index,
            speed,
            steps,
        })?;
        self.update(|status| {
            status.mode = Mode::MOVING
                | Mode::ACCEL
                | if steps < 0 {
                    Mode::REVERSE
                } else {
                    Mode::empty()
                };
            status.steps_to_go = status
                .steps_to_go
                .saturating_add(u64::from(steps.unsigned_abs()));
        });
        Ok(())
    }

    fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError> {
        self.accept(Call::Jog {
            axis: self.index,
            speed,
            direction,
        })?;
        self.update(|status| status.mode = Mode::MOVING | Mode::JOG);
        Ok(())
    }

    fn jog_release(&self) -> Result<(), AxisError> {
        self.accept(Call::JogRelease { axis: self.index })
    }

    fn set_stop_pin(&self, high: bool) -> Result<(), AxisError> {
        self.accept(Call::StopPin {
            axis: self.index,
            high,
        })?;
        self.update(|status| status.stop_pin_high = high);
        Ok(())
    }

    fn emergency_stop(&self) -> Result<(), AxisError> {
        self.accept(Call::EmergencyStop { axis: self.index })?;
        self.update(|status| {
            status.mode = Mode::ESTOP;
            status.steps_to_go = 0;
            status.velocity_steps_per_s = 0;
        });
        Ok(())
    }

    fn set_position(&self, position: i64) -> Result<(), AxisError> {
        // A real axis refuses this while moving; so does the fake.
        if self.status.get().mode.has(Mode::MOVING) && self.refusal.get().is_none() {
            return Err(AxisError::NotIdle);
        }
        self.accept(Call::SetPosition {
            axis: self.index,
            position,
        })?;
        self.update(|status| status.position = position);
        Ok(())
    }

    fn status(&self) -> Result<AxisStatus, AxisError> {
        match self.status_failure.get() {
            Some(error) => Err(error),
            None => Ok(self.status.get()),
        }
    }
}

pub struct FakeBoard {
    pub axes: Vec<FakeAxis>,
    pub log: Rc<RefCell<Vec<Call>>>,
    /// What `I` reports as the firmware version; `None` for the default.
    pub version: Option<&'static str>,
}

pub const IDLE: AxisStatus = AxisStatus {
    position: 0,
    stm: 0,
    steps_to_go: 0,
    mode: Mode(0),
    velocity_steps_per_s: 0,
    stop_pin_high: true,
};

impl FakeBoard {
    pub fn new(axis_count: usize) -> Self {
        let log = Rc::new(RefCell::new(Vec::new()));
        let axes = (0..axis_count)
            .map(|index| FakeAxis {
                index,
                log: Rc::clone(&log),
                status: Cell::new(IDLE),
                refusal: Cell::new(None),
                status_failure: Cell::new(None),
            })
            .collect();
        FakeBoard {
            axes,
            log,
            version: None,
        }
    }

    pub fn calls(&self) -> Vec<Call> {
        self.log.borrow().clone()
    }

    pub fn call_count(&self) -> usize {
        self.log.borrow().len()
    }

    /// Every axis back to idle with the stop pin high.
    pub fn reset(&self) {
        for axis in &self.axes {
            axis.status.set(IDLE);
        }
    }
}

impl Board for FakeBoard {
    fn axis_count(&self) -> usize {
        self.axes.len()
    }

    fn axis(&self, index: usize) -> Option<&dyn AxisContract> {
        self.axes.get(index).map(|axis| axis as &dyn AxisContract)
    }

    fn clkfreq_hz(&self) -> u32 {
        200_000_000
    }

    fn firmware_version(&self) -> &str {
        self.version.unwrap_or(env!("CARGO_PKG_VERSION"))
    }
}

/// Feeds `bytes` to the session; returns everything the board wrote.
pub fn send(session: &mut Session, board: &FakeBoard, bytes: &[u8]) -> String {
    let mut out = String::new();
    for &byte in bytes {
        session
            .feed(byte, board, &mut out)
            .expect("a String never refuses");
    }
    out
}

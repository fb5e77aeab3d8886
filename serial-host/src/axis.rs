//! One axis of a board: [`SerialAxis`], the [`AxisContract`] over the
//! serial link.

use std::fmt;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use cogstep_motion::axis::LimitStatus;
use cogstep_motion::axis::{AxisContract, AxisError, AxisStatus, Direction, HomeConfig};
use cogstep_motion::profile::PlanError;
use cogstep_protocol::p2demo::check_demo_move;
use cogstep_protocol::{Command, Dialect, Target};

use super::handle::Handle;
use super::request::Op;
use super::state::Link;
use super::{Capabilities, FAULT_DISCONNECTED, P2DEMO_UNSUPPORTED};

/// One axis of a [`SerialBoard`](crate::SerialBoard): an [`AxisContract`].
/// Cheap to clone.
#[derive(Clone)]
pub struct SerialAxis {
    pub(crate) handle: Arc<Handle>,
    pub(crate) index: usize,
}

impl fmt::Debug for SerialAxis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SerialAxis")
            .field("port", &self.handle.shared.config.port)
            .field("index", &self.index)
            .finish()
    }
}

impl SerialAxis {
    /// The axis number on the board.
    pub fn index(&self) -> usize {
        self.index
    }

    /// What the board lets the host do with this axis.
    pub fn capabilities(&self) -> Capabilities {
        self.handle.shared.capabilities()
    }

    /// The axis's latched fault, if any (see
    /// [`FAULT_LOST_MID_MOVE`](crate::FAULT_LOST_MID_MOVE)).
    pub fn fault(&self) -> Option<&'static str> {
        self.handle
            .shared
            .state()
            .axes
            .get(self.index)
            .and_then(|axis| axis.latched)
    }

    fn is_p2demo(&self) -> bool {
        self.handle.shared.config.dialect == Dialect::P2Demo
    }

    fn command(&self, command: Command) -> Result<(), AxisError> {
        if self.is_p2demo() {
            return Err(AxisError::Unsupported(P2DEMO_UNSUPPORTED));
        }
        self.handle.call(Op::Command {
            axis: Some(self.index),
            command,
        })
    }
}

/// Moves and jogs check speed and steps as the hub does
/// (`StepsOutOfRange`, `ZeroSpeed`, `ZeroSteps`, in that order) before
/// anything is sent. A board's refusal comes back as exactly the
/// `AxisError` its axis gave: every refusal has its own reply line, read
/// back with the protocol's refusal table (`cogstep_protocol::refusal_of_error`,
/// listed in docs/protocol.md), the numbers of `PulseTooLong` and
/// `Plan(SpeedTooHigh)` included. Any other reply is:
///
/// | reply | `AxisError` |
/// |---|---|
/// | `error:1` | `Unsupported` |
/// | `error:2 fault: ...` | `Fault("the board reported an axis fault")` |
/// | `error:2` (any other text) | `Fault("the board refused an argument")` |
/// | `error:4` | `Unavailable` |
/// | `error:5` | `Fault("the board found the line too long")` |
/// | `error:6` (any other text) | `Fault("the board refused the speed")` |
/// | `error:3`, `7`, `9`, `10` with a text that is no refusal's | `Fault("the board gave a refusal this host does not know")` |
/// | `error:8` | the line is sent once more; a second `error:8` is `Fault("line noise")` |
/// | any other code | `Fault("the board sent an unknown error code")` |
///
/// `emergency_stop` stops the whole board (the protocol's `E` has no
/// axis). `jog_release` sends `S <axis>` and, once the axis reports that it
/// has stopped, `R <axis>` (protocol version 1 has no release; a
/// `set_stop_pin` in between cancels the `R`).
impl AxisContract for SerialAxis {
    fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        check_move(speed, steps)?;
        if self.is_p2demo() {
            // Refused before a byte is sent: the real board would botch it.
            check_demo_move(speed, steps).map_err(|flaw| AxisError::Unsupported(flaw.reason()))?;
            return self.handle.call(Op::DemoMove { speed, steps });
        }
        self.command(Command::Move {
            axis: self.index,
            speed_steps_per_s: speed,
            steps,
        })
    }

    fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError> {
        if self.is_p2demo() {
            return Err(AxisError::Unsupported(P2DEMO_UNSUPPORTED));
        }
        check_move(speed, 1)?;
        self.command(Command::Jog {
            axis: self.index,
            speed_steps_per_s: speed,
            direction,
        })
    }

    fn jog_release(&self) -> Result<(), AxisError> {
        if self.is_p2demo() {
            return Err(AxisError::Unsupported(P2DEMO_UNSUPPORTED));
        }
        self.handle.call(Op::JogRelease(self.index))
    }

    fn set_stop_pin(&self, high: bool) -> Result<(), AxisError> {
        let target = Target::Axis(self.index);
        self.command(if high {
            Command::Run(target)
        } else {
            Command::Stop(target)
        })
    }

    fn emergency_stop(&self) -> Result<(), AxisError> {
        if self.is_p2demo() {
            return Err(AxisError::Unsupported(P2DEMO_UNSUPPORTED));
        }
        self.handle.emergency_stop()
    }

    fn set_position(&self, position: i64) -> Result<(), AxisError> {
        self.command(Command::SetPosition {
            axis: self.index,
            position,
        })
    }

    fn home(&self, config: HomeConfig) -> Result<(), AxisError> {
        self.command(Command::Home {
            axis: self.index,
            config,
        })
    }

    fn set_soft_limits(&self, min: i64, max: i64) -> Result<(), AxisError> {
        self.command(Command::SoftLimits {
            axis: self.index,
            limits: Some((min, max)),
        })
    }

    fn clear_soft_limits(&self) -> Result<(), AxisError> {
        self.command(Command::SoftLimits {
            axis: self.index,
            limits: None,
        })
    }

    fn set_limit_pins(
        &self,
        min: Option<(u8, bool)>,
        max: Option<(u8, bool)>,
    ) -> Result<(), AxisError> {
        self.command(Command::LimitPins {
            axis: self.index,
            min,
            max,
        })
    }

    fn clear_limit_fault(&self) -> Result<(), AxisError> {
        self.command(Command::ClearLimitFault(self.index))
    }

    /// `L <axis>`: the board's `[limits ...]` line.
    fn limit_status(&self) -> Result<LimitStatus, AxisError> {
        self.command(Command::Limits(self.index))?;
        self.handle
            .shared
            .state()
            .axes
            .get(self.index)
            .and_then(|axis| axis.limits)
            .ok_or(AxisError::Fault("the board sent no limits line"))
    }

    fn status(&self) -> Result<AxisStatus, AxisError> {
        let shared = &self.handle.shared;
        if shared.closing.load(Ordering::Acquire) {
            return Err(AxisError::Unavailable);
        }
        let state = shared.state();
        let axis = state.axes.get(self.index).ok_or(AxisError::Unavailable)?;
        if state.link != Link::Up {
            return Err(AxisError::Fault(FAULT_DISCONNECTED));
        }
        match axis.latched {
            Some(what) => Err(AxisError::Fault(what)),
            None => Ok(axis.status),
        }
    }
}

/// The refusals the hub gives before planning, in its order (the v1 line
/// cannot carry i32::MIN steps, 0 steps or speed 0 to the axis).
pub(crate) fn check_move(speed: u32, steps: i32) -> Result<(), AxisError> {
    if steps == i32::MIN {
        return Err(AxisError::StepsOutOfRange);
    }
    if speed == 0 {
        return Err(PlanError::ZeroSpeed.into());
    }
    if steps == 0 {
        return Err(PlanError::ZeroSteps.into());
    }
    Ok(())
}

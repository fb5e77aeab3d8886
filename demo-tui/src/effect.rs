//! The app's effects on the backend, and what comes back: the only app
//! code that calls a [`Machine`].
//!
//! The update ([`crate::app`]) never touches the backend. A key gives a
//! list of [`Effect`]s; the app thread ([`crate::event_loop`]) ends the
//! demo on [`Effect::Quit`] and hands every [`Command`] to [`run`], which
//! makes the backend calls (they may block on a slow board) and says what
//! came of them as an [`Outcome`], fed back to [`crate::app::App::on_outcome`]:
//!
//! ```text
//! key ─► App::on_key ─► [Effect] ─► run(Command, Machine) ─► Outcome ─► App::on_outcome
//! frame tick ─► read_frame(Machine) ─► FrameReading ─► App::on_frame
//! ```
//!
//! The checks that need nothing but the app's own state (the prompt's
//! answers, what the backend says it can do) stay in the update; what
//! needs the backend (its move check, an axis's stop pin, its home switch)
//! is done here, in the order the backend needs it.

use driver::{AxisContract, AxisStatus, Direction, Edge, HomeConfig, LimitStatus};

use crate::backend::{Machine, MoveFigures};

/// What the update asks for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Effect {
    /// A command to the backend, run by [`run`].
    Send(Command),
    /// End the demo (`q`, Ctrl-C).
    Quit,
}

/// One thing to do to the backend. Axes are by index, from 0.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command {
    /// `move(speed, steps)` on one axis: the backend's check first, and a
    /// stop pin the stop key left low raised again.
    Move {
        /// The axis.
        axis: usize,
        /// Steps, signed.
        steps: i32,
        /// Speed, steps/s.
        speed: u32,
    },
    /// `g`: a coordinated move of axes 0 to `steps.len() − 1`
    /// ([`Machine::move_together`]), their low stop pins raised first.
    MoveTogether {
        /// Steps per axis, signed, axis 0 first.
        steps: Vec<i32>,
        /// Speed of the longest, steps/s.
        speed: u32,
    },
    /// `s`: the axis's stop pin low (a controlled deceleration).
    Stop {
        /// The axis.
        axis: usize,
    },
    /// `x`: emergency stop of every axis.
    EmergencyStop,
    /// A jog heartbeat (a jog key pressed or repeating): starts or
    /// continues a jog, a low stop pin raised first.
    JogBeat {
        /// The axis.
        axis: usize,
        /// Which way.
        direction: Direction,
        /// Speed, steps/s.
        speed: u32,
    },
    /// The jog key released: the jog decelerates now.
    JogRelease {
        /// The axis.
        axis: usize,
    },
    /// `h`: home the axis on its home switch, a low stop pin raised first.
    Home {
        /// The axis.
        axis: usize,
    },
    /// `c`: clear the axis's tripped hard limit.
    ClearLimit {
        /// The axis.
        axis: usize,
    },
}

/// What running a [`Command`] came to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outcome {
    /// The command run.
    pub command: Command,
    /// Taken, or why not.
    pub result: Result<Done, Refusal>,
}

/// A command taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Done {
    /// Sent and taken.
    Sent {
        /// Whether a low stop pin (any, for a group) was raised first.
        stop_pin_raised: bool,
    },
    /// [`Command::Home`] taken: homing runs with this configuration.
    Homing(HomeConfig),
}

/// A command not taken. Nothing after the step that refused was sent.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The backend has no such axis: nothing was sent.
    NoSuchAxis,
    /// The backend has no home switch for the axis: nothing was sent.
    NoHomeSwitch,
    /// The backend's check: no such move can be planned. Nothing was sent.
    Unplannable(String),
    /// A low stop pin could not be raised first.
    StopPin {
        /// The axis whose pin it was.
        axis: usize,
        /// Why.
        reason: String,
    },
    /// The axis or the backend refused the command itself.
    Refused(String),
}

/// Runs one command against the backend (this may block on a slow board).
pub fn run(command: Command, machine: &dyn Machine) -> Outcome {
    let result = match &command {
        Command::Move { axis, steps, speed } => send_move(machine, *axis, *steps, *speed),
        Command::MoveTogether { steps, speed } => send_group(machine, steps, *speed),
        Command::Stop { axis } => with_axis(machine, *axis, |axis| axis.set_stop_pin(false)),
        Command::EmergencyStop => machine
            .emergency_stop_all()
            .map(|()| Done::Sent {
                stop_pin_raised: false,
            })
            .map_err(|e| Refusal::Refused(e.to_string())),
        Command::JogBeat {
            axis,
            direction,
            speed,
        } => with_raised_pin(machine, *axis, |handle| handle.jog(*speed, *direction)),
        // The axis gone, there is nothing left to release.
        Command::JogRelease { axis } => match machine.axis(*axis) {
            Some(handle) => handle
                .jog_release()
                .map(|()| Done::Sent {
                    stop_pin_raised: false,
                })
                .map_err(|e| Refusal::Refused(e.to_string())),
            None => Ok(Done::Sent {
                stop_pin_raised: false,
            }),
        },
        Command::Home { axis } => home(machine, *axis),
        Command::ClearLimit { axis } => {
            with_axis(machine, *axis, |handle| handle.clear_limit_fault())
        }
    };
    Outcome { command, result }
}

/// One call on one axis, which must exist.
fn with_axis(
    machine: &dyn Machine,
    axis: usize,
    call: impl FnOnce(&dyn AxisContract) -> Result<(), driver::AxisError>,
) -> Result<Done, Refusal> {
    let handle = machine.axis(axis).ok_or(Refusal::NoSuchAxis)?;
    call(handle)
        .map(|()| Done::Sent {
            stop_pin_raised: false,
        })
        .map_err(|e| Refusal::Refused(e.to_string()))
}

/// One call on one axis after raising its stop pin if it is low.
fn with_raised_pin(
    machine: &dyn Machine,
    axis: usize,
    call: impl FnOnce(&dyn AxisContract) -> Result<(), driver::AxisError>,
) -> Result<Done, Refusal> {
    let handle = machine.axis(axis).ok_or(Refusal::NoSuchAxis)?;
    let stop_pin_raised =
        raise_stop_pin(handle).map_err(|reason| Refusal::StopPin { axis, reason })?;
    call(handle)
        .map(|()| Done::Sent { stop_pin_raised })
        .map_err(|e| Refusal::Refused(e.to_string()))
}

fn send_move(machine: &dyn Machine, axis: usize, steps: i32, speed: u32) -> Result<Done, Refusal> {
    machine
        .check_move(speed, steps)
        .map_err(Refusal::Unplannable)?;
    let handle = machine.axis(axis).ok_or(Refusal::NoSuchAxis)?;
    // The stop key left the pin low: this move raises it again (where the
    // backend drives the stop pin at all).
    let stop_pin_raised = match machine.info().capabilities.stop_pin {
        Some(_) => false,
        None => raise_stop_pin(handle).map_err(|reason| Refusal::StopPin { axis, reason })?,
    };
    handle
        .move_steps(speed, steps)
        .map(|()| Done::Sent { stop_pin_raised })
        .map_err(|e| Refusal::Refused(e.to_string()))
}

fn send_group(machine: &dyn Machine, steps: &[i32], speed: u32) -> Result<Done, Refusal> {
    // The backend checks the longest member; the others follow its line.
    let lead = steps
        .iter()
        .copied()
        .max_by_key(|steps| steps.unsigned_abs())
        .unwrap_or(0);
    machine
        .check_move(speed, lead)
        .map_err(Refusal::Unplannable)?;
    let mut stop_pin_raised = false;
    if machine.info().capabilities.stop_pin.is_none() {
        // A stop key left a pin low: the group move raises it (every
        // member's pin must be high for the move to be taken).
        for axis in 0..steps.len() {
            let Some(handle) = machine.axis(axis) else {
                continue;
            };
            stop_pin_raised |=
                raise_stop_pin(handle).map_err(|reason| Refusal::StopPin { axis, reason })?;
        }
    }
    machine
        .move_together(steps, speed)
        .map(|()| Done::Sent { stop_pin_raised })
        .map_err(|e| Refusal::Refused(e.to_string()))
}

fn home(machine: &dyn Machine, axis: usize) -> Result<Done, Refusal> {
    let (Some(handle), Some(config)) = (machine.axis(axis), machine.home_config(axis)) else {
        return Err(Refusal::NoHomeSwitch);
    };
    raise_stop_pin(handle).map_err(|reason| Refusal::StopPin { axis, reason })?;
    handle
        .home(config)
        .map(|()| Done::Homing(config))
        .map_err(|e| Refusal::Refused(e.to_string()))
}

/// Raises an axis's stop pin if it is low; tells whether it was.
fn raise_stop_pin(axis: &dyn AxisContract) -> Result<bool, String> {
    let status = axis.status().map_err(|e| e.to_string())?;
    if status.stop_pin_high {
        return Ok(false);
    }
    axis.set_stop_pin(true)
        .map(|()| true)
        .map_err(|e| format!("could not raise the stop pin: {e}"))
}

/// What an axis showed at a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Readout {
    /// Position, STM, mode, velocity and stop pin.
    pub status: AxisStatus,
    /// The reference demo's move figures.
    pub figures: MoveFigures,
}

/// One axis's limit and homing state and its switches (home, min, max),
/// where the backend reads them.
pub type LimitReading = (Option<LimitStatus>, Option<[bool; 3]>);

/// Everything a frame reads from the backend.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FrameReading {
    /// Per axis: its readout, or why it could not be read.
    pub readouts: Vec<Result<Readout, String>>,
    /// The backend's fault, if any.
    pub fault: Option<String>,
    /// Per axis: its limits and switches.
    pub limits: Vec<LimitReading>,
    /// The pin edges since the last frame and the clock now (ticks), when
    /// asked for and recorded (`--motor`).
    pub edges: Option<(Vec<Edge>, u64)>,
}

/// Reads a frame of `axis_count` axes; takes the recorded pin edges only
/// when `with_edges` (taking them empties the backend's record).
pub fn read_frame(machine: &dyn Machine, axis_count: usize, with_edges: bool) -> FrameReading {
    let readouts = (0..axis_count)
        .map(|index| match machine.axis(index) {
            Some(axis) => axis
                .status()
                .map(|status| Readout {
                    status,
                    figures: machine.figures(index),
                })
                .map_err(|e| e.to_string()),
            None => Err("no such axis on this backend".to_string()),
        })
        .collect();
    let edges = if with_edges {
        machine.take_edges()
    } else {
        None
    };
    let fault = machine.fault();
    let limits = (0..axis_count)
        .map(|index| (machine.limit_status(index), machine.switches(index)))
        .collect();
    FrameReading {
        readouts,
        fault,
        limits,
        edges,
    }
}

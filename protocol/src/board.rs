//! The board: commands and realtime bytes carried out over its axes.
//!
//! [`Board`] is what a firmware (or the board simulator) implements: its
//! axes, each an [`AxisContract`], and the facts `I` reports. [`dispatch`]
//! runs one parsed command and writes its reply lines; [`realtime`] acts on
//! one realtime byte; [`Session`] does both for a raw byte stream.

use core::fmt;

use super::command::{parse_line_on, Command, Target};
use super::receiver::{Event, Realtime, Receiver};
use super::reply::{
    write_display_printable, write_printable, LimitLine, ProtocolError, StatusLine,
    BACKEND_TEXT_MAX, LINE_END,
};
use super::PROTOCOL_VERSION;
use cogstep_motion::axis::{AxisContract, AxisError};

/// A board's axes and identity, as the protocol needs them.
pub trait Board {
    /// How many axes the board has; they are numbered from 0.
    fn axis_count(&self) -> usize;

    /// Axis `index`, or `None` when there is no such axis.
    fn axis(&self, index: usize) -> Option<&dyn AxisContract>;

    /// The board's system clock, Hz (`clkfreq:` in the `I` reply).
    fn clkfreq_hz(&self) -> u32;

    /// The firmware version `I` reports; by default this crate's version.
    /// It should be one word of printable ASCII; at most 32 characters of
    /// it are sent.
    fn firmware_version(&self) -> &str {
        env!("CARGO_PKG_VERSION")
    }

    /// A coordinated move (`G`) of axes 0 to `steps.len() − 1` at `speed`
    /// (the lead's): all or nothing, every first edge on one CT (see
    /// `Hub::move_together`). By default not supported.
    fn move_together(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
        let _ = (steps, speed);
        Err(AxisError::Unsupported("group moves"))
    }

    /// Called after every command line and every realtime byte that acts
    /// (`!`, 0x18) has been carried out, before the reply is written: a
    /// board whose axes act on one another passes that on here (the
    /// firmware's group moves: a member's stop pin low stops the whole
    /// line). By default nothing.
    fn after_command(&self) {}

    /// Emergency stop of every axis (`E`, 0x18). By default each axis's
    /// [`emergency_stop`](AxisContract::emergency_stop), all of them even
    /// when one fails; the first failure is returned. A board with one
    /// hardware kill switch overrides this.
    fn emergency_stop_all(&self) -> Result<(), AxisError> {
        let mut first_error = Ok(());
        for index in 0..self.axis_count() {
            if let Some(axis) = self.axis(index) {
                let result = axis.emergency_stop();
                if first_error.is_ok() {
                    first_error = result;
                }
            }
        }
        first_error
    }
}

/// Carries out one command and writes its reply: any information lines,
/// then exactly one `ok` or `error:<code> <text>` line. An error from
/// `out` is returned after the command has been carried out.
pub fn dispatch<B, W>(board: &B, command: &Command, out: &mut W) -> fmt::Result
where
    B: Board + ?Sized,
    W: fmt::Write + ?Sized,
{
    let result = execute(board, command);
    board.after_command();
    match result {
        Ok(()) => {
            if *command == Command::Identify {
                write_identify(board, out)?;
            }
            if let Command::Limits(index) = *command {
                // `execute` read it once to check; the line shows a fresh read.
                match axis_of(board, index).and_then(|axis| Ok(axis.limit_status()?)) {
                    Ok(status) => LimitLine {
                        axis: index,
                        status,
                    }
                    .write_lines(out)?,
                    Err(error) => return error.write_reply(out),
                }
            }
            out.write_str("ok")?;
            out.write_str(LINE_END)
        }
        Err(error) => error.write_reply(out),
    }
}

/// Acts on one realtime byte. `?` writes one status line per axis (or an
/// information line for an axis whose status cannot be read); `!` and
/// 0x18 write nothing unless an axis refuses, which an information line
/// reports. None of them writes `ok`.
pub fn realtime<B, W>(board: &B, byte: Realtime, out: &mut W) -> fmt::Result
where
    B: Board + ?Sized,
    W: fmt::Write + ?Sized,
{
    match byte {
        Realtime::Status => {
            for index in 0..board.axis_count() {
                match axis_of(board, index).and_then(|axis| Ok(axis.status()?)) {
                    Ok(status) => write!(out, "{}{LINE_END}", StatusLine::new(index, &status))?,
                    Err(error) => write_info(out, "status", Some(index), &error)?,
                }
            }
            Ok(())
        }
        Realtime::Stop => {
            // Every axis is stopped even when a line cannot be written.
            let mut written = Ok(());
            for index in 0..board.axis_count() {
                let result = axis_of(board, index).and_then(|axis| stop_pin(axis, false));
                if let (Err(error), Ok(())) = (result, written) {
                    written = write_info(out, "stop", Some(index), &error);
                }
            }
            board.after_command();
            written
        }
        Realtime::EmergencyStop => {
            let result = board.emergency_stop_all();
            board.after_command();
            match result {
                Ok(()) => Ok(()),
                Err(error) => write_info(out, "emergency stop", None, &ProtocolError::Axis(error)),
            }
        }
    }
}

/// The board side of one serial connection: feed it every received byte.
#[derive(Clone, Debug, Default)]
pub struct Session {
    receiver: Receiver,
}

impl Session {
    /// A session with an empty line buffer.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one received byte; when it completes a line or is a realtime
    /// byte, acts on it and writes the reply lines to `out`.
    pub fn feed<B, W>(&mut self, byte: u8, board: &B, out: &mut W) -> fmt::Result
    where
        B: Board + ?Sized,
        W: fmt::Write + ?Sized,
    {
        match self.receiver.push(byte) {
            None => Ok(()),
            Some(Event::Realtime(realtime_byte)) => realtime(board, realtime_byte, out),
            Some(Event::Overlong) => ProtocolError::LineTooLong.write_reply(out),
            Some(Event::Line(line)) => match parse_line_on(line, board.axis_count()) {
                Ok(command) => dispatch(board, &command, out),
                Err(error) => error.write_reply(out),
            },
        }
    }

    /// The line buffer (for a firmware that wants to know whether a line is
    /// half typed).
    pub fn receiver(&self) -> &Receiver {
        &self.receiver
    }
}

fn execute<B: Board + ?Sized>(board: &B, command: &Command) -> Result<(), ProtocolError> {
    match *command {
        Command::Identify => Ok(()),
        Command::Move {
            axis,
            speed_steps_per_s,
            steps,
        } => Ok(axis_of(board, axis)?.move_steps(speed_steps_per_s, steps)?),
        Command::Jog {
            axis,
            speed_steps_per_s,
            direction,
        } => Ok(axis_of(board, axis)?.jog(speed_steps_per_s, direction)?),
        Command::Stop(target) => for_target(board, target, |axis| stop_pin(axis, false)),
        Command::Run(target) => for_target(board, target, |axis| stop_pin(axis, true)),
        Command::EmergencyStop => Ok(board.emergency_stop_all()?),
        Command::SetPosition { axis, position } => {
            Ok(axis_of(board, axis)?.set_position(position)?)
        }
        Command::GroupMove(group) => {
            let steps = group.steps();
            if steps.len() > board.axis_count() {
                return Err(ProtocolError::NoSuchAxis(board.axis_count()));
            }
            Ok(board.move_together(steps, group.speed_steps_per_s)?)
        }
        Command::Home { axis, config } => Ok(axis_of(board, axis)?.home(config)?),
        Command::SoftLimits { axis, limits } => {
            let axis = axis_of(board, axis)?;
            match limits {
                Some((min, max)) => axis.set_soft_limits(min, max)?,
                None => axis.clear_soft_limits()?,
            }
            Ok(())
        }
        Command::LimitPins { axis, min, max } => {
            Ok(axis_of(board, axis)?.set_limit_pins(min, max)?)
        }
        Command::ClearLimitFault(axis) => Ok(axis_of(board, axis)?.clear_limit_fault()?),
        Command::Limits(axis) => axis_of(board, axis)?
            .limit_status()
            .map(|_| ())
            .map_err(ProtocolError::from),
    }
}

fn axis_of<B: Board + ?Sized>(board: &B, index: usize) -> Result<&dyn AxisContract, ProtocolError> {
    if index >= board.axis_count() {
        return Err(ProtocolError::NoSuchAxis(index));
    }
    board.axis(index).ok_or(ProtocolError::NoSuchAxis(index))
}

fn stop_pin(axis: &dyn AxisContract, high: bool) -> Result<(), ProtocolError> {
    Ok(axis.set_stop_pin(high)?)
}

/// One axis, or every axis: all are tried even when one refuses (a stop
/// must reach every axis it can); the first refusal is the reply.
fn for_target<B, F>(board: &B, target: Target, mut action: F) -> Result<(), ProtocolError>
where
    B: Board + ?Sized,
    F: FnMut(&dyn AxisContract) -> Result<(), ProtocolError>,
{
    match target {
        Target::Axis(index) => action(axis_of(board, index)?),
        Target::All => {
            let mut first_error = Ok(());
            for index in 0..board.axis_count() {
                let result = axis_of(board, index).and_then(&mut action);
                if first_error.is_ok() {
                    first_error = result;
                }
            }
            first_error
        }
    }
}

/// The most characters of a firmware version `I` sends.
const VERSION_MAX: usize = 32;

/// `[cogstep <version> proto:1 axes:<n> clkfreq:<hz>]`
fn write_identify<B, W>(board: &B, out: &mut W) -> fmt::Result
where
    B: Board + ?Sized,
    W: fmt::Write + ?Sized,
{
    out.write_str("[cogstep ")?;
    write_printable(out, board.firmware_version(), VERSION_MAX)?;
    write!(
        out,
        " proto:{PROTOCOL_VERSION} axes:{} clkfreq:{}]{LINE_END}",
        board.axis_count(),
        board.clkfreq_hz()
    )
}

/// `[<what> failed: axis <n>: <error>]`, or without the axis.
fn write_info<W: fmt::Write + ?Sized>(
    out: &mut W,
    what: &str,
    axis: Option<usize>,
    error: &ProtocolError,
) -> fmt::Result {
    write!(out, "[{what} failed: ")?;
    if let Some(axis) = axis {
        write!(out, "axis {axis}: ")?;
    }
    write_display_printable(out, error, BACKEND_TEXT_MAX)?;
    write!(out, "]{LINE_END}")
}

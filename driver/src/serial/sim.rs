//! The board simulator: a real-time emulated [`Hub`] behind the serial
//! protocol, on a pseudo-terminal or a serial device (std only).
//!
//! [`BoardSim`] owns one thread that reads the port, feeds every byte to a
//! [`Session`] (cogstep) or a [`DemoSession`] (P2 demo) over the hub's
//! axes, and writes the replies. The `board-sim` binary is a thin main
//! over it; tests use it to talk to a board over a real pseudo-terminal:
//!
//! ```
//! use driver::serial::host::{SerialBoard, SerialConfig};
//! use driver::serial::sim::{BoardSim, SimConfig};
//!
//! let (sim, path) = BoardSim::spawn_pty(SimConfig::default())?;
//! let board = SerialBoard::open(SerialConfig::new(path))?;
//! assert_eq!(board.axis_count(), 4);
//! board.close();
//! sim.stop();
//! # Ok::<(), driver::serial::host::SerialError>(())
//! ```
//!
//! The simulated board:
//! - axis `i` uses pins `3i` (stop), `3i + 1` and `3i + 2`: step and
//!   direction (`sd`) on even axes, cw and ccw (`cc`) on odd ones;
//! - drives every stop pin high at start, so `M` runs; `S`, `R` and `!`
//!   drive them through [`Axis::set_stop_pin`](crate::Axis::set_stop_pin);
//! - answers a move only once its cog has taken it (at most a few
//!   milliseconds), so a status read right after `ok` shows the move;
//! - a cogstep board announces itself with its identity line when it
//!   starts and after [`BoardSim::reset`], as a firmware does on reset;
//!   a P2 demo board waits for a key, as the reference demo does.

use std::io::{self, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serialport::SerialPort;

use super::host::{Dialect, SerialError};
use super::p2demo::{DemoMotor, DemoScreen, DemoSession};
use super::{dispatch, Board, Command, Session};
use crate::axis::{AxisContract, AxisError, AxisStatus, Direction, Mode};
use crate::{Axis, ClockMode, Hub, HubConfig};

/// The most axes a simulated board has (one cog each, as on the P2).
pub const SIM_AXES_MAX: usize = 8;
/// How often a P2 demo board refreshes its display while a move runs.
pub const DISPLAY_INTERVAL: Duration = Duration::from_millis(50);
/// How long the board thread blocks in one read before it looks at its
/// stop and reset flags (and the P2 demo display).
const READ_SLICE: Duration = Duration::from_millis(10);
/// How long a reply may wait for a port that takes no bytes (nobody
/// reading); after it the reply is dropped.
const WRITE_TIMEOUT: Duration = Duration::from_millis(100);
/// The longest wait for a cog to take a command before the reply goes out.
const SETTLE_MAX: Duration = Duration::from_millis(20);

/// How to build a simulated board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimConfig {
    /// Axes, 1 to [`SIM_AXES_MAX`] (default 4). A P2 demo board drives one
    /// motor: it starts axis 0 only.
    pub axes: usize,
    /// The hub's clock, Hz (default 200 MHz).
    pub clkfreq: u32,
    /// What the board speaks (default cogstep).
    pub dialect: Dialect,
}

impl Default for SimConfig {
    fn default() -> Self {
        SimConfig {
            axes: 4,
            clkfreq: 200_000_000,
            dialect: Dialect::Cogstep,
        }
    }
}

/// A running board simulator. Stops with [`stop`](BoardSim::stop) or when
/// dropped.
pub struct BoardSim {
    control: Arc<Control>,
    thread: Option<JoinHandle<()>>,
    /// A pseudo-terminal's device end, held open so that the device stays
    /// usable while no host has it open.
    device_end: Option<Box<dyn SerialPort>>,
    path: Option<String>,
}

impl std::fmt::Debug for BoardSim {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BoardSim")
            .field("path", &self.path)
            .finish()
    }
}

/// Flags from the [`BoardSim`] handle to its thread.
#[derive(Default)]
struct Control {
    stop: AtomicBool,
    reset: AtomicBool,
}

impl BoardSim {
    /// Creates a pseudo-terminal pair and serves on its controlling end;
    /// returns the device path a host opens (the other end). Unix only.
    pub fn spawn_pty(config: SimConfig) -> Result<(BoardSim, String), SerialError> {
        let pty = open_pty()?;
        let mut sim = BoardSim::spawn_on(config, pty.board_end)?;
        sim.device_end = Some(pty.device_end);
        sim.path = Some(pty.path.clone());
        Ok((sim, pty.path))
    }

    /// Serves on a port that is already open (a serial device, or one end
    /// of a pseudo-terminal pair).
    pub fn spawn_on(
        config: SimConfig,
        mut port: Box<dyn SerialPort>,
    ) -> Result<BoardSim, SerialError> {
        let board = SimBoard::new(config)?;
        let name = port
            .name()
            .unwrap_or_else(|| "the board's port".to_string());
        let io_error = |source: serialport::Error| SerialError::Io {
            port: name.clone(),
            source: source.into(),
        };
        port.set_timeout(READ_SLICE).map_err(io_error)?;
        let mut writer = port.try_clone().map_err(io_error)?;
        writer.set_timeout(WRITE_TIMEOUT).map_err(io_error)?;
        // The start-up announcement; on a pseudo-terminal it waits in the
        // buffer, which a host clears when it opens the port.
        if config.dialect == Dialect::Cogstep {
            let _ = writer.write_all(announcement(&board).as_bytes());
        }
        let control = Arc::new(Control::default());
        let thread_control = Arc::clone(&control);
        let thread = std::thread::Builder::new()
            .name("board-sim".to_string())
            .spawn(move || serve(config, board, port, writer, &thread_control))
            .map_err(SerialError::Spawn)?;
        Ok(BoardSim {
            control,
            thread: Some(thread),
            device_end: None,
            path: None,
        })
    }

    /// Opens a serial device (`--port` of board-sim) and serves on it.
    pub fn spawn_on_device(
        config: SimConfig,
        path: &str,
        baud: u32,
    ) -> Result<BoardSim, SerialError> {
        let port = serialport::new(path, baud)
            .timeout(READ_SLICE)
            .open()
            .map_err(|source| SerialError::Open {
                port: path.to_string(),
                source,
            })?;
        let mut sim = BoardSim::spawn_on(config, port)?;
        sim.path = Some(path.to_string());
        Ok(sim)
    }

    /// The device path a host opens, when the simulator knows it.
    pub fn path(&self) -> Option<&str> {
        self.path.as_deref()
    }

    /// Simulates a board reset: every move is lost, positions restart at
    /// 0, stop pins go high, a half-typed line is forgotten, and a cogstep
    /// board announces itself again (a P2 demo board waits for a key).
    pub fn reset(&self) {
        self.control.reset.store(true, Ordering::Release);
    }

    /// Stops the board: the thread ends, the hub's cogs stop and the port
    /// closes (a host sees the device hang up).
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        self.control.stop.store(true, Ordering::Release);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
        self.device_end = None;
    }
}

impl Drop for BoardSim {
    fn drop(&mut self) {
        self.halt();
    }
}

/// A pseudo-terminal pair: the board's end, the device end, the device path.
struct Pty {
    board_end: Box<dyn SerialPort>,
    device_end: Box<dyn SerialPort>,
    path: String,
}

#[cfg(unix)]
fn open_pty() -> Result<Pty, SerialError> {
    let (board_end, device_end) =
        serialport::TTYPort::pair().map_err(|error| SerialError::Pty(error.to_string()))?;
    let path = device_end
        .name()
        .ok_or_else(|| SerialError::Pty("the pseudo-terminal has no device path".to_string()))?;
    Ok(Pty {
        board_end: Box::new(board_end),
        device_end: Box::new(device_end),
        path,
    })
}

#[cfg(not(unix))]
fn open_pty() -> Result<Pty, SerialError> {
    Err(SerialError::Pty(
        "pseudo-terminals need a Unix system; give a serial device instead".to_string(),
    ))
}

/// The identity line a cogstep board announces itself with (what `I`
/// writes before its `ok`).
fn announcement(board: &SimBoard) -> String {
    let mut reply = String::new();
    // Writing into a String cannot fail.
    let _ = dispatch(board, &Command::Identify, &mut reply);
    reply
        .split_inclusive('\n')
        .take_while(|line| line.starts_with('['))
        .collect()
}

/// The board thread.
fn serve(
    config: SimConfig,
    mut board: SimBoard,
    mut port: Box<dyn SerialPort>,
    mut writer: Box<dyn SerialPort>,
    control: &Control,
) {
    let mut session = Session::new();
    let mut demo = DemoSession::new();
    let mut replies = String::new();
    let mut bytes = [0u8; 512];
    let mut next_display = Instant::now();
    while !control.stop.load(Ordering::Acquire) {
        if control.reset.swap(false, Ordering::AcqRel) {
            // A new hub: the old cogs stop when it is dropped.
            if let Ok(fresh) = SimBoard::new(config) {
                board = fresh;
            }
            session = Session::new();
            demo = DemoSession::new();
            if config.dialect == Dialect::Cogstep {
                replies.push_str(&announcement(&board));
            }
        }
        match port.read(&mut bytes) {
            Ok(count) => {
                for &byte in &bytes[..count] {
                    // Writing into a String cannot fail.
                    let _ = match config.dialect {
                        Dialect::Cogstep => session.feed(byte, &board, &mut replies),
                        Dialect::P2Demo => demo.feed(byte, &mut board.demo_motor(), &mut replies),
                    };
                }
                if count == 0 {
                    // End of file: nobody on the other side; wait for one.
                    std::thread::sleep(READ_SLICE);
                }
            }
            Err(error)
                if matches!(
                    error.kind(),
                    io::ErrorKind::TimedOut
                        | io::ErrorKind::WouldBlock
                        | io::ErrorKind::Interrupted
                ) => {}
            // The device is gone or hung up: keep serving until stopped.
            Err(_) => std::thread::sleep(READ_SLICE),
        }
        if config.dialect == Dialect::P2Demo && Instant::now() >= next_display {
            next_display = Instant::now() + DISPLAY_INTERVAL;
            let _ = demo.poll(&mut board.demo_motor(), &mut replies);
        }
        if !replies.is_empty() {
            // Nobody reading: the reply is lost, as on a real UART.
            let _ = writer.write_all(replies.as_bytes());
            replies.clear();
        }
    }
}

/// The simulated board: a real-time hub and its axes.
struct SimBoard {
    /// Kept so the hub (and its cogs) live as long as the board.
    _hub: Hub,
    axes: Vec<SimAxis>,
    clkfreq: u32,
    demo: DemoState,
}

impl SimBoard {
    fn new(config: SimConfig) -> Result<Self, SerialError> {
        if config.axes == 0 || config.axes > SIM_AXES_MAX {
            return Err(SerialError::Config(format!(
                "axes must be 1 to {SIM_AXES_MAX}, not {}",
                config.axes
            )));
        }
        let hub = Hub::new(HubConfig {
            clkfreq: config.clkfreq,
            clock: ClockMode::Real,
            ..HubConfig::default()
        })?;
        let count = match config.dialect {
            Dialect::Cogstep => config.axes,
            Dialect::P2Demo => 1,
        };
        let mut axes = Vec::with_capacity(count);
        for index in 0..count {
            // At most 8 axes: pin numbers stay below 24.
            let base = u8::try_from(index * 3).unwrap_or(u8::MAX);
            let axis = if index % 2 == 0 {
                hub.start_sd(base, base + 1, base + 2)?
            } else {
                hub.start_cc(base, base + 1, base + 2)?
            };
            axis.set_stop_pin(true).map_err(|error| {
                SerialError::Config(format!("axis {index} would not start: {error}"))
            })?;
            axes.push(SimAxis(axis));
        }
        Ok(SimBoard {
            _hub: hub,
            axes,
            clkfreq: config.clkfreq,
            demo: DemoState::default(),
        })
    }

    fn demo_motor(&mut self) -> SimDemoMotor<'_> {
        SimDemoMotor {
            axis: self.axes.first(),
            state: &mut self.demo,
        }
    }
}

impl Board for SimBoard {
    fn axis_count(&self) -> usize {
        self.axes.len()
    }

    fn axis(&self, index: usize) -> Option<&dyn AxisContract> {
        self.axes.get(index).map(|axis| axis as &dyn AxisContract)
    }

    fn clkfreq_hz(&self) -> u32 {
        self.clkfreq
    }
}

/// A hub axis that answers a command only once its cog has taken it, so
/// that a status read right after the reply sees the command's effect (a
/// real-time cog takes a command within microseconds of its kick).
struct SimAxis(Axis);

/// What a taken command changes.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Snapshot {
    position: i64,
    steps_to_go: u64,
    mode: u32,
}

impl SimAxis {
    fn snapshot(&self) -> Snapshot {
        Snapshot {
            position: self.0.position(),
            steps_to_go: self.0.steps_to_go(),
            mode: self.0.mode().raw(),
        }
    }

    /// Waits (at most [`SETTLE_MAX`]) until `done` holds.
    fn settle(&self, done: impl Fn(&Self) -> bool) {
        let start = Instant::now();
        while !done(self) && start.elapsed() < SETTLE_MAX {
            std::thread::sleep(Duration::from_micros(50));
        }
    }
}

impl AxisContract for SimAxis {
    fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        let before = self.snapshot();
        self.0.move_steps(speed, steps)?;
        self.settle(|axis| axis.snapshot() != before);
        Ok(())
    }

    fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError> {
        let before = self.snapshot();
        self.0.jog(speed, direction)?;
        self.settle(|axis| axis.snapshot() != before || axis.0.mode().has(Mode::JOG));
        Ok(())
    }

    fn jog_release(&self) -> Result<(), AxisError> {
        self.0.jog_release()
    }

    fn set_stop_pin(&self, high: bool) -> Result<(), AxisError> {
        self.0.set_stop_pin(high)
    }

    fn emergency_stop(&self) -> Result<(), AxisError> {
        self.0.emergency_stop()?;
        self.settle(|axis| axis.0.mode().has(Mode::ESTOP));
        Ok(())
    }

    fn set_position(&self, position: i64) -> Result<(), AxisError> {
        self.0.set_position(position)?;
        self.settle(|axis| axis.0.position() == position);
        Ok(())
    }

    fn status(&self) -> Result<AxisStatus, AxisError> {
        AxisContract::status(&self.0)
    }
}

/// The P2 demo's own bookkeeping: the elapsed time of the current move.
#[derive(Default)]
struct DemoState {
    started: Option<Instant>,
    elapsed_ms: u32,
}

/// Axis 0 as the P2 demo's motor.
struct SimDemoMotor<'a> {
    axis: Option<&'a SimAxis>,
    state: &'a mut DemoState,
}

impl DemoMotor for SimDemoMotor<'_> {
    fn start_move(&mut self, speed: u32, steps: i32) -> Result<(), AxisError> {
        self.axis
            .ok_or(AxisError::Unavailable)?
            .move_steps(speed, steps)?;
        self.state.started = Some(Instant::now());
        self.state.elapsed_ms = 0;
        Ok(())
    }

    fn is_moving(&mut self) -> bool {
        let Some(axis) = self.axis else {
            return false;
        };
        let mode = axis.0.mode();
        let moving = axis.0.steps_to_go() != 0 || mode.has(Mode::MOVING) || mode.has(Mode::HOLD);
        if let Some(started) = self.state.started {
            self.state.elapsed_ms =
                u32::try_from(started.elapsed().as_millis()).unwrap_or(u32::MAX);
            if !moving {
                self.state.started = None;
            }
        }
        moving
    }

    fn screen(&mut self) -> DemoScreen {
        let Some(axis) = self.axis else {
            return DemoScreen::default();
        };
        let axis = &axis.0;
        let mut screen = DemoScreen {
            position: axis.position(),
            // bits() keeps 6 bits, so the cast is exact.
            mode_bits: axis.mode().bits() as u8,
            offset_deg: axis.offset(),
            accel_steps: axis.accel_steps(),
            slew_steps: axis.slew_steps(),
            max_velocity_steps_per_s: axis.top_velocity(),
            elapsed_ms: self.state.elapsed_ms,
        };
        if screen.offset_deg == 0 {
            // Before the first move the mailbox holds no offset yet.
            screen.offset_deg = HubConfig::default().offset_deg;
        }
        screen
    }
}

//! # cogstep-sim — the board simulator: a real-time emulated [`Hub`] behind
//! the serial protocol, on a pseudo-terminal or a serial device (std)
//!
//! [`BoardSim`] owns one thread that reads the port, feeds every byte to a
//! [`Session`] (cogstep) or a [`DemoSession`] (P2 demo) over the hub's
//! axes, and writes the replies. The `board-sim` binary is a thin main
//! over it; tests use it to talk to a board over a real pseudo-terminal:
//!
//! ```
//! use cogstep_serial_host::{SerialBoard, SerialConfig};
//! use cogstep_sim::{BoardSim, SimConfig};
//!
//! let (sim, path) = BoardSim::spawn_pty(SimConfig::default())?;
//! let board = SerialBoard::open(SerialConfig::new(path))?;
//! assert_eq!(board.axis_count(), 4);
//! board.close();
//! sim.stop();
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The simulated board:
//! - axis `i` uses pins `3i` (stop), `3i + 1` and `3i + 2`: step and
//!   direction (`sd`) on even axes, cw and ccw (`cc`) on odd ones;
//! - drives every stop pin high at start, so `M` runs; `S`, `R` and `!`
//!   drive them through [`Axis::set_stop_pin`](cogstep_hub::Axis::set_stop_pin);
//! - answers a command with the cog's own verdict, once the cog has
//!   applied it, so a status read right after `ok` shows the move;
//! - a grbl board ([`grbl`]) speaks grbl 1.1 to a G-code sender over
//!   three of the hub's axes (X, Y, Z), its `$` settings kept in a file
//!   when [`GrblOptions`] names one;
//! - a cogstep board announces itself with its identity line when it
//!   starts and after [`BoardSim::reset`], as a firmware does on reset;
//!   a P2 demo board waits for a key, as the reference demo does.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serialport::SerialPort;

use cogstep_hub::{Axis, ClockMode, Hub, HubConfig, HubError};
use cogstep_motion::axis::{AxisContract, AxisError, AxisStatus, Direction, HomeConfig};
use cogstep_motion::axis::{LimitStatus, Mode};
use cogstep_motion::profile::scurve::Arithmetic;
use cogstep_protocol::p2demo::{is_botched, CogLongs, DemoMotor, DemoPlan, DemoSession};
use cogstep_protocol::p2demo_cog::ReferenceCog;
use cogstep_protocol::{dispatch, Board, Command, Dialect, Session};

pub mod grbl;
pub use grbl::GrblOptions;

/// The most axes a simulated board has (one cog each, as on the P2).
pub const SIM_AXES_MAX: usize = 8;
/// How long the board thread blocks in one read before it looks at its
/// stop and reset flags (and the P2 demo display).
const READ_SLICE: Duration = Duration::from_millis(10);
/// How long one write waits for a port that takes no bytes (nobody
/// reading) before the board looks at its stop and reset flags again;
/// the bytes are kept and written later, never dropped.
const WRITE_SLICE: Duration = Duration::from_millis(10);

/// Why a simulated board could not start.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The device would not open.
    #[error("cannot open {port}: {source}")]
    Open {
        /// The device path.
        port: String,
        /// What the serial library said.
        #[source]
        source: serialport::Error,
    },
    /// Setting up the port failed.
    #[error("{port}: {source}")]
    Io {
        /// The device path.
        port: String,
        /// The I/O error.
        #[source]
        source: io::Error,
    },
    /// The settings cannot work.
    #[error("bad board simulator settings: {0}")]
    Config(String),
    /// The emulated hub would not start.
    #[error(transparent)]
    Hub(#[from] HubError),
    /// A pseudo-terminal could not be created.
    #[error("cannot create a pseudo-terminal: {0}")]
    Pty(String),
    /// The board's thread could not be started.
    #[error("cannot start a thread: {0}")]
    Spawn(#[source] io::Error),
}

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
    pub fn spawn_pty(config: SimConfig) -> Result<(BoardSim, String), SimError> {
        BoardSim::spawn_pty_with(config, GrblOptions::default())
    }

    /// [`spawn_pty`](BoardSim::spawn_pty) with a grbl board's options (its
    /// settings file); other dialects ignore them.
    pub fn spawn_pty_with(
        config: SimConfig,
        options: GrblOptions,
    ) -> Result<(BoardSim, String), SimError> {
        let pty = open_pty()?;
        let mut sim = BoardSim::spawn_on_with(config, options, pty.board_end)?;
        sim.device_end = Some(pty.device_end);
        sim.path = Some(pty.path.clone());
        Ok((sim, pty.path))
    }

    /// Serves on a port that is already open (a serial device, or one end
    /// of a pseudo-terminal pair).
    pub fn spawn_on(config: SimConfig, port: Box<dyn SerialPort>) -> Result<BoardSim, SimError> {
        BoardSim::spawn_on_with(config, GrblOptions::default(), port)
    }

    /// [`spawn_on`](BoardSim::spawn_on) with a grbl board's options.
    pub fn spawn_on_with(
        config: SimConfig,
        options: GrblOptions,
        mut port: Box<dyn SerialPort>,
    ) -> Result<BoardSim, SimError> {
        if config.dialect == Dialect::Grbl {
            // Checked here so that bad settings fail at the call.
            drop(grbl::HubMotion::new(
                config.clkfreq,
                &cogstep_protocol::grbl::Settings::default(),
            )?);
        }
        let name = port
            .name()
            .unwrap_or_else(|| "the board's port".to_string());
        let io_error = |source: serialport::Error| SimError::Io {
            port: name.clone(),
            source: source.into(),
        };
        port.set_timeout(READ_SLICE).map_err(io_error)?;
        let mut writer = port.try_clone().map_err(io_error)?;
        writer.set_timeout(WRITE_SLICE).map_err(io_error)?;
        let control = Arc::new(Control::default());
        let thread_control = Arc::clone(&control);
        let thread = if config.dialect == Dialect::Grbl {
            std::thread::Builder::new()
                .name("board-sim".to_string())
                .spawn(move || grbl::serve(config, options, port, writer, &thread_control))
        } else {
            let board = SimBoard::new(config)?;
            // The start-up announcement; on a pseudo-terminal it waits in the
            // buffer, which a host clears when it opens the port.
            if config.dialect == Dialect::Cogstep {
                let _ = writer.write_all(announcement(&board).as_bytes());
            }
            std::thread::Builder::new()
                .name("board-sim".to_string())
                .spawn(move || serve(config, board, port, writer, &thread_control))
        }
        .map_err(SimError::Spawn)?;
        Ok(BoardSim {
            control,
            thread: Some(thread),
            device_end: None,
            path: None,
        })
    }

    /// Opens a serial device (`--port` of board-sim) and serves on it.
    pub fn spawn_on_device(config: SimConfig, path: &str, baud: u32) -> Result<BoardSim, SimError> {
        BoardSim::spawn_on_device_with(config, GrblOptions::default(), path, baud)
    }

    /// [`spawn_on_device`](BoardSim::spawn_on_device) with a grbl board's options.
    pub fn spawn_on_device_with(
        config: SimConfig,
        options: GrblOptions,
        path: &str,
        baud: u32,
    ) -> Result<BoardSim, SimError> {
        let port = serialport::new(path, baud)
            .timeout(READ_SLICE)
            .open()
            .map_err(|source| SimError::Open {
                port: path.to_string(),
                source,
            })?;
        let mut sim = BoardSim::spawn_on_with(config, options, port)?;
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
fn open_pty() -> Result<Pty, SimError> {
    let (board_end, device_end) =
        serialport::TTYPort::pair().map_err(|error| SimError::Pty(error.to_string()))?;
    let path = device_end
        .name()
        .ok_or_else(|| SimError::Pty("the pseudo-terminal has no device path".to_string()))?;
    Ok(Pty {
        board_end: Box::new(board_end),
        device_end: Box::new(device_end),
        path,
    })
}

#[cfg(not(unix))]
fn open_pty() -> Result<Pty, SimError> {
    Err(SimError::Pty(
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
///
/// Backpressure: replies and screens go out before the board takes any
/// more input. When the host stops reading, the port's buffer fills, the
/// write waits, and the board reads nothing meanwhile, as a board whose
/// UART transmit buffer is full; the host's own writes then wait in turn.
/// No reply is ever dropped.
fn serve(
    config: SimConfig,
    mut board: SimBoard,
    mut port: Box<dyn SerialPort>,
    mut writer: Box<dyn SerialPort>,
    control: &Control,
) {
    let mut session = Session::new();
    let mut demo = DemoSession::new();
    let mut power_up = Instant::now();
    let mut replies = String::new();
    let mut unsent = Unsent::default();
    // P2 demo: what the program printed, and when it is out on the wire.
    let mut paced: VecDeque<(u64, String)> = VecDeque::new();
    let mut bytes = [0u8; 512];
    while !control.stop.load(Ordering::Acquire) {
        if control.reset.swap(false, Ordering::AcqRel) {
            // A new hub: the old cogs stop when it is dropped. What the
            // UART had not sent yet is lost with the reset.
            if let Ok(fresh) = SimBoard::new(config) {
                board = fresh;
            }
            session = Session::new();
            demo = DemoSession::new();
            power_up = Instant::now();
            unsent.clear();
            paced.clear();
            replies.clear();
            if config.dialect == Dialect::Cogstep {
                replies.push_str(&announcement(&board));
            }
        }
        if config.dialect == Dialect::P2Demo {
            // The demo's bytes go out at its baud rate: what it printed is
            // out on the wire when it has finished printing it.
            if !replies.is_empty() {
                paced.push_back((demo.printed_by_ns(), std::mem::take(&mut replies)));
            }
            let now_ns = nanos_since(power_up);
            while let Some((due_ns, _)) = paced.front() {
                if *due_ns > now_ns {
                    let due_in = Duration::from_nanos(due_ns - now_ns);
                    let _ = port.set_timeout(due_in.min(READ_SLICE));
                    break;
                }
                if let Some((_, mut printed)) = paced.pop_front() {
                    unsent.queue(&mut printed);
                }
                let _ = port.set_timeout(READ_SLICE);
            }
        } else {
            unsent.queue(&mut replies);
        }
        if !unsent.flush(writer.as_mut()) {
            // The host is not reading: take no input until it does.
            continue;
        }
        match port.read(&mut bytes) {
            Ok(count) => {
                let now_ns = nanos_since(power_up);
                for &byte in &bytes[..count] {
                    // Writing into a String cannot fail.
                    let _ = match config.dialect {
                        Dialect::Cogstep | Dialect::Grbl => {
                            session.feed(byte, &board, &mut replies)
                        }
                        Dialect::P2Demo => {
                            demo.feed(byte, now_ns, &mut board.demo_motor(), &mut replies)
                        }
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
        if config.dialect == Dialect::P2Demo {
            let now_ns = nanos_since(power_up);
            let _ = demo.poll(now_ns, &mut board.demo_motor(), &mut replies);
        }
    }
}

/// Time since power-up, ns.
fn nanos_since(power_up: Instant) -> u64 {
    u64::try_from(power_up.elapsed().as_nanos()).unwrap_or(u64::MAX)
}

/// Bytes the board has to send and has not sent yet.
#[derive(Default)]
struct Unsent {
    bytes: Vec<u8>,
    sent: usize,
}

impl Unsent {
    /// Moves `replies` to the end of the queue.
    fn queue(&mut self, replies: &mut String) {
        if !replies.is_empty() {
            self.bytes.extend_from_slice(replies.as_bytes());
            replies.clear();
        }
    }

    fn clear(&mut self) {
        self.bytes.clear();
        self.sent = 0;
    }

    /// Writes what it can within one write slice; true once all is out.
    fn flush(&mut self, writer: &mut dyn SerialPort) -> bool {
        while self.sent < self.bytes.len() {
            match writer.write(&self.bytes[self.sent..]) {
                Ok(0) => return false,
                Ok(count) => self.sent += count,
                Err(error) if error.kind() == io::ErrorKind::Interrupted => {}
                // Timed out: nobody reads. Another error: the device is
                // gone; the bytes wait for a host that opens it again.
                Err(error) => {
                    if error.kind() != io::ErrorKind::TimedOut {
                        std::thread::sleep(READ_SLICE);
                    }
                    return false;
                }
            }
        }
        self.clear();
        true
    }
}

/// The simulated board: a real-time hub and its axes.
struct SimBoard {
    /// The hub the axes run on (kept as long as the board).
    hub: Hub,
    axes: Vec<SimAxis>,
    clkfreq: u32,
    demo: DemoState,
}

impl SimBoard {
    fn new(config: SimConfig) -> Result<Self, SimError> {
        if config.axes == 0 || config.axes > SIM_AXES_MAX {
            return Err(SimError::Config(format!(
                "axes must be 1 to {SIM_AXES_MAX}, not {}",
                config.axes
            )));
        }
        // A real P2 runs the reference arithmetic.
        let arithmetic = match config.dialect {
            Dialect::Cogstep | Dialect::Grbl => HubConfig::default().arithmetic,
            Dialect::P2Demo => Arithmetic::P2Exact,
        };
        let hub = Hub::new(HubConfig {
            clkfreq: config.clkfreq,
            clock: ClockMode::Real,
            arithmetic,
            ..HubConfig::default()
        })?;
        let count = match config.dialect {
            Dialect::Cogstep | Dialect::Grbl => config.axes,
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
                SimError::Config(format!("axis {index} would not start: {error}"))
            })?;
            if config.dialect == Dialect::Cogstep {
                // A home switch and both hard limits on every axis, to home and trip.
                hub.fit_demo_switches(&axis, index)?;
            }
            axes.push(SimAxis(axis));
        }
        Ok(SimBoard {
            hub,
            axes,
            clkfreq: config.clkfreq,
            demo: DemoState::default(),
        })
    }

    fn demo_motor(&mut self) -> SimDemoMotor<'_> {
        SimDemoMotor {
            axis: self.axes.first(),
            state: &mut self.demo,
            clkfreq: self.clkfreq,
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

    fn move_together(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
        let group: Vec<(&Axis, i32)> = self
            .axes
            .iter()
            .zip(steps)
            .map(|(axis, steps)| (&axis.0, *steps))
            .collect();
        self.hub.move_together(&group, speed)
    }
}

/// A hub axis on the simulated board. The hub's calls return only once
/// the cog has applied the command (its answer is the reply), so a status
/// read right after `ok` already shows the command's effect: nothing to
/// wait for here.
struct SimAxis(Axis);

impl AxisContract for SimAxis {
    fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
        self.0.move_steps(speed, steps)
    }

    fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError> {
        self.0.jog(speed, direction)
    }

    fn jog_release(&self) -> Result<(), AxisError> {
        self.0.jog_release()
    }

    fn set_stop_pin(&self, high: bool) -> Result<(), AxisError> {
        self.0.set_stop_pin(high)
    }

    fn emergency_stop(&self) -> Result<(), AxisError> {
        self.0.emergency_stop()
    }

    fn set_position(&self, position: i64) -> Result<(), AxisError> {
        self.0.set_position(position)
    }

    fn status(&self) -> Result<AxisStatus, AxisError> {
        AxisContract::status(&self.0)
    }

    fn home(&self, config: HomeConfig) -> Result<(), AxisError> {
        self.0.home(config)
    }

    fn set_soft_limits(&self, min: i64, max: i64) -> Result<(), AxisError> {
        self.0.set_soft_limits(min, max)
    }

    fn clear_soft_limits(&self) -> Result<(), AxisError> {
        self.0.clear_soft_limits()
    }

    fn set_limit_pins(
        &self,
        min: Option<(u8, bool)>,
        max: Option<(u8, bool)>,
    ) -> Result<(), AxisError> {
        self.0.set_limit_pins(min, max)
    }

    fn clear_limit_fault(&self) -> Result<(), AxisError> {
        self.0.clear_limit_fault()
    }

    fn limit_status(&self) -> Result<LimitStatus, AxisError> {
        AxisContract::limit_status(&self.0)
    }
}

/// The P2 demo board's own longs, beside the hub's axis 0.
#[derive(Default)]
struct DemoState {
    /// A move the reference botches, on the model of the reference cog,
    /// and when the cog took it.
    model: Option<(ReferenceCog, Instant)>,
    /// The mode long a modelled move left (the hub's mode otherwise).
    mode: Option<u32>,
    /// `vel` as the screen shows it, when it is not the hub's top velocity.
    max_velocity: Option<i32>,
    /// A hub move runs, and the `vel` the reference cog writes for it when
    /// deceleration starts (the screen shows it from then on).
    velocity_pending: Option<i32>,
}

/// Axis 0 as the P2 demo's cog.
struct SimDemoMotor<'a> {
    axis: Option<&'a SimAxis>,
    state: &'a mut DemoState,
    clkfreq: u32,
}

impl SimDemoMotor<'_> {
    /// `vel` as the screen shows it now.
    fn max_velocity(&mut self) -> i32 {
        if let (Some(velocity), Some(axis)) = (self.state.velocity_pending, self.axis) {
            if axis.0.mode().has(Mode::DECEL) || !hub_axis_moving(&axis.0) {
                self.state.velocity_pending = None;
                self.state.max_velocity = Some(velocity);
            }
        }
        let held = self.state.max_velocity.unwrap_or(0);
        match &self.state.model {
            Some((model, _)) => model.max_velocity().unwrap_or(held),
            // The long is 0 until a cog first writes it.
            None => held,
        }
    }

    /// Runs the modelled move up to now; at its end the hub's axis takes
    /// over its position.
    fn run_model(&mut self) {
        let clkfreq = u128::from(self.clkfreq);
        let Some((model, taken)) = &mut self.state.model else {
            return;
        };
        let ticks = taken.elapsed().as_nanos() * clkfreq / 1_000_000_000;
        model.run_until(u64::try_from(ticks).unwrap_or(u64::MAX));
        if model.is_done() {
            let (position, mode) = (model.position(), model.mode());
            let velocity = model.max_velocity();
            if let Some(axis) = self.axis {
                let _ = axis.set_position(i64::from(position));
            }
            self.state.mode = Some(mode);
            if velocity.is_some() {
                self.state.max_velocity = velocity;
            }
            self.state.model = None;
        }
    }
}

impl DemoMotor for SimDemoMotor<'_> {
    fn preset_position(&mut self, position: i32) {
        if let Some(axis) = self.axis {
            let _ = axis.set_position(i64::from(position));
        }
    }

    fn start_move(&mut self, plan: &DemoPlan) {
        // The cog waits for STM to be non-zero.
        let Some(axis) = self.axis else {
            return;
        };
        if plan.steps == 0 {
            return;
        }
        if !is_botched(plan) {
            if let Ok(speed) = u32::try_from(plan.speed) {
                let shown = self.max_velocity();
                if axis.move_steps(speed, plan.steps).is_ok() {
                    self.state.mode = None;
                    self.state.max_velocity = Some(shown);
                    // The hub's top velocity is its plan's; the screen
                    // shows the reference cog's `t2`.
                    self.state.velocity_pending =
                        ReferenceCog::max_velocity_of(plan, self.clkfreq).or(Some(shown));
                    return;
                }
            }
        }
        // What the real cog does with it, which the hub would not do.
        self.state.max_velocity = Some(self.max_velocity());
        let position = axis.0.position() as i32;
        let model = ReferenceCog::start(position, plan, self.clkfreq);
        self.state.model = Some((model, Instant::now()));
    }

    fn is_moving(&mut self) -> bool {
        self.run_model();
        if self.state.model.is_some() {
            return true;
        }
        self.axis.is_some_and(|axis| hub_axis_moving(&axis.0))
    }

    fn cog(&mut self) -> CogLongs {
        self.run_model();
        let max_velocity = self.max_velocity();
        if let Some((model, _)) = &self.state.model {
            return CogLongs {
                position: model.position(),
                mode: model.mode(),
                max_velocity,
            };
        }
        let Some(axis) = self.axis else {
            return CogLongs::default();
        };
        let mut mode = axis.0.mode().reference_bits();
        if !hub_axis_moving(&axis.0) {
            // The reference's end of a move: `and mode, #%0100000`.
            mode &= Mode::STOP_LATCHED.bits();
        }
        CogLongs {
            // The board's position is a 32-bit long.
            position: axis.0.position() as i32,
            mode: self.state.mode.unwrap_or(mode),
            max_velocity,
        }
    }
}

/// Whether the hub's axis has a command to take or a move running (the
/// demo's loop ends when this turns false).
fn hub_axis_moving(axis: &Axis) -> bool {
    let mode = axis.mode();
    axis.stm() != 0 || axis.steps_to_go() != 0 || mode.has(Mode::MOVING) || mode.has(Mode::HOLD)
}

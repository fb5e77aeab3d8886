//! # cogstep-serial-host — drive a board over a serial port (std)
//!
//! [`SerialBoard::open`] opens the port, identifies the board (`I`, or the
//! P2 demo's screen) and starts one background thread that owns the port
//! from then on. Each [`SerialAxis`] implements the same
//! [`AxisContract`] as the emulated hub's `Axis` (`cogstep-hub`), so the
//! demo and scripts drive either the same way:
//!
//! ```text
//! SerialAxis::move_steps ─► request queue ─► link thread ─► "M 0 4000 800*HH\n" ─► port
//! port ─► reader thread ─► lines / screens ─► link thread ─► status cache ◄─ SerialAxis::status
//! ```
//!
//! - **Commands** go out one at a time: the link thread writes a line and
//!   waits (at most [`SerialConfig::timeout`]) for its final `ok` or
//!   `error:<code>`, which comes back to the caller mapped to an
//!   [`AxisError`]. After a command that changes an axis it reads the
//!   status once, so [`SerialAxis::status`] right after a call sees it.
//! - **Status** is polled in the background: `?` every
//!   [`SerialConfig::poll_interval`]; the status lines fill a cache that
//!   [`SerialAxis::status`] returns without any I/O.
//! - **Faults**: a read or write error, end of file, or no reply within the
//!   timeout takes the link down. [`SerialBoard::fault`] then says why,
//!   every call returns [`AxisError::Fault`]`("disconnected")` at once,
//!   and an axis that was moving keeps a latched fault
//!   ([`FAULT_LOST_MID_MOVE`]) until its next accepted command. The link
//!   thread reopens the port every [`RECONNECT_INTERVAL`] and identifies
//!   the board again. A cogstep board that announces itself unasked (its
//!   `[cogstep ...]` line, as it does when it starts) has reset: moving
//!   axes get [`FAULT_RESET_MID_MOVE`]. Nothing in here panics on what the
//!   port delivers, and no call waits longer than a few timeouts.
//! - **The P2 demo dialect** ([`Dialect::P2Demo`]) has no commands but
//!   the move prompts: the backend answers `Enter steps:` and
//!   `Enter speed:`, reads position and mode from the screens, and says
//!   [`AxisError::Unsupported`] for stop, jog, emergency stop and set
//!   position ([`SerialBoard::capabilities`] tells beforehand). Connecting
//!   sends nothing until the host knows the prompt state
//!   ([`DemoStart`]: wait for a screen, or, when asked, reset the board or
//!   press its first key), and moves the reference botches
//!   ([`check_demo_move`]) are refused
//!   with [`AxisError::Unsupported`] and the reason, before a byte is sent.
//!
//! ```no_run
//! use cogstep_serial_host::{SerialBoard, SerialConfig};
//! use cogstep_motion::AxisContract;
//!
//! let board = SerialBoard::open(SerialConfig::new("/dev/ttyUSB0"))?;
//! let x = board.axis(0).expect("the board has an axis 0");
//! x.move_steps(4_000, 800)?;
//! while x.status()?.steps_to_go != 0 {
//!     std::thread::sleep(std::time::Duration::from_millis(50));
//! }
//! board.close();
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fmt;
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam::channel::{self, Receiver, Sender};

use cogstep_motion::axis::{AxisContract, AxisError, AxisStatus, Direction, HomeConfig};
use cogstep_motion::axis::{LimitStatus, Mode};
use cogstep_motion::profile::PlanError;
use cogstep_protocol::p2demo::check_demo_move;
use cogstep_protocol::{Command, Target, DEFAULT_BAUD};

pub use cogstep_protocol::{Dialect, UnknownDialect};

mod cogstep;
mod demo;
mod link;
mod wire;

/// How a host gets a P2 demo board into a known prompt state when it
/// connects. The demo echoes nothing and every byte it reads at a prompt
/// is part of an answer (Backspace and CR end one, and an ended speed
/// answer starts a move), so the host sends nothing until it knows where
/// the program is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DemoStart {
    /// Send nothing; wait for the board to print a whole screen (it does
    /// while a move runs and when it ends). A board idle at a prompt
    /// prints nothing: the open then fails with
    /// [`SerialError::DemoStateUnknown`] and the motor has not moved.
    #[default]
    Passive,
    /// The user has just powered up or reset the board: it waits for its
    /// first key. The host presses one (a space) and reads the screen.
    PoweredUp,
    /// Reset the board first with a DTR/RTS pulse (the Prop Plug's reset),
    /// then press the first key. A reset restarts the program from flash:
    /// a program loaded into RAM only (F10) is lost, and the motor stops
    /// where it is.
    Reset,
}

impl DemoStart {
    /// The name on command lines: `passive`, `powered-up` or `reset`.
    pub fn as_str(self) -> &'static str {
        match self {
            DemoStart::Passive => "passive",
            DemoStart::PoweredUp => "powered-up",
            DemoStart::Reset => "reset",
        }
    }
}

/// `passive`, `powered-up` or `reset`.
impl fmt::Display for DemoStart {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A name that is not a [`DemoStart`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown P2 demo start `{0}` (expected passive, powered-up or reset)")]
pub struct UnknownDemoStart(pub String);

/// Reads `passive`, `powered-up` or `reset` (any case).
impl FromStr for DemoStart {
    type Err = UnknownDemoStart;

    fn from_str(name: &str) -> Result<Self, Self::Err> {
        match name.trim().to_ascii_lowercase().as_str() {
            "passive" => Ok(DemoStart::Passive),
            "powered-up" => Ok(DemoStart::PoweredUp),
            "reset" => Ok(DemoStart::Reset),
            _ => Err(UnknownDemoStart(name.to_string())),
        }
    }
}

/// How to reach a board.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SerialConfig {
    /// The device path (`/dev/ttyUSB0`, `COM3`, or the path board-sim prints).
    pub port: String,
    /// Baud rate (default [`DEFAULT_BAUD`], 115,200; 8N1, no flow control).
    pub baud: u32,
    /// What the board speaks (default [`Dialect::Cogstep`]).
    pub dialect: Dialect,
    /// How often the status is polled with `?` (default 50 ms).
    pub poll_interval: Duration,
    /// The longest wait for a reply (default 500 ms); past it the link is
    /// taken down as faulty and reopened.
    pub timeout: Duration,
    /// P2 demo boards: how the first open gets to a known prompt (default
    /// [`DemoStart::Passive`]; reopening after a lost link is always
    /// passive).
    pub demo_start: DemoStart,
}

impl SerialConfig {
    /// The defaults for `port`: 115,200 baud, cogstep, polling every 50 ms,
    /// replies within 500 ms.
    pub fn new(port: impl Into<String>) -> Self {
        SerialConfig {
            port: port.into(),
            baud: DEFAULT_BAUD,
            dialect: Dialect::Cogstep,
            poll_interval: Duration::from_millis(50),
            timeout: Duration::from_millis(500),
            demo_start: DemoStart::Passive,
        }
    }
}

/// What a board lets the host do besides moving and reading status.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Capabilities {
    /// `set_stop_pin` (and `jog_release`, which needs it) work.
    pub stop_pin: bool,
    /// `jog` works.
    pub jog: bool,
    /// `emergency_stop` works.
    pub emergency_stop: bool,
    /// `set_position` works.
    pub set_position: bool,
}

impl Capabilities {
    /// Everything (a cogstep board).
    pub const ALL: Capabilities = Capabilities {
        stop_pin: true,
        jog: true,
        emergency_stop: true,
        set_position: true,
    };
    /// Moves and status only (the P2 demo: stop and jog are pins there).
    pub const MOVE_ONLY: Capabilities = Capabilities {
        stop_pin: false,
        jog: false,
        emergency_stop: false,
        set_position: false,
    };
}

/// Why a board could not be opened (or simulated).
#[derive(Debug, thiserror::Error)]
pub enum SerialError {
    /// The port would not open.
    #[error("cannot open {port}: {source}")]
    Open {
        /// The device path.
        port: String,
        /// What the serial library said.
        #[source]
        source: serialport::Error,
    },
    /// Reading or writing the port failed.
    #[error("{port}: {source}")]
    Io {
        /// The device path.
        port: String,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The board did not answer in time.
    #[error("{port}: no answer within {timeout_ms} ms ({what})")]
    Timeout {
        /// The device path.
        port: String,
        /// What was waited for.
        what: &'static str,
        /// The timeout, ms.
        timeout_ms: u128,
    },
    /// Something answered, but not as a board of this dialect does.
    #[error("{port}: {reason}")]
    Handshake {
        /// The device path.
        port: String,
        /// What was wrong.
        reason: String,
    },
    /// A P2 demo board printed no screen: it waits at a prompt (or for its
    /// first key), where any byte sent could become part of an answer.
    #[error(
        "{port}: the P2 demo board printed no screen within {waited_ms} ms: it waits at a \
         prompt or for its first key, where any byte sent could become part of an answer and \
         move the motor; nothing was sent. Finish the prompt in a terminal (or start a move \
         there), or connect with a reset (restarts the program from flash: a program loaded \
         into RAM only is lost)"
    )]
    DemoStateUnknown {
        /// The device path.
        port: String,
        /// How long the host listened, ms.
        waited_ms: u128,
    },
    /// The DTR/RTS reset pulse could not be given.
    #[error("{port}: cannot pulse DTR/RTS to reset the board: {source}")]
    Reset {
        /// The device path.
        port: String,
        /// What the serial library said.
        #[source]
        source: serialport::Error,
    },
    /// A thread could not be started.
    #[error("cannot start a thread: {0}")]
    Spawn(#[source] std::io::Error),
}

/// [`AxisError::Fault`] while the link is down.
pub const FAULT_DISCONNECTED: &str = "disconnected";
/// [`AxisError::Fault`] latched on an axis that was moving when the link
/// went down: its position since is unknown.
pub const FAULT_LOST_MID_MOVE: &str = "board lost mid-move";
/// [`AxisError::Fault`] latched on an axis that was moving when the board
/// reset: the move is lost, the position counter restarted.
pub const FAULT_RESET_MID_MOVE: &str = "board reset mid-move";
/// [`AxisError::Unsupported`] of the P2 demo dialect.
pub const P2DEMO_UNSUPPORTED: &str = "stop and jog are pins on the P2 demo board";
/// How often the link thread tries to reopen a lost port.
pub const RECONNECT_INTERVAL: Duration = Duration::from_millis(250);
/// What [`SerialBoard::identity`] says for a P2 demo board.
pub const P2DEMO_IDENTITY: &str = "P2 Stepper Demo";

/// A board on a serial port. Cheap to clone (the clones share one port
/// and one link thread); the link closes with [`close`](SerialBoard::close)
/// or when the last clone and the last [`SerialAxis`] are dropped.
#[derive(Clone)]
pub struct SerialBoard {
    handle: Arc<Handle>,
}

/// One axis of a [`SerialBoard`]: an [`AxisContract`]. Cheap to clone.
#[derive(Clone)]
pub struct SerialAxis {
    handle: Arc<Handle>,
    index: usize,
}

impl fmt::Debug for SerialBoard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SerialBoard")
            .field("port", &self.handle.shared.config.port)
            .field("dialect", &self.handle.shared.config.dialect)
            .finish()
    }
}

impl fmt::Debug for SerialAxis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SerialAxis")
            .field("port", &self.handle.shared.config.port)
            .field("index", &self.index)
            .finish()
    }
}

impl SerialBoard {
    /// Opens the port and identifies the board: `I` for a cogstep board
    /// (then one status read), a key press and the screen for a P2 demo
    /// board. Fails if the port does not open or the board does not
    /// answer as its dialect does within [`SerialConfig::timeout`].
    pub fn open(config: SerialConfig) -> Result<SerialBoard, SerialError> {
        let (requests_tx, requests_rx) = channel::unbounded();
        let (urgent_tx, urgent_rx) = channel::unbounded();
        let shared = Arc::new(Shared {
            config,
            state: Mutex::new(BoardState::default()),
            closing: AtomicBool::new(false),
            requests: requests_rx,
            urgent: urgent_rx,
        });
        let connection = link::connect(&shared, shared.config.demo_start)?;
        let thread = link::spawn(Arc::clone(&shared), connection)?;
        Ok(SerialBoard {
            handle: Arc::new(Handle {
                shared,
                requests: requests_tx,
                urgent: urgent_tx,
                thread: Mutex::new(Some(thread)),
            }),
        })
    }

    /// How many axes the board has (1 for a P2 demo board).
    pub fn axis_count(&self) -> usize {
        self.handle.shared.state().axes.len()
    }

    /// Axis `index`, or `None` when the board has no such axis.
    pub fn axis(&self, index: usize) -> Option<SerialAxis> {
        (index < self.axis_count()).then(|| SerialAxis {
            handle: Arc::clone(&self.handle),
            index,
        })
    }

    /// What the board lets the host do ([`Capabilities::ALL`] for cogstep,
    /// [`Capabilities::MOVE_ONLY`] for the P2 demo).
    pub fn capabilities(&self) -> Capabilities {
        self.handle.shared.capabilities()
    }

    /// The dialect the board speaks.
    pub fn dialect(&self) -> Dialect {
        self.handle.shared.config.dialect
    }

    /// The configuration the board was opened with.
    pub fn config(&self) -> &SerialConfig {
        &self.handle.shared.config
    }

    /// The board's identity line, `[cogstep 0.1.0 proto:1 axes:2
    /// clkfreq:200000000]`, or [`P2DEMO_IDENTITY`].
    pub fn identity(&self) -> String {
        self.handle.shared.state().identity.clone()
    }

    /// The board's clock, Hz; 0 when the board does not say (the P2 demo).
    pub fn clkfreq(&self) -> u32 {
        self.handle.shared.state().clkfreq
    }

    /// The last fault: why the link is down (`disconnected: ...`,
    /// `timeout: ...`), or an axis's latched fault (`axis 0: board lost
    /// mid-move`); `None` when the link is up and no axis has a fault.
    pub fn fault(&self) -> Option<String> {
        let state = self.handle.shared.state();
        if let Link::Down(reason) = &state.link {
            return Some(reason.clone());
        }
        state
            .axes
            .iter()
            .enumerate()
            .find_map(|(index, axis)| axis.latched.map(|what| format!("axis {index}: {what}")))
    }

    /// Whether the link is up (the board answered its last exchange).
    pub fn is_connected(&self) -> bool {
        matches!(self.handle.shared.state().link, Link::Up)
    }

    /// Forgets the axes' latched faults (the caller has seen them).
    pub fn clear_faults(&self) {
        for axis in &mut self.handle.shared.state().axes {
            axis.latched = None;
        }
    }

    /// Reads every axis's status now (`?`) and waits for it, rather than
    /// for the next background poll. A P2 demo board has nothing to ask:
    /// this returns at once.
    pub fn refresh(&self) -> Result<(), AxisError> {
        self.handle.call(Op::Refresh)
    }

    /// Emergency stop of every axis: the realtime byte 0x18 goes out at
    /// once (even while a command waits for its reply), then `E`, whose
    /// `ok` this waits for. Positions are kept.
    pub fn emergency_stop_all(&self) -> Result<(), AxisError> {
        self.handle.emergency_stop()
    }

    /// A coordinated move (`G`): `steps[i]` for axis `i` (1 to 8 axes, 0
    /// leaves an axis still), the lead (the longest move) at `speed`; every
    /// first edge on one CT, one straight line, all or nothing (see
    /// `Hub::move_together`). Refused before anything is sent for a zero
    /// speed, no axes, more axes than the board (or than a `G` line) has,
    /// or a P2 demo board; the board's refusal maps as for
    /// [`SerialAxis`]'s moves.
    pub fn move_together(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
        if self.dialect() == Dialect::P2Demo {
            return Err(AxisError::Unsupported(P2DEMO_UNSUPPORTED));
        }
        // The hub's order: steps, then the lead's speed.
        if steps.contains(&i32::MIN) {
            return Err(AxisError::StepsOutOfRange);
        }
        if speed == 0 {
            return Err(PlanError::ZeroSpeed.into());
        }
        if steps.len() > self.axis_count() {
            return Err(AxisError::Unavailable);
        }
        let group = cogstep_protocol::GroupMove::new(speed, steps)
            .ok_or(AxisError::Unsupported("a group move of 1 to 8 axes"))?;
        self.handle.call(Op::Command {
            axis: None,
            command: Command::GroupMove(group),
        })
    }

    /// Closes the link: the link thread stops and the port is closed.
    /// Other clones and axes of this board get [`AxisError::Unavailable`].
    pub fn close(self) {
        self.handle.close();
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

    /// The axis's latched fault, if any (see [`FAULT_LOST_MID_MOVE`]).
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
fn check_move(speed: u32, steps: i32) -> Result<(), AxisError> {
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

/// What the handles hold: the shared state and the way to the link thread.
struct Handle {
    shared: Arc<Shared>,
    requests: Sender<Request>,
    urgent: Sender<u8>,
    thread: Mutex<Option<JoinHandle<()>>>,
}

impl Handle {
    /// Queues a request and waits for its answer. Never waits for ever:
    /// a request not started within the timeout is dropped unexecuted, and
    /// one started is answered within a bounded number of timeouts.
    fn call(&self, op: Op) -> Result<(), AxisError> {
        let shared = &self.shared;
        if shared.closing.load(Ordering::Acquire) {
            return Err(AxisError::Unavailable);
        }
        if let Op::Command {
            axis: Some(index), ..
        }
        | Op::JogRelease(index) = op
        {
            if index >= shared.state().axes.len() {
                return Err(AxisError::Unavailable);
            }
        }
        if shared.state().link != Link::Up {
            return Err(AxisError::Fault(FAULT_DISCONNECTED));
        }
        let timeout = shared.config.timeout;
        let start_by = Instant::now() + timeout;
        let (reply, answer) = channel::bounded(1);
        self.requests
            .send(Request {
                op,
                start_by,
                reply,
            })
            .map_err(|_| AxisError::Unavailable)?;
        // Queue wait, then at most: the command, a checksum retry, and the
        // status read after it, each a write and a reply bounded by the
        // timeout.
        let longest = timeout * 8 + Duration::from_millis(250);
        match answer.recv_timeout(longest) {
            Ok(result) => result,
            Err(channel::RecvTimeoutError::Timeout) => Err(AxisError::Fault("timeout")),
            Err(channel::RecvTimeoutError::Disconnected) => {
                Err(AxisError::Fault(FAULT_DISCONNECTED))
            }
        }
    }

    fn emergency_stop(&self) -> Result<(), AxisError> {
        if self.shared.closing.load(Ordering::Acquire) {
            return Err(AxisError::Unavailable);
        }
        if self.shared.config.dialect == Dialect::P2Demo {
            return Err(AxisError::Unsupported(P2DEMO_UNSUPPORTED));
        }
        if self.shared.state().link != Link::Up {
            // Not queued for later: a stop must not reach a board that
            // comes back long after the caller was told it failed.
            return Err(AxisError::Fault(FAULT_DISCONNECTED));
        }
        // The realtime byte first: it acts even while a line waits.
        let _ = self
            .urgent
            .send(cogstep_protocol::Realtime::EmergencyStop.byte());
        self.call(Op::Command {
            axis: None,
            command: Command::EmergencyStop,
        })
    }

    fn close(&self) {
        self.shared.closing.store(true, Ordering::Release);
        let thread = lock(&self.thread).take();
        if let Some(thread) = thread {
            let _ = thread.join();
        }
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        self.close();
    }
}

/// What the link thread and the handles share.
struct Shared {
    config: SerialConfig,
    state: Mutex<BoardState>,
    /// Set when the board is closed; the link thread stops.
    closing: AtomicBool,
    requests: Receiver<Request>,
    urgent: Receiver<u8>,
}

impl Shared {
    fn state(&self) -> MutexGuard<'_, BoardState> {
        lock(&self.state)
    }

    fn capabilities(&self) -> Capabilities {
        match self.config.dialect {
            Dialect::Cogstep => Capabilities::ALL,
            Dialect::P2Demo => Capabilities::MOVE_ONLY,
        }
    }

    fn is_closing(&self) -> bool {
        self.closing.load(Ordering::Acquire)
    }
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic elsewhere must not take every handle down with it.
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Whether the link is up.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Link {
    Up,
    /// Down, and why (what [`SerialBoard::fault`] says).
    Down(String),
}

/// The board as the host last saw it.
#[derive(Debug)]
struct BoardState {
    link: Link,
    identity: String,
    clkfreq: u32,
    axes: Vec<AxisCache>,
}

impl Default for BoardState {
    fn default() -> Self {
        BoardState {
            link: Link::Down("connecting".to_string()),
            identity: String::new(),
            clkfreq: 0,
            axes: Vec::new(),
        }
    }
}

/// One axis as the host last saw it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct AxisCache {
    status: AxisStatus,
    /// A fault that outlives the link's (re)connection, cleared by the
    /// axis's next accepted command.
    latched: Option<&'static str>,
    /// The limit and homing state the last `L` read.
    limits: Option<LimitStatus>,
}

impl Default for AxisCache {
    fn default() -> Self {
        AxisCache {
            status: AxisStatus {
                position: 0,
                stm: 0,
                steps_to_go: 0,
                mode: Mode(0),
                velocity_steps_per_s: 0,
                stop_pin_high: true,
            },
            latched: None,
            limits: None,
        }
    }
}

impl BoardState {
    /// The link is up with this board: `axes` axes.
    fn link_up(&mut self, identity: String, clkfreq: u32, axes: usize) {
        self.identity = identity;
        self.clkfreq = clkfreq;
        self.axes.resize(axes, AxisCache::default());
        self.link = Link::Up;
    }

    /// The link went down: moving axes latch [`FAULT_LOST_MID_MOVE`].
    fn link_down(&mut self, reason: String) {
        self.latch_moving(FAULT_LOST_MID_MOVE);
        self.link = Link::Down(reason);
    }

    /// Every axis that is not idle latches `what` (unless it has a fault).
    fn latch_moving(&mut self, what: &'static str) {
        for axis in &mut self.axes {
            if is_busy(&axis.status) && axis.latched.is_none() {
                axis.latched = Some(what);
            }
        }
    }
}

/// Whether an axis is doing (or holding) something: not ready and idle.
fn is_busy(status: &AxisStatus) -> bool {
    status.steps_to_go != 0 || status.mode.has(Mode::MOVING) || status.mode.has(Mode::HOLD)
}

/// A request to the link thread.
struct Request {
    op: Op,
    /// Dropped unexecuted if not started by then (the caller gave up).
    start_by: Instant,
    reply: Sender<Result<(), AxisError>>,
}

impl Request {
    fn answer(self, result: Result<(), AxisError>) {
        // The caller may have given up; nothing to do then.
        let _ = self.reply.send(result);
    }
}

/// What a request asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Op {
    /// A cogstep command line; `axis` is the axis it changes (its latched
    /// fault is cleared when the board accepts it), `None` for all.
    Command {
        axis: Option<usize>,
        command: Command,
    },
    /// `S <axis>` now, `R <axis>` once it has stopped.
    JogRelease(usize),
    /// Read every status now.
    Refresh,
    /// A P2 demo move: answer the two prompts.
    DemoMove { speed: u32, steps: i32 },
}

#[cfg(test)]
mod tests;

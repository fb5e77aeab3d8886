//! How to reach a board: [`SerialConfig`], and [`DemoStart`], how a P2
//! demo board is brought to a known prompt.

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use cogstep_protocol::{Dialect, DEFAULT_BAUD};

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
    /// [`SerialError::DemoStateUnknown`](crate::SerialError::DemoStateUnknown)
    /// and the motor has not moved.
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

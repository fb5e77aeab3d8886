//! What goes wrong: [`SerialError`] (a board that cannot be opened), and
//! the texts of the [`AxisError`]s this backend gives.

#[cfg(doc)]
use cogstep_motion::axis::AxisError;

/// Why a G-code program could not be streamed to a grbl board
/// ([`SerialBoard::stream_gcode`](crate::SerialBoard::stream_gcode)):
/// nothing was sent.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum StreamError {
    /// A line of the program cannot go to the board as it is.
    #[error("{0}")]
    Refused(#[from] crate::StreamRefusal),
    /// The board cannot take a program now (not grbl, not at rest, in
    /// Alarm, another program streams, the link is down).
    #[error("{0}")]
    Board(#[from] cogstep_motion::axis::AxisError),
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

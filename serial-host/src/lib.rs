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
//!
//! One file each, in the order a call goes through them:
//!
//! - `config`: how to reach a board ([`SerialConfig`], [`DemoStart`]);
//!   `error`: why it cannot be opened ([`SerialError`]) and the fault texts;
//! - `board`: the board handle ([`SerialBoard`]); `axis`: one axis's
//!   [`AxisContract`] ([`SerialAxis`]); `capabilities`: what each dialect
//!   allows;
//! - `handle`: what the handles hold, and the call that queues a `request`
//!   (`request`: what the link thread is asked) and waits for its answer;
//! - `state`: what the handles and the link thread share: the link's
//!   state and each axis's cached status and latched fault;
//! - `link`: the link thread (connect, serve, reopen); `wire`: the port's
//!   bytes framed into lines or screens; `cogstep` and `demo`: each
//!   dialect's conversation.

#[cfg(doc)]
use cogstep_motion::axis::{AxisContract, AxisError};
#[cfg(doc)]
use cogstep_protocol::p2demo::check_demo_move;

mod axis;
mod board;
mod capabilities;
mod cogstep;
mod config;
mod demo;
mod error;
mod grbl;
mod grbl_stream;
mod handle;
mod link;
mod request;
mod state;
mod wire;

pub use axis::SerialAxis;
pub use board::SerialBoard;
pub use capabilities::Capabilities;
pub use cogstep_protocol::{Dialect, UnknownDialect};
pub use config::{DemoStart, SerialConfig, UnknownDemoStart};
pub use demo::P2DEMO_IDENTITY;
pub use error::{
    SerialError, StreamError, FAULT_DISCONNECTED, FAULT_LOST_MID_MOVE, FAULT_RESET_MID_MOVE,
    P2DEMO_UNSUPPORTED,
};
pub use grbl::{GrblStatus, FAULT_GRBL_ALARM, GRBL_UNSUPPORTED};
pub use grbl_stream::{prepare_line, GcodeStream, StreamProgress, StreamRefusal, StreamState};
pub use link::RECONNECT_INTERVAL;

#[cfg(test)]
mod tests;

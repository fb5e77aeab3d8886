//! # cogstep-protocol — the serial line protocol, board side (`no_std`, no allocation)
//!
//! A board (a real microcontroller, or the board simulator) talks to a host
//! or to a person at a plain terminal over a UART: ASCII command lines in,
//! reply lines out, plus three single-byte realtime commands that act at
//! once. The complete protocol, with a session transcript, is in
//! `docs/protocol.md`; this module is its board-side implementation, and
//! the host side reuses its encoders and parsers.
//!
//! A byte from the UART goes through these stages, one module each:
//!
//! ```text
//! byte ─► receiver (line buffer, realtime bytes, overlong lines)
//!      ─► command  (parse_line: checksum, tokens, numbers ─► Command)
//!      ─► board    (dispatch: Command over the Board's AxisContracts)
//!      ─► reply    (ok / error:<code> <text> / [info] / <status>;
//!                   refusal: the one table of the axis's refusals' lines)
//! ```
//!
//! [`Session`] strings the stages together: a firmware feeds it every
//! received byte with its [`Board`] and a [`core::fmt::Write`] sink for the
//! replies, and implements [`Board`] over its own pins and timer:
//!
//! ```
//! use cogstep_protocol::{Board, Session};
//! # use cogstep_motion::axis::{AxisContract, AxisError, AxisStatus, Direction, Mode};
//! # struct MyAxis;
//! # impl AxisContract for MyAxis {
//! #     fn move_steps(&self, _: u32, _: i32) -> Result<(), AxisError> { Ok(()) }
//! #     fn jog(&self, _: u32, _: Direction) -> Result<(), AxisError> { Ok(()) }
//! #     fn jog_release(&self) -> Result<(), AxisError> { Ok(()) }
//! #     fn set_stop_pin(&self, _: bool) -> Result<(), AxisError> { Ok(()) }
//! #     fn emergency_stop(&self) -> Result<(), AxisError> { Ok(()) }
//! #     fn set_position(&self, _: i64) -> Result<(), AxisError> { Ok(()) }
//! #     fn status(&self) -> Result<AxisStatus, AxisError> {
//! #         Ok(AxisStatus { position: 0, stm: 0, steps_to_go: 0, mode: Mode(0),
//! #             velocity_steps_per_s: 0, stop_pin_high: true })
//! #     }
//! # }
//!
//! struct MyBoard {
//!     axes: [MyAxis; 1],
//! }
//!
//! impl Board for MyBoard {
//!     fn axis_count(&self) -> usize {
//!         self.axes.len()
//!     }
//!     fn axis(&self, index: usize) -> Option<&dyn AxisContract> {
//!         self.axes.get(index).map(|axis| axis as &dyn AxisContract)
//!     }
//!     fn clkfreq_hz(&self) -> u32 {
//!         200_000_000
//!     }
//! }
//!
//! let board = MyBoard { axes: [MyAxis] };
//! let mut session = Session::new();
//! let mut replies: heapless::String<256> = heapless::String::new();
//! for &byte in b"M 0 20000 20000\n" {
//!     session.feed(byte, &board, &mut replies).unwrap();
//! }
//! assert_eq!(replies.as_str(), "ok\n");
//! ```
//!
//! [`p2demo`] is the other dialect a board may speak: the P2 reference
//! driver's stock demo program (`Stepper Demo`, `Enter steps:`), byte for
//! byte: its screens, formatted and parsed back, its prompt/answer flow,
//! and which moves the reference botches.
//!
//! [`grbl`] is the third: grbl 1.1's serial interface, the one G-code
//! senders (cncjs, Universal G-code Sender, bCNC) speak — realtime bytes,
//! the 128-byte receive buffer of character-counting streaming, `$`
//! settings, status reports and alarms — over a motion and a G-code
//! interpreter behind two traits.
//!
//! [`p2demo::cog`] is the reference cog's PASM for one demo command, step
//! for step: what a real P2 demo board does with the moves the reference
//! botches.
//!
//! Two `std` crates sit on top: `cogstep-serial-host` (the host side over a
//! real serial port, the same `AxisContract` as the emulated hub, for both
//! [`Dialect`]s) and `cogstep-sim` (the board simulator, a real-time hub
//! behind a [`Session`] or a [`p2demo::DemoSession`]; the `board-sim`
//! binary is a thin main over it).

#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod board;
mod command;
mod dialect;
pub mod grbl;
pub mod p2demo;
mod receiver;
mod refusal;
mod reply;

pub use board::{dispatch, realtime, Board, Session};
pub use command::{
    checksum, parse_line, parse_line_on, Command, GroupMove, Target, GROUP_AXES_MAX,
};
pub use dialect::{Dialect, UnknownDialect};
/// The reference cog model, at its older path (it lives in [`p2demo::cog`]).
pub use p2demo::cog as p2demo_cog;
pub use receiver::{Event, Realtime, Receiver};
pub use refusal::{
    axis_error_of_reply, refusal_code, refusal_of_error, refusal_of_reply, write_refusal_line,
    write_refusal_text,
};
pub use reply::{ErrorCode, LimitLine, ProtocolError, Reply, StatusLine, LINE_END};

/// The protocol version `I` reports (`proto:1`).
pub const PROTOCOL_VERSION: u32 = 1;

/// The default baud rate (8 data bits, no parity, 1 stop bit).
pub const DEFAULT_BAUD: u32 = 115_200;

/// The longest command line, in bytes, not counting its line end (CR, LF
/// or CRLF) but counting a `*HH` checksum.
pub const LINE_MAX: usize = 96;

/// The longest reply line the board sends, in bytes, line end included.
/// A firmware that buffers replies per line needs this much.
pub const REPLY_LINE_MAX: usize = 128;

#[cfg(test)]
mod fake_board;
#[cfg(test)]
mod fuzz_tests;
#[cfg(test)]
mod protocol_tests;

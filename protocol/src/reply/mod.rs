//! Reply lines: error codes, status lines, and reading replies back.
//!
//! Every command line gets exactly one final reply, `ok` or
//! `error:<code> <text>`; information lines (`[...]`) and status lines
//! (`<...>`) may come before it. The board ends every reply line with
//! [`LINE_END`].
//!
//! One file each: `error` (the error codes, why a line was refused and its
//! reply line), `printable` (backend text made safe for a line), `status`
//! (the status line), `limits` (the `L` reply's lines), and `read` (a
//! reply line read back by a host).

mod error;
mod limits;
mod printable;
mod read;
mod status;

pub use error::{ErrorCode, ProtocolError};
pub use limits::LimitLine;
pub(crate) use printable::{write_display_printable, write_printable, BACKEND_TEXT_MAX};
pub use read::Reply;
pub use status::StatusLine;

/// What the board ends each reply line with: LF, as the protocol's lines
/// are ended (hosts also accept CR LF from boards that send it).
pub const LINE_END: &str = "\n";

//! # grbl 1.1 — the third dialect of the board side (`no_std`, no allocation)
//!
//! The serial interface of grbl 1.1, the one every G-code sender already
//! speaks (cncjs, Universal G-code Sender, bCNC, LaserGRBL), over
//! cogstep's motion. What a sender sees, in the order a byte flows:
//!
//! ```text
//! byte ─► receiver (realtime bytes taken out at once; a 128-byte receive buffer)
//!      ─► session  (line assembly, `$` commands, alarms, check mode)
//!      ─► GcodeInterpreter (a G-code line ─► motion blocks in steps)
//!      ─► GrblMotion (the planner and the axes: queue, hold, resume, overrides)
//!      ─► report   (ok / error:N / ALARM:N / [MSG:..] / <status report>)
//! ```
//!
//! [`GrblSession`] owns the state a grbl board keeps (settings, alarm lock,
//! overrides, check mode, the report cadence) and drives motion through
//! the [`GrblMotion`] trait and G-code through the [`GcodeInterpreter`]
//! trait, so that the same engine runs in the board simulator, in tests
//! against a fake, and on a firmware.
//!
//! Exactness: the machine position in a report is the step count divided
//! by the axis's steps/mm (`$100`…), so a program that ends on X10 with
//! 250 steps/mm reports `MPos:10.000` — not grbl's float accumulation.
//!
//! The interface, with its differences from real grbl, is documented in
//! `docs/protocol.md` (the grbl section).

mod codes;
mod gcode;
mod motion;
mod realtime;
mod receiver;
mod report;
mod session;
mod settings;

pub use codes::{GrblAlarm, GrblError};
pub use gcode::{without_idle_words, GrblGcode};
pub use motion::{
    GcodeInterpreter, GrblMotion, HomeRequest, MotionBlock, MotionFault, MotionRefusal,
    MotionState, MotionStatus, Offsets, Overrides, ParserState,
};
pub use realtime::GrblRealtime;
pub use receiver::{GrblReceiver, Received, RX_BUFFER_SIZE};
pub use report::{format_mm, steps_to_mm, write_axes_mm};
pub use session::{GrblSession, GrblState};
pub use settings::{parse_grbl_number, Settings, SettingsError};

/// The number of axes a grbl board drives: X, Y and Z, cogstep axes 0, 1, 2.
pub const GRBL_AXES: usize = 3;

/// grbl's version string (`$I`'s `VER:` starts with it).
pub const GRBL_VERSION: &str = "1.1h";

/// The welcome line (without its line ends), at boot and after a soft reset;
/// senders detect the controller by it.
pub const WELCOME: &str = "Grbl 1.1h ['$' for help]";

/// The longest line, in characters kept (blanks and comments are not
/// kept), as grbl's line buffer; a longer line gets `error:11`.
pub const LINE_BUFFER_SIZE: usize = 80;

/// grbl's line end on everything it sends.
pub const GRBL_LINE_END: &str = "\r\n";

#[cfg(test)]
mod tests;

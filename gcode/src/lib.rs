//! # cogstep-gcode — G-code in, the machine file, arcs (`no_std`, no alloc)
//!
//! What turns a CNC or plotter program into the planner's lines: the
//! machine (steps per mm, limits, home switches, the planner's settings),
//! a G-code interpreter that keeps the modal state and the position in mm
//! and in steps, and arcs cut into chords within a tolerance.
//!
//! ```text
//! machine file (TOML, std) ─► MachineSpec ─► planner_machine::<N>() ─► planner::Machine
//! G-code line ─► words (tokenizer) ─► Interpreter (modal state, position) ─► Block
//!     ─► Block::Line (arcs: one per chord) ─► to_planner_line::<N>() ─► planner::Line
//! ```
//!
//! - [`machine`]: [`MachineSpec`], its axes and planner settings, and the
//!   conversion to the planner's steps; [`machine_file`] (feature `std`)
//!   reads the TOML file.
//! - [`interpreter`]: [`Interpreter::interpret_line`]: a line yields all
//!   of its [`Block`]s, or an error and no change.
//! - [`arc`]: G2/G3 in XY as chords whose sagitta is within
//!   `arc_tolerance_mm`.
//! - [`error`]: [`GcodeError`]: the line, the column of the word, the kind.
//! - [`check`] (feature `std`): every error of a whole file.
//!
//! The subset: G0 G1 G2 G3 G4 G17 G20 G21 G28 G61 G64 G90 G91 G92, M0 M2
//! M30, F (units/min), N, P (G4, seconds), I J R, the machine's axis
//! letters; comments in `( )` and after `;`, `%` lines, blank lines.
//! Anything else is a typed error at its line and column.
//!
//! ```
//! use cogstep_gcode::{Block, Interpreter, MachineSpec};
//!
//! let spec = MachineSpec::from_toml_str(
//!     "[axes.x]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 200.0\nmax_accel_mm_s2 = 2000.0\n\
//!      [axes.y]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 200.0\nmax_accel_mm_s2 = 2000.0\n\
//!      [planner]\njunction_deviation_mm = 0.01\narc_tolerance_mm = 0.002\n",
//! )?;
//! let mut gcode = Interpreter::new(&spec);
//! let mut blocks = Vec::new();
//! gcode.interpret_line(1, "G1 X10 Y-2.5 F600 ; 10 mm/s", &mut |block| blocks.push(block))?;
//! let Block::Line { steps, target_steps, feed_mm_s, .. } = blocks[0] else { panic!() };
//! assert_eq!((steps[0], steps[1], target_steps[1], feed_mm_s), (800, -200, -200, 10.0));
//! let line = blocks[0].to_planner_line::<2>().unwrap();
//! assert_eq!(line.steps, [800, -200]);
//!
//! let error = gcode.interpret_line(2, "G1 X20 S1000", &mut |_| {}).unwrap_err();
//! assert_eq!((error.line, error.column), (2, 8));
//! assert_eq!(error.to_string(), "line 2, column 8: unsupported word S1000");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![cfg_attr(not(any(feature = "std", test)), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod arc;
pub mod block;
pub mod error;
pub mod interpreter;
pub mod machine;
#[cfg(feature = "std")]
pub mod machine_file;
mod words;

#[cfg(test)]
mod tests;

pub use block::Block;
pub use error::{GcodeError, GcodeErrorKind};
pub use interpreter::{Distance, Interpreter, Motion, Units};
pub use machine::{AxisSpec, HomeEnd, Key, MachineError, MachineSpec, PlannerSpec, AXIS_LETTERS};

/// Interprets a whole program and lists every error, in order: a line
/// with an error changes nothing and the lines after it are interpreted
/// from the state before it. Lines are numbered from 1.
#[cfg(feature = "std")]
pub fn check(text: &str, spec: &MachineSpec) -> std::vec::Vec<GcodeError> {
    let mut interpreter = Interpreter::new(spec);
    let mut errors = std::vec::Vec::new();
    for (index, line) in text.lines().enumerate() {
        let line_no = u32::try_from(index + 1).unwrap_or(u32::MAX);
        if let Err(error) = interpreter.interpret_line(line_no, line, &mut |_| {}) {
            errors.push(error);
        }
    }
    errors
}

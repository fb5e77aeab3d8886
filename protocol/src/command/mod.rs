//! Command lines: parsed from bytes (board side), written back (host side).
//!
//! A line is a one-letter command and its arguments, separated by one or
//! more spaces, optionally ended by `*HH`: two hex digits of the XOR of
//! every byte before the `*`. Checks run in this order, and the first that
//! fails decides the error: checksum (when present), bytes (printable ASCII
//! only), command letter, then the arguments left to right.

//!
//! `parse` reads a line, `write` writes one back; the commands themselves
//! are here.

use cogstep_motion::axis::{Direction, HomeConfig};

mod parse;
mod write;

pub(crate) use parse::{parse_limit_pin, parse_signed};
pub use parse::{parse_line, parse_line_on};
pub(crate) use write::write_limit_pin;

/// Which axes a stop-pin command acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// One axis, 0-based.
    Axis(usize),
    /// Every axis (`*`).
    All,
}

/// One command line, parsed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// `I`: identify the board.
    Identify,
    /// `M <axis> <speed> <steps>`: start a move, or merge into the running one.
    Move {
        /// The axis, 0-based.
        axis: usize,
        /// Top speed, steps/s, at least 1.
        speed_steps_per_s: u32,
        /// Steps to move, signed (the sign is the direction), never 0.
        steps: i32,
    },
    /// `J <axis> <speed> <+|->`: a jog heartbeat.
    Jog {
        /// The axis, 0-based.
        axis: usize,
        /// Jog speed, steps/s, at least 1.
        speed_steps_per_s: u32,
        /// `+` forward, `-` reverse.
        direction: Direction,
    },
    /// `S <axis|*>`: stop pin low, a controlled stop.
    Stop(Target),
    /// `R <axis|*>`: stop pin high, running allowed.
    Run(Target),
    /// `E`: emergency stop of every axis, positions kept.
    EmergencyStop,
    /// `P <axis> <position>`: set the position counter of an idle axis.
    SetPosition {
        /// The axis, 0-based.
        axis: usize,
        /// The new position, steps.
        position: i64,
    },
    /// `H <axis> <pin> <0|1> <+|-> <seek> <latch> <backoff> <max_travel>
    /// <set_position>`: start homing an idle axis.
    Home {
        /// The axis, 0-based.
        axis: usize,
        /// How to home.
        config: HomeConfig,
    },
    /// `W <axis> <min> <max>`: soft limits; `W <axis> -` removes them.
    SoftLimits {
        /// The axis, 0-based.
        axis: usize,
        /// `(min, max)`, or none.
        limits: Option<(i64, i64)>,
    },
    /// `K <axis> <min> <max>`, each `<pin>/<0|1>` (the active level) or
    /// `-`: the hard limit inputs.
    LimitPins {
        /// The axis, 0-based.
        axis: usize,
        /// The limit met moving in reverse.
        min: Option<(u8, bool)>,
        /// The limit met moving forward.
        max: Option<(u8, bool)>,
    },
    /// `C <axis>`: clear a tripped hard limit.
    ClearLimitFault(usize),
    /// `L <axis>`: the limit and homing state, as a `[limits ...]` line.
    Limits(usize),
    /// `G <speed> <steps of axis 0> [<steps of axis 1> …]`: a coordinated
    /// move of axes 0 to n − 1 (1 ≤ n ≤ 8) along one straight line, every
    /// axis's first step on one CT; steps of 0 leave an axis still (it must
    /// still be idle). All or nothing.
    GroupMove(GroupMove),
}

/// The most axes one `G` line moves.
pub const GROUP_AXES_MAX: usize = 8;

/// The arguments of a `G` line: a speed and the signed steps of axes
/// 0 to n − 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct GroupMove {
    /// The lead's (the longest move's) top speed, steps/s, at least 1.
    pub speed_steps_per_s: u32,
    steps: [i32; GROUP_AXES_MAX],
    axes: u8,
}

impl GroupMove {
    /// `steps[i]` for axis `i`; `None` unless 1 to [`GROUP_AXES_MAX`]
    /// axes, each with steps in −(2³¹ − 1) ..= 2³¹ − 1.
    pub fn new(speed_steps_per_s: u32, steps: &[i32]) -> Option<Self> {
        if steps.is_empty() || steps.len() > GROUP_AXES_MAX || steps.contains(&i32::MIN) {
            return None;
        }
        let mut all = [0; GROUP_AXES_MAX];
        all[..steps.len()].copy_from_slice(steps);
        Some(GroupMove {
            speed_steps_per_s,
            steps: all,
            axes: steps.len() as u8,
        })
    }

    /// The steps of axes 0, 1, ….
    pub fn steps(&self) -> &[i32] {
        &self.steps[..usize::from(self.axes)]
    }
}

/// The XOR of `bytes`: the checksum a line's `*HH` suffix states.
pub fn checksum(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0, |acc, &byte| acc ^ byte)
}

#[cfg(test)]
mod tests;

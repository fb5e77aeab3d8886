//! The two boundaries of the grbl engine: the motion it drives
//! ([`GrblMotion`]) and the G-code interpreter that turns a line into
//! motion blocks ([`GcodeInterpreter`]).
//!
//! Both work in steps: the interpreter rounds every programmed point to
//! steps with the `$100`… settings it is given, the motion runs steps, and
//! the session reports positions as steps divided by steps/mm.

use super::codes::GrblError;
use super::settings::Settings;
use super::GRBL_AXES;

/// One block for the planner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum MotionBlock {
    /// A straight line in machine steps (an arc comes as many).
    Line {
        /// The G-code line it came from (the session's count of lines).
        line: u32,
        /// The end point, machine steps per axis (absolute).
        target_steps: [i64; GRBL_AXES],
        /// The programmed feed along the path, mm/s (for a rapid, the
        /// fastest the axes allow; the motion clamps it to every axis's
        /// `$110`… rate either way).
        feed_mm_s: f64,
        /// The length of the line, mm.
        length_mm: f64,
        /// G0: the rapid override applies, not the feed override.
        rapid: bool,
        /// A `$J=` jog (0x85 cancels it).
        jog: bool,
    },
    /// G4: wait, with the axes at rest, this long.
    Dwell {
        /// The G-code line it came from.
        line: u32,
        /// How long, ms.
        ms: u32,
    },
}

/// Why the motion did not take a block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionRefusal {
    /// The planner is full: try again when a block has run.
    Full,
    /// The block can never run (out of the axes' range).
    Invalid,
}

/// What the motion is doing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MotionState {
    /// At rest with nothing queued (a dwell counts as running).
    #[default]
    Idle,
    /// Running the queue.
    Run,
    /// Running a jog.
    Jog,
    /// Decelerating for a feed hold (grbl's `Hold:1`).
    Holding,
    /// Stopped by a feed hold, the rest of the path kept (`Hold:0`).
    Held,
    /// Homing.
    Homing,
}

/// Something the motion stopped for, which locks the machine in Alarm.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionFault {
    /// A hard limit switch tripped (the queue is gone).
    HardLimit,
    /// Homing did not find its switch.
    HomingSwitchNotFound,
    /// Homing failed otherwise (could not pull off).
    HomingFailed,
}

/// The motion's state, for a status report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotionStatus {
    /// Machine position, steps per axis (exact: what the axes stepped).
    pub steps: [i64; GRBL_AXES],
    /// What it does.
    pub state: MotionState,
    /// The speed along the path now, mm/s.
    pub feed_mm_s: f64,
    /// The G-code line of the block running, if any.
    pub line: Option<u32>,
}

/// The overrides in force, percent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Overrides {
    /// Feed override, 10–200.
    pub feed_pct: u8,
    /// Rapid override: 100, 50 or 25.
    pub rapid_pct: u8,
    /// Spindle override, 10–200 (reported only: no spindle).
    pub spindle_pct: u8,
}

impl Default for Overrides {
    fn default() -> Self {
        Overrides {
            feed_pct: 100,
            rapid_pct: 100,
            spindle_pct: 100,
        }
    }
}

/// `$H`: which axes home, how, from the settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomeRequest {
    /// Axes to home (bit 0 X, bit 1 Y, bit 2 Z).
    pub axes_mask: u8,
    /// `$23`: a set bit homes that axis towards negative.
    pub direction_mask: u8,
    /// `$24`: the slow approach, mm/min.
    pub feed_mm_min: f64,
    /// `$25`: the search, mm/min.
    pub seek_mm_min: f64,
    /// `$27`: the pull-off, mm.
    pub pull_off_mm: f64,
    /// `$100`…: steps per mm.
    pub steps_per_mm: [f64; GRBL_AXES],
    /// `$130`…: the search goes at most 1.5 × this, mm.
    pub max_travel_mm: [f64; GRBL_AXES],
}

/// The planner and the axes behind a grbl board.
///
/// Every call returns at once (a board runs it from its main loop); what
/// takes time is reported by [`status`](GrblMotion::status) and
/// [`take_fault`](GrblMotion::take_fault).
pub trait GrblMotion {
    /// Queues one block behind the others. `Ok` is a promise: the block
    /// runs unless a reset, a jog cancel or a fault cuts it.
    fn queue(&mut self, block: &MotionBlock) -> Result<(), MotionRefusal>;

    /// How many more blocks the planner takes now.
    fn free_blocks(&self) -> usize;

    /// The planner's size in blocks (`[OPT:` reports it less one).
    fn capacity(&self) -> usize;

    /// Feed hold: decelerate along the path and stop on it, nothing lost.
    fn hold(&mut self);

    /// Resume after a hold, the same path.
    fn resume(&mut self);

    /// Jog cancel: decelerate the jog and drop every queued jog block.
    fn cancel_jog(&mut self);

    /// Soft reset: stop every axis at once and forget the queue; positions
    /// stay what the axes stepped.
    fn reset(&mut self);

    /// The state now. A board polls it (status reports, the end of a hold,
    /// faults).
    fn status(&self) -> MotionStatus;

    /// A fault since the last call (then the motion is stopped and its
    /// queue gone), if any.
    fn take_fault(&mut self) -> Option<MotionFault>;

    /// Starts homing; the state is [`MotionState::Homing`] until done
    /// (done well, or a fault).
    fn home(&mut self, request: &HomeRequest) -> Result<(), MotionRefusal>;

    /// The overrides now in force, applied at the next planned point.
    fn set_overrides(&mut self, overrides: Overrides);

    /// The settings changed (or the board started): steps/mm, rates,
    /// accelerations, limits, junction deviation.
    fn configure(&mut self, settings: &Settings);

    /// The fastest step rate an axis makes, steps/s (`$100` × `$110` / 60
    /// above it is `error:12`).
    fn max_step_rate_hz(&self) -> u32;

    /// The most blocks the session queues in one turn (`poll`): a board
    /// whose planning is slow (each block a plan in software `f64`) keeps
    /// its turns short by taking a long arc's chords a few at a time; the
    /// line's `ok` comes once all are queued, as when the planner is full.
    /// Unbounded by default.
    fn blocks_per_poll(&self) -> usize {
        usize::MAX
    }
}

/// The parser state `$G` reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParserState {
    /// The motion mode: 0, 1, 2 or 3 (G0–G3).
    pub motion_mode: u8,
    /// 54 for G54.
    pub coordinate_system: u8,
    /// 17.
    pub plane: u8,
    /// 20 (inches) or 21 (mm).
    pub units: u8,
    /// 90 (absolute) or 91 (incremental).
    pub distance: u8,
    /// 94 (units per minute).
    pub feed_rate_mode: u8,
    /// The feed rate in the programmed units per minute.
    pub feed: f64,
}

impl Default for ParserState {
    fn default() -> Self {
        ParserState {
            motion_mode: 0,
            coordinate_system: 54,
            plane: 17,
            units: 21,
            distance: 90,
            feed_rate_mode: 94,
            feed: 0.0,
        }
    }
}

/// The offsets `$#` reports and `WCO:` adds up, mm.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Offsets {
    /// G54's origin, machine mm.
    pub g54: [f64; GRBL_AXES],
    /// G92's offset, mm.
    pub g92: [f64; GRBL_AXES],
}

impl Offsets {
    /// The work coordinate offset: work position = machine − this.
    pub fn wco(&self) -> [f64; GRBL_AXES] {
        let mut wco = [0.0; GRBL_AXES];
        for (axis, value) in wco.iter_mut().enumerate() {
            *value = self.g54[axis] + self.g92[axis];
        }
        wco
    }
}

/// `emit` as an interpreter that emits every block calls it: the blocks
/// after the first one `emit` did not want are dropped.
pub(super) fn while_wanted(
    emit: &mut dyn FnMut(&MotionBlock) -> bool,
) -> impl FnMut(&MotionBlock) + '_ {
    let mut wanted = true;
    move |block| {
        if wanted {
            wanted = emit(block);
        }
    }
}

/// A G-code interpreter: one line in, motion blocks out.
///
/// `Clone` because a line whose blocks do not all fit the planner at once
/// (an arc of many segments) is interpreted again from the state before
/// it once room frees up, the blocks already queued skipped; the
/// interpretation must therefore be a function of the state and the line.
pub trait GcodeInterpreter: Clone {
    /// Interprets one line (grbl's form: upper case, no blanks, no
    /// comments), emitting its blocks in order. `jog` for a `$J=` line's
    /// text after the `=`: only G20/G21, G90/G91, G53, axis words and F,
    /// and F required (`error:16` else). An error leaves the state as it was
    /// and emits nothing.
    fn interpret(
        &mut self,
        line_no: u32,
        text: &str,
        jog: bool,
        settings: &Settings,
        emit: &mut dyn FnMut(&MotionBlock),
    ) -> Result<(), GrblError>;

    /// [`Self::interpret`] for a caller that takes the blocks a few at a
    /// time: `emit` returns whether it wants the next block (the
    /// interpreter may then leave the rest of an arc's chords unworked;
    /// the state still ends where the whole line ends). `check` false: the
    /// same line again from the same state, which passed once (the
    /// interpreter may leave out the dry run that finds an error before any
    /// block goes out). By default [`Self::interpret`], the blocks not
    /// wanted dropped.
    fn interpret_part(
        &mut self,
        line_no: u32,
        text: &str,
        jog: bool,
        settings: &Settings,
        _check: bool,
        emit: &mut dyn FnMut(&MotionBlock) -> bool,
    ) -> Result<(), GrblError> {
        self.interpret(line_no, text, jog, settings, &mut while_wanted(emit))
    }

    /// Where the program is, after a jog cancel, a reset or homing: the
    /// machine position in steps.
    fn sync_position(&mut self, steps: &[i64; GRBL_AXES], settings: &Settings);

    /// A soft reset: modal state back to its defaults (G92 cleared).
    fn reset(&mut self);

    /// The modal state (`$G`).
    fn parser_state(&self) -> ParserState;

    /// The offsets (`$#`, `WCO:`).
    fn offsets(&self) -> Offsets;

    /// Whether the last line changed an offset (then the next report shows
    /// `WCO:`); cleared by the call.
    fn take_offsets_changed(&mut self) -> bool {
        false
    }
}

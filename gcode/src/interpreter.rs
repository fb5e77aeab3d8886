//! The interpreter: the modal state (G90/G91, G20/G21, G92 offsets, the
//! feed, the motion mode, G61/G64) and the position, in machine mm and in
//! steps; one line of text in, its blocks out.
//!
//! # A line
//!
//! A line's words are checked and its effects computed on a copy of the
//! state before anything is yielded: a line yields all of its blocks and
//! changes the state, or yields nothing, returns the error and changes
//! nothing. Within a line the order is grbl's: units (G20/G21), distance
//! mode, blending and the feed (in the line's units) first; then the
//! dwell, homing (G28) or the offset (G92); then the motion; then M0, M2
//! or M30. The blocks come in that order.
//!
//! # Positions
//!
//! The position is kept in machine mm exactly as programmed (work
//! position + G92 offset); a block's `target_steps` is that position times
//! steps/mm, rounded half away from zero. A move shorter than half a step
//! on every axis yields nothing but still moves the programmed position,
//! so rounding never accumulates.
//!
//! # What is not here
//!
//! G28 homes and ignores its axis values (grbl moves through them first);
//! after M2/M30 the state is kept as it is (no reset). Soft limits are
//! checked in machine coordinates on every block's end (an arc's chord
//! ends) for the axes that move; the machine starts at 0 on every axis.

use core::cell::Cell;

use cogstep_motion::planner::{Blending, MAX_AXES};

use crate::arc::{ArcFault, ArcPath, Turn};
use crate::block::Block;
use crate::error::{GcodeError, GcodeErrorKind};
use crate::machine::MachineSpec;
use crate::words::{scan, Fault, Word};

/// The modal motion mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// G0 (the mode at the start, as in grbl).
    Rapid,
    /// G1.
    Linear,
    /// G2.
    ArcClockwise,
    /// G3.
    ArcCounterClockwise,
}

/// Millimetres (G21, at the start) or inches (G20).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Units {
    /// G21.
    Millimetres,
    /// G20.
    Inches,
}

impl Units {
    /// mm per unit.
    pub fn mm(self) -> f64 {
        match self {
            Units::Millimetres => 1.0,
            Units::Inches => 25.4,
        }
    }
}

/// Absolute (G90, at the start) or incremental (G91) axis words.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Distance {
    /// G90.
    Absolute,
    /// G91.
    Incremental,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum NonModal {
    Dwell,
    Home,
    SetOffset,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stop {
    Pause,
    End,
}

/// A value and the column of its word.
type At<T> = Option<(T, u32)>;

/// One line's words, sorted by what they do.
#[derive(Clone, Copy, Debug, Default)]
struct Words {
    motion: At<Motion>,
    non_modal: At<NonModal>,
    distance: At<Distance>,
    units: At<Units>,
    blending: At<Blending>,
    plane: At<()>,
    stop: At<Stop>,
    line_number: At<f64>,
    axes: [At<f64>; MAX_AXES],
    feed: At<f64>,
    dwell: At<f64>,
    i: At<f64>,
    j: At<f64>,
    r: At<f64>,
}

impl Words {
    fn first_axis_column(&self) -> Option<u32> {
        self.axes.iter().flatten().map(|&(_, column)| column).min()
    }

    fn has_axis_words(&self) -> bool {
        self.axes.iter().any(Option::is_some)
    }
}

fn put<T>(slot: &mut At<T>, value: T, column: u32, twice: GcodeErrorKind) -> Result<(), Fault> {
    if slot.is_some() {
        return Err((column, twice));
    }
    *slot = Some((value, column));
    Ok(())
}

fn sort_word(words: &mut Words, word: Word, spec: &MachineSpec) -> Result<(), Fault> {
    let Word {
        letter,
        value,
        column,
    } = word;
    let conflict = GcodeErrorKind::ModalGroupConflict;
    let unsupported = Err((column, GcodeErrorKind::UnsupportedWord(letter, value)));
    let code = if libm::trunc(value) == value && (0.0..1000.0).contains(&value) {
        Some(value as u32)
    } else {
        None
    };
    match letter {
        'G' => match code {
            Some(0) => put(
                &mut words.motion,
                Motion::Rapid,
                column,
                GcodeErrorKind::TwoMotionWordsOnOneLine,
            ),
            Some(1) => put(
                &mut words.motion,
                Motion::Linear,
                column,
                GcodeErrorKind::TwoMotionWordsOnOneLine,
            ),
            Some(2) => put(
                &mut words.motion,
                Motion::ArcClockwise,
                column,
                GcodeErrorKind::TwoMotionWordsOnOneLine,
            ),
            Some(3) => put(
                &mut words.motion,
                Motion::ArcCounterClockwise,
                column,
                GcodeErrorKind::TwoMotionWordsOnOneLine,
            ),
            Some(4) => put(&mut words.non_modal, NonModal::Dwell, column, conflict),
            Some(28) => put(&mut words.non_modal, NonModal::Home, column, conflict),
            Some(92) => put(&mut words.non_modal, NonModal::SetOffset, column, conflict),
            Some(17) => put(&mut words.plane, (), column, conflict),
            Some(20) => put(&mut words.units, Units::Inches, column, conflict),
            Some(21) => put(&mut words.units, Units::Millimetres, column, conflict),
            Some(90) => put(&mut words.distance, Distance::Absolute, column, conflict),
            Some(91) => put(&mut words.distance, Distance::Incremental, column, conflict),
            Some(61) => put(&mut words.blending, Blending::ExactStop, column, conflict),
            Some(64) => put(&mut words.blending, Blending::Blend, column, conflict),
            _ => unsupported,
        },
        'M' => match code {
            Some(0) => put(&mut words.stop, Stop::Pause, column, conflict),
            Some(2 | 30) => put(&mut words.stop, Stop::End, column, conflict),
            _ => unsupported,
        },
        'N' => put(
            &mut words.line_number,
            value,
            column,
            GcodeErrorKind::RepeatedWord('N'),
        ),
        'F' => put(
            &mut words.feed,
            value,
            column,
            GcodeErrorKind::RepeatedWord('F'),
        ),
        'P' => put(
            &mut words.dwell,
            value,
            column,
            GcodeErrorKind::RepeatedWord('P'),
        ),
        'I' => put(
            &mut words.i,
            value,
            column,
            GcodeErrorKind::RepeatedWord('I'),
        ),
        'J' => put(
            &mut words.j,
            value,
            column,
            GcodeErrorKind::RepeatedWord('J'),
        ),
        'R' => put(
            &mut words.r,
            value,
            column,
            GcodeErrorKind::RepeatedWord('R'),
        ),
        'X' | 'Y' | 'Z' | 'A' | 'B' | 'C' | 'U' | 'V' | 'W' => {
            let index = spec
                .axis_index(letter)
                .ok_or((column, GcodeErrorKind::UnknownAxis(letter)))?;
            put(
                &mut words.axes[index],
                value,
                column,
                GcodeErrorKind::RepeatedWord(letter),
            )
        }
        _ => unsupported,
    }
}

/// The modal state and the position.
#[derive(Clone, Copy, Debug, PartialEq)]
struct State {
    motion: Motion,
    distance: Distance,
    units: Units,
    blending: Blending,
    feed_mm_s: Option<f64>,
    /// G92: work position = machine position − offset (mm).
    offset_mm: [f64; MAX_AXES],
    /// The programmed machine position (mm).
    position_mm: [f64; MAX_AXES],
    /// `position_mm` rounded to steps.
    position_steps: [i64; MAX_AXES],
}

/// The G-code interpreter for one machine: modal state and position in,
/// a line at a time; blocks out. `no_std`, no allocation.
#[derive(Clone, Debug)]
pub struct Interpreter {
    spec: MachineSpec,
    state: State,
}

/// The largest |position| in steps: positions stay exact in `f64`.
const MAX_POSITION_STEPS: f64 = 9_007_199_254_740_992.0; // 2^53

impl Interpreter {
    /// An interpreter at machine position 0 on every axis, in G0, G90,
    /// G21, G17, G64, no feed, no offsets.
    pub fn new(spec: &MachineSpec) -> Interpreter {
        Interpreter {
            spec: *spec,
            state: State {
                motion: Motion::Rapid,
                distance: Distance::Absolute,
                units: Units::Millimetres,
                blending: Blending::Blend,
                feed_mm_s: None,
                offset_mm: [0.0; MAX_AXES],
                position_mm: [0.0; MAX_AXES],
                position_steps: [0; MAX_AXES],
            },
        }
    }

    /// The machine.
    pub fn spec(&self) -> &MachineSpec {
        &self.spec
    }

    /// Interprets one line (`line_no` is carried into its blocks and
    /// errors): calls `out` with each of its blocks and updates the
    /// state, or returns the first error, having called `out` for none
    /// and changed nothing.
    pub fn interpret_line<F: FnMut(Block)>(
        &mut self,
        line_no: u32,
        text: &str,
        out: &mut F,
    ) -> Result<(), GcodeError> {
        self.interpret_line_part(line_no, text, true, &mut |block| {
            out(block);
            true
        })
    }

    /// [`Self::interpret_line`] for a caller that takes a line's blocks a
    /// few at a time (a board's main loop, whose planner has room for some
    /// and whose turns must stay short): `out` returns whether it wants the
    /// next block. Once it does not, the rest of an arc's chords are not
    /// worked out (each a sine and a cosine, in software on a small core);
    /// the state still ends where the whole line ends. With `check` false
    /// the dry run that finds an error before any block goes out is left
    /// out: for the same line from the same state again, which passed it
    /// (its blocks come out the same).
    pub fn interpret_line_part<F: FnMut(Block) -> bool>(
        &mut self,
        line_no: u32,
        text: &str,
        check: bool,
        out: &mut F,
    ) -> Result<(), GcodeError> {
        let at = |(column, kind): Fault| GcodeError {
            line: line_no,
            column,
            kind,
        };
        let mut words = Words::default();
        scan(text, |word| sort_word(&mut words, word, &self.spec)).map_err(at)?;
        // A dry run on a copy finds any error before a block goes out.
        let all = Cell::new(true);
        let mut dry = self.state;
        if check {
            self.execute(line_no, &words, &mut dry, &all, true, &mut |_| {})
                .map_err(at)?;
        }
        let wanted = Cell::new(true);
        let mut next = self.state;
        let real = self.execute(line_no, &words, &mut next, &wanted, false, &mut |block| {
            if wanted.get() {
                wanted.set(out(block));
            }
        });
        debug_assert!(
            !check || (real.is_ok() && next == dry),
            "the dry run is the run"
        );
        real.map_err(at)?;
        self.state = next;
        Ok(())
    }

    /// Puts the machine at `position_steps` (per axis in file order; the
    /// entries past the machine's axes are ignored), as a job starting
    /// where the axes are would: the programmed position becomes the
    /// steps over steps/mm. The modal state and the G92 offsets stay.
    pub fn set_position_steps(&mut self, position_steps: [i64; MAX_AXES]) {
        for (index, axis) in self.spec.axes().iter().enumerate() {
            self.state.position_steps[index] = position_steps[index];
            self.state.position_mm[index] = position_steps[index] as f64 / axis.steps_per_mm;
        }
    }

    /// The programmed machine position (mm), per axis in file order.
    pub fn position_mm(&self) -> [f64; MAX_AXES] {
        self.state.position_mm
    }

    /// The machine position in steps: the last block's `target_steps`.
    pub fn position_steps(&self) -> [i64; MAX_AXES] {
        self.state.position_steps
    }

    /// The work position (mm): the machine position less the G92 offsets.
    pub fn work_position_mm(&self) -> [f64; MAX_AXES] {
        let mut work = self.state.position_mm;
        for (axis, offset) in work.iter_mut().zip(&self.state.offset_mm) {
            *axis -= offset;
        }
        work
    }

    /// The G92 offsets (mm): machine position − work position.
    pub fn offsets_mm(&self) -> [f64; MAX_AXES] {
        self.state.offset_mm
    }

    /// The feed (mm/s), once an F has been read.
    pub fn feed_mm_s(&self) -> Option<f64> {
        self.state.feed_mm_s
    }

    /// The modal motion mode.
    pub fn motion(&self) -> Motion {
        self.state.motion
    }

    /// G90 or G91.
    pub fn distance(&self) -> Distance {
        self.state.distance
    }

    /// G21 or G20.
    pub fn units(&self) -> Units {
        self.state.units
    }

    /// G61 or G64.
    pub fn blending(&self) -> Blending {
        self.state.blending
    }

    /// Carries out one line on `state`, calling `out` with its blocks.
    /// The line's effect on `state`, its blocks to `out`; an arc stops
    /// working out its chords once `wanted` is false.
    fn execute<F: FnMut(Block)>(
        &self,
        line: u32,
        words: &Words,
        state: &mut State,
        wanted: &Cell<bool>,
        dry: bool,
        out: &mut F,
    ) -> Result<(), Fault> {
        let spec = &self.spec;
        let axis_count = spec.axis_count();
        // Where an error of the line as a whole is reported: the motion
        // word, or the first axis word, or the first of I, J, R.
        let line_column = words
            .motion
            .map(|(_, column)| column)
            .or(words.first_axis_column())
            .or([words.i, words.j, words.r]
                .iter()
                .flatten()
                .map(|&(_, column)| column)
                .min())
            .unwrap_or(1);

        if let Some((units, _)) = words.units {
            state.units = units;
        }
        if let Some((distance, _)) = words.distance {
            state.distance = distance;
        }
        if let Some((mode, _)) = words.blending {
            state.blending = mode;
            out(Block::Blending { line, mode });
        }
        if let Some((feed, column)) = words.feed {
            let feed_mm_s = feed * state.units.mm() / 60.0;
            if !(feed > 0.0 && feed_mm_s.is_finite()) {
                return Err((column, GcodeErrorKind::NumberOutOfRange));
            }
            state.feed_mm_s = Some(feed_mm_s);
        }
        if let Some((motion, _)) = words.motion {
            state.motion = motion;
        }

        // The non-modal words, and whether the axis words are theirs.
        let mut axes_taken = false;
        match words.non_modal {
            Some((NonModal::Dwell, column)) => {
                let (seconds, p_column) = words
                    .dwell
                    .ok_or((column, GcodeErrorKind::MissingDwellTime))?;
                if seconds < 0.0 {
                    return Err((p_column, GcodeErrorKind::NumberOutOfRange));
                }
                out(Block::Dwell { line, seconds });
            }
            Some((NonModal::Home, column)) => {
                if words.motion.is_some() {
                    return Err((column, GcodeErrorKind::ModalGroupConflict));
                }
                axes_taken = true;
                let homable = spec.homable_axes();
                let named = (0..axis_count)
                    .filter(|&axis| words.axes[axis].is_some())
                    .fold(0u8, |mask, axis| mask | 1 << axis);
                if let Some(axis) = (0..axis_count).find(|&axis| named & !homable & 1 << axis != 0)
                {
                    let column = words.axes[axis].map_or(column, |(_, at)| at);
                    return Err((column, GcodeErrorKind::NoHomeSwitch(spec.letters()[axis])));
                }
                let axes = if named == 0 { homable } else { named };
                for (index, axis) in spec.axes().iter().enumerate() {
                    if axes & 1 << index != 0 {
                        let home_mm = axis.home_position_mm().unwrap_or(0.0);
                        state.position_mm[index] = home_mm;
                        state.position_steps[index] = to_steps(home_mm * axis.steps_per_mm)
                            .ok_or((column, GcodeErrorKind::NumberOutOfRange))?;
                    }
                }
                if axes != 0 {
                    out(Block::Home { line, axes });
                }
            }
            Some((NonModal::SetOffset, column)) => {
                if words.motion.is_some() {
                    return Err((column, GcodeErrorKind::ModalGroupConflict));
                }
                if !words.has_axis_words() {
                    return Err((column, GcodeErrorKind::MissingAxisWord));
                }
                axes_taken = true;
                for axis in 0..axis_count {
                    if let Some((value, axis_column)) = words.axes[axis] {
                        let offset = state.position_mm[axis] - value * state.units.mm();
                        if !offset.is_finite() {
                            return Err((axis_column, GcodeErrorKind::NumberOutOfRange));
                        }
                        state.offset_mm[axis] = offset;
                    }
                }
            }
            None => {}
        }
        if words.non_modal.map(|(kind, _)| kind) != Some(NonModal::Dwell) {
            if let Some((_, column)) = words.dwell {
                return Err((column, GcodeErrorKind::UnusedWord('P')));
            }
        }

        // The motion.
        let arc = matches!(
            state.motion,
            Motion::ArcClockwise | Motion::ArcCounterClockwise
        );
        let arc_words = [(words.i, 'I'), (words.j, 'J'), (words.r, 'R')];
        if !arc || axes_taken {
            if let Some((letter, column)) = arc_words
                .iter()
                .find_map(|(word, letter)| word.map(|(_, column)| (*letter, column)))
            {
                return Err((column, GcodeErrorKind::UnusedWord(letter)));
            }
        }
        let moves = !axes_taken
            && (words.has_axis_words()
                || (arc && arc_words.iter().any(|(word, _)| word.is_some())));
        if moves {
            if state.motion != Motion::Rapid && state.feed_mm_s.is_none() {
                return Err((line_column, GcodeErrorKind::MissingFeed));
            }
            let mut target_mm = state.position_mm;
            // Axis words past the machine's axes are never set.
            for (axis, (target, word)) in target_mm.iter_mut().zip(&words.axes).enumerate() {
                if let Some((value, column)) = *word {
                    let value_mm = value * state.units.mm();
                    *target = match state.distance {
                        Distance::Absolute => value_mm + state.offset_mm[axis],
                        Distance::Incremental => state.position_mm[axis] + value_mm,
                    };
                    if !target.is_finite() {
                        return Err((column, GcodeErrorKind::NumberOutOfRange));
                    }
                }
            }
            let mut mover = Mover {
                spec,
                words,
                line,
                line_column,
                rapid: state.motion == Motion::Rapid,
                feed_mm_s: state.feed_mm_s.unwrap_or(f64::INFINITY),
                wanted,
                dry,
            };
            match state.motion {
                Motion::Rapid | Motion::Linear => mover.line_to(state, target_mm, out)?,
                Motion::ArcClockwise => mover.arc_to(state, target_mm, Turn::Clockwise, out)?,
                Motion::ArcCounterClockwise => {
                    mover.arc_to(state, target_mm, Turn::CounterClockwise, out)?
                }
            }
        }

        match words.stop {
            Some((Stop::Pause, _)) => out(Block::Pause { line }),
            Some((Stop::End, _)) => out(Block::End { line }),
            None => {}
        }
        Ok(())
    }
}

/// Steps from a position in steps (unrounded); `None` beyond ±2^53.
fn to_steps(position: f64) -> Option<i64> {
    (position.abs() <= MAX_POSITION_STEPS).then(|| libm::round(position) as i64)
}

/// What the lines of one G-code line share.
struct Mover<'a> {
    spec: &'a MachineSpec,
    words: &'a Words,
    line: u32,
    line_column: u32,
    rapid: bool,
    feed_mm_s: f64,
    /// Whether the caller still wants blocks (an arc's chords past it are
    /// not worked out).
    wanted: &'a Cell<bool>,
    /// The dry run, which only looks for an error.
    dry: bool,
}

impl Mover<'_> {
    /// The column an error of `axis` is reported at.
    fn axis_column(&self, axis: usize) -> u32 {
        self.words.axes[axis].map_or(self.line_column, |(_, column)| column)
    }

    /// One straight move to `target_mm` (machine mm): checked, yielded
    /// unless it rounds to no step, and the state moved there.
    fn line_to<F: FnMut(Block)>(
        &mut self,
        state: &mut State,
        target_mm: [f64; MAX_AXES],
        out: &mut F,
    ) -> Result<(), Fault> {
        let mut target_steps = state.position_steps;
        let mut steps = [0i32; MAX_AXES];
        let mut length_sq = 0.0;
        for (index, axis) in self.spec.axes().iter().enumerate() {
            let target = target_mm[index];
            if target == state.position_mm[index] {
                continue;
            }
            let column = self.axis_column(index);
            let beyond_min = axis.soft_min_mm.is_some_and(|min| target < min);
            let beyond_max = axis.soft_max_mm.is_some_and(|max| target > max);
            if beyond_min || beyond_max {
                return Err((
                    column,
                    GcodeErrorKind::BeyondSoftLimit { axis: axis.letter },
                ));
            }
            let out_of_range = (column, GcodeErrorKind::NumberOutOfRange);
            target_steps[index] = to_steps(target * axis.steps_per_mm).ok_or(out_of_range)?;
            steps[index] = i32::try_from(target_steps[index] - state.position_steps[index])
                .map_err(|_| out_of_range)?;
            let delta_mm = f64::from(steps[index]) / axis.steps_per_mm;
            length_sq += delta_mm * delta_mm;
        }
        state.position_mm = target_mm;
        if steps.iter().all(|&axis_steps| axis_steps == 0) {
            return Ok(());
        }
        state.position_steps = target_steps;
        out(Block::Line {
            line: self.line,
            steps,
            target_steps,
            feed_mm_s: if self.rapid {
                f64::INFINITY
            } else {
                self.feed_mm_s
            },
            length_mm: libm::sqrt(length_sq),
            rapid: self.rapid,
        });
        Ok(())
    }

    /// An arc in XY to `target_mm`, the other axes linear along it (a
    /// helix for Z): its chords, each a line.
    fn arc_to<F: FnMut(Block)>(
        &mut self,
        state: &mut State,
        target_mm: [f64; MAX_AXES],
        turn: Turn,
        out: &mut F,
    ) -> Result<(), Fault> {
        let words = self.words;
        let column = self.line_column;
        let x = self
            .spec
            .axis_index('x')
            .ok_or((column, GcodeErrorKind::UnknownAxis('X')))?;
        let y = self
            .spec
            .axis_index('y')
            .ok_or((column, GcodeErrorKind::UnknownAxis('Y')))?;
        let start_mm = state.position_mm;
        let start = [start_mm[x], start_mm[y]];
        let end = [target_mm[x], target_mm[y]];
        let tolerance = self.spec.planner().arc_tolerance_mm;
        let unit = state.units.mm();
        let offsets = words.i.or(words.j);
        let path = match (offsets, words.r) {
            (Some(_), Some((_, r_column))) => {
                return Err((r_column, GcodeErrorKind::ArcFormsMixed));
            }
            (Some((_, ij_column)), None) => {
                let ij_column = match (words.i, words.j) {
                    (Some((_, i)), Some((_, j))) => i.min(j),
                    _ => ij_column,
                };
                let offset = [
                    words.i.map_or(0.0, |(i, _)| i * unit),
                    words.j.map_or(0.0, |(j, _)| j * unit),
                ];
                ArcPath::from_centre(start, end, offset, turn, tolerance)
                    .map_err(|fault| (ij_column, arc_error(fault)))?
            }
            (None, Some((radius, r_column))) => {
                ArcPath::from_radius(start, end, radius * unit, turn, tolerance)
                    .map_err(|fault| (r_column, arc_error(fault)))?
            }
            (None, None) => return Err((column, GcodeErrorKind::MissingArcParameter)),
        };
        if self.dry && self.no_chord_can_fail(&path, &start_mm, &target_mm, x, y) {
            // The dry run's verdict without the chords (each a sine and a
            // cosine, in software on a small core): none can fail, so the
            // arc's error is its end's, and its state the end's.
            return self.line_to(state, target_mm, out);
        }
        for index in 0..path.chords {
            if !self.wanted.get() {
                // Not wanted now: straight to where the arc ends (the
                // state the whole arc leaves), its block to no one.
                return self.line_to(state, target_mm, &mut |_| {});
            }
            let point = path.point(index);
            let mut chord_end = target_mm;
            if index + 1 < path.chords {
                let fraction = f64::from(index + 1) / f64::from(path.chords);
                for axis in 0..self.spec.axis_count() {
                    chord_end[axis] =
                        start_mm[axis] + (target_mm[axis] - start_mm[axis]) * fraction;
                }
                chord_end[x] = point[0];
                chord_end[y] = point[1];
            }
            self.line_to(state, chord_end, out)?;
        }
        Ok(())
    }
}

impl Mover<'_> {
    /// Whether every chord of `path` from `start_mm` to `target_mm` is
    /// certain to pass [`Mover::line_to`]'s checks, from bounds alone: the
    /// circle's box on X and Y, the straight axes between their start and
    /// end, within the soft limits and the step range, and no chord's steps
    /// past an `i32`. When it is not certain the dry run works the chords
    /// out, and finds the error a chord has.
    fn no_chord_can_fail(
        &self,
        path: &ArcPath,
        start_mm: &[f64; MAX_AXES],
        target_mm: &[f64; MAX_AXES],
        x: usize,
        y: usize,
    ) -> bool {
        let radius = path.radius;
        self.spec.axes().iter().enumerate().all(|(index, axis)| {
            let (low, high, reach) = if index == x || index == y {
                let centre = path.centre[usize::from(index == y)];
                // The programmed end may be off the circle (up to 0.5 mm):
                // a millimetre more of reach for the step from the start.
                (centre - radius, centre + radius, 2.0 * radius + 1.0)
            } else {
                let (a, b) = (start_mm[index], target_mm[index]);
                (a.min(b), a.max(b), (b - a).abs())
            };
            let steps = axis.steps_per_mm;
            low.is_finite()
                && high.is_finite()
                && axis.soft_min_mm.is_none_or(|min| low >= min)
                && axis.soft_max_mm.is_none_or(|max| high <= max)
                && (low * steps).abs() < MAX_POSITION_STEPS / 2.0
                && (high * steps).abs() < MAX_POSITION_STEPS / 2.0
                && reach * steps + 2.0 < f64::from(i32::MAX)
        })
    }
}

fn arc_error(fault: ArcFault) -> GcodeErrorKind {
    match fault {
        ArcFault::ZeroRadius => GcodeErrorKind::ArcZeroRadius,
        ArcFault::RadiusMismatch => GcodeErrorKind::ArcRadiusMismatch,
        ArcFault::EndIsStart => GcodeErrorKind::ArcEndIsStart,
        ArcFault::TooManyChords => GcodeErrorKind::NumberOutOfRange,
    }
}

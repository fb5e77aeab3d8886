//! The G-code behind the grbl engine: `cogstep-gcode`'s [`Interpreter`]
//! as a [`GcodeInterpreter`].
//!
//! What grbl adds around it: the machine is built from the `$` settings
//! (`$100`… steps/mm, `$110`… rates, `$120`… accelerations, `$11`, `$12`);
//! words grbl accepts that have nothing to drive here (M3–M5, M7–M9, S, T,
//! G54, G94) are dropped before the line is read; `$J=` jogs are read as a
//! G1 on a copy, so that their G90/G91, G20/G21 and F stay out of the
//! program's modes; and the interpreter's errors become grbl's numbers.

use cogstep_gcode::{
    AxisSpec, Block, Distance, GcodeError, GcodeErrorKind, Interpreter, MachineSpec, Motion,
    PlannerSpec, Units,
};
use cogstep_motion::planner::MAX_AXES;

use super::codes::GrblError;
use super::motion::{while_wanted, GcodeInterpreter, MotionBlock, Offsets, ParserState};
use super::settings::Settings;
use super::{GRBL_AXES, LINE_BUFFER_SIZE};

/// The planner queue the machine spec states (the motion's own size
/// decides what is queued).
const QUEUE_LEN: usize = 16;

/// `cogstep-gcode`'s interpreter over a grbl board's settings.
#[derive(Clone, Debug)]
pub struct GrblGcode {
    inner: Interpreter,
    /// The settings the machine was built from.
    built_from: Settings,
    offsets_changed: bool,
}

/// The machine of three axes X, Y, Z from the settings, if they make one.
fn machine_spec(settings: &Settings) -> Option<MachineSpec> {
    let mut axes = [AxisSpec::new('x', 1.0, 1.0, 1.0); GRBL_AXES];
    for (index, (axis, letter)) in axes.iter_mut().zip(['x', 'y', 'z']).enumerate() {
        *axis = AxisSpec::new(
            letter,
            settings.steps_per_mm[index],
            settings.max_rate_mm_min[index] / 60.0,
            settings.accel_mm_s2[index],
        );
    }
    MachineSpec::new(
        &axes,
        PlannerSpec {
            junction_deviation_mm: settings.junction_deviation_mm,
            arc_tolerance_mm: settings.arc_tolerance_mm,
            queue_len: QUEUE_LEN,
        },
    )
    .ok()
}

/// Whether two settings build different machines.
fn machine_differs(a: &Settings, b: &Settings) -> bool {
    a.steps_per_mm != b.steps_per_mm
        || a.max_rate_mm_min != b.max_rate_mm_min
        || a.accel_mm_s2 != b.accel_mm_s2
        || a.junction_deviation_mm != b.junction_deviation_mm
        || a.arc_tolerance_mm != b.arc_tolerance_mm
}

/// The words of a grbl line (upper case, no blanks): `(letter, number
/// text)`, or `None` for a byte that starts no word.
fn words(text: &str) -> impl Iterator<Item = Option<(u8, &str)>> {
    let bytes = text.as_bytes();
    let mut at = 0;
    core::iter::from_fn(move || {
        if at >= bytes.len() {
            return None;
        }
        let letter = bytes[at];
        at += 1;
        if !letter.is_ascii_uppercase() {
            at = bytes.len();
            return Some(None);
        }
        let start = at;
        while at < bytes.len() && !bytes[at].is_ascii_uppercase() {
            at += 1;
        }
        Some(Some((letter, &text[start..at])))
    })
}

/// A word grbl accepts that drives nothing here (spindle, coolant, tool,
/// the one coordinate system, the one feed mode).
fn is_idle_word(letter: u8, number: &str) -> bool {
    let code = number.parse::<f64>().ok();
    match letter {
        b'S' | b'T' => true,
        b'M' => matches!(code, Some(c) if [3.0, 4.0, 5.0, 7.0, 8.0, 9.0].contains(&c)),
        b'G' => matches!(code, Some(c) if c == 54.0 || c == 94.0),
        _ => false,
    }
}

/// `text` (a line as the board keeps it: upper case, no blanks or
/// comments) without the words grbl accepts that drive nothing here (S,
/// T, M3–M5, M7–M9, G54, G94): what the interpreter reads. A line with
/// something that is no word is kept whole, for the interpreter to name
/// the error.
pub fn without_idle_words(text: &str) -> heapless::String<LINE_BUFFER_SIZE> {
    let mut kept: heapless::String<LINE_BUFFER_SIZE> = heapless::String::new();
    for word in words(text) {
        match word {
            Some((letter, number)) if is_idle_word(letter, number) => {}
            Some((letter, number)) => {
                // Words of a line that fitted the buffer fit again.
                let _ = kept.push(char::from(letter));
                let _ = kept.push_str(number);
            }
            None => {
                kept.clear();
                let _ = kept.push_str(text);
                break;
            }
        }
    }
    kept
}

/// grbl's number for an interpreter error on `text`.
fn grbl_error(error: &GcodeError, text: &str) -> GrblError {
    match error.kind {
        GcodeErrorKind::Malformed => {
            let column = usize::try_from(error.column).unwrap_or(0).saturating_sub(1);
            // A letter with a bad number, or something that is no word.
            match text.as_bytes().get(column) {
                Some(byte) if byte.is_ascii_uppercase() => GrblError::BadNumberFormat,
                _ => GrblError::ExpectedCommandLetter,
            }
        }
        GcodeErrorKind::UnsupportedWord(..) | GcodeErrorKind::UnknownAxis(_) => {
            GrblError::UnsupportedCommand
        }
        GcodeErrorKind::RepeatedWord(_) => GrblError::WordRepeated,
        GcodeErrorKind::TwoMotionWordsOnOneLine | GcodeErrorKind::ModalGroupConflict => {
            GrblError::ModalGroupViolation
        }
        GcodeErrorKind::UnusedWord(_) | GcodeErrorKind::ArcFormsMixed => GrblError::UnusedWords,
        GcodeErrorKind::MissingFeed => GrblError::UndefinedFeedRate,
        GcodeErrorKind::MissingDwellTime => GrblError::ValueWordMissing,
        GcodeErrorKind::MissingAxisWord => GrblError::NoAxisWords,
        GcodeErrorKind::MissingArcParameter => GrblError::NoOffsetsInPlane,
        GcodeErrorKind::ArcRadiusMismatch
        | GcodeErrorKind::ArcZeroRadius
        | GcodeErrorKind::ArcEndIsStart
        | GcodeErrorKind::NumberOutOfRange
        | GcodeErrorKind::BeyondSoftLimit { .. } => GrblError::InvalidTarget,
        // grbl's answer to homing it has not been set up for.
        GcodeErrorKind::NoHomeSwitch(_) => GrblError::SettingDisabled,
    }
}

fn first_axes(values: [i64; MAX_AXES]) -> [i64; GRBL_AXES] {
    let mut axes = [0; GRBL_AXES];
    axes.copy_from_slice(&values[..GRBL_AXES]);
    axes
}

impl GrblGcode {
    /// An interpreter at the origin for a machine of `settings`.
    ///
    /// Settings always make a machine (steps/mm, rates, accelerations and
    /// the arc tolerance are above 0, as [`Settings::set`] keeps them);
    /// should they not, grbl's defaults are used.
    pub fn new(settings: &Settings) -> Self {
        let spec = machine_spec(settings)
            .or_else(|| machine_spec(&Settings::default()))
            .unwrap_or_else(unreachable_spec);
        GrblGcode {
            inner: Interpreter::new(&spec),
            built_from: *settings,
            offsets_changed: false,
        }
    }

    /// The interpreter.
    pub fn interpreter(&self) -> &Interpreter {
        &self.inner
    }

    /// Rebuilds the machine when the settings changed; the position stays
    /// (the modes and G92 start over).
    fn follow_settings(&mut self, settings: &Settings) {
        if !machine_differs(&self.built_from, settings) {
            return;
        }
        if let Some(spec) = machine_spec(settings) {
            let position = self.inner.position_steps();
            let offsets = self.inner.offsets_mm();
            self.inner = Interpreter::new(&spec);
            self.inner.set_position_steps(position);
            self.offsets_changed |= offsets.iter().any(|&offset| offset != 0.0);
        }
        self.built_from = *settings;
    }

    fn jog(
        &mut self,
        line_no: u32,
        text: &str,
        emit: &mut dyn FnMut(&MotionBlock),
    ) -> Result<(), GrblError> {
        let mut has_feed = false;
        let mut has_axis = false;
        for word in words(text) {
            let Some((letter, number)) = word else {
                return Err(GrblError::InvalidJogCommand);
            };
            match letter {
                b'X' | b'Y' | b'Z' => has_axis = true,
                b'F' => has_feed = true,
                b'N' => {}
                b'G' if matches!(number, "20" | "21" | "90" | "91") => {}
                // G53 (machine coordinates) is not read by the interpreter.
                b'G' if number == "53" => return Err(GrblError::UnsupportedCommand),
                _ => return Err(GrblError::InvalidJogCommand),
            }
        }
        if !has_feed {
            return Err(GrblError::InvalidJogCommand);
        }
        if !has_axis {
            return Err(GrblError::NoAxisWords);
        }
        let mut line: heapless::String<{ LINE_BUFFER_SIZE + 2 }> = heapless::String::new();
        // A jog's text fitted the line buffer: "G1" and it fit this one.
        let _ = line.push_str("G1");
        let _ = line.push_str(text);
        let mut scratch = self.inner.clone();
        scratch
            .interpret_line(line_no, &line, &mut |block| {
                if let Block::Line {
                    line,
                    target_steps,
                    feed_mm_s,
                    length_mm,
                    ..
                } = block
                {
                    emit(&MotionBlock::Line {
                        line,
                        target_steps: first_axes(target_steps),
                        feed_mm_s,
                        length_mm,
                        rapid: false,
                        jog: true,
                    });
                }
            })
            .map_err(|error| grbl_error(&error, &line))?;
        // A jog moves the program's position and nothing else.
        self.inner.set_position_steps(scratch.position_steps());
        Ok(())
    }
}

/// A machine that always builds (grbl's defaults do).
fn unreachable_spec() -> MachineSpec {
    let axis = AxisSpec::new('x', 1.0, 1.0, 1.0);
    match MachineSpec::new(
        &[axis],
        PlannerSpec {
            junction_deviation_mm: 0.0,
            arc_tolerance_mm: 1.0,
            queue_len: 1,
        },
    ) {
        Ok(spec) => spec,
        Err(_) => unreachable!("a one-axis machine of ones is valid"),
    }
}

impl GcodeInterpreter for GrblGcode {
    fn interpret(
        &mut self,
        line_no: u32,
        text: &str,
        jog: bool,
        settings: &Settings,
        emit: &mut dyn FnMut(&MotionBlock),
    ) -> Result<(), GrblError> {
        self.interpret_part(line_no, text, jog, settings, true, &mut |block| {
            emit(block);
            true
        })
    }

    fn interpret_part(
        &mut self,
        line_no: u32,
        text: &str,
        jog: bool,
        settings: &Settings,
        check: bool,
        emit: &mut dyn FnMut(&MotionBlock) -> bool,
    ) -> Result<(), GrblError> {
        self.follow_settings(settings);
        if jog {
            return self.jog(line_no, text, &mut while_wanted(emit));
        }
        // grbl's G28 goes to a stored position; `$H` homes.
        if words(text).any(|word| word == Some((b'G', "28"))) {
            return Err(GrblError::UnsupportedCommand);
        }
        let kept = without_idle_words(text);
        let offsets_before = self.inner.offsets_mm();
        self.inner
            .interpret_line_part(line_no, &kept, check, &mut |block| match block {
                Block::Line {
                    line,
                    target_steps,
                    feed_mm_s,
                    length_mm,
                    rapid,
                    ..
                } => emit(&MotionBlock::Line {
                    line,
                    target_steps: first_axes(target_steps),
                    feed_mm_s,
                    length_mm,
                    rapid,
                    jog: false,
                }),
                Block::Dwell { line, seconds } => emit(&MotionBlock::Dwell {
                    line,
                    ms: (seconds * 1000.0 + 0.5) as u32,
                }),
                // INTERIM: the motion has no blending switch, pause or end
                // yet (and G28 does not come here).
                Block::Home { .. }
                | Block::Blending { .. }
                | Block::Pause { .. }
                | Block::End { .. } => true,
            })
            .map_err(|error| grbl_error(&error, &kept))?;
        if self.inner.offsets_mm() != offsets_before {
            self.offsets_changed = true;
        }
        Ok(())
    }

    fn sync_position(&mut self, steps: &[i64; GRBL_AXES], settings: &Settings) {
        self.follow_settings(settings);
        let mut position = self.inner.position_steps();
        position[..GRBL_AXES].copy_from_slice(steps);
        self.inner.set_position_steps(position);
    }

    fn reset(&mut self) {
        let position = self.inner.position_steps();
        let offsets = self.inner.offsets_mm();
        self.inner = Interpreter::new(self.inner.spec());
        self.inner.set_position_steps(position);
        self.offsets_changed |= offsets.iter().any(|&offset| offset != 0.0);
    }

    fn parser_state(&self) -> ParserState {
        let units = self.inner.units();
        ParserState {
            motion_mode: match self.inner.motion() {
                Motion::Rapid => 0,
                Motion::Linear => 1,
                Motion::ArcClockwise => 2,
                Motion::ArcCounterClockwise => 3,
            },
            units: match units {
                Units::Inches => 20,
                Units::Millimetres => 21,
            },
            distance: match self.inner.distance() {
                Distance::Absolute => 90,
                Distance::Incremental => 91,
            },
            feed: self.inner.feed_mm_s().unwrap_or(0.0) * 60.0 / units.mm(),
            ..ParserState::default()
        }
    }

    fn offsets(&self) -> Offsets {
        let mut g92 = [0.0; GRBL_AXES];
        g92.copy_from_slice(&self.inner.offsets_mm()[..GRBL_AXES]);
        Offsets {
            g54: [0.0; GRBL_AXES],
            g92,
        }
    }

    fn take_offsets_changed(&mut self) -> bool {
        core::mem::take(&mut self.offsets_changed)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;

    fn run(g: &mut GrblGcode, text: &str, jog: bool) -> Result<Vec<MotionBlock>, GrblError> {
        let mut blocks = Vec::new();
        g.interpret(1, text, jog, &Settings::default(), &mut |b| blocks.push(*b))?;
        Ok(blocks)
    }

    fn end(blocks: &[MotionBlock]) -> [i64; GRBL_AXES] {
        match blocks.last() {
            Some(MotionBlock::Line { target_steps, .. }) => *target_steps,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn lines_arcs_and_grbl_words() {
        let settings = Settings::default();
        let mut g = GrblGcode::new(&settings);
        assert_eq!(run(&mut g, "G17G21G90G94G54M3S1000", false), Ok(Vec::new()));
        assert_eq!(
            end(&run(&mut g, "G0X10Y5", false).unwrap()),
            [2500, 1250, 0]
        );
        assert_eq!(
            run(&mut g, "G1X1", false),
            Err(GrblError::UndefinedFeedRate)
        );
        assert_eq!(
            end(&run(&mut g, "G1X20F600M8", false).unwrap()),
            [5000, 1250, 0]
        );
        let arc = run(&mut g, "G2X30Y5I5J0", false).unwrap();
        assert!(arc.len() > 20);
        assert_eq!(end(&arc), [7500, 1250, 0]);
        assert_eq!(g.parser_state().motion_mode, 2);
        assert_eq!(g.parser_state().feed, 600.0);
        assert_eq!(
            run(&mut g, "G28", false),
            Err(GrblError::UnsupportedCommand)
        );
        assert_eq!(
            run(&mut g, "G1X1.2.3", false),
            Err(GrblError::BadNumberFormat)
        );
        assert_eq!(run(&mut g, "G1X1X2", false), Err(GrblError::WordRepeated));
        assert_eq!(
            run(&mut g, "G0G1X1", false),
            Err(GrblError::ModalGroupViolation)
        );
        assert_eq!(
            run(&mut g, "M99", false),
            Err(GrblError::UnsupportedCommand)
        );
        assert_eq!(run(&mut g, "G4", false), Err(GrblError::ValueWordMissing));
        assert_eq!(
            run(&mut g, "G4P0.25", false).unwrap(),
            [MotionBlock::Dwell { line: 1, ms: 250 }]
        );
    }

    #[test]
    fn g92_and_jogs() {
        let settings = Settings::default();
        let mut g = GrblGcode::new(&settings);
        run(&mut g, "G0X10", false).unwrap();
        run(&mut g, "G92X0", false).unwrap();
        assert!(g.take_offsets_changed());
        assert_eq!(g.offsets().wco(), [10.0, 0.0, 0.0]);
        let jog = run(&mut g, "G91X1F100", true).unwrap();
        assert_eq!(end(&jog), [2750, 0, 0]);
        assert!(matches!(jog[0], MotionBlock::Line { jog: true, .. }));
        // The jog's G91 and F are not the program's.
        assert_eq!(g.parser_state().distance, 90);
        assert_eq!(g.parser_state().feed, 0.0);
        assert_eq!(
            run(&mut g, "G1X1F100", true),
            Err(GrblError::InvalidJogCommand)
        );
        assert_eq!(run(&mut g, "X1", true), Err(GrblError::InvalidJogCommand));
        // The program goes on from the jog's end.
        assert_eq!(end(&run(&mut g, "G0X2", false).unwrap()), [3000, 0, 0]);
    }

    #[test]
    fn a_new_steps_per_mm_keeps_the_position() {
        let mut settings = Settings::default();
        let mut g = GrblGcode::new(&settings);
        run(&mut g, "G0X4", false).unwrap();
        settings.steps_per_mm[0] = 100.0;
        g.sync_position(&[1000, 0, 0], &settings);
        let mut blocks = Vec::new();
        g.interpret(2, "G0X20", false, &settings, &mut |b| blocks.push(*b))
            .unwrap();
        assert_eq!(end(&blocks), [2000, 0, 0]);
    }
}

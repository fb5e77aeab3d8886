//! INTERIM: a small G-code interpreter for the grbl board, until the
//! `cogstep-gcode` crate (issue 25) is merged; then its `Interpreter`
//! implements [`GcodeInterpreter`] and this file goes.
//!
//! It reads what a CNC or plotter file uses: G0, G1, G2, G3 (XY plane, I/J
//! or R, helical Z), G4, G17, G20/G21, G53, G54, G61/G64, G90/G91, G92 and
//! G92.1, G94, M0/M1 (no pause yet), M2/M30, M3–M5 and M7–M9 (no spindle or
//! coolant: accepted), F, N, S, T. Arcs are cut into chords within `$12`.

use cogstep_protocol::grbl::{
    parse_grbl_number, GcodeInterpreter, GrblError, MotionBlock, Offsets, ParserState, Settings,
    GRBL_AXES,
};

const MM_PER_INCH: f64 = 25.4;

/// The program's modal state and position.
#[derive(Clone, Debug)]
pub struct InterimGcode {
    /// The programmed position, machine mm (exact programmed values, so
    /// that rounding never accumulates).
    position_mm: [f64; GRBL_AXES],
    motion_mode: u8,
    inches: bool,
    incremental: bool,
    /// The modal feed, mm/min.
    feed_mm_min: f64,
    g92: [f64; GRBL_AXES],
    offsets_changed: bool,
}

impl Default for InterimGcode {
    fn default() -> Self {
        InterimGcode {
            position_mm: [0.0; GRBL_AXES],
            motion_mode: 0,
            inches: false,
            incremental: false,
            feed_mm_min: 0.0,
            g92: [0.0; GRBL_AXES],
            offsets_changed: false,
        }
    }
}

/// One line's words.
#[derive(Default)]
struct Words {
    motion: Option<u8>,
    units: Option<bool>,
    distance: Option<bool>,
    dwell: bool,
    g53: bool,
    g92: Option<bool>,
    axes: [Option<f64>; GRBL_AXES],
    ijk: [Option<f64>; 3],
    r: Option<f64>,
    f: Option<f64>,
    p: Option<f64>,
    program_end: bool,
    /// A word other than G20/21, G90/91, G53, X, Y, Z, F, N (jogs refuse it).
    not_for_jog: bool,
}

impl Words {
    fn parse(text: &str) -> Result<Words, GrblError> {
        let mut words = Words::default();
        let bytes = text.as_bytes();
        let mut at = 0;
        // Modal groups seen: motion, plane, distance, units, non-modal,
        // coordinate system, path, feed mode, program flow, spindle, coolant.
        let mut groups = [false; 11];
        let mut seen = [false; 26];
        let mut group = |index: usize| -> Result<(), GrblError> {
            if core::mem::replace(&mut groups[index], true) {
                return Err(GrblError::ModalGroupViolation);
            }
            Ok(())
        };
        while at < bytes.len() {
            let letter = bytes[at];
            if !letter.is_ascii_uppercase() {
                return Err(GrblError::ExpectedCommandLetter);
            }
            at += 1;
            let start = at;
            while at < bytes.len() && matches!(bytes[at], b'0'..=b'9' | b'.' | b'-' | b'+') {
                at += 1;
            }
            let value = parse_grbl_number(&text[start..at]).ok_or(GrblError::BadNumberFormat)?;
            match letter {
                b'G' => {
                    let code = (value * 10.0).round() as u32;
                    if code % 10 != 0 && code != 921 {
                        return Err(GrblError::UnsupportedCommand);
                    }
                    match code {
                        0 | 10 | 20 | 30 => {
                            group(0)?;
                            words.motion = Some((code / 10) as u8);
                            words.not_for_jog = true;
                        }
                        170 => {
                            group(1)?;
                            words.not_for_jog = true;
                        }
                        900 | 910 => {
                            group(2)?;
                            words.distance = Some(code == 910);
                        }
                        200 | 210 => {
                            group(3)?;
                            words.units = Some(code == 200);
                        }
                        40 => {
                            group(4)?;
                            words.dwell = true;
                            words.not_for_jog = true;
                        }
                        530 => {
                            group(4)?;
                            words.g53 = true;
                        }
                        920 | 921 => {
                            group(4)?;
                            words.g92 = Some(code == 920);
                            words.not_for_jog = true;
                        }
                        540 => {
                            group(5)?;
                            words.not_for_jog = true;
                        }
                        610 | 640 => {
                            group(6)?;
                            words.not_for_jog = true;
                        }
                        940 => {
                            group(7)?;
                            words.not_for_jog = true;
                        }
                        _ => return Err(GrblError::UnsupportedCommand),
                    }
                }
                b'M' => {
                    if value.fract() != 0.0 {
                        return Err(GrblError::UnsupportedCommand);
                    }
                    words.not_for_jog = true;
                    match value as u32 {
                        0 | 1 => group(8)?,
                        2 | 30 => {
                            group(8)?;
                            words.program_end = true;
                        }
                        3..=5 => group(9)?,
                        7..=9 => group(10)?,
                        _ => return Err(GrblError::UnsupportedCommand),
                    }
                }
                _ => {
                    let index = usize::from(letter - b'A');
                    if core::mem::replace(&mut seen[index], true) {
                        return Err(GrblError::WordRepeated);
                    }
                    match letter {
                        b'X' => words.axes[0] = Some(value),
                        b'Y' => words.axes[1] = Some(value),
                        b'Z' => words.axes[2] = Some(value),
                        b'I' | b'J' | b'K' => words.ijk[usize::from(letter - b'I')] = Some(value),
                        b'R' => words.r = Some(value),
                        b'F' => {
                            if value < 0.0 {
                                return Err(GrblError::NegativeValue);
                            }
                            words.f = Some(value);
                        }
                        b'P' => words.p = Some(value),
                        b'N' => {
                            if value < 0.0 || value.fract() != 0.0 || value > 9_999_999.0 {
                                return Err(GrblError::InvalidLineNumber);
                            }
                        }
                        b'S' | b'T' => {}
                        _ => return Err(GrblError::UnsupportedCommand),
                    }
                    if !matches!(letter, b'X' | b'Y' | b'Z' | b'F' | b'N') {
                        words.not_for_jog = true;
                    }
                }
            }
        }
        Ok(words)
    }

    fn has_axes(&self) -> bool {
        self.axes.iter().any(Option::is_some)
    }
}

impl InterimGcode {
    /// A program at the origin, grbl's power-up modes.
    pub fn new() -> Self {
        InterimGcode::default()
    }

    fn unit_mm(&self, inches: bool, value: f64) -> f64 {
        if inches {
            value * MM_PER_INCH
        } else {
            value
        }
    }

    /// The end point of axis words, machine mm.
    fn target(
        &self,
        words: &Words,
        inches: bool,
        incremental: bool,
        machine: bool,
    ) -> [f64; GRBL_AXES] {
        let mut target = self.position_mm;
        for axis in 0..GRBL_AXES {
            if let Some(value) = words.axes[axis] {
                let mm = self.unit_mm(inches, value);
                target[axis] = if incremental && !machine {
                    self.position_mm[axis] + mm
                } else if machine {
                    mm
                } else {
                    mm + self.g92[axis]
                };
            }
        }
        target
    }
}

fn to_steps(mm: &[f64; GRBL_AXES], settings: &Settings) -> [i64; GRBL_AXES] {
    let mut steps = [0; GRBL_AXES];
    for axis in 0..GRBL_AXES {
        steps[axis] = (mm[axis] * settings.steps_per_mm[axis]).round() as i64;
    }
    steps
}

fn distance(a: &[f64; GRBL_AXES], b: &[f64; GRBL_AXES]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (b - a) * (b - a))
        .sum::<f64>()
        .sqrt()
}

/// The fastest feed along a line that no axis's `$110`… passes, mm/s.
fn rapid_feed_mm_s(from: &[f64; GRBL_AXES], to: &[f64; GRBL_AXES], settings: &Settings) -> f64 {
    let length = distance(from, to);
    let mut feed = f64::INFINITY;
    for axis in 0..GRBL_AXES {
        let delta = (to[axis] - from[axis]).abs();
        if delta > 0.0 {
            feed = feed.min(settings.max_rate_mm_min[axis] / 60.0 * length / delta);
        }
    }
    if feed.is_finite() {
        feed
    } else {
        0.0
    }
}

impl GcodeInterpreter for InterimGcode {
    fn interpret(
        &mut self,
        line_no: u32,
        text: &str,
        jog: bool,
        settings: &Settings,
        emit: &mut dyn FnMut(&MotionBlock),
    ) -> Result<(), GrblError> {
        let words = Words::parse(text)?;
        let inches = words.units.unwrap_or(self.inches);
        let incremental = words.distance.unwrap_or(self.incremental);
        if jog {
            if words.not_for_jog {
                return Err(GrblError::InvalidJogCommand);
            }
            let Some(feed) = words.f else {
                return Err(GrblError::InvalidJogCommand);
            };
            if !words.has_axes() {
                return Err(GrblError::NoAxisWords);
            }
            let target = self.target(&words, inches, incremental, words.g53);
            let feed_mm_s = self.unit_mm(inches, feed) / 60.0;
            if feed_mm_s <= 0.0 {
                return Err(GrblError::InvalidJogCommand);
            }
            emit(&MotionBlock::Line {
                line: line_no,
                target_steps: to_steps(&target, settings),
                feed_mm_s,
                length_mm: distance(&self.position_mm, &target),
                rapid: false,
                jog: true,
            });
            // A jog moves the program's position, and nothing else.
            self.position_mm = target;
            return Ok(());
        }
        // Checks first: an error leaves everything as it was.
        let mut next = self.clone();
        next.inches = inches;
        next.incremental = incremental;
        if let Some(feed) = words.f {
            next.feed_mm_min = next.unit_mm(inches, feed);
        }
        if let Some(mode) = words.motion {
            next.motion_mode = mode;
        }
        let arc_words = words.ijk.iter().any(Option::is_some) || words.r.is_some();
        if let Some(set) = words.g92 {
            if words.motion.is_some() {
                return Err(GrblError::AxisCommandConflict);
            }
            if set {
                if !words.has_axes() {
                    return Err(GrblError::NoAxisWords);
                }
                for axis in 0..GRBL_AXES {
                    if let Some(value) = words.axes[axis] {
                        next.g92[axis] = self.position_mm[axis] - next.unit_mm(inches, value);
                    }
                }
            } else {
                next.g92 = [0.0; GRBL_AXES];
            }
            next.offsets_changed = true;
            if arc_words {
                return Err(GrblError::UnusedWords);
            }
            *self = next;
            return Ok(());
        }
        if words.dwell {
            let seconds = words.p.ok_or(GrblError::ValueWordMissing)?;
            if seconds < 0.0 {
                return Err(GrblError::NegativeValue);
            }
            if words.has_axes() && words.motion.is_none() {
                return Err(GrblError::AxisWordsExist);
            }
        } else if words.p.is_some() {
            return Err(GrblError::UnusedWords);
        }
        let mut blocks: Vec<MotionBlock> = Vec::new();
        if words.dwell {
            let seconds = words.p.unwrap_or(0.0);
            blocks.push(MotionBlock::Dwell {
                line: line_no,
                ms: (seconds * 1000.0).round() as u32,
            });
        }
        let moves = words.has_axes() || (words.motion.is_some() && arc_words);
        if moves {
            let target = next.target(&words, inches, incremental, words.g53);
            if words.g53 && !matches!(next.motion_mode, 0 | 1) {
                return Err(GrblError::UnsupportedCommand);
            }
            let start = self.position_mm;
            match next.motion_mode {
                0 => blocks.push(MotionBlock::Line {
                    line: line_no,
                    target_steps: to_steps(&target, settings),
                    feed_mm_s: rapid_feed_mm_s(&start, &target, settings),
                    length_mm: distance(&start, &target),
                    rapid: true,
                    jog: false,
                }),
                mode => {
                    if next.feed_mm_min <= 0.0 {
                        return Err(GrblError::UndefinedFeedRate);
                    }
                    let feed_mm_s = next.feed_mm_min / 60.0;
                    let points = if mode == 1 {
                        if arc_words {
                            return Err(GrblError::UnusedWords);
                        }
                        vec![target]
                    } else {
                        arc_points(&words, &next, inches, &start, &target, mode == 2, settings)?
                    };
                    let mut from = start;
                    for point in points {
                        blocks.push(MotionBlock::Line {
                            line: line_no,
                            target_steps: to_steps(&point, settings),
                            feed_mm_s,
                            length_mm: distance(&from, &point),
                            rapid: false,
                            jog: false,
                        });
                        from = point;
                    }
                }
            }
            next.position_mm = target;
        } else if arc_words {
            return Err(GrblError::UnusedWords);
        } else if words.motion.is_some_and(|mode| mode != 0) && !words.program_end {
            // grbl: a G1–G3 without axis words only sets the mode.
        }
        if words.program_end {
            next.motion_mode = 1;
            next.incremental = false;
        }
        *self = next;
        for block in &blocks {
            emit(block);
        }
        Ok(())
    }

    fn sync_position(&mut self, steps: &[i64; GRBL_AXES], settings: &Settings) {
        for axis in 0..GRBL_AXES {
            self.position_mm[axis] = steps[axis] as f64 / settings.steps_per_mm[axis];
        }
    }

    fn reset(&mut self) {
        let position = self.position_mm;
        *self = InterimGcode {
            position_mm: position,
            ..InterimGcode::default()
        };
        self.offsets_changed = true;
    }

    fn parser_state(&self) -> ParserState {
        ParserState {
            motion_mode: self.motion_mode,
            units: if self.inches { 20 } else { 21 },
            distance: if self.incremental { 91 } else { 90 },
            feed: if self.inches {
                self.feed_mm_min / MM_PER_INCH
            } else {
                self.feed_mm_min
            },
            ..ParserState::default()
        }
    }

    fn offsets(&self) -> Offsets {
        Offsets {
            g54: [0.0; GRBL_AXES],
            g92: self.g92,
        }
    }

    fn take_offsets_changed(&mut self) -> bool {
        core::mem::take(&mut self.offsets_changed)
    }
}

/// The chord end points of an XY arc from `start` to `target` (the last
/// one `target` itself), within `$12` of the true circle.
fn arc_points(
    words: &Words,
    state: &InterimGcode,
    inches: bool,
    start: &[f64; GRBL_AXES],
    target: &[f64; GRBL_AXES],
    clockwise: bool,
    settings: &Settings,
) -> Result<Vec<[f64; GRBL_AXES]>, GrblError> {
    let (dx, dy) = (target[0] - start[0], target[1] - start[1]);
    let (center_x, center_y, radius) = if let Some(r) = words.r {
        if words.axes[0].is_none() && words.axes[1].is_none() {
            return Err(GrblError::NoAxisWordsInPlane);
        }
        let r = state.unit_mm(inches, r);
        let h2 = 4.0 * r * r - dx * dx - dy * dy;
        if h2 < 0.0 {
            return Err(GrblError::ArcRadiusError);
        }
        // The centre on the side the direction and the sign of R pick.
        let mut h = -(h2.sqrt()) / (dx * dx + dy * dy).sqrt();
        if !clockwise {
            h = -h;
        }
        if r < 0.0 {
            h = -h;
        }
        let cx = start[0] + 0.5 * (dx - dy * h);
        let cy = start[1] + 0.5 * (dy + dx * h);
        (cx, cy, r.abs())
    } else {
        if words.ijk[0].is_none() && words.ijk[1].is_none() {
            return Err(GrblError::NoOffsetsInPlane);
        }
        let i = state.unit_mm(inches, words.ijk[0].unwrap_or(0.0));
        let j = state.unit_mm(inches, words.ijk[1].unwrap_or(0.0));
        let (cx, cy) = (start[0] + i, start[1] + j);
        let r_start = i.hypot(j);
        let r_end = (target[0] - cx).hypot(target[1] - cy);
        let delta = (r_start - r_end).abs();
        if delta > 0.005 && (delta > 0.5 || delta > 0.001 * r_start) {
            return Err(GrblError::InvalidTarget);
        }
        (cx, cy, r_start)
    };
    if radius <= 0.0 {
        return Err(GrblError::InvalidTarget);
    }
    let a0 = (start[1] - center_y).atan2(start[0] - center_x);
    let a1 = (target[1] - center_y).atan2(target[0] - center_x);
    let mut sweep = a1 - a0;
    if clockwise {
        if sweep >= -1e-9 {
            sweep -= 2.0 * std::f64::consts::PI;
        }
    } else if sweep <= 1e-9 {
        sweep += 2.0 * std::f64::consts::PI;
    }
    let tolerance = settings.arc_tolerance_mm.min(radius);
    // The chord whose middle is `tolerance` from the circle.
    let chord_angle = 2.0 * (1.0 - tolerance / radius).acos();
    let segments = ((sweep.abs() / chord_angle).ceil() as usize).max(1);
    let mut points = Vec::with_capacity(segments);
    for k in 1..segments {
        let t = k as f64 / segments as f64;
        let angle = a0 + sweep * t;
        points.push([
            center_x + radius * angle.cos(),
            center_y + radius * angle.sin(),
            start[2] + (target[2] - start[2]) * t,
        ]);
    }
    points.push(*target);
    Ok(points)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(gcode: &mut InterimGcode, text: &str) -> Result<Vec<MotionBlock>, GrblError> {
        let mut blocks = Vec::new();
        gcode.interpret(1, text, false, &Settings::default(), &mut |block| {
            blocks.push(*block)
        })?;
        Ok(blocks)
    }

    fn end(blocks: &[MotionBlock]) -> [i64; GRBL_AXES] {
        match blocks.last() {
            Some(MotionBlock::Line { target_steps, .. }) => *target_steps,
            _ => panic!("no line"),
        }
    }

    #[test]
    fn lines_arcs_and_modes() {
        let mut g = InterimGcode::new();
        assert_eq!(end(&run(&mut g, "G0X10Y5").unwrap()), [2500, 1250, 0]);
        assert_eq!(run(&mut g, "G1X1"), Err(GrblError::UndefinedFeedRate));
        assert_eq!(end(&run(&mut g, "G1X20F600").unwrap()), [5000, 1250, 0]);
        // A half circle, centre 5 mm to the right: many chords, exact end.
        let arc = run(&mut g, "G2X30Y5I5J0").unwrap();
        assert!(arc.len() > 20);
        assert_eq!(end(&arc), [7500, 1250, 0]);
        for block in &arc {
            if let MotionBlock::Line { target_steps, .. } = block {
                let (x, y) = (target_steps[0] as f64 / 250.0, target_steps[1] as f64 / 250.0);
                let r = (x - 25.0).hypot(y - 5.0);
                assert!((r - 5.0).abs() < 0.002 + 0.004, "{r}");
                // Clockwise from the left end: over the top.
                assert!(y >= 5.0 - 1e-9);
            }
        }
        assert_eq!(end(&run(&mut g, "G3X20Y5R5").unwrap()), [5000, 1250, 0]);
        assert_eq!(end(&run(&mut g, "G91G1X-1Y-1").unwrap()), [4750, 1000, 0]);
        assert_eq!(end(&run(&mut g, "G90G20X1").unwrap()), [6350, 1000, 0]);
        assert_eq!(g.parser_state().units, 20);
    }

    #[test]
    fn errors_change_nothing() {
        let mut g = InterimGcode::new();
        run(&mut g, "G1X1F100").unwrap();
        let before = format!("{g:?}");
        for (text, error) in [
            ("G1X1X2", GrblError::WordRepeated),
            ("G0G1X1", GrblError::ModalGroupViolation),
            ("G7X1", GrblError::UnsupportedCommand),
            ("X1.2.3", GrblError::BadNumberFormat),
            ("1X", GrblError::ExpectedCommandLetter),
            ("G2X3", GrblError::NoOffsetsInPlane),
            ("G2X30R1", GrblError::ArcRadiusError),
            ("G4", GrblError::ValueWordMissing),
            ("G1X2I1", GrblError::UnusedWords),
            ("M99", GrblError::UnsupportedCommand),
            ("A1", GrblError::UnsupportedCommand),
        ] {
            assert_eq!(run(&mut g, text), Err(error), "{text}");
            assert_eq!(format!("{g:?}"), before, "{text}");
        }
    }

    #[test]
    fn g92_and_jogs() {
        let mut g = InterimGcode::new();
        run(&mut g, "G0X10").unwrap();
        run(&mut g, "G92X0").unwrap();
        assert!(g.take_offsets_changed());
        assert_eq!(g.offsets().wco(), [10.0, 0.0, 0.0]);
        assert_eq!(end(&run(&mut g, "G0X5").unwrap()), [3750, 0, 0]);
        let mut blocks = Vec::new();
        let settings = Settings::default();
        g.interpret(2, "G91X1F100", true, &settings, &mut |b| blocks.push(*b))
            .unwrap();
        assert_eq!(end(&blocks), [4000, 0, 0]);
        assert!(matches!(blocks[0], MotionBlock::Line { jog: true, .. }));
        // The jog's G91 is not modal.
        assert_eq!(g.parser_state().distance, 90);
        assert_eq!(
            g.interpret(3, "G1X1F100", true, &settings, &mut |_| {}),
            Err(GrblError::InvalidJogCommand)
        );
        assert_eq!(
            g.interpret(3, "X1", true, &settings, &mut |_| {}),
            Err(GrblError::InvalidJogCommand)
        );
    }
}

//! Model-based: random programs (G0/G1 with G90/G91, G20/G21 and G92
//! switches, arcs in the I/J and R forms, dwells, and lines spoilt by a
//! malformed or unsupported word) against a small reference model of the
//! modal state and the position.
//!
//! After every line: each block's `target_steps` is its predecessor's plus
//! its `steps`; a move's last block ends on the programmed end point in
//! machine mm rounded to steps (and a move that rounds to no step yields
//! nothing); every arc chord ends within half a step per axis of the
//! circle; the feed is F in mm/s; a spoilt line is refused at its line and
//! the bad word's column, with nothing yielded and nothing changed. At the
//! end the sum of all `steps` is the final target.

use core::f64::consts::TAU;

use proptest::prelude::*;

use super::cases;
use crate::{AxisSpec, Block, GcodeErrorKind, Interpreter, MachineSpec, PlannerSpec};

const AXES: usize = 3;
const STEPS_PER_MM: [f64; AXES] = [80.0, 57.3, 400.0];
const LETTERS: [char; AXES] = ['X', 'Y', 'Z'];
/// Numbers are written with 4 decimals: a value is an integer of 1e-4.
const SCALE: f64 = 10_000.0;

fn machine() -> MachineSpec {
    let axes = [
        AxisSpec::new('x', STEPS_PER_MM[0], 200.0, 2000.0),
        AxisSpec::new('y', STEPS_PER_MM[1], 200.0, 2000.0),
        AxisSpec::new('z', STEPS_PER_MM[2], 20.0, 500.0),
    ];
    let planner = PlannerSpec {
        junction_deviation_mm: 0.01,
        arc_tolerance_mm: 0.005,
        queue_len: 32,
    };
    MachineSpec::new(&axes, planner).unwrap()
}

/// A number as G-code writes it: `k` in 1e-4, 4 decimals.
fn number(k: i64) -> String {
    let sign = if k < 0 { "-" } else { "" };
    format!(
        "{sign}{}.{:04}",
        k.unsigned_abs() / 10_000,
        k.unsigned_abs() % 10_000
    )
}

fn value(k: i64) -> f64 {
    k as f64 / SCALE
}

#[derive(Clone, Debug)]
enum Op {
    Absolute(bool),
    Inches(bool),
    Feed(u32),
    Offset([Option<i32>; AXES]),
    Move {
        rapid: bool,
        axes: [Option<i32>; AXES],
    },
    /// An I/J arc: the centre at `radius` (units) in direction
    /// `centre_angle` from the start, the end `sweep` round (signed:
    /// negative clockwise), Z to `z` (units, incremental) if given.
    ArcCentre {
        radius: f64,
        centre_angle: f64,
        sweep: f64,
        z: Option<i32>,
    },
    /// An R arc to the start plus (`dx`, `dy`) (1e-4 units) of radius
    /// `stretch` times half the chord, the long way if `long`.
    ArcRadius {
        clockwise: bool,
        dx: i32,
        dy: i32,
        stretch: f64,
        long: bool,
    },
    Dwell(u16),
}

#[derive(Clone, Copy, Debug)]
enum Spoiler {
    Unsupported(char, u16),
    UnknownAxis(u16),
    LoneLetter,
    Hash,
    OpenComment,
}

fn op() -> impl Strategy<Value = Op> {
    let axes = || proptest::array::uniform3(proptest::option::weighted(0.6, -500_000..500_000i32));
    prop_oneof![
        any::<bool>().prop_map(Op::Absolute),
        any::<bool>().prop_map(Op::Inches),
        (1..6000u32).prop_map(Op::Feed),
        axes().prop_map(Op::Offset),
        (any::<bool>(), axes()).prop_map(|(rapid, axes)| Op::Move { rapid, axes }),
        (any::<bool>(), axes()).prop_map(|(rapid, axes)| Op::Move { rapid, axes }),
        (
            0.05..40.0f64,
            0.0..TAU,
            -TAU..TAU,
            proptest::option::of(-100_000..100_000i32)
        )
            .prop_map(|(radius, centre_angle, sweep, z)| Op::ArcCentre {
                radius,
                centre_angle,
                sweep,
                z
            }),
        (
            any::<bool>(),
            -400_000..400_000i32,
            -400_000..400_000i32,
            1.01..3.0f64,
            any::<bool>()
        )
            .prop_map(|(clockwise, dx, dy, stretch, long)| Op::ArcRadius {
                clockwise,
                dx,
                dy,
                stretch,
                long
            }),
        (0..5000u16).prop_map(Op::Dwell),
    ]
}

fn spoiler() -> impl Strategy<Value = Spoiler> {
    prop_oneof![
        (
            prop::sample::select(vec!['S', 'T', 'Q', 'E', 'H', 'K']),
            0..1000u16
        )
            .prop_map(|(letter, value)| Spoiler::Unsupported(letter, value)),
        (0..1000u16).prop_map(Spoiler::UnknownAxis),
        Just(Spoiler::LoneLetter),
        Just(Spoiler::Hash),
        Just(Spoiler::OpenComment),
    ]
}

/// The reference model: the modal state and the programmed machine
/// position in mm.
#[derive(Clone, Debug, PartialEq)]
struct Model {
    absolute: bool,
    inch: bool,
    feed_mm_s: f64,
    offset: [f64; AXES],
    position: [f64; AXES],
}

impl Model {
    fn unit(&self) -> f64 {
        if self.inch {
            25.4
        } else {
            1.0
        }
    }

    /// The machine mm of an axis word of `k`.
    fn target(&self, axis: usize, k: i64) -> f64 {
        let mm = value(k) * self.unit();
        if self.absolute {
            mm + self.offset[axis]
        } else {
            self.position[axis] + mm
        }
    }

    /// The axis word that reaches machine `mm` on `axis` (to 1e-4 units).
    fn word_for(&self, axis: usize, mm: f64) -> i64 {
        let units = if self.absolute {
            (mm - self.offset[axis]) / self.unit()
        } else {
            (mm - self.position[axis]) / self.unit()
        };
        (units * SCALE).round() as i64
    }

    fn steps(&self) -> [i64; AXES] {
        let mut steps = [0; AXES];
        for axis in 0..AXES {
            steps[axis] = (self.position[axis] * STEPS_PER_MM[axis]).round() as i64;
        }
        steps
    }
}

/// What the model expects of a line's blocks.
enum Expect {
    Nothing,
    Dwell(f64),
    Move { rapid: bool },
    Arc { centre: [f64; 2], radius: f64 },
}

/// The words of one op's line and what it expects, with the model moved
/// on as the line would move it.
fn line_for(op: &Op, model: &mut Model) -> (Vec<String>, Expect) {
    match *op {
        Op::Absolute(absolute) => {
            model.absolute = absolute;
            (
                vec![if absolute { "G90" } else { "G91" }.into()],
                Expect::Nothing,
            )
        }
        Op::Inches(inch) => {
            model.inch = inch;
            (
                vec![if inch { "G20" } else { "G21" }.into()],
                Expect::Nothing,
            )
        }
        Op::Feed(feed) => {
            model.feed_mm_s = f64::from(feed) * model.unit() / 60.0;
            (vec![format!("F{feed}")], Expect::Nothing)
        }
        Op::Offset(axes) => {
            let mut words = vec!["G92".to_string()];
            for axis in 0..AXES {
                if let Some(k) = axes[axis] {
                    words.push(format!("{}{}", LETTERS[axis], number(k.into())));
                    model.offset[axis] = model.position[axis] - value(k.into()) * model.unit();
                }
            }
            if words.len() == 1 {
                words.push(format!("X{}", number(0)));
                model.offset[0] = model.position[0];
            }
            (words, Expect::Nothing)
        }
        Op::Move { rapid, axes } => {
            let mut words = vec![if rapid { "G0" } else { "G1" }.to_string()];
            let mut target = model.position;
            for axis in 0..AXES {
                if let Some(k) = axes[axis] {
                    words.push(format!("{}{}", LETTERS[axis], number(k.into())));
                    target[axis] = model.target(axis, k.into());
                }
            }
            model.position = target;
            (words, Expect::Move { rapid })
        }
        Op::ArcCentre {
            radius,
            centre_angle,
            sweep,
            z,
        } => {
            let unit = model.unit();
            let i = (radius * centre_angle.cos() * SCALE).round() as i64;
            let j = (radius * centre_angle.sin() * SCALE).round() as i64;
            let start = [model.position[0], model.position[1]];
            let centre = [start[0] + value(i) * unit, start[1] + value(j) * unit];
            let arc_radius = (start[0] - centre[0]).hypot(start[1] - centre[1]);
            let start_angle = (start[1] - centre[1]).atan2(start[0] - centre[0]);
            let end = [
                centre[0] + arc_radius * (start_angle + sweep).cos(),
                centre[1] + arc_radius * (start_angle + sweep).sin(),
            ];
            let x = model.word_for(0, end[0]);
            let y = model.word_for(1, end[1]);
            let mut words = vec![
                if sweep < 0.0 { "G2" } else { "G3" }.to_string(),
                format!("X{}", number(x)),
                format!("Y{}", number(y)),
            ];
            let mut target = [model.target(0, x), model.target(1, y), model.position[2]];
            if let Some(z) = z {
                // Z is written incremental or absolute as the mode is.
                let z_mm = model.position[2] + value(z.into()) * unit;
                let z_word = model.word_for(2, z_mm);
                words.push(format!("Z{}", number(z_word)));
                target[2] = model.target(2, z_word);
            }
            words.push(format!("I{}", number(i)));
            words.push(format!("J{}", number(j)));
            model.position = target;
            (
                words,
                Expect::Arc {
                    centre,
                    radius: arc_radius,
                },
            )
        }
        Op::ArcRadius {
            clockwise,
            dx,
            dy,
            stretch,
            long,
        } => {
            let unit = model.unit();
            let start = [model.position[0], model.position[1]];
            let x = model.word_for(0, start[0] + value(dx.into()) * unit);
            let y = model.word_for(1, start[1] + value(dy.into()) * unit);
            let end = [model.target(0, x), model.target(1, y)];
            let chord = (end[0] - start[0]).hypot(end[1] - start[1]);
            let r_units = ((chord / 2.0 * stretch / unit) * SCALE).round() as i64;
            let r_units = if long { -r_units } else { r_units };
            let words = vec![
                if clockwise { "G2" } else { "G3" }.to_string(),
                format!("X{}", number(x)),
                format!("Y{}", number(y)),
                format!("R{}", number(r_units)),
            ];
            if chord == 0.0 || r_units == 0 {
                // Not an arc; the generator's rare degenerate case.
                return (vec!["G4 P0".into()], Expect::Dwell(0.0));
            }
            // The centre, found independently of the interpreter: of the
            // two circles of radius |R| through both ends, the one on
            // which the turn from start to end is short for R > 0.
            let size = value(r_units).abs() * unit;
            let half = chord / 2.0;
            let rise = (size * size - half * half).max(0.0).sqrt();
            let middle = [(start[0] + end[0]) / 2.0, (start[1] + end[1]) / 2.0];
            let normal = [-(end[1] - start[1]) / chord, (end[0] - start[0]) / chord];
            let candidates = [
                [middle[0] + rise * normal[0], middle[1] + rise * normal[1]],
                [middle[0] - rise * normal[0], middle[1] - rise * normal[1]],
            ];
            let turn_of = |centre: [f64; 2]| {
                let from = (start[1] - centre[1]).atan2(start[0] - centre[0]);
                let to = (end[1] - centre[1]).atan2(end[0] - centre[0]);
                let ccw = (to - from).rem_euclid(TAU);
                if clockwise {
                    TAU - ccw
                } else {
                    ccw
                }
            };
            let short = turn_of(candidates[0]) <= core::f64::consts::PI;
            let centre = if short != long {
                candidates[0]
            } else {
                candidates[1]
            };
            model.position[0] = end[0];
            model.position[1] = end[1];
            (
                words,
                Expect::Arc {
                    centre,
                    radius: size.max(half),
                },
            )
        }
        Op::Dwell(ms) => {
            let seconds = f64::from(ms) / 1000.0;
            (
                vec![format!("G4 P{}", number(i64::from(ms) * 10))],
                Expect::Dwell(seconds),
            )
        }
    }
}

fn spoil(words: &mut Vec<String>, spoiler: Spoiler, at: usize) -> (u32, GcodeErrorKind) {
    let (word, kind) = match spoiler {
        Spoiler::Unsupported(letter, value) => (
            format!("{letter}{value}"),
            GcodeErrorKind::UnsupportedWord(letter, f64::from(value)),
        ),
        Spoiler::UnknownAxis(value) => (format!("A{value}"), GcodeErrorKind::UnknownAxis('A')),
        Spoiler::LoneLetter => ("Q".into(), GcodeErrorKind::Malformed),
        Spoiler::Hash => ("#".into(), GcodeErrorKind::Malformed),
        Spoiler::OpenComment => ("(no end".into(), GcodeErrorKind::Malformed),
    };
    let at = if matches!(spoiler, Spoiler::OpenComment | Spoiler::LoneLetter) {
        words.len()
    } else {
        at % (words.len() + 1)
    };
    let column = 1 + words[..at].iter().map(|word| word.len() + 1).sum::<usize>();
    words.insert(at, word);
    (column as u32, kind)
}

fn check_program(ops: &[(Op, Option<(Spoiler, usize)>)]) -> Result<(), TestCaseError> {
    let spec = machine();
    let mut gcode = Interpreter::new(&spec);
    let mut model = Model {
        absolute: true,
        inch: false,
        feed_mm_s: 10.0,
        offset: [0.0; AXES],
        position: [0.0; AXES],
    };
    let mut blocks = Vec::new();
    gcode
        .interpret_line(1, "F600", &mut |block| blocks.push(block))
        .unwrap();
    let mut previous = [0i64; 8];
    let mut sum = [0i64; 8];
    for (index, (op, spoiler)) in ops.iter().enumerate() {
        let line_no = index as u32 + 2;
        let before_model = model.clone();
        let before = format!("{gcode:?}");
        let (mut words, expect) = line_for(op, &mut model);
        blocks.clear();
        if let Some((spoiler, at)) = *spoiler {
            let (column, kind) = spoil(&mut words, spoiler, at);
            let text = words.join(" ");
            let error = gcode
                .interpret_line(line_no, &text, &mut |block| blocks.push(block))
                .expect_err(&text);
            prop_assert_eq!(
                (error.line, error.column, error.kind),
                (line_no, column, kind),
                "{}",
                text
            );
            prop_assert!(blocks.is_empty());
            prop_assert_eq!(format!("{gcode:?}"), before, "an error changes nothing");
            model = before_model;
            continue;
        }
        let text = words.join(" ");
        gcode
            .interpret_line(line_no, &text, &mut |block| blocks.push(block))
            .map_err(|error| TestCaseError::fail(format!("{text}: {error}")))?;
        let expected_steps = model.steps();
        prop_assert_eq!(
            &gcode.position_steps()[..AXES],
            &expected_steps[..],
            "{}",
            text
        );
        prop_assert_eq!(
            &gcode.position_mm()[..AXES],
            &model.position[..],
            "{}",
            text
        );
        for block in &blocks {
            prop_assert_eq!(block.line(), line_no);
            if let Block::Line {
                steps,
                target_steps,
                feed_mm_s,
                length_mm,
                rapid,
                ..
            } = *block
            {
                for axis in 0..8 {
                    prop_assert_eq!(target_steps[axis], previous[axis] + i64::from(steps[axis]));
                    sum[axis] += i64::from(steps[axis]);
                }
                prop_assert!(steps.iter().any(|&s| s != 0), "no empty lines");
                prop_assert!(length_mm > 0.0);
                previous = target_steps;
                match expect {
                    Expect::Move { rapid: want } => {
                        prop_assert_eq!(rapid, want);
                        if !want {
                            prop_assert_eq!(feed_mm_s, model.feed_mm_s);
                        }
                    }
                    Expect::Arc { centre, radius } => {
                        prop_assert!(!rapid);
                        prop_assert_eq!(feed_mm_s, model.feed_mm_s);
                        // Within half a step per axis of the circle (the
                        // last chord ends at the programmed end, on it to
                        // 1e-4 units).
                        let x = target_steps[0] as f64 / STEPS_PER_MM[0];
                        let y = target_steps[1] as f64 / STEPS_PER_MM[1];
                        let slack =
                            0.5 * (1.0 / STEPS_PER_MM[0]).hypot(1.0 / STEPS_PER_MM[1]) + 0.004;
                        let off = ((x - centre[0]).hypot(y - centre[1]) - radius).abs();
                        prop_assert!(off <= slack, "{}: a chord end {} off the circle", text, off);
                    }
                    _ => prop_assert!(false, "a line from {}", text),
                }
            } else if let Expect::Dwell(seconds) = expect {
                prop_assert_eq!(
                    *block,
                    Block::Dwell {
                        line: line_no,
                        seconds
                    }
                );
            } else {
                prop_assert!(false, "{:?} from {}", block, text);
            }
        }
        if matches!(expect, Expect::Move { .. } | Expect::Arc { .. }) {
            // The move's last block ends on the programmed end; no block
            // when it rounds to no step.
            match blocks.last() {
                Some(Block::Line { target_steps, .. }) => {
                    prop_assert_eq!(&target_steps[..AXES], &expected_steps[..])
                }
                _ => prop_assert_eq!(&expected_steps[..], &previous[..AXES]),
            }
        }
    }
    prop_assert_eq!(
        &sum[..AXES],
        &model.steps()[..],
        "the steps add up to the final target"
    );
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    #[test]
    fn programs_follow_the_model(
        ops in prop::collection::vec(
            (op(), proptest::option::weighted(0.1, (spoiler(), 0..8usize))),
            1..40,
        )
    ) {
        check_program(&ops)?;
    }
}

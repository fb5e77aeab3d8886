//! Arcs: the chords' geometry as properties, and the G2/G3 lines' forms
//! and errors as examples.

use core::f64::consts::{PI, TAU};

use proptest::prelude::*;

use super::{cases, plotter, run};
use crate::arc::{chord_count, sagitta, ArcPath, Turn};
use crate::{AxisSpec, Block, GcodeErrorKind, Interpreter, MachineSpec, PlannerSpec};

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// Every chord of `path` from `start`: its end on the circle (but the
/// last, which is the programmed end), its sagitta within `tolerance`.
fn check_chords(path: &ArcPath, start: [f64; 2], tolerance: f64) -> Result<(), TestCaseError> {
    let radius = path.radius;
    let mut from = start;
    prop_assert!(path.chords >= 1);
    for index in 0..path.chords {
        let to = path.point(index);
        let last = index + 1 == path.chords;
        if last {
            prop_assert_eq!(to, path.end, "the last chord ends at the programmed end");
        } else {
            let off = (distance(path.centre, to) - radius).abs();
            prop_assert!(
                off <= 1e-9 * radius.max(1.0),
                "chord {} end {} off the circle",
                index,
                off
            );
        }
        // The arc's farthest point from the chord is at the middle of the
        // chord's turn: the sagitta is the radius less the distance of the
        // chord's midpoint from the centre.
        let middle = [(from[0] + to[0]) / 2.0, (from[1] + to[1]) / 2.0];
        let end_error = (distance(path.centre, to) - radius).abs();
        let chord_sagitta = radius - distance(path.centre, middle);
        prop_assert!(
            chord_sagitta <= tolerance + end_error + 1e-9 * radius.max(1.0),
            "chord {} sagitta {} above {}",
            index,
            chord_sagitta,
            tolerance
        );
        from = to;
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    /// I/J arcs with the end on the circle: the sweep turns the right way
    /// by the right angle, every chord end is on the circle and every
    /// sagitta within the tolerance.
    #[test]
    fn centre_arcs_cut_within_tolerance(
        start in (-500.0..500.0f64, -500.0..500.0f64),
        radius in 0.01..300.0f64,
        centre_angle in 0.0..TAU,
        sweep in 0.0..TAU,
        clockwise: bool,
        tolerance in 0.0005..0.05f64,
    ) {
        let start = [start.0, start.1];
        let offset = [radius * centre_angle.cos(), radius * centre_angle.sin()];
        let centre = [start[0] + offset[0], start[1] + offset[1]];
        let start_angle = (start[1] - centre[1]).atan2(start[0] - centre[0]);
        let signed = if clockwise { -sweep } else { sweep };
        let end = [
            centre[0] + radius * (start_angle + signed).cos(),
            centre[1] + radius * (start_angle + signed).sin(),
        ];
        let turn = if clockwise { Turn::Clockwise } else { Turn::CounterClockwise };
        let path = ArcPath::from_centre(start, end, offset, turn, tolerance).unwrap();
        prop_assert_eq!(path.sweep < 0.0, clockwise);
        // The sweep asked for, or a full turn where it is a hair from 0.
        let expected = if sweep < 1e-6 { TAU } else { sweep };
        prop_assert!((path.sweep.abs() - expected).abs() < 1e-6 || (sweep > TAU - 1e-6));
        prop_assert!(path.chords >= chord_count(path.radius, path.sweep, tolerance).unwrap());
        check_chords(&path, start, tolerance)?;
    }

    /// R arcs: the centre at |R| from both ends, the short way for R > 0
    /// (at most half a turn), the long way for R < 0, the chords within
    /// the tolerance.
    #[test]
    fn radius_arcs_take_the_right_way(
        start in (-500.0..500.0f64, -500.0..500.0f64),
        chord in 0.01..400.0f64,
        chord_angle in 0.0..TAU,
        stretch in 1.0001..4.0f64,
        long: bool,
        clockwise: bool,
        tolerance in 0.0005..0.05f64,
    ) {
        let start = [start.0, start.1];
        let end = [start[0] + chord * chord_angle.cos(), start[1] + chord * chord_angle.sin()];
        let size = chord / 2.0 * stretch;
        let radius = if long { -size } else { size };
        let turn = if clockwise { Turn::Clockwise } else { Turn::CounterClockwise };
        let path = ArcPath::from_radius(start, end, radius, turn, tolerance).unwrap();
        prop_assert!((distance(path.centre, start) - size).abs() < 1e-9 * size.max(1.0));
        prop_assert!((distance(path.centre, end) - size).abs() < 1e-9 * size.max(1.0));
        prop_assert_eq!(path.sweep < 0.0, clockwise);
        prop_assert_eq!(path.sweep.abs() > PI, long);
        // The sweep takes the start to the end around the centre.
        let start_angle = (start[1] - path.centre[1]).atan2(start[0] - path.centre[0]);
        let reached = [
            path.centre[0] + size * (start_angle + path.sweep).cos(),
            path.centre[1] + size * (start_angle + path.sweep).sin(),
        ];
        prop_assert!(distance(reached, end) < 1e-7 * size.max(1.0));
        check_chords(&path, start, tolerance)?;
    }

    /// The chord count is the fewest equal chords within the tolerance
    /// (one chord fewer would be above it), and at least one per quarter
    /// turn.
    #[test]
    fn chord_counts_are_tight(radius in 0.01..1000.0f64, sweep in 0.001..TAU, tolerance in 0.0005..0.05f64) {
        let chords = chord_count(radius, sweep, tolerance).unwrap();
        prop_assert!(sagitta(radius, sweep / f64::from(chords)) <= tolerance);
        prop_assert!(f64::from(chords) >= (sweep / (PI / 2.0)).ceil());
        if chords > 1 && f64::from(chords - 1) >= (sweep / (PI / 2.0)).ceil() {
            prop_assert!(sagitta(radius, sweep / f64::from(chords - 1)) > tolerance * (1.0 - 1e-5));
        }
    }
}

fn targets(blocks: &[Block]) -> Vec<[i64; 8]> {
    blocks
        .iter()
        .filter_map(|block| match block {
            Block::Line { target_steps, .. } => Some(*target_steps),
            _ => None,
        })
        .collect()
}

#[test]
fn a_clockwise_half_circle_goes_over_the_top() {
    // From (0, 0) around (5, 0) to (10, 0), clockwise: through (5, 5).
    let blocks = run(&mut Interpreter::new(&plotter()), &["G2 X10 Y0 I5 J0 F600"]).unwrap();
    let over = targets(&blocks);
    assert!(over.len() > 10);
    assert!(blocks.iter().all(|block| block.line() == 1));
    assert_eq!(over.last().unwrap()[..2], [800, 0]);
    let top = over.iter().map(|target| target[1]).max().unwrap();
    assert!((398..=400).contains(&top), "the top, at y = 5 mm: {top}");
    assert!(over.iter().all(|target| target[1] >= 0));
    // Counter-clockwise the same arc goes under.
    let blocks = run(&mut Interpreter::new(&plotter()), &["G3 X10 Y0 I5 J0 F600"]).unwrap();
    assert!(targets(&blocks).iter().all(|target| target[1] <= 0));
}

#[test]
fn a_full_circle_returns_to_its_start() {
    let mut gcode = Interpreter::new(&plotter());
    let blocks = run(&mut gcode, &["G1 X10 F600", "G2 I5"]).unwrap();
    let chords = &blocks[1..];
    assert!(chords.len() >= 4);
    let sum: i64 = chords
        .iter()
        .map(|block| match block {
            Block::Line { steps, .. } => i64::from(steps[0]).abs() + i64::from(steps[1]).abs(),
            _ => 0,
        })
        .sum();
    // Round a circle of 5 mm: 4 diameters of x and y travel, 3,200 steps.
    assert!((3190..=3200).contains(&sum), "it went round: {sum}");
    assert_eq!(gcode.position_steps()[..2], [800, 0]);
}

#[test]
fn r_arcs_short_and_long() {
    // A quarter circle of radius 10 from (0, 0) to (10, 10), centre (10, 0)
    // clockwise the short way; the long way is three quarters round (0, 10).
    let blocks = run(&mut Interpreter::new(&plotter()), &["G2 X10 Y10 R10 F600"]).unwrap();
    let short = targets(&blocks);
    let blocks = run(&mut Interpreter::new(&plotter()), &["G2 X10 Y10 R-10 F600"]).unwrap();
    let long = targets(&blocks);
    assert!(long.len() > 2 * short.len());
    assert_eq!(short.last(), long.last());
    assert!(short
        .iter()
        .all(|target| target[0] <= 800 && target[1] >= 0));
    assert!(
        long.iter().any(|target| target[0] < -790),
        "through (-10, 10)"
    );
    assert!(
        long.iter().any(|target| target[1] > 1590),
        "through (0, 20)"
    );
}

#[test]
fn a_helix_moves_z_linearly() {
    let spec = super::cnc();
    let mut gcode = Interpreter::new(&spec);
    let blocks = run(&mut gcode, &["G0 X20 Y20", "G17 G2 X30 Y20 Z-5 I5 J0 F600"]).unwrap();
    let chords = targets(&blocks[1..]);
    let z: Vec<i64> = chords.iter().map(|target| target[2]).collect();
    assert!(
        z.windows(2).all(|pair| pair[1] <= pair[0]),
        "z only goes down"
    );
    assert_eq!(*z.last().unwrap(), -2000);
    // Chord k of n ends (k + 1)/n of the way down, rounded to a step.
    let chords = z.len() as f64;
    for (index, &steps) in z.iter().enumerate() {
        let exact = -2000.0 * (index as f64 + 1.0) / chords;
        assert!(
            (steps as f64 - exact).abs() <= 0.5 + 1e-9,
            "chord {index}: {steps}"
        );
    }
}

#[test]
fn arc_errors() {
    use GcodeErrorKind::*;
    let at = |text: &str| {
        let error = run(&mut Interpreter::new(&plotter()), &["F600", text]).unwrap_err();
        (error.column, error.kind)
    };
    assert_eq!(at("G2 X10 Y0 I4 J0"), (11, ArcRadiusMismatch));
    assert_eq!(at("G2 X10 Y0 J1 I4.99"), (11, ArcRadiusMismatch));
    assert_eq!(at("G2 X10 Y0"), (1, MissingArcParameter));
    assert_eq!(at("G2 X10 Y0 I5 R5"), (14, ArcFormsMixed));
    assert_eq!(at("G2 X10 I0 J0"), (8, ArcZeroRadius));
    assert_eq!(at("G2 X10 R0"), (8, ArcZeroRadius));
    assert_eq!(at("G2 R5"), (4, ArcEndIsStart));
    assert_eq!(at("G2 X10 R4.9"), (8, ArcRadiusMismatch));
    assert_eq!(at("G2 X10 K1"), (8, UnsupportedWord('K', 1.0)));
    assert_eq!(at("G19 G2 X10 R5"), (1, UnsupportedWord('G', 19.0)));
    // Within grbl's tolerance, the end's radius may be off: 0.004 mm here.
    run(
        &mut Interpreter::new(&plotter()),
        &["G2 X10.004 Y0 I5 J0 F600"],
    )
    .unwrap();
    // Just past the diameter (within the tolerance) is a half circle.
    run(&mut Interpreter::new(&plotter()), &["G2 X10.004 R5 F600"]).unwrap();
    // An arc on a machine without Y.
    let one_axis = MachineSpec::new(
        &[AxisSpec::new('x', 80.0, 100.0, 1000.0)],
        PlannerSpec {
            junction_deviation_mm: 0.01,
            arc_tolerance_mm: 0.002,
            queue_len: 8,
        },
    )
    .unwrap();
    let error = run(&mut Interpreter::new(&one_axis), &["G2 X1 I1 F60"]).unwrap_err();
    assert_eq!((error.column, error.kind), (1, UnknownAxis('Y')));
}

#[test]
fn arcs_stop_at_soft_limits() {
    // The CNC's Y starts at its soft minimum: an arc under it is refused,
    // the whole line, although its end is inside (the error at the Y word).
    let mut gcode = Interpreter::new(&super::cnc());
    let error = run(
        &mut gcode,
        &["G0 X10", "G2 X20 Y0 I5 J0 F600", "G3 X20 Y0 I5 J0"],
    )
    .unwrap_err();
    assert_eq!(
        (error.line, error.column, error.kind),
        (3, 8, GcodeErrorKind::BeyondSoftLimit { axis: 'y' })
    );
    assert_eq!(
        gcode.position_steps()[..2],
        [1600, 0],
        "line 2 ran, line 3 changed nothing"
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    /// A board takes an arc's chords a few at a time
    /// (`Interpreter::interpret_line_part`): the blocks it takes before it
    /// stops are the whole line's first ones, the state after it is the
    /// whole line's, and the same line again without the dry run (from the
    /// state before) gives the same blocks.
    #[test]
    fn an_arc_taken_a_few_chords_at_a_time_is_the_whole_arc(
        end in (-40.0f64..40.0, -40.0f64..40.0),
        centre in (-30.0f64..30.0, -30.0f64..30.0),
        clockwise in prop::bool::ANY,
        wanted in 0usize..40,
        check in prop::bool::ANY,
    ) {
        // Start at the circle's point through (0, 0) about the centre.
        let (i, j) = centre;
        prop_assume!(i.hypot(j) > 0.5);
        let radius = i.hypot(j);
        let angle = (end.1 - j).atan2(end.0 - i);
        let end = (i + radius * angle.cos(), j + radius * angle.sin());
        let g = if clockwise { 2 } else { 3 };
        let line = format!("G{g} X{:.4} Y{:.4} I{i:.4} J{j:.4} F600", end.0, end.1);
        let mut whole = Interpreter::new(&plotter());
        let mut all = Vec::new();
        let result = whole.interpret_line(1, &line, &mut |block| all.push(block));
        prop_assume!(result.is_ok());
        let mut part = Interpreter::new(&plotter());
        let mut taken = Vec::new();
        part.interpret_line_part(1, &line, check, &mut |block| {
            taken.push(block);
            taken.len() < wanted.max(1)
        })
        .unwrap();
        prop_assert_eq!(&taken[..], &all[..taken.len()]);
        prop_assert_eq!(taken.len(), wanted.max(1).min(all.len()));
        prop_assert_eq!(part.position_steps(), whole.position_steps());
        prop_assert_eq!(part.position_mm(), whole.position_mm());
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    /// The dry run decides an arc from its bounds when no chord can fail
    /// (`Mover::no_chord_can_fail`), and works the chords out otherwise:
    /// its verdict is the one the chords give, error and column, for arcs
    /// in and across the CNC's soft limits.
    #[test]
    fn the_dry_runs_verdict_on_an_arc_is_its_chords(
        start in (-20.0f64..320.0, -20.0f64..220.0),
        centre in (-60.0f64..60.0, -60.0f64..60.0),
        sweep in -6.0f64..6.0,
        z in -30.0f64..10.0,
    ) {
        let (i, j) = centre;
        prop_assume!(i.hypot(j) > 0.5);
        let radius = i.hypot(j);
        let angle = (-j).atan2(-i) + sweep;
        let end = (start.0 + i + radius * angle.cos(), start.1 + j + radius * angle.sin());
        let g = if sweep < 0.0 { 2 } else { 3 };
        let line = format!("G{g} X{:.4} Y{:.4} Z{z:.4} I{i:.4} J{j:.4} F600", end.0, end.1);
        let mut at_start = Interpreter::new(&super::cnc());
        at_start.set_position_steps([
            (start.0 * 80.0) as i64,
            (start.1 * 80.0) as i64,
            0, 0, 0, 0, 0, 0,
        ]);
        let mut checked = at_start.clone();
        let verdict = checked.interpret_line(1, &line, &mut |_| {});
        // The run alone (no dry run) works out every chord, and stops at the
        // first that fails.
        let mut chords = at_start.clone();
        let by_chords = chords.interpret_line_part(1, &line, false, &mut |_| true);
        prop_assert_eq!(verdict.err(), by_chords.err());
    }
}

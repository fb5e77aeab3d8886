//! Lines, modes and errors, one example each.

use cogstep_motion::planner::Blending;

use super::{cnc, plotter, run};
use crate::{check, Block, Distance, GcodeError, GcodeErrorKind, Interpreter, Units};

fn line(block: &Block) -> ([i32; 8], [i64; 8], f64, f64, bool) {
    match *block {
        Block::Line {
            steps,
            target_steps,
            feed_mm_s,
            length_mm,
            rapid,
            ..
        } => (steps, target_steps, feed_mm_s, length_mm, rapid),
        other => panic!("not a line: {other:?}"),
    }
}

fn fails(lines: &[&str]) -> GcodeError {
    run(&mut Interpreter::new(&plotter()), lines).expect_err("an error")
}

fn kind_at(text: &str) -> (u32, GcodeErrorKind) {
    let error = fails(&["F600", text]);
    assert_eq!(error.line, 2);
    (error.column, error.kind)
}

#[test]
fn absolute_and_incremental_lines() {
    let mut gcode = Interpreter::new(&plotter());
    let blocks = run(&mut gcode, &["G1 X10 F600", "G91", "X1 Y-1", "G90 X0"]).unwrap();
    assert_eq!(blocks.len(), 3);
    let (steps, target, feed, length, rapid) = line(&blocks[0]);
    assert_eq!(
        (steps[0], steps[1], target[0], feed, length, rapid),
        (800, 0, 800, 10.0, 10.0, false)
    );
    let (steps, target, ..) = line(&blocks[1]);
    assert_eq!(
        (steps[0], steps[1], target[0], target[1]),
        (80, -80, 880, -80)
    );
    let (steps, target, ..) = line(&blocks[2]);
    assert_eq!(
        (steps[0], steps[1], target[0], target[1]),
        (-880, 0, 0, -80)
    );
    assert_eq!(gcode.distance(), Distance::Absolute);
    assert_eq!(gcode.position_steps()[..2], [0, -80]);
}

#[test]
fn rapids_are_infinite_feeds() {
    let blocks = run(&mut Interpreter::new(&plotter()), &["G0 X1 Y1"]).unwrap();
    let (_, _, feed, _, rapid) = line(&blocks[0]);
    assert!(rapid && feed == f64::INFINITY);
    let planner_line = blocks[0].to_planner_line::<2>().unwrap();
    assert_eq!(planner_line.feed_steps_per_s, f64::INFINITY);
}

#[test]
fn planner_feed_is_lead_steps_per_s() {
    // 3-4-5 in mm: 240 and 320 steps, 5 mm at 10 mm/s: the lead 320 steps
    // in 0.5 s.
    let blocks = run(&mut Interpreter::new(&plotter()), &["G1 X3 Y4 F600"]).unwrap();
    let planner_line = blocks[0].to_planner_line::<2>().unwrap();
    assert_eq!(planner_line.steps, [240, 320]);
    assert!((planner_line.feed_steps_per_s - 640.0).abs() < 1e-9);
    assert!(Block::Dwell {
        line: 1,
        seconds: 1.0
    }
    .to_planner_line::<2>()
    .is_none());
    assert!(blocks[0].to_planner_line::<1>().is_none(), "y moves");
}

#[test]
fn inches_scale_positions_and_feeds() {
    let mut gcode = Interpreter::new(&plotter());
    let blocks = run(&mut gcode, &["G20 G1 X1 F60"]).unwrap();
    let (steps, _, feed, ..) = line(&blocks[0]);
    assert_eq!(steps[0], 2032);
    assert!((feed - 25.4).abs() < 1e-12);
    assert_eq!(gcode.units(), Units::Inches);
}

#[test]
fn rounding_never_accumulates() {
    // 0.004 mm is 0.32 steps: a thousand of them are 320 steps exactly.
    let mut gcode = Interpreter::new(&plotter());
    let mut lines = vec!["G91 G1 F600"];
    lines.extend(std::iter::repeat_n("X0.004", 1000));
    let blocks = run(&mut gcode, &lines).unwrap();
    let total: i64 = blocks.iter().map(|block| i64::from(line(block).0[0])).sum();
    assert_eq!(total, 320);
    assert_eq!(gcode.position_steps()[0], 320);
    assert!(blocks.len() < 1000, "moves under half a step yield nothing");
}

#[test]
fn g92_offsets_the_work_position_only() {
    let mut gcode = Interpreter::new(&plotter());
    let blocks = run(&mut gcode, &["G1 X10 F600", "G92 X0", "X5"]).unwrap();
    assert_eq!(blocks.len(), 2, "G92 yields nothing");
    let (steps, target, ..) = line(&blocks[1]);
    assert_eq!((steps[0], target[0]), (400, 1200));
    assert_eq!(gcode.work_position_mm()[0], 5.0);
    assert_eq!(gcode.offsets_mm()[0], 10.0);
}

#[test]
fn dwell_pause_end_blending_in_order() {
    let blocks = run(
        &mut Interpreter::new(&plotter()),
        &["G61 G4 P0.5 G1 X1 F60 M0", "M30", "G64"],
    )
    .unwrap();
    assert_eq!(
        blocks[0],
        Block::Blending {
            line: 1,
            mode: Blending::ExactStop
        }
    );
    assert_eq!(
        blocks[1],
        Block::Dwell {
            line: 1,
            seconds: 0.5
        }
    );
    assert!(matches!(blocks[2], Block::Line { line: 1, .. }));
    assert_eq!(blocks[3], Block::Pause { line: 1 });
    assert_eq!(blocks[4], Block::End { line: 2 });
    assert_eq!(
        blocks[5],
        Block::Blending {
            line: 3,
            mode: Blending::Blend
        }
    );
}

#[test]
fn home_takes_the_homable_axes() {
    let mut gcode = Interpreter::new(&cnc());
    let blocks = run(&mut gcode, &["G1 X10 Y10 Z-10 F600", "G28 X0 Z0", "G28"]).unwrap();
    assert_eq!(
        blocks[1],
        Block::Home {
            line: 2,
            axes: 0b101
        }
    );
    assert_eq!(
        blocks[2],
        Block::Home {
            line: 3,
            axes: 0b111
        }
    );
    assert_eq!(gcode.position_steps()[..3], [0, 0, 0]);
    // Nothing to home on a plotter: nothing yielded.
    assert_eq!(
        run(&mut Interpreter::new(&plotter()), &["G28"]).unwrap(),
        []
    );
}

#[test]
fn comments_blank_and_percent_lines() {
    let blocks = run(
        &mut Interpreter::new(&plotter()),
        &[
            "%",
            "",
            "   ",
            "(a comment) ; another",
            "N10 G1 (x) X1 F60 ; y",
            "%",
        ],
    )
    .unwrap();
    assert_eq!(blocks.len(), 1);
    assert_eq!(blocks[0].line(), 5);
}

#[test]
fn errors_name_line_column_and_kind() {
    use GcodeErrorKind::*;
    assert_eq!(kind_at("G1 X1 M3"), (7, UnsupportedWord('M', 3.0)));
    assert_eq!(kind_at("G38.2 X1"), (1, UnsupportedWord('G', 38.2)));
    assert_eq!(kind_at("G18"), (1, UnsupportedWord('G', 18.0)));
    assert_eq!(kind_at("G1 Z1"), (4, UnknownAxis('Z')));
    assert_eq!(kind_at("G1 X1 X2"), (7, RepeatedWord('X')));
    assert_eq!(kind_at("G0 G1 X1"), (4, TwoMotionWordsOnOneLine));
    assert_eq!(kind_at("G90 G91"), (5, ModalGroupConflict));
    assert_eq!(kind_at("G92 G1 X1"), (1, ModalGroupConflict));
    assert_eq!(kind_at("G4"), (1, MissingDwellTime));
    assert_eq!(kind_at("G4 P-1"), (4, NumberOutOfRange));
    assert_eq!(kind_at("G1 X1 P1"), (7, UnusedWord('P')));
    assert_eq!(kind_at("G1 X1 I1"), (7, UnusedWord('I')));
    assert_eq!(kind_at("G92"), (1, MissingAxisWord));
    assert_eq!(kind_at("G1 X1 F0"), (7, NumberOutOfRange));
    assert_eq!(kind_at("G1 X1 F-5"), (7, NumberOutOfRange));
    assert_eq!(kind_at("G1 X99999999999"), (4, NumberOutOfRange));
    assert_eq!(kind_at("G1 X1 #"), (7, Malformed));
    assert_eq!(kind_at("G1 X"), (4, Malformed));
    assert_eq!(kind_at("  G1 (open X1"), (6, Malformed));
    let error = fails(&["G1 X1"]);
    assert_eq!((error.line, error.column, error.kind), (1, 1, MissingFeed));
    let error = fails(&["X1 G1"]);
    assert_eq!((error.column, error.kind), (4, MissingFeed));
    let error = run(&mut Interpreter::new(&cnc()), &["G1 Y-1 F60"]).unwrap_err();
    assert_eq!(
        (error.column, error.kind),
        (4, BeyondSoftLimit { axis: 'y' })
    );
    assert_eq!(
        error.to_string(),
        "line 1, column 4: the move would end beyond axis y's soft limit"
    );
}

#[test]
fn an_error_changes_nothing() {
    let mut gcode = Interpreter::new(&plotter());
    run(&mut gcode, &["G1 X1 F60"]).unwrap();
    let before = gcode.clone();
    let mut yielded = 0;
    let error = gcode
        .interpret_line(2, "G91 G20 G61 F1 G4 P1 X1 M3", &mut |_| yielded += 1)
        .unwrap_err();
    assert_eq!(error.column, 25);
    assert_eq!(yielded, 0);
    let error = gcode
        .interpret_line(3, "G91 G20 G61 F1 G4 P1 X1 Y", &mut |_| yielded += 1)
        .unwrap_err();
    assert_eq!(error.kind, GcodeErrorKind::Malformed);
    assert_eq!(yielded, 0);
    assert_eq!(format!("{gcode:?}"), format!("{before:?}"));
}

#[test]
fn check_lists_every_error() {
    let errors = check("G1 X1\nF60\nG1 X1 S2\nG1 Z3\nG1 X2\n", &plotter());
    let found: Vec<_> = errors
        .iter()
        .map(|error| (error.line, error.column))
        .collect();
    assert_eq!(found, [(1, 1), (3, 7), (4, 4)]);
    assert!(check("%\nG0 X1\n%\n", &plotter()).is_empty());
}

#[test]
fn a_job_starts_where_the_axes_are() {
    let mut gcode = Interpreter::new(&cnc());
    let mut at = [0; 8];
    at[..3].copy_from_slice(&[800, 1600, -400]);
    gcode.set_position_steps(at);
    assert_eq!(gcode.position_mm()[..3], [10.0, 20.0, -1.0]);
    let blocks = run(&mut gcode, &["G91 G1 X1 F60"]).unwrap();
    let (steps, target, ..) = line(&blocks[0]);
    assert_eq!((steps[0], target[0], target[2]), (80, 880, -400));
}

#[test]
fn a_modal_arc_line_reports_at_its_arc_word() {
    let error = run(&mut Interpreter::new(&plotter()), &["G2", "I5"]).unwrap_err();
    assert_eq!(
        (error.line, error.column, error.kind),
        (2, 1, GcodeErrorKind::MissingFeed)
    );
    let error = run(&mut Interpreter::new(&plotter()), &["G2", "  J5"]).unwrap_err();
    assert_eq!((error.column, error.kind), (3, GcodeErrorKind::MissingFeed));
}

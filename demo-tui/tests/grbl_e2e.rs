//! The demo driving a grbl board (`--serial PORT --dialect grbl`), as a
//! person uses it: the real binary in a pseudo-terminal, the board
//! simulator's grbl dialect on another. A G-code file streamed by
//! character counting (`--gcode FILE`, the machine read from the board's
//! `$$`) runs to its exact end with its progress, MPos and state on
//! screen; a hold holds and `r` finishes; `c` cancels; a file the board's
//! machine cannot run is refused whole before a byte is streamed; and the
//! live demo moves a grbl axis to its exact target.

mod pty;

use std::path::{Path, PathBuf};
use std::time::Duration;

use cogstep_test_support::grbl::GrblBoard;
use driver::serial::host::{Dialect, SerialBoard, SerialConfig};
use driver::AxisContract;
use pty::{line_of, read_position, state, steps, Demo, Keyboard};

const BIN: &str = env!("CARGO_BIN_EXE_demo-tui");
const LONG: Duration = Duration::from_secs(20);

/// 80 steps/mm, 300 mm/s; `accel` mm/s² on every axis.
fn settings(accel: u32) -> String {
    let mut text = String::from("$100=80\n$101=80\n$102=80\n$110=18000\n$111=18000\n$112=18000\n");
    for axis in 0..3 {
        text.push_str(&format!("$12{axis}={accel}\n"));
    }
    text
}

fn board(name: &str, accel: u32) -> GrblBoard {
    GrblBoard::start(&format!("demo-{name}"), &settings(accel))
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn start(gcode: &Path, board: &GrblBoard) -> Demo {
    let gcode = gcode.to_string_lossy().into_owned();
    let demo = Demo::spawn(
        BIN,
        &[
            "--gcode",
            &gcode,
            "--serial",
            &board.path,
            "--dialect",
            "grbl",
        ],
        Keyboard::Legacy,
    );
    demo.wait_text("State:", LONG);
    demo
}

fn quit(mut demo: Demo) {
    demo.send(b"q");
    let status = demo.wait_exit(LONG);
    assert!(status.success(), "{status:?}");
}

#[test]
fn a_program_streams_to_a_grbl_board_and_ends_on_its_exact_end() {
    let dir = tempfile::tempdir().unwrap();
    let board = board("square", 3_000);
    // M3, S and M5 are grbl's spindle words: the board accepts them (and
    // has nothing to drive), so the check does too.
    let mut text =
        String::from("; a square, a half circle, then many short lines\nG21 G90 M3 S1000\n");
    text.push_str("G1 X-20 F6000\nG1 Y-20\nG2 X0 Y-20 I10 J0\n");
    for i in 1..=60 {
        text.push_str(&format!(
            "G1 X{:.1} Y-{:.1}\n",
            -0.2 * f64::from(i),
            20.0 - 0.1 * f64::from(i)
        ));
    }
    text.push_str("G1 X-5 Y-7.5\nM5\nM2\n");
    let total = text.lines().count();
    let gcode = write(dir.path(), "square.gcode", &text);
    let demo = start(&gcode, &board);
    let first = demo.screen();
    assert!(first.contains("grbl board on"), "{first}");
    let mut lines_seen = Vec::new();
    let screen = demo.wait_for("Done", LONG, |s| {
        if let Some((n, of)) = line_of(s) {
            assert_eq!(of, total, "{s}");
            if !lines_seen.contains(&n) {
                lines_seen.push(n);
            }
        }
        state(s).as_deref() == Some("Done")
    });
    assert!(
        lines_seen
            .iter()
            .filter(|&&n| (3..total).contains(&n))
            .count()
            >= 3,
        "line n advanced through the moves: {lines_seen:?}"
    );
    assert_eq!(line_of(&screen), Some((total, total)), "{screen}");
    assert!(screen.contains("· 100 %"), "{screen}");
    // -5 mm and -7.5 mm at 80 steps/mm, exactly: MPos × steps/mm.
    assert_eq!(
        read_position(&screen, 'X'),
        Some(("-5.000".to_string(), -400))
    );
    assert_eq!(
        read_position(&screen, 'Y'),
        Some(("-7.500".to_string(), -600))
    );
    quit(demo);
}

#[test]
fn space_holds_the_grbl_board_and_r_resumes_to_the_exact_end() {
    let dir = tempfile::tempdir().unwrap();
    // Gentle: a hold from 50 mm/s takes about half a second.
    let board = board("hold", 200);
    let gcode = write(
        dir.path(),
        "long.gcode",
        "G21 G90\nG1 X-60 Y-10 F3000\nG1 X-30 Y-20\nM2\n",
    );
    let demo = start(&gcode, &board);
    demo.wait_for("under way", LONG, |s| {
        state(s).as_deref() == Some("Run") && steps(s).0 < -5 * 80
    });
    demo.send(b" ");
    let held = demo.wait_for("Held", LONG, |s| state(s).as_deref() == Some("Held"));
    let at = steps(&held);
    assert!(at.0 > -60 * 80, "held before the end: {at:?}");
    std::thread::sleep(Duration::from_millis(300));
    let still = demo.screen();
    assert_eq!(steps(&still), at, "held means still: {still}");
    demo.send(b"r");
    let done = demo.wait_for("Done", LONG, |s| state(s).as_deref() == Some("Done"));
    assert_eq!(steps(&done), (-30 * 80, -20 * 80), "{done}");
    assert_eq!(line_of(&done), Some((4, 4)));
    quit(demo);
}

#[test]
fn c_cancels_the_grbl_program_and_nothing_runs_after_it() {
    let dir = tempfile::tempdir().unwrap();
    let board = board("cancel", 200);
    let gcode = write(
        dir.path(),
        "far.gcode",
        "G21 G90\nG1 X-100 F3000\nG1 X0\nM2\n",
    );
    let demo = start(&gcode, &board);
    demo.wait_for("under way", LONG, |s| steps(s).0 < -5 * 80);
    demo.send(b"c");
    let cancelled = demo.wait_for("Cancelled", LONG, |s| {
        state(s).as_deref() == Some("Cancelled")
    });
    let at = steps(&cancelled);
    std::thread::sleep(Duration::from_millis(400));
    let after = demo.screen();
    assert_eq!(steps(&after), at, "nothing moves after a cancel: {after}");
    assert!(at.0 > -100 * 80 && at.0 < 0, "{at:?}");
    quit(demo);
    // The board is at rest, unlocked, where the screen said.
    let mut config = SerialConfig::new(&board.path);
    config.dialect = Dialect::Grbl;
    let host = SerialBoard::open(config).expect("the board opens again");
    let x = host.axis(0).expect("X");
    assert_eq!(x.status().expect("status").position, at.0);
    x.move_steps(8_000, 80).expect("the board takes a move");
    host.close();
}

#[test]
fn a_file_the_boards_machine_cannot_run_is_refused_whole_before_a_byte() {
    let dir = tempfile::tempdir().unwrap();
    let board = board("refused", 3_000);
    let gcode = write(
        dir.path(),
        "bad.gcode",
        "G21 G90 F600\nG1 X-10 W3\nG1 Q4\nG1 Y-5\n",
    );
    let output = std::process::Command::new(BIN)
        .args(["--gcode", &gcode.to_string_lossy(), "--serial", &board.path])
        .args(["--dialect", "grbl"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1), "{output:?}");
    assert!(output.stdout.is_empty(), "nothing drawn");
    let stderr = String::from_utf8(output.stderr).unwrap();
    let name = gcode.to_string_lossy();
    assert!(
        stderr.contains("errors in the G-code; nothing was run"),
        "{stderr}"
    );
    for at in ["2:", "3:"] {
        assert!(stderr.contains(&format!("{name}:{at}")), "{at}:\n{stderr}");
    }
    let mut config = SerialConfig::new(&board.path);
    config.dialect = Dialect::Grbl;
    let host = SerialBoard::open(config).expect("the board opens again");
    assert_eq!(
        host.axis(0).expect("X").status().expect("status").position,
        0
    );
    host.close();

    // A cogstep board takes no G-code, and --machine is the hub's.
    let output = std::process::Command::new(BIN)
        .args(["--gcode", &gcode.to_string_lossy(), "--serial", &board.path])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("needs a grbl board"),
        "{output:?}"
    );
}

#[test]
fn the_live_demo_moves_a_grbl_axis_to_its_exact_target() {
    let board = board("live", 3_000);
    let demo = Demo::spawn(
        BIN,
        &["--serial", &board.path, "--dialect", "grbl"],
        Keyboard::Legacy,
    );
    let screen = demo.wait_text("Enter steps:", LONG);
    assert!(screen.contains("grbl"), "{screen}");
    pty::enter_move(&demo, -1_234, 8_000, LONG);
    demo.wait_for("the axis at its target", LONG, |s| {
        pty::number(s, "Current Position:", 1) == Some(-1_234) && pty::to_go(s, 1) == 0
    });
    // x is the board's soft reset: a board that was moving is in Alarm,
    // moves are refused with the way out, and c ($X) lifts it.
    pty::enter_move(&demo, 40_000, 8_000, LONG);
    demo.wait_for("moving", LONG, |s| {
        pty::number(s, "Current Position:", 1).is_some_and(|p| p > 0)
    });
    demo.send(b"x");
    let stopped = demo.wait_for("stopped", LONG, |s| {
        pty::to_go(s, 1) == 0 && pty::number(s, "Current Position:", 1).is_some_and(|p| p > 0)
    });
    let at = pty::position(&stopped, 1);
    assert!(at < 38_766, "stopped short of the target: {stopped}");
    demo.send(b"100\r");
    demo.wait_text("Enter speed:", LONG);
    demo.send(b"8000\r");
    demo.wait_text("unlock it with $X", LONG);
    // The refused answers stay on the prompt to be edited: Esc clears them.
    demo.send(b"\x1b");
    std::thread::sleep(Duration::from_millis(100));
    demo.send(b"\x1b");
    demo.wait_for("the steps prompt", LONG, |s| !s.contains("Enter speed:"));
    demo.send(b"c");
    demo.wait_text("cleared", LONG);
    pty::enter_move(&demo, 100, 8_000, LONG);
    demo.wait_for("the axis 100 steps on, exactly", LONG, |s| {
        pty::position(s, 1) == at + 100 && pty::to_go(s, 1) == 0
    });
    quit(demo);
}

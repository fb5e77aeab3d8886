//! `--gcode FILE --machine M.toml` end to end, as a person uses it: the
//! real binary in a pseudo-terminal, keys typed as bytes, the screen read
//! back with vt100. Small programs at fast feeds, so each run takes a
//! second or two.

mod pty;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use pty::{line_of, read_position, state, steps, Demo, Keyboard};

const BIN: &str = env!("CARGO_BIN_EXE_demo-tui");
const LONG: Duration = Duration::from_secs(20);

fn plotter() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../spreadsheet-export/machines/plotter.toml")
        .to_string_lossy()
        .into_owned()
}

/// A plotter that accelerates gently, so that a hold takes long enough to
/// be seen on screen (about half a second from 50 mm/s).
const GENTLE: &str = "[axes.x]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 300.0\nmax_accel_mm_s2 = 200.0\n\
                      [axes.y]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 300.0\nmax_accel_mm_s2 = 200.0\n\
                      [planner]\njunction_deviation_mm = 0.02\narc_tolerance_mm = 0.01\n";

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn start(gcode: &Path, machine: &str) -> Demo {
    let gcode = gcode.to_string_lossy().into_owned();
    let demo = Demo::spawn(
        BIN,
        &["--gcode", &gcode, "--machine", machine],
        Keyboard::Legacy,
    );
    demo.wait_text("State:", LONG);
    demo
}

fn position(screen: &str, letter: char) -> (String, i64) {
    read_position(screen, letter).unwrap_or_else(|| panic!("no {letter} position:\n{screen}"))
}

fn quit(mut demo: Demo) {
    demo.send(b"q");
    let status = demo.wait_exit(LONG);
    assert!(status.success(), "{status:?}");
}

#[test]
fn a_program_runs_line_by_line_to_done_on_its_exact_end() {
    let dir = tempfile::tempdir().unwrap();
    let gcode = write(
        dir.path(),
        "square.gcode",
        "; a square with a half circle\nG21 G90 G64\nG1 X20 F6000\nG1 Y20\n\
         G2 X0 Y20 I-10 J0\nG1 X5 Y7.5\nM2\n",
    );
    let demo = start(&gcode, &plotter());
    let mut lines_seen = Vec::new();
    let mut xy_seen = false;
    let screen = demo.wait_for("Done", LONG, |s| {
        if let Some((n, total)) = line_of(s) {
            assert_eq!(total, 7, "{s}");
            if !lines_seen.contains(&n) {
                lines_seen.push(n);
            }
        }
        xy_seen |= s.contains("XY view") && s.contains('●');
        state(s).as_deref() == Some("Done")
    });
    assert!(
        lines_seen.iter().filter(|&&n| (3..=6).contains(&n)).count() >= 2,
        "line n advanced through the moves: {lines_seen:?}"
    );
    assert!(xy_seen, "the XY view and the tool were drawn");
    assert_eq!(line_of(&screen), Some((7, 7)), "{screen}");
    assert!(screen.contains("· 100 %"), "{screen}");
    // 5 mm and 7.5 mm at 80 steps/mm, exactly.
    assert_eq!(position(&screen, 'X'), ("5.000".to_string(), 400));
    assert_eq!(position(&screen, 'Y'), ("7.500".to_string(), 600));
    quit(demo);
}

/// G28 homes onto the demo's simulated switches (2 mm beyond where each
/// axis starts): x at its low end becomes 10 mm, y at its high end 40 mm,
/// and the lines after it run from there to their exact ends.
#[test]
fn g28_homes_onto_the_simulated_switches_and_the_program_goes_on_from_home() {
    let dir = tempfile::tempdir().unwrap();
    let machine = write(
        dir.path(),
        "homing.toml",
        "[axes.x]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 300.0\nmax_accel_mm_s2 = 3000.0\n\
         soft_min_mm = 10.0\nsoft_max_mm = 200.0\nhome = \"min\"\nhome_speed_mm_s = 40.0\n\
         [axes.y]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 300.0\nmax_accel_mm_s2 = 3000.0\n\
         soft_min_mm = 0.0\nsoft_max_mm = 40.0\nhome = \"max\"\nhome_speed_mm_s = 40.0\n\
         [planner]\njunction_deviation_mm = 0.02\narc_tolerance_mm = 0.01\n",
    );
    let gcode = write(
        dir.path(),
        "home.gcode",
        "G21 G90\nG28\nG1 X15 Y30 F6000\nM2\n",
    );
    let demo = start(&gcode, &machine.to_string_lossy());
    let screen = demo.wait_for("Done", LONG, |s| state(s).as_deref() == Some("Done"));
    assert_eq!(
        position(&screen, 'X'),
        ("15.000".to_string(), 1_200),
        "{screen}"
    );
    assert_eq!(
        position(&screen, 'Y'),
        ("30.000".to_string(), 2_400),
        "{screen}"
    );
    quit(demo);
}

/// G28 naming an axis that has no home switch is an error at its column
/// before anything moves.
#[test]
fn g28_of_an_axis_without_a_switch_is_refused_with_its_column() {
    let dir = tempfile::tempdir().unwrap();
    let gcode = write(dir.path(), "home.gcode", "G21 G90\nG28 X0\nM2\n");
    let output = std::process::Command::new(BIN)
        .args(["--gcode", &gcode.to_string_lossy(), "--machine", &plotter()])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("home.gcode:2:5: G28: axis x has no home switch"),
        "{stderr}"
    );
}

#[test]
fn space_holds_along_the_path_and_r_resumes_to_the_exact_end() {
    let dir = tempfile::tempdir().unwrap();
    let machine = write(dir.path(), "gentle.toml", GENTLE);
    let gcode = write(
        dir.path(),
        "long.gcode",
        "G21 G90\nG1 X60 Y10 F3000\nG1 X30 Y20\nM2\n",
    );
    let demo = start(&gcode, &machine.to_string_lossy());
    demo.wait_for("under way", LONG, |s| {
        state(s).as_deref() == Some("Run") && steps(s).0 > 5 * 80
    });
    demo.send(b" ");
    let mut hold_seen = false;
    let held = demo.wait_for("Held", LONG, |s| {
        hold_seen |= state(s).as_deref() == Some("Hold");
        state(s).as_deref() == Some("Held")
    });
    assert!(hold_seen, "Hold came before Held");
    let at = steps(&held);
    assert!(at.0 < 60 * 80, "held before the end: {at:?}");
    // Held means still.
    std::thread::sleep(Duration::from_millis(300));
    let still = demo.screen();
    assert_eq!(steps(&still), at, "{still}");
    assert_eq!(state(&still).as_deref(), Some("Held"));
    demo.send(b"r");
    demo.wait_for("running again", LONG, |s| {
        state(s).as_deref() != Some("Held")
    });
    let done = demo.wait_for("Done", LONG, |s| state(s).as_deref() == Some("Done"));
    assert_eq!(steps(&done), (30 * 80, 20 * 80), "{done}");
    assert_eq!(line_of(&done), Some((4, 4)));
    quit(demo);
}

#[test]
fn c_cancels_along_the_path_and_nothing_runs_after_it() {
    let dir = tempfile::tempdir().unwrap();
    let machine = write(dir.path(), "gentle.toml", GENTLE);
    // An arc of many chords, so that the worker is still feeding.
    let gcode = write(
        dir.path(),
        "arc.gcode",
        "G21 G90\nG1 X10 F3000\nG3 X10 Y0 I-10 J0\nG1 X0 Y0\nM2\n",
    );
    let demo = start(&gcode, &machine.to_string_lossy());
    demo.wait_for("on the arc", LONG, |s| {
        line_of(s).is_some_and(|(n, _)| n == 3)
    });
    demo.send(b"c");
    let cancelled = demo.wait_for("Cancelled", LONG, |s| {
        state(s).as_deref() == Some("Cancelled")
    });
    let at = steps(&cancelled);
    std::thread::sleep(Duration::from_millis(400));
    let after = demo.screen();
    assert_eq!(steps(&after), at, "nothing moves after a cancel: {after}");
    assert_eq!(state(&after).as_deref(), Some("Cancelled"));
    assert_ne!(at, (0, 0), "cancelled before the end");
    // Keys for a program that is over are refused, with the reason.
    demo.send(b"r");
    demo.wait_text("the program is over (Cancelled)", LONG);
    quit(demo);
}

#[test]
fn q_while_moving_stops_the_axes_and_ends_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let gcode = write(dir.path(), "far.gcode", "G1 X500 F3000\nM2\n");
    let demo = start(&gcode, &plotter());
    demo.wait_for("moving", LONG, |s| steps(s).0 > 80);
    let started = Instant::now();
    quit(demo);
    assert!(started.elapsed() < Duration::from_secs(5));
}

#[test]
fn a_file_with_errors_lists_each_with_its_line_and_column_and_runs_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let gcode = write(
        dir.path(),
        "bad.gcode",
        "G21 F600\nG1 X10 M3\nG1 Q4\nG1 X20\nG2 X30\n",
    );
    let output = std::process::Command::new(BIN)
        .args(["--gcode", &gcode.to_string_lossy(), "--machine", &plotter()])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1), "{output:?}");
    assert!(output.stdout.is_empty(), "nothing drawn");
    let stderr = String::from_utf8(output.stderr).unwrap();
    let name = gcode.to_string_lossy();
    assert!(
        stderr.contains(&format!("{name}: 3 errors in the G-code; nothing was run")),
        "{stderr}"
    );
    for at in ["2:8: unsupported word M3", "3:4:", "5:1:"] {
        assert!(
            stderr.contains(&format!("{name}:{at}")),
            "{at} missing:\n{stderr}"
        );
    }

    // A machine file that is not one, and --serial, are refused the same way.
    let machine = write(dir.path(), "bad.toml", "[axes.x]\nsteps_per_mm = 80.0\n");
    let output = std::process::Command::new(BIN)
        .args(["--gcode", &gcode.to_string_lossy(), "--machine"])
        .arg(&machine)
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&output.stderr).contains("bad.toml"));
    let output = std::process::Command::new(BIN)
        .args(["--gcode", &gcode.to_string_lossy(), "--machine", &plotter()])
        .args(["--serial", "/dev/null"])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&output.stderr).contains("emulated hub only"),
        "{output:?}"
    );
}

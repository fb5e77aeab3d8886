//! `--motor` end to end: the real binary in a pseudo-terminal, a move on an
//! axis whose motor keeps up and one on an axis whose motor cannot.

mod pty;

use std::path::Path;
use std::time::Duration;

use pty::{number, Demo, Keyboard};

const BIN: &str = env!("CARGO_BIN_EXE_demo-tui");
const LONG: Duration = Duration::from_secs(20);

fn motor(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../spreadsheet-export/motors")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

#[test]
fn the_selected_axis_shows_its_rotor_and_a_lost_synchronism() {
    let strong = format!("1={}", motor("type-300.toml"));
    let weak = format!("2={}", motor("type-100.toml"));
    let demo = Demo::spawn(
        BIN,
        &["--axes", "2", "--motor", &strong, "--motor", &weak],
        Keyboard::Legacy,
    );
    demo.wait_text("Rotor · axis 1 (type-300): lag", LONG);
    enter_move(&demo, 1_000, 1_500);
    let screen = demo.wait_for("axis 1 at 1000", LONG, |s| {
        number(s, "Current Position:", 1) == Some(1_000) && number(s, "STM:", 1) == Some(0)
    });
    assert!(!screen.contains("LOST"), "{screen}");
    demo.wait_text("· synchronous", LONG);

    // Axis 2: 2,000 steps at 4,000 steps/s is beyond the type 100.
    demo.send(b"\t");
    demo.wait_text("Rotor · axis 2 (type-100)", LONG);
    enter_move(&demo, 2_000, 4_000);
    let screen = demo.wait_text("LOST SYNCHRONISM at step", LONG);
    assert!(
        screen.contains("Rotor · axis 2 (type-100): LOST SYNCHRONISM"),
        "{screen}"
    );
    // The axis itself still makes every step: only the rotor is lost.
    demo.wait_for("axis 2 at 2000", LONG, |s| {
        number(s, "Current Position:", 2) == Some(2_000)
    });
}

/// Answers both prompts for the selected axis.
fn enter_move(demo: &Demo, steps: i64, speed: u32) {
    pty::enter_move(demo, steps, speed, LONG);
}

//! A real G-code sender: cncjs 1.11.5 (`tests/cncjs/`, installed with
//! `npm ci` there) streams G-code files of lines and arcs to the board
//! simulator's grbl dialect over a pseudo-terminal, headless (its server
//! and its socket.io client, driven by `tests/cncjs/run.js`). The end
//! position cncjs reads from the board's reports is the program's, exactly.
//!
//! Ignored: it needs Node.js and the npm install (`.ci/run` does both and
//! runs it).
//! `cargo test -p cogstep-tests --test grbl_cncjs -- --ignored`

use std::path::{Path, PathBuf};
use std::process::Command;

use cogstep_test_support::grbl::{GrblBoard, FAST};

/// Lines and arcs (G2 and G3, I/J and R, a helix, G91), ending on
/// X12.34 Y6.78 Z0.5: 3,085, 1,695 and 125 steps.
const PROGRAM: &str = "\
(cogstep: lines and arcs through cncjs)
G21 G90 G17
G0 X5 Y5
G1 X25 Y5 F3000
G2 X35 Y15 I0 J10
G3 X25 Y25 R10
G1 X5 Y25 Z-1
G2 X5 Y5 Z0 I0 J-10 ; a half circle, with Z
G91 G1 X1.25 Y-0.5
G90 G0 X12.34 Y6.78 Z0.5
";

const END: &str = r#""mpos":{"x":"12.340","y":"6.780","z":"0.500"}"#;

fn cncjs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("cncjs")
}

/// Runs `program` through cncjs with `actions` (`MS:COMMAND[:ARG]`);
/// returns run.js's JSON line.
fn run_cncjs(name: &str, program: &str, actions: &[&str]) -> String {
    let dir = cncjs_dir();
    assert!(
        dir.join("node_modules/cncjs").exists(),
        "cncjs is not installed: run `npm ci` in {}",
        dir.display()
    );
    let tmp = std::env::temp_dir();
    let id = std::process::id();
    let gcode = tmp.join(format!("cogstep-cncjs-{id}-{name}.nc"));
    std::fs::write(&gcode, program).expect("program");
    let board = GrblBoard::start(&format!("cncjs-{name}"), FAST);
    let mut command = Command::new("node");
    command
        .arg(dir.join("run.js"))
        .args(["--port", &board.path])
        .arg("--gcode")
        .arg(&gcode)
        .args(["--timeout-ms", "120000"]);
    for action in actions {
        command.args(["--at", action]);
    }
    let output = command.output().expect("node runs");
    drop(board);
    let _ = std::fs::remove_file(&gcode);
    let stdout = String::from_utf8_lossy(&output.stdout).trim().to_string();
    eprintln!("{name}: {stdout}");
    assert!(output.status.success(), "cncjs: {stdout}");
    stdout
}

fn field<'a>(json: &'a str, key: &str) -> &'a str {
    let start = json.find(&format!("\"{key}\":")).expect(key) + key.len() + 3;
    let end = json[start..]
        .find([',', '}'])
        .map_or(json.len(), |end| start + end);
    &json[start..end]
}

fn assert_clean_finish(json: &str) {
    assert!(json.contains(r#""finished":true"#), "{json}");
    assert!(json.contains(END), "{json}");
    assert!(json.contains(r#""errors":[]"#), "{json}");
    assert!(json.contains(r#""alarms":[]"#), "{json}");
    assert_eq!(field(json, "sent"), field(json, "total"));
    assert_eq!(field(json, "received"), field(json, "total"));
}

#[test]
#[ignore]
fn cncjs_streams_lines_and_arcs_to_the_exact_end() {
    let json = run_cncjs("plain", PROGRAM, &[]);
    assert_clean_finish(&json);
}

#[test]
#[ignore]
fn cncjs_feed_hold_and_resume_finish_at_the_exact_end() {
    let json = run_cncjs("hold", PROGRAM, &["700:feedhold", "1700:cyclestart"]);
    assert_clean_finish(&json);
    assert!(json.contains(r#""hold_seen":true"#), "{json}");
}

#[test]
#[ignore]
fn cncjs_feed_override_changes_the_time_not_the_end() {
    let plain = run_cncjs("override-plain", PROGRAM, &[]);
    let slow = run_cncjs(
        "override-slow",
        PROGRAM,
        &[
            "100:feedOverride:-10",
            "100:feedOverride:-10",
            "100:feedOverride:-10",
        ],
    );
    assert_clean_finish(&plain);
    assert_clean_finish(&slow);
    let time = |json: &str| {
        field(json, "elapsed_ms")
            .parse::<u64>()
            .expect("elapsed_ms")
    };
    assert!(time(&slow) > time(&plain), "{plain}\n{slow}");
}

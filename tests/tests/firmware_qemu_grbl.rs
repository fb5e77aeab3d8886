//! grbl 1.1 on the firmware: cogstep's LM3S6965 firmware under QEMU
//! (`firmware/run-qemu --dialect grbl`), driven byte for byte over its
//! UART's pseudo-terminal as a G-code sender drives it (the conversations
//! of `tests/grbl.rs`, which run against the board simulator), and once by
//! a real sender, cncjs (as `tests/grbl_cncjs.rs` does with the simulator).
//! Every program's end position is checked exactly: MPos is the axes'
//! step count over steps/mm, printed with 3 decimals.
//!
//! These tests need `qemu-system-arm` and Debian's Rust toolchain (see
//! firmware/README.md), and the cncjs one Node.js and `npm ci` in
//! `tests/cncjs`, so they are `#[ignore]`d; `.ci/run` runs them with
//! `cargo test -p cogstep-tests --test firmware_qemu_grbl -- --ignored`.
//!
//! The firmware runs in real time: the moves are short and every wait has
//! a generous limit; nothing here asserts how fast anything is.
#![cfg(unix)]

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::process::Command;
use std::time::{Duration, Instant};

use cogstep_test_support::script::{repo_root, DeviceScript};
use serialport::SerialPort;

/// The longest any wait in these tests may take before it fails.
const PATIENCE: Duration = Duration::from_secs(60);

/// Quick axes for the tests (the firmware keeps settings in RAM: every
/// test sends them): 250 steps/mm (grbl's default), 50 mm/s (12,500
/// steps/s), 2,000 mm/s².
const QUICK: [&str; 6] = [
    "$110=3000",
    "$111=3000",
    "$112=3000",
    "$120=2000",
    "$121=2000",
    "$122=2000",
];

/// grbl's receive buffer: what a character-counting sender keeps in flight.
const RX_BUFFER: usize = 128;

const WELCOME: &str = "Grbl 1.1h ['$' for help]";

/// The firmware under QEMU in its grbl dialect, through
/// `firmware/run-qemu --dialect grbl`; taken down (SIGTERM to the script,
/// which stops QEMU) when dropped.
fn qemu() -> DeviceScript {
    DeviceScript::start("firmware/run-qemu", &["--dialect", "grbl"], false)
}

/// A grbl conversation on the firmware's pseudo-terminal.
struct Board {
    port: Box<dyn SerialPort>,
    pending: Vec<u8>,
    /// Lines (not status reports) the board sent and no one has read.
    lines: VecDeque<String>,
    /// The last status report.
    last_status: Option<String>,
    // Last: the port closes before QEMU goes.
    qemu: DeviceScript,
}

impl Board {
    /// A fresh firmware, reset at rest (its welcome line read), with the
    /// [`QUICK`] settings.
    fn start() -> Board {
        let qemu = qemu();
        let port = serialport::new(&qemu.path, 115_200)
            .timeout(Duration::from_millis(5))
            .open()
            .expect("the pty opens");
        let mut board = Board {
            port,
            pending: Vec::new(),
            lines: VecDeque::new(),
            last_status: None,
            qemu,
        };
        // run-qemu read the boot's welcome line; a reset at rest brings
        // another, and no alarm. Then start from a clean slate.
        board.send(b"\x18");
        board.expect_line(WELCOME);
        std::thread::sleep(Duration::from_millis(200));
        board.fill();
        board.lines.clear();
        for setting in QUICK {
            assert_eq!(board.command(setting), ["ok"], "{setting}");
        }
        board
    }

    fn path(&self) -> String {
        self.qemu.path.clone()
    }

    fn send(&mut self, bytes: &[u8]) {
        self.port.write_all(bytes).expect("write");
    }

    /// Reads what came, sorting reports from lines.
    fn fill(&mut self) {
        let mut bytes = [0u8; 4096];
        match self.port.read(&mut bytes) {
            Ok(count) => self.pending.extend_from_slice(&bytes[..count]),
            Err(error) if error.kind() == std::io::ErrorKind::TimedOut => {}
            Err(error) => panic!("read: {error}"),
        }
        while let Some(end) = self.pending.iter().position(|&b| b == b'\n') {
            let raw: Vec<u8> = self.pending.drain(..=end).collect();
            let line = String::from_utf8(raw).expect("ASCII");
            assert!(
                line.ends_with("\r\n"),
                "grbl ends lines with CRLF: {line:?}"
            );
            let line = line.trim_end().to_string();
            if line.is_empty() {
                continue;
            }
            if line.starts_with('<') {
                self.last_status = Some(line);
            } else {
                self.lines.push_back(line);
            }
        }
    }

    fn next_line(&mut self) -> String {
        let start = Instant::now();
        loop {
            if let Some(line) = self.lines.pop_front() {
                return line;
            }
            assert!(start.elapsed() < PATIENCE, "no line");
            self.fill();
        }
    }

    /// Reads lines until `expected` (what comes before it is left over
    /// from run-qemu's first questions, or a reset's).
    fn expect_line(&mut self, expected: &str) {
        let start = Instant::now();
        while self.next_line() != expected {
            assert!(start.elapsed() < PATIENCE, "no {expected:?}");
        }
    }

    /// One line and its replies, the `ok` or `error:N` last.
    fn command(&mut self, line: &str) -> Vec<String> {
        self.send(format!("{line}\n").as_bytes());
        let mut reply = Vec::new();
        loop {
            let line = self.next_line();
            let last = line == "ok" || line.starts_with("error:");
            reply.push(line);
            if last {
                return reply;
            }
        }
    }

    fn status(&mut self) -> String {
        self.last_status = None;
        self.send(b"?");
        let start = Instant::now();
        while self.last_status.is_none() {
            assert!(start.elapsed() < PATIENCE, "no report");
            self.fill();
        }
        self.last_status.clone().unwrap_or_default()
    }

    /// The overrides of the next report that shows them (a report after
    /// a change does, unless it is the one that shows `WCO:`).
    fn overrides_shown(&mut self) -> String {
        for _ in 0..3 {
            let report = self.status();
            if let Some(start) = report.find("|Ov:") {
                let rest = &report[start + 4..];
                let end = rest.find(['|', '>']).unwrap_or(rest.len());
                return rest[..end].to_string();
            }
        }
        panic!("no report shows the overrides");
    }

    fn wait_state(&mut self, state: &str) -> String {
        let start = Instant::now();
        loop {
            let report = self.status();
            if report.starts_with(&format!("<{state}|")) {
                return report;
            }
            assert!(start.elapsed() < PATIENCE, "never {state}: {report}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Streams `program` line by line by grbl's character counting: no
    /// more than 128 bytes of unanswered lines in flight; `between` runs
    /// after every answer with the number answered so far. Returns the
    /// answers.
    fn stream(
        &mut self,
        program: &[&str],
        mut between: impl FnMut(&mut Board, usize),
    ) -> Vec<String> {
        let mut in_flight: VecDeque<usize> = VecDeque::new();
        let mut answers = Vec::new();
        let mut next = 0;
        let start = Instant::now();
        while answers.len() < program.len() {
            while next < program.len()
                // The line and its LF.
                && in_flight.iter().sum::<usize>() + program[next].len() < RX_BUFFER
            {
                let line = format!("{}\n", program[next]);
                self.send(line.as_bytes());
                in_flight.push_back(line.len());
                next += 1;
            }
            self.fill();
            while let Some(line) = self.lines.pop_front() {
                assert!(
                    line == "ok" || line.starts_with("error:"),
                    "unexpected {line:?}"
                );
                in_flight.pop_front().expect("an answer per line sent");
                answers.push(line);
                between(self, answers.len());
            }
            assert!(start.elapsed() < PATIENCE * 2, "streaming stalled");
        }
        answers
    }
}

/// The MPos of a report.
fn mpos(report: &str) -> &str {
    let start = report.find("MPos:").expect("MPos") + 5;
    let end = report[start..]
        .find('|')
        .map_or(report.len() - 1, |end| start + end);
    &report[start..end]
}

/// Lines and arcs (G2 and G3, I/J and R, a helix, G91), ending on
/// X12.34 Y6.78 Z0.5: 3,085, 1,695 and 125 steps.
const PROGRAM: [&str; 9] = [
    "G21 G90 G17",
    "G0 X5 Y5",
    "G1 X25 Y5 F3000",
    "G2 X35 Y15 I0 J10",
    "G3 X25 Y25 R10",
    "G1 X5 Y25 Z-1",
    "G2 X5 Y5 Z0 I0 J-10",
    "G91 G1 X1.25 Y-0.5",
    "G90 G0 X12.34 Y6.78 Z0.5",
];

const PROGRAM_END: &str = "12.340,6.780,0.500";

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn welcome_build_info_and_settings_in_ram() {
    let mut board = Board::start();
    let info = board.command("$I");
    assert_eq!(
        info,
        [
            format!("[VER:1.1h.cogstep-{}:]", env!("CARGO_PKG_VERSION")),
            "[OPT:,31,128]".to_string(),
            "ok".to_string()
        ]
    );
    let settings = board.command("$$");
    for expected in ["$100=250.000", "$110=3000.000", "$122=2000.000"] {
        assert!(
            settings.contains(&expected.to_string()),
            "{expected} in {settings:?}"
        );
    }
    // 250 steps/mm × 6,000 mm/min is 25,000 steps/s: more than the
    // firmware's axes make.
    assert_eq!(board.command("$110=6000"), ["error:12"]);
    assert_eq!(
        mpos(&board.wait_state("Idle")),
        "0.000,0.000,0.000",
        "at rest at boot"
    );
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn homing_has_no_switch_to_find_under_qemu() {
    let mut board = Board::start();
    // Homing off (grbl's default): the setting is disabled.
    assert_eq!(board.command("$H"), ["error:5"]);
    // On: there is no switch input to read, so it fails at once, without
    // moving: grbl's alarm for a switch not found.
    assert_eq!(board.command("$22=1"), ["ok"]);
    assert_eq!(board.command("$H"), ["ALARM:9", "ok"]);
    let report = board.wait_state("Alarm");
    assert_eq!(mpos(&report), "0.000,0.000,0.000");
    assert_eq!(board.command("$X"), ["[MSG:Caution: Unlocked]", "ok"]);
    assert_eq!(board.command("G0X1"), ["ok"]);
    assert_eq!(mpos(&board.wait_state("Idle")), "1.000,0.000,0.000");
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn lines_and_arcs_streamed_line_by_line_end_exactly() {
    let mut board = Board::start();
    let answers = board.stream(&PROGRAM, |_, _| {});
    assert!(answers.iter().all(|answer| answer == "ok"), "{answers:?}");
    assert_eq!(mpos(&board.wait_state("Idle")), PROGRAM_END);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn a_feed_hold_stops_on_the_path_and_resume_finishes_exactly() {
    let mut board = Board::start();
    let mut program = vec!["G21G90"];
    let lines: Vec<String> = (1..=10)
        .map(|k| format!("G1X{}Y{}F1200", k * 2, (k % 3) as f64 * 0.5))
        .collect();
    program.extend(lines.iter().map(String::as_str));
    let mut held = None;
    let answers = board.stream(&program, |board, answered| {
        if answered == 4 && held.is_none() {
            board.wait_state("Run");
            board.send(b"!");
            let report = board.wait_state("Hold:0");
            // At rest: a later report shows the same position.
            std::thread::sleep(Duration::from_millis(200));
            assert_eq!(mpos(&board.status()), mpos(&report));
            held = Some(report);
            board.send(b"~");
        }
    });
    assert!(answers.iter().all(|answer| answer == "ok"), "{answers:?}");
    let held = held.expect("the hold happened");
    assert_ne!(mpos(&held), "20.000,0.500,0.000");
    assert_eq!(mpos(&board.wait_state("Idle")), "20.000,0.500,0.000");
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn feed_and_rapid_overrides_mid_program_keep_the_end_exact() {
    let mut board = Board::start();
    let lines: Vec<String> = (1..=8)
        .map(|k| {
            if k % 2 == 0 {
                format!("G0X{}Y{}", k * 2, k)
            } else {
                format!("G1X{}Y{}F900", k * 2, k)
            }
        })
        .collect();
    let program: Vec<&str> = lines.iter().map(String::as_str).collect();
    let mut shown = None;
    let answers = board.stream(&program, |board, answered| {
        if answered == 1 && shown.is_none() {
            // Feed +10 % five times (150 %), rapids at 50 %.
            board.send(&[0x91, 0x91, 0x91, 0x91, 0x91, 0x96]);
            shown = Some(board.overrides_shown());
        }
    });
    assert!(answers.iter().all(|answer| answer == "ok"), "{answers:?}");
    let shown = shown.expect("the overrides were sent");
    assert_eq!(shown, "150,50,100");
    assert_eq!(mpos(&board.wait_state("Idle")), "16.000,8.000,0.000");
    // Back to 100 % (0x90, 0x95): the next move ends exactly too.
    board.send(&[0x90, 0x95]);
    assert_eq!(board.overrides_shown(), "100,100,100");
    assert_eq!(board.command("G1X0Y0F3000"), ["ok"]);
    assert_eq!(mpos(&board.wait_state("Idle")), "0.000,0.000,0.000");
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn a_malformed_line_is_an_error_and_moves_nothing() {
    let mut board = Board::start();
    assert_eq!(board.command("G1X5Q7F100"), ["error:20"]);
    assert_eq!(board.command("G1X"), ["error:2"]);
    assert_eq!(board.command("G1X5"), ["error:22"]);
    assert_eq!(board.command("$J=G1X5F100"), ["error:16"]);
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(mpos(&board.wait_state("Idle")), "0.000,0.000,0.000");
    // The next line runs.
    assert_eq!(board.command("G1X1F3000"), ["ok"]);
    assert_eq!(mpos(&board.wait_state("Idle")), "1.000,0.000,0.000");
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn a_soft_reset_mid_move_is_alarm_3_and_unlock_recovers() {
    let mut board = Board::start();
    assert_eq!(board.command("G1X40F1200"), ["ok"]);
    board.wait_state("Run");
    std::thread::sleep(Duration::from_millis(300));
    board.send(b"\x18");
    assert_eq!(board.next_line(), "ALARM:3");
    assert_eq!(board.next_line(), WELCOME);
    assert_eq!(board.next_line(), "[MSG:'$H'|'$X' to unlock]");
    let report = board.wait_state("Alarm");
    let stopped = mpos(&report).to_string();
    assert_ne!(stopped, "0.000,0.000,0.000");
    assert_ne!(stopped, "40.000,0.000,0.000");
    // Stopped at once: the position stays.
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(mpos(&board.status()), stopped);
    // Locked: G-code and jogs are refused.
    assert_eq!(board.command("G0X0"), ["error:9"]);
    assert_eq!(board.command("$J=X0F100"), ["error:9"]);
    assert_eq!(board.command("$X"), ["[MSG:Caution: Unlocked]", "ok"]);
    assert_eq!(mpos(&board.wait_state("Idle")), stopped);
    // The position was kept exactly: the program goes on from it.
    assert_eq!(board.command("G0X2.5Y1"), ["ok"]);
    assert_eq!(mpos(&board.wait_state("Idle")), "2.500,1.000,0.000");
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn a_jog_and_a_jog_cancel_stop_on_the_path() {
    let mut board = Board::start();
    assert_eq!(board.command("$J=G91X1Y-0.5F1200"), ["ok"]);
    assert_eq!(mpos(&board.wait_state("Idle")), "1.000,-0.500,0.000");
    assert_eq!(board.command("$J=G90X30F600"), ["ok"]);
    board.wait_state("Jog");
    std::thread::sleep(Duration::from_millis(200));
    board.send(&[0x85]);
    let report = board.wait_state("Idle");
    let stopped = mpos(&report).to_string();
    assert_ne!(stopped, "30.000,-0.500,0.000");
    // What the axes stepped is where the next line starts.
    assert_eq!(board.command("G0X3Y2"), ["ok"]);
    assert_eq!(mpos(&board.wait_state("Idle")), "3.000,2.000,0.000");
}

/// cncjs 1.11.5 (`tests/cncjs`, `npm ci` there) streams the lines-and-arcs
/// program to the firmware and reads the exact end from its reports.
#[test]
#[ignore = "needs qemu-system-arm, the firmware toolchain and cncjs (npm ci): .ci/run runs it"]
fn cncjs_streams_lines_and_arcs_to_the_firmware_to_the_exact_end() {
    let dir = repo_root().join("tests/cncjs");
    assert!(
        dir.join("node_modules/cncjs").exists(),
        "cncjs is not installed: run `npm ci` in {}",
        dir.display()
    );
    // The settings live in the firmware's RAM: set them, then let go of
    // the port for cncjs (run-qemu keeps QEMU's side open).
    let board = Board::start();
    let path = board.path();
    let Board { port, qemu, .. } = board;
    drop(port);
    let gcode = std::env::temp_dir().join(format!("cogstep-fw-cncjs-{}.nc", std::process::id()));
    std::fs::write(&gcode, format!("{}\n", PROGRAM.join("\n"))).expect("program");
    let output = Command::new("node")
        .arg(dir.join("run.js"))
        .args(["--port", &path])
        .arg("--gcode")
        .arg(&gcode)
        .args(["--timeout-ms", "120000"])
        .output()
        .expect("node runs");
    let _ = std::fs::remove_file(&gcode);
    drop(qemu);
    let json = String::from_utf8_lossy(&output.stdout).trim().to_string();
    eprintln!("cncjs: {json}");
    assert!(output.status.success(), "cncjs: {json}");
    assert!(json.contains(r#""finished":true"#), "{json}");
    assert!(
        json.contains(r#""mpos":{"x":"12.340","y":"6.780","z":"0.500"}"#),
        "{json}"
    );
    assert!(json.contains(r#""errors":[]"#), "{json}");
    assert!(json.contains(r#""alarms":[]"#), "{json}");
}

/// The host's side against the firmware: `SerialBoard` opens the grbl
/// board (its `$$` read), streams the lines-and-arcs program by character
/// counting (`stream_gcode`) to the exact end, then moves an axis in
/// steps to its exact target.
#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn the_host_streams_a_program_to_the_firmware_and_moves_in_exact_steps() {
    use driver::serial::host::{SerialBoard, SerialConfig, StreamState};
    use driver::serial::Dialect;
    use driver::AxisContract;

    let Board { port, qemu, .. } = Board::start();
    // The raw conversation is over: the host has the port alone.
    drop(port);
    let mut config = SerialConfig::new(&qemu.path);
    config.dialect = Dialect::Grbl;
    config.timeout = Duration::from_secs(3);
    let host = SerialBoard::open(config).expect("the host opens the firmware");
    assert_eq!(host.identity(), WELCOME);
    assert!(host.grbl_settings().contains(&(110, 3000.0)));
    let program: Vec<String> = PROGRAM.iter().map(|line| line.to_string()).collect();
    let stream = host.stream_gcode(&program).expect("it streams");
    let start = Instant::now();
    while !stream.progress().state.is_over() {
        assert!(start.elapsed() < PATIENCE, "{:?}", stream.progress());
        std::thread::sleep(Duration::from_millis(20));
    }
    let progress = stream.progress();
    assert_eq!(progress.state, StreamState::Done, "{progress:?}");
    assert!(progress.most_bytes_in_flight <= RX_BUFFER);
    let position = |index: usize| {
        host.refresh().expect("a report");
        host.axis(index)
            .expect("an axis")
            .status()
            .expect("status")
            .position
    };
    assert_eq!([position(0), position(1), position(2)], [3_085, 1_695, 125]);
    let y = host.axis(1).expect("Y");
    y.move_steps(5_000, -695).expect("a move in steps");
    let start = Instant::now();
    while position(1) != 1_000 || y.status().expect("status").steps_to_go != 0 {
        assert!(start.elapsed() < PATIENCE, "Y at {}", position(1));
        std::thread::sleep(Duration::from_millis(20));
    }
    host.close();
    drop(qemu);
}

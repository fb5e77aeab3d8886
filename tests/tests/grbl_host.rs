//! The host driving a grbl board: `SerialBoard` against the board
//! simulator's grbl dialect over a real pseudo-terminal — opening it (its
//! settings read from `$$`), moves in steps, a G-code program streamed by
//! character counting (never more than the board's 128 bytes in flight),
//! a feed hold and resume, a cancel, an emergency stop and `$X`, a program
//! refused before a byte goes out, and an `error:N` that stops the stream.
//! Every end position is checked exactly, in steps.

use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use cogstep_test_support::grbl::{GrblBoard, FAST};
use driver::serial::host::{
    Capabilities, GcodeStream, SerialBoard, SerialConfig, StreamError, StreamRefusal, StreamState,
    FAULT_GRBL_ALARM,
};
use driver::serial::Dialect;
use driver::{AxisContract, AxisError};

/// grbl's receive buffer.
const RX_BUFFER: usize = 128;
/// The longest any wait here may take before it fails.
const PATIENCE: Duration = Duration::from_secs(30);

struct Rig {
    board: SerialBoard,
    _sim: GrblBoard,
    _turn: MutexGuard<'static, ()>,
}

/// One board at a time: each runs a hub in real time, and the machine
/// has two cores.
static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

fn rig(name: &str) -> Rig {
    rig_with(name, FAST)
}

fn rig_with(name: &str, settings: &str) -> Rig {
    let turn = ONE_AT_A_TIME
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    let sim = GrblBoard::start(&format!("host-{name}"), settings);
    let mut config = SerialConfig::new(&sim.path);
    config.dialect = Dialect::Grbl;
    // A loaded machine (the suites run side by side) may answer slowly.
    config.timeout = Duration::from_secs(3);
    let board = SerialBoard::open(config).expect("the grbl board opens");
    Rig {
        board,
        _sim: sim,
        _turn: turn,
    }
}

fn lines(text: &str) -> Vec<String> {
    text.lines().map(str::to_string).collect()
}

fn positions(board: &SerialBoard) -> [i64; 3] {
    board.refresh().expect("a status report");
    [0, 1, 2].map(|index| {
        board
            .axis(index)
            .expect("an axis")
            .status()
            .expect("status")
            .position
    })
}

/// Waits until the stream is over; returns how it ended.
fn wait_over(stream: &GcodeStream) -> StreamState {
    let start = Instant::now();
    loop {
        let progress = stream.progress();
        assert!(
            progress.bytes_in_flight <= RX_BUFFER,
            "{} bytes in flight",
            progress.bytes_in_flight
        );
        if progress.state.is_over() {
            return progress.state;
        }
        assert!(start.elapsed() < PATIENCE, "not over: {progress:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

fn wait_for(what: &str, mut condition: impl FnMut() -> bool) {
    let start = Instant::now();
    while !condition() {
        assert!(start.elapsed() < PATIENCE, "never: {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn a_grbl_board_opens_with_its_settings_and_moves_in_exact_steps() {
    let rig = rig("open");
    let board = &rig.board;
    assert_eq!(board.identity(), "Grbl 1.1h ['$' for help]");
    assert_eq!(board.capabilities(), Capabilities::GRBL);
    assert_eq!(board.axis_count(), 3);
    let settings = board.grbl_settings();
    assert!(settings.contains(&(100, 250.0)), "{settings:?}");
    assert!(settings.contains(&(110, 12_000.0)), "{settings:?}");
    let x = board.axis(0).expect("X");
    x.move_steps(20_000, 1_001).expect("a move");
    wait_for("X at rest", || {
        board.refresh().is_ok() && x.status().is_ok_and(|s| s.steps_to_go == 0)
    });
    let y = board.axis(1).expect("Y");
    y.move_steps(10_000, -333).expect("a move");
    wait_for("Y at rest", || {
        board.refresh().is_ok() && y.status().is_ok_and(|s| s.steps_to_go == 0)
    });
    assert_eq!(positions(board), [1_001, -333, 0]);
    // Faster than $110 allows: refused before anything is sent.
    assert!(matches!(
        x.move_steps(60_000, 10),
        Err(AxisError::Unsupported(_))
    ));
    assert_eq!(positions(board), [1_001, -333, 0]);
}

/// A shallow zigzag of `count` lines of 0.1 mm along X (Y 0 or 0.02 mm)
/// at 50 mm/s, then a comment, a blank and a last line to a known point.
fn zigzag(count: usize) -> (String, [i64; 3]) {
    let mut text = String::from("G21 G90 ; a zigzag\nG1 F3000\n");
    for i in 1..=count {
        let y = if i % 2 == 0 { "0" } else { "0.02" };
        text.push_str(&format!("G1 X{:.1} Y{y}\n", i as f64 * 0.1));
    }
    text.push_str("(the end)\n\nG1 X12.344 Y-6.788 Z1.5\n");
    (text, [3_086, -1_697, 375])
}

#[test]
fn a_long_program_streams_by_character_counting_to_its_exact_end() {
    let rig = rig("stream");
    let (text, end) = zigzag(1_500);
    let program = lines(&text);
    let stream = rig.board.stream_gcode(&program).expect("it streams");
    assert_eq!(wait_over(&stream), StreamState::Done);
    let progress = stream.progress();
    assert_eq!(progress.lines, program.len());
    assert_eq!(
        (progress.sent, progress.answered),
        (program.len(), program.len())
    );
    // Two lines of the program are a comment and a blank: not sent.
    assert_eq!(progress.ok, program.len() - 2);
    assert!(progress.most_bytes_in_flight <= RX_BUFFER);
    assert!(
        progress.most_bytes_in_flight > RX_BUFFER / 2,
        "character counting keeps the buffer full: {}",
        progress.most_bytes_in_flight
    );
    assert_eq!(positions(&rig.board), end);
}

#[test]
fn a_feed_hold_mid_program_and_resume_finish_at_the_exact_end() {
    let rig = rig("hold");
    let (text, end) = zigzag(400);
    let stream = rig.board.stream_gcode(&lines(&text)).expect("it streams");
    wait_for("some lines answered", || stream.progress().answered > 40);
    stream.hold().expect("feed hold");
    let x = rig.board.axis(0).expect("X");
    wait_for("held at rest", || {
        rig.board.refresh().is_ok() && x.status().is_ok_and(|s| s.velocity_steps_per_s == 0)
    });
    let held = positions(&rig.board);
    std::thread::sleep(Duration::from_millis(150));
    assert_eq!(positions(&rig.board), held, "nothing moves while held");
    assert_eq!(stream.progress().state, StreamState::Streaming);
    stream.resume().expect("resume");
    assert_eq!(wait_over(&stream), StreamState::Done);
    assert_eq!(positions(&rig.board), end);
}

#[test]
fn a_cancel_stops_along_the_path_and_the_board_takes_moves_after_it() {
    let rig = rig("cancel");
    let (text, _) = zigzag(800);
    let stream = rig.board.stream_gcode(&lines(&text)).expect("it streams");
    wait_for("some lines answered", || stream.progress().answered > 30);
    stream.cancel().expect("cancel");
    assert_eq!(wait_over(&stream), StreamState::Cancelled);
    let stopped = positions(&rig.board);
    std::thread::sleep(Duration::from_millis(150));
    assert_eq!(
        positions(&rig.board),
        stopped,
        "nothing runs after a cancel"
    );
    assert!(stopped[0] < 800 * 25, "it stopped part way: {stopped:?}");
    // At rest and unlocked: a move in steps lands exactly.
    let y = rig.board.axis(1).expect("Y");
    y.move_steps(5_000, 100).expect("a move after a cancel");
    wait_for("Y at rest", || {
        rig.board.refresh().is_ok() && y.status().is_ok_and(|s| s.steps_to_go == 0)
    });
    assert_eq!(positions(&rig.board)[1], stopped[1] + 100);
}

#[test]
fn an_emergency_stop_mid_program_resets_to_alarm_and_unlock_recovers() {
    let rig = rig("estop");
    let (text, _) = zigzag(800);
    let stream = rig.board.stream_gcode(&lines(&text)).expect("it streams");
    wait_for("some lines answered", || stream.progress().answered > 30);
    rig.board.emergency_stop_all().expect("soft reset");
    assert_eq!(wait_over(&stream), StreamState::Reset);
    let x = rig.board.axis(0).expect("X");
    assert_eq!(
        x.move_steps(1_000, 10),
        Err(AxisError::Fault(FAULT_GRBL_ALARM))
    );
    assert!(matches!(
        rig.board.stream_gcode(&lines("G1X1")),
        Err(StreamError::Board(AxisError::Fault(FAULT_GRBL_ALARM)))
    ));
    let stopped = positions(&rig.board);
    rig.board.unlock().expect("$X");
    x.move_steps(1_000, 10).expect("a move after $X");
    wait_for("X at rest", || {
        rig.board.refresh().is_ok() && x.status().is_ok_and(|s| s.steps_to_go == 0)
    });
    assert_eq!(positions(&rig.board)[0], stopped[0] + 10);
    // A soft reset mid-move again: an axis's clear_limit_fault is `$X` too.
    x.move_steps(2_000, 200_000).expect("a long move");
    wait_for("X moving", || {
        rig.board.refresh().is_ok() && x.status().is_ok_and(|s| s.velocity_steps_per_s > 0)
    });
    rig.board.emergency_stop_all().expect("soft reset");
    assert_eq!(
        x.move_steps(1_000, 10),
        Err(AxisError::Fault(FAULT_GRBL_ALARM))
    );
    let stopped = positions(&rig.board);
    x.clear_limit_fault().expect("$X");
    x.move_steps(1_000, -10).expect("a move after $X");
    wait_for("X at rest", || {
        rig.board.refresh().is_ok() && x.status().is_ok_and(|s| s.steps_to_go == 0)
    });
    assert_eq!(positions(&rig.board)[0], stopped[0] - 10);
}

#[test]
fn a_program_the_board_cannot_take_is_refused_whole_before_a_byte() {
    let rig = rig("refused");
    let program = lines("G1 X5 F600\nG1 X6 ? Y1\nG1 X7");
    assert_eq!(
        rig.board.stream_gcode(&program).map(|_| ()),
        Err(StreamError::Refused(StreamRefusal::RealtimeByte {
            line: 2,
            byte: b'?'
        }))
    );
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(positions(&rig.board), [0, 0, 0]);
}

#[test]
fn an_error_line_stops_the_stream_and_a_malformed_first_line_moves_nothing() {
    let rig = rig("error");
    let stream = rig
        .board
        .stream_gcode(&lines("G1 X5 Q7 F600"))
        .expect("it streams");
    let state = wait_over(&stream);
    let StreamState::Error { line: 1, code } = state else {
        panic!("{state:?}");
    };
    assert!(code > 0);
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(positions(&rig.board), [0, 0, 0]);
    // The lines after an error were in flight before it came: they run.
    let stream = rig
        .board
        .stream_gcode(&lines("G1 X1 F600\nG1 X5 Q7\nG1 X6\nG1 X7"))
        .expect("it streams");
    let StreamState::Error { line: 2, .. } = wait_over(&stream) else {
        panic!("{:?}", stream.progress());
    };
    assert_eq!(stream.progress().sent_after_error, 2);
    wait_for("at rest at X7", || positions(&rig.board) == [1_750, 0, 0]);
    // A long program whose third line is malformed: nothing after the
    // lines already in flight is sent.
    let (mut text, _) = zigzag(300);
    text.insert_str(0, "G1 X0 Y0 F6000\nG1 X0.1\nG1 X0.2 W3\n");
    let stream = rig.board.stream_gcode(&lines(&text)).expect("it streams");
    let StreamState::Error { line: 3, .. } = wait_over(&stream) else {
        panic!("{:?}", stream.progress());
    };
    let progress = stream.progress();
    assert!(progress.sent < progress.lines, "{progress:?}");
    assert_eq!(progress.sent, 3 + progress.sent_after_error);
}

#[test]
fn an_emergency_stop_during_a_cancel_acts_at_once() {
    // Gentle: a hold from 50 mm/s takes about a quarter of a second.
    let rig = rig_with("cancel-estop", "$120=200\n$121=200\n$122=200\n$110=6000\n");
    let stream = rig
        .board
        .stream_gcode(&lines("G1 X-100 F3000\nG1 X0\n"))
        .expect("it streams");
    let x = rig.board.axis(0).expect("X");
    wait_for("X at speed", || {
        rig.board.refresh().is_ok() && x.status().is_ok_and(|s| s.velocity_steps_per_s > 10_000)
    });
    stream.cancel().expect("cancel");
    // The board decelerates along its path; the stop does not wait for it.
    rig.board.emergency_stop_all().expect("soft reset");
    assert_eq!(wait_over(&stream), StreamState::Reset);
    // It was still moving: grbl's reset while moving leaves an alarm.
    assert_eq!(
        x.move_steps(1_000, 10),
        Err(AxisError::Fault(FAULT_GRBL_ALARM))
    );
    let stopped = positions(&rig.board);
    std::thread::sleep(Duration::from_millis(150));
    assert_eq!(positions(&rig.board), stopped, "nothing moves after it");
}

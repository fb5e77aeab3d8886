//! The protocol end to end: bytes into a [`Session`] over a fake board,
//! reply bytes and the board's recorded calls out.

extern crate std;
use std::format;
use std::string::String;
use std::vec::Vec;

use super::fake_board::{send, Call, FakeBoard, IDLE};
use super::*;
use cogstep_motion::axis::{AxisError, AxisStatus, Direction, Mode};
use cogstep_motion::profile::PlanError;

fn board_and_session() -> (FakeBoard, Session) {
    (FakeBoard::new(2), Session::new())
}

/// The reply to `line`, and the calls it made.
fn exchange(line: &str) -> (String, Vec<Call>) {
    let (board, mut session) = board_and_session();
    let reply = send(&mut session, &board, line.as_bytes());
    (reply, board.calls())
}

#[test]
fn identify() {
    let (reply, calls) = exchange("I\n");
    assert_eq!(
        reply,
        format!(
            "[cogstep {} proto:1 axes:2 clkfreq:200000000]\nok\n",
            env!("CARGO_PKG_VERSION")
        )
    );
    assert!(calls.is_empty());
}

#[test]
fn move_is_passed_to_the_axis() {
    let (reply, calls) = exchange("M 1 20000 -1500\n");
    assert_eq!(reply, "ok\n");
    assert_eq!(
        calls,
        [Call::Move {
            axis: 1,
            speed: 20000,
            steps: -1500
        }]
    );
}

#[test]
fn a_second_move_goes_to_the_axis_which_merges_it() {
    let (reply, calls) = exchange("M 0 1000 500\nM 0 1000 500\n");
    assert_eq!(reply, "ok\nok\n");
    assert_eq!(calls.len(), 2);
}

#[test]
fn jog_heartbeats() {
    let (reply, calls) = exchange("J 0 800 +\nJ 1 800 -\n");
    assert_eq!(reply, "ok\nok\n");
    assert_eq!(
        calls,
        [
            Call::Jog {
                axis: 0,
                speed: 800,
                direction: Direction::Forward
            },
            Call::Jog {
                axis: 1,
                speed: 800,
                direction: Direction::Reverse
            }
        ]
    );
}

#[test]
fn stop_and_run_pins() {
    let (reply, calls) = exchange("S 1\nR 1\nS *\nR *\n");
    assert_eq!(reply, "ok\nok\nok\nok\n");
    let pin = |axis, high| Call::StopPin { axis, high };
    assert_eq!(
        calls,
        [
            pin(1, false),
            pin(1, true),
            pin(0, false),
            pin(1, false),
            pin(0, true),
            pin(1, true)
        ]
    );
}

#[test]
fn emergency_stop_command() {
    let (reply, calls) = exchange("E\n");
    assert_eq!(reply, "ok\n");
    assert_eq!(
        calls,
        [
            Call::EmergencyStop { axis: 0 },
            Call::EmergencyStop { axis: 1 }
        ]
    );
}

#[test]
fn set_position_only_when_idle() {
    let (board, mut session) = board_and_session();
    assert_eq!(send(&mut session, &board, b"P 0 -250\n"), "ok\n");
    assert_eq!(
        board.calls(),
        [Call::SetPosition {
            axis: 0,
            position: -250
        }]
    );
    assert_eq!(send(&mut session, &board, b"M 0 100 100\n"), "ok\n");
    let before = board.calls();
    assert_eq!(send(&mut session, &board, b"P 0 7\n"), "error:7 not idle\n");
    assert_eq!(board.calls(), before);
}

#[test]
fn no_such_axis() {
    for line in [
        "M 2 100 100\n",
        "J 9 1 +\n",
        "S 2\n",
        "R 77\n",
        "P 3 0\n",
        "S 99999999999999999999999\n",
    ] {
        let (reply, calls) = exchange(line);
        assert_eq!(reply, "error:4 no such axis\n", "{line:?}");
        assert!(calls.is_empty());
    }
}

#[test]
fn status_realtime_byte_gives_one_exact_line_per_axis() {
    let (board, mut session) = board_and_session();
    board.axes[0].set_status(AxisStatus {
        position: 1200,
        stm: 0,
        steps_to_go: 800,
        mode: Mode::MOVING | Mode::ACCEL | Mode::SLEW,
        velocity_steps_per_s: 20000,
        stop_pin_high: true,
    });
    board.axes[1].set_status(AxisStatus {
        position: -7,
        stm: 0,
        steps_to_go: 0,
        mode: Mode::STOP_LATCHED,
        velocity_steps_per_s: 0,
        stop_pin_high: false,
    });
    assert_eq!(
        send(&mut session, &board, b"?"),
        "<0|Run|pos:1200|stm:0|togo:800|mode:001011|vel:20000|stop:high>\n\
         <1|Hold|pos:-7|stm:0|togo:0|mode:100000|vel:0|stop:low>\n"
    );
    assert!(board.calls().is_empty());
}

#[test]
fn every_state_is_spelled_as_the_protocol_says() {
    let (board, mut session) = board_and_session();
    let cases = [
        (Mode(0), true, 0, "Idle"),
        (Mode::MOVING, true, 5, "Run"),
        // The last step's period: nothing left to make, idle for every command.
        (Mode::MOVING, true, 0, "Idle"),
        (Mode::MOVING | Mode::JOG, true, 5, "Jog"),
        (Mode::HOLD, false, 5, "Hold"),
        (Mode::ESTOP, true, 0, "Alarm"),
    ];
    for (mode, stop_pin_high, steps_to_go, state) in cases {
        board.axes[0].set_status(AxisStatus {
            mode,
            stop_pin_high,
            steps_to_go,
            ..IDLE
        });
        let reply = send(&mut session, &board, b"?");
        assert!(reply.starts_with(&format!("<0|{state}|")), "{reply}");
    }
}

#[test]
fn bang_stops_every_axis_without_a_reply() {
    let (reply, calls) = exchange("!");
    assert_eq!(reply, "");
    assert_eq!(
        calls,
        [
            Call::StopPin {
                axis: 0,
                high: false
            },
            Call::StopPin {
                axis: 1,
                high: false
            }
        ]
    );
}

#[test]
fn ctrl_x_stops_everything_and_clears_the_line() {
    let (board, mut session) = board_and_session();
    let reply = send(&mut session, &board, b"M 0 100 2\x1800\n");
    // The half line was dropped: what came after 0x18 is a line on its own.
    assert_eq!(reply, "error:1 unknown command\n");
    assert_eq!(
        board.calls(),
        [
            Call::EmergencyStop { axis: 0 },
            Call::EmergencyStop { axis: 1 }
        ]
    );
    assert_eq!(
        send(&mut session, &board, b"I\n").lines().last(),
        Some("ok")
    );
}

#[test]
fn realtime_bytes_mid_line_do_not_disturb_it() {
    let (board, mut session) = board_and_session();
    let reply = send(&mut session, &board, b"M 0 1?00 2!00\n");
    let lines: Vec<&str> = reply.lines().collect();
    assert_eq!(lines.len(), 3, "{reply}");
    assert!(lines[0].starts_with("<0|Idle|"));
    assert!(lines[1].starts_with("<1|Idle|"));
    assert_eq!(lines[2], "ok");
    let calls = board.calls();
    assert_eq!(
        calls.last(),
        Some(&Call::Move {
            axis: 0,
            speed: 100,
            steps: 200
        })
    );
    assert_eq!(calls.len(), 3, "two stop pins, then the move");
}

#[test]
fn cr_lf_and_crlf_each_end_one_line() {
    for ending in ["\n", "\r", "\r\n"] {
        let (reply, _) = exchange(&format!("I{ending}E{ending}"));
        assert_eq!(reply.matches("ok\n").count(), 2, "{ending:?}");
        assert_eq!(reply.lines().count(), 3, "{ending:?}");
    }
}

#[test]
fn blank_lines_get_no_reply() {
    let (reply, calls) = exchange("\n\r\n\r   \n  \r\n");
    assert_eq!(reply, "");
    assert!(calls.is_empty());
}

#[test]
fn checksums_good_and_bad() {
    let line = "M 0 20000 20000";
    let good = format!("{line}*{:02X}\n", checksum(line.as_bytes()));
    let (reply, calls) = exchange(&good);
    assert_eq!(reply, "ok\n");
    assert_eq!(calls.len(), 1);

    let lower = format!("{line}*{:02x}\n", checksum(line.as_bytes()));
    assert_eq!(exchange(&lower).0, "ok\n");

    let bad = format!("{line}*{:02X}\n", checksum(line.as_bytes()) ^ 0x10);
    let (reply, calls) = exchange(&bad);
    assert_eq!(reply, "error:8 checksum\n");
    assert!(calls.is_empty());

    // One flipped bit in the body is caught.
    let flipped = good.replacen("20000", "20001", 1);
    assert_eq!(exchange(&flipped).0, "error:8 checksum\n");
}

#[test]
fn overlong_lines_get_one_error_when_they_end() {
    let (board, mut session) = board_and_session();
    let exactly = format!("M 0 100 {:0>88}\n", 5);
    assert_eq!(exactly.len(), LINE_MAX + 1);
    assert_eq!(send(&mut session, &board, exactly.as_bytes()), "ok\n");

    let long = format!("M 0 100 {:0>89}", 5);
    assert_eq!(
        send(&mut session, &board, long.as_bytes()),
        "",
        "no reply before the end"
    );
    assert_eq!(
        send(&mut session, &board, b"\r\n"),
        "error:5 line too long\n"
    );

    let very_long = [b'M'; 1000];
    assert_eq!(send(&mut session, &board, &very_long), "");
    assert_eq!(send(&mut session, &board, b"\n"), "error:5 line too long\n");
    assert_eq!(board.call_count(), 1);
    assert_eq!(
        send(&mut session, &board, b"I\n").lines().last(),
        Some("ok")
    );
}

#[test]
fn garbage_bytes_reject_the_line_and_the_next_line_works() {
    let (board, mut session) = board_and_session();
    for garbage in [
        &b"M 0 100 200\x00\n"[..],
        b"\xff\xfe\xfd\n",
        b"M 0 100\t200\n",
        b"I\x7f\n",
        b"\x1b[A\n",
        b"S \xc3\xa9\n",
    ] {
        assert_eq!(
            send(&mut session, &board, garbage),
            "error:2 bad argument\n",
            "{garbage:?}"
        );
    }
    assert!(board.calls().is_empty());
    assert_eq!(send(&mut session, &board, b"E\n"), "ok\n");
}

#[test]
fn a_lost_line_end_is_one_bad_line() {
    let (board, mut session) = board_and_session();
    assert_eq!(
        send(&mut session, &board, b"M 0 100 200M 0 100 200\n"),
        "error:2 bad argument\n"
    );
    assert_eq!(
        send(&mut session, &board, b"S 0E\n"),
        "error:2 bad argument\n"
    );
    assert!(board.calls().is_empty());
    assert_eq!(send(&mut session, &board, b"S 0\n"), "ok\n");
}

#[test]
fn parse_errors_have_their_codes() {
    let cases = [
        ("X\n", "error:1 unknown command"),
        ("move 0 1 1\n", "error:1 unknown command"),
        ("M 0 100\n", "error:2 bad argument"),
        ("M 0 fast 100\n", "error:2 bad argument"),
        ("M 0 100 0\n", "error:2 bad argument"),
        ("J 0 100 up\n", "error:2 bad argument"),
        ("E 1\n", "error:2 bad argument"),
        ("M 0 0 100\n", "error:6 speed out of range"),
        ("M 0 -10 100\n", "error:6 speed out of range"),
        ("J 0 99999999999 +\n", "error:6 speed out of range"),
    ];
    for (line, reply) in cases {
        let (got, calls) = exchange(line);
        assert_eq!(got, format!("{reply}\n"), "{line:?}");
        assert!(calls.is_empty());
    }
}

#[test]
fn axis_refusals_have_their_codes_and_change_nothing() {
    let cases: [(AxisError, &str); 7] = [
        (
            PlanError::ZeroSpeed.into(),
            "error:6 speed out of range: below 1 step/s",
        ),
        (
            PlanError::SpeedTooHigh {
                speed: 1,
                clkfreq: 1,
            }
            .into(),
            "error:6 speed out of range: 1 steps/s is too fast for 1 Hz",
        ),
        (
            PlanError::ZeroSteps.into(),
            "error:2 bad argument: zero steps",
        ),
        (AxisError::Busy, "error:3 busy"),
        (
            AxisError::PulseTooLong { speed: 1 },
            "error:6 speed out of range: no room for the step pulse at 1 steps/s",
        ),
        (AxisError::Unavailable, "error:4 axis not available"),
        (AxisError::Fault("lost"), "error:2 fault: lost"),
    ];
    for (error, reply) in cases {
        let (board, mut session) = board_and_session();
        board.axes[0].refusal.set(Some(error));
        for line in ["M 0 100 100\n", "J 0 100 +\n", "S 0\n", "R 0\n", "P 0 5\n"] {
            let got = send(&mut session, &board, line.as_bytes());
            assert_eq!(got, format!("{reply}\n"), "{line:?} {error:?}");
        }
        assert!(board.calls().is_empty());
    }
}

#[test]
fn all_axes_commands_try_every_axis() {
    let (board, mut session) = board_and_session();
    board.axes[0].refusal.set(Some(AxisError::Busy));
    assert_eq!(send(&mut session, &board, b"S *\n"), "error:3 busy\n");
    assert_eq!(
        board.calls(),
        [Call::StopPin {
            axis: 1,
            high: false
        }]
    );
    assert_eq!(send(&mut session, &board, b"E\n"), "error:3 busy\n");
    assert_eq!(board.calls().last(), Some(&Call::EmergencyStop { axis: 1 }));
}

#[test]
fn realtime_failures_are_information_lines() {
    let (board, mut session) = board_and_session();
    board.axes[1]
        .status_failure
        .set(Some(AxisError::Unavailable));
    let reply = send(&mut session, &board, b"?");
    let lines: Vec<&str> = reply.lines().collect();
    assert!(lines[0].starts_with("<0|Idle|"));
    assert_eq!(
        lines[1],
        "[status failed: axis 1: the axis is not available (stopped or disconnected)]"
    );

    board.axes[0]
        .refusal
        .set(Some(AxisError::Fault("driver\r\nhot")));
    assert_eq!(
        send(&mut session, &board, b"!"),
        "[stop failed: axis 0: fault: driver??hot]\n"
    );
    assert_eq!(
        send(&mut session, &board, b"\x18"),
        "[emergency stop failed: fault: driver??hot]\n"
    );
}

#[test]
fn every_reply_parses_back() {
    let (board, mut session) = board_and_session();
    let reply = send(&mut session, &board, b"I\nX\n?M 0 1 1\n");
    for line in reply.lines() {
        assert!(Reply::parse(line).is_some(), "{line}");
    }
    let finals = reply
        .lines()
        .filter(|line| Reply::parse(line).is_some_and(|r| r.is_final()))
        .count();
    assert_eq!(finals, 3);
}

#[test]
fn the_longest_reply_lines_fit() {
    let (mut board, mut session) = board_and_session();
    board.version = Some("0.1.0-a-very-long-pre-release-tag+and.build.metadata.that.goes.on");
    board.axes[0].set_status(AxisStatus {
        position: i64::MIN,
        stm: i32::MIN,
        steps_to_go: u64::MAX,
        mode: Mode(u32::MAX),
        velocity_steps_per_s: u32::MAX,
        stop_pin_high: false,
    });
    let mut replies = send(&mut session, &board, b"?");
    replies += &send(&mut session, &board, b"I\n");

    const LONG: &str = "a description of a fault that goes on and on, far longer than a \
                        reply line, with a line break\r\n and more";
    board.axes[1]
        .status_failure
        .set(Some(AxisError::Fault(LONG)));
    board.axes[1]
        .refusal
        .set(Some(AxisError::Unsupported(LONG)));
    replies += &send(&mut session, &board, b"?!\x18S 1\nJ 1 1 +\n");
    assert_eq!(replies.lines().count(), 2 + 2 + 6, "{replies}");
    for line in replies.split_inclusive('\n') {
        assert!(line.len() <= REPLY_LINE_MAX, "{line}");
        assert!(Reply::parse(line).is_some(), "{line}");
    }
    assert!(replies.contains("[cogstep 0.1.0-a-very-long-pre-release-ta proto:1 axes:2 "));
}

#[test]
fn the_doc_example_session() {
    // The transcript in docs/protocol.md, replayed.
    let (board, mut session) = board_and_session();
    let transcript: [(&[u8], &str); 6] = [
        (b"M 0 20000 20000\r", "ok\n"),
        (b"M 5 100 100\r", "error:4 no such axis\n"),
        (b"M 0 0 100\r", "error:6 speed out of range\n"),
        (b"P 0 0\r", "error:7 not idle\n"),
        (b"E\r", "ok\n"),
        (b"frobnicate\r", "error:1 unknown command\n"),
    ];
    for (input, output) in transcript {
        assert_eq!(send(&mut session, &board, input), output);
    }
}

/// A writer whose every write fails (a reply buffer that is full).
struct Full;

impl core::fmt::Write for Full {
    fn write_str(&mut self, _text: &str) -> core::fmt::Result {
        Err(core::fmt::Error)
    }
}

#[test]
fn a_stop_reaches_every_axis_even_when_its_refusal_cannot_be_written() {
    let board = FakeBoard::new(3);
    board.axes[0].refusal.set(Some(AxisError::Busy));
    let result = realtime(&board, Realtime::Stop, &mut Full);
    assert!(result.is_err(), "the failed write is reported");
    assert_eq!(
        board.calls(),
        [
            Call::StopPin {
                axis: 1,
                high: false
            },
            Call::StopPin {
                axis: 2,
                high: false
            }
        ]
    );
}

//! The host side's pieces without a port: identity and status lines read
//! back, refusals mapped, bytes framed. End-to-end tests over real
//! pseudo-terminals are in `driver/tests/serial_e2e.rs`.

use super::axis::check_move;
use super::cogstep::{axis_error, parse_identity, status_from_line};
use super::state::{is_busy, BoardState};
use super::wire::{Framer, Incoming};
use super::*;
use cogstep_motion::axis::{AxisError, AxisState, Mode};
use cogstep_motion::profile::PlanError;
use cogstep_protocol::p2demo::{DemoPrompt, DemoScreen, ScreenEvent};
use cogstep_protocol::StatusLine;
use std::time::Duration;

#[test]
fn demo_starts_read_and_print_their_names() {
    for start in [DemoStart::Passive, DemoStart::PoweredUp, DemoStart::Reset] {
        assert_eq!(start.to_string().parse(), Ok(start));
    }
    assert_eq!(" Powered-Up".parse(), Ok(DemoStart::PoweredUp));
    assert!("on".parse::<DemoStart>().is_err());
    assert_eq!(SerialConfig::new("x").demo_start, DemoStart::Passive);
}

#[test]
fn a_truncated_position_field_is_widened_from_the_known_position() {
    use super::demo::unwrap_position;
    assert_eq!(unwrap_position(1000, None), 1000);
    assert_eq!(unwrap_position(-12_345, Some(5_000_000)), -12_345);
    // 1,000,123 shows "000123".
    assert_eq!(unwrap_position(123, Some(999_900)), 1_000_123);
    assert_eq!(unwrap_position(123, Some(200)), 123);
    // -123,456 shows "123456".
    assert_eq!(unwrap_position(123_456, Some(-123_000)), -123_456);
    assert_eq!(unwrap_position(123_456, Some(123_000)), 123_456);
    // -1,234,567 shows "234567".
    assert_eq!(unwrap_position(234_567, Some(-1_234_000)), -1_234_567);
}

#[test]
fn dialects_read_and_print_their_names() {
    assert_eq!("cogstep".parse(), Ok(Dialect::Cogstep));
    assert_eq!("P2Demo".parse(), Ok(Dialect::P2Demo));
    assert_eq!("GRBL".parse(), Ok(Dialect::Grbl));
    assert_eq!("marlin".parse::<Dialect>(), Err(UnknownDialect));
    assert_eq!(" P2DEMO ".parse(), Ok(Dialect::P2Demo));
    assert_eq!(Dialect::P2Demo.to_string(), "p2demo");
    assert_eq!(Dialect::Cogstep.to_string(), "cogstep");
    assert_eq!(Dialect::Grbl.to_string(), "grbl");
}

#[test]
fn config_defaults() {
    let config = SerialConfig::new("/dev/ttyACM0");
    assert_eq!(config.port, "/dev/ttyACM0");
    assert_eq!(config.baud, 115_200);
    assert_eq!(config.dialect, Dialect::Cogstep);
    assert_eq!(config.poll_interval, Duration::from_millis(50));
    assert_eq!(config.timeout, Duration::from_millis(500));
}

#[test]
fn identity_lines_are_read() {
    let identity = parse_identity("cogstep 0.1.0 proto:1 axes:2 clkfreq:200000000").unwrap();
    assert_eq!(
        identity.line,
        "[cogstep 0.1.0 proto:1 axes:2 clkfreq:200000000]"
    );
    assert_eq!(
        (identity.proto, identity.axes, identity.clkfreq),
        (1, 2, 200_000_000)
    );
    // Unknown fields are skipped; missing ones make it no identity.
    assert!(parse_identity("cogstep 9 proto:2 axes:1 clkfreq:80000000 leds:4").is_some());
    for info in [
        "cogstep 0.1.0 proto:1 axes:2",
        "grbl 1.1 proto:1 axes:2 clkfreq:1",
        "cogstep",
        "cogstep 0.1.0 proto:x axes:2 clkfreq:1",
        "stop failed: axis 1: busy",
    ] {
        assert_eq!(parse_identity(info), None, "{info}");
    }
}

#[test]
fn status_lines_keep_their_state() {
    for line in [
        "<0|Idle|pos:0|stm:0|togo:0|mode:000000|vel:0|stop:high>",
        "<0|Run|pos:1200|stm:0|togo:800|mode:001011|vel:20000|stop:high>",
        "<1|Jog|pos:-40|stm:0|togo:9000|mode:011001|vel:800|stop:high>",
        "<0|Hold|pos:9120|stm:0|togo:0|mode:100000|vel:0|stop:low>",
        "<0|Hold|pos:5|stm:0|togo:0|mode:000000|vel:0|stop:low>",
        "<2|Alarm|pos:-5|stm:0|togo:0|mode:110000|vel:0|stop:low>",
        "<0|Idle|pos:7|stm:0|togo:0|mode:000000|vel:0|stop:low>",
    ] {
        let parsed = StatusLine::parse(line).unwrap();
        let status = status_from_line(&parsed);
        assert_eq!(status.state(), parsed.state, "{line}");
        // Formatting the status again gives the same line.
        assert_eq!(
            StatusLine::new(parsed.axis, &status).to_string(),
            line,
            "{line}"
        );
    }
    let held = status_from_line(
        &StatusLine::parse("<0|Hold|pos:5|stm:0|togo:0|mode:000000|vel:0|stop:low>").unwrap(),
    );
    assert!(held.mode.has(Mode::HOLD));
    assert!(is_busy(&held));
    let alarm = status_from_line(
        &StatusLine::parse("<2|Alarm|pos:-5|stm:0|togo:0|mode:110000|vel:0|stop:low>").unwrap(),
    );
    assert_eq!(alarm.state(), AxisState::Alarm);
    assert!(!is_busy(&alarm));
}

/// Every refusal, written as the board writes it (the protocol crate's
/// writer) and read back here, is the same `AxisError`, numbers and all.
#[test]
fn every_refusal_comes_back_as_the_error_the_board_gave() {
    use cogstep_motion::refusal::{Refusal, RefusalValues};
    use cogstep_protocol::{ProtocolError, Reply};
    for refusal in Refusal::ALL {
        for values in [
            RefusalValues::default(),
            RefusalValues {
                speed: 50_000_000,
                clkfreq: 200_000_000,
                offset_deg: 90,
            },
            RefusalValues {
                speed: u32::MAX,
                clkfreq: u32::MAX,
                offset_deg: u32::MAX,
            },
        ] {
            let error = AxisError::from_refusal(refusal, values);
            let mut line = String::new();
            ProtocolError::Axis(error).write_reply(&mut line).unwrap();
            let Some(Reply::Error { code, text }) = Reply::parse(&line) else {
                panic!("{line} is no error line");
            };
            assert_eq!(axis_error(code, text), error, "{line}");
        }
    }
}

#[test]
fn other_errors_map_to_transport_errors_and_clear_faults() {
    let cases: [(u8, &str, AxisError); 15] = [
        (
            1,
            "not supported: jog",
            AxisError::Unsupported("not supported by the board"),
        ),
        (
            1,
            "unknown command",
            AxisError::Unsupported("the board does not know this command"),
        ),
        (
            2,
            "fault: driver hot",
            AxisError::Fault("the board reported an axis fault"),
        ),
        (
            2,
            "bad argument",
            AxisError::Fault("the board refused an argument"),
        ),
        // A setting no refusal names.
        (
            2,
            "bad argument: a made-up setting",
            AxisError::Fault("the board refused an argument"),
        ),
        (4, "no such axis", AxisError::Unavailable),
        (4, "axis not available", AxisError::Unavailable),
        (
            5,
            "line too long",
            AxisError::Fault("the board found the line too long"),
        ),
        // A parse error, or an older board's text for a speed.
        (
            6,
            "speed out of range",
            AxisError::Fault("the board refused the speed"),
        ),
        (8, "checksum", AxisError::Fault("line noise")),
        // Texts that are no refusal's are not guessed at.
        (
            3,
            "busy: with something new",
            AxisError::Fault("the board gave a refusal this host does not know"),
        ),
        (
            9,
            "limit: max limit ahead",
            AxisError::Fault("the board gave a refusal this host does not know"),
        ),
        (
            10,
            "homing: switch not found, really",
            AxisError::Fault("the board gave a refusal this host does not know"),
        ),
        (
            7,
            "busy",
            AxisError::Fault("the board gave a refusal this host does not know"),
        ),
        (
            11,
            "new",
            AxisError::Fault("the board sent an unknown error code"),
        ),
    ];
    for (code, text, expected) in cases {
        assert_eq!(axis_error(code, text), expected, "error:{code} {text}");
    }
}

#[test]
fn moves_are_checked_before_anything_is_sent() {
    assert_eq!(
        check_move(0, 10),
        Err(AxisError::Plan(PlanError::ZeroSpeed))
    );
    assert_eq!(
        check_move(10, 0),
        Err(AxisError::Plan(PlanError::ZeroSteps))
    );
    assert_eq!(check_move(10, -3), Ok(()));
    // The hub's order: the steps' range first.
    assert_eq!(check_move(0, i32::MIN), Err(AxisError::StepsOutOfRange));
}

fn frame(dialect: Dialect, bytes: &[u8]) -> Vec<Incoming> {
    let mut framer = Framer::new(dialect);
    let mut events = Vec::new();
    for &byte in bytes {
        framer.push(byte, &mut |event| events.push(event));
    }
    events
}

#[test]
fn reply_lines_are_framed() {
    let events = frame(
        Dialect::Cogstep,
        b"ok\r\nerror:4 no such axis\r\n\r\n<0|Idle|pos:0|stm:0|togo:0|mode:000000|vel:0|stop:high>\r\nhalf",
    );
    assert_eq!(
        events,
        [
            Incoming::Line("ok".to_string()),
            Incoming::Line("error:4 no such axis".to_string()),
            Incoming::Line("<0|Idle|pos:0|stm:0|togo:0|mode:000000|vel:0|stop:high>".to_string()),
        ]
    );
    // An overlong line is dropped whole; the next one is read.
    let mut noise = vec![b'x'; 2_000];
    noise.extend_from_slice(b"\nok\n\xff\xfe\n");
    let events = frame(Dialect::Cogstep, &noise);
    assert_eq!(events[0], Incoming::Line("ok".to_string()));
    assert_eq!(events.len(), 2);
}

#[test]
fn screens_are_framed() {
    let screen = DemoScreen {
        position: 1200,
        mode_bits: 0b001011,
        offset_deg: 40,
        accel_steps: 2002,
        slew_steps: 15996,
        max_velocity_steps_per_s: 20000,
        elapsed_ms: 12,
    };
    let mut bytes = vec![cogstep_protocol::p2demo::CLEAR];
    let mut text = String::new();
    screen.write_display(&mut text).unwrap();
    bytes.extend_from_slice(text.as_bytes());
    bytes.extend_from_slice(b"\r\rEnter steps: ");
    let events = frame(Dialect::P2Demo, &bytes);
    assert_eq!(events.first(), Some(&Incoming::Cleared));
    assert!(events.contains(&Incoming::Screen(ScreenEvent::Display(screen))));
    assert_eq!(
        events.last(),
        Some(&Incoming::Screen(ScreenEvent::Prompt(DemoPrompt::Steps)))
    );
}

#[test]
fn a_lost_link_latches_moving_axes_only() {
    let mut state = BoardState::default();
    state.link_up("[cogstep]".to_string(), 1, 3);
    state.axes[1].status.stm = 10;
    state.axes[1].status.mode = Mode::MOVING;
    state.axes[2].status.mode = Mode::HOLD;
    state.link_down("disconnected: read: Broken pipe".to_string());
    assert_eq!(state.axes[0].latched, None);
    assert_eq!(state.axes[1].latched, Some(FAULT_LOST_MID_MOVE));
    assert_eq!(state.axes[2].latched, Some(FAULT_LOST_MID_MOVE));
    // A reset later does not overwrite the first fault.
    state.latch_moving(FAULT_RESET_MID_MOVE);
    assert_eq!(state.axes[1].latched, Some(FAULT_LOST_MID_MOVE));
}

#[test]
fn opening_a_missing_port_fails_cleanly() {
    let error = SerialBoard::open(SerialConfig::new("/nonexistent/cogstep-port")).unwrap_err();
    assert!(matches!(error, SerialError::Open { .. }), "{error}");
    assert!(error.to_string().contains("/nonexistent/cogstep-port"));
}

#[test]
fn handles_go_to_other_threads() {
    fn send_and_sync<T: Send + Sync + Clone>() {}
    send_and_sync::<SerialBoard>();
    send_and_sync::<SerialAxis>();
}

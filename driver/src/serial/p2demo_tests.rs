//! Tests of the demo dialect: the formatter and the parser against each
//! other and against hand-written bytes, and the prompt/answer flow.

extern crate std;
use std::string::String;
use std::vec::Vec;

use super::*;
use crate::profile::PlanError;
use proptest::prelude::*;

const EXAMPLE: DemoScreen = DemoScreen {
    position: 1200,
    mode_bits: 0b001011,
    offset_deg: 40,
    accel_steps: 2002,
    slew_steps: 15996,
    max_velocity_steps_per_s: 20000,
    elapsed_ms: 1234,
};

/// The example display, byte for byte, as the reference demo prints it.
const EXAMPLE_BYTES: &[u8] = b"\x01Stepper Demo\r\
\rCurrent Position:   1200\
\r            Mode: 001011\
\r          Offset:     40\
\r     Accel steps:   2002\
\r  Steps at speed:  15996\
\r    Max Velocity:  20000\
\r\tElapsed time (msec):   1234";

fn display(screen: &DemoScreen) -> String {
    let mut out = String::new();
    screen.write_display(&mut out).unwrap();
    out
}

fn events(parser: &mut ScreenParser, bytes: &[u8]) -> Vec<ScreenEvent> {
    bytes.iter().filter_map(|&byte| parser.push(byte)).collect()
}

#[test]
fn the_formatter_writes_the_reference_bytes() {
    assert_eq!(display(&EXAMPLE).as_bytes(), EXAMPLE_BYTES);
}

#[test]
fn numbers_are_right_aligned_in_six_and_wider_ones_kept_whole() {
    let screen = DemoScreen {
        position: -1_234_567,
        mode_bits: 0b110000,
        offset_deg: 0,
        accel_steps: 5,
        slew_steps: 0,
        max_velocity_steps_per_s: 1_000_000,
        elapsed_ms: 0,
    };
    let text = display(&screen);
    assert!(text.contains("\rCurrent Position: -1234567\r"));
    assert!(text.contains("\r            Mode: 110000\r"));
    assert!(text.contains("\r          Offset:      0\r"));
    assert!(text.contains("\r     Accel steps:      5\r"));
    assert!(text.contains("\r    Max Velocity: 1000000\r"));
    assert!(text.ends_with("\r\tElapsed time (msec):      0"));
    assert!(display(&DemoScreen {
        position: -42,
        ..screen
    })
    .contains("Position:    -42\r"));
}

#[test]
fn the_parser_reads_the_reference_bytes() {
    let mut parser = ScreenParser::new();
    let mut bytes = EXAMPLE_BYTES.to_vec();
    bytes.extend_from_slice(b"\r\rEnter steps: ");
    assert_eq!(
        events(&mut parser, &bytes),
        [
            ScreenEvent::Field(DemoField::Position(1200)),
            ScreenEvent::Field(DemoField::Mode(0b001011)),
            ScreenEvent::Field(DemoField::Offset(40)),
            ScreenEvent::Field(DemoField::AccelSteps(2002)),
            ScreenEvent::Field(DemoField::SlewSteps(15996)),
            ScreenEvent::Field(DemoField::MaxVelocity(20000)),
            ScreenEvent::Display(EXAMPLE),
            ScreenEvent::Prompt(DemoPrompt::Steps),
        ]
    );
    assert_eq!(parser.position(), Some(1200));
    assert_eq!(parser.mode_bits(), Some(0b001011));
}

#[test]
fn the_next_display_or_a_clear_ends_the_last_line() {
    let mut parser = ScreenParser::new();
    let mut bytes = EXAMPLE_BYTES.to_vec();
    bytes.extend_from_slice(EXAMPLE_BYTES);
    bytes.push(CLEAR);
    let displays = events(&mut parser, &bytes)
        .into_iter()
        .filter(|event| matches!(event, ScreenEvent::Display(_)))
        .count();
    assert_eq!(displays, 2);
}

#[test]
fn a_partial_screen_yields_its_fields_but_no_display() {
    let mut parser = ScreenParser::new();
    // Joined mid-display: the title and the position were lost.
    let mut tail = EXAMPLE_BYTES[40..].to_vec();
    // The elapsed line is only ended by what follows it.
    tail.push(CR);
    let got = events(&mut parser, &tail);
    assert!(got.contains(&ScreenEvent::Field(DemoField::Mode(0b001011))));
    assert!(got.contains(&ScreenEvent::Field(DemoField::ElapsedMs(1234))));
    assert!(!got.iter().any(|e| matches!(e, ScreenEvent::Display(_))));
    assert_eq!(parser.position(), None);
    assert_eq!(parser.mode_bits(), Some(0b001011));

    // A display cut short by a clear is not reported either.
    let mut parser = ScreenParser::new();
    let mut bytes = EXAMPLE_BYTES[..60].to_vec();
    bytes.push(CLEAR);
    bytes.extend_from_slice(&EXAMPLE_BYTES[100..]);
    bytes.push(CR);
    let got = events(&mut parser, &bytes);
    assert_eq!(
        got.first(),
        Some(&ScreenEvent::Field(DemoField::Position(1200)))
    );
    assert!(!got.iter().any(|e| matches!(e, ScreenEvent::Display(_))));
}

#[test]
fn garbled_lines_are_skipped() {
    let mut parser = ScreenParser::new();
    let bytes: &[u8] = b"\rCurrent Posit\x00ion:   12\
        \rCurrent Position:  12a\
        \rCurrent Position:\
        \r            Mode: 0012\
        \r            Mode: 0101011\
        \r          Offset:    -40\
        \r     Accel steps: 99999999999\
        \r      \xff\xfe\x80\
        \rCurrent Position: 99999999999999999999\
        \r";
    assert_eq!(events(&mut parser, bytes), []);
    let long = [b'7'; 200];
    assert_eq!(events(&mut parser, &long), []);
    assert_eq!(
        events(&mut parser, b"\rCurrent Position: 5\r"),
        [ScreenEvent::Field(DemoField::Position(5))]
    );
}

#[test]
fn both_prompts_are_recognised() {
    let mut parser = ScreenParser::new();
    assert_eq!(
        events(&mut parser, b"\r\rEnter steps: \rEnter speed: "),
        [
            ScreenEvent::Prompt(DemoPrompt::Steps),
            ScreenEvent::Prompt(DemoPrompt::Speed)
        ]
    );
    assert_eq!(events(&mut parser, b"\rEnter steps:"), []);
}

fn any_screen() -> impl Strategy<Value = DemoScreen> {
    (
        any::<i64>(),
        0u8..64,
        any::<u32>(),
        any::<u32>(),
        any::<u32>(),
        any::<u32>(),
        any::<u32>(),
    )
        .prop_map(
            |(position, mode_bits, offset_deg, accel, slew, velocity, elapsed)| DemoScreen {
                position,
                mode_bits,
                offset_deg,
                accel_steps: accel,
                slew_steps: slew,
                max_velocity_steps_per_s: velocity,
                elapsed_ms: elapsed,
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn format_then_parse_gives_the_screen_back(screen in any_screen()) {
        let mut parser = ScreenParser::new();
        let mut bytes = display(&screen).into_bytes();
        bytes.push(CR);
        prop_assert_eq!(parser.push_all(&bytes), Some(ScreenEvent::Display(screen)));
        prop_assert_eq!(parser.position(), Some(screen.position));
        prop_assert_eq!(parser.mode_bits(), Some(screen.mode_bits));
    }

    #[test]
    fn a_chopped_and_damaged_stream_gives_only_true_values(
        screens in proptest::collection::vec(any_screen(), 1..5),
        start in 0usize..400,
        damage in proptest::collection::vec((0usize..1000, any::<u8>()), 0..4),
    ) {
        let mut bytes = Vec::new();
        bytes.push(CLEAR);
        for screen in &screens {
            bytes.extend_from_slice(display(screen).as_bytes());
        }
        bytes.push(CR);
        let mut damaged = bytes.clone();
        for &(at, byte) in &damage {
            if let Some(slot) = damaged.get_mut(at) {
                *slot = byte;
            }
        }
        let start = start.min(damaged.len());
        let mut parser = ScreenParser::new();
        for event in events(&mut parser, &damaged[start..]) {
            if let ScreenEvent::Display(got) = event {
                // Undamaged displays come back whole; a damaged one may
                // mix lines of neighbours, but never invents a mode digit.
                prop_assert!(got.mode_bits < 64);
                if damage.is_empty() {
                    prop_assert!(screens.contains(&got));
                }
            }
        }
        if damage.is_empty() && start == 0 {
            prop_assert_eq!(parser.position(), screens.last().map(|s| s.position));
        }
    }
}

/// A motor that runs each move for a number of polls and records starts.
#[derive(Default)]
struct FakeMotor {
    starts: Vec<(u32, i32)>,
    polls_per_move: u32,
    polls_left: u32,
    screen: DemoScreen,
    refusal: Option<AxisError>,
}

impl DemoMotor for FakeMotor {
    fn start_move(&mut self, speed: u32, steps: i32) -> Result<(), AxisError> {
        if let Some(error) = self.refusal {
            return Err(error);
        }
        self.starts.push((speed, steps));
        self.polls_left = self.polls_per_move;
        self.screen.mode_bits = 1;
        Ok(())
    }

    fn is_moving(&mut self) -> bool {
        if self.polls_left == 0 {
            self.screen.mode_bits = 0;
            return false;
        }
        self.polls_left -= 1;
        self.screen.position += 10;
        true
    }

    fn screen(&mut self) -> DemoScreen {
        self.screen
    }
}

fn feed(session: &mut DemoSession, motor: &mut FakeMotor, bytes: &[u8]) -> String {
    let mut out = String::new();
    for &byte in bytes {
        session.feed(byte, motor, &mut out).unwrap();
    }
    out
}

fn poll(session: &mut DemoSession, motor: &mut FakeMotor) -> String {
    let mut out = String::new();
    session.poll(motor, &mut out).unwrap();
    out
}

#[test]
fn the_flow_runs_as_the_reference_demo() {
    let mut motor = FakeMotor {
        polls_per_move: 3,
        ..FakeMotor::default()
    };
    let mut session = DemoSession::new();
    assert_eq!(session.phase(), DemoPhase::WaitingForKey);
    assert_eq!(poll(&mut session, &mut motor), "");

    // Any key: clear, display, prompt.
    let shown = feed(&mut session, &mut motor, b"x");
    let expected = std::format!("\x10{}\r\rEnter steps: ", display(&motor.screen));
    assert_eq!(shown, expected);
    assert_eq!(session.phase(), DemoPhase::EnterSteps);

    // Steps, then speed (negative taken as positive); nothing echoed.
    assert_eq!(feed(&mut session, &mut motor, b"-400\r"), "\rEnter speed: ");
    assert_eq!(feed(&mut session, &mut motor, b"-2500\r"), "\x10");
    assert_eq!(motor.starts, [(2500, -400)]);
    assert_eq!(session.phase(), DemoPhase::Running);

    // It reads nothing while the move runs.
    assert_eq!(feed(&mut session, &mut motor, b"123\r456\r"), "");
    assert_eq!(motor.starts.len(), 1);

    // Displays while it runs, each from home; then clear, display, prompt.
    for _ in 0..3 {
        let shown = poll(&mut session, &mut motor);
        assert!(shown.starts_with("\x01Stepper Demo\r"), "{shown:?}");
        assert!(!shown.contains('\x10'));
    }
    let last = poll(&mut session, &mut motor);
    assert_eq!(
        last,
        std::format!("\x10{}\r\rEnter steps: ", display(&motor.screen))
    );
    assert_eq!(session.phase(), DemoPhase::EnterSteps);
    assert_eq!(poll(&mut session, &mut motor), "");
}

#[test]
fn speed_zero_runs_at_one_and_bad_answers_prompt_again() {
    let mut motor = FakeMotor::default();
    let mut session = DemoSession::new();
    feed(&mut session, &mut motor, b"\r");
    assert_eq!(feed(&mut session, &mut motor, b"abc\r"), "\rEnter steps: ");
    assert_eq!(feed(&mut session, &mut motor, b"0\r"), "\rEnter steps: ");
    assert_eq!(feed(&mut session, &mut motor, b"\r"), "\rEnter steps: ");
    // Backspace, LF ignored, spaces around the number.
    assert_eq!(
        feed(&mut session, &mut motor, b" 129\x08\x7f5 \n\r"),
        "\rEnter speed: "
    );
    assert_eq!(feed(&mut session, &mut motor, b"fast\r"), "\rEnter speed: ");
    feed(&mut session, &mut motor, b"0\r");
    assert_eq!(motor.starts, [(1, 15)]);
}

#[test]
fn huge_answers_are_clamped() {
    let mut motor = FakeMotor::default();
    let mut session = DemoSession::new();
    feed(&mut session, &mut motor, b" ");
    feed(&mut session, &mut motor, b"-99999999999999999999999\r");
    feed(&mut session, &mut motor, b"99999999999\r");
    assert_eq!(motor.starts, [(u32::MAX, -i32::MAX)]);
}

#[test]
fn a_refused_move_is_reported_and_prompts_again() {
    let mut motor = FakeMotor {
        refusal: Some(AxisError::Plan(PlanError::SpeedTooHigh {
            speed: 9_000_000,
            clkfreq: 200_000_000,
        })),
        ..FakeMotor::default()
    };
    let mut session = DemoSession::new();
    feed(&mut session, &mut motor, b"k100\r");
    let shown = feed(&mut session, &mut motor, b"9000000\r");
    assert!(
        shown.starts_with("\rRefused: 9000000 steps/s is too fast"),
        "{shown:?}"
    );
    assert!(shown.ends_with("\rEnter steps: "));
    assert_eq!(session.phase(), DemoPhase::EnterSteps);
}

#[test]
fn a_host_follows_the_board_through_the_parser() {
    let mut motor = FakeMotor {
        polls_per_move: 5,
        ..FakeMotor::default()
    };
    let mut session = DemoSession::new();
    let mut parser = ScreenParser::new();
    let last = |bytes: String, parser: &mut ScreenParser| parser.push_all(bytes.as_bytes());

    let shown = feed(&mut session, &mut motor, b"\r");
    assert_eq!(
        last(shown, &mut parser),
        Some(ScreenEvent::Prompt(DemoPrompt::Steps))
    );
    let shown = feed(&mut session, &mut motor, b"50\r");
    assert_eq!(
        last(shown, &mut parser),
        Some(ScreenEvent::Prompt(DemoPrompt::Speed))
    );
    feed(&mut session, &mut motor, b"1000\r");
    let mut positions = Vec::new();
    loop {
        let shown = poll(&mut session, &mut motor);
        if let Some(ScreenEvent::Prompt(DemoPrompt::Steps)) = last(shown, &mut parser) {
            break;
        }
        positions.push(parser.position());
    }
    // One display per poll while running, the position read from each.
    assert_eq!(
        positions,
        [Some(10), Some(20), Some(30), Some(40), Some(50)]
    );
    assert_eq!(parser.position(), Some(50));
    // The final display shows the move ended.
    assert_eq!(parser.mode_bits(), Some(0));
}

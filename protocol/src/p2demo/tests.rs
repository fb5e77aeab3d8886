//! Tests of the demo dialect: the formatter and the parser against each
//! other and against hand-written bytes, and the prompt/answer flow.

extern crate std;
use std::string::String;
use std::vec::Vec;

use super::cog::ReferenceCog;
use super::*;
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
\r\x0bElapsed time (msec):   1234";

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
fn numbers_are_right_aligned_in_six_and_wider_ones_keep_their_rightmost_six() {
    // jm_nstr's padstr: `bytemove(@pbuf, p_str+len-width, width)`.
    for (value, field) in [
        (0, "     0"),
        (5, "     5"),
        (-42, "   -42"),
        (-12_345, "-12345"),
        (123_456, "123456"),
        (-123_456, "123456"),
        (1_000_000, "000000"),
        (-1_234_567, "234567"),
        (i32::MAX, "483647"),
        (i32::MIN, "483648"),
    ] {
        assert_eq!(number_field(value).as_str(), field, "{value}");
    }
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
    assert!(text.contains("\rCurrent Position: 234567\r"));
    assert!(text.contains("\r            Mode: 110000\r"));
    assert!(text.contains("\r          Offset:      0\r"));
    assert!(text.contains("\r     Accel steps:      5\r"));
    assert!(text.contains("\r    Max Velocity: 000000\r"));
    assert!(text.ends_with("\r\x0bElapsed time (msec):      0"));
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
        \r          Offset:    +40\
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
        any::<i32>(),
        0u8..64,
        any::<i32>(),
        any::<i32>(),
        any::<i32>(),
        any::<i32>(),
        any::<i32>(),
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
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn format_then_parse_gives_the_shown_screen_back(screen in any_screen()) {
        let mut parser = ScreenParser::new();
        let mut bytes = display(&screen).into_bytes();
        bytes.push(CR);
        let shown = screen.as_shown();
        prop_assert_eq!(parser.push_all(&bytes), Some(ScreenEvent::Display(shown)));
        prop_assert_eq!(parser.position(), Some(shown.position));
        prop_assert_eq!(parser.mode_bits(), Some(screen.mode_bits));
        // A value that fits its field comes back exactly.
        if (-99_999..=999_999).contains(&screen.position) {
            prop_assert_eq!(shown.position, screen.position);
        }
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
        let shown: Vec<DemoScreen> = screens.iter().map(DemoScreen::as_shown).collect();
        for event in events(&mut parser, &damaged[start..]) {
            if let ScreenEvent::Display(got) = event {
                // Undamaged displays come back whole; a damaged one may
                // mix lines of neighbours, but never invents a mode digit.
                prop_assert!(got.mode_bits < 64);
                if damage.is_empty() {
                    prop_assert!(shown.contains(&got));
                }
            }
        }
        if damage.is_empty() && start == 0 {
            prop_assert_eq!(parser.position(), shown.last().map(|s| s.position));
        }
    }
}

/// The demo's cog in virtual time: every move on the reference cog model.
#[derive(Default)]
struct ModelMotor {
    now_ns: u64,
    position: i32,
    mode: u32,
    max_velocity: i32,
    running: Option<(ReferenceCog, u64)>,
    starts: Vec<DemoPlan>,
}

impl ModelMotor {
    fn advance(&mut self) {
        if let Some((cog, taken)) = &mut self.running {
            // 200 MHz: 1 clock every 5 ns.
            cog.run_until((self.now_ns - *taken) / 5);
            self.position = cog.position();
            self.mode = cog.mode();
            if let Some(velocity) = cog.max_velocity() {
                self.max_velocity = velocity;
            }
            if cog.is_done() {
                self.running = None;
            }
        }
    }
}

impl DemoMotor for ModelMotor {
    fn preset_position(&mut self, position: i32) {
        self.position = position;
    }

    fn start_move(&mut self, plan: &DemoPlan) {
        self.starts.push(*plan);
        if plan.steps != 0 {
            let cog = ReferenceCog::start(self.position, plan, DEMO_CLKFREQ);
            self.running = Some((cog, self.now_ns));
            self.advance();
        }
    }

    fn is_moving(&mut self) -> bool {
        self.advance();
        self.running.is_some()
    }

    fn cog(&mut self) -> CogLongs {
        self.advance();
        CogLongs {
            position: self.position,
            mode: self.mode,
            max_velocity: self.max_velocity,
        }
    }
}

/// A simulated board: the demo program over the model cog, in virtual time.
#[derive(Default)]
struct DemoBoard {
    session: DemoSession,
    motor: ModelMotor,
}

const SECOND: u64 = 1_000_000_000;
const MS: u64 = 1_000_000;

impl DemoBoard {
    /// Bytes sent in one go at `at_ns` (the line spaces them); what the
    /// board printed meanwhile.
    fn type_at(&mut self, bytes: &[u8], at_ns: u64) -> String {
        let mut out = String::new();
        self.motor.now_ns = at_ns;
        for &byte in bytes {
            self.session
                .feed(byte, at_ns, &mut self.motor, &mut out)
                .unwrap();
        }
        out
    }

    /// Polls every ms from `from_ns` until the steps prompt (at most 60 s).
    fn run_move(&mut self, from_ns: u64) -> (String, u64) {
        let mut out = String::new();
        let mut now = from_ns;
        while !out.ends_with(STEPS_TAIL) {
            assert!(now < from_ns + 60 * SECOND, "the move never ended");
            self.motor.now_ns = now;
            self.session.poll(now, &mut self.motor, &mut out).unwrap();
            now += MS;
        }
        (out, now)
    }
}

// The demo's strings, as the Spin source writes them.
/// `term.tx(16)` and `term.CLS`.
const CLS: &str = "\x10";
/// `"\r\rEnter steps: "`.
const STEPS_TAIL: &str = "\r\rEnter steps: ";
/// `"\rEnter speed: "`.
const SPEED_TAIL: &str = "\rEnter speed: ";

/// `Showvalues()` for values that fit their 6-character fields, from the
/// Spin source's strings: `"\001%s\r"` with `Banner`, then one `"\r…: "`
/// string and a `jdpdec(value, 0, 6, " ")` or `fbin(mode, 6)` per line
/// (`\011` is decimal 11).
fn showvalues(values: [i32; 7]) -> String {
    let [position, mode, offset, accel, slew, velocity, elapsed] = values;
    let mut text = String::from("\x01Stepper Demo\r");
    text += &std::format!("\rCurrent Position: {position:>6}");
    text += &std::format!("\r            Mode: {:06b}", mode & 0b11_1111);
    text += &std::format!("\r          Offset: {offset:>6}");
    text += &std::format!("\r     Accel steps: {accel:>6}");
    text += &std::format!("\r  Steps at speed: {slew:>6}");
    text += &std::format!("\r    Max Velocity: {velocity:>6}");
    text += &std::format!("\r\x0bElapsed time (msec): {elapsed:>6}");
    text
}

#[test]
fn a_session_from_power_up_is_byte_exact() {
    let mut board = DemoBoard::default();
    assert_eq!(board.session.phase(), DemoPhase::WaitingForKey);
    let mut idle = String::new();
    board
        .session
        .poll(SECOND, &mut board.motor, &mut idle)
        .unwrap();
    assert_eq!(idle, "");

    // Any key: clear, the position preset to 1000, one display (Offset 0:
    // no move() yet), the steps prompt.
    let shown = board.type_at(b" ", 2 * SECOND);
    assert_eq!(
        shown,
        std::format!("{CLS}{}{STEPS_TAIL}", showvalues([1000, 0, 0, 0, 0, 0, 0]))
    );
    // Answers are not echoed.
    assert_eq!(board.type_at(b"200\r", 3 * SECOND), SPEED_TAIL);
    assert_eq!(board.type_at(b"1000\r", 4 * SECOND), CLS);
    // 200 steps at 1000: asteps = 102, capped at 100, no steps at speed,
    // so the speed becomes 10 * (100 - 2) = 980.
    assert_eq!(
        board.motor.starts,
        [DemoPlan {
            speed: 980,
            steps: 200,
            accel_steps: 100,
            slew_steps: 0,
            offset_deg: 40,
        }]
    );

    let (shown, _) = board.run_move(4 * SECOND);
    // The first display: the cog's first step is at once; nothing has
    // written Max Velocity yet; endt = start.
    let first = showvalues([1001, 0b11, 40, 100, 0, 0, 0]);
    assert!(shown.starts_with(&first), "{shown:?}");
    let displays = shown.matches("\x01Stepper Demo\r").count();
    assert!(displays > 10, "{displays} displays");

    // The final display, after a clear: what the reference cog left.
    let mut cog = ReferenceCog::start(1000, &board.motor.starts[0], DEMO_CLKFREQ);
    cog.run_until(u64::MAX);
    let (_, last) = shown.rsplit_once(CLS).unwrap();
    let elapsed: i32 = last
        .split("Elapsed time (msec): ")
        .nth(1)
        .and_then(|tail| tail.split('\r').next())
        .map(|field| field.trim().parse().unwrap())
        .unwrap();
    assert_eq!(
        last,
        std::format!(
            "{}{STEPS_TAIL}",
            showvalues([1200, 0, 40, 100, 0, cog.max_velocity().unwrap(), elapsed])
        )
    );
    assert!(cog.max_velocity().unwrap() > 0 && cog.max_velocity().unwrap() <= 980);
    // The elapsed time covers the move (the cog's last delay included)
    // up to the end of the display during which it ended (a display is
    // about 17 ms at 115,200 baud).
    let move_ms = (cog.next_step_at() / 200_000) as i32;
    assert!(
        (move_ms..=move_ms + 19).contains(&elapsed),
        "{elapsed} ms for a {move_ms} ms move"
    );
}

#[test]
fn answers_are_read_as_str_to_base_reads_them() {
    for (answer, value) in [
        (&b"1a2"[..], 12),
        (b"12 34", 1234),
        (b" -5", 5),
        (b"--3", -3),
        (b"-12", -12),
        (b"", 0),
        (b"abc", 0),
        (b"-0", 0),
        (b"0x1F", 1),
        (b"+7", 7),
        (b"1\x7f2", 12),
        // Control bytes 16 to 25 map to 0 to 9 as well.
        (b"\x10\x19", 9),
        (b"12\x0034", 12),
        // 32-bit wrapping: 2^32 + 1.
        (b"4294967297", 1),
        (b"2147483648", i32::MIN),
    ] {
        assert_eq!(demo_number(answer), value, "{answer:?}");
    }
}

#[test]
fn every_answer_is_taken_and_the_next_prompt_follows() {
    let mut board = DemoBoard::default();
    board.type_at(b"x", 0);
    // Not a number: 0 steps, and the speed prompt still follows.
    assert_eq!(board.type_at(b"abc\r", SECOND), SPEED_TAIL);
    // An empty speed means 1, and the move starts (a 0-step move: the cog
    // never takes it).
    assert_eq!(board.type_at(b"\r", 2 * SECOND), CLS);
    let (shown, _) = board.run_move(2 * SECOND);
    assert_eq!(
        board.motor.starts,
        [DemoPlan {
            speed: -20,
            steps: 0,
            accel_steps: 0,
            slew_steps: 0,
            offset_deg: 40
        }]
    );
    // One display, then the final one; never a refusal.
    assert_eq!(shown.matches("\x01Stepper Demo\r").count(), 2);
    assert!(!shown.contains("Refused"));
    assert!(shown.contains("\r          Offset:     40"));
    assert!(shown.contains("\rCurrent Position:   1000"));

    // Backspace ends an answer and drops its last character.
    let now = 10 * SECOND;
    assert_eq!(board.type_at(b"123\x08", now), SPEED_TAIL);
    // Byte 127 is stored and ignored; a negative speed counts as positive
    // (and 12 steps at 400 are slowed to 10 * (6 - 2) = 40).
    assert_eq!(board.type_at(b"-4\x7f00\r", now + SECOND), CLS);
    assert_eq!(board.motor.starts[1].steps, 12);
    assert_eq!(board.motor.starts[1].speed, 40);
    board.run_move(now + SECOND);
    assert_eq!(board.motor.position, 1012);

    // An answer ends by itself at 99 characters.
    let now = 20 * SECOND;
    let long = [b'1'; ANSWER_MAX];
    assert_eq!(board.type_at(&long[..ANSWER_MAX - 1], now), "");
    assert_eq!(board.session.phase(), DemoPhase::EnterSteps);
    assert_eq!(board.type_at(b"1", now + SECOND), SPEED_TAIL);
    assert_eq!(board.session.phase(), DemoPhase::EnterSpeed);
}

#[test]
fn bytes_that_arrive_while_the_board_prints_overwrite_each_other() {
    let mut board = DemoBoard::default();
    board.type_at(b" ", 0);
    // Both answers in one go: "2000\r" reaches the board while it prints
    // the speed prompt; only the CR is left in the receive pin, so the
    // speed answer is empty and the move starts at speed 1.
    let shown = board.type_at(b"100\r2000\r", SECOND);
    assert_eq!(shown, SPEED_TAIL);
    let mut out = String::new();
    board.motor.now_ns = 2 * SECOND;
    board
        .session
        .poll(2 * SECOND, &mut board.motor, &mut out)
        .unwrap();
    assert!(out.starts_with(CLS), "{out:?}");
    assert_eq!(board.motor.starts.len(), 1);
    assert_eq!(board.motor.starts[0].steps, 100);
    // Speed 1: asteps = 2, 96 steps at speed 1.
    assert_eq!(board.motor.starts[0].speed, 1);

    // While a move runs the board reads nothing; the last byte waits.
    board.type_at(b"777\r5", 3 * SECOND);
    assert_eq!(board.motor.starts.len(), 1);
}

#[test]
fn the_botched_moves_are_the_reference_planners() {
    for steps in [1, -1] {
        assert_eq!(check_demo_move(20_000, steps), Err(DemoFlaw::OneStep));
    }
    for speed in [1, 10, 45_000] {
        assert_eq!(check_demo_move(speed, 2), Err(DemoFlaw::TwoSteps));
        assert_eq!(check_demo_move(speed, -4), Err(DemoFlaw::FourSteps));
        assert!(matches!(
            check_demo_move(speed, 3),
            Err(DemoFlaw::OddShortFullSpeed { steps: 3, .. })
        ));
    }
    assert_eq!(demo_move(1000, 2).speed, -10);
    assert_eq!(demo_move(1000, 4).speed, 0);
    // 5 steps: capped from 10 steps/s (asteps 3 > 2).
    assert!(check_demo_move(9, 5).is_ok());
    assert_eq!(
        check_demo_move(10, -5),
        Err(DemoFlaw::OddShortFullSpeed {
            steps: 5,
            speed: 10,
            accel_steps: 2
        })
    );
    // Even short moves are slowed, as designed; the exact boundary too.
    assert_eq!(check_demo_move(1000, 6).map(|plan| plan.speed), Ok(10));
    assert_eq!(check_demo_move(1009, 204).map(|plan| plan.speed), Ok(1000));
    assert_eq!(check_demo_move(25, 8).map(|plan| plan.speed), Ok(20));
    // Long odd moves reach their speed: one step at speed is fine.
    assert_eq!(
        check_demo_move(1000, 205).map(|plan| (plan.accel_steps, plan.slew_steps)),
        Ok((102, 1))
    );
    assert_eq!(
        check_demo_move(2_147_483_648, 100),
        Err(DemoFlaw::SpeedUnreadable {
            speed: 2_147_483_648
        })
    );
    assert_eq!(
        check_demo_move(DEMO_SPEED_MAX + 1, 1000),
        Err(DemoFlaw::SpeedTooHigh {
            speed: DEMO_SPEED_MAX + 1
        })
    );
    assert!(check_demo_move(DEMO_SPEED_MAX, 1000).is_ok());
    assert_eq!(
        check_demo_move(100, i32::MIN),
        Err(DemoFlaw::StepsUnreadable)
    );
}

#[test]
fn the_reference_cog_shows_the_flaws() {
    // 2 steps: speed -10 makes halfsp huge, the first delay 0, a target
    // already passed: the second step waits for the counter to wrap.
    let plan = demo_move(1000, 2);
    let mut cog = ReferenceCog::start(0, &plan, DEMO_CLKFREQ);
    cog.run_until(0);
    assert_eq!((cog.position(), cog.mode()), (1, 0b101));
    let wrap = cog.next_step_at();
    assert!(wrap > 1 << 32, "{wrap}");
    // Max Velocity was written from the bogus velocity.
    assert!(cog.max_velocity().unwrap() > 100_000_000);
    cog.run_until(wrap);
    assert_eq!(cog.position(), 2);
    cog.run_until(u64::MAX);
    assert!(cog.is_done());
    assert_eq!(cog.mode(), 0);

    // 4 steps: speed 0, every delay is the 95,000,000-clock ceiling.
    let plan = demo_move(1000, -4);
    let mut cog = ReferenceCog::start(0, &plan, DEMO_CLKFREQ);
    let mut edges = Vec::new();
    while !cog.is_done() {
        edges.push(cog.next_step_at());
        cog.run_until(cog.next_step_at());
    }
    assert_eq!(cog.position(), -4);
    assert_eq!(edges.len(), 5);
    for pair in edges.windows(2) {
        // Each period: the delay, the pulse, the cog's 8-clock loop.
        assert_eq!(pair[1] - pair[0], 95_000_000 + 1_000 + 8);
    }

    // 1 step: QDIV by stom = 0 gives $FFFF_FFFF; the angle wraps to just
    // below 40 degrees, and the move ends after one step.
    let plan = demo_move(20_000, 1);
    let mut cog = ReferenceCog::start(7, &plan, DEMO_CLKFREQ);
    cog.run_until(u64::MAX);
    assert!(cog.is_done());
    assert_eq!(cog.position(), 8);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Every move the host lets through runs on the reference cog as
    /// asked: every step made, no counter-wrap stall, a sane Max Velocity.
    #[test]
    fn the_moves_let_through_run_sanely_on_the_reference_cog(
        speed in 1u32..60_000,
        steps in -3_000i32..3_000,
    ) {
        prop_assume!(steps != 0);
        let Ok(plan) = check_demo_move(speed, steps) else {
            return Ok(());
        };
        let mut cog = ReferenceCog::start(1000, &plan, DEMO_CLKFREQ);
        let mut last = 0;
        while !cog.is_done() {
            let next = cog.next_step_at();
            prop_assert!(next - last < 96_000_000, "a stall of {} clocks", next - last);
            last = next;
            cog.run_until(next);
        }
        prop_assert_eq!(cog.position(), 1000 + steps);
        prop_assert_eq!(
            ReferenceCog::max_velocity_of(&plan, DEMO_CLKFREQ),
            cog.max_velocity()
        );
        let velocity = cog.max_velocity().unwrap();
        prop_assert!(velocity >= 1 && velocity as u32 <= speed, "{}", velocity);
        prop_assert_eq!(cog.mode(), 0);
    }
}

/// `StrInMax(@str_buffer, 99)` and `StrToBase(@str_buffer, 10)` run the
/// way the Spin source runs them: a byte buffer (after the demo's `cpin`
/// and `dpin` bytes), a moving pointer, the terminator writes. Gives the
/// value and how many bytes the answer took, or `None` if `typed` does not
/// end an answer.
fn spin_answer(typed: &[u8]) -> Option<(i32, usize)> {
    const NL: u8 = 13;
    let mut memory = [0u8; 2 + ANSWER_MAX + 1];
    memory[0] = 17; // cpin
    memory[1] = 19; // dpin
    let buffer = 2;
    let mut pointer = buffer;
    let mut maxcount = ANSWER_MAX;
    let mut taken = 0;
    while maxcount > 0 {
        maxcount -= 1;
        let c = *typed.get(taken)?;
        taken += 1;
        if c == 8 {
            memory[pointer] = 0;
            pointer -= 1;
            break;
        }
        memory[pointer] = c;
        pointer += 1;
        if c == NL {
            break;
        }
    }
    // `byte[stringptr+(byte[stringptr-1] == NL)]~`: true is -1.
    let at = if memory[pointer - 1] == NL {
        pointer - 1
    } else {
        pointer
    };
    memory[at] = 0;
    let mut value: i32 = 0;
    let mut index = buffer;
    loop {
        let mut chr = i32::from(memory[index]);
        index += 1;
        if chr == 0 {
            break;
        }
        chr -= 1;
        chr = -15 + (chr & 0b1101_1111) + 39 * if chr > 56 { -1 } else { 0 };
        if chr > -1 && chr < 10 {
            value = value.wrapping_mul(10).wrapping_add(chr);
        }
    }
    if memory[buffer] == b'-' {
        value = value.wrapping_neg();
    }
    Some((value, taken))
}

fn typed_byte() -> impl Strategy<Value = u8> {
    prop_oneof![
        6 => b'0'..=b'9',
        2 => Just(b'-'),
        1 => Just(b' '),
        1 => Just(8u8),
        1 => Just(13u8),
        1 => Just(127u8),
        1 => Just(0u8),
        1 => 16u8..=25,
        1 => b'a'..=b'z',
        1 => any::<u8>(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// The steps answer the board takes is the one the Spin source reads,
    /// for any bytes typed one by one at the steps prompt.
    #[test]
    fn steps_answers_are_read_as_the_spin_source_reads_them(
        typed in proptest::collection::vec(typed_byte(), 0..130),
    ) {
        let mut board = DemoBoard::default();
        board.type_at(b" ", 0);
        let expected = spin_answer(&typed);
        let mut now = SECOND;
        let mut taken = None;
        for (index, &byte) in typed.iter().enumerate() {
            board.type_at(&[byte], now);
            now += MS;
            if board.session.phase() == DemoPhase::EnterSpeed {
                taken = Some(index + 1);
                break;
            }
        }
        prop_assert_eq!(taken, expected.map(|(_, taken)| taken));
        if let Some((value, _)) = expected {
            // An empty speed answer: speed 1, and the move is given.
            board.type_at(b"\r", now + MS);
            prop_assert_eq!(board.motor.starts.len(), 1);
            prop_assert_eq!(board.motor.starts[0].steps, value);
        }
    }
}

#[test]
fn the_speed_limit_is_the_clock_over_the_delay_computation() {
    assert_eq!(GETDELAY_TICKS, 350);
    assert_eq!(DEMO_SPEED_MAX, 571_428);
    assert_eq!(BYTE_NS, 86_805);
}

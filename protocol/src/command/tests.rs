//! Tests of command lines: every command parsed and written back, the
//! order of the checks, checksums.

extern crate std;
use std::string::String;

use super::*;
use crate::ProtocolError;
use proptest::prelude::*;

fn parse(line: &str) -> Result<Command, ProtocolError> {
    parse_line(line.as_bytes())
}

fn with_checksum(body: &str) -> String {
    std::format!("{body}*{:02X}", checksum(body.as_bytes()))
}

#[test]
fn every_command_parses() {
    assert_eq!(parse("I"), Ok(Command::Identify));
    assert_eq!(parse("E"), Ok(Command::EmergencyStop));
    assert_eq!(
        parse("M 0 20000 -1500"),
        Ok(Command::Move {
            axis: 0,
            speed_steps_per_s: 20_000,
            steps: -1500
        })
    );
    assert_eq!(
        parse("J 3 800 +"),
        Ok(Command::Jog {
            axis: 3,
            speed_steps_per_s: 800,
            direction: Direction::Forward
        })
    );
    assert_eq!(
        parse("J 3 800 -"),
        Ok(Command::Jog {
            axis: 3,
            speed_steps_per_s: 800,
            direction: Direction::Reverse
        })
    );
    assert_eq!(parse("S 1"), Ok(Command::Stop(Target::Axis(1))));
    assert_eq!(parse("S *"), Ok(Command::Stop(Target::All)));
    assert_eq!(parse("R 0"), Ok(Command::Run(Target::Axis(0))));
    assert_eq!(parse("R *"), Ok(Command::Run(Target::All)));
    assert_eq!(
        parse("P 2 -9223372036854775808"),
        Ok(Command::SetPosition {
            axis: 2,
            position: i64::MIN
        })
    );
    assert_eq!(
        parse("H 0 10 1 - 8000 500 200 100000 0"),
        Ok(Command::Home {
            axis: 0,
            config: HomeConfig {
                switch_pin: 10,
                ..HomeConfig::default()
            }
        })
    );
    assert_eq!(
        parse("W 1 -1000 50000"),
        Ok(Command::SoftLimits {
            axis: 1,
            limits: Some((-1_000, 50_000))
        })
    );
    assert_eq!(
        parse("W 1 -"),
        Ok(Command::SoftLimits {
            axis: 1,
            limits: None
        })
    );
    assert_eq!(
        parse("K 0 11/1 -"),
        Ok(Command::LimitPins {
            axis: 0,
            min: Some((11, true)),
            max: None
        })
    );
    assert_eq!(parse("C 3"), Ok(Command::ClearLimitFault(3)));
    assert_eq!(parse("L 3"), Ok(Command::Limits(3)));
    for bad in [
        "K 0 256/1 -",
        "K 0 +1/1 -",
        "K 0 11/2 -",
        "K 0 11 -",
        "H 0 10 2 - 1 1 1 1 0",
        "H 0 256 1 - 1 1 1 1 0",
    ] {
        assert_eq!(parse(bad), Err(ProtocolError::BadPin), "{bad}");
    }
    // Pins and counts the axis refuses reach the axis, so that the
    // board answers with its own refusal.
    assert_eq!(
        parse("K 0 64/1 255/0"),
        Ok(Command::LimitPins {
            axis: 0,
            min: Some((64, true)),
            max: Some((255, false))
        })
    );
    assert!(matches!(
        parse("H 0 64 1 - 8000 500 0 4294967295 0"),
        Ok(Command::Home {
            config: HomeConfig {
                switch_pin: 64,
                backoff_steps: 0,
                max_travel: u32::MAX,
                ..
            },
            ..
        })
    ));
    assert_eq!(
        parse("H 0 10 1 - 8000 500 1 4294967296 0"),
        Err(ProtocolError::StepsOutOfRange)
    );
    assert_eq!(parse("W 1 5"), Err(ProtocolError::MissingArgument));
}

#[test]
fn spacing_and_case_are_forgiving() {
    assert_eq!(
        parse("  m   0  100   +200  "),
        Ok(Command::Move {
            axis: 0,
            speed_steps_per_s: 100,
            steps: 200
        })
    );
    assert_eq!(parse("i"), Ok(Command::Identify));
}

#[test]
fn unknown_commands() {
    for line in ["X", "MM 0 1 1", "M0 1 1", "1", "*", "Identify", "*00"] {
        assert_eq!(parse(line), Err(ProtocolError::UnknownCommand), "{line}");
    }
}

#[test]
fn bad_arguments() {
    use ProtocolError::*;
    let cases = [
        ("M", MissingArgument),
        ("M 0 100", MissingArgument),
        ("M 0 100 200 5", ExtraArgument),
        ("I 0", ExtraArgument),
        ("E now", ExtraArgument),
        ("M x 100 200", BadNumber),
        ("M -1 100 200", BadNumber),
        ("M +1 100 200", BadNumber),
        ("M 0 1e3 200", BadNumber),
        ("M 0 100 2.5", BadNumber),
        ("M 0 100 -", BadNumber),
        ("M 0 100 0", StepsOutOfRange),
        ("M 0 100 2147483648", StepsOutOfRange),
        ("M 0 100 -2147483648", StepsOutOfRange),
        ("J 0 100 x", BadDirection),
        ("J 0 100 ++", BadDirection),
        ("S", MissingArgument),
        ("S * 1", ExtraArgument),
        ("S **", BadNumber),
        ("P 0 9223372036854775808", BadNumber),
        ("P 0 -9223372036854775809", BadNumber),
        ("P 0 99999999999999999999999999", BadNumber),
    ];
    for (line, error) in cases {
        assert_eq!(parse(line), Err(error), "{line}");
    }
}

#[test]
fn speeds_out_of_range() {
    for line in [
        "M 0 0 100",
        "M 0 -5 100",
        "M 0 4294967296 100",
        "J 0 0 +",
        "M 0 -0 1",
    ] {
        assert_eq!(parse(line), Err(ProtocolError::SpeedOutOfRange), "{line}");
    }
    assert!(parse("M 0 4294967295 1").is_ok());
}

#[test]
fn a_huge_axis_number_is_a_number() {
    assert_eq!(
        parse("S 99999999999999999999999"),
        Ok(Command::Stop(Target::Axis(usize::MAX)))
    );
}

#[test]
fn bad_bytes_are_rejected() {
    assert_eq!(parse_line(b"M 0 1\t1"), Err(ProtocolError::BadByte(b'\t')));
    assert_eq!(parse_line(b"I\x7f"), Err(ProtocolError::BadByte(0x7f)));
    assert_eq!(parse_line(b"\xffI"), Err(ProtocolError::BadByte(0xff)));
    assert_eq!(parse_line(b"\0"), Err(ProtocolError::BadByte(0)));
}

#[test]
fn checksums() {
    // "I" is 0x49.
    assert_eq!(parse("I*49"), Ok(Command::Identify));
    assert_eq!(
        parse("I*48"),
        Err(ProtocolError::Checksum {
            computed: 0x49,
            stated: 0x48
        })
    );
    let line = with_checksum("M 0 20000 -1500");
    assert!(parse(&line).is_ok());
    // Hex digits in either case.
    let body = "M 0 20000 -1508";
    let lower = std::format!("{body}*{:02x}", checksum(body.as_bytes()));
    assert!(lower.bytes().any(|b| b.is_ascii_lowercase()));
    assert!(parse(&lower).is_ok());
    // The checksum covers every byte before '*', spaces included.
    let line = with_checksum(" S * ");
    assert_eq!(parse(&line), Ok(Command::Stop(Target::All)));
    // A bad checksum wins over everything else wrong with the line.
    assert!(matches!(
        parse("X\t*00"),
        Err(ProtocolError::Checksum { .. })
    ));
    // Not a checksum: one digit, or not hex; then the line is just wrong.
    assert_eq!(parse("I*4"), Err(ProtocolError::UnknownCommand));
    assert_eq!(parse("I *4"), Err(ProtocolError::ExtraArgument));
    assert!(parse("I*4G").is_err());
    // A trailing space after the checksum is trimmed.
    assert_eq!(parse("I*49 "), Ok(Command::Identify));
}

#[test]
fn write_checked_states_the_right_checksum() {
    let command = Command::Jog {
        axis: 1,
        speed_steps_per_s: 400,
        direction: Direction::Reverse,
    };
    let mut line = String::new();
    command.write_checked(&mut line).unwrap();
    assert_eq!(line, with_checksum("J 1 400 -"));
    assert_eq!(parse(&line), Ok(command));
}

fn any_command() -> impl Strategy<Value = Command> {
    let target = prop_oneof![Just(Target::All), (0usize..9).prop_map(Target::Axis)];
    let direction = prop_oneof![Just(Direction::Forward), Just(Direction::Reverse)];
    let steps = prop_oneof![1..=i32::MAX, -i32::MAX..=-1];
    prop_oneof![
        Just(Command::Identify),
        Just(Command::EmergencyStop),
        (any::<usize>(), 1..=u32::MAX, steps).prop_map(|(axis, speed, steps)| {
            Command::Move {
                axis,
                speed_steps_per_s: speed,
                steps,
            }
        }),
        (0usize..9, 1..=u32::MAX, direction).prop_map(|(axis, speed, direction)| {
            Command::Jog {
                axis,
                speed_steps_per_s: speed,
                direction,
            }
        }),
        target.clone().prop_map(Command::Stop),
        target.prop_map(Command::Run),
        (0usize..9, any::<i64>())
            .prop_map(|(axis, position)| Command::SetPosition { axis, position }),
        (
            1..=u32::MAX,
            prop::collection::vec(-9_999_999..=9_999_999i32, 1..=GROUP_AXES_MAX)
        )
            .prop_map(|(speed, steps)| Command::GroupMove(GroupMove::new(speed, &steps).unwrap())),
    ]
}

#[test]
fn a_group_move_names_the_steps_of_axes_0_to_n() {
    let group =
        |speed, steps: &[i32]| Ok(Command::GroupMove(GroupMove::new(speed, steps).unwrap()));
    assert_eq!(
        parse("G 20000 12000 -4000 0"),
        group(20_000, &[12_000, -4_000, 0])
    );
    assert_eq!(parse("g 5 0"), group(5, &[0]));
    assert_eq!(
        parse("G 1 1 2 3 4 5 6 7 8"),
        group(1, &[1, 2, 3, 4, 5, 6, 7, 8])
    );
    assert_eq!(
        parse("G 1 1 2 3 4 5 6 7 8 9"),
        Err(ProtocolError::ExtraArgument)
    );
    assert_eq!(parse("G 20000"), Err(ProtocolError::MissingArgument));
    assert_eq!(parse("G 0 10"), Err(ProtocolError::SpeedOutOfRange));
    assert_eq!(parse("G 10 1 x"), Err(ProtocolError::BadNumber));
    assert_eq!(
        parse("G 10 -2147483648"),
        Err(ProtocolError::StepsOutOfRange)
    );
    assert_eq!(
        std::format!(
            "{}",
            Command::GroupMove(GroupMove::new(800, &[-3, 0, 7]).unwrap())
        ),
        "G 800 -3 0 7"
    );
    assert_eq!(GroupMove::new(1, &[]), None);
    assert_eq!(GroupMove::new(1, &[0; 9]), None);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn display_then_parse_is_identity(command in any_command()) {
        let line = std::format!("{command}");
        prop_assert!(line.len() <= crate::LINE_MAX);
        prop_assert_eq!(parse(&line), Ok(command));
        let mut checked = String::new();
        command.write_checked(&mut checked).unwrap();
        prop_assert_eq!(parse(&checked), Ok(command));
    }
}

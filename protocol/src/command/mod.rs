//! Command lines: parsed from bytes (board side), written back (host side).
//!
//! A line is a one-letter command and its arguments, separated by one or
//! more spaces, optionally ended by `*HH`: two hex digits of the XOR of
//! every byte before the `*`. Checks run in this order, and the first that
//! fails decides the error: checksum (when present), bytes (printable ASCII
//! only), command letter, then the arguments left to right.

use core::fmt;

use super::reply::ProtocolError;
use cogstep_motion::axis::{Direction, HomeConfig};

/// Which axes a stop-pin command acts on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// One axis, 0-based.
    Axis(usize),
    /// Every axis (`*`).
    All,
}

/// One command line, parsed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// `I`: identify the board.
    Identify,
    /// `M <axis> <speed> <steps>`: start a move, or merge into the running one.
    Move {
        /// The axis, 0-based.
        axis: usize,
        /// Top speed, steps/s, at least 1.
        speed_steps_per_s: u32,
        /// Steps to move, signed (the sign is the direction), never 0.
        steps: i32,
    },
    /// `J <axis> <speed> <+|->`: a jog heartbeat.
    Jog {
        /// The axis, 0-based.
        axis: usize,
        /// Jog speed, steps/s, at least 1.
        speed_steps_per_s: u32,
        /// `+` forward, `-` reverse.
        direction: Direction,
    },
    /// `S <axis|*>`: stop pin low, a controlled stop.
    Stop(Target),
    /// `R <axis|*>`: stop pin high, running allowed.
    Run(Target),
    /// `E`: emergency stop of every axis, positions kept.
    EmergencyStop,
    /// `P <axis> <position>`: set the position counter of an idle axis.
    SetPosition {
        /// The axis, 0-based.
        axis: usize,
        /// The new position, steps.
        position: i64,
    },
    /// `H <axis> <pin> <0|1> <+|-> <seek> <latch> <backoff> <max_travel>
    /// <set_position>`: start homing an idle axis.
    Home {
        /// The axis, 0-based.
        axis: usize,
        /// How to home.
        config: HomeConfig,
    },
    /// `W <axis> <min> <max>`: soft limits; `W <axis> -` removes them.
    SoftLimits {
        /// The axis, 0-based.
        axis: usize,
        /// `(min, max)`, or none.
        limits: Option<(i64, i64)>,
    },
    /// `K <axis> <min> <max>`, each `<pin>/<0|1>` (the active level) or
    /// `-`: the hard limit inputs.
    LimitPins {
        /// The axis, 0-based.
        axis: usize,
        /// The limit met moving in reverse.
        min: Option<(u8, bool)>,
        /// The limit met moving forward.
        max: Option<(u8, bool)>,
    },
    /// `C <axis>`: clear a tripped hard limit.
    ClearLimitFault(usize),
    /// `L <axis>`: the limit and homing state, as a `[limits ...]` line.
    Limits(usize),
    /// `G <speed> <steps of axis 0> [<steps of axis 1> …]`: a coordinated
    /// move of axes 0 to n − 1 (1 ≤ n ≤ 8) along one straight line, every
    /// axis's first step on one CT; steps of 0 leave an axis still (it must
    /// still be idle). All or nothing.
    GroupMove(GroupMove),
}

/// The most axes one `G` line moves.
pub const GROUP_AXES_MAX: usize = 8;

/// The arguments of a `G` line: a speed and the signed steps of axes
/// 0 to n − 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct GroupMove {
    /// The lead's (the longest move's) top speed, steps/s, at least 1.
    pub speed_steps_per_s: u32,
    steps: [i32; GROUP_AXES_MAX],
    axes: u8,
}

impl GroupMove {
    /// `steps[i]` for axis `i`; `None` unless 1 to [`GROUP_AXES_MAX`]
    /// axes, each with steps in −(2³¹ − 1) ..= 2³¹ − 1.
    pub fn new(speed_steps_per_s: u32, steps: &[i32]) -> Option<Self> {
        if steps.is_empty() || steps.len() > GROUP_AXES_MAX || steps.contains(&i32::MIN) {
            return None;
        }
        let mut all = [0; GROUP_AXES_MAX];
        all[..steps.len()].copy_from_slice(steps);
        Some(GroupMove {
            speed_steps_per_s,
            steps: all,
            axes: steps.len() as u8,
        })
    }

    /// The steps of axes 0, 1, ….
    pub fn steps(&self) -> &[i32] {
        &self.steps[..usize::from(self.axes)]
    }
}

/// The XOR of `bytes`: the checksum a line's `*HH` suffix states.
pub fn checksum(bytes: &[u8]) -> u8 {
    bytes.iter().fold(0, |acc, &byte| acc ^ byte)
}

/// Parses one line (without its line end). Never panics, on any bytes.
pub fn parse_line(line: &[u8]) -> Result<Command, ProtocolError> {
    parse_line_on(line, usize::MAX)
}

/// [`parse_line`] for a board of `axis_count` axes: an axis number out of
/// range is `NoSuchAxis` where it stands, before the arguments after it
/// (the documented order: arguments left to right).
pub fn parse_line_on(line: &[u8], axis_count: usize) -> Result<Command, ProtocolError> {
    let parse_axis = |token: &[u8]| {
        let axis = parse_axis(token)?;
        if axis >= axis_count {
            return Err(ProtocolError::NoSuchAxis(axis));
        }
        Ok(axis)
    };
    let line = trim_trailing_spaces(line);
    let body = match split_checksum(line) {
        Some((body, stated)) => {
            let computed = checksum(body);
            if computed != stated {
                return Err(ProtocolError::Checksum { computed, stated });
            }
            body
        }
        None => line,
    };
    if let Some(&byte) = body.iter().find(|&&byte| !(b' '..=b'~').contains(&byte)) {
        return Err(ProtocolError::BadByte(byte));
    }

    let mut tokens = body.split(|&byte| byte == b' ').filter(|t| !t.is_empty());
    let letter = match tokens.next() {
        Some([letter]) => letter.to_ascii_uppercase(),
        _ => return Err(ProtocolError::UnknownCommand),
    };
    let mut next = || tokens.next().ok_or(ProtocolError::MissingArgument);
    let command = match letter {
        b'I' => Command::Identify,
        b'E' => Command::EmergencyStop,
        b'M' => Command::Move {
            axis: parse_axis(next()?)?,
            speed_steps_per_s: parse_speed(next()?)?,
            steps: parse_steps(next()?)?,
        },
        b'J' => Command::Jog {
            axis: parse_axis(next()?)?,
            speed_steps_per_s: parse_speed(next()?)?,
            direction: parse_direction(next()?)?,
        },
        b'S' => Command::Stop(parse_target(next()?)?),
        b'R' => Command::Run(parse_target(next()?)?),
        b'P' => Command::SetPosition {
            axis: parse_axis(next()?)?,
            position: parse_position(next()?)?,
        },
        b'G' => {
            let speed = parse_speed(next()?)?;
            let mut steps = [0; GROUP_AXES_MAX];
            steps[0] = parse_group_steps(next()?)?;
            let mut axes = 1;
            for token in tokens.by_ref() {
                if axes == GROUP_AXES_MAX {
                    return Err(ProtocolError::ExtraArgument);
                }
                steps[axes] = parse_group_steps(token)?;
                axes += 1;
            }
            let group =
                GroupMove::new(speed, &steps[..axes]).ok_or(ProtocolError::StepsOutOfRange)?;
            Command::GroupMove(group)
        }
        b'H' => {
            let axis = parse_axis(next()?)?;
            let (switch_pin, active_level) = (parse_pin(next()?)?, parse_level(next()?)?);
            let direction = parse_direction(next()?)?;
            let (seek_speed, latch_speed) = (parse_speed(next()?)?, parse_speed(next()?)?);
            let (backoff_steps, max_travel) = (parse_count(next()?)?, parse_count(next()?)?);
            Command::Home {
                axis,
                config: HomeConfig {
                    switch_pin,
                    active_level,
                    direction,
                    seek_speed,
                    latch_speed,
                    backoff_steps,
                    max_travel,
                    set_position: parse_position(next()?)?,
                },
            }
        }
        b'W' => {
            let axis = parse_axis(next()?)?;
            let limits = match next()? {
                b"-" => None,
                min => Some((parse_position(min)?, parse_position(next()?)?)),
            };
            Command::SoftLimits { axis, limits }
        }
        b'K' => Command::LimitPins {
            axis: parse_axis(next()?)?,
            min: parse_limit_pin(next()?)?,
            max: parse_limit_pin(next()?)?,
        },
        b'C' => Command::ClearLimitFault(parse_axis(next()?)?),
        b'L' => Command::Limits(parse_axis(next()?)?),
        _ => return Err(ProtocolError::UnknownCommand),
    };
    if tokens.next().is_some() {
        return Err(ProtocolError::ExtraArgument);
    }
    Ok(command)
}

impl Command {
    /// Writes the line with its `*HH` checksum (no line end): what a host
    /// sends when it wants line noise caught.
    pub fn write_checked<W: fmt::Write + ?Sized>(&self, out: &mut W) -> fmt::Result {
        let mut xor = XorWriter { out, xor: 0 };
        fmt::write(&mut xor, format_args!("{self}"))?;
        let xor = xor.xor;
        write!(out, "*{xor:02X}")
    }
}

/// The canonical line (no line end): `M 0 20000 -500`, `J 1 800 +`, `S *`.
impl fmt::Display for Command {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Command::Identify => f.write_str("I"),
            Command::EmergencyStop => f.write_str("E"),
            Command::Move {
                axis,
                speed_steps_per_s,
                steps,
            } => write!(f, "M {axis} {speed_steps_per_s} {steps}"),
            Command::Jog {
                axis,
                speed_steps_per_s,
                direction,
            } => {
                let sign = match direction {
                    Direction::Forward => '+',
                    Direction::Reverse => '-',
                };
                write!(f, "J {axis} {speed_steps_per_s} {sign}")
            }
            Command::Stop(target) => write!(f, "S {target}"),
            Command::Run(target) => write!(f, "R {target}"),
            Command::SetPosition { axis, position } => write!(f, "P {axis} {position}"),
            Command::GroupMove(group) => {
                write!(f, "G {}", group.speed_steps_per_s)?;
                group
                    .steps()
                    .iter()
                    .try_for_each(|steps| write!(f, " {steps}"))
            }
            Command::Home { axis, config } => {
                let sign = match config.direction {
                    Direction::Forward => '+',
                    Direction::Reverse => '-',
                };
                write!(
                    f,
                    "H {axis} {} {} {sign} {} {} {} {} {}",
                    config.switch_pin,
                    u8::from(config.active_level),
                    config.seek_speed,
                    config.latch_speed,
                    config.backoff_steps,
                    config.max_travel,
                    config.set_position
                )
            }
            Command::SoftLimits { axis, limits } => match limits {
                Some((min, max)) => write!(f, "W {axis} {min} {max}"),
                None => write!(f, "W {axis} -"),
            },
            Command::LimitPins { axis, min, max } => {
                write!(f, "K {axis} ")?;
                write_limit_pin(f, min)?;
                f.write_str(" ")?;
                write_limit_pin(f, max)
            }
            Command::ClearLimitFault(axis) => write!(f, "C {axis}"),
            Command::Limits(axis) => write!(f, "L {axis}"),
        }
    }
}

/// `<pin>/<0|1>` or `-`.
pub(crate) fn write_limit_pin<W: fmt::Write + ?Sized>(
    f: &mut W,
    pin: Option<(u8, bool)>,
) -> fmt::Result {
    match pin {
        Some((pin, level)) => write!(f, "{pin}/{}", u8::from(level)),
        None => f.write_str("-"),
    }
}

/// `*` or the axis number.
impl fmt::Display for Target {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Target::All => f.write_str("*"),
            Target::Axis(axis) => write!(f, "{axis}"),
        }
    }
}

/// Passes text through and XORs its bytes.
struct XorWriter<'w, W: fmt::Write + ?Sized> {
    out: &'w mut W,
    xor: u8,
}

impl<W: fmt::Write + ?Sized> fmt::Write for XorWriter<'_, W> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        self.xor ^= checksum(s.as_bytes());
        self.out.write_str(s)
    }
}

fn trim_trailing_spaces(mut line: &[u8]) -> &[u8] {
    while let [rest @ .., b' '] = line {
        line = rest;
    }
    line
}

/// The body and the stated checksum, when the line ends with `*HH`.
fn split_checksum(line: &[u8]) -> Option<(&[u8], u8)> {
    match line {
        [body @ .., b'*', high, low] => Some((body, hex_digit(*high)? << 4 | hex_digit(*low)?)),
        _ => None,
    }
}

fn hex_digit(byte: u8) -> Option<u8> {
    match byte {
        b'0'..=b'9' => Some(byte - b'0'),
        b'a'..=b'f' => Some(byte - b'a' + 10),
        b'A'..=b'F' => Some(byte - b'A' + 10),
        _ => None,
    }
}

/// A decimal number with an optional sign: (negative, magnitude). The
/// magnitude saturates at `u64::MAX`, which is out of every range used here.
pub(crate) fn parse_signed(token: &[u8]) -> Option<(bool, u64)> {
    let (negative, digits) = match token {
        [b'-', digits @ ..] => (true, digits),
        [b'+', digits @ ..] => (false, digits),
        digits => (false, digits),
    };
    if digits.is_empty() || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    let magnitude = digits.iter().fold(0u64, |acc, &digit| {
        acc.saturating_mul(10)
            .saturating_add(u64::from(digit - b'0'))
    });
    Some((negative, magnitude))
}

/// An axis number: unsigned decimal. Too large a number is a valid number
/// of an axis that does not exist (`usize::MAX`), not a bad argument.
fn parse_axis(token: &[u8]) -> Result<usize, ProtocolError> {
    match parse_signed(token) {
        Some((false, magnitude)) if token.first() != Some(&b'+') => {
            Ok(usize::try_from(magnitude).unwrap_or(usize::MAX))
        }
        _ => Err(ProtocolError::BadNumber),
    }
}

/// A speed: 1 to `u32::MAX` steps/s; a number outside is out of range.
fn parse_speed(token: &[u8]) -> Result<u32, ProtocolError> {
    match parse_signed(token) {
        None => Err(ProtocolError::BadNumber),
        Some((true, _)) | Some((false, 0)) => Err(ProtocolError::SpeedOutOfRange),
        Some((false, magnitude)) => {
            u32::try_from(magnitude).map_err(|_| ProtocolError::SpeedOutOfRange)
        }
    }
}

/// Steps: signed, non-zero, magnitude at most `i32::MAX`.
fn parse_steps(token: &[u8]) -> Result<i32, ProtocolError> {
    let (negative, magnitude) = parse_signed(token).ok_or(ProtocolError::BadNumber)?;
    let magnitude = i32::try_from(magnitude).map_err(|_| ProtocolError::StepsOutOfRange)?;
    match (negative, magnitude) {
        (_, 0) => Err(ProtocolError::StepsOutOfRange),
        (true, magnitude) => Ok(-magnitude),
        (false, magnitude) => Ok(magnitude),
    }
}

/// A group member's steps: signed, 0 allowed, magnitude at most `i32::MAX`.
fn parse_group_steps(token: &[u8]) -> Result<i32, ProtocolError> {
    let (negative, magnitude) = parse_signed(token).ok_or(ProtocolError::BadNumber)?;
    let magnitude = i32::try_from(magnitude).map_err(|_| ProtocolError::StepsOutOfRange)?;
    Ok(if negative { -magnitude } else { magnitude })
}

/// A position: any `i64`.
fn parse_position(token: &[u8]) -> Result<i64, ProtocolError> {
    let (negative, magnitude) = parse_signed(token).ok_or(ProtocolError::BadNumber)?;
    if negative {
        0i64.checked_sub_unsigned(magnitude)
    } else {
        i64::try_from(magnitude).ok()
    }
    .ok_or(ProtocolError::BadNumber)
}

/// A pin: 0 to 255 on the line. Which pins an axis can use is the axis's
/// to say (a refusal such as `bad argument: limit pins are 0 to 63`), so
/// that the board answers with its axis's own error.
fn parse_pin(token: &[u8]) -> Result<u8, ProtocolError> {
    match parse_signed(token) {
        Some((false, pin)) if token.first() != Some(&b'+') => {
            u8::try_from(pin).map_err(|_| ProtocolError::BadPin)
        }
        _ => Err(ProtocolError::BadPin),
    }
}

/// A level: `0` or `1`.
fn parse_level(token: &[u8]) -> Result<bool, ProtocolError> {
    match token {
        b"0" => Ok(false),
        b"1" => Ok(true),
        _ => Err(ProtocolError::BadPin),
    }
}

/// `<pin>/<0|1>` or `-`.
pub(crate) fn parse_limit_pin(token: &[u8]) -> Result<Option<(u8, bool)>, ProtocolError> {
    if token == b"-" {
        return Ok(None);
    }
    let slash = token
        .iter()
        .position(|&byte| byte == b'/')
        .ok_or(ProtocolError::BadPin)?;
    let (pin, level) = (&token[..slash], &token[slash + 1..]);
    Ok(Some((parse_pin(pin)?, parse_level(level)?)))
}

/// A count of steps: 0 to 4,294,967,295 on the line. Which counts homing
/// can use is the axis's to say (`bad argument: max_travel must be 1 to
/// 2^31 - 1`, ...), so that the board answers with its axis's own error.
fn parse_count(token: &[u8]) -> Result<u32, ProtocolError> {
    match parse_signed(token) {
        None | Some((true, _)) => Err(ProtocolError::BadNumber),
        Some((false, count)) => u32::try_from(count).map_err(|_| ProtocolError::StepsOutOfRange),
    }
}

fn parse_direction(token: &[u8]) -> Result<Direction, ProtocolError> {
    match token {
        b"+" => Ok(Direction::Forward),
        b"-" => Ok(Direction::Reverse),
        _ => Err(ProtocolError::BadDirection),
    }
}

fn parse_target(token: &[u8]) -> Result<Target, ProtocolError> {
    match token {
        b"*" => Ok(Target::All),
        axis => parse_axis(axis).map(Target::Axis),
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::string::String;

    use super::*;
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
                .prop_map(|(speed, steps)| Command::GroupMove(
                    GroupMove::new(speed, &steps).unwrap()
                )),
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
}

//! Parsing a command line (board side): checksum, bytes, command letter,
//! then the arguments left to right ([`parse_line_on`]).

use cogstep_motion::axis::{Direction, HomeConfig};

use super::{checksum, Command, GroupMove, Target, GROUP_AXES_MAX};
use crate::reply::ProtocolError;

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

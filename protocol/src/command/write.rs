//! Writing a command line back (host side): the canonical text, and
//! [`Command::write_checked`] with its `*HH` checksum.

use core::fmt;

use cogstep_motion::axis::Direction;

use super::{checksum, Command, Target};

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

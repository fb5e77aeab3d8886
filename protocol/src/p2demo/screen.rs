//! A display, formatted: its labels, its 6-character number fields, and
//! [`DemoScreen::write_display`], byte for byte as `Showvalues()` prints it.

use core::fmt;

use cogstep_motion::axis::Mode;

use super::{CLEAR_EOL, CR, HOME, TITLE};

/// The labels, right-aligned as the reference prints them, in display order.
pub(super) const POSITION_LABEL: &str = "Current Position: ";
pub(super) const MODE_LABEL: &str = "            Mode: ";
pub(super) const OFFSET_LABEL: &str = "          Offset: ";
pub(super) const ACCEL_LABEL: &str = "     Accel steps: ";
pub(super) const SLEW_LABEL: &str = "  Steps at speed: ";
pub(super) const VELOCITY_LABEL: &str = "    Max Velocity: ";
pub(super) const ELAPSED_LABEL: &str = "Elapsed time (msec): ";

/// Width of a number's field.
const NUMBER_WIDTH: usize = 6;

/// The values one display shows: the board's longs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DemoScreen {
    /// `Current Position`, steps.
    pub position: i32,
    /// `Mode`: the reference's 6 mode bits (bits 0–5; higher bits are not shown).
    pub mode_bits: u8,
    /// `Offset`, degrees (0 before the first move).
    pub offset_deg: i32,
    /// `Accel steps`, as `move()` planned them.
    pub accel_steps: i32,
    /// `Steps at speed` (slew steps), as `move()` planned them.
    pub slew_steps: i32,
    /// `Max Velocity`, steps/s, as the cog last wrote it.
    pub max_velocity_steps_per_s: i32,
    /// `Elapsed time (msec)` of the current or last move.
    pub elapsed_ms: i32,
}

/// What `jdpdec(value, 0, 6, " ")` prints: the decimal text, right-aligned
/// in 6 characters, or its rightmost 6 characters when it is wider.
pub fn number_field(value: i32) -> heapless::String<NUMBER_WIDTH> {
    let mut digits: heapless::String<11> = heapless::String::new();
    // An i32 has at most 11 characters: this cannot fail.
    let _ = fmt::write(&mut digits, format_args!("{value}"));
    let mut field = heapless::String::new();
    let text = digits.as_str();
    if text.len() < NUMBER_WIDTH {
        for _ in text.len()..NUMBER_WIDTH {
            let _ = field.push(' ');
        }
        let _ = field.push_str(text);
    } else {
        let _ = field.push_str(&text[text.len() - NUMBER_WIDTH..]);
    }
    field
}

impl DemoScreen {
    /// The screen as a host reads it back: each number through its
    /// 6-character field (a wider number loses its leading characters).
    pub fn as_shown(&self) -> DemoScreen {
        let shown = |value: i32| parse_number(number_field(value).as_bytes()).unwrap_or(0);
        DemoScreen {
            position: shown(self.position),
            mode_bits: self.mode_bits & 0b11_1111,
            offset_deg: shown(self.offset_deg),
            accel_steps: shown(self.accel_steps),
            slew_steps: shown(self.slew_steps),
            max_velocity_steps_per_s: shown(self.max_velocity_steps_per_s),
            elapsed_ms: shown(self.elapsed_ms),
        }
    }

    /// Writes one display (`Showvalues()`), from the home byte to the
    /// elapsed time (no line end after it: the prompt or the next display
    /// follows).
    pub fn write_display<W: fmt::Write + ?Sized>(&self, out: &mut W) -> fmt::Result {
        let cr = char::from(CR);
        write!(out, "{}{TITLE}{cr}", char::from(HOME))?;
        write!(out, "{cr}{POSITION_LABEL}{}", number_field(self.position))?;
        write!(out, "{cr}{MODE_LABEL}")?;
        for digit in Mode(u32::from(self.mode_bits)).binary() {
            out.write_char(char::from(digit))?;
        }
        write!(out, "{cr}{OFFSET_LABEL}{}", number_field(self.offset_deg))?;
        write!(out, "{cr}{ACCEL_LABEL}{}", number_field(self.accel_steps))?;
        write!(out, "{cr}{SLEW_LABEL}{}", number_field(self.slew_steps))?;
        write!(
            out,
            "{cr}{VELOCITY_LABEL}{}",
            number_field(self.max_velocity_steps_per_s)
        )?;
        write!(
            out,
            "{cr}{}{ELAPSED_LABEL}{}",
            char::from(CLEAR_EOL),
            number_field(self.elapsed_ms)
        )
    }
}

/// A number's field: optional `-`, then digits (at most 6 characters
/// once trimmed, as the board prints them).
pub(super) fn parse_number(text: &[u8]) -> Option<i32> {
    let text = trim(text);
    if text.len() > NUMBER_WIDTH {
        return None;
    }
    let (negative, magnitude) = crate::command::parse_signed(text)?;
    if text.first() == Some(&b'+') {
        return None;
    }
    let magnitude = i32::try_from(magnitude).ok()?;
    Some(if negative { -magnitude } else { magnitude })
}

pub(super) fn trim(mut bytes: &[u8]) -> &[u8] {
    while let [b' ' | b'\t' | CLEAR_EOL, rest @ ..] = bytes {
        bytes = rest;
    }
    while let [rest @ .., b' ' | b'\t' | CLEAR_EOL] = bytes {
        bytes = rest;
    }
    bytes
}

//! Reading a board's screens back: [`ScreenParser`] turns the byte stream
//! into value lines, whole displays and prompts.

use super::screen::{
    parse_number, trim, ACCEL_LABEL, ELAPSED_LABEL, MODE_LABEL, OFFSET_LABEL, POSITION_LABEL,
    SLEW_LABEL, VELOCITY_LABEL,
};
use super::{DemoScreen, CLEAR, CR, HOME, SPEED_PROMPT, STEPS_PROMPT};

/// One value line of a display, as read back (each number through its
/// 6-character field).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DemoField {
    /// `Current Position`.
    Position(i32),
    /// `Mode`, the 6 bits.
    Mode(u8),
    /// `Offset`.
    Offset(i32),
    /// `Accel steps`.
    AccelSteps(i32),
    /// `Steps at speed`.
    SlewSteps(i32),
    /// `Max Velocity`.
    MaxVelocity(i32),
    /// `Elapsed time (msec)`.
    ElapsedMs(i32),
}

/// Which prompt the board shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DemoPrompt {
    /// `Enter steps: `
    Steps,
    /// `Enter speed: `
    Speed,
}

/// What a byte of a demo screen stream completed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ScreenEvent {
    /// A value line, read on its own (a display that is not complete still
    /// yields its fields).
    Field(DemoField),
    /// A whole display: every value line since the last home or clear byte.
    /// It takes the place of the [`DemoField::ElapsedMs`] field that ends it.
    Display(DemoScreen),
    /// The board prompts and now reads a line.
    Prompt(DemoPrompt),
}

/// The longest screen line the parser keeps; longer lines are skipped.
const SCREEN_LINE_MAX: usize = 48;

/// Bits of [`ScreenParser::seen`], one per field.
const ALL_FIELDS_BUT_ELAPSED: u8 = 0b11_1111;

/// Reads demo screens back from a byte stream, one byte at a time.
///
/// Robust to partial screens: every value line is read on its own, lines
/// it does not know (or that got garbled) are skipped, and a whole
/// [`ScreenEvent::Display`] is only reported when all its lines arrived
/// since the last home or clear byte. Never panics, never allocates.
#[derive(Clone, Debug, Default)]
pub struct ScreenParser {
    line: heapless::Vec<u8, SCREEN_LINE_MAX>,
    /// The current line outgrew the buffer; skip it.
    overflow: bool,
    /// Fields of the current display seen so far (bit i: field i in display order).
    seen: u8,
    partial: DemoScreen,
    position: Option<i32>,
    mode_bits: Option<u8>,
}

impl ScreenParser {
    /// A parser that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one byte; returns what it completes, if anything (at most one
    /// event per byte).
    pub fn push(&mut self, byte: u8) -> Option<ScreenEvent> {
        match byte {
            CR | b'\n' | HOME | CLEAR => {
                let event = self.end_line();
                if byte == HOME || byte == CLEAR {
                    self.seen = 0;
                }
                event
            }
            _ => {
                if self.overflow || self.line.push(byte).is_err() {
                    self.overflow = true;
                    return None;
                }
                let prompt = match self.line.as_slice() {
                    line if line == STEPS_PROMPT.as_bytes() => DemoPrompt::Steps,
                    line if line == SPEED_PROMPT.as_bytes() => DemoPrompt::Speed,
                    _ => return None,
                };
                Some(ScreenEvent::Prompt(prompt))
            }
        }
    }

    /// Takes many bytes; returns the last event they completed.
    pub fn push_all(&mut self, bytes: &[u8]) -> Option<ScreenEvent> {
        bytes
            .iter()
            .fold(None, |last, &byte| self.push(byte).or(last))
    }

    /// The last position read (its 6-character field), from a whole
    /// display or a lone line.
    pub fn position(&self) -> Option<i32> {
        self.position
    }

    /// The last mode bits read.
    pub fn mode_bits(&self) -> Option<u8> {
        self.mode_bits
    }

    fn end_line(&mut self) -> Option<ScreenEvent> {
        let overflow = core::mem::take(&mut self.overflow);
        let field = if overflow {
            None
        } else {
            parse_field(self.line.as_slice())
        };
        self.line.clear();
        let field = field?;
        let (bit, partial) = (field_bit(field), &mut self.partial);
        match field {
            DemoField::Position(position) => {
                partial.position = position;
                self.position = Some(position);
            }
            DemoField::Mode(bits) => {
                partial.mode_bits = bits;
                self.mode_bits = Some(bits);
            }
            DemoField::Offset(value) => partial.offset_deg = value,
            DemoField::AccelSteps(value) => partial.accel_steps = value,
            DemoField::SlewSteps(value) => partial.slew_steps = value,
            DemoField::MaxVelocity(value) => partial.max_velocity_steps_per_s = value,
            DemoField::ElapsedMs(value) => {
                partial.elapsed_ms = value;
                let complete = self.seen == ALL_FIELDS_BUT_ELAPSED;
                self.seen = 0;
                if complete {
                    return Some(ScreenEvent::Display(self.partial));
                }
                return Some(ScreenEvent::Field(field));
            }
        }
        self.seen |= bit;
        Some(ScreenEvent::Field(field))
    }
}

/// Makes a field from its value.
type NumberField = fn(i32) -> DemoField;

fn field_bit(field: DemoField) -> u8 {
    match field {
        DemoField::Position(_) => 1 << 0,
        DemoField::Mode(_) => 1 << 1,
        DemoField::Offset(_) => 1 << 2,
        DemoField::AccelSteps(_) => 1 << 3,
        DemoField::SlewSteps(_) => 1 << 4,
        DemoField::MaxVelocity(_) => 1 << 5,
        DemoField::ElapsedMs(_) => 1 << 6,
    }
}

/// Reads one value line (label and number; spaces, tabs and the
/// clear-to-end-of-line byte around them do not matter).
fn parse_field(line: &[u8]) -> Option<DemoField> {
    let line = trim(line);
    if let Some(rest) = line.strip_prefix(MODE_LABEL.trim().as_bytes()) {
        let digits = trim(rest);
        if digits.len() != 6 || !digits.iter().all(|&b| b == b'0' || b == b'1') {
            return None;
        }
        let bits = digits
            .iter()
            .fold(0u8, |acc, &digit| acc << 1 | (digit - b'0'));
        return Some(DemoField::Mode(bits));
    }
    let fields: [(&str, NumberField); 6] = [
        (POSITION_LABEL, DemoField::Position),
        (OFFSET_LABEL, DemoField::Offset),
        (ACCEL_LABEL, DemoField::AccelSteps),
        (SLEW_LABEL, DemoField::SlewSteps),
        (VELOCITY_LABEL, DemoField::MaxVelocity),
        (ELAPSED_LABEL, DemoField::ElapsedMs),
    ];
    fields.into_iter().find_map(|(label, field)| {
        let rest = line.strip_prefix(label.trim().as_bytes())?;
        parse_number(rest).map(field)
    })
}

//! The P2 reference driver's demo dialect: its screens and its prompts.
//!
//! The reference demo talks to the Parallax Serial Terminal, where byte 1
//! moves the cursor home, byte 16 clears the screen, byte 13 (CR) starts a
//! new line and byte 9 is a tab. After start it waits for any key, clears
//! the screen and shows one display:
//!
//! ```text
//! ␁Stepper Demo␍
//! ␍Current Position:   1200
//! ␍            Mode: 001011
//! ␍          Offset:     40
//! ␍     Accel steps:   2002
//! ␍  Steps at speed:  15996
//! ␍    Max Velocity:  20000
//! ␍␉Elapsed time (msec):   1234
//! ```
//!
//! Numbers are right-aligned in 6 characters (wider numbers are written in
//! full); the mode is its 6 reference bits, bit 5 first. It then prompts
//! CR CR `Enter steps: `, reads a line ended by CR, prompts CR
//! `Enter speed: `, reads another (a negative speed counts as positive, 0
//! as 1), starts the move, clears the screen and shows displays while the
//! move runs (reading nothing meanwhile), then clears, shows the final
//! display and prompts again.
//!
//! Here: [`DemoScreen::write_display`] formats a display, [`ScreenParser`]
//! reads displays and prompts back from a byte stream (a host drives a
//! board that speaks this dialect with it), and [`DemoSession`] is the
//! board's prompt/answer flow over a [`DemoMotor`].

use core::fmt;

use crate::axis::{AxisError, Mode};

/// Byte 1: cursor home. Every display starts with it.
pub const HOME: u8 = 1;
/// Byte 9: tab (before `Elapsed time (msec): `).
pub const TAB: u8 = 9;
/// Byte 13: carriage return, the terminal's new line.
pub const CR: u8 = 13;
/// Byte 16: clear screen.
pub const CLEAR: u8 = 16;

/// The display's first line.
pub const TITLE: &str = "Stepper Demo";
/// The prompt for the steps of the next move.
pub const STEPS_PROMPT: &str = "Enter steps: ";
/// The prompt for its speed.
pub const SPEED_PROMPT: &str = "Enter speed: ";

/// The labels, right-aligned as the reference prints them, in display order.
const POSITION_LABEL: &str = "Current Position: ";
const MODE_LABEL: &str = "            Mode: ";
const OFFSET_LABEL: &str = "          Offset: ";
const ACCEL_LABEL: &str = "     Accel steps: ";
const SLEW_LABEL: &str = "  Steps at speed: ";
const VELOCITY_LABEL: &str = "    Max Velocity: ";
const ELAPSED_LABEL: &str = "Elapsed time (msec): ";

/// Width of a number's field.
const NUMBER_WIDTH: usize = 6;

/// The values one display shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DemoScreen {
    /// `Current Position`, steps.
    pub position: i64,
    /// `Mode`: the reference's 6 mode bits (bits 0–5; higher bits are not shown).
    pub mode_bits: u8,
    /// `Offset`, degrees.
    pub offset_deg: u32,
    /// `Accel steps`.
    pub accel_steps: u32,
    /// `Steps at speed` (slew steps).
    pub slew_steps: u32,
    /// `Max Velocity`, steps/s.
    pub max_velocity_steps_per_s: u32,
    /// `Elapsed time (msec)` of the current or last move.
    pub elapsed_ms: u32,
}

impl DemoScreen {
    /// Writes one display, from the home byte to the elapsed time (no line
    /// end after it: the prompt or the next display follows).
    pub fn write_display<W: fmt::Write + ?Sized>(&self, out: &mut W) -> fmt::Result {
        let cr = char::from(CR);
        write!(out, "{}{TITLE}{cr}", char::from(HOME))?;
        write!(out, "{cr}{POSITION_LABEL}{:>NUMBER_WIDTH$}", self.position)?;
        write!(out, "{cr}{MODE_LABEL}")?;
        for digit in Mode(u32::from(self.mode_bits)).binary() {
            out.write_char(char::from(digit))?;
        }
        write!(out, "{cr}{OFFSET_LABEL}{:>NUMBER_WIDTH$}", self.offset_deg)?;
        write!(out, "{cr}{ACCEL_LABEL}{:>NUMBER_WIDTH$}", self.accel_steps)?;
        write!(out, "{cr}{SLEW_LABEL}{:>NUMBER_WIDTH$}", self.slew_steps)?;
        write!(
            out,
            "{cr}{VELOCITY_LABEL}{:>NUMBER_WIDTH$}",
            self.max_velocity_steps_per_s
        )?;
        write!(
            out,
            "{cr}{}{ELAPSED_LABEL}{:>NUMBER_WIDTH$}",
            char::from(TAB),
            self.elapsed_ms
        )
    }
}

/// One value line of a display.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DemoField {
    /// `Current Position`.
    Position(i64),
    /// `Mode`, the 6 bits.
    Mode(u8),
    /// `Offset`.
    Offset(u32),
    /// `Accel steps`.
    AccelSteps(u32),
    /// `Steps at speed`.
    SlewSteps(u32),
    /// `Max Velocity`.
    MaxVelocity(u32),
    /// `Elapsed time (msec)`.
    ElapsedMs(u32),
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
    position: Option<i64>,
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

    /// The last position read, from a whole display or a lone line.
    pub fn position(&self) -> Option<i64> {
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

/// Makes a field from its unsigned value.
type UnsignedField = fn(u32) -> DemoField;

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

/// Reads one value line (label and number; spaces and tabs around them
/// do not matter).
fn parse_field(line: &[u8]) -> Option<DemoField> {
    let line = trim(line);
    let unsigned = |label: &str| {
        let rest = line.strip_prefix(label.trim().as_bytes())?;
        let (negative, magnitude) = super::command::parse_signed(trim(rest))?;
        if negative {
            return None;
        }
        u32::try_from(magnitude).ok()
    };
    if let Some(rest) = line.strip_prefix(POSITION_LABEL.trim().as_bytes()) {
        let (negative, magnitude) = super::command::parse_signed(trim(rest))?;
        let position = if negative {
            0i64.checked_sub_unsigned(magnitude)?
        } else {
            i64::try_from(magnitude).ok()?
        };
        return Some(DemoField::Position(position));
    }
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
    let fields: [(&str, UnsignedField); 5] = [
        (OFFSET_LABEL, DemoField::Offset),
        (ACCEL_LABEL, DemoField::AccelSteps),
        (SLEW_LABEL, DemoField::SlewSteps),
        (VELOCITY_LABEL, DemoField::MaxVelocity),
        (ELAPSED_LABEL, DemoField::ElapsedMs),
    ];
    fields
        .into_iter()
        .find_map(|(label, field)| unsigned(label).map(field))
}

fn trim(mut bytes: &[u8]) -> &[u8] {
    while let [b' ' | b'\t', rest @ ..] = bytes {
        bytes = rest;
    }
    while let [rest @ .., b' ' | b'\t'] = bytes {
        bytes = rest;
    }
    bytes
}

/// What a board running the demo offers: one motor, started and watched.
pub trait DemoMotor {
    /// Starts a move (`speed` ≥ 1 steps/s, `steps` ≠ 0). A refused move
    /// changes nothing.
    fn start_move(&mut self, speed: u32, steps: i32) -> Result<(), AxisError>;
    /// Whether the move is still running: true from a successful
    /// [`start_move`](DemoMotor::start_move) until it has ended.
    fn is_moving(&mut self) -> bool;
    /// The values to show now.
    fn screen(&mut self) -> DemoScreen;
}

/// Where the demo's prompt/answer flow is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DemoPhase {
    /// Waiting for any key after start.
    #[default]
    WaitingForKey,
    /// `Enter steps: ` shown, reading a line.
    EnterSteps,
    /// `Enter speed: ` shown, reading a line.
    EnterSpeed,
    /// A move runs; input is ignored.
    Running,
}

/// The longest answer kept; further characters are ignored.
const ANSWER_MAX: usize = 16;

/// The board side of the demo dialect: feed it received bytes, and call
/// [`poll`](DemoSession::poll) at the display rate while a move runs.
///
/// Answers are not echoed (the reference does not; turn on the
/// terminal's local echo). Backspace (8 or 127) deletes the last
/// character; LF is ignored; an answer that is not a number, or steps of
/// 0, prompt again; the steps are clamped to ±2,147,483,647, the speed to
/// 1..=4,294,967,295 after taking it as positive.
#[derive(Clone, Debug, Default)]
pub struct DemoSession {
    phase: DemoPhase,
    answer: heapless::Vec<u8, ANSWER_MAX>,
    steps: i32,
}

impl DemoSession {
    /// A session waiting for the first key.
    pub fn new() -> Self {
        Self::default()
    }

    /// Where the flow is.
    pub fn phase(&self) -> DemoPhase {
        self.phase
    }

    /// Takes one received byte and writes what the board shows in answer.
    pub fn feed<M, W>(&mut self, byte: u8, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        match self.phase {
            DemoPhase::WaitingForKey => self.show_and_prompt(motor, out),
            DemoPhase::Running => Ok(()),
            DemoPhase::EnterSteps | DemoPhase::EnterSpeed => match byte {
                CR => self.answer(motor, out),
                8 | 127 => {
                    self.answer.pop();
                    Ok(())
                }
                b' '..=b'~' => {
                    // A full answer ignores further characters.
                    let _ = self.answer.push(byte);
                    Ok(())
                }
                _ => Ok(()),
            },
        }
    }

    /// While a move runs: one display, or, once it has ended, clear, the
    /// final display and the steps prompt. Does nothing in other phases.
    pub fn poll<M, W>(&mut self, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        if self.phase != DemoPhase::Running {
            return Ok(());
        }
        if motor.is_moving() {
            motor.screen().write_display(out)
        } else {
            self.show_and_prompt(motor, out)
        }
    }

    /// Clear, display, steps prompt.
    fn show_and_prompt<M, W>(&mut self, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        out.write_char(char::from(CLEAR))?;
        motor.screen().write_display(out)?;
        out.write_char(char::from(CR))?;
        self.prompt(DemoPrompt::Steps, out)
    }

    fn prompt<W: fmt::Write + ?Sized>(&mut self, prompt: DemoPrompt, out: &mut W) -> fmt::Result {
        self.answer.clear();
        let (phase, text) = match prompt {
            DemoPrompt::Steps => (DemoPhase::EnterSteps, STEPS_PROMPT),
            DemoPrompt::Speed => (DemoPhase::EnterSpeed, SPEED_PROMPT),
        };
        self.phase = phase;
        write!(out, "{}{text}", char::from(CR))
    }

    fn answer<M, W>(&mut self, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        let number = super::command::parse_signed(trim(self.answer.as_slice()));
        match self.phase {
            DemoPhase::EnterSteps => match number {
                Some((_, 0)) | None => self.prompt(DemoPrompt::Steps, out),
                Some((negative, magnitude)) => {
                    let magnitude = i32::try_from(magnitude).unwrap_or(i32::MAX);
                    self.steps = if negative { -magnitude } else { magnitude };
                    self.prompt(DemoPrompt::Speed, out)
                }
            },
            DemoPhase::EnterSpeed => match number {
                None => self.prompt(DemoPrompt::Speed, out),
                Some((_, magnitude)) => {
                    let speed = u32::try_from(magnitude).unwrap_or(u32::MAX).max(1);
                    match motor.start_move(speed, self.steps) {
                        Ok(()) => {
                            self.answer.clear();
                            self.phase = DemoPhase::Running;
                            out.write_char(char::from(CLEAR))
                        }
                        Err(error) => {
                            write!(out, "{}Refused: ", char::from(CR))?;
                            super::reply::write_display_printable(
                                out,
                                &error,
                                super::reply::BACKEND_TEXT_MAX,
                            )?;
                            self.prompt(DemoPrompt::Steps, out)
                        }
                    }
                }
            },
            DemoPhase::WaitingForKey | DemoPhase::Running => Ok(()),
        }
    }
}

#[cfg(test)]
#[path = "p2demo_tests.rs"]
mod tests;

//! The P2 reference driver's demo dialect: its screens and its prompts,
//! byte for byte.
//!
//! The stock demo (`step_driver2_demo.spin2` in the Step_driver2 library)
//! prints through `jm_serial` and `jm_nstr` to the Parallax Serial
//! Terminal, where byte 1 moves the cursor home, byte 16 clears the
//! screen, byte 13 (CR) starts a new line and byte 11 clears to the end of
//! the line. From power-up it waits for any key, clears the screen,
//! presets the position to 1000 and shows one display:
//!
//! ```text
//! ␁Stepper Demo␍
//! ␍Current Position:   1000
//! ␍            Mode: 000000
//! ␍          Offset:      0
//! ␍     Accel steps:      0
//! ␍  Steps at speed:      0
//! ␍    Max Velocity:      0
//! ␍␋Elapsed time (msec):      0
//! ```
//!
//! Every number is the board's signed 32-bit long, printed by
//! `jdpdec(value, 0, 6, " ")`: right-aligned in 6 characters, and a wider
//! number keeps only its rightmost 6 characters (`-1234567` shows
//! `234567`). The mode is its low 6 bits, bit 5 first. `Offset`,
//! `Accel steps` and `Steps at speed` are what the driver's Spin `move()`
//! planned (so the offset shows 0 until the first move), `Max Velocity` is
//! what the cog wrote when it last started to decelerate.
//!
//! It then prompts CR CR `Enter steps: `, reads an answer, prompts CR
//! `Enter speed: `, reads another (its absolute value; 0 means 1), calls
//! `move(speed, steps)`, clears the screen and shows displays while the
//! mode's bit 0 says the motor moves (reading nothing meanwhile), then
//! clears, shows the final display and prompts again. It never refuses
//! anything and never echoes.
//!
//! An answer (`StrInMax` and `StrToBase`) ends at CR, at Backspace (which
//! also drops the last character), or by itself at 99 characters; its
//! value is made of the characters that map to 0–9 (the digits, and
//! also the control bytes 16–25), read up to the first NUL byte, in
//! 32-bit wrapping arithmetic, negated when the answer's first character
//! is `-`: `1a2` is 12, `12 34` is 1234, ` -5` is 5, `--3` is −3, and an
//! empty answer, `abc` or `-0` are 0. The serial input is the P2's
//! receive smart pin, which holds one byte: while the program prints (or
//! runs a move) the bytes that arrive overwrite each other, and the last
//! one is read when it reads again.
//!
//! Here: [`DemoScreen::write_display`] formats a display, [`ScreenParser`]
//! reads displays and prompts back from a byte stream (a host drives a
//! board that speaks this dialect with it), [`DemoSession`] is the demo
//! program over a [`DemoMotor`], [`demo_move`] is the driver's `move()`
//! planning, and [`check_demo_move`] says which moves the reference
//! botches.

use core::fmt::{self, Write as _};

use cogstep_motion::axis::Mode;

pub mod cog;

/// Byte 1: cursor home. Every display starts with it.
pub const HOME: u8 = 1;
/// Byte 8: Backspace. It ends an answer, dropping its last character.
pub const BACKSPACE: u8 = 8;
/// Byte 11: clear to the end of the line (before `Elapsed time (msec): `;
/// the Spin source writes it as the decimal escape `\011`).
pub const CLEAR_EOL: u8 = 11;
/// Byte 13: carriage return, the terminal's new line; it ends an answer.
pub const CR: u8 = 13;
/// Byte 16: clear screen.
pub const CLEAR: u8 = 16;

/// The display's first line.
pub const TITLE: &str = "Stepper Demo";
/// The prompt for the steps of the next move.
pub const STEPS_PROMPT: &str = "Enter steps: ";
/// The prompt for its speed.
pub const SPEED_PROMPT: &str = "Enter speed: ";

/// The position the demo presets before its first display.
pub const PRESET_POSITION: i32 = 1000;
/// The longest answer: it ends by itself at this many characters
/// (`MAXSTR_LENGTH`).
pub const ANSWER_MAX: usize = 99;
/// The demo's terminal baud rate (`BR_TERM`); 8N1, so a byte takes 10 bits.
pub const DEMO_BAUD: u32 = 115_200;
/// One byte on the demo's serial line, ns (10 bits at [`DEMO_BAUD`]).
pub const BYTE_NS: u64 = 10 * 1_000_000_000 / DEMO_BAUD as u64;
/// The demo's system clock (`CLK_FREQ`), Hz.
pub const DEMO_CLKFREQ: u32 = 200_000_000;
/// The offset `move()` writes, degrees.
pub const DEMO_OFFSET_DEG: i32 = 40;

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

/// A number's field: optional `-`, then digits (at most 6 characters
/// once trimmed, as the board prints them).
fn parse_number(text: &[u8]) -> Option<i32> {
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

fn trim(mut bytes: &[u8]) -> &[u8] {
    while let [b' ' | b'\t' | CLEAR_EOL, rest @ ..] = bytes {
        bytes = rest;
    }
    while let [rest @ .., b' ' | b'\t' | CLEAR_EOL] = bytes {
        bytes = rest;
    }
    bytes
}

/// The longs the driver's Spin `move(sp, st)` leaves for the cog and the
/// screen, in the driver's own 32-bit arithmetic.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DemoPlan {
    /// The speed the cog gets (`spd`): the one asked, or `10·(asteps − 2)`
    /// for a move with no steps at speed (−10 for 2 steps, 0 for 4).
    pub speed: i32,
    /// The signed steps (`stm`); 0 is never taken by the cog.
    pub steps: i32,
    /// `asteps`: `sp/10 + 2`, at most `|st|/2`.
    pub accel_steps: i32,
    /// `ss`: `|st| − 2·asteps`.
    pub slew_steps: i32,
    /// `offset`: always 40.
    pub offset_deg: i32,
}

/// The driver's `move(sp, st)` planning, as its Spin code computes it
/// (signed longs, wrapping, division towards zero).
pub fn demo_move(speed: i32, steps: i32) -> DemoPlan {
    let mut accel_steps = (speed / 10).wrapping_add(2);
    let half = (steps / 2).wrapping_abs();
    if accel_steps > half {
        accel_steps = half;
    }
    let slew_steps = steps
        .wrapping_abs()
        .wrapping_sub(accel_steps.wrapping_mul(2));
    let speed = if slew_steps == 0 {
        accel_steps.wrapping_sub(2).wrapping_mul(10)
    } else {
        speed
    };
    DemoPlan {
        speed,
        steps,
        accel_steps,
        slew_steps,
        offset_deg: DEMO_OFFSET_DEG,
    }
}

/// The clocks the reference cog needs, from the end of a step pulse, to
/// compute the next ramp delay (`_getdelay`) and set its timer: four
/// CORDIC commands and a QDIV, each a hub-slot wait (up to 7 clocks) plus
/// the 55-clock pipeline, and about twenty 2-clock instructions. A delay
/// shorter than this sets a timer target already passed, and WAITCT2
/// then waits for the 32-bit counter to come round again (2^32 clocks,
/// 21.5 s at 200 MHz). An upper estimate: it makes the speed limit below
/// conservative.
pub const GETDELAY_TICKS: u32 = 5 * (7 + 55) + 20 * 2;

/// The highest speed the host gives a P2 demo board: above it the
/// shortest delay (`clkfreq / speed` at the top of the ramp) could be
/// shorter than [`GETDELAY_TICKS`] at the demo's 200 MHz.
pub const DEMO_SPEED_MAX: u32 = DEMO_CLKFREQ / GETDELAY_TICKS;

/// A move the reference driver botches; [`check_demo_move`] finds them.
/// The reasons come from the driver's planning (`move()`) and its cog.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, thiserror::Error)]
pub enum DemoFlaw {
    /// The demo reads numbers into a signed 32-bit long.
    #[error(
        "the P2 demo reads a 32-bit signed number: a speed of {speed} would wrap \
         (at most {DEMO_SPEED_MAX} steps/s)"
    )]
    SpeedUnreadable {
        /// The speed asked, steps/s.
        speed: u32,
    },
    /// `abs(-2147483648)` overflows in the planner.
    #[error("the P2 demo's planner cannot take -2147483648 steps (its abs() overflows)")]
    StepsUnreadable,
    /// `stom = 0`: the first delay divides by zero, and a stop-pin stop
    /// wraps the step count to about 4 billion.
    #[error(
        "the reference cog divides by zero on a 1-step move (stom = 0), and a stop-pin stop \
         during it wraps the step count to about 4 billion steps"
    )]
    OneStep,
    /// The planner gives a 2-step move the speed −10.
    #[error(
        "the reference planner gives a 2-step move the speed -10: its first delay is 0, \
         a timer target already passed, and the cog stalls 21.5 s for its counter to wrap"
    )]
    TwoSteps,
    /// The planner gives a 4-step move the speed 0.
    #[error(
        "the reference planner gives a 4-step move the speed 0: every step waits the \
         0.475 s delay ceiling"
    )]
    FourSteps,
    /// An odd move too short to reach its speed keeps it anyway.
    #[error(
        "the reference planner keeps the full speed of {speed} steps/s for an odd short \
         move of {steps} steps: it ramps over {accel_steps} steps only and stops from full speed"
    )]
    OddShortFullSpeed {
        /// |steps|.
        steps: u32,
        /// The speed asked, steps/s.
        speed: u32,
        /// The accel (and decel) steps it gets.
        accel_steps: u32,
    },
    /// Delays shorter than the cog needs to compute them.
    #[error(
        "{speed} steps/s: the reference cog's delays would be shorter than the clocks it \
         needs to compute them, and it would stall 21.5 s per counter wrap \
         (at most {DEMO_SPEED_MAX} steps/s)"
    )]
    SpeedTooHigh {
        /// The speed asked, steps/s.
        speed: u32,
    },
}

impl DemoFlaw {
    /// The reason in a few words, for a `&'static str` error.
    pub fn reason(&self) -> &'static str {
        match self {
            DemoFlaw::SpeedUnreadable { .. } => {
                "the P2 demo reads speeds as 32-bit signed numbers: this one would wrap"
            }
            DemoFlaw::StepsUnreadable => "the P2 demo's planner overflows on -2147483648 steps",
            DemoFlaw::OneStep => "the P2 demo board divides by zero on a 1-step move",
            DemoFlaw::TwoSteps => {
                "the P2 demo board plans a 2-step move at speed -10 and stalls 21.5 s"
            }
            DemoFlaw::FourSteps => {
                "the P2 demo board plans a 4-step move at speed 0 (0.475 s per step)"
            }
            DemoFlaw::OddShortFullSpeed { .. } => {
                "the P2 demo board keeps full speed on an odd move too short to reach it"
            }
            DemoFlaw::SpeedTooHigh { .. } => {
                "the P2 demo board's cog cannot compute its delays at this speed"
            }
        }
    }
}

/// Whether the stock demo and driver would carry out `move(speed, steps)`
/// sanely; `Ok` gives its plan. Speed and steps as a host sends them
/// (speed ≥ 1, steps ≠ 0; 0 is for the caller to refuse as it likes).
///
/// The botched set, from `move()` and the cog: a speed that does not fit
/// the demo's signed long or whose delays the cog cannot compute in time
/// ([`DEMO_SPEED_MAX`]); −2^31 steps; |steps| = 1 (`stom = 0`), 2 (speed
/// −10) and 4 (speed 0); and every odd |steps| whose accel steps were
/// capped at |steps|/2 (one step at speed is left, so the speed is never
/// lowered): whenever `speed/10 + 2 > |steps|/2`, so 3 steps always, 5
/// steps from 10 steps/s, 7 steps from 20 steps/s, and so on.
pub fn check_demo_move(speed: u32, steps: i32) -> Result<DemoPlan, DemoFlaw> {
    let Ok(signed_speed) = i32::try_from(speed) else {
        return Err(DemoFlaw::SpeedUnreadable { speed });
    };
    if speed > DEMO_SPEED_MAX {
        return Err(DemoFlaw::SpeedTooHigh { speed });
    }
    if steps == i32::MIN {
        return Err(DemoFlaw::StepsUnreadable);
    }
    let plan = demo_move(signed_speed, steps);
    if let Some(flaw) = plan_flaw(&plan, speed) {
        return Err(flaw);
    }
    Ok(plan)
}

/// The planning flaws of a plan made from `speed` (see [`check_demo_move`]).
fn plan_flaw(plan: &DemoPlan, speed: u32) -> Option<DemoFlaw> {
    let magnitude = plan.steps.unsigned_abs();
    match magnitude {
        1 => return Some(DemoFlaw::OneStep),
        2 => return Some(DemoFlaw::TwoSteps),
        4 => return Some(DemoFlaw::FourSteps),
        _ => {}
    }
    let capped = i64::from(speed) / 10 + 2 > i64::from(magnitude / 2);
    if magnitude % 2 == 1 && capped {
        return Some(DemoFlaw::OddShortFullSpeed {
            steps: magnitude,
            speed,
            accel_steps: plan.accel_steps.unsigned_abs(),
        });
    }
    None
}

/// Whether a plan, as `move()` made it from any answer, is one the
/// reference botches: what a simulated board must run as the real cog
/// would, rather than on cogstep's hub, which fixes those flaws.
pub fn is_botched(plan: &DemoPlan) -> bool {
    if plan.steps == 0 {
        return false;
    }
    match u32::try_from(plan.speed) {
        Ok(speed) if speed > 0 && speed <= DEMO_SPEED_MAX && plan.steps != i32::MIN => {
            plan_flaw(plan, speed).is_some()
        }
        _ => true,
    }
}

/// `StrToBase(answer, 10)`: the characters that map to 0–9 (see the
/// module documentation), up to the first NUL, in 32-bit wrapping
/// arithmetic; negated when the first character is `-`.
pub fn demo_number(answer: &[u8]) -> i32 {
    let mut value: i32 = 0;
    for &byte in answer.iter().take_while(|&&byte| byte != 0) {
        // `chr := -15 + --chr & %11011111 + 39*(chr > 56)`: Spin2's `&`
        // binds before `+`, and `(chr > 56)` is −1 when true.
        let decremented = i32::from(byte) - 1;
        let digit = -15 + (decremented & 0b1101_1111) - if decremented > 56 { 39 } else { 0 };
        if (0..10).contains(&digit) {
            value = value.wrapping_mul(10).wrapping_add(digit);
        }
    }
    if answer.first() == Some(&b'-') {
        value = value.wrapping_neg();
    }
    value
}

/// An answer being typed (`StrInMax(@str_buffer, 99)`).
#[derive(Clone, Debug)]
struct Answer {
    bytes: [u8; ANSWER_MAX],
    len: usize,
}

impl Default for Answer {
    fn default() -> Self {
        Answer {
            bytes: [0; ANSWER_MAX],
            len: 0,
        }
    }
}

impl Answer {
    /// Takes one byte; gives the answer's value when the byte ends it.
    fn push(&mut self, byte: u8) -> Option<i32> {
        let kept = match byte {
            // `byte[stringptr--] := 0`, and the terminator then lands on
            // the last character typed.
            BACKSPACE => self.len.saturating_sub(1),
            // Stored, then overwritten by the terminator.
            CR => self.len,
            _ => {
                self.bytes[self.len] = byte;
                self.len += 1;
                if self.len < ANSWER_MAX {
                    return None;
                }
                ANSWER_MAX
            }
        };
        let value = demo_number(&self.bytes[..kept]);
        self.len = 0;
        Some(value)
    }
}

/// The cog's longs the demo shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct CogLongs {
    /// `cpos`.
    pub position: i32,
    /// `modeb` (the display shows its low 6 bits).
    pub mode: u32,
    /// `vel`: written when a deceleration starts.
    pub max_velocity: i32,
}

/// What a board running the demo offers: the driver's cog and its hub
/// longs.
pub trait DemoMotor {
    /// Writes the position long (`long[cpos][0] := 1000`; the cog reads it
    /// when it takes its next command).
    fn preset_position(&mut self, position: i32);
    /// `move()` has written the plan's speed and steps: the cog takes the
    /// command (never if its steps are 0). The demo never refuses.
    fn start_move(&mut self, plan: &DemoPlan);
    /// The mode's bit 0 (moving).
    fn is_moving(&mut self) -> bool;
    /// The cog's longs now.
    fn cog(&mut self) -> CogLongs;
}

/// Where the demo program is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DemoPhase {
    /// Waiting for any key after power-up (`wait_for_terminal`).
    #[default]
    WaitingForKey,
    /// `Enter steps: ` shown, reading an answer.
    EnterSteps,
    /// `Enter speed: ` shown, reading an answer.
    EnterSpeed,
    /// A move runs: displays, no reading.
    Running,
}

/// A [`fmt::Write`] that counts what goes through it.
struct Counting<'a, W: ?Sized> {
    out: &'a mut W,
    bytes: u64,
}

impl<W: fmt::Write + ?Sized> fmt::Write for Counting<'_, W> {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        self.bytes += text.len() as u64;
        self.out.write_str(text)
    }
}

/// The demo program (`main()` of `step_driver2_demo.spin2`), sans I/O:
/// feed it every received byte with the time it arrived, and call
/// [`poll`](DemoSession::poll) often (every few ms) with the time.
///
/// Time is in ns since power-up. Printing takes the wire time of its
/// bytes at [`DEMO_BAUD`] (the demo waits for each byte to go out), and
/// received bytes take theirs too: a byte that arrives while the program
/// prints or runs a move lands in the receive pin's one-byte buffer,
/// overwriting the one before, and is read when the program reads again.
#[derive(Clone, Debug, Default)]
pub struct DemoSession {
    phase: DemoPhase,
    answer: Answer,
    steps: i32,
    /// `offset`, `asteps` and `ss` as the last `move()` wrote them.
    plan: DemoPlan,
    start_ms: u32,
    end_ms: u32,
    /// The program prints until then (ns).
    busy_until: u64,
    /// The receive line is free from then (ns).
    line_free: u64,
    /// The receive pin's one-byte buffer.
    latch: Option<u8>,
    /// A display went out: the loop's `while` check comes next.
    check_pending: bool,
}

impl DemoSession {
    /// The program at power-up, waiting for the first key.
    pub fn new() -> Self {
        Self::default()
    }

    /// Where the program is.
    pub fn phase(&self) -> DemoPhase {
        self.phase
    }

    /// When what the program has printed so far has gone out on the wire
    /// (ns since power-up): a board simulator releases its bytes then, so
    /// that a host sees a prompt when the program starts to read.
    pub fn printed_by_ns(&self) -> u64 {
        self.busy_until
    }

    /// Takes one received byte (that reached the board at `now_ns`) and
    /// writes what the board prints in answer.
    pub fn feed<M, W>(&mut self, byte: u8, now_ns: u64, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        let arrival = now_ns.max(self.line_free);
        self.line_free = arrival + BYTE_NS;
        self.catch_up(arrival, motor, out)?;
        if self.phase == DemoPhase::Running || arrival < self.busy_until {
            self.latch = Some(byte);
            return Ok(());
        }
        self.take(byte, arrival, motor, out)
    }

    /// Lets the program run up to `now_ns`: the next display while a move
    /// runs (once the last one has gone out), or, once the move has ended,
    /// clear, the final display and the steps prompt; and a byte waiting
    /// in the receive buffer once the program reads again.
    pub fn poll<M, W>(&mut self, now_ns: u64, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        self.catch_up(now_ns, motor, out)?;
        if self.phase != DemoPhase::Running || now_ns < self.busy_until {
            return Ok(());
        }
        // `repeat showvalues(); endt := getms() while moving`: the check
        // comes once the display has gone out.
        if core::mem::take(&mut self.check_pending) && !motor.is_moving() {
            let mut counting = Counting { out, bytes: 0 };
            counting.write_char(char::from(CLEAR))?;
            self.show_values(motor, &mut counting)?;
            self.prompt(DemoPrompt::Steps, &mut counting)?;
            self.busy_until = now_ns + counting.bytes * BYTE_NS;
            return Ok(());
        }
        let mut counting = Counting { out, bytes: 0 };
        self.show_values(motor, &mut counting)?;
        self.busy_until = now_ns + counting.bytes * BYTE_NS;
        self.end_ms = ms(self.busy_until);
        self.check_pending = true;
        Ok(())
    }

    /// Reads the byte waiting in the receive buffer once the program
    /// reads again (at most one: a byte read may start more printing).
    fn catch_up<M, W>(&mut self, now_ns: u64, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        if self.phase == DemoPhase::Running || now_ns < self.busy_until {
            return Ok(());
        }
        match self.latch.take() {
            Some(byte) => self.take(byte, self.busy_until, motor, out),
            None => Ok(()),
        }
    }

    /// The program reads `byte` at `at_ns`.
    fn take<M, W>(&mut self, byte: u8, at_ns: u64, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        let mut counting = Counting { out, bytes: 0 };
        match self.phase {
            DemoPhase::WaitingForKey => {
                counting.write_char(char::from(CLEAR))?;
                motor.preset_position(PRESET_POSITION);
                self.show_values(motor, &mut counting)?;
                self.prompt(DemoPrompt::Steps, &mut counting)?;
            }
            DemoPhase::EnterSteps => {
                if let Some(steps) = self.answer.push(byte) {
                    self.steps = steps;
                    self.prompt(DemoPrompt::Speed, &mut counting)?;
                }
            }
            DemoPhase::EnterSpeed => {
                if let Some(answer) = self.answer.push(byte) {
                    let mut speed = answer.wrapping_abs();
                    if speed == 0 {
                        speed = 1;
                    }
                    self.start_ms = ms(at_ns);
                    self.end_ms = self.start_ms;
                    self.plan = demo_move(speed, self.steps);
                    motor.start_move(&self.plan);
                    counting.write_char(char::from(CLEAR))?;
                    self.phase = DemoPhase::Running;
                }
            }
            DemoPhase::Running => {}
        }
        self.busy_until = at_ns + counting.bytes * BYTE_NS;
        Ok(())
    }

    /// `Showvalues()`.
    fn show_values<M, W>(&mut self, motor: &mut M, out: &mut W) -> fmt::Result
    where
        M: DemoMotor + ?Sized,
        W: fmt::Write + ?Sized,
    {
        let cog = motor.cog();
        DemoScreen {
            position: cog.position,
            // The low 6 bits: `fbin(mode, 6)`.
            mode_bits: (cog.mode & 0b11_1111) as u8,
            offset_deg: self.plan.offset_deg,
            accel_steps: self.plan.accel_steps,
            slew_steps: self.plan.slew_steps,
            max_velocity_steps_per_s: cog.max_velocity,
            elapsed_ms: self.end_ms.wrapping_sub(self.start_ms) as i32,
        }
        .write_display(out)
    }

    fn prompt<W: fmt::Write + ?Sized>(&mut self, prompt: DemoPrompt, out: &mut W) -> fmt::Result {
        let cr = char::from(CR);
        let (phase, text) = match prompt {
            DemoPrompt::Steps => (DemoPhase::EnterSteps, STEPS_PROMPT),
            DemoPrompt::Speed => (DemoPhase::EnterSpeed, SPEED_PROMPT),
        };
        self.phase = phase;
        self.answer = Answer::default();
        match prompt {
            DemoPrompt::Steps => write!(out, "{cr}{cr}{text}"),
            DemoPrompt::Speed => write!(out, "{cr}{text}"),
        }
    }
}

/// `getms()`: ms since power-up, a wrapping 32-bit count.
fn ms(ns: u64) -> u32 {
    (ns / 1_000_000) as u32
}

#[cfg(test)]
mod tests;

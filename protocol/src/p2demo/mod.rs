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
//!
//! One file each:
//!
//! - `screen`: a display, formatted ([`DemoScreen`], [`number_field`]);
//! - `parser`: screens and prompts read back ([`ScreenParser`]);
//! - `plan`: the driver's `move()` and the moves it botches ([`DemoPlan`],
//!   [`check_demo_move`], [`DemoFlaw`]);
//! - `answer`: an answer typed at a prompt and its value ([`demo_number`]);
//! - `session`: the program's prompt/answer flow ([`DemoSession`]);
//! - [`cog`]: the reference cog's PASM for one command, which the board
//!   simulator runs the botched moves on.

pub mod cog;

mod answer;
mod parser;
mod plan;
mod screen;
mod session;

pub use answer::{demo_number, ANSWER_MAX};
pub use parser::{DemoField, DemoPrompt, ScreenEvent, ScreenParser};
pub use plan::{
    check_demo_move, demo_move, is_botched, DemoFlaw, DemoPlan, DEMO_CLKFREQ, DEMO_OFFSET_DEG,
    DEMO_SPEED_MAX, GETDELAY_TICKS,
};
pub use screen::{number_field, DemoScreen};
pub use session::{
    CogLongs, DemoMotor, DemoPhase, DemoSession, BYTE_NS, DEMO_BAUD, PRESET_POSITION,
};

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

#[cfg(test)]
mod tests;

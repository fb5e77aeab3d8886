//! Reading an answer at a prompt: `StrInMax` (where it ends) and
//! `StrToBase` ([`demo_number`], its value).

use super::{BACKSPACE, CR};

/// The longest answer: it ends by itself at this many characters
/// (`MAXSTR_LENGTH`).
pub const ANSWER_MAX: usize = 99;

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
pub(super) struct Answer {
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
    pub(super) fn push(&mut self, byte: u8) -> Option<i32> {
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

//! The tokenizer: one line of text into words (a letter and a number),
//! each with its 1-based column; comments `( … )` and after `;`, blanks
//! and `%` lines skipped.
//!
//! Written here rather than taken from the `gcode` crate (0.7): the
//! interpreter takes one line at a time, and that crate's spans give a
//! byte offset and a line but no column, its allocation-free path is a
//! visitor over a whole program, and it needs edition 2024; a line's
//! words are forty lines of code.

use crate::error::GcodeErrorKind;

/// One word: `X-12.5` is `('X', -12.5)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Word {
    /// The letter, upper case.
    pub letter: char,
    /// The number.
    pub value: f64,
    /// The column of the letter (1-based, in characters).
    pub column: u32,
}

/// A tokenizer fault: the column and the kind.
pub(crate) type Fault = (u32, GcodeErrorKind);

/// Calls `each` with every word of `text` in order; stops at the first
/// fault, of the tokenizer or of `each`.
pub(crate) fn scan(
    text: &str,
    mut each: impl FnMut(Word) -> Result<(), Fault>,
) -> Result<(), Fault> {
    if text.trim_start().starts_with('%') {
        return Ok(());
    }
    let chars: &[u8] = text.as_bytes();
    let mut index = 0;
    let mut column: u32 = 1;
    // Moves past one character (of any length in UTF-8).
    let step = |index: &mut usize, column: &mut u32| {
        let width = text[*index..].chars().next().map_or(1, char::len_utf8);
        *index += width;
        *column = column.saturating_add(1);
    };
    while index < chars.len() {
        let byte = chars[index];
        match byte {
            b' ' | b'\t' | b'\r' | b'\n' => step(&mut index, &mut column),
            b';' => return Ok(()),
            b'(' => {
                let start = column;
                loop {
                    if index >= chars.len() {
                        return Err((start, GcodeErrorKind::Malformed));
                    }
                    let close = chars[index] == b')';
                    step(&mut index, &mut column);
                    if close {
                        break;
                    }
                }
            }
            letter if letter.is_ascii_alphabetic() => {
                let word_column = column;
                step(&mut index, &mut column);
                while index < chars.len() && matches!(chars[index], b' ' | b'\t') {
                    step(&mut index, &mut column);
                }
                let start = index;
                if index < chars.len() && matches!(chars[index], b'+' | b'-') {
                    index += 1;
                }
                let mut digits = 0;
                let mut points = 0;
                while index < chars.len() {
                    match chars[index] {
                        b'0'..=b'9' => digits += 1,
                        b'.' => points += 1,
                        _ => break,
                    }
                    index += 1;
                }
                // Only ASCII was read since `start`: one column a byte.
                column = column.saturating_add((index - start) as u32);
                if digits == 0 || points > 1 {
                    return Err((word_column, GcodeErrorKind::Malformed));
                }
                let value: f64 = text[start..index]
                    .parse()
                    .map_err(|_| (word_column, GcodeErrorKind::Malformed))?;
                if !value.is_finite() {
                    return Err((word_column, GcodeErrorKind::NumberOutOfRange));
                }
                each(Word {
                    letter: char::from(letter.to_ascii_uppercase()),
                    value,
                    column: word_column,
                })?;
            }
            _ => return Err((column, GcodeErrorKind::Malformed)),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn words(text: &str) -> Result<Vec<(char, f64, u32)>, Fault> {
        let mut all = Vec::new();
        scan(text, |word| {
            all.push((word.letter, word.value, word.column));
            Ok(())
        })?;
        Ok(all)
    }

    #[test]
    fn words_comments_and_columns() {
        assert_eq!(
            words("G1 x-1.5 (cut) Y.25;rest").unwrap(),
            [('G', 1.0, 1), ('X', -1.5, 4), ('Y', 0.25, 16)]
        );
        assert_eq!(words("g01x+2").unwrap(), [('G', 1.0, 1), ('X', 2.0, 4)]);
        assert_eq!(words("G 1").unwrap(), [('G', 1.0, 1)]);
        assert_eq!(words("X5. Y-.5").unwrap(), [('X', 5.0, 1), ('Y', -0.5, 5)]);
        assert_eq!(words("  % anything").unwrap(), []);
        assert_eq!(words("(é) X1").unwrap(), [('X', 1.0, 5)]);
        assert_eq!(words("").unwrap(), []);
    }

    #[test]
    fn malformed_words_name_their_column() {
        assert_eq!(words("G1 X"), Err((4, GcodeErrorKind::Malformed)));
        assert_eq!(words("G1 X1.2.3"), Err((4, GcodeErrorKind::Malformed)));
        assert_eq!(words("G1 (open"), Err((4, GcodeErrorKind::Malformed)));
        assert_eq!(words("G1 #1"), Err((4, GcodeErrorKind::Malformed)));
        assert_eq!(words("X-"), Err((1, GcodeErrorKind::Malformed)));
        // No exponents: `e5` is a word of its own.
        assert_eq!(words("X1e5"), Ok(std::vec![('X', 1.0, 1), ('E', 5.0, 3)]));
    }
}

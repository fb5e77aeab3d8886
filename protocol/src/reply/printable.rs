//! Text from a backend, made safe for a reply line: printable ASCII only,
//! cut to fit.

use core::fmt;

/// The most characters of text from a backend (a fault's or an
/// unsupported request's description, an error message) that go into one
/// reply line; the rest is cut, so that every line fits in
/// [`REPLY_LINE_MAX`](crate::REPLY_LINE_MAX).
pub(crate) const BACKEND_TEXT_MAX: usize = 64;

/// Writes `text` with every character outside printable ASCII replaced by
/// `?`, cut at `max_chars` characters, so that no text from a backend can
/// break a reply line or make it too long.
pub(crate) fn write_printable<W: fmt::Write + ?Sized>(
    out: &mut W,
    text: &str,
    max_chars: usize,
) -> fmt::Result {
    write_display_printable(out, &text, max_chars)
}

/// Formats anything [`fmt::Display`] as [`write_printable`] writes text.
pub(crate) fn write_display_printable<W: fmt::Write + ?Sized>(
    out: &mut W,
    value: &dyn fmt::Display,
    max_chars: usize,
) -> fmt::Result {
    let mut printable = Printable {
        out,
        remaining: max_chars,
    };
    fmt::write(&mut printable, format_args!("{value}"))
}

struct Printable<'w, W: fmt::Write + ?Sized> {
    out: &'w mut W,
    /// Characters still allowed.
    remaining: usize,
}

impl<W: fmt::Write + ?Sized> fmt::Write for Printable<'_, W> {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        for c in text.chars() {
            if self.remaining == 0 {
                break;
            }
            self.remaining -= 1;
            self.out
                .write_char(if (' '..='~').contains(&c) { c } else { '?' })?;
        }
        Ok(())
    }
}

//! The line buffer: bytes in, one at a time; lines and realtime bytes out.
//!
//! Realtime bytes (`?`, `!`, 0x18) are taken out of the stream wherever they
//! come, even in the middle of a line, and never enter the buffer. A line
//! ends at CR or LF; CRLF gives one line and an empty one, and empty or
//! all-space lines are dropped here, so a person pressing Enter gets no
//! reply. A line longer than [`LINE_MAX`] is discarded as it comes and
//! reported once, when its line end finally arrives.

use super::LINE_MAX;

/// A byte that acts at once, outside the line buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Realtime {
    /// `?`: one status line per axis.
    Status,
    /// `!`: controlled stop of every axis (stop pins low).
    Stop,
    /// 0x18 (Ctrl-X, CAN): emergency stop of every axis; clears the line buffer.
    EmergencyStop,
}

impl Realtime {
    /// The realtime command a byte stands for, if any.
    pub fn from_byte(byte: u8) -> Option<Self> {
        match byte {
            b'?' => Some(Realtime::Status),
            b'!' => Some(Realtime::Stop),
            0x18 => Some(Realtime::EmergencyStop),
            _ => None,
        }
    }

    /// The byte on the wire.
    pub fn byte(self) -> u8 {
        match self {
            Realtime::Status => b'?',
            Realtime::Stop => b'!',
            Realtime::EmergencyStop => 0x18,
        }
    }
}

/// What one received byte amounts to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event<'a> {
    /// A complete, non-blank line of at most [`LINE_MAX`] bytes, without its
    /// line end. It may still hold any byte but CR, LF and the realtime
    /// bytes; [`parse_line`](super::parse_line) judges it.
    Line(&'a [u8]),
    /// A realtime byte.
    Realtime(Realtime),
    /// The line end of a line that was longer than [`LINE_MAX`] bytes; the
    /// line was discarded.
    Overlong,
}

/// Assembles lines from single bytes; never allocates, never panics.
#[derive(Clone, Debug, Default)]
pub struct Receiver {
    line: heapless::Vec<u8, LINE_MAX>,
    /// The current line passed [`LINE_MAX`]: its bytes are being dropped.
    overlong: bool,
    /// The buffer holds a line already handed out; empty it on the next byte.
    handed_out: bool,
}

impl Receiver {
    /// An empty receiver.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one byte; returns what it completes, if anything.
    pub fn push(&mut self, byte: u8) -> Option<Event<'_>> {
        if self.handed_out {
            self.line.clear();
            self.handed_out = false;
        }
        if let Some(realtime) = Realtime::from_byte(byte) {
            if realtime == Realtime::EmergencyStop {
                self.clear();
            }
            return Some(Event::Realtime(realtime));
        }
        match byte {
            b'\r' | b'\n' => {
                if core::mem::take(&mut self.overlong) {
                    self.line.clear();
                    return Some(Event::Overlong);
                }
                if self.line.iter().all(|&b| b == b' ') {
                    self.line.clear();
                    return None;
                }
                self.handed_out = true;
                Some(Event::Line(self.line.as_slice()))
            }
            _ => {
                if !self.overlong && self.line.push(byte).is_err() {
                    // The line is too long: drop it now, report it at its end.
                    self.overlong = true;
                    self.line.clear();
                }
                None
            }
        }
    }

    /// Forgets the partial line (0x18 does this).
    pub fn clear(&mut self) {
        self.line.clear();
        self.overlong = false;
        self.handed_out = false;
    }

    /// How many bytes of an unfinished line are buffered (0 while an
    /// overlong line is being dropped).
    pub fn pending(&self) -> usize {
        if self.handed_out {
            0
        } else {
            self.line.len()
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::vec::Vec;

    use super::*;

    /// Every event of a byte string, lines copied out.
    fn events(bytes: &[u8]) -> Vec<std::string::String> {
        let mut receiver = Receiver::new();
        let mut out = Vec::new();
        for &byte in bytes {
            match receiver.push(byte) {
                Some(Event::Line(line)) => out.push(std::format!(
                    "line:{}",
                    std::string::String::from_utf8_lossy(line)
                )),
                Some(Event::Realtime(rt)) => out.push(std::format!("rt:{rt:?}")),
                Some(Event::Overlong) => out.push("overlong".into()),
                None => {}
            }
        }
        out
    }

    #[test]
    fn cr_lf_and_crlf_all_end_a_line() {
        assert_eq!(events(b"I\n"), ["line:I"]);
        assert_eq!(events(b"I\r"), ["line:I"]);
        assert_eq!(events(b"I\r\n"), ["line:I"]);
        assert_eq!(events(b"I\r\nE\rS 0\n"), ["line:I", "line:E", "line:S 0"]);
    }

    #[test]
    fn blank_lines_are_dropped() {
        assert!(events(b"\n\r\n\r   \n").is_empty());
    }

    #[test]
    fn realtime_bytes_never_enter_the_line() {
        assert_eq!(
            events(b"M 0 1?00 2!00\n"),
            ["rt:Status", "rt:Stop", "line:M 0 100 200"]
        );
    }

    #[test]
    fn ctrl_x_clears_the_partial_line() {
        assert_eq!(
            events(b"M 0 100\x18 200\nI\n"),
            ["rt:EmergencyStop", "line: 200", "line:I"]
        );
        let long = [b'x'; LINE_MAX + 10];
        let mut bytes = long.to_vec();
        bytes.extend_from_slice(b"\x18I\n");
        assert_eq!(events(&bytes), ["rt:EmergencyStop", "line:I"]);
    }

    #[test]
    fn exactly_line_max_bytes_is_a_line_one_more_is_overlong() {
        let mut bytes = [b'x'; LINE_MAX].to_vec();
        bytes.push(b'\n');
        let got = events(&bytes);
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].len(), "line:".len() + LINE_MAX);

        let mut bytes = [b'x'; LINE_MAX + 1].to_vec();
        bytes.extend_from_slice(b"\r\nI\n");
        assert_eq!(events(&bytes), ["overlong", "line:I"]);
    }

    #[test]
    fn a_very_long_line_is_reported_once() {
        let mut bytes = [b'7'; 10 * LINE_MAX].to_vec();
        bytes.push(b'\n');
        assert_eq!(events(&bytes), ["overlong"]);
    }

    #[test]
    fn pending_counts_the_unfinished_line() {
        let mut receiver = Receiver::new();
        for &byte in b"M 0" {
            receiver.push(byte);
        }
        assert_eq!(receiver.pending(), 3);
        receiver.push(b'\n');
        assert_eq!(receiver.pending(), 0);
        receiver.push(b'I');
        assert_eq!(receiver.pending(), 1);
    }
}

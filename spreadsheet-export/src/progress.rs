//! A one-line progress report on stderr for long exports, only when stderr
//! is a terminal (never in a pipe, a log or CI).

use std::io::{IsTerminal, Write};

/// Moves shorter than this finish too fast to need a progress line.
const MIN_STEPS: u32 = 500_000;

/// Rows between checks of the percentage.
const CHECK_EVERY: u32 = 1 << 14;

/// Progress of an export.
#[derive(Debug)]
pub struct Progress {
    total: u32,
    shown_percent: Option<u32>,
    enabled: bool,
}

impl Progress {
    /// Progress for `total` steps; silent unless stderr is a terminal and
    /// the move is long.
    pub fn new(total: u32) -> Self {
        Self {
            total,
            shown_percent: None,
            enabled: total >= MIN_STEPS && std::io::stderr().is_terminal(),
        }
    }

    /// Reports that `done` rows are written.
    #[inline]
    pub fn update(&mut self, done: u32) {
        if !self.enabled || !done.is_multiple_of(CHECK_EVERY) {
            return;
        }
        let percent = (u64::from(done) * 100 / u64::from(self.total.max(1))) as u32;
        if self.shown_percent != Some(percent) {
            self.shown_percent = Some(percent);
            let mut stderr = std::io::stderr().lock();
            // Progress is a courtesy: a failed write to the terminal is ignored.
            let _ = write!(
                stderr,
                "\rspreadsheet-export: {percent:3}% ({done} of {} steps)",
                self.total
            );
            let _ = stderr.flush();
        }
    }

    /// Clears the line (before anything else goes to stderr).
    pub fn finish(&mut self) {
        if self.enabled && self.shown_percent.is_some() {
            let mut stderr = std::io::stderr().lock();
            let _ = write!(stderr, "\r\x1b[2K");
            let _ = stderr.flush();
            self.shown_percent = None;
        }
    }
}

impl Drop for Progress {
    /// An export that fails part-way clears the line before its error.
    fn drop(&mut self) {
        self.finish();
    }
}

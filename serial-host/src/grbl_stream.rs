//! Streaming a G-code program to a grbl board by character counting, as
//! every grbl sender does: the host keeps as many lines in flight as fit
//! in the board's 128-byte receive buffer, and each `ok` or `error:N`
//! answers the oldest line in flight.
//!
//! ```text
//! SerialBoard::stream_gcode ─► prepared lines ─► link thread ─► "G1X10F600\n" ... (≤ 128 bytes in flight)
//! port ─► "ok" / "error:N" ─► oldest line in flight answered ─► GcodeStream::progress
//! ```
//!
//! The lines are prepared as senders do before a byte is sent: comments
//! (`;…` and `(…)`) and blanks are removed, an empty line is not sent; a
//! line that cannot go whole into the board's buffers, or that holds a
//! byte the board would take as a realtime command (`?`, `!`, `~`, 0x18,
//! 0x80 and above), refuses the whole program with [`StreamRefusal`], so
//! nothing moves.
//!
//! An `error:N` stops the stream: no line after it is sent. The lines
//! already in the board's buffer when the error came were sent before it
//! was known and still run (as with every character-counting sender); the
//! progress says how many. An alarm or a reset of the board ends it too (the
//! board drops what it had buffered).

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};

use cogstep_protocol::grbl::{GrblRealtime, LINE_BUFFER_SIZE, RX_BUFFER_SIZE};

use super::state::lock;

/// Why a program cannot be streamed; nothing was sent.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum StreamRefusal {
    /// A line is longer than the board's line buffer once prepared.
    #[error("line {line}: {length} characters once comments and blanks are removed; a grbl board takes at most {max}")]
    LineTooLong {
        /// The line, from 1.
        line: usize,
        /// Its prepared length.
        length: usize,
        /// The most the board takes.
        max: usize,
    },
    /// A line holds a byte the board would act on as a realtime command.
    #[error("line {line}: the character {byte:#04x} is a grbl realtime command, not G-code")]
    RealtimeByte {
        /// The line, from 1.
        line: usize,
        /// The byte.
        byte: u8,
    },
    /// A line is not ASCII text.
    #[error("line {line}: not ASCII text")]
    NotAscii {
        /// The line, from 1.
        line: usize,
    },
}

/// Where a streamed program stands.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StreamState {
    /// Lines are being sent or answered, or the board still moves.
    Streaming,
    /// Every line was answered `ok` and the board came to rest after it.
    Done,
    /// The board answered line `line` (from 1) with `error:code`: nothing
    /// after it was sent.
    Error {
        /// The line, from 1.
        line: usize,
        /// grbl's error code.
        code: u8,
    },
    /// The board raised `ALARM:code`: it dropped what it had buffered.
    Alarm(u8),
    /// The host cancelled it ([`GcodeStream::cancel`]): the board came to
    /// rest along the path and was reset there (positions kept, no alarm).
    Cancelled,
    /// The board reset (an emergency stop, or on its own): it dropped what
    /// it had buffered.
    Reset,
    /// The link to the board was lost.
    Lost,
}

impl StreamState {
    /// Whether nothing more will be sent.
    pub fn is_over(&self) -> bool {
        *self != StreamState::Streaming
    }
}

/// A streamed program's progress.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StreamProgress {
    /// The lines of the program (blank and comment lines included).
    pub lines: usize,
    /// Lines sent (or passed over as empty), from the first.
    pub sent: usize,
    /// Lines answered (or passed over as empty), from the first: the
    /// board has taken these into its planner.
    pub answered: usize,
    /// Lines answered `ok`.
    pub ok: usize,
    /// Bytes sent and not yet answered (at most the board's 128).
    pub bytes_in_flight: usize,
    /// The most bytes ever in flight.
    pub most_bytes_in_flight: usize,
    /// Lines sent after an error (sent before it was known; they run).
    pub sent_after_error: usize,
    /// Where it stands.
    pub state: StreamState,
}

impl StreamProgress {
    /// A program of `lines` lines, nothing sent yet.
    pub(super) fn new(lines: usize) -> Self {
        StreamProgress {
            lines,
            sent: 0,
            answered: 0,
            ok: 0,
            bytes_in_flight: 0,
            most_bytes_in_flight: 0,
            sent_after_error: 0,
            state: StreamState::Streaming,
        }
    }
}

/// One line as it goes to the board; `None` for a line with nothing to
/// send.
pub(super) type Prepared = Option<String>;

/// What the handle and the link thread share of one stream.
#[derive(Debug)]
pub(super) struct StreamShared {
    pub(super) lines: Vec<Prepared>,
    pub(super) progress: Mutex<StreamProgress>,
}

/// A program being streamed to a grbl board
/// ([`SerialBoard::stream_gcode`](super::SerialBoard::stream_gcode)).
/// Cheap to clone; dropping it does not stop the program.
#[derive(Clone, Debug)]
pub struct GcodeStream {
    pub(super) shared: Arc<StreamShared>,
    pub(super) board: super::SerialBoard,
}

impl GcodeStream {
    /// Where the program stands now.
    pub fn progress(&self) -> StreamProgress {
        lock(&self.shared.progress).clone()
    }

    /// Feed hold (`!`): the board decelerates along its path to rest.
    pub fn hold(&self) -> Result<(), cogstep_motion::axis::AxisError> {
        self.board.grbl_realtime(GrblRealtime::FeedHold)
    }

    /// Cycle start (`~`): the board goes on after a hold.
    pub fn resume(&self) -> Result<(), cogstep_motion::axis::AxisError> {
        self.board.grbl_realtime(GrblRealtime::CycleStart)
    }

    /// Ends the program as a machine owner would: a feed hold now and no
    /// more lines; then, once the board is at rest, a soft reset, which
    /// drops what it buffered and keeps the position (no alarm: nothing
    /// moved), and the state is [`StreamState::Cancelled`]. Returns once
    /// the hold is sent: the link serves on meanwhile (an emergency stop
    /// still acts at once).
    pub fn cancel(&self) -> Result<(), cogstep_motion::axis::AxisError> {
        self.board.grbl_cancel_stream()
    }
}

/// Prepares a program's lines as a sender does; refuses it whole if a
/// line cannot go to the board as it is.
pub(super) fn prepare(lines: &[String]) -> Result<Vec<Prepared>, StreamRefusal> {
    lines
        .iter()
        .enumerate()
        .map(|(index, text)| prepare_line(index + 1, text))
        .collect()
}

/// Line `line` (from 1) as it goes to a grbl board: comments and white
/// space removed (`None` when nothing is left), or why it cannot go.
pub fn prepare_line(line: usize, text: &str) -> Result<Option<String>, StreamRefusal> {
    let mut kept = String::new();
    let mut in_paren = false;
    for c in text.chars() {
        if !c.is_ascii() {
            return Err(StreamRefusal::NotAscii { line });
        }
        match c {
            _ if in_paren => in_paren = c != ')',
            '(' => in_paren = true,
            ';' => break,
            c if c.is_ascii_whitespace() => {}
            c => {
                let byte = c as u8;
                if GrblRealtime::from_byte(byte).is_some() || byte.is_ascii_control() {
                    return Err(StreamRefusal::RealtimeByte { line, byte });
                }
                kept.push(c);
            }
        }
    }
    // The board keeps at most LINE_BUFFER_SIZE − 1 characters of a line.
    let max = LINE_BUFFER_SIZE - 1;
    if kept.len() > max {
        return Err(StreamRefusal::LineTooLong {
            line,
            length: kept.len(),
            max,
        });
    }
    Ok((!kept.is_empty()).then_some(kept))
}

/// The link thread's side of a stream.
pub(super) struct Streamer {
    pub(super) shared: Arc<StreamShared>,
    next: usize,
    /// (line index, bytes) of each line in flight, oldest first.
    in_flight: VecDeque<(usize, usize)>,
    /// Every line is answered `ok`: done once the board is at rest.
    pub(super) all_answered: bool,
    stopped: bool,
    /// No more lines go (a cancel is under way).
    paused: bool,
}

impl Streamer {
    pub(super) fn new(shared: Arc<StreamShared>) -> Self {
        Streamer {
            shared,
            next: 0,
            in_flight: VecDeque::new(),
            all_answered: false,
            stopped: false,
            paused: false,
        }
    }

    /// No more lines are sent (a cancel is under way); answers still count.
    pub(super) fn pause(&mut self) {
        self.paused = true;
    }

    fn bytes_in_flight(&self) -> usize {
        self.in_flight.iter().map(|&(_, bytes)| bytes).sum()
    }

    /// The lines to send now: as many as fit in the board's buffer.
    pub(super) fn pump(&mut self) -> Vec<u8> {
        let mut out = Vec::new();
        if self.stopped || self.paused {
            return out;
        }
        let mut in_flight = self.bytes_in_flight();
        while let Some(line) = self.shared.lines.get(self.next) {
            match line {
                None => self.next += 1,
                Some(text) => {
                    let bytes = text.len() + 1;
                    if in_flight + bytes > RX_BUFFER_SIZE {
                        break;
                    }
                    out.extend_from_slice(text.as_bytes());
                    out.push(b'\n');
                    self.in_flight.push_back((self.next, bytes));
                    in_flight += bytes;
                    self.next += 1;
                }
            }
        }
        self.publish(|_| {});
        out
    }

    /// The board answered the oldest line in flight; false if none was.
    pub(super) fn answer(&mut self, result: Result<(), u8>) -> bool {
        let Some((index, _)) = self.in_flight.pop_front() else {
            return false;
        };
        match result {
            Ok(()) => self.publish(|progress| progress.ok += 1),
            Err(code) => {
                if !self.stopped {
                    self.stopped = true;
                    let after = self.in_flight.len();
                    self.publish(|progress| {
                        progress.state = StreamState::Error {
                            line: index + 1,
                            code,
                        };
                        progress.sent_after_error = after;
                    });
                }
            }
        }
        true
    }

    /// The board dropped its buffers (`state`): nothing more is answered
    /// or sent.
    pub(super) fn end(&mut self, state: StreamState) {
        self.stopped = true;
        self.in_flight.clear();
        self.publish(|progress| {
            if !progress.state.is_over() || matches!(progress.state, StreamState::Error { .. }) {
                progress.state = state;
            }
        });
    }

    /// A status report at rest came: the program is done if every line
    /// was answered before it.
    pub(super) fn at_rest(&mut self) {
        if self.all_answered && !self.stopped {
            self.stopped = true;
            self.publish(|progress| progress.state = StreamState::Done);
        }
    }

    /// Whether the link thread still has to serve it.
    pub(super) fn is_over(&self) -> bool {
        self.stopped && self.in_flight.is_empty()
    }

    fn publish(&mut self, change: impl FnOnce(&mut StreamProgress)) {
        let total = self.shared.lines.len();
        // Lines with nothing to send right after the last sent one are
        // passed over.
        while self.next < total && self.shared.lines[self.next].is_none() && !self.stopped {
            self.next += 1;
        }
        let answered = self
            .in_flight
            .front()
            .map_or(self.next, |&(index, _)| index);
        let bytes = self.bytes_in_flight();
        self.all_answered = self.in_flight.is_empty() && self.next == total;
        let mut progress = lock(&self.shared.progress);
        progress.sent = self.next;
        progress.answered = answered;
        progress.bytes_in_flight = bytes;
        progress.most_bytes_in_flight = progress.most_bytes_in_flight.max(bytes);
        change(&mut progress);
    }
}

impl Drop for Streamer {
    /// The conversation ends with a program still streaming: the link was
    /// lost (or the board closed).
    fn drop(&mut self) {
        if !self.stopped {
            self.end(StreamState::Lost);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(text: &str) -> Vec<String> {
        text.lines().map(str::to_string).collect()
    }

    #[test]
    fn lines_are_prepared_as_a_sender_does() {
        let prepared = prepare(&lines(
            "G1 X10 (to the edge) Y2 ; comment\n\n  ; only a comment\nM2",
        ))
        .expect("prepared");
        assert_eq!(
            prepared,
            vec![
                Some("G1X10Y2".to_string()),
                None,
                None,
                Some("M2".to_string())
            ]
        );
    }

    #[test]
    fn a_line_the_board_cannot_take_refuses_the_program_whole() {
        assert_eq!(
            prepare(&lines("G0X1\nG1X2?")),
            Err(StreamRefusal::RealtimeByte {
                line: 2,
                byte: b'?'
            })
        );
        let long = format!("G1X{}", "1".repeat(90));
        assert!(matches!(
            prepare(&[long]),
            Err(StreamRefusal::LineTooLong { line: 1, .. })
        ));
        assert_eq!(
            prepare(&lines("G1X1 é")),
            Err(StreamRefusal::NotAscii { line: 1 })
        );
    }

    fn streamer(text: &str) -> Streamer {
        let prepared = prepare(&lines(text)).expect("prepared");
        let total = prepared.len();
        Streamer::new(Arc::new(StreamShared {
            lines: prepared,
            progress: Mutex::new(StreamProgress::new(total)),
        }))
    }

    #[test]
    fn never_more_than_the_buffer_in_flight_and_every_line_once_in_order() {
        // 200 lines of 13 bytes (with the line end): 9 fit in 128.
        let text: String = (0..200).map(|i| format!("G1X{:03}.5F600\n", i)).collect();
        let mut streamer = streamer(&text);
        let mut wire = Vec::new();
        let mut answered = 0;
        loop {
            wire.extend(streamer.pump());
            let progress = lock(&streamer.shared.progress).clone();
            assert!(progress.bytes_in_flight <= RX_BUFFER_SIZE);
            if !streamer.answer(Ok(())) {
                break;
            }
            answered += 1;
        }
        assert_eq!(answered, 200);
        assert_eq!(wire, text.into_bytes());
        let progress = lock(&streamer.shared.progress).clone();
        assert_eq!(progress.most_bytes_in_flight, 9 * 13);
        assert_eq!(
            (progress.sent, progress.answered, progress.ok),
            (200, 200, 200)
        );
        assert!(streamer.all_answered);
        streamer.at_rest();
        assert_eq!(streamer.progress_state(), StreamState::Done);
    }

    #[test]
    fn an_error_stops_the_stream_and_counts_what_was_already_sent() {
        let text: String = (0..40).map(|i| format!("G1X{i}F600\n")).collect();
        let mut streamer = streamer(&text);
        let first = streamer.pump();
        let sent = first.iter().filter(|&&b| b == b'\n').count();
        assert!(streamer.answer(Ok(())));
        assert!(streamer.answer(Err(33)));
        assert!(streamer.pump().is_empty(), "nothing after an error");
        let progress = lock(&streamer.shared.progress).clone();
        assert_eq!(progress.state, StreamState::Error { line: 2, code: 33 });
        assert_eq!(progress.sent_after_error, sent - 2);
        while streamer.answer(Ok(())) {}
        assert!(streamer.is_over());
    }

    impl Streamer {
        fn progress_state(&self) -> StreamState {
            lock(&self.shared.progress).state.clone()
        }
    }
}

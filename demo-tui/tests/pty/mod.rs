//! Runs the real `demo-tui` binary in a pseudo-terminal and reads its
//! screen with `vt100`, as a person at a terminal would see it. The fake
//! terminal answers the two queries the demo makes at start (primary
//! device attributes, and — when asked to play kitty — the keyboard
//! protocol flags), so key releases can be tested too.

#![allow(dead_code)] // each test binary uses its own part of the harness

use std::io::{Read, Write};
use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use portable_pty::{native_pty_system, Child, CommandBuilder, MasterPty, PtySize};

/// The screen size every test uses.
pub const ROWS: u16 = 40;
/// The screen size every test uses.
pub const COLS: u16 = 120;

/// How the fake terminal answers the keyboard-protocol query.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Keyboard {
    /// A terminal without the kitty keyboard protocol (answers only the
    /// device-attributes query): keys repeat, never release.
    Legacy,
    /// A terminal with the kitty keyboard protocol: it can report releases.
    Kitty,
    /// A bare screen that answers no query (as a plain vt100 harness).
    Silent,
}

/// Arrow right, as a legacy terminal sends it.
pub const RIGHT: &[u8] = b"\x1b[C";
/// Arrow left, as a legacy terminal sends it.
pub const LEFT: &[u8] = b"\x1b[D";
/// Arrow right pressed, kitty protocol with event types.
pub const KITTY_RIGHT_PRESS: &[u8] = b"\x1b[1;1:1C";
/// Arrow right repeated, kitty protocol with event types.
pub const KITTY_RIGHT_REPEAT: &[u8] = b"\x1b[1;1:2C";
/// Arrow right released, kitty protocol with event types.
pub const KITTY_RIGHT_RELEASE: &[u8] = b"\x1b[1;1:3C";

struct Shared {
    parser: vt100::Parser,
    /// Everything the demo wrote.
    raw: Vec<u8>,
    /// How far `raw` was scanned for queries.
    scanned: usize,
    /// The reader hit the end (the demo closed the terminal), or stopped
    /// for [`Demo::hang_up`].
    closed: bool,
    /// [`Demo::hang_up`] asks the reader to let go of the terminal.
    hang_up: bool,
}

/// The demo running in a pseudo-terminal.
pub struct Demo {
    shared: Arc<Mutex<Shared>>,
    /// `None` once the terminal was hung up.
    writer: Arc<Mutex<Option<Box<dyn Write + Send>>>>,
    child: Box<dyn Child + Send + Sync>,
    /// `None` once the terminal was hung up.
    master: Option<Box<dyn MasterPty + Send>>,
    reader: Option<JoinHandle<()>>,
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Occurrences of `needle` in `raw` that end after `scanned`.
fn new_matches(raw: &[u8], scanned: usize, needle: &[u8]) -> usize {
    let from = scanned.saturating_sub(needle.len() - 1);
    raw[from..]
        .windows(needle.len())
        .enumerate()
        .filter(|(i, w)| *w == needle && from + i + needle.len() > scanned)
        .count()
}

impl Demo {
    /// Starts the demo binary at `binary` with `args`, in a 120×40 terminal.
    pub fn spawn(binary: impl AsRef<Path>, args: &[&str], keyboard: Keyboard) -> Demo {
        let pair = native_pty_system()
            .openpty(PtySize {
                rows: ROWS,
                cols: COLS,
                pixel_width: 0,
                pixel_height: 0,
            })
            .expect("a pseudo-terminal");
        let mut command = CommandBuilder::new(binary.as_ref());
        command.args(args);
        command.env("TERM", "xterm-256color");
        if let Ok(dir) = std::env::current_dir() {
            command.cwd(dir);
        }
        let child = pair.slave.spawn_command(command).expect("spawn demo-tui");
        // Only the child holds the terminal's slave side: the reader sees
        // the end when the demo exits.
        drop(pair.slave);
        let mut reader = pair.master.try_clone_reader().expect("reader");
        // Non-blocking (the reader shares the file), so that the reader
        // thread can let go of the terminal when asked to hang up.
        {
            use nix::fcntl::{fcntl, FcntlArg, OFlag};
            let fd = pair.master.as_raw_fd().expect("the master's fd");
            fcntl(fd, FcntlArg::F_SETFL(OFlag::O_NONBLOCK)).expect("O_NONBLOCK");
        }
        let writer = Arc::new(Mutex::new(Some(pair.master.take_writer().expect("writer"))));
        let shared = Arc::new(Mutex::new(Shared {
            parser: vt100::Parser::new(
                ROWS.try_into().expect("rows"),
                COLS.try_into().expect("cols"),
                0,
            ),
            raw: Vec::new(),
            scanned: 0,
            closed: false,
            hang_up: false,
        }));
        let reader = {
            let shared = Arc::clone(&shared);
            let writer = Arc::clone(&writer);
            std::thread::spawn(move || {
                let mut buf = [0u8; 16 * 1024];
                loop {
                    if lock(&shared).hang_up {
                        break;
                    }
                    let n = match reader.read(&mut buf) {
                        Ok(0) => break,
                        Ok(n) => n,
                        Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                            std::thread::sleep(Duration::from_millis(2));
                            continue;
                        }
                        Err(_) => break,
                    };
                    let mut state = lock(&shared);
                    state.parser.process(&buf[..n]);
                    state.raw.extend_from_slice(&buf[..n]);
                    let scanned = state.scanned;
                    let flags_queries = new_matches(&state.raw, scanned, b"\x1b[?u");
                    let attribute_queries = new_matches(&state.raw, scanned, b"\x1b[c");
                    state.scanned = state.raw.len();
                    drop(state);
                    let mut answer = Vec::new();
                    if keyboard == Keyboard::Kitty {
                        for _ in 0..flags_queries {
                            answer.extend_from_slice(b"\x1b[?0u");
                        }
                    }
                    if keyboard != Keyboard::Silent {
                        for _ in 0..attribute_queries {
                            answer.extend_from_slice(b"\x1b[?62;22c");
                        }
                    }
                    if let (false, Some(writer)) = (answer.is_empty(), lock(&writer).as_mut()) {
                        let _ = writer.write_all(&answer);
                        let _ = writer.flush();
                    }
                }
                lock(&shared).closed = true;
            })
        };
        Demo {
            shared,
            writer,
            child,
            master: Some(pair.master),
            reader: Some(reader),
        }
    }

    /// The screen's text, row by row.
    pub fn screen(&self) -> String {
        lock(&self.shared).parser.screen().contents()
    }

    /// Whether the alternate screen is on, and whether the cursor is hidden.
    pub fn modes(&self) -> (bool, bool) {
        let state = lock(&self.shared);
        let screen = state.parser.screen();
        (screen.alternate_screen(), screen.hide_cursor())
    }

    /// The cursor's (row, column).
    pub fn cursor(&self) -> (u16, u16) {
        lock(&self.shared).parser.screen().cursor_position()
    }

    /// Whether the demo wrote `bytes` at some point.
    pub fn wrote(&self, bytes: &[u8]) -> bool {
        lock(&self.shared)
            .raw
            .windows(bytes.len())
            .any(|w| w == bytes)
    }

    /// Sends bytes as typed keys.
    pub fn send(&self, bytes: &[u8]) {
        let mut writer = lock(&self.writer);
        let writer = writer.as_mut().expect("the terminal is there");
        writer.write_all(bytes).expect("write to the demo");
        writer.flush().expect("flush");
    }

    /// Closes the terminal under the demo, as closing its window (or
    /// killing its tmux session) does: every handle on the pty's master
    /// side is let go.
    pub fn hang_up(&mut self) {
        lock(&self.shared).hang_up = true;
        if let Some(reader) = self.reader.take() {
            reader.join().expect("the reader thread");
        }
        lock(&self.writer).take();
        self.master.take();
    }

    /// Waits (polling the screen) until `done` holds; panics with the
    /// screen after `timeout`. Returns the screen that satisfied it.
    pub fn wait_for(
        &self,
        what: &str,
        timeout: Duration,
        mut done: impl FnMut(&str) -> bool,
    ) -> String {
        let start = Instant::now();
        loop {
            let screen = self.screen();
            if done(&screen) {
                return screen;
            }
            if start.elapsed() > timeout {
                panic!("timed out after {timeout:?} waiting for {what}; the screen:\n{screen}");
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Waits until the screen shows `text`.
    pub fn wait_text(&self, text: &str, timeout: Duration) -> String {
        self.wait_for(&format!("{text:?} on screen"), timeout, |s| {
            s.contains(text)
        })
    }

    /// Waits for the demo to exit and for its last output to be read.
    pub fn wait_exit(&mut self, timeout: Duration) -> portable_pty::ExitStatus {
        let start = Instant::now();
        let status = loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
                break status;
            }
            if start.elapsed() > timeout {
                panic!(
                    "the demo did not exit within {timeout:?}:\n{}",
                    self.screen()
                );
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        while !lock(&self.shared).closed && start.elapsed() < timeout {
            std::thread::sleep(Duration::from_millis(5));
        }
        if let Some(reader) = self.reader.take() {
            if reader.is_finished() {
                let _ = reader.join();
            }
        }
        status
    }

    /// The demo's process id.
    pub fn pid(&self) -> i32 {
        self.child
            .process_id()
            .and_then(|pid| i32::try_from(pid).ok())
            .expect("a pid")
    }

    /// The terminal's line discipline: (canonical input, echo).
    pub fn line_modes(&self) -> Option<(bool, bool)> {
        use nix::sys::termios::LocalFlags;
        let termios = self.master.as_ref()?.get_termios()?;
        Some((
            termios.local_flags.contains(LocalFlags::ICANON),
            termios.local_flags.contains(LocalFlags::ECHO),
        ))
    }
}

impl Drop for Demo {
    fn drop(&mut self) {
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// The value after `label` in axis `n`'s panel (from 1). Panels are laid
/// out left to right, top to bottom, so the n-th `label` on the screen is
/// axis n's.
pub fn field(screen: &str, label: &str, n: usize) -> Option<String> {
    let mut seen = 0;
    for line in screen.lines() {
        let mut rest = line;
        while let Some(at) = rest.find(label) {
            rest = &rest[at + label.len()..];
            seen += 1;
            if seen == n {
                return Some(
                    rest.trim_start()
                        .chars()
                        .take_while(|c| !c.is_whitespace() && !"│┃".contains(*c))
                        .collect(),
                );
            }
        }
    }
    None
}

/// A number after `label` in axis `n`'s panel.
pub fn number(screen: &str, label: &str, n: usize) -> Option<i64> {
    field(screen, label, n)?.parse().ok()
}

/// Axis `n`'s `Current Position:`.
pub fn position(screen: &str, axis: usize) -> i64 {
    number(screen, "Current Position:", axis)
        .unwrap_or_else(|| panic!("no position for axis {axis}:\n{screen}"))
}

/// Axis `n`'s `Steps to go:` countdown (0 exactly when it is idle).
pub fn to_go(screen: &str, axis: usize) -> i64 {
    number(screen, "Steps to go:", axis)
        .unwrap_or_else(|| panic!("no steps to go for axis {axis}:\n{screen}"))
}

/// Answers both prompts for the selected axis, each wait at most `timeout`.
pub fn enter_move(demo: &Demo, steps: i64, speed: u32, timeout: Duration) {
    demo.send(format!("{steps}\r").as_bytes());
    demo.wait_text("Enter speed:", timeout);
    demo.send(format!("{speed}\r").as_bytes());
    demo.wait_for("the prompt back at Enter steps:", timeout, |s| {
        !s.contains("Enter speed:")
    });
}

/// Answers the group prompts (`g`, then one line of steps per axis, then
/// the speed), each wait at most `timeout`.
pub fn enter_group_move(demo: &Demo, steps: &[i64], speed: u32, timeout: Duration) {
    demo.send(b"g");
    demo.wait_text("Group steps:", timeout);
    let line: Vec<String> = steps.iter().map(i64::to_string).collect();
    demo.send(format!("{}\r", line.join(" ")).as_bytes());
    demo.wait_text("Enter speed:", timeout);
    demo.send(format!("{speed}\r").as_bytes());
    demo.wait_for("the prompt back at Enter steps:", timeout, |s| {
        s.contains("Enter steps:") && !s.contains("Enter speed:")
    });
}

/// `--gcode`'s state word on screen (`State: Run`).
pub fn state(screen: &str) -> Option<String> {
    let at = screen.find("State: ")?;
    screen[at + 7..]
        .split_whitespace()
        .next()
        .map(str::to_string)
}

/// `--gcode`'s `line n of N`: n and N.
pub fn line_of(screen: &str) -> Option<(usize, usize)> {
    let at = screen.find("Progress: line ")?;
    let mut words = screen[at + 15..].split_whitespace();
    let n = words.next()?.parse().ok()?;
    let _of = words.next()?;
    Some((n, words.next()?.parse().ok()?))
}

/// `--gcode`'s position of axis `letter`: (mm as shown, steps); `None`
/// before the first reading.
pub fn read_position(screen: &str, letter: char) -> Option<(String, i64)> {
    let label = format!("{letter}: ");
    let line = screen
        .lines()
        .find_map(|line| line.find(&label).map(|at| &line[at + label.len()..]))?;
    let words: Vec<&str> = line.split_whitespace().collect();
    if words.get(1) != Some(&"mm") || words.get(3) != Some(&"steps") {
        return None;
    }
    Some((words[0].to_string(), words[2].parse().ok()?))
}

/// `--gcode`'s X and Y steps ((0, 0) before the first reading).
pub fn steps(screen: &str) -> (i64, i64) {
    let of = |letter| read_position(screen, letter).map_or(0, |(_, steps)| steps);
    (of('X'), of('Y'))
}

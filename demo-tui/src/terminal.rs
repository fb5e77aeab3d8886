//! The terminal: raw mode and the alternate screen while the demo runs,
//! and the normal screen back however it ends — `q`, an error (the
//! [`Session`] guard's `Drop`), a panic (the hook from
//! [`install_panic_hook`]), SIGTERM / SIGHUP / SIGINT (the [`Termination`]
//! the event loop checks every frame) or the terminal going away (its
//! [`Input`] hung up: a closed window, a killed tmux session, a dropped
//! ssh link).
//!
//! A hung-up terminal reads as ready and gives 0 bytes forever, and
//! crossterm's reader loops on that inside one `poll` call: the event loop
//! asks [`Input::wait`] before it lets crossterm read, and
//! [`end_on_hang_up`] ends the process should crossterm be caught reading
//! at the moment the terminal goes.

use std::fs::File;
use std::io::{self, IsTerminal, Stdout, Write};
use std::os::fd::{AsFd, OwnedFd};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossterm::event::{
    KeyboardEnhancementFlags, PopKeyboardEnhancementFlags, PushKeyboardEnhancementFlags,
};
use crossterm::terminal::{
    disable_raw_mode, enable_raw_mode, supports_keyboard_enhancement, EnterAlternateScreen,
    LeaveAlternateScreen,
};
use crossterm::{cursor, execute};
use ratatui::backend::CrosstermBackend;
use ratatui::Terminal;
use rustix::event::{PollFd, PollFlags, Timespec};

/// The terminal the demo draws on.
pub type DemoTerminal = Terminal<CrosstermBackend<Stdout>>;

/// Whether the terminal is in the demo's modes (restore has work to do).
static ENTERED: AtomicBool = AtomicBool::new(false);
/// Whether keyboard enhancement flags were pushed (and must be popped).
static KEYBOARD_PUSHED: AtomicBool = AtomicBool::new(false);

/// The terminal in raw mode on the alternate screen; dropping it restores
/// the terminal.
pub struct Session {
    /// Where frames are drawn.
    pub terminal: DemoTerminal,
    /// Where keys come from, watched for the terminal's end.
    pub input: Input,
}

impl Session {
    /// Enters raw mode and the alternate screen.
    pub fn enter() -> io::Result<Self> {
        let input = Input::open()?;
        enable_raw_mode()?;
        ENTERED.store(true, Ordering::SeqCst);
        let mut stdout = io::stdout();
        if let Err(e) = execute!(stdout, EnterAlternateScreen, cursor::Hide) {
            restore();
            return Err(e);
        }
        match Terminal::new(CrosstermBackend::new(stdout)) {
            Ok(terminal) => Ok(Self { terminal, input }),
            Err(e) => {
                restore();
                Err(e)
            }
        }
    }

    /// Asks the terminal to report key releases (and repeats) through the
    /// kitty keyboard protocol, if it supports it; tells whether it does.
    /// A terminal that does not answer the query costs up to 2 s here.
    pub fn request_key_release(&mut self) -> bool {
        if !matches!(supports_keyboard_enhancement(), Ok(true)) {
            return false;
        }
        let flags = KeyboardEnhancementFlags::DISAMBIGUATE_ESCAPE_CODES
            | KeyboardEnhancementFlags::REPORT_EVENT_TYPES;
        let pushed = execute!(io::stdout(), PushKeyboardEnhancementFlags(flags)).is_ok();
        KEYBOARD_PUSHED.store(pushed, Ordering::SeqCst);
        pushed
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        restore();
    }
}

/// Puts the terminal back as it was: keyboard flags popped, the alternate
/// screen left, the cursor shown, raw mode off. Safe to call more than
/// once and from a panic hook; errors are ignored (there is nowhere left
/// to report them).
pub fn restore() {
    if !ENTERED.swap(false, Ordering::SeqCst) {
        return;
    }
    let mut stdout = io::stdout();
    if KEYBOARD_PUSHED.swap(false, Ordering::SeqCst) {
        let _ = execute!(stdout, PopKeyboardEnhancementFlags);
    }
    let _ = execute!(stdout, LeaveAlternateScreen, cursor::Show);
    let _ = disable_raw_mode();
    let _ = stdout.flush();
}

/// Restores the terminal before a panic's message is printed, so the
/// message lands on the normal screen and the shell is usable after.
pub fn install_panic_hook() {
    let report = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        restore();
        report(info);
    }));
}

/// The exit status for a signal: 128 + its number, as a shell reports it.
pub fn signal_status(signal: i32) -> u8 {
    u8::try_from(128 + signal).unwrap_or(u8::MAX)
}

/// The exit status when the terminal went away: SIGHUP's, which is what
/// a terminal's end means.
pub const TERMINAL_GONE_STATUS: u8 = 129;

/// The signals that end the demo.
const ENDING_SIGNALS: [i32; 3] = [
    signal_hook::consts::SIGTERM,
    signal_hook::consts::SIGHUP,
    signal_hook::consts::SIGINT,
];

/// SIGTERM, SIGHUP or SIGINT, once one has arrived: the event loop ends
/// when it sees one, and the [`Session`] guard restores the terminal. A
/// second signal while the first is pending ends the process at once,
/// with that signal's status.
#[derive(Clone, Debug)]
pub struct Termination {
    /// The last ending signal's number, 0 before any.
    signal: Arc<AtomicUsize>,
}

impl Termination {
    /// Installs the handlers.
    pub fn install() -> io::Result<Self> {
        let pending = Arc::new(AtomicBool::new(false));
        let signal = Arc::new(AtomicUsize::new(0));
        for number in ENDING_SIGNALS {
            // The shutdown first: it acts only if an earlier signal set `pending`.
            signal_hook::flag::register_conditional_shutdown(
                number,
                i32::from(signal_status(number)),
                Arc::clone(&pending),
            )?;
            signal_hook::flag::register(number, Arc::clone(&pending))?;
            let value = usize::try_from(number).unwrap_or(usize::MAX);
            signal_hook::flag::register_usize(number, Arc::clone(&signal), value)?;
        }
        Ok(Self { signal })
    }

    /// The signal that asked the demo to end, if one has.
    pub fn signal(&self) -> Option<i32> {
        // Relaxed: the number is the whole message, nothing else is published with it.
        match self.signal.load(Ordering::Relaxed) {
            0 => None,
            number => i32::try_from(number).ok(),
        }
    }
}

/// What the terminal's input holds, as [`Input::wait`] found it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputState {
    /// Bytes to read.
    Ready,
    /// Nothing yet (or a signal interrupted the wait).
    Idle,
    /// The terminal hung up: nothing will ever come.
    Gone,
}

/// The terminal's input, the very file crossterm reads keys from (stdin
/// when it is a terminal, `/dev/tty` otherwise), watched for its end.
#[derive(Debug)]
pub struct Input {
    fd: OwnedFd,
}

impl Input {
    /// Opens the terminal's input as crossterm does.
    pub fn open() -> io::Result<Self> {
        let stdin = io::stdin();
        let fd = if stdin.is_terminal() {
            stdin.as_fd().try_clone_to_owned()?
        } else {
            File::open("/dev/tty")?.into()
        };
        Ok(Self { fd })
    }

    /// Waits up to `timeout` for input, or for the terminal's end.
    pub fn wait(&self, timeout: Duration) -> io::Result<InputState> {
        let revents = poll_input(&self.fd, PollFlags::IN, timeout)?;
        Ok(if revents.intersects(HUNG_UP) {
            InputState::Gone
        } else if revents.contains(PollFlags::IN) {
            InputState::Ready
        } else {
            InputState::Idle
        })
    }
}

/// What `poll` reports when the other side of a terminal is gone.
const HUNG_UP: PollFlags = PollFlags::HUP.union(PollFlags::ERR).union(PollFlags::NVAL);

/// `poll` on one file; a signal's interruption reads as nothing happened.
fn poll_input(fd: &OwnedFd, events: PollFlags, timeout: Duration) -> io::Result<PollFlags> {
    let timeout = Timespec::try_from(timeout).unwrap_or(Timespec {
        tv_sec: i64::MAX,
        tv_nsec: 0,
    });
    let mut fds = [PollFd::new(fd, events)];
    match rustix::event::poll(&mut fds, Some(&timeout)) {
        Ok(_) => Ok(fds[0].revents()),
        Err(rustix::io::Errno::INTR) => Ok(PollFlags::empty()),
        Err(error) => Err(error.into()),
    }
}

/// How often [`end_on_hang_up`] looks at the terminal.
const HANG_UP_CHECK: Duration = Duration::from_millis(200);

/// Watches the terminal from a thread of its own: once it hangs up, the
/// event loop has `grace` to end the demo in order (it sees the end before
/// every read); after that — crossterm was caught spinning on the dead
/// terminal — the terminal is restored as far as it can be, `last_words`
/// run (what must not be lost: a recording's end) and the process exits
/// with [`TERMINAL_GONE_STATUS`].
pub fn end_on_hang_up(
    input: &Input,
    grace: Duration,
    last_words: impl FnOnce() + Send + 'static,
) -> io::Result<()> {
    let fd = input.fd.try_clone()?;
    std::thread::Builder::new()
        .name("demo-hang-up".into())
        .spawn(move || {
            // Only the end is asked for: input pending does not wake this thread.
            loop {
                match poll_input(&fd, PollFlags::empty(), HANG_UP_CHECK) {
                    Ok(revents) if revents.intersects(HUNG_UP) => break,
                    Ok(_) => {}
                    // Nothing left to watch with.
                    Err(_) => return,
                }
            }
            std::thread::sleep(grace);
            // The session was left: the demo is ending on its own.
            if ENTERED.load(Ordering::SeqCst) {
                restore();
                last_words();
                std::process::exit(i32::from(TERMINAL_GONE_STATUS));
            }
        })?;
    Ok(())
}

/// A line on stderr, which may be a terminal that is gone: nothing to do
/// if it cannot be written (`eprintln!` would panic).
pub fn report(line: &str) {
    let _ = writeln!(io::stderr(), "demo-tui: {line}");
}

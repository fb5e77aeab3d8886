//! The terminal: raw mode and the alternate screen while the demo runs,
//! and the normal screen back however it ends — `q`, an error (the
//! [`Session`] guard's `Drop`), a panic (the hook from
//! [`install_panic_hook`]) or SIGTERM / SIGHUP / SIGINT (the flag from
//! [`termination_flag`], which the event loop checks every frame).

use std::io::{self, Stdout, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

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
}

impl Session {
    /// Enters raw mode and the alternate screen.
    pub fn enter() -> io::Result<Self> {
        enable_raw_mode()?;
        ENTERED.store(true, Ordering::SeqCst);
        let mut stdout = io::stdout();
        if let Err(e) = execute!(stdout, EnterAlternateScreen, cursor::Hide) {
            restore();
            return Err(e);
        }
        match Terminal::new(CrosstermBackend::new(stdout)) {
            Ok(terminal) => Ok(Self { terminal }),
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

/// A flag set by SIGTERM, SIGHUP or SIGINT; the event loop ends when it
/// is set, and the [`Session`] guard restores the terminal. A second
/// signal while the first is pending ends the process at once.
pub fn termination_flag() -> io::Result<Arc<AtomicBool>> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let flag = Arc::new(AtomicBool::new(false));
    for signal in [SIGTERM, SIGHUP, SIGINT] {
        signal_hook::flag::register_conditional_shutdown(signal, 1, Arc::clone(&flag))?;
        signal_hook::flag::register(signal, Arc::clone(&flag))?;
    }
    Ok(flag)
}

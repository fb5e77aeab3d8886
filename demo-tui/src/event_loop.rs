//! The event loop: input as it comes, frames at a steady rate, and a screen
//! that never freezes.
//!
//! Two threads share the work:
//!
//! ```text
//! UI thread:      terminal input ─► keys ──channel──►  app thread
//!                 frame tick ─► draw the latest view ◄── App snapshot
//! app thread:     keys, ticks ─► App (update, pure) ─► effects
//!                 effects ─► effect::run (backend calls, may block) ─► outcomes ─► App
//!                 frames ─► effect::read_frame (backend) ─► App
//! ```
//!
//! Only the app thread touches the backend: a serial board that is slow to
//! answer (a call may wait for its timeout, several seconds in all) holds up
//! the app thread, never the screen. The UI thread keeps drawing the last
//! view at the frame rate, says that the board is slow after
//! [`SLOW_BACKEND`], and `q` or Ctrl-C quits even then.
//!
//! The UI thread sleeps in `poll(2)` on the terminal ([`Input::wait`])
//! until the next frame is due, so an idle demo costs next to nothing, and
//! lets crossterm read only a terminal that is there: a terminal that hangs
//! up ends the loop ([`Ending::TerminalGone`]). While anything moves (or a
//! key was just pressed) frames come every [`ACTIVE_FRAME`] (≈ 33 fps),
//! otherwise every [`IDLE_FRAME`].

use std::io;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crossterm::event::{self, Event, KeyCode, KeyEvent, KeyEventKind, KeyModifiers};

use crate::app::App;
use crate::backend::Machine;
use crate::effect::{self, Effect};
use crate::terminal::{Input, InputState, Session, Termination};
use crate::ui;

/// The frame interval while anything moves.
pub const ACTIVE_FRAME: Duration = Duration::from_millis(30);
/// The frame interval while everything is still.
pub const IDLE_FRAME: Duration = Duration::from_millis(250);
/// Input is echoed at once, but frames never come closer than this.
const MIN_FRAME_GAP: Duration = Duration::from_millis(8);
/// A backend call that has not answered after this long is shown as slow.
pub const SLOW_BACKEND: Duration = Duration::from_millis(300);

/// What ended the loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ending {
    /// The person quit (`q`, Ctrl-C).
    Quit,
    /// A signal (its number) asked the demo to end.
    Signal(i32),
    /// The terminal went away (hung up): no key will ever come.
    TerminalGone,
}

/// Options of the loop.
#[derive(Clone, Copy, Debug, Default)]
pub struct LoopOptions {
    /// Ask the terminal for key-release events after the first frame.
    pub key_release: bool,
    /// Panic this long after the start (the test suite's check that a
    /// panic restores the terminal).
    pub panic_after: Option<Duration>,
}

/// What the UI thread tells the app thread.
enum ToApp {
    Key(KeyEvent, Instant),
    /// Draw soon: sample the backend for a frame.
    Frame,
    /// Whether the terminal reports key releases.
    KeyRelease(bool),
}

/// What the app thread shows the UI thread.
struct View {
    app: App,
    /// Set when the app asked to end the demo ([`Effect::Quit`]).
    quit: bool,
    /// When the app thread began the backend work it is still doing.
    busy_since: Option<Instant>,
}

/// Runs until the person quits, a signal arrives or the terminal goes. The machine moves to
/// the app thread; when the demo ends while a backend call still waits,
/// that thread is left to finish on its own.
pub fn run(
    session: &mut Session,
    app: App,
    machine: Box<dyn Machine + Send>,
    termination: &Termination,
    options: LoopOptions,
) -> io::Result<Ending> {
    let view = Arc::new(Mutex::new(View {
        app: app.clone(),
        quit: false,
        busy_since: None,
    }));
    let (to_app, inbox) = mpsc::channel();
    {
        let view = Arc::clone(&view);
        std::thread::Builder::new()
            .name("demo-app".into())
            .spawn(move || app_thread(app, machine, &inbox, &view))?;
    }
    ui_thread(session, &view, &to_app, termination, options)
}

/// The app thread: the app's update, and every backend call, happen here.
fn app_thread(
    mut app: App,
    machine: Box<dyn Machine + Send>,
    inbox: &Receiver<ToApp>,
    view: &Mutex<View>,
) {
    let machine = machine.as_ref();
    let publish = |app: &App, quit: bool, busy: Option<Instant>| {
        let mut view = view.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        view.app.clone_from(app);
        view.quit |= quit;
        view.busy_since = busy;
    };
    loop {
        let timeout = app
            .next_deadline()
            .map_or(IDLE_FRAME, |d| d.saturating_duration_since(Instant::now()));
        let message = match inbox.recv_timeout(timeout) {
            Ok(message) => Some(message),
            Err(RecvTimeoutError::Timeout) => None,
            Err(RecvTimeoutError::Disconnected) => return,
        };
        let started = Instant::now();
        set_busy(view, Some(started));
        let mut quit = false;
        match message {
            Some(ToApp::Key(key, at)) => {
                for effect in app.on_key(key, at) {
                    match effect {
                        Effect::Quit => quit = true,
                        Effect::Send(command) => {
                            app.on_outcome(effect::run(command, machine), at);
                        }
                    }
                }
            }
            Some(ToApp::Frame) => {
                let now = Instant::now();
                let reading = effect::read_frame(machine, app.axes.len(), app.wants_edges());
                app.on_frame(now, reading);
            }
            Some(ToApp::KeyRelease(on)) => app.key_release = on,
            None => {}
        }
        app.on_tick(Instant::now());
        publish(&app, quit, None);
    }
}

fn set_busy(view: &Mutex<View>, busy: Option<Instant>) {
    view.lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
        .busy_since = busy;
}

/// The UI thread: input and frames; it never waits on the backend.
///
/// A terminal that hangs up can fail a draw or a read before the loop sees
/// the hang-up or its SIGHUP: such an error is the ending it stands for
/// (the signal, or the terminal gone), not a failure of the demo.
fn ui_thread(
    session: &mut Session,
    view: &Mutex<View>,
    to_app: &Sender<ToApp>,
    termination: &Termination,
    options: LoopOptions,
) -> io::Result<Ending> {
    let error = match ui_loop(session, view, to_app, termination, options) {
        Ok(ending) => return Ok(ending),
        Err(error) => error,
    };
    if let Some(signal) = termination.signal() {
        return Ok(Ending::Signal(signal));
    }
    match session.input.wait(Duration::ZERO) {
        Ok(InputState::Gone) | Err(_) => Ok(Ending::TerminalGone),
        Ok(_) => Err(error),
    }
}

fn ui_loop(
    session: &mut Session,
    view: &Mutex<View>,
    to_app: &Sender<ToApp>,
    termination: &Termination,
    options: LoopOptions,
) -> io::Result<Ending> {
    let started = Instant::now();
    let mut next_frame = started;
    let mut last_frame = started;
    let mut first_frame = true;
    loop {
        let now = Instant::now();
        let (mut shown, quit, busy_since) = {
            let view = view.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
            (view.app.clone(), view.quit, view.busy_since)
        };
        let slow = busy_since.filter(|since| now.duration_since(*since) >= SLOW_BACKEND);
        if quit {
            return Ok(Ending::Quit);
        }
        if now >= next_frame {
            if let Some(since) = slow {
                shown.fault = Some(format!(
                    "the board is slow: no answer for {:.1} s (q quits)",
                    now.duration_since(since).as_secs_f64()
                ));
            }
            session.terminal.draw(|frame| ui::render(frame, &shown))?;
            // A new sample for the next frame (skipped while one is pending).
            if busy_since.is_none() {
                let _ = to_app.send(ToApp::Frame);
            }
            last_frame = now;
            let interval = if shown.active(now) || slow.is_some() {
                ACTIVE_FRAME
            } else {
                IDLE_FRAME
            };
            next_frame += interval;
            if next_frame <= now {
                next_frame = now + interval;
            }
            if first_frame {
                first_frame = false;
                if options.key_release {
                    let on = session.request_key_release();
                    let _ = to_app.send(ToApp::KeyRelease(on));
                }
            }
        }
        if let Some(signal) = termination.signal() {
            return Ok(Ending::Signal(signal));
        }
        if let Some(after) = options.panic_after {
            if now.duration_since(started) >= after {
                panic!("demo-tui: --test-panic-after-ms: a deliberate panic for the test suite");
            }
        }
        let deadline = shown
            .next_deadline()
            .map_or(next_frame, |d| d.min(next_frame));
        let timeout = deadline
            .saturating_duration_since(Instant::now())
            .min(ACTIVE_FRAME);
        match wait_for_input(&session.input, timeout)? {
            None => return Ok(Ending::TerminalGone),
            Some(false) => continue,
            Some(true) => {}
        }
        loop {
            if let Event::Key(key) = event::read()? {
                // Quitting never waits for the backend.
                if slow.is_some() && is_quit(&key) {
                    return Ok(Ending::Quit);
                }
                if to_app.send(ToApp::Key(key, Instant::now())).is_err() {
                    return Ok(Ending::Quit);
                }
            }
            match wait_for_input(&session.input, Duration::ZERO)? {
                None => return Ok(Ending::TerminalGone),
                Some(false) => break,
                Some(true) => {}
            }
        }
        // Echo the input at the next chance, not at the next tick.
        next_frame = next_frame.min(last_frame + MIN_FRAME_GAP);
    }
}

/// Whether an event can be read at once, waiting up to `timeout` for one;
/// `None` once the terminal is gone. crossterm is let read only a terminal
/// that is there: on a hung-up one it would spin inside `poll`, reading 0
/// bytes, and never return ([`crate::terminal::end_on_hang_up`] covers the moment
/// between the check and the read).
fn wait_for_input(input: &Input, timeout: Duration) -> io::Result<Option<bool>> {
    if input.wait(Duration::ZERO)? == InputState::Gone {
        return Ok(None);
    }
    // Events crossterm has read already (keys typed while it waited for the
    // answer to a query, several keys in one read) wait in its queue.
    if poll(Duration::ZERO)? {
        return Ok(Some(true));
    }
    match input.wait(timeout)? {
        InputState::Gone => Ok(None),
        InputState::Idle => Ok(Some(false)),
        InputState::Ready => Ok(Some(poll(Duration::ZERO)?)),
    }
}

/// `q` or Ctrl-C, pressed.
fn is_quit(key: &KeyEvent) -> bool {
    key.kind != KeyEventKind::Release
        && (key.code == KeyCode::Char('q')
            || (key.modifiers.contains(KeyModifiers::CONTROL)
                && matches!(key.code, KeyCode::Char('c' | 'C'))))
}

/// `event::poll`, with a signal's interruption read as "no event".
fn poll(timeout: Duration) -> io::Result<bool> {
    match event::poll(timeout) {
        Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(false),
        other => other,
    }
}

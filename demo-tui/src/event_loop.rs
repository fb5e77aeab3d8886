//! The event loop: input as it comes, frames at a steady rate.
//!
//! The loop sleeps in `crossterm::event::poll` until the next frame is due
//! (or a lone key's wait ends), so an idle demo costs next to nothing. A
//! frame samples every axis and draws; while anything moves (or a key was
//! just pressed) frames come every [`ACTIVE_FRAME`] (≈ 33 fps), otherwise
//! every [`IDLE_FRAME`]. The
//! cogs run on their own threads: the frame rate does not depend on them.

use std::io;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crossterm::event::{self, Event};

use crate::app::App;
use crate::backend::Machine;
use crate::terminal::Session;
use crate::ui;

/// The frame interval while anything moves.
pub const ACTIVE_FRAME: Duration = Duration::from_millis(30);
/// The frame interval while everything is still.
pub const IDLE_FRAME: Duration = Duration::from_millis(250);
/// Input is echoed at once, but frames never come closer than this.
const MIN_FRAME_GAP: Duration = Duration::from_millis(8);

/// What ended the loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ending {
    /// The person quit (`q`, Ctrl-C).
    Quit,
    /// A signal asked the demo to end.
    Signal,
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

/// Runs until the person quits or a signal arrives.
pub fn run(
    session: &mut Session,
    app: &mut App,
    machine: &dyn Machine,
    signalled: &AtomicBool,
    options: LoopOptions,
) -> io::Result<Ending> {
    let started = Instant::now();
    let mut next_frame = started;
    let mut last_frame = started;
    let mut first_frame = true;
    loop {
        let now = Instant::now();
        if now >= next_frame {
            app.sample(now, machine);
            session.terminal.draw(|frame| ui::render(frame, app))?;
            last_frame = now;
            let interval = if app.active(now) {
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
                    app.key_release = session.request_key_release();
                }
            }
        }
        if app.quit {
            return Ok(Ending::Quit);
        }
        if signalled.load(Ordering::Relaxed) {
            return Ok(Ending::Signal);
        }
        if let Some(after) = options.panic_after {
            if now.duration_since(started) >= after {
                panic!("demo-tui: --test-panic-after-ms: a deliberate panic for the test suite");
            }
        }
        let deadline = app
            .next_deadline()
            .map_or(next_frame, |d| d.min(next_frame));
        let timeout = deadline.saturating_duration_since(Instant::now());
        if poll(timeout)? {
            loop {
                if let Event::Key(key) = event::read()? {
                    app.on_key(key, Instant::now(), machine);
                }
                if !poll(Duration::ZERO)? {
                    break;
                }
            }
            // Echo the input at the next chance, not at the next tick.
            next_frame = next_frame.min(last_frame + MIN_FRAME_GAP);
        }
        app.on_tick(Instant::now(), machine);
    }
}

/// `event::poll`, with a signal's interruption read as "no event".
fn poll(timeout: Duration) -> io::Result<bool> {
    match event::poll(timeout) {
        Err(e) if e.kind() == io::ErrorKind::Interrupted => Ok(false),
        other => other,
    }
}

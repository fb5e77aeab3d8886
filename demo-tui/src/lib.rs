//! # demo-tui — cogstep's terminal demo
//!
//! Emulated P2 stepper axes (or a real board over a serial port), driven
//! live: the reference demo's `Enter steps:` / `Enter speed:` prompts, every
//! axis's position, STM, mode and move figures, the velocity S-curve as it
//! happens, a stop key, an emergency stop, and jogging by holding a key.
//!
//! It follows ratatui's app pattern; a key press travels:
//!
//! ```text
//! UI thread:  crossterm event ─► event_loop ──keys──► app thread
//!             frame tick ─► ui::render (pure) of the app's latest view
//! app thread: app (update, pure: keys ─► effects) ─► effect::run
//!             (AxisContract calls) ─► backend (Machine: emulated hub |
//!             serial board) ─► cogs; outcomes ─► app (update);
//!             effect::read_frame ─► app (readouts, velocity traces) ─► the view
//! ```
//!
//! Only the app thread waits on the backend, so a slow or silent board
//! never freezes the screen: it says so, and `q` still quits.
//!
//! - [`cli`]: the command line.
//! - [`backend`]: the [`backend::Machine`] trait over the emulated hub and
//!   a serial board: [`driver::AxisContract`] handles plus the extra
//!   figures and capabilities.
//! - [`prompt`]: the two questions and the answers they accept.
//! - [`app`]: the state, and the input model (events → state + effects),
//!   which never touches the backend.
//! - [`effect`]: what the app asks of the backend, run against a
//!   [`backend::Machine`], and what comes back (outcomes, frame readings).
//! - [`ui`]: rendering (state → frame), a pure function.
//! - [`motor_view`]: `--motor`, a rotor model behind an axis's pins.
//! - [`program`]: `--gcode FILE --machine M.toml`: the program read,
//!   checked and drawn before anything moves; [`program_backend`]: the
//!   emulated hub running it (a worker thread feeds the lines), and
//!   [`app::program`]: its keys and screen state; [`grbl_program`]:
//!   `--gcode FILE --serial PORT --dialect grbl`, the program streamed to
//!   a grbl board by character counting.
//! - [`event_loop`]: input as it comes, frames at a steady rate, backend
//!   calls on their own thread.
//! - [`terminal`]: raw mode and the alternate screen, restored on every
//!   way out (quit, error, panic, a signal, the terminal hanging up).
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod app;
pub mod backend;
pub mod cli;
pub mod effect;
pub mod event_loop;
pub mod grbl_program;
pub mod motor_view;
pub mod program;
pub mod program_backend;
pub mod prompt;
pub mod terminal;
pub mod ui;

//! # spreadsheet-export — a move, one row per step
//!
//! The P2 driver's author checked his S-curve in a spreadsheet: one row per
//! motor step with its angle, velocity and delay. This crate produces that
//! table from cogstep's own motion code (`driver::profile`), so what you
//! export is exactly what an emulated or real cog would run, and it checks
//! whether a given motor can follow the move.
//!
//! The pieces, in the order a row travels through them:
//!
//! ```text
//! cli (flags) ─► profiles (a driver Profile) ─► table (rows: time, acceleration)
//!     ─► motor (torque check, optional) ─► dynamics (the rotor, optional)
//!     ─► csv_out | xlsx_out (the table)   plot (PNG/SVG, optional)
//! waveform (--vcd: the same move on an emulated cog, its pin edges as VCD)
//! ```
//!
//! - [`cli`]: the command line (clap derive) and its validation.
//! - [`profiles`]: builds the chosen [`driver::profile::Profile`].
//! - [`table`]: turns steps into [`table::Row`]s (edge time in integer ticks,
//!   acceleration between adjacent steps), decimation for charts, summary.
//! - [`motor`]: `MOTOR.toml`, the torque–speed curve and the margin per step.
//! - [`dynamics`]: `--dynamics`, the rotor model of [`driver::motor`] fed
//!   the rows: rotor angle, lag, synchronism.
//! - [`compare`]: the `compare` subcommand: every profile on one move and
//!   motor, and the fastest setting that keeps synchronism.
//! - [`csv_out`], [`xlsx_out`], [`plot`]: the outputs.
//! - [`waveform`]: `--vcd`, the move run on the hub in virtual time.
//! - [`together`]: `--together`, a coordinated move of several axes on the
//!   hub: one position column per axis against time and the deviation from
//!   the line.
//! - [`output`]: files appear whole or not at all (temporary file, then
//!   rename, removed on a failed write or a stopping signal); FIFOs and
//!   devices are written in place; two outputs naming one file are refused.
//! - [`progress`]: a one-line progress report when stderr is a terminal.
//! - [`gcode`]: the `gcode` subcommand: a G-code program through the
//!   look-ahead planner and the path runner (`cogstep_motion::planner`),
//!   one row per tick at which an axis steps, with its VCD and plot.
//! - [`export`]: one streaming pass that ties them together; `main` is a thin
//!   shell around it.
//!
//! Everything streams: a move of any length runs in constant memory (the XLSX
//! step sheet goes through `rust_xlsxwriter`'s constant-memory mode).
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod cli;
pub mod compare;
pub mod csv_out;
pub mod dynamics;
pub mod error;
pub mod export;
pub mod gcode;
pub mod motor;
pub mod output;
pub mod plot;
pub mod profiles;
pub mod progress;
pub mod report;
pub mod table;
pub mod together;
pub mod waveform;
pub mod xlsx_out;

pub use error::ExportError;
pub use export::{run, Outcome};

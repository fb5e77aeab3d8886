//! # cogstep-firmware — cogstep on a microcontroller, board-independent
//!
//! The part of the firmware that every board shares: protocol v1 on a
//! byte stream, up to [`AXES_MAX`] axes, and the step scheduler that a
//! board's hardware timer interrupt runs. A board is a thin layer that
//! implements [`Hardware`] (a 64-bit tick counter, a way to run the step
//! interrupt now, GPIO) and calls three functions:
//!
//! ```text
//! UART byte ─► Firmware::feed ─► driver::serial::Session ─► Board (axes)
//!                                          │                  │ commands at CT now
//!                                          ▼                  ▼
//!                               replies ─► UART        driver::AxisCore
//!                                                             │ next event CT
//! timer interrupt ─► Firmware::step_interrupt ─► edges ─► Hardware::set_pin
//!                      └─► returns the next CT ─► the board arms its timer
//! ```
//!
//! A board whose pins follow a queue of edges with their CTs, filled ahead
//! of the clock (the Pico's main loop), runs each wake-up with
//! [`Firmware::step_interrupt_ahead`] instead: a step pulse's falling edge
//! then goes out with its rising edge ([`Hardware::set_pin_at`]), and with
//! [`Firmware::step_interrupt_ahead_trains`] a train's steps go out up to
//! the board's frontier in one call, not one wake-up each.
//!
//! - [`scheduler`]: [`Firmware`], the [`driver::serial::Board`] the session
//!   talks to, and the step interrupt over all axes.
//! - [`axis`]: one axis: the driver's `AxisCore` (the same core the host's
//!   cogs run: everything the axis decides, time in and edges out), run a
//!   little ahead of the clock, and its edges queued until their CT.
//! - [`fast`]: the step interrupt's fast path for one axis at speed.
//! - [`inputs`]: stop and switch inputs on a board whose cores run ahead
//!   of its pins: each axis's recent steps ([`StepHistory`]), so that a
//!   switch change latches the step on which it happened. A board that
//!   reads switches names them ([`Hardware::switch_pins`]); then `H`, `K`
//!   and `C` work as on the hub, elsewhere they answer `error:1 not
//!   supported`. A board's stop input and the protocol's `S`/`R` level
//!   combine: the axis runs while both are high.
//! - `group`: coordinated moves (`G`): every member reserved and started
//!   on one CT in one critical section, and a member's stop passed on to
//!   the whole line by the step interrupt ([`Firmware::start_group`]).
//! - [`merge`]: a board's step edges in one CT order, each axis's staged
//!   in its own and merged after each wake-up ([`merge::EdgeMerge`], the
//!   Pico's timer build).
//! - [`grbl`]: grbl 1.1's motion ([`PathMotion`]): X, Y and Z on the
//!   motion crate's look-ahead `PathRunner`, its edges pushed onto the
//!   axes a few ms ahead of the clock, for the protocol crate's
//!   `GrblSession` (a board runs one or the other dialect).
//!
//! Everything here is `no_std`, allocation-free and free of `unsafe`; the
//! axes sit behind [`critical_section::Mutex`]es, so the step interrupt and
//! the main loop (which runs the protocol) can share them on one core.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod axis;
pub mod fast;
pub mod grbl;
mod group;
pub mod inputs;
pub mod merge;
pub mod scheduler;

pub use axis::{core_config, AxisRunner, Output, RunAheadTicks, TrainRises, Variant, Work};
pub use fast::{FastEvent, FastTrain};
pub use grbl::PathMotion;
pub use inputs::{StepHistory, StepRun};
pub use scheduler::{Firmware, FirmwareAxis, Hardware, AXES_MAX};

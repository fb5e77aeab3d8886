//! # driver — cogstep's motion core, hub and cogs
//!
//! A move command follows one path through this crate, and the modules are
//! named after its stages:
//!
//! ```text
//! move(speed, steps) ─► mailbox ─► cog ─► profile (angles, velocity)
//!     ─► CORDIC (cordic-core: QROTATE, QDIV) ─► step timing (ticks) ─► pins
//! ```
//!
//! - [`profile`] (`no_std`): everything a cog computes between "a move
//!   command arrived" and "the next step is due in N clock ticks": the P2
//!   cosine S-curve ([`profile::scurve`]) with its live re-planning, and the
//!   comparison profiles (Austin, Leib, exact trapezoid).
//!
//! - [`axis`] (`no_std`): the axis contract every backend implements.
//!
//! - [`axis_core`] (`no_std`): everything one axis decides — admission of
//!   commands, the step schedule, pulse and direction timing, stop pin,
//!   held moves, jogs, emergency stop, mode bits, position and the step
//!   ledger — time in, edges out. The host's cogs and a firmware's timer
//!   interrupt run the same [`AxisCore`].
//!
//! With the default `std` feature the crate also carries the hub and its
//! cogs (without it, it is the allocation-free `no_std` core):
//!
//! - [`Hub`] (`hub`): shared memory, the system counter, 64 pins, the cogs;
//!   [`Axis`] is a handle on one cog.
//! - `mailbox`: each axis's hub memory, lock-free, and the command handoff
//!   protocol (model-checked with loom).
//! - `cog`: the worker thread that owns one axis.
//! - [`pins`]: the pin bank and the `sd` / `cc` output variants.
//! - [`switch`]: simulated switches, driven by where an axis physically is.
//! - `clock`: virtual (deterministic) or real time ([`ClockMode`]).
//! - [`trace`]: edge rings, the in-memory trace, VCD files and the session
//!   recorder.
#![cfg_attr(not(feature = "std"), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod axis;
pub mod axis_core;
pub mod motor;
pub mod profile;
pub mod serial;

#[cfg(feature = "std")]
mod clock;
#[cfg(feature = "std")]
mod cog;
#[cfg(feature = "std")]
mod hub;
#[cfg(feature = "std")]
mod mailbox;
#[cfg(feature = "std")]
pub mod pins;
#[cfg(feature = "std")]
pub mod switch;
#[cfg(feature = "std")]
mod sync;
#[cfg(feature = "std")]
pub mod trace;

pub use axis::{AxisContract, AxisError, AxisState, AxisStatus, Direction, Mode};
pub use axis::{HomeConfig, HomeReport, LimitStatus, LimitTrip};
pub use axis_core::{AxisCore, AxisCoreConfig, CoreCommand, StepLedger};
pub use axis_core::{Edge, Outputs};
#[cfg(feature = "std")]
pub use clock::ClockMode;
#[cfg(feature = "std")]
pub use hub::{Axis, Hub, HubConfig, HubError};

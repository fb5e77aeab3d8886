//! # cogstep-motion — what one axis computes and decides (`no_std`, no alloc)
//!
//! The part of cogstep that runs everywhere: on the host's cogs, in the
//! board simulator and in a microcontroller's timer interrupt. It has no
//! threads, clocks, atomics or allocation: time comes in as plain values,
//! edges go out as plain values.
//!
//! ```text
//! move(speed, steps) ─► axis_core (admission, schedule, pins' edges)
//!     ─► profile (angles, velocity) ─► CORDIC (cordic-core) ─► ticks
//! ```
//!
//! - [`profile`]: everything between "a move command arrived" and "the
//!   next step is due in N clock ticks": the P2 cosine S-curve
//!   ([`profile::scurve`]) with its live re-planning, and one axis's
//!   signed motion ([`profile::motion`]). The comparison ramps (Austin,
//!   Leib, the exact trapezoid) are in the `cogstep-ramps` crate.
//! - [`axis`]: the axis contract every backend implements
//!   ([`AxisContract`]), its errors, states and mode bits.
//! - [`refusal`]: why an axis refuses, as one kind with stable codes and
//!   tokens ([`Refusal`]), which every link carries.
//! - [`planner`]: look-ahead over a queue of coordinated lines: junction
//!   speeds by junction deviation, cosine ramps with zero acceleration at
//!   every junction (planning only; not run by the axis cores yet).
//! - [`axis_core`]: everything one axis decides — admission of commands,
//!   the step schedule, pulse and direction timing, stop pin, held moves,
//!   jogs, emergency stop, mode bits, position and the step ledger — time
//!   in, edges out ([`AxisCore`]).
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
// The planner's square root from `core` (feature `core-sqrt`, the firmware's).
#![cfg_attr(feature = "core-sqrt", feature(core_float_math))]
#![warn(missing_docs)]

pub mod axis;
pub mod axis_core;
pub mod planner;
pub mod profile;
pub mod refusal;

pub use axis::{AxisContract, AxisError, AxisState, AxisStatus, Direction, Mode};
pub use axis_core::{AxisCore, AxisCoreConfig, CoreCommand, Edge, Outputs, StepLedger, StepTrain};
pub use refusal::{Refusal, RefusalValues};

//! # cogstep-hub — the emulated P2 hub: cogs, mailboxes, pins and clocks (std)
//!
//! The host runs each axis's [`AxisCore`](cogstep_motion::AxisCore) on a
//! worker thread, a "cog", as the P2 runs each motor on a cog:
//!
//! ```text
//! Axis::move_steps ─► mailbox (lock-free slot, the cog's answer) ─► cog
//!     ─► AxisCore (cogstep-motion) ─► edges ─► pins ─► trace / VCD
//! ```
//!
//! - [`Hub`] (`hub`): shared memory, the system counter, 64 pins, the cogs;
//!   [`Axis`] is a handle on one cog and implements the
//!   [`AxisContract`](cogstep_motion::AxisContract).
//! - `mailbox`: each axis's hub memory, lock-free, and the command handoff
//!   protocol (model-checked with loom: `RUSTFLAGS="--cfg loom"`).
//! - `status`: what a cog publishes, read as one snapshot (a seqlock,
//!   model-checked with loom).
//! - `cog`: the worker thread that owns one axis, a thin loop around its
//!   `AxisCore`.
//! - [`pins`]: the pin bank and the `sd` / `cc` output variants.
//! - [`switch`]: simulated switches, driven by where an axis physically is.
//! - `clock`: virtual (deterministic) or real time ([`ClockMode`]).
//! - [`trace`]: edge rings, the in-memory trace, VCD files and the session
//!   recorder.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod axis;
mod clock;
mod cog;
mod hub;
mod mailbox;
pub mod path;
pub mod pins;
mod status;
pub mod switch;
mod sync;
pub mod trace;

pub use axis::Axis;
pub use clock::ClockMode;
pub use hub::{Hub, HubConfig, HubError};
pub use path::{
    PathControl, PathError, PathFault, PathJob, PathMachine, PathProgress, PATH_QUEUE_LINES,
};

//! # planner — look-ahead over a queue of coordinated lines (`no_std`, no alloc)
//!
//! Continuous motion: lines in step space go into a
//! fixed-capacity queue ([`Planner`]), and every push re-plans each line's
//! entry, cruise and exit speed so that consecutive lines join at speed,
//! with **zero acceleration at every junction**, within the feed, every
//! axis's speed and acceleration, the corner rule and the rule that the
//! machine can always stop by the end of what is queued.
//!
//! ```text
//! Line ─► queue (Planner::push) ─► junction limit (junction)
//!       ─► backward + forward passes ─► Plan per line (ramp: cosine ramps)
//!       ─► PathRunner (run): every axis's edges in time order
//! ```
//!
//! - [`ramp`]: the junction ramp `v(θ) = v0 + (v1 − v0)·(1 − cos θ)/2`,
//!   the seed's cosine in time, its acceleration (zero at both ends), peak and jerk;
//!   [`ramp_distance`] and [`max_entry_speed`].
//! - [`junction`]: grbl's junction deviation in step space, with
//!   Klipper's chord bound, and why it was chosen over a velocity-jump
//!   limit.
//! - [`queue`]: the queue, the passes, exact stop and blending, frozen
//!   lines, overrides.
//! - [`run`]: the runner: a timeline of the frozen lines' plans, every
//!   axis's edges at the half-step crossings of its line, hold along the
//!   path, resume, cancel (see `docs/planner.md`); `ramp_time`: when a
//!   cosine ramp has covered a distance (Kepler's equation).

pub mod junction;
pub mod queue;
pub mod ramp;
mod ramp_time;
pub mod run;
mod sqrt;

#[cfg(test)]
mod run_tests;
#[cfg(test)]
mod tests;

pub use junction::{chord_speed, junction_deviation_speed};
pub use queue::{
    Blending, Line, Machine, MachineError, Plan, Planner, PushError, Segment, MAX_AXES,
};
pub use ramp::{
    max_entry_speed, peak_acceleration, peak_jerk, ramp_distance, ramp_length, ramp_time,
};
pub use run::{PathEdge, PathRunner, PathState, RunError};

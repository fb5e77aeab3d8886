//! # cogstep-ramps — the comparison ramps (`no_std`)
//!
//! The profiles cogstep's S-curve is measured against, behind the same
//! [`Profile`] trait as the S-curve (`cogstep-motion`):
//!
//! | module | profile |
//! |---|---|
//! | [`austin`] | Austin's (2004) real-time linear ramp, in `f64` and in 24.8 fixed point |
//! | [`leib`] | the Leib (Eiderman) ramp |
//! | [`trapezoid`] | the exact trapezoid from its closed form: the reference |
//! | [`lookahead`] | a grbl-style trapezoid look-ahead over a stream of lines: the comparison for cogstep's planner |
//!
//! Only their users (the export's comparison, the benchmarks, the virtual
//! motor's tests) build this crate and its `fixed` dependency.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod austin;
pub mod leib;
pub mod lookahead;
pub mod trapezoid;

#[cfg(test)]
mod test_support;

// The trait and types every ramp implements, under the names the ramps'
// files use (`super::Profile`).
use cogstep_motion::profile::{Phase, PlanError, Profile, Step};

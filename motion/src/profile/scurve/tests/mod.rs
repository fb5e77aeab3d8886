//! Tests of the S-curve: planning, both arithmetic modes, re-planning.

extern crate std;
use std::vec::Vec;

use super::*;
use crate::profile::{Phase, PlanError, Profile, Step};
use proptest::prelude::*;

mod arithmetic;
mod fast_paths;
mod planning;
mod reference_cog;
mod replan;

fn config(arithmetic: Arithmetic) -> ScurveConfig {
    ScurveConfig {
        arithmetic,
        ..ScurveConfig::default()
    }
}

fn steps_of(arithmetic: Arithmetic, speed: u32, steps: u32) -> Vec<Step> {
    SCurve::new(config(arithmetic), speed, steps)
        .expect("valid move")
        .collect()
}

/// The largest change of velocity between two neighbouring positions of the
/// ramp a move of this speed uses: the most a single step may change it.
fn ramp_velocity_step(arithmetic: Arithmetic, speed: u32) -> f64 {
    let steps = steps_of(arithmetic, speed, speed.saturating_mul(4) / 10 + 100);
    steps
        .windows(2)
        .map(|w| (w[1].velocity_steps_per_s - w[0].velocity_steps_per_s).abs())
        .fold(0.0, f64::max)
}

//! Builds the driver profile that `--profile` names. Adding a profile: a
//! variant in [`crate::cli::ProfileKind`] and an arm in [`build`].

use driver::profile::austin::AustinProfile;
use driver::profile::leib::LeibProfile;
use driver::profile::scurve::{Arithmetic, Plan, SCurve, ScurveConfig};
use driver::profile::trapezoid::Trapezoid;
use driver::profile::Profile;

use crate::cli::{ProfileKind, Request};
use crate::error::ExportError;
use crate::table::EdgeTiming;

/// A profile ready to yield its steps, with what is known before the first.
pub struct Built {
    /// The steps.
    pub profile: Box<dyn Profile>,
    /// The S-curve's plan (`None` for the other profiles).
    pub plan: Option<Plan>,
    /// The fastest the move will run, steps/s: the S-curve's planned top
    /// speed, or the requested speed for the other profiles.
    pub top_speed_steps_per_s: f64,
    /// How its edges follow its delays: the reference cog's for
    /// `p2-exact`, the delay itself for every other profile.
    pub edge_timing: EdgeTiming,
}

/// Builds the profile for a checked request.
pub fn build(request: &Request) -> Result<Built, ExportError> {
    let (clkfreq, speed, steps) = (request.clkfreq, request.speed_steps_per_s, request.steps);
    let profile: Box<dyn Profile> = match request.profile {
        ProfileKind::P2 => return scurve(request, Arithmetic::Smooth),
        ProfileKind::P2Exact => return scurve(request, Arithmetic::P2Exact),
        ProfileKind::Austin => {
            Box::new(AustinProfile::new(clkfreq, speed, accel(request)?, steps)?)
        }
        ProfileKind::Leib => Box::new(LeibProfile::new(clkfreq, speed, accel(request)?, steps)?),
        ProfileKind::Trapezoid => Box::new(Trapezoid::new(clkfreq, speed, accel(request)?, steps)?),
    };
    Ok(Built {
        profile,
        plan: None,
        top_speed_steps_per_s: speed,
        edge_timing: EdgeTiming::Delay,
    })
}

/// `--accel`, which the linear-ramp profiles need.
fn accel(request: &Request) -> Result<f64, ExportError> {
    request
        .accel_steps_per_s2
        .ok_or(ExportError::MissingAccel(request.profile.as_str()))
}

fn scurve(request: &Request, arithmetic: Arithmetic) -> Result<Built, ExportError> {
    let speed = request.speed_steps_per_s;
    if speed.fract() != 0.0 || speed > f64::from(u32::MAX) {
        return Err(ExportError::FractionalSpeed(speed));
    }
    let config = ScurveConfig {
        clkfreq: request.clkfreq,
        offset_deg: request.offset_deg,
        accel_div: request.accel_div,
        arithmetic,
    };
    // Checked above: a whole number in u32 range.
    let curve = SCurve::new(config, speed as u32, request.steps)?;
    let plan = *curve.plan();
    let edge_timing = match arithmetic {
        Arithmetic::P2Exact => EdgeTiming::P2_REFERENCE,
        Arithmetic::Smooth => EdgeTiming::Delay,
    };
    Ok(Built {
        profile: Box::new(curve),
        plan: Some(plan),
        top_speed_steps_per_s: f64::from(plan.speed),
        edge_timing,
    })
}

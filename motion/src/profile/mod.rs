//! Motion profiles: the per-step timing of a move.
//!
//! Every profile yields one [`Step`] per motor step, in order, through the
//! [`Profile`] trait (an [`Iterator`] of steps that also knows how many are
//! left). A step carries its index, its [`Phase`], the S-curve angle where the
//! profile has one, the velocity the profile computed for it and the delay,
//! in clock ticks, from this step's rising edge to the next one.
//!
//! | module | profile |
//! |---|---|
//! | [`scurve`] | the P2 cosine S-curve, `P2Exact` and `Smooth` arithmetic, live re-planning |
//! | [`motion`] | one axis: signed commands, merge, speed change, reversal, stops |
//!
//! The comparison ramps (Austin's, Leib's and the exact trapezoid) implement
//! the same [`Profile`] trait in the `cogstep-ramps` crate, so that only
//! their users (the export, the benchmarks) build them and `fixed`.
//!
//! Profiles work on step counts (magnitudes); the direction of a move is the
//! cog's business.

pub mod ieee_div;
pub mod motion;
pub mod scurve;

/// Which part of a move a step belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Phase {
    /// Speeding up.
    Accel,
    /// At the top speed ("slew", the reference's "steps at speed").
    Slew,
    /// Slowing down.
    Decel,
}

impl Phase {
    /// The name used in exports: `accel`, `slew` or `decel`.
    pub fn as_str(self) -> &'static str {
        match self {
            Phase::Accel => "accel",
            Phase::Slew => "slew",
            Phase::Decel => "decel",
        }
    }
}

/// One motor step of a move, as a profile computed it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Step {
    /// Index of the step within the move, from 0.
    pub index: u32,
    /// Accelerating, at speed or decelerating.
    pub phase: Phase,
    /// The S-curve angle of this step as a binary angle (2^32 = 360°);
    /// `None` for profiles without one.
    pub binary_angle: Option<u32>,
    /// The velocity the profile computed for this step, in steps/s (a report
    /// value: the timing itself is `delay_ticks`).
    pub velocity_steps_per_s: f64,
    /// Clock ticks from this step's rising edge to the next step's (for the
    /// last step: until the axis is ready again). Always ≥ 1.
    pub delay_ticks: u32,
}

impl Step {
    /// The S-curve angle in degrees, where the profile has one.
    pub fn angle_deg(&self) -> Option<f64> {
        self.binary_angle
            .map(|angle| f64::from(angle) * (360.0 / 4_294_967_296.0))
    }
}

/// A move's timing, one [`Step`] at a time.
pub trait Profile: Iterator<Item = Step> {
    /// Steps not yet yielded.
    fn remaining_steps(&self) -> u32;
}

/// Why a move cannot be planned. Nothing is started when planning fails.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PlanError {
    /// The speed must be at least 1 step/s.
    #[error("speed must be at least 1 step/s")]
    ZeroSpeed,
    /// A move must have at least one step.
    #[error("a move must have at least one step")]
    ZeroSteps,
    /// The clock frequency must be at least 1 Hz.
    #[error("clock frequency must be at least 1 Hz")]
    ZeroClock,
    /// At this speed a step would take less than one clock tick (or less than
    /// the minimum the profile needs).
    #[error("{speed} steps/s is too fast for a {clkfreq} Hz clock")]
    SpeedTooHigh {
        /// The requested speed, steps/s.
        speed: u32,
        /// The clock, Hz.
        clkfreq: u32,
    },
    /// The S-curve offset must lie in 1..=89 degrees.
    #[error("offset must be 1 to 89 degrees, got {0}")]
    BadOffset(u32),
    /// The acceleration divisor must be at least 1.
    #[error("acceleration divisor must be at least 1")]
    BadAccelDiv,
    /// The acceleration must be positive and finite (steps/s²).
    #[error("acceleration must be a positive, finite number of steps/s²")]
    BadAccel,
    /// The speed must be positive and finite (steps/s).
    #[error("speed must be a positive, finite number of steps/s")]
    BadSpeed,
    /// A step at this speed would take longer than a `u32` of ticks.
    #[error("a step would take longer than 2^32 clock ticks")]
    DelayOverflow,
}

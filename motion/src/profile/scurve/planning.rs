//! Planning a move: the settings that do not change from move to move
//! ([`ScurveConfig`], [`Arithmetic`]) and [`plan`], the reference's
//! `move(sp, st)` with cogstep's short-move rule (see the module docs).

use crate::profile::PlanError;

/// How a cog turns angles into delays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Arithmetic {
    /// The reference P2 driver's integer arithmetic, tick for tick.
    P2Exact,
    /// Exact angles, full-precision velocity, carried rounding (see the module docs).
    #[default]
    Smooth,
}

/// The settings of the S-curve that do not change from move to move.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ScurveConfig {
    /// System clock, Hz (ticks per second).
    pub clkfreq: u32,
    /// Where the ramp starts on the cosine, degrees (1..=89; default 40).
    pub offset_deg: u32,
    /// Acceleration divisor: accel steps = speed / divisor + 2 (default 10).
    pub accel_div: u32,
    /// Integer arithmetic of the reference, or the improved default.
    pub arithmetic: Arithmetic,
}

impl Default for ScurveConfig {
    fn default() -> Self {
        Self {
            clkfreq: 200_000_000,
            offset_deg: 40,
            accel_div: 10,
            arithmetic: Arithmetic::Smooth,
        }
    }
}

impl ScurveConfig {
    fn validate(&self) -> Result<(), PlanError> {
        if self.clkfreq == 0 {
            return Err(PlanError::ZeroClock);
        }
        if !(1..=89).contains(&self.offset_deg) {
            return Err(PlanError::BadOffset(self.offset_deg));
        }
        if self.accel_div == 0 {
            return Err(PlanError::BadAccelDiv);
        }
        Ok(())
    }
}

/// What [`plan`] made of a move command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Plan {
    /// The speed asked for, steps/s.
    pub requested_speed: u32,
    /// The top speed of the move, steps/s: the requested one, or lower for a
    /// short move.
    pub speed: u32,
    /// Steps in the move (magnitude).
    pub steps: u32,
    /// Steps spent accelerating (and as many decelerating).
    pub accel_steps: u32,
    /// Steps at the top speed.
    pub slew_steps: u32,
    /// The ramp's starting angle, degrees.
    pub offset_deg: u32,
    /// Whether the short-move speed limit lowered the speed.
    pub short_move: bool,
}

/// Plans a move of `steps` steps at `speed` steps/s as the reference does,
/// with cogstep's short-move rule (see the module docs).
///
/// ```
/// use cogstep_motion::profile::scurve::{plan, ScurveConfig};
/// let p = plan(&ScurveConfig::default(), 20_000, 20_000).unwrap();
/// assert_eq!((p.accel_steps, p.slew_steps, p.speed), (2_002, 15_996, 20_000));
/// let short = plan(&ScurveConfig::default(), 20_000, 101).unwrap();
/// assert_eq!((short.accel_steps, short.slew_steps, short.speed), (50, 1, 480));
/// ```
pub fn plan(config: &ScurveConfig, speed: u32, steps: u32) -> Result<Plan, PlanError> {
    config.validate()?;
    if speed == 0 {
        return Err(PlanError::ZeroSpeed);
    }
    if steps == 0 {
        return Err(PlanError::ZeroSteps);
    }
    if speed > config.clkfreq {
        return Err(PlanError::SpeedTooHigh {
            speed,
            clkfreq: config.clkfreq,
        });
    }
    let natural = speed / config.accel_div + 2;
    let accel_steps = natural.min(steps / 2);
    let slew_steps = steps - 2 * accel_steps;
    let capped = accel_steps < natural;
    // The reference's `if ss == 0` also fires when the move is exactly
    // 2·(sp/10 + 2) steps long and was never capped: sp is then rounded
    // down to a multiple of 10. P2Exact follows it; Smooth keeps sp.
    let p2_rounds = config.arithmetic == Arithmetic::P2Exact && slew_steps == 0;
    let top = if capped || p2_rounds {
        let limit = config
            .accel_div
            .saturating_mul(accel_steps.saturating_sub(2))
            .max(config.accel_div);
        speed.min(limit)
    } else {
        speed
    };
    Ok(Plan {
        requested_speed: speed,
        speed: top,
        steps,
        accel_steps,
        slew_steps,
        offset_deg: config.offset_deg,
        short_move: top < speed,
    })
}

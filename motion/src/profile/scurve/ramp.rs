//! One ramp ([`Ramp`]): a top speed, its number of positions and the
//! constants each arithmetic computes once per ramp; a slew step's delay.

use super::cosines::Recurrence;
use super::planning::{Arithmetic, ScurveConfig};
use super::smooth::{smooth_angle_span, TWO_TO_THE_63};

/// One ramp: a top speed and the number of positions between the offset
/// angle and 180°.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Ramp {
    pub(super) speed: u32,
    pub(super) accel_steps: u32,
    /// Smooth: clkfreq·2^63 / speed as the bits of an `f64` (rounded once),
    /// so that a step's delay is one division (see [`smooth_delay_q32`]).
    ///
    /// [`smooth_delay_q32`]: super::smooth::smooth_delay_q32
    pub(super) numerator: u64,
    /// Smooth: the constants of the cosine recurrence (see
    /// [`smooth_cosines`]); `None` for a ramp of a few positions, whose
    /// cosines are each computed alone.
    ///
    /// [`smooth_cosines`]: super::cosines::smooth_cosines
    pub(super) recurrence: Option<Recurrence>,
    /// Smooth: the steps of [`smooth_angle`]'s numerator over its divisor
    /// for one and for two positions, (quotient, remainder), so that a
    /// block of angles takes one division, not three.
    ///
    /// [`smooth_angle`]: super::smooth::smooth_angle
    pub(super) angle_steps: [(u64, u64); 2],
}

impl Ramp {
    pub(super) fn new(config: &ScurveConfig, speed: u32, accel_steps: u32) -> Self {
        // Both factors and 2^63 are exact in f64: one rounding.
        let numerator = f64::from(config.clkfreq) * TWO_TO_THE_63 / f64::from(speed.max(1));
        let (recurrence, angle_steps) = match config.arithmetic {
            Arithmetic::Smooth => {
                let (span, divisor) = smooth_angle_span(config.offset_deg, accel_steps);
                (
                    Recurrence::new(config.offset_deg, accel_steps),
                    [
                        (span / divisor, span % divisor),
                        (2 * span / divisor, 2 * span % divisor),
                    ],
                )
            }
            Arithmetic::P2Exact => (None, [(0, 0); 2]),
        };
        Self {
            speed,
            accel_steps,
            numerator: numerator.to_bits(),
            recurrence,
            angle_steps,
        }
    }
}

/// One slew step's delay, clkfreq / speed, in 32.32 ticks.
pub(super) fn slew_q32(clkfreq: u32, speed: u32) -> u64 {
    (u64::from(clkfreq) << 32) / u64::from(speed.max(1))
}

//! The timing of one ramp position in either arithmetic: which cosine it
//! needs, where that cosine comes from (alone, or from a block computed
//! together) and the (angle, velocity, delay) it gives.

use crate::profile::Phase;
use cordic_core::{cos_batch, qrotate};

use super::cosines::{smooth_cosines, COSINE_BLOCK};
use super::curve::SCurve;
use super::p2exact::{p2_ramp_angles, p2_velocity_delay, P2_DEG128_TO_BINARY};
use super::planning::Arithmetic;
use super::ramp::{slew_q32, Ramp};
use super::runs::RUN_STEPS;
use super::smooth::{smooth_angle, smooth_velocity_delay, COS_SCALE};
use super::HALF_TURN;

/// P2Exact's cosines computed together ([`SCurve::fill_cosines`]): a block
/// on a host, where the batch is cheap; as many as a ramp run takes
/// ([`RUN_STEPS`]) on a microcontroller, so that the work comes evenly, a
/// few keys a run, not a whole block on one step. The cosines are the
/// same either way.
pub(super) const P2_FILL_KEYS: u32 = RUN_STEPS as u32;

impl SCurve {
    /// The highest accelerating position of `ramp` whose delay is at least
    /// `current` (32.32 ticks), 0 when none is: where a switch of ramps
    /// (a speed change, a merge into a short move) goes on from. Delays
    /// shrink as the position grows, so it is a bisection; in Smooth it
    /// first bisects over the positions that start a cosine block (each
    /// one cosine from its anchor), then within the one block left,
    /// computed once. The same answer as bisecting with
    /// [`SCurve::delay_at`] alone, for about a tenth of the cosines: on a
    /// core without an FPU a merge into a ramp costs a few steps' work,
    /// not a few hundred.
    pub(super) fn last_position_not_faster(&self, ramp: Ramp, current: u64) -> u32 {
        if self.delay_at(ramp, 0, Phase::Accel) < current {
            return 0;
        }
        // The answer is in [low, high]; delay(low) >= current.
        let (mut low, mut high) = (0u32, ramp.accel_steps);
        let block = COSINE_BLOCK as u32;
        let smooth = self.config.arithmetic == Arithmetic::Smooth;
        if smooth {
            while high / block > low / block {
                let (first, last) = (low / block, high / block);
                let mid = (first + (last - first).div_ceil(2)) * block;
                if self.delay_at(ramp, mid, Phase::Accel) >= current {
                    low = mid;
                } else {
                    high = mid - 1;
                }
            }
        }
        // One block left (Smooth): its cosines once, for every probe.
        let first = low - low % block;
        let len = (ramp.accel_steps.saturating_sub(first)).min(block) as usize;
        let cached = smooth && len > 0;
        let (angles, cosines) = if cached {
            self.smooth_block(ramp, first, len)
        } else {
            ([0; COSINE_BLOCK], [0; COSINE_BLOCK])
        };
        let delay = |position: u32| {
            let index = position.wrapping_sub(first) as usize;
            if cached && position < ramp.accel_steps && index < len {
                self.timing_from_cosine(ramp, Phase::Accel, angles[index], cosines[index])
                    .2
            } else {
                self.delay_at(ramp, position, Phase::Accel)
            }
        };
        while low < high {
            let mid = low + (high - low).div_ceil(2);
            if delay(mid) >= current {
                low = mid;
            } else {
                high = mid - 1;
            }
        }
        low
    }

    /// Smooth's angles and cosines of the `len` keys of `ramp` from `first`
    /// (a block's first key), in the first `len` entries.
    fn smooth_block(
        &self,
        ramp: Ramp,
        first: u32,
        len: usize,
    ) -> ([u32; COSINE_BLOCK], [i32; COSINE_BLOCK]) {
        let (mut angles, mut cosines) = ([0; COSINE_BLOCK], [0; COSINE_BLOCK]);
        smooth_cosines(
            &self.config,
            ramp,
            first,
            &mut angles[..len],
            &mut cosines[..len],
        );
        (angles, cosines)
    }

    /// The delay (32.32 ticks) the arithmetic gives at a ramp position.
    pub(super) fn delay_at(&self, ramp: Ramp, position: u32, phase: Phase) -> u64 {
        self.timing(ramp, position, phase).2
    }

    /// (binary angle, velocity steps/s, delay in 32.32 ticks) at a position.
    pub(super) fn timing(&self, ramp: Ramp, position: u32, phase: Phase) -> (u32, f64, u64) {
        if let Some(slew) = self.slew_timing(ramp, position) {
            return slew;
        }
        let key = self.cosine_key(ramp, position, phase);
        let (angle, x) = match self.config.arithmetic {
            Arithmetic::Smooth => {
                // The cosine the block holding `key` has (it depends on
                // where the block starts).
                let first = key - key % COSINE_BLOCK as u32;
                let len = (key - first + 1) as usize;
                let (angles, cosines) = self.smooth_block(ramp, first, len);
                (angles[len - 1], cosines[len - 1])
            }
            Arithmetic::P2Exact => {
                let (radius, angle) = self.rotation(ramp, key);
                (angle, qrotate(radius, 0, angle).0)
            }
        };
        self.timing_from_cosine(ramp, phase, angle, x)
    }

    /// [`SCurve::timing`] on the ramp in use, its cosines taken from a block
    /// computed together (as the P2 keeps its CORDIC pipeline full):
    /// [`cos_batch`] gives the same bits as one QROTATE each, for less work.
    pub(super) fn timing_batched(&mut self, position: u32, phase: Phase) -> (u32, f64, u64) {
        let ramp = self.ramp;
        if let Some(slew) = self.slew_timing(ramp, position) {
            return slew;
        }
        let key = self.cosine_key(ramp, position, phase);
        if !self.cosines.holds(ramp, key) {
            self.fill_cosines(ramp, key);
        }
        let (angle, x) = self.cosines.get(key);
        self.timing_from_cosine(ramp, phase, angle, x)
    }

    /// Computes the block of cosines that holds `key`: the keys from the
    /// multiple of the block's span at or below it, so that a key's cosine
    /// does not depend on the order the keys are asked for in. Smooth's
    /// span is [`COSINE_BLOCK`] (its recurrence starts at the block's first
    /// key). P2Exact's cosines do not depend on the block (each is QROTATE's
    /// bits), so its span is [`P2_FILL_KEYS`]: on a microcontroller a few
    /// keys at a time, since each costs thousands of cycles there (64-bit
    /// multiplications in software) and a whole block, on four axes at
    /// once, would hold the main loop longer than its lead on the pins.
    pub(super) fn fill_cosines(&mut self, ramp: Ramp, key: u32) {
        let (keys, span) = match self.config.arithmetic {
            Arithmetic::Smooth => (ramp.accel_steps, COSINE_BLOCK as u32),
            Arithmetic::P2Exact => (2 * ramp.accel_steps + 1, P2_FILL_KEYS),
        };
        let first = key - key % span;
        let len = (keys.max(key + 1) - first).min(span) as usize;
        let block = &mut self.cosines;
        match self.config.arithmetic {
            Arithmetic::Smooth => smooth_cosines(
                &self.config,
                ramp,
                first,
                &mut block.angles[..len],
                &mut block.cosines[..len],
            ),
            Arithmetic::P2Exact => {
                let radius = p2_ramp_angles(&self.config, ramp, first, &mut block.angles[..len]);
                cos_batch(radius, &block.angles[..len], &mut block.cosines[..len]);
            }
        }
        block.ramp = Some(ramp);
        block.first = first;
        block.len = len as u32;
    }

    /// A position at or above the top of the ramp: the slew timing (smooth).
    fn slew_timing(&self, ramp: Ramp, position: u32) -> Option<(u32, f64, u64)> {
        (self.config.arithmetic == Arithmetic::Smooth && position >= ramp.accel_steps).then(|| {
            (
                HALF_TURN,
                f64::from(ramp.speed),
                slew_q32(self.config.clkfreq, ramp.speed),
            )
        })
    }

    /// Which cosine a position needs: smooth, the position itself (the
    /// deceleration mirrors the acceleration); P2Exact, the reference's
    /// step number (the deceleration numbered on from the acceleration).
    pub(super) fn cosine_key(&self, ramp: Ramp, position: u32, phase: Phase) -> u32 {
        match (self.config.arithmetic, phase) {
            (Arithmetic::P2Exact, Phase::Decel) => (2 * ramp.accel_steps)
                .saturating_sub(1)
                .saturating_sub(position),
            _ => position,
        }
    }

    /// The QROTATE of a cosine key: (radius, binary angle).
    fn rotation(&self, ramp: Ramp, key: u32) -> (i32, u32) {
        let offset = self.config.offset_deg;
        match self.config.arithmetic {
            Arithmetic::Smooth => (COS_SCALE, smooth_angle(offset, ramp.accel_steps, key)),
            Arithmetic::P2Exact => {
                let stom = 2 * ramp.accel_steps;
                let deg128 = if stom == 0 {
                    180 * 128
                } else {
                    (u64::from(key) * u64::from(360 - 2 * offset) * 128 / u64::from(stom)) as u32
                        + offset * 128
                };
                let halfsp = (ramp.speed / 2) as i32;
                (halfsp, deg128.wrapping_mul(P2_DEG128_TO_BINARY))
            }
        }
    }

    /// (angle, velocity, delay in 32.32 ticks) from the rotation's angle and
    /// the X it gave.
    fn timing_from_cosine(&self, ramp: Ramp, phase: Phase, angle: u32, x: i32) -> (u32, f64, u64) {
        match self.config.arithmetic {
            Arithmetic::Smooth => {
                let angle = if phase == Phase::Decel {
                    angle.wrapping_neg()
                } else {
                    angle
                };
                let (velocity, delay_q32) = smooth_velocity_delay(ramp, x);
                (angle, velocity, delay_q32)
            }
            Arithmetic::P2Exact => {
                let (velocity, delay) = p2_velocity_delay(self.config.clkfreq, ramp, x);
                (angle, f64::from(velocity), u64::from(delay) << 32)
            }
        }
    }

    /// The reference cog's arithmetic at a ramp position: (angle, v, delay).
    pub(super) fn p2_timing(&self, ramp: Ramp, position: u32, phase: Phase) -> (u32, u32, u32) {
        let key = self.cosine_key(ramp, position, phase);
        let (halfsp, angle) = self.rotation(ramp, key);
        let (x, _) = qrotate(halfsp, 0, angle);
        let (velocity, delay) = p2_velocity_delay(self.config.clkfreq, ramp, x);
        (angle, velocity, delay)
    }
}

//! Ramp runs: the ramp steps computed ahead in one tight loop while nothing
//! re-plans, yielded by three loads each, and settled back into the general
//! path's state when something does.

use crate::profile::{Phase, Step};

use super::cosines::COSINE_BLOCK;
use super::curve::SCurve;
use super::p2exact::{div_u32, p2_velocity_delay, P2_MAX_DELAY_TICKS};
use super::planning::{Arithmetic, ScurveConfig};
use super::ramp::Ramp;
use super::rounding::{carry_round, carry_round_held};
use super::smooth::{scaled_velocity, smooth_delay_q32, smooth_run_timing, DelayNumerator};
use super::HALF_TURN;

/// Ramp steps computed ahead at most ([`SCurve::arm_ramp`]): a block's worth
/// on a host; on a microcontroller (no FPU: a division is a library call),
/// fewer, so that no one step interrupt computes many (and the run takes
/// little RAM): 8, 32 with the feature `long-ramp-runs` (a board whose
/// cores run in a main loop ahead of the pins), a block's worth with
/// `block-ramp-runs` (one whose edges then keep their own time). The steps
/// are the same either way.
pub(super) const RUN_STEPS: usize = if cfg!(any(
    target_arch = "x86_64",
    target_arch = "aarch64",
    feature = "block-ramp-runs"
)) {
    COSINE_BLOCK
} else if cfg!(feature = "long-ramp-runs") {
    32
} else {
    8
};

/// The run armed right after a step of the general path (a ramp's first,
/// the turn at an all-ramp move's peak, the first after a slew or a
/// re-plan): short, so that the core that made that step computes few,
/// and the runs after it, from the state at its end, can be computed
/// ahead by another core while it yields them (a board's core 1:
/// [`SCurve::run_ahead_from`]). The steps are the same whatever a run's
/// length.
pub(super) const FIRST_RUN_STEPS: usize = 8;

/// Ramp steps computed ahead, in one tight loop, for a ramp that nothing
/// re-plans: entry `i` is the step after entry `i − 1`, exactly as
/// [`SCurve::next_general`] would give it (see [`SCurve::arm_ramp`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct RampRun {
    /// The next entry to yield.
    pub(super) next: u32,
    /// Entries computed (`0`: no run).
    pub(super) len: u32,
    /// Every entry's phase (accelerating or decelerating).
    pub(super) phase: Phase,
    /// The ramp position of entry 0; the others follow one apart (up when
    /// accelerating, down when decelerating).
    first_position: u32,
    pub(super) delay_ticks: [u32; RUN_STEPS],
    /// Each entry's velocity is `velocity_scale · units · velocity_pow2`
    /// (computed when a step is yielded: a caller that does not read it
    /// does not pay for it).
    velocity_units: [u32; RUN_STEPS],
    velocity_scale: u32,
    velocity_pow2: f64,
    pub(super) angles: [u32; RUN_STEPS],
    /// The carry and the previous step's ticks before entry 0, and the
    /// carry after the last entry.
    start_carry: i64,
    previous_ticks: u32,
    end_carry: i64,
}

/// Field by field, the arrays a word at a time ([`same_words`]): a board
/// compares a whole curve each ramp run it takes from another core.
impl PartialEq for RampRun {
    fn eq(&self, other: &Self) -> bool {
        // Every field: `same_but_arrays` names each one.
        self.same_but_arrays(other)
            && same_words(&self.delay_ticks, &other.delay_ticks)
            && same_words(&self.velocity_units, &other.velocity_units)
            && same_words(&self.angles, &other.angles)
    }
}

/// Whether two arrays of words hold the same words: one pass without an
/// early exit or a library call. A derived `==` on an array is `memcmp`,
/// which on the M0+ compares a byte at a time (about 8 cycles a byte).
#[inline]
pub(super) fn same_words<T, const N: usize>(a: &[T; N], b: &[T; N]) -> bool
where
    T: Copy + Default + PartialEq + core::ops::BitXor<Output = T> + core::ops::BitOr<Output = T>,
{
    a.iter()
        .zip(b)
        .fold(T::default(), |diff, (&x, &y)| diff | (x ^ y))
        == T::default()
}

impl RampRun {
    /// Every field but the entries' arrays (see `SCurve::same_but_arrays`).
    pub(super) fn same_but_arrays(&self, other: &Self) -> bool {
        // Every field named: a new one does not compile until compared.
        let RampRun {
            next,
            len,
            phase,
            first_position,
            delay_ticks: _,
            velocity_units: _,
            velocity_scale,
            velocity_pow2,
            angles: _,
            start_carry,
            previous_ticks,
            end_carry,
        } = self;
        *next == other.next
            && *len == other.len
            && *phase == other.phase
            && *first_position == other.first_position
            && *velocity_scale == other.velocity_scale
            && velocity_pow2.to_bits() == other.velocity_pow2.to_bits()
            && *start_carry == other.start_carry
            && *previous_ticks == other.previous_ticks
            && *end_carry == other.end_carry
    }

    /// Entry `i`'s velocity, steps/s.
    #[inline(always)]
    pub(super) fn velocity(&self, i: usize) -> f64 {
        scaled_velocity(
            self.velocity_scale,
            self.velocity_units[i],
            self.velocity_pow2,
        )
    }

    pub(super) const EMPTY: Self = Self {
        next: 0,
        len: 0,
        phase: Phase::Accel,
        first_position: 0,
        delay_ticks: [0; RUN_STEPS],
        velocity_units: [0; RUN_STEPS],
        velocity_scale: 0,
        velocity_pow2: 0.0,
        angles: [0; RUN_STEPS],
        start_carry: 0,
        previous_ticks: 0,
        end_carry: 0,
    };
}

/// Entry `i`'s delay before rounding, 32.32 ticks, computed again from its
/// velocity units (the run keeps its whole ticks only; only a re-planning
/// call needs the exact delays, to settle the run).
fn run_delay_q32(config: &ScurveConfig, ramp: Ramp, run: &RampRun, i: usize) -> u64 {
    let units = run.velocity_units[i];
    match config.arithmetic {
        Arithmetic::Smooth => smooth_delay_q32(ramp.numerator, u64::from(units)),
        Arithmetic::P2Exact => {
            u64::from(div_u32(config.clkfreq, units).min(P2_MAX_DELAY_TICKS)) << 32
        }
    }
}

/// Fills a run's entries from (angle, X) pairs, each step's velocity
/// units and 32.32 delay from `timing(X)`, its ticks by
/// [`carry_round_held`], held to the step before (the first to
/// `previous`), in one loop without bounds checks; returns the carry after
/// the last and the entries filled: `len`, or fewer where a P2Exact stop's
/// hold would bind. `phase` is a constant where it is called, so no step
/// tests it.
///
/// `hold`: a P2Exact stop's rule (`SCurve::next_general`): no step faster
/// than the one before, in velocity units or in its 32.32 delay; the
/// previous step's (units, delay) before entry 0. The run ends before the
/// first step the rule would change: that step is the general path's,
/// which holds it (rare: where a stop turns round mid-ramp). `None` where
/// no rule applies (a constant there).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn fill_run(
    run: &mut RampRun,
    len: usize,
    source: impl Fn(usize) -> (u32, i32),
    timing: impl Fn(i32) -> (u32, u64),
    mut carry: i64,
    phase: Phase,
    mut previous: u32,
    mut hold: Option<(u32, u64)>,
) -> (i64, usize) {
    // Every tick count is at least 1, so `previous` is too.
    debug_assert!(previous >= 1);
    let angles = &mut run.angles[..len];
    let units_out = &mut run.velocity_units[..len];
    let ticks_out = &mut run.delay_ticks[..len];
    for i in 0..len {
        let (angle, x) = source(i);
        let (units, delay_q32) = timing(x);
        if let Some((held_units, held_delay_q32)) = hold.as_mut() {
            if units > *held_units || delay_q32 < *held_delay_q32 {
                return (carry, i);
            }
            (*held_units, *held_delay_q32) = (units, delay_q32);
        }
        // The usual step: a carry in 0..2^32 (one tick), no clamp binding;
        // then `carry_round_held` reduces to an addition and a mask: the sum
        // is below 2^64 (delays are below 2^63), so its whole ticks fit 32
        // bits, and whole ≥ 1 is implied by the order (previous ≥ 1).
        let total = delay_q32 + (carry as u64 & 0xFFFF_FFFF);
        let whole = (total >> 32) as u32;
        let in_order = match phase {
            Phase::Accel => whole.wrapping_sub(1) < previous,
            Phase::Decel => whole >= previous,
            Phase::Slew => whole != 0,
        };
        let ticks;
        if (carry as u64) >> 32 == 0 && in_order {
            ticks = whole;
            carry = (total & 0xFFFF_FFFF) as i64;
        } else {
            (ticks, carry) = carry_round_held(delay_q32, carry, phase, previous);
        }
        angles[i] = angle;
        units_out[i] = units;
        ticks_out[i] = ticks;
        previous = ticks;
    }
    (carry, len)
}

/// The ramp steps [`SCurve`] has computed ahead and yields next with
/// nothing re-planned in between (see [`SCurve::ramp_span`]): one phase,
/// their whole-tick delays known already.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RampSpan<'a> {
    /// [`Phase::Accel`] or [`Phase::Decel`], every one of them.
    pub phase: Phase,
    /// Each step's delay, ticks, the next step's first (at least one).
    pub delay_ticks: &'a [u32],
}

impl SCurve {
    /// The ramp steps computed ahead that the next calls of `next` yield,
    /// or `None` when the next step is not one of them (the first of a
    /// ramp, one after a re-planning, a slew step, the end).
    pub fn ramp_span(&self) -> Option<RampSpan<'_>> {
        let run = &self.run;
        (run.next < run.len).then(|| RampSpan {
            phase: run.phase,
            delay_ticks: &run.delay_ticks[run.next as usize..run.len as usize],
        })
    }

    /// Yields `steps` steps of [`SCurve::ramp_span`] at once (1 to its
    /// length, else nothing happens): the state after is bit for bit what
    /// `steps` calls of `next` leave. Returns the delay of the last one.
    pub fn skip_ramp(&mut self, steps: u32) -> Option<u32> {
        let run = &mut self.run;
        if steps == 0 || steps > run.len - run.next {
            return None;
        }
        run.next += steps;
        Some(run.delay_ticks[run.next as usize - 1])
    }

    /// The step count at which the armed run is used up (the steps yielded
    /// so far plus the run's), or `None` when no run is armed: a key for
    /// [`SCurve::run_ahead_from`]'s prediction, cheaper to compare than the
    /// state.
    pub fn run_end_index(&self) -> Option<u32> {
        (self.run.len > 0).then(|| self.index + self.run.len)
    }

    /// Writes into `into` (an earlier request's room, or none) the state
    /// this curve will be in once its armed run is used up, if nothing
    /// re-plans meanwhile: what another core computes the following run
    /// from ([`SCurve::arm_run_ahead_from`]) while this one yields the armed
    /// run. Returns `false` (and leaves `into` as it was) when no run is
    /// armed or its last step is already yielded.
    pub fn run_ahead_from(&self, into: &mut Option<SCurve>) -> bool {
        if self.run.len == 0 || self.run.next >= self.run.len {
            return false;
        }
        let into = self.copy_into(into);
        into.run.next = into.run.len;
        true
    }

    /// This curve copied into `into` (an earlier copy's room, or none) in
    /// place (`clone_from`), not built on the stack first.
    fn copy_into<'a>(&self, into: &'a mut Option<SCurve>) -> &'a mut SCurve {
        match into {
            Some(into) => {
                into.clone_from(self);
                into
            }
            None => into.insert(self.clone()),
        }
    }

    /// The helper's work on a request (another core's): copies `from`, a
    /// state written by [`SCurve::run_ahead_from`], into `ahead` (an
    /// earlier answer's room, or none) and does there what the owner's
    /// next step would do before yielding: settles the used-up run and
    /// arms the one that follows, exactly as [`Iterator::next`] does.
    /// Returns whether a run was armed; `false` means the next step is not
    /// a run's (a slew step, the end, the general path), and the answer is
    /// then of no use.
    pub fn arm_run_ahead_from(from: &SCurve, ahead: &mut Option<SCurve>) -> bool {
        from.copy_into(ahead).arm_run_ahead()
    }

    /// [`SCurve::arm_run_ahead_from`]'s work on its copy.
    pub(super) fn arm_run_ahead(&mut self) -> bool {
        // `next`'s own order: a run's entries, then the slew, then this.
        if self.run.len == 0 || self.run.next != self.run.len || self.remaining > self.slew_floor {
            return false;
        }
        self.settle();
        self.arm_ramp()
    }

    /// Takes a run computed ahead: `from` is the state the helper started
    /// from, `ahead` what [`SCurve::arm_run_ahead_from`] made of it (a run
    /// armed: it returned `true`). Only when this curve is `from` exactly (its armed
    /// run used up, nothing re-planned since the prediction) does it become
    /// `ahead`; then its next steps are, bit for bit, the ones it would
    /// have computed itself (the same code on the same state). Returns
    /// whether it did. "Exactly" is every field but the arrays' contents,
    /// which those fields decide (`SCurve::same_but_arrays`; checked whole
    /// in debug builds).
    pub fn adopt_run_ahead(&mut self, from: &SCurve, ahead: &SCurve) -> bool {
        let armed = ahead.run.next < ahead.run.len;
        if !armed
            || self.run.len == 0
            || self.run.next != self.run.len
            || !self.same_but_arrays(from)
        {
            return false;
        }
        // The arrays' live entries too (which `same_but_arrays` argues
        // follow), in debug builds: every test of the helper checks them.
        debug_assert!(self.live_entries_match(from));
        self.clone_from(ahead);
        true
    }

    /// Whether the run's entries and the block's cosines up to their
    /// lengths are `other`'s (what `same_but_arrays` leaves out).
    fn live_entries_match(&self, other: &SCurve) -> bool {
        let (run, block) = (&self.run, &self.cosines);
        let (n, k) = (run.len as usize, block.len as usize);
        run.delay_ticks[..n] == other.run.delay_ticks[..n]
            && run.velocity_units[..n] == other.run.velocity_units[..n]
            && run.angles[..n] == other.run.angles[..n]
            && block.angles[..k] == other.cosines.angles[..k]
            && block.cosines[..k] == other.cosines.cosines[..k]
    }

    /// A ramp step computed ahead by [`SCurve::arm_ramp`].
    #[inline(always)]
    pub(super) fn next_ramp(&mut self) -> Step {
        let i = self.run.next as usize % RUN_STEPS;
        self.run.next += 1;
        self.ramp_entry(i)
    }

    /// Entry `i` of the run as a step.
    #[inline(always)]
    pub(super) fn ramp_entry(&self, i: usize) -> Step {
        let run = &self.run;
        Step {
            index: self.index + i as u32,
            phase: run.phase,
            binary_angle: Some(run.angles[i]),
            velocity_steps_per_s: run.velocity(i),
            delay_ticks: run.delay_ticks[i],
        }
    }

    /// The run is used up: the next one, or the general path.
    #[inline(never)]
    pub(super) fn next_after_run(&mut self) -> Option<Step> {
        if self.run.len > 0 {
            self.settle();
            if self.arm_ramp() {
                return Some(self.next_ramp());
            }
        }
        self.next_general()
    }

    /// Ends a run of ramp steps: the state becomes what the general path
    /// would have after the last entry yielded, and the rest is dropped.
    pub(super) fn settle(&mut self) {
        let run = &mut self.run;
        self.index += run.next;
        self.remaining -= run.next;
        if let Some(last) = (run.next as usize).checked_sub(1) {
            let offset = last as u32;
            self.position = Some(match run.phase {
                Phase::Decel => run.first_position - offset,
                _ => run.first_position + offset,
            });
            self.velocity = run.velocity(last);
            self.last_delay_q32 = run_delay_q32(&self.config, self.ramp, run, last);
            self.carry = if last + 1 == run.len as usize {
                run.end_carry
            } else {
                // Left part way (a re-planning call): the carry so far.
                let mut carry = run.start_carry;
                for i in 0..=last {
                    let delay_q32 = run_delay_q32(&self.config, self.ramp, run, i);
                    let previous = match i.checked_sub(1) {
                        Some(before) => run.delay_ticks[before],
                        None => run.previous_ticks,
                    };
                    carry = carry_round(delay_q32, carry, run.phase, Some(previous)).1;
                }
                carry
            };
            self.last_emitted = Some((run.phase, run.delay_ticks[last]));
            if self.config.arithmetic == Arithmetic::P2Exact {
                self.last_ramp = Some(((self.last_delay_q32 >> 32) as u32, self.velocity as u32));
            }
        }
        run.next = 0;
        run.len = 0;
    }

    /// After a ramp step with nothing re-planned: computes the steps that
    /// follow on the same side of the ramp (up to the end of the cosine
    /// block), each as [`SCurve::next_general`] would, so that yielding one
    /// is three loads. Returns whether it made any.
    ///
    /// Accelerating, the walk climbs one position a step while it stays
    /// below the top and keeps room to stop (`position + 2 ≤ remaining`
    /// before each step); decelerating with `position == remaining`, it
    /// descends one a step to 0. A slower ramp pending or any other state
    /// takes the general path.
    ///
    /// A stop decelerates on runs like any deceleration. What a stop
    /// changes is that its first deceleration step is held to the step
    /// before whatever that step's phase ([`SCurve::round_delay`]), and
    /// that step is the general path's (a run follows a step of its own
    /// phase); and, in P2Exact, that no step is faster than the one before
    /// (`next_general`): a run ends before the first step that rule would
    /// hold ([`fill_run`]'s `hold`), and the general path makes that one.
    /// (Before, every step of a stop took the general path, then every
    /// step of a P2Exact stop: a board that stops an axis at speed paid
    /// its full cost on every step of the deceleration.)
    pub(super) fn arm_ramp(&mut self) -> bool {
        self.arm_ramp_up_to(RUN_STEPS)
    }

    /// [`SCurve::arm_ramp`], a run of `most` steps at most.
    pub(super) fn arm_ramp_up_to(&mut self, most: usize) -> bool {
        let (Some(position), Some((phase, previous))) = (self.position, self.last_emitted) else {
            return false;
        };
        if self.pending_ramp.is_some() {
            return false;
        }
        let ramp = self.ramp;
        let remaining = self.remaining;
        let (first_position, steps) = match phase {
            Phase::Accel if position + 1 < ramp.accel_steps => (
                position + 1,
                (ramp.accel_steps - 1 - position).min(remaining.saturating_sub(position) / 2),
            ),
            Phase::Decel if remaining == position && position > 0 => (position - 1, remaining),
            _ => return false,
        };
        let key = self.cosine_key(ramp, first_position, phase);
        if !self.cosines.holds(ramp, key) {
            self.fill_cosines(ramp, key);
        }
        let block = &self.cosines;
        // Smooth deceleration walks its keys down; all else walks them up.
        let descending = self.config.arithmetic == Arithmetic::Smooth && phase == Phase::Decel;
        let in_block = if descending {
            key - block.first + 1
        } else {
            block.first + block.len - key
        };
        let len = steps.min(in_block).min(most.min(RUN_STEPS) as u32) as usize;
        if len == 0 {
            return false;
        }
        let start = (key - block.first) as usize;
        let run = &mut self.run;
        let carry = self.carry;
        // Smooth's delays: the numerator taken apart once a run.
        let numerator = DelayNumerator::new(ramp.numerator);
        let smooth_timing = |x| smooth_run_timing(numerator, x);
        // One loop: each step's division is independent of the others (they
        // overlap), its rounding a short chain from the step before.
        let (carry, len) = match (self.config.arithmetic, phase) {
            (Arithmetic::Smooth, Phase::Accel) => {
                let angles = &block.angles[start..start + len];
                let cosines = &block.cosines[start..start + len];
                let source = |i: usize| (angles[i], cosines[i]);
                fill_run(
                    run,
                    len,
                    source,
                    smooth_timing,
                    carry,
                    Phase::Accel,
                    previous,
                    None,
                )
            }
            (Arithmetic::Smooth, _) => {
                // The mirror half: the keys walked down, the angles negated.
                let angles = &block.angles[start + 1 - len..start + 1];
                let cosines = &block.cosines[start + 1 - len..start + 1];
                let source = |i: usize| {
                    let at = len - 1 - i;
                    (angles[at].wrapping_neg(), cosines[at])
                };
                fill_run(
                    run,
                    len,
                    source,
                    smooth_timing,
                    carry,
                    Phase::Decel,
                    previous,
                    None,
                )
            }
            (Arithmetic::P2Exact, _) => {
                let angles = &block.angles[start..start + len];
                let cosines = &block.cosines[start..start + len];
                let source = |i: usize| (angles[i], cosines[i]);
                let clkfreq = self.config.clkfreq;
                let timing = |x| {
                    let (velocity, delay) = p2_velocity_delay(clkfreq, ramp, x);
                    (velocity, u64::from(delay) << 32)
                };
                // A stop's rule, checked against the step before (its
                // velocity a whole number of units in P2Exact).
                let hold = self
                    .stopping
                    .then_some((self.velocity as u32, self.last_delay_q32));
                match phase {
                    Phase::Decel => fill_run(
                        run,
                        len,
                        source,
                        timing,
                        carry,
                        Phase::Decel,
                        previous,
                        hold,
                    ),
                    _ => fill_run(
                        run,
                        len,
                        source,
                        timing,
                        carry,
                        Phase::Accel,
                        previous,
                        hold,
                    ),
                }
            }
        };
        if len == 0 {
            return false;
        }
        match self.config.arithmetic {
            // smooth_velocity_delay's velocity: the product rounded once,
            // then scaled exactly.
            Arithmetic::Smooth => {
                run.velocity_scale = ramp.speed;
                run.velocity_pow2 = 1.0 / f64::from(HALF_TURN);
            }
            Arithmetic::P2Exact => (run.velocity_scale, run.velocity_pow2) = (1, 1.0),
        }
        run.start_carry = self.carry;
        run.previous_ticks = self.last_emitted.map_or(0, |(_, ticks)| ticks);
        run.end_carry = carry;
        run.next = 0;
        run.len = len as u32;
        run.phase = phase;
        run.first_position = first_position;
        true
    }
}

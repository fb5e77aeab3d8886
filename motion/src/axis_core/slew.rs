//! The fast paths: steps whose edges are known before they are made.
//! Slew steps in closed form, made by the core itself
//! ([`AxisCore::run_slew`]) or by a caller that drives the edges
//! ([`StepTrain`]); and the ramp steps the profile has computed ahead, in
//! a [`StepTrain`] too. One implementation: `run_slew` is a train made and
//! committed at once.

use super::state::State;
use super::{AxisCore, LastStep};
use crate::axis::{Direction, Mode};
use crate::profile::ieee_div::f64_to_u32;
use crate::profile::scurve::{self, Arithmetic};
use crate::profile::Phase;

/// Steps made at once by [`AxisCore::run_slew`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlewRun {
    /// The pin each step pulsed.
    pub pin: u8,
    /// How many steps: a rising and a falling edge each.
    pub steps: u32,
}

/// Ramp steps a [`StepTrain`] carries at most: the profile computes that
/// many ahead at a time on a microcontroller, 8, 32 with the feature
/// `long-ramp-runs`, 64 with `block-ramp-runs` (a host computes 64; with
/// fewer here its train takes them this many at a time).
pub const RAMP_TRAIN_STEPS: usize = if cfg!(feature = "block-ramp-runs") {
    64
} else if cfg!(feature = "long-ramp-runs") {
    32
} else {
    8
};

/// Steps whose edges are known before they are made, for a caller that
/// drives them without the core (a timer interrupt): from
/// [`AxisCore::step_train`] (or [`AxisCore::slew_train`], slew steps
/// only), stepped by [`StepTrain::make_step`], handed back with
/// [`AxisCore::commit_train`]. Each step is a rising edge on
/// [`StepTrain::pin`] at its CT and a falling edge `pulse_ticks` later,
/// the same edges [`AxisCore::run_event`] would emit. At speed the
/// arithmetic per step is one 32.32 addition; on a ramp each step's delay
/// is one the profile computed ahead ([`StepTrain::is_ramp`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepTrain {
    /// CT of the next step's rising edge.
    pub rise_ct: u64,
    /// The pin pulsed.
    pub pin: u8,
    /// Width of each pulse, ticks.
    pub pulse_ticks: u32,
    /// Steps the train may still make.
    pub steps_left: u32,
    /// No step of the train may rise at or after this CT (a jog's
    /// deadline; [`u64::MAX`] for none): the core decides what happens then.
    pub limit_ct: u64,
    delay_q32: u64,
    carry: u32,
    /// Ticks added to each delay to make the period (P2Exact's pulse and
    /// cog overhead; 0 in Smooth).
    period_extra: u32,
    made: u32,
    last_rise_ct: u64,
    last_delay_ticks: u32,
    /// [`Phase::Slew`]: the 32.32 arithmetic; else the ramp's phase, and
    /// step `made` takes `ramp_delays[made]`.
    phase: Phase,
    ramp_delays: [u32; RAMP_TRAIN_STEPS],
}

impl StepTrain {
    /// Whether the step at [`StepTrain::rise_ct`] is the train's to make.
    #[inline(always)]
    pub fn has_step(&self) -> bool {
        self.steps_left > 0 && self.rise_ct < self.limit_ct
    }

    /// Makes the step at [`StepTrain::rise_ct`] (the caller drives its
    /// edges) and moves on to the next; call only when
    /// [`StepTrain::has_step`].
    #[inline(always)]
    pub fn make_step(&mut self) {
        let delay_ticks = if self.phase == Phase::Slew {
            let total = self.delay_q32 + u64::from(self.carry);
            self.carry = total as u32;
            (total >> 32) as u32
        } else {
            self.ramp_delays[self.made as usize % RAMP_TRAIN_STEPS]
        };
        self.last_rise_ct = self.rise_ct;
        self.last_delay_ticks = delay_ticks;
        self.rise_ct += u64::from(delay_ticks) + u64::from(self.period_extra);
        self.steps_left -= 1;
        self.made += 1;
    }

    /// Makes the train's next steps that rise at or before CT `last`, at
    /// most `rises.len()` of them, putting each one's rising CT in
    /// `rises`; returns how many. The train is then what as many
    /// [`StepTrain::make_step`] calls would leave, each made while
    /// [`StepTrain::has_step`] held and its CT was at most `last`.
    ///
    /// One loop over locals for a board that makes a run of steps at once
    /// (the Pico's PIO build: every step of four axes goes through it):
    /// one `make_step` a step through the train's fields kept a
    /// Cortex-M0+'s eight registers too busy, every field a load and a
    /// store. Out of line, so that the loop has the registers to itself.
    #[inline(never)]
    pub fn make_steps_into(&mut self, last: u64, rises: &mut [u64]) -> usize {
        let last = last.min(self.limit_ct.saturating_sub(1));
        let most = rises.len().min(self.steps_left as usize);
        let rises = &mut rises[..most];
        let extra = u64::from(self.period_extra);
        let mut rise_ct = self.rise_ct;
        let mut made = self.made;
        let mut delay_ticks = self.last_delay_ticks;
        let mut count = 0;
        if self.phase == Phase::Slew {
            let delay_q32 = self.delay_q32;
            let mut carry = self.carry;
            for slot in rises.iter_mut() {
                if rise_ct > last {
                    break;
                }
                *slot = rise_ct;
                let total = delay_q32 + u64::from(carry);
                carry = total as u32;
                delay_ticks = (total >> 32) as u32;
                rise_ct += u64::from(delay_ticks) + extra;
                count += 1;
            }
            self.carry = carry;
        } else {
            for slot in rises.iter_mut() {
                if rise_ct > last {
                    break;
                }
                *slot = rise_ct;
                delay_ticks = self.ramp_delays[made as usize % RAMP_TRAIN_STEPS];
                rise_ct += u64::from(delay_ticks) + extra;
                made += 1;
                count += 1;
            }
        }
        if count > 0 {
            self.last_rise_ct = rises[count - 1];
            self.last_delay_ticks = delay_ticks;
            self.rise_ct = rise_ct;
            self.steps_left -= count as u32;
            self.made += count as u32;
        }
        count
    }

    /// Steps made so far.
    pub fn made(&self) -> u32 {
        self.made
    }

    /// Whether the train carries ramp steps (their delays computed
    /// ahead) rather than slew steps (the 32.32 arithmetic, which
    /// [`StepTrain::delay_q32`] and [`StepTrain::carry`] describe).
    pub fn is_ramp(&self) -> bool {
        self.phase != Phase::Slew
    }

    /// Makes `steps` steps at once (at most [`StepTrain::steps_left`]):
    /// the same train as that many calls of [`StepTrain::make_step`], in
    /// closed form at speed (the carry makes the sum of k delays
    /// `⌊(carry + k·delay_q32) / 2^32⌋`). For a caller that makes the
    /// steps with [`StepTrain::delay_q32`] and [`StepTrain::carry`] itself
    /// and hands the train back with its count.
    pub fn make_steps(&mut self, steps: u32) {
        let steps = steps.min(self.steps_left);
        if steps == 0 {
            return;
        }
        if self.is_ramp() {
            for _ in 0..steps {
                self.make_step();
            }
            return;
        }
        let delay_q32 = u128::from(self.delay_q32);
        let before_last = u128::from(self.carry) + delay_q32 * u128::from(steps - 1);
        let total = before_last + delay_q32;
        let extra = u64::from(self.period_extra);
        self.last_rise_ct =
            self.rise_ct + (before_last >> 32) as u64 + extra * u64::from(steps - 1);
        self.last_delay_ticks = ((total >> 32) - (before_last >> 32)) as u32;
        self.rise_ct += (total >> 32) as u64 + extra * u64::from(steps);
        self.carry = total as u32;
        self.steps_left -= steps;
        self.made += steps;
    }

    /// The delay between steps, 32.32 ticks: each step's delay in ticks
    /// is the integer part of this plus [`StepTrain::carry`], the carry
    /// its fraction.
    pub fn delay_q32(&self) -> u64 {
        self.delay_q32
    }

    /// The fraction carried to the next step's delay (of 2^32).
    pub fn carry(&self) -> u32 {
        self.carry
    }

    /// Ticks added to each delay to make the period (P2Exact's pulse and
    /// cog overhead; 0 in Smooth).
    pub fn period_extra(&self) -> u32 {
        self.period_extra
    }
}

impl StepTrain {
    /// The CT of the rising edge of the train's step `index` (0 = the
    /// next), as [`StepTrain::make_step`] would reach it.
    fn rise_of(&self, index: u32) -> u64 {
        let ticks = (u128::from(self.carry) + u128::from(self.delay_q32) * u128::from(index)) >> 32;
        self.rise_ct + ticks as u64 + u64::from(self.period_extra) * u64::from(index)
    }

    /// How many of the next steps (at most `max_steps`) rise at or before
    /// CT `last`, and before [`StepTrain::limit_ct`].
    fn steps_until(&self, last: u64, max_steps: u32) -> u32 {
        let last = last.min(self.limit_ct.saturating_sub(1));
        let most = self.steps_left.min(max_steps);
        if most == 0 || self.rise_ct > last {
            return 0;
        }
        // The rising edges only move forward: the last one in time is
        // found by bisection (step `low` always rises in time).
        let (mut low, mut high) = (0u32, most - 1);
        while low < high {
            let middle = low + (high - low).div_ceil(2);
            if self.rise_of(middle) <= last {
                low = middle;
            } else {
                high = middle - 1;
            }
        }
        low + 1
    }
}

impl AxisCore {
    /// The event at CT `t` and the ones after it, up to CT `limit` and at
    /// most `max_steps` of them, when every one is a plain slew step: made
    /// at once, in closed form. The core is then bit for bit what
    /// [`AxisCore::run_event`] at each of those steps leaves; the edges are
    /// not passed one by one but summed up in the [`SlewRun`] (each step a
    /// rising and a falling edge on its pin, the pin low after the last).
    /// `None` (and nothing changed) when the event at `t` is anything else:
    /// a ramp step, a re-planned curve, a direction change, a jog deadline.
    ///
    /// The caller runs no input between those steps: it is for a caller
    /// that would find nothing new at them (nothing asked, no edge traced,
    /// no simulated switch moving with the axis). An axis that watches
    /// inputs on every step (limit pins, homing) gets `None`.
    pub fn run_slew(&mut self, t: u64, limit: u64, max_steps: u32) -> Option<SlewRun> {
        let mut train = self.slew_train().filter(|train| train.rise_ct == t)?;
        let (_, direction) = self.motion.slew_span()?;
        if (direction == Direction::Reverse) != self.dir_reverse {
            return None;
        }
        let steps = train.steps_until(limit, max_steps);
        if steps == 0 {
            return None;
        }
        train.make_steps(steps);
        self.commit_train(&train);
        Some(SlewRun {
            pin: train.pin,
            steps,
        })
    }

    /// The next event when it is a step whose edges are known before it is
    /// made: `(due, pin)` when the step due at `due` goes on in the current
    /// curve's direction with no direction edge before it, and no jog
    /// deadline comes first. Its first edge is then the rising edge of
    /// `pin` at `due`, and nothing the step decides happens before `due`:
    /// a caller may drive that edge at `due` and only then run the event
    /// ([`AxisCore::run_event`] emits the same edge first, with the rest).
    /// `None` says nothing about when the next event is.
    ///
    /// A group member's next step is such a step too when nothing its lead
    /// edge decides can take it away (see `Follower::plain_step_due`).
    #[inline]
    pub fn next_plain_step(&self) -> Option<(u64, u8)> {
        let (due, direction) = match &self.state {
            State::Running(run) => {
                let due = run.due;
                if self.deadline().is_some_and(|deadline| deadline <= due) {
                    return None;
                }
                let (curve, direction) = self.motion.current()?;
                if !curve.is_running() {
                    return None;
                }
                (due, direction)
            }
            State::Group(follower) => (follower.plain_step_due()?, follower.direction),
            _ => return None,
        };
        let outputs = self.config.outputs;
        let reverse = direction == Direction::Reverse;
        if reverse != self.dir_reverse && outputs.dir_pin().is_some() {
            return None;
        }
        Some((due, outputs.pulse_pin(direction)))
    }

    /// The slew steps from the next event on that need no decision: the
    /// next event is a step with known edges ([`AxisCore::next_plain_step`])
    /// and the profile's fast slew path (see
    /// [`crate::profile::scurve::SCurve::slew_span`]) makes it and those
    /// after it. `None` otherwise. While a caller holds a train it must
    /// not run the core; it hands the train back with
    /// [`AxisCore::commit_train`] before anything else touches the core.
    pub fn slew_train(&self) -> Option<StepTrain> {
        self.train(false)
    }

    /// A train of the next steps that need no decision, whichever the
    /// profile has: slew steps (as [`AxisCore::slew_train`]) or the ramp
    /// steps it computed ahead (up to [`RAMP_TRAIN_STEPS`] of them, all
    /// accelerating or all decelerating). `None` when the next event is
    /// not such a step. The same rules as for a slew train: nothing else
    /// touches the core until [`AxisCore::commit_train`].
    pub fn step_train(&self) -> Option<StepTrain> {
        self.train(true)
    }

    /// [`AxisCore::step_train`], or with `ramps` false
    /// [`AxisCore::slew_train`]: the checks once, then the profile's slew
    /// span or its ramp steps computed ahead.
    fn train(&self, ramps: bool) -> Option<StepTrain> {
        // A group part's steps follow the lead's curve, not the profile's.
        if !matches!(self.state, State::Running(_)) {
            return None;
        }
        let (due, pin) = self.next_plain_step()?;
        let (curve, _) = self.motion.current()?;
        // Inputs looked at on every step (limit pins, a home switch) make
        // every step an event of its own.
        if self.watched_pins() != 0 || self.state.homing().is_some() {
            return None;
        }
        let mut train = StepTrain {
            rise_ct: due,
            pin,
            pulse_ticks: self.config.pulse_ticks,
            steps_left: 0,
            limit_ct: self.state.jog().map_or(u64::MAX, |jog| jog.deadline),
            delay_q32: 0,
            carry: 0,
            // Ticks added to each delay to make the period (see
            // `AxisCore`'s `period_ticks`).
            period_extra: match self.config.scurve.arithmetic {
                Arithmetic::Smooth => 0,
                Arithmetic::P2Exact => (scurve::p2_period_ticks(0, self.config.pulse_ticks))
                    .min(u64::from(u32::MAX)) as u32,
            },
            made: 0,
            last_rise_ct: 0,
            last_delay_ticks: 0,
            phase: Phase::Slew,
            ramp_delays: [0; RAMP_TRAIN_STEPS],
        };
        if let Some(ahead) = curve.slew_span() {
            train.steps_left = ahead.steps;
            train.delay_q32 = ahead.delay_q32;
            train.carry = ahead.carry_q32 as u32;
        } else {
            let span = curve.ramp_span().filter(|_| ramps)?;
            let len = span.delay_ticks.len().min(RAMP_TRAIN_STEPS);
            train.ramp_delays[..len].copy_from_slice(&span.delay_ticks[..len]);
            train.steps_left = len as u32;
            train.phase = span.phase;
        }
        Some(train)
    }

    /// When the profile's armed ramp run is used up
    /// ([`SCurve::run_end_index`](crate::profile::scurve::SCurve::run_end_index)):
    /// a key for a run computed ahead.
    pub fn run_end_index(&self) -> Option<u32> {
        self.motion.run_end_index()
    }

    /// Whether the steps left in the profile's armed ramp run take at
    /// least `ticks` ticks (their delays: each step's period is at least
    /// its delay): whether the run lasts that long before it is used up.
    /// Adds the delays only until it knows. With no run armed, only 0
    /// ticks is.
    pub fn ramp_run_lasts(&self, ticks: u64) -> bool {
        let Some((span, _)) = self.motion.ramp_span() else {
            return ticks == 0;
        };
        let mut lasts = 0u64;
        for &delay in span.delay_ticks {
            if lasts >= ticks {
                return true;
            }
            lasts += u64::from(delay);
        }
        lasts >= ticks
    }

    /// Writes the profile's state as it will be once its armed ramp run is
    /// used up, for another core to compute the next run from
    /// ([`SCurve::arm_run_ahead_from`](crate::profile::scurve::SCurve::arm_run_ahead_from)).
    /// `false`: no run to compute ahead.
    pub fn run_ahead_from(&self, into: &mut Option<scurve::SCurve>) -> bool {
        self.motion.run_ahead_from(into)
    }

    /// Takes a ramp run another core computed ahead, from `from` to
    /// `ahead`: only when the profile is `from` exactly, so that the steps
    /// are bit for bit the ones the core would have computed itself (the
    /// same code on the same state). Nothing else in the core changes.
    /// Returns whether it did.
    pub fn adopt_run_ahead(&mut self, from: &scurve::SCurve, ahead: &scurve::SCurve) -> bool {
        self.motion.adopt_run_ahead(from, ahead)
    }

    /// Takes back a train from [`AxisCore::step_train`] (or
    /// [`AxisCore::slew_train`]): the core is left as if it had run the
    /// events of the steps the train made, one by one, at their CTs (same
    /// position, accounts, last step and next event).
    pub fn commit_train(&mut self, train: &StepTrain) {
        let steps = train.made;
        if steps == 0 {
            return;
        }
        let (velocity, direction) = if train.is_ramp() {
            let Some((_, direction)) = self.motion.ramp_span() else {
                return;
            };
            let delay = self.motion.skip_ramp(steps);
            debug_assert_eq!(delay, Some(train.last_delay_ticks));
            // What `step` counts and notes on each of them.
            let made = &train.ramp_delays[..(steps as usize).min(RAMP_TRAIN_STEPS)];
            let math_ticks = self.config.math_ticks;
            self.math_overruns += made
                .iter()
                .filter(|&&delay| u64::from(delay) < math_ticks)
                .count() as u64;
            // A run follows a step of its own phase, so a train never
            // begins a deceleration (where `step` notes the max velocity).
            debug_assert!(train.phase != Phase::Decel || self.step_bits.contains(Mode::DECEL));
            let velocity = self
                .motion
                .current()
                .map_or(0.0, |(curve, _)| curve.velocity());
            (f64_to_u32(velocity), direction)
        } else {
            let Some((span, direction)) = self.motion.slew_span() else {
                return;
            };
            let delay = self.motion.skip_slew(steps);
            debug_assert_eq!(delay, Some(train.last_delay_ticks));
            (f64_to_u32(span.velocity_steps_per_s), direction)
        };
        let moved = direction.sign() * i64::from(steps);
        self.position = self.position.saturating_add(moved);
        self.physical = self.physical.saturating_add(moved);
        if self.state.jog_owns() {
            self.ledger.jogged += moved;
        }
        self.dir_reverse = direction == Direction::Reverse;
        self.last_fall_ct = train.last_rise_ct + u64::from(self.config.pulse_ticks);
        self.last_step = LastStep {
            velocity,
            delay_ticks: train.last_delay_ticks,
            ct: train.last_rise_ct,
        };
        let phase = match train.phase {
            Phase::Accel => Mode::ACCEL,
            Phase::Slew => Mode::SLEW,
            Phase::Decel => Mode::DECEL,
        };
        self.step_bits = phase
            | if direction == Direction::Reverse {
                Mode::REVERSE
            } else {
                Mode::empty()
            };
        if let Some(run) = self.state.run_mut() {
            run.due = train.rise_ct;
        }
        self.ready_ct = train.rise_ct;
    }
}

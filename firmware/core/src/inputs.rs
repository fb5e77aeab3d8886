//! Switch inputs on a board whose cores run ahead of its pins.
//!
//! A board that queues its axes' edges some time before their CT (the
//! Pico's cores run milliseconds ahead of the timer) learns of a switch
//! change at CT `t` when its cores have already made the steps up to CT
//! now. The axis core latches homing's and a limit trip's position at the
//! step on which the change happened if it is told how many steps it has
//! made since (`AxisCore::set_inputs_late`). [`StepHistory`] answers that:
//! it keeps the CT and the way of each recent rising step edge as the
//! board drives it, and the physical position now, so that
//!
//! ```text
//! late steps = the core's physical position now − StepHistory::physical_at(t)
//! ```
//!
//! ([`crate::FirmwareAxis::set_inputs`] does the subtraction.)

use crate::axis::{Output, Variant};

/// The step edges of one axis over the last `N` steps: the CT of each
/// rising step edge and which way it stepped; with the physical position
/// now (the signed count of its step edges since boot, as the axis core
/// counts them), where the pins stood at any CT the history covers.
///
/// A ring written in place: every step of every axis is recorded (the
/// Pico's main loop, for each rising edge it queues), and once `N` steps
/// are in, each one replaces the oldest. Each step is one word, its CT
/// with the top bit set for a step back: a train's steps (one way, one
/// after the other) go in through a [`StepRun`] at one store a step, the
/// count and the position settled once after them. The question
/// ([`StepHistory::physical_at`]) walks back from the newest step: it is
/// asked when an input changes, the steps at every edge.
#[derive(Clone, Debug)]
pub struct StepHistory<const N: usize> {
    variant: Variant,
    /// Level of the direction pin (`sd`: high runs in reverse).
    reverse: bool,
    physical: i64,
    /// The steps recorded, each its CT, [`BACK`] set for a step of −1,
    /// oldest at `next` once `len` is `N`.
    steps: [u64; N],
    /// Where the next step goes.
    next: usize,
    /// How many of `steps` hold a step (up to `N`).
    len: usize,
}

/// A recorded step's mark for a step back (−1); CTs stay below 2^63.
const BACK: u64 = 1 << 63;

impl<const N: usize> StepHistory<N> {
    /// An axis with outputs `variant` that has made no step.
    pub const fn new(variant: Variant) -> Self {
        const { assert!(N > 0, "a step history keeps at least one step") };
        StepHistory {
            variant,
            reverse: false,
            physical: 0,
            steps: [0; N],
            next: 0,
            len: 0,
        }
    }

    /// Output `output` goes to `level` at CT `ct` (CTs never go back).
    pub fn record(&mut self, ct: u64, output: Output, level: bool) {
        if (self.variant, output) == (Variant::Sd, Output::Second) {
            self.reverse = level;
            return;
        }
        if let Some(step) = self.step_of(output).filter(|_| level) {
            self.push(ct, step);
        }
    }

    /// What a rising edge of output `output` counts, as [`StepHistory::record`]
    /// takes it: +1 or −1, or `None` for no step (`sd`'s direction pin).
    #[inline(always)]
    pub fn step_of(&self, output: Output) -> Option<i64> {
        match (self.variant, output) {
            (Variant::Sd, Output::Second) => None,
            (Variant::Sd, Output::First) if self.reverse => Some(-1),
            (Variant::Sd, Output::First) | (Variant::Cc, Output::First) => Some(1),
            (Variant::Cc, Output::Second) => Some(-1),
        }
    }

    /// A step of `step` ([`StepHistory::step_of`]'s: +1 or −1) at CT `ct`:
    /// what [`StepHistory::record`] does for its rising edge.
    #[inline(always)]
    pub fn push(&mut self, ct: u64, step: i64) {
        let mut run = self.run(step);
        run.push(ct);
    }

    /// Steps of `step` (+1 or −1) one after the other, each given by
    /// [`StepRun::push`]: the same as a [`StepHistory::push`] each, the
    /// count and the position settled when the run is dropped.
    #[inline(always)]
    pub fn run(&mut self, step: i64) -> StepRun<'_, N> {
        StepRun {
            mark: if step < 0 { BACK } else { 0 },
            next: self.next,
            made: 0,
            step,
            history: self,
        }
    }

    /// The physical position after the last rising step edge at or before
    /// CT `ct`: where the pins stood at `ct`. A CT older than the history
    /// (more than `N` steps ago) gets its oldest step's (where the axis
    /// stood before it).
    pub fn physical_at(&self, ct: u64) -> i64 {
        // Newest first, each step after `ct` taken back.
        let mut position = self.physical;
        let mut index = self.next;
        for _ in 0..self.len {
            index = index.checked_sub(1).unwrap_or(N - 1);
            let step = self.steps[index];
            if step & !BACK <= ct {
                break;
            }
            position += if step & BACK != 0 { 1 } else { -1 };
        }
        position
    }

    /// The physical position after the last step recorded.
    pub fn physical(&self) -> i64 {
        self.physical
    }
}

/// A run of steps one way going into a [`StepHistory`] (from
/// [`StepHistory::run`]): one store a step; the history's count and
/// position are settled when it is dropped.
#[derive(Debug)]
pub struct StepRun<'a, const N: usize> {
    history: &'a mut StepHistory<N>,
    /// [`BACK`] for steps of −1.
    mark: u64,
    /// Where the next step goes.
    next: usize,
    made: usize,
    step: i64,
}

impl<const N: usize> StepRun<'_, N> {
    /// The run's next step, at CT `ct` (CTs never go back).
    #[inline(always)]
    pub fn push(&mut self, ct: u64) {
        debug_assert!(ct < BACK, "CT {ct} past 2^63");
        self.history.steps[self.next] = ct | self.mark;
        self.next = if self.next + 1 == N { 0 } else { self.next + 1 };
        self.made += 1;
    }

    /// [`StepRun::push`] for each of `cts` in turn: one loop over locals
    /// (a board that makes a run of steps at once calls it once a run:
    /// the Pico's PIO build).
    #[inline(never)]
    pub fn push_all(&mut self, cts: &[u64]) {
        let (mark, mut next) = (self.mark, self.next);
        let steps = &mut self.history.steps;
        for &ct in cts {
            debug_assert!(ct < BACK, "CT {ct} past 2^63");
            steps[next] = ct | mark;
            next = if next + 1 == N { 0 } else { next + 1 };
        }
        self.next = next;
        self.made += cts.len();
    }
}

impl<const N: usize> Drop for StepRun<'_, N> {
    #[inline(always)]
    fn drop(&mut self) {
        let history = &mut *self.history;
        history.next = self.next;
        history.len = (history.len + self.made).min(N);
        history.physical += self.step * self.made as i64;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn the_physical_position_at_a_ct_is_the_last_step_at_or_before_it() {
        let mut history = StepHistory::<8>::new(Variant::Sd);
        assert_eq!(history.physical_at(5), 0);
        for ct in [10, 20, 30] {
            history.record(ct, Output::First, true);
            history.record(ct + 5, Output::First, false);
        }
        // Reverse: direction high, then two steps back.
        history.record(35, Output::Second, true);
        history.record(40, Output::First, true);
        history.record(50, Output::First, true);
        assert_eq!(history.physical(), 1);
        let at = |ct| history.physical_at(ct);
        assert_eq!(
            [at(9), at(10), at(19), at(30), at(39), at(40), at(99)],
            [0, 1, 1, 3, 3, 2, 1]
        );
    }

    /// What the history promises, over every step kept: the physical
    /// position after the last step at or before a CT, the newest step
    /// gone for a CT older than every step kept, 0 before any step.
    fn model_at(steps: &[(u64, i64)], kept: usize, ct: u64) -> i64 {
        let first_kept = steps.len().saturating_sub(kept);
        let floor = first_kept.checked_sub(1).map_or(0, |gone| steps[gone].1);
        steps[first_kept..]
            .iter()
            .take_while(|&&(step_ct, _)| step_ct <= ct)
            .last()
            .map_or(floor, |&(_, physical)| physical)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Random edges (steps both ways, direction changes, falls) into
        /// histories of 1, 3 and 8 steps, checked against a list of every
        /// step after each edge, at CTs around every step's.
        #[test]
        fn the_ring_answers_as_the_list_of_every_step(
            edges in proptest::collection::vec((0u64..4, 0usize..2, any::<bool>()), 0..40),
        ) {
            let mut one = StepHistory::<1>::new(Variant::Sd);
            let mut three = StepHistory::<3>::new(Variant::Sd);
            let mut eight = StepHistory::<8>::new(Variant::Sd);
            let (mut ct, mut reverse, mut physical) = (0u64, false, 0i64);
            let mut steps = Vec::new();
            for (gap, output, level) in edges {
                ct += gap;
                let output = if output == 0 { Output::First } else { Output::Second };
                one.record(ct, output, level);
                three.record(ct, output, level);
                eight.record(ct, output, level);
                match output {
                    Output::Second => reverse = level,
                    Output::First if level => {
                        physical += if reverse { -1 } else { 1 };
                        steps.push((ct, physical));
                    }
                    Output::First => {}
                }
                for probe in 0..=ct + 1 {
                    prop_assert_eq!(one.physical_at(probe), model_at(&steps, 1, probe));
                    prop_assert_eq!(three.physical_at(probe), model_at(&steps, 3, probe));
                    prop_assert_eq!(eight.physical_at(probe), model_at(&steps, 8, probe));
                }
                prop_assert_eq!(eight.physical(), physical);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Steps given a run at a time (a train's, one way), one `push`
        /// each or a slice at a time (`push_all`, in pieces of random
        /// lengths), leave the history where a push each leaves it: the
        /// same answers at every CT, the same position, in rings of 1, 3
        /// and 8.
        #[test]
        fn a_run_of_steps_is_a_push_each(
            runs in proptest::collection::vec(
                (any::<bool>(), proptest::collection::vec(0u64..4, 0..12), 0usize..5),
                0..8,
            ),
        ) {
            fn check<const N: usize>(runs: &[(bool, Vec<u64>, usize)]) -> Result<(), TestCaseError> {
                let mut each = StepHistory::<N>::new(Variant::Sd);
                let mut by_runs = StepHistory::<N>::new(Variant::Sd);
                let mut ct = 0u64;
                for (back, gaps, piece) in runs {
                    let step = if *back { -1 } else { 1 };
                    let mut run = by_runs.run(step);
                    let mut cts = Vec::new();
                    for gap in gaps {
                        ct += gap;
                        each.push(ct, step);
                        cts.push(ct);
                    }
                    // A piece of 0: one `push` a step.
                    match piece {
                        0 => cts.iter().for_each(|&ct| run.push(ct)),
                        _ => cts.chunks(*piece).for_each(|cts| run.push_all(cts)),
                    }
                    drop(run);
                    for probe in 0..=ct + 1 {
                        prop_assert_eq!(by_runs.physical_at(probe), each.physical_at(probe));
                    }
                    prop_assert_eq!(by_runs.physical(), each.physical());
                }
                Ok(())
            }
            check::<1>(&runs)?;
            check::<3>(&runs)?;
            check::<8>(&runs)?;
        }
    }

    #[test]
    fn cw_and_ccw_count_both_ways_and_an_old_ct_gets_the_oldest_step() {
        let mut history = StepHistory::<2>::new(Variant::Cc);
        history.record(10, Output::First, true);
        history.record(20, Output::First, true);
        history.record(30, Output::Second, true);
        history.record(40, Output::Second, true);
        assert_eq!(history.physical(), 0);
        // 10 and 20 left the history: anything before 30 is put on 20's.
        assert_eq!(history.physical_at(5), 2);
        assert_eq!(history.physical_at(35), 1);
        assert_eq!(history.physical_at(45), 0);
    }
}

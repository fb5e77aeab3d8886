//! Switch inputs on a board whose cores run ahead of its pins.
//!
//! A board that queues its axes' edges some time before their CT (the
//! Pico's cores run milliseconds ahead of the timer) learns of a switch
//! change at CT `t` when its cores have already made the steps up to CT
//! now. The axis core latches homing's and a limit trip's position at the
//! step on which the change happened if it is told how many steps it has
//! made since (`AxisCore::set_inputs_late`). [`StepHistory`] answers that:
//! it keeps the CT of each recent rising step edge as the board drives it,
//! and the physical position after it, so that
//!
//! ```text
//! late steps = the core's physical position now − StepHistory::physical_at(t)
//! ```
//!
//! ([`crate::FirmwareAxis::set_inputs`] does the subtraction.)

use heapless::Deque;

use crate::axis::{Output, Variant};

/// The step edges of one axis over the last `N` steps: the CT of each
/// rising step edge and the physical position after it (the signed count
/// of its step edges since boot, as the axis core counts them).
#[derive(Clone, Debug)]
pub struct StepHistory<const N: usize> {
    variant: Variant,
    /// Level of the direction pin (`sd`: high runs in reverse).
    reverse: bool,
    physical: i64,
    steps: Deque<(u64, i64), N>,
    /// The newest step that left the history (CT, physical after it):
    /// a change older than it is placed on it.
    floor: Option<(u64, i64)>,
}

impl<const N: usize> StepHistory<N> {
    /// An axis with outputs `variant` that has made no step.
    pub const fn new(variant: Variant) -> Self {
        StepHistory {
            variant,
            reverse: false,
            physical: 0,
            steps: Deque::new(),
            floor: None,
        }
    }

    /// Output `output` goes to `level` at CT `ct` (CTs never go back).
    pub fn record(&mut self, ct: u64, output: Output, level: bool) {
        let step = match (self.variant, output) {
            (Variant::Sd, Output::Second) => {
                self.reverse = level;
                return;
            }
            (_, _) if !level => return,
            (Variant::Sd, Output::First) if self.reverse => -1,
            (Variant::Sd, Output::First) | (Variant::Cc, Output::First) => 1,
            (Variant::Cc, Output::Second) => -1,
        };
        self.physical += step;
        if self.steps.is_full() {
            self.floor = self.steps.pop_front();
        }
        let _ = self.steps.push_back((ct, self.physical));
    }

    /// The physical position after the last rising step edge at or before
    /// CT `ct`: where the pins stood at `ct`. A CT older than the history
    /// (more than `N` steps ago) gets its oldest step's.
    pub fn physical_at(&self, ct: u64) -> i64 {
        // With no step gone yet, every step since boot is here: 0 before them.
        let mut at = self.floor.map_or(0, |(_, physical)| physical);
        for &(step_ct, physical) in self.steps.iter() {
            if step_ct > ct {
                break;
            }
            at = physical;
        }
        at
    }

    /// The physical position after the last step recorded.
    pub fn physical(&self) -> i64 {
        self.physical
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

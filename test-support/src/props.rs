//! Property-test plumbing: case counts, the strategies several suites
//! draw from, and the closing tally of a model-based property.

use std::sync::atomic::{AtomicUsize, Ordering};

use cogstep_motion::axis::Direction;
use proptest::prelude::*;

/// How many random cases a property runs: `default`, or the number in
/// `COGSTEP_MODEL_CASES` (the long `--ignored` runs set it).
pub fn cases(default: u32) -> u32 {
    std::env::var("COGSTEP_MODEL_CASES")
        .ok()
        .and_then(|cases| cases.parse().ok())
        .unwrap_or(default)
}

/// Either direction.
pub fn direction() -> impl Strategy<Value = Direction> {
    prop_oneof![Just(Direction::Forward), Just(Direction::Reverse)]
}

/// What a model-based property checked: sequences run and operations in
/// them, counted from proptest's cases (which may run on several threads).
#[derive(Debug, Default)]
pub struct Tally {
    sequences: AtomicUsize,
    operations: AtomicUsize,
}

impl Tally {
    /// Counts one sequence of `operations` checked operations.
    pub fn add(&self, operations: usize) {
        // Counters only, read once all cases are done: no ordering needed.
        self.sequences.fetch_add(1, Ordering::Relaxed);
        self.operations.fetch_add(operations, Ordering::Relaxed);
    }

    /// Prints `name: N sequences, M operations checked, 0 anomalies` on
    /// stderr (a failing case panics before this).
    pub fn report(&self, name: &str) {
        eprintln!(
            "{name}: {} sequences, {} operations checked, 0 anomalies",
            self.sequences.load(Ordering::Relaxed),
            self.operations.load(Ordering::Relaxed)
        );
    }
}

//! The status a cog publishes, as one snapshot: a sequence lock around the
//! status words, so that [`Status::snapshot`] is always one instant's
//! fields, never a mix of two steps.
//!
//! # The seqlock
//!
//! One writer (the axis's cog), any number of readers, no lock and no
//! unsafe code: every field is an atomic, so a reader that races a write
//! reads stale or new words (never torn ones), and the sequence tells it to
//! try again.
//!
//! ```text
//! writer (the cog)                         reader (any thread)
//! seq: 2n ─store(Relaxed)─► 2n + 1         s = load(Acquire)        (s even, else retry)
//! fence(Release)                           read the fields (Relaxed)
//! store the fields (Relaxed)               fence(Acquire)
//! seq ◄─store(Release)─ 2n + 2             load(Relaxed) == s ? done : retry
//! ```
//!
//! - The reader's `Acquire` load of an even `s` pairs with the `Release`
//!   store that ended write `s / 2`: the fields it then reads are at least
//!   that write's.
//! - If any field load reads a store of a later write, that store comes
//!   after the writer's `Release` fence, and the reader's `Acquire` fence
//!   comes after the load: the fences synchronise, so the odd sequence
//!   stored before the writer's fence is visible to the reader's second
//!   load, which then differs from `s`: the reader tries again. So a
//!   snapshot that returns holds exactly write `s / 2`'s fields.
//! - The writer's loads of `seq` are `Relaxed`: it is the only writer and
//!   reads its own last store.
//!
//! Single-field readers ([`Axis::position`](crate::Axis::position),
//! [`Axis::mode`](crate::Axis::mode), …) read their one atomic as before.
//! Inside each write `steps_to_go` is stored last with `Release`, so a
//! reader that sees it 0 with `Acquire` also sees the final position.
//!
//! Model-checked with loom (`status::loom_tests`), through these functions.

use crate::sync::{fence, yield_now, AtomicI64, AtomicU32, AtomicU64, Ordering};
use cogstep_motion::axis_core::StepLedger;

/// A sequence lock for one writer: the protocol above, around closures
/// that store or load the protected atomics with `Relaxed`.
#[derive(Debug, Default)]
pub(crate) struct SeqLock {
    /// Even between writes, odd while one is under way.
    seq: AtomicU64,
}

impl SeqLock {
    /// The writer's side: `store` writes the protected fields. Only one
    /// thread may write, and writes do not nest. `store` only stores
    /// atomics (it cannot panic): a write left half done would keep the
    /// sequence odd and readers waiting.
    pub fn write<R>(&self, store: impl FnOnce() -> R) -> R {
        // Relaxed: the only writer reads its own last store.
        let seq = self.seq.load(Ordering::Relaxed);
        debug_assert!(seq & 1 == 0, "status writes do not nest");
        // Relaxed, then the Release fence: a reader that sees any store
        // made after the fence (through its Acquire fence) sees this odd
        // value, and retries.
        self.seq.store(seq.wrapping_add(1), Ordering::Relaxed);
        fence(Ordering::Release);
        let result = store();
        // Release: a reader that loads this value with Acquire sees every
        // field this write stored.
        self.seq.store(seq.wrapping_add(2), Ordering::Release);
        result
    }

    /// A reader's side: `load` reads the protected fields; the value
    /// returned is one write's, whole.
    pub fn read<T>(&self, mut load: impl FnMut() -> T) -> T {
        let mut attempts = 0u32;
        loop {
            // Acquire: pairs with the Release that ended the write `before`
            // names: the loads below see at least its fields.
            let before = self.seq.load(Ordering::Acquire);
            if before & 1 == 0 {
                let value = load();
                // Acquire fence: a load above that read a later write's
                // store makes the writer's Release fence, and the odd
                // value before it, visible to the load below.
                fence(Ordering::Acquire);
                // Relaxed: ordered by the fence above.
                if self.seq.load(Ordering::Relaxed) == before {
                    return value;
                }
            }
            // A write takes a few dozen stores: spin briefly, then let
            // the writer's core go (it may share it with this reader).
            attempts += 1;
            if cfg!(loom) || attempts > 64 {
                yield_now();
            } else {
                std::hint::spin_loop();
            }
        }
    }
}

/// What changes on every step.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct StepStatus {
    pub position: i64,
    pub steps_to_go: u64,
    pub mode: u32,
    /// The velocity of the last step, steps/s.
    pub velocity: u32,
    /// The delay after the last step, ticks.
    pub delay_ticks: u32,
    /// CT of the last step's rising edge.
    pub last_step_ct: u64,
}

/// What changes with a command, a stop or the end of a move.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct MoveStatus {
    pub move_speed: u32,
    pub accel_steps: u32,
    pub slew_steps: u32,
    pub top_velocity: u32,
    pub max_velocity: u32,
    /// CT at which the current move was taken.
    pub move_start_ct: u64,
    pub offset: u32,
    /// Steps the last controlled or emergency stop left unmade.
    pub dropped_steps: u32,
    pub ledger: StepLedger,
    /// Steps whose delay was shorter than the CORDIC math they needed.
    pub math_overruns: u64,
}

/// One instant's status, whole.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct StatusSnapshot {
    pub step: StepStatus,
    pub moves: MoveStatus,
}

/// The status a cog publishes: written by the cog only, read by anyone.
#[derive(Debug, Default)]
pub(crate) struct Status {
    lock: SeqLock,
    pub position: AtomicI64,
    pub steps_to_go: AtomicU64,
    pub mode: AtomicU32,
    pub velocity: AtomicU32,
    pub delay_ticks: AtomicU32,
    pub last_step_ct: AtomicU64,
    pub move_speed: AtomicU32,
    pub accel_steps: AtomicU32,
    pub slew_steps: AtomicU32,
    pub top_velocity: AtomicU32,
    pub max_velocity: AtomicU32,
    pub move_start_ct: AtomicU64,
    pub offset: AtomicU32,
    pub dropped_steps: AtomicU32,
    pub ledger_base: AtomicI64,
    pub ledger_accepted: AtomicI64,
    pub ledger_dropped: AtomicI64,
    pub ledger_dropped_total: AtomicU64,
    pub ledger_jogged: AtomicI64,
    pub math_overruns: AtomicU64,
}

impl Status {
    /// The cog's side, on every step: one write of the step's fields.
    pub fn publish_step(&self, step: &StepStatus) {
        self.lock.write(|| self.store_step(step));
    }

    /// The cog's side, when a command, a stop or a move's end changed
    /// more: one write of every field.
    pub fn publish_all(&self, snapshot: &StatusSnapshot) {
        self.lock.write(|| {
            self.store_moves(&snapshot.moves);
            self.store_step(&snapshot.step);
        });
    }

    /// Sets the S-curve offset before the cog runs (its thread starts
    /// after this, so the writer stays one at a time).
    pub fn show_offset(&self, offset_deg: u32) {
        self.lock
            .write(|| self.offset.store(offset_deg, Ordering::Relaxed));
    }

    /// Every field of one instant.
    pub fn snapshot(&self) -> StatusSnapshot {
        self.lock.read(|| StatusSnapshot {
            step: StepStatus {
                position: self.position.load(Ordering::Relaxed),
                steps_to_go: self.steps_to_go.load(Ordering::Relaxed),
                mode: self.mode.load(Ordering::Relaxed),
                velocity: self.velocity.load(Ordering::Relaxed),
                delay_ticks: self.delay_ticks.load(Ordering::Relaxed),
                last_step_ct: self.last_step_ct.load(Ordering::Relaxed),
            },
            moves: MoveStatus {
                move_speed: self.move_speed.load(Ordering::Relaxed),
                accel_steps: self.accel_steps.load(Ordering::Relaxed),
                slew_steps: self.slew_steps.load(Ordering::Relaxed),
                top_velocity: self.top_velocity.load(Ordering::Relaxed),
                max_velocity: self.max_velocity.load(Ordering::Relaxed),
                move_start_ct: self.move_start_ct.load(Ordering::Relaxed),
                offset: self.offset.load(Ordering::Relaxed),
                dropped_steps: self.dropped_steps.load(Ordering::Relaxed),
                ledger: StepLedger {
                    base: self.ledger_base.load(Ordering::Relaxed),
                    accepted: self.ledger_accepted.load(Ordering::Relaxed),
                    dropped: self.ledger_dropped.load(Ordering::Relaxed),
                    dropped_total: self.ledger_dropped_total.load(Ordering::Relaxed),
                    jogged: self.ledger_jogged.load(Ordering::Relaxed),
                },
                math_overruns: self.math_overruns.load(Ordering::Relaxed),
            },
        })
    }

    fn store_step(&self, step: &StepStatus) {
        // Relaxed: the seqlock orders them for snapshots.
        self.position.store(step.position, Ordering::Relaxed);
        self.mode.store(step.mode, Ordering::Relaxed);
        self.velocity.store(step.velocity, Ordering::Relaxed);
        self.delay_ticks.store(step.delay_ticks, Ordering::Relaxed);
        self.last_step_ct
            .store(step.last_step_ct, Ordering::Relaxed);
        // Release, last: a single-field reader that sees it (Acquire) sees
        // the position of the same step.
        self.steps_to_go.store(step.steps_to_go, Ordering::Release);
    }

    fn store_moves(&self, moves: &MoveStatus) {
        // Relaxed: the seqlock orders them for snapshots.
        self.move_speed.store(moves.move_speed, Ordering::Relaxed);
        self.accel_steps.store(moves.accel_steps, Ordering::Relaxed);
        self.slew_steps.store(moves.slew_steps, Ordering::Relaxed);
        self.top_velocity
            .store(moves.top_velocity, Ordering::Relaxed);
        self.max_velocity
            .store(moves.max_velocity, Ordering::Relaxed);
        self.move_start_ct
            .store(moves.move_start_ct, Ordering::Relaxed);
        self.offset.store(moves.offset, Ordering::Relaxed);
        self.dropped_steps
            .store(moves.dropped_steps, Ordering::Relaxed);
        self.ledger_base.store(moves.ledger.base, Ordering::Relaxed);
        self.ledger_accepted
            .store(moves.ledger.accepted, Ordering::Relaxed);
        self.ledger_dropped
            .store(moves.ledger.dropped, Ordering::Relaxed);
        self.ledger_dropped_total
            .store(moves.ledger.dropped_total, Ordering::Relaxed);
        self.ledger_jogged
            .store(moves.ledger.jogged, Ordering::Relaxed);
        self.math_overruns
            .store(moves.math_overruns, Ordering::Relaxed);
    }
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;

    /// Write `n`: every field a function of `n`, so a mix shows.
    fn write_number(n: u64) -> StatusSnapshot {
        let small = n as u32;
        let signed = n as i64;
        StatusSnapshot {
            step: StepStatus {
                position: signed,
                steps_to_go: n,
                mode: small,
                velocity: small,
                delay_ticks: small,
                last_step_ct: n,
            },
            moves: MoveStatus {
                move_speed: small,
                accel_steps: small,
                slew_steps: small,
                top_velocity: small,
                max_velocity: small,
                move_start_ct: n,
                offset: small,
                dropped_steps: small,
                ledger: StepLedger {
                    base: signed,
                    accepted: signed,
                    dropped: signed,
                    dropped_total: n,
                    jogged: signed,
                },
                math_overruns: n,
            },
        }
    }

    /// Threads hammer a status the writer rewrites as fast as it can:
    /// every snapshot is one write, whole (the loom model proves it; this
    /// runs it on the real memory system).
    #[test]
    fn snapshots_under_a_busy_writer_are_whole() {
        let status = Arc::new(Status::default());
        let stop = Arc::new(AtomicBool::new(false));
        let readers: Vec<_> = (0..2)
            .map(|_| {
                let status = Arc::clone(&status);
                let stop = Arc::clone(&stop);
                std::thread::spawn(move || {
                    let mut last = 0;
                    let mut reads = 0u64;
                    while !stop.load(Ordering::Relaxed) || reads == 0 {
                        let seen = status.snapshot();
                        let n = seen.step.steps_to_go;
                        assert_eq!(seen, write_number(n), "a torn status");
                        assert!(n >= last, "a snapshot went back in time");
                        last = n;
                        reads += 1;
                    }
                    reads
                })
            })
            .collect();
        for n in 1..=200_000 {
            status.publish_all(&write_number(n));
            if n % 3 == 0 {
                // A step write too (the same step's fields again).
                status.publish_step(&write_number(n).step);
            }
        }
        stop.store(true, Ordering::Relaxed);
        for reader in readers {
            assert!(reader.join().unwrap() > 0);
        }
        assert_eq!(status.snapshot(), write_number(200_000));
    }
}

#[cfg(all(test, loom))]
mod loom_tests {
    use super::*;
    use loom::sync::Arc;
    use loom::thread;

    /// Two writes of three fields, a reader racing them: what the reader
    /// gets is the first write, the second, or the state before (all
    /// zero), never a mix. Three fields through the same [`SeqLock`] the
    /// status uses (the protocol is the lock's; more fields only multiply
    /// the states loom explores).
    #[test]
    fn a_reader_never_sees_a_mix_of_two_writes() {
        loom::model(|| {
            let lock = Arc::new(SeqLock::default());
            let fields = Arc::new([AtomicU64::new(0), AtomicU64::new(0), AtomicU64::new(0)]);
            let writer = {
                let lock = Arc::clone(&lock);
                let fields = Arc::clone(&fields);
                thread::spawn(move || {
                    for n in 1..=2 {
                        lock.write(|| {
                            for field in fields.iter() {
                                field.store(n, Ordering::Relaxed);
                            }
                        });
                    }
                })
            };
            let seen = lock.read(|| fields.each_ref().map(|field| field.load(Ordering::Relaxed)));
            assert!(
                seen.iter().all(|field| *field == seen[0]),
                "a mix of two writes: {seen:?}"
            );
            writer.join().unwrap();
            // After the writer, a reader sees its last write.
            let last = lock.read(|| fields.each_ref().map(|field| field.load(Ordering::Relaxed)));
            assert_eq!(last, [2, 2, 2]);
        });
    }

    /// The status itself: the cog's step write against a snapshot, with
    /// every field of [`Status`] (a preemption bound keeps the model small).
    #[test]
    fn a_status_snapshot_is_one_step() {
        let mut model = loom::model::Builder::new();
        model.preemption_bound = Some(2);
        model.check(|| {
            let status = Arc::new(Status::default());
            let cog = {
                let status = Arc::clone(&status);
                thread::spawn(move || {
                    for n in 1..=2u64 {
                        status.publish_step(&StepStatus {
                            position: n as i64,
                            steps_to_go: 2 - n,
                            mode: n as u32,
                            velocity: n as u32,
                            delay_ticks: n as u32,
                            last_step_ct: n,
                        });
                    }
                })
            };
            let step = status.snapshot().step;
            let n = step.last_step_ct;
            if n > 0 {
                assert_eq!(
                    (
                        step.position,
                        step.steps_to_go,
                        step.mode,
                        step.velocity,
                        step.delay_ticks
                    ),
                    (n as i64, 2 - n, n as u32, n as u32, n as u32)
                );
            } else {
                assert_eq!(step, StepStatus::default());
            }
            cog.join().unwrap();
        });
    }
}

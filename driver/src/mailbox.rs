//! Hub memory for one axis: the command slot and the shared status.
//!
//! Everything here is an atomic: any thread may read an axis's status at any
//! time, and commands reach the cog without a lock.
//!
//! # The handoff protocol
//!
//! The command slot follows the reference driver: the parameters are
//! written first and the slot's state last, with release; the cog takes the
//! command with acquire and marks the slot empty ("STM = 0, command taken").
//! Several producers may race for one slot, so a producer first *claims* it:
//!
//! ```text
//! producer                               cog
//! state: EMPTY ─CAS(Acquire)─► CLAIMED
//!   write kind, speed, steps (Relaxed)
//! state ◄─store(Release)─ READY          load(Acquire) == READY
//!                                         read kind, speed, steps (Relaxed)
//!                                         state ◄─store(Release)─ EMPTY
//! ```
//!
//! - A producer whose CAS fails gets [`Busy`](crate::axis::AxisError::Busy):
//!   the slot holds another command not yet taken. Nothing is overwritten,
//!   so no command is lost, and each is taken once because only the cog
//!   empties the slot.
//! - The CAS is `Acquire` so that the cog's reads of the previous command
//!   (before its `Release` store of EMPTY) happen before this producer's
//!   writes: a command's fields are never changed under the cog.
//! - The READY store is `Release` and the cog's load `Acquire`: the fields
//!   written before READY are visible to the cog after it sees READY.
//! - The fields themselves are `Relaxed`: the state word orders them.
//!
//! The status fields are written by the cog only (one writer) and read by
//! anyone; each is independent (`Relaxed`), except `stm`, stored with
//! `Release` after the position and mode of the same step so that a reader
//! who sees STM = 0 with `Acquire` also sees the final position.
//!
//! This protocol is model-checked with loom (`mailbox::loom_tests`).

use crate::sync::{AtomicI64, AtomicU32, AtomicU64, Ordering};

/// The slot holds no command.
const EMPTY: u32 = 0;
/// A producer owns the slot and is writing the fields.
const CLAIMED: u32 = 1;
/// A command waits for the cog.
const READY: u32 = 2;

/// What a command asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CommandKind {
    /// `move(speed, steps)`.
    Move,
    /// Set the position counter (`steps` holds the new value).
    SetPosition,
}

impl CommandKind {
    fn code(self) -> u32 {
        match self {
            CommandKind::Move => 1,
            CommandKind::SetPosition => 2,
        }
    }

    fn from_code(code: u32) -> Option<Self> {
        match code {
            1 => Some(CommandKind::Move),
            2 => Some(CommandKind::SetPosition),
            _ => None,
        }
    }
}

/// A command as the cog takes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Command {
    pub kind: CommandKind,
    pub speed: u32,
    pub steps: i64,
}

/// One axis's hub memory.
#[derive(Debug, Default)]
pub(crate) struct Mailbox {
    state: AtomicU32,
    kind: AtomicU32,
    speed: AtomicU32,
    steps: AtomicI64,
    /// Status, written by the cog.
    pub position: AtomicI64,
    pub stm: AtomicU32,
    pub mode: AtomicU32,
    pub move_speed: AtomicU32,
    pub accel_steps: AtomicU32,
    pub offset: AtomicU32,
    pub top_velocity: AtomicU32,
    pub slew_steps: AtomicU32,
    pub velocity: AtomicU32,
    pub delay_ticks: AtomicU32,
    /// Steps the last controlled or emergency stop left unmade.
    pub dropped_steps: AtomicU32,
    /// CT of the last step's rising edge.
    pub last_step_ct: AtomicU64,
    /// CT at which the current move was taken.
    pub move_start_ct: AtomicU64,
    /// Steps whose delay was shorter than the CORDIC math they needed.
    pub math_overruns: AtomicU64,
    /// Commands the cog could not apply after taking them (never silent).
    pub refused: AtomicU64,
    /// Jog request: speed in the low 32 bits, bit 32 reverse, bit 33 active.
    pub jog: AtomicU64,
    /// CT of the last jog heartbeat.
    pub jog_beat_ct: AtomicU64,
    /// Incremented to ask for an emergency stop.
    pub estop_requests: AtomicU32,
    /// Set while a reversal waits for the axis to stop (so a producer can say Busy).
    pub queued: AtomicU32,
}

/// The slot was not free.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct SlotBusy;

impl Mailbox {
    /// Posts a command; `Err(SlotBusy)` when another one waits.
    pub fn post(&self, command: Command) -> Result<(), SlotBusy> {
        // Acquire: the cog's reads of the previous command happened before.
        self.state
            .compare_exchange(EMPTY, CLAIMED, Ordering::Acquire, Ordering::Relaxed)
            .map_err(|_| SlotBusy)?;
        self.kind.store(command.kind.code(), Ordering::Relaxed);
        self.speed.store(command.speed, Ordering::Relaxed);
        self.steps.store(command.steps, Ordering::Relaxed);
        // Release: publishes the fields with the state ("STM last").
        self.state.store(READY, Ordering::Release);
        Ok(())
    }

    /// The cog's side: takes the waiting command, if any, and frees the slot.
    pub fn take(&self) -> Option<Command> {
        // Acquire: pairs with the producer's Release of READY.
        if self.state.load(Ordering::Acquire) != READY {
            return None;
        }
        let kind = CommandKind::from_code(self.kind.load(Ordering::Relaxed));
        let speed = self.speed.load(Ordering::Relaxed);
        let steps = self.steps.load(Ordering::Relaxed);
        // Release: our reads above happen before the next producer's writes.
        self.state.store(EMPTY, Ordering::Release);
        kind.map(|kind| Command { kind, speed, steps })
    }

    /// Whether a command waits to be taken.
    pub fn has_command(&self) -> bool {
        self.state.load(Ordering::Acquire) != EMPTY
    }
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;

    #[test]
    fn a_second_command_waits_its_turn() {
        let mailbox = Mailbox::default();
        let first = Command {
            kind: CommandKind::Move,
            speed: 100,
            steps: 5,
        };
        let second = Command {
            kind: CommandKind::Move,
            speed: 200,
            steps: -5,
        };
        assert_eq!(mailbox.post(first), Ok(()));
        assert_eq!(mailbox.post(second), Err(SlotBusy));
        assert_eq!(mailbox.take(), Some(first));
        assert_eq!(mailbox.take(), None);
        assert_eq!(mailbox.post(second), Ok(()));
        assert_eq!(mailbox.take(), Some(second));
    }

    #[test]
    fn racing_producers_lose_nothing() {
        use std::sync::Arc;
        let mailbox = Arc::new(Mailbox::default());
        let producers: Vec<_> = (0..4u32)
            .map(|p| {
                let mailbox = Arc::clone(&mailbox);
                std::thread::spawn(move || {
                    let mut accepted = Vec::new();
                    for i in 0..2_000u32 {
                        let command = Command {
                            kind: CommandKind::Move,
                            speed: p * 10_000 + i + 1,
                            steps: i64::from(i),
                        };
                        while mailbox.post(command).is_err() {
                            std::thread::yield_now();
                        }
                        accepted.push(command.speed);
                    }
                    accepted
                })
            })
            .collect();
        let mut taken = Vec::new();
        while taken.len() < 8_000 {
            if let Some(command) = mailbox.take() {
                assert_eq!(i64::from((command.speed - 1) % 10_000), command.steps);
                taken.push(command.speed);
            }
        }
        let mut posted: Vec<u32> = producers
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect();
        posted.sort_unstable();
        taken.sort_unstable();
        assert_eq!(posted, taken);
    }
}

#[cfg(all(test, loom))]
mod loom_tests {
    use super::*;
    use loom::sync::Arc;
    use loom::thread;

    /// Two producers race for one slot while the cog takes: every command is
    /// either refused (Busy) or taken exactly once, with its own fields.
    #[test]
    fn handoff_loses_and_duplicates_nothing() {
        loom::model(|| {
            let mailbox = Arc::new(Mailbox::default());
            let producers: Vec<_> = [(10u32, 1i64), (20, 2)]
                .into_iter()
                .map(|(speed, steps)| {
                    let mailbox = Arc::clone(&mailbox);
                    thread::spawn(move || {
                        mailbox
                            .post(Command {
                                kind: CommandKind::Move,
                                speed,
                                steps,
                            })
                            .is_ok()
                    })
                })
                .collect();
            let mut taken = Vec::new();
            for _ in 0..3 {
                if let Some(command) = mailbox.take() {
                    taken.push(command);
                }
                thread::yield_now();
            }
            let accepted: Vec<bool> = producers.into_iter().map(|h| h.join().unwrap()).collect();
            if let Some(command) = mailbox.take() {
                taken.push(command);
            }
            for command in &taken {
                // Fields never mix between producers.
                assert_eq!(i64::from(command.speed / 10), command.steps);
            }
            let expected = accepted.iter().filter(|a| **a).count();
            assert_eq!(taken.len(), expected);
            if taken.len() == 2 {
                assert_ne!(taken[0].speed, taken[1].speed);
            }
        });
    }

    /// The status handshake: the cog stores the position of a step, then STM
    /// with Release; a reader that sees the final STM = 0 with Acquire also
    /// sees the final position (what `run_until_idle` callers and status
    /// readers rely on).
    #[test]
    fn a_reader_that_sees_stm_zero_sees_the_final_position() {
        loom::model(|| {
            let mailbox = Arc::new(Mailbox::default());
            mailbox.stm.store(2, Ordering::Relaxed);
            let cog = {
                let mailbox = Arc::clone(&mailbox);
                thread::spawn(move || {
                    for (position, stm) in [(1, 1), (2, 0)] {
                        mailbox.position.store(position, Ordering::Relaxed);
                        mailbox.stm.store(stm, Ordering::Release);
                    }
                })
            };
            if mailbox.stm.load(Ordering::Acquire) == 0 {
                assert_eq!(mailbox.position.load(Ordering::Relaxed), 2);
            }
            cog.join().unwrap();
        });
    }

    /// A taken command's fields are never overwritten under the cog: a
    /// producer that wins the slot after the cog freed it cannot change what
    /// the cog read before freeing it.
    #[test]
    fn a_freed_slot_is_reused_only_after_the_cog_has_read_it() {
        loom::model(|| {
            let mailbox = Arc::new(Mailbox::default());
            let first = Command {
                kind: CommandKind::Move,
                speed: 10,
                steps: 1,
            };
            mailbox.post(first).unwrap();
            let producer = {
                let mailbox = Arc::clone(&mailbox);
                thread::spawn(move || {
                    let second = Command {
                        kind: CommandKind::Move,
                        speed: 20,
                        steps: 2,
                    };
                    while mailbox.post(second).is_err() {
                        thread::yield_now();
                    }
                })
            };
            assert_eq!(mailbox.take(), Some(first));
            producer.join().unwrap();
            assert_eq!(mailbox.take().map(|c| (c.speed, c.steps)), Some((20, 2)));
        });
    }
}

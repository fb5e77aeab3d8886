//! Hub memory for one axis: the command slot and the shared status.
//!
//! Everything here is an atomic: any thread may read an axis's status at any
//! time, and commands reach the cog without a lock.
//!
//! # The handoff protocol
//!
//! The command slot follows the reference driver — the parameters are
//! written first and the slot's state last, with release; the cog takes the
//! command with acquire and writes STM = 0 ("command taken") — with one
//! addition that makes every `Ok` a promise: the cog decides whether to take
//! the command with the state it acts on ([`AxisCore`](cogstep_motion::axis_core::AxisCore)),
//! writes its answer into the slot, and the producer reads it before it
//! returns. Several producers may race for one slot, so a producer first
//! *claims* it:
//!
//! ```text
//! producer                               cog
//! state: EMPTY ─CAS(Acquire)─► CLAIMED
//!   write kind, speed, steps, STM (Relaxed)
//! state ◄─store(Release)─ READY          load(Acquire) == READY
//!                                         read kind, speed, steps (Relaxed)
//!                                         apply: Ok, or a typed refusal
//!                                         write reply, STM = 0 (Relaxed)
//! load(Acquire) == DONE ◄─────────────── state ◄─store(Release)─ DONE
//! read reply (Relaxed)
//! state ◄─store(Release)─ EMPTY
//! ```
//!
//! - A producer whose CAS fails waits for the slot (the other producer's
//!   command is answered within one look of the cog): the slot being taken is
//!   not a refusal. Nothing is overwritten, so no command is lost, and each
//!   is applied once because only the cog moves READY to DONE.
//! - The CAS is `Acquire` so that the previous producer's read of its reply
//!   (before its `Release` store of EMPTY) happens before this producer's
//!   writes: a command's fields and reply are never changed under a reader.
//! - READY is stored with `Release` and loaded by the cog with `Acquire`:
//!   the fields written before are visible to the cog. DONE likewise
//!   publishes the reply (and everything the command changed in the status)
//!   to the producer.
//! - The fields themselves are `Relaxed`: the state word orders them.
//!   (A refusal's text rides in a small lock beside the reply words, taken
//!   only for the three refusals that carry one.)
//!
//! The words themselves are the codec's (`mailbox::codec`): exhaustive
//! both ways, an unknown word a typed decode error, never another command.
//!
//! Settings too large for the words (homing's configuration, soft limits,
//! limit pins, a fault clear) take the same slot and the same handshake:
//! kind `Setting`, the command itself in a small lock beside the words,
//! ordered by the state word like them ([`Mailbox::post_setting`],
//! [`Mailbox::take_setting`]). A cog has one command channel.
//!
//! The status is written by the cog only (one writer) and read by anyone,
//! as one snapshot: see [`crate::status`] (a seqlock).
//!
//! This protocol is model-checked with loom (`mailbox::loom_tests`), through
//! these very functions.

use crossbeam::utils::CachePadded;

use crate::sync::{AtomicI64, AtomicU32, AtomicU64, Mutex, Ordering};
use cogstep_motion::axis::AxisError;
use cogstep_motion::axis_core::CoreCommand;

pub(crate) use crate::status::Status;

mod codec;

use codec::{decode_reply, encode_reply, ReplyWords, TEXT_CODES};
pub(crate) use codec::{Command, CommandKind, DecodeError};

/// The slot holds no command.
const EMPTY: u32 = 0;
/// A producer owns the slot and is writing the fields.
const CLAIMED: u32 = 1;
/// A command waits for the cog.
const READY: u32 = 2;
/// The cog has answered; the producer reads the reply and frees the slot.
const DONE: u32 = 3;

/// The command slot: what producers CAS on, on a cache line of its own.
#[derive(Debug, Default)]
struct Slot {
    state: AtomicU32,
    kind: AtomicU32,
    speed: AtomicU32,
    steps: AtomicI64,
    reply: AtomicU32,
    /// A refusal's numbers ([`ReplyWords`]).
    reply_numbers: [AtomicU32; 2],
    /// A refusal's text: only for the few that carry one, so the lock is
    /// never contended (the state word orders it like the other fields).
    reply_text: Mutex<&'static str>,
    /// A setting's command ([`CommandKind::Setting`]): only for those, so
    /// the lock is never contended (the state word orders it like the
    /// other fields).
    setting: Mutex<Option<CoreCommand>>,
}

/// One axis's hub memory.
#[derive(Debug, Default)]
pub(crate) struct Mailbox {
    slot: CachePadded<Slot>,
    /// The reference's STM: the signed steps of a move not yet taken.
    pub stm: AtomicI64,
    /// Status, written by the cog (on its own cache line, away from the slot).
    pub status: CachePadded<Status>,
    /// Emergency stops asked for and carried out.
    pub estop: Handshake,
    /// Changes of the stop pin made and seen by the cog.
    pub inputs: Handshake,
}

/// A request counter and the cog's "done up to here" (emergency stops,
/// input changes): the asker counts up with Release after writing what the
/// cog must see (a pin level); the cog reads the count with Acquire, acts,
/// and publishes the count it handled with Release, so an asker that sees
/// its request done also sees what the cog did about it.
#[derive(Debug, Default)]
pub(crate) struct Handshake {
    asked: AtomicU64,
    done: AtomicU64,
}

impl Handshake {
    /// Asks once more; returns the number to wait for with [`Handshake::is_done`].
    pub fn ask(&self) -> u64 {
        // AcqRel: Release publishes what the asker wrote before; Acquire
        // orders concurrent askers.
        self.asked.fetch_add(1, Ordering::AcqRel) + 1
    }

    /// The cog's side: how many requests there are (Acquire: what the
    /// askers wrote before is visible).
    pub fn asked(&self) -> u64 {
        self.asked.load(Ordering::Acquire)
    }

    /// The cog's side: every request up to `count` is carried out
    /// (Release: its effects are visible to whoever sees this).
    pub fn finish(&self, count: u64) {
        self.done.store(count, Ordering::Release);
    }

    /// Whether request `count` has been carried out.
    pub fn is_done(&self, count: u64) -> bool {
        self.done.load(Ordering::Acquire) >= count
    }
}

/// The slot was not free.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct SlotBusy;

impl Mailbox {
    /// Posts a command; `Err(SlotBusy)` while another one is in the slot.
    /// A posted command must then be awaited with [`Mailbox::poll_reply`].
    pub fn post(&self, command: Command) -> Result<(), SlotBusy> {
        let slot = &self.slot;
        // Acquire: the previous producer's read of its reply happened before.
        slot.state
            .compare_exchange(EMPTY, CLAIMED, Ordering::Acquire, Ordering::Relaxed)
            .map_err(|_| SlotBusy)?;
        slot.kind.store(command.kind.code(), Ordering::Relaxed);
        slot.speed.store(command.speed, Ordering::Relaxed);
        slot.steps.store(command.steps, Ordering::Relaxed);
        if command.kind == CommandKind::Move {
            self.stm.store(command.steps, Ordering::Relaxed);
        }
        // Release: publishes the fields with the state ("STM last").
        slot.state.store(READY, Ordering::Release);
        Ok(())
    }

    /// Posts a setting (homing, soft limits, limit pins, a fault clear):
    /// the same slot and handshake as [`Mailbox::post`], the command in the
    /// slot's setting lock. Awaited with [`Mailbox::poll_reply`] likewise.
    pub fn post_setting(&self, setting: CoreCommand) -> Result<(), SlotBusy> {
        let slot = &self.slot;
        // Acquire: the previous producer's read of its reply happened before.
        slot.state
            .compare_exchange(EMPTY, CLAIMED, Ordering::Acquire, Ordering::Relaxed)
            .map_err(|_| SlotBusy)?;
        slot.kind
            .store(CommandKind::Setting.code(), Ordering::Relaxed);
        slot.speed.store(0, Ordering::Relaxed);
        slot.steps.store(0, Ordering::Relaxed);
        *slot
            .setting
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner()) = Some(setting);
        // Release: publishes the fields and the setting with the state.
        slot.state.store(READY, Ordering::Release);
        Ok(())
    }

    /// The cog's side, after [`Mailbox::take`] gave a
    /// [`CommandKind::Setting`]: the setting's command (`None` if the slot
    /// held none, which the cog answers as a fault).
    pub fn take_setting(&self) -> Option<CoreCommand> {
        self.slot
            .setting
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .take()
    }

    /// The producer's side after a post: `Some(answer)` once the cog has
    /// answered (the slot is then free again), `None` while it has not.
    pub fn poll_reply(&self) -> Option<Result<(), AxisError>> {
        let slot = &self.slot;
        // Acquire: pairs with the cog's Release of DONE.
        if slot.state.load(Ordering::Acquire) != DONE {
            return None;
        }
        let code = slot.reply.load(Ordering::Relaxed);
        let words = ReplyWords {
            code,
            numbers: [
                slot.reply_numbers[0].load(Ordering::Relaxed),
                slot.reply_numbers[1].load(Ordering::Relaxed),
            ],
            // Only a text code's text is this reply's (the lock is taken
            // for those alone).
            text: TEXT_CODES.contains(&code).then(|| {
                *slot
                    .reply_text
                    .lock()
                    .unwrap_or_else(|poisoned| poisoned.into_inner())
            }),
        };
        // Release: our read above happens before the next producer's writes.
        slot.state.store(EMPTY, Ordering::Release);
        Some(decode_reply(words).unwrap_or_else(|error| Err(error.into_axis_error())))
    }

    /// The cog's side: the waiting command, if any: `Some(Err(..))` for a
    /// word that is no command (the cog answers it with that fault). The
    /// cog answers it with [`Mailbox::answer`] before it looks at the slot
    /// again.
    pub fn take(&self) -> Option<Result<Command, DecodeError>> {
        let slot = &self.slot;
        // Acquire: pairs with the producer's Release of READY.
        if slot.state.load(Ordering::Acquire) != READY {
            return None;
        }
        let kind = CommandKind::from_code(slot.kind.load(Ordering::Relaxed));
        let speed = slot.speed.load(Ordering::Relaxed);
        let steps = slot.steps.load(Ordering::Relaxed);
        Some(kind.map(|kind| Command { kind, speed, steps }))
    }

    /// The cog's answer to the command it took: STM = 0 (taken), and the
    /// reply; Release so the producer sees it and the applied status.
    pub fn answer(&self, reply: Result<(), AxisError>) {
        let slot = &self.slot;
        let words = encode_reply(reply);
        slot.reply.store(words.code, Ordering::Relaxed);
        for (word, number) in slot.reply_numbers.iter().zip(words.numbers) {
            word.store(number, Ordering::Relaxed);
        }
        if let Some(text) = words.text {
            *slot
                .reply_text
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner()) = text;
        }
        self.stm.store(0, Ordering::Relaxed);
        slot.state.store(DONE, Ordering::Release);
    }

    /// Whether a command waits for the cog.
    pub fn has_command(&self) -> bool {
        self.slot.state.load(Ordering::Acquire) == READY
    }

    /// Whether the slot is in use (a command waits or is being answered).
    pub fn slot_in_use(&self) -> bool {
        self.slot.state.load(Ordering::Acquire) != EMPTY
    }
}

/// The answer the test cogs below give: odd speeds are refused, so that
/// a reply reaching the wrong producer would show.
#[cfg(test)]
fn test_answer(command: &Command) -> Result<(), AxisError> {
    if command.speed % 2 == 1 {
        Err(AxisError::Busy)
    } else {
        Ok(())
    }
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::*;

    fn command(speed: u32, steps: i64) -> Command {
        Command {
            kind: CommandKind::Move,
            speed,
            steps,
        }
    }

    #[test]
    fn a_command_is_answered_then_the_slot_is_free() {
        let mailbox = Mailbox::default();
        assert_eq!(mailbox.post(command(100, 5)), Ok(()));
        assert_eq!(mailbox.stm.load(Ordering::Relaxed), 5);
        // The slot is taken until the producer has read the answer.
        assert_eq!(mailbox.post(command(200, -5)), Err(SlotBusy));
        assert_eq!(mailbox.poll_reply(), None);
        assert_eq!(mailbox.take(), Some(Ok(command(100, 5))));
        mailbox.answer(Err(AxisError::Jogging));
        assert_eq!(mailbox.stm.load(Ordering::Relaxed), 0);
        assert_eq!(mailbox.take(), None);
        assert_eq!(mailbox.post(command(200, -5)), Err(SlotBusy));
        assert_eq!(mailbox.poll_reply(), Some(Err(AxisError::Jogging)));
        assert_eq!(mailbox.post(command(200, -5)), Ok(()));
    }

    #[test]
    fn a_setting_goes_through_the_one_slot() {
        let mailbox = Mailbox::default();
        let setting = CoreCommand::SetLimitPins {
            min: Some((9, true)),
            max: None,
        };
        mailbox.post_setting(setting).unwrap();
        assert_eq!(mailbox.post(command(1, 1)), Err(SlotBusy));
        let taken = mailbox.take().unwrap().unwrap();
        assert_eq!(taken.kind, CommandKind::Setting);
        assert_eq!(mailbox.take_setting(), Some(setting));
        assert_eq!(mailbox.take_setting(), None);
        mailbox.answer(Ok(()));
        assert_eq!(mailbox.poll_reply(), Some(Ok(())));
        assert!(!mailbox.slot_in_use());
    }

    #[test]
    fn racing_producers_each_get_their_own_answer() {
        use std::sync::Arc;
        let mailbox = Arc::new(Mailbox::default());
        let producers: Vec<_> = (0..4u32)
            .map(|p| {
                let mailbox = Arc::clone(&mailbox);
                std::thread::spawn(move || {
                    let mut answers = Vec::new();
                    for i in 0..2_000u32 {
                        let command = command(p * 10_000 + i + 1, i64::from(i));
                        while mailbox.post(command).is_err() {
                            std::thread::yield_now();
                        }
                        let reply = loop {
                            if let Some(reply) = mailbox.poll_reply() {
                                break reply;
                            }
                            std::thread::yield_now();
                        };
                        assert_eq!(reply, test_answer(&command));
                        answers.push(command.speed);
                    }
                    answers
                })
            })
            .collect();
        let mut taken = Vec::new();
        while taken.len() < 8_000 {
            if let Some(command) = mailbox.take() {
                let command = command.expect("a command the producers wrote");
                assert_eq!(i64::from((command.speed - 1) % 10_000), command.steps);
                mailbox.answer(test_answer(&command));
                taken.push(command.speed);
            } else {
                std::thread::yield_now();
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

    fn post_and_wait(mailbox: &Mailbox, command: Command) -> Result<(), AxisError> {
        while mailbox.post(command).is_err() {
            thread::yield_now();
        }
        loop {
            if let Some(reply) = mailbox.poll_reply() {
                return reply;
            }
            thread::yield_now();
        }
    }

    /// Two producers race for one slot while the cog takes and answers:
    /// the one that wins gets the answer the cog gave to its own command,
    /// with its own fields; the one that finds the slot taken is told so
    /// and changes nothing (the real caller then waits and posts again, as
    /// the non-loom test `racing_producers_each_get_their_own_answer` runs).
    #[test]
    fn every_command_is_answered_once_to_its_own_producer() {
        // Three threads that wait by spinning: the preemptions are bounded,
        // as loom advises for spin loops (the model then runs in about a
        // minute in release).
        let mut model = loom::model::Builder::new();
        model.preemption_bound = Some(3);
        model.check(|| {
            let mailbox = Arc::new(Mailbox::default());
            let done = Arc::new(AtomicU64::new(0));
            let producers: Vec<_> = [(10u32, 1i64), (21, 2)]
                .into_iter()
                .map(|(speed, steps)| {
                    let mailbox = Arc::clone(&mailbox);
                    let done = Arc::clone(&done);
                    thread::spawn(move || {
                        let command = Command {
                            kind: CommandKind::Move,
                            speed,
                            steps,
                        };
                        let posted = mailbox.post(command).is_ok();
                        if posted {
                            let reply = loop {
                                if let Some(reply) = mailbox.poll_reply() {
                                    break reply;
                                }
                                thread::yield_now();
                            };
                            assert_eq!(reply, test_answer(&command));
                        }
                        done.fetch_add(1, Ordering::Release);
                        posted
                    })
                })
                .collect();
            // The cog: answers whatever it finds until both producers are done.
            let mut taken = Vec::new();
            while done.load(Ordering::Acquire) < 2 {
                if let Some(command) = mailbox.take() {
                    let command = command.expect("a command the producers wrote");
                    // Fields never mix between producers.
                    assert_eq!(i64::from(command.speed / 10), command.steps);
                    mailbox.answer(test_answer(&command));
                    taken.push(command.speed);
                } else {
                    thread::yield_now();
                }
            }
            let posted = producers
                .into_iter()
                .map(|p| p.join().unwrap())
                .filter(|posted| *posted)
                .count();
            assert_eq!(taken.len(), posted);
            assert!(posted >= 1, "the slot was free for the first");
            assert!(mailbox.take().is_none());
        });
    }

    /// The status handshake: the cog stores the position of a step, then
    /// steps-to-go with Release; a reader that sees the final 0 with Acquire
    /// also sees the final position (what status readers rely on).
    #[test]
    fn a_reader_that_sees_zero_steps_to_go_sees_the_final_position() {
        loom::model(|| {
            let mailbox = Arc::new(Mailbox::default());
            mailbox.status.steps_to_go.store(2, Ordering::Relaxed);
            let cog = {
                let mailbox = Arc::clone(&mailbox);
                thread::spawn(move || {
                    for (position, to_go) in [(1, 1), (2, 0)] {
                        mailbox.status.position.store(position, Ordering::Relaxed);
                        mailbox.status.steps_to_go.store(to_go, Ordering::Release);
                    }
                })
            };
            if mailbox.status.steps_to_go.load(Ordering::Acquire) == 0 {
                assert_eq!(mailbox.status.position.load(Ordering::Relaxed), 2);
            }
            cog.join().unwrap();
        });
    }

    /// What the cog applied before answering is seen by the producer once it
    /// has its answer (a status read right after `move_steps` shows the move).
    #[test]
    fn the_answer_publishes_what_the_command_changed() {
        loom::model(|| {
            let mailbox = Arc::new(Mailbox::default());
            let cog = {
                let mailbox = Arc::clone(&mailbox);
                thread::spawn(move || loop {
                    if mailbox.take().is_some() {
                        mailbox.status.steps_to_go.store(7, Ordering::Relaxed);
                        mailbox.answer(Ok(()));
                        return;
                    }
                    thread::yield_now();
                })
            };
            let command = Command {
                kind: CommandKind::Move,
                speed: 10,
                steps: 7,
            };
            assert_eq!(post_and_wait(&mailbox, command), Ok(()));
            assert_eq!(mailbox.status.steps_to_go.load(Ordering::Relaxed), 7);
            assert_eq!(mailbox.stm.load(Ordering::Relaxed), 0);
            cog.join().unwrap();
        });
    }

    /// The emergency-stop and input handshake: the asker writes a level,
    /// asks; the cog sees the request, reads the level, acts and finishes;
    /// an asker that sees its request done sees the cog's action.
    #[test]
    fn a_request_seen_done_shows_what_the_cog_did() {
        loom::model(|| {
            let mailbox = Arc::new(Mailbox::default());
            let cog = {
                let mailbox = Arc::clone(&mailbox);
                thread::spawn(move || {
                    let mut seen = 0;
                    while seen == 0 {
                        seen = mailbox.inputs.asked();
                        thread::yield_now();
                    }
                    // The level written before the request is visible.
                    let level = mailbox.status.offset.load(Ordering::Relaxed);
                    assert_eq!(level, 1);
                    mailbox.status.mode.store(level + 1, Ordering::Relaxed);
                    mailbox.inputs.finish(seen);
                })
            };
            mailbox.status.offset.store(1, Ordering::Relaxed);
            let wanted = mailbox.inputs.ask();
            while !mailbox.inputs.is_done(wanted) {
                thread::yield_now();
            }
            assert_eq!(mailbox.status.mode.load(Ordering::Relaxed), 2);
            cog.join().unwrap();
        });
    }

    /// A setting rides the same slot: the cog that takes a `Setting` finds
    /// its very command in the setting lock, and the producer gets the
    /// cog's answer to it (the one command channel a cog has).
    #[test]
    fn a_setting_reaches_the_cog_with_its_command() {
        loom::model(|| {
            let mailbox = Arc::new(Mailbox::default());
            let producer = {
                let mailbox = Arc::clone(&mailbox);
                thread::spawn(move || {
                    while mailbox
                        .post_setting(CoreCommand::SetSoftLimits(Some((-5, 5))))
                        .is_err()
                    {
                        thread::yield_now();
                    }
                    loop {
                        if let Some(reply) = mailbox.poll_reply() {
                            return reply;
                        }
                        thread::yield_now();
                    }
                })
            };
            let command = loop {
                if let Some(command) = mailbox.take() {
                    break command;
                }
                thread::yield_now();
            };
            assert_eq!(command.map(|c| c.kind), Ok(CommandKind::Setting));
            let setting = mailbox.take_setting();
            assert_eq!(setting, Some(CoreCommand::SetSoftLimits(Some((-5, 5)))));
            mailbox.answer(Err(AxisError::Homing));
            assert_eq!(producer.join().unwrap(), Err(AxisError::Homing));
        });
    }
}

//! The mailbox's codec: what a command and an answer are as words in the
//! slot. Exhaustive both ways: every [`CommandKind`] and every
//! [`AxisError`] (a [`PlanError`] included) has a code of its own, with its
//! numbers and text; a word that is none of them is a [`DecodeError`],
//! which the caller sees as a fault, never as another command or refusal.

use cogstep_motion::axis::{AxisError, Direction};
use cogstep_motion::profile::PlanError;

/// What a command asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CommandKind {
    /// `move(speed, steps)`.
    Move,
    /// Set the position counter (`steps` holds the new value).
    SetPosition,
    /// A jog heartbeat (`steps` is +1 or −1: the direction).
    Jog,
    /// End a jog.
    JogRelease,
    /// Reserve the axis for a group move (`steps`: its part).
    GroupReserve,
    /// Give a group reservation back.
    GroupCancel,
    /// Run the axis's part of a group move (`steps`; the rest of the move
    /// is in the axis's [`GroupShared`](crate::cog::GroupShared)).
    GroupStart,
    /// Put the axis on a look-ahead path.
    PathStart,
    /// The path sends no more steps.
    PathEnd,
    /// A setting too large for the words (homing, soft limits, limit pins,
    /// a fault clear): the command itself rides in the slot's setting lock.
    Setting,
}

/// A word in the slot that is not one the codec writes: never the cog's
/// answer or another command, a fault of its own.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub(crate) enum DecodeError {
    /// The command word names no command.
    #[error("the mailbox held an unknown command code")]
    UnknownCommand(u32),
    /// The reply word names no answer.
    #[error("the mailbox held an unknown reply code")]
    UnknownReply(u32),
    /// The reply's code carries a text, and the slot held none.
    #[error("the mailbox held a reply without its text")]
    MissingText(u32),
}

impl DecodeError {
    /// What the caller is told: a fault, with the decoder's reason.
    pub fn into_axis_error(self) -> AxisError {
        match self {
            DecodeError::UnknownCommand(_) => {
                AxisError::Fault("the mailbox held an unknown command code")
            }
            DecodeError::UnknownReply(_) => {
                AxisError::Fault("the mailbox held an unknown reply code")
            }
            DecodeError::MissingText(_) => {
                AxisError::Fault("the mailbox held a reply without its text")
            }
        }
    }
}

impl CommandKind {
    /// Every kind, for the codec's round trip.
    #[cfg(all(test, not(loom)))]
    pub(super) const ALL: [CommandKind; 10] = [
        CommandKind::Move,
        CommandKind::SetPosition,
        CommandKind::Jog,
        CommandKind::JogRelease,
        CommandKind::GroupReserve,
        CommandKind::GroupCancel,
        CommandKind::GroupStart,
        CommandKind::Setting,
        CommandKind::PathStart,
        CommandKind::PathEnd,
    ];

    pub(super) fn code(self) -> u32 {
        match self {
            CommandKind::Move => 1,
            CommandKind::SetPosition => 2,
            CommandKind::Jog => 3,
            CommandKind::JogRelease => 4,
            CommandKind::GroupReserve => 5,
            CommandKind::GroupCancel => 6,
            CommandKind::GroupStart => 7,
            CommandKind::Setting => 8,
            CommandKind::PathStart => 9,
            CommandKind::PathEnd => 10,
        }
    }

    pub(super) fn from_code(code: u32) -> Result<Self, DecodeError> {
        match code {
            1 => Ok(CommandKind::Move),
            2 => Ok(CommandKind::SetPosition),
            3 => Ok(CommandKind::Jog),
            4 => Ok(CommandKind::JogRelease),
            5 => Ok(CommandKind::GroupReserve),
            6 => Ok(CommandKind::GroupCancel),
            7 => Ok(CommandKind::GroupStart),
            8 => Ok(CommandKind::Setting),
            9 => Ok(CommandKind::PathStart),
            10 => Ok(CommandKind::PathEnd),
            unknown => Err(DecodeError::UnknownCommand(unknown)),
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

/// The cog's answer as the slot holds it: a code, two words of numbers
/// (a speed, a clock) and a text, for the refusals that carry one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct ReplyWords {
    pub code: u32,
    pub numbers: [u32; 2],
    pub text: Option<&'static str>,
}

impl ReplyWords {
    const fn code(code: u32) -> Self {
        Self {
            code,
            numbers: [0; 2],
            text: None,
        }
    }

    const fn numbers(code: u32, numbers: [u32; 2]) -> Self {
        Self {
            code,
            numbers,
            text: None,
        }
    }

    const fn text(code: u32, text: &'static str) -> Self {
        Self {
            code,
            numbers: [0; 2],
            text: Some(text),
        }
    }
}

/// The cog's answer, as words in the slot. Every answer has a code of its
/// own, so nothing the cog says decodes as something else; a new
/// [`AxisError`] or [`PlanError`] variant does not compile until it has one.
pub(super) fn encode_reply(reply: Result<(), AxisError>) -> ReplyWords {
    let error = match reply {
        Ok(()) => return ReplyWords::code(0),
        Err(error) => error,
    };
    match error {
        AxisError::Busy => ReplyWords::code(1),
        AxisError::NotIdle => ReplyWords::code(2),
        AxisError::Jogging => ReplyWords::code(3),
        AxisError::StopPinLow => ReplyWords::code(4),
        AxisError::TooManySteps => ReplyWords::code(5),
        AxisError::PositionOutOfRange => ReplyWords::code(6),
        AxisError::StepsOutOfRange => ReplyWords::code(7),
        AxisError::Unavailable => ReplyWords::code(8),
        AxisError::Fault(text) => ReplyWords::text(9, text),
        AxisError::Homing => ReplyWords::code(10),
        AxisError::BeyondSoftLimit => ReplyWords::code(11),
        AxisError::IntoLimit(Direction::Forward) => ReplyWords::code(12),
        AxisError::IntoLimit(Direction::Reverse) => ReplyWords::code(13),
        AxisError::DuplicateAxis => ReplyWords::code(14),
        AxisError::PulseTooLong { speed } => ReplyWords::numbers(15, [speed, 0]),
        AxisError::Unsupported(text) => ReplyWords::text(16, text),
        AxisError::HomeSwitchNotFound => ReplyWords::code(17),
        AxisError::HomeSwitchStuck => ReplyWords::code(18),
        AxisError::HomingAborted => ReplyWords::code(19),
        AxisError::BadSetting(text) => ReplyWords::text(20, text),
        AxisError::Plan(plan) => match plan {
            PlanError::ZeroSpeed => ReplyWords::code(21),
            PlanError::ZeroSteps => ReplyWords::code(22),
            PlanError::ZeroClock => ReplyWords::code(23),
            PlanError::SpeedTooHigh { speed, clkfreq } => ReplyWords::numbers(24, [speed, clkfreq]),
            PlanError::BadOffset(offset_deg) => ReplyWords::numbers(25, [offset_deg, 0]),
            PlanError::BadAccelDiv => ReplyWords::code(26),
            PlanError::BadAccel => ReplyWords::code(27),
            PlanError::BadSpeed => ReplyWords::code(28),
            PlanError::DelayOverflow => ReplyWords::code(29),
        },
    }
}

/// The reply codes that carry a text (in the slot's `reply_text`).
pub(super) const TEXT_CODES: [u32; 3] = [9, 16, 20];

/// The highest reply code [`encode_reply`] writes.
#[cfg(all(test, not(loom)))]
const LAST_REPLY_CODE: u32 = 29;

pub(super) fn decode_reply(words: ReplyWords) -> Result<Result<(), AxisError>, DecodeError> {
    let [a, b] = words.numbers;
    let error = match words.code {
        0 => return Ok(Ok(())),
        1 => AxisError::Busy,
        2 => AxisError::NotIdle,
        3 => AxisError::Jogging,
        4 => AxisError::StopPinLow,
        5 => AxisError::TooManySteps,
        6 => AxisError::PositionOutOfRange,
        7 => AxisError::StepsOutOfRange,
        8 => AxisError::Unavailable,
        9 => AxisError::Fault(words.text.ok_or(DecodeError::MissingText(9))?),
        10 => AxisError::Homing,
        11 => AxisError::BeyondSoftLimit,
        12 => AxisError::IntoLimit(Direction::Forward),
        13 => AxisError::IntoLimit(Direction::Reverse),
        14 => AxisError::DuplicateAxis,
        15 => AxisError::PulseTooLong { speed: a },
        16 => AxisError::Unsupported(words.text.ok_or(DecodeError::MissingText(16))?),
        17 => AxisError::HomeSwitchNotFound,
        18 => AxisError::HomeSwitchStuck,
        19 => AxisError::HomingAborted,
        20 => AxisError::BadSetting(words.text.ok_or(DecodeError::MissingText(20))?),
        21 => AxisError::Plan(PlanError::ZeroSpeed),
        22 => AxisError::Plan(PlanError::ZeroSteps),
        23 => AxisError::Plan(PlanError::ZeroClock),
        24 => AxisError::Plan(PlanError::SpeedTooHigh {
            speed: a,
            clkfreq: b,
        }),
        25 => AxisError::Plan(PlanError::BadOffset(a)),
        26 => AxisError::Plan(PlanError::BadAccelDiv),
        27 => AxisError::Plan(PlanError::BadAccel),
        28 => AxisError::Plan(PlanError::BadSpeed),
        29 => AxisError::Plan(PlanError::DelayOverflow),
        unknown => return Err(DecodeError::UnknownReply(unknown)),
    };
    Ok(Err(error))
}

#[cfg(all(test, not(loom)))]
mod tests {
    use super::super::Mailbox;
    use super::*;
    use crate::sync::Ordering;

    fn command(speed: u32, steps: i64) -> Command {
        Command {
            kind: CommandKind::Move,
            speed,
            steps,
        }
    }

    /// One example of every [`AxisError`] (and [`PlanError`]) variant;
    /// `variant` below has no catch-all, so a new variant must be added.
    fn every_error(number: u32, other: u32, text: &'static str) -> Vec<AxisError> {
        vec![
            AxisError::Plan(PlanError::ZeroSpeed),
            AxisError::Plan(PlanError::ZeroSteps),
            AxisError::Plan(PlanError::ZeroClock),
            AxisError::Plan(PlanError::SpeedTooHigh {
                speed: number,
                clkfreq: other,
            }),
            AxisError::Plan(PlanError::BadOffset(number)),
            AxisError::Plan(PlanError::BadAccelDiv),
            AxisError::Plan(PlanError::BadAccel),
            AxisError::Plan(PlanError::BadSpeed),
            AxisError::Plan(PlanError::DelayOverflow),
            AxisError::Busy,
            AxisError::NotIdle,
            AxisError::PulseTooLong { speed: number },
            AxisError::Unsupported(text),
            AxisError::Unavailable,
            AxisError::Fault(text),
            AxisError::Jogging,
            AxisError::StopPinLow,
            AxisError::TooManySteps,
            AxisError::PositionOutOfRange,
            AxisError::StepsOutOfRange,
            AxisError::DuplicateAxis,
            AxisError::Homing,
            AxisError::BeyondSoftLimit,
            AxisError::IntoLimit(Direction::Forward),
            AxisError::IntoLimit(Direction::Reverse),
            AxisError::HomeSwitchNotFound,
            AxisError::HomeSwitchStuck,
            AxisError::HomingAborted,
            AxisError::BadSetting(text),
        ]
    }

    /// Which variant an error is, without a catch-all.
    fn variant(error: &AxisError) -> usize {
        match error {
            AxisError::Plan(plan) => match plan {
                PlanError::ZeroSpeed => 0,
                PlanError::ZeroSteps => 1,
                PlanError::ZeroClock => 2,
                PlanError::SpeedTooHigh { .. } => 3,
                PlanError::BadOffset(_) => 4,
                PlanError::BadAccelDiv => 5,
                PlanError::BadAccel => 6,
                PlanError::BadSpeed => 7,
                PlanError::DelayOverflow => 8,
            },
            AxisError::Busy => 9,
            AxisError::NotIdle => 10,
            AxisError::PulseTooLong { .. } => 11,
            AxisError::Unsupported(_) => 12,
            AxisError::Unavailable => 13,
            AxisError::Fault(_) => 14,
            AxisError::Jogging => 15,
            AxisError::StopPinLow => 16,
            AxisError::TooManySteps => 17,
            AxisError::PositionOutOfRange => 18,
            AxisError::StepsOutOfRange => 19,
            AxisError::DuplicateAxis => 20,
            AxisError::Homing => 21,
            AxisError::BeyondSoftLimit => 22,
            AxisError::IntoLimit(Direction::Forward) => 23,
            AxisError::IntoLimit(Direction::Reverse) => 24,
            AxisError::HomeSwitchNotFound => 25,
            AxisError::HomeSwitchStuck => 26,
            AxisError::HomingAborted => 27,
            AxisError::BadSetting(_) => 28,
        }
    }

    #[test]
    fn the_error_list_names_every_variant_once() {
        let errors = every_error(1, 2, "x");
        let mut seen: Vec<usize> = errors.iter().map(variant).collect();
        seen.sort_unstable();
        assert_eq!(seen, (0..errors.len()).collect::<Vec<_>>());
    }

    #[test]
    fn every_reply_code_is_one_answer_and_back() {
        let mut codes: Vec<u32> = every_error(7, 9, "why")
            .into_iter()
            .map(|error| encode_reply(Err(error)).code)
            .chain([encode_reply(Ok(())).code])
            .collect();
        codes.sort_unstable();
        // One code per answer, and no gap: 0 ..= LAST_REPLY_CODE.
        assert_eq!(codes, (0..=LAST_REPLY_CODE).collect::<Vec<_>>());
        for code in 0..=LAST_REPLY_CODE {
            let words = ReplyWords {
                code,
                numbers: [3, 4],
                text: TEXT_CODES.contains(&code).then_some("t"),
            };
            let reply = decode_reply(words).expect("a code the codec writes");
            assert_eq!(encode_reply(reply).code, code);
        }
        for unknown in [LAST_REPLY_CODE + 1, 100, u32::MAX] {
            assert_eq!(
                decode_reply(ReplyWords::code(unknown)),
                Err(DecodeError::UnknownReply(unknown))
            );
        }
        for code in TEXT_CODES {
            assert_eq!(
                decode_reply(ReplyWords::code(code)),
                Err(DecodeError::MissingText(code))
            );
        }
    }

    #[test]
    fn every_command_kind_is_one_code_and_back() {
        let mut codes: Vec<u32> = CommandKind::ALL.iter().map(|kind| kind.code()).collect();
        codes.sort_unstable();
        codes.dedup();
        assert_eq!(codes.len(), CommandKind::ALL.len());
        for kind in CommandKind::ALL {
            assert_eq!(CommandKind::from_code(kind.code()), Ok(kind));
        }
        for unknown in (0..1_000)
            .chain([u32::MAX])
            .filter(|code| !codes.contains(code))
        {
            assert_eq!(
                CommandKind::from_code(unknown),
                Err(DecodeError::UnknownCommand(unknown))
            );
        }
    }

    /// A word no producer writes comes out as the typed decode error and
    /// the producer is told a fault: never another command, never Ok.
    #[test]
    fn a_corrupt_word_in_the_slot_is_a_fault_not_another_command() {
        let mailbox = Mailbox::default();
        mailbox.post(command(100, 5)).unwrap();
        mailbox.slot.kind.store(99, Ordering::Relaxed);
        assert_eq!(mailbox.take(), Some(Err(DecodeError::UnknownCommand(99))));
        mailbox.answer(Err(DecodeError::UnknownCommand(99).into_axis_error()));
        assert_eq!(
            mailbox.poll_reply(),
            Some(Err(AxisError::Fault(
                "the mailbox held an unknown command code"
            )))
        );
        mailbox.post(command(100, 5)).unwrap();
        assert!(mailbox.take().is_some());
        mailbox.answer(Ok(()));
        mailbox
            .slot
            .reply
            .store(LAST_REPLY_CODE + 1, Ordering::Relaxed);
        assert_eq!(
            mailbox.poll_reply(),
            Some(Err(AxisError::Fault(
                "the mailbox held an unknown reply code"
            )))
        );
    }

    proptest::proptest! {
        /// Every command through the slot comes out as it went in.
        #[test]
        fn every_command_round_trips_through_the_slot(
            kind in proptest::sample::select(CommandKind::ALL.to_vec()),
            speed in proptest::num::u32::ANY,
            steps in proptest::num::i64::ANY,
        ) {
            let mailbox = Mailbox::default();
            let sent = Command { kind, speed, steps };
            mailbox.post(sent).unwrap();
            proptest::prop_assert_eq!(mailbox.take(), Some(Ok(sent)));
            mailbox.answer(Ok(()));
            proptest::prop_assert_eq!(mailbox.poll_reply(), Some(Ok(())));
        }

        /// Every answer the cog gives, each error variant with any
        /// numbers and text, reaches the producer as it was given, also
        /// after another answer in the same slot.
        #[test]
        fn every_answer_round_trips_through_the_slot(
            number in proptest::num::u32::ANY,
            other in proptest::num::u32::ANY,
            text in proptest::sample::select(vec!["", "a", "the cog refused the command"]),
            before in 0usize..29,
        ) {
            let mailbox = Mailbox::default();
            let errors = every_error(number, other, text);
            let earlier = every_error(other, number, "earlier")[before];
            for error in errors {
                for answer in [Err(earlier), Err(error), Ok(())] {
                    proptest::prop_assert_eq!(decode_reply(encode_reply(answer)), Ok(answer));
                    mailbox.post(command(1, 1)).unwrap();
                    proptest::prop_assert!(mailbox.take().is_some());
                    mailbox.answer(answer);
                    proptest::prop_assert_eq!(mailbox.poll_reply(), Some(answer));
                }
            }
        }
    }
}

//! What an axis is doing, as one value.
//!
//! Everything that says what the axis does now — a move waiting for the
//! stop pin, a group reservation, a group move, the motion in progress and
//! whom it belongs to (moves, a jog, homing), a stop under way — is one
//! [`State`], so no two flags can disagree: a held move cannot coexist
//! with a jog, a group member cannot also run a move of its own, homing
//! cannot outlive the motion it drives.
//!
//! ```text
//!            move (stop pin low)          stop pin high
//!   Idle ─────────────────────────► Held ──────────────► Running(Moves)
//!    │ ▲ move / jog / home                                 │   ▲
//!    │ └───────────── last period ends, e-stop ────────────┘   │
//!    │ GroupReserve        GroupStart                          │
//!    └────────────► Reserved ────────► Group ── line ends ─► Idle
//! ```

use super::group::Follower;
use super::homing::Homing;
use super::path::PathPart;
use crate::axis::Direction;

/// What the axis is doing (see the module docs).
// No allocation here (`no_std`, no alloc): a group part's copy of the lead
// curve lives inline, as it did beside the flags before; one per axis.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub(super) enum State {
    /// Nothing moves, nothing waits: a command is taken at once.
    Idle,
    /// A move taken while the stop pin is low (nothing else moves): it
    /// runs when the pin goes high.
    Held(HeldMove),
    /// A coordinated move reserved the axis: nothing else may start until
    /// it starts or is cancelled.
    Reserved,
    /// The axis runs its part of a coordinated move.
    Group(Follower),
    /// The axis is on a look-ahead path: it makes the steps pushed to it.
    Path(PathPart),
    /// The motion has steps scheduled (or the last step's period still
    /// runs): a move, merged moves or a queued reversal.
    Running(Run),
}

/// A move that waits for the stop pin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct HeldMove {
    pub(super) speed: u32,
    pub(super) steps: i32,
}

/// The motion in progress.
#[derive(Clone, Copy, Debug)]
pub(super) struct Run {
    /// When the next step (or the end of the last step's period) is due.
    pub(super) due: u64,
    /// Whom the steps belong to.
    pub(super) owner: Owner,
    /// The stop pin went low and the motion was told to stop.
    pub(super) stopping: bool,
    /// A reversal was queued: its first step begins a new move.
    pub(super) queued_start: bool,
}

/// Whom the running motion belongs to.
#[derive(Clone, Copy, Debug)]
pub(super) enum Owner {
    /// Moves; `held` is a move taken after the stop pin went low, run when
    /// it goes high (the motion is then stopping).
    Moves { held: Option<HeldMove> },
    /// A jog: its heartbeat, until it is released or times out (the motion
    /// then decelerates, still the jog's: its steps are not a target's).
    Jog(Option<Jog>),
    /// Homing: its current stage's move.
    Homing(Homing),
}

/// A jog's heartbeat.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Jog {
    pub(super) speed: u32,
    pub(super) direction: Direction,
    /// The CT by which the next heartbeat must come.
    pub(super) deadline: u64,
}

impl State {
    /// The running motion, if any.
    pub(super) fn run(&self) -> Option<&Run> {
        match self {
            State::Running(run) => Some(run),
            _ => None,
        }
    }

    /// The running motion, if any, to change.
    pub(super) fn run_mut(&mut self) -> Option<&mut Run> {
        match self {
            State::Running(run) => Some(run),
            _ => None,
        }
    }

    /// The jog's heartbeat, while a jog owns the axis and is not released.
    pub(super) fn jog(&self) -> Option<Jog> {
        match self.run()?.owner {
            Owner::Jog(jog) => jog,
            _ => None,
        }
    }

    /// Whether the running motion belongs to a jog.
    pub(super) fn jog_owns(&self) -> bool {
        matches!(
            self,
            State::Running(Run {
                owner: Owner::Jog(_),
                ..
            })
        )
    }

    /// Homing in progress.
    pub(super) fn homing(&self) -> Option<&Homing> {
        match &self.run()?.owner {
            Owner::Homing(homing) => Some(homing),
            _ => None,
        }
    }

    /// The move waiting for the stop pin.
    pub(super) fn held(&self) -> Option<HeldMove> {
        match self {
            State::Held(held) => Some(*held),
            State::Running(Run {
                owner: Owner::Moves { held },
                ..
            }) => *held,
            _ => None,
        }
    }

    /// The group move this axis follows.
    pub(super) fn follower(&self) -> Option<&Follower> {
        match self {
            State::Group(follower) => Some(follower),
            _ => None,
        }
    }

    /// The group move this axis follows, to change.
    pub(super) fn follower_mut(&mut self) -> Option<&mut Follower> {
        match self {
            State::Group(follower) => Some(follower),
            _ => None,
        }
    }
}

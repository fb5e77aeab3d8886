//! What a cog shares with the hub and the axis handles: the hub's pins and
//! clocks ([`HubShared`]), one axis's mailbox, handshakes and published
//! state ([`CogShared`], with the calls that post a command and wait for
//! the cog's answer), and a group move's shared stop ([`GroupShared`]).

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex};
use std::thread::Thread;
use std::time::Duration;

use crate::clock::{ClockMode, EpochDone, Epochs, RealClock};
use crate::mailbox::{Command, Mailbox};
use crate::pins::PinBank;
use crate::switch::Switch;
use crate::sync::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use crate::trace::EdgeTap;
use cogstep_motion::axis::{AxisError, Direction, HomeReport, LimitTrip};
use cogstep_motion::axis_core::{CoreCommand, Outputs};

/// The hub's state that cogs read: pins, time, the epoch protocol.
#[derive(Debug)]
pub(crate) struct HubShared {
    pub clock: ClockMode,
    pub pins: PinBank,
    pub real: RealClock,
    /// Virtual clock: CT and the epochs the cogs run.
    pub epochs: Epochs,
    /// The thread waiting for an epoch to finish.
    pub waiter: Mutex<Option<Thread>>,
    /// Real-clock cogs ask for real-time priority ([`crate::HubConfig::realtime_priority`]).
    pub realtime_priority: bool,
}

impl HubShared {
    /// CT now, for inputs applied from outside.
    pub fn now(&self) -> u64 {
        match self.clock {
            ClockMode::Virtual => self.epochs.now(),
            ClockMode::Real => self.real.now(),
        }
    }

    pub(super) fn wake_waiter(&self) {
        if let Ok(waiter) = self.waiter.lock() {
            if let Some(thread) = waiter.as_ref() {
                thread.unpark();
            }
        }
    }
}

/// One group move, shared by its members' cogs: what every member runs
/// (the lead's speed and steps, the start CT) and the group's stop.
///
/// The stop is one word: `stop_after` (u64::MAX = none), lowered with
/// `fetch_min` (Release) by whoever stops the group and read (Acquire) by
/// every member's cog before each of its events. A member's copy of the
/// lead curve decelerates from the first lead edge after that CT, so the
/// copies agree as long as no cog has passed that CT when the word is
/// written: with the virtual clock the hub writes it between epochs at the
/// CT every cog stands at; with the real clock it names a CT a millisecond
/// ahead of the clock ([`GroupShared::REAL_STOP_LEAD_MS`]), and cogs never
/// run events ahead of the clock.
#[derive(Debug)]
pub(crate) struct GroupShared {
    pub speed: u32,
    pub lead_steps: u32,
    pub start_ct: u64,
    pub stop_after: AtomicU64,
    /// The members (weak: the members hold this group).
    pub members: Vec<std::sync::Weak<CogShared>>,
    /// With the virtual clock, each member's progress (same order as
    /// `members`): every event of its part before this CT is done
    /// (`u64::MAX` once its part ended). A member runs an event at `t` only
    /// when every other member has reached `t`, so a stop one of them asks
    /// for at `t` (a hard limit) reaches all of them before they pass it:
    /// the members run in lockstep, and the line stays one line.
    pub progress: Vec<AtomicU64>,
}

impl GroupShared {
    /// With the real clock, how far ahead of the clock a group stop lands, ms.
    pub const REAL_STOP_LEAD_MS: u64 = 1;

    /// Stops the group along its line from the first lead edge after `ct`.
    pub fn stop_after(&self, ct: u64) {
        // AcqRel: Release publishes the stop to the members' Acquire load;
        // racing stoppers agree on the earliest CT.
        self.stop_after.fetch_min(ct, Ordering::AcqRel);
    }

    /// Publishes member `slot`'s progress (see [`GroupShared::progress`]).
    pub fn set_progress(&self, slot: usize, ct: u64) {
        if let Some(progress) = self.progress.get(slot) {
            // Release: a stop (or an e-stop request) this member made before
            // is seen by a member that reads this progress with Acquire.
            progress.store(ct, Ordering::Release);
        }
    }

    /// Whether a member still runs its part (the group has not ended).
    pub fn is_live(&self) -> bool {
        // Acquire: pairs with set_progress's Release.
        self.progress
            .iter()
            .any(|progress| progress.load(Ordering::Acquire) != u64::MAX)
    }

    /// Whether every member but `slot` has reached `t` (or is gone).
    pub fn others_reached(&self, slot: usize, t: u64) -> bool {
        self.progress.iter().enumerate().all(|(i, progress)| {
            let gone = || {
                self.members
                    .get(i)
                    .is_some_and(|member| member.upgrade().is_none_or(|m| m.is_shut_down()))
            };
            // Acquire: pairs with set_progress's Release.
            i == slot || progress.load(Ordering::Acquire) >= t || gone()
        })
    }

    /// The CT the group stops after, if a stop was asked (a member's cog
    /// reads it before each of its events).
    pub fn stop_ct(&self) -> Option<u64> {
        // Acquire: pairs with the stopper's fetch_min.
        let after = self.stop_after.load(Ordering::Acquire);
        (after != u64::MAX).then_some(after)
    }
}

/// One axis's state shared between its handles, the hub and its cog.
#[derive(Debug)]
pub(crate) struct CogShared {
    pub id: usize,
    pub mailbox: Mailbox,
    pub outputs: Outputs,
    pub stop_pin: u8,
    pub tap: EdgeTap,
    /// Set when the cog is told to stop, and by the cog itself when its
    /// thread ends for any reason (a panic included): its axis is gone.
    pub shutdown: AtomicBool,
    /// Virtual clock: the last epoch this cog finished, and its CT then.
    pub epoch_done: EpochDone,
    pub thread: Mutex<Option<Thread>>,
    /// The last group move this axis was (or is) a member of; set by the hub
    /// before it posts the group's start.
    pub group: Mutex<Option<Arc<GroupShared>>>,
    /// Simulated switches this axis drives (read by the cog when the
    /// inputs sequence moves).
    pub switches: Mutex<Vec<Switch>>,
    /// The input pins the axis acts on (stop pin apart), published by the cog.
    pub watched: AtomicU64,
    /// The physical position (signed count of step edges), published by the cog.
    pub physical: AtomicI64,
    /// Limits and homing, published by the cog when they change.
    pub extras: Mutex<Extras>,
    /// A path's steps for this axis, `(CT, forward)` in time order, written
    /// by the path's owner ahead of the clock and moved into the core by
    /// the cog as it has room ([`crate::path`]).
    pub path_feed: Mutex<VecDeque<(u64, bool)>>,
    /// What the cog tells the path's owner (on the path or not, a trip, a
    /// refused step).
    pub path: PathSignals,
    /// Signalled whenever the cog answered a command or handled an input,
    /// for callers that wait for it ([`CogShared::wait_until`]).
    progress: Mutex<()>,
    progressed: Condvar,
}

impl CogShared {
    pub fn new(id: usize, outputs: Outputs, stop_pin: u8, tap: EdgeTap) -> Self {
        Self {
            id,
            mailbox: Mailbox::default(),
            outputs,
            stop_pin,
            tap,
            shutdown: AtomicBool::new(false),
            epoch_done: EpochDone::default(),
            thread: Mutex::new(None),
            group: Mutex::new(None),
            switches: Mutex::new(Vec::new()),
            watched: AtomicU64::new(0),
            physical: AtomicI64::new(0),
            extras: Mutex::new(Extras::default()),
            path_feed: Mutex::new(VecDeque::new()),
            path: PathSignals::default(),
            progress: Mutex::new(()),
            progressed: Condvar::new(),
        }
    }

    /// Wakes the cog's thread to look at its inputs.
    pub fn kick(&self) {
        if let Ok(thread) = self.thread.lock() {
            if let Some(thread) = thread.as_ref() {
                thread.unpark();
            }
        }
    }

    pub fn is_shut_down(&self) -> bool {
        self.shutdown.load(Ordering::Acquire)
    }

    /// Tells waiters that the cog did something they may wait for. Taking
    /// the lock orders this after the waiter's check, so no wake-up is lost.
    pub(super) fn notify(&self) {
        let _guard = self.progress.lock();
        self.progressed.notify_all();
    }

    /// Waits until `done()` holds: a real wait, woken by the cog. The only
    /// way out without it is the cog being gone, which is an error.
    pub fn wait_until(&self, mut done: impl FnMut() -> bool) -> Result<(), AxisError> {
        let mut guard = self
            .progress
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        loop {
            if done() {
                return Ok(());
            }
            if self.is_shut_down() {
                return Err(AxisError::Unavailable);
            }
            // The timeout only re-checks for a cog that died without a word.
            guard = self
                .progressed
                .wait_timeout(guard, Duration::from_millis(50))
                .unwrap_or_else(|poisoned| poisoned.into_inner())
                .0;
        }
    }

    /// Posts a command and waits for the cog's answer: `Ok` means the axis
    /// took it and will carry it out.
    pub fn call(&self, command: Command) -> Result<(), AxisError> {
        self.call_with(|| self.mailbox.post(command).is_ok())
    }

    /// Posts a setting (homing, soft limits, limit pins, a fault clear)
    /// through the same slot and handshake as every command, and waits for
    /// the cog's answer: `Ok` means it was taken.
    pub fn call_setting(&self, setting: CoreCommand) -> Result<(), AxisError> {
        self.call_with(|| self.mailbox.post_setting(setting).is_ok())
    }

    /// Posts with `post` (true once the slot took it) and waits for the
    /// cog's answer.
    fn call_with(&self, post: impl Fn() -> bool) -> Result<(), AxisError> {
        if self.is_shut_down() {
            return Err(AxisError::Unavailable);
        }
        // The slot is busy only while another caller's command is answered.
        self.wait_until(&post)?;
        self.kick();
        let mut reply = None;
        let waited = self.wait_until(|| {
            reply = reply.or_else(|| self.mailbox.poll_reply());
            reply.is_some()
        });
        match (reply, waited) {
            (Some(reply), _) => reply,
            (None, Err(error)) => Err(error),
            (None, Ok(())) => Err(AxisError::Unavailable),
        }
    }
}

/// What an axis's cog tells the owner of the path the axis is on: whether
/// its core is on the path, a hard limit that tripped, a step it refused.
///
/// The cog writes the trip and the refusal before it says the core left
/// the path (Release), and the owner reads that word first (Acquire), so a
/// core that left because of a trip is reported as the trip, never as a
/// plain stop (loom: `a_trip_is_seen_with_the_core_leaving_the_path`).
#[derive(Debug, Default)]
pub(crate) struct PathSignals {
    on_path: AtomicBool,
    tripped: crate::sync::Mutex<Option<Direction>>,
    refused: crate::sync::Mutex<Option<AxisError>>,
}

/// What [`PathSignals::fault`] finds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum PathSignal {
    /// A step the core refused.
    Refused(AxisError),
    /// A hard limit tripped.
    Tripped(Direction),
    /// The core left the path (an e-stop).
    Left,
}

impl PathSignals {
    /// The cog: where its core stands (`trip`: its tripped hard limit).
    pub fn publish(&self, on_path: bool, trip: Option<Direction>) {
        *signal_lock(&self.tripped) = trip;
        // Release: the trip above is seen by whoever sees this word.
        self.on_path.store(on_path, Ordering::Release);
    }

    /// The cog: the core refused a step of the path.
    pub fn refuse(&self, error: AxisError) {
        *signal_lock(&self.refused) = Some(error);
    }

    /// The path's owner: what went wrong, if anything.
    pub fn fault(&self) -> Option<PathSignal> {
        // Acquire first: pairs with publish's Release.
        let left = !self.on_path.load(Ordering::Acquire);
        if let Some(error) = signal_lock(&self.refused).take() {
            return Some(PathSignal::Refused(error));
        }
        if let Some(side) = *signal_lock(&self.tripped) {
            return Some(PathSignal::Tripped(side));
        }
        left.then_some(PathSignal::Left)
    }

    /// The path's owner, starting: nothing refused yet.
    pub fn clear(&self) {
        *signal_lock(&self.refused) = None;
    }
}

fn signal_lock<T>(mutex: &crate::sync::Mutex<T>) -> impl std::ops::DerefMut<Target = T> + '_ {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// The limit and homing state of an axis, as its cog last published it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Extras {
    pub home_outcome: Option<Result<HomeReport, AxisError>>,
    pub limit_trip: Option<LimitTrip>,
    pub soft_limits: Option<(i64, i64)>,
    pub limit_pins: [Option<(u8, bool)>; 2],
    pub homing: bool,
}

pub(super) fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl CogShared {
    /// Re-reads the switches and settings: the cog has taken them when this returns.
    pub fn refresh(&self) -> Result<(), AxisError> {
        let seq = self.mailbox.inputs.ask();
        self.kick();
        self.wait_until(|| self.mailbox.inputs.is_done(seq))
    }
}

/// Marks the axis gone when the cog's thread ends, however it ends.
pub(super) struct ExitGuard(pub(super) Arc<CogShared>);

impl Drop for ExitGuard {
    fn drop(&mut self) {
        self.0.shutdown.store(true, Ordering::Release);
        self.0.notify();
    }
}

/// The group stop's handoff, model-checked: with the virtual clock the hub
/// stops a group between epochs (`Hub::set_input`), then starts the next
/// epoch (`epoch.fetch_add`, AcqRel); every member's cog that sees the new
/// epoch (Acquire) must see the stop before it runs an event of that epoch,
/// or the copies of the lead curve would part. A second stopper racing in
/// (another member's stop pin, from another thread) cannot make a member
/// see a later stop than the hub's.
#[cfg(all(test, loom))]
mod loom_tests {
    use super::*;
    use loom::sync::Arc;
    use loom::thread;

    fn group() -> GroupShared {
        GroupShared {
            speed: 1_000,
            lead_steps: 100,
            start_ct: 0,
            stop_after: AtomicU64::new(u64::MAX),
            members: Vec::new(),
            progress: (0..2).map(|_| AtomicU64::new(0)).collect(),
        }
    }

    /// The lockstep of a group's members with the virtual clock: a member
    /// that trips a limit at CT 5 asks for the line's stop, then says it is
    /// past CT 5; the other member, about to run its event at CT 8, waits
    /// for that and must then see the stop (or its copy of the lead curve
    /// would run past the line's end).
    #[test]
    fn a_member_sees_a_stop_asked_at_a_ct_before_it_passes_it() {
        loom::model(|| {
            let group = Arc::new(group());
            let tripper = {
                let group = Arc::clone(&group);
                thread::spawn(move || {
                    group.stop_after(5);
                    group.set_progress(0, 10);
                })
            };
            while !group.others_reached(1, 8) {
                thread::yield_now();
            }
            assert_eq!(group.stop_ct(), Some(5));
            tripper.join().unwrap();
        });
    }

    /// A path axis's cog trips a limit and says its core left the path;
    /// the path's owner, polling, must report the trip (it stops the path
    /// as a limit fault), never a plain stop.
    #[test]
    fn a_trip_is_seen_with_the_core_leaving_the_path() {
        loom::model(|| {
            let signals = Arc::new(PathSignals::default());
            signals.publish(true, None);
            let cog = {
                let signals = Arc::clone(&signals);
                thread::spawn(move || signals.publish(false, Some(Direction::Forward)))
            };
            let seen = loop {
                if let Some(fault) = signals.fault() {
                    break fault;
                }
                thread::yield_now();
            };
            assert_eq!(seen, PathSignal::Tripped(Direction::Forward));
            cog.join().unwrap();
        });
    }

    #[test]
    fn every_member_sees_the_stop_before_the_next_epoch() {
        loom::model(|| {
            let group = Arc::new(group());
            let epoch = Arc::new(AtomicU64::new(0));
            // One member: each member's cog reads the same two words alike.
            let members: Vec<_> = (0..1)
                .map(|_| {
                    let group = Arc::clone(&group);
                    let epoch = Arc::clone(&epoch);
                    thread::spawn(move || {
                        // The cog: once it sees the new epoch, it looks at
                        // the group before its first event (look_at_group).
                        // (Seeing the old epoch it would wait: no event runs.)
                        (epoch.load(Ordering::Acquire) == 1).then(|| group.stop_ct())
                    })
                })
                .collect();
            let racer = {
                let group = Arc::clone(&group);
                thread::spawn(move || group.stop_after(7_000))
            };
            // The hub: the stop at the CT every cog stands at, then the epoch.
            group.stop_after(5_000);
            epoch.fetch_add(1, Ordering::AcqRel);
            for member in members {
                if let Some(seen) = member.join().unwrap() {
                    assert_eq!(seen, Some(5_000));
                }
            }
            racer.join().unwrap();
            assert_eq!(group.stop_ct(), Some(5_000));
        });
    }
}

//! Stops and their accounts: the stop pin, the emergency stop, and the
//! ledger entries of the steps they leave unmade.

use super::state::{HeldMove, Owner, State};
use super::{AxisCore, StepLedger};
use crate::axis::{AxisError, Direction, Mode};

impl AxisCore {
    /// Sets the position counter; the ledger starts again from it.
    pub(super) fn reset_position(&mut self, position: i64) {
        self.position = position;
        self.ledger = StepLedger {
            base: position,
            dropped_total: self.ledger.dropped_total,
            ..StepLedger::default()
        };
    }

    /// Counts steps of taken moves that will not be made.
    pub(super) fn drop_steps(&mut self, signed: i64) {
        self.ledger.dropped += signed;
        self.ledger.dropped_total = self
            .ledger
            .dropped_total
            .saturating_add(signed.unsigned_abs());
    }

    /// Drops a held move: its steps are counted as not made.
    pub(super) fn drop_held(&mut self, held: HeldMove) {
        self.drop_steps(i64::from(held.steps));
        self.last_dropped = self.last_dropped.saturating_add(held.steps.unsigned_abs());
    }

    /// A stop ended what the motion still had to make: counted as dropped
    /// (and reported as the last stop's) unless a jog owned it (a jog has
    /// no target: its unmade chunk was never promised).
    pub(super) fn account_stop(&mut self, dropped: i64, jog_owned: bool) {
        self.last_dropped = 0;
        if !jog_owned {
            self.drop_steps(dropped);
            self.last_dropped = u32::try_from(dropped.unsigned_abs()).unwrap_or(u32::MAX);
        }
    }

    /// Controlled stop of the motion, its unmade steps accounted for.
    pub(super) fn stop_motion(&mut self) {
        let dropped = self.motion.stop();
        let jog_owned = self.state.jog_owns();
        self.account_stop(dropped, jog_owned);
        if let Some(run) = self.state.run_mut() {
            run.queued_start = false;
        }
    }

    /// Emergency stop at CT `t`: no more steps of anything taken; the
    /// position is kept, every unmade step is counted.
    pub(super) fn emergency_stop(&mut self, t: u64) {
        let state = core::mem::replace(&mut self.state, State::Idle);
        match state {
            State::Group(follower) => {
                // A part whose line already ended counted its unmade steps then.
                if follower.finish_at.is_none() {
                    let unmade = follower.steps - follower.made;
                    self.drop_steps(i64::from(unmade) * follower.direction.sign());
                    self.last_dropped = unmade;
                }
            }
            State::Path(part) => {
                self.state = State::Path(part);
                self.drop_path();
                self.state = State::Idle;
            }
            State::Idle | State::Reserved => {
                let dropped = self.motion.estop();
                self.account_stop(dropped, false);
            }
            State::Held(held) => {
                let dropped = self.motion.estop();
                self.account_stop(dropped, false);
                self.drop_held(held);
            }
            State::Running(run) => {
                let dropped = self.motion.estop();
                self.account_stop(dropped, matches!(run.owner, Owner::Jog(_)));
                match run.owner {
                    Owner::Moves { held: Some(held) } => self.drop_held(held),
                    Owner::Homing(_) => self.end_homing(Err(AxisError::HomingAborted)),
                    Owner::Moves { held: None } | Owner::Jog(_) => {}
                }
            }
        }
        // No more steps of the old move: the next one starts now, once the
        // last pulse has fallen and stayed low for a pulse width (not when
        // the old step's delay would have ended).
        self.ready_ct = t.max(self.last_fall_ct + u64::from(self.config.pulse_ticks));
        self.sticky = Mode::ESTOP | (self.sticky & Mode::STOP_LATCHED);
        self.step_bits = Mode::empty();
        self.last_step.velocity = 0;
    }

    /// The stop pin's level at CT `t`: low decelerates at once from the
    /// current velocity (the steps left are counted as dropped); high lets
    /// a held move run.
    pub fn set_stop_pin(&mut self, t: u64, high: bool) {
        self.stop_pin_high = high;
        if high {
            let held = match &mut self.state {
                State::Held(held) => {
                    let held = *held;
                    self.state = State::Idle;
                    Some(held)
                }
                State::Running(run) => {
                    run.stopping = false;
                    match &mut run.owner {
                        Owner::Moves { held } => held.take(),
                        Owner::Jog(_) | Owner::Homing(_) => None,
                    }
                }
                State::Idle | State::Reserved | State::Group(_) | State::Path(_) => None,
            };
            if let Some(held) = held {
                // Admitted again: a limit may have tripped or a soft limit
                // moved while it waited. The motion can only be stopping (or
                // idle) now, so it runs, merges or queues. Should it be
                // refused, its steps are counted, not lost.
                let started = self
                    .check_limit(Direction::of(held.steps))
                    .and_then(|()| self.check_soft_move(held.speed, held.steps))
                    .and_then(|()| self.start_or_merge(t, held.speed, held.steps));
                if started.is_err() {
                    self.last_dropped = 0;
                    self.drop_held(held);
                }
            }
            return;
        }
        let stopping = self.state.run().is_none_or(|run| run.stopping);
        if !stopping && self.motion.is_moving() {
            self.abort_homing(AxisError::HomingAborted);
            self.stop_motion();
            if let Some(run) = self.state.run_mut() {
                run.stopping = true;
                if let Owner::Jog(beat) = &mut run.owner {
                    *beat = None;
                }
            }
            self.sticky |= Mode::STOP_LATCHED;
        }
    }
}

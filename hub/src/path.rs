//! A look-ahead path on the hub: a stream of coordinated lines run through
//! blended junctions ([`cogstep_motion::planner`]), with hold, resume,
//! overrides, cancel and progress.
//!
//! [`Hub::path`] puts axes on a path ([`PathJob`]); lines pushed to it are
//! planned together, and the job's [`PathRunner`] decides when every axis
//! steps. The steps go to each axis's cog through a feed, ahead of the
//! clock, and each axis's core makes them on their CTs (with its pins'
//! set-up and pulse, its limits and its step accounts; see
//! `cogstep_motion::axis_core`'s path part).
//!
//! ```text
//! PathJob::push(line) ─► PathRunner (plan, timeline) ─► edges, ahead of the clock
//!     ─► each axis's feed ─► its cog ─► AxisCore (path part) ─► pins
//! ```
//!
//! - **Virtual clock:** the hub's [`Hub::advance`] runs a path in slices of
//!   at most [`PATH_SLICE_MS`]: before each, the job reads its axes' stop
//!   pins and faults and computes every edge of the slice. A push to a full
//!   queue advances the clock until a line is done; [`PathJob::wait`]
//!   advances it until the path is done.
//! - **Real clock:** a thread of the job's does the same every millisecond,
//!   [`PATH_HORIZON_MS`] ahead of the clock; a push to a full queue waits.
//!
//! A stop pin low on any axis of the path holds the path along the path
//! ([`PathRunner::hold`]); it resumes when [`PathJob::resume`] is called
//! with every stop pin high. An emergency stop of any of its axes, or a
//! hard limit that trips, stops every axis of the path at once: the path
//! ends with a [`PathFault`], the positions are those of the steps made,
//! and the steps not made are in each axis's ledger. With the real clock
//! the other axes stop when the job sees it (within a millisecond); with
//! the virtual clock at the end of the slice.

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex, Weak};
use std::thread::JoinHandle;
use std::time::Duration;

use crate::axis::Axis;
use crate::clock::ClockMode;
use crate::cog::{CogShared, HubShared, PathSignal};
use crate::hub::{lock, request_estop, wait_for_estop, Hub};
use crate::mailbox::{Command, CommandKind};
use cogstep_motion::axis::{AxisError, Direction};
use cogstep_motion::planner::{
    Blending, Line, Machine, MachineError, PathRunner, PathState, PushError, RunError, MAX_AXES,
};

/// The most lines a path plans over.
pub const PATH_QUEUE_LINES: usize = 32;

/// With the virtual clock, the longest slice a path's axes run between two
/// looks at their inputs, ms.
pub const PATH_SLICE_MS: u64 = 1;

/// With the real clock, how far ahead of the clock a path's steps are
/// computed, ms: the longest a hold waits before it starts.
pub const PATH_HORIZON_MS: u64 = 10;

type Runner = PathRunner<PATH_QUEUE_LINES, MAX_AXES>;

/// A path's machine: every axis's limits in steps, the corner rule.
#[derive(Clone, Debug, PartialEq)]
pub struct PathMachine {
    /// Each axis's top speed, steps/s (one per axis of the path).
    pub max_speed_steps_per_s: Vec<f64>,
    /// Each axis's top acceleration, steps/s².
    pub max_accel_steps_per_s2: Vec<f64>,
    /// grbl's junction deviation, in steps of step space.
    pub junction_deviation_steps: f64,
    /// Exact stop or blending, for the lines pushed until it is changed.
    pub blending: Blending,
}

/// Why a path stopped at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PathFault {
    /// An axis of the path (its index in the path) was stopped: an
    /// emergency stop, or its cog is gone.
    #[error("axis {0} of the path was stopped")]
    Stopped(usize),
    /// A hard limit tripped on axis `axis` of the path.
    #[error("axis {axis} of the path met its {side:?} hard limit")]
    Limit {
        /// The axis, as its index in the path.
        axis: usize,
        /// Which limit.
        side: Direction,
    },
    /// The core refused a step of the path (a limit), on axis `axis`.
    #[error("axis {axis} of the path refused a step: {error}")]
    Refused {
        /// The axis, as its index in the path.
        axis: usize,
        /// The core's refusal.
        error: AxisError,
    },
    /// [`PathJob::emergency_stop`].
    #[error("the path was stopped at once")]
    EmergencyStop,
}

/// What a path refuses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PathError {
    /// Starting the path: an axis refused (see [`Hub::path`]).
    #[error(transparent)]
    Axis(#[from] AxisError),
    /// The machine's limits.
    #[error(transparent)]
    Machine(#[from] MachineError),
    /// A line the planner does not take (no motion, a bad feed).
    #[error(transparent)]
    Line(#[from] PushError),
    /// A line's steps are not one per axis of the path.
    #[error("a line must give steps for each of the path's {0} axes")]
    AxisCount(usize),
    /// A line would end beyond axis `axis`'s soft limits.
    #[error("the line ends beyond axis {axis}'s soft limits")]
    BeyondSoftLimit {
        /// The axis, as its index in the path.
        axis: usize,
    },
    /// A line's end is beyond the range of a position.
    #[error("the line's end is beyond the range of a position")]
    PositionOutOfRange,
    /// A dwell that is not 0 or more seconds and finite.
    #[error("a dwell must be 0 or more seconds and finite")]
    Dwell,
    /// An override outside 10 % to 200 % (rapids: 1 % to 100 %).
    #[error("an override must be 10 % to 200 % (rapids 1 % to 100 %)")]
    Override,
    /// The queue is full ([`PathJob::try_push`]).
    #[error("the path's queue is full")]
    Full,
    /// The path was cancelled while the push waited for room (or since
    /// the count the push was given, [`PathJob::push_unless_cancelled`]).
    #[error("the path was cancelled")]
    Cancelled,
    /// `resume` while the path is not held at rest, or with a stop pin low.
    #[error("the path is not held at rest with every stop pin high")]
    NotHeld,
    /// A push waited for room with the virtual clock while the path came
    /// to rest in a hold: nothing frees room until it is resumed, so the
    /// push is refused (nothing queued) rather than advancing the clock
    /// for ever. Resume ([`PathControl::resume`]) and push again.
    #[error("the path's queue is full and the path is held: resume it first")]
    HeldFull,
    /// The path stopped at once and takes nothing more.
    #[error("the path stopped: {0}")]
    Stopped(PathFault),
}

impl From<RunError> for PathError {
    fn from(error: RunError) -> Self {
        match error {
            RunError::Push(push) => PathError::Line(push),
            RunError::PositionOutOfRange => PathError::PositionOutOfRange,
            RunError::NotHeld => PathError::NotHeld,
            RunError::Dwell => PathError::Dwell,
        }
    }
}

/// Where a path stands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathProgress {
    /// Running, holding, held at rest, or idle (everything queued made:
    /// the axes at rest too).
    pub state: PathState,
    /// The tag of the line the axes run now (its G-code line number, say);
    /// 0 before the first.
    pub tag: u32,
    /// Lines whose every step has been made.
    pub done: u64,
    /// Lines queued and not done.
    pub queued: usize,
    /// The speed along the path now, steps/s in step space.
    pub speed_steps_per_s: f64,
    /// The feed and rapid overrides, percent.
    pub overrides: (u32, u32),
    /// Why the path stopped at once, if it did.
    pub fault: Option<PathFault>,
}

/// One line's span of edges, for progress: the CT of its first and last
/// edge computed so far.
#[derive(Clone, Copy, Debug)]
struct Span {
    tag: u32,
    first: u64,
    last: u64,
}

/// The job's state, under its lock.
struct PathInner {
    runner: Box<Runner>,
    /// Edges computed up to this CT (the slice or horizon filled).
    filled: u64,
    spans: VecDeque<Span>,
    /// Lines whose spans ended before the clock.
    spans_done: u64,
    overrides: (u32, u32),
    fault: Option<PathFault>,
    /// A hold asked for by the owner (not a stop pin).
    hold_asked: bool,
    /// How many times the path was cancelled.
    cancels: u64,
    /// The path took `end` (no more lines): its axes are let go.
    ended: bool,
    /// Lines pushed (tags given) in all.
    pushed: u64,
}

/// A path's state shared between its handle, the hub and its thread.
pub(crate) struct PathShared {
    hub: Arc<HubShared>,
    axes: Vec<Arc<CogShared>>,
    inner: Mutex<PathInner>,
    changed: Condvar,
    clkfreq: u32,
}

impl PathShared {
    /// Looks at the axes, holds or stops the path, and computes its edges
    /// up to `fill_to` into the axes' feeds. `now` is the clock's CT.
    pub(crate) fn service(&self, now: u64, fill_to: u64) {
        let mut inner = lock(&self.inner);
        if inner.ended || inner.fault.is_some() {
            return;
        }
        if let Some(fault) = self.find_fault() {
            self.stop_all(&mut inner, fault);
            self.changed.notify_all();
            return;
        }
        let stop_pin_low = self
            .axes
            .iter()
            .any(|axis| !self.hub.pins.input(axis.stop_pin));
        if stop_pin_low || inner.hold_asked {
            // The hold starts after every edge computed (the feeds hold
            // what is ahead of the clock).
            let at = inner.filled.max(now);
            inner.runner.hold(at);
        }
        let mut fed = [false; MAX_AXES];
        while let Some(edge) = inner.runner.next_edge_until(fill_to) {
            let axis = usize::from(edge.axis);
            if let Some(cog) = self.axes.get(axis) {
                lock(&cog.path_feed).push_back((edge.ct, edge.forward));
                fed[axis] = true;
            }
            match inner.spans.back_mut() {
                Some(span) if span.tag == edge.tag => span.last = edge.ct,
                _ => inner.spans.push_back(Span {
                    tag: edge.tag,
                    first: edge.ct,
                    last: edge.ct,
                }),
            }
        }
        inner.filled = inner.filled.max(fill_to);
        while inner.spans.len() > 1 && inner.spans[0].last < now {
            inner.spans.pop_front();
            inner.spans_done += 1;
        }
        for (cog, fed) in self.axes.iter().zip(fed) {
            if fed {
                cog.kick();
            }
        }
        self.changed.notify_all();
    }

    /// An axis that left the path, tripped a limit or refused a step.
    fn find_fault(&self) -> Option<PathFault> {
        for (index, cog) in self.axes.iter().enumerate() {
            if cog.is_shut_down() {
                return Some(PathFault::Stopped(index));
            }
            let Some(signal) = cog.path.fault() else {
                continue;
            };
            return Some(match signal {
                PathSignal::Refused(error) => PathFault::Refused { axis: index, error },
                PathSignal::Tripped(side) => PathFault::Limit { axis: index, side },
                PathSignal::Left => PathFault::Stopped(index),
            });
        }
        None
    }

    /// Stops every axis at once and ends the path with `fault`.
    fn stop_all(&self, inner: &mut PathInner, fault: PathFault) {
        inner.runner.emergency_stop();
        inner.fault = Some(fault);
        for cog in &self.axes {
            lock(&cog.path_feed).clear();
            request_estop(cog);
        }
    }

    /// Whether the path needs its axes to run: something queued, or steps
    /// in a feed.
    /// (Held at rest, the path waits for its owner: not active.)
    pub(crate) fn is_active(&self) -> bool {
        let inner = lock(&self.inner);
        let running = matches!(
            inner.runner.state(),
            PathState::Running | PathState::Holding
        );
        !inner.ended && inner.fault.is_none() && running
            || self.axes.iter().any(|cog| !lock(&cog.path_feed).is_empty())
    }

    fn is_done(&self, inner: &PathInner) -> bool {
        (inner.fault.is_some() || matches!(inner.runner.state(), PathState::Idle))
            && self.axes_at_rest()
    }

    /// Every step fed to the axes made: nothing in a feed, nothing to go.
    fn axes_at_rest(&self) -> bool {
        self.axes.iter().all(|cog| {
            lock(&cog.path_feed).is_empty() && cog.mailbox.status.snapshot().step.steps_to_go == 0
        })
    }
}

/// A look-ahead path on some axes of a hub (see the module docs and
/// [`Hub::path`]). Dropping it without [`PathJob::finish`] stops its axes
/// at once if they still move, and lets them go.
pub struct PathJob {
    control: PathControl,
    thread: Option<JoinHandle<()>>,
}

/// A handle on a path for another thread ([`PathJob::control`]): hold,
/// resume, cancel, overrides, emergency stop and progress, while the
/// job's owner may be waiting in [`PathJob::push`]. It does not keep the
/// path's axes: once the job is finished or dropped, a hold or a resume
/// does nothing more and the progress stays where the path ended.
#[derive(Clone)]
pub struct PathControl {
    hub: Hub,
    shared: Arc<PathShared>,
}

impl std::fmt::Debug for PathControl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PathControl")
            .field("axes", &self.shared.axes.len())
            .finish()
    }
}

impl std::fmt::Debug for PathJob {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PathJob")
            .field("axes", &self.control.shared.axes.len())
            .finish()
    }
}

impl Hub {
    /// Puts `axes` (1 to 8 axes of this hub, each once) on a look-ahead
    /// path with `machine`'s limits (one entry per axis, in the same
    /// order). All or nothing, as [`Hub::move_together`]: each axis must be
    /// idle with its stop pin high and no hard limit tripped, or nothing
    /// starts and the first refusal is the error ([`AxisError::Busy`],
    /// [`AxisError::StopPinLow`], [`AxisError::IntoLimit`],
    /// [`AxisError::DuplicateAxis`], [`AxisError::Unsupported`] for an axis
    /// of another hub, [`AxisError::Unavailable`]); a machine the planner
    /// refuses is [`PathError::Machine`]. While on the path an axis refuses
    /// every other motion.
    pub fn path(&self, axes: &[&Axis], machine: PathMachine) -> Result<PathJob, PathError> {
        if axes.is_empty() || axes.len() > MAX_AXES {
            return Err(MachineError::AxisCount.into());
        }
        if machine.max_speed_steps_per_s.len() != axes.len()
            || machine.max_accel_steps_per_s2.len() != axes.len()
        {
            return Err(PathError::AxisCount(axes.len()));
        }
        for (i, axis) in axes.iter().enumerate() {
            if !Arc::ptr_eq(&axis.hub.inner, &self.inner) {
                return Err(AxisError::Unsupported("an axis of another hub").into());
            }
            axis.alive()?;
            if axes[..i].iter().any(|other| other.cog() == axis.cog()) {
                return Err(AxisError::DuplicateAxis.into());
            }
        }
        // The unused axes of the runner never move; their limits are the first's.
        let mut planner_machine = Machine {
            max_speed_steps_per_s: [machine.max_speed_steps_per_s[0]; MAX_AXES],
            max_accel_steps_per_s2: [machine.max_accel_steps_per_s2[0]; MAX_AXES],
            junction_deviation_steps: machine.junction_deviation_steps,
            blending: machine.blending,
        };
        planner_machine.max_speed_steps_per_s[..axes.len()]
            .copy_from_slice(&machine.max_speed_steps_per_s);
        planner_machine.max_accel_steps_per_s2[..axes.len()]
            .copy_from_slice(&machine.max_accel_steps_per_s2);
        let mut positions = [0i64; MAX_AXES];
        for (position, axis) in positions.iter_mut().zip(axes) {
            *position = axis.position();
        }
        let clkfreq = self.inner.config.clkfreq;
        // Checked before any axis is reserved.
        Runner::new(planner_machine, positions, 0, clkfreq)?;

        let _admission = lock(&self.inner.grouping);
        let mut started: Vec<&Axis> = Vec::with_capacity(axes.len());
        for axis in axes {
            lock(&axis.shared.path_feed).clear();
            axis.shared.path.clear();
            let reply = axis.shared.call(Command {
                kind: CommandKind::PathStart,
                speed: 0,
                steps: 0,
            });
            if let Err(error) = reply {
                for axis in started {
                    let _ = axis.shared.call(Command {
                        kind: CommandKind::PathEnd,
                        speed: 0,
                        steps: 0,
                    });
                }
                return Err(error.into());
            }
            started.push(axis);
        }
        // Positions read again: the axes are on the path, nothing moves them.
        for (position, axis) in positions.iter_mut().zip(axes) {
            *position = axis.position();
        }
        let setup = u64::from(self.inner.config.dir_setup_ticks);
        let origin = match self.inner.config.clock {
            ClockMode::Virtual => self.now() + setup,
            ClockMode::Real => self.now() + setup + u64::from(clkfreq) / 500,
        };
        let runner = Runner::new(planner_machine, positions, origin, clkfreq)?;
        let shared = Arc::new(PathShared {
            hub: Arc::clone(&self.inner.shared),
            axes: axes.iter().map(|axis| Arc::clone(&axis.shared)).collect(),
            inner: Mutex::new(PathInner {
                runner: Box::new(runner),
                filled: origin,
                spans: VecDeque::new(),
                spans_done: 0,
                overrides: (100, 100),
                fault: None,
                hold_asked: false,
                cancels: 0,
                ended: false,
                pushed: 0,
            }),
            changed: Condvar::new(),
            clkfreq,
        });
        let thread = match self.inner.config.clock {
            ClockMode::Virtual => {
                lock(&self.inner.paths).push(Arc::downgrade(&shared));
                None
            }
            ClockMode::Real => Some(spawn_real(Arc::downgrade(&shared))?),
        };
        Ok(PathJob {
            control: PathControl {
                hub: self.clone(),
                shared,
            },
            thread,
        })
    }

    /// The live paths (virtual clock), the dead ones forgotten.
    pub(crate) fn live_paths(&self) -> Vec<Arc<PathShared>> {
        let mut paths = lock(&self.inner.paths);
        paths.retain(|path| path.strong_count() > 0);
        paths.iter().filter_map(Weak::upgrade).collect()
    }
}

/// The real clock's job thread: every millisecond, the path's edges up to
/// [`PATH_HORIZON_MS`] ahead.
fn spawn_real(path: Weak<PathShared>) -> Result<JoinHandle<()>, PathError> {
    std::thread::Builder::new()
        .name("cogstep-path".into())
        .spawn(move || loop {
            let Some(path) = path.upgrade() else {
                return;
            };
            if lock(&path.inner).ended {
                return;
            }
            let now = path.hub.now();
            let ahead = u64::from(path.clkfreq) / 1_000 * PATH_HORIZON_MS;
            path.service(now, now + ahead);
            drop(path);
            std::thread::sleep(Duration::from_millis(1));
        })
        .map_err(|_| PathError::Axis(AxisError::Fault("the path's thread could not start")))
}

impl PathJob {
    /// The number of axes.
    pub fn axes(&self) -> usize {
        self.control.shared.axes.len()
    }

    /// Queues a line: `steps` per axis of the path (signed), the lead (the
    /// axis with the most steps) at up to `feed_steps_per_s`
    /// (`f64::INFINITY`: a rapid, at the axes' limits), tagged `tag` (for
    /// progress). Blocks while the queue is full: with the virtual clock it
    /// advances the clock until a line is done. Refused, with nothing
    /// queued: a wrong number of steps, no motion, a feed not above 0, an
    /// end beyond an axis's soft limits, or a path that stopped.
    /// A push still waiting for room when the path is cancelled is refused
    /// ([`PathError::Cancelled`]): the cancel drops what was queued before
    /// it, and the line that waited is not run after it. With the virtual
    /// clock, a push that waits while the path comes to rest in a hold is
    /// refused ([`PathError::HeldFull`]): nothing else would move it on.
    pub fn push(&self, steps: &[i32], feed_steps_per_s: f64, tag: u32) -> Result<(), PathError> {
        let cancels = self.cancels();
        self.push_unless_cancelled(steps, feed_steps_per_s, tag, cancels)
    }

    /// [`PathJob::push`], refused with [`PathError::Cancelled`] (nothing
    /// queued) once the path has been cancelled more than `cancels` times
    /// ([`PathJob::cancels`]): a producer that queues several lines as one
    /// (the chords of an arc) reads the count once, so that a cancel
    /// between two of them drops the first and refuses the rest.
    pub fn push_unless_cancelled(
        &self,
        steps: &[i32],
        feed_steps_per_s: f64,
        tag: u32,
        cancels: u64,
    ) -> Result<(), PathError> {
        loop {
            match self.try_push_since(steps, feed_steps_per_s, tag, Some(cancels)) {
                Err(PathError::Full) if self.held_for_good() => return Err(PathError::HeldFull),
                Err(PathError::Full) => self.wait_for_change(),
                other => return other,
            }
        }
    }

    /// Virtual clock, held at rest: only a resume moves the path on, and
    /// nobody advances the clock but this job's owner. (With the real clock
    /// another thread may resume: a push waits for it.)
    fn held_for_good(&self) -> bool {
        matches!(self.control.hub.inner.config.clock, ClockMode::Virtual)
            && lock(&self.control.shared.inner).runner.is_held()
    }

    /// How many times the path has been cancelled so far.
    pub fn cancels(&self) -> u64 {
        lock(&self.control.shared.inner).cancels
    }

    /// [`PathJob::push`] without waiting: [`PathError::Full`] when the
    /// queue is full.
    pub fn try_push(
        &self,
        steps: &[i32],
        feed_steps_per_s: f64,
        tag: u32,
    ) -> Result<(), PathError> {
        self.try_push_since(steps, feed_steps_per_s, tag, None)
    }

    fn try_push_since(
        &self,
        steps: &[i32],
        feed_steps_per_s: f64,
        tag: u32,
        cancels: Option<u64>,
    ) -> Result<(), PathError> {
        let mut inner = lock(&self.control.shared.inner);
        if let Some(fault) = inner.fault {
            return Err(PathError::Stopped(fault));
        }
        if cancels.is_some_and(|cancels| cancels != inner.cancels) {
            return Err(PathError::Cancelled);
        }
        let count = self.control.shared.axes.len();
        if steps.len() != count {
            return Err(PathError::AxisCount(count));
        }
        let mut line = Line {
            steps: [0; MAX_AXES],
            feed_steps_per_s,
        };
        line.steps[..steps.len()].copy_from_slice(steps);
        let targets = inner.runner.targets();
        for (axis, cog) in self.control.shared.axes.iter().enumerate() {
            let Some((min, max)) = lock(&cog.extras).soft_limits else {
                continue;
            };
            let end = targets[axis]
                .checked_add(i64::from(steps[axis]))
                .ok_or(PathError::PositionOutOfRange)?;
            if steps[axis] != 0 && (end < min || end > max) {
                return Err(PathError::BeyondSoftLimit { axis });
            }
        }
        if inner.runner.is_full() {
            return Err(PathError::Full);
        }
        // A path that ran dry starts again from rest, not in the past.
        let earliest = self.control.earliest_start(inner.filled);
        inner.runner.push_no_earlier_than(line, tag, earliest)?;
        inner.pushed += 1;
        Ok(())
    }

    /// A pause of `seconds` at rest after the lines queued (G4).
    pub fn dwell(&self, seconds: f64) -> Result<(), PathError> {
        lock(&self.control.shared.inner)
            .runner
            .push_dwell(seconds)?;
        Ok(())
    }

    /// Exact stop (G61) or blending (G64) for the lines pushed from now on.
    pub fn set_blending(&self, blending: Blending) {
        lock(&self.control.shared.inner)
            .runner
            .set_blending(blending);
    }

    /// A handle for another thread: hold, resume, cancel, overrides,
    /// emergency stop and progress while this job's owner waits in
    /// [`PathJob::push`].
    pub fn control(&self) -> PathControl {
        self.control.clone()
    }

    /// See [`PathControl::set_overrides`].
    pub fn set_overrides(&self, feed_percent: u32, rapid_percent: u32) -> Result<(), PathError> {
        self.control.set_overrides(feed_percent, rapid_percent)
    }

    /// See [`PathControl::hold`].
    pub fn hold(&self) {
        self.control.hold();
    }

    /// See [`PathControl::resume`].
    pub fn resume(&self) -> Result<(), PathError> {
        self.control.resume()
    }

    /// See [`PathControl::cancel`].
    pub fn cancel(&self) {
        self.control.cancel();
    }

    /// See [`PathControl::emergency_stop`].
    pub fn emergency_stop(&self) {
        self.control.emergency_stop();
    }

    /// See [`PathControl::progress`].
    pub fn progress(&self) -> PathProgress {
        self.control.progress()
    }

    /// See [`PathControl::targets`].
    pub fn targets(&self) -> Vec<i64> {
        self.control.targets()
    }

    /// Waits until everything queued has been made (or the path stopped):
    /// with the virtual clock it advances the clock. Returns the progress
    /// then, or the fault that stopped the path.
    pub fn wait(&self) -> Result<PathProgress, PathError> {
        loop {
            {
                let inner = lock(&self.control.shared.inner);
                if let Some(fault) = inner.fault {
                    return Err(PathError::Stopped(fault));
                }
                if self.control.shared.is_done(&inner) || inner.runner.is_held() {
                    drop(inner);
                    return Ok(self.progress());
                }
            }
            self.wait_for_change();
        }
    }

    /// Waits for the path to move on: the virtual clock advances a slice;
    /// with the real clock, the job's thread says so (or a millisecond).
    fn wait_for_change(&self) {
        match self.control.hub.inner.config.clock {
            ClockMode::Virtual => {
                let slice = u64::from(self.control.shared.clkfreq) / 1_000 * PATH_SLICE_MS;
                self.control.hub.advance(slice);
            }
            ClockMode::Real => {
                let inner = lock(&self.control.shared.inner);
                let _ = self
                    .control
                    .shared
                    .changed
                    .wait_timeout(inner, Duration::from_millis(2));
            }
        }
    }

    /// Runs everything queued to its end ([`PathJob::wait`]) and lets the
    /// axes go: they take other commands again.
    pub fn finish(mut self) -> Result<PathProgress, PathError> {
        let outcome = self.wait();
        self.release();
        outcome
    }

    fn release(&mut self) {
        {
            let mut inner = lock(&self.control.shared.inner);
            if inner.ended {
                return;
            }
            inner.ended = true;
        }
        for cog in &self.control.shared.axes {
            let _ = cog.call(Command {
                kind: CommandKind::PathEnd,
                speed: 0,
                steps: 0,
            });
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl PathControl {
    /// How far after the clock a start from rest may begin: the direction
    /// set-up, and with the real clock 2 ms more for the job's thread to
    /// compute the first edges ahead of the clock.
    fn lead_ticks(&self) -> u64 {
        let config = &self.hub.inner.config;
        let setup = u64::from(config.dir_setup_ticks);
        match config.clock {
            ClockMode::Virtual => setup,
            ClockMode::Real => setup + u64::from(self.shared.clkfreq) / 500,
        }
    }

    /// Where a resume's timeline begins: after every edge computed
    /// (`filled`) and the clock, plus the lead.
    fn start_ct(&self, filled: u64) -> u64 {
        filled.max(self.hub.now()) + self.lead_ticks()
    }

    /// The earliest CT a line pushed to a path that ran dry may start:
    /// not before the edges computed, nor the clock plus the lead (a fresh
    /// path's origin is both).
    fn earliest_start(&self, filled: u64) -> u64 {
        filled.max(self.hub.now() + self.lead_ticks())
    }

    /// The feed override (10 % to 200 %) and the rapid override (1 % to
    /// 100 %): they take effect at the next junction not yet planned for
    /// good, without a jump in speed or acceleration; the end positions do
    /// not change.
    pub fn set_overrides(&self, feed_percent: u32, rapid_percent: u32) -> Result<(), PathError> {
        if !(10..=200).contains(&feed_percent) || !(1..=100).contains(&rapid_percent) {
            return Err(PathError::Override);
        }
        let mut inner = lock(&self.shared.inner);
        inner.runner.set_overrides(
            f64::from(feed_percent) / 100.0,
            f64::from(rapid_percent) / 100.0,
        )?;
        inner.overrides = (feed_percent, rapid_percent);
        Ok(())
    }

    /// Brings the path to rest along the path (a feed hold); no step is
    /// lost, [`PathControl::resume`] goes on. An idle path is held too: the
    /// lines pushed then wait for the resume.
    pub fn hold(&self) {
        let mut inner = lock(&self.shared.inner);
        if inner.ended || inner.fault.is_some() {
            return;
        }
        inner.hold_asked = true;
        let at = inner.filled;
        inner.runner.hold_even_idle(at);
    }

    /// Goes on after a hold once the path is at rest and every stop pin of
    /// its axes is high; refused otherwise ([`PathError::NotHeld`]).
    pub fn resume(&self) -> Result<(), PathError> {
        let mut inner = lock(&self.shared.inner);
        if let Some(fault) = inner.fault {
            return Err(PathError::Stopped(fault));
        }
        let pins_high = self
            .shared
            .axes
            .iter()
            .all(|axis| self.shared.hub.pins.input(axis.stop_pin));
        if !pins_high || !inner.runner.is_held() {
            return Err(PathError::NotHeld);
        }
        let at = self.start_ct(inner.filled);
        inner.hold_asked = false;
        inner.runner.resume(at)?;
        Ok(())
    }

    /// Brings the path to rest along the path and drops every line queued;
    /// a push waiting for room is refused ([`PathError::Cancelled`]).
    pub fn cancel(&self) {
        let mut inner = lock(&self.shared.inner);
        inner.hold_asked = false;
        inner.cancels += 1;
        let at = inner.filled;
        inner.runner.cancel(at);
    }

    /// Stops every axis of the path at once; the path takes nothing more.
    pub fn emergency_stop(&self) {
        let mut inner = lock(&self.shared.inner);
        if inner.fault.is_none() {
            self.shared.stop_all(&mut inner, PathFault::EmergencyStop);
        }
        drop(inner);
        for cog in &self.shared.axes {
            let _ = wait_for_estop(cog);
        }
    }

    /// Where every axis stands once everything queued is made, steps (in
    /// the path's order of axes): the next line starts there.
    pub fn targets(&self) -> Vec<i64> {
        let inner = lock(&self.shared.inner);
        let targets = inner.runner.targets();
        targets[..self.shared.axes.len()].to_vec()
    }

    /// Where the path stands.
    pub fn progress(&self) -> PathProgress {
        let now = self.hub.now();
        let inner = lock(&self.shared.inner);
        let current = inner
            .spans
            .iter()
            .take_while(|span| span.first <= now)
            .last()
            .copied();
        let done_in_spans = inner
            .spans
            .iter()
            .filter(|span| span.last < now && inner.spans.back().is_some_and(|b| b.first <= now))
            .count() as u64;
        let done = (inner.spans_done + done_in_spans).min(inner.pushed);
        // With the real clock the stop's last edges are computed ahead of
        // the clock: held once the axes have made them.
        let state = match inner.runner.state() {
            PathState::Held if !self.shared.axes_at_rest() => PathState::Holding,
            // Everything computed is not everything made: idle once the
            // axes have made the last steps too.
            PathState::Idle if inner.fault.is_none() && !self.shared.axes_at_rest() => {
                PathState::Running
            }
            state => state,
        };
        PathProgress {
            state,
            tag: current.map_or(0, |span| span.tag),
            done,
            // A cancel's dropped lines are neither done nor queued.
            queued: inner
                .pushed
                .saturating_sub(done + inner.runner.lines_dropped()) as usize,
            speed_steps_per_s: inner.runner.path_speed_at(now),
            overrides: inner.overrides,
            fault: inner.fault,
        }
    }
}

impl Drop for PathJob {
    fn drop(&mut self) {
        let moving = {
            let inner = lock(&self.control.shared.inner);
            !inner.ended && !self.control.shared.is_done(&inner)
        };
        if moving {
            self.emergency_stop();
        }
        self.release();
    }
}

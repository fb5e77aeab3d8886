//! The grbl board's motion on the emulated hub: the hub's look-ahead path
//! ([`PathJob`]), as grbl's own planner.
//!
//! The three axes (X, Y, Z) stand on one path whose machine comes from the
//! settings: each axis's top speed (`$110`…, at most
//! [`MAX_STEP_RATE_HZ`]) and acceleration (`$120`…) in steps, and the
//! junction deviation (`$11`) in steps of the finest axis. Every line is
//! pushed as it comes, so the planner blends through the junctions of the
//! lines queued and plans to rest at the last one, as grbl does; a feed
//! hold decelerates along the path and resume finishes it exactly; a
//! feed or rapid override takes effect at the next junction not yet
//! frozen; a jog cancel stops along the path and drops the jog. The
//! positions are the axes' own step counts.
//!
//! The path is set aside (and made again from the settings) for what it
//! cannot do: homing (each axis's own homing), a settings change, a soft
//! reset (an emergency stop of every axis) and a hard limit (the path
//! stops every axis at once). A dwell (`G4`) waits here, after the path
//! has come to rest: the session takes no line behind it before it ends.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use cogstep_hub::switch::DemoSwitches;
use cogstep_hub::{
    Axis, ClockMode, Hub, HubConfig, PathError, PathFault, PathJob, PathMachine, PathProgress,
    PATH_QUEUE_LINES,
};
use cogstep_motion::axis::{AxisError, Direction, HomeConfig, Mode};
use cogstep_motion::planner::{Blending, PathState};
use cogstep_protocol::grbl::{
    GrblMotion, HomeRequest, MotionBlock, MotionFault, MotionRefusal, MotionState, MotionStatus,
    Overrides, Settings, GRBL_AXES,
};

use crate::SimError;

/// The planner's size in blocks: the path's queue (grbl's is 16 on an
/// Uno; `[OPT:` reports one less).
pub const PLANNER_BLOCKS: usize = PATH_QUEUE_LINES;
/// The fastest step rate a grbl setting may ask for, steps/s.
pub const MAX_STEP_RATE_HZ: u32 = 100_000;
/// The slowest homing speed, steps/s.
const MIN_LEAD_SPEED: u32 = 10;

/// A line on the path, for status reports.
#[derive(Clone, Copy, Debug)]
struct Queued {
    /// The path's tag for it (a count of the lines pushed, from 1).
    tag: u32,
    /// The G-code line it came from.
    line: u32,
    jog: bool,
    /// mm along the path per step of step space (to report the feed).
    mm_per_step: f64,
}

/// A dwell: waiting for the path to come to rest, then for its time.
#[derive(Clone, Copy, Debug)]
enum Dwell {
    AfterPath { line: u32, ms: u32 },
    Until { line: u32, until: Instant },
}

/// Three hub axes (X, Y, Z) on a look-ahead path behind the grbl engine.
pub struct HubMotion {
    hub: Hub,
    axes: Vec<Axis>,
    /// The path; `None` while homing, and until the next line after a
    /// settings change, a reset or a hard limit.
    job: Option<PathJob>,
    /// The lines on the path not yet done, oldest first.
    queued: VecDeque<Queued>,
    /// Tags given so far.
    tags: u32,
    dwell: Option<Dwell>,
    /// A jog cancel: stopping along the path, then the jog is gone.
    cancelling: bool,
    homing: bool,
    fault: Option<MotionFault>,
    overrides: Overrides,
    settings: Settings,
}

impl std::fmt::Debug for HubMotion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HubMotion")
            .field("on_path", &self.job.is_some())
            .field("queued", &self.queued.len())
            .field("dwell", &self.dwell)
            .field("cancelling", &self.cancelling)
            .field("homing", &self.homing)
            .finish()
    }
}

impl HubMotion {
    /// A real-time hub at `clkfreq` with three axes, pins as board-sim's
    /// (axis `i`: stop pin `3i`, step/dir or cw/ccw on `3i + 1`, `3i + 2`),
    /// the demo home and limit switches fitted (limits armed by `$21`).
    pub fn new(clkfreq: u32, settings: &Settings) -> Result<Self, SimError> {
        let hub = Hub::new(HubConfig {
            clkfreq,
            clock: ClockMode::Real,
            accel_div: accel_div(settings),
            ..HubConfig::default()
        })?;
        let mut axes = Vec::with_capacity(GRBL_AXES);
        for index in 0..GRBL_AXES {
            let base = (index * 3) as u8;
            let axis = if index % 2 == 0 {
                hub.start_sd(base, base + 1, base + 2)?
            } else {
                hub.start_cc(base, base + 1, base + 2)?
            };
            axis.set_stop_pin(true)
                .map_err(|error| SimError::Config(format!("axis {index}: {error}")))?;
            hub.fit_demo_switches(&axis, index)?;
            axis.set_limit_pins(None, None)
                .map_err(|error| SimError::Config(format!("axis {index}: {error}")))?;
            axes.push(axis);
        }
        let mut motion = HubMotion {
            hub,
            axes,
            job: None,
            queued: VecDeque::with_capacity(PLANNER_BLOCKS),
            tags: 0,
            dwell: None,
            cancelling: false,
            homing: false,
            fault: None,
            overrides: Overrides::default(),
            settings: *settings,
        };
        // The machine must be one the planner takes: refused here, at start.
        motion
            .ensure_path()
            .map_err(|error| SimError::Config(format!("the settings make no path: {error}")))?;
        Ok(motion)
    }

    /// The axes, X, Y, Z.
    pub fn axes(&self) -> &[Axis] {
        &self.axes
    }

    fn positions(&self) -> [i64; GRBL_AXES] {
        let mut steps = [0; GRBL_AXES];
        for (axis, position) in self.axes.iter().zip(steps.iter_mut()) {
            *position = axis.position();
        }
        steps
    }

    /// Off the path: every axis idle.
    fn axes_at_rest(&self) -> bool {
        self.axes.iter().all(|axis| {
            let mode = axis.mode();
            axis.stm() == 0
                && axis.steps_to_go() == 0
                && !mode.has(Mode::MOVING)
                && !mode.has(Mode::HOLD)
                && !axis.is_homing()
        })
    }

    /// The path's machine from the settings.
    fn machine(&self) -> PathMachine {
        let settings = &self.settings;
        let finest = settings
            .steps_per_mm
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        PathMachine {
            max_speed_steps_per_s: (0..GRBL_AXES)
                .map(|axis| {
                    (settings.max_rate_mm_min[axis] / 60.0 * settings.steps_per_mm[axis])
                        .min(f64::from(MAX_STEP_RATE_HZ))
                })
                .collect(),
            max_accel_steps_per_s2: (0..GRBL_AXES)
                .map(|axis| settings.accel_mm_s2[axis] * settings.steps_per_mm[axis])
                .collect(),
            junction_deviation_steps: settings.junction_deviation_mm * finest,
            blending: Blending::Blend,
        }
    }

    /// Puts the axes on a path if they are not on one.
    fn ensure_path(&mut self) -> Result<&PathJob, PathError> {
        let job = match self.job.take() {
            Some(job) => job,
            None => {
                let refs: Vec<&Axis> = self.axes.iter().collect();
                let job = self.hub.path(&refs, self.machine())?;
                job.set_overrides(
                    u32::from(self.overrides.feed_pct),
                    u32::from(self.overrides.rapid_pct),
                )?;
                job
            }
        };
        Ok(self.job.insert(job))
    }

    /// Takes the axes off the path (nothing on it moves: the callers are
    /// idle, or stopped it).
    fn leave_path(&mut self) {
        if let Some(job) = self.job.take() {
            let _ = job.finish();
        }
        self.queued.clear();
    }

    fn progress(&self) -> Option<PathProgress> {
        self.job.as_ref().map(PathJob::progress)
    }

    /// Moves time on: faults, the end of a jog cancel, of a dwell, of
    /// homing. The board calls it from its loop (every millisecond while
    /// busy); the path itself runs on its own thread.
    pub fn advance(&mut self) {
        if self.homing {
            self.advance_homing();
            return;
        }
        let Some(progress) = self.progress() else {
            return;
        };
        if let Some(fault) = progress.fault {
            // Every axis of the path is stopped already.
            self.job = None;
            self.queued.clear();
            self.dwell = None;
            self.cancelling = false;
            for axis in &self.axes {
                let _ = axis.clear_limit_fault();
            }
            if matches!(fault, PathFault::Limit { .. } | PathFault::Refused { .. }) {
                self.fault = Some(MotionFault::HardLimit);
            }
            return;
        }
        // Lines done are forgotten (the tag runs now, or none runs).
        let done_before = if progress.state == PathState::Idle {
            u32::MAX
        } else {
            progress.tag
        };
        while self.queued.front().is_some_and(|q| q.tag < done_before) {
            self.queued.pop_front();
        }
        if self.cancelling && progress.state == PathState::Idle {
            self.cancelling = false;
        }
        match self.dwell {
            Some(Dwell::AfterPath { line, ms }) if progress.state == PathState::Idle => {
                let until = Instant::now() + Duration::from_millis(u64::from(ms));
                self.dwell = Some(Dwell::Until { line, until });
            }
            Some(Dwell::Until { until, .. }) if Instant::now() >= until => self.dwell = None,
            _ => {}
        }
    }

    fn advance_homing(&mut self) {
        let outcomes: Vec<_> = self.axes.iter().map(Axis::home_outcome).collect();
        if outcomes.iter().any(Option::is_none) {
            return;
        }
        self.homing = false;
        for outcome in outcomes.into_iter().flatten() {
            match outcome {
                Ok(_) => {}
                Err(AxisError::HomeSwitchNotFound) => {
                    self.fault = Some(MotionFault::HomingSwitchNotFound)
                }
                Err(_) => self.fault = Some(MotionFault::HomingFailed),
            }
        }
    }

    fn push_line(&mut self, block: &MotionBlock) -> Result<(), MotionRefusal> {
        let MotionBlock::Line {
            line,
            target_steps,
            feed_mm_s,
            rapid,
            jog,
            ..
        } = *block
        else {
            return Ok(());
        };
        let settings = self.settings;
        let tag = self.tags.wrapping_add(1).max(1);
        let job = self.ensure_path().map_err(|_| MotionRefusal::Invalid)?;
        let from = job.targets();
        let mut steps = [0i32; GRBL_AXES];
        let mut length_mm = 0.0;
        let mut length_steps = 0.0;
        for axis in 0..GRBL_AXES {
            let delta = target_steps[axis] - from[axis];
            steps[axis] = i32::try_from(delta).map_err(|_| MotionRefusal::Invalid)?;
            let mm = delta as f64 / settings.steps_per_mm[axis];
            length_mm += mm * mm;
            length_steps += (delta as f64) * (delta as f64);
        }
        if steps.iter().all(|&s| s == 0) {
            // Already there (a line shorter than half a step): done.
            return Ok(());
        }
        let (length_mm, length_steps) = (length_mm.sqrt(), length_steps.sqrt());
        let lead = steps.iter().map(|s| s.unsigned_abs()).max().unwrap_or(0);
        // The lead's feed for the path's feed; a rapid goes at the axes' limits.
        let feed_steps_per_s = if rapid {
            f64::INFINITY
        } else {
            feed_mm_s * f64::from(lead) / length_mm
        };
        match job.try_push(&steps, feed_steps_per_s, tag) {
            Ok(()) => {
                self.tags = tag;
                self.queued.push_back(Queued {
                    tag,
                    line,
                    jog,
                    mm_per_step: length_mm / length_steps,
                });
                Ok(())
            }
            Err(PathError::Full) => Err(MotionRefusal::Full),
            Err(_) => Err(MotionRefusal::Invalid),
        }
    }
}

/// The hub's `accel_div` for the settings (homing moves use the hub's own
/// S-curve): a ramp to `v` takes `v / div` steps, an average acceleration
/// of `v · div / 2`; at each axis's top rate that is its `$120` when
/// `div = 2 · a / v` (steps cancel out).
fn accel_div(settings: &Settings) -> u32 {
    let div = (0..GRBL_AXES)
        .map(|axis| 2.0 * settings.accel_mm_s2[axis] / (settings.max_rate_mm_min[axis] / 60.0))
        .fold(f64::INFINITY, f64::min);
    if div.is_finite() {
        div.clamp(10.0, 100_000.0) as u32
    } else {
        10
    }
}

impl GrblMotion for HubMotion {
    fn queue(&mut self, block: &MotionBlock) -> Result<(), MotionRefusal> {
        if self.homing || self.cancelling || self.dwell.is_some() {
            return Err(MotionRefusal::Full);
        }
        match *block {
            MotionBlock::Dwell { line, ms } => {
                self.dwell = Some(Dwell::AfterPath { line, ms });
                self.advance();
                Ok(())
            }
            MotionBlock::Line { .. } => self.push_line(block),
        }
    }

    fn free_blocks(&self) -> usize {
        if self.homing || self.cancelling || self.dwell.is_some() {
            return 0;
        }
        let queued = self.progress().map_or(0, |progress| progress.queued);
        PLANNER_BLOCKS.saturating_sub(queued)
    }

    fn capacity(&self) -> usize {
        PLANNER_BLOCKS
    }

    fn hold(&mut self) {
        if self.homing {
            return;
        }
        // From Idle too, as grbl: held at once, the lines sent then wait
        // for `~`.
        if let Ok(job) = self.ensure_path() {
            job.hold();
        }
    }

    fn resume(&mut self) {
        if let Some(job) = &self.job {
            let _ = job.resume();
        }
    }

    fn cancel_jog(&mut self) {
        if let Some(job) = &self.job {
            job.cancel();
            self.cancelling = true;
        }
    }

    fn reset(&mut self) {
        if let Some(job) = self.job.take() {
            job.emergency_stop();
        }
        for axis in &self.axes {
            let _ = axis.emergency_stop();
        }
        self.queued.clear();
        self.dwell = None;
        self.cancelling = false;
        self.homing = false;
    }

    fn status(&self) -> MotionStatus {
        let steps = self.positions();
        let progress = self.progress();
        let current = progress.and_then(|progress| {
            self.queued
                .iter()
                .find(|q| q.tag == progress.tag)
                .or(self.queued.front())
                .copied()
        });
        let jog = current.is_some_and(|q| q.jog);
        let path_state = progress.map_or(PathState::Idle, |progress| progress.state);
        let state = if self.homing {
            MotionState::Homing
        } else if self.cancelling {
            MotionState::Jog
        } else {
            match path_state {
                PathState::Holding => MotionState::Holding,
                PathState::Held => MotionState::Held,
                PathState::Running if jog => MotionState::Jog,
                PathState::Running => MotionState::Run,
                PathState::Idle if self.dwell.is_some() => MotionState::Run,
                PathState::Idle if self.job.is_none() && !self.axes_at_rest() => MotionState::Run,
                PathState::Idle => MotionState::Idle,
            }
        };
        let feed_mm_s = match (progress, current) {
            (Some(progress), Some(q)) if path_state != PathState::Idle => {
                progress.speed_steps_per_s * q.mm_per_step
            }
            _ => 0.0,
        };
        let line = match (self.dwell, current) {
            (Some(Dwell::AfterPath { line, .. } | Dwell::Until { line, .. }), None) => Some(line),
            (_, Some(q)) if path_state != PathState::Idle => Some(q.line),
            _ => None,
        };
        MotionStatus {
            steps,
            state,
            feed_mm_s,
            line,
        }
    }

    fn take_fault(&mut self) -> Option<MotionFault> {
        self.fault.take()
    }

    fn home(&mut self, request: &HomeRequest) -> Result<(), MotionRefusal> {
        let busy = self.progress().is_some_and(|p| p.state != PathState::Idle);
        if busy || self.dwell.is_some() || self.cancelling {
            return Err(MotionRefusal::Invalid);
        }
        // Each axis homes on its own, off the path.
        self.leave_path();
        if !self.axes_at_rest() {
            return Err(MotionRefusal::Invalid);
        }
        for (index, axis) in self.axes.iter().enumerate() {
            if request.axes_mask & (1 << index) == 0 {
                continue;
            }
            let switches = DemoSwitches::for_axis(index).ok_or(MotionRefusal::Invalid)?;
            let steps_per_mm = request.steps_per_mm[index];
            let rate =
                |mm_min: f64| ((mm_min / 60.0 * steps_per_mm).round() as u32).max(MIN_LEAD_SPEED);
            let travel = (1.5 * request.max_travel_mm[index] * steps_per_mm).round();
            // The demo switch is at the negative end: machine zero is the
            // far (positive) end, as grbl's machine space runs −travel…0.
            let config = HomeConfig {
                switch_pin: switches.home_pin,
                active_level: true,
                direction: Direction::Reverse,
                seek_speed: rate(request.seek_mm_min),
                latch_speed: rate(request.feed_mm_min),
                backoff_steps: (request.pull_off_mm * steps_per_mm).round() as u32,
                max_travel: travel.min(f64::from(u32::MAX)) as u32,
                set_position: -(request.max_travel_mm[index] * steps_per_mm).round() as i64,
            };
            axis.home(config).map_err(|_| MotionRefusal::Invalid)?;
        }
        self.homing = true;
        Ok(())
    }

    fn set_overrides(&mut self, overrides: Overrides) {
        self.overrides = overrides;
        if let Some(job) = &self.job {
            let _ = job.set_overrides(
                u32::from(overrides.feed_pct),
                u32::from(overrides.rapid_pct),
            );
        }
    }

    fn configure(&mut self, settings: &Settings) {
        self.settings = *settings;
        // The session changes settings only when idle: the path is made
        // again from them at the next line.
        self.leave_path();
        for (index, axis) in self.axes.iter().enumerate() {
            let pins = DemoSwitches::for_axis(index)
                .filter(|_| settings.hard_limits)
                .map(|switches| {
                    (
                        Some((switches.min_pin, true)),
                        Some((switches.max_pin, true)),
                    )
                });
            let (min, max) = pins.unwrap_or((None, None));
            let _ = axis.set_limit_pins(min, max);
        }
    }

    fn max_step_rate_hz(&self) -> u32 {
        MAX_STEP_RATE_HZ
    }
}

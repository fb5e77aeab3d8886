//! grbl 1.1 on the firmware: [`PathMotion`], the [`GrblMotion`] that the
//! protocol crate's [`GrblSession`](driver::serial::grbl::GrblSession)
//! drives, over the motion crate's look-ahead [`PathRunner`].
//!
//! ```text
//! G-code line ─► GrblSession ─► PathMotion::queue ─► PathRunner (plan, timeline)
//! main loop ─► PathMotion::advance ─► the runner's edges, a few ms ahead of the clock
//!           ─► each axis's path queue (AxisCore, 32 steps) ─► step interrupt ─► pins
//! ```
//!
//! The three axes X, Y, Z are firmware axes 0, 1, 2, kept on a path
//! (`CoreCommand::PathStart`) for as long as the board speaks grbl. The
//! runner decides when every axis steps; the main loop takes its edges
//! up to [`HORIZON_MS`] ahead of the clock and pushes each onto its axis's
//! path queue, whose core makes it on its CT in the step interrupt, as it
//! makes any other step (direction set-up, pulse, edges queued until their
//! CT). An edge whose axis queue is full waits here, taken from the
//! runner but not yet pushed, until the axis has room: no edge is lost.
//!
//! Positions are the axes' own step counts (what they stepped), so a
//! report's `MPos` is exactly steps / steps-per-mm. A feed hold comes to
//! rest along the path and a resume plans the rest from rest, so the
//! program ends exactly where it would have; a jog cancel stops along the
//! path and drops the jog; a soft reset stops every axis at once (the
//! steps queued and not made are dropped from each axis's ledger) and
//! starts a fresh runner at the positions reached.
//!
//! What this dialect cannot do: it reads no input pins (protocol v1 on
//! the Pico does, see [`crate::inputs`]; grbl's path does not yet), so
//! homing (`$H`) is refused (grbl's `ALARM:9`, no switch found, without moving) and
//! hard limits (`$21`) have no switch to trip. The settings live in RAM
//! (the session's): they are grbl's defaults again after a power cycle.

use driver::axis::{AxisContract, AxisError};
use driver::planner::{
    Blending, Line, Machine, PathEdge, PathRunner, PathState, PushError, RunError,
};
use driver::serial::grbl::{
    GrblMotion, HomeRequest, MotionBlock, MotionFault, MotionRefusal, MotionState, MotionStatus,
    Overrides, Settings, GRBL_AXES,
};
use driver::serial::Board;
use heapless::Deque;

use crate::scheduler::{Firmware, Hardware};

/// The planner's size in lines (`[OPT:,31,128]` reports one less), as the
/// board simulator's.
pub const PLANNER_BLOCKS: usize = 32;

/// The fastest step rate a grbl setting may ask of an axis, steps/s
/// (`$100` × `$110` / 60 above it is `error:12`). A bound chosen, not
/// measured on a chip: a path step takes up to three step interrupts, and
/// its edge is computed in soft `f64` in the main loop. Steps that come
/// late are still made, and counted. (The Pico's PIO build under rp2040py
/// keeps up at 2,500 steps/s in a fast ramp, not at 5,000:
/// docs/performance.md.)
pub const MAX_STEP_RATE_HZ: u32 = 20_000;

/// The most blocks the grbl session queues in one turn of the main loop:
/// each is a plan in software `f64` on a small core (about 60,000 cycles a
/// chord of an arc on the Pico's M0+, the look-ahead's passes). A long
/// arc's chords all at once paused every axis for 25 ms at its start
/// (`G2 X11 Y0 I5 J0` at F150 on the Pico's PIO build). 2 a turn: 19
/// gaps of at most 0.58 ms over the arc, 3.7 ms in all (4 a turn: gaps of
/// up to 2.6 ms; 1 a turn: up to 0.93 ms). docs/performance.md.
pub const BLOCKS_PER_TURN: usize = 2;

/// How far ahead of the clock the main loop computes the path's edges,
/// ms: the longest a feed hold waits before its ramp to rest may start.
pub const HORIZON_MS: u64 = 5;

/// How far after the clock a path that starts from rest (the first line,
/// a resume) begins, ms: time for the main loop to push its first edges.
pub const START_LEAD_MS: u64 = 2;

/// The runner of the grbl board's three axes.
pub type GrblRunner = PathRunner<PLANNER_BLOCKS, GRBL_AXES>;

/// A line on the path, for status reports.
#[derive(Clone, Copy, Debug)]
struct Queued {
    /// The runner's tag for it (a count of the lines pushed, from 1).
    tag: u32,
    /// The G-code line it came from.
    line: u32,
    jog: bool,
    /// mm along the path per step of step space (to report the feed).
    mm_per_step: f64,
}

/// A dwell (`G4`): waiting for the path to come to rest, then its time.
#[derive(Clone, Copy, Debug)]
enum Dwell {
    AfterPath { line: u32, ms: u32 },
    Until { line: u32, ct: u64 },
}

/// The grbl board's motion: the firmware's axes 0 to 2 on a look-ahead
/// path (see the module docs).
pub struct PathMotion<'a, H> {
    firmware: &'a Firmware<H>,
    /// The runner, in storage the board gives (about 10 KB: a static,
    /// never moved, so that no copy of it lands on a small stack); `None`
    /// while the settings make no machine the planner takes (every line is
    /// then refused).
    runner: &'a mut Option<GrblRunner>,
    /// An edge taken from the runner whose axis had no room yet.
    waiting_edge: Option<PathEdge>,
    /// Every edge up to this CT has been taken from the runner.
    filled_ct: u64,
    /// The lines on the path not yet done, oldest first.
    queued: Deque<Queued, PLANNER_BLOCKS>,
    /// Tags given so far.
    tags: u32,
    /// The tag of the last edge pushed to an axis.
    current_tag: u32,
    dwell: Option<Dwell>,
    /// A jog cancel: stopping along the path, then the jog is gone.
    cancelling: bool,
    fault: Option<MotionFault>,
    overrides: Overrides,
    settings: Settings,
}

impl<H> core::fmt::Debug for PathMotion<'_, H> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("PathMotion")
            .field("state", &self.runner.as_ref().map(GrblRunner::state))
            .field("waiting_edge", &self.waiting_edge)
            .field("queued", &self.queued.len())
            .field("dwell", &self.dwell)
            .field("cancelling", &self.cancelling)
            .finish()
    }
}

impl<'a, H: Hardware> PathMotion<'a, H> {
    /// The motion of a grbl board over `firmware`'s first three axes
    /// (it must have [`GRBL_AXES`]), with `settings`; its runner lives in
    /// `runner` (whatever is there is replaced).
    pub fn new(
        firmware: &'a Firmware<H>,
        runner: &'a mut Option<GrblRunner>,
        settings: &Settings,
    ) -> Self {
        let mut motion = PathMotion {
            firmware,
            runner,
            waiting_edge: None,
            filled_ct: firmware.now_ticks(),
            queued: Deque::new(),
            tags: 0,
            current_tag: 0,
            dwell: None,
            cancelling: false,
            fault: None,
            overrides: Overrides::default(),
            settings: *settings,
        };
        motion.fresh_runner();
        motion
    }

    /// The runner, if the settings make a machine.
    pub fn runner(&self) -> Option<&GrblRunner> {
        self.runner.as_ref()
    }

    fn ticks_per_ms(&self) -> u64 {
        u64::from(self.firmware.clkfreq_hz()) / 1_000
    }

    /// Where a start from rest may begin: after every edge taken and
    /// [`START_LEAD_MS`] after the clock.
    fn start_ct(&self) -> u64 {
        let now = self.firmware.now_ticks();
        self.filled_ct
            .max(now.saturating_add(START_LEAD_MS * self.ticks_per_ms()))
    }

    /// The axes' positions, steps (what they stepped).
    fn positions(&self) -> [i64; GRBL_AXES] {
        let mut steps = [0; GRBL_AXES];
        for (axis, position) in self.firmware.axes().iter().zip(steps.iter_mut()) {
            if let Ok(status) = axis.status() {
                *position = status.position;
            }
        }
        steps
    }

    /// Every step pushed to the axes made, none waiting here.
    fn axes_at_rest(&self) -> bool {
        self.waiting_edge.is_none()
            && self.firmware.axes().iter().take(GRBL_AXES).all(|axis| {
                axis.status().is_ok_and(|status| {
                    status.steps_to_go == 0 && !status.mode.has(driver::Mode::MOVING)
                })
            })
    }

    /// The planner's machine from the settings, in steps.
    fn machine(&self) -> Machine<GRBL_AXES> {
        let settings = &self.settings;
        let finest = settings
            .steps_per_mm
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        Machine {
            max_speed_steps_per_s: core::array::from_fn(|axis| {
                (settings.max_rate_mm_min[axis] / 60.0 * settings.steps_per_mm[axis])
                    .min(f64::from(MAX_STEP_RATE_HZ))
            }),
            max_accel_steps_per_s2: core::array::from_fn(|axis| {
                settings.accel_mm_s2[axis] * settings.steps_per_mm[axis]
            }),
            junction_deviation_steps: settings.junction_deviation_mm * finest,
            blending: Blending::Blend,
        }
    }

    /// A runner at rest at the axes' positions, its timeline from now
    /// (after a reset or a settings change); the overrides carried over.
    // Not inlined: its temporaries (a runner is about 10 KB) stay in its
    // own frame, gone once it returns.
    #[inline(never)]
    fn fresh_runner(&mut self) {
        let now = self.firmware.now_ticks();
        *self.runner = None;
        // Too few axes: no runner, every line refused (an edge must have
        // an axis to go to).
        if self.firmware.axes().len() >= GRBL_AXES {
            let positions = self.positions();
            let hz = self.firmware.clkfreq_hz();
            if let Ok(runner) = GrblRunner::new(self.machine(), positions, now, hz) {
                let runner = self.runner.insert(runner);
                let (feed, rapid) = scales(self.overrides);
                if runner.set_overrides(feed, rapid).is_err() {
                    *self.runner = None;
                }
            }
        }
        self.waiting_edge = None;
        self.filled_ct = now;
        self.queued.clear();
        self.current_tag = 0;
    }

    /// The main loop's turn (call it often while anything moves): puts the
    /// axes on the path, pushes the runner's edges up to [`HORIZON_MS`]
    /// ahead of the clock onto them, and moves dwells and a jog cancel on.
    pub fn advance(&mut self) {
        let now = self.firmware.now_ticks();
        if self.ensure_axes_on_path() {
            self.fill(now.saturating_add(HORIZON_MS * self.ticks_per_ms()));
        }
        let Some(runner) = self.runner.as_ref() else {
            return;
        };
        let path_idle = runner.state() == PathState::Idle;
        let resting = path_idle && self.axes_at_rest();
        while self
            .queued
            .front()
            .is_some_and(|queued| resting || queued.tag < self.current_tag)
        {
            self.queued.pop_front();
        }
        if self.cancelling && resting {
            self.cancelling = false;
        }
        match self.dwell {
            Some(Dwell::AfterPath { line, ms }) if resting => {
                let ct = now.saturating_add(u64::from(ms) * self.ticks_per_ms());
                self.dwell = Some(Dwell::Until { line, ct });
            }
            Some(Dwell::Until { ct, .. }) if now >= ct => self.dwell = None,
            _ => {}
        }
    }

    /// Whether every axis is on the path (one that is not is put on it:
    /// after a reset, once its last pulse is over).
    fn ensure_axes_on_path(&self) -> bool {
        let mut all = true;
        for axis in self.firmware.axes().iter().take(GRBL_AXES) {
            if !axis.on_path() && axis.start_path().is_err() {
                all = false;
            }
        }
        all
    }

    /// Pushes the runner's edges due by `fill_to` onto the axes.
    fn fill(&mut self, fill_to: u64) {
        let Some(runner) = self.runner.as_mut() else {
            return;
        };
        let axes = self.firmware.axes();
        let mut pushed = false;
        let mut refused = None;
        while let Some(edge) = self
            .waiting_edge
            .take()
            .or_else(|| runner.next_edge_until(fill_to))
        {
            let Some(axis) = axes.get(usize::from(edge.axis)) else {
                continue;
            };
            match axis.push_path_step(edge.ct, edge.forward) {
                Ok(()) => {
                    pushed = true;
                    self.current_tag = edge.tag;
                }
                // The axis's queue is full (or it is not on the path yet):
                // the edge waits for room.
                Err(AxisError::Busy | AxisError::NotIdle) => {
                    self.waiting_edge = Some(edge);
                    break;
                }
                Err(error) => {
                    refused = Some(error);
                    break;
                }
            }
        }
        self.filled_ct = match self.waiting_edge {
            Some(edge) => self.filled_ct.max(edge.ct),
            None => self.filled_ct.max(fill_to),
        };
        if pushed {
            self.firmware.request_step_interrupt();
        }
        if refused.is_some() {
            // A limit refused a step (this board has no switch inputs and
            // sets no soft limits on the axes, so it does not happen):
            // stop everything, as a hard limit would.
            self.stop_at_once();
            self.fault = Some(MotionFault::HardLimit);
        }
    }

    /// Every axis stopped at once, the queue forgotten, a fresh runner at
    /// the positions reached.
    fn stop_at_once(&mut self) {
        for axis in self.firmware.axes().iter().take(GRBL_AXES) {
            let _ = axis.emergency_stop();
        }
        self.dwell = None;
        self.cancelling = false;
        self.fresh_runner();
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
        let start_ct = self.start_ct();
        let settings = self.settings;
        let runner = self.runner.as_mut().ok_or(MotionRefusal::Invalid)?;
        let from = runner.targets();
        let mut steps = [0i32; GRBL_AXES];
        let (mut length_mm, mut length_steps) = (0.0, 0.0);
        for axis in 0..GRBL_AXES {
            let delta = target_steps[axis]
                .checked_sub(from[axis])
                .ok_or(MotionRefusal::Invalid)?;
            steps[axis] = i32::try_from(delta).map_err(|_| MotionRefusal::Invalid)?;
            let mm = delta as f64 / settings.steps_per_mm[axis];
            length_mm += mm * mm;
            length_steps += (delta as f64) * (delta as f64);
        }
        if steps.iter().all(|&steps| steps == 0) {
            // Already there (a line shorter than half a step): done.
            return Ok(());
        }
        let (length_mm, length_steps) = (libm::sqrt(length_mm), libm::sqrt(length_steps));
        let lead = steps.iter().map(|s| s.unsigned_abs()).max().unwrap_or(0);
        // The lead's feed for the path's feed; a rapid goes at the axes' limits.
        let feed_steps_per_s = if rapid {
            f64::INFINITY
        } else {
            feed_mm_s * f64::from(lead) / length_mm
        };
        let tag = self.tags.wrapping_add(1).max(1);
        let line_steps = Line {
            steps,
            feed_steps_per_s,
        };
        match runner.push_no_earlier_than(line_steps, tag, start_ct) {
            Ok(()) => {
                self.tags = tag;
                if self.queued.is_full() {
                    self.queued.pop_front();
                }
                let _ = self.queued.push_back(Queued {
                    tag,
                    line,
                    jog,
                    mm_per_step: length_mm / length_steps,
                });
                Ok(())
            }
            Err(RunError::Push(PushError::Full)) => Err(MotionRefusal::Full),
            Err(_) => Err(MotionRefusal::Invalid),
        }
    }

    /// The motion's state, as [`GrblMotion::status`] reports it, without
    /// the rest of the report (its feed is the path's speed now: `f64`
    /// trigonometry, which a main loop asking only whether to sleep
    /// should not pay for on every turn).
    pub fn state(&self) -> MotionState {
        if self.cancelling {
            return MotionState::Jog;
        }
        let jog = self.current().is_some_and(|queued| queued.jog);
        let path_state = self
            .runner
            .as_ref()
            .map_or(PathState::Idle, GrblRunner::state);
        let at_rest = self.axes_at_rest();
        match path_state {
            PathState::Holding => MotionState::Holding,
            // The stop's last edges are computed ahead of the clock:
            // held once the axes have made them.
            PathState::Held if at_rest => MotionState::Held,
            PathState::Held => MotionState::Holding,
            PathState::Running | PathState::Idle if !at_rest && jog => MotionState::Jog,
            PathState::Running if jog => MotionState::Jog,
            PathState::Running => MotionState::Run,
            PathState::Idle if self.dwell.is_some() || !at_rest => MotionState::Run,
            PathState::Idle => MotionState::Idle,
        }
    }

    /// The line the axes run now (or the oldest not done).
    fn current(&self) -> Option<Queued> {
        self.queued
            .iter()
            .find(|queued| queued.tag == self.current_tag)
            .or(self.queued.front())
            .copied()
    }
}

/// The overrides as the runner's scales (1 = 100 %).
fn scales(overrides: Overrides) -> (f64, f64) {
    (
        f64::from(overrides.feed_pct) / 100.0,
        f64::from(overrides.rapid_pct) / 100.0,
    )
}

impl<H: Hardware> GrblMotion for PathMotion<'_, H> {
    fn queue(&mut self, block: &MotionBlock) -> Result<(), MotionRefusal> {
        if self.cancelling || self.dwell.is_some() {
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
        if self.cancelling || self.dwell.is_some() {
            return 0;
        }
        let queued = self.runner.as_ref().map_or(0, GrblRunner::queued);
        PLANNER_BLOCKS.saturating_sub(queued)
    }

    fn capacity(&self) -> usize {
        PLANNER_BLOCKS
    }

    fn hold(&mut self) {
        let at = self.filled_ct.max(self.firmware.now_ticks());
        if let Some(runner) = self.runner.as_mut() {
            // From Idle too, as grbl: held at once, the lines sent then
            // wait for `~`.
            runner.hold_even_idle(at);
        }
    }

    fn resume(&mut self) {
        let at = self.start_ct();
        if let Some(runner) = self.runner.as_mut() {
            // Refused unless held at rest (grbl too waits for the hold).
            let _ = runner.resume(at);
        }
    }

    fn cancel_jog(&mut self) {
        let at = self.filled_ct.max(self.firmware.now_ticks());
        if let Some(runner) = self.runner.as_mut() {
            if runner.state() != PathState::Idle {
                runner.cancel(at);
                self.cancelling = true;
            }
        }
    }

    fn reset(&mut self) {
        self.stop_at_once();
    }

    fn status(&self) -> MotionStatus {
        let steps = self.positions();
        let current = self.current();
        let state = self.state();
        let moving = !matches!(state, MotionState::Idle | MotionState::Held);
        let feed_mm_s = match (self.runner.as_ref(), current) {
            (Some(runner), Some(queued)) if moving => {
                runner.path_speed_at(self.firmware.now_ticks()) * queued.mm_per_step
            }
            _ => 0.0,
        };
        let line = match (self.dwell, current) {
            (Some(Dwell::AfterPath { line, .. } | Dwell::Until { line, .. }), None) => Some(line),
            (_, Some(queued)) if moving => Some(queued.line),
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

    /// No input pin is read on this board: there is no switch to home
    /// on, and `$H` is refused without moving (the session answers grbl's
    /// `ALARM:9`, no switch found).
    fn home(&mut self, _request: &HomeRequest) -> Result<(), MotionRefusal> {
        Err(MotionRefusal::Invalid)
    }

    fn set_overrides(&mut self, overrides: Overrides) {
        self.overrides = overrides;
        if let Some(runner) = self.runner.as_mut() {
            let (feed, rapid) = scales(overrides);
            let _ = runner.set_overrides(feed, rapid);
        }
    }

    fn configure(&mut self, settings: &Settings) {
        self.settings = *settings;
        // The session changes settings only at rest: a runner for them.
        self.fresh_runner();
    }

    fn max_step_rate_hz(&self) -> u32 {
        MAX_STEP_RATE_HZ
    }

    fn blocks_per_poll(&self) -> usize {
        BLOCKS_PER_TURN
    }
}

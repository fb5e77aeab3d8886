//! The grbl board's motion on the emulated hub.
//!
//! INTERIM: each line runs as one `Hub::move_together` from rest to rest
//! (an exact stop at every block end; no look-ahead, the hub's own S-curve
//! acceleration rather than `$120`…), until the hub's path job (issue 25:
//! the look-ahead planner with blended junctions, hold along the path and
//! overrides at the next planned point) lands on main; then that job
//! implements [`GrblMotion`] and this queue goes. The hub's S-curve
//! reaches a speed `v` in `v / accel_div` steps, so its acceleration grows
//! with the speed; the board sets `accel_div` when it starts so that each
//! axis reaches its `$110` rate with its `$120` acceleration on average
//! (at least the P2's 10), and a `$120` change applies from the next
//! start. What already holds:
//! a feed hold stops every axis on the line (the group's stop pin), resume
//! runs the rest of the same line, positions are the axes' own step
//! counts, and a block's end is its target in steps exactly.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use cogstep_hub::switch::DemoSwitches;
use cogstep_hub::{Axis, ClockMode, Hub, HubConfig};
use cogstep_motion::axis::{AxisError, Direction, HomeConfig, Mode};
use cogstep_protocol::grbl::{
    GrblMotion, HomeRequest, MotionBlock, MotionFault, MotionRefusal, MotionState, MotionStatus,
    Overrides, Settings, GRBL_AXES,
};

use crate::SimError;

/// The planner's size in blocks (grbl's is 16 on an Uno).
pub const PLANNER_BLOCKS: usize = 16;
/// The fastest step rate a grbl setting may ask for, steps/s.
const MAX_STEP_RATE_HZ: u32 = 100_000;
/// The slowest lead speed a move is given, steps/s.
const MIN_LEAD_SPEED: u32 = 10;

/// A line being run.
#[derive(Clone, Copy, Debug)]
struct Running {
    block: MotionBlock,
    /// A move for (part of) it is on the axes.
    issued: bool,
}

/// The feed hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Hold {
    None,
    /// Decelerating (the stop pin is low).
    Stopping,
    /// At rest on the path.
    Held,
}

/// Three hub axes (X, Y, Z) behind the grbl engine.
pub struct HubMotion {
    hub: Hub,
    axes: Vec<Axis>,
    queue: VecDeque<MotionBlock>,
    running: Option<Running>,
    dwell_until: Option<Instant>,
    hold: Hold,
    /// A jog cancel: stopping, then the jog blocks go.
    cancelling: bool,
    homing: bool,
    fault: Option<MotionFault>,
    overrides: Overrides,
    settings: Settings,
}

impl std::fmt::Debug for HubMotion {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HubMotion")
            .field("queue", &self.queue.len())
            .field("running", &self.running)
            .field("hold", &self.hold)
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
        Ok(HubMotion {
            hub,
            axes,
            queue: VecDeque::with_capacity(PLANNER_BLOCKS),
            running: None,
            dwell_until: None,
            hold: Hold::None,
            cancelling: false,
            homing: false,
            fault: None,
            overrides: Overrides::default(),
            settings: *settings,
        })
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

    fn set_stop_pins(&self, high: bool) {
        // The group's stop reaches every member from one pin; all three
        // are driven so that a single move of one axis stops too.
        for axis in &self.axes {
            let _ = axis.set_stop_pin(high);
        }
    }

    /// Moves time on: starts the next block when the last one is done,
    /// ends holds, homing and dwells. The board calls it from its loop
    /// (every millisecond while busy).
    pub fn advance(&mut self) {
        if self.homing {
            self.advance_homing();
            return;
        }
        if self.settings.hard_limits && self.axes.iter().any(|axis| axis.limit_fault().is_some()) {
            self.drop_everything();
            for axis in &self.axes {
                let _ = axis.clear_limit_fault();
            }
            self.fault = Some(MotionFault::HardLimit);
            return;
        }
        let at_rest = self.axes_at_rest();
        if self.hold == Hold::Stopping && at_rest {
            self.hold = Hold::Held;
        }
        if self.cancelling {
            if !at_rest {
                return;
            }
            self.queue.retain(|block| !is_jog(block));
            if self.running.is_some_and(|running| is_jog(&running.block)) {
                self.running = None;
            }
            self.cancelling = false;
            if self.hold == Hold::Held {
                self.hold = Hold::None;
            }
            self.set_stop_pins(true);
        }
        if self.hold != Hold::None {
            return;
        }
        if let Some(until) = self.dwell_until {
            if Instant::now() < until {
                return;
            }
            self.dwell_until = None;
        }
        loop {
            match self.running {
                Some(Running { issued: true, .. }) if !at_rest => return,
                Some(mut running) => {
                    if self.issue(&mut running) {
                        self.running = Some(running);
                        return;
                    }
                    self.running = None;
                }
                None => {}
            }
            let Some(block) = self.queue.pop_front() else {
                return;
            };
            match block {
                MotionBlock::Dwell { ms, .. } => {
                    self.dwell_until = Some(Instant::now() + Duration::from_millis(u64::from(ms)));
                    return;
                }
                MotionBlock::Line { .. } => {
                    self.running = Some(Running {
                        block,
                        issued: false,
                    });
                }
            }
        }
    }

    /// Starts (the rest of) a line from where the axes are; false when the
    /// line is done (the axes stand on its target).
    fn issue(&self, running: &mut Running) -> bool {
        let MotionBlock::Line {
            target_steps,
            feed_mm_s,
            rapid,
            ..
        } = running.block
        else {
            return false;
        };
        let position = self.positions();
        let mut deltas = [0i32; GRBL_AXES];
        let mut mm = [0.0f64; GRBL_AXES];
        for axis in 0..GRBL_AXES {
            let delta = target_steps[axis] - position[axis];
            deltas[axis] = delta.clamp(i64::from(-i32::MAX), i64::from(i32::MAX)) as i32;
            mm[axis] = f64::from(deltas[axis]) / self.settings.steps_per_mm[axis];
        }
        let lead = deltas.iter().map(|d| d.unsigned_abs()).max().unwrap_or(0);
        if lead == 0 {
            return false;
        }
        let length_mm = mm.iter().map(|m| m * m).sum::<f64>().sqrt();
        // The path speed: the feed (with its override), never more than
        // any axis's max rate allows on this line.
        let mut speed_mm_s = if rapid {
            f64::INFINITY
        } else {
            feed_mm_s * f64::from(self.overrides.feed_pct) / 100.0
        };
        let mut limit = f64::INFINITY;
        for (axis_mm, rate_mm_min) in mm.iter().zip(self.settings.max_rate_mm_min) {
            if *axis_mm != 0.0 {
                limit = limit.min(rate_mm_min / 60.0 * length_mm / axis_mm.abs());
            }
        }
        if rapid {
            speed_mm_s = limit * f64::from(self.overrides.rapid_pct) / 100.0;
        }
        speed_mm_s = speed_mm_s.min(limit);
        let lead_speed = (speed_mm_s * f64::from(lead) / length_mm).round();
        let lead_speed = (lead_speed.min(f64::from(MAX_STEP_RATE_HZ)) as u32).max(MIN_LEAD_SPEED);
        let group: Vec<(&Axis, i32)> = self.axes.iter().zip(deltas).collect();
        match self.hub.move_together(&group, lead_speed) {
            Ok(()) => {
                running.issued = true;
                true
            }
            // An axis still settles: try again on the next turn.
            Err(AxisError::Busy | AxisError::StopPinLow) => {
                running.issued = false;
                true
            }
            // Cannot run (a limit): the block is dropped, the axes stay.
            Err(_) => false,
        }
    }

    fn drop_everything(&mut self) {
        self.queue.clear();
        self.running = None;
        self.dwell_until = None;
        self.cancelling = false;
        self.hold = Hold::None;
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
}

/// The hub's `accel_div` for the settings: a ramp to `v` takes `v / div`
/// steps, an average acceleration of `v · div / 2`; at each axis's top rate
/// that is its `$120` when `div = 2 · a / v` (steps cancel out).
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

fn is_jog(block: &MotionBlock) -> bool {
    matches!(block, MotionBlock::Line { jog: true, .. })
}

impl GrblMotion for HubMotion {
    fn queue(&mut self, block: &MotionBlock) -> Result<(), MotionRefusal> {
        if self.queue.len() >= PLANNER_BLOCKS {
            return Err(MotionRefusal::Full);
        }
        self.queue.push_back(*block);
        if self.hold == Hold::None && !self.cancelling {
            self.advance();
        }
        Ok(())
    }

    fn free_blocks(&self) -> usize {
        PLANNER_BLOCKS - self.queue.len()
    }

    fn capacity(&self) -> usize {
        PLANNER_BLOCKS
    }

    fn hold(&mut self) {
        if self.hold == Hold::None {
            self.set_stop_pins(false);
            self.hold = Hold::Stopping;
        }
    }

    fn resume(&mut self) {
        if self.hold == Hold::Held {
            self.set_stop_pins(true);
            self.hold = Hold::None;
            if let Some(running) = &mut self.running {
                running.issued = false;
            }
            self.advance();
        }
    }

    fn cancel_jog(&mut self) {
        self.set_stop_pins(false);
        self.cancelling = true;
        if let Some(running) = &mut self.running {
            running.issued = false;
        }
    }

    fn reset(&mut self) {
        for axis in &self.axes {
            let _ = axis.emergency_stop();
        }
        self.drop_everything();
        self.homing = false;
        self.set_stop_pins(true);
    }

    fn status(&self) -> MotionStatus {
        let steps = self.positions();
        let state = if self.homing {
            MotionState::Homing
        } else if self.cancelling {
            MotionState::Jog
        } else {
            match self.hold {
                Hold::Stopping => MotionState::Holding,
                Hold::Held => MotionState::Held,
                Hold::None => {
                    let busy = self.running.is_some() || self.dwell_until.is_some();
                    match self
                        .running
                        .map(|running| running.block)
                        .or(self.queue.front().copied())
                    {
                        Some(block) if is_jog(&block) => MotionState::Jog,
                        Some(_) => MotionState::Run,
                        None if busy || !self.axes_at_rest() => MotionState::Run,
                        None => MotionState::Idle,
                    }
                }
            }
        };
        let mut feed_mm_s = 0.0;
        if let Some(Running {
            block: MotionBlock::Line { target_steps, .. },
            ..
        }) = self.running
        {
            // The lead's speed scaled to the path: v · |Δ| / lead steps.
            let mut lead = 0u64;
            let mut length = 0.0;
            let mut lead_velocity = 0u32;
            for axis in 0..GRBL_AXES {
                let delta = (target_steps[axis] - steps[axis]).unsigned_abs();
                let mm = delta as f64 / self.settings.steps_per_mm[axis];
                length += mm * mm;
                if delta > lead {
                    lead = delta;
                    lead_velocity = self.axes[axis].velocity();
                }
            }
            if lead > 0 {
                feed_mm_s = f64::from(lead_velocity) * length.sqrt() / lead as f64;
            }
        }
        let line = self.running.map(|running| match running.block {
            MotionBlock::Line { line, .. } | MotionBlock::Dwell { line, .. } => line,
        });
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
        if !self.axes_at_rest() || self.running.is_some() || !self.queue.is_empty() {
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
    }

    fn configure(&mut self, settings: &Settings) {
        self.settings = *settings;
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

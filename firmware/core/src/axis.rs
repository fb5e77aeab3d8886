//! One axis: everything it decides, time in and edges out.
//!
//! **Interim.** The driver crate is getting `AxisCore`, the `no_std` core
//! extracted from the host's cog (issue 13). Until it lands, this module is
//! the firmware's own axis core over [`Motion`], written to behave as the
//! cog does (`driver/src/cog.rs`): the same planning, merges, reversals,
//! held moves, stop pin, jog deadline, emergency stop, mode bits, STM and
//! dropped steps. Nothing else in the firmware knows what is inside
//! [`AxisLogic`]: swapping it for `AxisCore` changes this file only.
//!
//! Every input carries the CT it happens at; [`AxisLogic::advance`] makes
//! every event up to a CT and reports the pin edges through an
//! [`EdgeSink`]. A step at CT `t` raises the pulse pin at `t` and lowers it
//! `pulse_ticks` later; on a change of direction (`sd`) the direction pin
//! changes first and the rising edge waits `dir_setup_ticks` (the host's
//! virtual trace sets the direction that much *before* `t` instead, which a
//! timer interrupt cannot do without planning a step ahead, so a reversal's
//! first step here comes up to `dir_setup_ticks` later).

use driver::axis::{AxisError, AxisStatus, Direction, Mode};
use driver::profile::motion::{Accepted, CommandError, Motion};
use driver::profile::scurve::{self, ScurveConfig};
use driver::profile::{Phase, Profile};

/// The most steps a jog asks for at a time (as the host's cog).
const JOG_CHUNK_MAX: u32 = 1 << 28;

/// The two output variants: step and direction, or clockwise and
/// counter-clockwise pulses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// A step pin and a direction pin.
    Sd,
    /// A clockwise pin and a counter-clockwise pin.
    Cc,
}

/// Which of an axis's two output pins an edge is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    /// The step pin (`sd`) or the clockwise pin (`cc`).
    First,
    /// The direction pin (`sd`) or the counter-clockwise pin (`cc`).
    Second,
}

impl Output {
    /// 0 for [`Output::First`], 1 for [`Output::Second`].
    pub fn index(self) -> usize {
        match self {
            Output::First => 0,
            Output::Second => 1,
        }
    }
}

/// Where an axis's pin edges go (GPIO on a board, a recorder in tests).
pub trait EdgeSink {
    /// Drive `output` to `level`; `ct` is when the edge was scheduled.
    fn edge(&mut self, ct: u64, output: Output, level: bool);
}

impl<F: FnMut(u64, Output, bool)> EdgeSink for F {
    fn edge(&mut self, ct: u64, output: Output, level: bool) {
        self(ct, output, level)
    }
}

/// The settings of one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisConfig {
    /// The S-curve (clock, offset, acceleration divisor, arithmetic).
    pub scurve: ScurveConfig,
    /// Step pulse width, ticks.
    pub pulse_ticks: u32,
    /// Direction set-up before a step edge, ticks.
    pub dir_setup_ticks: u32,
    /// A jog decelerates this long after its last heartbeat, ticks.
    pub jog_timeout_ticks: u64,
    /// The output variant.
    pub variant: Variant,
}

impl AxisConfig {
    /// The host hub's defaults (5 µs pulse and set-up, 150 ms jog timeout)
    /// at `clkfreq`.
    pub fn at_clock(clkfreq: u32, variant: Variant) -> Self {
        let micros = |us: u64| u64::from(clkfreq) * us / 1_000_000;
        AxisConfig {
            scurve: ScurveConfig {
                clkfreq,
                ..ScurveConfig::default()
            },
            pulse_ticks: u32::try_from(micros(5)).unwrap_or(u32::MAX).max(1),
            dir_setup_ticks: u32::try_from(micros(5)).unwrap_or(u32::MAX).max(1),
            jog_timeout_ticks: micros(150_000),
            variant,
        }
    }
}

/// What one call to [`AxisLogic::advance`] did (for cost measurements).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Work {
    /// Ramp steps made (accelerating or decelerating).
    pub ramp_steps: u32,
    /// Slew steps made.
    pub slew_steps: u32,
    /// Other events: pulse ends, delayed rising edges, move ends, jog deadlines.
    pub other: u32,
}

impl Work {
    /// Adds another call's work.
    pub fn add(&mut self, other: Work) {
        self.ramp_steps += other.ramp_steps;
        self.slew_steps += other.slew_steps;
        self.other += other.other;
    }
}

/// The rising edges an axis has made on each output, and the position
/// they amount to (checked in tests).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EdgeCounts {
    /// Rising edges on [`Output::First`] and [`Output::Second`].
    pub rising: [u64; 2],
    /// Falling edges on each output.
    pub falling: [u64; 2],
}

/// One axis (see the module docs).
#[derive(Clone, Debug)]
pub struct AxisLogic {
    config: AxisConfig,
    motion: Motion,
    position: i64,
    stm: u32,
    mode: u32,
    velocity: u32,
    dropped: u32,
    stop_pin_high: bool,
    /// Flags that outlive a move (STOP_LATCHED, ESTOP, JOG).
    sticky: u32,
    /// A move given while the stop pin is low, waiting for it to go high.
    held: Option<(u32, i32)>,
    /// The stop pin was low at the last look and the move was told to stop.
    stopping: bool,
    /// Jogging: speed, direction and the CT by which the next beat must come.
    jog: Option<(u32, Direction, u64)>,
    /// When the next step is due (or the last delay ends), while moving.
    due: Option<u64>,
    /// When the axis is ready for a next first step.
    ready_ct: u64,
    dir_reverse: bool,
    /// A rising edge waiting for the direction set-up.
    rise_at: Option<(u64, Output)>,
    /// The pulse that ends next.
    fall_at: Option<(u64, Output)>,
    edges: EdgeCounts,
}

impl AxisLogic {
    /// An idle axis at position 0 with its stop pin high.
    pub fn new(config: AxisConfig) -> Self {
        AxisLogic {
            config,
            motion: Motion::new(config.scurve),
            position: 0,
            stm: 0,
            mode: 0,
            velocity: 0,
            dropped: 0,
            stop_pin_high: true,
            sticky: 0,
            held: None,
            stopping: false,
            jog: None,
            due: None,
            ready_ct: 0,
            dir_reverse: false,
            rise_at: None,
            fall_at: None,
            edges: EdgeCounts::default(),
        }
    }

    /// The settings.
    pub fn config(&self) -> &AxisConfig {
        &self.config
    }

    /// The reference `move(speed, steps)` at CT `now`, with the hub's
    /// rules: bad input or a command that cannot be taken now is refused
    /// and changes nothing; a move while the stop pin is low waits (Hold).
    pub fn move_steps(&mut self, now: u64, speed: u32, steps: i32) -> Result<(), AxisError> {
        self.check_speed(speed, steps.unsigned_abs())?;
        if self.held.is_some() || self.reversal_queued() {
            return Err(AxisError::Busy);
        }
        if self.stop_pin_high {
            self.apply_move(now, speed, steps)?;
        } else {
            self.held = Some((speed, steps));
        }
        self.look(now);
        Ok(())
    }

    /// A jog heartbeat at CT `now`.
    pub fn jog(&mut self, now: u64, speed: u32, direction: Direction) -> Result<(), AxisError> {
        self.check_speed(speed, 1)?;
        if self.stop_pin_high {
            let same = self
                .jog
                .is_some_and(|(s, d, _)| s == speed && d == direction);
            let running_this_way = self
                .motion
                .current()
                .is_some_and(|(curve, d)| d == direction && curve.is_running());
            let chunk = self.jog_chunk(speed);
            let low = running_this_way && self.remaining_in_current() < u64::from(chunk / 2);
            if !same || low || !self.motion.is_moving() {
                let magnitude = i32::try_from(chunk).unwrap_or(i32::MAX);
                let steps = match direction {
                    Direction::Reverse => -magnitude,
                    Direction::Forward => magnitude,
                };
                self.apply_move(now, speed, steps)?;
            }
            if self.motion.is_moving() {
                let deadline = now.saturating_add(self.config.jog_timeout_ticks);
                self.jog = Some((speed, direction, deadline));
                self.sticky |= Mode::JOG;
            }
        }
        self.look(now);
        Ok(())
    }

    /// Ends a jog at once (key released): controlled deceleration.
    pub fn jog_release(&mut self, now: u64) {
        if self.jog.take().is_some() {
            self.motion.stop();
            self.sticky &= !Mode::JOG;
        }
        self.look(now);
    }

    /// Drives the stop pin at CT `now`.
    pub fn set_stop_pin(&mut self, now: u64, high: bool) {
        self.stop_pin_high = high;
        self.look(now);
    }

    /// Emergency stop at CT `now`: no more steps (a pulse in progress still
    /// ends), position kept.
    pub fn emergency_stop(&mut self, now: u64) {
        self.dropped = self.motion.estop();
        self.held = None;
        self.jog = None;
        self.due = None;
        self.rise_at = None;
        self.ready_ct = self.ready_ct.max(now);
        self.sticky = Mode::ESTOP | (self.sticky & Mode::STOP_LATCHED);
        self.publish_idle();
        self.look(now);
    }

    /// Sets the position counter; only while idle.
    pub fn set_position(&mut self, position: i64) -> Result<(), AxisError> {
        if self.motion.is_moving() || self.held.is_some() || self.stm != 0 || self.due.is_some() {
            return Err(AxisError::NotIdle);
        }
        self.position = position;
        Ok(())
    }

    /// A snapshot, as the status line shows it.
    pub fn status(&self) -> AxisStatus {
        AxisStatus {
            position: self.position,
            stm: self.stm,
            mode: Mode(self.mode),
            velocity_steps_per_s: self.velocity,
            stop_pin_high: self.stop_pin_high,
        }
    }

    /// Steps the last stop (stop pin or emergency) left unmade.
    pub fn dropped_steps(&self) -> u32 {
        self.dropped
    }

    /// The edges made so far.
    pub fn edge_counts(&self) -> EdgeCounts {
        self.edges
    }

    /// The next CT at which something happens without outside input.
    pub fn next_event(&self) -> Option<u64> {
        [
            self.fall_at.map(|(t, _)| t),
            self.rise_at.map(|(t, _)| t),
            self.due,
            self.jog.map(|(_, _, deadline)| deadline),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// Makes every event up to CT `now`, in time order.
    pub fn advance(&mut self, now: u64, pins: &mut impl EdgeSink) -> Work {
        let mut work = Work::default();
        while let Some(t) = self.next_event().filter(|&t| t <= now) {
            if let Some((fall, output)) = self.fall_at.filter(|&(fall, _)| fall <= t) {
                self.fall_at = None;
                self.edges.falling[output.index()] += 1;
                pins.edge(fall, output, false);
                work.other += 1;
            } else if let Some((rise, output)) = self.rise_at.filter(|&(rise, _)| rise <= t) {
                self.rise_at = None;
                self.rise(rise, output, pins);
                work.other += 1;
            } else if self.due.is_some_and(|due| due <= t) {
                match self.step(t, pins) {
                    Some(Phase::Slew) => work.slew_steps += 1,
                    Some(_) => work.ramp_steps += 1,
                    None => work.other += 1,
                }
            } else {
                // The jog deadline: no heartbeat in time, the caller is gone.
                self.look(t);
                work.other += 1;
            }
        }
        work
    }

    fn check_speed(&self, speed: u32, steps: u32) -> Result<(), AxisError> {
        scurve::plan(&self.config.scurve, speed, steps)?;
        let shortest = self.config.scurve.clkfreq / speed;
        if self.config.pulse_ticks >= shortest.saturating_sub(1) {
            return Err(AxisError::PulseTooLong { speed });
        }
        Ok(())
    }

    fn reversal_queued(&self) -> bool {
        self.motion.steps_to_go() > self.remaining_in_current()
    }

    fn remaining_in_current(&self) -> u64 {
        self.motion
            .current()
            .map_or(0, |(curve, _)| u64::from(curve.remaining_steps()))
    }

    /// Steps a jog asks for at a time (the host cog's rule: reach the
    /// speed, run two heartbeat timeouts at it, still stop).
    fn jog_chunk(&self, speed: u32) -> u32 {
        let config = &self.config.scurve;
        let accel_steps = u64::from(speed / config.accel_div.max(1) + 2);
        let timeout_steps = u64::from(speed) * self.config.jog_timeout_ticks
            / u64::from(config.clkfreq.max(1))
            + 1;
        let chunk = 2 * (2 * accel_steps + timeout_steps) + 16;
        u32::try_from(chunk.min(u64::from(JOG_CHUNK_MAX))).unwrap_or(JOG_CHUNK_MAX)
    }

    /// The inputs at CT `t`: held moves, the stop pin, the jog deadline,
    /// and the mode they amount to.
    fn look(&mut self, t: u64) {
        if let Some((_, _, deadline)) = self.jog {
            if t >= deadline {
                self.jog = None;
                self.motion.stop();
                self.sticky &= !Mode::JOG;
            }
        }
        if self.stop_pin_high {
            self.stopping = false;
            if let Some((speed, steps)) = self.held.take() {
                // Checked when it was given; a move that cannot start now
                // (a reversal still stopping) is dropped, as the cog does.
                let _ = self.apply_move(t, speed, steps);
            }
        } else if !self.stopping && self.motion.is_moving() {
            // Stop pin low: decelerate at once from the current velocity.
            self.stopping = true;
            self.dropped = self.motion.stop();
            self.jog = None;
            self.sticky = (self.sticky | Mode::STOP_LATCHED) & !Mode::JOG;
        }
        let mut mode = self.mode_now();
        if self.held.is_some() {
            mode |= Mode::HOLD;
        }
        self.mode = mode;
    }

    /// Hands a move to the motion and schedules its first step.
    fn apply_move(&mut self, t: u64, speed: u32, steps: i32) -> Result<(), AxisError> {
        let was_moving = self.motion.is_moving();
        let accepted = self.motion.command(speed, steps).map_err(|error| match error {
            CommandError::Plan(plan) => AxisError::Plan(plan),
            // A merge past 2^32 - 1 steps: taken once the move has ended.
            CommandError::Busy | CommandError::TooManySteps => AxisError::Busy,
        })?;
        if accepted == Accepted::Started {
            self.sticky &= !(Mode::STOP_LATCHED | Mode::ESTOP | Mode::JOG);
            let reverse = if steps < 0 { Mode::REVERSE } else { 0 };
            self.mode = Mode::MOVING | Mode::ACCEL | reverse;
            self.dropped = 0;
        }
        if !was_moving {
            self.due = Some(self.due.unwrap_or(t).max(t).max(self.ready_ct));
        }
        self.stm = u32::try_from(self.motion.steps_to_go()).unwrap_or(u32::MAX);
        Ok(())
    }

    /// The step due at `t`, or the end of the move.
    fn step(&mut self, t: u64, pins: &mut impl EdgeSink) -> Option<Phase> {
        let Some(next) = self.motion.next_step() else {
            self.due = None;
            self.ready_ct = t;
            self.publish_idle();
            self.look(t);
            return None;
        };
        let reverse = next.direction == Direction::Reverse;
        let pulse = match (self.config.variant, next.direction) {
            (Variant::Sd, _) | (Variant::Cc, Direction::Forward) => Output::First,
            (Variant::Cc, Direction::Reverse) => Output::Second,
        };
        let mut rise = t;
        if reverse != self.dir_reverse {
            if self.config.variant == Variant::Sd {
                pins.edge(t, Output::Second, reverse);
                if reverse {
                    self.edges.rising[1] += 1;
                } else {
                    self.edges.falling[1] += 1;
                }
                rise = t + u64::from(self.config.dir_setup_ticks);
            }
            self.dir_reverse = reverse;
        }
        if rise == t {
            self.rise(t, pulse, pins);
        } else {
            self.rise_at = Some((rise, pulse));
        }
        self.position += next.direction.sign();
        self.velocity = next.step.velocity_steps_per_s as u32;
        let mut mode = Mode::MOVING | (self.sticky & !Mode::HOLD);
        mode |= match next.step.phase {
            Phase::Accel => Mode::ACCEL,
            Phase::Slew => Mode::SLEW,
            Phase::Decel => Mode::DECEL,
        };
        if reverse {
            mode |= Mode::REVERSE;
        }
        self.mode = mode;
        self.stm = u32::try_from(self.motion.steps_to_go()).unwrap_or(u32::MAX);
        let next_due = rise + u64::from(next.step.delay_ticks);
        self.due = Some(next_due);
        self.ready_ct = next_due;
        Some(next.step.phase)
    }

    fn rise(&mut self, t: u64, output: Output, pins: &mut impl EdgeSink) {
        pins.edge(t, output, true);
        self.edges.rising[output.index()] += 1;
        self.fall_at = Some((t + u64::from(self.config.pulse_ticks), output));
    }

    /// Mode bits between steps (as the cog's).
    fn mode_now(&self) -> u32 {
        const STEP_BITS: u32 =
            Mode::MOVING | Mode::ACCEL | Mode::DECEL | Mode::SLEW | Mode::REVERSE;
        if self.due.is_some() {
            (self.mode & STEP_BITS) | self.sticky
        } else {
            let reverse = if self.dir_reverse { Mode::REVERSE } else { 0 };
            self.sticky | reverse
        }
    }

    fn publish_idle(&mut self) {
        let reverse = if self.dir_reverse { Mode::REVERSE } else { 0 };
        self.mode = (self.sticky & !Mode::JOG) | reverse;
        self.velocity = 0;
        self.stm = 0;
    }
}

//! One axis of the firmware: the driver's [`AxisCore`] (everything the axis
//! decides, time in and edges out, the same core the host's cogs run) and
//! the edges it has decided but whose time has not come yet.
//!
//! The core emits a step's edges when it makes the step: the direction
//! edge `dir_setup_ticks` *before* the rising edge, the falling edge
//! `pulse_ticks` after it. A timer interrupt cannot drive a pin in the
//! past, so the firmware's core lives [`AxisRunner::lookahead`] ticks (the
//! set-up time) ahead of the clock: a command arriving at CT `now` reaches
//! the core at `now + lookahead`, the core runs its events up to that
//! time, and the edges it decides are queued and driven each at its CT,
//! which is then never in the past. Every step and edge is the core's,
//! shifted by the set-up time (5 µs); position and mode show a step that
//! long before its rising edge.

use driver::axis::{AxisError, AxisStatus, LimitStatus, Mode};
use driver::axis_core::{AxisCore, AxisCoreConfig, CoreCommand, Edge, Outputs};
use driver::profile::scurve::ScurveConfig;
use heapless::Deque;

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

    fn of_pin(pin: u8) -> Self {
        if pin == 0 {
            Output::First
        } else {
            Output::Second
        }
    }
}

/// The two output variants.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variant {
    /// Step and direction.
    Sd,
    /// Clockwise and counter-clockwise.
    Cc,
}

/// The core's settings for an axis of a board whose CT runs at `clkfreq`:
/// the host hub's timings (5 µs pulse and direction set-up, 150 ms jog
/// timeout), the axis's own pins numbered 0 ([`Output::First`]) and 1.
pub fn core_config(clkfreq: u32, variant: Variant) -> AxisCoreConfig {
    let micros = |us: u64| u64::from(clkfreq) * us / 1_000_000;
    let outputs = match variant {
        Variant::Sd => Outputs::StepDir { step: 0, dir: 1 },
        Variant::Cc => Outputs::CwCcw { cw: 0, ccw: 1 },
    };
    AxisCoreConfig {
        scurve: ScurveConfig {
            clkfreq,
            ..ScurveConfig::default()
        },
        outputs,
        pulse_ticks: u32::try_from(micros(5)).unwrap_or(u32::MAX).max(1),
        dir_setup_ticks: u32::try_from(micros(5)).unwrap_or(u32::MAX),
        jog_timeout_ticks: micros(150_000),
        math_ticks: 0,
        limit_estop: false,
    }
}

/// What one run of an axis did (for cost measurements).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Work {
    /// Ramp steps made (accelerating or decelerating).
    pub ramp_steps: u32,
    /// Slew steps made.
    pub slew_steps: u32,
    /// Edges driven.
    pub edges: u32,
}

impl Work {
    /// Adds another run's work.
    pub fn add(&mut self, other: Work) {
        self.ramp_steps += other.ramp_steps;
        self.slew_steps += other.slew_steps;
        self.edges += other.edges;
    }
}

/// Rising and falling edges driven on each output since boot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EdgeCounts {
    /// Rising edges on [`Output::First`] and [`Output::Second`].
    pub rising: [u64; 2],
    /// Falling edges on each output.
    pub falling: [u64; 2],
}

/// Edges decided and not yet driven: a step's direction, rising and
/// falling edges, for the steps inside the look-ahead (two at most while
/// the pulse fits between steps, which the core checks).
const QUEUE: usize = 8;

/// An [`AxisCore`] run ahead of the clock, with its pending edges.
#[derive(Clone, Debug)]
pub struct AxisRunner {
    core: AxisCore,
    pending: Deque<Edge, QUEUE>,
    edges: EdgeCounts,
}

impl AxisRunner {
    /// An idle axis at CT `ct`, its stop pin high (running allowed), as a
    /// board starts.
    pub fn new(config: AxisCoreConfig, ct: u64) -> Self {
        let mut core = AxisCore::new(config, ct);
        core.set_stop_pin(ct, true);
        AxisRunner {
            core,
            pending: Deque::new(),
            edges: EdgeCounts::default(),
        }
    }

    /// The core's settings.
    pub fn config(&self) -> &AxisCoreConfig {
        self.core.config()
    }

    /// How far ahead of the clock the core runs: the direction set-up time.
    pub fn lookahead(&self) -> u64 {
        u64::from(self.core.config().dir_setup_ticks)
    }

    /// A command arriving at CT `now` (the core's `now + lookahead`);
    /// refused commands change nothing.
    pub fn command(&mut self, now: u64, command: CoreCommand) -> Result<(), AxisError> {
        let core_ct = now.saturating_add(self.lookahead());
        self.core.command(core_ct, command).map(|_| ())
    }

    /// The stop pin's level from CT `now` (the core's `now + lookahead`).
    pub fn set_stop_pin(&mut self, now: u64, high: bool) {
        let core_ct = now.saturating_add(self.lookahead());
        self.core.set_stop_pin(core_ct, high);
    }

    /// The limit and homing state (soft limits only: this firmware reads
    /// no switch inputs, so it has no hard limits and no homing).
    pub fn limit_status(&self) -> LimitStatus {
        LimitStatus {
            soft_limits: self.core.soft_limits(),
            limit_pins: self.core.limit_pins(),
            trip: self.core.limit_trip(),
            homing: self.core.is_homing(),
            home_outcome: self.core.home_outcome(),
        }
    }

    /// A snapshot as the status line shows it. STM is 0: a firmware takes
    /// each command before it replies.
    pub fn status(&self) -> AxisStatus {
        AxisStatus {
            position: self.core.position(),
            stm: 0,
            steps_to_go: self.core.steps_to_go(),
            mode: self.core.mode(),
            velocity_steps_per_s: self.core.last_step().velocity,
            stop_pin_high: self.core.stop_pin_high(),
        }
    }

    /// Steps the last stop left unmade.
    pub fn dropped_steps(&self) -> u32 {
        self.core.dropped_steps()
    }

    /// The edges driven so far.
    pub fn edge_counts(&self) -> EdgeCounts {
        self.edges
    }

    /// Runs the core up to `now` + the look-ahead and drives every edge due
    /// by `now` through `drive`.
    pub fn advance(&mut self, now: u64, drive: &mut impl FnMut(Output, bool)) -> Work {
        let mut work = Work::default();
        let horizon = now.saturating_add(self.lookahead());
        while let Some(t) = self.core.next_event().filter(|&t| t <= horizon) {
            let position_before = self.core.position();
            let (pending, edges) = (&mut self.pending, &mut self.edges);
            self.core.run_event(t, &mut |edge: Edge| {
                if let Err(edge) = pending.push_back(edge) {
                    // Never lost: a full queue drives its oldest edge now.
                    if let Some(oldest) = pending.pop_front() {
                        Self::drive_edge(edges, oldest, drive);
                    }
                    let _ = pending.push_back(edge);
                }
            });
            if self.core.position() != position_before {
                if self.core.mode().has(Mode::SLEW) {
                    work.slew_steps += 1;
                } else {
                    work.ramp_steps += 1;
                }
            }
        }
        while let Some(edge) = self.pending.front().copied().filter(|edge| edge.ct <= now) {
            self.pending.pop_front();
            Self::drive_edge(&mut self.edges, edge, drive);
            work.edges += 1;
        }
        work
    }

    /// When this axis next needs the step interrupt.
    pub fn next_wake(&self) -> Option<u64> {
        let core = self
            .core
            .next_event()
            .map(|t| t.saturating_sub(self.lookahead()));
        let edge = self.pending.front().map(|edge| edge.ct);
        match (core, edge) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    fn drive_edge(edges: &mut EdgeCounts, edge: Edge, drive: &mut impl FnMut(Output, bool)) {
        let output = Output::of_pin(edge.pin);
        if edge.level {
            edges.rising[output.index()] += 1;
        } else {
            edges.falling[output.index()] += 1;
        }
        drive(output, edge.level);
    }
}

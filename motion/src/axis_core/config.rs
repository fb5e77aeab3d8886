//! What an axis core is told and what it reports: pins, configuration,
//! commands, and the accounts and parameters it publishes.

use crate::axis::{Direction, HomeConfig};
use crate::profile::motion::Accepted;
use crate::profile::scurve::ScurveConfig;

/// One level change on a pin, at a system counter time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Edge {
    /// The system counter (CT) when the pin changed, in clkfreq ticks.
    pub ct: u64,
    /// The pin number.
    pub pin: u8,
    /// The new level: `true` = high.
    pub level: bool,
}

/// How an axis's step outputs map onto pins: all that differs between the
/// two variants.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Outputs {
    /// Step and direction (`sd`).
    StepDir {
        /// Pulsed once per step.
        step: u8,
        /// Low for positive steps, high for negative.
        dir: u8,
    },
    /// Clockwise and counter-clockwise (`cc`).
    CwCcw {
        /// Pulsed for each positive step.
        cw: u8,
        /// Pulsed for each negative step.
        ccw: u8,
    },
}

impl Outputs {
    /// The pin pulsed for a step in `direction`.
    pub fn pulse_pin(self, direction: Direction) -> u8 {
        match (self, direction) {
            (Outputs::StepDir { step, .. }, _) => step,
            (Outputs::CwCcw { cw, .. }, Direction::Forward) => cw,
            (Outputs::CwCcw { ccw, .. }, Direction::Reverse) => ccw,
        }
    }

    /// The direction pin, for `sd`.
    pub fn dir_pin(self) -> Option<u8> {
        match self {
            Outputs::StepDir { dir, .. } => Some(dir),
            Outputs::CwCcw { .. } => None,
        }
    }

    /// Both output pins.
    pub fn pins(self) -> [u8; 2] {
        match self {
            Outputs::StepDir { step, dir } => [step, dir],
            Outputs::CwCcw { cw, ccw } => [cw, ccw],
        }
    }

    /// `"sd"` or `"cc"`.
    pub fn variant(self) -> &'static str {
        match self {
            Outputs::StepDir { .. } => "sd",
            Outputs::CwCcw { .. } => "cc",
        }
    }
}

/// How an axis runs: its profile settings, pins and timing limits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AxisCoreConfig {
    /// The S-curve settings (clock, offset, acceleration divisor, arithmetic).
    pub scurve: ScurveConfig,
    /// The output pins.
    pub outputs: Outputs,
    /// Step pulse width, ticks (≥ 1).
    pub pulse_ticks: u32,
    /// Direction set-up time before the next step edge, ticks.
    pub dir_setup_ticks: u32,
    /// A jog decelerates this long after its last heartbeat, ticks.
    pub jog_timeout_ticks: u64,
    /// Clock ticks of CORDIC work a ramp step needs (counted as an overrun
    /// when its delay is shorter).
    pub math_ticks: u64,
    /// A hard limit stops the axis with an emergency stop instead of the
    /// fastest controlled deceleration.
    pub limit_estop: bool,
    /// How late, at most, the caller tells an input change after the step
    /// on which it happened, ticks (`AxisCore::set_inputs_late`): 0 for a
    /// caller that tells every change on time (the hub). A core run ahead
    /// of its pins may end homing's backoff before its pins have left the
    /// switch; it then starts the approach and waits this long for the
    /// release before it calls the switch stuck.
    pub input_latency_ticks: u64,
}

impl AxisCoreConfig {
    /// The defaults of a P2 at 200 MHz (5 µs pulse and set-up, 150 ms jog
    /// timeout) on `outputs`.
    pub fn new(outputs: Outputs) -> Self {
        let scurve = ScurveConfig::default();
        Self {
            scurve,
            outputs,
            pulse_ticks: 1_000,
            dir_setup_ticks: 1_000,
            jog_timeout_ticks: u64::from(scurve.clkfreq) * 150 / 1_000,
            math_ticks: 0,
            limit_estop: false,
            input_latency_ticks: 0,
        }
    }
}

/// A command for one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CoreCommand {
    /// The reference `move(speed, steps)`.
    Move {
        /// Steps/s.
        speed: u32,
        /// Signed: the sign is the direction.
        steps: i32,
    },
    /// A jog heartbeat: run at `speed` in `direction` until the beats stop.
    Jog {
        /// Steps/s.
        speed: u32,
        /// Which way.
        direction: Direction,
    },
    /// End a jog at once: controlled deceleration.
    JogRelease,
    /// Set the position counter (idle only).
    SetPosition(i64),
    /// No more steps; the position is kept.
    EmergencyStop,
    /// Start homing (idle only; see [`AxisCore`](super::AxisCore)'s homing section).
    Home(HomeConfig),
    /// Soft limits `(min, max)` on the position, or none.
    SetSoftLimits(Option<(i64, i64)>),
    /// The hard limit inputs: `(pin, active level)` for the min and max side.
    SetLimitPins {
        /// The limit met moving in reverse.
        min: Option<(u8, bool)>,
        /// The limit met moving forward.
        max: Option<(u8, bool)>,
    },
    /// Forget a tripped hard limit.
    ClearLimitFault,
    /// A coordinated move's first phase: check that this member could run
    /// its part (`steps`, signed) now, and refuse every other move until
    /// [`CoreCommand::GroupStart`] or [`CoreCommand::GroupCancel`].
    GroupReserve {
        /// This member's signed steps.
        steps: i32,
    },
    /// Give a reservation back: nothing moves.
    GroupCancel,
    /// A coordinated move's second phase: run this member's part of the
    /// line. Never refused after a [`CoreCommand::GroupReserve`] that was
    /// taken (the checks were made then).
    GroupStart(GroupMove),
    /// Put the axis on a look-ahead path (idle, stop pin high, no hard
    /// limit tripped): it then makes the steps pushed to it
    /// ([`AxisCore::push_path_step`](super::AxisCore::push_path_step)) and
    /// refuses every other motion.
    PathStart,
    /// No more steps of the path will come: idle once they are made.
    PathEnd,
}

/// One member's part of a coordinated move (see [`AxisCore`](super::AxisCore)'s "Coordinated
/// moves").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GroupMove {
    /// The lead's speed, steps/s.
    pub speed: u32,
    /// The lead's steps (the longest move of the group), ≥ |`steps`|.
    pub lead_steps: u32,
    /// This member's signed steps (0 allowed: it makes none).
    pub steps: i32,
    /// The CT of every member's first edge.
    pub start_ct: u64,
}

/// What a taken command became.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Taken {
    /// A move started, merged, changed speed or was queued behind a reversal.
    Move(Accepted),
    /// The stop pin is low: the move waits for it to go high (mode HOLD).
    Held,
    /// A jog heartbeat was taken.
    Jog,
    /// Anything else (release, set position, emergency stop).
    Done,
}

/// The step accounts of an axis since it started (or since its position was
/// last set): what was asked for, what was not made, what jogs made.
///
/// Whenever the axis is idle, `position = base + accepted − dropped + jogged`,
/// all signed: no step vanishes unaccounted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StepLedger {
    /// The position the accounts start from (the last set position).
    pub base: i64,
    /// Signed sum of the steps of every taken move.
    pub accepted: i64,
    /// Signed sum of the steps of taken moves that were then not made.
    pub dropped: i64,
    /// Total (unsigned) of the steps not made, stop after stop.
    pub dropped_total: u64,
    /// Signed steps made while a jog owned the axis.
    pub jogged: i64,
}

/// The state of a move's parameters as the reference driver's hub longs
/// show them (speed asked, accel steps, slew steps, top velocity, start CT).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MoveInfo {
    /// The speed the move asked for, steps/s.
    pub speed: u32,
    /// Accel steps of the ramp in use.
    pub accel_steps: u32,
    /// Steps at speed, as planned.
    pub slew_steps: u32,
    /// The top velocity the move heads for, steps/s.
    pub top_velocity: u32,
    /// CT at which the move began.
    pub start_ct: u64,
    /// The reference's "Max Velocity" long: written when deceleration
    /// starts (`_mlp5`), with the velocity of the last ramp step before it;
    /// it keeps the last move's value until then.
    pub max_velocity: u32,
}

/// What the last step did, for status displays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LastStep {
    /// Velocity of the step, steps/s.
    pub velocity: u32,
    /// The delay computed after it, ticks.
    pub delay_ticks: u32,
    /// CT of its rising edge.
    pub ct: u64,
}

//! How a hub is built: [`HubConfig`], the errors it refuses with, and
//! what every cog's axis core runs with (the CORDIC work of a step included).

use super::Hub;
use crate::clock::ClockMode;
use crate::pins::Outputs;
use cogstep_motion::axis_core::AxisCoreConfig;
use cogstep_motion::profile::scurve::{Arithmetic, ScurveConfig};
use cogstep_motion::profile::PlanError;

/// How to build a hub.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HubConfig {
    /// System clock, Hz (default 200 MHz, as the P2 usually runs).
    pub clkfreq: u32,
    /// Virtual (deterministic) or real time.
    pub clock: ClockMode,
    /// How many cogs may run at once (default 8, as the P2 has).
    pub max_cogs: usize,
    /// Step pulse width, ticks (default 1,000: the reference's 5 µs at 200 MHz).
    pub pulse_ticks: u32,
    /// Direction set-up time before the next step edge, ticks (default
    /// 1,000: 5 µs at 200 MHz, enough for common driver chips).
    pub dir_setup_ticks: u32,
    /// S-curve offset, degrees (default 40).
    pub offset_deg: u32,
    /// Acceleration divisor (default 10).
    pub accel_div: u32,
    /// Reference integer arithmetic, or the improved default.
    pub arithmetic: Arithmetic,
    /// A jog decelerates this long after its last heartbeat, ms (default 150).
    pub jog_timeout_ms: u32,
    /// Record every pin edge for [`Hub::trace`] and VCD (default off; the
    /// per-pin counters are always on).
    pub trace_edges: bool,
    /// Undrained edges each cog's ring holds (default 65,536).
    pub trace_ring: usize,
    /// A hard limit stops its axis with an emergency stop instead of the
    /// fastest controlled deceleration (default off).
    pub limit_estop: bool,
    /// With the real clock, each cog asks the kernel for the lowest
    /// real-time priority (`SCHED_FIFO` 1) where the process may have it,
    /// so that late wake-ups do not become lag (default on; a cog that is
    /// refused stays an ordinary thread). Off: cogs stay ordinary threads.
    pub realtime_priority: bool,
}

impl Default for HubConfig {
    fn default() -> Self {
        Self {
            clkfreq: 200_000_000,
            clock: ClockMode::Virtual,
            max_cogs: 8,
            pulse_ticks: 1_000,
            dir_setup_ticks: 1_000,
            offset_deg: 40,
            accel_div: 10,
            arithmetic: Arithmetic::Smooth,
            jog_timeout_ms: 150,
            trace_edges: false,
            trace_ring: 1 << 16,
            limit_estop: false,
            realtime_priority: true,
        }
    }
}

impl HubConfig {
    /// The S-curve settings every cog uses.
    pub fn scurve(&self) -> ScurveConfig {
        ScurveConfig {
            clkfreq: self.clkfreq,
            offset_deg: self.offset_deg,
            accel_div: self.accel_div,
            arithmetic: self.arithmetic,
        }
    }
}

/// Why the hub refused a request. Nothing changes when it does.
#[derive(Debug, thiserror::Error)]
pub enum HubError {
    /// All cogs are taken.
    #[error("all {max} cogs are running")]
    TooManyCogs {
        /// The limit.
        max: usize,
    },
    /// Pins are numbered 0 to 63.
    #[error("pin {0} does not exist (pins are 0 to 63)")]
    PinOutOfRange(u8),
    /// Another cog (or this one) already uses the pin.
    #[error("pin {0} is already in use")]
    PinInUse(u8),
    /// The configuration cannot work.
    #[error("bad hub configuration: {0}")]
    Config(&'static str),
    /// The S-curve settings are invalid.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// The operating system would not start the cog's thread.
    #[error("could not start a cog thread: {0}")]
    Spawn(#[from] std::io::Error),
    /// A virtual-clock operation was asked of a real-clock hub.
    #[error("only a hub with the virtual clock can be advanced")]
    NotVirtual,
    /// The axis is not one of this hub's running axes.
    #[error("the axis is stopped or belongs to another hub")]
    NoSuchAxis,
    /// The pin is driven by a simulated switch ([`Hub::attach_switch`]).
    #[error("pin {0} is driven by a simulated switch")]
    SwitchPin(u8),
}

impl Hub {
    /// What every cog's axis core runs with, on `outputs`.
    pub(crate) fn core_config(&self, outputs: Outputs) -> AxisCoreConfig {
        let config = &self.inner.config;
        AxisCoreConfig {
            scurve: config.scurve(),
            outputs,
            pulse_ticks: config.pulse_ticks,
            dir_setup_ticks: config.dir_setup_ticks,
            jog_timeout_ticks: u64::from(config.jog_timeout_ms) * u64::from(config.clkfreq) / 1_000,
            math_ticks: self.inner.math_ticks,
            limit_estop: config.limit_estop,
            input_latency_ticks: 0,
        }
    }
}

/// The CORDIC work of a ramp step on the P2, from cordic-core's pipeline
/// model: QROTATE issued in the cog's hub slot, GETQX waiting the 55 clocks
/// for its result, then QDIV in the next slot and GETQX again; the worst
/// case over where in the 8-clock slot rotation the step begins.
pub(super) fn step_math_ticks() -> u64 {
    use cordic_core::pipeline::{Command, Cordic};
    (0..8u64)
        .map(|start| {
            let mut cordic = Cordic::starting_at(0, start);
            cordic.issue(Command::Rotate {
                x: 25_000,
                y: 0,
                angle: 1 << 30,
            });
            let _ = cordic.getqx();
            cordic.issue(Command::Div {
                dividend: 200_000_000,
                divisor: 25_000,
            });
            let _ = cordic.getqx();
            cordic.now() - start
        })
        .max()
        .unwrap_or(0)
}

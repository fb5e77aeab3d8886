//! # driver — cogstep under one name
//!
//! cogstep is split into crates along the `no_std` line; this façade keeps
//! the paths programs and scripts use (`driver::Hub`,
//! `driver::profile::scurve`, `driver::serial::host::SerialBoard`, ...). A
//! move command flows through them in this order:
//!
//! ```text
//! move(speed, steps) ─► hub: mailbox ─► cog ─► motion: axis core ─► profile
//!     ─► cordic-core (QROTATE, QDIV) ─► step timing (ticks) ─► pins
//! ```
//!
//! | path | crate | runs on |
//! |---|---|---|
//! | [`profile`], [`axis`], [`axis_core`] | `cogstep-motion` | everywhere (`no_std`, no alloc) |
//! | `profile::{austin, leib, trapezoid}` | `cogstep-ramps` | everywhere (`no_std`; feature `ramps`) |
//! | [`serial`] (board side, `p2demo`) | `cogstep-protocol` | everywhere (`no_std`, no alloc) |
//! | [`motor`] | `cogstep-motor` | everywhere (`no_std`) |
//! | [`Hub`], [`Axis`], `pins`, `switch`, `trace` | `cogstep-hub` | the host (feature `std`) |
//! | `serial::host` | `cogstep-serial-host` | the host (feature `std`) |
//! | `serial::sim` | `cogstep-sim` | the host (feature `std`) |
//!
//! Without the default `std` feature this crate is the allocation-free
//! `no_std` core a firmware builds on.
//!
//! # Homing and limits
//!
//! The README's homing example (a doc test here):
//!
//! ```
//! use driver::{AxisError, Direction, HomeConfig, Hub, HubConfig};
//!
//! let hub = Hub::new(HubConfig::default())?;            // virtual clock
//! let x = hub.start_sd(0, 1, 2)?;
//! hub.set_input(0, true)?;
//! // A simulated home switch on pin 10: pressed while x is at −3,217 or below.
//! hub.attach_switch(10, &x, i64::MIN..=-3_217, true)?;
//! x.home(HomeConfig { switch_pin: 10, active_level: true, direction: Direction::Reverse,
//!                     seek_speed: 8_000, latch_speed: 500, backoff_steps: 200,
//!                     max_travel: 100_000, set_position: 0 })?;
//! hub.run_until_idle();
//! let report = x.home_outcome().expect("homing ended")?;
//! assert_eq!(report.latch_physical, -3_217);               // the step the switch changed on
//! assert_eq!(x.position(), x.physical_position() + 3_217); // that point is now 0
//! x.set_soft_limits(-1_000, 50_000)?;
//! assert_eq!(x.move_steps(8_000, 60_000), Err(AxisError::BeyondSoftLimit));
//! x.set_limit_pins(Some((11, true)), Some((12, true)))?;   // hard limits: (pin, active level)
//! assert_eq!(x.limit_fault(), None);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![cfg_attr(not(feature = "std"), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub use cogstep_motion::{axis, axis_core, planner, refusal};
pub use cogstep_motor as motor;

/// Motion profiles: the S-curve and one axis's motion (`cogstep-motion`),
/// and with the `ramps` feature the comparison ramps (`cogstep-ramps`).
pub mod profile {
    pub use cogstep_motion::profile::*;
    #[cfg(feature = "ramps")]
    pub use cogstep_ramps::{austin, leib, lookahead, trapezoid};
}

/// The serial line protocol, board side (`cogstep-protocol`); with the
/// `std` feature the host side ([`serial::host`](self::serial)) and the
/// board simulator (`serial::sim`).
pub mod serial {
    pub use cogstep_protocol::*;
    #[cfg(feature = "std")]
    pub use cogstep_serial_host as host;
    #[cfg(feature = "std")]
    pub use cogstep_sim as sim;
}

#[cfg(feature = "std")]
pub use cogstep_hub::{pins, switch, trace};

#[cfg(feature = "std")]
pub use cogstep_hub::{Axis, ClockMode, Hub, HubConfig, HubError};
#[cfg(feature = "std")]
pub use cogstep_hub::{PathControl, PathError, PathFault, PathJob, PathMachine, PathProgress};

/// G-code in: the interpreter and the machine file ([`cogstep_gcode`]),
/// and running a program on a hub's path ([`gcode::GcodePath`]).
#[cfg(feature = "std")]
pub mod gcode {
    pub use crate::gcode_path::{home_config, GcodePath, GcodePathError, LineOutcome};
    pub use cogstep_gcode::*;
}
#[cfg(feature = "std")]
mod gcode_path;
pub use cogstep_motion::axis::{AxisContract, AxisError, AxisState, AxisStatus, Direction, Mode};
pub use cogstep_motion::axis::{HomeConfig, HomeReport, LimitStatus, LimitTrip};
pub use cogstep_motion::axis_core::{AxisCore, AxisCoreConfig, CoreCommand, StepLedger};
pub use cogstep_motion::axis_core::{Edge, Outputs};

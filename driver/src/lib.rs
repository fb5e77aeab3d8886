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
//! | [`Hub`], [`Axis`], `pins`, `trace` | `cogstep-hub` | the host (feature `std`) |
//! | `serial::host` | `cogstep-serial-host` | the host (feature `std`) |
//! | `serial::sim` | `cogstep-sim` | the host (feature `std`) |
//!
//! Without the default `std` feature this crate is the allocation-free
//! `no_std` core a firmware builds on.
#![cfg_attr(not(feature = "std"), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub use cogstep_motion::{axis, axis_core};
pub use cogstep_motor as motor;

/// Motion profiles: the S-curve and one axis's motion (`cogstep-motion`),
/// and with the `ramps` feature the comparison ramps (`cogstep-ramps`).
pub mod profile {
    pub use cogstep_motion::profile::*;
    #[cfg(feature = "ramps")]
    pub use cogstep_ramps::{austin, leib, trapezoid};
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
pub use cogstep_hub::{pins, trace};

#[cfg(feature = "std")]
pub use cogstep_hub::{Axis, ClockMode, Hub, HubConfig, HubError};
pub use cogstep_motion::axis::{AxisContract, AxisError, AxisState, AxisStatus, Direction, Mode};
pub use cogstep_motion::axis_core::{AxisCore, AxisCoreConfig, CoreCommand, StepLedger};
pub use cogstep_motion::axis_core::{Edge, Outputs};

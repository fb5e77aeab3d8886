//! # cordic-core — the Propeller 2's hub CORDIC solver, emulated in integers
//!
//! The P2 has one CORDIC solver in its hub, shared by all eight cogs. Every
//! command takes 32-bit operands and gives 32-bit results; cogstep's motion
//! code uses it for each step (a cosine with [`qrotate`], a division with
//! [`qdiv`]), so this crate reproduces those commands on the same widths:
//!
//! | function | P2 command | result |
//! |---|---|---|
//! | [`qrotate`] | QROTATE (with SETQ y) | the vector rotated by a binary angle (2^32 = 360°) |
//! | [`qvector`] | QVECTOR | (length, angle) |
//! | [`qmul`] | QMUL | (low, high) halves of the 64-bit product |
//! | [`qdiv`] | QDIV (with SETQ high) | (quotient, remainder) |
//! | [`qfrac`] | QFRAC | ({d:0}/s quotient, remainder) |
//! | [`qsqrt`] | QSQRT | floor of the square root of a u64 |
//! | [`qlog`] | QLOG | log2 as 5.27 fixed point |
//! | [`qexp`] | QEXP | 2^x of a 5.27 value |
//!
//! [`qrotate`] and [`qvector`] are a real CORDIC (shift-and-add iterations,
//! gain compensated, integer only) rounded to nearest like the chip — not
//! like the `spinsim` simulator, which truncates a floating-point result.
//! The crate is `no_std` and has no floating point in any library path.
//!
//! ```
//! use cordic_core::{qdiv, qrotate};
//! // The S-curve's velocity at 90°: v = sp·(1 − cos θ)/2 with sp = 50,000.
//! let half_speed = 25_000;
//! let (x, _) = qrotate(half_speed, 0, 0x4000_0000);
//! let velocity = (half_speed - x) as u32;
//! assert_eq!(velocity, 25_000);
//! // The step delay at 200 MHz: clkfreq / v ticks.
//! assert_eq!(qdiv(200_000_000, velocity).0, 8_000);
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod arith;
mod log;
mod rotate;
mod tables;

pub use arith::{qdiv, qfrac, qmul, qsqrt};
pub use log::{qexp, qlog};
pub use rotate::{qrotate, qvector};

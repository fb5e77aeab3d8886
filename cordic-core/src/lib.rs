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
//! | [`cos_batch`] | QROTATE of (r, 0), many angles | X of each, as [`qrotate`] gives it |
//!
//! [`qrotate`] and [`qvector`] are a real CORDIC (shift-and-add iterations,
//! gain compensated, integer only) rounded to nearest like the chip — not
//! like the `spinsim` simulator, which truncates a floating-point result.
//! [`cos_batch`] is `qrotate` as a cosine over a slice of angles, bit for bit
//! the same, from a table and a short polynomial (falling back to `qrotate`
//! itself within 1/64 LSB of a rounding boundary). The crate is `no_std`,
//! does not allocate, and has no floating point in any library path.
//!
//! [`pipeline`] models the solver's timing as the P2 has it (one shared
//! 54-stage pipeline, a hub slot every 8 clocks per cog, results 55 clocks
//! after issue), so that emulated cogs can count the clocks their math costs.
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
//!
//! // A ramp of cosines at once: 40°, 45°, ..., 75°.
//! let degree = 0x00B6_0B61; // 2^32 / 360, rounded
//! let angles: Vec<u32> = (40..80).step_by(5).map(|deg| deg * degree).collect();
//! let mut cosines = vec![0; angles.len()];
//! cordic_core::cos_batch(half_speed, &angles, &mut cosines);
//! assert_eq!(cosines[0], 19_151); // 25,000 · cos 40° = 19,151.1
//! assert!(angles.iter().zip(&cosines).all(|(&a, &c)| c == qrotate(half_speed, 0, a).0));
//! ```
//!
//! # Accuracy
//!
//! Measured by the crate's tests (`src/accuracy.rs`) over a million seeded
//! pseudo-random inputs per operation, against `f64` references: inputs of
//! every magnitude, full-scale vectors ((±2^31, …), `i32::MIN`), angles just
//! either side of every multiple of 45° (0/90/180/270° and the octant edges),
//! the S-curve's (r, 0) operands and short vectors. Errors are in LSB of the
//! 32-bit result against the exact value, so correct rounding alone accounts
//! for up to 0.5 LSB; "misrounded" counts results more than 0.5 LSB off (the
//! exact value was within that much of a rounding boundary).
//!
//! | operation | max error | mean error | misrounded |
//! |---|---|---|---|
//! | [`qrotate`] X | 0.5011 LSB | 0.2224 LSB | 54 of 929,148 (0.006 %) |
//! | [`qrotate`] Y | 0.5010 LSB | 0.2224 LSB | 60 of 929,204 (0.006 %) |
//! | [`qvector`] length | 0.5000 LSB | 0.1626 LSB | 0 of 994,698 |
//! | [`qvector`] angle | 0.5012 LSB | 0.2249 LSB | 491 of 994,698 (0.05 %) |
//! | [`qlog`] | 0.5000 LSB | 0.2001 LSB | 0 of 998,455 |
//! | [`qexp`] | 0.5000 LSB | 0.1256 LSB | 0 of 1,000,000 |
//!
//! The tests assert a maximum of 0.51 LSB for each (so the documented 1 LSB
//! bound holds with room to spare) and that results whose exact value lies
//! outside `i32` saturate; the counts leave out those saturated components
//! and the zero vector. By design, QROTATE's arithmetic adds at most
//! 0.002 LSB to the rounding (for the longest vectors; proportionally less
//! for shorter ones, so motion-sized operands below 2^20 always come out
//! correctly rounded), and QVECTOR's angle at most 0.0013 LSB (2^-39 rad
//! left after 40 iterations). [`cos_batch`] equals [`qrotate`] bit for bit
//! (tested over the same million angles). QLOG and QEXP compute the
//! mathematically exact value and round it: within 0.5 LSB in every case
//! measured.
//!
//! # Speed
//!
//! `cargo bench -p cordic-core` (`benches/cosine.rs`) times the cosine of
//! 16,384 random angles with [`qrotate`], [`cos_batch`], the `cordic`
//! crate's `sin_cos` on `fixed::types::I32F32`, and `f64::sin_cos`, and
//! prints the ratios (best of interleaved rounds, so that a busy machine
//! slows every contender alike). On the development machine (2-core AMD
//! EPYC, Zen 4, under a 2.5 load average; the default x86-64 target, so
//! SSE2 vectors only), per cosine:
//!
//! | contender | ns per cosine | `cordic` crate ÷ this |
//! |---|---|---|
//! | [`cos_batch`] | 8.0 (9.6 with the earlier block CORDIC) | 31x |
//! | [`qrotate`] in a loop | 22.7–27 | 8.5–9x |
//! | `cordic::sin_cos`, `I32F32` | 194–249 | 1 |
//! | `f64::sin_cos` | 9–20 | 13–21x |
//!
//! (`cargo run --release -p driver --example bench -- --json` reports
//! `ratio_cos_batch_vs_f64`: 2.69 in the run of `docs/performance.md`.)
//!
//! The same run measures the error over its angles: 0.5000 LSB for
//! [`qrotate`] and [`cos_batch`] (radius 2^31 − 1), against up to 24 LSB of
//! 2^-32 for the `cordic` crate's `I32F32` cosine.
//!
//! QROTATE's 10 iterations are branch free; the `cordic` crate's 32 are
//! not, and with a set of angles small enough to be learnt by the branch
//! predictor (about a thousand, repeated) it runs a third faster than any real
//! caller would see, which is why the bench uses 16,384.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(test)]
mod accuracy;
mod arith;
mod log;
pub mod pipeline;
mod rotate;
mod tables;
pub mod wide_mul;

pub use arith::{qdiv, qfrac, qmul, qsqrt};
pub use log::{qexp, qlog};
pub use rotate::{cos_batch, cos_sin_q62, qrotate, qvector, sin_cos, SIN_COS_ERROR};

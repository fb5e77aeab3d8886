//! Accuracy of QROTATE, QVECTOR, QLOG and QEXP against `f64` references,
//! over a million seeded pseudo-random inputs each, extremes included.
//!
//! These tests produce the figures of the crate docs' "Accuracy" section;
//! `cargo test -p cordic-core accuracy -- --nocapture` prints them. Errors
//! are in LSB of the 32-bit result, measured against the exact value (not
//! against the exact value rounded), so a correctly rounded result is up to
//! 0.5 LSB off and "misrounded" counts results more than 0.5 LSB off. The
//! `f64` references are good to about 2^-20 LSB.

extern crate std;

use core::f64::consts::TAU;
use std::println;
use std::vec::Vec;

use crate::{cos_batch, qexp, qlog, qrotate, qvector};

/// Inputs per operation.
const INPUTS: usize = 1_000_000;

/// The error bound asserted for every operation: rounding (0.5 LSB) plus
/// what the arithmetic may add (at most 0.002 LSB for QROTATE, by design).
const MAX_ERROR_LSB: f64 = 0.51;

/// SplitMix64: a tiny seeded generator, so every run sees the same inputs.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn next_u32(&mut self) -> u32 {
        (self.next_u64() >> 32) as u32
    }

    fn next_i32(&mut self) -> i32 {
        self.next_u32() as i32
    }

    /// A value spread over all magnitudes: a random word shifted right by
    /// 0 to 31 bits.
    fn any_magnitude(&mut self) -> u32 {
        let shift = self.next_u32() % 32;
        self.next_u32() >> shift
    }

    fn pick<T: Copy>(&mut self, choices: &[T]) -> T {
        choices[self.next_u32() as usize % choices.len()]
    }
}

/// Max and mean error, and how many results are more than ½ LSB off.
#[derive(Default)]
struct ErrorStats {
    max: f64,
    sum: f64,
    count: u64,
    misrounded: u64,
    worst: Option<(i64, i64, i64)>,
}

impl ErrorStats {
    fn add(&mut self, error: f64, input: (i64, i64, i64)) {
        let error = error.abs();
        if error > self.max {
            self.max = error;
            self.worst = Some(input);
        }
        self.sum += error;
        self.count += 1;
        // Allow the reference's own noise at exact ties.
        if error > 0.5 + 1e-6 {
            self.misrounded += 1;
        }
    }

    fn mean(&self) -> f64 {
        self.sum / self.count as f64
    }

    fn report(&self, name: &str) {
        println!(
            "{name:>14}: max {:.4} LSB, mean {:.4} LSB, misrounded {} of {} ({:.4}%), worst input {:?}",
            self.max,
            self.mean(),
            self.misrounded,
            self.count,
            100.0 * self.misrounded as f64 / self.count as f64,
            self.worst,
        );
    }

    fn assert_within(&self, name: &str, bound: f64) {
        self.report(name);
        assert!(self.count > 0, "{name}: nothing measured");
        assert!(
            self.max <= bound,
            "{name}: max error {} LSB > {bound} at {:?}",
            self.max,
            self.worst
        );
    }
}

/// A binary angle (2^32 = 360°) in radians, in [−π, π).
fn radians(angle: u32) -> f64 {
    f64::from(angle as i32) * TAU / 4_294_967_296.0
}

/// Adds the error of one result component against its exact value, or, if
/// the exact value is outside `i32`, checks that the result saturated.
fn add_component(stats: &mut ErrorStats, result: i32, exact: f64, input: (i64, i64, i64)) {
    if exact >= f64::from(i32::MAX) + 0.5 {
        assert_eq!(result, i32::MAX, "must saturate: {input:?}");
    } else if exact < f64::from(i32::MIN) - 0.5 {
        assert_eq!(result, i32::MIN, "must saturate: {input:?}");
    } else {
        stats.add(f64::from(result) - exact, input);
    }
}

/// QROTATE's operands: the kinds of input the error could hide in, in turn.
fn rotate_input(rng: &mut Rng, k: usize) -> (i32, i32, u32) {
    const EXTREMES: [i32; 6] = [i32::MAX, i32::MIN, -i32::MAX, i32::MIN + 1, 0, 1];
    // Just either side of every multiple of 45° (the quadrant split
    // changes at the odd ones).
    let near_axis = |rng: &mut Rng| {
        let eighth = rng.next_u32() << 29;
        let offset = rng.next_u32() >> (16 + rng.next_u32() % 16);
        if rng.next_u32() & 1 == 0 {
            eighth.wrapping_add(offset)
        } else {
            eighth.wrapping_sub(offset)
        }
    };
    match k % 8 {
        // Anything.
        0 => (rng.next_i32(), rng.next_i32(), rng.next_u32()),
        // Full-scale vectors at any angle.
        1 => (rng.pick(&EXTREMES), rng.pick(&EXTREMES), rng.next_u32()),
        // Full-scale vectors near 0/45/90/…/315°.
        2 => (rng.pick(&EXTREMES), rng.pick(&EXTREMES), near_axis(rng)),
        // Any vector near 0/45/90/…/315°.
        3 => (rng.next_i32(), rng.next_i32(), near_axis(rng)),
        // The S-curve's cosine: (r, 0), r up to full scale.
        4 => (rng.next_u32() as i32 & i32::MAX, 0, rng.next_u32()),
        // Short vectors, as motion code uses (speeds up to 2^20).
        5 => (rng.next_i32() >> 11, rng.next_i32() >> 11, rng.next_u32()),
        // Every magnitude.
        6 => (
            rng.any_magnitude() as i32 * rng.pick(&[1, -1]),
            rng.any_magnitude() as i32 * rng.pick(&[1, -1]),
            rng.next_u32(),
        ),
        // Exact multiples of 90° and tiny angles.
        _ => (
            rng.next_i32(),
            rng.next_i32(),
            rng.pick(&[
                0,
                1,
                u32::MAX,
                0x4000_0000,
                0x8000_0000,
                0xC000_0000,
                0x2000_0000,
            ]),
        ),
    }
}

#[test]
fn qrotate_error_is_at_most_half_an_lsb_plus_arithmetic() {
    let mut rng = Rng(0x0C0D_1C00_0000_0001);
    let (mut x_stats, mut y_stats) = (ErrorStats::default(), ErrorStats::default());
    for k in 0..INPUTS {
        let (x, y, angle) = rotate_input(&mut rng, k);
        let (rx, ry) = qrotate(x, y, angle);
        let (sin, cos) = radians(angle).sin_cos();
        let (fx, fy) = (f64::from(x), f64::from(y));
        let input = (i64::from(x), i64::from(y), i64::from(angle));
        add_component(&mut x_stats, rx, fx * cos - fy * sin, input);
        add_component(&mut y_stats, ry, fx * sin + fy * cos, input);
    }
    x_stats.assert_within("qrotate x", MAX_ERROR_LSB);
    y_stats.assert_within("qrotate y", MAX_ERROR_LSB);
}

#[test]
fn cos_batch_is_qrotate_over_a_million_angles() {
    let mut rng = Rng(0x0C0D_1C00_0000_0002);
    let angles: Vec<u32> = (0..INPUTS).map(|_| rng.next_u32()).collect();
    let mut cosines = std::vec![0; INPUTS];
    // Full scale, the S-curve's radii (2^30 in Smooth, sp/2 in P2Exact), negative.
    for radius in [i32::MAX, 1 << 30, 25_000, 7, -123_456_789] {
        cos_batch(radius, &angles, &mut cosines);
        for (&angle, &cosine) in angles.iter().zip(&cosines) {
            assert_eq!(cosine, qrotate(radius, 0, angle).0, "{radius} {angle:#x}");
        }
    }
}

#[test]
fn qvector_error_is_at_most_half_an_lsb_plus_arithmetic() {
    let mut rng = Rng(0x0C0D_1C00_0000_0003);
    let (mut length_stats, mut angle_stats) = (ErrorStats::default(), ErrorStats::default());
    const EXTREMES: [i32; 7] = [i32::MAX, i32::MIN, -i32::MAX, 0, 1, -1, 2];
    for k in 0..INPUTS {
        let (x, y) = match k % 4 {
            0 => (rng.next_i32(), rng.next_i32()),
            1 => (rng.pick(&EXTREMES), rng.pick(&EXTREMES)),
            // Every magnitude, so short vectors get their full angle too.
            2 => (
                rng.any_magnitude() as i32 * rng.pick(&[1, -1]),
                rng.any_magnitude() as i32 * rng.pick(&[1, -1]),
            ),
            // Nearly on an axis or a diagonal.
            _ => {
                let big = rng.next_i32();
                let small = rng.next_i32() >> (8 + rng.next_u32() % 24);
                match rng.next_u32() % 3 {
                    0 => (big, small),
                    1 => (small, big),
                    _ => (big, big.saturating_add(small)),
                }
            }
        };
        if x == 0 && y == 0 {
            assert_eq!(qvector(x, y), (0, 0));
            continue;
        }
        let (length, angle) = qvector(x, y);
        let (fx, fy) = (f64::from(x), f64::from(y));
        let input = (i64::from(x), i64::from(y), 0);
        length_stats.add(f64::from(length) - fx.hypot(fy), input);
        // Angles wrap: measure the error around the circle.
        let exact = fy.atan2(fx) / TAU * 4_294_967_296.0;
        let error = (f64::from(angle) - exact).rem_euclid(4_294_967_296.0);
        let error = if error >= 2_147_483_648.0 {
            error - 4_294_967_296.0
        } else {
            error
        };
        angle_stats.add(error, input);
    }
    length_stats.assert_within("qvector length", MAX_ERROR_LSB);
    angle_stats.assert_within("qvector angle", MAX_ERROR_LSB);
}

#[test]
fn qlog_error_is_at_most_half_an_lsb_plus_arithmetic() {
    let mut rng = Rng(0x0C0D_1C00_0000_0004);
    let mut stats = ErrorStats::default();
    for k in 0..INPUTS {
        let value = match k % 4 {
            0 => rng.next_u32(),
            1 => rng.any_magnitude().max(1),
            2 => rng.pick(&[
                1,
                2,
                3,
                255,
                256,
                257,
                u32::MAX - 31,
                1 << 31,
                (1 << 31) - 1,
            ]),
            // Just above and below powers of two.
            _ => (1u32 << (rng.next_u32() % 32))
                .wrapping_add(rng.next_u32() % 5)
                .wrapping_sub(2)
                .max(1),
        };
        let exact = f64::from(value).log2() * 134_217_728.0;
        let result = qlog(value);
        if exact >= 4_294_967_295.5 {
            assert_eq!(result, u32::MAX, "qlog({value}) must saturate");
            continue;
        }
        stats.add(f64::from(result) - exact, (i64::from(value), 0, 0));
    }
    stats.assert_within("qlog", MAX_ERROR_LSB);
}

#[test]
fn qexp_error_is_at_most_half_an_lsb_plus_arithmetic() {
    let mut rng = Rng(0x0C0D_1C00_0000_0005);
    let mut stats = ErrorStats::default();
    for k in 0..INPUTS {
        let value = match k % 3 {
            0 => rng.next_u32(),
            1 => rng.any_magnitude(),
            // Near whole numbers, where the fraction's factors are all or none.
            _ => ((rng.next_u32() % 32) << 27)
                .wrapping_add(rng.next_u32() % 9)
                .wrapping_sub(4),
        };
        let exact = (f64::from(value) / 134_217_728.0).exp2();
        stats.add(f64::from(qexp(value)) - exact, (i64::from(value), 0, 0));
    }
    stats.assert_within("qexp", MAX_ERROR_LSB);
}

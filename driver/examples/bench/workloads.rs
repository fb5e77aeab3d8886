//! The workloads the benchmark times, shared by `examples/bench` (the table
//! and JSON figures) and `benches/motion.rs` (criterion).
//!
//! The comparable move: 1,000,000 steps at 50,000 steps/s. The S-curve's
//! acceleration is set by its ramp length, `asteps = sp/10 + 2` = 5,002 steps
//! from the 40° offset to the top speed. The peer trapezoid gets the constant
//! acceleration that reaches the same top speed in the same number of steps
//! (`v² = 2·a·s` from rest): `a = sp² / (2·asteps)` ≈ 249,900 steps/s². Both
//! moves therefore spend about 1% of their steps on each ramp and the rest at
//! the top speed, as a long move does.

use std::hint::black_box;

use driver::profile::scurve::{self, Arithmetic, SCurve, ScurveConfig};
use driver::{ClockMode, Hub, HubConfig};
use fixed::types::{I32F32, U32F32};
use ramp_maker::{MotionProfile, Trapezoidal};

/// Top speed of the comparable move, steps/s.
pub const SPEED_STEPS_PER_S: u32 = 50_000;
/// Length of the comparable move, steps.
pub const MOVE_STEPS: u32 = 1_000_000;

/// The S-curve settings of the comparable move (the hub's defaults).
pub fn scurve_config(arithmetic: Arithmetic) -> ScurveConfig {
    ScurveConfig {
        arithmetic,
        ..ScurveConfig::default()
    }
}

/// Runs the comparable S-curve move; returns (steps, sum of delays in ticks).
pub fn scurve_move(arithmetic: Arithmetic, steps: u32) -> (u64, u64) {
    let curve = SCurve::new(
        scurve_config(arithmetic),
        black_box(SPEED_STEPS_PER_S),
        black_box(steps),
    )
    .expect("a valid move");
    let (mut count, mut ticks) = (0u64, 0u64);
    for step in curve {
        count += 1;
        ticks += u64::from(step.delay_ticks);
    }
    (count, black_box(ticks))
}

/// Accel steps of the comparable move (5,002).
pub fn scurve_accel_steps() -> u32 {
    scurve::plan(&ScurveConfig::default(), SPEED_STEPS_PER_S, MOVE_STEPS)
        .expect("a valid move")
        .accel_steps
}

/// The peer's acceleration, steps/s²: the same top speed reached in the same
/// number of steps as the S-curve's ramp (see the module docs).
pub fn peer_accel_steps_per_s2() -> f64 {
    let speed = f64::from(SPEED_STEPS_PER_S);
    speed * speed / (2.0 * f64::from(scurve_accel_steps()))
}

/// ramp-maker's `Trapezoidal` on its default `U32F32`, in seconds;
/// returns (delays yielded, sum of their raw bits).
pub fn ramp_maker_u32f32(steps: u32) -> (u64, u64) {
    let accel = U32F32::from_num(peer_accel_steps_per_s2());
    let mut profile = Trapezoidal::new(black_box(accel));
    profile.enter_position_mode(U32F32::from_num(SPEED_STEPS_PER_S), black_box(steps));
    let (mut count, mut sum) = (0u64, 0u64);
    while let Some(delay) = profile.next_delay() {
        count += 1;
        sum = sum.wrapping_add(delay.to_bits());
    }
    (count, black_box(sum))
}

/// ramp-maker's `Trapezoidal` on `f64`, in seconds; returns (delays
/// yielded, their sum in nanoseconds).
pub fn ramp_maker_f64(steps: u32) -> (u64, u64) {
    let mut profile = Trapezoidal::new(black_box(peer_accel_steps_per_s2()));
    profile.enter_position_mode(f64::from(SPEED_STEPS_PER_S), black_box(steps));
    let (mut count, mut seconds) = (0u64, 0.0f64);
    while let Some(delay) = profile.next_delay() {
        count += 1;
        seconds += delay;
    }
    (count, black_box((seconds * 1e9) as u64))
}

/// Moves in the short-move workload.
pub const SHORT_MOVES: usize = 1_000;

/// 1,000 seeded random moves (xorshift64): 10 to 2,000 steps at 1,000 to
/// 50,000 steps/s, as (speed, steps). Nearly all of them are all ramp.
pub fn short_moves() -> Vec<(u32, u32)> {
    let mut state = 0x9E37_79B9_7F4A_7C15_u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 32) as u32
    };
    (0..SHORT_MOVES)
        .map(|_| (1_000 + next() % 49_001, 10 + next() % 1_991))
        .collect()
}

/// Plans and runs each move on the S-curve (Smooth); returns the steps made.
pub fn scurve_short_moves(moves: &[(u32, u32)]) -> u64 {
    let config = scurve_config(Arithmetic::Smooth);
    let mut count = 0u64;
    let mut ticks = 0u64;
    for &(speed, steps) in moves {
        let curve = SCurve::new(config, black_box(speed), black_box(steps)).expect("a valid move");
        for step in curve {
            count += 1;
            ticks += u64::from(step.delay_ticks);
        }
    }
    black_box(ticks);
    count
}

/// The same moves on ramp-maker's `Trapezoidal` (U32F32), each with the
/// acceleration that reaches its speed in the S-curve's ramp length
/// (`a = sp² / (2·(sp/10 + 2))`); returns the delays yielded.
pub fn ramp_maker_short_moves(moves: &[(u32, u32)]) -> u64 {
    let mut count = 0u64;
    let mut sum = 0u64;
    for &(speed, steps) in moves {
        let sp = f64::from(speed);
        let accel = sp * sp / (2.0 * f64::from(speed / 10 + 2));
        let mut profile = Trapezoidal::new(black_box(U32F32::from_num(accel)));
        profile.enter_position_mode(U32F32::from_num(speed), black_box(steps));
        while let Some(delay) = profile.next_delay() {
            count += 1;
            sum = sum.wrapping_add(delay.to_bits());
        }
    }
    black_box(sum);
    count
}

/// The angles every cosine contender gets, in its own representation.
pub struct Angles {
    /// Binary angles (2^32 = 360°), for `qrotate`.
    pub binary: Vec<u32>,
    /// Radians in [−π, π), for the `cordic` crate.
    pub fixed: Vec<I32F32>,
    /// Radians in [−π, π), for `f64::sin_cos`.
    pub radians: Vec<f64>,
}

/// Radius of the `qrotate` cosine: full scale, so the result is 1.31 fixed point.
pub const COS_RADIUS: i32 = i32::MAX;

/// `count` angles spread over the whole turn, reproducibly (xorshift64).
pub fn angles(count: usize) -> Angles {
    let mut state = 0x2545_F491_4F6C_DD1D_u64;
    let binary: Vec<u32> = (0..count)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 32) as u32
        })
        .collect();
    let radians: Vec<f64> = binary
        .iter()
        .map(|&a| f64::from(a as i32) * std::f64::consts::TAU / 4_294_967_296.0)
        .collect();
    let fixed = radians.iter().map(|&r| I32F32::from_num(r)).collect();
    Angles {
        binary,
        fixed,
        radians,
    }
}

/// One `qrotate` cosine per angle; returns a checksum.
pub fn qrotate_cosines(binary: &[u32]) -> i64 {
    binary
        .iter()
        .map(|&a| i64::from(cordic_core::qrotate(COS_RADIUS, 0, black_box(a)).0))
        .sum()
}

/// The same cosines through `cordic_core::cos_batch` (the pipelined form).
pub fn batch_cosines(binary: &[u32], out: &mut [i32]) -> i64 {
    cordic_core::cos_batch(COS_RADIUS, black_box(binary), out);
    out.iter().map(|&c| i64::from(c)).sum()
}

/// One `cordic::sin_cos` cosine per angle; returns a checksum.
pub fn cordic_crate_cosines(fixed: &[I32F32]) -> i64 {
    fixed
        .iter()
        .map(|&a| cordic::sin_cos(black_box(a)).1.to_bits())
        .fold(0i64, i64::wrapping_add)
}

/// One `f64::sin_cos` cosine per angle; returns a checksum.
pub fn f64_cosines(radians: &[f64]) -> f64 {
    radians.iter().map(|&a| black_box(a).sin_cos().1).sum()
}

/// Pins of axis `i` on an 8-axis hub: (stop, step, dir).
pub fn axis_pins(i: u8) -> (u8, u8, u8) {
    (3 * i, 3 * i + 1, 3 * i + 2)
}

/// A hub with `axes` step/dir axes on [`axis_pins`], stop pins high, trace off.
pub fn hub_with_axes(clock: ClockMode, axes: u8) -> (Hub, Vec<driver::Axis>) {
    let hub = Hub::new(HubConfig {
        clock,
        ..HubConfig::default()
    })
    .expect("a valid hub");
    let handles = (0..axes)
        .map(|i| {
            let (stop, step, dir) = axis_pins(i);
            hub.set_input(stop, true).unwrap();
            hub.start_sd(stop, step, dir).expect("free pins")
        })
        .collect();
    (hub, handles)
}

/// Rising edges on every axis's step pin.
pub fn step_edges(hub: &Hub, axes: u8) -> u64 {
    (0..axes).map(|i| hub.rising_edges(axis_pins(i).1)).sum()
}

/// Virtual clock: 8 axes each make a `steps`-step move at the comparable
/// speed, run until idle; returns the steps made (edges counted).
pub fn hub8_virtual_move(hub: &Hub, axes: &[driver::Axis], steps: i32) -> u64 {
    let before = step_edges(hub, axes.len() as u8);
    for axis in axes {
        axis.move_steps(SPEED_STEPS_PER_S, steps)
            .expect("the axis is idle");
    }
    hub.run_until_idle();
    step_edges(hub, axes.len() as u8) - before
}

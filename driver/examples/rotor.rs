//! How long the rotor model takes to follow a long move.
//!
//! ```text
//! cargo run --release -p driver --example rotor
//! ```
//!
//! Runs a 100,000-step move of each kind below through [`driver::motor`]
//! (every edge, every substep) and prints the best of five runs, with the
//! substeps per second it comes to. The profile's own stepping is timed
//! apart and left out.

use std::hint::black_box;
use std::time::{Duration, Instant};

use driver::motor::{MotorParams, Rotor, TorquePoints};
use driver::profile::scurve::{SCurve, ScurveConfig};
use driver::profile::trapezoid::Trapezoid;

const CLKFREQ: u32 = 200_000_000;
const STEPS: u32 = 100_000;

/// A 5-phase 0.72° motor on a light load (as `motors/p2-5phase.toml`).
const FIVE_PHASE_CURVE: [(f64, f64); 8] = [
    (0.0, 0.83),
    (2_000.0, 0.78),
    (5_000.0, 0.72),
    (10_000.0, 0.62),
    (20_000.0, 0.45),
    (30_000.0, 0.32),
    (40_000.0, 0.22),
    (50_000.0, 0.15),
];

/// The lecture's type 200 on its load (as `motors/type-200.toml`).
const TYPE_200_CURVE: [(f64, f64); 8] = [
    (0.0, 0.60),
    (1_000.0, 0.58),
    (2_000.0, 0.54),
    (3_000.0, 0.49),
    (4_000.0, 0.43),
    (6_000.0, 0.33),
    (8_000.0, 0.25),
    (10_000.0, 0.19),
];

fn follow(params: MotorParams, curve: &[(f64, f64)], delays: &[u32]) -> (Duration, bool, f64) {
    let mut best = Duration::MAX;
    let mut result = (false, 0.0);
    for _ in 0..5 {
        let started = Instant::now();
        let mut rotor = Rotor::new(params, TorquePoints::new(curve));
        for &delay in delays {
            rotor.step(true);
            rotor.run_for(f64::from(delay) / f64::from(CLKFREQ));
        }
        rotor.settle();
        best = best.min(started.elapsed());
        result = black_box((rotor.lost_at_step().is_none(), rotor.error_steps()));
    }
    (best, result.0, result.1)
}

fn main() {
    let five_phase = MotorParams::new(0.72, 5, 4.8e-5, 1e-4, 0.05, 0.83).expect("motor");
    let type_200 = MotorParams::new(1.8, 2, 8.5e-5, 1e-4, 0.3, 0.60).expect("motor");
    let p2: Vec<u32> = SCurve::new(ScurveConfig::default(), 20_000, STEPS)
        .expect("plan")
        .map(|step| step.delay_ticks)
        .collect();
    let trapezoid: Vec<u32> = Trapezoid::new(CLKFREQ, 4_000.0, 20_000.0, STEPS)
        .expect("plan")
        .map(|step| step.delay_ticks)
        .collect();
    println!("move ({STEPS} steps)                         motor          time      synchronous  at rest (steps)");
    for (name, motor, params, curve, delays) in [
        (
            "p2 S-curve, 20,000 steps/s             ",
            "p2-5phase",
            five_phase,
            &FIVE_PHASE_CURVE[..],
            &p2,
        ),
        (
            "trapezoid, 4,000 steps/s, 20,000 /s²   ",
            "type-200 ",
            type_200,
            &TYPE_200_CURVE[..],
            &trapezoid,
        ),
    ] {
        let move_s = delays.iter().map(|&d| f64::from(d)).sum::<f64>() / f64::from(CLKFREQ);
        let (time, synchronous, error) = follow(params, curve, delays);
        println!(
            "{name} ({move_s:5.2} s of motion)  {motor}  {:7.1} ms  {synchronous:11}  {error:+.3}",
            time.as_secs_f64() * 1e3
        );
    }
}

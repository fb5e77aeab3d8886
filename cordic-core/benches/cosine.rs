//! Cosine speed: `qrotate` (and its batch form) against the `cordic` crate's
//! `sin_cos` on `I32F32` and against `f64::sin_cos`.
//!
//! Every contender computes the cosine of the same 16,384 random angles spread
//! over the whole turn. After criterion's report, the bench times each contender
//! once more with a plain clock and prints the ratios, so one run gives the
//! numbers side by side. `cargo bench -p cordic-core`.

use std::hint::black_box;
use std::time::{Duration, Instant};

use cordic_core::{cos_batch, qrotate};
use criterion::{Criterion, Throughput};
use fixed::types::I32F32;

/// Angles per round: more than a branch predictor can learn by heart. With
/// only ~1,000 angles repeated round after round, the predictor memorises
/// the `cordic` crate's data-dependent branches and its time drops by a third,
/// which no real caller sees (the branch-free `qrotate` gains nothing).
const COUNT: usize = 16_384;
/// Full-scale radius: `qrotate(R, 0, angle).0` is cos(angle) in 1.31 fixed point.
const RADIUS: i32 = i32::MAX;

/// The same angles in the three representations.
struct Angles {
    binary: Vec<u32>,
    fixed: Vec<I32F32>,
    radians: Vec<f64>,
}

fn angles() -> Angles {
    // xorshift64: the inputs only need to be spread out and reproducible.
    let mut state = 0x9E37_79B9_7F4A_7C15_u64;
    let binary: Vec<u32> = (0..COUNT)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 32) as u32
        })
        .collect();
    // Radians in [-pi, pi): the binary angle read as signed.
    let radians: Vec<f64> = binary
        .iter()
        .map(|&a| f64::from(a as i32) * core::f64::consts::TAU / 4_294_967_296.0)
        .collect();
    let fixed = radians.iter().map(|&r| I32F32::from_num(r)).collect();
    Angles {
        binary,
        fixed,
        radians,
    }
}

fn qrotate_cos(binary: &[u32]) -> i64 {
    binary
        .iter()
        .map(|&a| i64::from(qrotate(RADIUS, 0, black_box(a)).0))
        .sum()
}

fn cos_batch_run(binary: &[u32], out: &mut [i32]) -> i32 {
    cos_batch(RADIUS, black_box(binary), out);
    out[COUNT / 2]
}

fn cordic_cos(fixed: &[I32F32]) -> I32F32 {
    fixed
        .iter()
        .map(|&a| cordic::sin_cos(black_box(a)).1)
        .fold(I32F32::ZERO, |sum, c| sum.wrapping_add(c))
}

fn f64_cos(radians: &[f64]) -> f64 {
    radians.iter().map(|&a| black_box(a).sin_cos().1).sum()
}

fn criterion_benches(c: &mut Criterion, input: &Angles) {
    let mut out = vec![0; COUNT];
    let mut group = c.benchmark_group("cosine");
    group.throughput(Throughput::Elements(COUNT as u64));
    group.bench_function("qrotate", |b| b.iter(|| qrotate_cos(&input.binary)));
    group.bench_function("cos_batch", |b| {
        b.iter(|| cos_batch_run(&input.binary, &mut out))
    });
    group.bench_function("cordic_sin_cos_I32F32", |b| {
        b.iter(|| cordic_cos(&input.fixed))
    });
    group.bench_function("f64_sin_cos", |b| b.iter(|| f64_cos(&input.radians)));
    group.finish();
}

/// Times the contenders in turn, round after round, and keeps each one's
/// best time in nanoseconds per cosine: the machine's slow spells then hit
/// them all alike. Each turn runs the contender once untimed (so that it
/// starts warm, whoever ran before), then times two passes.
fn best_ns_per_cosine<const N: usize>(mut contenders: [&mut dyn FnMut(); N]) -> [f64; N] {
    let mut best = [f64::MAX; N];
    for _round in 0..ROUNDS {
        for (contender, best) in contenders.iter_mut().zip(&mut best) {
            contender();
            let start = Instant::now();
            contender();
            contender();
            *best = best.min(start.elapsed().as_secs_f64() * 1e9 / (2 * COUNT) as f64);
        }
    }
    best
}

/// Rounds of [`best_ns_per_cosine`].
const ROUNDS: usize = 30;

fn print_ratios(input: &Angles) {
    let mut out = vec![0; COUNT];
    let [qrotate_ns, batch_ns, cordic_ns, f64_ns] = best_ns_per_cosine([
        &mut || {
            black_box(qrotate_cos(&input.binary));
        },
        &mut || {
            black_box(cos_batch_run(&input.binary, &mut out));
        },
        &mut || {
            black_box(cordic_cos(&input.fixed));
        },
        &mut || {
            black_box(f64_cos(&input.radians));
        },
    ]);
    println!();
    println!("ns per cosine (best of {ROUNDS} interleaved rounds of 2 x {COUNT} angles):");
    println!("  qrotate            {qrotate_ns:8.2}");
    println!("  cos_batch          {batch_ns:8.2}");
    println!("  cordic I32F32      {cordic_ns:8.2}");
    println!("  f64::sin_cos       {f64_ns:8.2}");
    // The same run's accuracy, against f64, in each result's own LSB.
    let exact = |k: usize| input.radians[k].cos();
    let qrotate_error = (0..COUNT)
        .map(|k| {
            (f64::from(qrotate(RADIUS, 0, input.binary[k]).0) - f64::from(RADIUS) * exact(k)).abs()
        })
        .fold(0.0, f64::max);
    let cordic_error = (0..COUNT)
        .map(|k| {
            (cordic::sin_cos(input.fixed[k]).1.to_num::<f64>() - exact(k)).abs() * 4_294_967_296.0
        })
        .fold(0.0, f64::max);
    println!("max error over these angles:");
    println!("  qrotate (and cos_batch, bit for bit) {qrotate_error:.4} LSB of 2^-31");
    println!("  cordic I32F32                        {cordic_error:.1} LSB of 2^-32");
    println!("ratios (how many times faster):");
    println!(
        "  qrotate   vs cordic: {:6.1}x   vs f64: {:5.2}x",
        cordic_ns / qrotate_ns,
        f64_ns / qrotate_ns
    );
    println!(
        "  cos_batch vs cordic: {:6.1}x   vs f64: {:5.2}x",
        cordic_ns / batch_ns,
        f64_ns / batch_ns
    );
}

fn main() {
    let input = angles();
    let mut criterion = Criterion::default()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .sample_size(30)
        .configure_from_args();
    criterion_benches(&mut criterion, &input);
    criterion.final_summary();
    // Under `cargo test --benches` criterion runs each bench once; skip the timing.
    if !std::env::args().any(|arg| arg == "--test") {
        print_ratios(&input);
    }
}

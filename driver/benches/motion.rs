//! Criterion benches for the kernels `examples/bench` reports: the S-curve
//! (both arithmetics) and the peer trapezoid per step, on the long move and
//! the all-ramp one, the 1,000 short moves, and a hub epoch with eight
//! moving cogs. `cargo bench -p driver`; the workloads are the
//! example's own (`examples/bench/workloads.rs`).

use std::time::Duration;

use criterion::{Criterion, Throughput};
use driver::profile::scurve::Arithmetic;
use driver::ClockMode;

#[path = "../examples/bench/workloads.rs"]
#[allow(dead_code)]
mod workloads;

/// A shorter move than the example's, so that one iteration stays short.
const STEPS: u32 = 100_000;

fn profiles(c: &mut Criterion) {
    let mut group = c.benchmark_group("profile_100k_steps");
    group.throughput(Throughput::Elements(u64::from(STEPS)));
    group.bench_function("scurve_smooth", |b| {
        b.iter(|| workloads::scurve_move(Arithmetic::Smooth, STEPS))
    });
    group.bench_function("scurve_p2exact", |b| {
        b.iter(|| workloads::scurve_move(Arithmetic::P2Exact, STEPS))
    });
    group.bench_function("ramp_maker_u32f32", |b| {
        b.iter(|| workloads::ramp_maker_u32f32(STEPS))
    });
    group.bench_function("ramp_maker_f64", |b| {
        b.iter(|| workloads::ramp_maker_f64(STEPS))
    });
    group.finish();

    // All ramp: a cosine and a division per S-curve step.
    let ramp_steps = 2 * workloads::scurve_accel_steps();
    let mut group = c.benchmark_group("profile_all_ramp");
    group.throughput(Throughput::Elements(u64::from(ramp_steps)));
    group.bench_function("scurve_smooth", |b| {
        b.iter(|| workloads::scurve_move(Arithmetic::Smooth, ramp_steps))
    });
    group.bench_function("scurve_p2exact", |b| {
        b.iter(|| workloads::scurve_move(Arithmetic::P2Exact, ramp_steps))
    });
    group.bench_function("ramp_maker_u32f32", |b| {
        b.iter(|| workloads::ramp_maker_u32f32(ramp_steps))
    });
    group.finish();

    // 1,000 seeded short moves, plan + every step.
    let moves = workloads::short_moves();
    let mut group = c.benchmark_group("short_moves_1000");
    group.throughput(Throughput::Elements(moves.len() as u64));
    group.bench_function("scurve_smooth", |b| {
        b.iter(|| workloads::scurve_short_moves(&moves))
    });
    group.bench_function("ramp_maker_u32f32", |b| {
        b.iter(|| workloads::ramp_maker_short_moves(&moves))
    });
    group.finish();
}

fn hub_epoch(c: &mut Criterion) {
    let (hub, axes) = workloads::hub_with_axes(ClockMode::Virtual, 8);
    for axis in &axes {
        axis.move_steps(workloads::SPEED_STEPS_PER_S, i32::MAX)
            .expect("the axis is idle");
    }
    // Past the ramp: every epoch is 1 ms at the top speed, 8 x 50 steps.
    hub.advance(200_000_000);
    let mut group = c.benchmark_group("hub8_virtual");
    group.throughput(Throughput::Elements(8 * 50));
    group.bench_function("epoch_1ms", |b| b.iter(|| hub.advance(200_000)));
    group.throughput(Throughput::Elements(8 * 500));
    group.bench_function("epoch_10ms", |b| b.iter(|| hub.advance(2_000_000)));
    group.finish();
    hub.shutdown();
}

fn main() {
    let mut criterion = Criterion::default()
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1))
        .sample_size(20)
        .configure_from_args();
    profiles(&mut criterion);
    hub_epoch(&mut criterion);
    criterion.final_summary();
}

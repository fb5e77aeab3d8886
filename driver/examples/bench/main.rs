//! cogstep's benchmark: the S-curve against a peer trapezoid, the CORDIC
//! cosine against two peers, the hub in virtual and real time, allocations.
//!
//! ```text
//! cargo run --release -p driver --example bench            # a readable table
//! cargo run --release -p driver --example bench -- --json  # one JSON object
//! cargo run --release -p driver --example bench -- --quick # under a minute
//! ```
//!
//! Every kernel is timed several times and the fastest run is kept (the
//! least disturbed by the rest of the machine); peers run in the same
//! process, on the same inputs, so the ratios compare like with like.
//! `docs/performance.md` explains each figure.

mod alloc_count;
mod path;
mod workloads;

use std::hint::black_box;
use std::time::{Duration, Instant};

use driver::profile::scurve::{Arithmetic, SCurve};
use driver::ClockMode;

use workloads::{MOVE_STEPS, SPEED_STEPS_PER_S};

#[global_allocator]
static ALLOCATOR: alloc_count::Counting = alloc_count::Counting;

/// Step rate of each axis in the real-time run, steps/s.
const REALTIME_SPEED_STEPS_PER_S: u32 = 45_000;
/// Axes in the hub runs.
const AXES: u8 = 8;
/// Angles per cosine round.
const ANGLES: usize = 16_384;

struct Options {
    json: bool,
    quick: bool,
}

fn options() -> Result<Options, String> {
    let mut options = Options {
        json: false,
        quick: false,
    };
    for arg in std::env::args().skip(1) {
        match arg.as_str() {
            "--json" => options.json = true,
            "--quick" => options.quick = true,
            "-h" | "--help" => {
                println!("usage: bench [--json] [--quick]");
                std::process::exit(0);
            }
            other => return Err(format!("unknown argument {other:?} (try --help)")),
        }
    }
    Ok(options)
}

/// How many times each kernel runs (the fastest run counts).
struct Effort {
    profile_runs: u32,
    cosine_runs: u32,
    hub_runs: u32,
    hub_steps_per_axis: i32,
    realtime: Duration,
    /// Lines the planner alone plans.
    planner_lines: usize,
    /// Runs of each G-code and long-line contender.
    path_runs: u32,
}

impl Effort {
    fn of(quick: bool) -> Self {
        if quick {
            Effort {
                profile_runs: 5,
                cosine_runs: 30,
                hub_runs: 2,
                hub_steps_per_axis: 500_000,
                realtime: Duration::from_secs(2),
                planner_lines: 100_000,
                path_runs: 1,
            }
        } else {
            Effort {
                profile_runs: 25,
                cosine_runs: 300,
                hub_runs: 5,
                hub_steps_per_axis: 2_000_000,
                realtime: Duration::from_secs(5),
                planner_lines: 1_000_000,
                path_runs: 3,
            }
        }
    }
}

/// Runs `work` `runs` times; returns the fastest time and the last result.
fn fastest<T>(runs: u32, mut work: impl FnMut() -> T) -> (Duration, T) {
    let mut best = Duration::MAX;
    let mut result = None;
    for _ in 0..runs.max(1) {
        let start = Instant::now();
        let value = black_box(work());
        best = best.min(start.elapsed());
        result = Some(value);
    }
    (best, result.expect("at least one run"))
}

/// Runs each contender once per round, round after round, and keeps each
/// one's fastest time in ns per item (a contender returns its item count):
/// interleaved, a slow spell of the machine hits them all alike.
fn fastest_interleaved(rounds: u32, contenders: &mut [&mut dyn FnMut() -> u64]) -> Vec<f64> {
    let mut best = vec![f64::INFINITY; contenders.len()];
    for _ in 0..rounds.max(1) {
        for (contender, best) in contenders.iter_mut().zip(&mut best) {
            let start = Instant::now();
            let items = black_box(contender());
            *best = best.min(ns_per(start.elapsed(), items));
        }
    }
    best
}

fn ns_per(duration: Duration, count: u64) -> f64 {
    duration.as_secs_f64() * 1e9 / count.max(1) as f64
}

/// One figure: its JSON key, value, and how the table shows it.
struct Figure {
    key: &'static str,
    value: f64,
    what: &'static str,
}

struct Report {
    figures: Vec<Figure>,
}

impl Report {
    fn add(&mut self, key: &'static str, value: f64, what: &'static str) {
        self.figures.push(Figure { key, value, what });
    }

    fn get(&self, key: &str) -> f64 {
        self.figures
            .iter()
            .find(|f| f.key == key)
            .map_or(f64::NAN, |f| f.value)
    }

    fn json(&self) -> String {
        let fields: Vec<String> = self
            .figures
            .iter()
            .map(|f| {
                let value = if f.value.is_finite() {
                    format_number(f.value)
                } else {
                    "null".to_string()
                };
                format!("\"{}\": {}", f.key, value)
            })
            .collect();
        format!("{{{}}}", fields.join(", "))
    }

    fn table(&self) -> String {
        let width = self.figures.iter().map(|f| f.key.len()).max().unwrap_or(0);
        let mut out = String::new();
        for f in &self.figures {
            out.push_str(&format!(
                "{:<width$}  {:>14}  {}\n",
                f.key,
                format_number(f.value),
                f.what
            ));
        }
        out
    }
}

/// Whole numbers as such and from 1,000 up; two decimals from 10; four below.
fn format_number(value: f64) -> String {
    if (value == value.trunc() && value.abs() < 1e15) || value.abs() >= 1_000.0 {
        format!("{value:.0}")
    } else if value.abs() >= 10.0 {
        format!("{value:.2}")
    } else {
        format!("{value:.4}")
    }
}

fn main() {
    let options = match options() {
        Ok(options) => options,
        Err(message) => {
            eprintln!("bench: {message}");
            std::process::exit(2);
        }
    };
    let effort = Effort::of(options.quick);
    let started = Instant::now();
    let mut report = Report {
        figures: Vec::new(),
    };
    if !options.json {
        println!(
            "cogstep bench ({}): {} on {} cores",
            if options.quick { "quick" } else { "full" },
            cpu_model(),
            cores()
        );
    }

    profiles(&effort, &mut report);
    cosines(&effort, &mut report);
    hub_virtual(&effort, &mut report);
    realtime(&effort, &mut report);
    allocations(&mut report);
    paths(&effort, &mut report);

    report.add(
        "ratio_scurve_vs_ramp_maker",
        report.get("ramp_maker_u32f32_ns_per_step") / report.get("scurve_ns_per_step"),
        "ramp-maker U32F32 time / S-curve time (target >= 2)",
    );
    report.add(
        "ratio_p2exact_vs_ramp_maker",
        report.get("ramp_maker_u32f32_ns_per_step") / report.get("scurve_p2exact_ns_per_step"),
        "ramp-maker U32F32 time / P2Exact time (target >= 1)",
    );
    report.add(
        "ratio_scurve_ramp_vs_ramp_maker",
        report.get("ramp_maker_u32f32_ramp_ns_per_step") / report.get("scurve_ramp_ns_per_step"),
        "ramp-maker U32F32 time / S-curve (Smooth) time, all-ramp move (target >= 2)",
    );
    report.add(
        "ratio_p2exact_ramp_vs_ramp_maker",
        report.get("ramp_maker_u32f32_ramp_ns_per_step")
            / report.get("scurve_p2exact_ramp_ns_per_step"),
        "ramp-maker U32F32 time / P2Exact time, all-ramp move (target >= 1)",
    );
    report.add(
        "ratio_short_moves_vs_ramp_maker",
        report.get("ramp_maker_short_moves_ns_per_move") / report.get("short_moves_ns_per_move"),
        "ramp-maker U32F32 time / S-curve (Smooth) time, 1,000 short moves (target >= 2)",
    );
    report.add(
        "ratio_cos_batch_vs_f64",
        report.get("f64_sin_cos_ns") / report.get("cos_batch_ns"),
        "f64::sin_cos time / cos_batch time per cosine (target >= 2)",
    );
    report.add(
        "ratio_scurve_vs_ramp_maker_f64",
        report.get("ramp_maker_f64_ns_per_step") / report.get("scurve_ns_per_step"),
        "ramp-maker f64 time / S-curve time",
    );
    report.add(
        "ratio_qrotate_vs_cordic_crate",
        report.get("cordic_crate_i32f32_ns") / report.get("qrotate_ns"),
        "cordic crate time / qrotate time, one cosine (target >= 20)",
    );
    report.add(
        "ratio_cos_batch_vs_cordic_crate",
        report.get("cordic_crate_i32f32_ns") / report.get("cos_batch_ns"),
        "cordic crate time / cos_batch time per cosine",
    );
    report.add(
        "ratio_gcode_exact_stop_vs_blend",
        report.get("gcode_exact_stop_time_s") / report.get("gcode_blend_time_s"),
        "arc-heavy G-code: time with --exact-stop / time with blending (target >= 3)",
    );
    report.add(
        "ratio_gcode_blend_vs_trapezoid_lookahead",
        report.get("gcode_blend_time_s") / report.get("gcode_trapezoid_time_s"),
        "the same file: cogstep's time / the trapezoid look-ahead's (target <= 1.15)",
    );
    report.add(
        "ratio_path_step_vs_move_together_step",
        report.get("path_hub_cpu_ns_per_step") / report.get("move_together_cpu_ns_per_step"),
        "a path's CPU per step / move_together's, both on the same virtual hub, one 3-axis line (target <= 1)",
    );
    report.add("cores", cores() as f64, "logical CPUs of the machine");
    report.add(
        "bench_wall_s",
        started.elapsed().as_secs_f64(),
        "wall time of this benchmark run",
    );

    if options.json {
        println!("{}", report.json());
    } else {
        print!("{}", report.table());
    }
}

fn profiles(effort: &Effort, report: &mut Report) {
    // A move that never reaches the slew: all ramp, a CORDIC step each.
    let ramp_steps = 2 * workloads::scurve_accel_steps();
    let short_moves = workloads::short_moves();
    let moves = short_moves.len() as u64;
    let mut contenders: [&mut dyn FnMut() -> u64; 9] = [
        &mut || workloads::scurve_move(Arithmetic::Smooth, MOVE_STEPS).0,
        &mut || workloads::scurve_move(Arithmetic::P2Exact, MOVE_STEPS).0,
        &mut || workloads::ramp_maker_u32f32(MOVE_STEPS).0,
        &mut || workloads::ramp_maker_f64(MOVE_STEPS).0,
        &mut || workloads::scurve_move(Arithmetic::Smooth, ramp_steps).0,
        &mut || workloads::scurve_move(Arithmetic::P2Exact, ramp_steps).0,
        &mut || workloads::ramp_maker_u32f32(ramp_steps).0,
        &mut || {
            black_box(workloads::scurve_short_moves(&short_moves));
            moves
        },
        &mut || {
            black_box(workloads::ramp_maker_short_moves(&short_moves));
            moves
        },
    ];
    let ns = fastest_interleaved(effort.profile_runs, &mut contenders);
    report.add(
        "scurve_ns_per_step",
        ns[0],
        "S-curve (Smooth), 1,000,000 steps at 50,000 steps/s, per step",
    );
    report.add(
        "scurve_p2exact_ns_per_step",
        ns[1],
        "the same move in P2Exact arithmetic",
    );
    report.add(
        "ramp_maker_u32f32_ns_per_step",
        ns[2],
        "ramp-maker 0.2 Trapezoidal<U32F32>, same move",
    );
    report.add(
        "ramp_maker_f64_ns_per_step",
        ns[3],
        "ramp-maker 0.2 Trapezoidal<f64>, same move",
    );
    report.add(
        "scurve_ramp_ns_per_step",
        ns[4],
        "S-curve (Smooth), a 10,004-step move: all ramp: a cosine and a division per step",
    );
    report.add(
        "scurve_p2exact_ramp_ns_per_step",
        ns[5],
        "the same all-ramp move in P2Exact arithmetic",
    );
    report.add(
        "ramp_maker_u32f32_ramp_ns_per_step",
        ns[6],
        "ramp-maker U32F32, the same all-ramp move",
    );
    report.add(
        "short_moves_ns_per_move",
        ns[7],
        "S-curve (Smooth), 1,000 seeded moves of 10-2,000 steps at 1,000-50,000 steps/s: plan + every step, per move",
    );
    report.add(
        "ramp_maker_short_moves_ns_per_move",
        ns[8],
        "ramp-maker U32F32 on the same moves (same top speed, same ramp length), per move",
    );
    report.add(
        "peer_accel_steps_per_s2",
        workloads::peer_accel_steps_per_s2(),
        "the peer's acceleration: same top speed in the same ramp steps",
    );
}

/// Continuous motion: the planner alone, the G-code file three ways, the
/// path runner's cost per step against `move_together`'s.
fn paths(effort: &Effort, report: &mut Report) {
    let (machine, items) = path::program();
    let (time, lines) = fastest(effort.path_runs, || {
        path::plan_only(machine, &items, effort.planner_lines)
    });
    report.add(
        "planner_segments_per_s",
        lines as f64 / time.as_secs_f64(),
        "planner alone (queue of 32, 3 axes), the arc file's short segments: lines planned per second (target >= 1,000,000)",
    );
    let mut blend = (0.0, 0u64);
    let (blend_wall, _) = fastest(effort.path_runs, || {
        blend = path::run_path(machine, &items, false);
    });
    let (exact_stop, _) = path::run_path(machine, &items, true);
    let trapezoid = path::run_trapezoid(machine, &items);
    report.add(
        "gcode_blend_time_s",
        blend.0,
        "arcs-short-segments.gcode on xyz-cnc.toml, blending: machine time (s)",
    );
    report.add(
        "gcode_exact_stop_time_s",
        exact_stop,
        "the same with a stop at every line's end (s)",
    );
    report.add(
        "gcode_trapezoid_time_s",
        trapezoid.total_time_s,
        "the same lines on the trapezoid look-ahead (same junction limits, constant acceleration) (s)",
    );
    report.add(
        "gcode_trapezoid_accel_jumps",
        trapezoid.accel_jumps as f64,
        "points where the trapezoid's path acceleration jumps (cogstep's: 0)",
    );
    report.add(
        "gcode_path_ns_per_step",
        ns_per(blend_wall, blend.1),
        "the blending run on the path runner: wall time per step edge, planning included",
    );
    let (hub, axes) = path::hub_for_long_line();
    let mut hub_cpu_ns = f64::INFINITY;
    let mut hub_path_cpu_ns = f64::INFINITY;
    let mut path_cpu_ns = f64::INFINITY;
    let per_step = |run: &mut dyn FnMut() -> u64| {
        let cpu = cpu_seconds();
        let steps = run();
        (cpu_seconds() - cpu) * 1e9 / steps as f64
    };
    for _ in 0..effort.path_runs.max(2) {
        hub_cpu_ns = hub_cpu_ns.min(per_step(&mut || path::hub_long_line(&hub, &axes)));
        hub_path_cpu_ns =
            hub_path_cpu_ns.min(per_step(&mut || path::hub_path_long_line(&hub, &axes)));
        path_cpu_ns = path_cpu_ns.min(per_step(&mut path::path_long_line));
    }
    hub.shutdown();
    report.add(
        "move_together_cpu_ns_per_step",
        hub_cpu_ns,
        "move_together of (400,000, -240,000, 100,000) steps at 50,000 steps/s on a virtual hub: CPU per step, all threads",
    );
    report.add(
        "path_hub_cpu_ns_per_step",
        hub_path_cpu_ns,
        "the same line on a look-ahead path of the same hub (Hub::path): CPU per step, all threads",
    );
    report.add(
        "path_ns_per_step",
        path_cpu_ns,
        "the same line on the path runner alone (one thread, no hub): CPU per step edge",
    );
}

fn cosines(effort: &Effort, report: &mut Report) {
    let angles = workloads::angles(ANGLES);
    let count = ANGLES as u64;
    let mut out = vec![0i32; ANGLES];
    let mut contenders: [&mut dyn FnMut() -> u64; 4] = [
        &mut || {
            black_box(workloads::qrotate_cosines(&angles.binary));
            count
        },
        &mut || {
            black_box(workloads::batch_cosines(&angles.binary, &mut out));
            count
        },
        &mut || {
            black_box(workloads::cordic_crate_cosines(&angles.fixed));
            count
        },
        &mut || {
            black_box(workloads::f64_cosines(&angles.radians));
            count
        },
    ];
    let ns = fastest_interleaved(effort.cosine_runs, &mut contenders);
    report.add(
        "qrotate_ns",
        ns[0],
        "qrotate(2^31-1, 0, angle).0, one cosine",
    );
    report.add(
        "cos_batch_ns",
        ns[1],
        "cordic_core::cos_batch, per cosine (the pipelined form)",
    );
    report.add(
        "cordic_crate_i32f32_ns",
        ns[2],
        "cordic 0.1 sin_cos on I32F32, one cosine",
    );
    report.add("f64_sin_cos_ns", ns[3], "f64::sin_cos, one cosine");

    // Accuracy against f64, each in its own LSB.
    let radius = f64::from(workloads::COS_RADIUS);
    let mut qrotate_error = 0.0f64;
    let mut cordic_error = 0.0f64;
    for ((&binary, &fixed), &radians) in
        angles.binary.iter().zip(&angles.fixed).zip(&angles.radians)
    {
        let exact = radians.cos();
        let q = f64::from(cordic_core::qrotate(workloads::COS_RADIUS, 0, binary).0);
        qrotate_error = qrotate_error.max((q - radius * exact).abs());
        let c: f64 = cordic::sin_cos(fixed).1.to_num();
        cordic_error = cordic_error.max((c - exact).abs() * 4_294_967_296.0);
    }
    report.add(
        "qrotate_max_error_lsb",
        qrotate_error,
        "qrotate's largest error over those angles, LSB of the 2^31-1 radius",
    );
    report.add(
        "cordic_crate_max_error_lsb",
        cordic_error,
        "the cordic crate's largest error, LSB of I32F32 (2^-32)",
    );
}

fn hub_virtual(effort: &Effort, report: &mut Report) {
    let (hub, axes) = workloads::hub_with_axes(ClockMode::Virtual, AXES);
    let mut cpu_ns_per_step = f64::INFINITY;
    let (time, steps) = fastest(effort.hub_runs, || {
        let cpu = cpu_seconds();
        let steps = workloads::hub8_virtual_move(&hub, &axes, effort.hub_steps_per_axis);
        cpu_ns_per_step = cpu_ns_per_step.min((cpu_seconds() - cpu) * 1e9 / steps as f64);
        steps
    });
    let rate = steps as f64 / time.as_secs_f64();
    report.add(
        "hub8_virtual_steps_per_s",
        rate,
        "8 cogs, virtual clock, all moving at 50,000 steps/s: steps per wall second",
    );
    report.add(
        "hub8_realtime_factor",
        rate / (f64::from(AXES) * f64::from(SPEED_STEPS_PER_S)),
        "that rate / (8 x 50,000 steps/s) (target >= 1,000)",
    );
    report.add(
        "hub8_cpu_ns_per_step",
        cpu_ns_per_step,
        "CPU time per step in that run, all threads (wall rate <= cores / this)",
    );
    hub.shutdown();
}

/// Real clock: 8 axes at 45,000 steps/s; a sampler compares each mailbox
/// position with the schedule the profile sets.
fn realtime(effort: &Effort, report: &mut Report) {
    let (hub, axes) = workloads::hub_with_axes(ClockMode::Real, AXES);
    let clkfreq = u64::from(hub.config().clkfreq);
    let window = effort.realtime;
    // Long enough to outlast the window; stopped at its end.
    let steps = REALTIME_SPEED_STEPS_PER_S * (window.as_secs() as u32 + 2);
    let schedule: Vec<u64> = SCurve::new(hub.config().scurve(), REALTIME_SPEED_STEPS_PER_S, steps)
        .expect("a valid move")
        .scan(0u64, |ct, step| {
            let at = *ct;
            *ct += u64::from(step.delay_ticks);
            Some(at)
        })
        .collect();
    for axis in &axes {
        axis.move_steps(REALTIME_SPEED_STEPS_PER_S, steps as i32)
            .expect("the axis is idle");
    }
    // `Ok` came with the cog's answer: the move and its start CT are set.
    let starts: Vec<u64> = axes.iter().map(|a| a.move_start_ct()).collect();
    let cpu_before = cpu_seconds();
    let wall_before = Instant::now();
    let fifo_cogs = threads_with_policy("cog", SCHED_FIFO);
    let mut lags_ticks = Vec::with_capacity(window.as_millis() as usize * usize::from(AXES));
    while wall_before.elapsed() < window {
        std::thread::sleep(Duration::from_millis(1));
        for (axis, &start) in axes.iter().zip(&starts) {
            // Position first, then the clock: a late read can only overstate the lag.
            let position = usize::try_from(axis.position()).unwrap_or(0);
            let now = hub.now();
            if let Some(&due) = schedule.get(position) {
                lags_ticks.push(now.saturating_sub(start + due));
            }
        }
    }
    let cpu = cpu_seconds() - cpu_before;
    let wall = wall_before.elapsed().as_secs_f64();
    hub.emergency_stop();
    hub.shutdown();
    lags_ticks.sort_unstable();
    let p99 = percentile(&lags_ticks, 0.99) as f64 * 1e6 / clkfreq as f64;
    let p999 = percentile(&lags_ticks, 0.999) as f64 * 1e6 / clkfreq as f64;
    let max = lags_ticks.last().copied().unwrap_or(0) as f64 * 1e6 / clkfreq as f64;
    report.add(
        "realtime_lag_p99_us",
        p99,
        "real clock, 8 axes x 45,000 steps/s: mailbox position behind schedule, p99 (target <= 1,000)",
    );
    report.add(
        "realtime_lag_p999_us",
        p999,
        "the same, p99.9 (target <= 1,000)",
    );
    report.add(
        "realtime_lag_max_us",
        max,
        "the same, the worst sample (the scheduler: see docs/performance.md)",
    );
    report.add(
        "realtime_cogs_fifo",
        fifo_cogs as f64,
        "cog threads that got SCHED_FIFO (0 where the process may not: the lag is then the scheduler's)",
    );
    report.add(
        "realtime_cpu_percent",
        100.0 * cpu / wall,
        "process CPU time / wall time in that run, % of one core (target <= 50)",
    );
}

fn percentile(sorted: &[u64], fraction: f64) -> u64 {
    if sorted.is_empty() {
        return 0;
    }
    let index = ((sorted.len() - 1) as f64 * fraction).round() as usize;
    sorted[index.min(sorted.len() - 1)]
}

/// Allocations per step: in a running cog (8 axes, virtual clock, trace
/// off, 1 ms epochs) and in the S-curve iterator alone.
fn allocations(report: &mut Report) {
    let (hub, axes) = workloads::hub_with_axes(ClockMode::Virtual, AXES);
    for axis in &axes {
        axis.move_steps(SPEED_STEPS_PER_S, 1_000_000)
            .expect("the axis is idle");
    }
    // Warm up: thread-locals, the first epoch.
    hub.advance(2_000_000);
    let edges_before = workloads::step_edges(&hub, AXES);
    let allocations_before = alloc_count::allocations();
    for _ in 0..200 {
        hub.advance(200_000);
    }
    let allocations = alloc_count::allocations() - allocations_before;
    let steps = workloads::step_edges(&hub, AXES) - edges_before;
    hub.shutdown();
    report.add(
        "allocations_per_step",
        allocations as f64 / steps.max(1) as f64,
        "heap allocations per step, 8 running cogs, 200 epochs of 1 ms (target 0)",
    );

    let before = alloc_count::allocations();
    let (steps, _) = workloads::scurve_move(Arithmetic::Smooth, MOVE_STEPS);
    let allocations = alloc_count::allocations() - before;
    report.add(
        "scurve_allocations_per_step",
        allocations as f64 / steps.max(1) as f64,
        "heap allocations per step of the S-curve iterator",
    );
}

/// User + system CPU time of this process, seconds (Linux `/proc`, in
/// USER_HZ = 100 ticks); NaN elsewhere.
/// Linux's number for the `SCHED_FIFO` policy.
const SCHED_FIFO: u32 = 1;

/// How many of the process's threads whose name starts with `prefix` run
/// under scheduling `policy` (field 41 of `/proc/self/task/*/stat`).
fn threads_with_policy(prefix: &str, policy: u32) -> usize {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return 0;
    };
    tasks
        .filter_map(|task| task.ok())
        .filter_map(|task| std::fs::read_to_string(task.path().join("stat")).ok())
        .filter(|stat| {
            let Some((head, rest)) = stat.rsplit_once(')') else {
                return false;
            };
            let named = head
                .split_once('(')
                .is_some_and(|(_, name)| name.starts_with(prefix));
            // Fields from the third (the state) on follow the name: policy is the 41st.
            named
                && rest
                    .split_whitespace()
                    .nth(38)
                    .and_then(|p| p.parse::<u32>().ok())
                    == Some(policy)
        })
        .count()
}

fn cpu_seconds() -> f64 {
    // Every live thread's time on a CPU, in nanoseconds (the first field of
    // its schedstat): /proc/self/stat counts in 10 ms ticks, too coarse for
    // a hub run of a few milliseconds.
    let threads_ns = std::fs::read_dir("/proc/self/task").ok().map(|tasks| {
        tasks
            .filter_map(|task| task.ok())
            .filter_map(|task| std::fs::read_to_string(task.path().join("schedstat")).ok())
            .filter_map(|stat| stat.split_whitespace().next()?.parse::<u64>().ok())
            .sum::<u64>()
    });
    if let Some(ns) = threads_ns.filter(|ns| *ns > 0) {
        return ns as f64 * 1e-9;
    }
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // Fields after the command name (which is in parentheses and may hold spaces).
    let Some(rest) = stat.rsplit_once(')').map(|(_, rest)| rest) else {
        return f64::NAN;
    };
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the line, 12 and 13 after ')'.
    let ticks: f64 = fields
        .get(11..13)
        .map(|f| f.iter().filter_map(|v| v.parse::<f64>().ok()).sum())
        .unwrap_or(f64::NAN);
    ticks / 100.0
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find(|line| line.starts_with("model name"))
                .and_then(|line| line.split_once(':'))
                .map(|(_, model)| model.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".to_string())
}

fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

//! The continuous-motion workloads (issue 25): the planner alone on short
//! segments, a G-code file of arcs in short segments run with blending,
//! with exact stop and on the trapezoid look-ahead, and the path runner's
//! cost per step against `move_together`'s.
//!
//! The G-code file and the machine are the export's shipped ones
//! (`spreadsheet-export/examples/arcs-short-segments.gcode`,
//! `spreadsheet-export/machines/xyz-cnc.toml`), read at compile time.

use std::hint::black_box;

use cogstep_gcode::{Block, Interpreter, MachineSpec};
use cogstep_motion::planner::{Blending, Line, Machine, PathRunner, Planner};
use driver::profile::lookahead::{LookaheadSummary, TrapezoidLookahead};
use driver::{ClockMode, Hub};

/// The arc-heavy program of short segments.
pub const ARC_PROGRAM: &str =
    include_str!("../../../spreadsheet-export/examples/arcs-short-segments.gcode");
/// The 3-axis machine it runs on.
pub const MACHINE: &str = include_str!("../../../spreadsheet-export/machines/xyz-cnc.toml");

/// Axes of the machine.
pub const AXES: usize = 3;
/// The queue length (the machine file's `queue_len`).
pub const QUEUE: usize = 32;
/// The CT clock of the runs (the P2's).
pub const CLKFREQ: u32 = 200_000_000;

/// What a program asks of the planner, in order.
#[derive(Clone, Copy, Debug)]
pub enum Item {
    /// A line.
    Line(Line<AXES>),
    /// A dwell (s) or a pause (0 s).
    Dwell(f64),
    /// G61 or G64.
    Blending(Blending),
}

/// The machine and the program as planner items.
pub fn program() -> (Machine<AXES>, Vec<Item>) {
    let spec = MachineSpec::from_toml_str(MACHINE).expect("the shipped machine file");
    let mut interpreter = Interpreter::new(&spec);
    let mut items = Vec::new();
    for (index, text) in ARC_PROGRAM.lines().enumerate() {
        interpreter
            .interpret_line(index as u32 + 1, text, &mut |block| match block {
                Block::Line { .. } => {
                    if let Some(line) = block.to_planner_line::<AXES>() {
                        items.push(Item::Line(line));
                    }
                }
                Block::Dwell { seconds, .. } => items.push(Item::Dwell(seconds)),
                Block::Pause { .. } | Block::Home { .. } => items.push(Item::Dwell(0.0)),
                Block::Blending { mode, .. } => items.push(Item::Blending(mode)),
                Block::End { .. } => {}
            })
            .expect("the shipped program has no errors");
    }
    (spec.planner_machine::<AXES>(), items)
}

/// The planner alone: `count` lines of the program (over and over),
/// pushed into a queue of [`QUEUE`] that runs (freezes and pops) its
/// front when full. Returns the lines pushed.
pub fn plan_only(machine: Machine<AXES>, items: &[Item], count: usize) -> u64 {
    let lines: Vec<Line<AXES>> = items
        .iter()
        .filter_map(|item| match item {
            Item::Line(line) => Some(*line),
            _ => None,
        })
        .collect();
    let mut planner = Planner::<QUEUE, AXES>::new(machine).expect("a valid machine");
    let mut pushed = 0u64;
    // Forwards then backwards, so that the path is continuous.
    let mut forward = true;
    while (pushed as usize) < count {
        for i in 0..lines.len() {
            let mut line = if forward {
                lines[i]
            } else {
                lines[lines.len() - 1 - i]
            };
            if !forward {
                for steps in &mut line.steps {
                    *steps = -*steps;
                }
            }
            if planner.is_full() {
                planner.freeze_front(1);
                black_box(planner.pop_front());
            }
            planner.push(black_box(line)).expect("a valid line");
            if std::env::var("DBG").is_ok() {
                eprintln!("len {} settled {}", planner.len(), planner.settled());
            }
            pushed += 1;
            if pushed as usize >= count {
                break;
            }
        }
        forward = !forward;
    }
    pushed
}

/// A run of the program on the path runner: (total time s, edges).
pub fn run_path(machine: Machine<AXES>, items: &[Item], exact_stop: bool) -> (f64, u64) {
    let mut machine = machine;
    if exact_stop {
        machine.blending = Blending::ExactStop;
    }
    let mut runner =
        PathRunner::<QUEUE, AXES>::new(machine, [0; AXES], 0, CLKFREQ).expect("a valid machine");
    let mut edges = 0u64;
    for (tag, item) in items.iter().enumerate() {
        match *item {
            Item::Line(line) => {
                while runner.queued() >= QUEUE {
                    if runner.next_edge_until(u64::MAX).is_none() {
                        break;
                    }
                    edges += 1;
                }
                runner.push(line, tag as u32).expect("a valid line");
            }
            Item::Dwell(seconds) => runner.push_dwell(seconds).expect("a valid dwell"),
            Item::Blending(mode) => {
                if !exact_stop {
                    runner.set_blending(mode);
                }
            }
        }
    }
    let end = runner.end_ct();
    while runner.next_edge_until(u64::MAX).is_some() {
        edges += 1;
    }
    (end as f64 / f64::from(CLKFREQ), edges)
}

/// The program on the trapezoid look-ahead.
pub fn run_trapezoid(machine: Machine<AXES>, items: &[Item]) -> LookaheadSummary {
    let mut lookahead = TrapezoidLookahead::<QUEUE, AXES>::new(machine).expect("a valid machine");
    for item in items {
        match *item {
            Item::Line(line) => lookahead.push(line).expect("a valid line"),
            Item::Dwell(seconds) => lookahead.push_dwell(seconds),
            Item::Blending(mode) => lookahead.set_blending(mode),
        }
    }
    lookahead.finish()
}

/// One long straight 3-axis line at a lead speed of 50,000 steps/s.
pub const LONG_LINE: [i32; AXES] = [400_000, -240_000, 100_000];
/// Its lead speed.
pub const LONG_LINE_SPEED: u32 = 50_000;

/// The long line on the path runner; returns the edges.
pub fn path_long_line() -> u64 {
    let machine = Machine {
        max_speed_steps_per_s: [1e6; AXES],
        // The S-curve's acceleration at 50,000 steps/s (5,002 ramp steps).
        max_accel_steps_per_s2: [250_000.0; AXES],
        junction_deviation_steps: 1.0,
        blending: Blending::Blend,
    };
    let mut runner =
        PathRunner::<QUEUE, AXES>::new(machine, [0; AXES], 0, CLKFREQ).expect("a valid machine");
    runner
        .push(
            Line {
                steps: LONG_LINE,
                feed_steps_per_s: f64::from(LONG_LINE_SPEED),
            },
            0,
        )
        .expect("a valid line");
    let mut edges = 0;
    while let Some(edge) = runner.next_edge_until(u64::MAX) {
        black_box(edge);
        edges += 1;
    }
    edges
}

/// The same line as a `move_together` on a virtual hub's three axes; returns
/// the steps made.
pub fn hub_long_line(hub: &Hub, axes: &[driver::Axis]) -> u64 {
    let before = super::workloads::step_edges(hub, AXES as u8);
    let group: Vec<(&driver::Axis, i32)> = axes.iter().zip(LONG_LINE).collect();
    hub.move_together(&group, LONG_LINE_SPEED)
        .expect("the axes are idle");
    hub.run_until_idle();
    super::workloads::step_edges(hub, AXES as u8) - before
}

/// The same line on a look-ahead path of the same virtual hub's three
/// axes (`Hub::path`: the runner, the feeds, the cores); returns the
/// steps made.
pub fn hub_path_long_line(hub: &Hub, axes: &[driver::Axis]) -> u64 {
    let before = super::workloads::step_edges(hub, AXES as u8);
    let refs: Vec<&driver::Axis> = axes.iter().collect();
    let job = hub
        .path(
            &refs,
            driver::PathMachine {
                max_speed_steps_per_s: vec![1e6; AXES],
                max_accel_steps_per_s2: vec![250_000.0; AXES],
                junction_deviation_steps: 1.0,
                blending: Blending::Blend,
            },
        )
        .expect("the axes are idle");
    job.push(&LONG_LINE, f64::from(LONG_LINE_SPEED), 0)
        .expect("a valid line");
    job.finish().expect("the line runs");
    super::workloads::step_edges(hub, AXES as u8) - before
}

/// A virtual hub with the three axes of [`hub_long_line`].
pub fn hub_for_long_line() -> (Hub, Vec<driver::Axis>) {
    super::workloads::hub_with_axes(ClockMode::Virtual, AXES as u8)
}

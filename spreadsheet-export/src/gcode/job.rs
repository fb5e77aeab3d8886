//! A G-code program's blocks through the path runner, in virtual time:
//! blocks in, step edges and table rows out, and what they measure.
//!
//! ```text
//! Block ─► Job::block ─► PathRunner::push (the queue, look-ahead)
//!       ─► next_edge_timed ─► Sink::edge (VCD) ─► a row per tick ─► Sink::row (table, plot)
//! ```
//!
//! The runner's CT is the P2 system counter (`clkfreq` ticks per second,
//! 200 MHz by default): an edge's CT is its exact time rounded down to a
//! tick, and the edges of one tick share a row. Lines are pushed until the
//! machine file's queue length is reached, then stepped until one line is
//! done, so the look-ahead sees as far ahead as the machine's would and
//! memory stays bounded whatever the program's length.
//!
//! Every planner line is tagged with its own sequence number, which finds
//! its G-code line, its programmed piece of path ([`super::geometry`]) and
//! its mm per step of path.

use std::collections::VecDeque;

use cogstep_gcode::{Block, MachineSpec};
use cogstep_motion::planner::{Blending, Line, PathEdge, PathRunner, MAX_AXES};

use super::geometry::{Circle, Piece};
use crate::error::ExportError;

/// The most lines the runner queues (the machine file's `queue_len` is
/// held to it).
pub const QUEUE_CAPACITY: usize = 64;

/// The runner the export drives: up to 8 axes, the unused ones never move.
pub type Runner = PathRunner<QUEUE_CAPACITY, MAX_AXES>;

/// One row of the table: every axis's position after the edges of one tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// The tick (CT since the program's start).
    pub ct: u64,
    /// The same in seconds.
    pub time_s: f64,
    /// The G-code line of the tick's last edge.
    pub line: u32,
    /// Every axis's position (steps), in the machine file's order.
    pub positions: [i64; MAX_AXES],
    /// Every axis's position (mm).
    pub positions_mm: [f64; MAX_AXES],
    /// The speed along the path (mm/s) at the tick.
    pub feed_mm_s: f64,
    /// The distance (mm) of the position from the programmed path.
    pub deviation_mm: f64,
}

/// Where the edges and rows go.
pub trait Sink {
    /// A step edge, as the runner makes it.
    fn edge(&mut self, _edge: &PathEdge) -> Result<(), ExportError> {
        Ok(())
    }
    /// A row, once every edge of its tick is known.
    fn row(&mut self, row: &Row) -> Result<(), ExportError>;
}

/// What a run measured.
#[derive(Clone, Debug, PartialEq)]
pub struct JobSummary {
    /// Rows (ticks with an edge).
    pub rows: u64,
    /// Step edges.
    pub edges: u64,
    /// When the path came to rest at the end (s).
    pub total_time_s: f64,
    /// The largest distance of the stepped position from the programmed
    /// path (mm), and the G-code line it was on.
    pub max_deviation_mm: f64,
    /// The line of the largest deviation.
    pub max_deviation_line: u32,
    /// Per axis: the largest acceleration (mm/s²) measured from three
    /// consecutive edges within one planner line.
    pub peak_accel_mm_s2: Vec<f64>,
    /// Per axis: the largest velocity change (mm/s) measured across a
    /// junction (the corner's kink; 0 on a straight or smooth path).
    pub peak_corner_jump_mm_s: Vec<f64>,
    /// Every axis's position at the end (steps).
    pub end_steps: Vec<i64>,
    /// The axis letters, in order.
    pub letters: Vec<char>,
}

impl JobSummary {
    /// The summary line for stderr.
    pub fn line(&self) -> String {
        let per_axis = |values: &[f64], decimals: usize| {
            self.letters
                .iter()
                .zip(values)
                .map(|(letter, value)| format!("{letter}:{value:.decimals$}"))
                .collect::<Vec<_>>()
                .join(",")
        };
        format!(
            "total_time_s={:.6} max_deviation_mm={:.6} peak_accel_mm_s2={} corner_jump_mm_s={} rows={} edges={}",
            self.total_time_s,
            self.max_deviation_mm,
            per_axis(&self.peak_accel_mm_s2, 1),
            per_axis(&self.peak_corner_jump_mm_s, 3),
            self.rows,
            self.edges,
        )
    }
}

/// A pushed line's G-code line, programmed piece and scale.
#[derive(Clone, Copy, Debug)]
struct Chord {
    line: u32,
    piece: Piece,
    /// mm of path per step of path (step space).
    mm_per_path_step: f64,
}

/// The row being gathered: its tick's edges so far.
#[derive(Clone, Copy, Debug)]
struct PendingRow {
    ct: u64,
    line: u32,
    first_tag: u32,
    last_tag: u32,
    path_steps_per_s: f64,
}

/// One axis's acceleration from its edges.
#[derive(Clone, Copy, Debug, Default)]
struct AxisMeasure {
    /// The last edge: exact time (s) and tag.
    last_edge: Option<(f64, u32)>,
    /// The velocity between the last two edges: (mid time, steps/s, tag of
    /// the earlier edge).
    last_velocity: Option<(f64, f64, u32)>,
    peak_accel_steps_per_s2: f64,
    peak_jump_steps_per_s: f64,
}

impl AxisMeasure {
    fn edge(&mut self, time_s: f64, forward: bool, tag: u32) {
        if let Some((before_s, before_tag)) = self.last_edge {
            let interval = time_s - before_s;
            if interval > 0.0 {
                let sign = if forward { 1.0 } else { -1.0 };
                let velocity = sign / interval;
                let middle = (time_s + before_s) / 2.0;
                if let Some((middle_before, velocity_before, first_tag)) = self.last_velocity {
                    if first_tag == before_tag && before_tag == tag {
                        let accel = (velocity - velocity_before) / (middle - middle_before);
                        self.peak_accel_steps_per_s2 =
                            self.peak_accel_steps_per_s2.max(accel.abs());
                    } else {
                        self.peak_jump_steps_per_s = self
                            .peak_jump_steps_per_s
                            .max((velocity - velocity_before).abs());
                    }
                }
                self.last_velocity = Some((middle, velocity, before_tag));
            }
        }
        self.last_edge = Some((time_s, tag));
    }
}

/// A program being run.
pub struct Job {
    runner: Box<Runner>,
    axes: usize,
    letters: Vec<char>,
    steps_per_mm: [f64; MAX_AXES],
    /// The indices of X and Y, for arcs' circles.
    xy: Option<[usize; 2]>,
    queue_len: usize,
    exact_stop: bool,
    hz: f64,
    chords: VecDeque<Chord>,
    /// The tag of `chords[0]`.
    first_tag: u32,
    next_tag: u32,
    /// The programmed position after the last pushed line (mm).
    programmed_mm: [f64; MAX_AXES],
    pending: Option<PendingRow>,
    measures: [AxisMeasure; MAX_AXES],
    rows: u64,
    edges: u64,
    max_deviation: (f64, u32),
}

impl Job {
    /// A job for `spec` at machine position 0, its CT at `clkfreq` Hz;
    /// `exact_stop` stops at every line's end whatever the program says.
    pub fn new(spec: &MachineSpec, clkfreq: u32, exact_stop: bool) -> Result<Job, ExportError> {
        let mut machine = spec.planner_machine::<MAX_AXES>();
        if exact_stop {
            machine.blending = Blending::ExactStop;
        }
        let runner = Runner::new(machine, [0; MAX_AXES], 0, clkfreq)
            .map_err(|error| ExportError::GcodeRun(error.to_string()))?;
        let mut steps_per_mm = [1.0; MAX_AXES];
        for (own, axis) in steps_per_mm.iter_mut().zip(spec.axes()) {
            *own = axis.steps_per_mm;
        }
        let xy = match (spec.axis_index('x'), spec.axis_index('y')) {
            (Some(x), Some(y)) => Some([x, y]),
            _ => None,
        };
        Ok(Job {
            runner: Box::new(runner),
            axes: spec.axis_count(),
            letters: spec.letters().to_vec(),
            steps_per_mm,
            xy,
            queue_len: spec.planner().queue_len.clamp(1, QUEUE_CAPACITY),
            exact_stop,
            hz: f64::from(clkfreq.max(1)),
            chords: VecDeque::new(),
            first_tag: 0,
            next_tag: 0,
            programmed_mm: [0.0; MAX_AXES],
            pending: None,
            measures: [AxisMeasure::default(); MAX_AXES],
            rows: 0,
            edges: 0,
            max_deviation: (0.0, 0),
        })
    }

    /// The runner (positions, targets, state).
    pub fn runner(&self) -> &Runner {
        &self.runner
    }

    /// Takes one block. `end_mm` is the programmed position after it (mm,
    /// machine coordinates), `circle` the arc it is a chord of. Returns
    /// whether the program ended (M2, M30).
    pub fn block(
        &mut self,
        block: &Block,
        end_mm: [f64; MAX_AXES],
        circle: Option<Circle>,
        sink: &mut impl Sink,
    ) -> Result<bool, ExportError> {
        match *block {
            Block::Line {
                line,
                steps,
                length_mm,
                ..
            } => {
                if let Some(planner_line) = block.to_planner_line::<MAX_AXES>() {
                    let path_steps = steps
                        .iter()
                        .map(|&s| f64::from(s) * f64::from(s))
                        .sum::<f64>()
                        .sqrt();
                    self.push(
                        planner_line,
                        line,
                        end_mm,
                        circle,
                        length_mm / path_steps,
                        sink,
                    )?;
                } else {
                    self.programmed_mm = end_mm;
                }
            }
            Block::Dwell { seconds, .. } => self.dwell(seconds)?,
            Block::Pause { .. } => self.dwell(0.0)?,
            Block::Blending { mode, .. } => {
                if !self.exact_stop {
                    self.runner.set_blending(mode);
                }
            }
            Block::Home { line, .. } => {
                // No switches in virtual time: a rapid to the home
                // position, from rest and to rest.
                let mut steps = [0i32; MAX_AXES];
                let targets = self.runner.targets();
                for axis in 0..self.axes {
                    let home = (end_mm[axis] * self.steps_per_mm[axis]).round() as i64;
                    steps[axis] = i32::try_from(home - targets[axis]).map_err(|_| {
                        ExportError::GcodeRun(format!("line {line}: homing moves too far"))
                    })?;
                }
                self.dwell(0.0)?;
                if steps.iter().any(|&s| s != 0) {
                    let mm: f64 = (0..self.axes)
                        .map(|axis| {
                            let d = f64::from(steps[axis]) / self.steps_per_mm[axis];
                            d * d
                        })
                        .sum::<f64>()
                        .sqrt();
                    let path_steps = steps
                        .iter()
                        .map(|&s| f64::from(s) * f64::from(s))
                        .sum::<f64>()
                        .sqrt();
                    let rapid = Line {
                        steps,
                        feed_steps_per_s: f64::INFINITY,
                    };
                    self.push(rapid, line, end_mm, None, mm / path_steps, sink)?;
                }
                self.dwell(0.0)?;
            }
            Block::End { .. } => return Ok(true),
        }
        Ok(false)
    }

    fn dwell(&mut self, seconds: f64) -> Result<(), ExportError> {
        self.runner
            .push_dwell(seconds)
            .map_err(|error| ExportError::GcodeRun(error.to_string()))
    }

    fn push(
        &mut self,
        line: Line<MAX_AXES>,
        gcode_line: u32,
        end_mm: [f64; MAX_AXES],
        circle: Option<Circle>,
        mm_per_path_step: f64,
        sink: &mut impl Sink,
    ) -> Result<(), ExportError> {
        while self.runner.queued() >= self.queue_len {
            if !self.step(sink)? {
                break;
            }
        }
        let tag = self.next_tag;
        self.runner
            .push(line, tag)
            .map_err(|error| ExportError::GcodeRun(format!("line {gcode_line}: {error}")))?;
        if self.chords.is_empty() {
            self.first_tag = tag;
        }
        self.chords.push_back(Chord {
            line: gcode_line,
            piece: Piece {
                start_mm: self.programmed_mm,
                end_mm,
                circle: circle.filter(|_| self.xy.is_some()),
            },
            mm_per_path_step,
        });
        self.next_tag = tag.wrapping_add(1);
        self.programmed_mm = end_mm;
        Ok(())
    }

    /// The arc's circle for a chord, if the machine has X and Y.
    pub fn circle(&self, centre: [f64; 2], radius: f64) -> Option<Circle> {
        self.xy.map(|axes| Circle {
            axes,
            centre,
            radius,
        })
    }

    fn chord(&self, tag: u32) -> Option<&Chord> {
        self.chords.get(tag.wrapping_sub(self.first_tag) as usize)
    }

    /// Takes the next edge; false when none is left in the queue.
    fn step(&mut self, sink: &mut impl Sink) -> Result<bool, ExportError> {
        let Some(ct) = self.runner.peek_ct() else {
            return Ok(false);
        };
        if self.pending.is_none_or(|pending| pending.ct != ct) {
            self.flush(sink)?;
            // Read now: the line may be done (and gone) after the edge.
            let speed = self.runner.path_speed_at(ct);
            self.pending = Some(PendingRow {
                ct,
                line: 0,
                first_tag: u32::MAX,
                last_tag: 0,
                path_steps_per_s: speed,
            });
        }
        let Some((edge, ticks)) = self.runner.next_edge_timed(u64::MAX) else {
            return Ok(false);
        };
        sink.edge(&edge)?;
        self.edges += 1;
        self.measures[usize::from(edge.axis)].edge(ticks / self.hz, edge.forward, edge.tag);
        let line = self.chord(edge.tag).map_or(0, |chord| chord.line);
        if let Some(pending) = &mut self.pending {
            pending.line = line;
            if pending.first_tag == u32::MAX {
                pending.first_tag = edge.tag;
            }
            pending.last_tag = edge.tag;
        }
        Ok(true)
    }

    /// Writes the gathered row.
    fn flush(&mut self, sink: &mut impl Sink) -> Result<(), ExportError> {
        let Some(pending) = self.pending.take() else {
            return Ok(());
        };
        let positions = self.runner.positions();
        let mut positions_mm = [0.0; MAX_AXES];
        for axis in 0..self.axes {
            positions_mm[axis] = positions[axis] as f64 / self.steps_per_mm[axis];
        }
        // The pieces around the row's lines: a corner is measured against
        // both of its pieces.
        let from = pending.first_tag.wrapping_sub(1);
        let mut deviation = f64::INFINITY;
        let span = pending.last_tag.wrapping_sub(from).wrapping_add(2);
        for offset in 0..span.min(1_000) {
            if let Some(chord) = self.chord(from.wrapping_add(offset)) {
                deviation = deviation.min(chord.piece.distance_mm(&positions_mm, self.axes));
            }
        }
        if !deviation.is_finite() {
            deviation = 0.0;
        }
        if deviation > self.max_deviation.0 {
            self.max_deviation = (deviation, pending.line);
        }
        let scale = self
            .chord(pending.last_tag)
            .map_or(0.0, |chord| chord.mm_per_path_step);
        let row = Row {
            ct: pending.ct,
            time_s: pending.ct as f64 / self.hz,
            line: pending.line,
            positions,
            positions_mm,
            feed_mm_s: pending.path_steps_per_s * scale,
            deviation_mm: deviation,
        };
        sink.row(&row)?;
        self.rows += 1;
        // Pieces before the one ahead of this row are measured no more.
        while self.chords.len() > 1 && (from.wrapping_sub(self.first_tag) as i32) > 0 {
            self.chords.pop_front();
            self.first_tag = self.first_tag.wrapping_add(1);
        }
        Ok(())
    }

    /// Runs what is queued to its end and says what it came to.
    pub fn finish(mut self, sink: &mut impl Sink) -> Result<JobSummary, ExportError> {
        let end_ct = self.runner.end_ct();
        while self.step(sink)? {}
        self.flush(sink)?;
        let end = self.runner.positions();
        let axes = self.axes;
        let per_mm = |value: f64, axis: usize| value / self.steps_per_mm[axis];
        Ok(JobSummary {
            rows: self.rows,
            edges: self.edges,
            total_time_s: end_ct as f64 / self.hz,
            max_deviation_mm: self.max_deviation.0,
            max_deviation_line: self.max_deviation.1,
            peak_accel_mm_s2: (0..axes)
                .map(|axis| per_mm(self.measures[axis].peak_accel_steps_per_s2, axis))
                .collect(),
            peak_corner_jump_mm_s: (0..axes)
                .map(|axis| per_mm(self.measures[axis].peak_jump_steps_per_s, axis))
                .collect(),
            end_steps: end[..axes].to_vec(),
            letters: self.letters.clone(),
        })
    }
}

//! `--together`: a coordinated move of several axes, as one table.
//!
//! The move runs on an emulated hub in virtual time (`Hub::move_together`,
//! every axis on its own cog, `sd` outputs), and the table has one row at
//! the start and one per system-counter tick at which any axis steps:
//!
//! | column | meaning |
//! |---|---|
//! | `time_s` | seconds since the group's first edge |
//! | `ct_ticks` | the same, in clock ticks |
//! | `progress` | the line's progress `s(t)`: `k/L` at the lead's `k`-th edge, linear between |
//! | `axisN_position` | axis N's position (signed steps) after every edge at this tick |
//! | `deviation_steps` | the largest `|position − steps · s(t)|` over the axes |
//!
//! The summary (on stderr) states the largest deviation of the whole move,
//! which the line promises to keep within one step.

use std::collections::VecDeque;
use std::io::Write;

use driver::profile::scurve::Arithmetic;
use driver::{Axis, ClockMode, Edge, Hub, HubConfig};

use crate::error::ExportError;

/// The most axes of one group move (the hub's cogs).
pub const AXES_MAX: usize = 8;

/// What `--together` asks for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TogetherRequest {
    /// Each axis's signed steps (1 to [`AXES_MAX`] axes, 0 allowed).
    pub steps: Vec<i32>,
    /// The lead's top speed, steps/s.
    pub speed_steps_per_s: u32,
    /// Smooth or the reference's integer arithmetic.
    pub arithmetic: Arithmetic,
    /// System clock, Hz.
    pub clkfreq: u32,
    /// S-curve offset, degrees.
    pub offset_deg: u32,
    /// S-curve acceleration divisor.
    pub accel_div: u32,
}

/// What the table showed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TogetherSummary {
    /// Rows written (the header not counted).
    pub rows: u64,
    /// The largest deviation from the line, steps.
    pub largest_deviation_steps: f64,
    /// The axis it occurred on.
    pub axis: usize,
    /// When, seconds since the first edge.
    pub time_s: f64,
    /// When the last axis made its last step, seconds since the first edge.
    pub duration_s: f64,
}

impl TogetherSummary {
    /// One line for stderr.
    pub fn line(&self) -> String {
        format!(
            "{} rows, {:.6} s; largest deviation from the line {:.4} steps (axis {} at {:.6} s)",
            self.rows, self.duration_s, self.largest_deviation_steps, self.axis, self.time_s
        )
    }
}

/// Edges a slice of the hub's run aims at (a slice's time doubles or
/// halves towards it), as for `--vcd`: memory stays bounded however long
/// the move.
const SLICE_EDGES: usize = 50_000;

/// Runs the group move and writes its table as CSV to `out`, a slice of
/// virtual time at a time.
pub fn run(request: &TogetherRequest, out: impl Write) -> Result<TogetherSummary, ExportError> {
    let refused = |reason: String| ExportError::TogetherMove(reason);
    if request.steps.is_empty() || request.steps.len() > AXES_MAX {
        return Err(ExportError::TogetherAxes(request.steps.len()));
    }
    let hub = Hub::new(HubConfig {
        clkfreq: request.clkfreq,
        clock: ClockMode::Virtual,
        offset_deg: request.offset_deg,
        accel_div: request.accel_div,
        arithmetic: request.arithmetic,
        trace_edges: true,
        max_cogs: request.steps.len(),
        ..HubConfig::default()
    })
    .map_err(|error| refused(error.to_string()))?;
    let axes = (0..request.steps.len())
        .map(|i| {
            let stop = (3 * i) as u8;
            let axis = hub.start_sd(stop, stop + 1, stop + 2)?;
            hub.set_input(stop, true)?;
            Ok(axis)
        })
        .collect::<Result<Vec<Axis>, driver::HubError>>()
        .map_err(|error| refused(error.to_string()))?;
    drop(hub.take_trace());
    let group: Vec<(&Axis, i32)> = axes.iter().zip(request.steps.iter().copied()).collect();
    let setup_ticks = u64::from(hub.config().dir_setup_ticks);
    hub.move_together(&group, request.speed_steps_per_s)
        .map_err(|error| refused(error.to_string()))?;
    let mut table = Table::new(request, &axes, out)?;
    let step_pins: Vec<u8> = axes.iter().map(|axis| pins_of(axis).0).collect();
    let made = |hub: &Hub| -> u64 { step_pins.iter().map(|&pin| hub.rising_edges(pin)).sum() };
    let total: u64 = request
        .steps
        .iter()
        .map(|steps| u64::from(steps.unsigned_abs()))
        .sum();
    let mut slice_ticks = u64::from(request.clkfreq / 1_000).max(1);
    while made(&hub) < total {
        let before = made(&hub);
        let ct = hub.advance(slice_ticks);
        let edges = hub.take_trace();
        table.take(&edges);
        // A later step may set its direction up to `setup_ticks` before
        // its CT: only what is older is final.
        table.write_before(ct.saturating_sub(setup_ticks))?;
        if edges.len() < SLICE_EDGES / 2 {
            slice_ticks = slice_ticks.saturating_mul(2);
        } else if edges.len() > SLICE_EDGES * 2 {
            slice_ticks = (slice_ticks / 2).max(1);
        }
        if made(&hub) == before && slice_ticks == u64::MAX {
            return Err(refused("the cogs made no step".into()));
        }
    }
    hub.run_until_idle();
    table.take(&hub.take_trace());
    hub.shutdown();
    table.finish()
}

/// An axis's (pulse pin, direction pin).
fn pins_of(axis: &Axis) -> (u8, u8) {
    match axis.outputs() {
        driver::Outputs::StepDir { step, dir } => (step, dir),
        driver::Outputs::CwCcw { cw, ccw } => (cw, ccw),
    }
}

/// The table being written: the steps taken from the hub wait until every
/// axis's edges at their CT are known and the lead's next edge (which the
/// progress needs) has come, then become rows.
struct Table<W: Write> {
    writer: csv::Writer<W>,
    /// Each axis's signed steps.
    steps: Vec<i32>,
    /// Each axis's (pulse pin, direction pin).
    pins: Vec<(u8, u8)>,
    /// Each axis's direction pin level and position after the last edge taken.
    reverse: Vec<bool>,
    taken_position: Vec<i64>,
    /// Each axis's steps taken but not yet in a row: (CT, position after it).
    waiting: Vec<VecDeque<(u64, i64)>>,
    /// Each axis's position as of the last row.
    row_position: Vec<i64>,
    lead: usize,
    lead_steps: u32,
    /// The lead's edges taken so far, and those after the last row's CT.
    lead_taken: u64,
    lead_upcoming: VecDeque<u64>,
    /// The lead's edges up to the last row's CT, and the last of them.
    lead_passed: u64,
    lead_last: Option<u64>,
    /// Every edge has been taken (the move is over).
    complete: bool,
    /// The lead's first edge: time 0 of the table.
    start: Option<u64>,
    last_ct: Option<u64>,
    clkfreq: f64,
    record: Vec<String>,
    summary: TogetherSummary,
}

impl<W: Write> Table<W> {
    /// Writes the header and the row at the start.
    fn new(request: &TogetherRequest, axes: &[Axis], out: W) -> Result<Self, ExportError> {
        let lead = (0..request.steps.len())
            .max_by_key(|&i| (request.steps[i].unsigned_abs(), std::cmp::Reverse(i)))
            .unwrap_or(0);
        let count = axes.len();
        let mut table = Self {
            writer: csv::Writer::from_writer(out),
            steps: request.steps.clone(),
            pins: axes.iter().map(pins_of).collect(),
            reverse: vec![false; count],
            taken_position: vec![0; count],
            waiting: vec![VecDeque::new(); count],
            row_position: vec![0; count],
            lead,
            lead_steps: request.steps[lead].unsigned_abs(),
            lead_taken: 0,
            lead_upcoming: VecDeque::new(),
            lead_passed: 0,
            lead_last: None,
            complete: false,
            start: None,
            last_ct: None,
            clkfreq: f64::from(request.clkfreq),
            record: Vec::with_capacity(count + 4),
            summary: TogetherSummary {
                rows: 0,
                largest_deviation_steps: 0.0,
                axis: 0,
                time_s: 0.0,
                duration_s: 0.0,
            },
        };
        let mut header = vec!["time_s".to_string(), "ct_ticks".into(), "progress".into()];
        header.extend((0..count).map(|i| format!("axis{i}_position")));
        header.push("deviation_steps".into());
        table.writer.write_record(&header).map_err(csv_error)?;
        table.write_row(None, 0.0)?;
        Ok(table)
    }

    /// Takes a batch of the hub's edges (each cog's in the order it made them).
    fn take(&mut self, edges: &[Edge]) {
        for edge in edges {
            for (i, &(step, dir)) in self.pins.iter().enumerate() {
                if edge.pin == dir {
                    self.reverse[i] = edge.level;
                } else if edge.pin == step && edge.level {
                    self.taken_position[i] += if self.reverse[i] { -1 } else { 1 };
                    self.waiting[i].push_back((edge.ct, self.taken_position[i]));
                    if i == self.lead {
                        self.start.get_or_insert(edge.ct);
                        self.lead_taken += 1;
                        self.lead_upcoming.push_back(edge.ct);
                    }
                }
            }
        }
    }

    /// Writes the rows of the CTs before `horizon_ct` that can be written
    /// (the lead's next edge known, or the move over).
    fn write_before(&mut self, horizon_ct: u64) -> Result<(), ExportError> {
        loop {
            let Some(ct) = self
                .waiting
                .iter()
                .filter_map(|steps| steps.front().map(|&(ct, _)| ct))
                .min()
            else {
                return Ok(());
            };
            if ct >= horizon_ct {
                return Ok(());
            }
            while let Some(&edge) = self.lead_upcoming.front().filter(|&&edge| edge <= ct) {
                self.lead_upcoming.pop_front();
                self.lead_passed += 1;
                self.lead_last = Some(edge);
            }
            let lead_over = self.complete || self.lead_taken >= u64::from(self.lead_steps);
            if self.lead_upcoming.is_empty() && !lead_over {
                return Ok(());
            }
            for (waiting, position) in self.waiting.iter_mut().zip(&mut self.row_position) {
                while let Some(&(_, after)) = waiting.front().filter(|(at, _)| *at <= ct) {
                    *position = after;
                    waiting.pop_front();
                }
            }
            let progress = line_progress(
                self.lead_passed,
                self.lead_last,
                self.lead_upcoming.front().copied(),
                self.lead_steps,
                ct,
            );
            self.write_row(Some(ct), progress)?;
        }
    }

    /// One row: at the start (`None`) or at a CT where an axis steps.
    fn write_row(&mut self, ct: Option<u64>, progress: f64) -> Result<(), ExportError> {
        let start = self.start.unwrap_or(0);
        let elapsed = ct.map_or(0, |ct| ct.saturating_sub(start));
        if ct.is_some() {
            self.last_ct = ct;
        }
        self.record.clear();
        self.record
            .push(format!("{}", elapsed as f64 / self.clkfreq));
        self.record.push(elapsed.to_string());
        self.record.push(format!("{progress}"));
        let mut worst = (0.0f64, 0usize);
        for (i, &position) in self.row_position.iter().enumerate() {
            let deviation = (position as f64 - f64::from(self.steps[i]) * progress).abs();
            if deviation > worst.0 {
                worst = (deviation, i);
            }
            self.record.push(position.to_string());
        }
        self.record.push(format!("{}", worst.0));
        self.writer.write_record(&self.record).map_err(csv_error)?;
        self.summary.rows += 1;
        if worst.0 > self.summary.largest_deviation_steps {
            self.summary.largest_deviation_steps = worst.0;
            self.summary.axis = worst.1;
            self.summary.time_s = elapsed as f64 / self.clkfreq;
        }
        Ok(())
    }

    /// Writes the rows left and flushes.
    fn finish(mut self) -> Result<TogetherSummary, ExportError> {
        self.complete = true;
        self.write_before(u64::MAX)?;
        self.writer.flush().map_err(write_error)?;
        let start = self.start.unwrap_or(0);
        self.summary.duration_s = self
            .last_ct
            .map_or(0.0, |last| last.saturating_sub(start) as f64 / self.clkfreq);
        Ok(self.summary)
    }
}

fn write_error(source: std::io::Error) -> ExportError {
    ExportError::Write {
        path: "-".into(),
        source,
    }
}

fn csv_error(error: csv::Error) -> ExportError {
    match error.into_kind() {
        csv::ErrorKind::Io(source) => write_error(source),
        other => write_error(std::io::Error::other(format!("{other:?}"))),
    }
}

/// `s(t)`: `k / L` at the lead's `k`-th edge, linear in time between its
/// edges, 0 before the first, constant after the last; `passed` is `k`
/// at `ct`, `before` and `after` the lead's edges around it.
fn line_progress(
    passed: u64,
    before: Option<u64>,
    after: Option<u64>,
    lead_steps: u32,
    ct: u64,
) -> f64 {
    if lead_steps == 0 {
        return 0.0;
    }
    let fraction = match (before, after) {
        (Some(before), Some(after)) => (ct - before) as f64 / (after - before) as f64,
        _ => 0.0,
    };
    (passed as f64 + fraction) / f64::from(lead_steps)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(steps: &[i32], arithmetic: Arithmetic) -> TogetherRequest {
        TogetherRequest {
            steps: steps.to_vec(),
            speed_steps_per_s: 20_000,
            arithmetic,
            clkfreq: 200_000_000,
            offset_deg: 40,
            accel_div: 10,
        }
    }

    #[test]
    fn the_table_has_a_column_per_axis_and_stays_on_the_line() {
        for arithmetic in [Arithmetic::Smooth, Arithmetic::P2Exact] {
            let mut out = Vec::new();
            let summary = run(&request(&[3_000, -1_000, 0], arithmetic), &mut out).unwrap();
            let text = String::from_utf8(out).unwrap();
            let mut lines = text.lines();
            assert_eq!(
                lines.next(),
                Some("time_s,ct_ticks,progress,axis0_position,axis1_position,axis2_position,deviation_steps")
            );
            assert_eq!(lines.next(), Some("0,0,0,0,0,0,0"));
            // The first edges: both moving axes on the same tick.
            assert!(lines.next().unwrap().starts_with("0,0,"));
            let last = text.lines().last().unwrap();
            let fields: Vec<&str> = last.split(',').collect();
            assert_eq!(&fields[2..6], ["1", "3000", "-1000", "0"]);
            // The start, the lead's 3,000 edges and axis 1's 1,000, its first
            // and last on the lead's.
            assert_eq!(summary.rows, 1 + 3_000 + 1_000 - 2);
            assert!(summary.largest_deviation_steps <= 1.0, "{summary:?}");
            assert!(summary.largest_deviation_steps > 0.5, "{summary:?}");
        }
    }

    #[test]
    fn bad_groups_are_refused() {
        assert!(matches!(
            run(&request(&[], Arithmetic::Smooth), Vec::new()),
            Err(ExportError::TogetherAxes(0))
        ));
        assert!(matches!(
            run(&request(&[1; 9], Arithmetic::Smooth), Vec::new()),
            Err(ExportError::TogetherAxes(9))
        ));
        let mut fast = request(&[100, 10], Arithmetic::Smooth);
        fast.speed_steps_per_s = 150_000_000;
        assert!(matches!(
            run(&fast, Vec::new()),
            Err(ExportError::TogetherMove(_))
        ));
    }
}

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

/// Runs the group move and writes its table as CSV to `out`.
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
    hub.move_together(&group, request.speed_steps_per_s)
        .map_err(|error| refused(error.to_string()))?;
    hub.run_until_idle();
    let trace = hub.take_trace();
    hub.shutdown();
    write_table(request, &axes, &trace, out)
}

/// Each axis's rising step edges: (CT, position after it).
fn steps_of(axis: &Axis, trace: &[Edge]) -> Vec<(u64, i64)> {
    let (step, dir) = match axis.outputs() {
        driver::Outputs::StepDir { step, dir } => (step, dir),
        driver::Outputs::CwCcw { cw, ccw } => (cw, ccw),
    };
    let mut reverse = false;
    let mut position = 0;
    let mut steps = Vec::new();
    for edge in trace {
        if edge.pin == dir {
            reverse = edge.level;
        } else if edge.pin == step && edge.level {
            position += if reverse { -1 } else { 1 };
            steps.push((edge.ct, position));
        }
    }
    steps
}

fn write_table(
    request: &TogetherRequest,
    axes: &[Axis],
    trace: &[Edge],
    out: impl Write,
) -> Result<TogetherSummary, ExportError> {
    let write_error = |source| ExportError::Write {
        path: "-".into(),
        source,
    };
    let csv_error = |error: csv::Error| match error.into_kind() {
        csv::ErrorKind::Io(source) => write_error(source),
        other => write_error(std::io::Error::other(format!("{other:?}"))),
    };
    let steps: Vec<Vec<(u64, i64)>> = axes.iter().map(|axis| steps_of(axis, trace)).collect();
    let lead = (0..request.steps.len())
        .max_by_key(|&i| (request.steps[i].unsigned_abs(), std::cmp::Reverse(i)))
        .unwrap_or(0);
    let lead_steps = request.steps[lead].unsigned_abs();
    let lead_edges: Vec<u64> = steps[lead].iter().map(|(ct, _)| *ct).collect();
    let start = lead_edges.first().copied().unwrap_or(0);
    let mut cts: Vec<u64> = steps.iter().flatten().map(|(ct, _)| *ct).collect();
    cts.sort_unstable();
    cts.dedup();

    let mut writer = csv::Writer::from_writer(out);
    let mut header = vec!["time_s".to_string(), "ct_ticks".into(), "progress".into()];
    header.extend((0..axes.len()).map(|i| format!("axis{i}_position")));
    header.push("deviation_steps".into());
    writer.write_record(&header).map_err(csv_error)?;

    let clkfreq = f64::from(request.clkfreq);
    let mut summary = TogetherSummary {
        rows: 0,
        largest_deviation_steps: 0.0,
        axis: 0,
        time_s: 0.0,
        duration_s: cts
            .last()
            .map_or(0.0, |last| (last - start) as f64 / clkfreq),
    };
    let mut made = vec![0usize; axes.len()];
    let mut record = Vec::with_capacity(header.len());
    let rows = std::iter::once(None).chain(cts.iter().copied().map(Some));
    for ct in rows {
        let (elapsed, progress) = match ct {
            None => (0, 0.0),
            Some(ct) => (ct - start, line_progress(&lead_edges, lead_steps, ct)),
        };
        record.clear();
        record.push(format!("{}", elapsed as f64 / clkfreq));
        record.push(elapsed.to_string());
        record.push(format!("{progress}"));
        let mut worst = (0.0f64, 0usize);
        for (i, axis_steps) in steps.iter().enumerate() {
            if let Some(ct) = ct {
                while made[i] < axis_steps.len() && axis_steps[made[i]].0 <= ct {
                    made[i] += 1;
                }
            }
            let position = if made[i] == 0 {
                0
            } else {
                axis_steps[made[i] - 1].1
            };
            let deviation = (position as f64 - f64::from(request.steps[i]) * progress).abs();
            if deviation > worst.0 {
                worst = (deviation, i);
            }
            record.push(position.to_string());
        }
        record.push(format!("{}", worst.0));
        writer.write_record(&record).map_err(csv_error)?;
        summary.rows += 1;
        if worst.0 > summary.largest_deviation_steps {
            summary.largest_deviation_steps = worst.0;
            summary.axis = worst.1;
            summary.time_s = elapsed as f64 / clkfreq;
        }
    }
    writer.flush().map_err(write_error)?;
    Ok(summary)
}

/// `s(t)`: `k / L` at the lead's `k`-th edge, linear in time between its
/// edges, 0 before the first, constant after the last.
fn line_progress(lead_edges: &[u64], lead_steps: u32, ct: u64) -> f64 {
    if lead_steps == 0 {
        return 0.0;
    }
    let k = lead_edges.partition_point(|&edge| edge <= ct);
    let fraction = match (k.checked_sub(1).map(|i| lead_edges[i]), lead_edges.get(k)) {
        (Some(before), Some(&after)) => (ct - before) as f64 / (after - before) as f64,
        _ => 0.0,
    };
    (k as f64 + fraction) / f64::from(lead_steps)
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

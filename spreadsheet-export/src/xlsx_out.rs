//! The table as an Excel workbook (`rust_xlsxwriter`).
//!
//! Sheets, in order:
//!
//! - `steps`: the table, the same columns as the CSV, streamed through the
//!   library's constant-memory mode (rows go to a temporary file in the
//!   destination's directory, so memory stays flat for any length);
//! - `summary`: the inputs and what the move came to, and two charts:
//!   velocity against time (scatter with straight lines) and velocity
//!   against step (line chart); with `--dynamics` the rotor's speed is drawn
//!   beside the command's in the first, and a third chart shows the rotor's
//!   lag against time;
//! - `chart_data`: the points the charts draw: every step of a short move;
//!   for a long one at most [`CHART_POINTS`] steps, chosen so that the
//!   extremes stay (see [`Sampler`]).
//!
//! A sheet holds 1,048,576 rows, one of them the header, so a move of more
//! than [`MAX_STEPS`] steps is refused before anything is written (CSV has
//! no limit).

use std::any::Any;
use std::cell::Cell;
use std::panic::AssertUnwindSafe;
use std::path::Path;
use std::sync::Once;

use rust_xlsxwriter::{Chart, ChartType, Format, Workbook, Worksheet, XlsxError};

use crate::csv_out::Columns;
use crate::dynamics::DynamicsRow;
use crate::error::ExportError;
use crate::motor::MotorRow;
use crate::output::PendingFile;
use crate::report::{Report, SummaryLine, SummaryValue};
use crate::table::{RotorPoint, Row, SamplePoint, Sampler};

/// The most steps one `steps` sheet holds (1,048,576 rows less the header).
pub const MAX_STEPS: u32 = 1_048_575;

/// The most points a chart draws.
pub const CHART_POINTS: u32 = 4_000;

/// Sheet names.
pub const STEPS_SHEET: &str = "steps";
/// The summary sheet (also holds the charts).
pub const SUMMARY_SHEET: &str = "summary";
/// The decimated points behind the charts.
pub const CHART_DATA_SHEET: &str = "chart_data";

/// A workbook being written.
pub struct XlsxOut {
    pending: PendingFile,
    workbook: Workbook,
    steps: Worksheet,
    sampler: Sampler,
    columns: Columns,
}

impl XlsxOut {
    /// Starts a workbook for a move of `total_steps` steps.
    pub fn new(
        pending: PendingFile,
        total_steps: u32,
        columns: Columns,
    ) -> Result<Self, ExportError> {
        if total_steps > MAX_STEPS {
            return Err(ExportError::TooManyRowsForXlsx {
                steps: total_steps,
                max: MAX_STEPS,
            });
        }
        let mut workbook = Workbook::new();
        let temp_directory = pending.scratch_directory().map(Path::to_path_buf);
        if let Some(directory) = temp_directory {
            workbook
                .set_tempdir(&directory)
                .map_err(|error| xlsx_error(&pending, error))?;
        }
        let mut steps = workbook
            .new_worksheet_with_constant_memory()
            .map_err(|error| xlsx_error(&pending, error))?;
        guarded(pending.destination(), || write_header(&mut steps, columns))?;
        Ok(Self {
            pending,
            workbook,
            steps,
            sampler: Sampler::new(total_steps, CHART_POINTS),
            columns,
        })
    }

    /// Writes one row.
    pub fn row(
        &mut self,
        row: &Row,
        motor: Option<&MotorRow>,
        dynamics: Option<&DynamicsRow>,
    ) -> Result<(), ExportError> {
        self.sampler.offer(row, dynamics.map(rotor_point));
        let steps = &mut self.steps;
        guarded(self.pending.destination(), || {
            write_row(steps, row, motor, dynamics)
        })
    }

    /// Adds the summary and charts and saves; the caller commits the file.
    pub fn finish(self, report: &Report) -> Result<PendingFile, ExportError> {
        let Self {
            pending,
            mut workbook,
            steps,
            sampler,
            columns,
        } = self;
        let destination = pending.destination().to_path_buf();
        guarded(&destination, || {
            workbook.push_worksheet(steps);
            let summary = workbook.add_worksheet();
            write_summary(summary, &report.summary_lines())?;
            let points = sampler.into_points();
            insert_charts(summary, points.len() as u32, columns.dynamics)?;
            write_chart_data(workbook.add_worksheet(), &points, columns.dynamics)?;
            Ok(())
        })?;
        let mut pending = pending;
        let mut latch = FirstError {
            inner: pending.file(),
            error: None,
        };
        let saved = guarded(&destination, || workbook.save_to_writer(&mut latch));
        if let Some(source) = latch.error {
            return Err(ExportError::Write {
                path: destination,
                source,
            });
        }
        saved?;
        Ok(pending)
    }
}

thread_local! {
    /// Set while [`guarded`] runs: its panics are reported as errors, not
    /// printed.
    static QUIET_PANICS: Cell<bool> = const { Cell::new(false) };
}

/// `rust_xlsxwriter` panics (`expect`) when it cannot write a sheet's
/// scratch file, as on a full disk. Runs `write` with such a panic caught,
/// its message kept off stderr, and turned into the write error it stands
/// for; the unwinding drops the pending file and with it the temporary one.
pub(crate) fn guarded<T>(
    destination: &Path,
    write: impl FnOnce() -> Result<T, XlsxError>,
) -> Result<T, ExportError> {
    static QUIET_HOOK: Once = Once::new();
    QUIET_HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET_PANICS.with(Cell::get) {
                previous(info);
            }
        }));
    });
    QUIET_PANICS.with(|quiet| quiet.set(true));
    let result = std::panic::catch_unwind(AssertUnwindSafe(write));
    QUIET_PANICS.with(|quiet| quiet.set(false));
    match result {
        Ok(result) => result.map_err(|error| ExportError::Xlsx {
            path: destination.to_path_buf(),
            reason: error.to_string(),
        }),
        Err(payload) => Err(panic_error(destination, payload.as_ref())),
    }
}

/// The library's panic as an error: the OS error its message carries
/// (`... Os { code: 28, ... }`: "No space left on device"), or the message.
fn panic_error(destination: &Path, payload: &(dyn Any + Send)) -> ExportError {
    let message = payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("the XLSX writer stopped");
    let os_code = message.split_once("code: ").and_then(|(_, rest)| {
        let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
        digits.parse::<i32>().ok()
    });
    match os_code {
        Some(code) => ExportError::Write {
            path: destination.to_path_buf(),
            source: std::io::Error::from_raw_os_error(code),
        },
        None => ExportError::Xlsx {
            path: destination.to_path_buf(),
            reason: message.to_string(),
        },
    }
}

/// Passes writes on until the first error, then keeps it and takes every
/// later write without writing it. The zip writer, when finishing fails,
/// tries again as it is dropped and prints that failure to stderr; past
/// the first error it finds nothing to report, and the caller reports the
/// first error, once.
pub(crate) struct FirstError<W> {
    pub(crate) inner: W,
    pub(crate) error: Option<std::io::Error>,
}

impl<W: std::io::Write> std::io::Write for FirstError<W> {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        if self.error.is_some() {
            return Ok(bytes.len());
        }
        match self.inner.write(bytes) {
            Err(error) if error.kind() != std::io::ErrorKind::Interrupted => {
                self.error = Some(error);
                Ok(bytes.len())
            }
            result => result,
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        if self.error.is_none() {
            if let Err(error) = self.inner.flush() {
                self.error = Some(error);
            }
        }
        Ok(())
    }
}

fn xlsx_error(pending: &PendingFile, error: XlsxError) -> ExportError {
    ExportError::Xlsx {
        path: pending.destination().to_path_buf(),
        reason: error.to_string(),
    }
}

/// The rotor's chart point of a row.
pub fn rotor_point(rotor: &DynamicsRow) -> RotorPoint {
    RotorPoint {
        velocity_steps_per_s: rotor.rotor_velocity_steps_per_s,
        lag_steps: rotor.rotor_lag_steps,
    }
}

fn write_header(sheet: &mut Worksheet, columns: Columns) -> Result<(), XlsxError> {
    sheet.set_name(STEPS_SHEET)?;
    let bold = Format::new().set_bold();
    for (column, name) in columns.names().iter().enumerate() {
        let column = column as u16;
        sheet.write_string_with_format(0, column, *name, &bold)?;
        sheet.set_column_width(column, (name.len() as f64 + 2.0).max(10.0))?;
    }
    sheet.set_freeze_panes(1, 0)?;
    Ok(())
}

fn write_row(
    sheet: &mut Worksheet,
    row: &Row,
    motor: Option<&MotorRow>,
    dynamics: Option<&DynamicsRow>,
) -> Result<(), XlsxError> {
    let line = row.step + 1;
    sheet.write_number(line, 0, row.step)?;
    sheet.write_string(line, 1, row.phase.as_str())?;
    if let Some(angle) = row.angle_deg {
        sheet.write_number(line, 2, angle)?;
    }
    sheet.write_number(line, 3, row.velocity_steps_per_s)?;
    sheet.write_number(line, 4, row.delay_ticks)?;
    sheet.write_number(line, 5, row.time_s)?;
    // Exact in a cell: periods stay far below 2^53 ticks.
    sheet.write_number(line, 6, row.period_ticks as f64)?;
    if let Some(motor) = motor {
        sheet.write_number(line, 7, motor.accel_steps_per_s2)?;
        sheet.write_number(line, 8, motor.torque_required_nm)?;
        sheet.write_number(line, 9, motor.torque_available_nm)?;
        // A cell cannot hold infinity: no torque required leaves it empty.
        if motor.margin.is_finite() {
            sheet.write_number(line, 10, motor.margin)?;
        }
    }
    if let Some(rotor) = dynamics {
        sheet.write_number(line, 11, rotor.rotor_angle_deg)?;
        sheet.write_number(line, 12, rotor.rotor_lag_steps)?;
        sheet.write_boolean(line, 13, rotor.synchronous)?;
    }
    Ok(())
}

fn write_summary(sheet: &mut Worksheet, lines: &[SummaryLine]) -> Result<(), XlsxError> {
    sheet.set_name(SUMMARY_SHEET)?;
    let bold = Format::new().set_bold();
    for (column, title) in ["quantity", "value", "unit"].iter().enumerate() {
        sheet.write_string_with_format(0, column as u16, *title, &bold)?;
    }
    sheet.set_column_width(0, 34)?;
    sheet.set_column_width(1, 18)?;
    sheet.set_column_width(2, 12)?;
    for (index, (quantity, value, unit)) in lines.iter().enumerate() {
        let line = index as u32 + 1;
        sheet.write_string(line, 0, *quantity)?;
        match value {
            SummaryValue::Number(number) => sheet.write_number(line, 1, *number)?,
            SummaryValue::Text(text) => sheet.write_string(line, 1, text)?,
        };
        if !unit.is_empty() {
            sheet.write_string(line, 2, *unit)?;
        }
    }
    Ok(())
}

fn write_chart_data(
    sheet: &mut Worksheet,
    points: &[SamplePoint],
    rotor: bool,
) -> Result<(), XlsxError> {
    sheet.set_name(CHART_DATA_SHEET)?;
    let bold = Format::new().set_bold();
    let mut header = vec![
        "step",
        "time_s",
        "velocity_steps_per_s",
        "accel_steps_per_s2",
    ];
    if rotor {
        header.extend(["rotor_velocity_steps_per_s", "rotor_lag_steps"]);
    }
    for (column, name) in header.iter().enumerate() {
        sheet.write_string_with_format(0, column as u16, *name, &bold)?;
        sheet.set_column_width(column as u16, name.len() as f64 + 2.0)?;
    }
    for (index, point) in points.iter().enumerate() {
        let line = index as u32 + 1;
        sheet.write_number(line, 0, point.step)?;
        sheet.write_number(line, 1, point.time_s)?;
        sheet.write_number(line, 2, point.velocity_steps_per_s)?;
        sheet.write_number(line, 3, point.accel_steps_per_s2)?;
        if let Some(rotor) = point.rotor {
            sheet.write_number(line, 4, rotor.velocity_steps_per_s)?;
            sheet.write_number(line, 5, rotor.lag_steps)?;
        }
    }
    Ok(())
}

/// Two charts on the summary sheet (three with the rotor), drawn from
/// `chart_data` rows 2..=points+1.
fn insert_charts(summary: &mut Worksheet, points: u32, rotor: bool) -> Result<(), XlsxError> {
    let (first, last) = (1, points.max(1));
    let mut by_time = Chart::new(ChartType::ScatterStraight);
    by_time
        .add_series()
        .set_name("command")
        .set_categories((CHART_DATA_SHEET, first, 1, last, 1))
        .set_values((CHART_DATA_SHEET, first, 2, last, 2));
    if rotor {
        by_time
            .add_series()
            .set_name("rotor")
            .set_categories((CHART_DATA_SHEET, first, 1, last, 1))
            .set_values((CHART_DATA_SHEET, first, 4, last, 4));
    }
    by_time.title().set_name("Velocity against time");
    by_time.x_axis().set_name("time (s)");
    by_time.y_axis().set_name("velocity (steps/s)");
    if !rotor {
        by_time.legend().set_hidden();
    }
    by_time.set_width(720).set_height(360);
    summary.insert_chart(1, 4, &by_time)?;

    let mut by_step = Chart::new(ChartType::Line);
    by_step
        .add_series()
        .set_name("velocity")
        .set_categories((CHART_DATA_SHEET, first, 0, last, 0))
        .set_values((CHART_DATA_SHEET, first, 2, last, 2));
    by_step.title().set_name("Velocity against step");
    by_step.x_axis().set_name("step");
    // About ten step labels along the axis, whatever the number of points.
    let interval = u16::try_from(points.div_ceil(10).max(1)).unwrap_or(u16::MAX);
    by_step
        .x_axis()
        .set_label_interval(interval)
        .set_tick_interval(interval);
    by_step.y_axis().set_name("velocity (steps/s)");
    by_step.legend().set_hidden();
    by_step.set_width(720).set_height(360);
    summary.insert_chart(20, 4, &by_step)?;

    if rotor {
        let mut lag = Chart::new(ChartType::ScatterStraight);
        lag.add_series()
            .set_name("rotor lag")
            .set_categories((CHART_DATA_SHEET, first, 1, last, 1))
            .set_values((CHART_DATA_SHEET, first, 5, last, 5));
        lag.title().set_name("Rotor lag against time");
        lag.x_axis().set_name("time (s)");
        lag.y_axis().set_name("lag behind the command (steps)");
        lag.legend().set_hidden();
        lag.set_width(720).set_height(360);
        summary.insert_chart(39, 4, &lag)?;
    }
    Ok(())
}

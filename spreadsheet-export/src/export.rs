//! One streaming pass: profile ─► rows ─► (motor check) ─► (rotor) ─► table
//! and plot.
//!
//! Nothing is collected: each row is written as it is made, and only the
//! decimated chart points and the running summary stay in memory. Output
//! files are committed together at the end (see [`crate::output`]), so a
//! failure anywhere leaves none behind.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::cli::{Format, Request};
use crate::csv_out::{Columns, CsvOut};
use crate::dynamics::{Dynamics, DynamicsRow, DynamicsSummary};
use crate::error::ExportError;
use crate::motor::{Motor, MotorRow, SmallestMargin};
use crate::output::{self, PendingFile};
use crate::plot::{self, PLOT_POINTS};
use crate::profiles;
use crate::progress::Progress;
use crate::report::Report;
use crate::table::{Row, Rows, Sampler, Summary};
use crate::waveform;
use crate::xlsx_out::{rotor_point, XlsxOut};

/// How an export ended (errors aside).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// Counts and extremes of the rows.
    pub summary: Summary,
    /// With `--motor`: the smallest margin (if any row) and the safety factor.
    pub motor: Option<(Option<SmallestMargin>, f64)>,
    /// With `--dynamics`: what the rotor did.
    pub dynamics: Option<DynamicsSummary>,
}

impl Outcome {
    /// 0; 4 when the rotor lost synchronism (ahead of 3); 3 when the motor
    /// margin fell below the safety factor.
    pub fn exit_code(&self) -> i32 {
        if self.lost_synchronism() {
            4
        } else if self.margin_too_small() {
            3
        } else {
            0
        }
    }

    /// Whether the rotor model lost synchronism (`--dynamics`).
    pub fn lost_synchronism(&self) -> bool {
        self.dynamics
            .is_some_and(|dynamics| !dynamics.synchronous())
    }

    /// The rotor's one-line summary for stderr.
    pub fn dynamics_summary(&self) -> Option<String> {
        self.dynamics.map(|dynamics| dynamics.line())
    }

    /// Whether the smallest margin is below the safety factor.
    pub fn margin_too_small(&self) -> bool {
        matches!(self.motor, Some((Some(smallest), factor)) if smallest.motor_row.margin < factor)
    }

    /// The motor check's one-line summary for stderr.
    pub fn motor_summary(&self) -> Option<String> {
        let (smallest, factor) = self.motor?;
        let smallest = smallest?;
        let row = smallest.motor_row;
        let verdict = if self.margin_too_small() {
            "BELOW the safety factor: the motor may lose steps"
        } else {
            "ok"
        };
        Some(format!(
            "motor check: smallest margin {:.3} at step {} (required {:.4} N·m, available {:.4} N·m); safety factor {}: {verdict}",
            row.margin,
            smallest.step,
            row.torque_required_nm.abs(),
            row.torque_available_nm,
            factor,
        ))
    }
}

/// Where the table goes.
// One is made per run, so the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
enum TableOut<'a> {
    Csv {
        out: CsvOut<Box<dyn Write + 'a>>,
        /// `None`: stdout.
        pending: Option<PendingFile>,
    },
    Xlsx(XlsxOut),
}

impl TableOut<'_> {
    fn row(
        &mut self,
        row: &Row,
        motor: Option<&MotorRow>,
        dynamics: Option<&DynamicsRow>,
    ) -> Result<(), ExportError> {
        match self {
            TableOut::Csv { out, pending } => out
                .row(row, motor, dynamics)
                .map_err(|source| write_error(pending.as_ref(), source)),
            TableOut::Xlsx(out) => out.row(row, motor, dynamics),
        }
    }

    /// Finishes writing; returns the file still to commit (none for stdout).
    fn finish(self, report: &Report) -> Result<Option<PendingFile>, ExportError> {
        match self {
            TableOut::Csv { out, pending } => {
                let mut destination = out
                    .finish()
                    .map_err(|source| write_error(pending.as_ref(), source))?;
                destination
                    .flush()
                    .map_err(|source| write_error(pending.as_ref(), source))?;
                Ok(pending)
            }
            TableOut::Xlsx(out) => out.finish(report).map(Some),
        }
    }
}

fn write_error(pending: Option<&PendingFile>, source: std::io::Error) -> ExportError {
    ExportError::Write {
        path: pending.map_or_else(|| PathBuf::from("-"), |p| p.destination().to_path_buf()),
        source,
    }
}

/// Runs an export. CSV without `-o` goes to `stdout`.
pub fn run<'a>(request: &Request, stdout: impl Write + 'a) -> Result<Outcome, ExportError> {
    let outputs: Vec<(&'static str, &Path)> = [
        request.output.as_deref().map(|path| ("-o", path)),
        request
            .vcd
            .as_ref()
            .map(|(path, _)| ("--vcd", path.as_path())),
        request
            .plot
            .as_ref()
            .map(|(path, _)| ("--plot", path.as_path())),
    ]
    .into_iter()
    .flatten()
    .collect();
    output::check_distinct(&outputs)?;
    let motor = request.motor.as_deref().map(Motor::load).transpose()?;
    let built = profiles::build(request)?;
    if let Some(motor) = &motor {
        let end = motor.curve_end_steps_per_s();
        if built.top_speed_steps_per_s > end {
            return Err(ExportError::TopSpeedBeyondTorqueCurve {
                path: motor.path.clone(),
                top_steps_per_s: built.top_speed_steps_per_s,
                last_steps_per_s: end,
            });
        }
    }
    // The move on the hub first: its refusal leaves nothing behind.
    let vcd_file = match &request.vcd {
        Some((path, outputs)) => Some(waveform::write(request, path, *outputs)?.0),
        None => None,
    };
    let stdout: Box<dyn Write + 'a> = match (&request.vcd, &request.output) {
        // --vcd alone: the rows still feed the plot and the motor check.
        (Some(_), None) => Box::new(std::io::sink()),
        _ => Box::new(stdout),
    };
    let mut dynamics = match (&motor, request.dynamics) {
        (Some(motor), true) => Some(Dynamics::new(
            motor,
            request.clkfreq,
            request.direction,
            1.0,
        )?),
        _ => None,
    };
    let columns = Columns {
        motor: motor.is_some(),
        dynamics: dynamics.is_some(),
    };
    let mut table = open_table(request, stdout, columns)?;
    let plot_file = match &request.plot {
        Some((path, format)) => Some((PendingFile::create(path)?, *format)),
        None => None,
    };
    let mut plot_points = plot_file
        .as_ref()
        .map(|_| Sampler::new(request.steps, PLOT_POINTS));

    let mut summary = Summary::default();
    let mut smallest: Option<SmallestMargin> = None;
    let mut progress = Progress::new(request.steps);
    let rows = Rows::new(
        built.profile,
        request.clkfreq,
        request.direction,
        built.edge_timing,
    );
    for row in rows {
        let motor_row = match &motor {
            Some(motor) => Some(motor.check(&row)?),
            None => None,
        };
        if let Some(motor_row) = motor_row {
            smallest = SmallestMargin::track(smallest, row.step, motor_row);
        }
        let rotor_row = match &mut dynamics {
            Some(dynamics) => Some(dynamics.row(&row)?),
            None => None,
        };
        table.row(&row, motor_row.as_ref(), rotor_row.as_ref())?;
        summary.add(&row);
        if let Some(points) = &mut plot_points {
            points.offer(&row, rotor_row.as_ref().map(rotor_point));
        }
        progress.update(row.step + 1);
    }
    progress.finish();
    let dynamics = dynamics.map(Dynamics::finish).transpose()?;

    let report = Report {
        request,
        plan: built.plan,
        summary,
        motor: motor.as_ref().map(|motor| (motor, smallest)),
        dynamics,
    };
    let table_file = table.finish(&report)?;
    if let (Some((pending, format)), Some(points)) = (&plot_file, plot_points) {
        let end_s = summary.total_time_s(request.clkfreq);
        plot::draw(
            pending,
            *format,
            &report.title(),
            &points.into_points(),
            end_s,
            dynamics.map(|dynamics| dynamics.sync_limit_steps),
        )?;
    }
    if let Some(pending) = table_file {
        pending.commit()?;
    }
    if let Some((pending, _)) = plot_file {
        pending.commit()?;
    }
    if let Some(pending) = vcd_file {
        pending.commit()?;
    }
    Ok(Outcome {
        summary,
        motor: motor.map(|motor| (smallest, motor.safety_factor)),
        dynamics,
    })
}

fn open_table<'a>(
    request: &Request,
    stdout: impl Write + 'a,
    columns: Columns,
) -> Result<TableOut<'a>, ExportError> {
    match (&request.output, request.format) {
        (None, Format::Csv) => {
            let out = CsvOut::new(Box::new(stdout) as Box<dyn Write + 'a>, columns)
                .map_err(|source| write_error(None, source))?;
            Ok(TableOut::Csv { out, pending: None })
        }
        (Some(path), Format::Csv) => {
            let mut pending = PendingFile::create(path)?;
            let file = pending
                .file()
                .try_clone()
                .map_err(|source| write_error(Some(&pending), source))?;
            let out = CsvOut::new(Box::new(file) as Box<dyn Write + 'a>, columns)
                .map_err(|source| write_error(Some(&pending), source))?;
            Ok(TableOut::Csv {
                out,
                pending: Some(pending),
            })
        }
        (Some(path), Format::Xlsx) => {
            let pending = PendingFile::create(path)?;
            let out = XlsxOut::new(pending, request.steps, columns)?;
            Ok(TableOut::Xlsx(out))
        }
        (None, Format::Xlsx) => Err(ExportError::XlsxNeedsPath),
    }
}

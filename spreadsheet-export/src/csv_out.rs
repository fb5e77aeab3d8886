//! The table as CSV, one record per row, streamed.
//!
//! Numbers are written in their shortest round-trip form (`ryu`, `itoa`);
//! an empty field is a value the profile does not have (the angle of a
//! profile without one); an infinite margin (no torque required) is `inf`.

use std::io::{self, Write};

use crate::motor::MotorRow;
use crate::table::Row;

/// The table's columns. `delay_ticks` is the delay the profile computed;
/// `period_ticks` is rising edge to next rising edge (see
/// [`crate::table::EdgeTiming`]); `time_s` is the sum of the earlier periods.
pub const HEADER: [&str; 7] = [
    "step",
    "phase",
    "angle_deg",
    "velocity_steps_per_s",
    "delay_ticks",
    "time_s",
    "period_ticks",
];

/// The columns `--motor` adds.
pub const MOTOR_HEADER: [&str; 4] = [
    "accel_steps_per_s2",
    "torque_required_nm",
    "torque_available_nm",
    "margin",
];

/// A CSV table being written to `W`.
pub struct CsvOut<W: Write> {
    writer: csv::Writer<W>,
    floats: ryu::Buffer,
    integers: itoa::Buffer,
}

impl<W: Write> CsvOut<W> {
    /// Starts the table: writes the header (with the motor columns if asked).
    pub fn new(destination: W, motor_columns: bool) -> io::Result<Self> {
        let mut writer = csv::WriterBuilder::new()
            .buffer_capacity(1 << 16)
            .from_writer(destination);
        if motor_columns {
            writer
                .write_record(HEADER.iter().chain(MOTOR_HEADER.iter()))
                .map_err(io_error)?;
        } else {
            writer.write_record(HEADER).map_err(io_error)?;
        }
        Ok(Self {
            writer,
            floats: ryu::Buffer::new(),
            integers: itoa::Buffer::new(),
        })
    }

    /// Writes one row (and its motor columns, when the table has them).
    pub fn row(&mut self, row: &Row, motor: Option<&MotorRow>) -> io::Result<()> {
        self.write_row(row, motor).map_err(io_error)
    }

    fn write_row(&mut self, row: &Row, motor: Option<&MotorRow>) -> csv::Result<()> {
        let writer = &mut self.writer;
        writer.write_field(self.integers.format(row.step))?;
        writer.write_field(row.phase.as_str())?;
        match row.angle_deg {
            Some(angle) => writer.write_field(self.floats.format(angle))?,
            None => writer.write_field("")?,
        }
        writer.write_field(self.floats.format(tidy(row.velocity_steps_per_s)))?;
        writer.write_field(self.integers.format(row.delay_ticks))?;
        writer.write_field(self.floats.format(tidy(row.time_s)))?;
        writer.write_field(self.integers.format(row.period_ticks))?;
        if let Some(motor) = motor {
            writer.write_field(self.floats.format(tidy(motor.accel_steps_per_s2)))?;
            writer.write_field(self.floats.format(tidy(motor.torque_required_nm)))?;
            writer.write_field(self.floats.format(tidy(motor.torque_available_nm)))?;
            writer.write_field(self.floats.format(tidy(motor.margin)))?;
        }
        writer.write_record(None::<&[u8]>)?;
        Ok(())
    }

    /// Flushes and hands back the destination.
    pub fn finish(self) -> io::Result<W> {
        self.writer
            .into_inner()
            .map_err(|error| io::Error::new(error.error().kind(), error.error().to_string()))
    }
}

/// The I/O error inside a csv error, so that its kind (a closed pipe)
/// survives.
fn io_error(error: csv::Error) -> io::Error {
    let message = error.to_string();
    match error.into_kind() {
        csv::ErrorKind::Io(error) => error,
        _ => io::Error::other(message),
    }
}

/// −0.0 as 0.0 (a reverse move's zero acceleration would read `-0.0`).
fn tidy(value: f64) -> f64 {
    value + 0.0
}

#[cfg(test)]
mod tests {
    use driver::profile::Phase;

    use super::*;

    fn row() -> Row {
        Row {
            step: 3,
            phase: Phase::Slew,
            angle_deg: None,
            velocity_steps_per_s: -20_000.0,
            delay_ticks: 10_000,
            period_ticks: 11_008,
            time_ticks: 50,
            time_s: 2.5e-7,
            accel_steps_per_s2: -0.0,
            peak_rate_steps_per_s: 20_000.0,
        }
    }

    #[test]
    fn writes_header_and_rows() {
        let mut table = CsvOut::new(Vec::new(), false).unwrap();
        table.row(&row(), None).unwrap();
        let text = String::from_utf8(table.finish().unwrap()).unwrap();
        assert_eq!(
            text,
            "step,phase,angle_deg,velocity_steps_per_s,delay_ticks,time_s,period_ticks\n\
             3,slew,,-20000.0,10000,2.5e-7,11008\n"
        );
    }

    #[test]
    fn motor_columns() {
        let mut table = CsvOut::new(Vec::new(), true).unwrap();
        let motor = MotorRow {
            accel_steps_per_s2: -0.0,
            torque_required_nm: -0.3,
            torque_available_nm: 0.5,
            margin: f64::INFINITY,
        };
        table.row(&row(), Some(&motor)).unwrap();
        let text = String::from_utf8(table.finish().unwrap()).unwrap();
        let mut lines = text.lines();
        assert_eq!(
            lines.next(),
            Some(
                "step,phase,angle_deg,velocity_steps_per_s,delay_ticks,time_s,period_ticks,\
                 accel_steps_per_s2,torque_required_nm,torque_available_nm,margin"
            )
        );
        assert_eq!(
            lines.next(),
            Some("3,slew,,-20000.0,10000,2.5e-7,11008,0.0,-0.3,0.5,inf")
        );
    }
}

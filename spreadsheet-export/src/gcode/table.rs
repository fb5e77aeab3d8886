//! The G-code table, as CSV or XLSX, a row at a time.
//!
//! | column | meaning |
//! |---|---|
//! | `time_s` | seconds since the program's start (the row's tick) |
//! | `line` | the G-code line of the tick's last edge |
//! | `<a>_steps` | each axis's position in steps, in the machine file's order |
//! | `<a>_mm` | the same in mm |
//! | `feed_mm_s` | the speed along the path, mm/s |
//!
//! CSV numbers are in their shortest round-trip form; the XLSX sheet is
//! written in the library's constant-memory mode and holds at most
//! [`crate::xlsx_out::MAX_STEPS`] rows (a longer program stops with an
//! error and leaves no file).

use std::io::Write;
use std::path::{Path, PathBuf};

use rust_xlsxwriter::{Format, Workbook, Worksheet};

use super::job::Row;
use crate::error::ExportError;
use crate::output::PendingFile;
use crate::xlsx_out::{guarded, FirstError, MAX_STEPS};

/// The header for axes `letters`.
pub fn header(letters: &[char]) -> Vec<String> {
    let mut names = vec!["time_s".to_string(), "line".to_string()];
    names.extend(letters.iter().map(|letter| format!("{letter}_steps")));
    names.extend(letters.iter().map(|letter| format!("{letter}_mm")));
    names.push("feed_mm_s".to_string());
    names
}

/// Where the rows go.
pub enum Table<'a> {
    /// CSV to stdout (`pending` none) or a file.
    Csv {
        /// The writer.
        out: std::io::BufWriter<Box<dyn Write + 'a>>,
        /// The file, for `-o`.
        pending: Option<PendingFile>,
        /// Axes.
        axes: usize,
    },
    /// An XLSX workbook.
    Xlsx {
        /// The file.
        pending: PendingFile,
        /// The workbook.
        workbook: Box<Workbook>,
        /// Its one sheet, in constant-memory mode.
        sheet: Box<Worksheet>,
        /// Rows written.
        rows: u32,
        /// Axes.
        axes: usize,
    },
}

impl<'a> Table<'a> {
    /// CSV to `out`; `pending` is the file behind it, if any.
    pub fn csv(
        out: Box<dyn Write + 'a>,
        pending: Option<PendingFile>,
        letters: &[char],
    ) -> Result<Self, ExportError> {
        let mut table = Table::Csv {
            out: std::io::BufWriter::with_capacity(1 << 16, out),
            pending,
            axes: letters.len(),
        };
        let line = header(letters).join(",");
        if let Table::Csv { out, pending, .. } = &mut table {
            writeln!(out, "{line}").map_err(|source| write_error(pending.as_ref(), source))?;
        }
        Ok(table)
    }

    /// An XLSX workbook into `pending`.
    pub fn xlsx(pending: PendingFile, letters: &[char]) -> Result<Self, ExportError> {
        let destination = pending.destination().to_path_buf();
        let mut workbook = Box::new(Workbook::new());
        if let Some(directory) = pending.scratch_directory().map(Path::to_path_buf) {
            guarded(&destination, || {
                workbook.set_tempdir(&directory).map(|_| ())
            })?;
        }
        let mut sheet = guarded(&destination, || {
            workbook.new_worksheet_with_constant_memory()
        })?;
        guarded(&destination, || {
            sheet.set_name("path")?;
            let bold = Format::new().set_bold();
            for (column, name) in header(letters).iter().enumerate() {
                sheet.write_string_with_format(0, column as u16, name, &bold)?;
                sheet.set_column_width(column as u16, (name.len() as f64 + 2.0).max(10.0))?;
            }
            sheet.set_freeze_panes(1, 0)?;
            Ok(())
        })?;
        Ok(Table::Xlsx {
            pending,
            workbook,
            sheet: Box::new(sheet),
            rows: 0,
            axes: letters.len(),
        })
    }

    /// Writes one row.
    pub fn row(&mut self, row: &Row) -> Result<(), ExportError> {
        match self {
            Table::Csv { out, pending, axes } => write_csv_row(out, row, *axes)
                .map_err(|source| write_error(pending.as_ref(), source)),
            Table::Xlsx {
                pending,
                sheet,
                rows,
                axes,
                ..
            } => {
                if *rows >= MAX_STEPS {
                    return Err(ExportError::GcodeXlsxRows(MAX_STEPS));
                }
                *rows += 1;
                let at = *rows;
                let axes = *axes;
                guarded(pending.destination(), || {
                    sheet.write_number(at, 0, row.time_s)?;
                    sheet.write_number(at, 1, row.line)?;
                    for axis in 0..axes {
                        sheet.write_number(at, (2 + axis) as u16, row.positions[axis] as f64)?;
                        sheet.write_number(at, (2 + axes + axis) as u16, row.positions_mm[axis])?;
                    }
                    sheet.write_number(at, (2 + 2 * axes) as u16, row.feed_mm_s)?;
                    Ok(())
                })
            }
        }
    }

    /// Flushes or saves; returns the file to commit (none for stdout).
    pub fn finish(self) -> Result<Option<PendingFile>, ExportError> {
        match self {
            Table::Csv {
                mut out, pending, ..
            } => {
                out.flush()
                    .map_err(|source| write_error(pending.as_ref(), source))?;
                Ok(pending)
            }
            Table::Xlsx {
                mut pending,
                mut workbook,
                sheet,
                ..
            } => {
                let destination = pending.destination().to_path_buf();
                workbook.push_worksheet(*sheet);
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
                Ok(Some(pending))
            }
        }
    }
}

fn write_csv_row(out: &mut impl Write, row: &Row, axes: usize) -> std::io::Result<()> {
    let mut float = ryu::Buffer::new();
    let mut integer = itoa::Buffer::new();
    out.write_all(float_text(&mut float, row.time_s).as_bytes())?;
    out.write_all(b",")?;
    out.write_all(integer.format(row.line).as_bytes())?;
    for axis in 0..axes {
        out.write_all(b",")?;
        out.write_all(integer.format(row.positions[axis]).as_bytes())?;
    }
    for axis in 0..axes {
        out.write_all(b",")?;
        out.write_all(float_text(&mut float, row.positions_mm[axis]).as_bytes())?;
    }
    out.write_all(b",")?;
    out.write_all(float_text(&mut float, row.feed_mm_s).as_bytes())?;
    out.write_all(b"\n")
}

/// Shortest round-trip text; whole numbers without ".0".
fn float_text(buffer: &mut ryu::Buffer, value: f64) -> &str {
    let text = buffer.format(value);
    text.strip_suffix(".0").unwrap_or(text)
}

fn write_error(pending: Option<&PendingFile>, source: std::io::Error) -> ExportError {
    ExportError::Write {
        path: pending.map_or_else(|| PathBuf::from("-"), |p| p.destination().to_path_buf()),
        source,
    }
}

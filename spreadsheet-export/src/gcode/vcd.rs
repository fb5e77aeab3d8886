//! `gcode --vcd`: every axis's pins as the runner's edges drive them.
//!
//! Axis `i` (machine file order) has its stop pin on `3i` (high from time
//! 0), its step pin on `3i + 1` and its direction pin on `3i + 2` (high =
//! towards lower positions), named `<letter>_stop`, `<letter>_step`,
//! `<letter>_dir`, as the hub's `sd` axes are. A step pulse rises at the
//! edge's CT and lasts [`PULSE_TICKS`] (or until just before the axis's
//! next step, if that is sooner); a change of direction comes
//! [`DIR_SETUP_TICKS`] before the step it is for. Edges are written as
//! soon as no later edge can come before them, so memory stays bounded.

use driver::trace::{Signal, VcdStream};
use driver::Edge;

use cogstep_motion::planner::{PathEdge, MAX_AXES};

use crate::error::ExportError;
use crate::output::PendingFile;

/// The step pulse, ticks (the hub's default).
pub const PULSE_TICKS: u64 = 1_000;
/// The direction's set-up time before a step, ticks (the hub's default).
pub const DIR_SETUP_TICKS: u64 = 1_000;

/// Edges taken between writes.
const BATCH: usize = 4_096;

/// A VCD being written from path edges.
pub struct VcdSink {
    pending: PendingFile,
    stream: VcdStream<std::fs::File>,
    clkfreq: u32,
    reverse: [bool; MAX_AXES],
    last_step: [Option<u64>; MAX_AXES],
    batch: Vec<Edge>,
    latest_ct: u64,
}

impl VcdSink {
    /// Declares the pins of axes `letters` and writes the header.
    pub fn new(
        mut pending: PendingFile,
        letters: &[char],
        clkfreq: u32,
    ) -> Result<Self, ExportError> {
        let mut signals = Vec::new();
        for (axis, letter) in letters.iter().enumerate() {
            let base = (3 * axis) as u8;
            for (offset, role, input, level) in [
                (0, "stop", true, true),
                (1, "step", false, false),
                (2, "dir", false, false),
            ] {
                signals.push(Signal {
                    pin: base + offset,
                    name: format!("{letter}_{role}"),
                    input,
                    level,
                });
            }
        }
        let destination = pending.destination().to_path_buf();
        let file = pending
            .file()
            .try_clone()
            .map_err(|source| ExportError::Write {
                path: destination.clone(),
                source,
            })?;
        let stream =
            VcdStream::new(file, clkfreq, 0, &signals).map_err(|source| ExportError::Write {
                path: destination,
                source,
            })?;
        Ok(VcdSink {
            pending,
            stream,
            clkfreq,
            reverse: [false; MAX_AXES],
            last_step: [None; MAX_AXES],
            batch: Vec::with_capacity(BATCH * 3),
            latest_ct: 0,
        })
    }

    /// Takes one step edge.
    pub fn edge(&mut self, edge: &PathEdge) -> Result<(), ExportError> {
        let axis = usize::from(edge.axis);
        let base = (3 * axis) as u8;
        let ct = edge.ct;
        if self.reverse[axis] == edge.forward {
            self.reverse[axis] = !edge.forward;
            let after_pulse = self.last_step[axis].map_or(0, |last| last + 1);
            self.batch.push(Edge {
                ct: ct.saturating_sub(DIR_SETUP_TICKS).max(after_pulse).min(ct),
                pin: base + 2,
                level: !edge.forward,
            });
        }
        self.batch.push(Edge {
            ct,
            pin: base + 1,
            level: true,
        });
        self.batch.push(Edge {
            ct: ct + PULSE_TICKS,
            pin: base + 1,
            level: false,
        });
        // A pulse longer than the time to the next step is cut short.
        if let Some(last) = self.last_step[axis] {
            if last + PULSE_TICKS >= ct {
                if let Some(fall) = self
                    .batch
                    .iter_mut()
                    .rev()
                    .find(|e| e.pin == base + 1 && !e.level && e.ct == last + PULSE_TICKS)
                {
                    fall.ct = ct.saturating_sub(1).max(last);
                }
            }
        }
        self.last_step[axis] = Some(ct);
        self.latest_ct = self.latest_ct.max(ct);
        if self.batch.len() >= BATCH {
            self.write()?;
        }
        Ok(())
    }

    fn write(&mut self) -> Result<(), ExportError> {
        self.stream.push(self.batch.drain(..));
        // Nothing later can come before the latest step less the set-up time.
        let horizon = self.latest_ct.saturating_sub(DIR_SETUP_TICKS);
        self.stream
            .write_before(horizon)
            .map_err(|source| self.error(source))
    }

    fn error(&self, source: std::io::Error) -> ExportError {
        ExportError::Write {
            path: self.pending.destination().to_path_buf(),
            source,
        }
    }

    /// Writes the rest and ends the file at `end_s` (or the last edge);
    /// returns the file to commit.
    pub fn finish(mut self, end_s: f64) -> Result<PendingFile, ExportError> {
        self.stream.push(self.batch.drain(..));
        let end_ct = ((end_s * f64::from(self.clkfreq)) as u64).max(self.latest_ct + PULSE_TICKS);
        let VcdSink {
            pending, stream, ..
        } = self;
        stream.finish(end_ct).map_err(|source| ExportError::Write {
            path: pending.destination().to_path_buf(),
            source,
        })?;
        Ok(pending)
    }
}

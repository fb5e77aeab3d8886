//! `--gcode FILE --machine M.toml`: the program as the demo shows it,
//! read and checked before anything moves.
//!
//! [`Program::load`] reads the machine file and the G-code file, checks
//! every line ([`driver::gcode::check`]: each error with its line and
//! column; one is enough for nothing to run), and interprets the program
//! once more to draw it: every move as a segment in machine mm (the XY
//! view), and each line's length and time at its programmed feed (the
//! progress and the time left). Running it is the backend's
//! ([`crate::program_backend`]).

use std::io::Read;
use std::path::Path;

use driver::gcode::{check, Block, GcodeError, Interpreter, MachineError, MachineSpec};

/// The most a G-code or machine file may hold: a runaway FIFO or
/// `/dev/zero` is refused, not read until memory runs out.
pub const FILE_MAX_BYTES: u64 = 16 << 20;

/// Why a program cannot run.
#[derive(Debug, thiserror::Error)]
pub enum ProgramError {
    /// A file could not be read.
    #[error("cannot read {path}: {reason}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
    /// The machine file is not one.
    #[error("{path}: {error}")]
    Machine {
        /// The machine file.
        path: String,
        /// What is wrong with it.
        error: MachineError,
    },
    /// The G-code file has errors: every one, in order (nothing ran).
    #[error("{path}: {} error{} in the G-code; nothing was run", errors.len(), if errors.len() == 1 { "" } else { "s" })]
    Check {
        /// The G-code file.
        path: String,
        /// Every error, with its line and column.
        errors: Vec<GcodeError>,
    },
}

impl ProgramError {
    /// The lines to print: the error, then (for a check) one
    /// `FILE:LINE:COLUMN: what` per error.
    pub fn report_lines(&self) -> Vec<String> {
        let mut lines = vec![self.to_string()];
        if let ProgramError::Check { path, errors } = self {
            lines.extend(
                errors
                    .iter()
                    .map(|e| format!("{path}:{}:{}: {}", e.line, e.column, e.kind)),
            );
        }
        lines
    }
}

/// One move of the program, in machine mm, for the XY view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// The G-code line it comes from.
    pub line: u32,
    /// Where it starts, per axis (mm).
    pub from_mm: [f64; 2],
    /// Where it ends (mm).
    pub to_mm: [f64; 2],
    /// A G0 rapid.
    pub rapid: bool,
}

/// A G-code program and its machine, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    /// The G-code file's name as given.
    pub name: String,
    /// The machine file's name as given.
    pub machine_name: String,
    /// The machine.
    pub spec: MachineSpec,
    /// The program's lines (line `n` is `lines[n − 1]`).
    pub lines: Vec<String>,
    /// The axes the XY view draws (indices in the machine file): `x` and
    /// `y` where the machine has them.
    pub view_axes: [Option<usize>; 2],
    /// Every move, in order.
    pub segments: Vec<Segment>,
    /// Per line (index `n − 1`): its length, time and scale.
    pub line_costs: Vec<LineCost>,
}

/// What one line of the program costs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LineCost {
    /// Its moves' length, mm.
    pub length_mm: f64,
    /// Their time at the programmed feed, held to each axis's top speed,
    /// without the ramps, s.
    pub time_s: f64,
    /// mm along the path per step of step space, on its first move (the
    /// path's speed is in steps of step space); 0 for a line without one.
    pub mm_per_step: f64,
}

/// Reads a text file of at most [`FILE_MAX_BYTES`].
pub fn read_text(path: &Path) -> Result<String, ProgramError> {
    let failed = |reason: String| ProgramError::Read {
        path: path.display().to_string(),
        reason,
    };
    let file = std::fs::File::open(path).map_err(|e| failed(e.to_string()))?;
    let mut bytes = Vec::new();
    file.take(FILE_MAX_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| failed(e.to_string()))?;
    if bytes.len() as u64 > FILE_MAX_BYTES {
        return Err(failed(format!("larger than {} MiB", FILE_MAX_BYTES >> 20)));
    }
    String::from_utf8(bytes).map_err(|_| failed("not UTF-8 text".to_string()))
}

impl Program {
    /// Reads and checks `gcode` for the machine in `machine`.
    pub fn load(gcode: &Path, machine: &Path) -> Result<Program, ProgramError> {
        let machine_name = machine.display().to_string();
        let spec = MachineSpec::from_toml_str(&read_text(machine)?).map_err(|error| {
            ProgramError::Machine {
                path: machine_name.clone(),
                error,
            }
        })?;
        let text = read_text(gcode)?;
        Program::from_text(&gcode.display().to_string(), &machine_name, spec, &text)
    }

    /// Reads and checks `gcode` for a machine given whole (a grbl board's
    /// `$$`), named `machine_name` on screen.
    pub fn load_for(
        gcode: &Path,
        machine_name: &str,
        spec: MachineSpec,
    ) -> Result<Program, ProgramError> {
        let text = read_text(gcode)?;
        Program::from_text(&gcode.display().to_string(), machine_name, spec, &text)
    }

    /// [`Program::load`] of a text already read.
    pub fn from_text(
        name: &str,
        machine_name: &str,
        spec: MachineSpec,
        text: &str,
    ) -> Result<Program, ProgramError> {
        let errors = check(text, &spec);
        if !errors.is_empty() {
            return Err(ProgramError::Check {
                path: name.to_string(),
                errors,
            });
        }
        let letter = |wanted: char| spec.letters().iter().position(|&c| c == wanted);
        let view_axes = match (letter('x'), letter('y')) {
            (Some(x), Some(y)) => [Some(x), Some(y)],
            _ => [Some(0), (spec.axis_count() > 1).then_some(1)],
        };
        let lines: Vec<String> = text.lines().map(str::to_string).collect();
        let mut interpreter = Interpreter::new(&spec);
        let mut segments = Vec::new();
        let mut line_costs = Vec::with_capacity(lines.len());
        let mut at_steps = interpreter.position_steps();
        for (index, text) in lines.iter().enumerate() {
            let line_no = u32::try_from(index + 1).unwrap_or(u32::MAX);
            let mut blocks = Vec::new();
            // Checked above: every line is interpreted.
            let _ = interpreter.interpret_line(line_no, text, &mut |block| blocks.push(block));
            let mut cost = LineCost::default();
            for block in blocks {
                let Block::Line {
                    target_steps,
                    feed_mm_s,
                    length_mm: block_mm,
                    rapid,
                    ..
                } = block
                else {
                    continue;
                };
                let mm = |steps: &[i64], axis: Option<usize>| {
                    axis.map_or(0.0, |a| steps[a] as f64 / spec.axes()[a].steps_per_mm)
                };
                segments.push(Segment {
                    line: line_no,
                    from_mm: view_axes.map(|axis| mm(&at_steps, axis)),
                    to_mm: view_axes.map(|axis| mm(&target_steps, axis)),
                    rapid,
                });
                // The axes' top speeds hold the feed along this move.
                let mut speed_mm_s = feed_mm_s;
                for (axis, spec_axis) in spec.axes().iter().enumerate() {
                    let moved_mm =
                        (target_steps[axis] - at_steps[axis]).abs() as f64 / spec_axis.steps_per_mm;
                    if moved_mm > 0.0 {
                        speed_mm_s = speed_mm_s.min(spec_axis.max_speed_mm_s * block_mm / moved_mm);
                    }
                }
                if cost.mm_per_step == 0.0 {
                    let step_space: f64 = (0..spec.axis_count())
                        .map(|axis| ((target_steps[axis] - at_steps[axis]) as f64).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    cost.mm_per_step = block_mm / step_space;
                }
                cost.length_mm += block_mm;
                cost.time_s += block_mm / speed_mm_s;
                at_steps = target_steps;
            }
            // G28 (and anything else that moves the machine without a
            // line) starts the next segment where the interpreter is.
            at_steps = interpreter.position_steps();
            line_costs.push(cost);
        }
        Ok(Program {
            name: name.to_string(),
            machine_name: machine_name.to_string(),
            spec,
            lines,
            view_axes,
            segments,
            line_costs,
        })
    }

    /// How many lines the file has (N in `line n of N`).
    pub fn line_count(&self) -> usize {
        self.lines.len()
    }

    /// The program's length (mm) and time at its feeds (s) from line
    /// `from` (1-based) to the end.
    pub fn cost_from(&self, from: usize) -> (f64, f64) {
        self.line_costs
            .iter()
            .skip(from.saturating_sub(1))
            .fold((0.0, 0.0), |(length, time), cost| {
                (length + cost.length_mm, time + cost.time_s)
            })
    }

    /// Where the XY view's bounds are (mm): every segment, with a margin.
    pub fn bounds_mm(&self) -> [[f64; 2]; 2] {
        let mut bounds = [[0.0f64, 0.0f64]; 2];
        for segment in &self.segments {
            for point in [segment.from_mm, segment.to_mm] {
                for (axis, value) in point.iter().enumerate() {
                    bounds[axis][0] = bounds[axis][0].min(*value);
                    bounds[axis][1] = bounds[axis][1].max(*value);
                }
            }
        }
        bounds.map(|[low, high]| {
            let margin = ((high - low) * 0.05).max(1.0);
            [low - margin, high + margin]
        })
    }
}

/// What the app asks of a running program's path (`--gcode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathCommand {
    /// A feed hold: the path decelerates along itself to rest.
    Hold,
    /// Go on after a hold (or an M0), once at rest.
    Resume,
    /// Come to rest along the path and drop the rest of the program.
    Cancel,
    /// Stop every axis at once (positions kept) and drop the rest.
    EmergencyStop,
    /// The feed override, percent (10 to 200).
    FeedOverride(u32),
}

/// A running program as a frame reads it.
#[derive(Clone, Debug, PartialEq)]
pub struct PathReading {
    /// The path's progress (state, the line running, speed, overrides).
    pub progress: driver::PathProgress,
    /// The last line given to the path (queued whole), 0 before the first.
    pub fed_line: u32,
    /// Every line has been given to the path (or the program ended, or
    /// stopped): nothing more comes.
    pub fed_all: bool,
    /// The program was cancelled or emergency-stopped.
    pub stopped: bool,
    /// The line that stopped the program at run time (a limit, a G28
    /// without homing), and why.
    pub error: Option<(u32, String)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plotter() -> MachineSpec {
        MachineSpec::from_toml_str(
            "[axes.x]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 300.0\nmax_accel_mm_s2 = 3000.0\n\
             [axes.y]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 300.0\nmax_accel_mm_s2 = 3000.0\n\
             [planner]\njunction_deviation_mm = 0.02\narc_tolerance_mm = 0.01\n",
        )
        .unwrap()
    }

    #[test]
    fn a_program_is_drawn_in_mm_and_costed_per_line() {
        let text = "G21 G90\nG0 X10\nG1 Y5 F600\n; done\nG1 X0 Y0\nM2\n";
        let program = Program::from_text("p.gcode", "m.toml", plotter(), text).unwrap();
        assert_eq!(program.line_count(), 6);
        assert_eq!(program.view_axes, [Some(0), Some(1)]);
        assert_eq!(program.segments.len(), 3);
        assert_eq!(program.segments[0].to_mm, [10.0, 0.0]);
        assert!(program.segments[0].rapid);
        assert_eq!(program.segments[1].from_mm, [10.0, 0.0]);
        assert_eq!(program.segments[1].to_mm, [10.0, 5.0]);
        // G0 at the axes' top speed, 10 mm at 300 mm/s; 5 mm at 10 mm/s.
        let rapid = program.line_costs[1];
        assert!((rapid.length_mm - 10.0).abs() < 1e-9);
        assert!((rapid.time_s - 10.0 / 300.0).abs() < 1e-9);
        assert_eq!(rapid.mm_per_step, 1.0 / 80.0);
        assert!((program.line_costs[2].time_s - 0.5).abs() < 1e-9);
        assert_eq!(program.line_costs[3], LineCost::default());
        let (rest, _) = program.cost_from(3);
        assert!((rest - (5.0 + 125f64.sqrt())).abs() < 1e-9, "{rest}");
    }

    #[test]
    fn every_error_of_the_file_is_listed_with_its_line_and_column() {
        let text = "G1 X1 F100\nG1 X2 M3\nG1 Q4\nG1 X3\n";
        let error = Program::from_text("bad.gcode", "m.toml", plotter(), text).unwrap_err();
        let lines = error.report_lines();
        assert_eq!(
            lines[0],
            "bad.gcode: 2 errors in the G-code; nothing was run"
        );
        assert!(lines[1].starts_with("bad.gcode:2:7: "), "{lines:?}");
        assert!(lines[2].starts_with("bad.gcode:3:4: "), "{lines:?}");
        assert_eq!(lines.len(), 3);
    }
}

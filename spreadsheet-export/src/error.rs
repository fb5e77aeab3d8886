//! Why an export failed. Every variant ends the run with exit code 2 and
//! leaves no output file behind.

use std::path::PathBuf;

use driver::profile::PlanError;

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The command line did not parse (clap's message, on one line).
    #[error("{0}")]
    Usage(String),
    /// `--steps 0`.
    #[error("--steps must not be 0 (a move has at least one step)")]
    ZeroSteps,
    /// More steps than one move can hold.
    #[error("--steps {0} is too large: one move has at most 4294967295 steps")]
    TooManySteps(i64),
    /// Zero, negative or not a number.
    #[error("--speed must be a positive number of steps/s, got {0}")]
    BadSpeed(f64),
    /// The S-curve runs at a whole number of steps/s.
    #[error("the S-curve takes a whole number of steps/s up to 4294967295, got {0}")]
    FractionalSpeed(f64),
    /// Zero, negative or not a number.
    #[error("--accel must be a positive number of steps/s², got {0}")]
    BadAccel(f64),
    /// austin, leib and trapezoid need an acceleration.
    #[error("--profile {0} needs --accel (steps/s²)")]
    MissingAccel(&'static str),
    /// The profile refused the move.
    #[error("cannot plan the move: {0}")]
    Plan(#[from] PlanError),
    /// XLSX cannot go to stdout.
    #[error("--format xlsx needs an output file: add -o PATH.xlsx")]
    XlsxNeedsPath,
    /// An XLSX sheet has 1,048,576 rows, one of them the header.
    #[error(
        "a move of {steps} steps does not fit in an XLSX sheet (at most {max} steps); export it as CSV"
    )]
    TooManyRowsForXlsx {
        /// Steps in the move.
        steps: u32,
        /// Steps one sheet holds.
        max: u32,
    },
    /// `--plot` with another extension.
    #[error("--plot needs a file name ending in .png or .svg, got {}", .0.display())]
    PlotExtension(PathBuf),
    /// The motor file could not be read or is not valid.
    #[error("motor file {}: {reason}", path.display())]
    Motor {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A figure computed from the motor file is infinite or not a number.
    #[error(
        "motor file {}: the {what} at step {step} is not a finite number: the file's figures are out of the range the model computes in",
        path.display()
    )]
    NotFinite {
        /// The file.
        path: PathBuf,
        /// The step.
        step: u32,
        /// Which figure.
        what: &'static str,
    },
    /// The move runs faster than the motor's torque curve reaches.
    #[error(
        "motor file {}: step {step} runs at {rate_steps_per_s:.1} steps/s, beyond the torque curve's last point ({last_steps_per_s} steps/s)",
        path.display()
    )]
    BeyondTorqueCurve {
        /// The file.
        path: PathBuf,
        /// The step.
        step: u32,
        /// Its step rate.
        rate_steps_per_s: f64,
        /// The curve's last speed.
        last_steps_per_s: f64,
    },
    /// The move's top speed is beyond the motor's torque curve.
    #[error(
        "motor file {}: the move reaches {top_steps_per_s} steps/s, beyond the torque curve's last point ({last_steps_per_s} steps/s)",
        path.display()
    )]
    TopSpeedBeyondTorqueCurve {
        /// The file.
        path: PathBuf,
        /// The move's top speed.
        top_steps_per_s: f64,
        /// The curve's last speed.
        last_steps_per_s: f64,
    },
    /// Two outputs name the same file.
    #[error(
        "{first} and {second} name the same file ({}): each output needs its own file",
        path.display()
    )]
    OutputClash {
        /// The first flag (`-o`, `--vcd`, `--plot`).
        first: &'static str,
        /// The second.
        second: &'static str,
        /// The second's path, as given.
        path: PathBuf,
    },
    /// The table goes to stdout, which is closed.
    #[error("standard output is closed: the table has nowhere to go (give -o FILE)")]
    StdoutClosed,
    /// Writing an output failed.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The destination (`-` for stdout).
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The XLSX library refused.
    #[error("cannot write {}: {reason}", path.display())]
    Xlsx {
        /// The destination.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// `--vcd` runs the move on the hub, whose cogs run the S-curve.
    #[error(
        "--vcd runs the move on the emulated hub, whose cogs run the P2 S-curve: use --profile p2 or p2-exact (not {0})"
    )]
    VcdNeedsScurve(&'static str),
    /// The hub's `move` takes a 32-bit signed step count.
    #[error("--vcd: the hub moves at most 2147483647 steps at once, got --steps {0}")]
    VcdTooManySteps(i64),
    /// The hub refused the move.
    #[error("--vcd: the emulated hub cannot run this move: {0}")]
    VcdMove(String),
    /// `--together` takes 1 to 8 step counts.
    #[error("--together takes 1 to 8 comma-separated step counts, got {0}")]
    TogetherAxes(usize),
    /// `--together` runs on the hub, whose cogs run the S-curve.
    #[error(
        "--together runs the move on the emulated hub, whose cogs run the P2 S-curve: use --profile p2 or p2-exact (not {0})"
    )]
    TogetherNeedsScurve(&'static str),
    /// `--together` writes its table as CSV only, and not with the
    /// single-move flags.
    #[error("--together writes a CSV table: {0}")]
    TogetherFlags(&'static str),
    /// The hub refused the group move.
    #[error("--together: the emulated hub cannot run this group move: {0}")]
    TogetherMove(String),
    /// The machine file (`gcode --machine`) could not be read or is not valid.
    #[error("machine file {}: {reason}", path.display())]
    MachineFile {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// The G-code program could not be read.
    #[error("{}: {reason}", path.display())]
    Program {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// An error in the G-code program: the run stopped at it.
    #[error("{}: {error}", path.display())]
    Gcode {
        /// The program.
        path: PathBuf,
        /// The line, column and what is wrong.
        error: cogstep_gcode::GcodeError,
    },
    /// `gcode --check` found errors (each is reported on its own line).
    #[error("{}: {count} error(s) in the program", path.display())]
    GcodeCheck {
        /// The program.
        path: PathBuf,
        /// How many.
        count: usize,
    },
    /// The path runner refused a line of the program.
    #[error("the path runner cannot run the program: {0}")]
    GcodeRun(String),
    /// More rows than an XLSX sheet holds.
    #[error("the program's table has more than {0} rows, more than an XLSX sheet holds; export it as CSV")]
    GcodeXlsxRows(u32),
    /// The plot could not be drawn.
    #[error("cannot draw the plot {}: {reason}", path.display())]
    Plot {
        /// The destination.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

impl ExportError {
    /// The process exit code for this error.
    pub fn exit_code(&self) -> i32 {
        2
    }
}

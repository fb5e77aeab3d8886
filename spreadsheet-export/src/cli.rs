//! The command line: flags, defaults, and what they mean together.

use std::path::{Path, PathBuf};

use clap::{Args, Parser, Subcommand, ValueEnum};

use driver::profile::scurve::Arithmetic;

use crate::error::ExportError;
use crate::together::TogetherRequest;

/// Per-step table of a cogstep move as CSV or XLSX, with optional plot,
/// motor torque check and rotor dynamics.
///
/// Exit codes: 0 done, 2 bad input or output error (nothing left behind),
/// 3 the motor check's margin fell below the motor file's safety factor,
/// 4 the rotor lost synchronism (--dynamics; ahead of 3).
///
/// `spreadsheet-export compare --motor M --steps N --speed S [--accel A]
/// [--fastest]` compares every profile on one move and motor (see
/// `compare --help`); `spreadsheet-export gcode FILE --machine M.toml`
/// runs a G-code program (see `gcode --help`).
#[derive(Clone, Debug, Parser)]
#[command(
    name = "spreadsheet-export",
    version,
    allow_negative_numbers = true,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
pub struct Cli {
    /// A subcommand instead of an export.
    #[command(subcommand)]
    pub command: Option<Command>,

    /// Steps to move; negative means reverse (velocity, acceleration and
    /// torque are then negative).
    #[arg(long, allow_hyphen_values = true, required_unless_present = "together")]
    pub steps: Option<i64>,

    /// A coordinated move instead: each axis's signed steps, comma-separated
    /// (1 to 8 axes, 0 allowed), the longest leading at --speed. Writes a
    /// CSV table with one position column per axis against time and each
    /// row's deviation from the line (see the README).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        value_name = "STEPS,STEPS,...",
        conflicts_with_all = ["steps", "motor", "plot", "vcd", "accel"]
    )]
    pub together: Option<Vec<i32>>,

    /// Top speed, steps/s (a whole number for the S-curve profiles).
    #[arg(long, allow_hyphen_values = true, required = true)]
    pub speed: Option<f64>,

    /// Motion profile.
    #[arg(long, value_enum, default_value_t = ProfileKind::P2)]
    pub profile: ProfileKind,

    /// Acceleration, steps/s² (required by austin, leib and trapezoid).
    #[arg(long, allow_hyphen_values = true)]
    pub accel: Option<f64>,

    /// System clock, Hz.
    #[arg(long, default_value_t = 200_000_000)]
    pub clkfreq: u32,

    /// S-curve: where the ramp starts on the cosine, degrees (1–89).
    #[arg(long, default_value_t = 40)]
    pub offset: u32,

    /// S-curve: acceleration divisor (accel steps = speed / D + 2).
    #[arg(long = "accel-div", default_value_t = 10)]
    pub accel_div: u32,

    /// Output file; CSV goes to stdout without it.
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,

    /// Table format; by default it follows the extension of -o (.xlsx or CSV).
    #[arg(long, value_enum)]
    pub format: Option<Format>,

    /// Plot of velocity and acceleration against time (.png or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,

    /// Motor description (TOML): adds torque columns and a margin check.
    #[arg(long)]
    pub motor: Option<PathBuf>,

    /// With --motor: run the rotor model (columns rotor_angle_deg,
    /// rotor_lag_steps, synchronous; exit code 4 when synchronism is lost).
    #[arg(long, requires = "motor")]
    pub dynamics: bool,

    /// Also run the move on the emulated hub (virtual time, S-curve
    /// profiles) and write every pin's edges to this VCD file (GTKWave,
    /// PulseView). Without -o only the VCD is written.
    #[arg(long, value_name = "FILE")]
    pub vcd: Option<PathBuf>,

    /// The axis's outputs in the VCD: step/dir (sd) or cw/ccw (cc).
    #[arg(long, value_enum, default_value_t = OutputsArg::Sd, requires = "vcd")]
    pub outputs: OutputsArg,
}

/// The output variants `--outputs` offers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OutputsArg {
    /// A step pin and a direction pin.
    Sd,
    /// A clockwise pin and a counter-clockwise pin.
    Cc,
}

/// The subcommands.
#[derive(Clone, Debug, Subcommand)]
pub enum Command {
    /// Every profile on one move and motor, a CSV line each: time, peak
    /// torque, smallest margin, largest rotor lag, synchronism; with
    /// --fastest, the fastest setting that keeps synchronism.
    Compare(CompareArgs),
    /// A G-code program through the look-ahead planner, in virtual time:
    /// one row per tick at which an axis steps (time_s, line, each axis's
    /// steps and mm, feed_mm_s), and a summary on stderr.
    Gcode(GcodeArgs),
}

/// `gcode`'s flags.
#[derive(Clone, Debug, Args)]
pub struct GcodeArgs {
    /// The G-code program.
    pub file: PathBuf,

    /// The machine file (TOML: axes, limits, planner settings).
    #[arg(long)]
    pub machine: PathBuf,

    /// Output file (.csv or .xlsx); CSV goes to stdout without it (none
    /// with only --vcd or --plot).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,

    /// Table format; by default it follows the extension of -o.
    #[arg(long, value_enum)]
    pub format: Option<Format>,

    /// Every axis's step and direction pins as a VCD file.
    #[arg(long, value_name = "FILE")]
    pub vcd: Option<PathBuf>,

    /// The XY path coloured by speed, and speed against time (.png or .svg).
    #[arg(long)]
    pub plot: Option<PathBuf>,

    /// Stop at the end of every line (G61 throughout), for comparison.
    #[arg(long)]
    pub exact_stop: bool,

    /// Interpret the whole program and list every error; run nothing.
    #[arg(long, conflicts_with_all = ["output", "format", "vcd", "plot", "exact_stop"])]
    pub check: bool,

    /// The system clock the CT counts (Hz).
    #[arg(long, default_value_t = 200_000_000)]
    pub clkfreq: u32,
}

impl GcodeArgs {
    /// The checked request.
    pub fn into_request(self) -> Result<crate::gcode::GcodeRequest, ExportError> {
        let format = table_format(self.format, self.output.as_deref())?;
        let plot = plot_format(self.plot)?;
        if self.clkfreq < 1_000 {
            return Err(ExportError::Usage(
                "--clkfreq must be at least 1000 Hz (see --help)".into(),
            ));
        }
        Ok(crate::gcode::GcodeRequest {
            program: self.file,
            machine: self.machine,
            output: self.output,
            format,
            vcd: self.vcd,
            plot,
            exact_stop: self.exact_stop,
            clkfreq: self.clkfreq,
        })
    }
}

/// `compare`'s flags.
#[derive(Clone, Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct CompareArgs {
    /// Motor description (TOML), with damping_nm_s_per_rad for the rotor
    /// model.
    #[arg(long)]
    pub motor: PathBuf,

    /// Steps to move; negative means reverse.
    #[arg(long, allow_hyphen_values = true)]
    pub steps: i64,

    /// Top speed, steps/s (a whole number: the S-curves take it too).
    #[arg(long, allow_hyphen_values = true)]
    pub speed: f64,

    /// Acceleration of austin, leib and trapezoid, steps/s²; without it they
    /// take the P2 S-curve's (its speed reached in as many steps).
    #[arg(long, allow_hyphen_values = true)]
    pub accel: Option<f64>,

    /// Also search, per profile, the fastest speed (and acceleration) that
    /// keeps synchronism with every torque divided by the motor file's
    /// safety factor.
    #[arg(long)]
    pub fastest: bool,

    /// System clock, Hz.
    #[arg(long, default_value_t = 200_000_000)]
    pub clkfreq: u32,

    /// S-curve: where the ramp starts on the cosine, degrees (1–89).
    #[arg(long, default_value_t = 40)]
    pub offset: u32,

    /// S-curve: acceleration divisor (accel steps = speed / D + 2).
    #[arg(long = "accel-div", default_value_t = 10)]
    pub accel_div: u32,
}

/// The profiles `--profile` offers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ProfileKind {
    /// P2 cosine S-curve, cogstep's smooth arithmetic.
    P2,
    /// P2 cosine S-curve, the reference driver's integer arithmetic.
    #[value(name = "p2-exact")]
    P2Exact,
    /// Austin (2004) real-time linear ramp.
    Austin,
    /// Leib (Eiderman) ramp.
    Leib,
    /// Exact trapezoid from its closed form.
    Trapezoid,
}

impl ProfileKind {
    /// The name used on the command line and in the XLSX summary.
    pub fn as_str(self) -> &'static str {
        match self {
            ProfileKind::P2 => "p2",
            ProfileKind::P2Exact => "p2-exact",
            ProfileKind::Austin => "austin",
            ProfileKind::Leib => "leib",
            ProfileKind::Trapezoid => "trapezoid",
        }
    }

    /// Whether the profile is the S-curve (angle, offset, divisor apply).
    pub fn is_scurve(self) -> bool {
        matches!(self, ProfileKind::P2 | ProfileKind::P2Exact)
    }
}

/// Table formats.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Format {
    /// Comma-separated values.
    Csv,
    /// Excel workbook: the table, charts and a summary sheet.
    Xlsx,
}

/// Where the plot goes and in which format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PlotFormat {
    /// Raster image.
    Png,
    /// Vector image.
    Svg,
}

/// The checked meaning of a command line.
#[derive(Clone, Debug, PartialEq)]
pub struct Request {
    /// The profile to run.
    pub profile: ProfileKind,
    /// Step count, magnitude.
    pub steps: u32,
    /// +1.0 forward, −1.0 reverse.
    pub direction: f64,
    /// Top speed, steps/s (> 0, finite).
    pub speed_steps_per_s: f64,
    /// Acceleration, steps/s², for the profiles that take one.
    pub accel_steps_per_s2: Option<f64>,
    /// System clock, Hz.
    pub clkfreq: u32,
    /// S-curve offset, degrees.
    pub offset_deg: u32,
    /// S-curve acceleration divisor.
    pub accel_div: u32,
    /// Table destination: `None` is stdout.
    pub output: Option<PathBuf>,
    /// Table format.
    pub format: Format,
    /// Plot destination and format.
    pub plot: Option<(PathBuf, PlotFormat)>,
    /// Motor file.
    pub motor: Option<PathBuf>,
    /// Run the rotor model (needs `motor`).
    pub dynamics: bool,

    /// `--vcd`: the VCD file and the axis's outputs.
    pub vcd: Option<(PathBuf, OutputsArg)>,
}

impl Cli {
    /// Checks the flags against each other (profile-specific checks happen
    /// when the profile is built).
    pub fn into_request(self) -> Result<Request, ExportError> {
        let (Some(signed_steps), Some(speed)) = (self.steps, self.speed) else {
            return Err(ExportError::Usage(
                "--steps and --speed are required (see --help)".into(),
            ));
        };
        let (steps, direction) = check_move(signed_steps, speed, self.accel)?;
        let format = table_format(self.format, self.output.as_deref())?;
        let plot = plot_format(self.plot)?;
        if self.vcd.is_some() {
            if !self.profile.is_scurve() {
                return Err(ExportError::VcdNeedsScurve(self.profile.as_str()));
            }
            if i32::try_from(signed_steps.unsigned_abs()).is_err() {
                return Err(ExportError::VcdTooManySteps(signed_steps));
            }
        }
        Ok(Request {
            profile: self.profile,
            steps,
            direction,
            speed_steps_per_s: speed,
            accel_steps_per_s2: self.accel,
            clkfreq: self.clkfreq,
            offset_deg: self.offset,
            accel_div: self.accel_div,
            output: self.output,
            format,
            plot,
            motor: self.motor,
            dynamics: self.dynamics,
            vcd: self.vcd.map(|path| (path, self.outputs)),
        })
    }
}

/// Steps (magnitude, direction) once checked with the speed and
/// acceleration.
fn check_move(steps: i64, speed: f64, accel: Option<f64>) -> Result<(u32, f64), ExportError> {
    if steps == 0 {
        return Err(ExportError::ZeroSteps);
    }
    let magnitude =
        u32::try_from(steps.unsigned_abs()).map_err(|_| ExportError::TooManySteps(steps))?;
    if !(speed.is_finite() && speed > 0.0) {
        return Err(ExportError::BadSpeed(speed));
    }
    if let Some(accel) = accel {
        if !(accel.is_finite() && accel > 0.0) {
            return Err(ExportError::BadAccel(accel));
        }
    }
    Ok((magnitude, if steps < 0 { -1.0 } else { 1.0 }))
}

impl Cli {
    /// `--together`'s request, when the flag is given.
    pub fn together_request(&self) -> Option<Result<TogetherRequest, ExportError>> {
        let steps = self.together.clone()?;
        Some(self.check_together(steps))
    }

    fn check_together(&self, steps: Vec<i32>) -> Result<TogetherRequest, ExportError> {
        if steps.is_empty() || steps.len() > crate::together::AXES_MAX {
            return Err(ExportError::TogetherAxes(steps.len()));
        }
        let arithmetic = match self.profile {
            ProfileKind::P2 => Arithmetic::Smooth,
            ProfileKind::P2Exact => Arithmetic::P2Exact,
            other => return Err(ExportError::TogetherNeedsScurve(other.as_str())),
        };
        let Some(speed) = self.speed else {
            return Err(ExportError::Usage(
                "--speed is required (see --help)".into(),
            ));
        };
        if !(speed.is_finite() && speed > 0.0) {
            return Err(ExportError::BadSpeed(speed));
        }
        if speed.fract() != 0.0 || speed > f64::from(u32::MAX) {
            return Err(ExportError::FractionalSpeed(speed));
        }
        if self.format == Some(Format::Xlsx)
            || (self.format.is_none()
                && self
                    .output
                    .as_deref()
                    .is_some_and(|path| has_extension(path, "xlsx")))
        {
            return Err(ExportError::TogetherFlags("no XLSX"));
        }
        if self.dynamics {
            return Err(ExportError::TogetherFlags("no --dynamics"));
        }
        Ok(TogetherRequest {
            steps,
            speed_steps_per_s: speed as u32,
            arithmetic,
            clkfreq: self.clkfreq,
            offset_deg: self.offset,
            accel_div: self.accel_div,
        })
    }
}

impl CompareArgs {
    /// The move every profile makes, as an export request (profile P2,
    /// CSV to stdout, with the motor and its dynamics).
    pub fn into_request(self) -> Result<(Request, bool), ExportError> {
        let (steps, direction) = check_move(self.steps, self.speed, self.accel)?;
        let request = Request {
            profile: ProfileKind::P2,
            steps,
            direction,
            speed_steps_per_s: self.speed,
            accel_steps_per_s2: self.accel,
            clkfreq: self.clkfreq,
            offset_deg: self.offset,
            accel_div: self.accel_div,
            output: None,
            format: Format::Csv,
            plot: None,
            motor: Some(self.motor),
            dynamics: true,
            vcd: None,
        };
        Ok((request, self.fastest))
    }
}

fn has_extension(path: &Path, extension: &str) -> bool {
    path.extension()
        .and_then(|found| found.to_str())
        .is_some_and(|found| found.eq_ignore_ascii_case(extension))
}

/// The table's format: as asked, or from the output's extension (XLSX
/// needs a file).
fn table_format(asked: Option<Format>, output: Option<&Path>) -> Result<Format, ExportError> {
    let format = match (asked, output) {
        (Some(format), _) => format,
        (None, Some(path)) if has_extension(path, "xlsx") => Format::Xlsx,
        (None, _) => Format::Csv,
    };
    if format == Format::Xlsx && output.is_none() {
        return Err(ExportError::XlsxNeedsPath);
    }
    Ok(format)
}

/// The plot's file and format, from its extension (PNG or SVG).
fn plot_format(plot: Option<PathBuf>) -> Result<Option<(PathBuf, PlotFormat)>, ExportError> {
    let Some(path) = plot else {
        return Ok(None);
    };
    let format = if has_extension(&path, "png") {
        PlotFormat::Png
    } else if has_extension(&path, "svg") {
        PlotFormat::Svg
    } else {
        return Err(ExportError::PlotExtension(path));
    };
    Ok(Some((path, format)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(args: &[&str]) -> Result<Request, ExportError> {
        let mut full = vec!["spreadsheet-export"];
        full.extend_from_slice(args);
        Cli::try_parse_from(full)
            .map_err(|error| ExportError::Usage(error.to_string()))?
            .into_request()
    }

    #[test]
    fn dynamics_needs_a_motor_and_compare_is_a_subcommand() {
        assert!(matches!(
            parse(&["--steps", "9", "--speed", "9", "--dynamics"]),
            Err(ExportError::Usage(_))
        ));
        let request = parse(&[
            "--steps",
            "9",
            "--speed",
            "9",
            "--motor",
            "m.toml",
            "--dynamics",
        ])
        .unwrap();
        assert!(request.dynamics);
        let cli = Cli::try_parse_from([
            "spreadsheet-export",
            "compare",
            "--motor",
            "m.toml",
            "--steps",
            "-2000",
            "--speed",
            "4000",
            "--fastest",
        ])
        .unwrap();
        let Some(Command::Compare(args)) = cli.command else {
            panic!("compare");
        };
        let (request, fastest) = args.into_request().unwrap();
        assert!(fastest);
        assert_eq!((request.steps, request.direction), (2_000, -1.0));
        assert_eq!(request.accel_steps_per_s2, None);
        // An export's flags and a subcommand do not mix.
        assert!(Cli::try_parse_from([
            "spreadsheet-export",
            "--steps",
            "9",
            "compare",
            "--motor",
            "m.toml",
            "--steps",
            "9",
            "--speed",
            "9"
        ])
        .is_err());
        assert!(Cli::try_parse_from(["spreadsheet-export", "compare", "--steps", "9"]).is_err());
    }

    #[test]
    fn defaults_follow_the_issue() {
        let request = parse(&["--steps", "100", "--speed", "2000"]).unwrap();
        assert_eq!(request.profile, ProfileKind::P2);
        assert_eq!(request.clkfreq, 200_000_000);
        assert_eq!(request.offset_deg, 40);
        assert_eq!(request.accel_div, 10);
        assert_eq!(request.format, Format::Csv);
        assert_eq!(request.output, None);
    }

    #[test]
    fn negative_steps_reverse() {
        let request = parse(&["--steps", "-20000", "--speed", "20000"]).unwrap();
        assert_eq!((request.steps, request.direction), (20_000, -1.0));
    }

    #[test]
    fn format_follows_extension_unless_told() {
        let xlsx = parse(&["--steps", "9", "--speed", "9", "-o", "a.XLSX"]).unwrap();
        assert_eq!(xlsx.format, Format::Xlsx);
        let csv = parse(&["--steps", "9", "--speed", "9", "-o", "a.txt"]).unwrap();
        assert_eq!(csv.format, Format::Csv);
        let told = parse(&[
            "--steps", "9", "--speed", "9", "-o", "a.xlsx", "--format", "csv",
        ]);
        assert_eq!(told.unwrap().format, Format::Csv);
    }

    #[test]
    fn bad_flags_are_refused() {
        assert!(matches!(
            parse(&["--steps", "0", "--speed", "9"]),
            Err(ExportError::ZeroSteps)
        ));
        assert!(matches!(
            parse(&["--steps", "9", "--speed", "-5"]),
            Err(ExportError::BadSpeed(_))
        ));
        assert!(matches!(
            parse(&["--steps", "9", "--speed", "0"]),
            Err(ExportError::BadSpeed(_))
        ));
        assert!(matches!(
            parse(&["--steps", "9", "--speed", "9", "--format", "xlsx"]),
            Err(ExportError::XlsxNeedsPath)
        ));
        assert!(matches!(
            parse(&["--steps", "9", "--speed", "9", "--plot", "a.jpg"]),
            Err(ExportError::PlotExtension(_))
        ));
        assert!(matches!(
            parse(&["--steps", "9999999999", "--speed", "9"]),
            Err(ExportError::TooManySteps(_))
        ));
        assert!(matches!(
            parse(&["--steps", "9", "--speed", "9", "--profile", "bogus"]),
            Err(ExportError::Usage(_))
        ));
        assert!(matches!(
            parse(&[
                "--steps",
                "9",
                "--speed",
                "9",
                "--profile",
                "leib",
                "--vcd",
                "a.vcd"
            ]),
            Err(ExportError::VcdNeedsScurve("leib"))
        ));
        assert!(matches!(
            parse(&["--steps", "-2147483648", "--speed", "9", "--vcd", "a.vcd"]),
            Err(ExportError::VcdTooManySteps(-2_147_483_648))
        ));
    }

    fn together(args: &[&str]) -> Result<TogetherRequest, ExportError> {
        let mut full = vec!["spreadsheet-export"];
        full.extend_from_slice(args);
        Cli::try_parse_from(full)
            .map_err(|error| ExportError::Usage(error.to_string()))?
            .together_request()
            .expect("--together given")
    }

    #[test]
    fn together_takes_one_steps_per_axis() {
        let request = together(&["--together", "12000,-4000,0", "--speed", "20000"]).unwrap();
        assert_eq!(request.steps, [12_000, -4_000, 0]);
        assert_eq!(request.speed_steps_per_s, 20_000);
        assert_eq!(request.arithmetic, Arithmetic::Smooth);
        let exact = together(&["--together=-5,7", "--speed", "900", "--profile", "p2-exact"]);
        assert_eq!(exact.unwrap().arithmetic, Arithmetic::P2Exact);
        assert!(matches!(
            together(&["--together", "1,2,3,4,5,6,7,8,9", "--speed", "9"]),
            Err(ExportError::TogetherAxes(9))
        ));
        assert!(matches!(
            together(&["--together", "1,2", "--speed", "9", "--profile", "leib"]),
            Err(ExportError::TogetherNeedsScurve("leib"))
        ));
        assert!(matches!(
            together(&["--together", "1,2", "--speed", "9.5"]),
            Err(ExportError::FractionalSpeed(_))
        ));
        assert!(matches!(
            together(&["--together", "1,2", "--speed", "9", "-o", "a.xlsx"]),
            Err(ExportError::TogetherFlags(_))
        ));
        assert!(matches!(
            together(&["--together", "1,x", "--speed", "9"]),
            Err(ExportError::Usage(_))
        ));
        assert!(matches!(
            together(&["--together", "1,2", "--steps", "5", "--speed", "9"]),
            Err(ExportError::Usage(_))
        ));
    }

    #[test]
    fn vcd_takes_the_outputs() {
        let plain = parse(&["--steps", "9", "--speed", "9"]).unwrap();
        assert_eq!(plain.vcd, None);
        let sd = parse(&["--steps", "9", "--speed", "9", "--vcd", "m.vcd"]).unwrap();
        assert_eq!(sd.vcd, Some((PathBuf::from("m.vcd"), OutputsArg::Sd)));
        let cc = parse(&[
            "--steps",
            "9",
            "--speed",
            "9",
            "--vcd",
            "m.vcd",
            "--outputs",
            "cc",
        ]);
        assert_eq!(
            cc.unwrap().vcd,
            Some((PathBuf::from("m.vcd"), OutputsArg::Cc))
        );
        assert!(
            matches!(
                parse(&["--steps", "9", "--speed", "9", "--outputs", "cc"]),
                Err(ExportError::Usage(_))
            ),
            "--outputs without --vcd"
        );
    }
}

//! The command line.

use clap::{Parser, ValueEnum};
use driver::serial::host::DemoStart;

use crate::app::DEFAULT_JOG_SPEED;
use crate::motor_view::{parse_motor_spec, MotorSpec};

/// cogstep's terminal demo: emulated P2 stepper axes (or a real board),
/// driven live.
///
/// Answer `Enter steps:` (signed) and `Enter speed:` (steps/s) to move the
/// selected axis; watch position, STM, mode and the velocity S-curve as it
/// runs. `g` asks `Group steps:` instead (one signed number per axis, axis 1
/// first, spaces between) and then the speed: a coordinated move of all the
/// axes on one straight line. Keys: Tab/1-8 select the axis, s stop (stop
/// pin low), x emergency stop of all axes, ←/→ held jog, +/- jog speed, q
/// quit. Digits always go
/// to the prompt: on an empty steps prompt a lone 1-8 selects that axis
/// (and a lone - lowers the jog speed) after a 0.6 s pause.
///
/// `--gcode FILE --machine M.toml` runs a G-code program instead, on the
/// emulated hub in real time (one axis per axis of the machine file): the
/// whole file is checked first (every error listed with its line and
/// column, exit status 1, nothing moves), then it runs along a look-ahead
/// path with an XY view of the path and the tool. Keys: space or s hold,
/// r (or space once held) resumes, c or Esc cancels, +/- feed override,
/// x emergency stop, q quits. With `--serial PORT --dialect grbl` instead
/// of `--machine`, the program streams to a grbl board (character
/// counting), checked first against the machine its `$$` describes.
#[derive(Clone, Debug, Parser)]
#[command(name = "demo-tui", version, about, long_about)]
pub struct Cli {
    /// How many emulated axes (cogs), 1 to 8. Odd-numbered axes drive
    /// step/dir (sd) outputs, even-numbered ones cw/ccw (cc).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(1..=8))]
    pub axes: u8,

    /// The jog speed at start, steps/s (+ and - change it while running).
    #[arg(long, value_name = "STEPS_PER_S", default_value_t = DEFAULT_JOG_SPEED,
          value_parser = clap::value_parser!(u32).range(1..=150_000))]
    pub jog_speed: u32,

    /// Drive a board on this serial port instead of the emulation.
    #[arg(long, value_name = "PORT")]
    pub serial: Option<String>,

    /// The serial port's baud rate (with --serial), 1 or more (0 would
    /// ask the port to hang up).
    #[arg(long, requires = "serial", default_value_t = 115_200,
          value_parser = clap::value_parser!(u32).range(1..))]
    pub baud: u32,

    /// What the board speaks (with --serial): the cogstep line protocol,
    /// the P2 reference demo's screens (where stop and jog are pins, not
    /// commands), or grbl 1.1 (any grbl board, cogstep's included: the stop
    /// key is its feed hold, x its soft reset; with --gcode the program
    /// streams to it).
    #[arg(long, requires = "serial", value_enum, default_value_t = DialectArg::Cogstep)]
    pub dialect: DialectArg,

    /// Record every pin of every axis (step/dir or cw/ccw, and the stop
    /// pins) for the whole session to this VCD file, streamed as it goes
    /// (GTKWave, PulseView). Emulated hub only: a board over --serial
    /// reports no pin edges.
    #[arg(long, value_name = "FILE")]
    pub record: Option<std::path::PathBuf>,

    /// How to reach a known prompt on a P2 demo board, which reads every
    /// byte as part of an answer: passive (send nothing, wait for a screen;
    /// a board idle at a prompt cannot be connected), powered-up (the board
    /// was just powered up: press its first key), or reset (a DTR/RTS
    /// pulse first: restarts the program from flash, so a program loaded
    /// into RAM only is lost).
    #[arg(long, requires = "serial", value_name = "HOW", default_value_t = DemoStart::Passive,
          value_parser = clap::value_parser!(DemoStart))]
    pub p2demo_start: DemoStart,

    /// A virtual motor behind the pins (a spreadsheet-export motor file with
    /// damping_nm_s_per_rad): FILE for every axis, AXIS=FILE for one
    /// (repeatable). The selected axis then shows its rotor lag, or "LOST
    /// SYNCHRONISM at step N". Not with --record (both read the hub's
    /// edges; one at a time).
    #[arg(long, value_name = "[AXIS=]FILE", value_parser = parse_motor_spec,
          conflicts_with_all = ["serial", "record"])]
    pub motor: Vec<MotorSpec>,

    /// Run this G-code program: with --machine on the emulated hub, along
    /// its look-ahead path; with --serial PORT --dialect grbl on a grbl
    /// board, streamed by character counting (the board plans), the
    /// machine read from the board's `$$`. It is checked whole first.
    /// Not with --axes (the machine gives the axes), --motor or --record.
    #[arg(long, value_name = "FILE",
          conflicts_with_all = ["axes", "motor", "record"])]
    pub gcode: Option<std::path::PathBuf>,

    /// The machine file for --gcode (TOML: per axis letter steps_per_mm,
    /// max_speed_mm_s, max_accel_mm_s2, soft limits; a `[planner]` table), e.g.
    /// spreadsheet-export/machines/plotter.toml. Not with --serial (a grbl
    /// board's `$$` is its machine).
    #[arg(long, value_name = "M.toml", requires = "gcode")]
    pub machine: Option<std::path::PathBuf>,

    /// Do not ask the terminal to report key releases (kitty keyboard
    /// protocol): a jog then ends only by its 150 ms heartbeat timeout.
    #[arg(long)]
    pub no_key_release: bool,

    /// Panic this many ms after the start, to check that the terminal is
    /// restored (for the test suite; hidden from --help).
    #[arg(long, value_name = "MS", hide = true)]
    pub test_panic_after_ms: Option<u64>,
}

/// The dialects `--dialect` accepts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum DialectArg {
    /// The cogstep line protocol.
    Cogstep,
    /// The P2 reference driver's demo screens and prompts.
    P2demo,
    /// grbl 1.1's serial interface.
    Grbl,
}

impl DialectArg {
    /// The name on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            DialectArg::Cogstep => "cogstep",
            DialectArg::P2demo => "p2demo",
            DialectArg::Grbl => "grbl",
        }
    }
}

impl From<DialectArg> for driver::serial::host::Dialect {
    fn from(dialect: DialectArg) -> Self {
        match dialect {
            DialectArg::Cogstep => driver::serial::host::Dialect::Cogstep,
            DialectArg::P2demo => driver::serial::host::Dialect::P2Demo,
            DialectArg::Grbl => driver::serial::host::Dialect::Grbl,
        }
    }
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::*;

    #[test]
    fn the_test_only_panic_flag_is_not_in_the_help() {
        let help = Cli::command().render_long_help().to_string();
        assert!(!help.contains("panic"), "{help}");
        assert!(help.contains("--serial"));
        // It still works for the test suite.
        let cli = Cli::try_parse_from(["demo-tui", "--test-panic-after-ms", "5"]).expect("parse");
        assert_eq!(cli.test_panic_after_ms, Some(5));
    }

    #[test]
    fn the_command_line_is_consistent_and_bounded() {
        Cli::command().debug_assert();
        let cli = Cli::try_parse_from(["demo-tui"]).expect("defaults");
        assert_eq!(
            (cli.axes, cli.jog_speed, cli.serial),
            (4, DEFAULT_JOG_SPEED, None)
        );
        assert!(Cli::try_parse_from(["demo-tui", "--axes", "0"]).is_err());
        assert!(Cli::try_parse_from(["demo-tui", "--axes", "9"]).is_err());
        assert!(
            Cli::try_parse_from(["demo-tui", "--baud", "9600"]).is_err(),
            "needs --serial"
        );
        let cli = Cli::try_parse_from([
            "demo-tui",
            "--serial",
            "/dev/ttyUSB0",
            "--baud",
            "9600",
            "--dialect",
            "p2demo",
        ])
        .expect("serial");
        assert_eq!(cli.dialect, DialectArg::P2demo);
        assert_eq!(cli.baud, 9_600);
        let zero = Cli::try_parse_from(["demo-tui", "--serial", "/dev/ttyUSB0", "--baud", "0"])
            .expect_err("baud 0 refused");
        assert!(zero.to_string().contains("--baud"), "{zero}");
        assert_eq!(cli.p2demo_start, DemoStart::Passive);
        let cli = Cli::try_parse_from([
            "demo-tui",
            "--serial",
            "/dev/ttyUSB0",
            "--p2demo-start",
            "powered-up",
        ])
        .expect("serial");
        assert_eq!(cli.p2demo_start, DemoStart::PoweredUp);
    }
}

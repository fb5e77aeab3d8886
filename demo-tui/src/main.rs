//! `demo-tui`: the cogstep terminal demo. Thin: the command line, the
//! backend, the terminal session, the event loop (see the library docs).

use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Parser;
use driver::HubConfig;

use demo_tui::app::program::ProgramView;
use demo_tui::app::App;
use demo_tui::backend::{Emulated, Machine, RecordError, Serial};
use demo_tui::cli::{Cli, DialectArg};
use demo_tui::event_loop::{self, Ending, LoopOptions};
use demo_tui::grbl_program::{load_for_grbl, machine_from_settings, GrblProgram};
use demo_tui::motor_view::Motors;
use demo_tui::program::Program;
use demo_tui::program_backend::ProgramBackend;
use demo_tui::terminal::{self, Session, Termination};
use driver::serial::host::{Dialect, SerialBoard, SerialConfig};

/// Why the demo could not run.
#[derive(Debug, thiserror::Error)]
enum DemoError {
    #[error("the emulated hub would not start: {0}")]
    Hub(#[from] driver::HubError),
    #[error("serial port: {0}")]
    Serial(#[from] driver::serial::host::SerialError),
    #[error("terminal: {0}")]
    Terminal(#[from] std::io::Error),
    #[error("--motor: {0}")]
    Motor(String),
    #[error(transparent)]
    Record(#[from] RecordError),
    #[error(
        "--record needs the emulated hub: a board over --serial reports positions, not pin edges, so there is no waveform to record"
    )]
    RecordSerial,
    #[error(
        "--gcode over --serial needs a grbl board (--dialect grbl): a board of the {0} dialect takes no G-code"
    )]
    GcodeSerial(&'static str),
    #[error(
        "--machine runs the program on the emulated hub only: over --serial the board's $$ is the machine (leave --machine out, with --dialect grbl)"
    )]
    MachineSerial,
    #[error("--gcode needs --machine M.toml (the emulated hub) or --serial PORT --dialect grbl (a grbl board)")]
    GcodeWhere,
    #[error("the grbl board's machine: {0}")]
    GrblMachine(String),
    #[error("the program could not be streamed: {0}")]
    Stream(#[from] driver::serial::host::StreamError),
    #[error(transparent)]
    Program(#[from] demo_tui::program_backend::StartError),
}

/// How long the event loop has to end the demo in order once the terminal
/// hangs up, before the watch ends the process.
const HANG_UP_GRACE: Duration = Duration::from_millis(500);

fn main() -> ExitCode {
    let cli = Cli::parse();
    // stderr may be a terminal that has gone: `terminal::report` ignores that.
    let ran = match (&cli.gcode, &cli.machine, &cli.serial) {
        (Some(_), Some(_), Some(_)) => Err(DemoError::MachineSerial),
        (Some(gcode), Some(machine), None) => {
            // Checked whole before the terminal is touched: nothing moves.
            match Program::load(gcode, machine) {
                Ok(program) => ProgramBackend::start(&program)
                    .map_err(DemoError::from)
                    .and_then(|machine| run_program(&cli, program, Box::new(machine))),
                Err(error) => {
                    for line in error.report_lines() {
                        terminal::report(&line);
                    }
                    return ExitCode::FAILURE;
                }
            }
        }
        (Some(gcode), None, Some(port)) => match open_grbl_program(&cli, gcode, port) {
            Ok(Some((program, machine))) => run_program(&cli, program, machine),
            Ok(None) => return ExitCode::FAILURE,
            Err(error) => Err(error),
        },
        (Some(_), None, None) => Err(DemoError::GcodeWhere),
        _ => run(&cli),
    };
    match ran {
        Ok((Ending::Quit, Ok(()))) => ExitCode::SUCCESS,
        Ok((Ending::Signal(signal), _)) => {
            terminal::report("ended by a signal; terminal restored");
            ExitCode::from(terminal::signal_status(signal))
        }
        Ok((Ending::TerminalGone, _)) => {
            terminal::report("the terminal went away; ended");
            ExitCode::from(terminal::TERMINAL_GONE_STATUS)
        }
        Ok((Ending::Quit, Err(()))) => ExitCode::FAILURE,
        Err(e) => {
            terminal::report(&e.to_string());
            ExitCode::FAILURE
        }
    }
}

fn open_machine(cli: &Cli) -> Result<Box<dyn Machine + Send>, DemoError> {
    if let Some(port) = &cli.serial {
        if cli.record.is_some() {
            return Err(DemoError::RecordSerial);
        }
        return Ok(Box::new(Serial::open(
            port,
            cli.baud,
            cli.dialect.into(),
            cli.p2demo_start,
        )?));
    }
    let axes = usize::from(cli.axes);
    match &cli.record {
        Some(path) => Ok(Box::new(Emulated::start_recording(
            axes,
            path,
            HubConfig::default().trace_ring,
        )?)),
        // The motor models read the hub's edges as they come.
        None => Ok(Box::new(Emulated::start_with_edges(
            axes,
            !cli.motor.is_empty(),
        )?)),
    }
}

/// The loop's ending, and whether what the machine recorded was finished.
fn run(cli: &Cli) -> Result<(Ending, Result<(), ()>), DemoError> {
    let machine = open_machine(cli)?;
    let outputs: Vec<_> = (0..machine.info().axis_kinds.len())
        .map(|index| machine.outputs(index))
        .collect();
    let motors =
        Motors::load(&cli.motor, &outputs, machine.info().clkfreq_hz).map_err(DemoError::Motor)?;
    // The loop takes the machine to its own thread: end the recording here.
    let recording = machine.recording();
    let termination = Termination::install()?;
    terminal::install_panic_hook();
    let mut session = Session::enter()?;
    let unfinished = recording.clone();
    terminal::end_on_hang_up(&session.input, HANG_UP_GRACE, move || {
        if let Some(recording) = unfinished {
            let _ = recording.finish();
        }
    })?;
    let mut app = App::new(machine.info().clone(), cli.jog_speed, Instant::now());
    app.motors = motors;
    let options = LoopOptions {
        key_release: !cli.no_key_release,
        panic_after: cli.test_panic_after_ms.map(Duration::from_millis),
    };
    let ending = event_loop::run(&mut session, app, machine, &termination, options);
    // The terminal first, so that any message lands on the normal screen.
    drop(session);
    let ending = ending?;
    let finished = match recording.map_or(Ok(None), |recording| recording.finish()) {
        Ok(Some(line)) => {
            terminal::report(&line);
            Ok(())
        }
        Ok(None) => Ok(()),
        Err(error) => {
            terminal::report(&error.to_string());
            Err(())
        }
    };
    Ok((ending, finished))
}

/// A machine the app thread takes.
type BoxedMachine = Box<dyn Machine + Send>;

/// `--gcode FILE --serial PORT --dialect grbl`: opens the board, checks
/// the file whole against the machine its `$$` describes (`Ok(None)`
/// once the errors are reported: nothing was streamed), and starts
/// streaming it.
fn open_grbl_program(
    cli: &Cli,
    gcode: &std::path::Path,
    port: &str,
) -> Result<Option<(Program, BoxedMachine)>, DemoError> {
    if cli.dialect != DialectArg::Grbl {
        return Err(DemoError::GcodeSerial(cli.dialect.as_str()));
    }
    let mut config = SerialConfig::new(port);
    config.baud = cli.baud;
    config.dialect = Dialect::Grbl;
    let board = SerialBoard::open(config)?;
    let spec = machine_from_settings(&board.grbl_settings()).map_err(DemoError::GrblMachine)?;
    let machine_name = format!("grbl board on {port} ($$)");
    let program = match load_for_grbl(gcode, &machine_name, spec) {
        Ok(program) => program,
        Err(error) => {
            for line in error.report_lines() {
                terminal::report(&line);
            }
            board.close();
            return Ok(None);
        }
    };
    let machine = GrblProgram::start(board, program.clone())?;
    Ok(Some((program, Box::new(machine))))
}

/// `--gcode`: the program on a machine that runs it (the emulated hub,
/// or a grbl board), its own screen and keys.
fn run_program(
    cli: &Cli,
    program: Program,
    machine: BoxedMachine,
) -> Result<(Ending, Result<(), ()>), DemoError> {
    let termination = Termination::install()?;
    terminal::install_panic_hook();
    let mut session = Session::enter()?;
    terminal::end_on_hang_up(&session.input, HANG_UP_GRACE, || {})?;
    let mut app = App::new(machine.info().clone(), cli.jog_speed, Instant::now());
    app.program = Some(ProgramView::new(program));
    let options = LoopOptions {
        key_release: false,
        panic_after: cli.test_panic_after_ms.map(Duration::from_millis),
    };
    let ending = event_loop::run(&mut session, app, machine, &termination, options);
    drop(session);
    Ok((ending?, Ok(())))
}

//! `demo-tui`: the cogstep terminal demo. Thin: the command line, the
//! backend, the terminal session, the event loop (see the library docs).

use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Parser;
use driver::HubConfig;

use demo_tui::app::program::ProgramView;
use demo_tui::app::App;
use demo_tui::backend::{Emulated, Machine, RecordError, Serial};
use demo_tui::cli::Cli;
use demo_tui::event_loop::{self, Ending, LoopOptions};
use demo_tui::motor_view::Motors;
use demo_tui::program::Program;
use demo_tui::program_backend::ProgramBackend;
use demo_tui::terminal::{self, Session, Termination};

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
        "--gcode runs on the emulated hub only for now: a board over --serial has no look-ahead path yet"
    )]
    GcodeSerial,
    #[error(transparent)]
    Program(#[from] demo_tui::program_backend::StartError),
}

/// How long the event loop has to end the demo in order once the terminal
/// hangs up, before the watch ends the process.
const HANG_UP_GRACE: Duration = Duration::from_millis(500);

fn main() -> ExitCode {
    let cli = Cli::parse();
    // stderr may be a terminal that has gone: `terminal::report` ignores that.
    let ran = match (&cli.gcode, &cli.machine) {
        (Some(gcode), Some(machine)) => {
            if cli.serial.is_some() {
                terminal::report(&DemoError::GcodeSerial.to_string());
                return ExitCode::FAILURE;
            }
            // Checked whole before the terminal is touched: nothing moves.
            match Program::load(gcode, machine) {
                Ok(program) => run_program(&cli, program),
                Err(error) => {
                    for line in error.report_lines() {
                        terminal::report(&line);
                    }
                    return ExitCode::FAILURE;
                }
            }
        }
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

/// `--gcode`: the program on the emulated hub, its own screen and keys.
fn run_program(cli: &Cli, program: Program) -> Result<(Ending, Result<(), ()>), DemoError> {
    let machine = ProgramBackend::start(&program)?;
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
    let ending = event_loop::run(&mut session, app, Box::new(machine), &termination, options);
    drop(session);
    Ok((ending?, Ok(())))
}

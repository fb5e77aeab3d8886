//! `demo-tui`: the cogstep terminal demo. Thin: the command line, the
//! backend, the terminal session, the event loop (see the library docs).

use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Parser;

use demo_tui::app::App;
use demo_tui::backend::{Emulated, Machine, Serial};
use demo_tui::cli::Cli;
use demo_tui::event_loop::{self, Ending, LoopOptions};
use demo_tui::motor_view::Motors;
use demo_tui::terminal::{self, Session};

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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(&cli) {
        Ok(Ending::Quit) => ExitCode::SUCCESS,
        Ok(Ending::Signal) => {
            eprintln!("demo-tui: ended by a signal; terminal restored");
            ExitCode::from(143)
        }
        Err(e) => {
            eprintln!("demo-tui: {e}");
            ExitCode::FAILURE
        }
    }
}

fn open_machine(cli: &Cli) -> Result<Box<dyn Machine + Send>, DemoError> {
    if let Some(port) = &cli.serial {
        return Ok(Box::new(Serial::open(
            port,
            cli.baud,
            cli.dialect.into(),
            cli.p2demo_start,
        )?));
    }
    let record_edges = !cli.motor.is_empty();
    Ok(Box::new(Emulated::start_with_edges(
        usize::from(cli.axes),
        record_edges,
    )?))
}

fn run(cli: &Cli) -> Result<Ending, DemoError> {
    let machine = open_machine(cli)?;
    let outputs: Vec<_> = (0..machine.info().axis_kinds.len())
        .map(|index| machine.outputs(index))
        .collect();
    let motors =
        Motors::load(&cli.motor, &outputs, machine.info().clkfreq_hz).map_err(DemoError::Motor)?;
    let signalled = terminal::termination_flag()?;
    terminal::install_panic_hook();
    let mut session = Session::enter()?;
    let mut app = App::new(machine.info().clone(), cli.jog_speed, Instant::now());
    app.motors = motors;
    let options = LoopOptions {
        key_release: !cli.no_key_release,
        panic_after: cli.test_panic_after_ms.map(Duration::from_millis),
    };
    let ending = event_loop::run(&mut session, app, machine, &signalled, options);
    // The terminal first, so that any message lands on the normal screen.
    drop(session);
    Ok(ending?)
}

//! # board-sim — a cogstep board, simulated
//!
//! Runs an emulated hub in real time behind the serial protocol
//! (`docs/protocol.md`), on a pseudo-terminal it creates or on a serial
//! device it is given. The first line it prints is the device path a host
//! opens; then it serves until SIGTERM, SIGINT (Ctrl-C) or SIGHUP.
//!
//! ```text
//! board-sim [--axes 4] [--clkfreq 200000000] [--dialect cogstep|p2demo|grbl]
//!           [--settings FILE] [--port PATH] [--baud 115200]
//! ```
//!
//! `--dialect grbl` speaks grbl 1.1 to a G-code sender (cncjs, Universal
//! G-code Sender, …) over three axes, X, Y and Z; `--settings FILE` keeps
//! its `$` settings across restarts.
//!
//! Everything it does is the `cogstep-sim` library; this is only the
//! command line.

use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use clap::Parser;
use cogstep_protocol::{Dialect, DEFAULT_BAUD};
use cogstep_sim::{BoardSim, GrblOptions, SimConfig, SIM_AXES_MAX};

/// A simulated cogstep board on a pseudo-terminal (or a serial device).
/// Prints the device path to open as its first line, then serves until
/// stopped (Ctrl-C, SIGTERM).
#[derive(Debug, Parser)]
#[command(name = "board-sim", version)]
struct Args {
    /// Number of axes (1 to 8; a p2demo board drives one).
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u8).range(1..=SIM_AXES_MAX as i64))]
    axes: u8,
    /// The emulated hub's clock, Hz.
    #[arg(long, default_value_t = 200_000_000, value_parser = clap::value_parser!(u32).range(1_000..))]
    clkfreq: u32,
    /// What the board speaks: cogstep (the line protocol) or p2demo (the
    /// P2 reference demo, byte for byte from power-up: press a key first;
    /// P2Exact arithmetic, and the moves the reference botches run as the
    /// real board runs them) or grbl (grbl 1.1 for G-code senders, axes X,
    /// Y, Z).
    #[arg(long, default_value_t = Dialect::Cogstep)]
    dialect: Dialect,
    /// grbl: keep the `$` settings in this file (read at start, written
    /// after every change); without it, grbl's defaults at every start.
    #[arg(long, value_name = "FILE")]
    settings: Option<std::path::PathBuf>,
    /// Serve on this existing serial device instead of a new pseudo-terminal.
    #[arg(long, value_name = "PATH")]
    port: Option<String>,
    /// Baud rate for --port (8N1, no flow control).
    #[arg(long, default_value_t = DEFAULT_BAUD)]
    baud: u32,
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("board-sim: {error}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: &Args) -> Result<(), Box<dyn std::error::Error>> {
    let config = SimConfig {
        axes: usize::from(args.axes),
        clkfreq: args.clkfreq,
        dialect: args.dialect,
    };
    // Registered first, so that a signal right after the path is printed
    // still ends the simulator cleanly.
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [
        signal_hook::consts::SIGTERM,
        signal_hook::consts::SIGINT,
        #[cfg(unix)]
        signal_hook::consts::SIGHUP,
    ] {
        signal_hook::flag::register(signal, Arc::clone(&stop))?;
    }
    let options = GrblOptions {
        settings_file: args.settings.clone(),
    };
    let (sim, path) = match &args.port {
        Some(path) => (
            BoardSim::spawn_on_device_with(config, options, path, args.baud)?,
            path.clone(),
        ),
        None => BoardSim::spawn_pty_with(config, options)?,
    };
    println!("{path}");
    eprintln!(
        "board-sim: {} board, {} axes, clkfreq {} Hz; Ctrl-C to stop",
        config.dialect,
        match config.dialect {
            Dialect::Cogstep => config.axes,
            Dialect::P2Demo => 1,
            Dialect::Grbl => cogstep_protocol::grbl::GRBL_AXES,
        },
        config.clkfreq
    );
    while !stop.load(Ordering::Acquire) {
        std::thread::sleep(Duration::from_millis(50));
    }
    sim.stop();
    Ok(())
}

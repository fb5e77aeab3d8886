//! Driving a board over a serial port with `SerialBoard`.
//!
//! Run with `cargo run -p driver --example serial_host [-- [PORT] [DIALECT]]`.
//! Without a port it starts the board simulator (of the dialect given,
//! `cogstep` or `p2demo`) on a pseudo-terminal and drives that; with one
//! it drives the board there.

use std::time::{Duration, Instant};

use driver::serial::host::{DemoStart, Dialect, SerialBoard, SerialConfig};
use driver::serial::sim::{BoardSim, SimConfig};
use driver::{AxisContract, AxisStatus, Mode};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    // `[PORT] [DIALECT]`; a dialect alone simulates a board of that dialect.
    let (port, dialect) = match args.first().map(|first| first.parse::<Dialect>()) {
        None => (None, Dialect::Cogstep),
        Some(Ok(dialect)) => (None, dialect),
        Some(Err(_)) => (
            args.first().cloned(),
            args.get(1).map_or("cogstep", String::as_str).parse()?,
        ),
    };
    // A P2 demo board is never typed into until the host knows its prompt:
    // a simulator just started waits for its first key (a real board found
    // idle at a prompt would need `DemoStart::Reset` or a terminal).
    let demo_start = match port {
        Some(_) => DemoStart::Passive,
        None => DemoStart::PoweredUp,
    };
    let (_sim, port) = match port {
        Some(port) => (None, port),
        None => {
            let (sim, path) = BoardSim::spawn_pty(SimConfig {
                axes: 2,
                dialect,
                ..SimConfig::default()
            })?;
            println!("started the board simulator on {path}");
            (Some(sim), path)
        }
    };

    let board = SerialBoard::open(SerialConfig {
        dialect,
        demo_start,
        ..SerialConfig::new(port)
    })?;
    println!("identity:     {}", board.identity());
    println!("axes:         {}", board.axis_count());
    println!("capabilities: {:?}", board.capabilities());

    let x = board.axis(0).ok_or("the board has no axis 0")?;
    x.move_steps(4_000, 1_000)?;
    println!("move 1000 steps at 4000 steps/s: ok");
    let done = wait_idle(&x)?;
    println!("done: position {}, state {:?}", done.position, done.state());

    // What the board refuses comes back as the same errors the hub gives.
    match x.set_position(0) {
        Ok(()) => println!("set position 0: ok"),
        Err(error) => println!("set position 0: {error}"),
    }
    if let Err(error) = x.move_steps(50_000_000, 100) {
        println!("move at 50,000,000 steps/s: {error}");
    }
    println!("fault: {:?}", board.fault());
    board.close();
    Ok(())
}

/// Polls the cached status (no I/O) until the axis is ready again.
fn wait_idle(axis: &impl AxisContract) -> Result<AxisStatus, Box<dyn std::error::Error>> {
    let start = Instant::now();
    loop {
        let status = axis.status()?;
        if status.steps_to_go == 0 && !status.mode.has(Mode::MOVING) {
            return Ok(status);
        }
        if start.elapsed() > Duration::from_secs(30) {
            return Err("the move did not end".into());
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

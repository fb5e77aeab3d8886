//! Round-trip latency of `?` → status over a real pseudo-terminal, against
//! the board simulator (a real-time hub). Prints p50 and p99.
//!
//! Run with `cargo run --release -p driver --example serial_latency
//! [-- ROUNDS]` (default 5,000 rounds per measurement). Three figures:
//!
//! - **raw, idle**: write `?` on the device, read until every axis's status
//!   line has arrived (the protocol's own round trip);
//! - **raw, moving**: the same while all four axes run moves (their cogs
//!   wake every few hundred microseconds);
//! - **SerialBoard::refresh**: the host backend's `?` through its link
//!   thread, the status lines parsed into its cache (what a caller that
//!   wants fresh status waits).
//!
//! The target is a p99 of at most 2 ms. Nothing asserts it: timing
//! depends on the machine, so it is measured here and reported, never
//! checked in tests.

use std::io::Write;
use std::time::{Duration, Instant};

use driver::serial::host::{SerialBoard, SerialConfig};
use driver::serial::sim::{BoardSim, SimConfig};
use driver::AxisContract;

const AXES: usize = 4;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let rounds: usize = match std::env::args().nth(1) {
        Some(text) => text.parse()?,
        None => 5_000,
    };
    let (sim, path) = BoardSim::spawn_pty(SimConfig {
        axes: AXES,
        ..SimConfig::default()
    })?;
    println!("board-sim on {path}, {AXES} axes, {rounds} rounds each");

    {
        let mut port = serialport::new(&path, 115_200)
            .timeout(Duration::from_secs(1))
            .open()?;
        port.clear(serialport::ClearBuffer::Input)?;
        report("raw `?`, axes idle", &raw_rounds(port.as_mut(), rounds)?);

        // Long moves on every axis, so the cogs are busy while we measure.
        for axis in 0..AXES {
            port.write_all(format!("M {axis} 20000 2000000\n").as_bytes())?;
            read_lines(port.as_mut(), 1)?;
        }
        report("raw `?`, axes moving", &raw_rounds(port.as_mut(), rounds)?);
        port.write_all(b"E\n")?;
        read_lines(port.as_mut(), 1)?;
    }

    let board = SerialBoard::open(SerialConfig {
        // No background polls in between the measured ones.
        poll_interval: Duration::from_secs(3_600),
        ..SerialConfig::new(&path)
    })?;
    let mut samples = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        let start = Instant::now();
        board.refresh()?;
        samples.push(start.elapsed());
    }
    let axis = board.axis(0).ok_or("no axis 0")?;
    report("SerialBoard::refresh (backend)", &samples);
    println!("last status of axis 0: {:?}", axis.status()?);
    board.close();
    sim.stop();
    Ok(())
}

/// `rounds` timed `?` round trips (after a short warm-up).
fn raw_rounds(
    port: &mut dyn serialport::SerialPort,
    rounds: usize,
) -> Result<Vec<Duration>, Box<dyn std::error::Error>> {
    let mut samples = Vec::with_capacity(rounds);
    for round in 0..rounds + 100 {
        let start = Instant::now();
        port.write_all(b"?")?;
        read_lines(port, AXES)?;
        if round >= 100 {
            samples.push(start.elapsed());
        }
    }
    Ok(samples)
}

/// Reads until `count` line ends have arrived (replies never run ahead:
/// each round waits for its own lines).
fn read_lines(
    port: &mut dyn serialport::SerialPort,
    count: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    let mut seen = 0;
    let mut bytes = [0u8; 1024];
    while seen < count {
        let read = port.read(&mut bytes)?;
        seen += bytes[..read].iter().filter(|&&byte| byte == b'\n').count();
    }
    Ok(())
}

fn report(what: &str, samples: &[Duration]) {
    let mut sorted = samples.to_vec();
    sorted.sort_unstable();
    let at = |fraction: f64| {
        let index = ((sorted.len() as f64 * fraction) as usize).min(sorted.len() - 1);
        sorted[index]
    };
    println!(
        "{what:<34} p50 {:>9.1?}  p99 {:>9.1?}  max {:>9.1?}",
        at(0.50),
        at(0.99),
        at(1.0)
    );
}

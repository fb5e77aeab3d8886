//! cogstep in a minute: a hub with two axes in virtual time.
//!
//! Run with `cargo run -p driver --example quickstart`.

use driver::{ClockMode, Hub, HubConfig, Mode};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The hub: 200 MHz system clock, deterministic virtual time, and a
    // record of every pin edge.
    let hub = Hub::new(HubConfig {
        clkfreq: 200_000_000,
        clock: ClockMode::Virtual,
        trace_edges: true,
        ..Default::default()
    })?;

    // One cog per axis: x drives a step/dir driver, y a cw/ccw one.
    let x = hub.start_sd(0, 1, 2)?; // stop pin 0, step pin 1, dir pin 2
    let y = hub.start_cc(3, 4, 5)?; // stop pin 3, cw pin 4, ccw pin 5
    hub.set_input(0, true).unwrap(); // a stop pin must be high to run
    hub.set_input(3, true).unwrap();

    // The reference move(speed, steps): steps/s, signed steps.
    x.move_steps(20_000, 10_000)?;
    y.move_steps(5_000, -2_000)?;
    println!(
        "x: {} steps planned, {} accelerating, {} at speed",
        x.stm(),
        x.accel_steps(),
        x.slew_steps()
    );

    // Let 100 ms of CT pass, and look at the shared state.
    hub.advance(20_000_000);
    println!(
        "after 100 ms: x at {} ({}), y at {} ({}), mode bits {:06b}",
        x.position(),
        x.mode().describe(),
        y.position(),
        y.mode().describe(),
        x.mode().reference_bits()
    );

    // Same direction and speed while moving: the steps merge into the slew.
    x.move_steps(20_000, 5_000)?;

    // Pull x's stop pin low: a controlled stop from the current velocity.
    hub.advance(40_000_000);
    hub.set_input(0, false).unwrap();
    let end = hub.run_until_idle();
    println!(
        "stopped at {} with {} steps left (stop latched: {})",
        x.position(),
        x.dropped_steps(),
        x.mode().has(Mode::STOP_LATCHED)
    );

    // Finish the original target.
    hub.set_input(0, true).unwrap();
    x.move_steps(20_000, i32::try_from(x.dropped_steps())?)?;
    let end = end.max(hub.run_until_idle());
    println!(
        "x reached {}, y reached {}, at CT {} ({:.3} s); {} step pulses on pin 1",
        x.position(),
        y.position(),
        end,
        end as f64 / 200e6,
        hub.rising_edges(1)
    );

    // Every edge can be written as a VCD file for GTKWave or PulseView.
    let mut vcd = Vec::new();
    hub.write_vcd(&mut vcd)?;
    println!(
        "{} edges recorded, {} bytes of VCD",
        hub.trace().len(),
        vcd.len()
    );
    Ok(())
}

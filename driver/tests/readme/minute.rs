use driver::{ClockMode, Hub, HubConfig};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let hub = Hub::new(HubConfig { clkfreq: 200_000_000, clock: ClockMode::Virtual, ..Default::default() })?;
    let x = hub.start_sd(0, 1, 2)?;   // stop pin 0, step pin 1, dir pin 2
    let y = hub.start_cc(3, 4, 5)?;   // stop pin 3, cw pin 4, ccw pin 5
    hub.set_input(0, true)?;          // a stop pin must be high to run; low = controlled stop
    hub.set_input(3, true)?;
    x.move_steps(20_000, 10_000)?;    // the reference move(speed, steps)
    y.move_steps(5_000, -2_000)?;
    hub.advance(20_000_000);          // 100 ms of virtual time
    println!("{} {} {:06b}", x.position(), x.steps_to_go(), x.mode().bits());
    hub.run_until_idle();             // returns the CT when the last axis is ready

    // A coordinated move: both first edges on one CT, one straight line in
    // step space, the longest move (x) leading on its S-curve at 20,000 steps/s.
    hub.move_together(&[(&x, -4_000), (&y, 1_500)], 20_000)?;
    hub.run_until_idle();
    assert_eq!((x.position(), y.position()), (6_000, -500));
    Ok(())
}

//! How far Austin's ramp (f64 and 24.8 fixed point) and Leib's ramp stray
//! from the exact trapezoid, in clock ticks of edge time, on a few moves:
//!
//! ```text
//! cargo run --release -p cogstep-ramps --example ramp_errors
//! ```
//!
//! The bounds these figures stay within are asserted in the crate's tests
//! (`austin::tests`, `leib::tests`: `the_measured_cases_lie_within_the_bound`
//! and the properties).

use cogstep_ramps::austin::{c0_exact, AustinFixedProfile, AustinProfile};
use cogstep_ramps::leib::LeibProfile;
use cogstep_ramps::trapezoid::{EdgeTimingError, Trapezoid};

fn row(name: &str, error: &EdgeTimingError, c0: f64) {
    println!(
        "    {name:<6} max {:>9} ticks ({:.3} c0)  rms {:>9.0}  end {:>9}  worst at edge {}",
        error.max_abs_ticks,
        error.max_abs_ticks as f64 / c0,
        error.rms_ticks,
        error.end_diff_ticks,
        error.worst_edge
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    for (clkfreq, speed, accel, steps) in [
        (200_000_000u32, 20_000.0, 50_000.0, 20_000u32),
        (200_000_000, 5_000.0, 20_000.0, 3_000),
        (1_000_000, 1_000.0, 10_000.0, 1_000),
        (1_000_000, 1_000.0, 10_000.0, 31),
        (200_000_000, 50_000.0, 1_000_000.0, 100_000),
    ] {
        let reference = Trapezoid::new(clkfreq, speed, accel, steps)?;
        let c0 = c0_exact(f64::from(clkfreq), accel);
        println!(
            "f={clkfreq} Hz v={speed} steps/s a={accel} steps/s² n={steps}: exact c0 {c0:.0} ticks"
        );
        let austin = reference.compare(AustinProfile::new(clkfreq, speed, accel, steps)?);
        row("austin", &austin, c0);
        match AustinFixedProfile::new(clkfreq, speed, accel, steps) {
            Ok(fixed) => row("fixed", &reference.compare(fixed), c0),
            Err(error) => println!("    fixed  {error}"),
        }
        let leib = reference.compare(LeibProfile::new(clkfreq, speed, accel, steps)?);
        row("leib", &leib, c0);
    }
    Ok(())
}

//! Cost of the step interrupt, measured in the firmware itself.
//!
//! Built with the `bench` feature and run by `firmware/bench-qemu` under
//! `qemu -icount shift=0`, where virtual time advances 1 ns per guest
//! instruction: the SysTick count (one CT tick, 20 ns at 50 MHz) read as
//! the handler starts and again after it has re-armed the timer (or, on
//! the fast path, driven its edge and re-armed the timer) gives,
//! in ns, the number of instructions it ran (± one tick per reading,
//! averaged over thousands of interrupts). The count covers the whole
//! handler (clearing the time-out, reading the CT, the axes' work,
//! re-arming the timer) but its register saves and the exception entry
//! and exit (12 cycles each on a Cortex-M3).
//!
//! Every axis in use makes the same move at once; the results go to the
//! semihosting console, one line per kind of interrupt, then QEMU exits.

use core::cell::RefCell;

use cogstep_firmware::{Firmware, Work};
use cortex_m_semihosting::{debug, hprintln};
use critical_section::Mutex;
use driver::axis::{AxisContract, Mode};

use crate::hw::{self, Lm3s, CLKFREQ_HZ};

/// The move every axis makes: 20,000 steps at 20,000 steps/s, so 4,004
/// ramp steps and 15,996 slew steps.
const SPEED_STEPS_PER_S: u32 = 20_000;
const STEPS: i32 = 20_000;

#[derive(Clone, Copy, Default)]
struct Bucket {
    interrupts: u64,
    ticks: u64,
    steps: u64,
}

#[derive(Clone, Copy, Default)]
struct Stats {
    /// Interrupts that made at least one ramp step.
    ramp: Bucket,
    /// Interrupts that made slew steps only (the fast path's rising edges
    /// among them).
    slew: Bucket,
    /// The fast path's falling edges of slew steps.
    slew_edge: Bucket,
    /// The fast path's falling edges of ramp steps.
    ramp_edge: Bucket,
    /// Whether the last step made was a ramp step (its falling edge is
    /// the next one the fast path drives).
    last_step_ramp: bool,
    /// Other interrupts that made no step: they drive queued edges (a
    /// rising edge, a pulse end) or end a move.
    other: Bucket,
}

const EMPTY: Bucket = Bucket {
    interrupts: 0,
    ticks: 0,
    steps: 0,
};

static STATS: Mutex<RefCell<Stats>> = Mutex::new(RefCell::new(Stats {
    ramp: EMPTY,
    slew: EMPTY,
    slew_edge: EMPTY,
    ramp_edge: EMPTY,
    other: EMPTY,
    last_step_ramp: false,
}));

/// What an interrupt did.
pub enum Kind {
    /// The fast path drove a rising edge and made a slew step.
    FastRise,
    /// The fast path drove a falling edge (of the last step made).
    FastFall,
    /// The general interrupt's work.
    General(Work),
}

/// Books one interrupt body from SysTick count `start` to `end`.
pub fn record(start: u32, end: u32, kind: Kind) {
    // SysTick counts down, 24 bits.
    let ticks = u64::from(start.wrapping_sub(end) & 0x00FF_FFFF);
    critical_section::with(|cs| {
        let stats = &mut *STATS.borrow_ref_mut(cs);
        match kind {
            Kind::FastRise => stats.last_step_ramp = false,
            Kind::General(work) if work.ramp_steps + work.slew_steps > 0 => {
                stats.last_step_ramp = work.ramp_steps > 0;
            }
            _ => {}
        }
        let (bucket, steps) = match kind {
            Kind::FastRise => (&mut stats.slew, 1),
            Kind::FastFall if stats.last_step_ramp => (&mut stats.ramp_edge, 0),
            Kind::FastFall => (&mut stats.slew_edge, 0),
            Kind::General(work) if work.ramp_steps > 0 => {
                (&mut stats.ramp, work.ramp_steps + work.slew_steps)
            }
            Kind::General(work) if work.slew_steps > 0 => (&mut stats.slew, work.slew_steps),
            Kind::General(_) => (&mut stats.other, 0),
        };
        bucket.interrupts += 1;
        bucket.ticks += ticks;
        bucket.steps += u64::from(steps);
    });
}

/// Runs the move on every axis, prints the figures and ends QEMU.
pub fn run(firmware: &'static Firmware<Lm3s>) -> ! {
    for axis in firmware.axes() {
        if axis.move_steps(SPEED_STEPS_PER_S, STEPS).is_err() {
            hprintln!("bench: the move was refused");
            debug::exit(debug::EXIT_FAILURE);
        }
    }
    let start = hw::now_ticks();
    // Waits for every step's falling edge: reading the status would hand
    // the axes' slew trains back to their cores (as a host's `?` does).
    let pulses = u64::from(STEPS.unsigned_abs());
    while firmware
        .axes()
        .iter()
        .any(|axis| axis.edge_counts().falling[0] < pulses)
    {
        cortex_m::asm::wfi();
    }
    // The move ends a step period after its last step.
    while firmware.axes().iter().any(|axis| {
        axis.status()
            .is_ok_and(|status| status.mode.has(Mode::MOVING))
    }) {
        cortex_m::asm::wfi();
    }
    let elapsed = hw::now_ticks() - start;
    let stats = critical_section::with(|cs| *STATS.borrow_ref(cs));
    let arithmetic = firmware.axes()[0].config().scurve.arithmetic;
    let ns_per_tick = 1_000_000_000 / u64::from(CLKFREQ_HZ);
    hprintln!(
        "bench axes={} arithmetic={:?} clkfreq={} speed={} steps={} move_ticks={}",
        firmware.axes().len(),
        arithmetic,
        CLKFREQ_HZ,
        SPEED_STEPS_PER_S,
        STEPS,
        elapsed
    );
    for (name, bucket) in [
        ("ramp", stats.ramp),
        ("slew", stats.slew),
        ("slewedge", stats.slew_edge),
        ("rampedge", stats.ramp_edge),
        ("other", stats.other),
    ] {
        hprintln!(
            "bench kind={} interrupts={} steps={} ns={}",
            name,
            bucket.interrupts,
            bucket.steps,
            bucket.ticks * ns_per_tick
        );
    }
    let positions_ok = firmware.axes().iter().all(|axis| {
        axis.status().is_ok_and(|status| {
            status.position == i64::from(STEPS) && !status.mode.has(Mode::MOVING)
        })
    });
    debug::exit(if positions_ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    hw::halt()
}

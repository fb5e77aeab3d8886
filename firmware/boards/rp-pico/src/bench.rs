//! The cost of a step on the RP2040, measured in the firmware itself.
//!
//! Built with the `bench` feature and run by `firmware/bench-pico` under
//! the rp2040py emulator, whose SysTick counts the emulated core's cycles
//! (clk_sys, 125 MHz). On the Pico the axes' work runs in the main loop
//! (`produce`: each wake-up's `Firmware::step_interrupt_ahead_trains`,
//! its edges queued for the edge interrupt, with the steps of a train
//! that come before any other axis's wake-up), so that call is what is
//! timed: SysTick read before and after each wake-up, its cycles booked
//! by what it did (ramp steps, slew steps only, no step). The main loop
//! works in rounds, as it does serving a host: it waits until its next
//! wake-up is `edges::REFILL_TICKS` away, then runs every wake-up up to
//! the frontier. The edge interrupt's own cost (driving pins through SIO)
//! is not in these figures, but for the edges it drives during a timed
//! wake-up.
//!
//! Every axis makes the same move at once (or, with `COGSTEP_BENCH_APART`,
//! each a little slower than the one before); the figures go out on
//! UART0, one line per kind of wake-up, then `bench done`.

use core::cell::RefCell;
use core::fmt::Write;

use cogstep_firmware::{Firmware, Work};
use critical_section::Mutex;
use driver::axis::{AxisContract, Mode};

use crate::Pico;

/// The move every axis makes: 10,000 steps at 20,000 steps/s (about
/// 4,000 ramp steps, the rest at speed).
pub const SPEED_STEPS_PER_S: u32 = 20_000;
/// See [`SPEED_STEPS_PER_S`].
pub const STEPS: i32 = 10_000;
/// With [`COGSTEP_BENCH_APART`] set, axis `i` runs this much slower than
/// [`SPEED_STEPS_PER_S`] for each `i`: the axes' edges then fall apart,
/// as in a real job, rather than on one CT (where the main loop merges
/// the four axes' edges a CT at a time).
pub const APART_STEPS_PER_S: u32 = 1_000;

/// 1: the axes run at speeds [`APART_STEPS_PER_S`] apart (the harness's
/// `run-pico-sim --bench-apart` sets this flash byte); 0: all at one speed.
#[no_mangle]
pub static COGSTEP_BENCH_APART: u8 = 0;

#[derive(Clone, Copy, Default)]
struct Bucket {
    wakeups: u64,
    cycles: u64,
    steps: u64,
}

#[derive(Clone, Copy, Default)]
struct Stats {
    /// Wake-ups that made at least one ramp step.
    ramp: Bucket,
    /// Wake-ups that made slew steps only.
    slew: Bucket,
    /// Wake-ups that made no step (an edge's end, a move's end).
    other: Bucket,
}

static STATS: Mutex<RefCell<Stats>> = Mutex::new(RefCell::new(Stats {
    ramp: Bucket {
        wakeups: 0,
        cycles: 0,
        steps: 0,
    },
    slew: Bucket {
        wakeups: 0,
        cycles: 0,
        steps: 0,
    },
    other: Bucket {
        wakeups: 0,
        cycles: 0,
        steps: 0,
    },
}));

/// SysTick at the core clock, counting down from 2^24 − 1, no interrupt.
pub fn start_systick() {
    // SAFETY: SysTick is the bench's alone (nothing else uses it here).
    let mut core = unsafe { cortex_m::Peripherals::steal() };
    core.SYST.set_reload(0x00FF_FFFF);
    core.SYST.clear_current();
    core.SYST
        .set_clock_source(cortex_m::peripheral::syst::SystClkSource::Core);
    core.SYST.enable_counter();
}

/// SysTick's count now.
#[inline(always)]
pub fn now() -> u32 {
    cortex_m::peripheral::SYST::get_current()
}

/// Books one wake-up from SysTick count `start` to now.
pub fn record(start: u32, work: Work) {
    // Counts down, 24 bits.
    let cycles = u64::from(start.wrapping_sub(now()) & 0x00FF_FFFF);
    critical_section::with(|cs| {
        let stats = &mut *STATS.borrow_ref_mut(cs);
        let steps = u64::from(work.ramp_steps + work.slew_steps);
        let bucket = if work.ramp_steps > 0 {
            &mut stats.ramp
        } else if work.slew_steps > 0 {
            &mut stats.slew
        } else {
            &mut stats.other
        };
        bucket.wakeups += 1;
        bucket.cycles += cycles;
        bucket.steps += steps;
    });
}

/// Starts the move on every axis; `serve` runs the main loop until
/// `done` says every axis has finished; then the figures go to `out`.
pub fn run(
    firmware: &'static Firmware<Pico>,
    out: &mut impl Write,
    mut serve: impl FnMut() -> bool,
) -> ! {
    start_systick();
    // SAFETY: a read of a byte in flash the harness may have patched.
    let apart = unsafe { core::ptr::read_volatile(&COGSTEP_BENCH_APART) } == 1;
    for (index, axis) in firmware.axes().iter().enumerate() {
        let slower = if apart {
            APART_STEPS_PER_S * index as u32
        } else {
            0
        };
        if axis.move_steps(SPEED_STEPS_PER_S - slower, STEPS).is_err() {
            let _ = writeln!(out, "bench: the move was refused");
            crate::halt()
        }
    }
    let pulses = u64::from(STEPS.unsigned_abs());
    loop {
        let done = serve();
        // Every step's falling edge, and no axis moving any more.
        let falling = firmware
            .axes()
            .iter()
            .all(|axis| axis.edge_counts().falling[0] >= pulses);
        if done && falling {
            let moving = firmware.axes().iter().any(|axis| {
                axis.status()
                    .is_ok_and(|status| status.mode.has(Mode::MOVING))
            });
            if !moving {
                break;
            }
        }
    }
    let stats = critical_section::with(|cs| *STATS.borrow_ref(cs));
    let _ = writeln!(
        out,
        "bench axes={} clk_sys={} speed={} steps={} apart={}",
        firmware.axes().len(),
        crate::SYS_CLOCK_HZ,
        SPEED_STEPS_PER_S,
        STEPS,
        u32::from(apart) * APART_STEPS_PER_S
    );
    for (name, bucket) in [
        ("ramp", stats.ramp),
        ("slew", stats.slew),
        ("other", stats.other),
    ] {
        let _ = writeln!(
            out,
            "bench kind={} wakeups={} steps={} cycles={}",
            name, bucket.wakeups, bucket.steps, bucket.cycles
        );
    }
    let exact = firmware.axes().iter().all(|axis| {
        axis.status()
            .is_ok_and(|status| status.position == i64::from(STEPS))
    });
    let _ = writeln!(out, "bench done positions_exact={exact}");
    crate::halt()
}

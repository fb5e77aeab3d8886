//! # cogstep on the LM3S6965 evaluation board (Cortex-M3), under QEMU
//!
//! A thin board layer over `cogstep-firmware`:
//!
//! - **UART0** (0x4000_C000, PA0/PA1): protocol v1 at 115,200 baud, 8N1.
//!   The identity line goes out at boot.
//! - **Clock**: the system clock runs at 50 MHz (the chip's maximum);
//!   every CT is a tick of it (`clkfreq:50000000`).
//! - **Time**: SysTick counts down at the core clock and its wraps extend
//!   it to a 64-bit CT; **Timer0A** (one-shot) fires at the next step event.
//!   A slew train of an axis alone at speed runs on the fast path: each
//!   interrupt drives one edge and re-arms Timer0A from that edge's CT
//!   (SysTick's low 24 bits tell how late the interrupt runs), so the
//!   schedule does not drift.
//! - **Pins**: axis `i` drives GPIO port B pins `2i` and `2i + 1`: step and
//!   direction (`sd`) on even axes, cw and ccw (`cc`) on odd ones, as the
//!   board simulator. The stop "pin" of each axis is the level `S`, `R`
//!   and `!` set (no GPIO input is read: `H`, `K` and `C` answer `error:1
//!   not supported`, see firmware/README.md for why QEMU cannot test
//!   switches here).
//! - **Axes**: 1 to 4, from the semihosting command line (`axes=N`, which
//!   `firmware/run-qemu --axes N` passes); 4 without one. The command line
//!   may also say `arithmetic=p2exact` (the default is Smooth).
//! - **Dialect**: protocol v1, or grbl 1.1 when the command line says
//!   `dialect=grbl` (`firmware/run-qemu --dialect grbl`): then three axes
//!   (X, Y, Z) on a look-ahead path (`cogstep_firmware::grbl`), grbl's
//!   welcome line at boot, the settings in RAM.
//!
//! With the `bench` feature it measures the step interrupt instead (see
//! `bench.rs` and `firmware/bench-qemu`).
#![no_std]
#![no_main]

mod hw;

#[cfg(feature = "bench")]
mod bench;

use core::cell::Cell;

#[cfg(not(feature = "bench"))]
use cogstep_firmware::grbl::GrblRunner;
#[cfg(not(feature = "bench"))]
use cogstep_firmware::PathMotion;
use cogstep_firmware::{core_config, FastEvent, FastTrain, Firmware, Variant};
use cortex_m_rt::{entry, exception};
use critical_section::Mutex;
use driver::profile::scurve::Arithmetic;
use driver::serial::grbl::GRBL_AXES;
#[cfg(not(feature = "bench"))]
use driver::serial::grbl::{GrblGcode, GrblSession, MotionState, Settings};
use lm3s6965::interrupt;

use hw::{Lm3s, CLKFREQ_HZ};

/// The firmware, once `main` has built it (the interrupts read it).
static FIRMWARE: Mutex<Cell<Option<&'static Firmware<Lm3s>>>> = Mutex::new(Cell::new(None));

/// The axes when the command line names none.
const DEFAULT_AXES: usize = 4;

fn firmware() -> Option<&'static Firmware<Lm3s>> {
    critical_section::with(|cs| FIRMWARE.borrow(cs).get())
}

#[entry]
fn main() -> ! {
    let mut core = cortex_m::Peripherals::take().unwrap_or_else(|| hw::halt());
    hw::init(&mut core);
    let command_line = hw::command_line();
    let firmware = build_firmware(command_line);
    critical_section::with(|cs| FIRMWARE.borrow(cs).set(Some(firmware)));
    hw::enable_interrupts();

    #[cfg(feature = "bench")]
    bench::run(firmware);
    #[cfg(not(feature = "bench"))]
    if command_line.grbl {
        serve_grbl(build_grbl_session(firmware))
    }
    #[cfg(not(feature = "bench"))]
    serve(firmware)
}

/// The firmware the command line asks for, in its static. A function of
/// its own (not inlined) so that the value built on the stack before it
/// moves into the static is off the stack once it has: `main` never
/// returns, and its frame stays under everything else.
#[inline(never)]
fn build_firmware(command_line: hw::CommandLine) -> &'static Firmware<Lm3s> {
    let config = |index: usize| {
        let variant = if index.is_multiple_of(2) {
            Variant::Sd
        } else {
            Variant::Cc
        };
        let mut config = core_config(CLKFREQ_HZ, variant);
        if command_line.p2exact {
            config.scurve.arithmetic = Arithmetic::P2Exact;
        }
        config
    };
    // grbl drives X, Y and Z. A bad count (run-qemu checks it first)
    // falls back to the default.
    let axes = if command_line.grbl {
        GRBL_AXES
    } else {
        command_line.axes.unwrap_or(DEFAULT_AXES)
    };
    let built =
        Firmware::new(Lm3s, axes, config).or_else(|_| Firmware::new(Lm3s, DEFAULT_AXES, config));
    let Ok(built) = built else { hw::halt() };
    cortex_m::singleton!(: Firmware<Lm3s> = built).unwrap_or_else(|| hw::halt())
}

/// The grbl board's session: its motion on the firmware's axes.
#[cfg(not(feature = "bench"))]
type GrblBoard = GrblSession<PathMotion<'static, Lm3s>, GrblGcode>;

/// grbl 1.1 on UART0, for ever: bytes in as far as the receive buffer
/// has room (the rest wait in the UART, as a sender's character counting
/// expects), the path's edges pushed ahead of the clock, the session's
/// lines taken as the planner has room. The main loop sleeps only when
/// nothing moves or waits.
///
/// UART0's FIFO is off (as for protocol v1), so a byte must be read
/// before the next one ends: QEMU's UART holds the next byte back until
/// then, but on a real chip a main loop busy for longer than a byte (87 µs
/// at 115,200 baud; a long arc's chords are planned in one turn) would
/// lose bytes. A board that runs this on hardware wants the receive FIFO
/// or an interrupt-fed ring.
#[cfg(not(feature = "bench"))]
fn serve_grbl(session: &'static mut GrblBoard) -> ! {
    let mut uart = hw::Uart0;
    let _ = session.start(&mut uart);
    loop {
        while session.room() > 0 {
            let Some(byte) = uart.read_byte() else { break };
            let _ = session.receive(byte, &mut uart);
        }
        session.motion_mut().advance();
        let _ = session.poll(&mut uart);
        // At rest (idle, or held on the path) the runner has no edge to
        // compute: sleep until a byte comes. (The state alone: a status
        // report would compute the path's speed on every turn.)
        let busy = session.is_busy()
            || !matches!(
                session.motion().state(),
                MotionState::Idle | MotionState::Held
            );
        if !busy {
            cortex_m::interrupt::free(|_| {
                if !uart.has_byte() {
                    cortex_m::asm::wfi();
                }
            });
        }
    }
}

/// The grbl session over `firmware`, grbl's default settings, in its
/// static (not inlined: see [`build_firmware`]).
#[cfg(not(feature = "bench"))]
#[inline(never)]
fn build_grbl_session(firmware: &'static Firmware<Lm3s>) -> &'static mut GrblBoard {
    // The runner (about 10 KB) in a static of its own, the session
    // (about 4 KB) in another: a copy of either on the stack costs that.
    let runner: &'static mut Option<GrblRunner> =
        cortex_m::singleton!(: Option<GrblRunner> = None).unwrap_or_else(|| hw::halt());
    let settings = Settings::default();
    let session = GrblSession::new(
        PathMotion::new(firmware, runner, &settings),
        GrblGcode::new(&settings),
        settings,
        env!("CARGO_PKG_VERSION"),
    );
    cortex_m::singleton!(: GrblBoard = session).unwrap_or_else(|| hw::halt())
}

/// Protocol v1 on UART0, for ever.
#[cfg(not(feature = "bench"))]
fn serve(firmware: &'static Firmware<Lm3s>) -> ! {
    let mut uart = hw::Uart0;
    let _ = firmware.announce(&mut uart);
    let mut session = driver::serial::Session::new();
    loop {
        while let Some(byte) = uart.read_byte() {
            let _ = firmware.feed(&mut session, byte, &mut uart);
        }
        // Sleep until a byte (or any interrupt) comes; with interrupts
        // masked, so that a byte arriving after the check still wakes us.
        cortex_m::interrupt::free(|_| {
            if !uart.has_byte() {
                cortex_m::asm::wfi();
            }
        });
    }
}

/// The step interrupt. A slew train lent to the fast path
/// ([`cogstep_firmware::fast`]) makes its edges with no more than the
/// edge and the timer re-armed from the edge's own CT; anything else runs
/// the general interrupt: every due event of every axis, then the timer
/// armed for the next (and the train of an axis alone at speed lent).
#[interrupt]
fn TIMER_0A() {
    let start = bench_start();
    hw::timer0_clear();
    // SAFETY: only this interrupt and code with interrupts masked reach
    // the fast train (see `hw::fast_train`); this is the only reference
    // made here, and it ends with this run.
    let fast = unsafe { hw::fast_train() };
    let served = fast.armed_ct_inverted();
    match fast.on_timer(hw::drive_fast_pin) {
        FastEvent::Rise { interval } => {
            hw::timer0_arm_after(served, interval);
            #[cfg(feature = "bench")]
            bench::record(
                start,
                cortex_m::peripheral::SYST::get_current(),
                bench::Kind::FastRise,
            );
        }
        FastEvent::Fall { interval } => {
            hw::timer0_arm_after(served, interval);
            #[cfg(feature = "bench")]
            bench::record(
                start,
                cortex_m::peripheral::SYST::get_current(),
                bench::Kind::FastFall,
            );
        }
        FastEvent::Slow => step_interrupt(fast, start),
    }
}

/// SysTick's count as the step interrupt starts, for the bench (0 without).
#[inline(always)]
fn bench_start() -> u32 {
    #[cfg(feature = "bench")]
    return cortex_m::peripheral::SYST::get_current();
    #[cfg(not(feature = "bench"))]
    0
}

/// The general step interrupt. One CT reading serves both to find what is
/// due and to arm the timer.
#[inline(never)]
fn step_interrupt(fast: &mut FastTrain, _start: u32) {
    let Some(firmware) = firmware() else { return };
    let (now, systick) = hw::now_and_systick();
    let (next, _work) = firmware.step_interrupt_lending(now, fast);
    hw::timer0_arm_from(next, now, systick);
    #[cfg(feature = "bench")]
    {
        let end = cortex_m::peripheral::SYST::get_current();
        bench::record(_start, end, bench::Kind::General(_work));
    }
}

/// A received byte: the main loop reads it; this only wakes the core.
#[interrupt]
fn UART0() {
    hw::uart0_clear_interrupts();
}

/// SysTick wrapped: one more 2^24 ticks of CT.
#[exception]
fn SysTick() {
    hw::systick_wrapped();
}

#[exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    hw::halt()
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    hw::halt()
}

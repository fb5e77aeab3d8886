//! # cogstep on a Raspberry Pi Pico (RP2040, Cortex-M0+)
//!
//! Runs in CI under the rp2040py emulator (`firmware/run-pico-sim`); not
//! yet run on a real Pico (see README.md beside this crate for the pin
//! map, how to flash it and what is tested where). A thin board layer
//! over `cogstep-firmware`:
//!
//! - **USB CDC** ([`usb`]): plugged into a host, the Pico is a serial
//!   device (`/dev/ttyACM0` on Linux) that speaks protocol v1; the
//!   identity line goes out when the host opens the port (raises DTR).
//! - **UART0** on GP0 (TX) and GP1 (RX): protocol v1 at 115,200 baud, 8N1;
//!   the identity line goes out at boot. Bytes both ways go through rings
//!   that UART0's interrupt fills and drains ([`uart`]): a reply never
//!   holds the main loop while the FIFO sends it. Both ports are live: one session
//!   reads whichever port bytes come on and answers on the port it last
//!   heard from (one host at a time). The main loop sleeps (WFE) until a
//!   byte, a USB event or a timer alarm wakes it.
//! - **Time**: the RP2040's 64-bit microsecond timer is the CT
//!   (`clkfreq:1000000`). The axes' cores run [`edges::LEAD_TICKS`] ahead
//!   of it in the main loop; alarm 1 wakes the loop for the next wake-up.
//! - **Edges**: the cores' edges wait in a lock-free queue; the edge
//!   interrupt (`TIMER_IRQ_0`, alarm 0) drives each at its CT through SIO
//!   and does nothing else ([`edges`]). Critical sections leave it live
//!   ([`cs`]).
//! - **Pins**: axis `i` drives GP`2 + 2i` and GP`3 + 2i`: step and
//!   direction (`sd`) on even axes, cw and ccw (`cc`) on odd ones.
//! - **Inputs** ([`inputs`]): axis `i`'s stop input on GP`10 + i` (low
//!   holds it, as does `S`), home and limit switches on GP14–GP22 and
//!   GP26–GP28 for `H` and `K`, pulled up, read by a GPIO interrupt with
//!   the timer so that homing and a trip latch the step the pins had made.
//! - **Axes**: 4, or the count in the `COGSTEP_AXES` byte of the flash
//!   image (the emulator's harness patches it for `--axes`).
//! - **Arithmetic**: Smooth, or P2Exact (the P2 driver's integer
//!   arithmetic and emulated CORDIC) when the `COGSTEP_ARITHMETIC` byte of
//!   the flash image is 1 (`firmware/run-pico-sim --arithmetic p2exact`).
//! - **Dialect**: protocol v1, or grbl 1.1 when the `COGSTEP_DIALECT`
//!   byte of the flash image is 1 (`firmware/run-pico-sim --dialect
//!   grbl` patches it): then three axes (X, Y, Z) on a look-ahead path
//!   (`cogstep_firmware::grbl`, as on the LM3S6965), grbl's welcome line
//!   at boot, the settings in RAM.
//! - **Core 1** ([`core1`]): computes each axis's next ramp run (the
//!   ramp's cosines and divisions) while core 0 yields the armed one, from
//!   the state the axis will be in; core 0 takes it only if that came
//!   true, so the steps are its own to the bit. Off when the
//!   `COGSTEP_CORE1` byte of the flash image is 0
//!   (`firmware/run-pico-sim --core1 off`): core 0 then computes them all.
//! - **Feature `pio`**: the CT is the 125 MHz system clock and PIO0's
//!   state machines make the edges from FIFO words: the main loop turns
//!   each axis's edges into its words (`pio.rs`), with no edge queue and
//!   no edge interrupt.
#![no_std]
#![no_main]
// The bench build measures and halts: the serving code is there, unused.
#![cfg_attr(feature = "bench", allow(unreachable_code, dead_code))]

#[cfg(feature = "bench")]
mod bench;
mod core1;
mod cs;
mod edges;
mod inputs;
#[cfg(feature = "pio")]
mod pio;
mod uart;
mod usb;

use core::fmt;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cogstep_firmware::grbl::GrblRunner;
use cogstep_firmware::TrainRises;
use cogstep_firmware::{core_config, Firmware, Hardware, Output, PathMotion, Variant};
use driver::profile::scurve::Arithmetic;
use driver::serial::grbl::{GrblGcode, GrblSession, MotionState, Settings, GRBL_AXES};
use driver::serial::Session;
use fugit::RateExtU32;
use rp2040_hal as hal;
use rp2040_hal::clocks::Clock;
use rp2040_hal::pac;
use rp2040_hal::pac::interrupt;
use rp2040_hal::uart::{DataBits, StopBits, UartConfig, UartPeripheral};

/// The second-stage boot loader for the Pico's W25Q080 flash.
#[link_section = ".boot2"]
#[used]
pub static BOOT2_FIRMWARE: [u8; 256] = rp2040_boot2::BOOT_LOADER_W25Q080;

/// The axes this firmware drives: 4 unless the flash image says fewer
/// (read once at boot; a harness may patch this byte, found by its symbol).
#[no_mangle]
#[used]
pub static COGSTEP_AXES: u8 = 4;

/// The dialect this firmware speaks: 0 protocol v1, 1 grbl 1.1 (read
/// once at boot; a harness may patch this byte, found by its symbol).
#[no_mangle]
#[used]
pub static COGSTEP_DIALECT: u8 = 0;

/// The axis cores' S-curve arithmetic: 0 Smooth (the default), 1 P2Exact
/// (the P2 driver's own, CORDIC emulated) (read once at boot; a harness may
/// patch this byte, found by its symbol).
#[no_mangle]
#[used]
pub static COGSTEP_ARITHMETIC: u8 = 0;

/// Whether core 1 computes the axes' ramp runs ahead ([`core1`]): 1 yes
/// (the default), 0 no: core 0 computes every run, the steps the same
/// (read once at boot; a harness may patch this byte, found by its symbol).
#[no_mangle]
#[used]
pub static COGSTEP_CORE1: u8 = 1;

/// CT (low 32 bits, µs) at which the last protocol byte reached the
/// firmware: a command in it acted on its axis at that CT plus the 5 µs
/// set-up. For a debugger, or the emulator's harness (`ct`), which checks
/// the pins against the axis core's own schedule.
#[no_mangle]
pub static COGSTEP_COMMAND_CT: AtomicU32 = AtomicU32::new(0);

/// The Pico's crystal.
const XTAL_FREQ_HZ: u32 = 12_000_000;
/// The system clock `init_clocks_and_plls` sets up: the core's cycles.
const SYS_CLOCK_HZ: u32 = 125_000_000;
/// The CT rate: the microsecond timer.
#[cfg(not(feature = "pio"))]
const CLKFREQ_HZ: u32 = 1_000_000;
/// The CT rate: the system clock, the PIO state machines' clock.
#[cfg(feature = "pio")]
const CLKFREQ_HZ: u32 = 125_000_000;
/// The first output pin (GP2); axis `i` uses `FIRST_PIN + 2i` and the next.
const FIRST_PIN: usize = 2;

/// The GPIO of output `output` of axis `axis`.
#[cfg(not(feature = "pio"))]
fn pin_of(axis: usize, output: Output) -> u32 {
    (FIRST_PIN + 2 * axis + output.index()) as u32
}

/// The board as the firmware sees it: CT is the frontier (the timer plus
/// the lead), and pins change through the edge queue (with the `pio`
/// feature, through the axes' state machines' words).
#[derive(Clone, Copy)]
struct Pico;

impl Hardware for Pico {
    fn now_ticks(&self) -> u64 {
        edges::frontier()
    }

    fn request_step_interrupt(&self) {
        edges::request_replan();
    }

    fn set_pin(&self, axis: usize, output: Output, level: bool) {
        #[cfg(not(feature = "pio"))]
        let ct = edges::set_pin(axis, pin_of(axis, output), level);
        #[cfg(feature = "pio")]
        let ct = {
            let ct = edges::stamped();
            pio::set_pin(axis, output.index(), level, ct);
            ct
        };
        inputs::record(axis, output, level, ct);
    }

    #[cfg(not(feature = "pio"))]
    fn drive_pin(&self, axis: usize, output: Output, level: bool, ct: u64) {
        let ct = edges::drive_pin(axis, pin_of(axis, output), level, ct, timer_now());
        inputs::record(axis, output, level, ct);
    }

    #[cfg(feature = "pio")]
    fn drive_pin(&self, axis: usize, output: Output, level: bool, ct: u64) {
        // Each axis's words keep their own time: an edge goes in at its
        // own CT, not the stamp (edges driven together, a train's due by
        // one wake-up or a catch-up's past its axis's few pending slots,
        // would otherwise share one CT and go out back to back, or early).
        pio::set_pin(axis, output.index(), level, ct);
        inputs::record(axis, output, level, ct);
    }

    fn set_pin_at(&self, axis: usize, output: Output, level: bool, ct: u64) {
        // Step edges come here: a train's rising edge, and a step pulse's
        // falling edge, its pulse's width after the rising edge. The
        // board ends each rise's pulse itself, exactly then: with the
        // `pio` feature its state machine (the falling edge would only
        // cost the encoder a look: `cogstep_pio_steps::AxisWords::edge`
        // takes an on-time falling edge as no change), else the
        // main loop, which stages each rise with its pulse's end
        // (`edges::set_pin_at` takes the core's falling edge for such a
        // pulse as that end). The step history takes falls as nothing.
        #[cfg(not(feature = "pio"))]
        let ct = edges::set_pin_at(axis, pin_of(axis, output), level, ct);
        #[cfg(feature = "pio")]
        {
            if !level {
                return;
            }
            edges::reach(ct);
            pio::set_pin(axis, output.index(), level, ct);
        }
        inputs::record(axis, output, level, ct);
    }

    fn switch_pins(&self) -> u64 {
        u64::from(inputs::SWITCH_PINS)
    }

    fn pulses_end_themselves(&self) -> bool {
        // Each state machine ends its pulses (the PIO build), or the main
        // loop stages each step's rise with its end (see `set_pin_at`).
        true
    }

    fn rises_per_axis(&self) -> bool {
        // Each state machine keeps its own time, its words owing nothing
        // to the other axes' (`pio.rs`); the timer build stages each
        // axis's edges in its own order and merges them (`edges.rs`).
        true
    }

    fn set_rises_at(&self, axis: usize, output: Output, rises: &mut TrainRises<'_>) {
        // A train's steps up to the frontier: `set_pin_at`'s work for
        // each, its encoder (its queue) found once.
        let last = inputs::with_history(axis, |history| {
            // The train's steps go one way: one store each into the
            // history, its count settled after them.
            let mut run = history.and_then(|history| {
                let step = history.step_of(output)?;
                Some(history.run(step))
            });
            #[cfg(feature = "pio")]
            return pio::set_rises(axis, output.index(), rises, |cts| {
                if let Some(run) = run.as_mut() {
                    run.push_all(cts);
                }
            });
            #[cfg(not(feature = "pio"))]
            return edges::set_rises(axis, pin_of(axis, output), rises, |ct| {
                if let Some(run) = run.as_mut() {
                    run.push(ct);
                }
            });
        });
        #[cfg(feature = "pio")]
        if let Some(ct) = last {
            edges::reach(ct);
        }
        #[cfg(not(feature = "pio"))]
        let _ = last;
    }
}

/// The microsecond timer now (TIMERAWH, TIMERAWL: no latching, so no
/// lock; a carry between the two reads is caught by reading high again).
pub(crate) fn timer_now() -> u64 {
    // SAFETY: reads of the timer's raw count.
    let timer = unsafe { &*pac::TIMER::ptr() };
    loop {
        let high = timer.timerawh().read().bits();
        let low = timer.timerawl().read().bits();
        if timer.timerawh().read().bits() == high {
            return (u64::from(high) << 32) | u64::from(low);
        }
    }
}

fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

#[hal::entry]
fn main() -> ! {
    let Some(mut pac) = pac::Peripherals::take() else {
        halt()
    };
    let mut watchdog = hal::Watchdog::new(pac.WATCHDOG);
    let Ok(clocks) = hal::clocks::init_clocks_and_plls(
        XTAL_FREQ_HZ,
        pac.XOSC,
        pac.CLOCKS,
        pac.PLL_SYS,
        pac.PLL_USB,
        &mut pac.RESETS,
        &mut watchdog,
    ) else {
        halt()
    };
    let mut sio = hal::Sio::new(pac.SIO);
    let pins = hal::gpio::Pins::new(
        pac.IO_BANK0,
        pac.PADS_BANK0,
        sio.gpio_bank0,
        &mut pac.RESETS,
    );
    // GP2..GP9: the axes' outputs, low. Kept as typed pins so that they
    // stay configured; the edge interrupt drives them through SIO.
    #[cfg(not(feature = "pio"))]
    let _outputs = (
        pins.gpio2.into_push_pull_output(),
        pins.gpio3.into_push_pull_output(),
        pins.gpio4.into_push_pull_output(),
        pins.gpio5.into_push_pull_output(),
        pins.gpio6.into_push_pull_output(),
        pins.gpio7.into_push_pull_output(),
        pins.gpio8.into_push_pull_output(),
        pins.gpio9.into_push_pull_output(),
    );
    // GP2..GP9: the axes' outputs, driven by PIO0's state machines.
    #[cfg(feature = "pio")]
    let _outputs = (
        pins.gpio2.into_function::<hal::gpio::FunctionPio0>(),
        pins.gpio3.into_function::<hal::gpio::FunctionPio0>(),
        pins.gpio4.into_function::<hal::gpio::FunctionPio0>(),
        pins.gpio5.into_function::<hal::gpio::FunctionPio0>(),
        pins.gpio6.into_function::<hal::gpio::FunctionPio0>(),
        pins.gpio7.into_function::<hal::gpio::FunctionPio0>(),
        pins.gpio8.into_function::<hal::gpio::FunctionPio0>(),
        pins.gpio9.into_function::<hal::gpio::FunctionPio0>(),
    );
    let uart_pins = (
        pins.gpio0.into_function::<hal::gpio::FunctionUart>(),
        pins.gpio1.into_function::<hal::gpio::FunctionUart>(),
    );
    let Ok(mut uart) = UartPeripheral::new(pac.UART0, uart_pins, &mut pac.RESETS).enable(
        UartConfig::new(115_200.Hz(), DataBits::Eight, None, StopBits::One),
        clocks.peripheral_clock.freq(),
    ) else {
        halt()
    };

    let timer = hal::Timer::new(pac.TIMER, &mut pac.RESETS, &clocks);
    // A step pulse's width, as the axis cores time it (each axis's own
    // `core_config`): each train step's pulse is staged so.
    let pulse = core_config(CLKFREQ_HZ, Variant::Sd).pulse_ticks;
    edges::init(timer.get_counter().ticks(), pulse);
    // SAFETY: alarm 0 and 1 interrupt enables; the handlers are below.
    let timer_regs = unsafe { &*pac::TIMER::ptr() };
    #[cfg(not(feature = "pio"))]
    timer_regs
        .inte()
        .modify(|_, w| w.alarm_0().set_bit().alarm_1().set_bit());
    #[cfg(feature = "pio")]
    timer_regs.inte().modify(|_, w| w.alarm_1().set_bit());

    // SAFETY: bytes in flash, read once.
    let grbl = unsafe { core::ptr::read_volatile(&COGSTEP_DIALECT) } == 1;
    let wanted = unsafe { core::ptr::read_volatile(&COGSTEP_AXES) };
    let p2exact = unsafe { core::ptr::read_volatile(&COGSTEP_ARITHMETIC) } == 1;
    let axes = if grbl {
        GRBL_AXES
    } else {
        usize::from(wanted).clamp(1, cogstep_firmware::AXES_MAX)
    };
    let config = |index: usize| {
        let variant = if index.is_multiple_of(2) {
            Variant::Sd
        } else {
            Variant::Cc
        };
        let mut config = core_config(CLKFREQ_HZ, variant);
        // The input interrupt's changes reach the cores the lead after the
        // pins made them, plus the main loop's delay in serving them:
        // homing's approach waits up to twice the lead for a release.
        config.input_latency_ticks = 2 * edges::LEAD_TICKS * edges::CT_PER_US;
        if p2exact {
            config.scurve.arithmetic = Arithmetic::P2Exact;
        }
        config
    };
    let Ok(built) = Firmware::new(Pico, axes, config) else {
        halt()
    };
    let Some(firmware) = cortex_m::singleton!(: Firmware<Pico> = built) else {
        halt()
    };
    let firmware: &'static Firmware<Pico> = firmware;
    // SAFETY: a byte in flash, read once.
    if unsafe { core::ptr::read_volatile(&COGSTEP_CORE1) } == 1 {
        core1::start(firmware, &mut pac.PSM, &mut pac.PPB, &mut sio.fifo, p2exact);
    }
    #[cfg(feature = "pio")]
    if pio::start(pac.PIO0, &mut pac.RESETS, FIRST_PIN as u8, axes, timer_now).is_none() {
        halt()
    }
    let Some(usb) = usb::UsbSerial::new(
        pac.USBCTRL_REGS,
        pac.USBCTRL_DPRAM,
        clocks.usb_clock,
        &mut pac.RESETS,
    ) else {
        halt()
    };
    let Some((rx, tx)) = uart::init() else { halt() };
    uart.enable_rx_interrupt();
    // SAFETY: the handlers touch only their own registers and the edge
    // queue (the PIO build: the word rings; UART0's: its receive ring).
    unsafe {
        // Below the edge (or PIO feeder) and input interrupts: they
        // preempt it (it drains up to 32 bytes at a time).
        cortex_m::Peripherals::steal()
            .NVIC
            .set_priority(pac::Interrupt::UART0_IRQ, uart::PRIORITY);
        #[cfg(not(feature = "pio"))]
        cortex_m::peripheral::NVIC::unmask(pac::Interrupt::TIMER_IRQ_0);
        #[cfg(feature = "pio")]
        cortex_m::peripheral::NVIC::unmask(pac::Interrupt::DMA_IRQ_0);
        cortex_m::peripheral::NVIC::unmask(pac::Interrupt::TIMER_IRQ_1);
        cortex_m::peripheral::NVIC::unmask(pac::Interrupt::UART0_IRQ);
    }

    let mut port = Port {
        _uart: uart,
        rx,
        tx,
        usb,
        to_usb: false,
    };
    #[cfg(feature = "bench")]
    {
        let mut next_wake: Option<u64> = None;
        bench::run(firmware, &mut port, move || {
            // In rounds, as the main loop: it sleeps until its next
            // wake-up is `REFILL_TICKS` away (here a wait on the timer).
            if let Some(t) = next_wake {
                let at = edges::timer_us(t).saturating_sub(edges::REFILL_TICKS);
                while timer_now() < at {}
            }
            let frontier = edges::advance_frontier(timer_now());
            next_wake = catch_up(firmware, next_wake, frontier);
            next_wake.is_none()
        })
    }
    #[cfg(not(feature = "bench"))]
    if grbl {
        serve_grbl(firmware, build_grbl_session(firmware), &mut port)
    }
    inputs::start(firmware);
    let _ = firmware.announce(&mut port);
    let mut session = Session::new();
    let mut next_wake: Option<u64> = None;
    loop {
        let frontier = edges::advance_frontier(timer_now());
        next_wake = produce(firmware, next_wake, frontier);
        if port.poll_usb() {
            let _ = firmware.announce(&mut port);
        }
        // From here on the frontier as it stands: a falling edge queued
        // ahead past it moved it up (`edges::set_pin_at`).
        if inputs::serve(firmware) {
            next_wake = catch_up(firmware, next_wake, edges::frontier());
        }
        while let Some(byte) = port.read_byte() {
            let frontier = edges::frontier();
            COGSTEP_COMMAND_CT.store(frontier as u32, Ordering::Relaxed);
            let _ = firmware.feed(&mut session, byte, &mut port);
            if edges::take_replan() {
                next_wake = produce(firmware, Some(frontier), frontier);
            }
        }
        sleep(&port, next_wake, None);
    }
}

/// The grbl board's session: its motion on the firmware's axes.
type GrblBoard = GrblSession<PathMotion<'static, Pico>, GrblGcode>;

/// How long the main loop sleeps at most while the path moves (µs): the
/// path's edges are pushed at most `cogstep_firmware::grbl::HORIZON_MS`
/// ahead of the clock, so it looks again well within that.
const PATH_WAKE_TICKS: u64 = 1_000;

/// grbl 1.1 on UART0 and USB, for ever: grbl's welcome again when a USB
/// host opens the port (as grbl boots when an Arduino's port opens), bytes
/// in as far as the receive buffer has room (the rest wait in the UART or
/// the USB port, as a sender's character counting expects), the path's
/// edges pushed ahead of the clock onto the axes' path queues, every
/// wake-up of the axes run up to the frontier (their edges queued for the
/// edge interrupt), the session's lines taken as the planner has room. It
/// sleeps until a byte or a USB event, the axes' next wake-up, or (while
/// the path moves) [`PATH_WAKE_TICKS`].
fn serve_grbl<D: hal::uart::UartDevice, P: hal::uart::ValidUartPinout<D>>(
    firmware: &'static Firmware<Pico>,
    session: &'static mut GrblBoard,
    port: &mut Port<D, P>,
) -> ! {
    let _ = session.start(port);
    let mut next_wake: Option<u64> = None;
    loop {
        let frontier = edges::advance_frontier(timer_now());
        // The wake-ups up to the new frontier first, each edge stamped with
        // its own CT. The path's pushes bring an axis up to the frontier
        // (`FirmwareAxis::synced`), and the edges that catch-up makes past
        // the axis's few pending slots go out with the last stamp: a CT
        // the PIO build's words had passed (refused, not made) or an old
        // one on the timer build (made late). At 5,000 steps/s a turn of a
        // millisecond overflowed them.
        next_wake = catch_up(firmware, next_wake, frontier);
        session.motion_mut().advance();
        next_wake = catch_up(firmware, next_wake, frontier);
        // A falling edge queued ahead past the frontier moved it up.
        let frontier = edges::frontier();
        if port.poll_usb() {
            let _ = session.start(port);
        }
        while session.room() > 0 {
            let Some(byte) = port.read_byte() else {
                break;
            };
            COGSTEP_COMMAND_CT.store(frontier as u32, Ordering::Relaxed);
            let _ = session.receive(byte, port);
        }
        let _ = session.poll(port);
        // A line's plan can take milliseconds on this core (soft `f64`):
        // the clock has moved on, and the pins are held only up to the
        // frontier made before it (the PIO build).
        let frontier = edges::advance_frontier(timer_now());
        next_wake = catch_up(firmware, next_wake, frontier);
        if session.is_busy() {
            continue;
        }
        // The state alone: a status report would compute the path's
        // speed (`f64` trigonometry) on every turn.
        let resting = matches!(
            session.motion().state(),
            MotionState::Idle | MotionState::Held
        );
        let cap = (!resting).then(|| timer_now() + PATH_WAKE_TICKS);
        sleep(port, next_wake, cap);
    }
}

/// The grbl session over `firmware`, grbl's default settings, in its
/// static (not inlined, so that the value built before it moves into the
/// static is off the stack once it has).
#[inline(never)]
fn build_grbl_session(firmware: &'static Firmware<Pico>) -> &'static mut GrblBoard {
    let Some(runner) = cortex_m::singleton!(: Option<GrblRunner> = None) else {
        halt()
    };
    let settings = Settings::default();
    let session = GrblSession::new(
        PathMotion::new(firmware, runner, &settings),
        GrblGcode::new(&settings),
        settings,
        env!("CARGO_PKG_VERSION"),
    );
    let Some(session) = cortex_m::singleton!(: GrblBoard = session) else {
        halt()
    };
    session
}

/// [`produce`] from the next wake-up, or from `frontier` if an axis took
/// a command since (`Hardware::request_step_interrupt`): its new events
/// may come before the wake-up planned.
fn catch_up(firmware: &Firmware<Pico>, next_wake: Option<u64>, frontier: u64) -> Option<u64> {
    let from = if edges::take_replan() {
        Some(next_wake.map_or(frontier, |t| t.min(frontier)))
    } else {
        next_wake
    };
    produce(firmware, from, frontier)
}

/// Runs every wake-up up to `frontier` (and the one at `from`, a
/// re-plan), each with its edges stamped with its CT and queued; returns
/// the next wake-up.
fn produce(firmware: &Firmware<Pico>, from: Option<u64>, frontier: u64) -> Option<u64> {
    let mut next = from;
    while let Some(t) = next.filter(|&t| t <= frontier) {
        if !edges::has_room() {
            break;
        }
        // The PIO build's words keep their own time: no timer to read.
        #[cfg(not(feature = "pio"))]
        edges::stamp_wake_up(t, timer_now());
        #[cfg(feature = "pio")]
        edges::stamp(t);
        #[cfg(feature = "bench")]
        let start = bench::now();
        // A step pulse's falling edge goes into the queue with its
        // rising edge when nothing comes between: no wake-up of its own
        // (on the timer build one past the frontier moves it up; the PIO
        // build's state machines end pulses themselves). So do the next
        // steps of a train up to the frontier, a few at a time.
        let (wake, _work) = firmware.step_interrupt_ahead_trains(
            t,
            frontier + edges::FALL_AHEAD_TICKS,
            frontier,
            edges::RISES_AHEAD,
        );
        next = wake;
        // A ramp run armed: core 1 computes the next meanwhile.
        core1::ring();
        // The edges staged, merged into the queue (the timer build).
        edges::flush(next);
        #[cfg(feature = "bench")]
        bench::record(start, _work);
        // The idle axes running low, held up to the next wake-up: a round
        // may run for milliseconds.
        #[cfg(feature = "pio")]
        pio::hold(no_edge_before(next, frontier), pio::Hold::RunningLow);
    }
    // Edges staged outside a wake-up (a command's) join the queue; a
    // run a command's catch-up armed goes to core 1.
    edges::flush(next);
    core1::ring();
    // Past any falling edge queued ahead.
    let frontier = edges::frontier();
    edges::stamp(frontier);
    // No edge comes before the next wake-up or the frontier: `pio.rs`
    // holds the pins of the axes that need it up to there (not those
    // whose rings are full: their words last milliseconds).
    #[cfg(feature = "pio")]
    pio::hold(no_edge_before(next, frontier), pio::Hold::RoundEnd);
    next
}

/// No edge of any axis comes before the next wake-up `next` or, if that
/// comes first, the `frontier` (where a command acts).
#[cfg(feature = "pio")]
fn no_edge_before(next: Option<u64>, frontier: u64) -> u64 {
    next.map_or(frontier, |t| t.min(frontier))
}

/// Sleeps until a byte or a USB event comes, the next wake-up is
/// [`edges::REFILL_TICKS`] away, or the timer reaches `cap` (alarm 1).
fn sleep<D: hal::uart::UartDevice, P: hal::uart::ValidUartPinout<D>>(
    port: &Port<D, P>,
    next_wake: Option<u64>,
    cap: Option<u64>,
) {
    // SAFETY: alarm 1 is the main loop's alone.
    let timer = unsafe { &*pac::TIMER::ptr() };
    let now = timer_now();
    // The PIO feeder holds the pins only up to the last frontier mark
    // (the timer plus the lead when it was made): mark again before that.
    #[cfg(feature = "pio")]
    let cap = Some(cap.map_or(now + pio::MARK_EVERY_US, |cap| {
        cap.min(now + pio::MARK_EVERY_US)
    }));
    let wake_at = match next_wake {
        // The queue full: look again when some edges have gone out.
        Some(t) if !edges::has_room() => Some((now + 100).min(edges::timer_us(t))),
        Some(t) => Some(edges::timer_us(t).saturating_sub(edges::REFILL_TICKS)),
        None => None,
    };
    let wake_at = match (wake_at, cap) {
        (Some(at), Some(cap)) => Some(at.min(cap)),
        (at, cap) => at.or(cap),
    };
    if wake_at.is_some_and(|at| at <= now + 2) {
        return;
    }
    // The UART and USB interrupts wake the loop (USB's masks itself).
    port.usb.arm_wake();
    // WFE, not WFI under PRIMASK: every exception's entry sets the event
    // register, so an alarm or a byte between the check and the WFE
    // makes it fall through (rp2040py's WFI would sleep through a
    // pending interrupt; the chip's would not). The interrupts that can
    // end the sleep (alarm 1, UART0, USB, an input change) set
    // [`MAIN_WAKE`]; the others (each edge's, the PIO feeder's) end a
    // WFE too, and the loop goes back to sleep on one load (it used to
    // look at the timer, the ports and the inputs each time: about 200
    // cycles a step with four axes ramping).
    // Alarm 1 is armed again before each WFE after it fired: rp2040py
    // fires an alarm up to 1 µs before its count (the chip fires on it),
    // and an alarm that came early would leave the loop asleep with none
    // armed.
    loop {
        // Cleared before the look: a wake after it is seen by the next.
        MAIN_WAKE.store(false, Ordering::Relaxed);
        if wake_at.is_some_and(|at| timer_now() >= at)
            || port.rx.ready()
            || port.usb.has_work()
            || inputs::pending()
        {
            return;
        }
        if let Some(at) = wake_at {
            // SAFETY: any 32-bit value arms alarm 1 for that count.
            timer.alarm1().write(|w| unsafe { w.bits(at as u32) });
            // An interrupt between the look and the arming can take it
            // past `at`: an alarm for a count gone by fires only when the
            // count comes round again (the chip compares for equality).
            if timer_now() >= at {
                return;
            }
        }
        loop {
            cortex_m::asm::wfe();
            if MAIN_WAKE.load(Ordering::Relaxed) {
                break;
            }
        }
    }
}

/// One of the main loop's wake sources (alarm 1, UART0, USB, an input
/// change) fired since it last looked ([`sleep`]).
pub(crate) static MAIN_WAKE: AtomicBool = AtomicBool::new(false);

/// Tells the main loop's [`sleep`] to look again (from a wake source's
/// interrupt).
#[inline(always)]
pub(crate) fn wake_main_loop() {
    MAIN_WAKE.store(true, Ordering::Relaxed);
}

/// The session's two ports: UART0 and USB CDC. Bytes come from either;
/// replies go to the port the last byte came on (USB once a host opens it).
struct Port<D: hal::uart::UartDevice, P: hal::uart::ValidUartPinout<D>> {
    /// UART0, set up and enabled: kept so that it stays so (its interrupt
    /// moves the bytes, `uart`).
    _uart: UartPeripheral<hal::uart::Enabled, D, P>,
    /// UART0's received bytes (`uart`: its interrupt fills the ring).
    rx: heapless::spsc::Consumer<'static, u8>,
    /// UART0's replies (`uart`: its interrupt sends the ring's bytes).
    tx: uart::Transmit,
    usb: usb::UsbSerial,
    /// Replies go to USB (else UART0).
    to_usb: bool,
}

impl<D: hal::uart::UartDevice, P: hal::uart::ValidUartPinout<D>> Port<D, P> {
    /// Serves the USB bus; `true` when a USB host has just opened the
    /// port, which then gets the replies (and the identity line is due).
    fn poll_usb(&mut self) -> bool {
        let opened = self.usb.poll();
        self.to_usb |= opened;
        opened
    }

    /// The next byte from USB, else from UART0; its port gets the replies.
    fn read_byte(&mut self) -> Option<u8> {
        if let Some(byte) = self.usb.read_byte() {
            self.to_usb = true;
            return Some(byte);
        }
        let byte = self.rx.dequeue()?;
        self.to_usb = false;
        Some(byte)
    }
}

impl<D: hal::uart::UartDevice, P: hal::uart::ValidUartPinout<D>> fmt::Write for Port<D, P> {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        if self.to_usb {
            self.usb.write(text.as_bytes(), timer_now);
        } else {
            self.tx.write(text.as_bytes());
        }
        Ok(())
    }
}

/// The edge interrupt: pins only ([`edges::on_edge_interrupt`]).
#[cfg(not(feature = "pio"))]
#[interrupt]
fn TIMER_IRQ_0() {
    edges::on_edge_interrupt();
}

/// The PIO feeder: a DMA channel done, or words waiting for an idle one
/// ([`pio::on_dma_interrupt`]).
#[cfg(feature = "pio")]
#[interrupt]
fn DMA_IRQ_0() {
    pio::on_dma_interrupt();
}

/// An input pin changed ([`inputs::on_input_interrupt`]).
#[interrupt]
fn IO_IRQ_BANK0() {
    inputs::on_input_interrupt();
    wake_main_loop();
}

/// Alarm 1 woke the main loop: it looks again.
#[interrupt]
fn TIMER_IRQ_1() {
    // SAFETY: clears alarm 1's interrupt only.
    let timer = unsafe { &*pac::TIMER::ptr() };
    timer.intr().write(|w| w.alarm_1().clear_bit_by_one());
    wake_main_loop();
}

/// Received bytes to their ring, replies from theirs to the FIFO
/// ([`uart`]); a byte received also wakes the main loop.
#[interrupt]
fn UART0_IRQ() {
    if uart::on_interrupt() {
        wake_main_loop();
    }
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    halt()
}

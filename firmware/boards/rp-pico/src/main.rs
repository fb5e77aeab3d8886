//! # cogstep on a Raspberry Pi Pico (RP2040, Cortex-M0+)
//!
//! Built in CI, **not yet run on hardware here** (see README.md beside
//! this crate for the pin map and how to flash it). A thin board layer
//! over `cogstep-firmware`:
//!
//! - **UART0** on GP0 (TX) and GP1 (RX): protocol v1 at 115,200 baud, 8N1;
//!   the identity line goes out at boot.
//! - **Time**: the RP2040's 64-bit microsecond timer is the CT
//!   (`clkfreq:1000000`); alarm 0 fires at the next step event.
//! - **Pins**: axis `i` drives GP`2 + 2i` and GP`3 + 2i`: step and
//!   direction (`sd`) on even axes, cw and ccw (`cc`) on odd ones. The
//!   stop "pin" of each axis is the level `S`, `R` and `!` set.
//! - **Axes**: 4.
#![no_std]
#![no_main]

use core::cell::{Cell, RefCell};
use core::fmt;

use cogstep_firmware::{core_config, Firmware, Hardware, Output, Variant};
use critical_section::Mutex;
use driver::serial::Session;
use fugit::RateExtU32;
use rp2040_hal as hal;
use rp2040_hal::clocks::Clock;
use rp2040_hal::pac;
use rp2040_hal::pac::interrupt;
use rp2040_hal::timer::{Alarm, Alarm0, Instant};
use rp2040_hal::uart::{DataBits, StopBits, UartConfig, UartPeripheral};

/// The second-stage boot loader for the Pico's W25Q080 flash.
#[link_section = ".boot2"]
#[used]
pub static BOOT2_FIRMWARE: [u8; 256] = rp2040_boot2::BOOT_LOADER_W25Q080;

/// The Pico's crystal.
const XTAL_FREQ_HZ: u32 = 12_000_000;
/// The CT rate: the microsecond timer.
const CLKFREQ_HZ: u32 = 1_000_000;
/// The axes this board drives.
const AXES: usize = 4;
/// The first output pin (GP2); axis `i` uses `FIRST_PIN + 2i` and the next.
const FIRST_PIN: usize = 2;

/// SIO's GPIO_OUT_SET and GPIO_OUT_CLR registers (RP2040 data sheet 2.3.1.7).
const SIO_GPIO_OUT_SET: usize = 0xD000_0014;
const SIO_GPIO_OUT_CLR: usize = 0xD000_0018;

static FIRMWARE: Mutex<Cell<Option<&'static Firmware<Pico>>>> = Mutex::new(Cell::new(None));
static ALARM: Mutex<RefCell<Option<Alarm0>>> = Mutex::new(RefCell::new(None));

/// The board as the firmware sees it.
#[derive(Clone, Copy)]
struct Pico {
    timer: hal::Timer,
}

impl Hardware for Pico {
    fn now_ticks(&self) -> u64 {
        self.timer.get_counter().ticks()
    }

    fn request_step_interrupt(&self) {
        cortex_m::peripheral::NVIC::pend(pac::Interrupt::TIMER_IRQ_0);
    }

    fn set_pin(&self, axis: usize, output: Output, level: bool) {
        let mask = 1u32 << (FIRST_PIN + 2 * axis + output.index());
        let register = if level {
            SIO_GPIO_OUT_SET
        } else {
            SIO_GPIO_OUT_CLR
        };
        // SAFETY: SIO's set/clear registers change only the masked pin,
        // which main made an output for this axis.
        unsafe { core::ptr::write_volatile(register as *mut u32, mask) }
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
    let sio = hal::Sio::new(pac.SIO);
    let pins = hal::gpio::Pins::new(
        pac.IO_BANK0,
        pac.PADS_BANK0,
        sio.gpio_bank0,
        &mut pac.RESETS,
    );
    // GP2..GP9: the axes' outputs, low. Kept as typed pins so that they
    // stay configured; the step interrupt drives them through SIO.
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
    let uart_pins = (
        pins.gpio0.into_function::<hal::gpio::FunctionUart>(),
        pins.gpio1.into_function::<hal::gpio::FunctionUart>(),
    );
    let Ok(uart) = UartPeripheral::new(pac.UART0, uart_pins, &mut pac.RESETS).enable(
        UartConfig::new(115_200.Hz(), DataBits::Eight, None, StopBits::One),
        clocks.peripheral_clock.freq(),
    ) else {
        halt()
    };

    let mut timer = hal::Timer::new(pac.TIMER, &mut pac.RESETS, &clocks);
    let Some(mut alarm) = timer.alarm_0() else {
        halt()
    };
    alarm.enable_interrupt();
    critical_section::with(|cs| ALARM.borrow(cs).replace(Some(alarm)));

    let config = |index: usize| {
        let variant = if index.is_multiple_of(2) {
            Variant::Sd
        } else {
            Variant::Cc
        };
        core_config(CLKFREQ_HZ, variant)
    };
    let Ok(built) = Firmware::new(Pico { timer }, AXES, config) else {
        halt()
    };
    let Some(firmware) = cortex_m::singleton!(: Firmware<Pico> = built) else {
        halt()
    };
    let firmware: &'static Firmware<Pico> = firmware;
    critical_section::with(|cs| FIRMWARE.borrow(cs).set(Some(firmware)));
    // SAFETY: the handler only touches state behind critical sections.
    unsafe { cortex_m::peripheral::NVIC::unmask(pac::Interrupt::TIMER_IRQ_0) };

    let mut port = Port(uart);
    let _ = firmware.announce(&mut port);
    let mut session = Session::new();
    loop {
        let mut byte = [0u8; 1];
        if let Ok(1) = port.0.read_raw(&mut byte) {
            let _ = firmware.feed(&mut session, byte[0], &mut port);
        }
    }
}

/// UART0 as a reply sink.
struct Port<D: hal::uart::UartDevice, P: hal::uart::ValidUartPinout<D>>(
    UartPeripheral<hal::uart::Enabled, D, P>,
);

impl<D: hal::uart::UartDevice, P: hal::uart::ValidUartPinout<D>> fmt::Write for Port<D, P> {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        self.0.write_full_blocking(text.as_bytes());
        Ok(())
    }
}

/// The step interrupt: every due event, then alarm 0 set for the next.
#[interrupt]
fn TIMER_IRQ_0() {
    let Some(firmware) = critical_section::with(|cs| FIRMWARE.borrow(cs).get()) else {
        return;
    };
    let (next, _work) = firmware.step_interrupt();
    critical_section::with(|cs| {
        let mut alarm = ALARM.borrow_ref_mut(cs);
        let Some(alarm) = alarm.as_mut() else { return };
        alarm.clear_interrupt();
        if let Some(at) = next {
            if alarm.schedule_at(Instant::from_ticks(at)).is_err() {
                // Already due: run again at once.
                cortex_m::peripheral::NVIC::pend(pac::Interrupt::TIMER_IRQ_0);
            }
        }
    });
}

#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    halt()
}

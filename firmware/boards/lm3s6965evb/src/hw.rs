//! The LM3S6965's registers this firmware touches: system clock, UART0,
//! GPIO port B, Timer0A, SysTick and the NVIC. Addresses and bits are from
//! the LM3S6965 data sheet.

use core::cell::Cell;
#[cfg(not(feature = "bench"))]
use core::fmt;

use core::cell::UnsafeCell;

use cogstep_firmware::{FastTrain, Hardware, Output};
use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::{NVIC, SCB, SYST};
use critical_section::CriticalSection;
use critical_section::Mutex;
use lm3s6965::Interrupt;

/// The system clock, Hz: the CT rate.
pub const CLKFREQ_HZ: u32 = 50_000_000;

const SYSCTL_RCC: usize = 0x400F_E060;
const SYSCTL_RCGC1: usize = 0x400F_E104;
const SYSCTL_RCGC2: usize = 0x400F_E108;
/// RCC.SYSDIV (bits 26:23) = 3: PLL (200 MHz) / 4 = 50 MHz; USESYSDIV (bit 22).
const RCC_SYSDIV_MASK: u32 = 0xF << 23;
const RCC_SYSDIV_50MHZ: u32 = (3 << 23) | (1 << 22);

const UART0: usize = 0x4000_C000;
#[cfg(not(feature = "bench"))]
const UART_DR: usize = 0x000;
#[cfg(not(feature = "bench"))]
const UART_FR: usize = 0x018;
const UART_IBRD: usize = 0x024;
const UART_FBRD: usize = 0x028;
const UART_LCRH: usize = 0x02C;
const UART_CTL: usize = 0x030;
const UART_IM: usize = 0x038;
const UART_ICR: usize = 0x044;
#[cfg(not(feature = "bench"))]
const UART_FR_RXFE: u32 = 1 << 4;
#[cfg(not(feature = "bench"))]
const UART_FR_TXFF: u32 = 1 << 5;

const GPIO_PORTB: usize = 0x4000_5000;
const GPIO_DIR: usize = 0x400;
const GPIO_DEN: usize = 0x51C;

const TIMER0: usize = 0x4003_0000;
const GPTM_CFG: usize = 0x000;
const GPTM_TAMR: usize = 0x004;
const GPTM_CTL: usize = 0x00C;
const GPTM_IMR: usize = 0x018;
const GPTM_ICR: usize = 0x024;
const GPTM_TAILR: usize = 0x028;

/// SysTick counts 2^24 ticks per wrap.
const SYSTICK_RELOAD: u32 = 0x00FF_FFFF;

fn read(address: usize) -> u32 {
    // SAFETY: every address passed is one of the memory-mapped registers
    // above, always mapped and readable on this chip.
    unsafe { core::ptr::read_volatile(address as *const u32) }
}

fn write(address: usize, value: u32) {
    // SAFETY: as in `read`; writing these registers has no effect on
    // memory the program uses.
    unsafe { core::ptr::write_volatile(address as *mut u32, value) }
}

/// Stops here for good (a fault, or start-up that cannot go on).
pub fn halt() -> ! {
    loop {
        cortex_m::asm::wfi();
    }
}

/// Clock, UART0, GPIO port B, Timer0A and SysTick.
pub fn init(core: &mut cortex_m::Peripherals) {
    write(
        SYSCTL_RCC,
        (read(SYSCTL_RCC) & !RCC_SYSDIV_MASK) | RCC_SYSDIV_50MHZ,
    );
    // Clocks for UART0 and Timer0 (RCGC1), GPIO A and B (RCGC2).
    write(SYSCTL_RCGC1, read(SYSCTL_RCGC1) | (1 << 16) | 1);
    write(SYSCTL_RCGC2, read(SYSCTL_RCGC2) | 0b11);

    // UART0: 115,200 baud at 50 MHz (27 + 8/64), 8N1, no FIFO so that
    // every byte raises the receive interrupt; receive interrupt on.
    write(UART0 + UART_CTL, 0);
    write(UART0 + UART_IBRD, 27);
    write(UART0 + UART_FBRD, 8);
    write(UART0 + UART_LCRH, 0x60);
    write(UART0 + UART_IM, 1 << 4);
    write(UART0 + UART_CTL, (1 << 9) | (1 << 8) | 1);

    // Port B: pins 0-7 digital outputs, low.
    write(GPIO_PORTB + GPIO_DIR, 0xFF);
    write(GPIO_PORTB + GPIO_DEN, 0xFF);
    write(GPIO_PORTB + (0xFF << 2), 0);

    // Timer0A: 32-bit one-shot, time-out interrupt.
    write(TIMER0 + GPTM_CTL, 0);
    write(TIMER0 + GPTM_CFG, 0);
    write(TIMER0 + GPTM_TAMR, 0x1);
    write(TIMER0 + GPTM_IMR, 1);

    let syst = &mut core.SYST;
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(SYSTICK_RELOAD);
    syst.clear_current();
    syst.enable_interrupt();
    syst.enable_counter();
}

/// Unmasks UART0 and Timer0A in the NVIC.
pub fn enable_interrupts() {
    // SAFETY: their handlers only touch state behind critical sections.
    unsafe {
        NVIC::unmask(Interrupt::UART0);
        NVIC::unmask(Interrupt::TIMER_0A);
    }
}

/// SysTick wraps so far.
static WRAPS: Mutex<Cell<u64>> = Mutex::new(Cell::new(0));

/// The SysTick handler's work.
pub fn systick_wrapped() {
    critical_section::with(|cs| {
        let wraps = WRAPS.borrow(cs);
        wraps.set(wraps.get() + 1);
    });
}

/// CT now: SysTick's count extended by its wraps.
pub fn now_ticks() -> u64 {
    now_and_systick().0
}

/// CT now, and the SysTick count it was read from (for
/// [`timer0_arm_from`]).
#[inline]
pub fn now_and_systick() -> (u64, u32) {
    critical_section::with(|cs| {
        let mut wraps = WRAPS.borrow(cs).get();
        let mut current = SYST::get_current();
        // A wrap whose interrupt cannot run yet (we hold the core): count
        // it here, with the counter read again after it.
        if SCB::is_pendst_pending() {
            wraps += 1;
            current = SYST::get_current();
        }
        let ct = (wraps << 24) | u64::from(SYSTICK_RELOAD - current);
        (ct, current)
    })
}

/// Clears Timer0A's time-out.
#[inline(always)]
pub fn timer0_clear() {
    write(TIMER0 + GPTM_ICR, 1);
}

/// Arms Timer0A to fire `interval` ticks after the CT of the edge the
/// fast path just drove (`served_inverted`: its low 32 bits, inverted,
/// `FastTrain::armed_ct_inverted`), or runs the step interrupt again at
/// once if that time has passed. Timer0A is stopped (a one-shot timer
/// clears its enable bit at its time-out; the fast path runs only on its
/// time-out or its own request). How late the interrupt runs is
/// SysTick's count since the edge: SysTick counts down and CT's low 24
/// bits are its count inverted, so that is `served_inverted − count`
/// (modulo 2^24: the interrupt is less than a wrap, 335 ms, late). The
/// next edge thus keeps its CT: no drift.
///
/// Periodic mode with the next interval written ahead into TAILR would
/// save this, and works under QEMU (its model reloads the count from
/// TAILR at the time-out only), but not on the chip: the LM3S69xx data
/// sheet says a TAILR written while the timer runs is loaded at the next
/// clock cycle, restarting the count.
#[inline(always)]
pub fn timer0_arm_after(served_inverted: u32, interval: u32) {
    let late = served_inverted.wrapping_sub(SYST::get_current()) & SYSTICK_RELOAD;
    if late < interval {
        write(TIMER0 + GPTM_TAILR, interval - late);
        write(TIMER0 + GPTM_CTL, 1);
    } else {
        NVIC::pend(Interrupt::TIMER_0A);
    }
}

/// GPIO port B's data register seen through the pin's mask: writing it
/// changes that pin alone.
fn pin_data_address(axis: usize, output: Output) -> usize {
    let mask = 1usize << (2 * axis + output.index());
    GPIO_PORTB + (mask << 2)
}

/// Drives a pin the fast path names by its data register's address
/// (`Lm3s::fast_pin`).
#[inline(always)]
pub fn drive_fast_pin(pin_data_address: u32, level: bool) {
    write(pin_data_address as usize, if level { 0xFF } else { 0 });
}

/// The fast path's train (see `cogstep_firmware::fast`).
struct FastCell(UnsafeCell<FastTrain>);

// SAFETY: the step interrupt (`TIMER_0A`) and code with interrupts masked
// (`Lm3s::with_fast_train`) are the only ones that reach it, and no
// handler that can preempt the step interrupt does.
unsafe impl Sync for FastCell {}

static FAST: FastCell = FastCell(UnsafeCell::new(FastTrain::new()));

/// The fast path's train, for the step interrupt.
///
/// # Safety
/// Call only in the step interrupt, once per run of it, and hold the
/// reference no longer than that run.
#[inline(always)]
pub unsafe fn fast_train() -> &'static mut FastTrain {
    // SAFETY: as the caller promises; code outside the interrupt reaches
    // it only with interrupts masked (`Lm3s::with_fast_train`).
    unsafe { &mut *FAST.0.get() }
}

/// Arms Timer0A to fire at CT `at` (at once if that has passed), or
/// stops it, from an earlier reading of [`now_and_systick`]: the ticks
/// since are SysTick's count down since then (the reading is less
/// than a SysTick wrap old: the step interrupt's body is far shorter).
/// Runs where nothing that touches Timer0 can preempt it (the step
/// interrupt, or with interrupts masked).
#[inline]
pub fn timer0_arm_from(at: Option<u64>, then: u64, systick_then: u32) {
    write(TIMER0 + GPTM_CTL, 0);
    // A time-out of the timer armed before is stale now (the fast path
    // must not take it for its edge's).
    write(TIMER0 + GPTM_ICR, 1);
    NVIC::unpend(Interrupt::TIMER_0A);
    let Some(at) = at else { return };
    let elapsed = systick_then.wrapping_sub(SYST::get_current()) & SYSTICK_RELOAD;
    let now = then + u64::from(elapsed);
    if at <= now {
        NVIC::pend(Interrupt::TIMER_0A);
        return;
    }
    let ticks = u32::try_from(at - now).unwrap_or(u32::MAX);
    write(TIMER0 + GPTM_TAILR, ticks);
    write(TIMER0 + GPTM_CTL, 1);
}

/// Clears UART0's interrupts (the main loop reads the bytes).
pub fn uart0_clear_interrupts() {
    write(UART0 + UART_ICR, 0x7FF);
}

/// UART0, for the protocol (the bench build reports by semihosting).
#[cfg(not(feature = "bench"))]
pub struct Uart0;

#[cfg(not(feature = "bench"))]
impl Uart0 {
    /// Whether a received byte waits.
    pub fn has_byte(&self) -> bool {
        read(UART0 + UART_FR) & UART_FR_RXFE == 0
    }

    /// The next received byte, if one waits.
    pub fn read_byte(&mut self) -> Option<u8> {
        if self.has_byte() {
            Some(read(UART0 + UART_DR) as u8)
        } else {
            None
        }
    }

    fn write_byte(&mut self, byte: u8) {
        while read(UART0 + UART_FR) & UART_FR_TXFF != 0 {}
        write(UART0 + UART_DR, u32::from(byte));
    }
}

#[cfg(not(feature = "bench"))]
impl fmt::Write for Uart0 {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        text.bytes().for_each(|byte| self.write_byte(byte));
        Ok(())
    }
}

/// The board as the firmware sees it.
#[derive(Clone, Copy, Debug)]
pub struct Lm3s;

impl Hardware for Lm3s {
    fn now_ticks(&self) -> u64 {
        now_ticks()
    }

    fn request_step_interrupt(&self) {
        NVIC::pend(Interrupt::TIMER_0A);
    }

    fn set_pin(&self, axis: usize, output: Output, level: bool) {
        write(pin_data_address(axis, output), if level { 0xFF } else { 0 });
    }

    /// The address of the pin's data register (see `drive_fast_pin`).
    fn fast_pin(&self, axis: usize, output: Output) -> u32 {
        pin_data_address(axis, output) as u32
    }

    fn with_fast_train<R>(
        &self,
        _cs: CriticalSection<'_>,
        use_it: impl FnOnce(&mut FastTrain) -> R,
    ) -> R {
        // SAFETY: interrupts are masked (the token says so): the step
        // interrupt cannot run meanwhile, and the firmware never nests
        // this call.
        use_it(unsafe { &mut *FAST.0.get() })
    }
}

/// What the semihosting command line says (`firmware/run-qemu` passes
/// it): `axes=N` (1 to 4), `arithmetic=p2exact` (default: smooth) and
/// `dialect=grbl` (default: protocol v1).
#[derive(Clone, Copy, Debug, Default)]
pub struct CommandLine {
    /// `axes=N`, when given and a number.
    pub axes: Option<usize>,
    /// `arithmetic=p2exact`.
    pub p2exact: bool,
    /// `dialect=grbl`.
    pub grbl: bool,
}

/// Reads the semihosting command line.
pub fn command_line() -> CommandLine {
    let mut buffer = [0u8; 128];
    let mut block = [buffer.as_mut_ptr() as usize, buffer.len() - 1];
    // SAFETY: SYS_GET_CMDLINE writes at most `block[1]` bytes into
    // `buffer` and its length into `block[1]`; run-qemu always enables
    // semihosting for this board.
    let result = unsafe {
        cortex_m_semihosting::syscall1(
            cortex_m_semihosting::nr::GET_CMDLINE,
            block.as_mut_ptr() as usize,
        )
    };
    let mut parsed = CommandLine::default();
    if result != 0 {
        return parsed;
    }
    let length = block[1].min(buffer.len());
    let Ok(line) = core::str::from_utf8(&buffer[..length]) else {
        return parsed;
    };
    for word in line.split_whitespace() {
        if let Some(count) = word.strip_prefix("axes=") {
            parsed.axes = count.parse().ok();
        } else if word == "arithmetic=p2exact" {
            parsed.p2exact = true;
        } else if word == "dialect=grbl" {
            parsed.grbl = true;
        }
    }
    parsed
}

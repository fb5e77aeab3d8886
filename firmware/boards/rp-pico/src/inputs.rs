//! Input pins: each axis's stop input, and the home and limit switches,
//! read with the time of their edge.
//!
//! ```text
//! pin edge ─► IO_IRQ_BANK0: timer now, GPIO_IN ─► input queue (lock-free)
//! main loop (after its round of edges): each change ─► stop input, or
//!     switch levels + the physical position the pins had then
//!     (StepHistory, fed from every edge the cores queue) ─► the axes
//! ```
//!
//! The cores run [`crate::edges::LEAD_TICKS`] ahead of the pins. The input
//! interrupt stamps a change with the timer; the main loop looks up, in
//! each axis's [`StepHistory`], the step the pins had made by then, and
//! the axis core latches homing's and a limit trip's position on that
//! step (`AxisCore::set_inputs_late`). The stop that follows starts from
//! where the core is, so it begins up to the lead (4 ms of steps) later
//! than on the hub, and a trip counts those steps in its stopping steps.
//! A stop input acts from where the core is too, like `S`.
//!
//! Every input has its pull-up on: an open switch reads high. A stop
//! input low holds its axis (as `S`); it runs while both it and the
//! protocol's level (`S`, `R`, `!`) are high. Home and limit switches
//! have the active level the host gives (`H`, `K`): 0 for a switch that
//! closes to ground. The input interrupt is live inside critical
//! sections (`cs.rs`: it touches only its own queue, the IO and pad
//! registers, the timer and SIO's input register) and ranks below the
//! edge interrupt.

use core::sync::atomic::{AtomicBool, Ordering};

use cogstep_firmware::{Firmware, Output, StepHistory, Variant, AXES_MAX};
use heapless::spsc::{Consumer, Producer, Queue};
use rp2040_hal::pac;

use crate::edges::{ct_of_us, MainLoopOnly};
use crate::Pico;

/// Axis `i`'s stop input.
pub const STOP_PINS: [u8; AXES_MAX] = [10, 11, 12, 13];
/// The pins a host may name as home and limit switches (`H`, `K`): GP14
/// to GP22 and GP26 to GP28. The pin map wires axis `i`'s home switch to
/// GP`14 + i`, its min limit to GP`18 + i` and its max limit to GP22,
/// GP26, GP27, GP28; any axis may use any of them.
pub const SWITCH_PINS: u32 = 0b1_1100_0111_1111_1100_0000_0000_0000;
/// Every input pin.
const INPUT_PINS: u32 = SWITCH_PINS | 0b11_1100_0000_0000;

/// Steps remembered per axis: more than the lead holds at the fastest
/// rate the cores make (a change older than that is placed on the
/// oldest step remembered).
const HISTORY: usize = 512;
/// Input changes waiting for the main loop.
const EVENTS: usize = 32;

/// IO_BANK0 (RP2040 data sheet 2.19.6): GPIOn_CTRL, INTR0 and PROC0_INTE0;
/// PADS_BANK0 (2.19.6.3): GPIOn; SIO: GPIO_IN, GPIO_OE_CLR.
const IO_BANK0: usize = 0x4001_4000;
const GPIO_CTRL: usize = IO_BANK0 + 0x004;
const INTR0: usize = IO_BANK0 + 0x0F0;
const PROC0_INTE0: usize = IO_BANK0 + 0x100;
const PADS_BANK0_GPIO: usize = 0x4001_C000 + 0x004;
const SIO_GPIO_IN: *const u32 = 0xD000_0004 as *const u32;
const SIO_GPIO_OE_CLR: *mut u32 = 0xD000_0028 as *mut u32;
/// FUNCSEL 5: SIO. Pad: input enable, pull-up, Schmitt trigger.
const FUNCSEL_SIO: u32 = 5;
const PAD_INPUT_PULL_UP: u32 = (1 << 6) | (1 << 3) | (1 << 1);
/// A pin's edge-low and edge-high bits in its INTR / INTE nibble.
const EDGES: u32 = 0b1100;
/// The input interrupt's NVIC priority: below the edge interrupt's (0).
const INPUT_PRIORITY: u8 = 0x40;

/// One input change: the timer when the interrupt saw it (µs) and every
/// input's level then (bit per GPIO).
#[derive(Clone, Copy, Debug)]
struct Change {
    timer_us: u64,
    levels: u32,
}

/// The interrupt's side, set once before the interrupt is unmasked.
static mut PRODUCER: Option<Producer<'static, Change>> = None;
/// The input levels the interrupt queued last (only it touches them).
static mut QUEUED_LEVELS: u32 = 0;
/// The queue was full: a change went unqueued (the main loop then reads
/// the pins itself).
static DROPPED: AtomicBool = AtomicBool::new(false);

/// What the main loop keeps: the queue's consumer, each axis's steps, and
/// the levels the axes were told last.
struct Reader {
    consumer: Option<Consumer<'static, Change>>,
    told: u32,
    histories: [StepHistory<HISTORY>; AXES_MAX],
}

static READER: MainLoopOnly<Reader> = MainLoopOnly::new(Reader {
    consumer: None,
    told: 0,
    histories: [
        StepHistory::new(Variant::Sd),
        StepHistory::new(Variant::Cc),
        StepHistory::new(Variant::Sd),
        StepHistory::new(Variant::Cc),
    ],
});

/// Output `output` of axis `axis` goes to `level` at CT `ct`: one more
/// edge in its history (the board's `set_pin` calls this for every edge).
pub fn record(axis: usize, output: Output, level: bool, ct: u64) {
    READER.with(|reader| {
        if let Some(history) = reader.histories.get_mut(axis) {
            history.record(ct, output, level);
        }
    });
}

/// Runs `use_it` on axis `axis`'s step history (`None` for an axis the
/// board does not have): for a run of steps, found once.
pub fn with_history<R>(
    axis: usize,
    use_it: impl FnOnce(Option<&mut StepHistory<HISTORY>>) -> R,
) -> R {
    READER.with(|reader| use_it(reader.histories.get_mut(axis)))
}

fn levels_now() -> u32 {
    // SAFETY: a read of SIO's input register.
    unsafe { core::ptr::read_volatile(SIO_GPIO_IN) & INPUT_PINS }
}

/// Makes the input pins SIO inputs with pull-ups, tells the axes their
/// levels, and starts the input interrupt (both edges of every input).
pub fn start(firmware: &Firmware<Pico>) {
    // SAFETY: the input pins' own pad and control registers and SIO's
    // output-enable clear register (only their bits): no other code
    // uses these pins.
    unsafe {
        core::ptr::write_volatile(SIO_GPIO_OE_CLR, INPUT_PINS);
        for pin in (0..32).filter(|pin| INPUT_PINS & (1 << pin) != 0) {
            let pad = (PADS_BANK0_GPIO + 4 * pin) as *mut u32;
            core::ptr::write_volatile(pad, PAD_INPUT_PULL_UP);
            core::ptr::write_volatile((GPIO_CTRL + 8 * pin) as *mut u32, FUNCSEL_SIO);
        }
    }
    // Let the pull-ups settle before the first reading.
    cortex_m::asm::delay(1_000);
    let queue: &'static mut Queue<Change, EVENTS> =
        cortex_m::singleton!(: Queue<Change, EVENTS> = Queue::new())
            .expect("inputs::start runs once");
    let (producer, consumer) = queue.split();
    let levels = levels_now();
    // SAFETY: the input interrupt is still masked; nothing else reads these.
    unsafe {
        *core::ptr::addr_of_mut!(PRODUCER) = Some(producer);
        *core::ptr::addr_of_mut!(QUEUED_LEVELS) = levels;
    }
    READER.with(|reader| {
        reader.consumer = Some(consumer);
        reader.told = levels;
    });
    tell(firmware, levels, None);
    // SAFETY: the edge interrupts of the input pins, cleared then enabled;
    // the NVIC priority and enable of the input interrupt (one core).
    unsafe {
        for bank in 0..4 {
            let mut mask = 0;
            for nibble in 0..8 {
                if INPUT_PINS & (1 << (8 * bank + nibble)) != 0 {
                    mask |= EDGES << (4 * nibble);
                }
            }
            core::ptr::write_volatile((INTR0 + 4 * bank) as *mut u32, mask);
            core::ptr::write_volatile((PROC0_INTE0 + 4 * bank) as *mut u32, mask);
        }
        let mut core = cortex_m::Peripherals::steal();
        core.NVIC
            .set_priority(pac::Interrupt::IO_IRQ_BANK0, INPUT_PRIORITY);
        cortex_m::peripheral::NVIC::unmask(pac::Interrupt::IO_IRQ_BANK0);
    }
}

/// The input interrupt: clears the input pins' edges, reads the timer and
/// the levels, and queues them if they changed.
pub fn on_input_interrupt() {
    // SAFETY: INTR is write-1-to-clear: only edge bits.
    unsafe {
        for bank in 0..4 {
            let intr = (INTR0 + 4 * bank) as *mut u32;
            let pending = core::ptr::read_volatile(intr);
            core::ptr::write_volatile(intr, pending & 0xcccc_cccc);
        }
    }
    let timer_us = crate::timer_now();
    let levels = levels_now();
    // SAFETY: only this interrupt uses PRODUCER and QUEUED_LEVELS after `start`.
    unsafe {
        let queued = &mut *core::ptr::addr_of_mut!(QUEUED_LEVELS);
        if levels == *queued {
            return;
        }
        if let Some(producer) = (*core::ptr::addr_of_mut!(PRODUCER)).as_mut() {
            if producer.enqueue(Change { timer_us, levels }).is_ok() {
                *queued = levels;
            } else {
                DROPPED.store(true, Ordering::Release);
            }
        }
    }
}

/// Whether a change waits for the main loop.
pub fn pending() -> bool {
    DROPPED.load(Ordering::Acquire)
        || READER.with(|reader| reader.consumer.as_ref().is_some_and(Consumer::ready))
}

/// Tells the axes of every change queued (the main loop calls this after
/// its round of edges, so that every step up to the changes' time is in
/// the histories). Returns whether there was any.
pub fn serve(firmware: &Firmware<Pico>) -> bool {
    let mut any = false;
    loop {
        let next = READER.with(|reader| {
            let change = reader.consumer.as_mut()?.dequeue()?;
            let before = core::mem::replace(&mut reader.told, change.levels);
            Some((before, change))
        });
        let Some((before, change)) = next else {
            break;
        };
        any = true;
        tell(
            firmware,
            change.levels,
            Some((before, Some(change_ct(change.timer_us)))),
        );
    }
    // A change the full queue dropped: the levels now, with no time (the
    // axes take them as from now).
    // No atomic swap on the M0+: read and clear with every interrupt
    // masked for those two instructions.
    let dropped = cortex_m::interrupt::free(|_| {
        let dropped = DROPPED.load(Ordering::Acquire);
        DROPPED.store(false, Ordering::Relaxed);
        dropped
    });
    if dropped {
        let now = levels_now();
        let before = READER.with(|reader| core::mem::replace(&mut reader.told, now));
        tell(firmware, now, Some((before, None)));
        any = true;
    }
    any
}

/// The CT by which a change stamped in timer microsecond `timer_us` had
/// come: the last CT of that microsecond. The stamp is the microsecond
/// the interrupt read, at or after the change. In the timer build an edge
/// is driven at or just after its CT, a whole microsecond, so this is the
/// stamp itself. In the `pio` build the CT is the system clock and the
/// state machines' pins run up to a microsecond behind it (they started
/// within the microsecond after the timer's count that fixed their CT,
/// `pio.rs`), so an edge stamped in microsecond `u` has a CT below `(u +
/// 1) × 125`: taking the microsecond's start instead placed a switch
/// reached on a step before that step (homing latched one step short,
/// about one time in two). A step within 2 µs after it would be taken
/// too: beyond the 198,000 steps/s a state machine can make.
fn change_ct(timer_us: u64) -> u64 {
    ct_of_us(timer_us + 1) - 1
}

/// Tells each axis its stop input and, when they changed, the switch
/// levels with the physical position its pins had at the change's CT
/// (`changed`: the levels before and that CT, if known; `None`: at start,
/// everything).
fn tell(firmware: &Firmware<Pico>, levels: u32, changed: Option<(u32, Option<u64>)>) {
    let differs = |mask: u32| changed.is_none_or(|(before, _)| (before ^ levels) & mask != 0);
    for (index, axis) in firmware.axes().iter().enumerate() {
        let stop = 1u32 << STOP_PINS[index];
        if differs(stop) {
            axis.set_stop_input(levels & stop != 0);
        }
        if differs(SWITCH_PINS) {
            let ct = changed.and_then(|(_, ct)| ct);
            let then = ct.map(|ct| READER.with(|reader| reader.histories[index].physical_at(ct)));
            axis.set_inputs(u64::from(levels & SWITCH_PINS), then);
        }
    }
}

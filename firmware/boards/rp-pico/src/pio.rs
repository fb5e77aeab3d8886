//! Step edges by PIO (cargo feature `pio`): one PIO0 state machine per
//! axis runs `cogstep_pio_steps::program`, and the edge queue's consumer
//! feeds them FIFO words instead of driving SIO pins.
//!
//! ```text
//! main loop: cores' edges ─► edge queue (CT in cycles) ─► + a frontier mark per round
//! PIO0_IRQ_0 (a TX FIFO not full): edges ─► AxisWords (per axis) ─► words ─► TX FIFOs
//! state machines: words ─► pins, exact to the 125 MHz clock
//! ```
//!
//! The CT is the system clock (125 MHz); the state machines start
//! together, and the CT of their first cycle is the timer's reading times
//! 125 (within a microsecond: the pins keep the cores' edges exactly
//! relative to one another, with that one offset). Each axis's words wait
//! in a small queue until its FIFO (8 words, joined) has room; the feeder
//! takes the next edge only while every axis has room for its words, then
//! tops the FIFOs up, and its interrupt stays enabled only for the axes
//! with words waiting (so it comes about once a word of a busy axis). The
//! main loop wakes it every few edges and with each round's frontier
//! mark, not once an edge, and never sleeps longer than [`MARK_EVERY_US`]. The queue
//! is in CT order, so each edge taken is also the promise that no other
//! axis has an edge before it: an axis running low in time (its words end
//! within `LOW_AHEAD` of the timer, read as a CT) is held up to there
//! (`AxisWords::hold_until`, holds of at least `HOLD_SPAN` unless it is
//! within `DRY_MARGIN` of running dry), and up to a round's mark (after
//! which the feeder may not run until the next round) every axis whose
//! words end before it. Holds are made once a pass of the
//! feeder, up to the last edge it took, not once an edge. Only
//! the board's axes' machines are fed. An edge the program cannot
//! make (`cogstep_pio_steps::EdgeError`) is counted in
//! [`COGSTEP_PIO_REFUSED`] and not made.
//!
//! Checked under the emulator (link 2 of the proof): `run-pico-sim --pio`
//! replaces PIO0 with a model that applies the program's closed form to
//! every word written here, at its simulated time
//! (`firmware/pico-sim/pio_model.py`), and `tests/tests/firmware_pico_pio.rs`
//! compares every edge with the axis cores' own schedule.

use core::sync::atomic::{AtomicU32, Ordering};

use cogstep_pio_steps::{
    AxisWords, StepPins, Word, Words, FIRST_WRITE_CYCLE, OUT_PIN_COUNT, PULSE_CYCLES,
};
use heapless::Deque;
use rp2040_hal::pac;
use rp2040_hal::pio::{Buffers, PIOBuilder, PIOExt, PinDir, ShiftDirection};

use crate::edges::{self, PinEdge, CT_PER_US};

/// Edges the PIO program could not make (see the module docs): for a
/// debugger or the emulator's harness.
#[no_mangle]
pub static COGSTEP_PIO_REFUSED: AtomicU32 = AtomicU32::new(0);

/// The core's 5 µs pulse is the program's.
const _: () = assert!(5 * CT_PER_US == PULSE_CYCLES as u64);

/// The longest the main loop may sleep, µs: each round's frontier mark
/// holds an idle axis's pins only up to the timer plus the lead
/// (`edges::LEAD_TICKS`), so the next round must come well before that, or
/// its state machine runs dry and every later edge is late.
pub const MARK_EVERY_US: u64 = edges::REFILL_TICKS;

/// From the timer's reading to the state machines' start, µs: enough to
/// make and push their first words, with room to spare (a start that
/// comes after this shifts every edge from its CT; 50 µs did, by 12.6 µs,
/// once the feeder's code moved: the emulator runs it from flash through
/// the XIP cache, as the chip does). Once, at boot.
const START_MARGIN_US: u64 = 500;
/// State machines (and axes) on PIO0.
const MACHINES: usize = 4;
/// Words an axis may have waiting for its FIFO.
const WAITING: usize = 32;
/// Closed words an axis may have beyond those (one is all it needs).
const SPILL: usize = 2;
/// Room an axis needs before the feeder takes another edge: the words one
/// edge can close (a word, split when it holds more than a second).
const ROOM: usize = 8;
/// An axis whose closed words end within this of now (cycles, 1 ms) is
/// held up to the last edge a pass of the feeder takes, by `HOLD_SPAN`
/// or more.
const LOW_AHEAD: u64 = 1_000 * CT_PER_US;
/// The shortest hold the feeder closes for an axis that still has words
/// (cycles, 100 µs): shorter holds would split steps into words for
/// little time gained.
const HOLD_SPAN: u64 = 100 * CT_PER_US;
/// An axis whose closed words end within this of now (cycles, 100 µs) is
/// held up to the last edge a pass takes, however near.
const DRY_MARGIN: u64 = 100 * CT_PER_US;
/// PIO0's registers (RP2040 data sheet 3.7): FLEVEL, TXF0..3, IRQ0_INTE,
/// and the atomic set and clear aliases (2.1.2).
const PIO0_BASE: usize = 0x5020_0000;
const FLEVEL: *const u32 = (PIO0_BASE + 0x00C) as *const u32;
const TXF0: usize = PIO0_BASE + 0x010;
const IRQ0_INTE: usize = PIO0_BASE + 0x12C;
const ALIAS_SET: usize = 0x2000;
const ALIAS_CLR: usize = 0x3000;
/// Each TX FIFO's depth: joined (`Buffers::OnlyTx`).
const FIFO_DEPTH: u32 = 8;
/// IRQ0_INTE's TXNFULL bits, of state machine 0.
const TXNFULL_SHIFT: u32 = 4;
/// The TXNFULL bits of the axes' machines (set once by [`start`]).
static ACTIVE_TXNFULL: AtomicU32 = AtomicU32::new(0);

/// One axis: its encoder and the words waiting for its FIFO.
struct AxisFeed {
    words: AxisWords,
    waiting: Deque<u32, WAITING>,
    /// Closed words not yet in `waiting` (a long hold's words, split).
    spill: Deque<Words, SPILL>,
}

impl AxisFeed {
    /// Queues closed words: one word (nearly always: only a word over a
    /// second splits) straight to `waiting`, more through the spill.
    /// Whether they spilled.
    fn queue(&mut self, words: Words) -> bool {
        if self.spill.is_empty() {
            // Words the encoder closes always encode.
            if let Some(Ok(raw)) = words.only().map(Word::encode) {
                if self.waiting.push_back(raw).is_ok() {
                    return false;
                }
            }
        }
        // The feeder takes an edge only with nothing spilled, and one edge
        // closes at most one word an axis: there is always room here.
        if self.spill.push_back(words).is_err() {
            refused();
        }
        self.refill();
        true
    }

    #[inline(always)]
    fn refill(&mut self) {
        if !self.spill.is_empty() {
            self.refill_from_spill();
        }
    }

    fn refill_from_spill(&mut self) {
        while self.waiting.len() < WAITING {
            let Some(spill) = self.spill.front_mut() else {
                return;
            };
            match spill.next() {
                // Words the splitter makes always encode.
                Some(word) => {
                    if let Ok(raw) = word.encode() {
                        let _ = self.waiting.push_back(raw);
                    }
                }
                None => {
                    self.spill.pop_front();
                }
            }
        }
    }

    fn idle(&self) -> bool {
        self.waiting.is_empty() && self.spill.is_empty()
    }
}

/// How many edges the feeder may take before it looks at the axes again:
/// each keeps `ROOM` free before every edge, and an edge closes at most
/// one word an axis unless its words spill (then it looks again at once).
fn room_for_edges(feeds: &[AxisFeed]) -> usize {
    let mut free = WAITING;
    for feed in feeds {
        if !feed.spill.is_empty() {
            return 0;
        }
        free = free.min(WAITING - feed.waiting.len());
    }
    (free + 1).saturating_sub(ROOM)
}

/// Counts an edge the program could not make.
fn refused() {
    // Only the feeder's interrupt writes it (the M0+ has no atomic add).
    let refused = COGSTEP_PIO_REFUSED.load(Ordering::Relaxed);
    COGSTEP_PIO_REFUSED.store(refused.wrapping_add(1), Ordering::Relaxed);
}

/// The feeder's state: its interrupt's alone once started.
static mut FEEDER: Option<Feeder> = None;

/// One [`AxisFeed`] per state machine; the first `active` (the board's
/// axes) are fed, the others never get a word.
struct Feeder {
    feeds: [AxisFeed; MACHINES],
    active: usize,
}

impl Feeder {
    /// The axes' feeds.
    #[inline(always)]
    fn feeds(&mut self) -> &mut [AxisFeed] {
        let active = self.active;
        &mut self.feeds[..active]
    }
}

/// The feeder's state.
///
/// # Safety
/// Only from the feeder's interrupt, or at start-up before that is
/// unmasked, and with no other reference from this function alive.
#[inline(always)]
unsafe fn feeder() -> Option<&'static mut Feeder> {
    // SAFETY: the caller's.
    unsafe { (*core::ptr::addr_of_mut!(FEEDER)).as_mut() }
}

/// Installs the program, sets up one state machine per axis (axis `i` on
/// GP`first_pin + 2i` and the next), gives each of the board's `axes`
/// (1 to 4) a first word holding its pins low, and starts them together at
/// the timer's reading `now()`. The machines of axes the board does not
/// have start too, hold their pins low and wait for a word that never
/// comes: they cost the feeder nothing. Call once, before unmasking
/// `PIO0_IRQ_0`. `None` if the program does not fit (it does: PIO0 is
/// this board's alone).
pub fn start(
    pio0: pac::PIO0,
    resets: &mut pac::RESETS,
    first_pin: u8,
    axes: usize,
    now: impl Fn() -> u64,
) -> Option<()> {
    let active = axes.clamp(1, MACHINES);
    let (mut pio, sm0, sm1, sm2, sm3) = pio0.split(resets);
    let installed = pio.install(&cogstep_pio_steps::program()).ok()?;
    let builder = |pin: u8| {
        // SAFETY: the four state machines share the program and none is
        // ever uninstalled.
        PIOBuilder::from_installed_program(unsafe { installed.share() })
            .out_pins(pin, OUT_PIN_COUNT)
            .out_shift_direction(ShiftDirection::Right)
            .autopull(false)
            .buffers(Buffers::OnlyTx)
            .clock_divisor_fixed_point(1, 0)
    };
    let outputs = |pin: u8| [(pin, PinDir::Output), (pin + 1, PinDir::Output)];
    let (mut m0, _, _) = builder(first_pin).build(sm0);
    let (mut m1, _, _) = builder(first_pin + 2).build(sm1);
    let (mut m2, _, _) = builder(first_pin + 4).build(sm2);
    let (mut m3, _, _) = builder(first_pin + 6).build(sm3);
    m0.set_pindirs(outputs(first_pin));
    m1.set_pindirs(outputs(first_pin + 2));
    m2.set_pindirs(outputs(first_pin + 4));
    m3.set_pindirs(outputs(first_pin + 6));

    // The first words go in before the start, so that each machine's
    // first `pull` finds one: its cycles then follow the closed form. The
    // start waits for the timer's count `start_us` (time enough to make
    // and push those words), so that its CT is known within the
    // microsecond.
    let start_us = now() + START_MARGIN_US;
    let start_ct = edges::ct_of_us(start_us);
    let first_write_ct = start_ct + u64::from(FIRST_WRITE_CYCLE);
    let feeds = core::array::from_fn(|axis| {
        let step_pins = if axis % 2 == 0 {
            StepPins::Sd
        } else {
            StepPins::Cc
        };
        let mut feed = AxisFeed {
            words: AxisWords::new(step_pins, first_write_ct),
            waiting: Deque::new(),
            spill: Deque::new(),
        };
        // Low until the first frontier mark (the frontier is at least a
        // lead ahead of the timer; a millisecond is well within it).
        let first_hold_end = first_write_ct + 1_000 * CT_PER_US;
        if axis < active {
            if let Some(words) = feed.words.hold_until(first_hold_end) {
                let _ = feed.queue(words);
            }
        }
        feed
    });
    // SAFETY: the feeder's interrupt is still masked.
    unsafe { *core::ptr::addr_of_mut!(FEEDER) = Some(Feeder { feeds, active }) };
    ACTIVE_TXNFULL.store(((1 << active) - 1) << TXNFULL_SHIFT, Ordering::Relaxed);
    // SAFETY: start-up, the interrupt still masked; the only reference.
    if let Some(feeder) = unsafe { feeder() } {
        let _ = top_up_fifos(feeder.feeds());
    }
    let machines = m0.with(m1).with(m2).with(m3).sync();
    while now() < start_us {}
    // All four in the same cycle.
    let _running = machines.start();
    // SAFETY: enables the TXNFULL interrupts of the axes' machines.
    unsafe { set_inte(ACTIVE_TXNFULL.load(Ordering::Relaxed)) };
    Some(())
}

/// Edges the main loop queued since it last woke the feeder (the main
/// loop's alone: a load and a store, the M0+ has no atomic add).
static QUEUED: AtomicU32 = AtomicU32::new(0);
/// The main loop wakes the feeder at least every this many queued edges
/// (and at each round's frontier mark): a long round of ramp arithmetic
/// must not leave the feeder without the edges it has made.
const WAKE_EVERY_EDGES: u32 = 8;

/// The main loop queued an edge: the feeder looks every few.
pub fn queued() {
    let queued = QUEUED.load(Ordering::Relaxed) + 1;
    if queued >= WAKE_EVERY_EDGES {
        wake();
    } else {
        QUEUED.store(queued, Ordering::Relaxed);
    }
}

/// The main loop queued edges or a frontier mark: the feeder looks at them.
pub fn wake() {
    QUEUED.store(0, Ordering::Relaxed);
    // SAFETY: the set alias changes only the bits written.
    unsafe { set_inte(ACTIVE_TXNFULL.load(Ordering::Relaxed)) };
}

unsafe fn set_inte(bits: u32) {
    // SAFETY: the caller's: IRQ0_INTE's atomic set alias.
    unsafe { core::ptr::write_volatile((IRQ0_INTE + ALIAS_SET) as *mut u32, bits) };
}

/// The four TX FIFOs' levels (FLEVEL: 4 bits a FIFO, TX first), read once:
/// a level only drops until the feeder writes again.
#[derive(Clone, Copy)]
struct Levels(u32);

impl Levels {
    fn read() -> Levels {
        // SAFETY: a read of FLEVEL, no side effect.
        Levels(unsafe { core::ptr::read_volatile(FLEVEL) })
    }

    fn of(self, machine: usize) -> u32 {
        self.0 >> (8 * machine) & 0xF
    }
}

/// Moves waiting words into every FIFO with room; the TXNFULL bits of
/// the machines left with no words waiting.
fn top_up_fifos(feeds: &mut [AxisFeed]) -> u32 {
    let levels = Levels::read();
    let mut idle = 0;
    for (machine, feed) in feeds.iter_mut().enumerate() {
        feed.refill();
        for _ in levels.of(machine)..FIFO_DEPTH {
            let Some(word) = feed.waiting.pop_front() else {
                break;
            };
            // SAFETY: the machine's TX FIFO register; it has room.
            unsafe { core::ptr::write_volatile((TXF0 + 4 * machine) as *mut u32, word) };
        }
        feed.refill();
        if feed.idle() {
            idle |= 1 << (TXNFULL_SHIFT + machine as u32);
        }
    }
    idle
}

/// What the edges one pass of the feeder took promise: that no edge
/// comes before `ct` (the queue is in CT order, so any edge taken is that
/// promise for every axis); `mark` if a round's frontier mark (an edge
/// with no pins) was among them.
#[derive(Clone, Copy)]
struct Promise {
    ct: u64,
    mark: bool,
}

impl Promise {
    /// The promise of the pass's edges so far (`None`: none yet), then
    /// `edge`'s.
    fn after(so_far: Option<Promise>, edge: &PinEdge) -> Promise {
        Promise {
            ct: edge.ct,
            mark: so_far.is_some_and(|promise| promise.mark) || is_mark(edge),
        }
    }
}

/// A round's frontier mark: an edge with no pins, the promise alone.
fn is_mark(edge: &PinEdge) -> bool {
    edge.set | edge.clear == 0
}

/// One queued edge to the encoders (a mark changes no pin); whether an
/// axis's words spilled.
fn take(feeder: &mut [AxisFeed], edge: &PinEdge, first_pin: u32) -> bool {
    !is_mark(edge) && make_edges(feeder, edge, first_pin)
}

/// Holds every axis running low up to what a pass's edges promise, so
/// that its state machine does not run dry while a busy axis holds the
/// feeder back. Once a pass, not once an edge: an axis held up to each
/// edge of a busy axis takes a word for each of its steps, and when the
/// core is overloaded every axis runs low.
///
/// Running low is in time, read from the timer: closed words that end
/// within `LOW_AHEAD` of now, where the hold would close at least
/// `HOLD_SPAN`; or within `DRY_MARGIN`. Between edges, holding an axis
/// with more time ahead would only split its steps into more words than
/// they need. After a round's frontier mark, every axis whose words end
/// before it: the main loop may not wake the feeder again until its next
/// round's mark, which may come as late as the lead allows (a round that
/// plans a move takes long: homing's turn from the seek to the backoff,
/// 1.16 ms on the emulator). Holding only the axes whose words ended
/// within 3 ms let an axis whose words ended 3.02 ms after a mark run dry
/// when the next mark came 3.2 ms later: 201 µs, and every later edge as
/// late (the PIO build's homing test failed on it about once in 75 runs).
/// Holds by words ahead, as the feeder first held, gave each idle axis
/// 2.3 words for every step of one busy axis; holds at every edge it
/// took, 0.82 under overload, now 0.17 (docs/performance.md).
fn hold_running_low(feeder: &mut [AxisFeed], promise: Promise) {
    let ct = promise.ct;
    // The CT now, read once if an axis needs it.
    let mut now = None;
    for feed in feeder.iter_mut() {
        if !feed.spill.is_empty() {
            continue;
        }
        let covered = feed.words.open_since();
        let span = ct.saturating_sub(covered);
        let hold = span > 0 && {
            let mut now = || *now.get_or_insert_with(now_ct);
            // After a mark every axis is held: the next mark may come as
            // late as the lead allows.
            promise.mark
                || covered < now() + DRY_MARGIN
                || (span >= HOLD_SPAN && covered < now() + LOW_AHEAD)
        };
        if hold {
            if let Some(words) = feed.words.hold_until(ct) {
                let _ = feed.queue(words);
            }
        }
    }
}

/// The CT now, from the timer's microseconds ([`edges::ct_of_us`]: no
/// 64-bit multiply; the feeder asks at most once a pass).
fn now_ct() -> u64 {
    edges::ct_of_us(crate::timer_now())
}

/// The pins an edge changes, to their axes' encoders; whether an axis's
/// words spilled.
fn make_edges(feeder: &mut [AxisFeed], edge: &PinEdge, first_pin: u32) -> bool {
    let ct = edge.ct;
    let changed = edge.set | edge.clear;
    let mut spilled = false;
    for (axis, feed) in feeder.iter_mut().enumerate() {
        if changed >> (first_pin + 2 * axis as u32) & 0b11 == 0 {
            continue;
        }
        for output in 0..2 {
            let mask = 1u32 << (first_pin + 2 * axis as u32 + output as u32);
            let level = if edge.set & mask != 0 {
                true
            } else if edge.clear & mask != 0 {
                false
            } else {
                continue;
            };
            match feed.words.edge(ct, output, level) {
                Ok(Some(words)) => spilled |= feed.queue(words),
                Ok(None) => {}
                Err(_) => refused(),
            }
        }
    }
    spilled
}

/// The feeder's interrupt: fills the FIFOs, turns queued edges into words
/// while every axis has room for them, and leaves its interrupt enabled
/// only for the machines with words waiting.
pub fn on_fifo_interrupt(first_pin: u32) {
    // SAFETY: the feeder's interrupt; the only reference.
    let Some(feeder) = (unsafe { feeder() }) else {
        return;
    };
    let feeder = feeder.feeds();
    let idle = loop {
        // Edges while every axis has room, then the axes running low held
        // and the FIFOs topped up once (not once an edge: this interrupt
        // comes about once a word).
        let mut room = room_for_edges(feeder);
        let mut queue_empty = false;
        let mut promise: Option<Promise> = None;
        while room > 0 {
            let Some(edge) = edges::next_edge() else {
                queue_empty = true;
                break;
            };
            room = if take(feeder, &edge, first_pin) {
                0
            } else {
                room - 1
            };
            promise = Some(Promise::after(promise, &edge));
        }
        if let Some(promise) = promise {
            hold_running_low(feeder, promise);
        }
        let idle = top_up_fifos(feeder);
        if queue_empty || room_for_edges(feeder) == 0 {
            break idle;
        }
    };
    // SAFETY: IRQ0_INTE's atomic clear alias: only the idle machines'
    // TXNFULL bits, which the main loop sets again when it queues edges.
    unsafe { core::ptr::write_volatile((IRQ0_INTE + ALIAS_CLR) as *mut u32, idle) };
}

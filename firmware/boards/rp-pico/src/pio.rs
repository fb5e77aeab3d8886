//! Step edges by PIO (cargo feature `pio`): one PIO0 state machine per
//! axis runs `cogstep_pio_steps::program`, and each axis's edges go
//! straight from the main loop to its own words, then by DMA to its TX
//! FIFO.
//!
//! ```text
//! main loop: a core's edges (CT in cycles) ─► its AxisWords ─► closed words ─► the axis's ring
//!            (a train's steps up to the frontier at once: set_rises)
//! DMA channel n, paced by TX FIFO n's data request: ring n ─► TX FIFO n
//! DMA_IRQ_0 (a channel done, or kicked): hands each idle channel the words written since
//! state machines: words ─► pins, exact to the 125 MHz clock
//! ```
//!
//! The CT is the system clock (125 MHz); the state machines start
//! together, and the CT of their first cycle is the timer's reading times
//! 125 (within a microsecond: the pins keep the cores' edges exactly
//! relative to one another, with that one offset).
//!
//! Each state machine keeps its own time, so an axis's words owe nothing
//! to the other axes: the main loop encodes every edge of an axis as it
//! decides it ([`set_pin`]), in the axis's CT order, and a train's steps
//! up to the frontier a run at a time ([`set_rises`], the board answering
//! yes to `Hardware::rises_per_axis`), each closed word going to the
//! axis's ring ([`RING`] words, 2 KiB aligned to its size). DMA channel n
//! reads ring n, its read address wrapping within it, and writes TX FIFO
//! n (8 words, joined) whenever that has room (TREQ DREQ_PIO0_TXn). A
//! channel is handed the words written since it last started when it is
//! idle: by the DMA interrupt, which its completion raises and the main
//! loop raises ([`kick`]) after writing to an idle channel's ring. So the
//! core takes an interrupt a run of words, not one a word: the state
//! machines' TXNFULL interrupt (the feeder until December 2026) cost
//! about 140 cycles a word.
//!
//! A word is known only when the axis's next edge is (its length is the
//! time to that edge), so an axis stepping slowly or standing still would
//! run its state machine dry. After each wake-up the main loop knows that
//! no edge of any axis comes before its next wake-up (or the frontier, if
//! that comes first: a command acts at the frontier), and [`hold`] closes,
//! up to there, the words of the axes that need it: within a round those
//! running low ([`Hold::RunningLow`]), at its end every axis that could
//! otherwise run dry before the next round ([`Hold::RoundEnd`]: holds of
//! at least `HOLD_SPAN`, or any hold within `DRY_MARGIN` of running dry).
//! Rounds come at least every [`MARK_EVERY_US`] and a round may be busy
//! for up to the lead, which the hold is ahead of the timer. The main loop runs a
//! wake-up only while every axis's ring has room for its words
//! ([`has_room`]). An edge whose CT the axis's words have already passed
//! (a late step: the main loop fell behind) is made as soon as they can,
//! and counted in [`COGSTEP_PIO_MADE_LATE`]; a pulse's fall is the state
//! machine's own. An edge the program cannot make even so
//! (`cogstep_pio_steps::EdgeError`) is counted in [`COGSTEP_PIO_REFUSED`]
//! and not made. Words the ring and its spill have no room for wait
//! there: the main loop waits until the state machine has taken words
//! ([`COGSTEP_PIO_WAITS`]), so no step is dropped for room.
//!
//! (Until December 2026 the edges went through the timer build's edge
//! queue, in one CT order for all axes, to a feeder in the interrupt that
//! encoded them and held the axes running low at each edge it took: the
//! queue's order was its only promise that no edge came earlier. That
//! cost the busy core about a quarter of its time at four axes ramping;
//! docs/performance.md has the figures.)
//!
//! Checked under the emulator (link 2 of the proof): `run-pico-sim --pio`
//! replaces PIO0 with a model that applies the program's closed form to
//! every word written here, at its simulated time
//! (`firmware/pico-sim/pio_model.py`), and `tests/tests/firmware_pico_pio.rs`
//! compares every edge with the axis cores' own schedule.

use core::sync::atomic::AtomicU32;

use cogstep_firmware::TrainRises;
use cogstep_pio_steps::ring::{Channel, RingCounts, RingWriter};
use cogstep_pio_steps::{
    AxisWords, EdgeError, StepPins, Word, Words, FIRST_WRITE_CYCLE, OUT_PIN_COUNT, PULSE_CYCLES,
    STEP_MIN_CYCLES,
};
use heapless::Deque;
use rp2040_hal::pac;
use rp2040_hal::pio::{Buffers, PIOBuilder, PIOExt, PinDir, ShiftDirection};

use crate::edges::{self, count, MainLoopOnly, CT_PER_US};

/// Edges the PIO program could not make, not even late (see the module
/// docs), or of an axis the board does not have: steps lost. (Words with
/// no room in an axis's ring are not: the main loop waits for room,
/// [`COGSTEP_PIO_WAITS`].) For a debugger or the emulator's harness.
#[no_mangle]
pub static COGSTEP_PIO_REFUSED: AtomicU32 = AtomicU32::new(0);

/// Edges made later than their CT: the axis's words had already passed
/// it (its core made late steps, the main loop having fallen behind:
/// the grbl path's `f64`), so the edge went out at the first CT the words
/// allow, [`STEP_MIN_CYCLES`] after the last write (a pulse's own fall,
/// asked at its rise, is the state machine's: nothing to make). Made, not
/// lost, as the timer build drives a late edge late; for a debugger or
/// the emulator's harness, which counts them as it counts a dry FIFO.
#[no_mangle]
pub static COGSTEP_PIO_MADE_LATE: AtomicU32 = AtomicU32::new(0);

/// Times the main loop waited for room in an axis's ring rather than drop
/// a word (see `AxisEncoder::wait_for_room`): the main loop had fallen
/// behind the pins by more than a ring of words. For a debugger or the
/// emulator's harness.
#[no_mangle]
pub static COGSTEP_PIO_WAITS: AtomicU32 = AtomicU32::new(0);

/// The core's 5 µs pulse is the program's.
const _: () = assert!(5 * CT_PER_US == PULSE_CYCLES as u64);

/// The longest the main loop may sleep, µs: each round's [`hold`]
/// closes an idle axis's words only up to the timer plus the lead
/// (`edges::LEAD_TICKS`), so the next round must come well before that, or
/// its state machine runs dry and every later edge is late. (Two
/// milliseconds, a lead's half, whatever `edges::REFILL_TICKS` is.)
pub const MARK_EVERY_US: u64 = 2_000;

/// From the timer's reading to the state machines' start, µs: enough to
/// make and push their first words, with room to spare (a start that
/// comes after this shifts every edge from its CT; 50 µs did, by 12.6 µs,
/// once the feeder's code moved: the emulator runs it from flash through
/// the XIP cache, as the chip does). Once, at boot.
const START_MARGIN_US: u64 = 500;
/// State machines (and axes) on PIO0.
const MACHINES: usize = 4;
/// An axis's ring: its closed words waiting for its FIFO (one slot of the
/// queue stays empty). The main loop runs up to the lead ahead of the
/// pins: 4 ms is 200 words at 50,000 steps/s, 792 at the program's
/// fastest (then the main loop waits for room, with the FIFO and the ring
/// 2.6 ms ahead).
pub const RING: usize = 512;
/// Closed words an axis may have that its ring had no room for (a word
/// over a second splits into several; one is all it needs).
const SPILL: usize = 4;
/// Free ring slots each axis needs before the main loop runs a wake-up:
/// the words one wake-up can close (its edges at one CT, the steps a train
/// makes ahead, `edges::RISES_AHEAD`, and a hold), with room to spare.
const HEADROOM: usize = 2 * edges::RISES_AHEAD;
/// Within a round, an axis whose words end within this of now (cycles,
/// 1 ms) is running low ([`Hold::RunningLow`]).
const LOW_AHEAD: u64 = 1_000 * CT_PER_US;
/// Within a round, the shortest hold (cycles, 500 µs): an axis stepping
/// faster than one step in this is busy, and its steps close its words.
const LOW_SPAN: u64 = 500 * CT_PER_US;
/// The shortest hold [`hold`] closes for an axis not about to run dry
/// (cycles, 100 µs): shorter ones would split steps into words for
/// little time gained.
const HOLD_SPAN: u64 = 100 * CT_PER_US;
/// An axis whose closed words end within this of now (cycles, 100 µs) is
/// held however short the hold.
const DRY_MARGIN: u64 = 100 * CT_PER_US;
/// PIO0's TX FIFO registers (RP2040 data sheet 3.7): TXF0..3.
const TXF0: usize = 0x5020_0000 + 0x010;
/// The DMA's registers (data sheet 2.5.7): channel n's at `DMA_BASE +
/// 0x40·n` (READ_ADDR, WRITE_ADDR, the CTRL alias that does not start it,
/// and the TRANS_COUNT alias that does), INTE0 and INTS0.
const DMA_BASE: usize = 0x5000_0000;
const CH_STRIDE: usize = 0x40;
const CH_READ_ADDR: usize = 0x00;
const CH_WRITE_ADDR: usize = 0x04;
const CH_AL1_CTRL: usize = 0x10;
const CH_AL1_TRANS_COUNT_TRIG: usize = 0x1C;
const DMA_INTE0: usize = DMA_BASE + 0x404;
const DMA_INTS0: usize = DMA_BASE + 0x40C;
/// CTRL: EN, DATA_SIZE (2: a word), INCR_READ, RING_SIZE (bits 6–9: the
/// read address wraps within 2^n bytes), CHAIN_TO (bits 11–14: the
/// channel itself, no chain), TREQ_SEL (bits 15–20: DREQ_PIO0_TXn is n),
/// BUSY.
const CTRL_EN: u32 = 1;
const CTRL_WORDS: u32 = 2 << 2;
const CTRL_INCR_READ: u32 = 1 << 4;
const CTRL_RING_SHIFT: u32 = 6;
const CTRL_CHAIN_SHIFT: u32 = 11;
const CTRL_TREQ_SHIFT: u32 = 15;
const CTRL_BUSY: u32 = 1 << 24;
/// A ring's size in bytes, as CTRL's RING_SIZE gives it (2^11 = 2 KiB).
const RING_BYTES_LOG2: u32 = 11;
const _: () = assert!(RING * 4 == 1 << RING_BYTES_LOG2);

/// One axis on the main loop's side: its encoder, the producer of its
/// ring, and the closed words its ring had no room for.
struct AxisEncoder {
    words: AxisWords,
    ring: Ring,
    spill: Deque<Words, SPILL>,
    /// How far behind its CT the last late edge went out (cycles), and
    /// where that left the words (`AxisWords::open_since`): while nothing
    /// else has moved them, the next late edge goes out as late, so that
    /// late steps keep their periods (see [`not_made_at_ct`]).
    lag: u64,
    lag_end: u64,
}

/// The axes' encoders, the main loop's alone once [`start`] has made them.
struct Encoders {
    axes: [AxisEncoder; MACHINES],
    /// The board's axes: the first `active` machines are fed.
    active: usize,
    /// [`set_rises`]'s steps and words of a run, kept here rather than
    /// zeroed on the stack at every call.
    run: RunScratch,
}

/// A run of steps on its way: their CTs and their words.
struct RunScratch {
    cts: [u64; FILL],
    words: [u32; FILL],
}

static ENCODERS: MainLoopOnly<Option<Encoders>> = MainLoopOnly::new(None);

/// An axis's ring of words: 2 KiB, aligned to its size, so that its DMA
/// channel's read address wraps within it (CTRL's RING_SIZE).
#[repr(C, align(2048))]
struct RingWords([u32; RING]);

/// The axes' rings. The main loop writes a slot only while the channel
/// has read it ([`Ring::room`]); the channel reads only the slots its
/// interrupt has handed it ([`arm`]), written before: the handshake of
/// `cogstep_pio_steps::ring`, model-checked there with loom.
static mut RING_WORDS: [RingWords; MACHINES] = [const { RingWords([0; RING]) }; MACHINES];
/// Each ring's counts: words written (the main loop's), words handed to
/// the channel (the DMA interrupt's).
static COUNTS: [RingCounts; MACHINES] = [const { RingCounts::new() }; MACHINES];

/// DMA channel `n`, which feeds machine `n`, as the ring's handshake sees
/// it (its registers, each access strongly ordered).
#[derive(Clone, Copy)]
struct DmaChannel(usize);

impl Channel for DmaChannel {
    #[inline(always)]
    fn busy(&self) -> bool {
        // SAFETY: a read of the channel's CTRL, no side effect.
        unsafe { core::ptr::read_volatile(channel(self.0, CH_AL1_CTRL)) & CTRL_BUSY != 0 }
    }

    #[inline(always)]
    fn read_slot(&self) -> usize {
        // SAFETY: a read of the channel's READ_ADDR, no side effect; it
        // wraps within the ring, aligned to its size.
        let read = unsafe { core::ptr::read_volatile(channel(self.0, CH_READ_ADDR)) };
        (read as usize >> 2) & (RING - 1)
    }

    #[inline(always)]
    fn start(&self, count: u32) {
        // SAFETY: the idle channel's TRANS_COUNT, starting it: it moves the
        // `count` words after its read address, all written.
        unsafe { core::ptr::write_volatile(channel(self.0, CH_AL1_TRANS_COUNT_TRIG), count) };
    }
}

/// The main loop's end of machine `machine`'s ring.
struct Ring {
    machine: usize,
    writer: RingWriter<RING>,
}

impl Ring {
    fn new(machine: usize) -> Ring {
        Ring {
            machine,
            writer: RingWriter::new(),
        }
    }

    /// The ring's first word's address.
    fn base(machine: usize) -> *mut u32 {
        // SAFETY: only the address is taken.
        unsafe { core::ptr::addr_of_mut!(RING_WORDS[machine]) as *mut u32 }
    }

    /// `word` into the next slot, if the ring has room; the DMA interrupt
    /// hands it to the channel ([`kick`]).
    #[inline(always)]
    fn enqueue(&mut self, word: u32) -> Result<(), u32> {
        if self.room() == 0 {
            return Err(word);
        }
        self.put(word);
        self.publish();
        Ok(())
    }

    /// Free slots now (the channel only frees more).
    #[inline(always)]
    fn room(&self) -> usize {
        self.writer.room(&DmaChannel(self.machine))
    }

    /// `word` into the next slot, which [`Ring::room`] said is free; the
    /// channel gets it once [`Ring::publish`] has counted it.
    #[inline(always)]
    fn put(&mut self, word: u32) {
        // SAFETY: a slot of this machine's ring that the channel has read
        // (or never had): it reads only slots handed to it, up to the
        // published count, which this word is not in yet.
        unsafe {
            core::ptr::write_volatile(Ring::base(self.machine).add(self.writer.next_slot()), word)
        };
        self.writer.advance();
    }

    /// Each of `words` into the next slots, which [`Ring::room`] said are
    /// free ([`Ring::put`] each).
    #[inline(always)]
    fn put_all(&mut self, words: &[u32]) {
        let base = Ring::base(self.machine);
        for &word in words {
            // SAFETY: as `put`'s.
            unsafe { core::ptr::write_volatile(base.add(self.writer.next_slot()), word) };
            self.writer.advance();
        }
    }

    /// The words put so far, counted for the DMA interrupt.
    #[inline(always)]
    fn publish(&self) {
        COUNTS[self.machine].publish(&self.writer);
    }
}

/// Register `offset` of DMA channel `machine` (channel n feeds machine n).
#[inline(always)]
fn channel(machine: usize, offset: usize) -> *mut u32 {
    (DMA_BASE + CH_STRIDE * machine + offset) as *mut u32
}

impl AxisEncoder {
    /// An axis of machine `machine` with both pins low, its first pin
    /// write at CT `first_write_ct`, its words going to `ring`.
    fn new(machine: usize, ring: Ring, first_write_ct: u64) -> AxisEncoder {
        let step_pins = if machine % 2 == 0 {
            StepPins::Sd
        } else {
            StepPins::Cc
        };
        AxisEncoder {
            words: AxisWords::new(step_pins, first_write_ct),
            ring,
            spill: Deque::new(),
            lag: 0,
            lag_end: u64::MAX,
        }
    }

    /// Whether the ring has room for another wake-up's words (the spilled
    /// words moved in first): else it holds milliseconds of words, at least
    /// 2.6 ms at the program's fastest step.
    fn has_room(&mut self, machine: usize) -> bool {
        self.refill(machine) && self.ring.room() >= HEADROOM
    }

    /// Queues closed words for machine `machine`: nearly always one word
    /// (only a word over a second splits), to the ring, from which the
    /// machine's DMA channel moves it to the FIFO.
    #[inline(always)]
    fn queue(&mut self, machine: usize, words: Words) {
        if self.spill.is_empty() {
            // Words the encoder closes always encode.
            if let Some(Ok(raw)) = words.only().map(Word::encode) {
                if self.ring.enqueue(raw).is_ok() {
                    kick(machine);
                    return;
                }
            }
        }
        if self.spill.is_full() {
            self.wait_for_room(machine);
        }
        let _ = self.spill.push_back(words);
        self.refill(machine);
    }

    /// Free ring slots for words queued straight in: none while words
    /// wait in the spill (they go first).
    #[inline(always)]
    fn room(&self) -> usize {
        if self.spill.is_empty() {
            self.ring.room()
        } else {
            0
        }
    }

    /// One encoded word for machine `machine`, as [`AxisEncoder::queue`]
    /// queues it but for the channel, which the caller kicks ([`kick`]).
    #[inline(always)]
    fn queue_word(&mut self, machine: usize, raw: u32) {
        if self.spill.is_empty() && self.ring.enqueue(raw).is_ok() {
            return;
        }
        self.queue(machine, Words::from(Word::decode(raw)));
    }

    /// The ring and the spill are full: waits until the state machine has
    /// taken enough words for the oldest spilled word to move into the
    /// ring. The main loop fell so far behind that the axis's words run
    /// more than a ring ahead of its pins (late steps, each made at the
    /// first CT the words allow, queued behind a long word: the grbl
    /// path's steps on an overloaded core). A step is never dropped for
    /// room: the wait makes the steps after it late instead, and is
    /// counted in [`COGSTEP_PIO_WAITS`]. The DMA interrupt stays live
    /// inside critical sections (`cs.rs`), so the ring drains meanwhile.
    #[cold]
    #[inline(never)]
    fn wait_for_room(&mut self, machine: usize) {
        count(&COGSTEP_PIO_WAITS);
        while !self.refill_from_spill(machine) && self.spill.is_full() {
            kick(machine);
            core::hint::spin_loop();
        }
    }

    /// Moves spilled words to the ring while it has room; whether the
    /// spill is empty.
    #[inline(always)]
    fn refill(&mut self, machine: usize) -> bool {
        if self.spill.is_empty() {
            return true;
        }
        self.refill_from_spill(machine)
    }

    fn refill_from_spill(&mut self, machine: usize) -> bool {
        while let Some(spill) = self.spill.front_mut() {
            if self.ring.room() == 0 {
                return false;
            }
            match spill.next() {
                // Words the splitter makes always encode.
                Some(word) => {
                    if let Ok(raw) = word.encode() {
                        let _ = self.ring.enqueue(raw);
                        kick(machine);
                    }
                }
                None => {
                    self.spill.pop_front();
                }
            }
        }
        true
    }
}

/// The ring's TX FIFO register of machine `machine`.
#[inline(always)]
fn txf(machine: usize) -> *mut u32 {
    (TXF0 + 4 * machine) as *mut u32
}

/// Installs the program, sets up one state machine per axis (axis `i` on
/// GP`first_pin + 2i` and the next), gives each of the board's `axes`
/// (1 to 4) a first word holding its pins low, and starts them together at
/// the timer's reading `now()`. The machines of axes the board does not
/// have start too, hold their pins low and wait for a word that never
/// comes: they cost the DMA nothing. Call once, from the main loop,
/// before unmasking `DMA_IRQ_0`. `None` if the program does not fit (it
/// does: PIO0 is this board's alone) or if called twice.
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

    // One DMA channel a machine: from the machine's ring (its read
    // address wrapping within it) to its TX FIFO, paced by the FIFO's
    // data request; completion raises DMA_IRQ_0 ([`on_dma_interrupt`]).
    resets.reset().modify(|_, w| w.dma().clear_bit());
    while resets.reset_done().read().dma().bit_is_clear() {}
    for machine in 0..MACHINES {
        let ctrl = CTRL_EN
            | CTRL_WORDS
            | CTRL_INCR_READ
            | RING_BYTES_LOG2 << CTRL_RING_SHIFT
            | (machine as u32) << CTRL_CHAIN_SHIFT
            | (machine as u32) << CTRL_TREQ_SHIFT;
        // SAFETY: channel `machine`'s registers, this module's alone; it
        // is idle (just out of reset).
        unsafe {
            core::ptr::write_volatile(channel(machine, CH_READ_ADDR), Ring::base(machine) as u32);
            core::ptr::write_volatile(channel(machine, CH_WRITE_ADDR), txf(machine) as u32);
            core::ptr::write_volatile(channel(machine, CH_AL1_CTRL), ctrl);
        }
    }
    // SAFETY: INTE0's bits of the four channels.
    unsafe { core::ptr::write_volatile(DMA_INTE0 as *mut u32, (1 << MACHINES) - 1) };

    // The first words go in before the start, so that each machine's
    // first `pull` finds one: its cycles then follow the closed form. The
    // start waits for the timer's count `start_us` (time enough to make
    // and push those words), so that its CT is known within the
    // microsecond.
    let start_us = now() + START_MARGIN_US;
    let start_ct = edges::ct_of_us(start_us);
    let first_write_ct = start_ct + u64::from(FIRST_WRITE_CYCLE);
    let mut encoders = Encoders {
        axes: [
            AxisEncoder::new(0, Ring::new(0), first_write_ct),
            AxisEncoder::new(1, Ring::new(1), first_write_ct),
            AxisEncoder::new(2, Ring::new(2), first_write_ct),
            AxisEncoder::new(3, Ring::new(3), first_write_ct),
        ],
        active,
        run: RunScratch {
            cts: [0; FILL],
            words: [0; FILL],
        },
    };
    // Low until the frontier (no edge comes before it: nothing has run
    // yet), and at least a millisecond (the main loop's first frontier is
    // a lead ahead of the timer, later than that). Up to the first
    // round's hold: the grbl build makes its session first, which took
    // 1.18 ms, and a hold of a millisecond ran dry. The channels take
    // them now (their interrupt is still masked): the FIFOs are empty.
    let first_hold_end = edges::frontier().max(first_write_ct + 1_000 * CT_PER_US);
    for (machine, encoder) in encoders.axes[..active].iter_mut().enumerate() {
        if let Some(words) = encoder.words.hold_until(first_hold_end) {
            encoder.queue(machine, words);
        }
        arm(machine);
    }
    ENCODERS.with(|slot| slot.replace(encoders));
    let machines = m0.with(m1).with(m2).with(m3).sync();
    while now() < start_us {}
    // All four in the same cycle.
    let _running = machines.start();
    Some(())
}

/// Pin `output` (0 or 1) of axis `axis` goes to `level` at CT `ct`: to the
/// axis's encoder, its closed words on their way to the FIFO. The main
/// loop's edges of an axis come in CT order; an edge the program cannot
/// make is counted and not made, as is one before [`start`] or of an axis
/// the board does not have.
pub fn set_pin(axis: usize, output: usize, level: bool, ct: u64) {
    ENCODERS.with(|encoders| match encoder_of(encoders, axis) {
        Some(encoder) => encoder.edge(axis, output, level, ct),
        None => count(&COGSTEP_PIO_REFUSED),
    });
}

/// Rising edges of pin `output` (0 or 1) of axis `axis`, each at its CT:
/// a train's steps, made as `rises` yields them (see [`set_pin`]); `each`
/// sees every CT after its edge, a run of them at a time. Returns the
/// last CT. The encoder is found once for the run, not once an edge, and
/// the steps go a run at a time through short loops, each over locals:
/// made (`TrainRises::fill`), encoded where their words are the
/// commonest kind (`cogstep_pio_steps::AxisWords::step_rises`), and put
/// in the ring; the channel is looked at once, after the run. (One step
/// at a time through all of it, the loop's state did not fit the M0+'s
/// registers: about 300 cycles a step went to loads and stores, 46 % of
/// core 0 with four axes at 45,000 steps/s.)
pub fn set_rises(
    axis: usize,
    output: usize,
    rises: &mut TrainRises<'_>,
    mut each: impl FnMut(&[u64]),
) -> Option<u64> {
    ENCODERS.with(|encoders| {
        let Some(Encoders {
            axes,
            run: RunScratch { cts, words },
            ..
        }) = encoders.as_mut().filter(|encoders| axis < encoders.active)
        else {
            let mut last = None;
            for ct in rises {
                count(&COGSTEP_PIO_REFUSED);
                each(&[ct]);
                last = Some(ct);
            }
            return last;
        };
        let encoder = &mut axes[axis];
        // The ring's free slots, read once: the short words go straight
        // in, counted for the channel once, after the run.
        let mut room = encoder.room();
        let mut last = None;
        loop {
            let made = rises.fill(cts);
            let mut done = 0;
            while done < made {
                let ahead = &cts[done..made];
                let encoded = encoder
                    .words
                    .step_rises(ahead, output, &mut words[..room.min(FILL)]);
                encoder.ring.put_all(&words[..encoded]);
                room -= encoded;
                done += encoded;
                let Some(&ct) = cts[..made].get(done) else {
                    break;
                };
                // Not the short way: no room, or another kind of word.
                match encoder.words.step_rise(ct, output) {
                    Some(raw) if room > 0 => {
                        encoder.ring.put(raw);
                        room -= 1;
                    }
                    Some(raw) => {
                        encoder.ring.publish();
                        encoder.queue_word(axis, raw);
                    }
                    None => {
                        encoder.ring.publish();
                        encoder.edge(axis, output, true, ct);
                        room = encoder.room();
                    }
                }
                done += 1;
            }
            each(&cts[..made]);
            if made > 0 {
                last = Some(cts[made - 1]);
            }
            if made < FILL {
                break;
            }
        }
        encoder.ring.publish();
        kick(axis);
        last
    })
}

/// Steps [`set_rises`] makes and encodes at a time.
const FILL: usize = 32;

/// Axis `axis`'s encoder, if the board has started with that axis.
#[inline(always)]
fn encoder_of(encoders: &mut Option<Encoders>, axis: usize) -> Option<&mut AxisEncoder> {
    encoders
        .as_mut()
        .filter(|encoders| axis < encoders.active)
        .map(|encoders| &mut encoders.axes[axis])
}

impl AxisEncoder {
    /// [`set_pin`] on this axis's encoder (machine `axis`).
    #[inline(always)]
    fn edge(&mut self, axis: usize, output: usize, level: bool, ct: u64) {
        // Only a rise's: a step's rise while the step before it is still
        // in its pulse is taken as no change (late steps come at one CT).
        let was_high = level && self.words.pins().bits() & (1 << (output & 1)) != 0;
        match self.words.edge(ct, output, level) {
            Ok(Some(words)) => self.queue(axis, words),
            Ok(None) if was_high => not_made_at_ct(self, axis, Ok(()), ct, output, level),
            Ok(None) => {}
            Err(error) => not_made_at_ct(self, axis, Err(error), ct, output, level),
        }
    }
}

/// An edge the words of axis `axis` did not make at its CT `ct` (`made`:
/// an error, or a rise taken as no change), made as soon as they can and
/// counted in [`COGSTEP_PIO_MADE_LATE`]; or, if not even so, counted in
/// [`COGSTEP_PIO_REFUSED`]. Late steps come so, when the main loop fell
/// behind: their rise and fall at one CT, or at a CT the words have
/// passed. Off the hot path (the hot path's result stays in registers).
///
/// A late edge goes out as late as the one before it, if that was late
/// and nothing has moved the words since (`AxisEncoder::lag`), and never
/// sooner than the words allow: late steps keep the periods the core gave
/// them, one lag behind, instead of going out back to back at the
/// program's fastest step (a burst at up to 198,000 steps/s after a pause,
/// which a real motor cannot follow: steps lost in the motor). The lag
/// ends where the axis's steps leave a gap longer than it (its next edge
/// is then on time), or a hold moves the words.
#[cold]
#[inline(never)]
fn not_made_at_ct(
    encoder: &mut AxisEncoder,
    axis: usize,
    made: Result<(), EdgeError>,
    ct: u64,
    output: usize,
    level: bool,
) {
    let words = &mut encoder.words;
    let pulses = words.pulses(output);
    let lag = if words.open_since() == encoder.lag_end {
        encoder.lag
    } else {
        0
    };
    let late = match made {
        // A step's rise while the step before it is still in its pulse:
        // the words took it as no change, and the step would be lost. It
        // goes as the next step.
        Ok(()) => {
            let next_step = words.open_since() + u64::from(STEP_MIN_CYCLES);
            if !pulses || ct >= next_step {
                return;
            }
            let at = next_step.max(ct + lag);
            words.edge(at, output, level).map(|made| (made, at))
        }
        // A pulse's fall: the state machine ends every pulse itself.
        Err(_) if pulses && !level => return,
        Err(error) => late_edge(words, error, ct + lag, output, level),
    };
    match late {
        Ok((made, made_ct)) => {
            count(&COGSTEP_PIO_MADE_LATE);
            encoder.lag = made_ct - ct;
            if let Some(words) = made {
                encoder.queue(axis, words);
            }
            encoder.lag_end = encoder.words.open_since();
        }
        Err(_) => count(&COGSTEP_PIO_REFUSED),
    }
}

/// An edge that its axis's words cannot make at its CT (`error`), made
/// at `not_before` or as soon after as they can: [`STEP_MIN_CYCLES`]
/// after the write or the pulse in its way (far enough for any write),
/// and after the next one in its way if that one is too (a few tries:
/// each moves past a write). Returns the words it closed and the edge's
/// CT.
fn late_edge(
    words: &mut AxisWords,
    mut error: EdgeError,
    not_before: u64,
    output: usize,
    level: bool,
) -> Result<(Option<Words>, u64), EdgeError> {
    for _ in 0..LATE_TRIES {
        let after_ct = match error {
            EdgeError::Pulse { rising_ct, .. } => rising_ct,
            EdgeError::Backwards { after_ct, .. } | EdgeError::TooClose { after_ct, .. } => {
                after_ct
            }
        };
        let at = (after_ct + u64::from(STEP_MIN_CYCLES)).max(not_before);
        match words.edge(at, output, level) {
            Err(next) => error = next,
            Ok(made) => return Ok((made, at)),
        }
    }
    Err(error)
}

/// How many times [`late_edge`] moves an edge past a write in its way.
const LATE_TRIES: usize = 3;

/// Whether every axis's ring has room for another wake-up's words (its
/// spilled words moved in first).
pub fn has_room() -> bool {
    ENCODERS.with(|encoders| {
        let Some(encoders) = encoders.as_mut() else {
            return true;
        };
        let active = encoders.active;
        encoders.axes[..active]
            .iter_mut()
            .enumerate()
            .all(|(machine, encoder)| encoder.has_room(machine))
    })
}

/// Which axes [`hold`] closes.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Hold {
    /// The end of a round: every axis whose hold is at least `HOLD_SPAN`,
    /// or whose words end within `DRY_MARGIN` of now. The next round may
    /// come as late as the lead allows (a round that plans a move takes
    /// long: homing's turn from the seek to the backoff, 1.16 ms on the
    /// emulator), so every axis that would run dry before then is held.
    /// An axis stepping faster than one step a `HOLD_SPAN` is not split:
    /// its next step comes within that, and its words with it.
    RoundEnd,
    /// Within a round, after a wake-up: only the axes standing still or
    /// stepping slowly (a hold of `LOW_SPAN` or more) whose words end
    /// within `LOW_AHEAD` of now. A round that makes milliseconds of a
    /// busy axis's steps would otherwise leave the idle axes without words
    /// until its end: one axis at 59,484 steps/s on a board of four ran
    /// the other three dry by up to 661 µs while it ramped, rounds of 2 ms
    /// and more coming one after the other. Busy axes are left alone: with
    /// holds of `HOLD_SPAN` (and any within `DRY_MARGIN` of running dry)
    /// after every wake-up, four axes ramping ran dry at 9,079 steps/s
    /// instead of 10,234, the holds splitting their steps.
    RunningLow,
}

/// No edge of any axis comes before CT `ct` (the next wake-up, or the
/// frontier if that comes first): closes, up to there, the words of the
/// axes `which` names.
pub fn hold(ct: u64, which: Hold) {
    ENCODERS.with(|encoders| {
        let Some(encoders) = encoders.as_mut() else {
            return;
        };
        let active = encoders.active;
        // The CT now, read once if an axis needs it.
        let mut now = None;
        for (machine, encoder) in encoders.axes[..active].iter_mut().enumerate() {
            let covered = encoder.words.open_since();
            let span = ct.saturating_sub(covered);
            if span == 0 {
                continue;
            }
            // An axis whose ring is (nearly) full has milliseconds of words.
            if !encoder.has_room(machine) {
                continue;
            }
            let hold = match which {
                Hold::RoundEnd => {
                    span >= HOLD_SPAN || covered < *now.get_or_insert_with(now_ct) + DRY_MARGIN
                }
                // A busy axis's next step comes within `LOW_SPAN`: not
                // split, and no timer read for it.
                Hold::RunningLow => {
                    span >= LOW_SPAN && covered < *now.get_or_insert_with(now_ct) + LOW_AHEAD
                }
            };
            if hold {
                if let Some(words) = encoder.words.hold_until(ct) {
                    encoder.queue(machine, words);
                }
            }
        }
    });
}

/// The CT now, from the timer's microseconds ([`edges::ct_of_us`]: no
/// 64-bit multiply).
fn now_ct() -> u64 {
    edges::ct_of_us(crate::timer_now())
}

/// Machine `machine` has words waiting in its ring: if its channel is idle,
/// the DMA interrupt hands them to it ([`arm`]). (A busy channel's
/// completion raises the interrupt, which hands it the words written
/// meanwhile.)
#[inline(always)]
fn kick(machine: usize) {
    if !DmaChannel(machine).busy() {
        cortex_m::peripheral::NVIC::pend(pac::Interrupt::DMA_IRQ_0);
    }
}

/// Hands the words written to machine `machine`'s ring since its channel
/// last started to the channel, if it is idle: it reads on from where it
/// stopped. Only from the DMA interrupt (or [`start`], before it is
/// unmasked).
#[inline(always)]
fn arm(machine: usize) {
    COUNTS[machine].arm(&DmaChannel(machine));
}

/// The DMA interrupt (a channel done, or a [`kick`]): hands each idle
/// channel the words its ring has for it.
pub fn on_dma_interrupt() {
    // SAFETY: INTS0's write-1-to-clear bits of the four channels, cleared
    // before the channels are looked at: one that finishes after raises
    // the interrupt again.
    unsafe { core::ptr::write_volatile(DMA_INTS0 as *mut u32, (1 << MACHINES) - 1) };
    for machine in 0..MACHINES {
        arm(machine);
    }
}

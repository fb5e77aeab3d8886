//! # One axis's step edges, made by an RP2040 PIO state machine
//!
//! The P2 has smart pins; the RP2040 has PIO state machines, one per axis.
//! The axis core still decides every step: the board turns its edges into
//! 32-bit words for the state machine's TX FIFO, and the state machine
//! turns the words into pin edges exact to its clock (8 ns at 125 MHz),
//! whatever the CPU is doing meanwhile. This crate is that contract, with
//! no hardware in it, so that it is tested on the host:
//!
//! - [`program`]: the PIO program (9 instructions, no side-set), one source
//!   for the board (which installs it) and for the emulator check (which
//!   runs its opcodes, exported by this crate's tests to
//!   `firmware/pico-sim/pio_steps.json`);
//! - [`Word`]: what a FIFO word says, [`Word::encode`] and the total
//!   [`Word::decode`];
//! - [`step_words`] and [`hold_words`]: a step period or a pin state held
//!   for a time, in cycles, as FIFO words (long ones split);
//! - [`pin_writes`]: the closed form, words to the cycle of every pin write;
//! - [`AxisWords`]: an axis's edges, as its core decides them, made into
//!   the words whose closed form gives them back.
//!
//! ## The program
//!
//! Two pins, written together by `out pins, 2` (OUT base = the axis's first
//! pin): bit 0 is the step pin (`sd`) or cw (`cc`), bit 1 the direction
//! pin or ccw. The OSR shifts right, autopull is off, the clock divider is 1.
//!
//! ```text
//!     .wrap_target
//! 0   pull block            ; the next word (stalls while the FIFO is empty)
//! 1   out x, 1              ; bit 0: 1 = a step, 0 = a hold
//! 2   jmp !x, 6             ; a hold writes its pins at 6
//! 3   out pins, 2           ; step: bits 1-2, the rising edge (cycle t)
//! 4   set x, 19       [3]
//! 5   jmp x--, 5      [30]  ; 20 × 31 cycles
//! 6   out pins, 2           ; step: bits 3-4 at t + 625, the falling edge;
//!                           ; hold: bits 1-2 at t
//! 7   out y, 27             ; the count c
//! 8   jmp y--, 8            ; c + 1 cycles
//!     .wrap
//! ```
//!
//! The pulse is the same for every step and `sd` and `cc` share the
//! program: only the words differ (`sd`: high = step + dir, low = dir;
//! `cc`: high = the one pin of the step's direction, low = none).
//!
//! ## The words
//!
//! | bits | step (bit 0 = 1) | hold (bit 0 = 0) |
//! |---|---|---|
//! | 1–2 | pins from the rising edge | pins from now |
//! | 3–4 | pins from the falling edge | count c (bits 3–29) |
//! | 5–31 | count c (27 bits) | (bits 30–31 unused, written 0) |
//!
//! ## The closed form
//!
//! With the state machine started at the `pull` (cycle 0) and word k in the
//! FIFO by the cycle its `pull` runs, word 0 makes its first pin write at
//! cycle [`FIRST_WRITE_CYCLE`] = 3 and word k + 1 its first write at
//! t(k + 1) = t(k) + d(k), where d = c + [`STEP_MIN_CYCLES`] (631) for a
//! step and d = c + [`HOLD_MIN_CYCLES`] (6) for a hold. A step writes its
//! high pins at t(k) and its low pins at t(k) + [`PULSE_CYCLES`] (625 =
//! 5 µs at 125 MHz). A word that reaches the FIFO late delays its edges and
//! every later one by its lateness: that is a late edge, outside the closed
//! form. Step rates: at most 125 MHz / 631 ≈ 198,000 steps/s; one word
//! holds a period of up to 2^27 − 1 + 631 cycles (≈ 1.07 s), longer ones
//! are a step word and hold words.
#![cfg_attr(not(test), no_std)]

use core::fmt;

mod axis;
pub use axis::{AxisWords, EdgeError, StepPins};
pub mod ring;

use pio::{JmpCondition, OutDestination, SetDestination};

/// The PIO clock these cycle counts are made for: the system clock, the
/// state machine's divider 1.
pub const PIO_CLOCK_HZ: u32 = 125_000_000;
/// Cycles from a `pull` to the first pin write of the word it takes.
pub const FIRST_WRITE_CYCLE: u32 = 3;
/// Pulse loop: iterations of `jmp x--` (x set to one less).
const PULSE_LOOPS: u32 = 20;
/// Pulse loop: cycles of one `jmp x--` (its delay plus one).
const PULSE_LOOP_CYCLES: u32 = 31;
/// The delay on `set x`.
const PULSE_SET_DELAY: u32 = 3;
/// Step pin high time: from `out pins` (3) through `set x` (4) and the loop
/// (5) to `out pins` (6). 5 µs at 125 MHz.
pub const PULSE_CYCLES: u32 = 2 + PULSE_SET_DELAY + PULSE_LOOPS * PULSE_LOOP_CYCLES;
const _: () = assert!(PULSE_CYCLES == 625);
/// The shortest hold (count 0): `out pins`, `out y`, one `jmp y--`, then
/// the next word's `pull`, `out x`, `jmp !x` before its first write.
pub const HOLD_MIN_CYCLES: u32 = 6;
/// The shortest step period (count 0): the pulse, then a shortest hold.
pub const STEP_MIN_CYCLES: u32 = PULSE_CYCLES + HOLD_MIN_CYCLES;
/// Bits of a word's count.
pub const COUNT_BITS: u32 = 27;
/// The largest count.
pub const COUNT_MAX: u32 = (1 << COUNT_BITS) - 1;
/// The longest step period one word holds.
pub const STEP_MAX_CYCLES: u32 = STEP_MIN_CYCLES + COUNT_MAX;
/// The longest hold one word holds.
pub const HOLD_MAX_CYCLES: u32 = HOLD_MIN_CYCLES + COUNT_MAX;
/// Pins the program writes (OUT count), from the axis's first pin.
pub const OUT_PIN_COUNT: u8 = 2;

/// The program, as the board installs it (origin free, wrap 8 → 0).
pub fn program() -> pio::Program<{ pio::RP2040_MAX_PROGRAM_SIZE }> {
    let mut asm = pio::Assembler::<{ pio::RP2040_MAX_PROGRAM_SIZE }>::new();
    let mut next_word = asm.label();
    let mut pulse = asm.label();
    let mut write_pins = asm.label();
    let mut wait = asm.label();
    let mut wrap_source = asm.label();
    asm.bind(&mut next_word);
    asm.pull(false, true);
    asm.out(OutDestination::X, 1);
    asm.jmp(JmpCondition::XIsZero, &mut write_pins);
    asm.out(OutDestination::PINS, OUT_PIN_COUNT);
    asm.set_with_delay(
        SetDestination::X,
        (PULSE_LOOPS - 1) as u8,
        PULSE_SET_DELAY as u8,
    );
    asm.bind(&mut pulse);
    asm.jmp_with_delay(
        JmpCondition::XDecNonZero,
        &mut pulse,
        (PULSE_LOOP_CYCLES - 1) as u8,
    );
    asm.bind(&mut write_pins);
    asm.out(OutDestination::PINS, OUT_PIN_COUNT);
    asm.out(OutDestination::Y, COUNT_BITS as u8);
    asm.bind(&mut wait);
    asm.jmp(JmpCondition::YDecNonZero, &mut wait);
    asm.bind(&mut wrap_source);
    asm.assemble_with_wrap(wrap_source, next_word)
}

/// The axis's two pins as one write: bit 0 the step pin (`sd`) or cw
/// (`cc`), bit 1 the direction pin or ccw.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Pins(u8);

impl Pins {
    /// Both pins low.
    pub const LOW: Pins = Pins(0);

    /// The low two bits of `bits`.
    pub const fn from_bits(bits: u8) -> Pins {
        Pins(bits & 0b11)
    }

    /// Step and direction levels (`sd`).
    pub const fn sd(step: bool, dir: bool) -> Pins {
        Pins(step as u8 | (dir as u8) << 1)
    }

    /// Clockwise and counter-clockwise levels (`cc`).
    pub const fn cc(cw: bool, ccw: bool) -> Pins {
        Pins(cw as u8 | (ccw as u8) << 1)
    }

    /// The two bits.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// Level of the first pin (step or cw).
    pub const fn first(self) -> bool {
        self.0 & 1 != 0
    }

    /// Level of the second pin (direction or ccw).
    pub const fn second(self) -> bool {
        self.0 & 2 != 0
    }
}

/// What one FIFO word tells the state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Word {
    /// Pins to `high` now, to `low` [`PULSE_CYCLES`] later; the next word's
    /// first write comes `period_cycles` after this word's.
    Step {
        /// The pins from the rising edge.
        high: Pins,
        /// The pins from the falling edge.
        low: Pins,
        /// [`STEP_MIN_CYCLES`] to [`STEP_MAX_CYCLES`].
        period_cycles: u32,
    },
    /// Pins to `pins` now; the next word's first write comes `cycles` later.
    Hold {
        /// The pins from now on.
        pins: Pins,
        /// [`HOLD_MIN_CYCLES`] to [`HOLD_MAX_CYCLES`].
        cycles: u32,
    },
}

/// Why cycles cannot be made into words.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WordError {
    /// A step period shorter than [`STEP_MIN_CYCLES`] (or, for one word,
    /// longer than [`STEP_MAX_CYCLES`]).
    StepPeriod {
        /// The period asked for.
        cycles: u64,
    },
    /// A hold shorter than [`HOLD_MIN_CYCLES`] (or, for one word, longer
    /// than [`HOLD_MAX_CYCLES`]).
    Hold {
        /// The hold asked for.
        cycles: u64,
    },
}

impl fmt::Display for WordError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WordError::StepPeriod { cycles } => write!(
                f,
                "a step period of {cycles} cycles (a step word holds {STEP_MIN_CYCLES} to {STEP_MAX_CYCLES}, step words {STEP_MIN_CYCLES} or more)"
            ),
            WordError::Hold { cycles } => write!(
                f,
                "a hold of {cycles} cycles (a hold word holds {HOLD_MIN_CYCLES} to {HOLD_MAX_CYCLES}, hold words {HOLD_MIN_CYCLES} or more)"
            ),
        }
    }
}

impl Word {
    /// The FIFO word, or why this word cannot be one.
    pub fn encode(self) -> Result<u32, WordError> {
        match self {
            Word::Step {
                high,
                low,
                period_cycles,
            } => match period_cycles.checked_sub(STEP_MIN_CYCLES) {
                Some(count) if count <= COUNT_MAX => {
                    Ok(1 | u32::from(high.bits()) << 1 | u32::from(low.bits()) << 3 | count << 5)
                }
                _ => Err(WordError::StepPeriod {
                    cycles: period_cycles.into(),
                }),
            },
            Word::Hold { pins, cycles } => match cycles.checked_sub(HOLD_MIN_CYCLES) {
                Some(count) if count <= COUNT_MAX => Ok(u32::from(pins.bits()) << 1 | count << 3),
                _ => Err(WordError::Hold {
                    cycles: cycles.into(),
                }),
            },
        }
    }

    /// What the program makes of any 32-bit word (bits 30–31 of a hold
    /// are ignored).
    pub fn decode(word: u32) -> Word {
        let pins = Pins::from_bits((word >> 1) as u8);
        if word & 1 == 1 {
            Word::Step {
                high: pins,
                low: Pins::from_bits((word >> 3) as u8),
                period_cycles: STEP_MIN_CYCLES + (word >> 5),
            }
        } else {
            Word::Hold {
                pins,
                cycles: HOLD_MIN_CYCLES + (word >> 3 & COUNT_MAX),
            }
        }
    }

    /// Cycles from this word's first pin write to the next word's.
    pub fn cycles(self) -> u32 {
        match self {
            Word::Step { period_cycles, .. } => period_cycles,
            Word::Hold { cycles, .. } => cycles,
        }
    }
}

/// The words of one step or hold, longer ones split: see [`step_words`]
/// and [`hold_words`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Words {
    first: Option<Word>,
    /// Pins held after the first word.
    hold_pins: Pins,
    /// Cycles still to hold after the first word (0, or at least
    /// [`HOLD_MIN_CYCLES`]).
    hold_cycles: u64,
}

/// The first part of `total` cycles for one word of at most `max`, leaving
/// 0 or at least [`HOLD_MIN_CYCLES`] for hold words.
fn split(total: u64, max: u32) -> (u32, u64) {
    if total <= u64::from(max) {
        (max.min(total as u32), 0)
    } else {
        let first = u64::from(max).min(total - u64::from(HOLD_MIN_CYCLES));
        (first as u32, total - first)
    }
}

/// A step: pins to `high` at its rising edge, to `low` [`PULSE_CYCLES`]
/// later, and the next word's first write `period_cycles` after the rising
/// edge (one step word, then hold words at `low` if the period is longer
/// than [`STEP_MAX_CYCLES`]).
pub fn step_words(high: Pins, low: Pins, period_cycles: u64) -> Result<Words, WordError> {
    if period_cycles < u64::from(STEP_MIN_CYCLES) {
        return Err(WordError::StepPeriod {
            cycles: period_cycles,
        });
    }
    let (first, rest) = split(period_cycles, STEP_MAX_CYCLES);
    Ok(Words {
        first: Some(Word::Step {
            high,
            low,
            period_cycles: first,
        }),
        hold_pins: low,
        hold_cycles: rest,
    })
}

/// Pins to `pins` now and held `cycles` until the next word's first write
/// (hold words of at most [`HOLD_MAX_CYCLES`] each).
pub fn hold_words(pins: Pins, cycles: u64) -> Result<Words, WordError> {
    if cycles < u64::from(HOLD_MIN_CYCLES) {
        return Err(WordError::Hold { cycles });
    }
    let (first, rest) = split(cycles, HOLD_MAX_CYCLES);
    Ok(Words {
        first: Some(Word::Hold {
            pins,
            cycles: first,
        }),
        hold_pins: pins,
        hold_cycles: rest,
    })
}

impl From<Word> for Words {
    /// One word alone.
    fn from(word: Word) -> Words {
        let pins = match word {
            Word::Step { low, .. } => low,
            Word::Hold { pins, .. } => pins,
        };
        Words {
            first: Some(word),
            hold_pins: pins,
            hold_cycles: 0,
        }
    }
}

impl Words {
    /// The one word these are, if they are one (every step and hold up to
    /// [`STEP_MAX_CYCLES`] or [`HOLD_MAX_CYCLES`], about a second): a
    /// feeder's fast path past the splitting.
    pub fn only(&self) -> Option<Word> {
        match self.first {
            Some(word) if self.hold_cycles == 0 => Some(word),
            _ => None,
        }
    }
}

impl Iterator for Words {
    type Item = Word;

    fn next(&mut self) -> Option<Word> {
        if let Some(word) = self.first.take() {
            return Some(word);
        }
        if self.hold_cycles == 0 {
            return None;
        }
        let (cycles, rest) = split(self.hold_cycles, HOLD_MAX_CYCLES);
        self.hold_cycles = rest;
        Some(Word::Hold {
            pins: self.hold_pins,
            cycles,
        })
    }
}

/// One pin write of the program: from `cycle` on, the pins are `pins`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PinWrite {
    /// Cycles since the state machine ran its first `pull`.
    pub cycle: u64,
    /// Both pins' levels from that cycle.
    pub pins: Pins,
}

/// The closed form: every pin write the program makes from `words`, in
/// order, when each word is in the FIFO by the time its `pull` runs.
pub fn pin_writes<I: IntoIterator<Item = u32>>(words: I) -> PinWrites<I::IntoIter> {
    PinWrites {
        words: words.into_iter(),
        next_cycle: u64::from(FIRST_WRITE_CYCLE),
        falling: None,
    }
}

/// The iterator of [`pin_writes`].
#[derive(Clone, Debug)]
pub struct PinWrites<I> {
    words: I,
    /// The next word's first write.
    next_cycle: u64,
    /// A step's falling edge, due before the next word.
    falling: Option<PinWrite>,
}

impl<I: Iterator<Item = u32>> Iterator for PinWrites<I> {
    type Item = PinWrite;

    fn next(&mut self) -> Option<PinWrite> {
        if let Some(falling) = self.falling.take() {
            return Some(falling);
        }
        let word = Word::decode(self.words.next()?);
        let cycle = self.next_cycle;
        self.next_cycle = cycle.saturating_add(u64::from(word.cycles()));
        match word {
            Word::Step { high, low, .. } => {
                self.falling = Some(PinWrite {
                    cycle: cycle.saturating_add(u64::from(PULSE_CYCLES)),
                    pins: low,
                });
                Some(PinWrite { cycle, pins: high })
            }
            Word::Hold { pins, .. } => Some(PinWrite { cycle, pins }),
        }
    }
}

#[cfg(test)]
mod tests;

//! One axis's edges, as the axis core decides them (CT order, CT in PIO
//! cycles), made into the words whose closed form gives them back.
//!
//! A word's length is the time to the next word's first write, so a word
//! is known only when the edge after it is: [`AxisWords`] keeps one word
//! open and closes it at the next edge, or at [`AxisWords::hold_until`]
//! when the board knows no edge comes before a CT (an idle axis must keep
//! its state machine fed, or the next edge comes late).

use crate::{
    hold_words, step_words, Pins, Words, HOLD_MIN_CYCLES, PULSE_CYCLES, STEP_MAX_CYCLES,
    STEP_MIN_CYCLES,
};

/// Which of the axis's pins carry step pulses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StepPins {
    /// Step and direction: pin 0 pulses, pin 1 is a level.
    Sd,
    /// Clockwise and counter-clockwise: either pin pulses.
    Cc,
}

impl StepPins {
    fn mask(self) -> u8 {
        match self {
            StepPins::Sd => 0b01,
            StepPins::Cc => 0b11,
        }
    }
}

/// An edge the program cannot make where it was asked for. The edge is not
/// made: the pins keep their levels, and the words stay those of the
/// edges before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EdgeError {
    /// Closer to the previous pin write (at `after_ct`) than the program's
    /// shortest word: a step within 631 cycles of the one before, or any
    /// other write within 6 cycles.
    TooClose {
        /// The edge's CT.
        ct: u64,
        /// The previous pin write's CT.
        after_ct: u64,
    },
    /// A step pulse that is not exactly [`PULSE_CYCLES`] long, or another
    /// edge during one.
    Pulse {
        /// The edge's CT.
        ct: u64,
        /// The pulse's rising edge.
        rising_ct: u64,
    },
    /// An edge before the previous pin write.
    Backwards {
        /// The edge's CT.
        ct: u64,
        /// The previous pin write's CT.
        after_ct: u64,
    },
}

/// The word being made: its first pin write's CT and what it writes.
#[derive(Clone, Copy, Debug)]
enum Open {
    Hold {
        at: u64,
        pins: Pins,
    },
    /// A step: `high` from `at`, then the pulse pins low from `at` +
    /// [`PULSE_CYCLES`].
    Step {
        at: u64,
        high: Pins,
    },
}

impl Open {
    fn at(self) -> u64 {
        match self {
            Open::Hold { at, .. } | Open::Step { at, .. } => at,
        }
    }
}

/// One axis's edges made into FIFO words.
///
/// A step's pulse is the program's: its pins go low [`PULSE_CYCLES`] after
/// its rising edge, and the pulse pin's falling edge is expected exactly
/// then (the axis core's pulse must be `PULSE_CYCLES` long). A falling edge
/// at another CT is refused; after the pulse's end the pin is low anyway.
#[derive(Clone, Debug)]
pub struct AxisWords {
    mask: u8,
    /// The pins as the edges so far leave them.
    pins: Pins,
    open: Open,
    /// The CT of the last edge taken (or of the last hold's end).
    last_ct: u64,
}

impl AxisWords {
    /// An axis with both pins low, whose state machine makes its first pin
    /// write at CT `first_write_ct` (its start plus
    /// [`FIRST_WRITE_CYCLE`](crate::FIRST_WRITE_CYCLE)): the first word
    /// holds both pins low from there.
    pub fn new(step_pins: StepPins, first_write_ct: u64) -> AxisWords {
        AxisWords {
            mask: step_pins.mask(),
            pins: Pins::LOW,
            open: Open::Hold {
                at: first_write_ct,
                pins: Pins::LOW,
            },
            last_ct: first_write_ct,
        }
    }

    /// The pins as the edges so far leave them.
    pub fn pins(&self) -> Pins {
        self.pins
    }

    /// Whether pin `output` (0 or 1; any other value is taken modulo 2)
    /// pulses: a step pin, whose pulses the program ends itself.
    pub fn pulses(&self, output: usize) -> bool {
        self.mask & (1 << (output & 1)) != 0
    }

    /// The CT of the open word's first write: the words returned so far
    /// make every edge before it.
    pub fn open_since(&self) -> u64 {
        self.open.at()
    }

    /// A step's pins once its pulse has ended.
    fn low(&self, high: Pins) -> Pins {
        Pins::from_bits(high.bits() & !self.mask)
    }

    /// Pin `output` (0 or 1; any other value is taken modulo 2) goes to
    /// `level` at CT `ct`. Returns the words of the word this edge closes,
    /// if it closes one. Always inlined: a board calls it for every edge,
    /// and again from its cold path for a late one (the Pico's PIO build);
    /// with more than one caller it went out of line, a call every edge.
    #[inline(always)]
    pub fn edge(
        &mut self,
        ct: u64,
        output: usize,
        level: bool,
    ) -> Result<Option<Words>, EdgeError> {
        let bit = 1u8 << (output & 1);
        let apply = |pins: Pins| {
            Pins::from_bits(if level {
                pins.bits() | bit
            } else {
                pins.bits() & !bit
            })
        };
        if ct < self.last_ct {
            return Err(EdgeError::Backwards {
                ct,
                after_ct: self.last_ct,
            });
        }
        let at = self.open.at();
        let mut after_ct = at;
        if let Open::Step { high, .. } = self.open {
            let pulse_end = at.saturating_add(u64::from(PULSE_CYCLES));
            if ct < pulse_end {
                return match apply(high) == high {
                    true => Ok(None),
                    false => Err(EdgeError::Pulse { ct, rising_ct: at }),
                };
            }
            let late_falling =
                self.pins == high && ct > pulse_end && !level && high.bits() & bit & self.mask != 0;
            // The program ends the pulse at its end, whatever comes after.
            self.pins = self.low(high);
            if late_falling {
                return Err(EdgeError::Pulse { ct, rising_ct: at });
            }
            after_ct = pulse_end;
        }
        let old = self.pins;
        let new = apply(old);
        if new == old {
            return Ok(None);
        }
        let rising = new.bits() & !old.bits() & self.mask != 0;
        let closed = if ct == at {
            // More pins at the CT of a hold's write: the same write.
            None
        } else {
            let words = match self.open {
                Open::Hold { pins, .. } => hold_words(pins, ct - at),
                Open::Step { high, .. } => step_words(high, self.low(high), ct - at),
            };
            Some(words.map_err(|_| EdgeError::TooClose { ct, after_ct })?)
        };
        self.open = if rising {
            Open::Step { at: ct, high: new }
        } else {
            Open::Hold { at: ct, pins: new }
        };
        self.pins = new;
        self.last_ct = ct;
        Ok(closed)
    }

    /// [`AxisWords::edge`] for the rising edge of a train's next step, in
    /// its commonest case, with no more work than that case needs: the
    /// open word is a step whose pulse has ended by `ct`, `output` is a
    /// step pin, and the step's period fits one word. Returns the encoded
    /// word the edge closes, the words left exactly as `edge(ct, output,
    /// true)` leaves them (which returns that word alone); `None`, with
    /// nothing changed, in any other case (then call `edge`).
    #[inline(always)]
    pub fn step_rise(&mut self, ct: u64, output: usize) -> Option<u32> {
        let Open::Step { at, high } = self.open else {
            return None;
        };
        let bit = 1u8 << (output & 1);
        let period = ct.checked_sub(at)?;
        if bit & self.mask == 0
            || period < u64::from(STEP_MIN_CYCLES)
            || period > u64::from(STEP_MAX_CYCLES)
            || ct < self.last_ct
        {
            return None;
        }
        // The pulse has ended (the period is longer than it): the pins are
        // the step's low ones, and this pin rises from them.
        let low = self.low(high);
        let new = Pins::from_bits(low.bits() | bit);
        self.open = Open::Step { at: ct, high: new };
        self.pins = new;
        self.last_ct = ct;
        Some(step_word_pins(high, low) | step_word_count(period))
    }

    /// [`AxisWords::step_rise`] for each CT of `rises` in turn while it
    /// gives a word, each word into `words` (at most `words.len()` of
    /// them): returns how many. The words and the state are what that
    /// many `step_rise` calls give and leave; the first CT it stops at
    /// (if any) is for [`AxisWords::step_rise`] or [`AxisWords::edge`].
    ///
    /// One loop over locals, for a board that encodes a run of steps at
    /// once (the Pico's PIO build): after the first step, each one's
    /// word is the same pins and its own period (the time since the step
    /// before), so a step is a subtraction, two comparisons and a store.
    /// Out of line, so that the loop has the registers to itself.
    #[inline(never)]
    pub fn step_rises(&mut self, rises: &[u64], output: usize, words: &mut [u32]) -> usize {
        let Open::Step { at, high } = self.open else {
            return 0;
        };
        let bit = 1u8 << (output & 1);
        let most = rises.len().min(words.len());
        if most == 0 || bit & self.mask == 0 || rises[0] < self.last_ct {
            return 0;
        }
        let low = self.low(high);
        let new = Pins::from_bits(low.bits() | bit);
        // The pins of each word: the first closes the open step's, the
        // rest the steps of this run (`new` up, `low` once it has ended).
        let mut pins = step_word_pins(high, low);
        let run_pins = step_word_pins(new, low);
        let mut previous = at;
        let mut count = 0;
        for (&ct, word) in rises[..most].iter().zip(&mut words[..most]) {
            let Some(period) = ct.checked_sub(previous) else {
                break;
            };
            if period < u64::from(STEP_MIN_CYCLES) || period > u64::from(STEP_MAX_CYCLES) {
                break;
            }
            *word = pins | step_word_count(period);
            pins = run_pins;
            previous = ct;
            count += 1;
        }
        if count > 0 {
            self.open = Open::Step {
                at: previous,
                high: new,
            };
            self.pins = new;
            self.last_ct = previous;
        }
        count
    }

    /// No edge of this axis comes before CT `ct`: closes the open word
    /// [`HOLD_MIN_CYCLES`] before it where the program allows (a hold, or
    /// a step whose pulse has ended), so that the state machine has words
    /// up to there. Returns the words it closed.
    pub fn hold_until(&mut self, ct: u64) -> Option<Words> {
        let end = ct.saturating_sub(u64::from(HOLD_MIN_CYCLES));
        let (words, pins) = match self.open {
            Open::Hold { at, pins } => (hold_words(pins, end.checked_sub(at)?).ok()?, pins),
            Open::Step { at, high } => {
                let low = self.low(high);
                (step_words(high, low, end.checked_sub(at)?).ok()?, low)
            }
        };
        self.open = Open::Hold { at: end, pins };
        self.pins = pins;
        self.last_ct = self.last_ct.max(end);
        Some(words)
    }
}

/// A step word's pins, raw (`step_rise`'s short form of `Word::encode`):
/// its kind bit, the pins high during the pulse and low after it.
#[inline(always)]
fn step_word_pins(high: Pins, low: Pins) -> u32 {
    1 | u32::from(high.bits()) << 1 | u32::from(low.bits()) << 3
}

/// A step word's count field, raw, for a period the program can make
/// (`STEP_MIN_CYCLES..=STEP_MAX_CYCLES`).
#[inline(always)]
fn step_word_count(period: u64) -> u32 {
    ((period - u64::from(STEP_MIN_CYCLES)) as u32) << 5
}

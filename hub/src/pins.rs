//! The pin bank and the two output variants.
//!
//! Like the P2, the hub has 64 pins; each is an output bit and an input bit
//! in an atomic word, so a pin reads and writes without a lock from any
//! thread. A cog drives its outputs in one of two ways, and that mapping is
//! all that differs between them:
//!
//! - `sd` ([`Outputs::StepDir`]): a pulse on the step pin per step, the
//!   direction pin's level giving the direction (high = negative steps, as
//!   the reference's direction bit);
//! - `cc` ([`Outputs::CwCcw`]): a pulse on the clockwise pin for a positive
//!   step, on the counter-clockwise pin for a negative one.
//!
//! A cog keeps the levels and rising-edge counts of its own output pins to
//! itself while it makes a batch of steps and publishes them to the bank at
//! the batch's end (an epoch, a real-time wake-up, the end of a move): one
//! shared word written on every edge by eight cogs would bounce its cache
//! line between the cores on every step. The edges themselves, with their
//! exact times, go to the trace as they happen.

use crate::sync::{AtomicU64, Ordering};

/// Pins in the bank (numbered 0 to 63).
pub const PIN_COUNT: u8 = 64;

pub use cogstep_motion::axis_core::{Edge, Outputs};

/// 64 output bits, 64 input bits and a rising-edge counter per pin.
#[derive(Debug)]
pub(crate) struct PinBank {
    outputs: AtomicU64,
    inputs: AtomicU64,
    rising: [AtomicU64; PIN_COUNT as usize],
}

impl Default for PinBank {
    fn default() -> Self {
        Self {
            outputs: AtomicU64::new(0),
            inputs: AtomicU64::new(0),
            rising: std::array::from_fn(|_| AtomicU64::new(0)),
        }
    }
}

impl PinBank {
    /// Publishes the levels of the output pins in `mask` (each pin has one
    /// driver, the cog that owns it, so other pins' bits are left alone).
    /// Relaxed: each pin is independent; order comes from the edge times,
    /// and whoever must see the levels synchronises with the cog through
    /// its own Release (the epoch's end, STM).
    pub fn publish_outputs(&self, mask: u64, levels: u64) {
        let high = mask & levels;
        let low = mask & !levels;
        if high != 0 {
            self.outputs.fetch_or(high, Ordering::Relaxed);
        }
        if low != 0 {
            self.outputs.fetch_and(!low, Ordering::Relaxed);
        }
    }

    /// Adds `count` rising edges to a pin's counter (Relaxed, as above).
    pub fn add_rising_edges(&self, pin: u8, count: u64) {
        self.rising[usize::from(pin)].fetch_add(count, Ordering::Relaxed);
    }

    pub fn output(&self, pin: u8) -> bool {
        self.outputs.load(Ordering::Relaxed) & (1 << pin) != 0
    }

    /// Sets an input pin and returns its previous level. Release: pairs
    /// with [`PinBank::input`]'s Acquire, so whatever the setter wrote
    /// before is seen by the cog that sees the level.
    pub fn set_input(&self, pin: u8, level: bool) -> bool {
        let bit = 1u64 << pin;
        let before = if level {
            self.inputs.fetch_or(bit, Ordering::Release)
        } else {
            self.inputs.fetch_and(!bit, Ordering::Release)
        };
        before & bit != 0
    }

    /// Every input level, bit per pin (Acquire, as [`PinBank::input`]).
    pub fn inputs_word(&self) -> u64 {
        self.inputs.load(Ordering::Acquire)
    }

    pub fn input(&self, pin: u8) -> bool {
        self.inputs.load(Ordering::Acquire) & (1 << pin) != 0
    }

    pub fn rising_edges(&self, pin: u8) -> u64 {
        self.rising[usize::from(pin)].load(Ordering::Relaxed)
    }
}

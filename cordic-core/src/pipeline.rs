//! The solver's timing, as the P2 has it: what a cog's CORDIC math costs in
//! clocks.
//!
//! Facts from the silicon documentation: one 54-stage pipelined solver in the
//! hub, shared by all cogs; a cog hands a command over only in its hub slot,
//! which comes round every 8 clocks (so it is 0–7 clocks away), and the result
//! is ready 55 clocks after the hand-off; GETQX/GETQY wait for it. A cog may
//! keep several commands in flight (issue some, then collect one and issue one
//! in turn), but each result must be read before the next one arrives, or it
//! is overwritten.
//!
//! [`Cordic`] is one cog's view of that solver: the cog's clock, its slot,
//! and its commands in flight, in a fixed-size queue (no allocation). The
//! cogs share nothing in this model because they need not: their slots are
//! distinct clocks modulo 8, so at most one command enters the pipeline per
//! clock, and eight cogs issuing flat out fill it at one command per clock.
//!
//! Model choices where the documentation is silent: cog `n`'s slot is every
//! clock `t` with `t % 8 == n`; a CORDIC instruction (QROTATE, QDIV, ...)
//! takes 2 clocks plus the wait for the slot, a GETQX/GETQY 2 clocks after the
//! result is there; results are read in issue order; a result counts as
//! overwritten if the next one has arrived by the clock its read happens.
//!
//! ```
//! use cordic_core::pipeline::{Command, Cordic};
//! // The S-curve's step: a QROTATE for the cosine, then a QDIV for the delay.
//! let mut cog = Cordic::new(3);
//! cog.issue(Command::Rotate { x: 25_000, y: 0, angle: 0x4000_0000 });
//! let x = cog.getqx().unwrap() as i32;
//! let velocity = (25_000 - x) as u32;
//! cog.issue(Command::Div { dividend: 200_000_000, divisor: velocity });
//! assert_eq!(cog.getqx(), Ok(8_000)); // ticks to the next step
//! // Two hand-offs, each result 55 clocks later; the slot waits add the rest.
//! assert_eq!(cog.now(), 124);
//! assert_eq!(cordic_core::pipeline::max_rate_hz(200_000_000, cog.now()), 1_612_903);
//! ```

use heapless::Deque;

use crate::{qdiv, qexp, qfrac, qlog, qmul, qrotate, qsqrt, qvector};

/// A count of system clock cycles.
pub type Clocks = u64;

/// Stages of the hub's CORDIC pipeline.
pub const PIPELINE_STAGES: u32 = 54;

/// Clocks from a command's hand-off (in its cog's hub slot) to its result.
pub const RESULT_LATENCY_CLOCKS: Clocks = 55;

/// Hub slots in a rotation: a cog's slot comes round every 8 clocks.
pub const HUB_SLOTS: u8 = 8;

/// Clocks of a cog instruction that does not wait (and of a GETQX/GETQY once
/// its result is there).
pub const INSTRUCTION_CLOCKS: Clocks = 2;

/// Commands one cog can usefully have in flight, and what this model holds:
/// results come back 55 clocks after hand-off and hand-offs are 8 clocks
/// apart, so at a hand-off at most 6 earlier commands are still under way and
/// at most one has arrived unspoilt. A cog juggling at full speed collects
/// the oldest of 8 and issues the next in every slot.
pub const MAX_IN_FLIGHT: usize = 8;

/// The first clock at or after `now` in which `cog` may hand a command over.
///
/// ```
/// use cordic_core::pipeline::next_slot;
/// assert_eq!(next_slot(3, 3), 3);
/// assert_eq!(next_slot(3, 4), 11); // just missed: 7 clocks away
/// ```
pub fn next_slot(cog: u8, now: Clocks) -> Clocks {
    let slot = Clocks::from(cog % HUB_SLOTS);
    let period = Clocks::from(HUB_SLOTS);
    now + (slot + period - now % period) % period
}

/// The highest rate (per second, rounded down) of something that costs
/// `clocks` each time at `clkfreq_hz`: for example the step rate a cog can
/// sustain when each step's math takes `clocks`. Zero clocks give `u64::MAX`.
///
/// ```
/// // 4,000 clocks per step at 200 MHz: 50,000 steps per second.
/// assert_eq!(cordic_core::pipeline::max_rate_hz(200_000_000, 4_000), 50_000);
/// ```
pub fn max_rate_hz(clkfreq_hz: u64, clocks: Clocks) -> u64 {
    clkfreq_hz.checked_div(clocks).unwrap_or(u64::MAX)
}

/// A solver command and its operands (the P2 instruction with its `SETQ`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    /// QROTATE: (`x`, `y`) rotated by `angle`; see [`qrotate`].
    Rotate {
        /// X, the instruction's D operand.
        x: i32,
        /// Y, given by `SETQ` (0 without it).
        y: i32,
        /// The binary angle (2^32 = 360°).
        angle: u32,
    },
    /// QVECTOR: (length, angle) of (`x`, `y`); see [`qvector`].
    Vector {
        /// X.
        x: i32,
        /// Y.
        y: i32,
    },
    /// QMUL: the 64-bit product; see [`qmul`].
    Mul {
        /// First factor.
        d: u32,
        /// Second factor.
        s: u32,
    },
    /// QDIV: 64-bit dividend (high half by `SETQ`) by 32-bit divisor; see
    /// [`qdiv`].
    Div {
        /// The dividend.
        dividend: u64,
        /// The divisor.
        divisor: u32,
    },
    /// QFRAC: {d:0} / s; see [`qfrac`].
    Frac {
        /// The numerator's high word.
        d: u32,
        /// The divisor.
        s: u32,
    },
    /// QSQRT: root of a 64-bit value; see [`qsqrt`].
    Sqrt {
        /// The radicand.
        value: u64,
    },
    /// QLOG: log2 as 5.27; see [`qlog`].
    Log {
        /// The operand.
        value: u32,
    },
    /// QEXP: 2^x of a 5.27 value; see [`qexp`].
    Exp {
        /// The 5.27 exponent.
        value: u32,
    },
}

impl Command {
    /// The result as the cog reads it: (GETQX, GETQY). Signed results
    /// (QROTATE's) are their two's-complement bits; commands with one result
    /// give 0 for Y in this model.
    ///
    /// ```
    /// use cordic_core::pipeline::Command;
    /// let (x, y) = Command::Rotate { x: 100, y: 100, angle: 0x4000_0000 }.result();
    /// assert_eq!((x as i32, y as i32), (-100, 100));
    /// assert_eq!(Command::Mul { d: 1 << 31, s: 4 }.result(), (0, 2));
    /// ```
    pub fn result(self) -> (u32, u32) {
        match self {
            Command::Rotate { x, y, angle } => {
                let (x, y) = qrotate(x, y, angle);
                (x as u32, y as u32)
            }
            Command::Vector { x, y } => qvector(x, y),
            Command::Mul { d, s } => qmul(d, s),
            Command::Div { dividend, divisor } => qdiv(dividend, divisor),
            Command::Frac { d, s } => qfrac(d, s),
            Command::Sqrt { value } => (qsqrt(value), 0),
            Command::Log { value } => (qlog(value), 0),
            Command::Exp { value } => (qexp(value), 0),
        }
    }
}

/// Why a GETQX/GETQY read no result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CollectError {
    /// No command was in flight (the chip returns at once and sets its QMT
    /// event).
    Empty,
    /// The oldest unread result was overwritten by the next one before it
    /// was read (on the chip the cog would silently read the later one); it
    /// is dropped, and the next read goes on with the next result.
    Overwritten,
}

impl core::fmt::Display for CollectError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CollectError::Empty => "no CORDIC command in flight",
            CollectError::Overwritten => "CORDIC result overwritten before it was read",
        })
    }
}

/// A command in flight: when its result arrives, and the result.
#[derive(Clone, Copy, Debug)]
struct InFlight {
    ready_at: Clocks,
    result: (u32, u32),
}

/// One cog's view of the hub CORDIC: the cog's clock, its hub slot, and its
/// commands in flight.
///
/// Each call advances [`now`](Cordic::now) by what the instruction costs on
/// the chip, so after a step's math `now()` says how many clocks it took.
/// Commands are collected in issue order; several may be in flight:
///
/// ```
/// use cordic_core::pipeline::{Command, Cordic};
/// let mut cog = Cordic::new(0);
/// // Issue four cosines back to back, then collect them: 8 clocks apart.
/// for k in 0..4 {
///     cog.issue(Command::Rotate { x: 1_000, y: 0, angle: k << 30 });
/// }
/// let cosines: Vec<i32> = (0..4).map(|_| cog.getqx().unwrap() as i32).collect();
/// assert_eq!(cosines, [1_000, 0, -1_000, 0]);
/// assert_eq!(cog.now(), 3 * 8 + 55 + 2); // the last hand-off, its result, one GETQX
/// ```
#[derive(Clone, Debug)]
pub struct Cordic {
    cog: u8,
    now: Clocks,
    in_flight: Deque<InFlight, MAX_IN_FLIGHT>,
    /// Results dropped unread to make room; the next reads report them.
    overwritten_unreported: u32,
    issued: u64,
}

impl Cordic {
    /// Cog `cog` (its slot is `cog % 8`), at clock 0 with nothing in flight.
    pub fn new(cog: u8) -> Self {
        Self::starting_at(cog, 0)
    }

    /// Cog `cog` at clock `now`, with nothing in flight.
    pub fn starting_at(cog: u8, now: Clocks) -> Self {
        Cordic {
            cog,
            now,
            in_flight: Deque::new(),
            overwritten_unreported: 0,
            issued: 0,
        }
    }

    /// The cog's clock: when its next instruction starts.
    pub fn now(&self) -> Clocks {
        self.now
    }

    /// The cog number this solver view belongs to.
    pub fn cog(&self) -> u8 {
        self.cog
    }

    /// Commands issued so far.
    pub fn issued(&self) -> u64 {
        self.issued
    }

    /// Commands issued and not yet collected (including any overwritten but
    /// not yet reported).
    pub fn in_flight(&self) -> usize {
        self.in_flight.len() + self.overwritten_unreported as usize
    }

    /// Spends `clocks` on other instructions.
    pub fn wait(&mut self, clocks: Clocks) {
        self.now += clocks;
    }

    /// Waits until clock `clock` (no effect if it has passed).
    pub fn wait_until(&mut self, clock: Clocks) {
        self.now = self.now.max(clock);
    }

    /// Issues `command` (QROTATE, QDIV, ...): waits for the cog's hub slot,
    /// hands the command over, and returns the clock its result will be
    /// ready. The instruction takes 2 clocks plus the wait (2..=9).
    pub fn issue(&mut self, command: Command) -> Clocks {
        let handoff = next_slot(self.cog, self.now);
        self.now = handoff + INSTRUCTION_CLOCKS;
        if self.in_flight.is_full() {
            self.drop_overwritten(handoff);
        }
        let ready_at = handoff + RESULT_LATENCY_CLOCKS;
        let entry = InFlight {
            ready_at,
            result: command.result(),
        };
        if self.in_flight.push_back(entry).is_err() {
            // Hand-offs are 8 clocks apart, so at most 6 earlier commands are
            // still under way at this one's hand-off, and of those that have
            // arrived only the newest is unspoilt: dropping the rest always
            // leaves room.
            unreachable!("CORDIC queue full after dropping overwritten results");
        }
        self.issued += 1;
        ready_at
    }

    /// GETQX: the X result of the oldest command not yet collected, waiting
    /// for it if needed. Collects that command (its Y is dropped).
    pub fn getqx(&mut self) -> Result<u32, CollectError> {
        self.collect(1).map(|(x, _)| x)
    }

    /// GETQY: the Y result of the oldest command not yet collected, waiting
    /// for it if needed. Collects that command (its X is dropped).
    pub fn getqy(&mut self) -> Result<u32, CollectError> {
        self.collect(1).map(|(_, y)| y)
    }

    /// GETQX then GETQY: both results of the oldest command not yet
    /// collected (4 clocks once it is there).
    pub fn getqxy(&mut self) -> Result<(u32, u32), CollectError> {
        self.collect(2)
    }

    /// Collects the oldest command with `reads` GETQ instructions.
    fn collect(&mut self, reads: Clocks) -> Result<(u32, u32), CollectError> {
        if self.overwritten_unreported > 0 {
            self.overwritten_unreported -= 1;
            self.now += INSTRUCTION_CLOCKS * reads;
            return Err(CollectError::Overwritten);
        }
        let Some(oldest) = self.in_flight.pop_front() else {
            self.now += INSTRUCTION_CLOCKS * reads;
            return Err(CollectError::Empty);
        };
        let first_read = self.now.max(oldest.ready_at);
        let last_read = first_read + INSTRUCTION_CLOCKS * (reads - 1);
        self.now = last_read + INSTRUCTION_CLOCKS;
        match self.in_flight.front() {
            Some(next) if next.ready_at <= last_read => Err(CollectError::Overwritten),
            _ => Ok(oldest.result),
        }
    }

    /// Drops the results that a later arrival overwrote by clock `clock`,
    /// keeping count so that reads still report them in order.
    fn drop_overwritten(&mut self, clock: Clocks) {
        while self
            .in_flight
            .get(1)
            .is_some_and(|next| next.ready_at <= clock)
        {
            self.in_flight.pop_front();
            self.overwritten_unreported += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use std::vec::Vec;

    #[test]
    fn slots_come_every_eight_clocks() {
        for cog in 0..HUB_SLOTS {
            for now in 0..64 {
                let slot = next_slot(cog, now);
                assert!(slot >= now && slot - now < 8, "cog {cog} now {now}");
                assert_eq!(slot % 8, Clocks::from(cog));
            }
        }
    }

    #[test]
    fn one_command_costs_the_slot_wait_and_the_latency() {
        for start in 0..16 {
            let mut cog = Cordic::starting_at(5, start);
            let wait = next_slot(5, start) - start;
            let ready = cog.issue(Command::Rotate {
                x: 100,
                y: 100,
                angle: 0x4000_0000,
            });
            assert_eq!(ready, start + wait + 55);
            assert_eq!(cog.now(), start + wait + 2);
            let (x, y) = cog.getqxy().unwrap();
            assert_eq!((x as i32, y as i32), (-100, 100));
            // GETQX at the result's clock, GETQY 2 clocks later.
            assert_eq!(cog.now(), ready + 4);
        }
    }

    #[test]
    fn a_dependent_rotate_then_divide_costs_two_latencies() {
        for start in 0..8 {
            let mut cog = Cordic::starting_at(2, start);
            let first_wait = next_slot(2, start) - start;
            cog.issue(Command::Rotate {
                x: 25_000,
                y: 0,
                angle: 0x2AAA_AAAB,
            });
            let x = cog.getqx().unwrap() as i32;
            cog.issue(Command::Div {
                dividend: 200_000_000,
                divisor: (25_000 - x) as u32,
            });
            assert_eq!(cog.getqx(), Ok(16_000)); // 200 MHz / 12,500 steps/s
            let clocks = cog.now() - start;
            // The GETQX ends 57 clocks after a hand-off, one clock past the
            // slot, so the QDIV waits 7: 2 × (slot wait + 55) plus 11.
            assert_eq!(clocks, first_wait + 57 + 7 + 57);
            let (low, high) = (2 * 55, 2 * (7 + 55) + 4);
            assert!((low..=high).contains(&clocks), "{clocks}");
        }
    }

    #[test]
    fn pipelined_commands_cost_eight_clocks_each_plus_one_latency() {
        // Issue N back to back, then collect N.
        for n in 1..=7u64 {
            let mut cog = Cordic::new(0);
            for k in 0..n {
                cog.issue(Command::Mul { d: k as u32, s: 3 });
            }
            for k in 0..n {
                assert_eq!(cog.getqx(), Ok(3 * k as u32));
            }
            // Last hand-off at 8(n − 1), its result 55 later, then one GETQX.
            assert_eq!(cog.now(), 8 * (n - 1) + 55 + 2);
        }
        // Steady state, as P2 code juggles: with 8 in flight the oldest
        // result (handed over 56 clocks ago) is there when the cog comes to
        // collect it, so it can collect one and issue one in every slot.
        let total = 1_000u64;
        let mut cog = Cordic::new(1);
        let mut collected = 0u32;
        for k in 0..total {
            if cog.in_flight() == MAX_IN_FLIGHT {
                assert_eq!(cog.getqx(), Ok(collected));
                collected += 1;
            }
            cog.issue(Command::Div {
                dividend: 7 * k,
                divisor: 7,
            });
        }
        while u64::from(collected) < total {
            assert_eq!(cog.getqx(), Ok(collected));
            collected += 1;
        }
        assert!(cog.now() <= 8 * total + 55 + 8, "{}", cog.now());
    }

    #[test]
    fn eight_cogs_fill_the_pipeline_one_command_per_clock() {
        let per_cog = 500u64;
        let mut handoffs = Vec::new();
        for cog_number in 0..HUB_SLOTS {
            let mut cog = Cordic::new(cog_number);
            for k in 0..per_cog {
                if cog.in_flight() == MAX_IN_FLIGHT {
                    cog.getqx().unwrap();
                }
                let ready = cog.issue(Command::Rotate {
                    x: 1,
                    y: 0,
                    angle: k as u32,
                });
                handoffs.push(ready - RESULT_LATENCY_CLOCKS);
            }
        }
        handoffs.sort_unstable();
        let distinct = handoffs.windows(2).all(|pair| pair[0] < pair[1]);
        assert!(distinct, "two commands entered the pipeline in one clock");
        let span = handoffs.last().unwrap() - handoffs.first().unwrap() + 1;
        let per_clock = handoffs.len() as f64 / span as f64;
        assert!(per_clock > 0.99, "{per_clock} commands per clock");
    }

    #[test]
    fn a_late_read_finds_the_result_overwritten() {
        let mut cog = Cordic::new(4);
        cog.issue(Command::Log { value: 256 });
        cog.issue(Command::Exp { value: 8 << 27 });
        cog.wait(200);
        assert_eq!(cog.getqx(), Err(CollectError::Overwritten));
        assert_eq!(cog.getqx(), Ok(256));
        assert_eq!(cog.getqx(), Err(CollectError::Empty));
        // Reading X then Y 2 clocks later: Y is spoilt if the next result
        // arrives in between.
        let mut cog = Cordic::new(0);
        cog.issue(Command::Vector { x: 3, y: 4 });
        cog.issue(Command::Sqrt { value: 81 });
        cog.wait_until(55 + 8);
        assert_eq!(cog.getqxy(), Err(CollectError::Overwritten));
        assert_eq!(cog.getqxy(), Ok((9, 0)));
    }

    #[test]
    fn results_left_unread_are_reported_in_order() {
        let mut cog = Cordic::new(6);
        for k in 0..20 {
            cog.issue(Command::Frac { d: k, s: 1 << 31 });
        }
        assert_eq!(cog.in_flight(), 20);
        cog.wait(1_000);
        for _ in 0..19 {
            assert_eq!(cog.getqx(), Err(CollectError::Overwritten));
        }
        assert_eq!(cog.getqx(), Ok(38)); // 19/2^31 as 0.32
        assert_eq!(cog.in_flight(), 0);
        assert_eq!(cog.issued(), 20);
    }

    #[test]
    fn empty_reads_cost_one_instruction() {
        let mut cog = Cordic::starting_at(1, 10);
        assert_eq!(cog.getqy(), Err(CollectError::Empty));
        assert_eq!(cog.now(), 12);
        assert_eq!(max_rate_hz(200_000_000, 0), u64::MAX);
    }
}

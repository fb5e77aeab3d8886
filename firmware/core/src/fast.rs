//! The step interrupt's fast path: edges lent to the board's timer
//! interrupt.
//!
//! At speed an axis's steps come from a
//! [`StepTrain`](driver::axis_core::StepTrain): each step's CT is one
//! 32.32 addition from the last and needs no decision. When that axis is
//! the only one that needs the step interrupt, the general interrupt
//! ([`crate::Firmware::step_interrupt_lending`]) lends its train to a
//! [`FastTrain`] the board keeps, and from then on every timer interrupt
//! is one call of [`FastTrain::on_timer`]: drive the edge due, say how many
//! ticks after it the next one comes. No critical section, no 64-bit CT
//! read, no loop over axes: the board arms its timer from the CT of the
//! edge just served, so the schedule never drifts.
//!
//! ```text
//!  rising edge (makes the step) ──pulse──► falling edge ──gap──► rising edge …
//! ```
//!
//! On a ramp the general interrupt decides each step at its rising edge;
//! the step's falling edge, when nothing else is due before the next
//! step, is lent the same way (one edge, then the general interrupt again).
//!
//! What is lent goes back to its axis exactly as if the axis had driven
//! the edges itself (a train's steps counted with
//! [`StepTrain::make_steps`](driver::axis_core::StepTrain::make_steps)):
//! after the fast path's last edge the timer waits for the next event and
//! [`FastTrain::on_timer`] answers [`FastEvent::Slow`] there, so the board
//! runs the general interrupt, which takes everything back first (the
//! train's last step, and any step at or after a jog's give-back, are the
//! axis's to make); and whatever reads or changes an axis from the main
//! loop takes it back before it looks (the board's
//! [`crate::Hardware::with_fast_train`]).

use driver::axis_core::Edge;

use crate::axis::{EdgeCounts, Train, NEVER};

/// What [`FastTrain::on_timer`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FastEvent {
    /// Drove a rising edge and made a slew step; the falling edge comes
    /// `interval` ticks after the edge served.
    Rise {
        /// Ticks from this edge to the next event.
        interval: u32,
    },
    /// Drove a falling edge; the next rising edge comes `interval` ticks
    /// after it.
    Fall {
        /// Ticks from this edge to the next event.
        interval: u32,
    },
    /// Nothing (more) lent: run the general step interrupt (it takes back
    /// what was lent).
    Slow,
}

/// A slew train lent to the timer interrupt (see the module docs). A board
/// keeps one where its step interrupt reaches it without a critical
/// section, and lends it to the main loop only with interrupts masked.
///
/// The interrupt's state is 32-bit: the edges' CTs are kept modulo 2^32
/// (a board's timer needs only the ticks from one edge to the next), and
/// the whole train is rebuilt from the count of steps made when it goes
/// back.
#[derive(Clone, Debug)]
#[repr(C)]
pub struct FastTrain {
    /// Edges still to drive: even, a rising edge is next; odd, a falling
    /// edge; 0, none (the timer then waits for the general interrupt).
    edges_left: u32,
    /// CT of the edge the timer waits for, modulo 2^32, bit-inverted (a
    /// down-counter's view: how late an interrupt runs is then one
    /// subtraction from a down-counting clock, see
    /// [`FastTrain::armed_ct_inverted`]).
    armed_ct_inverted: u32,
    /// The board's name for the pin ([`crate::Hardware::fast_pin`]).
    pin: u32,
    pulse_ticks: u32,
    /// Ticks from the next falling edge to the rising edge after it.
    gap: u32,
    /// The 32.32 delay arithmetic, as the train's `make_step` does it:
    /// a step's gap is ⌊delay_q32 + carry⌋ + period extra − pulse.
    delay_q32: u64,
    carry: u32,
    extra_less_pulse: u32,
    /// Steps it was lent with.
    rises_lent: u32,
    axis: usize,
    /// What was lent.
    lent: Option<Lent>,
}

/// What a [`FastTrain`] holds for its axis.
#[derive(Clone, Copy, Debug)]
enum Lent {
    /// A slew train, as lent (its steps counted from there).
    Train(Train),
    /// A step's falling edge alone.
    Fall(Edge),
}

/// What goes back to the axis.
pub(crate) enum Returned {
    /// The train, as if the axis had made the steps itself, and the edges
    /// the fast path drove.
    Train(Train, EdgeCounts),
    /// The falling edge, and whether it was driven.
    Fall(Edge, bool),
}

impl Default for FastTrain {
    fn default() -> Self {
        Self::new()
    }
}

impl FastTrain {
    /// Nothing lent.
    pub const fn new() -> Self {
        FastTrain {
            edges_left: 0,
            armed_ct_inverted: !0,
            pin: 0,
            pulse_ticks: 0,
            gap: 0,
            delay_q32: 0,
            carry: 0,
            extra_less_pulse: 0,
            rises_lent: 0,
            axis: 0,
            lent: None,
        }
    }

    /// CT of the edge the timer waits for, modulo 2^32: the board reads it
    /// before [`FastTrain::on_timer`] to arm its timer from the edge served.
    #[inline(always)]
    pub fn armed_ct(&self) -> u32 {
        !self.armed_ct_inverted
    }

    /// `!armed_ct()`: with a clock that counts down (CT = `!count` modulo
    /// its width, as SysTick), `inverted − count` is how many ticks after
    /// the edge the interrupt runs.
    #[inline(always)]
    pub fn armed_ct_inverted(&self) -> u32 {
        self.armed_ct_inverted
    }

    /// Whether a train is lent.
    pub fn is_lent(&self) -> bool {
        self.lent.is_some()
    }

    /// Steps the fast path may still make.
    fn rises_left(&self) -> u32 {
        self.edges_left / 2
    }

    /// Whether the edge the timer waits for is a falling one.
    fn falling_next(&self) -> bool {
        self.edges_left % 2 == 1
    }

    /// The timer interrupt: drives the edge due through `drive(pin,
    /// level)` (`pin` as [`crate::Hardware::fast_pin`] named it) and tells
    /// what comes next.
    #[inline(always)]
    pub fn on_timer(&mut self, drive: impl FnOnce(u32, bool)) -> FastEvent {
        let edges = self.edges_left;
        if edges == 0 {
            return FastEvent::Slow;
        }
        self.edges_left = edges - 1;
        if edges.is_multiple_of(2) {
            let armed = self.armed_ct_inverted.wrapping_sub(self.pulse_ticks);
            drive(self.pin, true);
            self.armed_ct_inverted = armed;
            // The next step's delay, as StepTrain::make_step makes it.
            let total = self.delay_q32 + u64::from(self.carry);
            self.carry = total as u32;
            self.gap = ((total >> 32) as u32).wrapping_add(self.extra_less_pulse);
            FastEvent::Rise {
                interval: self.pulse_ticks,
            }
        } else {
            let gap = self.gap;
            let armed = self.armed_ct_inverted.wrapping_sub(gap);
            drive(self.pin, false);
            self.armed_ct_inverted = armed;
            FastEvent::Fall { interval: gap }
        }
    }

    /// Takes a copy of axis `axis`'s `train` (its pin named `pin` by the
    /// board) if the fast path can run it: it has a step to make before
    /// its give-back and its periods hold the pulse. Returns the CT of the
    /// first edge it serves, for the board to arm its timer with (the
    /// axis then hands its train over, [`crate::axis::AxisRunner`]'s
    /// `lend_train`).
    pub(crate) fn lend(&mut self, axis: usize, pin: u32, train: &Train) -> Option<u64> {
        debug_assert!(!self.is_lent());
        let steps = &train.steps;
        let delay_floor = steps.delay_q32() >> 32;
        let pulse = u64::from(steps.pulse_ticks);
        let extra = u64::from(steps.period_extra());
        // Every period (delay + extra, from the floor to one tick more)
        // holds the pulse and fits 31 bits.
        let plain_periods = delay_floor + extra >= pulse && delay_floor + extra < 1 << 31;
        let pending_fall = train.fall_ct != NEVER;
        let first_gap = steps.rise_ct.checked_sub(train.fall_ct);
        let first_gap_fits = !pending_fall || first_gap.is_some_and(|gap| gap < 1 << 31);
        // Slew steps only: the timer interrupt makes them in closed form.
        if steps.is_ramp() || !steps.has_step() || !plain_periods || !first_gap_fits {
            return None;
        }
        // Rises surely before the give-back (each period at most the
        // floor + 1 + extra): the rest are the axis's to make.
        let period_max = delay_floor + 1 + extra;
        let before_give_back = match train.give_back_ct.checked_sub(steps.rise_ct) {
            Some(ticks) if ticks > 0 => (ticks - 1) / period_max + 1,
            _ => 0,
        };
        let rises = u64::from(steps.steps_left)
            .min(before_give_back)
            .min(1 << 30) as u32;
        if rises == 0 {
            return None;
        }
        let first_ct = if pending_fall {
            train.fall_ct
        } else {
            steps.rise_ct
        };
        *self = FastTrain {
            edges_left: 2 * rises + u32::from(pending_fall),
            armed_ct_inverted: !(first_ct as u32),
            pin,
            pulse_ticks: steps.pulse_ticks,
            gap: first_gap.unwrap_or(0) as u32,
            delay_q32: steps.delay_q32(),
            carry: steps.carry(),
            extra_less_pulse: steps.period_extra().wrapping_sub(steps.pulse_ticks),
            rises_lent: rises,
            axis,
            lent: Some(Lent::Train(*train)),
        };
        Some(first_ct)
    }

    /// Takes axis `axis`'s pending falling edge `fall` (its pin named
    /// `pin` by the board) if the axis's next event comes at `next_ct`,
    /// after it and less than 2^31 ticks later; returns the CT of the
    /// edge, for the board to arm its timer with.
    pub(crate) fn lend_fall(
        &mut self,
        axis: usize,
        pin: u32,
        fall: Edge,
        next_ct: u64,
    ) -> Option<u64> {
        debug_assert!(!self.is_lent() && !fall.level);
        let gap = next_ct
            .checked_sub(fall.ct)
            .filter(|&gap| gap > 0 && gap < 1 << 31)?;
        // Field by field: the train fields stay unused (and a whole new
        // value would copy a train's worth of memory once a ramp step).
        self.edges_left = 1;
        self.armed_ct_inverted = !(fall.ct as u32);
        self.pin = pin;
        self.gap = gap as u32;
        self.axis = axis;
        self.lent = Some(Lent::Fall(fall));
        Some(fall.ct)
    }

    /// The axis whose train is lent.
    pub(crate) fn lent_axis(&self) -> Option<usize> {
        self.is_lent().then_some(self.axis)
    }

    /// A falling edge lent alone, and whether it was driven; nothing is
    /// lent afterwards. `None` (and nothing changes) when no falling edge
    /// alone is lent. (The cheap case of [`FastTrain::take_back`], once a
    /// ramp step.)
    #[inline]
    pub(crate) fn take_back_fall(&mut self) -> Option<(Edge, bool)> {
        let Some(Lent::Fall(edge)) = &self.lent else {
            return None;
        };
        let returned = (*edge, !self.falling_next());
        self.lent = None;
        self.edges_left = 0;
        Some(returned)
    }

    /// What was lent, as the axis would hold it had it driven the fast
    /// path's edges itself; nothing is lent afterwards.
    pub(crate) fn take_back(&mut self) -> Option<Returned> {
        let mut edges = EdgeCounts::default();
        self.add_edges(&mut edges);
        let falling_next = self.falling_next();
        let returned = match self.lent.take()? {
            Lent::Train(mut train) => {
                train.steps.make_steps(self.rises_lent - self.rises_left());
                train.fall_ct = if falling_next {
                    // Less than 2^31 ticks before the next rising edge.
                    let before_rise = (train.steps.rise_ct as u32).wrapping_sub(self.armed_ct());
                    train.steps.rise_ct - u64::from(before_rise)
                } else {
                    debug_assert_eq!(train.steps.rise_ct as u32, self.armed_ct());
                    NEVER
                };
                Returned::Train(train, edges)
            }
            Lent::Fall(edge) => Returned::Fall(edge, !falling_next),
        };
        *self = FastTrain::new();
        Some(returned)
    }

    /// Adds the edges the fast path drove to `counts`.
    pub(crate) fn add_edges(&self, counts: &mut EdgeCounts) {
        match &self.lent {
            None => {}
            Some(Lent::Train(train)) => {
                let made = u64::from(self.rises_lent - self.rises_left());
                let index = train.output.index();
                counts.rising[index] += made;
                // A falling edge per step made but the one still to drive,
                // and the one the train was lent with.
                let pending_then = u64::from(train.fall_ct != NEVER);
                let pending_now = u64::from(self.falling_next());
                counts.falling[index] += made + pending_then - pending_now;
            }
            Some(Lent::Fall(edge)) if !self.falling_next() => {
                counts.falling[usize::from(edge.pin != 0)] += 1;
            }
            Some(Lent::Fall(_)) => {}
        }
    }
}

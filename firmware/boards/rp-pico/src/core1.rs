//! Core 1: the axes' ramp runs computed ahead, nothing else.
//!
//! Core 0 runs the firmware (the host's session, the axes' cores, the
//! edges). When an axis's core arms a ramp run, it posts the state it will
//! be in once that run is used up ([`cogstep_handoff::AheadSlot`], one
//! per axis) and rings core 1's doorbell: a word in the SIO FIFO and an
//! event (SEV). Core 1 computes the next run from that state
//! (`SCurve::arm_run_ahead_from`: the ramp's cosines and divisions,
//! most of a ramp step's cost) while core 0 yields the armed one. Core 0
//! takes the answer only when the axis is in the predicted state, so the
//! steps are bit for bit its own; when the answer is late or of no use
//! (a command re-planned the move), core 0 computes the run itself, as it
//! does with core 1 off (`COGSTEP_CORE1` = 0).
//!
//! With no request to serve, core 1 guesses: from its last answer for an
//! axis it computes the run after it, from the request the axis will post
//! once it has taken that answer and nothing re-planned ([`Guess`]). When
//! that request comes and is the guess's to the last bit, the answer is
//! the guess, copied: a run core 1 computed while it would have slept.
//! A guess that does not come true is not used (core 1 computes the run
//! as asked), so the steps are the axis's own either way.
//!
//! Core 1 touches nothing but the slots, its guesses, its own SIO divider
//! (the ramp's divisions; each core has one) and its FIFO: no peripheral,
//! no interrupt, no critical section.

use core::cell::UnsafeCell;
use core::sync::atomic::{AtomicU32, Ordering};

use cogstep_firmware::{Firmware, AXES_MAX};
use cogstep_handoff::AheadSlot;
use driver::axis_core::RAMP_TRAIN_STEPS;
use driver::profile::scurve::SCurve;
use rp2040_hal as hal;
use rp2040_hal::multicore::{Multicore, Stack};
use rp2040_hal::pac;

use crate::Pico;

/// Each axis's request and answer.
static RUNS_AHEAD: [AheadSlot<SCurve>; AXES_MAX] = [const { AheadSlot::new() }; AXES_MAX];

/// Core 1's guesses, an axis each: its alone.
static GUESSES: Core1Only<[Guess; AXES_MAX]> =
    Core1Only(UnsafeCell::new([const { Guess::new() }; AXES_MAX]));

/// State only core 1 touches.
struct Core1Only<T>(UnsafeCell<T>);

// SAFETY: only `serve`, core 1's one loop, reaches the cell.
unsafe impl<T> Sync for Core1Only<T> {}

/// An axis's next request guessed from core 1's last answer for it, and
/// the answer to that request once computed.
struct Guess {
    /// The request the axis will post once it has taken the last answer:
    /// that answer with its run used up (`SCurve::run_ahead_from`).
    from: Option<SCurve>,
    /// The answer to `from`, when `ready`.
    ahead: Option<SCurve>,
    /// `from` is a guess (the last answer armed a run).
    due: bool,
    /// `ahead` is `from`'s answer, of use.
    ready: bool,
}

impl Guess {
    const fn new() -> Guess {
        Guess {
            from: None,
            ahead: None,
            due: false,
            ready: false,
        }
    }

    /// Serves the request `from` into `ahead` (`AheadSlot::serve`'s work):
    /// the guess's answer when the request is the guess, bit for bit
    /// (the same code on the same state gives the same run), else
    /// computed now. Then guesses the request after this answer.
    fn answer(&mut self, from: &SCurve, ahead: &mut Option<SCurve>) -> bool {
        let useful = match (&self.ahead, self.ready && self.from.as_ref() == Some(from)) {
            (Some(guessed), true) => {
                match ahead {
                    Some(ahead) => ahead.clone_from(guessed),
                    None => *ahead = Some(guessed.clone()),
                }
                true
            }
            _ => SCurve::arm_run_ahead_from(from, ahead),
        };
        self.ready = false;
        self.due = useful
            && ahead
                .as_ref()
                .is_some_and(|answer| answer.run_ahead_from(&mut self.from));
        useful
    }

    /// Computes the guessed request's answer, if one is due. Returns
    /// whether it worked.
    fn guess(&mut self) -> bool {
        if !self.due {
            return false;
        }
        self.due = false;
        self.ready = self
            .from
            .as_ref()
            .is_some_and(|from| SCurve::arm_run_ahead_from(from, &mut self.ahead));
        true
    }
}

/// Core 1's stack (words): a run's arithmetic and a curve copied on the
/// first request of each axis.
static STACK: Stack<2048> = Stack::new();

/// Core 1's cycles for a ramp step, Smooth and P2Exact (`firmware/bench-pico`:
/// 977 and 1,289 on the timer build), rounded up.
const STEP_CYCLES: [u64; 2] = [1_000, 1_300];

/// System clock cycles per CT tick.
const CYCLES_PER_TICK: u64 = (crate::SYS_CLOCK_HZ / crate::CLKFREQ_HZ) as u64;

/// Core 1's ticks for a full ramp run in the axes' arithmetic (set by
/// [`start`]).
static RUN_TICKS: AtomicU32 = AtomicU32::new(0);

/// Starts core 1 and hands each axis its slot. Returns whether core 1
/// runs (if it does not answer, core 0 computes every run, as without it).
pub fn start(
    firmware: &'static Firmware<Pico>,
    psm: &mut pac::PSM,
    ppb: &mut pac::PPB,
    fifo: &mut hal::sio::SioFifo,
    p2exact: bool,
) -> bool {
    let Some(stack) = STACK.take() else {
        return false;
    };
    let mut multicore = Multicore::new(psm, ppb, fifo);
    if multicore.cores()[1].spawn(stack, serve).is_err() {
        return false;
    }
    // A full run: as many steps as a ramp train carries, the motion
    // crate's run on this build (64 on the PIO build, 32 on the timer's).
    let run_cycles = RAMP_TRAIN_STEPS as u64 * STEP_CYCLES[usize::from(p2exact)];
    RUN_TICKS.store(
        run_cycles.div_ceil(CYCLES_PER_TICK) as u32,
        Ordering::Relaxed,
    );
    for (axis, slot) in firmware.axes().iter().zip(&RUNS_AHEAD) {
        axis.set_run_ahead(slot, answer_ticks);
    }
    true
}

/// The ticks core 1 would take to answer a request posted now: the
/// requests it holds (served one after the other) and this one, a full
/// run each. An axis asks only when its armed run lasts that long. When
/// four axes ramp faster than core 1 can follow, about a third of its
/// answers came after their runs were used up and were thrown away (core
/// 0 had computed those runs itself), while the requests behind them
/// waited: now core 0 computes those runs without asking, and core 1's
/// time goes to runs it can deliver.
fn answer_ticks() -> u64 {
    let held = RUNS_AHEAD.iter().filter(|slot| !slot.idle()).count() as u32;
    u64::from((held + 1) * RUN_TICKS.load(Ordering::Relaxed))
}

/// The requests posted so far, all axes (wrapping).
fn posts() -> u32 {
    RUNS_AHEAD
        .iter()
        .fold(0u32, |sum, slot| sum.wrapping_add(slot.posts()))
}

/// The request count at core 0's last ring.
static RUNG: AtomicU32 = AtomicU32::new(0);

/// Core 0's doorbell: rings core 1 when a request was posted since the
/// last ring.
#[inline]
pub fn ring() {
    let posts = posts();
    if posts == RUNG.load(Ordering::Relaxed) {
        return;
    }
    RUNG.store(posts, Ordering::Relaxed);
    // SAFETY: core 0's side of the FIFO; core 0 writes nothing else to it
    // once core 1 runs.
    let sio = unsafe { &*pac::SIO::ptr() };
    // A full FIFO holds doorbells core 1 has yet to read: it will look.
    if sio.fifo_st().read().rdy().bit_is_set() {
        sio.fifo_wr().write(|w| unsafe { w.bits(posts) });
    }
    cortex_m::asm::sev();
}

/// Core 1, for ever: the doorbells read, every posted request served;
/// with none, one guess computed (the axes in turn); with none due,
/// asleep until the next doorbell (its SEV after the last look makes the
/// WFE fall through).
fn serve() {
    // SAFETY: core 1's side of the FIFO, its alone.
    let sio = unsafe { &*pac::SIO::ptr() };
    // SAFETY: core 1's alone (`Core1Only`), and this is core 1's loop.
    let guesses = unsafe { &mut *GUESSES.0.get() };
    let mut turn = 0;
    loop {
        while sio.fifo_st().read().vld().bit_is_set() {
            let _ = sio.fifo_rd().read().bits();
        }
        let mut served = false;
        for (slot, guess) in RUNS_AHEAD.iter().zip(guesses.iter_mut()) {
            served |= slot.serve(|from, ahead| guess.answer(from, ahead));
        }
        if served {
            continue;
        }
        let guessed = (0..AXES_MAX).any(|_| {
            turn = (turn + 1) % AXES_MAX;
            guesses[turn].guess()
        });
        if !guessed {
            cortex_m::asm::wfe();
        }
    }
}

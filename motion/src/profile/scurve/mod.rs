//! The P2 cosine S-curve: planning, per-step timing and live re-planning.
//!
//! # Planning (the reference `move(sp, st)`)
//!
//! ```text
//! asteps := sp / accel_div + 2          accel_div defaults to 10
//! asteps := min(asteps, st / 2)         accel and decel each at most half the move
//! ss     := st − 2·asteps               slew steps ("steps at speed")
//! ```
//!
//! Short moves: the reference lowers the speed to `10·(asteps − 2)` only when
//! `ss == 0`. Its flaws, which cogstep does not copy (each is shown beside
//! cogstep's behaviour by a model of the reference in this module's tests):
//! - an odd short move (`ss == 1`: 3, 5, 7, … steps when capped) keeps its
//!   full speed on a ramp cut short;
//! - a 2-step move gets a speed of −10 and a 4-step move a speed of 0
//!   (`asteps` = 1 or 2), so its delays are nonsense (a 2-step move's
//!   `halfsp` is 2^31 − 5);
//! - a 1-step move has `asteps = 0`, hence `stom = 0`: its delay divides by
//!   zero;
//! - a stop pin low during a 1-step move runs `steps − xsteps` = 0 − 1: the
//!   step count wraps to 4,294,967,295.
//!
//! cogstep's rule ([`plan`]): whenever the move length capped `asteps`, the
//! top speed is
//!
//! ```text
//! sp' := min(sp, max(accel_div·(asteps − 2), accel_div))
//! ```
//!
//! for odd and even moves alike, so the acceleration of a short move is that
//! of a full move at `sp'`, and every move of one step or more runs at a
//! positive speed no faster than requested. A one-step move is a single step
//! at `sp'` (at most `accel_div` steps/s).
//!
//! The reference's `if ss == 0` also fires on a move that was never capped,
//! when `|st| = 2·(sp/10 + 2)` exactly: `sp` is then rounded down to a
//! multiple of 10 (204 steps at 1,009 steps/s run at 1,000). That is the
//! reference's rule, not a flaw: [`Arithmetic::P2Exact`] follows it (the
//! same formula as above gives it), [`Arithmetic::Smooth`] keeps `sp`.
//!
//! # Per step
//!
//! The ramp steps climb the raised cosine `v(θ) = sp·(1 − cos θ)/2` from the
//! offset angle (default 40°) towards 180°, the slew steps run at 180°, and the
//! deceleration steps descend the mirror half towards 360° − offset. The delay
//! to the next step is `clkfreq / v(θ)` ticks. P2Exact's cosine and division
//! are [`cordic_core`]'s QROTATE and QDIV, bit for bit; Smooth's cosine is an
//! integer second-order recurrence and its division one IEEE `f64` division
//! (exact-rounded, so the same bits on every target; see below).
//!
//! Cost: a slew step reuses the cached slew delay and only carries the
//! rounding (a few instructions). Ramp steps are computed ahead while nothing
//! re-plans: after a ramp step, the steps that follow on the same side of the
//! ramp (up to 64, a block of cosines) are computed in one tight loop (the
//! divisions overlap, the carried rounding is an addition and a mask a step)
//! and each is then yielded by three loads. Any re-planning call first
//! settles the run (the state becomes what the general path would have after
//! the steps yielded) and drops the rest, so the steps are bit for bit the
//! general path's (a property test checks it). The cosines come a block of
//! 64 at a time: P2Exact's from [`cordic_core::cos_batch`] (bit for bit one
//! QROTATE each, as the P2 keeps its CORDIC pipeline full), Smooth's from a
//! second-order recurrence anchored at the block's first key (one
//! multiplication a key, within 0.51 LSB of the exact angle's cosine; see
//! `smooth_cosines`' error bound, in `cosines.rs`).
//!
//! Internally a move is a walk over *ramp positions* `k = 0..=asteps`
//! (0 = the offset angle, `asteps` = 180°, the top speed). Each step moves at
//! most one position up or down, which is what bounds the acceleration, and
//! the walk always keeps enough steps in hand to come back down to position 0:
//!
//! ```text
//! k_next = min(k + 1, asteps, steps_left − 1)
//! ```
//!
//! A fresh move walks 0, 1, … asteps−1 (accelerating), asteps × ss (slew),
//! asteps−1, … 0 (decelerating). Re-planning only changes the steps left (a
//! merge adds, a stop trims to what deceleration needs) or the ramp itself (a
//! speed change), and the walk does the rest: a merge while decelerating
//! climbs back from the current position (the mirror angle), a stop while
//! accelerating turns round at once.
//!
//! # Arithmetic modes
//!
//! [`Arithmetic::P2Exact`] reproduces the reference cog tick for tick:
//! `deg·128 = stepn·(360 − 2·offset)·128 / stom + offset·128`, angle =
//! `deg·128 × 93,206`, `halfsp = sp/2`, `X = QROTATE(halfsp, angle)`,
//! `v = max(halfsp − X, 1)`, `delay = min(QDIV(clkfreq, v), 95,000,000)`,
//! slew steps reusing the last ramp delay, deceleration numbered on from the
//! acceleration (`stepn = asteps … 2·asteps − 1`).
//!
//! [`Arithmetic::Smooth`] (the default) improves on it, each difference
//! measured in this module's tests:
//! - exact angles (`offset + k·(180° − offset)/asteps`; the reported
//!   binary angle rounded once, the cosine that of the exact angle to within
//!   0.51 LSB of 2^30) instead of the truncated `deg·128 × 93,206` mapping,
//!   which quantises angles to 1/128° and falls short by 8 parts per million
//!   (40° comes out as 39.99968°);
//! - the cosine at full 2^30 scale instead of `sp/2`, so low speeds keep their
//!   precision (the reference's `halfsp` truncates odd speeds and its velocity
//!   is an integer);
//! - slew steps at exactly the requested speed (the reference reuses the last
//!   ramp delay, slightly slower);
//! - a symmetric deceleration (step k from the end has the velocity of step k
//!   from the start; the reference's deceleration is one angle step early);
//! - delays rounded with the fraction carried from step to step, so the edge
//!   times stay within a few ticks of the ideal curve over any length of
//!   move (measured: at most 3.3 ticks, while keeping the ramp's delays
//!   monotonic holds some back near the top, and within 1 tick at the end);
//!   the reference truncates every delay: at 30,000 steps/s and 200 MHz its
//!   slew runs at 30,003 steps/s;
//! - no 95,000,000-tick cap (the longest delay is what the curve asks for, up
//!   to `u32::MAX` ticks); the reference's cap makes moves below 2.1 steps/s
//!   at 200 MHz run faster than asked, which P2Exact keeps.
//!
//! Measured (200 MHz, offset 40°): total move time against the ideal curve
//! (the sum of `clkfreq / v(θ)` at exact angles), and the slew delay.
//!
//! | move (speed, steps) | P2Exact total | Smooth total | P2Exact slew | Smooth slew |
//! |---|---|---|---|---|
//! | 20,000, 20,000 | −316 ppm | within 1 tick | 10,000 | 10,000 |
//! | 30,000, 50,000 | −220 ppm | within 1 tick | 6,666 (30,003 steps/s) | 6,666/6,667 (30,000) |
//! | 1,001, 3,000 | −1,329 ppm | within 1 tick | 200,000 (1,000 steps/s: `halfsp` truncated) | 199,800 |
//! | 50,000, 1,000,000 | −9.2 ppm | within 1 tick | 4,000 | 4,000 |
//!
//! # Where the code is
//!
//! | file | what |
//! |---|---|
//! | `planning.rs` | [`ScurveConfig`], [`Arithmetic`], [`plan`] and the short-move rule |
//! | `ramp.rs` | one ramp: its top speed, positions and per-ramp constants |
//! | `curve.rs` | [`SCurve`]: the move's state, the walk (the general path), the iterator |
//! | `replan.rs` | merge, stop, emergency stop, speed change ([`ReplanError`]) |
//! | `timing.rs` | one ramp position's angle, velocity and delay in either arithmetic |
//! | `p2exact.rs` | P2Exact's arithmetic and the board's step period ([`p2_period_ticks`]) |
//! | `smooth.rs` | Smooth's exact angles, velocity and delay |
//! | `cosines.rs` | blocks of ramp cosines and Smooth's cosine recurrence |
//! | `rounding.rs` | the carried rounding and the monotonic rule |
//! | `runs.rs` | ramp steps computed ahead while nothing re-plans, and [`RampSpan`] |
//! | `slew.rs` | the slew short path and [`SlewSpan`] |
//! | `tests/` | the tests, a file per concern, with models of the reference cog |

mod cosines;
mod curve;
mod p2exact;
mod planning;
mod ramp;
mod replan;
mod rounding;
mod runs;
mod slew;
mod smooth;
mod timing;

pub use curve::SCurve;
pub use p2exact::{
    p2_period_ticks, P2_DEG128_TO_BINARY, P2_MAX_DELAY_TICKS, P2_PULSE_TICKS,
    P2_STEP_OVERHEAD_TICKS,
};
pub use planning::{plan, Arithmetic, Plan, ScurveConfig};
pub use replan::ReplanError;
pub use runs::RampSpan;
pub use slew::SlewSpan;

// The module docs link to it.

/// 180° as a binary angle.
const HALF_TURN: u32 = 1 << 31;

#[cfg(test)]
mod tests;

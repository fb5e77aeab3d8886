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
//! [`smooth_cosines`]'s error bound).
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

use cordic_core::{cos_batch, cos_sin_q62, qrotate};

use super::{Phase, PlanError, Profile, Step};

/// The reference's cap on a step delay, in ticks.
pub const P2_MAX_DELAY_TICKS: u32 = 95_000_000;

/// The reference's degrees·128 to binary angle factor (2^32 / 46,080, truncated).
pub const P2_DEG128_TO_BINARY: u32 = 93_206;

/// The reference's step pulse (`delayh`): the step pin is high for 1,000
/// ticks (5 µs at 200 MHz), and that time is part of the step period.
pub const P2_PULSE_TICKS: u32 = 1_000;

/// The reference cog's fixed instruction overhead in a step period, in
/// clocks: from the moment CT reaches the CT2 target (`cv`) to the moment
/// the next `GETCT cv` samples CT.
///
/// The cog keeps one running target. Right after a rising edge it reads
/// CT into `cv` (`drvh steppin` / `getct cv`); `addct1 cv, delayh` moves
/// `cv` on by the pulse and `_ws2 addct2 cv, delay` by the step's delay,
/// so the next wait ends at `cv + delayh + delay`. Everything else the cog
/// does between two steps (the hub writes, the CORDIC's `_getdelay`, the
/// main loop's tests) runs while it waits, inside the pulse or the delay,
/// and costs nothing. What is *not* hidden is the path from the end of the
/// wait to the next `GETCT`, in cog execution (P2 silicon documentation:
/// 2 clocks an instruction, 4 for a branch taken, `WAITxxx` 2+):
///
/// | instruction | clocks | why |
/// |---|---|---|
/// | `waitct2` (in `_waitstep`) | 2 | the CT2 event flag is set as CT passes the target (MSB of CT − CT2 turns 0); the stalled wait then completes its 2 clocks |
/// | `tjnz steps, #_dostep1` | 4 | steps left: the branch is taken (2 + 2 to reload the pipeline) |
/// | `drvh steppin` | 2 | the rising edge |
/// | `getct cv` | 0 | CT is sampled as it executes: the new `cv` |
///
/// 2 + 4 + 2 = 8 clocks, so rising edge to rising edge is
/// `delay + delayh + 8` ([`p2_period_ticks`]): at 20,000 steps/s
/// (delay 10,000) the board makes 200 MHz / 11,008 = 18,169 steps/s, at
/// 45,000 (delay 4,444) 36,684. The wake-up is the least certain term; a
/// clock more or less moves those rates by under 0.01 %.
///
/// The sum holds while the cog's own work between two edges fits in the
/// period: at least the `_getdelay` CORDIC chain (about 300 clocks) after
/// the pulse, so delays above a few hundred ticks (every speed below
/// 500,000 steps/s at 200 MHz). The pulse edge itself (`drvh`) is a fixed
/// offset before `getct`, so the edges are spaced like the `cv` values.
pub const P2_STEP_OVERHEAD_TICKS: u32 = 8;

/// The reference cog's step period, rising edge to rising edge, in ticks:
/// the step's delay, plus the pulse the running target adds before it,
/// plus the cog's fixed overhead ([`P2_STEP_OVERHEAD_TICKS`]).
///
/// ```
/// use cogstep_motion::profile::scurve::{p2_period_ticks, P2_PULSE_TICKS};
/// // Asked for 20,000 steps/s (delay 10,000 ticks), the P2 board steps
/// // every 11,008 ticks: 18,169 steps/s at 200 MHz.
/// assert_eq!(p2_period_ticks(10_000, P2_PULSE_TICKS), 11_008);
/// ```
pub fn p2_period_ticks(delay_ticks: u32, pulse_ticks: u32) -> u64 {
    u64::from(delay_ticks) + u64::from(pulse_ticks) + u64::from(P2_STEP_OVERHEAD_TICKS)
}

/// 180° as a binary angle.
const HALF_TURN: u32 = 1 << 31;

/// Full scale of the cosine used by the smooth arithmetic.
const COS_SCALE: i32 = 1 << 30;

/// How a cog turns angles into delays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Arithmetic {
    /// The reference P2 driver's integer arithmetic, tick for tick.
    P2Exact,
    /// Exact angles, full-precision velocity, carried rounding (see the module docs).
    #[default]
    Smooth,
}

/// The settings of the S-curve that do not change from move to move.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ScurveConfig {
    /// System clock, Hz (ticks per second).
    pub clkfreq: u32,
    /// Where the ramp starts on the cosine, degrees (1..=89; default 40).
    pub offset_deg: u32,
    /// Acceleration divisor: accel steps = speed / divisor + 2 (default 10).
    pub accel_div: u32,
    /// Integer arithmetic of the reference, or the improved default.
    pub arithmetic: Arithmetic,
}

impl Default for ScurveConfig {
    fn default() -> Self {
        Self {
            clkfreq: 200_000_000,
            offset_deg: 40,
            accel_div: 10,
            arithmetic: Arithmetic::Smooth,
        }
    }
}

impl ScurveConfig {
    fn validate(&self) -> Result<(), PlanError> {
        if self.clkfreq == 0 {
            return Err(PlanError::ZeroClock);
        }
        if !(1..=89).contains(&self.offset_deg) {
            return Err(PlanError::BadOffset(self.offset_deg));
        }
        if self.accel_div == 0 {
            return Err(PlanError::BadAccelDiv);
        }
        Ok(())
    }
}

/// What [`plan`] made of a move command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Plan {
    /// The speed asked for, steps/s.
    pub requested_speed: u32,
    /// The top speed of the move, steps/s: the requested one, or lower for a
    /// short move.
    pub speed: u32,
    /// Steps in the move (magnitude).
    pub steps: u32,
    /// Steps spent accelerating (and as many decelerating).
    pub accel_steps: u32,
    /// Steps at the top speed.
    pub slew_steps: u32,
    /// The ramp's starting angle, degrees.
    pub offset_deg: u32,
    /// Whether the short-move speed limit lowered the speed.
    pub short_move: bool,
}

/// Plans a move of `steps` steps at `speed` steps/s as the reference does,
/// with cogstep's short-move rule (see the module docs).
///
/// ```
/// use cogstep_motion::profile::scurve::{plan, ScurveConfig};
/// let p = plan(&ScurveConfig::default(), 20_000, 20_000).unwrap();
/// assert_eq!((p.accel_steps, p.slew_steps, p.speed), (2_002, 15_996, 20_000));
/// let short = plan(&ScurveConfig::default(), 20_000, 101).unwrap();
/// assert_eq!((short.accel_steps, short.slew_steps, short.speed), (50, 1, 480));
/// ```
pub fn plan(config: &ScurveConfig, speed: u32, steps: u32) -> Result<Plan, PlanError> {
    config.validate()?;
    if speed == 0 {
        return Err(PlanError::ZeroSpeed);
    }
    if steps == 0 {
        return Err(PlanError::ZeroSteps);
    }
    if speed > config.clkfreq {
        return Err(PlanError::SpeedTooHigh {
            speed,
            clkfreq: config.clkfreq,
        });
    }
    let natural = speed / config.accel_div + 2;
    let accel_steps = natural.min(steps / 2);
    let slew_steps = steps - 2 * accel_steps;
    let capped = accel_steps < natural;
    // The reference's `if ss == 0` also fires when the move is exactly
    // 2·(sp/10 + 2) steps long and was never capped: sp is then rounded
    // down to a multiple of 10. P2Exact follows it; Smooth keeps sp.
    let p2_rounds = config.arithmetic == Arithmetic::P2Exact && slew_steps == 0;
    let top = if capped || p2_rounds {
        let limit = config
            .accel_div
            .saturating_mul(accel_steps.saturating_sub(2))
            .max(config.accel_div);
        speed.min(limit)
    } else {
        speed
    };
    Ok(Plan {
        requested_speed: speed,
        speed: top,
        steps,
        accel_steps,
        slew_steps,
        offset_deg: config.offset_deg,
        short_move: top < speed,
    })
}

/// One ramp: a top speed and the number of positions between the offset
/// angle and 180°.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Ramp {
    speed: u32,
    accel_steps: u32,
    /// Smooth: clkfreq·2^63 / speed as the bits of an `f64` (rounded once),
    /// so that a step's delay is one division (see [`smooth_delay_q32`]).
    numerator: u64,
    /// Smooth: the constants of the cosine recurrence (see
    /// [`smooth_cosines`]); `None` for a ramp of a few positions, whose
    /// cosines are each computed alone.
    recurrence: Option<Recurrence>,
    /// Smooth: the steps of [`smooth_angle`]'s numerator over its divisor
    /// for one and for two positions, (quotient, remainder), so that a
    /// block of angles takes one division, not three.
    angle_steps: [(u64, u64); 2],
}

/// Smooth: the constants of [`smooth_cosines`]' recurrence for a ramp whose
/// positions are Δ apart (Δ < 29°): for one chain over every key, and for
/// two chains side by side, each over every other key (2Δ < 29°), whose
/// multiplications overlap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Recurrence {
    /// Turning by Δ.
    one: Turn,
    /// Turning by 2Δ, when 2Δ < 29°.
    two: Option<Turn>,
}

/// The constants of one turn of the recurrence, by an angle φ < 29°.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Turn {
    /// sin φ in 2.62, within 2^-51.
    sin: i64,
    /// d = 2 − 2·cos φ = 4·sin²(φ/2) as `d_mantissa · 2^-(64 + d_shift)`,
    /// the mantissa in 2^61..2^62 (relative error below 2^-50), so that
    /// `d·c` is one multiplication and two shifts ([`mul_step`]) however
    /// small φ is.
    d_mantissa: i64,
    d_shift: u32,
}

impl Turn {
    /// From sin φ and d in `f64` (each within a few units in the last
    /// place); `None` when d ≥ 1/4 (φ ≥ 29°).
    fn new(sin: f64, d: f64) -> Option<Self> {
        if d >= 0.25 {
            return None;
        }
        // d = significand·2^(exponent − 52), significand in 2^52..2^53
        // (d is normal: φ ≥ 2^-33 rad for any u32 ramp).
        let bits = d.to_bits();
        let exponent = ((bits >> 52) & 0x7FF) as i32 - 1023;
        let significand = (bits & ((1 << 52) - 1)) | (1 << 52);
        // d·2^(64 + shift) in 2^61..2^62: shift = −3 − exponent ≥ 0 (d < 1/4).
        let shift = (-3 - exponent) as u32;
        let (d_mantissa, d_shift) = if shift <= 62 {
            ((significand << 9) as i64, shift)
        } else {
            // d < 2^-65: d·c is below 2^-65 and rounds to nothing in 2.62.
            (0, 0)
        };
        Some(Self {
            // sin φ < 1/2: the product is exact and fits.
            sin: (sin * TWO_TO_THE_62) as i64,
            d_mantissa,
            d_shift,
        })
    }

    /// `d·c` in 2.62 for `c` in 2.62, rounded down (within 2^-62).
    #[inline(always)]
    fn d_times(&self, c: i64) -> i64 {
        mul_step(c, self.d_mantissa, self.d_shift)
    }

    /// `(1 − cos φ)·c = d·c/2` in 2.62, rounded down.
    fn half_d_times(&self, c: i64) -> i64 {
        mul_step(c, self.d_mantissa, self.d_shift + 1)
    }

    /// `D(0) = c(0) − c(−1) = c(0)·(1 − cos φ) − sin θ·sin φ` for a chain
    /// anchored at (cos θ, sin θ), 2.62.
    fn first_difference(&self, (cos, sin): (i64, i64)) -> i64 {
        self.half_d_times(cos) - mul_q62(sin, self.sin)
    }

    /// (cos θ, sin θ) turned by φ, 2.62: the input's error plus 2^-61.
    fn turn(&self, (cos, sin): (i64, i64)) -> (i64, i64) {
        (
            cos - self.half_d_times(cos) - mul_q62(sin, self.sin),
            sin - self.half_d_times(sin) + mul_q62(cos, self.sin),
        )
    }
}

impl Recurrence {
    /// The constants for Δ = (180° − offset)/accel_steps, or `None` when
    /// d ≥ 1/4 (Δ ≥ 29°: ramps of at most six positions).
    ///
    /// sin(Δ/2) and cos(Δ/2) come from their Taylor series in `f64` (13
    /// terms each, Δ/2 ≤ 90°: the first term left out is below 2^-60 of
    /// the sum), with `+`, `−` and `×` only: IEEE arithmetic is
    /// exact-rounded, so every target gets the same bits (a
    /// microcontroller's software floating point included). Each is within
    /// a few units in the last place (2^-50 relative); so are `sin Δ =
    /// 2·sin(Δ/2)·cos(Δ/2)`, `d = 4·sin²(Δ/2)`, and for 2Δ, `sin 2Δ =
    /// 2·sin Δ·(1 − d/2)` and `4·sin²Δ`.
    fn new(offset_deg: u32, accel_steps: u32) -> Option<Self> {
        let half_step = f64::from(180 - offset_deg) * core::f64::consts::PI
            / (360.0 * f64::from(accel_steps.max(1)));
        let (sin_half, cos_half) = sin_cos_series(half_step);
        let d = 4.0 * sin_half * sin_half;
        let sin = 2.0 * sin_half * cos_half;
        let one = Turn::new(sin, d)?;
        let two = Turn::new(2.0 * sin * (1.0 - 0.5 * d), 4.0 * sin * sin);
        Some(Self { one, two })
    }
}

/// 2^62 as an `f64`.
const TWO_TO_THE_62: f64 = 4_611_686_018_427_387_904.0;

/// (sin x, cos x) for 0 ≤ x ≤ π/2 from their Taylor series, Horner's way,
/// in `f64` additions and multiplications only (the same bits on every
/// target): `sin x = x·(1 − x²/(2·3)·(1 − x²/(4·5)·(…)))`, `cos x = 1 −
/// x²/(1·2)·(1 − x²/(3·4)·(…))`, 13 factors each.
fn sin_cos_series(x: f64) -> (f64, f64) {
    let square = x * x;
    let (mut sin, mut cos) = (1.0, 1.0);
    for n in (1..=13u32).rev() {
        // The reciprocals are exact-rounded constants (a division, once).
        sin = 1.0 - square * (1.0 / f64::from((2 * n) * (2 * n + 1))) * sin;
        cos = 1.0 - square * (1.0 / f64::from((2 * n - 1) * (2 * n))) * cos;
    }
    (x * sin, cos)
}

/// `d·c` in 2.62 for the `d` of a [`Recurrence`] and `c` in 2.62, rounded
/// down (within 2^-62).
#[inline(always)]
fn mul_step(c: i64, d_mantissa: i64, d_shift: u32) -> i64 {
    (((i128::from(c) * i128::from(d_mantissa)) >> 64) as i64) >> d_shift
}

impl Ramp {
    fn new(config: &ScurveConfig, speed: u32, accel_steps: u32) -> Self {
        // Both factors and 2^63 are exact in f64: one rounding.
        let numerator = f64::from(config.clkfreq) * TWO_TO_THE_63 / f64::from(speed.max(1));
        let (recurrence, angle_steps) = match config.arithmetic {
            Arithmetic::Smooth => {
                let (span, divisor) = smooth_angle_span(config.offset_deg, accel_steps);
                (
                    Recurrence::new(config.offset_deg, accel_steps),
                    [
                        (span / divisor, span % divisor),
                        (2 * span / divisor, 2 * span % divisor),
                    ],
                )
            }
            Arithmetic::P2Exact => (None, [(0, 0); 2]),
        };
        Self {
            speed,
            accel_steps,
            numerator: numerator.to_bits(),
            recurrence,
            angle_steps,
        }
    }
}

/// One angle unit of [`smooth_angle`] (1/360 of a binary angle unit,
/// 2π/(360·2^32) rad) in radians, 2.62 fixed point: 18,740,330.145, rounded
/// down (the 0.145 left out is at most 27 units of 2^-62 for the ≤ 181
/// units it is ever multiplied by).
const RADIANS_Q62_PER_UNIT: i64 = 18_740_330;

/// (a·b) / 2^62 for 2.62 fixed-point values, rounded down.
#[inline(always)]
fn mul_q62(a: i64, b: i64) -> i64 {
    ((i128::from(a) * i128::from(b)) >> 62) as i64
}

/// (cos, sin) in 2.62 of the angle `units + remainder/divisor` in
/// [`smooth_angle`]'s units (360·2^32 a turn; `remainder < divisor`): the
/// nearest binary angle's from [`cos_sin_q62`] (within 2^-41), turned by the
/// rest, |ε| ≤ 181 units < 2^-30.2 rad, to first order (the ε²/2 left out
/// is below 2^-61).
fn cos_sin_of_units(units: u64, remainder: u64, divisor: u64) -> (i64, i64) {
    let binary = (units + 180) / 360;
    let rest_units = units as i64 - (binary * 360) as i64;
    let epsilon = rest_units * RADIANS_Q62_PER_UNIT
        + (remainder * RADIANS_Q62_PER_UNIT as u64 / divisor.max(1)) as i64;
    let (cos, sin) = cos_sin_q62(binary as u32);
    (cos - mul_q62(epsilon, sin), sin + mul_q62(epsilon, cos))
}

/// 2^63 as an `f64`.
const TWO_TO_THE_63: f64 = 9_223_372_036_854_775_808.0;

/// clkfreq / (sp·(1 − cos θ)/2) in 32.32 ticks from `one_minus_cos` =
/// (1 − cos θ)·2^30 (in 1..=2^31): `(clkfreq·2^63/sp) / one_minus_cos` as
/// one IEEE division (the numerator rounded once per ramp, the divisor
/// exact), so a relative error below 2^-52, truncated to 32.32 ticks and
/// held below 2^63. The same bits on every target (IEEE arithmetic is
/// exact-rounded); a division on a host FPU overlaps the next step's, where
/// a 64-bit integer division would not.
#[inline(always)]
fn smooth_delay_q32(numerator: u64, one_minus_cos: u64) -> u64 {
    // `as` saturates (the value is never NaN: both operands are positive),
    // at 2^63 − 1 for `i64`.
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    return (f64::from_bits(numerator) / one_minus_cos as f64) as i64 as u64;
    // No FPU: the same bits from integer arithmetic (32-bit UDIV, no
    // soft-float calls); `one_minus_cos` is at most 2^31.
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    return super::ieee_div::div_trunc(numerator, one_minus_cos as u32);
}

/// A move in progress: yields its steps and takes re-planning commands.
///
/// ```
/// use cogstep_motion::profile::{scurve::{SCurve, ScurveConfig}, Phase};
/// let move_ = SCurve::new(ScurveConfig::default(), 20_000, 20_000).unwrap();
/// let steps: Vec<_> = move_.collect();
/// assert_eq!(steps.len(), 20_000);
/// assert_eq!(steps[0].delay_ticks, 85_486); // v = 0.117·sp at 40°
/// assert_eq!(steps[10_000].phase, Phase::Slew);
/// assert_eq!(steps[10_000].delay_ticks, 10_000);
/// ```
#[derive(Clone, Debug)]
pub struct SCurve {
    config: ScurveConfig,
    plan: Plan,
    ramp: Ramp,
    /// A lower top speed still to be reached by decelerating on `ramp`.
    pending_ramp: Option<Ramp>,
    /// Steps yielded so far.
    index: u32,
    /// Steps still to yield.
    remaining: u32,
    /// Ramp position of the last step yielded.
    position: Option<u32>,
    /// Ticks carried to the next delay (smooth), signed 32.32 fixed point:
    /// the rounding remainder, plus whatever keeping the ramp monotonic held back.
    carry: i64,
    /// The reference's last ramp delay and velocity, reused at slew (P2Exact).
    last_ramp: Option<(u32, u32)>,
    /// The delay of one slew step in 32.32 ticks (smooth), cached per ramp.
    slew_q32: u64,
    /// Velocity of the last step, steps/s (a report value).
    velocity: f64,
    /// Delay of the last step in 32.32 ticks, before rounding: what the
    /// re-planning compares (a longer delay is a lower velocity).
    last_delay_q32: u64,
    /// Phase and whole-tick delay of the last step yielded.
    last_emitted: Option<(Phase, u32)>,
    /// The slew fast path (see [`SCurve::next_slew`]) holds while
    /// `remaining > slew_floor`; `u32::MAX` turns it off.
    slew_floor: u32,
    /// The delay of each fast slew step, 32.32 ticks.
    slew_delay_q32: u64,
    /// The velocity reported for each fast slew step, steps/s.
    slew_velocity: f64,
    /// Ramp cosines computed ahead, a block at a time.
    cosines: CosineBlock,
    /// Ramp steps computed ahead (see [`SCurve::arm_ramp`]).
    run: RampRun,
    /// A controlled stop is under way: no step may be faster than the one
    /// before it (P2Exact's deceleration angles sit one step above the
    /// mirror of its acceleration's, and its integer velocity can round up
    /// by one; see [`SCurve::stop`]).
    stopping: bool,
}

/// Why a re-planning request was refused. Nothing changes when it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ReplanError {
    /// The steps would exceed `u32::MAX` in one move.
    #[error("the move would exceed 2^32 - 1 steps")]
    TooManySteps,
    /// The new speed cannot be planned.
    #[error(transparent)]
    Plan(#[from] PlanError),
}

impl SCurve {
    /// Plans a move (see [`plan`]) and gets ready to yield its steps.
    pub fn new(config: ScurveConfig, speed: u32, steps: u32) -> Result<Self, PlanError> {
        let plan = plan(&config, speed, steps)?;
        let ramp = Ramp::new(&config, plan.speed, plan.accel_steps);
        Ok(Self {
            config,
            plan,
            ramp,
            pending_ramp: None,
            index: 0,
            remaining: steps,
            position: None,
            carry: 0,
            last_ramp: None,
            slew_q32: slew_q32(config.clkfreq, ramp.speed),
            velocity: 0.0,
            last_delay_q32: u64::MAX,
            last_emitted: None,
            slew_floor: u32::MAX,
            slew_delay_q32: 0,
            slew_velocity: 0.0,
            cosines: CosineBlock::EMPTY,
            run: RampRun::EMPTY,
            stopping: false,
        })
    }

    /// The plan the move started with.
    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// The configuration the move runs with.
    pub fn config(&self) -> &ScurveConfig {
        &self.config
    }

    /// The top speed the move is heading for now, steps/s.
    pub fn top_speed(&self) -> u32 {
        self.pending_ramp.unwrap_or(self.ramp).speed
    }

    /// Accel steps of the ramp in use now.
    pub fn accel_steps(&self) -> u32 {
        self.ramp.accel_steps
    }

    /// Steps yielded so far.
    pub fn steps_done(&self) -> u32 {
        self.index + self.run.next
    }

    /// The velocity of the last step yielded, steps/s (0 before the first).
    pub fn velocity(&self) -> f64 {
        match (self.run.next as usize).checked_sub(1) {
            Some(last) => self.run.velocity(last),
            None => self.velocity,
        }
    }

    /// Whether the move still has steps to yield.
    pub fn is_running(&self) -> bool {
        self.remaining_now() > 0
    }

    /// Steps still to yield. While a run of ramp steps is being yielded,
    /// `index` and `remaining` stay where the run began and the run's
    /// `next` counts the steps since (one counter a step instead of three);
    /// [`SCurve::settle`] brings them up to date.
    #[inline(always)]
    fn remaining_now(&self) -> u32 {
        self.remaining - self.run.next
    }

    /// Adds `extra_steps` to the move (the jog merge): they run at the top
    /// speed with no deceleration in between; a move already decelerating
    /// climbs back from its current velocity. A short move whose speed the
    /// plan had lowered climbs on towards the requested speed.
    pub fn merge(&mut self, extra_steps: u32) -> Result<(), ReplanError> {
        self.settle();
        let remaining = self
            .remaining
            .checked_add(extra_steps)
            .ok_or(ReplanError::TooManySteps)?;
        // A short move ran below the requested speed; with more steps it may
        // climb towards it again (the walk still keeps room to stop).
        let requested = self.plan.requested_speed;
        self.slew_floor = u32::MAX;
        if self.top_speed() < requested {
            self.change_speed(requested)?;
        }
        self.remaining = remaining;
        self.stopping = false;
        Ok(())
    }

    /// Controlled stop: from now on decelerate from the current velocity, at
    /// once, whatever the phase. Returns the steps that will not be made (the
    /// move's total shrinks by exactly that many).
    ///
    /// No step after a stop is faster than the step before it. In P2Exact
    /// the deceleration's angles are the reference's (one ramp step nearer
    /// 180° than the mirror of the acceleration's) and its velocity is an
    /// integer `sp/2 − X`, so turning round mid-ramp could step up by one
    /// unit of `sp/2` (+4.2 % at 49 steps/s, where `sp/2` = 24) or, from
    /// the slew, onto the 180° step; such a step keeps the previous delay.
    /// A later merge or speed change lifts the rule.
    pub fn stop(&mut self) -> u32 {
        self.settle();
        self.slew_floor = u32::MAX;
        self.stopping = true;
        let needed = self.position.unwrap_or(0);
        let dropped = self.remaining.saturating_sub(needed);
        self.remaining -= dropped;
        dropped
    }

    /// Emergency stop: no more steps. Returns the steps that will not be made.
    pub fn estop(&mut self) -> u32 {
        self.settle();
        let dropped = self.remaining;
        self.remaining = 0;
        self.pending_ramp = None;
        self.slew_floor = u32::MAX;
        dropped
    }

    /// Changes the top speed without stopping. Speeding up climbs the new
    /// ramp from the current velocity; slowing down descends the current
    /// ramp until the new speed is reached, then runs on the new ramp. The
    /// acceleration stays within what either ramp allows.
    pub fn change_speed(&mut self, speed: u32) -> Result<(), ReplanError> {
        let new_plan = plan(&self.config, speed, u32::MAX)?;
        self.settle();
        self.slew_floor = u32::MAX;
        self.stopping = false;
        let new_ramp = Ramp::new(&self.config, new_plan.speed, new_plan.accel_steps);
        if slew_q32(self.config.clkfreq, new_ramp.speed) <= self.last_delay_q32 {
            self.switch_ramp(new_ramp);
        } else {
            self.pending_ramp = Some(new_ramp);
        }
        Ok(())
    }

    /// Runs on `ramp` from here, at the highest position whose velocity does
    /// not exceed the current one (whose delay is at least the current one).
    fn switch_ramp(&mut self, ramp: Ramp) {
        let current = self.last_delay_q32;
        let mapped = self.position.map(|_| {
            // Delays shrink as the position grows: bisect for the last one ≥ current.
            let (mut low, mut high) = (0u32, ramp.accel_steps);
            if self.delay_at(ramp, 0, Phase::Accel) < current {
                return 0;
            }
            while low < high {
                let mid = low + (high - low).div_ceil(2);
                if self.delay_at(ramp, mid, Phase::Accel) >= current {
                    low = mid;
                } else {
                    high = mid - 1;
                }
            }
            low
        });
        self.ramp = ramp;
        self.position = mapped;
        self.pending_ramp = None;
        self.last_ramp = None;
        self.slew_q32 = slew_q32(self.config.clkfreq, ramp.speed);
        self.carry = 0;
        self.slew_floor = u32::MAX;
    }

    /// The delay (32.32 ticks) the arithmetic gives at a ramp position.
    fn delay_at(&self, ramp: Ramp, position: u32, phase: Phase) -> u64 {
        self.timing(ramp, position, phase).2
    }

    /// The ramp position of the next step and its phase.
    fn next_position(&self) -> (u32, Phase) {
        let ceiling = self.remaining - 1;
        match self.position {
            None => {
                let position = 0;
                let phase = if position == self.ramp.accel_steps {
                    Phase::Slew
                } else {
                    Phase::Accel
                };
                (position, phase)
            }
            Some(previous) => {
                let next = (previous + 1).min(self.ramp.accel_steps).min(ceiling);
                let phase = if next == self.ramp.accel_steps && next >= previous {
                    Phase::Slew
                } else if next > previous {
                    Phase::Accel
                } else {
                    Phase::Decel
                };
                (next, phase)
            }
        }
    }

    /// (binary angle, velocity steps/s, delay in 32.32 ticks) at a position.
    fn timing(&self, ramp: Ramp, position: u32, phase: Phase) -> (u32, f64, u64) {
        if let Some(slew) = self.slew_timing(ramp, position) {
            return slew;
        }
        let key = self.cosine_key(ramp, position, phase);
        let (angle, x) = match self.config.arithmetic {
            Arithmetic::Smooth => {
                // The cosine the block holding `key` has (it depends on
                // where the block starts).
                let first = key - key % COSINE_BLOCK as u32;
                let len = (key - first + 1) as usize;
                let (mut angles, mut cosines) = ([0; COSINE_BLOCK], [0; COSINE_BLOCK]);
                smooth_cosines(
                    &self.config,
                    ramp,
                    first,
                    &mut angles[..len],
                    &mut cosines[..len],
                );
                (angles[len - 1], cosines[len - 1])
            }
            Arithmetic::P2Exact => {
                let (radius, angle) = self.rotation(ramp, key);
                (angle, qrotate(radius, 0, angle).0)
            }
        };
        self.timing_from_cosine(ramp, phase, angle, x)
    }

    /// [`SCurve::timing`] on the ramp in use, its cosines taken from a block
    /// computed together (as the P2 keeps its CORDIC pipeline full):
    /// [`cos_batch`] gives the same bits as one QROTATE each, for less work.
    fn timing_batched(&mut self, position: u32, phase: Phase) -> (u32, f64, u64) {
        let ramp = self.ramp;
        if let Some(slew) = self.slew_timing(ramp, position) {
            return slew;
        }
        let key = self.cosine_key(ramp, position, phase);
        if !self.cosines.holds(ramp, key) {
            self.fill_cosines(ramp, key);
        }
        let (angle, x) = self.cosines.get(key);
        self.timing_from_cosine(ramp, phase, angle, x)
    }

    /// Computes the block of cosines that holds `key`: the keys from the
    /// multiple of [`COSINE_BLOCK`] at or below it, so that a key's cosine
    /// does not depend on the order the keys are asked for in.
    fn fill_cosines(&mut self, ramp: Ramp, key: u32) {
        let keys = match self.config.arithmetic {
            Arithmetic::Smooth => ramp.accel_steps,
            Arithmetic::P2Exact => 2 * ramp.accel_steps + 1,
        };
        let first = key - key % COSINE_BLOCK as u32;
        let len = (keys.max(key + 1) - first).min(COSINE_BLOCK as u32) as usize;
        let block = &mut self.cosines;
        match self.config.arithmetic {
            Arithmetic::Smooth => smooth_cosines(
                &self.config,
                ramp,
                first,
                &mut block.angles[..len],
                &mut block.cosines[..len],
            ),
            Arithmetic::P2Exact => {
                let radius = p2_ramp_angles(&self.config, ramp, first, &mut block.angles[..len]);
                cos_batch(radius, &block.angles[..len], &mut block.cosines[..len]);
            }
        }
        block.ramp = Some(ramp);
        block.first = first;
        block.len = len as u32;
    }

    /// A position at or above the top of the ramp: the slew timing (smooth).
    fn slew_timing(&self, ramp: Ramp, position: u32) -> Option<(u32, f64, u64)> {
        (self.config.arithmetic == Arithmetic::Smooth && position >= ramp.accel_steps).then(|| {
            (
                HALF_TURN,
                f64::from(ramp.speed),
                slew_q32(self.config.clkfreq, ramp.speed),
            )
        })
    }

    /// Which cosine a position needs: smooth, the position itself (the
    /// deceleration mirrors the acceleration); P2Exact, the reference's
    /// step number (the deceleration numbered on from the acceleration).
    fn cosine_key(&self, ramp: Ramp, position: u32, phase: Phase) -> u32 {
        match (self.config.arithmetic, phase) {
            (Arithmetic::P2Exact, Phase::Decel) => (2 * ramp.accel_steps)
                .saturating_sub(1)
                .saturating_sub(position),
            _ => position,
        }
    }

    /// The QROTATE of a cosine key: (radius, binary angle).
    fn rotation(&self, ramp: Ramp, key: u32) -> (i32, u32) {
        let offset = self.config.offset_deg;
        match self.config.arithmetic {
            Arithmetic::Smooth => (COS_SCALE, smooth_angle(offset, ramp.accel_steps, key)),
            Arithmetic::P2Exact => {
                let stom = 2 * ramp.accel_steps;
                let deg128 = if stom == 0 {
                    180 * 128
                } else {
                    (u64::from(key) * u64::from(360 - 2 * offset) * 128 / u64::from(stom)) as u32
                        + offset * 128
                };
                let halfsp = (ramp.speed / 2) as i32;
                (halfsp, deg128.wrapping_mul(P2_DEG128_TO_BINARY))
            }
        }
    }

    /// (angle, velocity, delay in 32.32 ticks) from the rotation's angle and
    /// the X it gave.
    fn timing_from_cosine(&self, ramp: Ramp, phase: Phase, angle: u32, x: i32) -> (u32, f64, u64) {
        match self.config.arithmetic {
            Arithmetic::Smooth => {
                let angle = if phase == Phase::Decel {
                    angle.wrapping_neg()
                } else {
                    angle
                };
                let (velocity, delay_q32) = smooth_velocity_delay(ramp, x);
                (angle, velocity, delay_q32)
            }
            Arithmetic::P2Exact => {
                let (velocity, delay) = p2_velocity_delay(self.config.clkfreq, ramp, x);
                (angle, f64::from(velocity), u64::from(delay) << 32)
            }
        }
    }

    /// The reference cog's arithmetic at a ramp position: (angle, v, delay).
    fn p2_timing(&self, ramp: Ramp, position: u32, phase: Phase) -> (u32, u32, u32) {
        let key = self.cosine_key(ramp, position, phase);
        let (halfsp, angle) = self.rotation(ramp, key);
        let (x, _) = qrotate(halfsp, 0, angle);
        let (velocity, delay) = p2_velocity_delay(self.config.clkfreq, ramp, x);
        (angle, velocity, delay)
    }
}

/// Smooth: (velocity, delay in 32.32 ticks) from the cosine X (2^30 scale).
#[inline(always)]
fn smooth_velocity_delay(ramp: Ramp, x: i32) -> (f64, u64) {
    let one_minus_cos = smooth_one_minus_cos(x);
    let velocity = scaled_velocity(ramp.speed, one_minus_cos as u32, 1.0 / f64::from(HALF_TURN));
    (velocity, smooth_delay_q32(ramp.numerator, one_minus_cos))
}

/// `scale · units · pow2` in steps/s (`pow2` a power of two): the exact
/// integer product rounded once to `f64` (as `f64::from(scale) *
/// f64::from(units)` would round it, but one conversion instead of two and a
/// multiplication, which a microcontroller does in software), then scaled
/// exactly.
#[inline(always)]
fn scaled_velocity(scale: u32, units: u32, pow2: f64) -> f64 {
    // Below 2^63 (Smooth: scale < 2^32 and units = (1 − cos θ)·2^30 ≤ 2^31;
    // P2Exact: a scale of 1), so the signed conversion, the cheaper one,
    // rounds alike.
    let product = u64::from(scale) * u64::from(units);
    debug_assert!(product < 1 << 63);
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    return product as i64 as f64 * pow2;
    // No FPU: the conversion and the scaling as integer and exponent
    // arithmetic, the same bits.
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    return super::ieee_div::u64_times_pow2(product, pow2);
}

/// Smooth: (1 − cos θ)·2^30 from the cosine X (2^30 scale), in 1..=2^31:
/// twice the velocity fraction.
#[inline(always)]
fn smooth_one_minus_cos(x: i32) -> u64 {
    (i64::from(COS_SCALE) - i64::from(x)).max(1) as u64
}

/// The reference's `v = max(halfsp − X, 1)` and `delay = min(QDIV(clkfreq, v), cap)`.
#[inline(always)]
fn p2_velocity_delay(clkfreq: u32, ramp: Ramp, x: i32) -> (u32, u32) {
    let halfsp = (ramp.speed / 2) as i32;
    let velocity = (i64::from(halfsp) - i64::from(x)).max(1) as u32;
    // The dividend fits 32 bits and v ≥ 1: QDIV's quotient is the 32-bit
    // one (`div_u32` is tested against `qdiv`).
    let delay = div_u32(clkfreq, velocity).min(P2_MAX_DELAY_TICKS);
    (velocity, delay)
}

/// `dividend / divisor` (`divisor ≥ 1`), exactly, the fastest way the target
/// has. On a host with an FPU: the IEEE quotient, truncated. It is exact:
/// were a/b = n − k/b (k ≥ 1) rounded up to n, its relative error would be
/// at least 1/(b·n) > 2^-32 (as b·n ≤ a + b < 2^33), but an IEEE division's is
/// at most 2^-53; and an exact integer a/b is exact in f64. A host's divider
/// is slow and not pipelined for integers, fast for `f64`. Elsewhere (a
/// Cortex-M has a 32-bit divider and no FPU): the integer division.
#[inline(always)]
fn div_u32(dividend: u32, divisor: u32) -> u32 {
    #[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
    {
        (f64::from(dividend) / f64::from(divisor)) as u32
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        dividend / divisor
    }
}

/// Cosines per block: enough that the CORDIC runs in full blocks, few
/// enough that a short move wastes little.
const COSINE_BLOCK: usize = 64;

/// Ramp steps computed ahead at most ([`SCurve::arm_ramp`]): a block's worth
/// on a host; on a microcontroller (no FPU: a division is a library call),
/// fewer, so that no one step interrupt computes many (and the run takes
/// little RAM). The steps are the same either way.
const RUN_STEPS: usize = if cfg!(any(target_arch = "x86_64", target_arch = "aarch64")) {
    COSINE_BLOCK
} else {
    8
};

/// Ramp steps computed ahead, in one tight loop, for a ramp that nothing
/// re-plans: entry `i` is the step after entry `i − 1`, exactly as
/// [`SCurve::next_general`] would give it (see [`SCurve::arm_ramp`]).
#[derive(Clone, Debug)]
struct RampRun {
    /// The next entry to yield.
    next: u32,
    /// Entries computed (`0`: no run).
    len: u32,
    /// Every entry's phase (accelerating or decelerating).
    phase: Phase,
    /// The ramp position of entry 0; the others follow one apart (up when
    /// accelerating, down when decelerating).
    first_position: u32,
    delay_ticks: [u32; RUN_STEPS],
    /// Each entry's velocity is `velocity_scale · units · velocity_pow2`
    /// (computed when a step is yielded: a caller that does not read it
    /// does not pay for it).
    velocity_units: [u32; RUN_STEPS],
    velocity_scale: u32,
    velocity_pow2: f64,
    angles: [u32; RUN_STEPS],
    /// The carry and the previous step's ticks before entry 0, and the
    /// carry after the last entry.
    start_carry: i64,
    previous_ticks: u32,
    end_carry: i64,
}

impl RampRun {
    /// Entry `i`'s velocity, steps/s.
    #[inline(always)]
    fn velocity(&self, i: usize) -> f64 {
        scaled_velocity(
            self.velocity_scale,
            self.velocity_units[i],
            self.velocity_pow2,
        )
    }

    const EMPTY: Self = Self {
        next: 0,
        len: 0,
        phase: Phase::Accel,
        first_position: 0,
        delay_ticks: [0; RUN_STEPS],
        velocity_units: [0; RUN_STEPS],
        velocity_scale: 0,
        velocity_pow2: 0.0,
        angles: [0; RUN_STEPS],
        start_carry: 0,
        previous_ticks: 0,
        end_carry: 0,
    };
}

/// A block of consecutive cosine keys of one ramp, with their rotation
/// angles and the X each rotation gave.
#[derive(Clone, Debug)]
struct CosineBlock {
    /// The ramp the keys belong to (`None`: empty).
    ramp: Option<Ramp>,
    first: u32,
    len: u32,
    angles: [u32; COSINE_BLOCK],
    cosines: [i32; COSINE_BLOCK],
}

impl CosineBlock {
    const EMPTY: Self = Self {
        ramp: None,
        first: 0,
        len: 0,
        angles: [0; COSINE_BLOCK],
        cosines: [0; COSINE_BLOCK],
    };

    fn holds(&self, ramp: Ramp, key: u32) -> bool {
        self.ramp == Some(ramp) && key.wrapping_sub(self.first) < self.len
    }

    /// (angle, X) of a key the block holds.
    fn get(&self, key: u32) -> (u32, i32) {
        let i = (key - self.first) as usize;
        (self.angles[i], self.cosines[i])
    }
}

impl SCurve {
    /// Turns an exact delay into whole ticks, carrying the remainder so that
    /// edge times stay on the ideal curve, while never letting a delay grow
    /// during acceleration or shrink during deceleration.
    fn round_delay(&mut self, delay_q32: u64, phase: Phase) -> u32 {
        let previous = self.last_emitted.and_then(|(previous_phase, previous)| {
            // After a stop, the first deceleration step is held to the last
            // step's delay too, whatever that step's phase.
            (previous_phase == phase || (self.stopping && phase == Phase::Decel))
                .then_some(previous)
        });
        let (ticks, carry) = carry_round(delay_q32, self.carry, phase, previous);
        self.carry = carry;
        self.last_emitted = Some((phase, ticks));
        ticks
    }
}

/// [`SCurve::round_delay`]'s arithmetic: (whole ticks, carry after), the
/// ticks held to `previous` (no longer when accelerating, no shorter when
/// decelerating) where the monotonic rule applies.
#[inline(always)]
fn carry_round(delay_q32: u64, carry: i64, phase: Phase, previous: Option<u32>) -> (u32, i64) {
    let held = previous.unwrap_or(match phase {
        Phase::Accel => u32::MAX,
        _ => 0,
    });
    carry_round_held(delay_q32, carry, phase, held)
}

/// [`carry_round`] with the ticks held to `previous` (`u32::MAX` when
/// accelerating, 0 otherwise, hold nothing). Every real delay takes the
/// 64-bit arithmetic, a chain of additions, shifts and selects without a
/// branch; the 128-bit one is for delays of 2^30 ticks and more.
#[inline(always)]
fn carry_round_held(delay_q32: u64, carry: i64, phase: Phase, previous: u32) -> (u32, i64) {
    // The carry is within ±2^50: below 2^62 + 2^50 the sum fits, and with
    // the ticks below 2^31 so does `ticks << 32`.
    if (delay_q32 >> 62) | u64::from(previous >> 31) != 0 {
        return carry_round_wide(delay_q32, carry, phase, previous);
    }
    let total = delay_q32 as i64 + carry;
    let ticks = hold(phase, (total >> 32).max(1) as u32, previous);
    // In practice the carry holds a few ticks at most (what the monotonic
    // clamp held back); the bound only keeps it finite on absurd input.
    let carry = (total - (i64::from(ticks) << 32)).clamp(-(1 << 50), 1 << 50);
    (ticks, carry)
}

/// Entry `i`'s delay before rounding, 32.32 ticks, computed again from its
/// velocity units (the run keeps its whole ticks only; only a re-planning
/// call needs the exact delays, to settle the run).
fn run_delay_q32(config: &ScurveConfig, ramp: Ramp, run: &RampRun, i: usize) -> u64 {
    let units = run.velocity_units[i];
    match config.arithmetic {
        Arithmetic::Smooth => smooth_delay_q32(ramp.numerator, u64::from(units)),
        Arithmetic::P2Exact => {
            u64::from(div_u32(config.clkfreq, units).min(P2_MAX_DELAY_TICKS)) << 32
        }
    }
}

/// Fills a run's entries from (angle, X) pairs, each step's velocity
/// units and 32.32 delay from `timing(X)`, its ticks by
/// [`carry_round_held`], held to the step before (the first to
/// `previous`), in one loop without bounds checks; returns the carry after
/// the last. `phase` is a constant where it is called, so no step tests it.
#[inline(always)]
fn fill_run(
    run: &mut RampRun,
    len: usize,
    source: impl Fn(usize) -> (u32, i32),
    timing: impl Fn(i32) -> (u32, u64),
    mut carry: i64,
    phase: Phase,
    mut previous: u32,
) -> i64 {
    // Every tick count is at least 1, so `previous` is too.
    debug_assert!(previous >= 1);
    let angles = &mut run.angles[..len];
    let units_out = &mut run.velocity_units[..len];
    let ticks_out = &mut run.delay_ticks[..len];
    for i in 0..len {
        let (angle, x) = source(i);
        let (units, delay_q32) = timing(x);
        // The usual step: a carry in 0..2^32 (one tick), no clamp binding;
        // then `carry_round_held` reduces to an addition and a mask: the sum
        // is below 2^64 (delays are below 2^63), so its whole ticks fit 32
        // bits, and whole ≥ 1 is implied by the order (previous ≥ 1).
        let total = delay_q32 + (carry as u64 & 0xFFFF_FFFF);
        let whole = (total >> 32) as u32;
        let in_order = match phase {
            Phase::Accel => whole.wrapping_sub(1) < previous,
            Phase::Decel => whole >= previous,
            Phase::Slew => whole != 0,
        };
        let ticks;
        if (carry as u64) >> 32 == 0 && in_order {
            ticks = whole;
            carry = (total & 0xFFFF_FFFF) as i64;
        } else {
            (ticks, carry) = carry_round_held(delay_q32, carry, phase, previous);
        }
        angles[i] = angle;
        units_out[i] = units;
        ticks_out[i] = ticks;
        previous = ticks;
    }
    carry
}

/// A Smooth ramp step's (velocity units, 32.32 delay) from its cosine X.
#[inline(always)]
fn smooth_run_timing(numerator: u64, x: i32) -> (u32, u64) {
    let one_minus_cos = smooth_one_minus_cos(x);
    (
        one_minus_cos as u32,
        smooth_delay_q32(numerator, one_minus_cos),
    )
}

/// The monotonic rule: `whole` ticks held to `previous` (no longer when
/// accelerating, no shorter when decelerating).
#[inline(always)]
fn hold(phase: Phase, whole: u32, previous: u32) -> u32 {
    match phase {
        Phase::Accel => whole.min(previous),
        Phase::Decel => whole.max(previous),
        Phase::Slew => whole,
    }
}

/// [`carry_round_held`] in 128-bit arithmetic, for any delay.
#[cold]
fn carry_round_wide(delay_q32: u64, carry: i64, phase: Phase, previous: u32) -> (u32, i64) {
    let total = i128::from(delay_q32) + i128::from(carry);
    let ticks = hold(
        phase,
        (total >> 32).clamp(1, i128::from(u32::MAX)) as u32,
        previous,
    );
    let carry = (total - (i128::from(ticks) << 32)).clamp(-(1 << 50), 1 << 50) as i64;
    (ticks, carry)
}

/// P2Exact: the rotations of the cosine keys `first..first + angles.len()`
/// of a ramp: fills `angles` with [`SCurve::rotation`]'s angles and returns
/// its radius, stepping the angle's quotient and remainder instead of
/// dividing per key. (Smooth's angles come with its cosines, from
/// [`smooth_cosines`].)
fn p2_ramp_angles(config: &ScurveConfig, ramp: Ramp, first: u32, angles: &mut [u32]) -> i32 {
    let offset = config.offset_deg;
    // deg·128 = key·(360 − 2·offset)·128 / stom + offset·128.
    let range = u64::from(360 - 2 * offset) * 128;
    let base = offset * 128;
    match core::num::NonZeroU64::new(u64::from(2 * ramp.accel_steps)) {
        None => angles.fill((180 * 128u32).wrapping_mul(P2_DEG128_TO_BINARY)),
        Some(stom) => {
            let product = u64::from(first) * range;
            let (mut quotient, mut remainder) = (product / stom, product % stom);
            let (step_quotient, step_remainder) = (range / stom, range % stom);
            for angle in angles.iter_mut() {
                // As the reference: the 32-bit sum, then the wrapping multiply.
                *angle = (quotient as u32 + base).wrapping_mul(P2_DEG128_TO_BINARY);
                quotient += step_quotient;
                remainder += step_remainder;
                if remainder >= stom.get() {
                    remainder -= stom.get();
                    quotient += 1;
                }
            }
        }
    }
    (ramp.speed / 2) as i32
}

/// Smooth: the binary angles (as [`smooth_angle`]) and cosines (2^30 scale)
/// of the keys `first..first + cosines.len()` of a ramp, all below
/// `accel_steps`.
///
/// The cosines follow the second-order recurrence `c(k+1) = 2·cos Δ·c(k) −
/// c(k−1)` in Reinsch's form, which keeps its precision however small the
/// step Δ between two ramp positions is: with `D(k) = c(k) − c(k−1)` and `d
/// = 2 − 2·cos Δ`,
///
/// ```text
/// D(k+1) = D(k) − d·c(k)        c(k+1) = c(k) + D(k+1)
/// ```
///
/// one multiplication a key (the rotation it replaces took four), anchored
/// at `first`: `c(0) = cos θ_first` from [`cos_sin_of_units`] (within e =
/// 2^-41) and `D(0) = c(0)·d/2 − sin θ_first·sin Δ`.
///
/// Error bound, for n ≤ 63 keys from the anchor, everything in units of
/// 1 (so 2^-30 is one LSB of the result). A perturbation of the start
/// values, ε in c(0) and δ in D(0), reaches c(n) as
/// `ε·cos((n+½)Δ)/cos(Δ/2) + δ·sin(nΔ)/sin Δ`: at most 1.15·ε (Δ < 29°) and
/// n·δ. Here ε ≤ e and δ ≤ e·(d/2 + sin Δ) + 2^-50 (the anchor's sine times
/// sin Δ, its cosine times d/2, and the constants' own errors), and n·(d/2 +
/// sin Δ) ≤ nΔ·(1 + Δ) < 2·π·1.6 (as nΔ < 180°), so the start contributes
/// below 12·e. Each step's product is rounded down (2^-62) and the
/// constants are within 2^-50 relative: together below 2^-47 over 63 keys.
/// So every cosine is within 2^-37 < 0.01 LSB of the exact 2^30·cos θ_k
/// before it is rounded, within 0.51 LSB after (tested against `f64`).
///
/// Where 2Δ < 29° too, two such chains run side by side, each turning by
/// 2Δ, on the even and the odd keys (so that their multiplications
/// overlap); the odd chain's anchor is the even one's turned by Δ, within
/// 1.6·e, and each chain takes at most 31 turns with n·2Δ < 180°: the same
/// bound holds. Ramps of six positions or fewer (Δ ≥ 29°) take each cosine
/// from its own anchor.
fn smooth_cosines(
    config: &ScurveConfig,
    ramp: Ramp,
    first: u32,
    angles: &mut [u32],
    cosines: &mut [i32],
) {
    debug_assert!(first as usize + cosines.len() <= ramp.accel_steps as usize);
    let asteps = u64::from(ramp.accel_steps.max(1));
    let offset_units = u64::from(config.offset_deg) << 32;
    let (span, divisor) = smooth_angle_span(config.offset_deg, ramp.accel_steps);
    // The exact angle of the first key, first·span/asteps = quotient +
    // remainder/asteps units past the offset: one division a block.
    let (quotient, remainder) = div_rem_wide(u128::from(span) * u128::from(first), asteps);
    // smooth_angle's floor((offset + floor(k·span/asteps) + 180)/360) is
    // floor((k·span + (offset + 180)·asteps) / (360·asteps)): stepped, from
    // the first key's, which is floor((offset + quotient + 180)/360) with the
    // rest (that sum mod 360)·asteps + remainder.
    let whole = offset_units + quotient + 180;
    let (angle, angle_rest) = (whole / 360, whole % 360 * asteps + remainder);
    // Two chains, on the even and the odd keys, so that their short
    // dependency chains (an addition and a select) overlap.
    let advance = |(angle, rest): (u64, u64), (step, step_rest): (u64, u64)| {
        let rest = rest + step_rest;
        if rest >= divisor {
            (angle + step + 1, rest - divisor)
        } else {
            (angle + step, rest)
        }
    };
    let [one, two] = ramp.angle_steps;
    let mut chains = [(angle, angle_rest), advance((angle, angle_rest), one)];
    let mut pairs = angles.chunks_exact_mut(2);
    for pair in &mut pairs {
        for (binary_angle, chain) in pair.iter_mut().zip(&mut chains) {
            *binary_angle = chain.0 as u32;
            *chain = advance(*chain, two);
        }
    }
    if let [last] = pairs.into_remainder() {
        *last = chains[0].0 as u32;
    }
    let Some(recurrence) = ramp.recurrence else {
        // A short ramp: each key from its own anchor.
        let (mut units, mut rest) = (offset_units + quotient, remainder);
        let (units_step, rest_step) = (span / asteps, span % asteps);
        for cosine in cosines.iter_mut() {
            *cosine = round_q62_to_q30(cos_sin_of_units(units, rest, asteps).0);
            units += units_step;
            rest += rest_step;
            if rest >= asteps {
                rest -= asteps;
                units += 1;
            }
        }
        return;
    };
    let anchor = cos_sin_of_units(offset_units + quotient, remainder, asteps);
    let Some(two) = recurrence.two else {
        // One chain.
        let one = recurrence.one;
        let mut difference = one.first_difference(anchor);
        let mut cos = anchor.0;
        for cosine in cosines.iter_mut() {
            *cosine = round_q62_to_q30(cos);
            difference -= one.d_times(cos);
            cos += difference;
        }
        return;
    };
    // Two chains turning by 2Δ, on the even and the odd keys; the odd
    // chain's anchor is the even one's turned by Δ (within 2^-40).
    let odd_anchor = recurrence.one.turn(anchor);
    let mut chains = [
        (anchor.0, two.first_difference(anchor)),
        (odd_anchor.0, two.first_difference(odd_anchor)),
    ];
    let mut pairs = cosines.chunks_exact_mut(2);
    for pair in &mut pairs {
        for (cosine, (cos, difference)) in pair.iter_mut().zip(&mut chains) {
            *cosine = round_q62_to_q30(*cos);
            *difference -= two.d_times(*cos);
            *cos += *difference;
        }
    }
    if let [last] = pairs.into_remainder() {
        *last = round_q62_to_q30(chains[0].0);
    }
}

/// (quotient, remainder) of a 128-bit value by a 64-bit one whose quotient
/// fits 64 bits, in 64-bit arithmetic where the value fits (every ramp
/// below 2^23 positions): a 128-bit division is a slow library call.
#[inline(always)]
fn div_rem_wide(value: u128, divisor: u64) -> (u64, u64) {
    match u64::try_from(value) {
        Ok(value) => (value / divisor, value % divisor),
        Err(_) => (
            (value / u128::from(divisor)) as u64,
            (value % u128::from(divisor)) as u64,
        ),
    }
}

/// A 2.62 value to 2^30 scale, rounded half up.
#[inline(always)]
fn round_q62_to_q30(value: i64) -> i32 {
    ((value + (1 << 31)) >> 32) as i32
}

/// One slew step's delay, clkfreq / speed, in 32.32 ticks.
fn slew_q32(clkfreq: u32, speed: u32) -> u64 {
    (u64::from(clkfreq) << 32) / u64::from(speed.max(1))
}

/// [`smooth_angle`]'s span (180° − offset, in units of 1/360 of a binary
/// angle unit) and the divisor of its numerator, `360·accel_steps`.
fn smooth_angle_span(offset_deg: u32, accel_steps: u32) -> (u64, u64) {
    let span = (180u64 << 32) - (u64::from(offset_deg) << 32);
    (span, 360 * u64::from(accel_steps.max(1)))
}

/// offset + position·(180° − offset)/accel_steps as a binary angle, rounded
/// once from exact wide arithmetic.
fn smooth_angle(offset_deg: u32, accel_steps: u32, position: u32) -> u32 {
    if accel_steps == 0 || position >= accel_steps {
        return HALF_TURN;
    }
    // Binary angles scaled by 360 so that whole degrees are exact.
    let offset = u64::from(offset_deg) << 32;
    let span = (180u64 << 32) - offset;
    // span < 2^40: 64 bits hold the product for ramps up to 2^24 positions
    // (every speed below 167 M steps/s), and give the same bits as 128.
    let climbed = match span.checked_mul(u64::from(position)) {
        Some(product) => product / u64::from(accel_steps),
        // Below `span` (position < accel_steps), so it fits again.
        None => (u128::from(span) * u128::from(position) / u128::from(accel_steps)) as u64,
    };
    ((offset + climbed + 180) / 360) as u32
}

impl SCurve {
    /// A step at the top speed, in the steady state the general path set up:
    /// the ramp position stays at the top, the delay is the cached one plus
    /// the carried fraction (in `0..2^32`, so whole ticks never need the
    /// clamps), and only the counters and the carry change. Gives exactly
    /// what [`SCurve::next_general`] would.
    #[inline(always)]
    fn next_slew(&mut self) -> Step {
        // In range by construction (see `arm_slew`): no overflow, ticks ≥ 1.
        let total = self.slew_delay_q32 + self.carry as u64;
        let delay_ticks = (total >> 32) as u32;
        self.carry = (total & 0xFFFF_FFFF) as i64;
        self.last_emitted = Some((Phase::Slew, delay_ticks));
        let index = self.index;
        self.index += 1;
        self.remaining -= 1;
        Step {
            index,
            phase: Phase::Slew,
            binary_angle: Some(HALF_TURN),
            velocity_steps_per_s: self.slew_velocity,
            delay_ticks,
        }
    }

    /// After a slew step of the general path: turns the fast path on for
    /// the slew steps that follow, when their arithmetic needs no clamp.
    fn arm_slew(&mut self, delay_q32: u64, velocity: f64) {
        let carry_in_range = (0..1i64 << 32).contains(&self.carry);
        let delay_in_range = (1u64 << 32..=u64::MAX - (1u64 << 32)).contains(&delay_q32);
        if self.pending_ramp.is_none()
            && self.position == Some(self.ramp.accel_steps)
            && carry_in_range
            && delay_in_range
        {
            // The walk stays at the top while more than `accel_steps` remain.
            self.slew_floor = self.ramp.accel_steps;
            self.slew_delay_q32 = delay_q32;
            self.slew_velocity = velocity;
        }
    }

    /// Any step: re-planning, ramps, the first slew step.
    #[inline(never)]
    fn next_general(&mut self) -> Option<Step> {
        self.settle();
        self.slew_floor = u32::MAX;
        if self.remaining == 0 {
            return None;
        }
        // Slowing to a lower speed: descend the old ramp until it is reached.
        if let Some(target) = self.pending_ramp {
            let down = self.position.map_or(0, |p| p.saturating_sub(1));
            if self.delay_at(self.ramp, down, Phase::Decel)
                >= slew_q32(self.config.clkfreq, target.speed)
                || down == 0
            {
                self.switch_ramp(target);
            }
        }
        let (position, phase) = match (self.pending_ramp, self.position) {
            (Some(_), Some(previous)) => {
                let down = previous.saturating_sub(1).min(self.remaining - 1);
                (down, Phase::Decel)
            }
            _ => self.next_position(),
        };
        let (angle, mut velocity, mut delay_q32) = match (self.config.arithmetic, phase) {
            (Arithmetic::Smooth, Phase::Slew) => {
                (HALF_TURN, f64::from(self.ramp.speed), self.slew_q32)
            }
            (Arithmetic::P2Exact, Phase::Slew) => {
                // The reference reuses its last ramp delay at speed.
                let (delay, velocity) = match self.last_ramp {
                    Some(last) => last,
                    None => {
                        let (_, v, d) = self.p2_timing(
                            self.ramp,
                            self.ramp.accel_steps.saturating_sub(1),
                            Phase::Accel,
                        );
                        (d, v)
                    }
                };
                (HALF_TURN, f64::from(velocity), u64::from(delay) << 32)
            }
            _ => {
                let timing = self.timing_batched(position, phase);
                if self.config.arithmetic == Arithmetic::P2Exact {
                    self.last_ramp = Some(((timing.2 >> 32) as u32, timing.1 as u32));
                }
                timing
            }
        };
        if self.stopping
            && self.config.arithmetic == Arithmetic::P2Exact
            && self.position.is_some()
            && (delay_q32 < self.last_delay_q32 || velocity > self.velocity)
        {
            delay_q32 = self.last_delay_q32;
            velocity = self.velocity;
        }
        let delay_ticks = self.round_delay(delay_q32, phase);
        let step = Step {
            index: self.index,
            phase,
            binary_angle: Some(angle),
            velocity_steps_per_s: velocity,
            delay_ticks,
        };
        self.index += 1;
        self.remaining -= 1;
        self.position = Some(position);
        self.velocity = velocity;
        self.last_delay_q32 = delay_q32;
        if phase == Phase::Slew {
            self.arm_slew(delay_q32, velocity);
        } else {
            self.arm_ramp();
        }
        Some(step)
    }

    /// A ramp step computed ahead by [`SCurve::arm_ramp`].
    #[inline(always)]
    fn next_ramp(&mut self) -> Step {
        let i = self.run.next as usize % RUN_STEPS;
        self.run.next += 1;
        self.ramp_entry(i)
    }

    /// Entry `i` of the run as a step.
    #[inline(always)]
    fn ramp_entry(&self, i: usize) -> Step {
        let run = &self.run;
        Step {
            index: self.index + i as u32,
            phase: run.phase,
            binary_angle: Some(run.angles[i]),
            velocity_steps_per_s: run.velocity(i),
            delay_ticks: run.delay_ticks[i],
        }
    }

    /// The run is used up: the next one, or the general path.
    #[inline(never)]
    fn next_after_run(&mut self) -> Option<Step> {
        if self.run.len > 0 {
            self.settle();
            if self.arm_ramp() {
                return Some(self.next_ramp());
            }
        }
        self.next_general()
    }

    /// Ends a run of ramp steps: the state becomes what the general path
    /// would have after the last entry yielded, and the rest is dropped.
    fn settle(&mut self) {
        let run = &mut self.run;
        self.index += run.next;
        self.remaining -= run.next;
        if let Some(last) = (run.next as usize).checked_sub(1) {
            let offset = last as u32;
            self.position = Some(match run.phase {
                Phase::Decel => run.first_position - offset,
                _ => run.first_position + offset,
            });
            self.velocity = run.velocity(last);
            self.last_delay_q32 = run_delay_q32(&self.config, self.ramp, run, last);
            self.carry = if last + 1 == run.len as usize {
                run.end_carry
            } else {
                // Left part way (a re-planning call): the carry so far.
                let mut carry = run.start_carry;
                for i in 0..=last {
                    let delay_q32 = run_delay_q32(&self.config, self.ramp, run, i);
                    let previous = match i.checked_sub(1) {
                        Some(before) => run.delay_ticks[before],
                        None => run.previous_ticks,
                    };
                    carry = carry_round(delay_q32, carry, run.phase, Some(previous)).1;
                }
                carry
            };
            self.last_emitted = Some((run.phase, run.delay_ticks[last]));
            if self.config.arithmetic == Arithmetic::P2Exact {
                self.last_ramp = Some(((self.last_delay_q32 >> 32) as u32, self.velocity as u32));
            }
        }
        run.next = 0;
        run.len = 0;
    }

    /// After a ramp step with nothing re-planned: computes the steps that
    /// follow on the same side of the ramp (up to the end of the cosine
    /// block), each as [`SCurve::next_general`] would, so that yielding one
    /// is three loads. Returns whether it made any.
    ///
    /// Accelerating, the walk climbs one position a step while it stays
    /// below the top and keeps room to stop (`position + 2 ≤ remaining`
    /// before each step); decelerating with `position == remaining`, it
    /// descends one a step to 0. A stop, a slower ramp pending or any
    /// other state takes the general path.
    fn arm_ramp(&mut self) -> bool {
        let (Some(position), Some((phase, previous))) = (self.position, self.last_emitted) else {
            return false;
        };
        if self.pending_ramp.is_some() || self.stopping {
            return false;
        }
        let ramp = self.ramp;
        let remaining = self.remaining;
        let (first_position, steps) = match phase {
            Phase::Accel if position + 1 < ramp.accel_steps => (
                position + 1,
                (ramp.accel_steps - 1 - position).min(remaining.saturating_sub(position) / 2),
            ),
            Phase::Decel if remaining == position && position > 0 => (position - 1, remaining),
            _ => return false,
        };
        let key = self.cosine_key(ramp, first_position, phase);
        if !self.cosines.holds(ramp, key) {
            self.fill_cosines(ramp, key);
        }
        let block = &self.cosines;
        // Smooth deceleration walks its keys down; all else walks them up.
        let descending = self.config.arithmetic == Arithmetic::Smooth && phase == Phase::Decel;
        let in_block = if descending {
            key - block.first + 1
        } else {
            block.first + block.len - key
        };
        let len = steps.min(in_block).min(RUN_STEPS as u32) as usize;
        if len == 0 {
            return false;
        }
        let start = (key - block.first) as usize;
        let run = &mut self.run;
        let carry = self.carry;
        // One loop: each step's division is independent of the others (they
        // overlap), its rounding a short chain from the step before.
        let carry = match (self.config.arithmetic, phase) {
            (Arithmetic::Smooth, Phase::Accel) => {
                let angles = &block.angles[start..start + len];
                let cosines = &block.cosines[start..start + len];
                let source = |i: usize| (angles[i], cosines[i]);
                let timing = |x| smooth_run_timing(ramp.numerator, x);
                fill_run(run, len, source, timing, carry, Phase::Accel, previous)
            }
            (Arithmetic::Smooth, _) => {
                // The mirror half: the keys walked down, the angles negated.
                let angles = &block.angles[start + 1 - len..start + 1];
                let cosines = &block.cosines[start + 1 - len..start + 1];
                let source = |i: usize| {
                    let at = len - 1 - i;
                    (angles[at].wrapping_neg(), cosines[at])
                };
                let timing = |x| smooth_run_timing(ramp.numerator, x);
                fill_run(run, len, source, timing, carry, Phase::Decel, previous)
            }
            (Arithmetic::P2Exact, _) => {
                let angles = &block.angles[start..start + len];
                let cosines = &block.cosines[start..start + len];
                let source = |i: usize| (angles[i], cosines[i]);
                let clkfreq = self.config.clkfreq;
                let timing = |x| {
                    let (velocity, delay) = p2_velocity_delay(clkfreq, ramp, x);
                    (velocity, u64::from(delay) << 32)
                };
                match phase {
                    Phase::Decel => {
                        fill_run(run, len, source, timing, carry, Phase::Decel, previous)
                    }
                    _ => fill_run(run, len, source, timing, carry, Phase::Accel, previous),
                }
            }
        };
        match self.config.arithmetic {
            // smooth_velocity_delay's velocity: the product rounded once,
            // then scaled exactly.
            Arithmetic::Smooth => {
                run.velocity_scale = ramp.speed;
                run.velocity_pow2 = 1.0 / f64::from(HALF_TURN);
            }
            Arithmetic::P2Exact => (run.velocity_scale, run.velocity_pow2) = (1, 1.0),
        }
        run.start_carry = self.carry;
        run.previous_ticks = self.last_emitted.map_or(0, |(_, ticks)| ticks);
        run.end_carry = carry;
        run.next = 0;
        run.len = len as u32;
        run.phase = phase;
        run.first_position = first_position;
        true
    }
}

/// The slew steps [`SCurve`]'s short path will yield next with nothing
/// re-planned in between (see [`SCurve::slew_span`]): every one a
/// [`Phase::Slew`] step of `velocity_steps_per_s` whose delay is the whole
/// ticks of a 32.32 running sum, so any of them is known in closed form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlewSpan {
    /// How many steps the short path has left (at least 1).
    pub steps: u32,
    /// The delay of each step before rounding, 32.32 ticks.
    pub delay_q32: u64,
    /// The fraction carried into the first of them, 32.32 ticks (< 1 tick).
    pub carry_q32: u64,
    /// The velocity each reports, steps/s.
    pub velocity_steps_per_s: f64,
}

impl SlewSpan {
    /// The whole-tick delays of the first `steps` steps, summed.
    pub fn ticks_before(&self, steps: u64) -> u64 {
        ((u128::from(steps) * u128::from(self.delay_q32) + u128::from(self.carry_q32)) >> 32) as u64
    }

    /// The whole-tick delay of step `i` (0 is the next one).
    pub fn delay_ticks(&self, i: u64) -> u32 {
        (self.ticks_before(i + 1) - self.ticks_before(i)) as u32
    }

    /// How many of the steps begin within `ticks` of the first: the count
    /// of `i` with `ticks_before(i) <= ticks` (at least 1; may exceed `steps`).
    pub fn steps_within(&self, ticks: u64) -> u64 {
        // ticks_before(i) <= ticks  ⇔  i·delay + carry < (ticks + 1)·2^32.
        let bound = ((u128::from(ticks) + 1) << 32) - 1 - u128::from(self.carry_q32);
        let steps = bound / u128::from(self.delay_q32.max(1)) + 1;
        u64::try_from(steps).unwrap_or(u64::MAX)
    }
}

impl SCurve {
    /// The steps the slew short path yields next, or `None` when the next
    /// step takes the general path (a ramp, a re-planning, the last steps).
    pub fn slew_span(&self) -> Option<SlewSpan> {
        (self.remaining > self.slew_floor).then(|| SlewSpan {
            steps: self.remaining - self.slew_floor,
            delay_q32: self.slew_delay_q32,
            // In 0..2^32 while the short path holds (see `arm_slew`).
            carry_q32: self.carry as u64,
            velocity_steps_per_s: self.slew_velocity,
        })
    }

    /// Yields `steps` steps of [`SCurve::slew_span`] at once (1 to its
    /// `steps`, else nothing happens): the state after is bit for bit what
    /// `steps` calls of `next` leave. Returns the delay of the last one.
    pub fn skip_slew(&mut self, steps: u32) -> Option<u32> {
        let span = self.slew_span()?;
        if steps == 0 || steps > span.steps {
            return None;
        }
        let total = u128::from(steps) * u128::from(span.delay_q32) + u128::from(span.carry_q32);
        let last = span.delay_ticks(u64::from(steps) - 1);
        self.carry = (total & 0xFFFF_FFFF) as i64;
        self.last_emitted = Some((Phase::Slew, last));
        self.index += steps;
        self.remaining -= steps;
        Some(last)
    }
}

impl Iterator for SCurve {
    type Item = Step;

    #[inline]
    fn next(&mut self) -> Option<Step> {
        // Ramp steps of a run computed ahead take the shortest path (no
        // run is open during the slew: `slew_floor` is off while one is).
        if self.run.next < self.run.len {
            return Some(self.next_ramp());
        }
        // Most steps of a long move are slew steps: they take the next
        // shortest path.
        if self.remaining > self.slew_floor {
            return Some(self.next_slew());
        }
        self.next_after_run()
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let remaining = self.remaining_now() as usize;
        (remaining, Some(remaining))
    }

    /// Every step, as `next` would give them, with the short paths' state
    /// in locals: a run's entries and the slew steps are yielded from
    /// registers, not through the struct a step at a time.
    fn fold<B, F>(mut self, init: B, mut f: F) -> B
    where
        F: FnMut(B, Step) -> B,
    {
        let mut acc = init;
        loop {
            // The run's entries.
            let (first, len) = (self.run.next, self.run.len);
            for i in first..len {
                self.run.next = i + 1;
                acc = f(acc, self.ramp_entry(i as usize % RUN_STEPS));
            }
            // The slew steps: the carry is the only state that moves.
            if self.remaining > self.slew_floor {
                let steps = self.remaining - self.slew_floor;
                let (delay_q32, velocity) = (self.slew_delay_q32, self.slew_velocity);
                let mut fraction = self.carry as u64;
                let mut delay_ticks = 0;
                for k in 0..steps {
                    let total = delay_q32 + fraction;
                    delay_ticks = (total >> 32) as u32;
                    fraction = total & 0xFFFF_FFFF;
                    let step = Step {
                        index: self.index + k,
                        phase: Phase::Slew,
                        binary_angle: Some(HALF_TURN),
                        velocity_steps_per_s: velocity,
                        delay_ticks,
                    };
                    acc = f(acc, step);
                }
                self.carry = fraction as i64;
                self.last_emitted = Some((Phase::Slew, delay_ticks));
                self.index += steps;
                self.remaining -= steps;
            }
            match self.next_after_run() {
                Some(step) => acc = f(acc, step),
                None => return acc,
            }
        }
    }
}

impl Profile for SCurve {
    fn remaining_steps(&self) -> u32 {
        self.remaining_now()
    }
}

#[cfg(test)]
mod tests;

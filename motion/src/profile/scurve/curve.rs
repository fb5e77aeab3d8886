//! The move in progress ([`SCurve`]): its state, what it reports, the walk
//! over ramp positions (the general path) and the iterator that yields its
//! steps, the short paths first.

use crate::profile::{Phase, PlanError, Profile, Step};

use super::cosines::CosineBlock;
use super::planning::{plan, Arithmetic, Plan, ScurveConfig};
use super::ramp::{slew_q32, Ramp};
use super::runs::{RampRun, FIRST_RUN_STEPS, RUN_STEPS};
use super::HALF_TURN;

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
#[derive(Debug, PartialEq)]
pub struct SCurve {
    pub(super) config: ScurveConfig,
    pub(super) plan: Plan,
    pub(super) ramp: Ramp,
    /// A lower top speed still to be reached by decelerating on `ramp`.
    pub(super) pending_ramp: Option<Ramp>,
    /// Steps yielded so far.
    pub(super) index: u32,
    /// Steps still to yield.
    pub(super) remaining: u32,
    /// Ramp position of the last step yielded.
    pub(super) position: Option<u32>,
    /// Ticks carried to the next delay (smooth), signed 32.32 fixed point:
    /// the rounding remainder, plus whatever keeping the ramp monotonic held back.
    pub(super) carry: i64,
    /// The reference's last ramp delay and velocity, reused at slew (P2Exact).
    pub(super) last_ramp: Option<(u32, u32)>,
    /// The delay of one slew step in 32.32 ticks (smooth), cached per ramp.
    pub(super) slew_q32: u64,
    /// Velocity of the last step, steps/s (a report value).
    pub(super) velocity: f64,
    /// Delay of the last step in 32.32 ticks, before rounding: what the
    /// re-planning compares (a longer delay is a lower velocity).
    pub(super) last_delay_q32: u64,
    /// Phase and whole-tick delay of the last step yielded.
    pub(super) last_emitted: Option<(Phase, u32)>,
    /// The slew fast path (see [`SCurve::next_slew`]) holds while
    /// `remaining > slew_floor`; `u32::MAX` turns it off.
    pub(super) slew_floor: u32,
    /// The delay of each fast slew step, 32.32 ticks.
    pub(super) slew_delay_q32: u64,
    /// The velocity reported for each fast slew step, steps/s.
    pub(super) slew_velocity: f64,
    /// Ramp cosines computed ahead, a block at a time.
    pub(super) cosines: CosineBlock,
    /// Ramp steps computed ahead (see [`SCurve::arm_ramp`]).
    pub(super) run: RampRun,
    /// A controlled stop is under way: no step may be faster than the one
    /// before it (P2Exact's deceleration angles sit one step above the
    /// mirror of its acceleration's, and its integer velocity can round up
    /// by one; see [`SCurve::stop`]).
    pub(super) stopping: bool,
}

/// A field at a time, into place: a board hands a curve (about 1.1 KiB with
/// its runs) to another core and back, and a derived `clone_from` would
/// build the copy on the stack first (on the M0+ each copy costs about a
/// thousand cycles).
impl Clone for SCurve {
    fn clone(&self) -> Self {
        Self {
            config: self.config,
            plan: self.plan,
            ramp: self.ramp,
            pending_ramp: self.pending_ramp,
            index: self.index,
            remaining: self.remaining,
            position: self.position,
            carry: self.carry,
            last_ramp: self.last_ramp,
            slew_q32: self.slew_q32,
            velocity: self.velocity,
            last_delay_q32: self.last_delay_q32,
            last_emitted: self.last_emitted,
            slew_floor: self.slew_floor,
            slew_delay_q32: self.slew_delay_q32,
            slew_velocity: self.slew_velocity,
            cosines: self.cosines,
            run: self.run,
            stopping: self.stopping,
        }
    }

    fn clone_from(&mut self, source: &Self) {
        // Every field named: a new one does not compile until copied.
        let SCurve {
            config,
            plan,
            ramp,
            pending_ramp,
            index,
            remaining,
            position,
            carry,
            last_ramp,
            slew_q32,
            velocity,
            last_delay_q32,
            last_emitted,
            slew_floor,
            slew_delay_q32,
            slew_velocity,
            cosines,
            run,
            stopping,
        } = self;
        *config = source.config;
        *plan = source.plan;
        *ramp = source.ramp;
        *pending_ramp = source.pending_ramp;
        *index = source.index;
        *remaining = source.remaining;
        *position = source.position;
        *carry = source.carry;
        *last_ramp = source.last_ramp;
        *slew_q32 = source.slew_q32;
        *velocity = source.velocity;
        *last_delay_q32 = source.last_delay_q32;
        *last_emitted = source.last_emitted;
        *slew_floor = source.slew_floor;
        *slew_delay_q32 = source.slew_delay_q32;
        *slew_velocity = source.slew_velocity;
        *cosines = source.cosines;
        *run = source.run;
        *stopping = source.stopping;
    }
}

impl SCurve {
    /// Whether two curves are in the same state but for the contents of
    /// their arrays (a run's entries, a block's cosines): every other
    /// field, the run's and the block's own included, `f64`s bit for bit.
    /// Two curves that pass are the same curve: the arrays' live entries
    /// are what arming a run and filling a block computed from those
    /// fields, by the same code (and nothing reads an entry past a run's
    /// or a block's length). About 40 words, where `==` also compares the
    /// arrays' 900 bytes: a board's core compares a curve each ramp run it
    /// takes from the other ([`SCurve::adopt_run_ahead`]).
    pub(super) fn same_but_arrays(&self, other: &SCurve) -> bool {
        // Every field named: a new one does not compile until compared.
        let SCurve {
            config,
            plan,
            ramp,
            pending_ramp,
            index,
            remaining,
            position,
            carry,
            last_ramp,
            slew_q32,
            velocity,
            last_delay_q32,
            last_emitted,
            slew_floor,
            slew_delay_q32,
            slew_velocity,
            cosines,
            run,
            stopping,
        } = self;
        *index == other.index
            && *remaining == other.remaining
            && run.same_but_arrays(&other.run)
            && *position == other.position
            && *carry == other.carry
            && *last_delay_q32 == other.last_delay_q32
            && *last_emitted == other.last_emitted
            && velocity.to_bits() == other.velocity.to_bits()
            && *config == other.config
            && *plan == other.plan
            && *ramp == other.ramp
            && *pending_ramp == other.pending_ramp
            && *last_ramp == other.last_ramp
            && *slew_q32 == other.slew_q32
            && *slew_floor == other.slew_floor
            && *slew_delay_q32 == other.slew_delay_q32
            && slew_velocity.to_bits() == other.slew_velocity.to_bits()
            && cosines.same_but_arrays(&other.cosines)
            && *stopping == other.stopping
    }

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

    /// Whether the next step comes from what the curve has computed ahead
    /// (an entry of a ramp's run, or a slew step): no arithmetic of its
    /// own. Otherwise the next step computes a run (and maybe a block of
    /// cosines), the costly path on a microcontroller.
    pub fn next_is_precomputed(&self) -> bool {
        self.run.next < self.run.len || self.remaining > self.slew_floor
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

    /// Any step: re-planning, ramps, the first slew step.
    #[inline(never)]
    pub(super) fn next_general(&mut self) -> Option<Step> {
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
            self.arm_ramp_up_to(FIRST_RUN_STEPS);
        }
        Some(step)
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

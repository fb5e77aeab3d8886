//! The driver's `move()` planning, and which moves the reference botches
//! ([`check_demo_move`], [`is_botched`]).

/// The demo's system clock (`CLK_FREQ`), Hz.
pub const DEMO_CLKFREQ: u32 = 200_000_000;
/// The offset `move()` writes, degrees.
pub const DEMO_OFFSET_DEG: i32 = 40;

/// The longs the driver's Spin `move(sp, st)` leaves for the cog and the
/// screen, in the driver's own 32-bit arithmetic.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DemoPlan {
    /// The speed the cog gets (`spd`): the one asked, or `10·(asteps − 2)`
    /// for a move with no steps at speed (−10 for 2 steps, 0 for 4).
    pub speed: i32,
    /// The signed steps (`stm`); 0 is never taken by the cog.
    pub steps: i32,
    /// `asteps`: `sp/10 + 2`, at most `|st|/2`.
    pub accel_steps: i32,
    /// `ss`: `|st| − 2·asteps`.
    pub slew_steps: i32,
    /// `offset`: always 40.
    pub offset_deg: i32,
}

/// The driver's `move(sp, st)` planning, as its Spin code computes it
/// (signed longs, wrapping, division towards zero).
pub fn demo_move(speed: i32, steps: i32) -> DemoPlan {
    let mut accel_steps = (speed / 10).wrapping_add(2);
    let half = (steps / 2).wrapping_abs();
    if accel_steps > half {
        accel_steps = half;
    }
    let slew_steps = steps
        .wrapping_abs()
        .wrapping_sub(accel_steps.wrapping_mul(2));
    let speed = if slew_steps == 0 {
        accel_steps.wrapping_sub(2).wrapping_mul(10)
    } else {
        speed
    };
    DemoPlan {
        speed,
        steps,
        accel_steps,
        slew_steps,
        offset_deg: DEMO_OFFSET_DEG,
    }
}

/// The clocks the reference cog needs, from the end of a step pulse, to
/// compute the next ramp delay (`_getdelay`) and set its timer: four
/// CORDIC commands and a QDIV, each a hub-slot wait (up to 7 clocks) plus
/// the 55-clock pipeline, and about twenty 2-clock instructions. A delay
/// shorter than this sets a timer target already passed, and WAITCT2
/// then waits for the 32-bit counter to come round again (2^32 clocks,
/// 21.5 s at 200 MHz). An upper estimate: it makes the speed limit below
/// conservative.
pub const GETDELAY_TICKS: u32 = 5 * (7 + 55) + 20 * 2;

/// The highest speed the host gives a P2 demo board: above it the
/// shortest delay (`clkfreq / speed` at the top of the ramp) could be
/// shorter than [`GETDELAY_TICKS`] at the demo's 200 MHz.
pub const DEMO_SPEED_MAX: u32 = DEMO_CLKFREQ / GETDELAY_TICKS;

/// A move the reference driver botches; [`check_demo_move`] finds them.
/// The reasons come from the driver's planning (`move()`) and its cog.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, thiserror::Error)]
pub enum DemoFlaw {
    /// The demo reads numbers into a signed 32-bit long.
    #[error(
        "the P2 demo reads a 32-bit signed number: a speed of {speed} would wrap \
         (at most {DEMO_SPEED_MAX} steps/s)"
    )]
    SpeedUnreadable {
        /// The speed asked, steps/s.
        speed: u32,
    },
    /// `abs(-2147483648)` overflows in the planner.
    #[error("the P2 demo's planner cannot take -2147483648 steps (its abs() overflows)")]
    StepsUnreadable,
    /// `stom = 0`: the first delay divides by zero, and a stop-pin stop
    /// wraps the step count to about 4 billion.
    #[error(
        "the reference cog divides by zero on a 1-step move (stom = 0), and a stop-pin stop \
         during it wraps the step count to about 4 billion steps"
    )]
    OneStep,
    /// The planner gives a 2-step move the speed −10.
    #[error(
        "the reference planner gives a 2-step move the speed -10: its first delay is 0, \
         a timer target already passed, and the cog stalls 21.5 s for its counter to wrap"
    )]
    TwoSteps,
    /// The planner gives a 4-step move the speed 0.
    #[error(
        "the reference planner gives a 4-step move the speed 0: every step waits the \
         0.475 s delay ceiling"
    )]
    FourSteps,
    /// An odd move too short to reach its speed keeps it anyway.
    #[error(
        "the reference planner keeps the full speed of {speed} steps/s for an odd short \
         move of {steps} steps: it ramps over {accel_steps} steps only and stops from full speed"
    )]
    OddShortFullSpeed {
        /// |steps|.
        steps: u32,
        /// The speed asked, steps/s.
        speed: u32,
        /// The accel (and decel) steps it gets.
        accel_steps: u32,
    },
    /// Delays shorter than the cog needs to compute them.
    #[error(
        "{speed} steps/s: the reference cog's delays would be shorter than the clocks it \
         needs to compute them, and it would stall 21.5 s per counter wrap \
         (at most {DEMO_SPEED_MAX} steps/s)"
    )]
    SpeedTooHigh {
        /// The speed asked, steps/s.
        speed: u32,
    },
}

impl DemoFlaw {
    /// The reason in a few words, for a `&'static str` error.
    pub fn reason(&self) -> &'static str {
        match self {
            DemoFlaw::SpeedUnreadable { .. } => {
                "the P2 demo reads speeds as 32-bit signed numbers: this one would wrap"
            }
            DemoFlaw::StepsUnreadable => "the P2 demo's planner overflows on -2147483648 steps",
            DemoFlaw::OneStep => "the P2 demo board divides by zero on a 1-step move",
            DemoFlaw::TwoSteps => {
                "the P2 demo board plans a 2-step move at speed -10 and stalls 21.5 s"
            }
            DemoFlaw::FourSteps => {
                "the P2 demo board plans a 4-step move at speed 0 (0.475 s per step)"
            }
            DemoFlaw::OddShortFullSpeed { .. } => {
                "the P2 demo board keeps full speed on an odd move too short to reach it"
            }
            DemoFlaw::SpeedTooHigh { .. } => {
                "the P2 demo board's cog cannot compute its delays at this speed"
            }
        }
    }
}

/// Whether the stock demo and driver would carry out `move(speed, steps)`
/// sanely; `Ok` gives its plan. Speed and steps as a host sends them
/// (speed ≥ 1, steps ≠ 0; 0 is for the caller to refuse as it likes).
///
/// The botched set, from `move()` and the cog: a speed that does not fit
/// the demo's signed long or whose delays the cog cannot compute in time
/// ([`DEMO_SPEED_MAX`]); −2^31 steps; |steps| = 1 (`stom = 0`), 2 (speed
/// −10) and 4 (speed 0); and every odd |steps| whose accel steps were
/// capped at |steps|/2 (one step at speed is left, so the speed is never
/// lowered): whenever `speed/10 + 2 > |steps|/2`, so 3 steps always, 5
/// steps from 10 steps/s, 7 steps from 20 steps/s, and so on.
pub fn check_demo_move(speed: u32, steps: i32) -> Result<DemoPlan, DemoFlaw> {
    let Ok(signed_speed) = i32::try_from(speed) else {
        return Err(DemoFlaw::SpeedUnreadable { speed });
    };
    if speed > DEMO_SPEED_MAX {
        return Err(DemoFlaw::SpeedTooHigh { speed });
    }
    if steps == i32::MIN {
        return Err(DemoFlaw::StepsUnreadable);
    }
    let plan = demo_move(signed_speed, steps);
    if let Some(flaw) = plan_flaw(&plan, speed) {
        return Err(flaw);
    }
    Ok(plan)
}

/// The planning flaws of a plan made from `speed` (see [`check_demo_move`]).
fn plan_flaw(plan: &DemoPlan, speed: u32) -> Option<DemoFlaw> {
    let magnitude = plan.steps.unsigned_abs();
    match magnitude {
        1 => return Some(DemoFlaw::OneStep),
        2 => return Some(DemoFlaw::TwoSteps),
        4 => return Some(DemoFlaw::FourSteps),
        _ => {}
    }
    let capped = i64::from(speed) / 10 + 2 > i64::from(magnitude / 2);
    if magnitude % 2 == 1 && capped {
        return Some(DemoFlaw::OddShortFullSpeed {
            steps: magnitude,
            speed,
            accel_steps: plan.accel_steps.unsigned_abs(),
        });
    }
    None
}

/// Whether a plan, as `move()` made it from any answer, is one the
/// reference botches: what a simulated board must run as the real cog
/// would, rather than on cogstep's hub, which fixes those flaws.
pub fn is_botched(plan: &DemoPlan) -> bool {
    if plan.steps == 0 {
        return false;
    }
    match u32::try_from(plan.speed) {
        Ok(speed) if speed > 0 && speed <= DEMO_SPEED_MAX && plan.steps != i32::MIN => {
            plan_flaw(plan, speed).is_some()
        }
        _ => true,
    }
}

//! The reference cog (Step_driver2's PASM) for one command, as the P2 demo
//! gives it: the stop pin high, no command pending while it runs (the
//! demo reads nothing then), so no merge and no clobbered Max Velocity.
//!
//! The board simulator runs the moves the reference botches
//! ([`is_botched`](super::is_botched)) on this model, so that its
//! screens show what a real board shows; cogstep's hub, which fixes those
//! flaws, runs every other move. Instruction for instruction where it
//! matters to the screen: the planning of `_setup`, `_getdelay`'s integer
//! angle, QROTATE and QDIV (cordic-core), the mode bits, `vel` written at
//! `_mlp5`, and the running timer target of `_dostep1`/`_ws2`, including a
//! target already passed, which waits for the 32-bit counter to come
//! round (2^32 clocks).

use super::{DemoPlan, GETDELAY_TICKS};
use cogstep_motion::profile::scurve::P2_STEP_OVERHEAD_TICKS;

/// The step pulse, clocks (`delayh`).
const PULSE_TICKS: u64 = 1_000;
/// `maxdelay`.
const MAX_DELAY: i32 = 95_000_000;
/// `mult`: 93,206 · 128 · 360 ≈ 2^32.
const ANGLE_MULT: u32 = 93_206;
/// From the end of the pulse to ADDCT2 on a step at speed (`drvl`,
/// `testb`, `sub`, `jmp`): a delay shorter than this is a passed target.
const SLEW_PATH_TICKS: u64 = 10;
/// From WAITCT2 waking to the next rising edge: the hub's P2Exact figure.
const RESUME_TICKS: u64 = P2_STEP_OVERHEAD_TICKS as u64;
/// One turn of the system counter.
const COUNTER_TURN: u64 = 1 << 32;

/// Mode bits.
const MOVING: u32 = 0b1;
const ACCEL: u32 = 0b10;
const DECEL: u32 = 0b100;
const AT_SPEED: u32 = 0b1000;
const REVERSE: u32 = 0b1_0000;
const DECEL_TO_STOP: u32 = 0b10_0000;

/// One command on the reference cog.
#[derive(Clone, Debug)]
pub struct ReferenceCog {
    clkfreq: u32,
    position: i32,
    mode: u32,
    steps: u32,
    xsteps: u32,
    stepn: u32,
    stom: u32,
    astps: u32,
    halfsp: u32,
    newmin: u32,
    newrange: u32,
    delay: u32,
    /// `t2`: the velocity `_getdelay` last computed.
    velocity: u32,
    max_velocity: Option<i32>,
    /// When the next `_dostep` runs, clocks since the command was taken.
    next_step_at: u64,
    done: bool,
}

impl ReferenceCog {
    /// The cog takes `plan` with the position long at `position` (the
    /// stop pin is high, so its first step is at once).
    pub fn start(position: i32, plan: &DemoPlan, clkfreq: u32) -> Self {
        let steps = plan.steps.unsigned_abs();
        let mode = if plan.steps < 0 { REVERSE } else { 0 };
        // Longs read as the cog's unsigned registers.
        let astps = plan.accel_steps as u32;
        let angoff = plan.offset_deg as u32;
        let mut cog = ReferenceCog {
            clkfreq,
            position,
            mode: mode | MOVING | ACCEL,
            steps,
            xsteps: 0,
            stepn: 0,
            stom: steps,
            astps,
            halfsp: (plan.speed as u32) >> 1,
            newmin: angoff << 7,
            newrange: 360u32.wrapping_sub(angoff).wrapping_sub(angoff),
            delay: 1,
            velocity: 0,
            max_velocity: None,
            next_step_at: 0,
            done: false,
        };
        let t3 = astps << 1;
        if t3 < cog.stom {
            cog.xsteps = steps.wrapping_sub(t3);
            cog.stom = t3;
        }
        cog
    }

    /// What the cog writes to `vel` when the move of `plan` starts to
    /// decelerate: the velocity `_getdelay` computed for the last
    /// acceleration step (steps at speed compute none). `None` for a move
    /// that never decelerates (no acceleration steps).
    pub fn max_velocity_of(plan: &DemoPlan, clkfreq: u32) -> Option<i32> {
        let mut cog = ReferenceCog::start(0, plan, clkfreq);
        if cog.astps == 0 {
            return None;
        }
        cog.stepn = cog.astps - 1;
        cog.get_delay();
        Some(cog.velocity as i32)
    }

    /// Runs the cog up to `ticks` clocks after it took the command.
    pub fn run_until(&mut self, ticks: u64) {
        while !self.done && self.next_step_at <= ticks {
            self.step();
        }
    }

    /// The position long.
    pub fn position(&self) -> i32 {
        self.position
    }

    /// The mode long.
    pub fn mode(&self) -> u32 {
        self.mode
    }

    /// What the cog wrote to `vel`, if it started to decelerate.
    pub fn max_velocity(&self) -> Option<i32> {
        self.max_velocity
    }

    /// Whether the command has ended (mode bit 0 clear).
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// When the next step runs, clocks after the command was taken.
    #[cfg(test)]
    pub fn next_step_at(&self) -> u64 {
        self.next_step_at
    }

    /// `_dostep`, then the main loop up to the next `_waitstep`.
    fn step(&mut self) {
        if self.steps == 0 {
            self.mode &= DECEL_TO_STOP;
            self.done = true;
            return;
        }
        let edge = self.next_step_at;
        self.position = if self.mode & REVERSE != 0 {
            self.position.wrapping_sub(1)
        } else {
            self.position.wrapping_add(1)
        };
        let at_speed = self.mode & AT_SPEED != 0;
        let path = if at_speed {
            self.xsteps = self.xsteps.wrapping_sub(1);
            SLEW_PATH_TICKS
        } else {
            self.get_delay();
            u64::from(GETDELAY_TICKS)
        };
        let mut target = edge + PULSE_TICKS + u64::from(self.delay);
        if u64::from(self.delay) < path {
            target += COUNTER_TURN;
        }
        self.steps = self.steps.wrapping_sub(1);
        if !at_speed {
            self.stepn = self.stepn.wrapping_add(1);
        }
        if self.astps == self.stepn {
            self.mode &= !(ACCEL | DECEL | AT_SPEED);
            if self.xsteps == 0 {
                self.mode |= DECEL;
                self.max_velocity = Some(self.velocity as i32);
            } else {
                self.mode |= AT_SPEED;
            }
        }
        self.next_step_at = target + RESUME_TICKS;
    }

    /// `_getdelay`.
    fn get_delay(&mut self) {
        let (scaled, _) = cordic_core::qmul(self.stepn, self.newrange);
        let (fraction, _) = cordic_core::qdiv(u64::from(scaled << 7), self.stom);
        let angle_deg128 = fraction.wrapping_add(self.newmin);
        let (angle, _) = cordic_core::qmul(angle_deg128, ANGLE_MULT);
        let (x, _) = cordic_core::qrotate(self.halfsp as i32, 0, angle);
        // `fges t2, #1`: a signed maximum.
        let velocity = (self.halfsp.wrapping_sub(x as u32) as i32).max(1) as u32;
        self.velocity = velocity;
        let (quotient, _) = cordic_core::qdiv(u64::from(self.clkfreq), velocity);
        // `fles delay, maxdelay`: a signed minimum.
        self.delay = (quotient as i32).min(MAX_DELAY) as u32;
    }
}

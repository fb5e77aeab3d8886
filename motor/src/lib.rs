//! # cogstep-motor — a virtual motor: the rotor behind the pins (`no_std`, no allocation)
//!
//! A profile says when each step edge comes; this module says what a real
//! stepper's rotor does with those edges. The rotor is an inertia on a
//! magnetic spring, driven by full steps:
//!
//! ```text
//! J·θ'' = T_h(r)·sin(N·(θ_cmd − θ)) − B·θ' − T_load·sign(θ')
//! ```
//!
//! - `θ_cmd` (rad, mechanical): the commanded position; it moves one full
//!   step at each step edge ([`Rotor::step`]; [`StepDecoder`] turns `sd` or
//!   `cc` pin edges into those steps);
//! - `θ`, `θ'`: the rotor's angle and speed;
//! - `J`: rotor plus load inertia, kg·m²;
//! - `N`: the electrical-to-mechanical factor, `180° / (phases × step
//!   angle)`: 50 for a 2-phase 1.8° hybrid (its 50 rotor teeth), and 50 for
//!   a 5-phase 0.72° one; a full step is `180°/phases` electrical;
//! - `T_h(r)`: the torque's amplitude, N·m: the motor's pull-out curve at
//!   the step rate `r` the drive is commutating at ([`PullOutCurve`]), and
//!   the holding torque at standstill. The rate is taken from the edges
//!   themselves: `1 / max(last interval, time since the last edge)`, so
//!   it is known at every instant, falls to 0 once the edges stop, and is
//!   the same whether the edges come from a profile or from pins;
//! - `B`: viscous damping, N·m·s/rad; `T_load`: Coulomb friction, N·m,
//!   which holds a resting rotor until the magnetic torque exceeds it
//!   (stiction), so a rotor comes to rest within a dead band of
//!   `asin(T_load / T_h) / N` of the command.
//!
//! # Integration
//!
//! Velocity Verlet (kick–drift–kick: symplectic, second order for the
//! magnetic spring, one `sin` per substep) with the command held constant
//! between edges. The substep is fixed within each interval between two
//! edges: at most 1/64 of the natural period, and short enough that the
//! rotor turns at most 0.25 electrical radians per substep. A 100,000-step
//! move takes a few tens of milliseconds (release build; see
//! `examples/rotor.rs`).
//!
//! # Loss of synchronism
//!
//! The criterion: the rotor is lost once the electrical angle between the
//! field and the rotor, `N·(θ_cmd − θ)`, passes ±π (half an electrical
//! cycle: `phases` full steps, two on a 2-phase motor). That is the point of
//! no return: beyond it `sin` changes sign, the torque pushes the rotor
//! away from the command, and the nearest stable position is a whole
//! electrical cycle (four full steps on a 2-phase motor) off: the position
//! is lost for good, so the state is latched. It is checked at every
//! substep and at every edge (an edge that puts the field more than half a
//! cycle ahead has already lost the rotor). A rotor that crosses the line
//! with speed to spare could in principle swing back; the criterion does not
//! wait to see, which makes it the cautious side.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod decode;
mod rotor;

#[cfg(test)]
mod tests;

pub use decode::{StepDecoder, StepLine};
pub use rotor::{Rotor, RotorSample};

use core::f64::consts::PI;

/// Why a motor description is refused.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum MotorError {
    /// The full-step angle must be a positive, finite number of degrees.
    #[error("the step angle must be a positive number of degrees, got {0}")]
    BadStepAngle(f64),
    /// 2 to 10 phases.
    #[error("a stepper has 2 to 10 phases, got {0}")]
    BadPhases(u8),
    /// Inertia must be positive and finite.
    #[error("the total inertia must be a positive number of kg·m², got {0}")]
    BadInertia(f64),
    /// Damping must be ≥ 0 and finite.
    #[error("damping must be a number of N·m·s/rad ≥ 0, got {0}")]
    BadDamping(f64),
    /// Load torque must be ≥ 0 and finite.
    #[error("the load torque must be a number of N·m ≥ 0, got {0}")]
    BadLoadTorque(f64),
    /// Holding torque must be positive and finite.
    #[error("the holding torque must be a positive number of N·m, got {0}")]
    BadHoldingTorque(f64),
    /// The rotor rings faster than any real stepper (check the inertia): the
    /// integrator would need millions of substeps per second of motion.
    #[error(
        "the rotor's natural frequency would be {0:.0} Hz, beyond {MAX_NATURAL_FREQUENCY_HZ} Hz: check the inertia and torque"
    )]
    TooStiff(f64),
}

/// The highest natural frequency a motor may have, Hz (real steppers ring
/// at tens to a few thousand Hz).
pub const MAX_NATURAL_FREQUENCY_HZ: f64 = 100_000.0;

/// What the rotor model needs to know about a motor and its load.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorParams {
    /// Full-step angle, rad (mechanical).
    pub step_angle_rad: f64,
    /// Phases: 2 for the common hybrid, 5 for a 5-phase motor.
    pub phases: u8,
    /// Rotor plus load inertia, kg·m².
    pub inertia_kgm2: f64,
    /// Viscous damping, N·m·s/rad.
    pub damping_nm_s_per_rad: f64,
    /// Coulomb friction of the load, N·m (opposes motion; holds at rest).
    pub load_torque_nm: f64,
    /// Torque amplitude at standstill, N·m.
    pub holding_torque_nm: f64,
}

impl MotorParams {
    /// Checks every figure.
    pub fn new(
        step_angle_deg: f64,
        phases: u8,
        inertia_kgm2: f64,
        damping_nm_s_per_rad: f64,
        load_torque_nm: f64,
        holding_torque_nm: f64,
    ) -> Result<Self, MotorError> {
        if !(step_angle_deg.is_finite() && step_angle_deg > 0.0 && step_angle_deg < 180.0) {
            return Err(MotorError::BadStepAngle(step_angle_deg));
        }
        if !(2..=10).contains(&phases) {
            return Err(MotorError::BadPhases(phases));
        }
        if !(inertia_kgm2.is_finite() && inertia_kgm2 > 0.0) {
            return Err(MotorError::BadInertia(inertia_kgm2));
        }
        if !(damping_nm_s_per_rad.is_finite() && damping_nm_s_per_rad >= 0.0) {
            return Err(MotorError::BadDamping(damping_nm_s_per_rad));
        }
        if !(load_torque_nm.is_finite() && load_torque_nm >= 0.0) {
            return Err(MotorError::BadLoadTorque(load_torque_nm));
        }
        if !(holding_torque_nm.is_finite() && holding_torque_nm > 0.0) {
            return Err(MotorError::BadHoldingTorque(holding_torque_nm));
        }
        let params = Self {
            step_angle_rad: step_angle_deg * (PI / 180.0),
            phases,
            inertia_kgm2,
            damping_nm_s_per_rad,
            load_torque_nm,
            holding_torque_nm,
        };
        let natural_hz = params.natural_frequency_hz();
        if natural_hz.is_nan() || natural_hz > MAX_NATURAL_FREQUENCY_HZ {
            return Err(MotorError::TooStiff(natural_hz));
        }
        Ok(params)
    }

    /// `N`: electrical radians per mechanical radian, `π / (phases × step)`.
    pub fn electrical_factor(&self) -> f64 {
        PI / (f64::from(self.phases) * self.step_angle_rad)
    }

    /// Small-oscillation natural frequency at standstill, Hz:
    /// `(1/2π)·sqrt(N·T_h/J)`.
    pub fn natural_frequency_hz(&self) -> f64 {
        libm::sqrt(self.electrical_factor() * self.holding_torque_nm / self.inertia_kgm2)
            / (2.0 * PI)
    }

    /// Damping ratio of the small oscillation at standstill (friction aside):
    /// `B / (2·sqrt(N·T_h·J))`.
    pub fn damping_ratio(&self) -> f64 {
        self.damping_nm_s_per_rad
            / (2.0
                * libm::sqrt(self.electrical_factor() * self.holding_torque_nm * self.inertia_kgm2))
    }

    /// The lag, in full steps, at which synchronism is lost: half an
    /// electrical cycle, `phases` steps.
    pub fn sync_limit_steps(&self) -> f64 {
        f64::from(self.phases)
    }

    /// The same motor with every torque divided by `factor` (> 0): the
    /// safety factor's derating.
    pub fn derated(&self, factor: f64) -> Self {
        Self {
            holding_torque_nm: self.holding_torque_nm / factor,
            ..*self
        }
    }
}

/// The torque amplitude a drive gets out of the motor at a step rate: the
/// pull-out torque–speed curve.
pub trait PullOutCurve {
    /// Torque amplitude, N·m (≥ 0), at `rate_steps_per_s` (≥ 0).
    fn pull_out_nm(&self, rate_steps_per_s: f64) -> f64;
}

/// A curve given as points `(steps/s, N·m)`, speeds increasing: linear in
/// between, the first torque below the first point, the last segment's line
/// beyond the last point (never below 0), scaled by `scale`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TorquePoints<'a> {
    points: &'a [(f64, f64)],
    scale: f64,
}

impl<'a> TorquePoints<'a> {
    /// The curve through `points` (at least one; speeds strictly
    /// increasing, torques ≥ 0: the caller checks, as the motor file does).
    pub fn new(points: &'a [(f64, f64)]) -> Self {
        Self { points, scale: 1.0 }
    }

    /// The same curve with every torque divided by `factor` (> 0).
    pub fn derated(self, factor: f64) -> Self {
        Self {
            scale: self.scale / factor,
            ..self
        }
    }
}

impl PullOutCurve for TorquePoints<'_> {
    fn pull_out_nm(&self, rate_steps_per_s: f64) -> f64 {
        let rate = rate_steps_per_s.abs();
        let torque = match self.points {
            [] => 0.0,
            [(_, only)] => *only,
            [(first_speed, first), ..] if rate <= *first_speed => *first,
            points => {
                let index = points
                    .windows(2)
                    .position(|pair| rate <= pair[1].0)
                    .unwrap_or(points.len() - 2);
                let ((low_speed, low), (high_speed, high)) = (points[index], points[index + 1]);
                low + (rate - low_speed) / (high_speed - low_speed) * (high - low)
            }
        };
        torque.max(0.0) * self.scale
    }
}

/// The same torque at every rate (a motor described by its holding torque
/// only, and the physics tests).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConstantTorque(pub f64);

impl PullOutCurve for ConstantTorque {
    fn pull_out_nm(&self, _rate_steps_per_s: f64) -> f64 {
        self.0
    }
}

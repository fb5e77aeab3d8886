//! The rotor's state and its integrator (see the module docs for the model).

use core::f64::consts::PI;

use super::{MotorParams, PullOutCurve};

/// Substeps per natural period, at least.
const SUBSTEPS_PER_PERIOD: f64 = 64.0;
/// Electrical radians the rotor may turn in one substep, at most.
const MAX_PHASE_PER_SUBSTEP: f64 = 0.25;
/// The longest a settle runs, s, however little the rotor is damped.
const MAX_SETTLE_S: f64 = 10.0;

/// The rotor at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RotorSample {
    /// Rotor angle, degrees (mechanical, from where it started).
    pub angle_deg: f64,
    /// Rotor speed, steps/s (signed).
    pub velocity_steps_per_s: f64,
    /// Command minus rotor, full steps (signed: positive when the rotor is
    /// behind a forward command).
    pub error_steps: f64,
    /// Whether synchronism has held so far.
    pub synchronous: bool,
}

/// One motor's rotor, driven by step edges.
///
/// Time only moves through [`Rotor::run_for`] / [`Rotor::run_until`]; a step
/// edge ([`Rotor::step`]) happens at the current time. Nothing allocates.
#[derive(Clone, Debug)]
pub struct Rotor<C> {
    params: MotorParams,
    curve: C,
    /// `N`.
    electrical: f64,
    /// Substep bound from the natural period, s.
    max_substep_s: f64,
    /// Angle, rad.
    theta_rad: f64,
    /// Speed, rad/s.
    omega_rad_s: f64,
    /// The command, full steps from the start.
    command_steps: i64,
    /// Time since the start, s.
    time_s: f64,
    /// When the last edge came.
    last_edge_s: Option<f64>,
    /// The interval between the last two edges, s.
    last_interval_s: f64,
    /// Edges seen.
    steps_seen: u64,
    /// The edge (index from 0) in whose interval synchronism was lost.
    lost_at_step: Option<u64>,
}

impl<C: PullOutCurve> Rotor<C> {
    /// A rotor at rest, aligned with the command, at time 0.
    pub fn new(params: MotorParams, curve: C) -> Self {
        // Stiffest the spring gets: the larger of the holding torque and the
        // curve's low-speed torque.
        let peak_torque = params.holding_torque_nm.max(curve.pull_out_nm(0.0));
        let natural_rad_s =
            libm::sqrt(params.electrical_factor() * peak_torque / params.inertia_kgm2);
        Self {
            params,
            curve,
            electrical: params.electrical_factor(),
            max_substep_s: 2.0 * PI / natural_rad_s.max(f64::MIN_POSITIVE) / SUBSTEPS_PER_PERIOD,
            theta_rad: 0.0,
            omega_rad_s: 0.0,
            command_steps: 0,
            time_s: 0.0,
            last_edge_s: None,
            last_interval_s: f64::INFINITY,
            steps_seen: 0,
            lost_at_step: None,
        }
    }

    /// The motor.
    pub fn params(&self) -> &MotorParams {
        &self.params
    }

    /// A step edge now: the command moves one full step, forward or back.
    pub fn step(&mut self, forward: bool) {
        if let Some(last) = self.last_edge_s {
            self.last_interval_s = self.time_s - last;
        }
        self.last_edge_s = Some(self.time_s);
        self.command_steps += if forward { 1 } else { -1 };
        self.steps_seen += 1;
        self.check_synchronism();
    }

    /// Lets `duration_s` seconds pass with the command where it is
    /// (nothing happens for a duration that is not positive and finite).
    pub fn run_for(&mut self, duration_s: f64) {
        if !(duration_s.is_finite() && duration_s > 0.0) {
            return;
        }
        // In step with the field the rotor turns about one step per interval.
        let step_speed = if self.last_interval_s.is_finite() && self.last_interval_s > 0.0 {
            self.params.step_angle_rad / self.last_interval_s
        } else {
            0.0
        };
        let speed = self.omega_rad_s.abs().max(step_speed);
        let by_phase = MAX_PHASE_PER_SUBSTEP / (self.electrical * speed).max(f64::MIN_POSITIVE);
        let bound = self.max_substep_s.min(by_phase);
        let substeps = libm::ceil(duration_s / bound).max(1.0);
        let dt = duration_s / substeps;
        let end_s = self.time_s + duration_s;
        let command_rad = self.command_steps as f64 * self.params.step_angle_rad;
        let mut amplitude = self.amplitude_nm();
        let mut magnetic = amplitude * libm::sin(self.electrical * (command_rad - self.theta_rad));
        // Whole substeps; the count is an f64 bounded by duration/bound.
        let mut left = substeps;
        while left > 0.0 {
            left -= 1.0;
            self.kick(magnetic, dt / 2.0);
            self.theta_rad += self.omega_rad_s * dt;
            self.time_s += dt;
            if self.standstill_rate() {
                amplitude = self.amplitude_nm();
            }
            magnetic = amplitude * libm::sin(self.electrical * (command_rad - self.theta_rad));
            self.kick(magnetic, dt / 2.0);
            self.check_synchronism();
        }
        self.time_s = end_s;
    }

    /// Runs until `time_s` (nothing happens if that is not later than now).
    pub fn run_until(&mut self, time_s: f64) {
        self.run_for(time_s - self.time_s);
    }

    /// Runs with the command still until the rotor rests (held by friction)
    /// or rings no more than `1e-4` of a step, for at most 10 s; returns the
    /// time it took, s.
    pub fn settle(&mut self) -> f64 {
        let started = self.time_s;
        let chunk = self.max_substep_s * SUBSTEPS_PER_PERIOD / 4.0;
        let mut quiet_chunks = 0;
        while self.time_s - started < MAX_SETTLE_S {
            let before = self.error_steps();
            self.run_for(chunk);
            let moved = (self.error_steps() - before).abs();
            let resting = self.omega_rad_s == 0.0;
            quiet_chunks = if resting || moved < 1e-4 {
                quiet_chunks + 1
            } else {
                0
            };
            // Four quarter-periods in a row: a whole period without motion.
            if quiet_chunks >= 4 {
                break;
            }
        }
        self.time_s - started
    }

    /// The rotor now.
    pub fn sample(&self) -> RotorSample {
        RotorSample {
            angle_deg: self.theta_rad * (180.0 / PI),
            velocity_steps_per_s: self.omega_rad_s / self.params.step_angle_rad,
            error_steps: self.error_steps(),
            synchronous: self.lost_at_step.is_none(),
        }
    }

    /// Command minus rotor, full steps.
    pub fn error_steps(&self) -> f64 {
        self.command_steps as f64 - self.theta_rad / self.params.step_angle_rad
    }

    /// The commanded position, full steps.
    pub fn command_steps(&self) -> i64 {
        self.command_steps
    }

    /// Step edges seen.
    pub fn steps_seen(&self) -> u64 {
        self.steps_seen
    }

    /// The index (from 0) of the step edge in whose interval synchronism
    /// was lost, if it was.
    pub fn lost_at_step(&self) -> Option<u64> {
        self.lost_at_step
    }

    /// Time since the start, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// The step rate the drive commutates at now, steps/s.
    pub fn step_rate(&self) -> f64 {
        match self.last_edge_s {
            None => 0.0,
            Some(last) => {
                let interval = self.last_interval_s.max(self.time_s - last);
                if interval.is_finite() && interval > 0.0 {
                    1.0 / interval
                } else {
                    0.0
                }
            }
        }
    }

    /// Re-homes the rotor: the command moves to where the rotor is (to the
    /// nearest step), and synchronism counts as kept again.
    pub fn rehome(&mut self) {
        self.command_steps = libm::round(self.theta_rad / self.params.step_angle_rad) as i64;
        self.lost_at_step = None;
    }

    /// Whether the time since the last edge has outgrown the last interval
    /// (the rate then falls as time passes).
    fn standstill_rate(&self) -> bool {
        self.last_edge_s
            .is_some_and(|last| self.time_s - last > self.last_interval_s)
    }

    fn amplitude_nm(&self) -> f64 {
        let rate = self.step_rate();
        if rate == 0.0 {
            self.params.holding_torque_nm
        } else {
            self.curve.pull_out_nm(rate)
        }
    }

    /// Half a substep's change of speed under the magnetic torque, damping
    /// and friction; friction stops the rotor rather than reversing it.
    fn kick(&mut self, magnetic_nm: f64, dt: f64) {
        let params = &self.params;
        let omega = self.omega_rad_s;
        let friction = params.load_torque_nm;
        let inertia = params.inertia_kgm2;
        if omega == 0.0 {
            // At rest: friction holds up to its full value (stiction).
            if magnetic_nm.abs() <= friction {
                return;
            }
            let net = magnetic_nm - friction.copysign(magnetic_nm);
            self.omega_rad_s = net / inertia * dt;
            return;
        }
        let net = magnetic_nm - params.damping_nm_s_per_rad * omega - friction.copysign(omega);
        let next = omega + net / inertia * dt;
        // Crossing zero with a torque that friction can hold: it stops there.
        self.omega_rad_s = if next * omega < 0.0 && magnetic_nm.abs() <= friction {
            0.0
        } else {
            next
        };
    }

    fn check_synchronism(&mut self) {
        if self.lost_at_step.is_none() && (self.electrical * self.error_steps_rad()).abs() > PI {
            self.lost_at_step = Some(self.steps_seen.saturating_sub(1));
        }
    }

    fn error_steps_rad(&self) -> f64 {
        self.command_steps as f64 * self.params.step_angle_rad - self.theta_rad
    }
}

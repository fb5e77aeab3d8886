//! `--dynamics`: what the rotor does with the move (the rotor model of
//! [`driver::motor`], fed the table's rows).
//!
//! Row `n` is step `n`'s edge (the command moves one step, in the move's
//! direction) and then its period (`period_ticks`: rising edge to rising
//! edge); the rotor columns are the rotor at the end of that period, just
//! before the next edge:
//!
//! - `rotor_angle_deg`: the rotor's angle from where it started, degrees;
//! - `rotor_lag_steps`: how far the rotor is behind the command, full steps,
//!   positive when behind in the direction of the move (negative: ahead);
//! - `synchronous`: `false` from the step in whose interval the field got
//!   more than half an electrical cycle (`phases` full steps) ahead of or
//!   behind the rotor: the position is then lost for good (see
//!   [`driver::motor`] for the criterion and why).
//!
//! After the last row the rotor settles with the command at the target, and
//! the summary gives where it came to rest.

use driver::motor::{MotorParams, Rotor, TorquePoints};

use crate::error::ExportError;
use crate::motor::{Motor, DAMPING_RATIO_MAX};
use crate::table::Row;

/// The rotor columns of one row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DynamicsRow {
    /// Rotor angle, degrees (signed like the move).
    pub rotor_angle_deg: f64,
    /// Lag behind the command, full steps (positive: behind).
    pub rotor_lag_steps: f64,
    /// Whether synchronism has held up to the end of this row's interval.
    pub synchronous: bool,
    /// Rotor speed at the end of the interval, steps/s (signed; for plots).
    pub rotor_velocity_steps_per_s: f64,
}

/// What the rotor did over the whole move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DynamicsSummary {
    /// Small-oscillation natural frequency at standstill, Hz.
    pub natural_frequency_hz: f64,
    /// Damping ratio (viscous part), at standstill.
    pub damping_ratio: f64,
    /// The lag at which synchronism is lost, full steps.
    pub sync_limit_steps: f64,
    /// The step in whose interval synchronism was lost (the last step if it
    /// was lost while settling).
    pub lost_at_step: Option<u32>,
    /// The largest |lag| of the rows, full steps, signed, and its step.
    pub largest_lag: Option<(u32, f64)>,
    /// Command minus rotor once settled, full steps (signed like the lag).
    pub final_error_steps: f64,
    /// How long the rotor took to settle after the last step, s.
    pub settle_s: f64,
}

impl DynamicsSummary {
    /// Whether the rotor kept synchronism to the end.
    pub fn synchronous(&self) -> bool {
        self.lost_at_step.is_none()
    }

    /// The largest |lag|, full steps (0 for no rows).
    pub fn largest_lag_steps(&self) -> f64 {
        self.largest_lag.map_or(0.0, |(_, lag)| lag.abs())
    }

    /// One line for stderr.
    pub fn line(&self) -> String {
        let largest = match self.largest_lag {
            Some((step, lag)) => format!("largest lag {lag:.3} steps at step {step}"),
            None => "no steps".to_string(),
        };
        match self.lost_at_step {
            Some(step) => format!(
                "rotor LOST SYNCHRONISM at step {step} (lag beyond {} steps, half an electrical cycle): the motor loses its position; {largest}",
                self.sync_limit_steps
            ),
            None => format!(
                "rotor dynamics: synchronous; {largest}; at rest {:.3} steps from the target after {:.3} s (natural frequency {:.1} Hz)",
                self.final_error_steps, self.settle_s, self.natural_frequency_hz
            ),
        }
    }
}

/// The rotor following a move, row by row.
pub struct Dynamics<'m> {
    rotor: Rotor<TorquePoints<'m>>,
    /// The motor file (for messages).
    path: &'m std::path::Path,
    clkfreq: f64,
    forward: bool,
    largest_lag: Option<(u32, f64)>,
    params: MotorParams,
}

impl<'m> Dynamics<'m> {
    /// A rotor at rest for `motor`, following a move in `direction` (+1.0
    /// or −1.0) at `clkfreq` Hz, with every torque divided by `derate`
    /// (1.0: the motor as described; the safety factor for `--fastest`).
    pub fn new(
        motor: &'m Motor,
        clkfreq: u32,
        direction: f64,
        derate: f64,
    ) -> Result<Self, ExportError> {
        let params = motor.rotor_params()?.derated(derate);
        let ratio = params.damping_ratio();
        if ratio.is_nan() || ratio > DAMPING_RATIO_MAX {
            return Err(ExportError::Motor {
                path: motor.path.clone(),
                reason: format!(
                    "damping_nm_s_per_rad = {:?} gives a damping ratio of {ratio:.3e}; the rotor model follows at most {DAMPING_RATIO_MAX} (real motors are well below 1)",
                    params.damping_nm_s_per_rad
                ),
            });
        }
        let curve = motor.pull_out_curve().derated(derate);
        Ok(Self {
            rotor: Rotor::new(params, curve),
            path: &motor.path,
            clkfreq: f64::from(clkfreq.max(1)),
            forward: direction >= 0.0,
            largest_lag: None,
            params,
        })
    }

    fn sign(&self) -> f64 {
        if self.forward {
            1.0
        } else {
            -1.0
        }
    }

    /// The rotor through one row: the step's edge, then its period; an
    /// error if the model's figures stop being finite numbers.
    pub fn row(&mut self, row: &Row) -> Result<DynamicsRow, ExportError> {
        self.rotor.step(self.forward);
        self.rotor.run_for(row.period_ticks as f64 / self.clkfreq);
        let sample = self.rotor.sample();
        let lag = self.sign() * sample.error_steps;
        if !(lag.is_finite() && sample.angle_deg.is_finite()) {
            return Err(self.not_finite(row.step, "rotor lag"));
        }
        if self
            .largest_lag
            .is_none_or(|(_, largest)| lag.abs() > largest.abs())
        {
            self.largest_lag = Some((row.step, lag));
        }
        Ok(DynamicsRow {
            rotor_angle_deg: sample.angle_deg,
            rotor_lag_steps: lag,
            synchronous: sample.synchronous,
            rotor_velocity_steps_per_s: sample.velocity_steps_per_s,
        })
    }

    fn not_finite(&self, step: u32, what: &'static str) -> ExportError {
        ExportError::NotFinite {
            path: self.path.to_path_buf(),
            step,
            what,
        }
    }

    /// Whether synchronism has held so far.
    pub fn synchronous(&self) -> bool {
        self.rotor.lost_at_step().is_none()
    }

    /// Lets the rotor settle at the target; what the move came to.
    pub fn finish(mut self) -> Result<DynamicsSummary, ExportError> {
        let settle_s = self.rotor.settle();
        let final_error_steps = self.sign() * self.rotor.error_steps();
        if !(final_error_steps.is_finite() && settle_s.is_finite()) {
            let steps = self.rotor.steps_seen().saturating_sub(1);
            let last = u32::try_from(steps).unwrap_or(u32::MAX);
            return Err(self.not_finite(last, "rotor's resting place after the move"));
        }
        Ok(DynamicsSummary {
            natural_frequency_hz: self.params.natural_frequency_hz(),
            damping_ratio: self.params.damping_ratio(),
            sync_limit_steps: self.params.sync_limit_steps(),
            lost_at_step: self
                .rotor
                .lost_at_step()
                .map(|step| u32::try_from(step).unwrap_or(u32::MAX)),
            largest_lag: self.largest_lag,
            final_error_steps,
            settle_s,
        })
    }
}

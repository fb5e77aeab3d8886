//! Can the motor follow the move? (The lecture's torque check, and the
//! figures the rotor model of `--dynamics` needs.)
//!
//! A motor file (TOML) describes the motor and its load:
//!
//! ```toml
//! step_angle_deg = 1.8          # full step, degrees
//! rotor_inertia_kgm2 = 2.5e-5   # kg·m²
//! load_inertia_kgm2 = 6e-5      # kg·m²
//! load_torque_nm = 0.3          # N·m: friction and other constant load
//! safety_factor = 1.5           # optional, default 1.0
//! # pull-out torque: [steps/s, N·m], speeds increasing
//! torque_curve = [[0, 0.6], [2000, 0.55], [5000, 0.45], [10000, 0.3]]
//! # for --dynamics (the rotor model, `driver::motor`):
//! phases = 2                    # optional, default 2 (5 for a 5-phase motor)
//! holding_torque_nm = 0.6       # optional, N·m; default: the curve at 0 steps/s
//! damping_nm_s_per_rad = 0.005  # N·m·s/rad, viscous; required by --dynamics
//! ```
//!
//! Per step: angular acceleration = step acceleration (see [`crate::table`])
//! × step angle in radians; torque required = (rotor + load inertia) ×
//! angular acceleration + load torque (which opposes the motion, so it takes
//! the sign of the velocity); torque available = the pull-out curve at the
//! faster of the two step rates the acceleration lies between (the curve
//! falls with speed, so this is the cautious side), linearly interpolated,
//! held at the first point's torque below it, and an error beyond the last
//! point; margin = available / |required| (infinite when nothing is
//! required). The check fails when the smallest margin is below the safety
//! factor.

use std::io::Read;
use std::path::{Path, PathBuf};

use driver::motor::{MotorParams, TorquePoints};
use serde::Deserialize;

use crate::error::ExportError;
use crate::table::Row;

/// The largest motor file read, bytes (a real one is well under 4 KiB).
pub const MOTOR_FILE_MAX_BYTES: u64 = 1 << 20;

/// The heaviest damping the rotor model follows, as a damping ratio: its
/// explicit integrator takes 64 substeps per natural period, which keeps
/// a damping ratio up to about 10 stable (real motors are well below 1).
pub const DAMPING_RATIO_MAX: f64 = 10.0;

/// The motor file as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MotorFile {
    step_angle_deg: f64,
    rotor_inertia_kgm2: f64,
    load_inertia_kgm2: f64,
    load_torque_nm: f64,
    safety_factor: Option<f64>,
    /// Checked for two numbers per point below (serde's `[f64; 2]` lets a
    /// third number pass unnoticed).
    torque_curve: Vec<Vec<f64>>,
    phases: Option<u8>,
    holding_torque_nm: Option<f64>,
    damping_nm_s_per_rad: Option<f64>,
}

/// A checked motor description.
#[derive(Clone, Debug, PartialEq)]
pub struct Motor {
    /// Where it was read from (for messages).
    pub path: PathBuf,
    /// Step angle, radians.
    pub step_angle_rad: f64,
    /// Rotor plus load inertia, kg·m².
    pub total_inertia_kgm2: f64,
    /// Constant load torque, N·m (≥ 0).
    pub load_torque_nm: f64,
    /// Smallest acceptable margin.
    pub safety_factor: f64,
    /// Pull-out torque curve: (steps/s, N·m), speeds strictly increasing.
    pub torque_curve: Vec<(f64, f64)>,
    /// Phases (2 unless the file says otherwise).
    pub phases: u8,
    /// Holding torque, N·m (the file's, or the curve at 0 steps/s).
    pub holding_torque_nm: f64,
    /// Viscous damping, N·m·s/rad, if the file gives it (`--dynamics`
    /// needs it).
    pub damping_nm_s_per_rad: Option<f64>,
}

/// The motor columns of one row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorRow {
    /// Acceleration, steps/s² (the table's).
    pub accel_steps_per_s2: f64,
    /// Torque the motor must give, N·m (signed like the motion).
    pub torque_required_nm: f64,
    /// Pull-out torque at this step rate, N·m.
    pub torque_available_nm: f64,
    /// available / |required| (`f64::INFINITY` when nothing is required).
    pub margin: f64,
}

/// The smallest margin of a move and where it occurs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SmallestMargin {
    /// The step.
    pub step: u32,
    /// Its motor columns.
    pub motor_row: MotorRow,
}

impl Motor {
    /// Reads and checks a motor file (at most [`MOTOR_FILE_MAX_BYTES`]:
    /// `/dev/zero` or a runaway FIFO is refused, not read until memory
    /// runs out).
    pub fn load(path: &Path) -> Result<Motor, ExportError> {
        let fail = |reason: String| ExportError::Motor {
            path: path.to_path_buf(),
            reason,
        };
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .and_then(|file| file.take(MOTOR_FILE_MAX_BYTES + 1).read_to_end(&mut bytes))
            .map_err(|error| fail(error.to_string()))?;
        if bytes.len() as u64 > MOTOR_FILE_MAX_BYTES {
            return Err(fail(format!(
                "larger than {} MiB: a motor file is a few lines of TOML",
                MOTOR_FILE_MAX_BYTES >> 20
            )));
        }
        let text = String::from_utf8(bytes).map_err(|error| {
            fail(format!(
                "not UTF-8 text (invalid byte at offset {})",
                error.utf8_error().valid_up_to()
            ))
        })?;
        Motor::parse(&text, path).map_err(fail)
    }

    /// Parses and checks a motor description; the error is one line.
    pub fn parse(text: &str, path: &Path) -> Result<Motor, String> {
        let file: MotorFile = toml::from_str(text).map_err(|error| {
            // toml's messages span several lines (with a source excerpt).
            error
                .message()
                .lines()
                .next()
                .unwrap_or("not valid TOML")
                .to_string()
                + &error
                    .span()
                    .map(|span| {
                        // Newlines before the error, plus one: `lines()` would
                        // miss the line of an error in its first column.
                        let before = text.get(..span.start).unwrap_or(text);
                        let line = before.matches('\n').count() + 1;
                        format!(" (line {line})")
                    })
                    .unwrap_or_default()
        })?;
        positive("step_angle_deg", file.step_angle_deg)?;
        non_negative("rotor_inertia_kgm2", file.rotor_inertia_kgm2)?;
        non_negative("load_inertia_kgm2", file.load_inertia_kgm2)?;
        non_negative("load_torque_nm", file.load_torque_nm)?;
        let safety_factor = file.safety_factor.unwrap_or(1.0);
        positive("safety_factor", safety_factor)?;
        if file.torque_curve.is_empty() {
            return Err(
                "torque_curve needs at least one [steps_per_s, newton_metres] point".into(),
            );
        }
        let mut previous: Option<f64> = None;
        let mut torque_curve = Vec::with_capacity(file.torque_curve.len());
        for (index, point) in file.torque_curve.iter().enumerate() {
            let &[speed, torque] = point.as_slice() else {
                return Err(format!(
                    "torque_curve point {index} must be [steps_per_s, newton_metres], got {point:?}"
                ));
            };
            non_negative(&format!("torque_curve[{index}] speed"), speed)?;
            non_negative(&format!("torque_curve[{index}] torque"), torque)?;
            if previous.is_some_and(|before| speed <= before) {
                return Err(format!(
                    "torque_curve speeds must increase, but point {index} ({speed} steps/s) does not"
                ));
            }
            previous = Some(speed);
            torque_curve.push((speed, torque));
        }
        let phases = file.phases.unwrap_or(2);
        if !(2..=10).contains(&phases) {
            return Err(format!("phases must be 2 to 10, got {phases}"));
        }
        let holding_torque_nm = match file.holding_torque_nm {
            Some(holding) => {
                positive("holding_torque_nm", holding)?;
                holding
            }
            None => torque_curve[0].1,
        };
        if let Some(damping) = file.damping_nm_s_per_rad {
            non_negative("damping_nm_s_per_rad", damping)?;
        }
        let total_inertia_kgm2 = file.rotor_inertia_kgm2 + file.load_inertia_kgm2;
        if !total_inertia_kgm2.is_finite() {
            return Err(
                "rotor_inertia_kgm2 + load_inertia_kgm2 is beyond the range of a number".into(),
            );
        }
        if total_inertia_kgm2 <= 0.0 {
            return Err("rotor_inertia_kgm2 + load_inertia_kgm2 must be above 0".into());
        }
        Ok(Motor {
            path: path.to_path_buf(),
            step_angle_rad: file.step_angle_deg.to_radians(),
            total_inertia_kgm2,
            load_torque_nm: file.load_torque_nm,
            safety_factor,
            torque_curve,
            phases,
            holding_torque_nm,
            damping_nm_s_per_rad: file.damping_nm_s_per_rad,
        })
    }

    /// The rotor model's figures (`--dynamics`): an error when the file
    /// lacks the damping, or the figures do not make a motor.
    pub fn rotor_params(&self) -> Result<MotorParams, ExportError> {
        let fail = |reason: String| ExportError::Motor {
            path: self.path.clone(),
            reason,
        };
        let damping = self.damping_nm_s_per_rad.ok_or_else(|| {
            fail("--dynamics needs damping_nm_s_per_rad (viscous damping, N·m·s/rad)".into())
        })?;
        let params = |torque_nm: f64| {
            MotorParams::new(
                self.step_angle_rad.to_degrees(),
                self.phases,
                self.total_inertia_kgm2,
                damping,
                self.load_torque_nm,
                torque_nm,
            )
            .map_err(|error| fail(error.to_string()))
        };
        // The stiffest the magnetic spring gets must make a motor too.
        let strongest = self
            .torque_curve
            .iter()
            .map(|&(_, torque)| torque)
            .fold(self.holding_torque_nm, f64::max);
        params(strongest)?;
        params(self.holding_torque_nm)
    }

    /// The pull-out curve, for the rotor model.
    pub fn pull_out_curve(&self) -> TorquePoints<'_> {
        TorquePoints::new(&self.torque_curve)
    }

    /// The fastest step rate the torque curve covers, steps/s.
    pub fn curve_end_steps_per_s(&self) -> f64 {
        self.torque_curve.last().map_or(0.0, |&(speed, _)| speed)
    }

    /// Torque needed for an angular acceleration (rad/s²) while moving in
    /// the direction of `velocity_sign` (the load torque opposes motion).
    pub fn torque_required_nm(&self, angular_accel_rad_s2: f64, velocity_sign: f64) -> f64 {
        self.total_inertia_kgm2 * angular_accel_rad_s2 + self.load_torque_nm.copysign(velocity_sign)
    }

    /// Pull-out torque at a step rate (magnitude), or `None` beyond the
    /// curve's last point.
    pub fn torque_available_nm(&self, rate_steps_per_s: f64) -> Option<f64> {
        let rate = rate_steps_per_s.abs();
        let &(first_speed, first_torque) = self.torque_curve.first()?;
        if rate <= first_speed {
            return Some(first_torque);
        }
        self.torque_curve.windows(2).find_map(|pair| {
            let ((low_speed, low_torque), (high_speed, high_torque)) = (pair[0], pair[1]);
            (rate <= high_speed).then(|| {
                let fraction = (rate - low_speed) / (high_speed - low_speed);
                low_torque + fraction * (high_torque - low_torque)
            })
        })
    }

    /// The motor columns of a row.
    pub fn check(&self, row: &Row) -> Result<MotorRow, ExportError> {
        let angular_accel = row.accel_steps_per_s2 * self.step_angle_rad;
        let required = self.torque_required_nm(angular_accel, row.velocity_steps_per_s);
        let available = self
            .torque_available_nm(row.peak_rate_steps_per_s)
            .ok_or_else(|| ExportError::BeyondTorqueCurve {
                path: self.path.clone(),
                step: row.step,
                rate_steps_per_s: row.peak_rate_steps_per_s,
                last_steps_per_s: self.curve_end_steps_per_s(),
            })?;
        if !required.is_finite() {
            return Err(ExportError::NotFinite {
                path: self.path.clone(),
                step: row.step,
                what: "torque required",
            });
        }
        let margin = if required == 0.0 {
            f64::INFINITY
        } else {
            available / required.abs()
        };
        Ok(MotorRow {
            accel_steps_per_s2: row.accel_steps_per_s2,
            torque_required_nm: required,
            torque_available_nm: available,
            margin,
        })
    }
}

impl SmallestMargin {
    /// Keeps the smaller of `current` and a new row's margin (the first
    /// step wins a tie).
    pub fn track(current: Option<SmallestMargin>, step: u32, motor_row: MotorRow) -> Option<Self> {
        match current {
            Some(smallest) if smallest.motor_row.margin <= motor_row.margin => Some(smallest),
            _ => Some(SmallestMargin { step, motor_row }),
        }
    }
}

fn positive(name: &str, value: f64) -> Result<(), String> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(format!("{name} must be a positive number, got {value}"))
    }
}

fn non_negative(name: &str, value: f64) -> Result<(), String> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(format!("{name} must be a number ≥ 0, got {value}"))
    }
}

#[cfg(test)]
mod tests {
    use driver::profile::Phase;

    use super::*;

    const LECTURE_LOAD: &str = "
        step_angle_deg = 1.8
        load_inertia_kgm2 = 6e-5
        load_torque_nm = 0.3
        torque_curve = [[0, 0.6], [4000, 0.5], [10000, 0.3]]
    ";

    fn lecture_motor(rotor_inertia_kgm2: f64) -> Motor {
        let text = format!("rotor_inertia_kgm2 = {rotor_inertia_kgm2:e}\n{LECTURE_LOAD}");
        Motor::parse(&text, Path::new("motor.toml")).unwrap()
    }

    /// 0 → 20 rev/s in 0.2 s with 1.8° steps: 4,000 steps/s, 20,000 steps/s²,
    /// 628.3 rad/s².
    const LECTURE_ACCEL_STEPS_PER_S2: f64 = 20_000.0;

    #[test]
    fn lecture_example_torques() {
        // The lecture quotes 0.353 N·m and 0.359 N·m (0.35969, truncated).
        for (rotor, expected) in [(2.5e-5, 0.353), (3.5e-5, 0.359)] {
            let motor = lecture_motor(rotor);
            let angular = LECTURE_ACCEL_STEPS_PER_S2 * motor.step_angle_rad;
            assert!((angular - 628.3).abs() < 0.05, "{angular}");
            let torque = motor.torque_required_nm(angular, 1.0);
            assert!((torque - expected).abs() < 1e-3, "{rotor}: {torque}");
        }
    }

    #[test]
    fn lecture_example_through_a_row() {
        let motor = lecture_motor(2.5e-5);
        let row = Row {
            step: 7,
            phase: Phase::Accel,
            angle_deg: None,
            velocity_steps_per_s: 3_990.0,
            delay_ticks: 50_125,
            period_ticks: 50_125,
            time_ticks: 0,
            time_s: 0.0,
            accel_steps_per_s2: LECTURE_ACCEL_STEPS_PER_S2,
            peak_rate_steps_per_s: 4_000.0,
        };
        let checked = motor.check(&row).unwrap();
        assert_eq!(format!("{:.3}", checked.torque_required_nm), "0.353");
        assert_eq!(checked.torque_available_nm, 0.5);
        assert!((checked.margin - 0.5 / 0.353_407).abs() < 1e-4);
        // Reverse: the same torque, the other way.
        let reverse = Row {
            velocity_steps_per_s: -3_990.0,
            accel_steps_per_s2: -LECTURE_ACCEL_STEPS_PER_S2,
            ..row
        };
        let checked_reverse = motor.check(&reverse).unwrap();
        assert_eq!(
            checked_reverse.torque_required_nm,
            -checked.torque_required_nm
        );
        assert_eq!(checked_reverse.margin, checked.margin);
    }

    #[test]
    fn curve_interpolates_holds_below_and_ends() {
        let motor = lecture_motor(2.5e-5);
        assert_eq!(motor.torque_available_nm(0.0), Some(0.6));
        assert_eq!(motor.torque_available_nm(2_000.0), Some(0.55));
        assert!((motor.torque_available_nm(7_000.0).unwrap() - 0.4).abs() < 1e-12);
        assert_eq!(motor.torque_available_nm(10_000.0), Some(0.3));
        assert_eq!(motor.torque_available_nm(10_000.1), None);
        let late = Motor::parse(
            "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 1e-5\nload_inertia_kgm2 = 0\n\
             load_torque_nm = 0\ntorque_curve = [[100, 0.4], [200, 0.2]]",
            Path::new("m.toml"),
        )
        .unwrap();
        assert_eq!(late.torque_available_nm(50.0), Some(0.4));
    }

    #[test]
    fn malformed_files_are_one_line_errors() {
        let cases = [
            ("", "missing field"),
            ("step_angle_deg = \"x\"", "invalid type"),
            (
                "step_angle_deg = 0\nrotor_inertia_kgm2 = 1e-5\nload_inertia_kgm2 = 0\n\
                 load_torque_nm = 0\ntorque_curve = [[0, 1]]",
                "step_angle_deg must be a positive number",
            ),
            (
                "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 1e-5\nload_inertia_kgm2 = 0\n\
                 load_torque_nm = 0\ntorque_curve = []",
                "at least one",
            ),
            (
                "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 1e-5\nload_inertia_kgm2 = 0\n\
                 load_torque_nm = 0\ntorque_curve = [[0, 1], [0, 1]]",
                "must increase",
            ),
            (
                "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 1e-5\nload_inertia_kgm2 = 0\n\
                 load_torque_nm = 0\ntorque_curve = [[0, 1]]\nsafety_factr = 2",
                "unknown field",
            ),
            (
                "step_angle_deg = 1.8\nrotor_inertia_kgm2 = 1e-5\nload_inertia_kgm2 = 0\n\
                 load_torque_nm = 0\ntorque_curve = [[0, 1, 2]]",
                "must be [steps_per_s, newton_metres]",
            ),
        ];
        for (text, expected) in cases {
            let error = Motor::parse(text, Path::new("m.toml")).unwrap_err();
            assert!(error.contains(expected), "{text:?}: {error}");
            assert!(!error.contains('\n'), "{text:?}: {error}");
        }
    }

    #[test]
    fn smallest_margin_keeps_the_first_minimum() {
        let row = |margin| MotorRow {
            accel_steps_per_s2: 0.0,
            torque_required_nm: 1.0,
            torque_available_nm: margin,
            margin,
        };
        let mut smallest = None;
        for (step, margin) in [(0, 3.0), (1, 2.0), (2, 2.0), (3, 5.0)] {
            smallest = SmallestMargin::track(smallest, step, row(margin));
        }
        assert_eq!(smallest.map(|s| s.step), Some(1));
    }
}

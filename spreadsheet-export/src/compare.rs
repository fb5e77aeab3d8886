//! `compare`: every profile on one move and one motor, a CSV line each.
//!
//! ```text
//! profile,total_time_s,peak_torque_nm,min_margin,max_rotor_lag_steps,synchronous
//! ```
//!
//! - `total_time_s`: the move's time (every delay summed, as the table's
//!   `time_s` plus the last delay);
//! - `peak_torque_nm`, `min_margin`: the static motor check's largest
//!   |torque required| and smallest margin (see [`crate::motor`]);
//! - `max_rotor_lag_steps`: the largest |`rotor_lag_steps`| of the table
//!   (the rotor at the end of each step's interval, see
//!   [`crate::dynamics`]);
//! - `synchronous`: whether the rotor kept synchronism, settling included.
//!
//! The S-curves (`p2`, `p2-exact`) run at `--speed` with their own ramp
//! (`--offset`, `--accel-div`); `austin`, `leib` and `trapezoid` at
//! `--speed` and `--accel`, or, without it, at the acceleration that
//! reaches the P2 S-curve's top speed in as many steps as its ramp
//! (`speed² / (2 × accel steps)`).
//!
//! `--fastest` appends `fastest_time_s,fastest_speed,fastest_accel`: per
//! profile, the shortest time found for the same move with the rotor kept
//! synchronous while every torque of the motor (curve and holding) is
//! divided by the motor file's safety factor, searching the speed (up to
//! the torque curve's last point) and, for the linear ramps, the
//! acceleration (`fastest_accel` is empty for the S-curves, whose ramp
//! follows from the speed). The search: a grid of 16 speeds up to the
//! curve's end; at each, the largest of 12 log-spaced accelerations that
//! keeps synchronism, refined by bisection; then a bisection of the speed
//! beside the best grid point. Every setting
//! reported was run and kept synchronism; a resonance between grid points
//! can hide a faster one. Empty fields: nothing tried kept synchronism.

use std::io::Write;

use crate::cli::{ProfileKind, Request};
use crate::dynamics::Dynamics;
use crate::error::ExportError;
use crate::motor::Motor;
use crate::profiles;
use crate::table::{Rows, Summary};

/// The compare table's columns.
pub const COMPARE_HEADER: [&str; 6] = [
    "profile",
    "total_time_s",
    "peak_torque_nm",
    "min_margin",
    "max_rotor_lag_steps",
    "synchronous",
];

/// The columns `--fastest` adds.
pub const FASTEST_HEADER: [&str; 3] = ["fastest_time_s", "fastest_speed", "fastest_accel"];

/// The profiles compared, in order.
pub const PROFILES: [ProfileKind; 5] = [
    ProfileKind::P2,
    ProfileKind::P2Exact,
    ProfileKind::Austin,
    ProfileKind::Leib,
    ProfileKind::Trapezoid,
];

/// Speeds tried on the grid.
const SPEED_GRID: u32 = 16;
/// Accelerations tried on the grid at each speed.
const ACCEL_GRID: u32 = 12;
/// Bisections of the acceleration beside the best grid point.
const ACCEL_BISECTIONS: u32 = 6;
/// Bisections of the speed beside the best grid point.
const SPEED_BISECTIONS: u32 = 6;

/// One profile on the move.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Evaluation {
    /// The profile.
    pub profile: ProfileKind,
    /// Time of the move, s.
    pub total_time_s: f64,
    /// Largest |torque required|, N·m.
    pub peak_torque_nm: f64,
    /// Smallest margin (infinite when no torque is required).
    pub min_margin: f64,
    /// Largest |rotor lag| of the rows, steps.
    pub max_rotor_lag_steps: f64,
    /// Whether the rotor kept synchronism.
    pub synchronous: bool,
}

/// The fastest setting found that keeps synchronism.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fastest {
    /// Time of the move, s.
    pub time_s: f64,
    /// Speed, steps/s.
    pub speed_steps_per_s: f64,
    /// Acceleration, steps/s² (the linear ramps).
    pub accel_steps_per_s2: Option<f64>,
}

/// Runs `compare` and writes its table to `out`.
pub fn run(request: &Request, fastest: bool, mut out: impl Write) -> Result<(), ExportError> {
    let motor_path = request.motor.as_deref().ok_or(ExportError::Usage(
        "compare needs --motor (see compare --help)".into(),
    ))?;
    let motor = Motor::load(motor_path)?;
    motor.rotor_params()?;
    let base = with_linear_accel(request)?;
    let mut lines = Vec::with_capacity(PROFILES.len());
    for profile in PROFILES {
        let request = Request {
            profile,
            ..base.clone()
        };
        let evaluation = evaluate(&request, &motor)?;
        let found = if fastest {
            Some(search_fastest(&request, &motor)?)
        } else {
            None
        };
        lines.push(format_line(&evaluation, found));
    }
    let write = |out: &mut dyn Write| -> std::io::Result<()> {
        let mut header = COMPARE_HEADER.join(",");
        if fastest {
            header.push(',');
            header.push_str(&FASTEST_HEADER.join(","));
        }
        writeln!(out, "{header}")?;
        for line in &lines {
            writeln!(out, "{line}")?;
        }
        out.flush()
    };
    write(&mut out).map_err(|source| ExportError::Write {
        path: "-".into(),
        source,
    })
}

/// The request with the linear ramps' acceleration filled in.
fn with_linear_accel(request: &Request) -> Result<Request, ExportError> {
    if request.accel_steps_per_s2.is_some() {
        return Ok(request.clone());
    }
    let p2 = profiles::build(&Request {
        profile: ProfileKind::P2,
        ..request.clone()
    })?;
    let plan = p2
        .plan
        .ok_or(ExportError::Usage("no S-curve plan".into()))?;
    let speed = f64::from(plan.speed.max(1));
    let accel = speed * speed / (2.0 * f64::from(plan.accel_steps.max(1)));
    Ok(Request {
        accel_steps_per_s2: Some(accel),
        ..request.clone()
    })
}

/// One profile on the move: the static check and the rotor.
pub fn evaluate(request: &Request, motor: &Motor) -> Result<Evaluation, ExportError> {
    let built = profiles::build(request)?;
    let end = motor.curve_end_steps_per_s();
    if built.top_speed_steps_per_s > end {
        return Err(ExportError::TopSpeedBeyondTorqueCurve {
            path: motor.path.clone(),
            top_steps_per_s: built.top_speed_steps_per_s,
            last_steps_per_s: end,
        });
    }
    let mut dynamics = Dynamics::new(motor, request.clkfreq, request.direction, 1.0)?;
    let mut summary = Summary::default();
    let mut peak_torque_nm = 0.0f64;
    let mut min_margin = f64::INFINITY;
    for row in Rows::new(
        built.profile,
        request.clkfreq,
        request.direction,
        built.edge_timing,
    ) {
        let checked = motor.check(&row)?;
        peak_torque_nm = peak_torque_nm.max(checked.torque_required_nm.abs());
        min_margin = min_margin.min(checked.margin);
        dynamics.row(&row)?;
        summary.add(&row);
    }
    let rotor = dynamics.finish()?;
    Ok(Evaluation {
        profile: request.profile,
        total_time_s: summary.total_time_s(request.clkfreq),
        peak_torque_nm,
        min_margin,
        max_rotor_lag_steps: rotor.largest_lag_steps(),
        synchronous: rotor.synchronous(),
    })
}

/// The move's time if the rotor, derated by the safety factor, keeps
/// synchronism at this speed (and acceleration); `None` otherwise, or when
/// the profile cannot plan it or it runs beyond the torque curve.
fn time_if_synchronous(
    request: &Request,
    motor: &Motor,
    speed: f64,
    accel: Option<f64>,
) -> Result<Option<f64>, ExportError> {
    let request = Request {
        speed_steps_per_s: speed,
        accel_steps_per_s2: accel,
        ..request.clone()
    };
    let Ok(built) = profiles::build(&request) else {
        return Ok(None);
    };
    if built.top_speed_steps_per_s > motor.curve_end_steps_per_s() {
        return Ok(None);
    }
    let mut dynamics = Dynamics::new(
        motor,
        request.clkfreq,
        request.direction,
        motor.safety_factor,
    )?;
    let mut summary = Summary::default();
    for row in Rows::new(
        built.profile,
        request.clkfreq,
        request.direction,
        built.edge_timing,
    ) {
        dynamics.row(&row)?;
        if !dynamics.synchronous() {
            return Ok(None);
        }
        summary.add(&row);
    }
    let rotor = dynamics.finish()?;
    Ok(rotor
        .synchronous()
        .then(|| summary.total_time_s(request.clkfreq)))
}

/// The fastest setting found for `request`'s profile (see the module docs).
pub fn search_fastest(request: &Request, motor: &Motor) -> Result<Option<Fastest>, ExportError> {
    let end = motor.curve_end_steps_per_s();
    let scurve = request.profile.is_scurve();
    // Whole steps/s (the S-curves take nothing else), so that the speed
    // reported is the one run.
    let speed_at = |fraction: f64| (end * fraction).floor().max(1.0);
    let accel_bounds = accel_bounds(motor);
    let try_speed = |speed: f64| -> Result<Option<Fastest>, ExportError> {
        if scurve {
            return Ok(
                time_if_synchronous(request, motor, speed, None)?.map(|time_s| Fastest {
                    time_s,
                    speed_steps_per_s: speed,
                    accel_steps_per_s2: None,
                }),
            );
        }
        let Some((low, high)) = accel_bounds else {
            return Ok(None);
        };
        largest_accel(request, motor, speed, low, high)
    };
    let better = |best: Option<Fastest>, found: Option<Fastest>| match (best, found) {
        (Some(best), Some(found)) if found.time_s < best.time_s => Some(found),
        (None, found) => found,
        (best, _) => best,
    };
    let mut best: Option<Fastest> = None;
    let mut best_index = 0;
    for index in 1..=SPEED_GRID {
        let found = try_speed(speed_at(f64::from(index) / f64::from(SPEED_GRID)))?;
        let improved = better(best, found);
        if improved != best {
            best = improved;
            best_index = index;
        }
    }
    let Some(grid_best) = best else {
        return Ok(None);
    };
    // Between the best grid speed and the next one up.
    if best_index < SPEED_GRID {
        let mut low = grid_best.speed_steps_per_s;
        let mut high = speed_at(f64::from(best_index + 1) / f64::from(SPEED_GRID));
        for _ in 0..SPEED_BISECTIONS {
            let middle = ((low + high) / 2.0).floor();
            if middle <= low || middle >= high {
                break;
            }
            let found = try_speed(middle)?;
            let improved = better(best, found);
            if improved != best {
                best = improved;
                low = middle;
            } else {
                high = middle;
            }
        }
    }
    Ok(best)
}

/// The range of accelerations worth trying, steps/s²: up to twice what the
/// motor's largest torque, less the load, gives the inertia.
fn accel_bounds(motor: &Motor) -> Option<(f64, f64)> {
    let strongest = motor
        .torque_curve
        .iter()
        .map(|&(_, torque)| torque)
        .fold(motor.holding_torque_nm, f64::max)
        / motor.safety_factor;
    let spare = strongest - motor.load_torque_nm;
    (spare > 0.0).then(|| {
        let high = 2.0 * spare / motor.total_inertia_kgm2 / motor.step_angle_rad;
        (high / 1_000.0, high)
    })
}

/// The largest acceleration in `[low, high]` found to keep synchronism at
/// `speed`, with the move's time: the largest of a log-spaced grid (tried
/// from the top: a resonance can make a lower acceleration fail where a
/// higher one passes, so feasibility is not assumed to be monotone), then
/// bisected towards the grid point above it.
fn largest_accel(
    request: &Request,
    motor: &Motor,
    speed: f64,
    low: f64,
    high: f64,
) -> Result<Option<Fastest>, ExportError> {
    // Whole steps/s², so that the acceleration reported is the one run.
    let at = |accel: f64| -> Result<Option<Fastest>, ExportError> {
        let accel = accel.floor().max(1.0);
        Ok(
            time_if_synchronous(request, motor, speed, Some(accel))?.map(|time_s| Fastest {
                time_s,
                speed_steps_per_s: speed,
                accel_steps_per_s2: Some(accel),
            }),
        )
    };
    let (low, high) = (low.ln(), high.ln());
    let grid = |index: u32| low + (high - low) * f64::from(index) / f64::from(ACCEL_GRID - 1);
    for index in (0..ACCEL_GRID).rev() {
        let Some(mut kept) = at(grid(index).exp())? else {
            continue;
        };
        if index + 1 < ACCEL_GRID {
            let (mut passed, mut failed) = (grid(index), grid(index + 1));
            for _ in 0..ACCEL_BISECTIONS {
                let middle = (passed + failed) / 2.0;
                match at(middle.exp())? {
                    Some(found) => {
                        kept = found;
                        passed = middle;
                    }
                    None => failed = middle,
                }
            }
        }
        return Ok(Some(kept));
    }
    Ok(None)
}

fn format_line(evaluation: &Evaluation, fastest: Option<Option<Fastest>>) -> String {
    let margin = if evaluation.min_margin.is_finite() {
        format!("{:.4}", evaluation.min_margin)
    } else {
        "inf".to_string()
    };
    let mut line = format!(
        "{},{:.6},{:.4},{margin},{:.4},{}",
        evaluation.profile.as_str(),
        evaluation.total_time_s,
        evaluation.peak_torque_nm,
        evaluation.max_rotor_lag_steps,
        evaluation.synchronous,
    );
    match fastest {
        None => {}
        Some(None) => line.push_str(",,,"),
        Some(Some(found)) => {
            line.push_str(&format!(
                ",{:.6},{:.0},",
                found.time_s, found.speed_steps_per_s
            ));
            if let Some(accel) = found.accel_steps_per_s2 {
                line.push_str(&format!("{accel:.0}"));
            }
        }
    }
    line
}

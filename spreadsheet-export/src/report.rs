//! What an export knows once its last row is written: the request, the
//! plan, the rows' summary, the motor's margin and the rotor's dynamics;
//! and the summary lines the workbook's summary sheet (and the terminal)
//! show of it.

use driver::profile::scurve::Plan;

use crate::cli::Request;
use crate::dynamics::DynamicsSummary;
use crate::motor::{Motor, SmallestMargin};
use crate::table::Summary;

/// One value of the summary sheet.
#[derive(Clone, Debug, PartialEq)]
pub enum SummaryValue {
    /// A number.
    Number(f64),
    /// Text.
    Text(String),
}

/// One line of the summary sheet: quantity, value, unit.
pub type SummaryLine = (&'static str, SummaryValue, &'static str);

/// Everything known once the last row is written.
pub struct Report<'a> {
    /// The request.
    pub request: &'a Request,
    /// The S-curve's plan, for the S-curve profiles.
    pub plan: Option<Plan>,
    /// Counts and extremes of the rows.
    pub summary: Summary,
    /// The motor and the smallest margin, with `--motor`.
    pub motor: Option<(&'a Motor, Option<SmallestMargin>)>,
    /// What the rotor did, with `--dynamics`.
    pub dynamics: Option<DynamicsSummary>,
}

impl Report<'_> {
    /// A title for the plot.
    pub fn title(&self) -> String {
        let request = self.request;
        let signed_steps = request.direction * f64::from(request.steps);
        let unit = if request.steps == 1 { "step" } else { "steps" };
        let mut title = format!(
            "{}: {signed_steps} {unit} at {} steps/s",
            request.profile.as_str(),
            request.speed_steps_per_s
        );
        if let Some(accel) = request
            .accel_steps_per_s2
            .filter(|_| !request.profile.is_scurve())
        {
            title.push_str(&format!(", {accel} steps/s²"));
        }
        if request.clkfreq.is_multiple_of(1_000_000) {
            title.push_str(&format!(", {} MHz clock", request.clkfreq / 1_000_000));
        } else {
            title.push_str(&format!(", {} Hz clock", request.clkfreq));
        }
        title
    }

    /// The summary sheet's lines: inputs, then results.
    pub fn summary_lines(&self) -> Vec<SummaryLine> {
        use SummaryValue::{Number, Text};
        let request = self.request;
        let summary = &self.summary;
        let mut lines: Vec<SummaryLine> = vec![
            ("profile", Text(request.profile.as_str().into()), ""),
            (
                "steps requested",
                Number(request.direction * f64::from(request.steps)),
                "steps",
            ),
            (
                "speed requested",
                Number(request.speed_steps_per_s),
                "steps/s",
            ),
        ];
        if request.profile.is_scurve() {
            lines.push(("offset", Number(request.offset_deg.into()), "deg"));
            lines.push(("acceleration divisor", Number(request.accel_div.into()), ""));
        } else if let Some(accel) = request.accel_steps_per_s2 {
            lines.push(("acceleration requested", Number(accel), "steps/s²"));
        }
        lines.push(("clock", Number(request.clkfreq.into()), "Hz"));
        if let Some(plan) = &self.plan {
            lines.push(("planned top speed", Number(plan.speed.into()), "steps/s"));
            lines.push((
                "short move (speed lowered)",
                Text(if plan.short_move { "yes" } else { "no" }.into()),
                "",
            ));
        }
        lines.push(("steps", Number(summary.steps.into()), "steps"));
        lines.push(("accel steps", Number(summary.accel_steps.into()), "steps"));
        lines.push(("slew steps", Number(summary.slew_steps.into()), "steps"));
        lines.push(("decel steps", Number(summary.decel_steps.into()), "steps"));
        lines.push((
            "top speed",
            Number(summary.top_speed_steps_per_s),
            "steps/s",
        ));
        lines.push((
            "total time",
            Number(summary.total_time_s(request.clkfreq)),
            "s",
        ));
        if let Some(rate) = summary.average_rate_steps_per_s(request.clkfreq) {
            // Steps over the time from the first rising edge to the axis
            // being ready again: for p2-exact, the rate a P2 board really
            // makes (pulse and cog overhead included).
            lines.push(("average step rate (real)", Number(rate), "steps/s"));
        }
        if let Some((step, accel)) = summary.largest_accel {
            lines.push(("largest acceleration", Number(accel.abs()), "steps/s²"));
            lines.push(("largest acceleration at step", Number(step.into()), ""));
        }
        if let Some((motor, smallest)) = &self.motor {
            lines.push(("safety factor", Number(motor.safety_factor), ""));
            if let Some(smallest) = smallest {
                let margin = smallest.motor_row.margin;
                if margin.is_finite() {
                    lines.push(("smallest motor margin", Number(margin), ""));
                } else {
                    lines.push((
                        "smallest motor margin",
                        Text("no torque required".into()),
                        "",
                    ));
                }
                lines.push(("smallest margin at step", Number(smallest.step.into()), ""));
                lines.push((
                    "motor check",
                    Text(
                        if margin < motor.safety_factor {
                            "FAIL"
                        } else {
                            "ok"
                        }
                        .into(),
                    ),
                    "",
                ));
            }
        }
        if let Some(dynamics) = &self.dynamics {
            lines.push((
                "rotor natural frequency",
                Number(dynamics.natural_frequency_hz),
                "Hz",
            ));
            lines.push(("rotor damping ratio", Number(dynamics.damping_ratio), ""));
            lines.push((
                "synchronism lost beyond",
                Number(dynamics.sync_limit_steps),
                "steps",
            ));
            lines.push((
                "synchronism",
                Text(
                    if dynamics.synchronous() {
                        "kept"
                    } else {
                        "LOST"
                    }
                    .into(),
                ),
                "",
            ));
            if let Some(step) = dynamics.lost_at_step {
                lines.push(("synchronism lost at step", Number(step.into()), ""));
            }
            if let Some((step, lag)) = dynamics.largest_lag {
                lines.push(("largest rotor lag", Number(lag), "steps"));
                lines.push(("largest rotor lag at step", Number(step.into()), ""));
            }
            lines.push((
                "rotor error at rest",
                Number(dynamics.final_error_steps),
                "steps",
            ));
            lines.push(("rotor settling time", Number(dynamics.settle_s), "s"));
        }
        lines
    }
}

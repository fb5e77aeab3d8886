//! A frame's readings from the backend into the state: readouts, velocity
//! traces, the frame rate, and limit and homing news as the message.
//! The loop reads them ([`crate::effect::read_frame`]); nothing here
//! touches the backend.

use std::time::{Duration, Instant};

use driver::Mode;

use super::{side_name, App, Tone};
use crate::effect::{FrameReading, LimitReading, Readout};

impl App {
    /// Whether a frame's reading should take the recorded pin edges (a
    /// virtual motor follows them, `--motor`).
    pub fn wants_edges(&self) -> bool {
        self.motors.any()
    }

    /// A frame, as read at `now`.
    pub fn on_frame(&mut self, now: Instant, reading: FrameReading) {
        if let Some((edges, now_ct)) = &reading.edges {
            self.motors.apply(edges, *now_ct);
        }
        self.apply(now, reading.readouts, reading.fault);
        self.apply_limits(reading.limits);
        self.apply_path(reading.path);
    }

    /// A frame's limit and switch readings: news (a limit tripped, homing
    /// ended) becomes the message.
    pub fn apply_limits(&mut self, readings: Vec<LimitReading>) {
        let mut news = Vec::new();
        for (view, (limits, switches)) in self.axes.iter_mut().zip(readings) {
            let number = view.number;
            let before = view.limits;
            view.switches = switches;
            view.limits = limits;
            let Some(now) = limits else { continue };
            if let Some(trip) = now.trip.filter(|_| before.is_none_or(|b| b.trip.is_none())) {
                let side = side_name(trip.side);
                news.push((
                    Tone::Warn,
                    format!(
                        "axis {number}: {side} limit tripped at position {}: stopped after {} steps; moves that way are refused until c clears it",
                        trip.position, trip.stopping_steps
                    ),
                ));
            }
            if before.is_some_and(|b| b.homing) && !now.homing {
                news.push(match now.home_outcome {
                    Some(Ok(report)) => (
                        Tone::Info,
                        format!(
                            "axis {number}: homed: switch found at physical {} (both passes), position now {}",
                            report.latch_physical, report.position
                        ),
                    ),
                    Some(Err(error)) => (Tone::Refused, format!("axis {number}: homing failed: {error}")),
                    None => (Tone::Refused, format!("axis {number}: homing ended without an outcome")),
                });
            }
        }
        for (tone, text) in news {
            self.say(tone, text);
        }
    }

    /// A frame's samples, as read (split from [`App::on_frame`] for tests).
    pub fn apply(
        &mut self,
        now: Instant,
        readouts: Vec<Result<Readout, String>>,
        fault: Option<String>,
    ) {
        let t_s = now.saturating_duration_since(self.started).as_secs_f64();
        self.clock_s = t_s;
        for (view, readout) in self.axes.iter_mut().zip(readouts) {
            match readout {
                Ok(readout) => {
                    let status = readout.status;
                    let magnitude = f64::from(status.velocity_steps_per_s);
                    let velocity = if status.mode.has(Mode::REVERSE) {
                        -magnitude
                    } else {
                        magnitude
                    };
                    view.readout = Some(readout);
                    view.error = None;
                    let moving = view.moving();
                    view.trace.record(t_s, velocity, moving);
                }
                Err(reason) => view.error = Some(reason),
            }
        }
        self.fault = fault;
        self.frames.push_back(now);
        while self
            .frames
            .front()
            .is_some_and(|t| now.duration_since(*t) >= Duration::from_secs(1))
        {
            self.frames.pop_front();
        }
        self.fps = self.frames.len();
    }
}

//! What became of the commands the update asked for ([`Outcome`]s from
//! [`crate::effect::run`]) into the state: the message, the prompt
//! cleared once a move is taken, the jog held, the last command per axis.

use std::time::Instant;

use driver::{Direction, HomeConfig};

use super::{App, Jogging, LastCommand, Tone};
use crate::effect::{Command, Done, Outcome, Refusal};
use crate::prompt::Stage;

impl App {
    /// What a command from [`App::on_key`] came to; `now` is when that
    /// key came (a jog's heartbeat counts from then).
    pub fn on_outcome(&mut self, outcome: Outcome, now: Instant) {
        let Outcome { command, result } = outcome;
        match command {
            Command::Move { axis, steps, speed } => self.moved(axis, steps, speed, result),
            Command::MoveTogether { steps, speed } => self.moved_together(&steps, speed, result),
            Command::Stop { axis } => {
                let number = axis + 1;
                match result {
                    Ok(_) => self.say(
                        Tone::Warn,
                        format!(
                            "axis {number}: stop pin low: decelerating under control; the next move raises it"
                        ),
                    ),
                    Err(refusal) => self.refused(axis, "stop refused", refusal),
                }
            }
            Command::EmergencyStop => match result {
                Ok(_) => self.say(
                    Tone::Warn,
                    "EMERGENCY STOP: every axis halted, positions kept; the next move clears it",
                ),
                Err(refusal) => self.say(
                    Tone::Refused,
                    format!("emergency stop failed: {}", reason(refusal)),
                ),
            },
            Command::JogBeat {
                axis,
                direction,
                speed,
            } => match result {
                Ok(_) => self.jogged(axis, direction, speed, now),
                Err(refusal) => self.refused(axis, "jog refused", refusal),
            },
            Command::JogRelease { axis } => {
                let number = axis + 1;
                match result {
                    Ok(_) => self.say(
                        Tone::Info,
                        format!("axis {number}: jog released (key up): decelerating"),
                    ),
                    Err(refusal) => self.say(
                        Tone::Refused,
                        format!("axis {number}: jog release: {}", reason(refusal)),
                    ),
                }
            }
            Command::Home { axis } => match result {
                Ok(Done::Homing(config)) => self.homing(axis, config),
                Ok(Done::Sent { .. }) => {}
                Err(refusal) => self.refused(axis, "homing refused", refusal),
            },
            Command::Path(command) => self.path_outcome(command, result),
            Command::ClearLimit { axis } => match result {
                Ok(_) => self.say(
                    Tone::Info,
                    format!("axis {}: limit fault cleared", axis + 1),
                ),
                Err(refusal) => self.refused(axis, "clear refused", refusal),
            },
        }
    }

    /// A refusal of a command to one axis: `what` names the axis's own
    /// refusal ("stop refused"); a missing axis is not news.
    fn refused(&mut self, axis: usize, what: &str, refusal: Refusal) {
        let number = axis + 1;
        let text = match refusal {
            Refusal::NoSuchAxis => return,
            Refusal::NoHomeSwitch => format!("axis {number}: no home switch on this backend"),
            Refusal::Unplannable(reason) => reason,
            Refusal::StopPin { axis, reason } => format!("axis {}: {reason}", axis + 1),
            Refusal::Refused(e) => format!("axis {number}: {what}: {e}"),
        };
        self.say(Tone::Refused, text);
    }

    fn moved(&mut self, axis: usize, steps: i32, speed: u32, result: Result<Done, Refusal>) {
        let number = axis + 1;
        match result {
            Ok(done) => {
                self.prompt.stage = Stage::Steps;
                self.prompt.field.clear();
                self.prompt.last_speed = Some(speed);
                if let Some(view) = self.axes.get_mut(axis) {
                    view.last_command = Some(LastCommand::Move { steps, speed });
                }
                let pin = if pin_raised(done) {
                    " (stop pin raised)"
                } else {
                    ""
                };
                self.say(
                    Tone::Info,
                    format!("axis {number}: move {steps} steps at {speed} steps/s{pin}"),
                );
            }
            Err(Refusal::NoSuchAxis) => {
                self.say(Tone::Refused, format!("axis {number} does not exist"));
            }
            Err(Refusal::Refused(e)) => self.say(
                Tone::Refused,
                format!("axis {number} refused the move: {e} (Enter to retry)"),
            ),
            Err(refusal) => self.refused(axis, "move refused", refusal),
        }
    }

    fn moved_together(&mut self, steps: &[i32], speed: u32, result: Result<Done, Refusal>) {
        let listed = steps
            .iter()
            .map(i32::to_string)
            .collect::<Vec<_>>()
            .join(" ");
        match result {
            Ok(done) => {
                self.prompt.stage = Stage::Steps;
                self.prompt.field.clear();
                self.prompt.group.clear();
                self.prompt.last_speed = Some(speed);
                for (view, steps) in self.axes.iter_mut().zip(steps) {
                    if *steps != 0 {
                        view.last_command = Some(LastCommand::Move {
                            steps: *steps,
                            speed,
                        });
                    }
                }
                let pin = if pin_raised(done) {
                    " (stop pins raised)"
                } else {
                    ""
                };
                self.say(
                    Tone::Info,
                    format!("group move {listed} at {speed} steps/s, all axes on one line{pin}"),
                );
            }
            Err(Refusal::Refused(e)) => self.say(
                Tone::Refused,
                format!("group move {listed} refused: {e} (Enter to retry)"),
            ),
            Err(refusal) => self.refused(0, "group move refused", refusal),
        }
    }

    fn jogged(&mut self, axis: usize, direction: Direction, speed: u32, now: Instant) {
        let number = axis + 1;
        let fresh = self
            .jogging
            .is_none_or(|jog| jog.axis != axis || jog.direction != direction);
        self.jogging = Some(Jogging {
            axis,
            direction,
            last_beat: now,
        });
        if let Some(view) = self.axes.get_mut(axis) {
            view.last_command = Some(LastCommand::Jog);
        }
        if fresh {
            let arrow = if direction == Direction::Forward {
                "→"
            } else {
                "←"
            };
            let how = if self.key_release {
                "release the key to stop".to_string()
            } else {
                format!("it decelerates {}", self.jog_end())
            };
            self.say(
                Tone::Info,
                format!("axis {number}: jogging {arrow} at {speed} steps/s ({how})"),
            );
        }
    }

    fn homing(&mut self, axis: usize, config: HomeConfig) {
        let number = axis + 1;
        if let Some(view) = self.axes.get_mut(axis) {
            view.last_command = Some(LastCommand::Home);
            // Homing is news until its outcome is read.
            if let Some(limits) = view.limits.as_mut() {
                limits.homing = true;
            }
        }
        self.say(
            Tone::Info,
            format!(
                "axis {number}: homing on pin {} ({}): seek at {} steps/s, latch at {} steps/s",
                config.switch_pin,
                if config.direction == Direction::Reverse {
                    "←"
                } else {
                    "→"
                },
                config.seek_speed,
                config.latch_speed
            ),
        );
    }
}

/// Whether a taken command raised a low stop pin first.
fn pin_raised(done: Done) -> bool {
    matches!(
        done,
        Done::Sent {
            stop_pin_raised: true
        }
    )
}

/// A refusal's reason, in words, where no axis is named.
fn reason(refusal: Refusal) -> String {
    match refusal {
        Refusal::NoSuchAxis => "no such axis".to_string(),
        Refusal::NoHomeSwitch => "no home switch".to_string(),
        Refusal::Unplannable(reason) | Refusal::Refused(reason) => reason,
        Refusal::StopPin { axis, reason } => format!("axis {}: {reason}", axis + 1),
    }
}

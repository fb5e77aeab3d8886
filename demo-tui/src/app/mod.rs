//! The demo's state (the "state" of the ratatui app pattern). How events
//! change it: [`update`] (keys and time into state and
//! [`Effect`](crate::effect::Effect)s), [`outcome`] (what the backend made
//! of them, as [`Outcome`](crate::effect::Outcome)s) and [`frame`] (a
//! frame's readings into readouts and velocity traces). Nothing here touches the backend,
//! and nothing here draws: [`crate::ui`] renders an [`App`] as it is.
//!
//! The input model, as the help line states it:
//! - the prompt is always active: digits go to `Enter steps:` (then
//!   `Enter speed:`), `Enter` submits, `Backspace` edits, `Esc` clears;
//! - on an empty `Enter steps:` a lone `1`–`8` (an axis number) or `-` waits
//!   [`PENDING_KEY`] for more digits: typed straight on it starts the
//!   number (`-` = negative steps), alone it acts as a key (select that
//!   axis; lower the jog speed). Any other key acts at once;
//! - `g` asks `Group steps:` instead: one signed number per axis, axis 1
//!   first, separated by spaces (spaces and `-` are then typed, not keys),
//!   then `Enter speed:`: a coordinated move of all of them at once
//!   (`Machine::move_together`); `Esc` on an empty field goes back;
//! - letters and arrows are keys: `s`, `x`, `h`, `c`, `g`, `q`, `←`/`→`,
//!   `+`/`-`, `Tab`.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use driver::{Direction, LimitStatus, Mode};

use crate::backend::MachineInfo;
use crate::effect::Readout;
use crate::motor_view::Motors;
use crate::prompt::Stage;

pub mod frame;
pub mod outcome;
pub mod program;
pub mod update;

/// How long a lone axis number or `-` on an empty `Enter steps:` waits for
/// more digits before it acts as a key.
pub const PENDING_KEY: Duration = Duration::from_millis(600);

/// The jog timeout assumed where the backend does not tell its own (a
/// board over serial): with no heartbeat for this long the axis
/// decelerates by itself (the app only stops showing "jogging").
pub const JOG_TIMEOUT: Duration = Duration::from_millis(150);

/// The jog speeds `+` and `-` step through, steps/s.
pub const JOG_SPEEDS: [u32; 11] = [
    100, 200, 500, 1_000, 2_000, 5_000, 10_000, 20_000, 50_000, 100_000, 150_000,
];

/// The default jog speed, steps/s.
pub const DEFAULT_JOG_SPEED: u32 = 5_000;

/// How much velocity history each axis keeps, seconds.
pub const TRACE_WINDOW_S: f64 = 30.0;

/// Frames stay at the full rate this long after a key, so that a move's
/// first steps are drawn even before its cog has taken the command.
pub const AFTER_KEY_ACTIVE: Duration = Duration::from_secs(1);

/// Idle longer than this between two moves starts a new velocity trace, s.
const TRACE_GAP_S: f64 = 1.0;

/// How a message reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tone {
    /// Something done.
    Info,
    /// Something that stopped motion.
    Warn,
    /// Something refused: input, or a command the axis or backend declined.
    Refused,
}

/// One line for the person at the keyboard.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Message {
    /// The text.
    pub text: String,
    /// How it reads.
    pub tone: Tone,
}

/// The last command given to an axis from this demo.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LastCommand {
    /// `move(speed, steps)`.
    Move {
        /// Steps, signed.
        steps: i32,
        /// Speed, steps/s.
        speed: u32,
    },
    /// A jog.
    Jog,
    /// Homing (`h`): the seek's travel it did not need ends in the step
    /// ledger's dropped count, which the panel then shows as the homing's
    /// unused travel, not as dropped steps.
    Home,
}

/// Velocity against time for one axis: (seconds since the demo started,
/// signed steps/s), sampled once a frame while the axis moves.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// The samples, oldest first.
    pub samples: VecDeque<(f64, f64)>,
    /// When the axis last moved, seconds.
    last_motion_s: Option<f64>,
}

impl Trace {
    /// Adds the sample of time `t_s`.
    pub fn record(&mut self, t_s: f64, velocity: f64, moving: bool) {
        if moving {
            let fresh = self
                .last_motion_s
                .is_none_or(|last| t_s - last > TRACE_GAP_S);
            if fresh {
                self.samples.clear();
            }
            if self.samples.back().is_none_or(|(_, v)| *v == 0.0) {
                // The move started since the last frame, from standstill.
                let from = self.last_sample_s().unwrap_or(t_s).max(t_s - 0.05);
                self.samples.push_back((from, 0.0));
            }
            self.samples.push_back((t_s, velocity));
            self.last_motion_s = Some(t_s);
        } else if self.samples.back().is_some_and(|(_, v)| *v != 0.0) {
            self.samples.push_back((t_s, 0.0));
        }
        while self
            .samples
            .front()
            .is_some_and(|(t, _)| *t < t_s - TRACE_WINDOW_S)
        {
            self.samples.pop_front();
        }
    }

    fn last_sample_s(&self) -> Option<f64> {
        self.samples.back().map(|(t, _)| *t)
    }
}

/// One axis as the screen shows it.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisView {
    /// Its number on screen, from 1.
    pub number: usize,
    /// Its output variant ("sd", "cc", ...).
    pub kind: String,
    /// Its pins in words.
    pub pins: String,
    /// The last readout, if the axis could be read.
    pub readout: Option<Readout>,
    /// Why the axis could not be read, if it could not.
    pub error: Option<String>,
    /// Velocity against time.
    pub trace: Trace,
    /// The last command given to it here.
    pub last_command: Option<LastCommand>,
    /// Its limit and homing state, where the backend reads it.
    pub limits: Option<LimitStatus>,
    /// Its switches pressed or not (home, min, max), where the backend reads them.
    pub switches: Option<[bool; 3]>,
}

impl AxisView {
    /// Steps still to make to reach the target of the last move after a
    /// stop (stop pin or emergency), signed, when that is known.
    pub fn remaining_after_stop(&self) -> Option<i64> {
        let readout = self.readout?;
        let Some(LastCommand::Move { steps, .. }) = self.last_command else {
            return None;
        };
        let stopped =
            readout.status.mode.has(Mode::STOP_LATCHED) || readout.status.mode.has(Mode::ESTOP);
        let dropped = readout.figures.dropped_steps?;
        if !stopped || readout.status.steps_to_go != 0 || dropped == 0 {
            return None;
        }
        Some(i64::from(dropped) * i64::from(steps.signum()))
    }

    /// Whether the axis was moving at the last frame.
    pub fn moving(&self) -> bool {
        self.readout.is_some_and(|r| {
            r.status.mode.has(Mode::MOVING)
                || r.status.steps_to_go != 0
                || r.status.velocity_steps_per_s != 0
        })
    }
}

/// A jog being held.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Jogging {
    /// The axis, by index.
    pub axis: usize,
    /// Which way.
    pub direction: Direction,
    /// When the last heartbeat was sent.
    pub last_beat: Instant,
}

/// The prompt: the question, the answer being typed, and what it remembers.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Prompt {
    /// Which question.
    pub stage: Stage,
    /// The answer typed so far.
    pub field: String,
    /// Since when a lone axis number or `-` waits for more digits.
    pub pending_since: Option<Instant>,
    /// The last speed used: an empty `Enter speed:` takes it.
    pub last_speed: Option<u32>,
    /// The answer to `Group steps:`, while `Enter speed:` asks for its speed.
    pub group: Vec<i32>,
}

impl Prompt {
    /// Whether the prompt asks for a group move.
    pub fn in_group(&self) -> bool {
        matches!(self.stage, Stage::GroupSteps | Stage::GroupSpeed)
    }
}

/// The whole demo state.
#[derive(Clone, Debug)]
pub struct App {
    /// What is being driven.
    pub info: MachineInfo,
    /// Every axis.
    pub axes: Vec<AxisView>,
    /// The selected axis, by index.
    pub selected: usize,
    /// The steps/speed prompt.
    pub prompt: Prompt,
    /// The jog speed, steps/s.
    pub jog_speed: u32,
    /// The jog being held, if any.
    pub jogging: Option<Jogging>,
    /// Whether the terminal reports key releases (kitty keyboard protocol).
    pub key_release: bool,
    /// The last message.
    pub message: Option<Message>,
    /// The backend's fault, if any.
    pub fault: Option<String>,
    /// Frames drawn in the last second.
    pub fps: usize,
    /// Seconds since the demo started, at the last frame.
    pub clock_s: f64,
    /// When the last key came.
    pub last_key: Option<Instant>,
    /// The virtual motors behind the axes (`--motor`).
    pub motors: Motors,
    /// The G-code program running (`--gcode`): the screen and the keys
    /// are then the program's.
    pub program: Option<program::ProgramView>,
    started: Instant,
    frames: VecDeque<Instant>,
}

impl App {
    /// A fresh demo over `info`'s axes, axis 1 selected.
    pub fn new(info: MachineInfo, jog_speed: u32, now: Instant) -> Self {
        let axes = info
            .axis_kinds
            .iter()
            .zip(&info.axis_pins)
            .enumerate()
            .map(|(index, (kind, pins))| AxisView {
                number: index + 1,
                kind: kind.clone(),
                pins: pins.clone(),
                readout: None,
                error: None,
                trace: Trace::default(),
                last_command: None,
                limits: None,
                switches: None,
            })
            .collect();
        Self {
            info,
            axes,
            selected: 0,
            prompt: Prompt {
                stage: Stage::Steps,
                field: String::new(),
                pending_since: None,
                last_speed: None,
                group: Vec::new(),
            },
            jog_speed: jog_speed.max(1),
            jogging: None,
            key_release: false,
            message: None,
            fault: None,
            fps: 0,
            clock_s: 0.0,
            last_key: None,
            motors: Motors::default(),
            program: None,
            started: now,
            frames: VecDeque::new(),
        }
    }

    /// How long a jog runs on after its last heartbeat.
    pub fn jog_timeout(&self) -> Duration {
        self.info.jog_timeout.unwrap_or(JOG_TIMEOUT)
    }

    /// When a jog ends, in words.
    pub fn jog_end(&self) -> String {
        if self.key_release {
            "on key release".to_string()
        } else {
            match self.info.jog_timeout {
                Some(timeout) => format!("{} ms after the last key repeat", timeout.as_millis()),
                None => "at the board's jog timeout after the last key repeat".to_string(),
            }
        }
    }

    /// The selected axis.
    pub fn selected_axis(&self) -> Option<&AxisView> {
        self.axes.get(self.selected)
    }

    /// Whether something moves, waits, or was just asked for: the screen
    /// then redraws at the full frame rate.
    pub fn active(&self, now: Instant) -> bool {
        self.last_key
            .is_some_and(|key| now.saturating_duration_since(key) < AFTER_KEY_ACTIVE)
            || self.jogging.is_some()
            || self.prompt.pending_since.is_some()
            || self.axes.iter().any(AxisView::moving)
            || self.program_active()
    }

    /// When the app next needs a tick regardless of input.
    pub fn next_deadline(&self) -> Option<Instant> {
        self.prompt.pending_since.map(|since| since + PENDING_KEY)
    }

    fn say(&mut self, tone: Tone, text: impl Into<String>) {
        self.message = Some(Message {
            text: text.into(),
            tone,
        });
    }
}

/// `min` or `max`: the limit met moving that way.
pub fn side_name(side: Direction) -> &'static str {
    match side {
        Direction::Forward => "max",
        Direction::Reverse => "min",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_trace_follows_a_move_and_freezes_when_idle() {
        let mut trace = Trace::default();
        trace.record(1.0, 0.0, false);
        assert!(trace.samples.is_empty());
        trace.record(1.1, 500.0, true);
        trace.record(1.2, 900.0, true);
        trace.record(1.3, 0.0, false);
        trace.record(1.4, 0.0, false);
        let samples: Vec<(f64, f64)> = trace.samples.iter().copied().collect();
        assert_eq!(samples.len(), 4, "{samples:?}");
        assert_eq!(samples[0].1, 0.0);
        assert_eq!(samples.last(), Some(&(1.3, 0.0)));
        // A move after a long pause starts a new trace.
        trace.record(5.0, 100.0, true);
        assert_eq!(trace.samples.len(), 2);
    }
}

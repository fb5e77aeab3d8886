//! The demo's state, and how events change it (the "update" of the
//! ratatui app pattern). Keys turn into axis commands through the
//! [`Machine`]; each frame's samples turn into readouts and velocity traces.
//! Nothing here draws: [`crate::ui`] renders an [`App`] as it is.
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
//! - letters and arrows are keys: `s`, `x`, `q`, `g`, `←`/`→`, `+`/`-`, `Tab`.
//! - letters and arrows are keys: `s`, `x`, `h`, `c`, `q`, `←`/`→`, `+`/`-`, `Tab`.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use crossterm::event::{KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
use driver::{AxisStatus, Direction, LimitStatus, Mode};

use crate::backend::{Machine, MachineInfo, MoveFigures};
use crate::motor_view::Motors;
use crate::prompt::{
    parse_group_steps, parse_speed, parse_steps, Stage, FIELD_MAX, GROUP_FIELD_MAX,
};

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

/// What an axis showed at the last frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Readout {
    /// Position, STM, mode, velocity and stop pin.
    pub status: AxisStatus,
    /// The reference demo's move figures.
    pub figures: MoveFigures,
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
    /// Set when the demo should end.
    pub quit: bool,
    /// When the last key came.
    pub last_key: Option<Instant>,
    /// The virtual motors behind the axes (`--motor`).
    pub motors: Motors,
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
            quit: false,
            last_key: None,
            motors: Motors::default(),
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

    /// Handles one key event.
    pub fn on_key(&mut self, key: KeyEvent, now: Instant, machine: &dyn Machine) {
        self.last_key = Some(now);
        if key.kind == KeyEventKind::Release {
            if matches!(key.code, KeyCode::Left | KeyCode::Right) {
                self.release_jog(machine);
            }
            return;
        }
        let key = if key.modifiers.contains(KeyModifiers::CONTROL) {
            // In raw mode LF reads as Ctrl-J and BS as Ctrl-H: a terminal
            // (or a script) that sends them means Enter and Backspace.
            match key.code {
                KeyCode::Char('c' | 'C') => {
                    self.quit = true;
                    return;
                }
                KeyCode::Char('j' | 'm') => KeyEvent::new(KeyCode::Enter, KeyModifiers::NONE),
                KeyCode::Char('h') => KeyEvent::new(KeyCode::Backspace, KeyModifiers::NONE),
                _ => return,
            }
        } else {
            key
        };
        if self.prompt.pending_since.is_some() {
            let continues_number = matches!(
                key.code,
                KeyCode::Char('0'..='9') | KeyCode::Enter | KeyCode::Backspace | KeyCode::Esc
            );
            if continues_number {
                self.prompt.pending_since = None;
            } else {
                self.resolve_pending(machine);
            }
        }
        match key.code {
            KeyCode::Char(c @ ('-' | ' ')) if self.prompt.stage == Stage::GroupSteps => {
                self.type_group_char(c)
            }
            KeyCode::Char(c @ '0'..='9') => self.type_digit(c, now),
            KeyCode::Char('g' | 'G') => self.ask_group(),
            KeyCode::Char('-') => {
                if self.prompt.stage == Stage::Steps && self.prompt.field.is_empty() {
                    self.prompt.field.push('-');
                    self.prompt.pending_since = Some(now);
                } else {
                    self.jog_speed_down();
                }
            }
            KeyCode::Char('+' | '=') => self.jog_speed_up(),
            KeyCode::Char('s' | 'S') => self.stop(machine),
            KeyCode::Char('x' | 'X') => self.emergency_stop(machine),
            KeyCode::Char('h' | 'H') => self.home(machine),
            KeyCode::Char('c' | 'C') => self.clear_limit_fault(machine),
            KeyCode::Char('q' | 'Q') => self.quit = true,
            KeyCode::Tab => self.select((self.selected + 1) % self.axes.len().max(1)),
            KeyCode::BackTab => {
                let count = self.axes.len().max(1);
                self.select((self.selected + count - 1) % count);
            }
            KeyCode::Left => self.jog(Direction::Reverse, now, machine),
            KeyCode::Right => self.jog(Direction::Forward, now, machine),
            KeyCode::Enter => self.submit(machine),
            KeyCode::Backspace => {
                self.prompt.field.pop();
            }
            KeyCode::Esc => {
                if self.prompt.field.is_empty() {
                    self.prompt.stage = Stage::Steps;
                    self.prompt.group.clear();
                }
                self.prompt.field.clear();
                self.message = None;
            }
            KeyCode::Char(c) if !c.is_control() => self.say(
                Tone::Refused,
                format!("'{c}' is not a key here: type digits at the prompt (keys below)"),
            ),
            _ => {}
        }
    }

    /// Time passes: a lone key that waited long enough acts; a jog whose
    /// heartbeats stopped is over.
    pub fn on_tick(&mut self, now: Instant, machine: &dyn Machine) {
        if self
            .prompt
            .pending_since
            .is_some_and(|since| now.duration_since(since) >= PENDING_KEY)
        {
            self.resolve_pending(machine);
        }
        if self
            .jogging
            .is_some_and(|jog| now.duration_since(jog.last_beat) > self.jog_timeout())
        {
            self.jogging = None;
        }
    }

    /// A frame: reads every axis and the backend's fault.
    pub fn sample(&mut self, now: Instant, machine: &dyn Machine) {
        let readouts: Vec<Result<Readout, String>> = (0..self.axes.len())
            .map(|index| match machine.axis(index) {
                Some(axis) => axis
                    .status()
                    .map(|status| Readout {
                        status,
                        figures: machine.figures(index),
                    })
                    .map_err(|e| e.to_string()),
                None => Err("no such axis on this backend".to_string()),
            })
            .collect();
        self.motors.update(machine);
        self.apply(now, readouts, machine.fault());
        let limits: Vec<_> = (0..self.axes.len())
            .map(|index| (machine.limit_status(index), machine.switches(index)))
            .collect();
        self.apply_limits(limits);
    }

    /// A frame's limit and switch readings: news (a limit tripped, homing
    /// ended) becomes the message.
    pub fn apply_limits(&mut self, readings: Vec<(Option<LimitStatus>, Option<[bool; 3]>)>) {
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

    /// `h`: homes the selected axis on its home switch.
    fn home(&mut self, machine: &dyn Machine) {
        let number = self.selected + 1;
        let (Some(axis), Some(config)) = (
            machine.axis(self.selected),
            machine.home_config(self.selected),
        ) else {
            self.say(
                Tone::Refused,
                format!("axis {number}: no home switch on this backend"),
            );
            return;
        };
        if let Err(reason) = raise_stop_pin(axis) {
            self.say(Tone::Refused, format!("axis {number}: {reason}"));
            return;
        }
        match axis.home(config) {
            Ok(()) => {
                if let Some(view) = self.axes.get_mut(self.selected) {
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
                        if config.direction == Direction::Reverse { "←" } else { "→" },
                        config.seek_speed,
                        config.latch_speed
                    ),
                );
            }
            Err(e) => self.say(Tone::Refused, format!("axis {number}: homing refused: {e}")),
        }
    }

    /// `c`: clears the selected axis's tripped hard limit.
    fn clear_limit_fault(&mut self, machine: &dyn Machine) {
        let number = self.selected + 1;
        let Some(axis) = machine.axis(self.selected) else {
            return;
        };
        match axis.clear_limit_fault() {
            Ok(()) => self.say(Tone::Info, format!("axis {number}: limit fault cleared")),
            Err(e) => self.say(Tone::Refused, format!("axis {number}: clear refused: {e}")),
        }
    }

    /// A frame's samples, as read (split from [`App::sample`] for tests).
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

    /// `g`: the prompt asks for one number of steps per axis.
    fn ask_group(&mut self) {
        if self.prompt.in_group() {
            self.say(
                Tone::Refused,
                "already asking for a group move (Esc goes back)",
            );
            return;
        }
        self.prompt.stage = Stage::GroupSteps;
        self.prompt.field.clear();
        self.prompt.pending_since = None;
        self.say(
            Tone::Info,
            format!(
                "group move: one number of steps per axis, axis 1 first ({} axes), 0 keeps an axis still",
                self.axes.len()
            ),
        );
    }

    /// A space or `-` typed at `Group steps:`.
    fn type_group_char(&mut self, c: char) {
        if self.prompt.field.len() >= GROUP_FIELD_MAX {
            self.say(
                Tone::Refused,
                "that is already as long as the answer can be",
            );
            return;
        }
        self.prompt.field.push(c);
    }

    fn type_digit(&mut self, digit: char, now: Instant) {
        if self.prompt.stage == Stage::GroupSteps {
            return self.type_group_char(digit);
        }
        if self.prompt.field.len() >= FIELD_MAX {
            self.say(Tone::Refused, "that is already as long as a number can be");
            return;
        }
        let axis_number = digit.to_digit(10).map_or(0, |d| d as usize);
        let could_select = self.prompt.stage == Stage::Steps
            && self.prompt.field.is_empty()
            && self.axes.len() > 1
            && (1..=self.axes.len().min(8)).contains(&axis_number);
        self.prompt.field.push(digit);
        if could_select {
            self.prompt.pending_since = Some(now);
        }
    }

    /// A lone axis number or `-` acts as a key.
    fn resolve_pending(&mut self, _machine: &dyn Machine) {
        self.prompt.pending_since = None;
        let field = std::mem::take(&mut self.prompt.field);
        match field.as_str() {
            "-" => self.jog_speed_down(),
            number => {
                if let Some(index) = number
                    .parse::<usize>()
                    .ok()
                    .and_then(|n| n.checked_sub(1))
                    .filter(|index| *index < self.axes.len())
                {
                    self.select(index);
                }
            }
        }
    }

    fn select(&mut self, index: usize) {
        if index < self.axes.len() {
            self.selected = index;
        }
    }

    fn jog_speed_up(&mut self) {
        let next = JOG_SPEEDS
            .iter()
            .copied()
            .find(|speed| *speed > self.jog_speed);
        match next.filter(|speed| self.info.max_speed.is_none_or(|max| *speed <= max)) {
            Some(speed) => {
                self.jog_speed = speed;
                self.say(Tone::Info, format!("jog speed {speed} steps/s"));
            }
            None => self.say(
                Tone::Refused,
                format!("jog speed {} steps/s is the highest", self.jog_speed),
            ),
        }
    }

    fn jog_speed_down(&mut self) {
        match JOG_SPEEDS
            .iter()
            .rev()
            .copied()
            .find(|speed| *speed < self.jog_speed)
        {
            Some(speed) => {
                self.jog_speed = speed;
                self.say(Tone::Info, format!("jog speed {speed} steps/s"));
            }
            None => self.say(
                Tone::Refused,
                format!("jog speed {} steps/s is the lowest", self.jog_speed),
            ),
        }
    }

    fn submit(&mut self, machine: &dyn Machine) {
        match self.prompt.stage {
            Stage::GroupSteps => match parse_group_steps(&self.prompt.field, self.axes.len()) {
                Ok(steps) => {
                    self.prompt.group = steps;
                    self.prompt.stage = Stage::GroupSpeed;
                    self.prompt.field.clear();
                    self.message = None;
                }
                Err(reason) => self.say(Tone::Refused, reason),
            },
            Stage::GroupSpeed => {
                let lead = self
                    .prompt
                    .group
                    .iter()
                    .copied()
                    .max_by_key(|steps| steps.unsigned_abs())
                    .unwrap_or(0);
                let speed = parse_speed(
                    &self.prompt.field,
                    self.prompt.last_speed,
                    self.info.max_speed,
                )
                .and_then(|speed| machine.check_move(speed, lead).map(|()| speed));
                match speed {
                    Ok(speed) => self.send_group(speed, machine),
                    Err(reason) => self.say(Tone::Refused, reason),
                }
            }
            Stage::Steps => match parse_steps(&self.prompt.field) {
                Ok(steps) => {
                    self.prompt.stage = Stage::Speed { steps };
                    self.prompt.field.clear();
                    self.message = None;
                }
                Err(reason) => self.say(Tone::Refused, reason),
            },
            Stage::Speed { steps } => {
                let speed = parse_speed(
                    &self.prompt.field,
                    self.prompt.last_speed,
                    self.info.max_speed,
                )
                .and_then(|speed| machine.check_move(speed, steps).map(|()| speed));
                match speed {
                    Ok(speed) => self.send_move(speed, steps, machine),
                    Err(reason) => self.say(Tone::Refused, reason),
                }
            }
        }
    }

    fn send_move(&mut self, speed: u32, steps: i32, machine: &dyn Machine) {
        let index = self.selected;
        let number = index + 1;
        let Some(axis) = machine.axis(index) else {
            self.say(Tone::Refused, format!("axis {number} does not exist"));
            return;
        };
        // The stop key left the pin low: this move raises it again (where
        // the backend drives the stop pin at all).
        let raised = match self.info.capabilities.stop_pin {
            Some(_) => Ok(false),
            None => raise_stop_pin(axis),
        };
        let raised = match raised {
            Ok(raised) => raised,
            Err(reason) => {
                self.say(Tone::Refused, format!("axis {number}: {reason}"));
                return;
            }
        };
        match axis.move_steps(speed, steps) {
            Ok(()) => {
                self.prompt.stage = Stage::Steps;
                self.prompt.field.clear();
                self.prompt.last_speed = Some(speed);
                if let Some(view) = self.axes.get_mut(index) {
                    view.last_command = Some(LastCommand::Move { steps, speed });
                }
                let pin = if raised { " (stop pin raised)" } else { "" };
                self.say(
                    Tone::Info,
                    format!("axis {number}: move {steps} steps at {speed} steps/s{pin}"),
                );
            }
            Err(e) => self.say(
                Tone::Refused,
                format!("axis {number} refused the move: {e} (Enter to retry)"),
            ),
        }
    }

    fn send_group(&mut self, speed: u32, machine: &dyn Machine) {
        let steps = self.prompt.group.clone();
        let mut raised = false;
        if self.info.capabilities.stop_pin.is_none() {
            // A stop key left a pin low: the group move raises it (every
            // member's pin must be high for the move to be taken).
            for index in 0..steps.len() {
                let Some(axis) = machine.axis(index) else {
                    continue;
                };
                match raise_stop_pin(axis) {
                    Ok(was_low) => raised |= was_low,
                    Err(reason) => {
                        self.say(Tone::Refused, format!("axis {}: {reason}", index + 1));
                        return;
                    }
                }
            }
        }
        let listed = steps
            .iter()
            .map(i32::to_string)
            .collect::<Vec<_>>()
            .join(" ");
        match machine.move_together(&steps, speed) {
            Ok(()) => {
                self.prompt.stage = Stage::Steps;
                self.prompt.field.clear();
                self.prompt.group.clear();
                self.prompt.last_speed = Some(speed);
                for (view, steps) in self.axes.iter_mut().zip(&steps) {
                    if *steps != 0 {
                        view.last_command = Some(LastCommand::Move {
                            steps: *steps,
                            speed,
                        });
                    }
                }
                let pin = if raised { " (stop pins raised)" } else { "" };
                self.say(
                    Tone::Info,
                    format!("group move {listed} at {speed} steps/s, all axes on one line{pin}"),
                );
            }
            Err(e) => self.say(
                Tone::Refused,
                format!("group move {listed} refused: {e} (Enter to retry)"),
            ),
        }
    }

    fn stop(&mut self, machine: &dyn Machine) {
        let number = self.selected + 1;
        if let Some(reason) = &self.info.capabilities.stop_pin {
            let text = format!("stop: {reason}");
            self.say(Tone::Refused, text);
            return;
        }
        let Some(axis) = machine.axis(self.selected) else {
            return;
        };
        match axis.set_stop_pin(false) {
            Ok(()) => self.say(
                Tone::Warn,
                format!(
                    "axis {number}: stop pin low: decelerating under control; the next move raises it"
                ),
            ),
            Err(e) => self.say(Tone::Refused, format!("axis {number}: stop refused: {e}")),
        }
    }

    fn emergency_stop(&mut self, machine: &dyn Machine) {
        if let Some(reason) = &self.info.capabilities.emergency_stop {
            let text = format!("emergency stop: {reason}");
            self.say(Tone::Refused, text);
            return;
        }
        self.jogging = None;
        match machine.emergency_stop_all() {
            Ok(()) => self.say(
                Tone::Warn,
                "EMERGENCY STOP: every axis halted, positions kept; the next move clears it",
            ),
            Err(e) => self.say(Tone::Refused, format!("emergency stop failed: {e}")),
        }
    }

    fn jog(&mut self, direction: Direction, now: Instant, machine: &dyn Machine) {
        let number = self.selected + 1;
        if let Some(reason) = &self.info.capabilities.jog {
            let text = format!("jog: {reason}");
            self.say(Tone::Refused, text);
            return;
        }
        let Some(axis) = machine.axis(self.selected) else {
            return;
        };
        if let Err(reason) = raise_stop_pin(axis) {
            self.say(Tone::Refused, format!("axis {number}: {reason}"));
            return;
        }
        match axis.jog(self.jog_speed, direction) {
            Ok(()) => {
                let fresh = self
                    .jogging
                    .is_none_or(|jog| jog.axis != self.selected || jog.direction != direction);
                self.jogging = Some(Jogging {
                    axis: self.selected,
                    direction,
                    last_beat: now,
                });
                if let Some(view) = self.axes.get_mut(self.selected) {
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
                        format!(
                            "axis {number}: jogging {arrow} at {} steps/s ({how})",
                            self.jog_speed
                        ),
                    );
                }
            }
            Err(e) => self.say(Tone::Refused, format!("axis {number}: jog refused: {e}")),
        }
    }

    fn release_jog(&mut self, machine: &dyn Machine) {
        let Some(jog) = self.jogging.take() else {
            return;
        };
        let number = jog.axis + 1;
        let result = machine
            .axis(jog.axis)
            .map_or(Ok(()), |axis| axis.jog_release());
        match result {
            Ok(()) => self.say(
                Tone::Info,
                format!("axis {number}: jog released (key up): decelerating"),
            ),
            Err(e) => self.say(Tone::Refused, format!("axis {number}: jog release: {e}")),
        }
    }
}

/// `min` or `max`: the limit met moving that way.
pub fn side_name(side: Direction) -> &'static str {
    match side {
        Direction::Forward => "max",
        Direction::Reverse => "min",
    }
}

/// Raises an axis's stop pin if it is low; tells whether it was.
fn raise_stop_pin(axis: &dyn driver::AxisContract) -> Result<bool, String> {
    let status = axis.status().map_err(|e| e.to_string())?;
    if status.stop_pin_high {
        return Ok(false);
    }
    axis.set_stop_pin(true)
        .map(|()| true)
        .map_err(|e| format!("could not raise the stop pin: {e}"))
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;

    use driver::{AxisContract, AxisError};

    use super::*;
    use crate::backend::Capabilities;

    /// Records what the app asks of each axis.
    #[derive(Default)]
    struct FakeAxis {
        calls: RefCell<Vec<String>>,
        stop_pin_high: RefCell<bool>,
    }

    impl AxisContract for FakeAxis {
        fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
            self.calls
                .borrow_mut()
                .push(format!("move {speed} {steps}"));
            Ok(())
        }
        fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError> {
            self.calls
                .borrow_mut()
                .push(format!("jog {speed} {direction:?}"));
            Ok(())
        }
        fn jog_release(&self) -> Result<(), AxisError> {
            self.calls.borrow_mut().push("jog_release".into());
            Ok(())
        }
        fn set_stop_pin(&self, high: bool) -> Result<(), AxisError> {
            self.calls.borrow_mut().push(format!("stop_pin {high}"));
            *self.stop_pin_high.borrow_mut() = high;
            Ok(())
        }
        fn emergency_stop(&self) -> Result<(), AxisError> {
            self.calls.borrow_mut().push("estop".into());
            Ok(())
        }
        fn set_position(&self, _: i64) -> Result<(), AxisError> {
            Ok(())
        }
        fn status(&self) -> Result<AxisStatus, AxisError> {
            Ok(AxisStatus {
                position: 0,
                stm: 0,
                steps_to_go: 0,
                mode: Mode(0),
                velocity_steps_per_s: 0,
                stop_pin_high: *self.stop_pin_high.borrow(),
            })
        }
    }

    struct FakeMachine {
        info: MachineInfo,
        axes: Vec<FakeAxis>,
        estops: RefCell<usize>,
        groups: RefCell<Vec<(Vec<i32>, u32)>>,
    }

    fn fake(count: usize, capabilities: Capabilities) -> FakeMachine {
        FakeMachine {
            info: MachineInfo {
                title: "fake".into(),
                clkfreq_hz: 200_000_000,
                capabilities,
                max_speed: Some(199_600),
                axis_kinds: vec!["sd".into(); count],
                axis_pins: vec!["pins".into(); count],
                jog_timeout: Some(JOG_TIMEOUT),
            },
            axes: (0..count)
                .map(|_| FakeAxis {
                    stop_pin_high: RefCell::new(true),
                    ..FakeAxis::default()
                })
                .collect(),
            estops: RefCell::new(0),
            groups: RefCell::new(Vec::new()),
        }
    }

    impl Machine for FakeMachine {
        fn info(&self) -> &MachineInfo {
            &self.info
        }
        fn axis(&self, index: usize) -> Option<&dyn AxisContract> {
            self.axes.get(index).map(|a| a as &dyn AxisContract)
        }
        fn figures(&self, _: usize) -> MoveFigures {
            MoveFigures::default()
        }
        fn emergency_stop_all(&self) -> Result<(), AxisError> {
            *self.estops.borrow_mut() += 1;
            Ok(())
        }
        fn fault(&self) -> Option<String> {
            None
        }
        fn check_move(&self, _: u32, _: i32) -> Result<(), String> {
            Ok(())
        }
        fn move_together(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
            self.groups.borrow_mut().push((steps.to_vec(), speed));
            Ok(())
        }
    }

    #[test]
    fn g_asks_one_line_of_steps_then_the_speed_and_moves_all_axes() {
        let machine = fake(3, Capabilities::all());
        let t0 = Instant::now();
        let mut app = App::new(machine.info.clone(), 5_000, t0);
        machine.axes[1].set_stop_pin(false).unwrap();
        type_keys(&mut app, &machine, "g", t0);
        assert_eq!(app.prompt.stage, Stage::GroupSteps);
        // Spaces and '-' are typed here, not keys; a lone digit selects nothing.
        type_keys(&mut app, &machine, "2000 -500 0\r", t0);
        assert_eq!(app.prompt.stage, Stage::GroupSpeed);
        assert_eq!(app.prompt.group, [2000, -500, 0]);
        assert_eq!(app.jog_speed, 5_000);
        type_keys(&mut app, &machine, "8000\r", t0);
        assert_eq!(*machine.groups.borrow(), [(vec![2000, -500, 0], 8_000)]);
        assert_eq!(app.prompt.stage, Stage::Steps);
        // The low stop pin was raised first.
        assert_eq!(calls(&machine, 1), ["stop_pin false", "stop_pin true"]);
        assert_eq!(
            app.axes[1].last_command,
            Some(LastCommand::Move {
                steps: -500,
                speed: 8_000
            })
        );
        assert_eq!(app.axes[2].last_command, None);
        // Refusals keep the prompt; an empty speed takes the last one.
        type_keys(&mut app, &machine, "g0 0\r", t0);
        assert_eq!(app.prompt.stage, Stage::GroupSteps);
        assert!(app
            .message
            .as_ref()
            .unwrap()
            .text
            .contains("nothing to move"));
        app.on_key(key(KeyCode::Esc), t0, &machine);
        app.on_key(key(KeyCode::Esc), t0, &machine);
        assert_eq!(app.prompt.stage, Stage::Steps);
        type_keys(&mut app, &machine, "g1 1 1 1\r", t0);
        assert!(app
            .message
            .as_ref()
            .unwrap()
            .text
            .contains("4 numbers for 3 axes"));
        app.prompt.field.clear();
        type_keys(&mut app, &machine, "5\r\r", t0);
        assert_eq!(machine.groups.borrow()[1], (vec![5], 8_000));
    }

    fn key(code: KeyCode) -> KeyEvent {
        KeyEvent::new(code, KeyModifiers::NONE)
    }

    fn type_keys(app: &mut App, machine: &FakeMachine, text: &str, now: Instant) {
        for c in text.chars() {
            let code = match c {
                '\r' => KeyCode::Enter,
                '\t' => KeyCode::Tab,
                c => KeyCode::Char(c),
            };
            app.on_key(key(code), now, machine);
        }
    }

    fn calls(machine: &FakeMachine, axis: usize) -> Vec<String> {
        machine.axes[axis].calls.borrow().clone()
    }

    #[test]
    fn typed_straight_on_digits_make_a_move_on_the_selected_axis() {
        let machine = fake(4, Capabilities::all());
        let t0 = Instant::now();
        let mut app = App::new(machine.info.clone(), 5_000, t0);
        type_keys(&mut app, &machine, "2000\r", t0);
        assert_eq!(app.prompt.stage, Stage::Speed { steps: 2000 });
        // A line feed (Ctrl-J in raw mode) submits too.
        type_keys(&mut app, &machine, "20000", t0);
        app.on_key(
            KeyEvent::new(KeyCode::Char('j'), KeyModifiers::CONTROL),
            t0,
            &machine,
        );
        assert_eq!(calls(&machine, 0), ["move 20000 2000"]);
        assert_eq!(app.prompt.stage, Stage::Steps);
        assert!(
            app.active(t0),
            "full frame rate at once, before the cog moves"
        );
        assert!(!app.active(t0 + AFTER_KEY_ACTIVE), "idle again");
        assert_eq!(app.selected, 0, "typing a number selects nothing");
        // A negative number, and Enter on an empty speed takes the last one.
        type_keys(&mut app, &machine, "-500\r\r", t0);
        assert_eq!(calls(&machine, 0), ["move 20000 2000", "move 20000 -500"]);
    }

    #[test]
    fn a_lone_axis_number_selects_after_the_pause() {
        let machine = fake(4, Capabilities::all());
        let t0 = Instant::now();
        let mut app = App::new(machine.info.clone(), 5_000, t0);
        type_keys(&mut app, &machine, "3", t0);
        app.on_tick(t0 + PENDING_KEY / 2, &machine);
        assert_eq!(app.selected, 0);
        assert_eq!(app.prompt.field, "3");
        app.on_tick(t0 + PENDING_KEY, &machine);
        assert_eq!(app.selected, 2);
        assert_eq!(app.prompt.field, "");
        // A key other than a digit resolves it at once: "2" then → jogs axis 2.
        type_keys(&mut app, &machine, "2", t0);
        app.on_key(key(KeyCode::Right), t0, &machine);
        assert_eq!(app.selected, 1);
        assert_eq!(calls(&machine, 1), ["jog 5000 Forward"]);
        // 9 is never an axis number; with 4 axes neither is 5.
        type_keys(&mut app, &machine, "5", t0);
        app.on_tick(t0 + PENDING_KEY * 2, &machine);
        assert_eq!((app.selected, app.prompt.field.as_str()), (1, "5"));
        // Tab and Shift-Tab cycle.
        app.on_key(key(KeyCode::Esc), t0, &machine);
        type_keys(&mut app, &machine, "\t\t\t", t0);
        assert_eq!(app.selected, 0);
        app.on_key(key(KeyCode::BackTab), t0, &machine);
        assert_eq!(app.selected, 3);
    }

    #[test]
    fn minus_is_a_sign_on_an_empty_steps_field_and_jog_speed_elsewhere() {
        let machine = fake(2, Capabilities::all());
        let t0 = Instant::now();
        let mut app = App::new(machine.info.clone(), 5_000, t0);
        type_keys(&mut app, &machine, "+", t0);
        assert_eq!(app.jog_speed, 10_000);
        type_keys(&mut app, &machine, "-", t0);
        app.on_tick(t0 + PENDING_KEY, &machine);
        assert_eq!(app.jog_speed, 5_000, "a lone '-' lowers the jog speed");
        type_keys(&mut app, &machine, "12-", t0);
        assert_eq!(app.jog_speed, 2_000);
        assert_eq!(app.prompt.field, "12");
        app.on_key(key(KeyCode::Esc), t0, &machine);
        type_keys(&mut app, &machine, "-7\r", t0);
        assert_eq!(app.prompt.stage, Stage::Speed { steps: -7 });
        type_keys(&mut app, &machine, "-", t0);
        assert_eq!(app.jog_speed, 1_000, "'-' is never a sign at Enter speed:");
    }

    #[test]
    fn invalid_answers_are_refused_at_the_prompt_and_nothing_is_sent() {
        let machine = fake(1, Capabilities::all());
        let t0 = Instant::now();
        let mut app = App::new(machine.info.clone(), 5_000, t0);
        type_keys(&mut app, &machine, "0\r", t0);
        assert_eq!(app.prompt.stage, Stage::Steps);
        let message = app.message.clone().expect("a reason");
        assert_eq!(message.tone, Tone::Refused);
        assert!(message.text.contains("nothing to move"));
        app.on_key(key(KeyCode::Esc), t0, &machine);
        type_keys(&mut app, &machine, "100\r0\r", t0);
        assert_eq!(app.prompt.stage, Stage::Speed { steps: 100 });
        assert!(app
            .message
            .clone()
            .expect("reason")
            .text
            .contains("at least 1"));
        type_keys(&mut app, &machine, "\r", t0); // field still "0"
        app.on_key(key(KeyCode::Backspace), t0, &machine);
        type_keys(&mut app, &machine, "999999\r", t0);
        assert!(app
            .message
            .clone()
            .expect("reason")
            .text
            .contains("too fast"));
        type_keys(&mut app, &machine, "a", t0);
        assert!(app
            .message
            .clone()
            .expect("reason")
            .text
            .contains("not a key"));
        assert!(calls(&machine, 0).is_empty());
        assert!(!app.quit);
    }

    #[test]
    fn stop_pulls_the_pin_low_and_the_next_move_raises_it() {
        let machine = fake(2, Capabilities::all());
        let t0 = Instant::now();
        let mut app = App::new(machine.info.clone(), 5_000, t0);
        type_keys(&mut app, &machine, "s", t0);
        assert_eq!(calls(&machine, 0), ["stop_pin false"]);
        type_keys(&mut app, &machine, "100\r1000\r", t0);
        assert_eq!(
            calls(&machine, 0),
            ["stop_pin false", "stop_pin true", "move 1000 100"]
        );
        type_keys(&mut app, &machine, "x", t0);
        assert_eq!(*machine.estops.borrow(), 1);
        type_keys(&mut app, &machine, "q", t0);
        assert!(app.quit);
    }

    #[test]
    fn jog_beats_on_each_press_or_repeat_and_release_ends_it() {
        let machine = fake(1, Capabilities::all());
        let t0 = Instant::now();
        let mut app = App::new(machine.info.clone(), 5_000, t0);
        let repeat =
            KeyEvent::new_with_kind(KeyCode::Left, KeyModifiers::NONE, KeyEventKind::Repeat);
        let release =
            KeyEvent::new_with_kind(KeyCode::Left, KeyModifiers::NONE, KeyEventKind::Release);
        app.on_key(key(KeyCode::Left), t0, &machine);
        app.on_key(repeat, t0 + Duration::from_millis(30), &machine);
        assert!(app.jogging.is_some());
        app.on_key(release, t0 + Duration::from_millis(60), &machine);
        assert_eq!(
            calls(&machine, 0),
            ["jog 5000 Reverse", "jog 5000 Reverse", "jog_release"]
        );
        assert!(app.jogging.is_none());
        // Without a release the display ends after the hub's timeout.
        app.on_key(key(KeyCode::Right), t0, &machine);
        app.on_tick(t0 + JOG_TIMEOUT + Duration::from_millis(1), &machine);
        assert!(app.jogging.is_none());
    }

    #[test]
    fn what_the_backend_cannot_do_is_refused_with_the_reason() {
        let machine = fake(
            1,
            Capabilities {
                stop_pin: Some("not supported by this board (a pin)".into()),
                jog: Some("not supported by this board (a pin)".into()),
                emergency_stop: None,
            },
        );
        let t0 = Instant::now();
        let mut app = App::new(machine.info.clone(), 5_000, t0);
        type_keys(&mut app, &machine, "s", t0);
        assert_eq!(
            app.message.clone().expect("reason").text,
            "stop: not supported by this board (a pin)"
        );
        app.on_key(key(KeyCode::Right), t0, &machine);
        assert!(app
            .message
            .clone()
            .expect("reason")
            .text
            .starts_with("jog: "));
        assert!(calls(&machine, 0).is_empty());
    }

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

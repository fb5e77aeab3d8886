//! `--gcode`: the program's keys, outcomes and readings into the state,
//! pure as the rest of the update. Keys (the screen lists them):
//! space or `s` holds (space resumes once held), `r` resumes, `c` or
//! `Esc` cancels, `+`/`-` change the feed override by 10 %, `x` stops at
//! once, `q` quits (stopping the axes at once if they move).

use std::sync::Arc;

use crossterm::event::{KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
use driver::planner::PathState;

use super::{App, Tone};
use crate::effect::{Command, Done, Effect, Refusal};
use crate::program::{PathCommand, PathReading, Program};

/// The feed override's steps, percent.
pub const FEED_STEP_PERCENT: u32 = 10;
/// The feed override's range, percent.
pub const FEED_RANGE_PERCENT: (u32, u32) = (10, 200);

/// Where a program stands, as the screen says it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RunState {
    /// Lines are running (or about to).
    Run,
    /// Decelerating along the path to rest (a hold, or a cancel).
    Hold,
    /// At rest on the path: space or `r` goes on.
    Held,
    /// Every line made, the axes at rest.
    Done,
    /// Cancelled (or stopped at once), the axes at rest.
    Cancelled,
    /// Stopped by a fault, or a line the path refused at run time.
    Fault(String),
}

impl RunState {
    /// The word on screen.
    pub fn word(&self) -> &'static str {
        match self {
            RunState::Run => "Run",
            RunState::Hold => "Hold",
            RunState::Held => "Held",
            RunState::Done => "Done",
            RunState::Cancelled => "Cancelled",
            RunState::Fault(_) => "Fault",
        }
    }

    /// Whether nothing more will move.
    pub fn is_over(&self) -> bool {
        matches!(
            self,
            RunState::Done | RunState::Cancelled | RunState::Fault(_)
        )
    }
}

/// A program as the screen shows it.
#[derive(Clone, Debug, PartialEq)]
pub struct ProgramView {
    /// The program (shared: the app is copied to the screen every frame).
    pub program: Arc<Program>,
    /// The last frame's reading of its path.
    pub reading: Option<PathReading>,
    /// The feed override asked for, percent.
    pub feed_percent: u32,
}

impl ProgramView {
    /// A program not started.
    pub fn new(program: Program) -> Self {
        Self {
            program: Arc::new(program),
            reading: None,
            feed_percent: 100,
        }
    }
}

impl App {
    /// The program's state at the last frame (`None` without `--gcode`).
    pub fn run_state(&self) -> Option<RunState> {
        let view = self.program.as_ref()?;
        let Some(reading) = &view.reading else {
            return Some(RunState::Run);
        };
        if let Some(fault) = reading.progress.fault {
            return Some(if reading.stopped {
                RunState::Cancelled
            } else {
                RunState::Fault(fault.to_string())
            });
        }
        if let Some((_, error)) = &reading.error {
            return Some(RunState::Fault(error.clone()));
        }
        let moving = self.axes.iter().any(super::AxisView::moving);
        Some(match reading.progress.state {
            PathState::Running => RunState::Run,
            PathState::Holding => RunState::Hold,
            PathState::Held if reading.stopped => RunState::Hold,
            PathState::Held => RunState::Held,
            PathState::Idle if moving => RunState::Run,
            PathState::Idle if reading.stopped => RunState::Cancelled,
            PathState::Idle if reading.fed_all => RunState::Done,
            PathState::Idle => RunState::Run,
        })
    }

    /// `line n of N`'s n: the line running; every line once done.
    pub fn program_line(&self) -> usize {
        let Some(view) = &self.program else { return 0 };
        if self.run_state() == Some(RunState::Done) {
            return view.program.line_count();
        }
        view.reading.as_ref().map_or(0, |reading| {
            let running = reading.progress.tag;
            (if running > 0 {
                running
            } else {
                reading.fed_line
            }) as usize
        })
    }

    /// The share of the program's length in the lines before the one
    /// running, percent (100 once done).
    pub fn program_percent(&self) -> f64 {
        let Some(view) = &self.program else {
            return 0.0;
        };
        let program = &view.program;
        if self.run_state() == Some(RunState::Done) {
            return 100.0;
        }
        let (total, _) = program.cost_from(1);
        let line = self.program_line().max(1);
        if total > 0.0 {
            let (left, _) = program.cost_from(line);
            100.0 * (total - left) / total
        } else {
            100.0 * (line - 1) as f64 / program.line_count().max(1) as f64
        }
    }

    /// The time left, s: the line running and those after it at their
    /// programmed feeds (times the feed override), without the ramps.
    pub fn program_time_left_s(&self) -> f64 {
        let Some(view) = &self.program else {
            return 0.0;
        };
        if self.run_state().is_some_and(|state| state.is_over()) {
            return 0.0;
        }
        let (_, time_s) = view.program.cost_from(self.program_line().max(1));
        time_s * 100.0 / f64::from(view.feed_percent.max(1))
    }

    /// The speed along the path, mm/s (the path's speed in steps of step
    /// space, scaled by the line running).
    pub fn program_speed_mm_s(&self) -> f64 {
        let Some(view) = &self.program else {
            return 0.0;
        };
        let Some(reading) = &view.reading else {
            return 0.0;
        };
        let line = reading.progress.tag as usize;
        let scale = line
            .checked_sub(1)
            .and_then(|index| view.program.line_costs.get(index))
            .map_or(0.0, |cost| cost.mm_per_step);
        reading.progress.speed_steps_per_s * scale
    }

    /// Axis `index`'s position at the last frame, mm (and steps).
    pub fn program_position(&self, index: usize) -> Option<(f64, i64)> {
        let view = self.program.as_ref()?;
        let steps = self.axes.get(index)?.readout?.status.position;
        let per_mm = view.program.spec.axes().get(index)?.steps_per_mm;
        Some((steps as f64 / per_mm, steps))
    }

    /// A key in `--gcode` mode.
    pub(super) fn program_key(&mut self, key: KeyEvent) -> Vec<Effect> {
        if key.kind == KeyEventKind::Release {
            return Vec::new();
        }
        let state = self.run_state().unwrap_or(RunState::Run);
        let send = |command: PathCommand| vec![Effect::Send(Command::Path(command))];
        let quit = key.code == KeyCode::Char('q')
            || key.code == KeyCode::Char('Q')
            || (key.modifiers.contains(KeyModifiers::CONTROL)
                && matches!(key.code, KeyCode::Char('c' | 'C')));
        if quit {
            // Nothing may run on once the demo has gone.
            let moving = !state.is_over() || self.axes.iter().any(super::AxisView::moving);
            return if moving {
                vec![
                    Effect::Send(Command::Path(PathCommand::EmergencyStop)),
                    Effect::Quit,
                ]
            } else {
                vec![Effect::Quit]
            };
        }
        if key.modifiers.contains(KeyModifiers::CONTROL) {
            return Vec::new();
        }
        let over = |app: &mut App| {
            app.say(
                Tone::Refused,
                format!("the program is over ({}): q quits", state.word()),
            );
            Vec::new()
        };
        match key.code {
            KeyCode::Char(' ') if state == RunState::Held => send(PathCommand::Resume),
            KeyCode::Char(' ' | 's' | 'S') => match state {
                RunState::Run => send(PathCommand::Hold),
                RunState::Hold => {
                    self.say(Tone::Info, "already coming to rest along the path");
                    Vec::new()
                }
                RunState::Held => Vec::new(),
                _ => over(self),
            },
            KeyCode::Char('r' | 'R') => match state {
                RunState::Held => send(PathCommand::Resume),
                RunState::Hold => {
                    self.say(
                        Tone::Refused,
                        "resume: not yet at rest (Held): try again in a moment",
                    );
                    Vec::new()
                }
                RunState::Run => {
                    self.say(Tone::Refused, "resume: the program is running, not held");
                    Vec::new()
                }
                _ => over(self),
            },
            KeyCode::Char('c' | 'C') | KeyCode::Esc => {
                if state.is_over() {
                    over(self)
                } else {
                    send(PathCommand::Cancel)
                }
            }
            KeyCode::Char('x' | 'X') => send(PathCommand::EmergencyStop),
            KeyCode::Char(c @ ('+' | '=' | '-')) => {
                let (low, high) = FEED_RANGE_PERCENT;
                let now = self.program.as_ref().map_or(100, |view| view.feed_percent);
                let next = if c == '-' {
                    now.saturating_sub(FEED_STEP_PERCENT).max(low)
                } else {
                    (now + FEED_STEP_PERCENT).min(high)
                };
                if next == now {
                    self.say(
                        Tone::Refused,
                        format!(
                            "feed override {now} % is the {}",
                            if c == '-' { "lowest" } else { "highest" }
                        ),
                    );
                    Vec::new()
                } else {
                    send(PathCommand::FeedOverride(next))
                }
            }
            KeyCode::Char(c) if !c.is_control() => {
                self.say(
                    Tone::Refused,
                    format!("'{c}' is not a key here (keys below)"),
                );
                Vec::new()
            }
            _ => Vec::new(),
        }
    }

    /// What a command to the program's path came to.
    pub(super) fn path_outcome(&mut self, command: PathCommand, result: Result<Done, Refusal>) {
        let refusal = match result {
            Ok(_) => None,
            Err(Refusal::Refused(reason) | Refusal::Unplannable(reason)) => Some(reason),
            Err(other) => Some(format!("{other:?}")),
        };
        if let Some(reason) = refusal {
            let what = match command {
                PathCommand::Hold => "hold",
                PathCommand::Resume => "resume",
                PathCommand::Cancel => "cancel",
                PathCommand::EmergencyStop => "emergency stop",
                PathCommand::FeedOverride(_) => "feed override",
            };
            self.say(Tone::Refused, format!("{what} refused: {reason}"));
            return;
        }
        match command {
            PathCommand::Hold => self.say(
                Tone::Warn,
                "hold: coming to rest along the path, no step lost (space or r resumes once Held)",
            ),
            PathCommand::Resume => self.say(Tone::Info, "resumed along the path"),
            PathCommand::Cancel => self.say(
                Tone::Warn,
                "cancelled: coming to rest along the path; the rest of the program is dropped",
            ),
            PathCommand::EmergencyStop => self.say(
                Tone::Warn,
                "EMERGENCY STOP: every axis halted at once, positions kept; the program is over",
            ),
            PathCommand::FeedOverride(percent) => {
                if let Some(view) = &mut self.program {
                    view.feed_percent = percent;
                }
                self.say(
                    Tone::Info,
                    format!("feed override {percent} % (from the next junction not yet planned)"),
                );
            }
        }
    }

    /// A frame's reading of the program's path: news (a line that
    /// stopped the program) becomes the message.
    pub(super) fn apply_path(&mut self, reading: Option<PathReading>) {
        let (Some(view), Some(reading)) = (&mut self.program, reading) else {
            return;
        };
        let before = view.reading.replace(reading.clone());
        if let Some((line, error)) = &reading.error {
            if before.as_ref().is_none_or(|b| b.error.is_none()) {
                self.say(
                    Tone::Refused,
                    format!("line {line} stopped the program: {error}"),
                );
            }
        }
    }

    /// Whether the program needs frames at the full rate.
    pub(super) fn program_active(&self) -> bool {
        self.run_state().is_some_and(|state| !state.is_over())
    }
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use crossterm::event::{KeyCode, KeyEvent, KeyModifiers};
    use driver::planner::PathState;
    use driver::{PathFault, PathProgress};

    use super::*;
    use crate::backend::{Capabilities, MachineInfo};
    use crate::effect::{FrameReading, Outcome};

    const TEXT: &str = "G21 G90\nG1 X10 F600\nG1 Y10\nG1 X0\nM2\n";

    fn app() -> App {
        let spec = driver::gcode::MachineSpec::from_toml_str(
            "[axes.x]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 300.0\nmax_accel_mm_s2 = 3000.0\n\
             [axes.y]\nsteps_per_mm = 80.0\nmax_speed_mm_s = 300.0\nmax_accel_mm_s2 = 3000.0\n\
             [planner]\njunction_deviation_mm = 0.02\narc_tolerance_mm = 0.01\n",
        )
        .unwrap();
        let info = MachineInfo {
            title: "no backend".into(),
            clkfreq_hz: 200_000_000,
            capabilities: Capabilities::all(),
            max_speed: None,
            axis_kinds: vec!["sd".into(); 2],
            axis_pins: vec!["pins".into(); 2],
            jog_timeout: None,
        };
        let mut app = App::new(info, 5_000, Instant::now());
        let program = Program::from_text("p.gcode", "m.toml", spec, TEXT).unwrap();
        app.program = Some(ProgramView::new(program));
        app
    }

    fn reading(state: PathState, tag: u32) -> PathReading {
        PathReading {
            progress: PathProgress {
                state,
                tag,
                done: 0,
                queued: 0,
                speed_steps_per_s: 800.0,
                overrides: (100, 100),
                fault: None,
            },
            fed_line: tag,
            fed_all: false,
            stopped: false,
            error: None,
        }
    }

    /// A frame whose only news is the path's `reading`.
    fn frame(app: &mut App, reading: PathReading) {
        app.on_frame(
            Instant::now(),
            FrameReading {
                path: Some(reading),
                ..FrameReading::default()
            },
        );
    }

    fn press(app: &mut App, code: KeyCode) -> Vec<Effect> {
        app.on_key(KeyEvent::new(code, KeyModifiers::NONE), Instant::now())
    }

    fn path(command: PathCommand) -> Vec<Effect> {
        vec![Effect::Send(Command::Path(command))]
    }

    fn taken(app: &mut App, effects: Vec<Effect>) {
        for effect in effects {
            if let Effect::Send(command) = effect {
                let result = Ok(Done::Sent {
                    stop_pin_raised: false,
                });
                app.on_outcome(Outcome { command, result }, Instant::now());
            }
        }
    }

    #[test]
    fn the_state_follows_the_path_and_the_worker() {
        let mut app = app();
        assert_eq!(
            app.run_state(),
            Some(RunState::Run),
            "before the first frame"
        );
        let cases = [
            (reading(PathState::Running, 2), RunState::Run),
            (reading(PathState::Holding, 2), RunState::Hold),
            (reading(PathState::Held, 2), RunState::Held),
            // Between two lines the path may be idle for a moment.
            (reading(PathState::Idle, 2), RunState::Run),
            (
                PathReading {
                    fed_all: true,
                    ..reading(PathState::Idle, 4)
                },
                RunState::Done,
            ),
            (
                PathReading {
                    stopped: true,
                    ..reading(PathState::Held, 3)
                },
                RunState::Hold,
            ),
            (
                PathReading {
                    stopped: true,
                    ..reading(PathState::Idle, 3)
                },
                RunState::Cancelled,
            ),
            (
                PathReading {
                    error: Some((3, "beyond a soft limit".into())),
                    ..reading(PathState::Idle, 2)
                },
                RunState::Fault("beyond a soft limit".into()),
            ),
        ];
        for (reading, state) in cases {
            frame(&mut app, reading.clone());
            assert_eq!(app.run_state(), Some(state), "{reading:?}");
        }
        let mut faulted = reading(PathState::Idle, 2);
        faulted.progress.fault = Some(PathFault::Limit {
            axis: 0,
            side: driver::Direction::Forward,
        });
        frame(&mut app, faulted.clone());
        assert!(matches!(app.run_state(), Some(RunState::Fault(_))));
        // An emergency stop the person asked for ends as a cancel.
        faulted.progress.fault = Some(PathFault::EmergencyStop);
        faulted.stopped = true;
        frame(&mut app, faulted);
        assert_eq!(app.run_state(), Some(RunState::Cancelled));
    }

    #[test]
    fn progress_counts_lines_length_and_time_left() {
        let mut app = app();
        frame(&mut app, reading(PathState::Running, 3));
        assert_eq!(app.program_line(), 3);
        // 10 mm of 30 before line 3; lines 3 and 4 at 10 mm/s are 2 s.
        assert!((app.program_percent() - 100.0 / 3.0).abs() < 1e-9);
        assert!((app.program_time_left_s() - 2.0).abs() < 1e-9);
        // 800 steps/s of step space at 80 steps/mm.
        assert!((app.program_speed_mm_s() - 10.0).abs() < 1e-9);
        app.program.as_mut().unwrap().feed_percent = 200;
        assert!((app.program_time_left_s() - 1.0).abs() < 1e-9);
        frame(
            &mut app,
            PathReading {
                fed_all: true,
                ..reading(PathState::Idle, 4)
            },
        );
        assert_eq!(app.program_line(), 5, "every line, once done");
        assert_eq!(app.program_percent(), 100.0);
        assert_eq!(app.program_time_left_s(), 0.0);
    }

    #[test]
    fn space_holds_and_resumes_s_holds_r_resumes_c_and_esc_cancel() {
        let mut app = app();
        frame(&mut app, reading(PathState::Running, 2));
        assert_eq!(press(&mut app, KeyCode::Char(' ')), path(PathCommand::Hold));
        assert_eq!(press(&mut app, KeyCode::Char('s')), path(PathCommand::Hold));
        // Resume is refused, with the reason, until the path is at rest.
        assert_eq!(press(&mut app, KeyCode::Char('r')), []);
        assert!(app.message.as_ref().unwrap().text.contains("not held"));
        frame(&mut app, reading(PathState::Holding, 2));
        assert_eq!(press(&mut app, KeyCode::Char('r')), []);
        assert!(app
            .message
            .as_ref()
            .unwrap()
            .text
            .contains("not yet at rest"));
        frame(&mut app, reading(PathState::Held, 2));
        assert_eq!(
            press(&mut app, KeyCode::Char(' ')),
            path(PathCommand::Resume)
        );
        assert_eq!(
            press(&mut app, KeyCode::Char('r')),
            path(PathCommand::Resume)
        );
        assert_eq!(
            press(&mut app, KeyCode::Char('c')),
            path(PathCommand::Cancel)
        );
        assert_eq!(press(&mut app, KeyCode::Esc), path(PathCommand::Cancel));
        assert_eq!(
            press(&mut app, KeyCode::Char('x')),
            path(PathCommand::EmergencyStop)
        );
        // Over: the keys say so and send nothing.
        frame(
            &mut app,
            PathReading {
                stopped: true,
                ..reading(PathState::Idle, 2)
            },
        );
        for code in [KeyCode::Char(' '), KeyCode::Char('r'), KeyCode::Char('c')] {
            assert_eq!(press(&mut app, code), []);
            assert!(app
                .message
                .as_ref()
                .unwrap()
                .text
                .contains("over (Cancelled)"));
        }
        // The prompt's keys are not the program's.
        assert_eq!(press(&mut app, KeyCode::Char('5')), []);
        assert!(app
            .message
            .as_ref()
            .unwrap()
            .text
            .contains("not a key here"));
    }

    #[test]
    fn plus_and_minus_step_the_feed_override_within_its_range() {
        let mut app = app();
        frame(&mut app, reading(PathState::Running, 2));
        let effects = press(&mut app, KeyCode::Char('+'));
        assert_eq!(effects, path(PathCommand::FeedOverride(110)));
        assert_eq!(
            app.program.as_ref().unwrap().feed_percent,
            100,
            "once taken"
        );
        taken(&mut app, effects);
        assert_eq!(app.program.as_ref().unwrap().feed_percent, 110);
        app.program.as_mut().unwrap().feed_percent = 200;
        assert_eq!(press(&mut app, KeyCode::Char('+')), []);
        assert!(app.message.as_ref().unwrap().text.contains("highest"));
        app.program.as_mut().unwrap().feed_percent = 10;
        assert_eq!(press(&mut app, KeyCode::Char('-')), []);
        app.program.as_mut().unwrap().feed_percent = 50;
        assert_eq!(
            press(&mut app, KeyCode::Char('-')),
            path(PathCommand::FeedOverride(40))
        );
    }

    #[test]
    fn q_stops_the_axes_first_while_anything_moves() {
        let mut app = app();
        frame(&mut app, reading(PathState::Running, 2));
        assert_eq!(
            press(&mut app, KeyCode::Char('q')),
            [
                Effect::Send(Command::Path(PathCommand::EmergencyStop)),
                Effect::Quit
            ]
        );
        let ctrl_c = KeyEvent::new(KeyCode::Char('c'), KeyModifiers::CONTROL);
        assert_eq!(
            app.on_key(ctrl_c, Instant::now()).last(),
            Some(&Effect::Quit)
        );
        frame(
            &mut app,
            PathReading {
                fed_all: true,
                ..reading(PathState::Idle, 4)
            },
        );
        assert_eq!(press(&mut app, KeyCode::Char('q')), [Effect::Quit]);
    }

    #[test]
    fn a_refused_resume_and_a_run_time_error_are_shown() {
        let mut app = app();
        app.on_outcome(
            Outcome {
                command: Command::Path(PathCommand::Resume),
                result: Err(Refusal::Refused("a stop pin is low".into())),
            },
            Instant::now(),
        );
        assert_eq!(
            app.message.as_ref().unwrap().text,
            "resume refused: a stop pin is low"
        );
        frame(
            &mut app,
            PathReading {
                error: Some((3, "line 3: the path stopped".into())),
                ..reading(PathState::Idle, 2)
            },
        );
        assert!(app
            .message
            .as_ref()
            .unwrap()
            .text
            .starts_with("line 3 stopped the program"));
    }
}

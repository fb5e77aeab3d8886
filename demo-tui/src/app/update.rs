//! How keys and time change the state (the "update" of the ratatui app
//! pattern), without touching the backend: a key gives the
//! [`Effect`]s it asks for, and what became of each comes back through
//! [`App::on_outcome`] ([`super::outcome`]). The state waits for the
//! outcome to change what depends on it (the prompt is cleared once the
//! axis took the move). The tests cover both halves, with no backend.

use std::time::Instant;

use crossterm::event::{KeyCode, KeyEvent, KeyEventKind, KeyModifiers};
use driver::Direction;

use super::{App, Tone, JOG_SPEEDS, PENDING_KEY};
use crate::effect::{Command, Effect};
use crate::prompt::{
    parse_group_steps, parse_speed, parse_steps, Stage, FIELD_MAX, GROUP_FIELD_MAX,
};

impl App {
    /// Handles one key event at `now`: what it asks of the backend (or of
    /// the loop: [`Effect::Quit`]). Nothing is sent from here.
    pub fn on_key(&mut self, key: KeyEvent, now: Instant) -> Vec<Effect> {
        if self.program.is_some() {
            self.last_key = Some(now);
            return self.program_key(key);
        }
        self.key(key, now).into_iter().collect()
    }

    fn key(&mut self, key: KeyEvent, now: Instant) -> Option<Effect> {
        self.last_key = Some(now);
        if key.kind == KeyEventKind::Release {
            if matches!(key.code, KeyCode::Left | KeyCode::Right) {
                return self.release_jog();
            }
            return None;
        }
        let key = if key.modifiers.contains(KeyModifiers::CONTROL) {
            // In raw mode LF reads as Ctrl-J and BS as Ctrl-H: a terminal
            // (or a script) that sends them means Enter and Backspace.
            match key.code {
                KeyCode::Char('c' | 'C') => return Some(Effect::Quit),
                KeyCode::Char('j' | 'm') => KeyEvent::new(KeyCode::Enter, KeyModifiers::NONE),
                KeyCode::Char('h') => KeyEvent::new(KeyCode::Backspace, KeyModifiers::NONE),
                _ => return None,
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
                self.resolve_pending();
            }
        }
        let axis = self.selected;
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
            KeyCode::Char('s' | 'S') => return self.stop(),
            KeyCode::Char('x' | 'X') => return self.emergency_stop(),
            KeyCode::Char('h' | 'H') => return Some(Effect::Send(Command::Home { axis })),
            KeyCode::Char('c' | 'C') => return Some(Effect::Send(Command::ClearLimit { axis })),
            KeyCode::Char('q' | 'Q') => return Some(Effect::Quit),
            KeyCode::Tab => self.select((self.selected + 1) % self.axes.len().max(1)),
            KeyCode::BackTab => {
                let count = self.axes.len().max(1);
                self.select((self.selected + count - 1) % count);
            }
            KeyCode::Left => return self.jog(Direction::Reverse),
            KeyCode::Right => return self.jog(Direction::Forward),
            KeyCode::Enter => return self.submit(),
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
        None
    }

    /// Time passes: a lone key that waited long enough acts; a jog whose
    /// heartbeats stopped is over. Nothing it does needs the backend.
    pub fn on_tick(&mut self, now: Instant) {
        if self
            .prompt
            .pending_since
            .is_some_and(|since| now.duration_since(since) >= PENDING_KEY)
        {
            self.resolve_pending();
        }
        if self
            .jogging
            .is_some_and(|jog| now.duration_since(jog.last_beat) > self.jog_timeout())
        {
            self.jogging = None;
        }
    }

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
    fn resolve_pending(&mut self) {
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

    /// `Enter`: the answer moves the prompt on, or (at `Enter speed:`)
    /// asks for the move, which clears the prompt once it is taken.
    fn submit(&mut self) -> Option<Effect> {
        let speed =
            |app: &Self| parse_speed(&app.prompt.field, app.prompt.last_speed, app.info.max_speed);
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
            Stage::GroupSpeed => match speed(self) {
                Ok(speed) => {
                    return Some(Effect::Send(Command::MoveTogether {
                        steps: self.prompt.group.clone(),
                        speed,
                    }))
                }
                Err(reason) => self.say(Tone::Refused, reason),
            },
            Stage::Steps => match parse_steps(&self.prompt.field) {
                Ok(steps) => {
                    self.prompt.stage = Stage::Speed { steps };
                    self.prompt.field.clear();
                    self.message = None;
                }
                Err(reason) => self.say(Tone::Refused, reason),
            },
            Stage::Speed { steps } => match speed(self) {
                Ok(speed) => {
                    return Some(Effect::Send(Command::Move {
                        axis: self.selected,
                        steps,
                        speed,
                    }))
                }
                Err(reason) => self.say(Tone::Refused, reason),
            },
        }
        None
    }

    fn stop(&mut self) -> Option<Effect> {
        if let Some(reason) = &self.info.capabilities.stop_pin {
            let text = format!("stop: {reason}");
            self.say(Tone::Refused, text);
            return None;
        }
        Some(Effect::Send(Command::Stop {
            axis: self.selected,
        }))
    }

    fn emergency_stop(&mut self) -> Option<Effect> {
        if let Some(reason) = &self.info.capabilities.emergency_stop {
            let text = format!("emergency stop: {reason}");
            self.say(Tone::Refused, text);
            return None;
        }
        self.jogging = None;
        Some(Effect::Send(Command::EmergencyStop))
    }

    /// A jog key pressed or repeating: one heartbeat.
    fn jog(&mut self, direction: Direction) -> Option<Effect> {
        if let Some(reason) = &self.info.capabilities.jog {
            let text = format!("jog: {reason}");
            self.say(Tone::Refused, text);
            return None;
        }
        Some(Effect::Send(Command::JogBeat {
            axis: self.selected,
            direction,
            speed: self.jog_speed,
        }))
    }

    fn release_jog(&mut self) -> Option<Effect> {
        let jog = self.jogging.take()?;
        Some(Effect::Send(Command::JogRelease { axis: jog.axis }))
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;
    use crate::app::{LastCommand, JOG_TIMEOUT, PENDING_KEY};
    use crate::backend::{Capabilities, MachineInfo};
    use crate::effect::{Done, Outcome, Refusal};

    fn info(count: usize, capabilities: Capabilities) -> MachineInfo {
        MachineInfo {
            title: "no backend".into(),
            clkfreq_hz: 200_000_000,
            capabilities,
            max_speed: Some(199_600),
            axis_kinds: vec!["sd".into(); count],
            axis_pins: vec!["pins".into(); count],
            jog_timeout: Some(JOG_TIMEOUT),
        }
    }

    fn app(count: usize, now: Instant) -> App {
        App::new(info(count, Capabilities::all()), 5_000, now)
    }

    fn key(code: KeyCode) -> KeyEvent {
        KeyEvent::new(code, KeyModifiers::NONE)
    }

    /// Types `text`; the effects of all its keys, in order.
    fn type_keys(app: &mut App, text: &str, now: Instant) -> Vec<Effect> {
        text.chars()
            .flat_map(|c| {
                let code = match c {
                    '\r' => KeyCode::Enter,
                    '\t' => KeyCode::Tab,
                    c => KeyCode::Char(c),
                };
                app.on_key(key(code), now)
            })
            .collect()
    }

    fn send(command: Command) -> Vec<Effect> {
        vec![Effect::Send(command)]
    }

    /// Feeds every command back as taken, no stop pin raised.
    fn taken(app: &mut App, effects: Vec<Effect>, now: Instant) {
        for effect in effects {
            if let Effect::Send(command) = effect {
                let result = Ok(match command {
                    Command::Home { .. } => panic!("homing needs its configuration"),
                    _ => Done::Sent {
                        stop_pin_raised: false,
                    },
                });
                app.on_outcome(Outcome { command, result }, now);
            }
        }
    }

    fn message(app: &App) -> String {
        app.message.clone().expect("a message").text
    }

    #[test]
    fn steps_then_speed_then_enter_is_one_move_and_the_prompt_clears_once_taken() {
        let t0 = Instant::now();
        let mut app = app(4, t0);
        assert_eq!(type_keys(&mut app, "2000\r", t0), []);
        assert_eq!(app.prompt.stage, Stage::Speed { steps: 2000 });
        assert_eq!(type_keys(&mut app, "20000", t0), []);
        // A line feed (Ctrl-J in raw mode) submits too.
        let effects = app.on_key(KeyEvent::new(KeyCode::Char('j'), KeyModifiers::CONTROL), t0);
        let move_2000 = Command::Move {
            axis: 0,
            steps: 2000,
            speed: 20_000,
        };
        assert_eq!(effects, send(move_2000.clone()));
        assert_eq!(
            app.prompt.stage,
            Stage::Speed { steps: 2000 },
            "the prompt waits for the axis to take it"
        );
        taken(&mut app, effects, t0);
        assert_eq!(app.prompt.stage, Stage::Steps);
        assert_eq!(app.prompt.last_speed, Some(20_000));
        assert_eq!(
            app.axes[0].last_command,
            Some(LastCommand::Move {
                steps: 2000,
                speed: 20_000
            })
        );
        assert_eq!(message(&app), "axis 1: move 2000 steps at 20000 steps/s");
        assert!(
            app.active(t0),
            "full frame rate at once, before the cog moves"
        );
        assert!(
            !app.active(t0 + super::super::AFTER_KEY_ACTIVE),
            "idle again"
        );
        assert_eq!(app.selected, 0, "typing a number selects nothing");
        // A negative number, and Enter on an empty speed takes the last one.
        let effects = type_keys(&mut app, "-500\r\r", t0);
        assert_eq!(
            effects,
            send(Command::Move {
                axis: 0,
                steps: -500,
                speed: 20_000
            })
        );
    }

    #[test]
    fn a_refused_move_keeps_the_prompt_and_enter_asks_again() {
        let t0 = Instant::now();
        let mut app = app(2, t0);
        let effects = type_keys(&mut app, "100\r1000\r", t0);
        let [Effect::Send(command)] = effects.as_slice() else {
            panic!("{effects:?}");
        };
        app.on_outcome(
            Outcome {
                command: command.clone(),
                result: Err(Refusal::Refused("a limit is tripped".into())),
            },
            t0,
        );
        assert_eq!(
            message(&app),
            "axis 1 refused the move: a limit is tripped (Enter to retry)"
        );
        assert_eq!(app.prompt.stage, Stage::Speed { steps: 100 });
        assert_eq!(app.axes[0].last_command, None);
        assert_eq!(type_keys(&mut app, "\r", t0), effects);
        // The backend's own check, and a stop pin it could not raise.
        for (refusal, text) in [
            (Refusal::Unplannable("too short".into()), "too short"),
            (
                Refusal::StopPin {
                    axis: 0,
                    reason: "could not raise the stop pin: gone".into(),
                },
                "axis 1: could not raise the stop pin: gone",
            ),
            (Refusal::NoSuchAxis, "axis 1 does not exist"),
        ] {
            app.on_outcome(
                Outcome {
                    command: command.clone(),
                    result: Err(refusal),
                },
                t0,
            );
            assert_eq!(message(&app), text);
        }
        // Taken, with the stop key's low pin raised first.
        app.on_outcome(
            Outcome {
                command: command.clone(),
                result: Ok(Done::Sent {
                    stop_pin_raised: true,
                }),
            },
            t0,
        );
        assert_eq!(
            message(&app),
            "axis 1: move 100 steps at 1000 steps/s (stop pin raised)"
        );
    }

    #[test]
    fn g_asks_one_line_of_steps_then_the_speed_and_moves_all_axes() {
        let t0 = Instant::now();
        let mut app = app(3, t0);
        assert_eq!(type_keys(&mut app, "g", t0), []);
        assert_eq!(app.prompt.stage, Stage::GroupSteps);
        // Spaces and '-' are typed here, not keys; a lone digit selects nothing.
        assert_eq!(type_keys(&mut app, "2000 -500 0\r", t0), []);
        assert_eq!(app.prompt.stage, Stage::GroupSpeed);
        assert_eq!(app.prompt.group, [2000, -500, 0]);
        assert_eq!(app.jog_speed, 5_000);
        let effects = type_keys(&mut app, "8000\r", t0);
        assert_eq!(
            effects,
            send(Command::MoveTogether {
                steps: vec![2000, -500, 0],
                speed: 8_000
            })
        );
        taken(&mut app, effects, t0);
        assert_eq!(app.prompt.stage, Stage::Steps);
        assert!(app.prompt.group.is_empty());
        assert_eq!(
            app.axes[1].last_command,
            Some(LastCommand::Move {
                steps: -500,
                speed: 8_000
            })
        );
        assert_eq!(app.axes[2].last_command, None);
        assert_eq!(
            message(&app),
            "group move 2000 -500 0 at 8000 steps/s, all axes on one line"
        );
        // Refusals keep the prompt; an empty speed takes the last one.
        assert_eq!(type_keys(&mut app, "g0 0\r", t0), []);
        assert_eq!(app.prompt.stage, Stage::GroupSteps);
        assert!(message(&app).contains("nothing to move"));
        app.on_key(key(KeyCode::Esc), t0);
        app.on_key(key(KeyCode::Esc), t0);
        assert_eq!(app.prompt.stage, Stage::Steps);
        assert_eq!(type_keys(&mut app, "g1 1 1 1\r", t0), []);
        assert!(message(&app).contains("4 numbers for 3 axes"));
        app.prompt.field.clear();
        assert_eq!(
            type_keys(&mut app, "5\r\r", t0),
            send(Command::MoveTogether {
                steps: vec![5],
                speed: 8_000
            })
        );
    }

    #[test]
    fn a_lone_axis_number_selects_after_the_pause() {
        let t0 = Instant::now();
        let mut app = app(4, t0);
        type_keys(&mut app, "3", t0);
        app.on_tick(t0 + PENDING_KEY / 2);
        assert_eq!(app.selected, 0);
        assert_eq!(app.prompt.field, "3");
        app.on_tick(t0 + PENDING_KEY);
        assert_eq!(app.selected, 2);
        assert_eq!(app.prompt.field, "");
        // A key other than a digit resolves it at once: "2" then → jogs axis 2.
        type_keys(&mut app, "2", t0);
        assert_eq!(
            app.on_key(key(KeyCode::Right), t0),
            send(Command::JogBeat {
                axis: 1,
                direction: Direction::Forward,
                speed: 5_000
            })
        );
        assert_eq!(app.selected, 1);
        // 9 is never an axis number; with 4 axes neither is 5.
        type_keys(&mut app, "5", t0);
        app.on_tick(t0 + PENDING_KEY * 2);
        assert_eq!((app.selected, app.prompt.field.as_str()), (1, "5"));
        // Tab and Shift-Tab cycle.
        app.on_key(key(KeyCode::Esc), t0);
        type_keys(&mut app, "\t\t\t", t0);
        assert_eq!(app.selected, 0);
        app.on_key(key(KeyCode::BackTab), t0);
        assert_eq!(app.selected, 3);
    }

    #[test]
    fn minus_is_a_sign_on_an_empty_steps_field_and_jog_speed_elsewhere() {
        let t0 = Instant::now();
        let mut app = app(2, t0);
        type_keys(&mut app, "+", t0);
        assert_eq!(app.jog_speed, 10_000);
        type_keys(&mut app, "-", t0);
        app.on_tick(t0 + PENDING_KEY);
        assert_eq!(app.jog_speed, 5_000, "a lone '-' lowers the jog speed");
        type_keys(&mut app, "12-", t0);
        assert_eq!(app.jog_speed, 2_000);
        assert_eq!(app.prompt.field, "12");
        app.on_key(key(KeyCode::Esc), t0);
        type_keys(&mut app, "-7\r", t0);
        assert_eq!(app.prompt.stage, Stage::Speed { steps: -7 });
        type_keys(&mut app, "-", t0);
        assert_eq!(app.jog_speed, 1_000, "'-' is never a sign at Enter speed:");
    }

    #[test]
    fn invalid_answers_are_refused_at_the_prompt_and_nothing_is_asked() {
        let t0 = Instant::now();
        let mut app = app(1, t0);
        let mut effects = type_keys(&mut app, "0\r", t0);
        assert_eq!(app.prompt.stage, Stage::Steps);
        let refusal = app.message.clone().expect("a reason");
        assert_eq!(refusal.tone, Tone::Refused);
        assert!(refusal.text.contains("nothing to move"));
        app.on_key(key(KeyCode::Esc), t0);
        effects.extend(type_keys(&mut app, "100\r0\r", t0));
        assert_eq!(app.prompt.stage, Stage::Speed { steps: 100 });
        assert!(message(&app).contains("at least 1"));
        effects.extend(type_keys(&mut app, "\r", t0)); // field still "0"
        app.on_key(key(KeyCode::Backspace), t0);
        effects.extend(type_keys(&mut app, "999999\r", t0));
        assert!(message(&app).contains("too fast"));
        effects.extend(type_keys(&mut app, "a", t0));
        assert!(message(&app).contains("not a key"));
        assert_eq!(effects, []);
    }

    #[test]
    fn stop_emergency_stop_home_clear_and_quit_are_one_effect_each() {
        let t0 = Instant::now();
        let mut app = app(2, t0);
        app.on_key(key(KeyCode::Tab), t0);
        assert_eq!(
            type_keys(&mut app, "s", t0),
            send(Command::Stop { axis: 1 })
        );
        assert_eq!(
            type_keys(&mut app, "h", t0),
            send(Command::Home { axis: 1 })
        );
        assert_eq!(
            type_keys(&mut app, "c", t0),
            send(Command::ClearLimit { axis: 1 })
        );
        assert_eq!(type_keys(&mut app, "q", t0), [Effect::Quit]);
        assert_eq!(
            app.on_key(KeyEvent::new(KeyCode::Char('c'), KeyModifiers::CONTROL), t0),
            [Effect::Quit]
        );
        // An emergency stop ends the jog on screen at once.
        assert_eq!(type_keys(&mut app, "\t", t0), []);
        let jog = app.on_key(key(KeyCode::Left), t0);
        taken(&mut app, jog, t0);
        assert!(app.jogging.is_some());
        assert_eq!(type_keys(&mut app, "x", t0), send(Command::EmergencyStop));
        assert!(app.jogging.is_none());
        // What came of them.
        taken(&mut app, send(Command::Stop { axis: 0 }), t0);
        assert!(message(&app).starts_with("axis 1: stop pin low"));
        app.on_outcome(
            Outcome {
                command: Command::Home { axis: 0 },
                result: Err(Refusal::NoHomeSwitch),
            },
            t0,
        );
        assert_eq!(message(&app), "axis 1: no home switch on this backend");
        let config = driver::switch::DemoSwitches::for_axis(0)
            .expect("demo switches")
            .home_config();
        app.on_outcome(
            Outcome {
                command: Command::Home { axis: 0 },
                result: Ok(Done::Homing(config)),
            },
            t0,
        );
        assert_eq!(app.axes[0].last_command, Some(LastCommand::Home));
        assert!(message(&app).starts_with("axis 1: homing on pin"));
        app.on_outcome(
            Outcome {
                command: Command::ClearLimit { axis: 0 },
                result: Err(Refusal::Refused("no limit tripped".into())),
            },
            t0,
        );
        assert_eq!(message(&app), "axis 1: clear refused: no limit tripped");
    }

    #[test]
    fn holding_the_jog_key_beats_on_each_press_or_repeat_and_release_ends_it() {
        let t0 = Instant::now();
        let mut app = app(1, t0);
        let repeat =
            KeyEvent::new_with_kind(KeyCode::Left, KeyModifiers::NONE, KeyEventKind::Repeat);
        let release =
            KeyEvent::new_with_kind(KeyCode::Left, KeyModifiers::NONE, KeyEventKind::Release);
        let beat = send(Command::JogBeat {
            axis: 0,
            direction: Direction::Reverse,
            speed: 5_000,
        });
        let t1 = t0 + Duration::from_millis(30);
        assert_eq!(app.on_key(key(KeyCode::Left), t0), beat);
        assert!(app.jogging.is_none(), "jogging once the axis takes it");
        taken(&mut app, beat.clone(), t0);
        assert!(message(&app).starts_with("axis 1: jogging ← at 5000 steps/s"));
        assert_eq!(app.on_key(repeat, t1), beat);
        taken(&mut app, beat.clone(), t1);
        assert_eq!(app.jogging.map(|jog| jog.last_beat), Some(t1));
        assert_eq!(
            app.on_key(release, t0 + Duration::from_millis(60)),
            send(Command::JogRelease { axis: 0 })
        );
        assert!(app.jogging.is_none());
        // A release with no jog held asks for nothing.
        assert_eq!(app.on_key(release, t1), []);
        // Without a release the display ends after the hub's timeout.
        let effects = app.on_key(key(KeyCode::Right), t0);
        taken(&mut app, effects, t0);
        app.on_tick(t0 + JOG_TIMEOUT / 2);
        assert!(app.jogging.is_some());
        app.on_tick(t0 + JOG_TIMEOUT + Duration::from_millis(1));
        assert!(app.jogging.is_none());
        // A refused beat is no jog.
        app.on_outcome(
            Outcome {
                command: Command::JogBeat {
                    axis: 0,
                    direction: Direction::Forward,
                    speed: 5_000,
                },
                result: Err(Refusal::Refused("limit".into())),
            },
            t0,
        );
        assert_eq!(message(&app), "axis 1: jog refused: limit");
        assert!(app.jogging.is_none());
    }

    #[test]
    fn what_the_backend_cannot_do_is_refused_with_the_reason_and_not_asked() {
        let t0 = Instant::now();
        let why = "not supported by this board (a pin)";
        let capabilities = Capabilities {
            stop_pin: Some(why.into()),
            jog: Some(why.into()),
            emergency_stop: Some(why.into()),
        };
        let mut app = App::new(info(1, capabilities), 5_000, t0);
        assert_eq!(type_keys(&mut app, "s", t0), []);
        assert_eq!(message(&app), format!("stop: {why}"));
        assert_eq!(app.on_key(key(KeyCode::Right), t0), []);
        assert_eq!(message(&app), format!("jog: {why}"));
        assert_eq!(type_keys(&mut app, "x", t0), []);
        assert_eq!(message(&app), format!("emergency stop: {why}"));
    }
}

//! The P2 demo dialect, host side: answer the two prompts, read position
//! and mode from the screens.
//!
//! The board has one motor and no commands: it prompts `Enter steps:`,
//! then `Enter speed:`, runs the move while it shows displays (reading
//! nothing), and prompts again. So a move is accepted only at the steps
//! prompt (else [`AxisError::Busy`]), status is whatever the screens last
//! showed, and a board that stops sending displays in the middle of a
//! move (for longer than the timeout) is taken as lost.

use std::time::{Duration, Instant};

use super::link::{Conversation, Incoming, LinkFault, Wire};
use super::{AxisCache, Op, Request, SerialError, Shared, FAULT_DISCONNECTED, P2DEMO_IDENTITY};
use crate::axis::{AxisError, Mode};
use crate::serial::p2demo::{DemoField, DemoPrompt, ScreenEvent};

/// How often the link thread looks at the board while it is quiet.
const IDLE_TICK: Duration = Duration::from_millis(100);
/// Backspace: deletes a character of an answer being typed.
const BACKSPACE: u8 = 8;
/// Backspaces sent before the handshake's CR: more than an answer holds.
const ANSWER_ERASE: usize = 20;

/// Where the board's prompt/answer flow is, as the host sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// `Enter steps:` shown: a move can be given.
    Ready,
    /// A move runs (its target, when this host started it).
    Running { target: Option<i64> },
}

/// The P2 demo conversation.
pub(super) struct Demo {
    phase: Phase,
    timeout: Duration,
    /// When the board last sent anything.
    last_heard: Instant,
    /// The last position read and when, for the velocity estimate.
    last_position: Option<(i64, Instant)>,
    /// A `Refused: ...` line, until the prompt after it.
    refused: Option<String>,
}

impl Demo {
    /// Presses keys and reads the screen: a steps prompt means the board
    /// is ready; displays without a prompt, that a move runs. The keys are
    /// backspaces (erasing any half-typed answer, so that it cannot start a
    /// move) and a CR (the key a board waiting after start needs, and an
    /// empty answer at a prompt, which asks again).
    pub fn handshake(wire: &mut Wire, shared: &Shared) -> Result<Demo, SerialError> {
        let config = &shared.config;
        let what = "the P2 demo screen";
        let fail = |fault: LinkFault| fault.into_open_error(shared, what);
        shared.state().axes.resize(1, AxisCache::default());
        let mut demo = Demo {
            phase: Phase::Ready,
            timeout: config.timeout,
            last_heard: Instant::now(),
            last_position: None,
            refused: None,
        };
        let mut keys = [BACKSPACE; ANSWER_ERASE + 1];
        keys[ANSWER_ERASE] = crate::serial::p2demo::CR;
        wire.send(&keys).map_err(fail)?;
        let deadline = Instant::now() + config.timeout;
        let (mut heard, mut displays) = (false, 0);
        loop {
            match wire.next_event(deadline).map_err(fail)? {
                None if heard => {
                    demo.phase = Phase::Running { target: None };
                    break;
                }
                None => {
                    return Err(SerialError::Timeout {
                        port: config.port.clone(),
                        what,
                        timeout_ms: config.timeout.as_millis(),
                    })
                }
                Some(Incoming::Screen(ScreenEvent::Prompt(DemoPrompt::Steps))) => {
                    demo.phase = Phase::Ready;
                    break;
                }
                Some(Incoming::Screen(ScreenEvent::Prompt(DemoPrompt::Speed))) => {
                    return Err(SerialError::Handshake {
                        port: config.port.clone(),
                        reason: "the P2 demo board waits for a speed: answer it in a terminal, \
                                 or reset the board"
                            .to_string(),
                    });
                }
                Some(event) => {
                    heard = true;
                    if let Incoming::Screen(ScreenEvent::Display(_)) = event {
                        displays += 1;
                    }
                    demo.apply(shared, &event);
                    // A ready board shows one display, then the prompt.
                    if displays >= 2 {
                        demo.phase = Phase::Running { target: None };
                        break;
                    }
                }
            }
        }
        demo.last_heard = Instant::now();
        demo.publish(shared);
        shared.state().link_up(P2DEMO_IDENTITY.to_string(), 0, 1);
        Ok(demo)
    }

    /// Takes what a screen says into the cache.
    fn apply(&mut self, shared: &Shared, event: &Incoming) {
        self.last_heard = Instant::now();
        let (position, mode_bits) = match event {
            Incoming::Screen(ScreenEvent::Field(DemoField::Position(position))) => {
                (Some(*position), None)
            }
            Incoming::Screen(ScreenEvent::Field(DemoField::Mode(bits))) => (None, Some(*bits)),
            Incoming::Screen(ScreenEvent::Display(screen)) => {
                (Some(screen.position), Some(screen.mode_bits))
            }
            Incoming::Screen(ScreenEvent::Prompt(DemoPrompt::Steps)) => {
                self.phase = Phase::Ready;
                (None, None)
            }
            Incoming::Text(text) => {
                self.refused = Some(text.clone());
                (None, None)
            }
            _ => (None, None),
        };
        let mut state = shared.state();
        let Some(axis) = state.axes.get_mut(0) else {
            return;
        };
        if let Some(bits) = mode_bits {
            axis.status.mode = Mode(u32::from(bits));
        }
        if let Some(position) = position {
            let now = Instant::now();
            if let Some((before, at)) = self.last_position {
                let seconds = now.duration_since(at).as_secs_f64();
                if seconds > 0.0 && position != before {
                    let steps = position.abs_diff(before) as f64;
                    axis.status.velocity_steps_per_s =
                        (steps / seconds).min(f64::from(u32::MAX)) as u32;
                }
            }
            self.last_position = Some((position, now));
            axis.status.position = position;
        }
        drop(state);
        self.publish(shared);
    }

    /// Makes STM, the moving bit and the velocity agree with the phase.
    fn publish(&self, shared: &Shared) {
        let mut state = shared.state();
        let Some(axis) = state.axes.get_mut(0) else {
            return;
        };
        let status = &mut axis.status;
        match self.phase {
            Phase::Ready => {
                status.steps_to_go = 0;
                status.mode = Mode(status.mode.0 & !Mode::MOVING);
                status.velocity_steps_per_s = 0;
            }
            Phase::Running { target } => {
                let left = target.map_or(1, |target| target.abs_diff(status.position));
                status.steps_to_go = left.max(1);
                status.mode = Mode(status.mode.0 | Mode::MOVING);
            }
        }
        // The stop pin is on the board, out of the host's sight.
        status.stop_pin_high = true;
    }

    /// Answers the two prompts; waits for the move to start (or be refused).
    fn start_move(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        speed: u32,
        steps: i32,
    ) -> Result<Result<(), AxisError>, LinkFault> {
        if self.phase != Phase::Ready {
            // The board reads nothing while a move runs.
            return Ok(Err(AxisError::Busy));
        }
        self.refused = None;
        wire.send(format!("{steps}\r").as_bytes())?;
        // One steps prompt may still be on its way from before the answer
        // (the handshake's CR makes the board ask twice): the answer goes
        // to that one, and the speed prompt follows it.
        let mut stale_prompt_allowed = true;
        loop {
            match self.await_prompt(wire, shared)? {
                Waited::Prompt(DemoPrompt::Speed) => break,
                Waited::Prompt(DemoPrompt::Steps) if stale_prompt_allowed => {
                    stale_prompt_allowed = false;
                }
                Waited::Prompt(DemoPrompt::Steps) | Waited::Cleared => {
                    return Ok(Err(AxisError::Fault(
                        "the P2 demo board did not take the steps",
                    )));
                }
            }
        }
        wire.send(format!("{speed}\r").as_bytes())?;
        match self.await_prompt(wire, shared)? {
            Waited::Cleared => {
                let start = shared
                    .state()
                    .axes
                    .first()
                    .map_or(0, |axis| axis.status.position);
                self.phase = Phase::Running {
                    target: Some(start.saturating_add(i64::from(steps))),
                };
                self.last_position = None;
                self.publish(shared);
                if let Some(axis) = shared.state().axes.get_mut(0) {
                    axis.latched = None;
                }
                Ok(Ok(()))
            }
            Waited::Prompt(_) => Ok(Err(refusal(self.refused.take(), speed))),
        }
    }

    /// Waits for a prompt or the clear byte that starts a move.
    fn await_prompt(&mut self, wire: &mut Wire, shared: &Shared) -> Result<Waited, LinkFault> {
        let deadline = Instant::now() + self.timeout;
        loop {
            let Some(event) = wire.next_event(deadline)? else {
                return Err(LinkFault::Timeout(format!(
                    "no P2 demo prompt within {} ms",
                    self.timeout.as_millis()
                )));
            };
            self.apply(shared, &event);
            match event {
                Incoming::Screen(ScreenEvent::Prompt(prompt)) => return Ok(Waited::Prompt(prompt)),
                Incoming::Cleared => return Ok(Waited::Cleared),
                _ => {}
            }
        }
    }
}

/// What [`Demo::await_prompt`] saw.
enum Waited {
    Prompt(DemoPrompt),
    Cleared,
}

/// The error a `Refused: <reason>` line stands for.
fn refusal(line: Option<String>, speed: u32) -> AxisError {
    let reason = line.unwrap_or_default();
    let reason = reason.trim_start_matches("Refused:").trim();
    if reason.starts_with("busy") {
        AxisError::Busy
    } else if reason.contains("not idle") {
        AxisError::NotIdle
    } else if reason.contains("not available") {
        AxisError::Unavailable
    } else if reason.contains("no room for the step pulse") {
        AxisError::PulseTooLong { speed }
    } else {
        AxisError::Fault("the P2 demo board refused the move")
    }
}

impl Conversation for Demo {
    fn on_event(
        &mut self,
        _wire: &mut Wire,
        shared: &Shared,
        event: Incoming,
    ) -> Result<(), LinkFault> {
        self.apply(shared, &event);
        Ok(())
    }

    fn on_request(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        request: Request,
    ) -> Result<(), LinkFault> {
        let result = match request.op {
            Op::DemoMove { speed, steps } => self.start_move(wire, shared, speed, steps),
            Op::Refresh => Ok(Ok(())),
            Op::Command { .. } | Op::JogRelease(_) => {
                Ok(Err(AxisError::Unsupported(super::P2DEMO_UNSUPPORTED)))
            }
        };
        match result {
            Ok(result) => {
                request.answer(result);
                Ok(())
            }
            Err(fault) => {
                request.answer(Err(AxisError::Fault(FAULT_DISCONNECTED)));
                Err(fault)
            }
        }
    }

    fn next_tick(&self) -> Instant {
        match self.phase {
            Phase::Running { .. } => self.last_heard + self.timeout,
            Phase::Ready => Instant::now() + IDLE_TICK,
        }
    }

    fn on_tick(&mut self, _wire: &mut Wire, _shared: &Shared) -> Result<(), LinkFault> {
        if matches!(self.phase, Phase::Running { .. }) && self.last_heard.elapsed() >= self.timeout
        {
            return Err(LinkFault::Timeout(format!(
                "the P2 demo board sent no screen for {} ms in the middle of a move",
                self.timeout.as_millis()
            )));
        }
        Ok(())
    }
}

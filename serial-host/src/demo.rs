//! The P2 demo dialect, host side: answer the two prompts, read position
//! and mode from the screens.
//!
//! The board has one motor and no commands: it prompts `Enter steps:`,
//! then `Enter speed:`, runs the move while it shows displays (reading
//! nothing), and prompts again. So a move is accepted only at the steps
//! prompt (else [`AxisError::Busy`]), status is whatever the screens last
//! showed, and a board that stops sending displays in the middle of a
//! move (for longer than the timeout) is taken as lost.
//!
//! Connecting sends nothing the demo could read as (part of) an answer
//! until the host knows where the program is ([`DemoStart`]): by default
//! it only listens for a whole screen.

use std::time::{Duration, Instant};

use super::request::{Op, Request};
use super::state::{AxisCache, Shared};
use super::wire::{Conversation, Incoming, LinkFault, Wire};
use super::{DemoStart, SerialError, FAULT_DISCONNECTED};
use cogstep_motion::axis::{AxisError, AxisStatus, Mode};
use cogstep_protocol::p2demo::{DemoField, DemoPrompt, ScreenEvent};

/// What [`SerialBoard::identity`](crate::SerialBoard::identity) says for a
/// P2 demo board.
pub const P2DEMO_IDENTITY: &str = "P2 Stepper Demo";

/// How often the link thread looks at the board while it is quiet.
const IDLE_TICK: Duration = Duration::from_millis(100);
/// The key pressed for a board that waits for its first key: a space,
/// which no answer reads as a digit, a sign or an end.
const WAKE_KEY: u8 = b' ';
/// How long DTR and RTS are held for a reset.
const RESET_PULSE: Duration = Duration::from_millis(10);
/// How long a reset board takes to boot from flash and reach its
/// `rxflush`/`rx` (the P2 boots in tens of ms; generous).
const RESET_BOOT: Duration = Duration::from_millis(500);
/// A position field holds 6 characters: wider positions keep their
/// rightmost 6 digits (and lose their sign).
const POSITION_FIELD_SPAN: i64 = 1_000_000;

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
    /// The position as best known (screens show 6 characters of it).
    position: Option<i64>,
}

impl Demo {
    /// Brings the board to a known prompt as `start` says, then listens:
    /// a steps prompt means the board is ready; two displays without a
    /// prompt, that a move runs; a speed prompt, that it waits for an
    /// answer this host did not start (an error). Nothing is sent unless
    /// `start` asks for it.
    pub fn handshake(
        wire: &mut Wire,
        shared: &Shared,
        start: DemoStart,
    ) -> Result<Demo, SerialError> {
        let config = &shared.config;
        let what = "the P2 demo screen";
        let fail = |fault: LinkFault| fault.into_open_error(shared, what);
        shared.state().axes.resize(1, AxisCache::default());
        let mut demo = Demo {
            phase: Phase::Ready,
            timeout: config.timeout,
            last_heard: Instant::now(),
            last_position: None,
            position: None,
        };
        if start == DemoStart::Reset {
            wire.pulse_reset(RESET_PULSE)
                .map_err(|source| SerialError::Reset {
                    port: config.port.clone(),
                    source,
                })?;
            // What a resetting board prints is noise.
            wire.discard_for(RESET_BOOT).map_err(fail)?;
        }
        if start != DemoStart::Passive {
            wire.send(&[WAKE_KEY]).map_err(fail)?;
        }
        let listened = Instant::now();
        let deadline = listened + config.timeout;
        let mut displays = 0;
        loop {
            match wire.next_event(deadline).map_err(fail)? {
                None if displays > 0 => {
                    demo.phase = Phase::Running { target: None };
                    break;
                }
                None if start == DemoStart::Passive => {
                    return Err(SerialError::DemoStateUnknown {
                        port: config.port.clone(),
                        waited_ms: listened.elapsed().as_millis(),
                    })
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
        let (shown_position, mode_bits) = match event {
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
            _ => (None, None),
        };
        let position = shown_position.map(|shown| {
            let position = unwrap_position(shown, self.position);
            self.position = Some(position);
            position
        });
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

    /// Makes the step counts, the moving bit and the velocity agree with
    /// the phase.
    fn publish(&self, shared: &Shared) {
        let mut state = shared.state();
        let Some(axis) = state.axes.get_mut(0) else {
            return;
        };
        let status = &mut axis.status;
        match self.phase {
            Phase::Ready => {
                set_steps_left(status, 0);
                status.mode = status.mode.difference(Mode::MOVING);
                status.velocity_steps_per_s = 0;
            }
            Phase::Running { target } => {
                let left = target.map_or(1, |target| target.abs_diff(status.position));
                set_steps_left(status, left.max(1));
                status.mode = status.mode.union(Mode::MOVING);
            }
        }
        // The stop pin is on the board, out of the host's sight.
        status.stop_pin_high = true;
    }

    /// Answers the two prompts; waits for the move to start.
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
        // The board reads at the steps prompt now; each answer goes out
        // only once its prompt has been printed whole (bytes that arrive
        // while the board prints overwrite each other in its receive pin).
        wire.send(format!("{steps}\r").as_bytes())?;
        match self.await_prompt(wire, shared)? {
            Waited::Prompt(DemoPrompt::Speed) => {}
            Waited::Prompt(DemoPrompt::Steps) | Waited::Cleared => {
                return Ok(Err(AxisError::Fault(
                    "the P2 demo board did not take the steps",
                )));
            }
        }
        wire.send(format!("{speed}\r").as_bytes())?;
        match self.await_prompt(wire, shared)? {
            Waited::Cleared => {
                let start = self.position.unwrap_or(0);
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
            Waited::Prompt(_) => Ok(Err(AxisError::Fault(
                "the P2 demo board did not start the move",
            ))),
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

/// The step counts of a P2 demo move in progress: the cog takes the
/// demo's command at once, so the steps left are a countdown, never a
/// command waiting.
fn set_steps_left(status: &mut AxisStatus, left: u64) {
    status.stm = 0;
    status.steps_to_go = left;
}

/// The position a 6-character field stands for: `shown` itself, or,
/// when it may have lost leading digits (a wider number keeps its
/// rightmost 6 characters, so its sign too), the candidate nearest to the
/// position known before.
pub(super) fn unwrap_position(shown: i32, known: Option<i64>) -> i64 {
    let shown = i64::from(shown);
    let Some(known) = known else {
        return shown;
    };
    if shown < 0 {
        // A sign survives only in a field that was not cut.
        return shown;
    }
    let span = POSITION_FIELD_SPAN;
    let turns = known.div_euclid(span);
    let mut best = shown;
    for turn in [turns - 1, turns, turns + 1] {
        let base = turn.saturating_mul(span);
        for candidate in [base.saturating_add(shown), base.saturating_sub(shown)] {
            // The board's position is a 32-bit long.
            let fits = i32::try_from(candidate).is_ok();
            let cut = candidate.unsigned_abs() >= 100_000 || candidate == shown;
            let consistent = if candidate >= 0 {
                candidate.rem_euclid(span) == shown
            } else {
                (-candidate).rem_euclid(span) == shown && -candidate >= 100_000
            };
            if fits && cut && consistent && candidate.abs_diff(known) < best.abs_diff(known) {
                best = candidate;
            }
        }
    }
    best
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
            Op::Command { .. }
            | Op::JogRelease(_)
            | Op::GrblUnlock
            | Op::GrblStream
            | Op::GrblCancel => Ok(Err(AxisError::Unsupported(super::P2DEMO_UNSUPPORTED))),
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

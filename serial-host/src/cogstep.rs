//! The cogstep dialect, host side: identify with `I`, poll with `?`,
//! send command lines with their checksum and read their final replies.

use std::time::{Duration, Instant};

use super::request::{Op, Request};
use super::state::{AxisCache, Shared};
use super::wire::{Conversation, Incoming, LinkFault, Wire};
use super::{SerialError, FAULT_DISCONNECTED, FAULT_RESET_MID_MOVE};
use cogstep_motion::axis::{AxisError, AxisState, AxisStatus, LimitStatus, Mode};
use cogstep_protocol::{
    refusal_of_error, Command, ErrorCode, LimitLine, Reply, StatusLine, Target, PROTOCOL_VERSION,
};

/// The most axes a board may report (more is taken as garbage).
const AXES_MAX: usize = 64;
/// How long a line another host left half written gets to be answered
/// before `I` is sent.
const SETTLE: Duration = Duration::from_millis(20);

/// What `I` says.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Identity {
    /// The whole line, brackets included.
    pub line: String,
    /// `proto:`
    pub proto: u32,
    /// `axes:`
    pub axes: usize,
    /// `clkfreq:`
    pub clkfreq: u32,
}

/// Reads `[cogstep <version> proto:<n> axes:<n> clkfreq:<hz>]` (given
/// without its brackets, as [`Reply::Info`] holds it).
pub(super) fn parse_identity(info: &str) -> Option<Identity> {
    let mut words = info.split(' ').filter(|word| !word.is_empty());
    if words.next()? != "cogstep" {
        return None;
    }
    words.next()?; // the firmware version
    let (mut proto, mut axes, mut clkfreq) = (None, None, None);
    for word in words {
        match word.split_once(':') {
            Some(("proto", value)) => proto = value.parse().ok(),
            Some(("axes", value)) => axes = value.parse().ok(),
            Some(("clkfreq", value)) => clkfreq = value.parse().ok(),
            _ => {}
        }
    }
    Some(Identity {
        line: format!("[{info}]"),
        proto: proto?,
        axes: axes?,
        clkfreq: clkfreq?,
    })
}

/// A status line as an [`AxisStatus`] whose [`state`](AxisStatus::state)
/// is the line's: cogstep's flags (emergency stop, hold, jog) are
/// restored from the state name, since the line carries only the 6
/// reference mode bits.
pub(super) fn status_from_line(line: &StatusLine) -> AxisStatus {
    let mut mode = Mode(u32::from(line.mode_bits));
    match line.state {
        AxisState::Alarm => mode |= Mode::ESTOP,
        AxisState::Jog => mode |= Mode::JOG,
        AxisState::Hold => {
            let explained = !line.stop_pin_high && mode.contains(Mode::STOP_LATCHED);
            if !explained {
                mode |= Mode::HOLD;
            }
        }
        AxisState::Idle | AxisState::Run => {}
    }
    AxisStatus {
        position: line.position,
        stm: line.stm,
        steps_to_go: line.steps_to_go,
        mode,
        velocity_steps_per_s: line.velocity_steps_per_s,
        stop_pin_high: line.stop_pin_high,
    }
}

/// The [`AxisError`] a board's `error:<code> <text>` stands for (see the
/// table on [`SerialAxis`](super::SerialAxis)'s contract): a refusal, read
/// back with the protocol's refusal table, is exactly the error the
/// board's axis gave; the transport errors keep their meaning; any other
/// line (a parse error, an older board's text) is a [`AxisError::Fault`]
/// that says what the code was.
pub(super) fn axis_error(code: u8, text: &str) -> AxisError {
    if let Some((refusal, values)) = refusal_of_error(code, text) {
        return AxisError::from_refusal(refusal, values);
    }
    match ErrorCode::from_number(code) {
        Some(ErrorCode::UnknownCommand) => {
            AxisError::Unsupported(if text.starts_with("not supported") {
                "not supported by the board"
            } else {
                "the board does not know this command"
            })
        }
        Some(ErrorCode::BadArgument) if text.starts_with("fault: ") => {
            AxisError::Fault("the board reported an axis fault")
        }
        Some(ErrorCode::BadArgument) => AxisError::Fault("the board refused an argument"),
        Some(ErrorCode::NoSuchAxis) => AxisError::Unavailable,
        Some(ErrorCode::LineTooLong) => AxisError::Fault("the board found the line too long"),
        Some(ErrorCode::SpeedOutOfRange) => AxisError::Fault("the board refused the speed"),
        Some(ErrorCode::Checksum) => AxisError::Fault("line noise"),
        Some(ErrorCode::Busy | ErrorCode::NotIdle | ErrorCode::Limit | ErrorCode::Homing) => {
            AxisError::Fault("the board gave a refusal this host does not know")
        }
        None => AxisError::Fault("the board sent an unknown error code"),
    }
}

/// What one received line amounted to.
enum Seen {
    /// `ok` or `error:<code> <text>`.
    Final(Result<(), (u8, String)>),
    /// A status line, or the information line that replaces one.
    Status,
    /// Anything else (information, an identity, garbage).
    Other,
}

/// The cogstep conversation.
pub(super) struct Cogstep {
    axes: usize,
    clkfreq: u32,
    poll_interval: Duration,
    timeout: Duration,
    next_poll: Instant,
    /// Axes whose `R` waits for them to stop (jog release).
    run_when_stopped: Vec<bool>,
}

impl Cogstep {
    /// Identifies the board (`I`), reads every status once, and marks the
    /// link up.
    pub fn handshake(wire: &mut Wire, shared: &Shared) -> Result<Cogstep, SerialError> {
        let config = &shared.config;
        let port = || config.port.clone();
        let fail = |fault: LinkFault, what| fault.into_open_error(shared, what);
        // A line another program left half written must not run: a DEL
        // makes it a line with a byte that is not printable, which the
        // board rejects whole (error:2); that reply is dropped.
        wire.send(b"\x7f\n")
            .and_then(|()| wire.discard_for(SETTLE))
            .map_err(|fault| fail(fault, "the port"))?;
        let mut line = String::new();
        // Writing into a String cannot fail.
        let _ = Command::Identify.write_checked(&mut line);
        line.push('\n');
        wire.send(line.as_bytes())
            .map_err(|fault| fail(fault, "the identity line (`I`)"))?;
        let deadline = Instant::now() + config.timeout;
        let mut identity = None;
        let identity = loop {
            let event = wire
                .next_event(deadline)
                .map_err(|fault| fail(fault, "the identity line (`I`)"))?;
            let Some(event) = event else {
                return Err(SerialError::Timeout {
                    port: port(),
                    what: "the identity line (`I`)",
                    timeout_ms: config.timeout.as_millis(),
                });
            };
            let Incoming::Line(text) = event else {
                continue;
            };
            match Reply::parse(&text) {
                Some(Reply::Info(info)) => {
                    if let Some(found) = parse_identity(info) {
                        identity = Some(found);
                    }
                }
                // A final reply before the identity belongs to an older line.
                Some(Reply::Ok) => {
                    if let Some(found) = identity.take() {
                        break found;
                    }
                }
                _ => {}
            }
        };
        if identity.proto != PROTOCOL_VERSION {
            return Err(SerialError::Handshake {
                port: port(),
                reason: format!(
                    "the board speaks protocol {}, this host {PROTOCOL_VERSION}",
                    identity.proto
                ),
            });
        }
        if identity.axes == 0 || identity.axes > AXES_MAX {
            return Err(SerialError::Handshake {
                port: port(),
                reason: format!("the board reports {} axes", identity.axes),
            });
        }
        let mut cogstep = Cogstep {
            axes: identity.axes,
            clkfreq: identity.clkfreq,
            // A zero interval would poll without pause.
            poll_interval: config.poll_interval.max(Duration::from_millis(1)),
            timeout: config.timeout,
            next_poll: Instant::now(),
            run_when_stopped: vec![false; identity.axes],
        };
        shared
            .state()
            .axes
            .resize(identity.axes, AxisCache::default());
        cogstep
            .exchange_status(wire, shared)
            .map_err(|fault| fail(fault, "the status lines (`?`)"))?;
        shared
            .state()
            .link_up(identity.line, identity.clkfreq, identity.axes);
        Ok(cogstep)
    }

    /// Takes one received line: statuses go to the cache; an identity
    /// nobody asked for is a reset.
    fn take_line(&mut self, shared: &Shared, text: &str) -> Seen {
        match Reply::parse(text) {
            Some(Reply::Ok) => Seen::Final(Ok(())),
            Some(Reply::Error { code, text }) => Seen::Final(Err((code, text.to_string()))),
            Some(Reply::Status(line)) => {
                if let Some(axis) = shared.state().axes.get_mut(line.axis) {
                    axis.status = status_from_line(&line);
                }
                Seen::Status
            }
            Some(Reply::Info(info)) if info.starts_with("status failed: ") => Seen::Status,
            Some(Reply::Info(info))
                if ["limits ", "fault ", "home "]
                    .iter()
                    .any(|kind| info.starts_with(kind)) =>
            {
                // The `L` reply's lines: each fills in its part.
                let mut state = shared.state();
                let mut status = LimitStatus::default();
                if let Some(index) = LimitLine::parse_into(info, &mut status) {
                    if let Some(axis) = state.axes.get_mut(index) {
                        let mut merged = axis.limits.unwrap_or_default();
                        LimitLine::parse_into(info, &mut merged);
                        axis.limits = Some(merged);
                    }
                }
                Seen::Other
            }
            Some(Reply::Info(info)) => {
                // The host sends `I` only in the handshake: an identity
                // line now was not asked for.
                if let Some(identity) = parse_identity(info) {
                    self.board_reset(shared, identity);
                }
                Seen::Other
            }
            None => Seen::Other,
        }
    }

    /// The board announced itself unasked: it has restarted.
    fn board_reset(&mut self, shared: &Shared, identity: Identity) {
        let axes = identity.axes.clamp(1, AXES_MAX);
        let mut state = shared.state();
        state.latch_moving(FAULT_RESET_MID_MOVE);
        state.link_up(identity.line, identity.clkfreq, axes);
        drop(state);
        self.axes = axes;
        self.clkfreq = identity.clkfreq;
        self.run_when_stopped = vec![false; axes];
        // Read the restarted board's status at once.
        self.next_poll = Instant::now();
    }

    /// Waits for the final reply to the line just sent.
    fn await_final(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        what: &str,
    ) -> Result<Result<(), (u8, String)>, LinkFault> {
        let deadline = Instant::now() + self.timeout;
        loop {
            match wire.next_event(deadline)? {
                None => {
                    return Err(LinkFault::Timeout(format!(
                        "no reply to `{what}` within {} ms",
                        self.timeout.as_millis()
                    )))
                }
                Some(Incoming::Line(text)) => {
                    if let Seen::Final(result) = self.take_line(shared, &text) {
                        return Ok(result);
                    }
                }
                Some(_) => {}
            }
        }
    }

    /// `?`, and waits for one status line per axis.
    fn exchange_status(&mut self, wire: &mut Wire, shared: &Shared) -> Result<(), LinkFault> {
        wire.send(b"?")?;
        let deadline = Instant::now() + self.timeout;
        let mut seen = 0;
        while seen < self.axes {
            match wire.next_event(deadline)? {
                None => {
                    return Err(LinkFault::Timeout(format!(
                        "{seen} of {} status lines within {} ms",
                        self.axes,
                        self.timeout.as_millis()
                    )))
                }
                Some(Incoming::Line(text)) => {
                    if let Seen::Status = self.take_line(shared, &text) {
                        seen += 1;
                    }
                }
                Some(_) => {}
            }
        }
        self.next_poll = Instant::now() + self.poll_interval;
        Ok(())
    }

    /// Sends one command line (with its checksum) and reads its reply;
    /// a checksum refusal (line noise) is sent once more.
    fn run_command(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        command: &Command,
    ) -> Result<Result<(), AxisError>, LinkFault> {
        let mut line = String::new();
        // Writing into a String cannot fail.
        let _ = command.write_checked(&mut line);
        let what = command.to_string();
        line.push('\n');
        for attempt in 0..2 {
            wire.send(line.as_bytes())?;
            match self.await_final(wire, shared, &what)? {
                Ok(()) => return Ok(Ok(())),
                Err((code, _)) if code == ErrorCode::Checksum.number() && attempt == 0 => {}
                Err((code, text)) => return Ok(Err(axis_error(code, &text))),
            }
        }
        Ok(Err(AxisError::Fault("line noise")))
    }

    /// Carries out one request and says what to answer.
    fn execute(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        op: Op,
    ) -> Result<Result<(), AxisError>, LinkFault> {
        let result = match op {
            Op::Refresh => return self.exchange_status(wire, shared).map(Ok),
            Op::DemoMove { .. } => {
                return Ok(Err(AxisError::Unsupported("not a P2 demo board")));
            }
            Op::GrblUnlock | Op::GrblStream | Op::GrblCancel => {
                return Ok(Err(AxisError::Unsupported("not a grbl board")))
            }
            Op::JogRelease(axis) => {
                let result = self.run_command(wire, shared, &Command::Stop(Target::Axis(axis)))?;
                if result.is_ok() {
                    if let Some(pending) = self.run_when_stopped.get_mut(axis) {
                        *pending = true;
                    }
                }
                (Some(axis), result)
            }
            Op::Command { axis, command } => {
                // An explicit stop-pin command overrides a pending release.
                match command {
                    Command::Stop(Target::Axis(index)) | Command::Run(Target::Axis(index)) => {
                        if let Some(pending) = self.run_when_stopped.get_mut(index) {
                            *pending = false;
                        }
                    }
                    Command::Stop(Target::All) | Command::Run(Target::All) => {
                        self.run_when_stopped.fill(false);
                    }
                    _ => {}
                }
                (axis, self.run_command(wire, shared, &command)?)
            }
        };
        let (axis, result) = result;
        if result.is_ok() {
            let mut state = shared.state();
            match axis {
                Some(index) => {
                    if let Some(cache) = state.axes.get_mut(index) {
                        cache.latched = None;
                    }
                }
                None => state.axes.iter_mut().for_each(|cache| cache.latched = None),
            }
        }
        Ok(result)
    }

    /// Sends `R` to the released axes that have stopped.
    fn finish_releases(&mut self, wire: &mut Wire, shared: &Shared) -> Result<(), LinkFault> {
        for axis in 0..self.run_when_stopped.len() {
            if !self.run_when_stopped[axis] {
                continue;
            }
            let stopped = shared
                .state()
                .axes
                .get(axis)
                .is_none_or(|cache| !cache.status.mode.has(Mode::MOVING));
            if stopped {
                self.run_when_stopped[axis] = false;
                // A refusal leaves the pin low; the caller sees it in the status.
                let _ = self.run_command(wire, shared, &Command::Run(Target::Axis(axis)))?;
            }
        }
        Ok(())
    }
}

impl Conversation for Cogstep {
    fn on_event(
        &mut self,
        _wire: &mut Wire,
        shared: &Shared,
        event: Incoming,
    ) -> Result<(), LinkFault> {
        if let Incoming::Line(text) = event {
            self.take_line(shared, &text);
        }
        Ok(())
    }

    fn on_request(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        request: Request,
    ) -> Result<(), LinkFault> {
        let changes_axes = !matches!(request.op, Op::Refresh | Op::DemoMove { .. });
        match self.execute(wire, shared, request.op) {
            Ok(result) => {
                // Read the status before answering, so that the caller's
                // next status() sees what the command did.
                let fresh = if changes_axes && result.is_ok() {
                    self.exchange_status(wire, shared)
                } else {
                    Ok(())
                };
                request.answer(result);
                fresh
            }
            Err(fault) => {
                request.answer(Err(AxisError::Fault(FAULT_DISCONNECTED)));
                Err(fault)
            }
        }
    }

    fn next_tick(&self) -> Instant {
        self.next_poll
    }

    fn on_tick(&mut self, wire: &mut Wire, shared: &Shared) -> Result<(), LinkFault> {
        self.exchange_status(wire, shared)?;
        self.finish_releases(wire, shared)
    }
}

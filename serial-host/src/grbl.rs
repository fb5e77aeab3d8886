//! The grbl 1.1 dialect, host side: recognise the board by its status
//! report, learn its axes from `$$`, move in steps with absolute `G1`
//! lines, read positions from `?` reports (MPos × steps/mm, rounded).
//!
//! Connecting never disturbs a board that runs: the host spoils a line
//! another program may have left half written (a DEL and a line end: the
//! board rejects the line whole), asks for one status report (a realtime
//! byte, answered in every state) and reads the settings only at rest
//! (grbl answers `$$` in Idle and Alarm only); a busy board is refused
//! with [`SerialError::Handshake`] and nothing else is sent.

use std::time::{Duration, Instant};

use super::grbl_stream::{StreamState, Streamer};
use super::request::{Op, Request};
use super::state::{AxisCache, Shared};
use super::wire::{Conversation, Incoming, LinkFault, Wire};
use super::{SerialError, FAULT_DISCONNECTED, FAULT_RESET_MID_MOVE};
use cogstep_motion::axis::{AxisError, AxisStatus, Mode};
use cogstep_protocol::grbl::{parse_grbl_number, GrblAlarm, GrblError, GRBL_AXES, WELCOME};
use cogstep_protocol::Command;

/// How long a line another host left half written gets to be answered.
const SETTLE: Duration = Duration::from_millis(20);
/// How long after a program's last answer a report at rest ends it (the
/// board may start its cycle a moment after it answered the last line).
const REST_CONFIRM: Duration = Duration::from_millis(60);
/// How long a cancel waits for the board to come to rest along its path.
const CANCEL_PATIENCE: Duration = Duration::from_secs(30);
/// How often a cancel asks for a report while it waits.
const CANCEL_POLL: Duration = Duration::from_millis(20);
/// Millimetres per inch (`$13=1` reports inches).
const MM_PER_INCH: f64 = 25.4;
/// The most decimals a target is written with.
const DECIMALS_MAX: usize = 12;

/// [`AxisError::Fault`] of a move refused because the board is in Alarm.
pub const FAULT_GRBL_ALARM: &str =
    "the grbl board is in Alarm: unlock it with $X (SerialBoard::unlock) or home it with $H";
/// [`AxisError::Unsupported`] of what grbl has no honest mapping for.
pub const GRBL_UNSUPPORTED: &str =
    "a grbl board has one planner for all axes: no per-axis jog, homing, limits or set position \
     (G92 offsets the work position, not MPos)";

/// What the last status report of a grbl board said
/// ([`SerialBoard::grbl_status`](super::SerialBoard::grbl_status)).
#[derive(Clone, Debug, PartialEq)]
pub struct GrblStatus {
    /// The state as the board wrote it: `Idle`, `Run`, `Hold:0`, `Hold:1`,
    /// `Jog`, `Alarm`, `Home`, `Check`…
    pub state: String,
    /// The feed now, mm/min (`FS:`'s first field, in mm).
    pub feed_mm_min: f64,
    /// The machine position, mm: the step counts over steps/mm.
    pub mpos_mm: [f64; GRBL_AXES],
}

/// A machine state as a report names it (`Hold:0` and `Hold:1` are `Hold`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum GrblMachine {
    Idle,
    Run,
    Hold,
    Jog,
    Alarm,
    Home,
    Check,
    Other,
}

impl GrblMachine {
    fn parse(name: &str) -> Self {
        match name.split(':').next().unwrap_or("") {
            "Idle" => GrblMachine::Idle,
            "Run" => GrblMachine::Run,
            "Hold" => GrblMachine::Hold,
            "Jog" => GrblMachine::Jog,
            "Alarm" => GrblMachine::Alarm,
            "Home" => GrblMachine::Home,
            "Check" => GrblMachine::Check,
            _ => GrblMachine::Other,
        }
    }

    /// At rest: settings can be read and targets follow the position.
    fn at_rest(self) -> bool {
        matches!(
            self,
            GrblMachine::Idle | GrblMachine::Alarm | GrblMachine::Check
        )
    }
}

/// One status report: `<State|MPos:x,y,z|FS:f,s|WCO:x,y,z|...>`.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Report {
    pub state: GrblMachine,
    /// The state as the board wrote it (`Hold:1`).
    pub state_text: String,
    /// MPos, when the report has it.
    pub mpos: Option<[f64; GRBL_AXES]>,
    /// WPos, when the report has it (`$10=0`).
    pub wpos: Option<[f64; GRBL_AXES]>,
    /// WCO, when the report has it.
    pub wco: Option<[f64; GRBL_AXES]>,
    /// The feed, units/min.
    pub feed: f64,
}

fn parse_axes(text: &str) -> Option<[f64; GRBL_AXES]> {
    let mut values = [0.0; GRBL_AXES];
    let mut parts = text.split(',');
    for value in &mut values {
        *value = parse_grbl_number(parts.next()?)?;
    }
    Some(values)
}

/// Reads a status report line; `None` for anything else.
pub(super) fn parse_report(line: &str) -> Option<Report> {
    let inner = line.strip_prefix('<')?.strip_suffix('>')?;
    let mut fields = inner.split('|');
    let state_text = fields.next()?.to_string();
    let mut report = Report {
        state: GrblMachine::parse(&state_text),
        state_text,
        mpos: None,
        wpos: None,
        wco: None,
        feed: 0.0,
    };
    for field in fields {
        let Some((name, value)) = field.split_once(':') else {
            continue;
        };
        match name {
            "MPos" => report.mpos = Some(parse_axes(value)?),
            "WPos" => report.wpos = Some(parse_axes(value)?),
            "WCO" => report.wco = Some(parse_axes(value)?),
            "FS" | "F" => {
                report.feed = value
                    .split(',')
                    .next()
                    .and_then(parse_grbl_number)
                    .unwrap_or(0.0)
            }
            _ => {}
        }
    }
    (report.mpos.is_some() || report.wpos.is_some()).then_some(report)
}

/// The text of a target in mm that the board's parser rounds back to
/// exactly `steps` (it reads the number as an `f64`, multiplies by
/// steps/mm and rounds half away from zero): the fewest decimals from 3
/// up that do.
pub(super) fn target_text(steps: i64, steps_per_mm: f64) -> Option<String> {
    let mm = steps as f64 / steps_per_mm;
    (3..=DECIMALS_MAX).find_map(|decimals| {
        let text = format!("{mm:.decimals$}");
        let back = text.parse::<f64>().ok()? * steps_per_mm;
        (back.round() as i64 == steps).then_some(text)
    })
}

/// The [`AxisError`] a board's `error:N` stands for.
pub(super) fn axis_error(code: u8) -> AxisError {
    match code {
        c if c == GrblError::SystemGcLock.code() => AxisError::Fault(FAULT_GRBL_ALARM),
        c if c == GrblError::IdleError.code() => AxisError::NotIdle,
        c if c == GrblError::TravelExceeded.code() => AxisError::BeyondSoftLimit,
        c if c == GrblError::UnsupportedCommand.code() => {
            AxisError::Unsupported("the grbl board does not support this G-code")
        }
        c if c == GrblError::InvalidTarget.code() => AxisError::PositionOutOfRange,
        c if c == GrblError::Overflow.code() => {
            AxisError::Fault("the board found the line too long")
        }
        _ => AxisError::Fault("the grbl board refused the line"),
    }
}

/// What one received line amounted to.
enum Seen {
    /// `ok`, or `error:N`.
    Final(Result<(), u8>),
    Report,
    /// `ALARM:N`.
    Alarm(u8),
    /// The welcome line: the board has (been) reset.
    Welcome,
    Other,
}

/// The grbl conversation.
pub(super) struct Grbl {
    steps_per_mm: [f64; GRBL_AXES],
    max_rate_mm_min: [f64; GRBL_AXES],
    report_inches: bool,
    /// The work offset (G92), mm, as the board last reported it.
    wco: [f64; GRBL_AXES],
    /// Where the host's moves end, steps (the position at rest).
    target: [i64; GRBL_AXES],
    /// The last report's position, steps, and when it came.
    last_position: Option<([i64; GRBL_AXES], Instant)>,
    machine: GrblMachine,
    /// The last report said `Hold:0`: held, at rest on the path.
    held_at_rest: bool,
    poll_interval: Duration,
    timeout: Duration,
    next_poll: Instant,
    /// The program being streamed, if any.
    stream: Option<Streamer>,
    /// When the program's last line was answered.
    answered_all_at: Option<Instant>,
    /// A cancel under way: the feed hold went out; the reset is due once
    /// the board is at rest, or by then.
    cancel_by: Option<Instant>,
}

impl Grbl {
    /// Recognises the board by a status report, reads `$$` and `$#`, and
    /// marks the link up. Refuses a board that is not at rest.
    pub fn handshake(wire: &mut Wire, shared: &Shared) -> Result<Grbl, SerialError> {
        let config = &shared.config;
        let port = || config.port.clone();
        let fail = |fault: LinkFault, what| fault.into_open_error(shared, what);
        let mut grbl = Grbl {
            steps_per_mm: [0.0; GRBL_AXES],
            max_rate_mm_min: [0.0; GRBL_AXES],
            report_inches: false,
            wco: [0.0; GRBL_AXES],
            target: [0; GRBL_AXES],
            last_position: None,
            machine: GrblMachine::Other,
            held_at_rest: false,
            poll_interval: config.poll_interval.max(Duration::from_millis(1)),
            timeout: config.timeout,
            next_poll: Instant::now(),
            stream: None,
            answered_all_at: None,
            cancel_by: None,
        };
        // The spoiled line's own reply (`error:1`, or `ok` for an empty
        // one) comes first: waited for, so that a slow link cannot make
        // it the reply to `$$`.
        wire.send(b"\x7f\n")
            .map_err(|fault| fail(fault, "the port"))?;
        let deadline = Instant::now() + config.timeout;
        loop {
            match wire
                .next_event(deadline)
                .map_err(|fault| fail(fault, "the reply to a spoiled line"))?
            {
                None => {
                    return Err(SerialError::Timeout {
                        port: port(),
                        what: "the reply to a spoiled line (DEL, line end)",
                        timeout_ms: config.timeout.as_millis(),
                    })
                }
                Some(Incoming::Line(text)) if final_of(&text).is_some() => break,
                Some(_) => {}
            }
        }
        // What else a board busy with another host sends meanwhile.
        wire.discard_for(SETTLE)
            .map_err(|fault| fail(fault, "the port"))?;
        wire.send(b"?")
            .map_err(|fault| fail(fault, "a grbl status report (`?`)"))?;
        let deadline = Instant::now() + config.timeout;
        let report = loop {
            match wire
                .next_event(deadline)
                .map_err(|fault| fail(fault, "a grbl status report (`?`)"))?
            {
                None => {
                    return Err(SerialError::Timeout {
                        port: port(),
                        what: "a grbl status report (`?`)",
                        timeout_ms: config.timeout.as_millis(),
                    })
                }
                Some(Incoming::Line(text)) => {
                    if let Some(report) = parse_report(&text) {
                        break report;
                    }
                }
                Some(_) => {}
            }
        };
        if !report.state.at_rest() {
            return Err(SerialError::Handshake {
                port: port(),
                reason: format!(
                    "the grbl board is busy ({}): its settings ($$) are read only at rest; \
                     nothing was sent. Connect when it is Idle",
                    report.state_text
                ),
            });
        }
        let mut settings_seen = [false; GRBL_AXES];
        let mut settings = Vec::new();
        grbl.line_collecting(wire, "$$", &mut |grbl, text| {
            let Some((number, value)) = text.strip_prefix('$').and_then(|t| t.split_once('='))
            else {
                return;
            };
            let (Ok(number), Some(value)) = (number.parse::<u16>(), parse_grbl_number(value))
            else {
                return;
            };
            settings.push((number, value));
            match number {
                13 => grbl.report_inches = value != 0.0,
                100..=102 => {
                    grbl.steps_per_mm[usize::from(number - 100)] = value;
                    settings_seen[usize::from(number - 100)] = true;
                }
                110..=112 => grbl.max_rate_mm_min[usize::from(number - 110)] = value,
                _ => {}
            }
        })
        .map_err(|fault| fail(fault, "the settings (`$$`)"))?
        .map_err(|code| SerialError::Handshake {
            port: port(),
            reason: format!("the board answered `$$` with error:{code}"),
        })?;
        let usable = |value: f64| value.is_finite() && value > 0.0;
        if settings_seen.contains(&false)
            || !grbl.steps_per_mm.iter().all(|&v| usable(v))
            || !grbl.max_rate_mm_min.iter().all(|&v| usable(v))
        {
            return Err(SerialError::Handshake {
                port: port(),
                reason: "the board's `$$` lacks usable $100-$102 and $110-$112".to_string(),
            });
        }
        grbl.line_collecting(wire, "$#", &mut |grbl, text| {
            if let Some(values) = text
                .strip_prefix("[G92:")
                .and_then(|rest| rest.strip_suffix(']'))
                .and_then(parse_axes)
            {
                grbl.wco = values.map(|value| grbl.to_mm(value));
            }
        })
        .map_err(|fault| fail(fault, "the offsets (`$#`)"))?
        .map_err(|code| SerialError::Handshake {
            port: port(),
            reason: format!("the board answered `$#` with error:{code}"),
        })?;
        shared.state().axes.resize(GRBL_AXES, AxisCache::default());
        shared.state().grbl_settings = settings;
        grbl.take_report(shared, &report);
        shared.state().link_up(WELCOME.to_string(), 0, GRBL_AXES);
        Ok(grbl)
    }

    fn to_mm(&self, value: f64) -> f64 {
        if self.report_inches {
            value * MM_PER_INCH
        } else {
            value
        }
    }

    /// Sends `line` and hands every line before its final reply to `take`.
    fn line_collecting(
        &mut self,
        wire: &mut Wire,
        line: &str,
        take: &mut dyn FnMut(&mut Grbl, &str),
    ) -> Result<Result<(), u8>, LinkFault> {
        wire.send(format!("{line}\n").as_bytes())?;
        let deadline = Instant::now() + self.timeout;
        loop {
            match wire.next_event(deadline)? {
                None => {
                    return Err(LinkFault::Timeout(format!(
                        "no reply to `{line}` within {} ms",
                        self.timeout.as_millis()
                    )))
                }
                Some(Incoming::Line(text)) => match final_of(&text) {
                    Some(result) => return Ok(result),
                    None => take(self, &text),
                },
                Some(_) => {}
            }
        }
    }

    /// Takes a report into the cache.
    fn take_report(&mut self, shared: &Shared, report: &Report) {
        if let Some(wco) = report.wco {
            self.wco = wco.map(|value| self.to_mm(value));
        }
        let mpos = match (report.mpos, report.wpos) {
            (Some(mpos), _) => mpos.map(|value| self.to_mm(value)),
            (None, Some(wpos)) => {
                let mut mpos = wpos.map(|value| self.to_mm(value));
                for (axis, value) in mpos.iter_mut().enumerate() {
                    *value += self.wco[axis];
                }
                mpos
            }
            (None, None) => return,
        };
        let mut position = [0i64; GRBL_AXES];
        for axis in 0..GRBL_AXES {
            position[axis] = (mpos[axis] * self.steps_per_mm[axis]).round() as i64;
        }
        self.machine = report.state;
        self.held_at_rest = report.state_text == "Hold:0";
        if report.state.at_rest() {
            // What ran (a host move, a program, a jog) has ended here.
            self.target = position;
            let settled = self
                .answered_all_at
                .is_some_and(|at| at.elapsed() >= REST_CONFIRM);
            if let Some(stream) = &mut self.stream {
                if settled && stream.all_answered {
                    stream.at_rest();
                }
            }
        }
        let now = Instant::now();
        let mut velocity = [0u32; GRBL_AXES];
        if let Some((before, at)) = self.last_position {
            let seconds = now.duration_since(at).as_secs_f64();
            if seconds > 0.0 && !report.state.at_rest() {
                for axis in 0..GRBL_AXES {
                    let speed = (position[axis] - before[axis]).unsigned_abs() as f64 / seconds;
                    velocity[axis] = speed.min(f64::from(u32::MAX)) as u32;
                }
            }
        }
        self.last_position = Some((position, now));
        let mut state = shared.state();
        state.grbl_status = Some(GrblStatus {
            state: report.state_text.clone(),
            feed_mm_min: self.to_mm(report.feed),
            mpos_mm: std::array::from_fn(|axis| position[axis] as f64 / self.steps_per_mm[axis]),
        });
        for (axis, cache) in state.axes.iter_mut().enumerate().take(GRBL_AXES) {
            let to_go = (self.target[axis] - position[axis]).unsigned_abs();
            let mut mode = Mode(0);
            match report.state {
                GrblMachine::Alarm => mode |= Mode::ESTOP,
                GrblMachine::Hold => mode |= Mode::HOLD,
                GrblMachine::Jog => mode |= Mode::JOG,
                GrblMachine::Home => mode |= Mode::HOMING,
                _ => {}
            }
            let moving = !report.state.at_rest() && (to_go > 0 || velocity[axis] > 0);
            if moving && report.state != GrblMachine::Hold {
                mode |= Mode::MOVING;
            }
            if self.target[axis] < position[axis] {
                mode |= Mode::REVERSE;
            }
            cache.status = AxisStatus {
                position: position[axis],
                stm: 0,
                // A program or jog the host did not send: busy until rest.
                steps_to_go: if report.state.at_rest() {
                    0
                } else {
                    to_go.max(u64::from(moving))
                },
                mode,
                velocity_steps_per_s: velocity[axis],
                stop_pin_high: report.state != GrblMachine::Hold,
            };
        }
    }

    /// Takes one received line.
    fn take_line(&mut self, shared: &Shared, text: &str) -> Seen {
        if let Some(result) = final_of(text) {
            return Seen::Final(result);
        }
        if let Some(report) = parse_report(text) {
            self.take_report(shared, &report);
            return Seen::Report;
        }
        if let Some(code) = text.strip_prefix("ALARM:").and_then(|c| c.parse().ok()) {
            return Seen::Alarm(code);
        }
        if text.starts_with("Grbl ") {
            return Seen::Welcome;
        }
        Seen::Other
    }

    /// The board printed its welcome unasked: it has restarted.
    fn board_reset(&mut self, shared: &Shared) {
        shared.state().latch_moving(FAULT_RESET_MID_MOVE);
        self.end_stream(StreamState::Reset);
        self.next_poll = Instant::now();
    }

    /// The program being streamed ends as `state` (the board dropped what
    /// it buffered).
    fn end_stream(&mut self, state: StreamState) {
        if let Some(mut stream) = self.stream.take() {
            stream.end(state);
        }
        self.answered_all_at = None;
    }

    /// A line seen while no command waits for its reply: a final reply
    /// answers the program's oldest line in flight (and lets the next
    /// lines go), an alarm or a welcome ends the program.
    fn on_unasked(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        seen: Seen,
    ) -> Result<(), LinkFault> {
        match seen {
            Seen::Final(result) => {
                if let Some(stream) = &mut self.stream {
                    if stream.answer(result) {
                        let bytes = stream.pump();
                        if stream.all_answered && self.answered_all_at.is_none() {
                            self.answered_all_at = Some(Instant::now());
                        }
                        if stream.is_over() {
                            self.stream = None;
                            self.answered_all_at = None;
                        }
                        if !bytes.is_empty() {
                            wire.send(&bytes)?;
                        }
                    }
                }
            }
            Seen::Alarm(code) => self.end_stream(StreamState::Alarm(code)),
            Seen::Welcome => self.board_reset(shared),
            Seen::Report => {
                if self.stream.as_ref().is_some_and(Streamer::is_over) {
                    self.stream = None;
                    self.answered_all_at = None;
                }
                self.cancel_progress(wire, shared)?;
            }
            Seen::Other => {}
        }
        Ok(())
    }

    /// `?`, and waits for the report.
    fn exchange_status(&mut self, wire: &mut Wire, shared: &Shared) -> Result<(), LinkFault> {
        wire.send(b"?")?;
        let deadline = Instant::now() + self.timeout;
        loop {
            match wire.next_event(deadline)? {
                None => {
                    return Err(LinkFault::Timeout(format!(
                        "no status report within {} ms",
                        self.timeout.as_millis()
                    )))
                }
                Some(Incoming::Line(text)) => match self.take_line(shared, &text) {
                    Seen::Report => {
                        self.on_unasked(wire, shared, Seen::Report)?;
                        break;
                    }
                    seen => self.on_unasked(wire, shared, seen)?,
                },
                Some(_) => {}
            }
        }
        // Sooner while a cancel waits for the board to come to rest.
        let interval = if self.cancel_by.is_some() {
            self.poll_interval.min(CANCEL_POLL)
        } else {
            self.poll_interval
        };
        self.next_poll = Instant::now() + interval;
        Ok(())
    }

    /// Sends one line and reads its final reply; an `ALARM:N` before it
    /// is the line's outcome (grbl answers `ok` to a soft-limit move).
    fn run_line(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        line: &str,
    ) -> Result<Result<(), AxisError>, LinkFault> {
        wire.send(format!("{line}\n").as_bytes())?;
        let deadline = Instant::now() + self.timeout;
        let mut alarm = None;
        loop {
            match wire.next_event(deadline)? {
                None => {
                    return Err(LinkFault::Timeout(format!(
                        "no reply to `{line}` within {} ms",
                        self.timeout.as_millis()
                    )))
                }
                Some(Incoming::Line(text)) => match self.take_line(shared, &text) {
                    Seen::Final(result) => {
                        return Ok(match (alarm, result) {
                            (Some(code), _) if code == GrblAlarm::SoftLimit.code() => {
                                Err(AxisError::BeyondSoftLimit)
                            }
                            (Some(_), _) => Err(AxisError::Fault(FAULT_GRBL_ALARM)),
                            (None, Ok(())) => Ok(()),
                            (None, Err(code)) => Err(axis_error(code)),
                        })
                    }
                    Seen::Alarm(code) => alarm = Some(code),
                    Seen::Welcome => self.board_reset(shared),
                    _ => {}
                },
                Some(_) => {}
            }
        }
    }

    /// A move of axis `axis` to `target` steps at `speed` steps/s, as a
    /// `G1` line; refused before a byte is sent when it cannot be exact.
    fn move_line(&self, axis: usize, target: i64, speed: u32) -> Result<String, AxisError> {
        if self.wco.iter().any(|&offset| offset != 0.0) {
            return Err(AxisError::Unsupported(
                "the grbl board has a G92 work offset: moves in steps need it cleared (G92.1)",
            ));
        }
        let steps_per_mm = self.steps_per_mm[axis];
        let feed_mm_min = f64::from(speed) / steps_per_mm * 60.0;
        if feed_mm_min > self.max_rate_mm_min[axis] {
            return Err(AxisError::Unsupported(
                "a speed above the axis's max rate ($110-$112)",
            ));
        }
        let text = target_text(target, steps_per_mm).ok_or(AxisError::PositionOutOfRange)?;
        let letter = ['X', 'Y', 'Z'][axis];
        Ok(format!("G90G21G1{letter}{text}F{feed_mm_min:.4}"))
    }

    /// Carries out one request and says what to answer.
    fn execute(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        op: Op,
    ) -> Result<Result<(), AxisError>, LinkFault> {
        // A cancel's reset would drop a line sent before it.
        let streaming = self.stream.is_some() || self.cancel_by.is_some();
        let command = match op {
            Op::Refresh => return self.exchange_status(wire, shared).map(Ok),
            Op::Command { command, .. } => command,
            Op::DemoMove { .. } => return Ok(Err(AxisError::Unsupported("not a P2 demo board"))),
            Op::JogRelease(_) => return Ok(Err(AxisError::Unsupported(GRBL_UNSUPPORTED))),
            Op::GrblUnlock if streaming => return Ok(Err(AxisError::NotIdle)),
            Op::GrblUnlock => return self.run_line(wire, shared, "$X"),
            // The program handed over is taken back by `stream_gcode`.
            Op::GrblStream if streaming => return Ok(Err(AxisError::NotIdle)),
            Op::GrblStream => return self.start_stream(wire, shared),
            Op::GrblCancel => return self.cancel_stream(wire, shared),
        };
        match command {
            Command::Move {
                axis,
                speed_steps_per_s,
                steps,
            } => {
                if axis >= GRBL_AXES {
                    return Ok(Err(AxisError::Unavailable));
                }
                if streaming {
                    return Ok(Err(AxisError::NotIdle));
                }
                if self.machine == GrblMachine::Alarm {
                    return Ok(Err(AxisError::Fault(FAULT_GRBL_ALARM)));
                }
                let Some(target) = self.target[axis].checked_add(i64::from(steps)) else {
                    return Ok(Err(AxisError::PositionOutOfRange));
                };
                let line = match self.move_line(axis, target, speed_steps_per_s) {
                    Ok(line) => line,
                    Err(error) => return Ok(Err(error)),
                };
                let result = self.run_line(wire, shared, &line)?;
                if result.is_ok() {
                    self.target[axis] = target;
                }
                Ok(result)
            }
            // A grbl board's faults (a limit, a soft reset while moving)
            // are one alarm lock for every axis: `$X` lifts it.
            Command::ClearLimitFault(axis) if axis < GRBL_AXES => {
                if streaming {
                    return Ok(Err(AxisError::NotIdle));
                }
                self.run_line(wire, shared, "$X")
            }
            Command::Stop(_) => wire.send(b"!").map(Ok),
            Command::Run(_) => wire.send(b"~").map(Ok),
            Command::EmergencyStop => self.soft_reset(wire, shared).map(Ok),
            _ => Ok(Err(AxisError::Unsupported(GRBL_UNSUPPORTED))),
        }
    }

    /// Starts streaming the program handed over in the shared state:
    /// refused unless the board is at rest and unlocked, and no other
    /// program streams.
    fn start_stream(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
    ) -> Result<Result<(), AxisError>, LinkFault> {
        let Some(job) = shared.state().grbl_stream.take() else {
            return Ok(Err(AxisError::Fault("no program was handed over")));
        };
        // The board's state now, not the last poll's.
        self.exchange_status(wire, shared)?;
        match self.machine {
            GrblMachine::Alarm => return Ok(Err(AxisError::Fault(FAULT_GRBL_ALARM))),
            GrblMachine::Idle | GrblMachine::Check => {}
            _ => return Ok(Err(AxisError::NotIdle)),
        }
        let mut stream = Streamer::new(job);
        let bytes = stream.pump();
        if stream.all_answered {
            // Nothing to send: done at once.
            stream.at_rest();
            return Ok(Ok(()));
        }
        self.stream = Some(stream);
        self.answered_all_at = None;
        wire.send(&bytes)?;
        Ok(Ok(()))
    }

    /// Cancels the program (or the motion an error left running): a feed
    /// hold now, no more lines; the rest is [`Grbl::cancel_progress`]'s,
    /// report by report, so that the link keeps serving (an emergency
    /// stop acts at once) while the board comes to rest.
    fn cancel_stream(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
    ) -> Result<Result<(), AxisError>, LinkFault> {
        self.exchange_status(wire, shared)?;
        if self.stream.is_none() && self.machine.at_rest() {
            // Nothing streams or moves: nothing to cancel.
            return Ok(Ok(()));
        }
        wire.send(b"!")?;
        if let Some(stream) = &mut self.stream {
            stream.pause();
        }
        self.cancel_by = Some(Instant::now() + CANCEL_PATIENCE);
        self.next_poll = Instant::now();
        Ok(Ok(()))
    }

    /// A cancel under way, after a report: once the board is at rest
    /// (`Hold:0`, or Idle), a soft reset there drops what it buffered and
    /// keeps the position with no alarm (nothing moved). A board still not
    /// at rest [`CANCEL_PATIENCE`] after the hold is reset all the same:
    /// it stops at once.
    fn cancel_progress(&mut self, wire: &mut Wire, shared: &Shared) -> Result<(), LinkFault> {
        let Some(by) = self.cancel_by else {
            return Ok(());
        };
        let at_rest = self.machine.at_rest() || self.held_at_rest;
        if !at_rest && Instant::now() < by {
            return Ok(());
        }
        self.cancel_by = None;
        self.end_stream(StreamState::Cancelled);
        if self.machine == GrblMachine::Alarm {
            return Ok(());
        }
        self.soft_reset(wire, shared)?;
        self.next_poll = Instant::now();
        Ok(())
    }

    /// 0x18: the board stops at once (Alarm if it moved; the position is
    /// kept) and prints its welcome, which this waits for.
    fn soft_reset(&mut self, wire: &mut Wire, shared: &Shared) -> Result<(), LinkFault> {
        self.end_stream(StreamState::Reset);
        self.cancel_by = None;
        wire.send(&[0x18])?;
        let deadline = Instant::now() + self.timeout;
        loop {
            match wire.next_event(deadline)? {
                None => {
                    return Err(LinkFault::Timeout(format!(
                        "no welcome after a soft reset within {} ms",
                        self.timeout.as_millis()
                    )))
                }
                Some(Incoming::Line(text)) => {
                    if let Seen::Welcome = self.take_line(shared, &text) {
                        return Ok(());
                    }
                }
                Some(_) => {}
            }
        }
    }
}

/// `ok` or `error:N`.
fn final_of(text: &str) -> Option<Result<(), u8>> {
    if text == "ok" {
        return Some(Ok(()));
    }
    text.strip_prefix("error:")
        .map(|code| Err(code.trim().parse().unwrap_or(0)))
}

impl Conversation for Grbl {
    fn on_event(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        event: Incoming,
    ) -> Result<(), LinkFault> {
        if let Incoming::Line(text) = event {
            let seen = self.take_line(shared, &text);
            self.on_unasked(wire, shared, seen)?;
        }
        Ok(())
    }

    fn on_request(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        request: Request,
    ) -> Result<(), LinkFault> {
        let changes = !matches!(request.op, Op::Refresh | Op::DemoMove { .. });
        match self.execute(wire, shared, request.op) {
            Ok(result) => {
                let fresh = if changes && result.is_ok() {
                    // The report reflects the line: the board reads `?`
                    // after it has planned the line it answered.
                    self.exchange_status(wire, shared)
                } else {
                    Ok(())
                };
                if result.is_ok() {
                    let mut state = shared.state();
                    state.axes.iter_mut().for_each(|cache| cache.latched = None);
                }
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
        self.exchange_status(wire, shared)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_round_back_to_their_steps() {
        for steps_per_mm in [250.0, 80.0, 3.0, 1234.5678, 6400.0] {
            for steps in [0i64, 1, -1, 7, 12_345, -98_765, 1 << 40] {
                let text = target_text(steps, steps_per_mm).expect("a text");
                let back = text.parse::<f64>().unwrap() * steps_per_mm;
                assert_eq!(back.round() as i64, steps, "{text} at {steps_per_mm}");
            }
        }
    }

    #[test]
    fn reports_read() {
        let report =
            parse_report("<Hold:1|MPos:1.000,-2.500,0.000|FS:600,0|WCO:0.000,0.000,0.000>")
                .expect("a report");
        assert_eq!(report.state, GrblMachine::Hold);
        assert_eq!(report.mpos, Some([1.0, -2.5, 0.0]));
        assert_eq!(report.feed, 600.0);
        assert_eq!(parse_report("<Idle|FS:0,0>"), None);
        assert_eq!(parse_report("ok"), None);
    }
}

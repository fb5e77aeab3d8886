//! The grbl engine: a board's grbl state, bytes in, replies out, motion
//! through [`GrblMotion`], G-code through [`GcodeInterpreter`].
//!
//! A board calls [`GrblSession::receive`] for every byte it reads (at
//! most [`GrblSession::room`] bytes at a time, so that nothing is ever
//! refused) and [`GrblSession::poll`] from its main loop: `receive` acts
//! on realtime bytes at once and stores line bytes; `poll` takes lines out
//! of the receive buffer while the planner has room and carries them out.
//! A line is answered (`ok` or `error:N`) once all of its blocks are in the
//! planner, so a sender counting characters never has more than the
//! receive buffer's 128 bytes in flight.

use core::fmt;

use super::codes::{GrblAlarm, GrblError};
use super::motion::{
    GcodeInterpreter, GrblMotion, HomeRequest, MotionBlock, MotionFault, MotionRefusal,
    MotionState, Overrides,
};
use super::realtime::GrblRealtime;
use super::receiver::{GrblReceiver, Received};
use super::report::{steps_to_mm, write_axes_mm, write_offsets, write_parser_state};
use super::settings::Settings;
use super::{GRBL_AXES, LINE_BUFFER_SIZE, WELCOME};

/// Reports between two `WCO:` fields while the machine is busy / idle.
const WCO_REFRESH_BUSY: u8 = 30;
const WCO_REFRESH_IDLE: u8 = 10;
/// Reports between two `Ov:` fields while the machine is busy / idle.
const OVR_REFRESH_BUSY: u8 = 20;
const OVR_REFRESH_IDLE: u8 = 10;

/// The machine state a status report names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GrblState {
    /// Nothing to do.
    Idle,
    /// Running G-code.
    Run,
    /// Feed hold: `Hold:0` stopped, `Hold:1` still decelerating.
    Hold(u8),
    /// Jogging.
    Jog,
    /// Locked by an alarm until `$X` or `$H`.
    Alarm,
    /// Homing.
    Home,
    /// Check mode (`$C`): lines are checked, nothing moves.
    Check,
}

impl GrblState {
    /// Whether grbl counts the state as busy for the report cadence.
    fn is_busy(self) -> bool {
        matches!(
            self,
            GrblState::Run | GrblState::Hold(_) | GrblState::Jog | GrblState::Home
        )
    }
}

/// `Idle`, `Run`, `Hold:0`, …
impl fmt::Display for GrblState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GrblState::Idle => f.write_str("Idle"),
            GrblState::Run => f.write_str("Run"),
            GrblState::Hold(code) => write!(f, "Hold:{code}"),
            GrblState::Jog => f.write_str("Jog"),
            GrblState::Alarm => f.write_str("Alarm"),
            GrblState::Home => f.write_str("Home"),
            GrblState::Check => f.write_str("Check"),
        }
    }
}

/// A line taken out of the receive buffer whose blocks are not all in the
/// planner yet.
#[derive(Clone, Debug)]
pub(super) struct PendingLine<G> {
    text: heapless::String<LINE_BUFFER_SIZE>,
    line_no: u32,
    jog: bool,
    /// Blocks of it already queued (skipped when it is interpreted again).
    queued: usize,
    /// The interpreter as it was before the line.
    before: G,
}

/// What the session waits for before it takes the next line.
#[derive(Clone, Debug)]
pub(super) enum Waiting<G> {
    /// Nothing: lines are taken as they come.
    Nothing,
    /// A line's blocks, for room in the planner.
    Line(PendingLine<G>),
    /// `$H`, for the homing cycle to end.
    Homing,
    /// A line with a G4, for the planner to empty and the dwell to end
    /// (grbl answers a dwell once it is over).
    Sync,
}

/// The line being assembled from the receive buffer, as grbl does it:
/// blanks, control characters and comments dropped, letters upper-cased.
#[derive(Clone, Debug, Default)]
pub(super) struct LineAssembly {
    text: heapless::String<LINE_BUFFER_SIZE>,
    overflow: bool,
    in_parens: bool,
    in_semicolon: bool,
}

impl LineAssembly {
    /// Takes one byte; true at the line's end.
    fn push(&mut self, byte: u8) -> bool {
        if byte == b'\n' || byte == b'\r' {
            return true;
        }
        if self.in_semicolon {
            return false;
        }
        if self.in_parens {
            if byte == b')' {
                self.in_parens = false;
            }
            return false;
        }
        match byte {
            0..=b' ' | b'/' => {}
            b'(' => self.in_parens = true,
            b';' => self.in_semicolon = true,
            _ => {
                // grbl keeps one byte of its buffer for the terminator.
                if self.text.len() >= LINE_BUFFER_SIZE - 1 {
                    self.overflow = true;
                } else {
                    let _ = self.text.push(char::from(byte.to_ascii_uppercase()));
                }
            }
        }
        false
    }

    fn clear(&mut self) {
        *self = LineAssembly::default();
    }
}

/// A grbl 1.1 board's state, over a motion `M` and an interpreter `G`.
#[derive(Debug)]
pub struct GrblSession<M, G> {
    pub(super) motion: M,
    pub(super) gcode: G,
    pub(super) settings: Settings,
    pub(super) version: &'static str,
    pub(super) rx: GrblReceiver,
    pub(super) assembly: LineAssembly,
    pub(super) waiting: Waiting<G>,
    /// Lines taken so far (the line numbers of the blocks).
    pub(super) lines: u32,
    pub(super) alarm: Option<GrblAlarm>,
    pub(super) check_mode: bool,
    /// Blocks queued in this turn (`poll`), against the motion's
    /// `blocks_per_poll`.
    queued_this_poll: usize,
    pub(super) overrides: Overrides,
    pub(super) wco_counter: u8,
    pub(super) ovr_counter: u8,
    /// The interpreter's position is to be set from the axes once they rest.
    pub(super) resync: bool,
    pub(super) settings_changed: bool,
    /// Line bytes refused because the receive buffer was full.
    pub(super) overruns: u64,
}

impl<M: GrblMotion, G: GcodeInterpreter> GrblSession<M, G> {
    /// A session over `motion` and `gcode`, with `settings` (a board's
    /// stored ones, or [`Settings::default`]). `version` is cogstep's
    /// (`$I` reports `VER:1.1h.cogstep-<version>:`). Write
    /// [`start`](Self::start)'s welcome before the first byte.
    pub fn new(mut motion: M, mut gcode: G, settings: Settings, version: &'static str) -> Self {
        motion.configure(&settings);
        let steps = motion.status().steps;
        gcode.sync_position(&steps, &settings);
        GrblSession {
            motion,
            gcode,
            settings,
            version,
            rx: GrblReceiver::new(),
            assembly: LineAssembly::default(),
            waiting: Waiting::Nothing,
            lines: 0,
            alarm: None,
            check_mode: false,
            queued_this_poll: 0,
            overrides: Overrides::default(),
            wco_counter: 0,
            ovr_counter: 0,
            resync: false,
            settings_changed: false,
            overruns: 0,
        }
    }

    /// Power-up: the welcome line, and with homing enabled (`$22=1`) the
    /// alarm lock that `$H` or `$X` lifts, as grbl boots.
    pub fn start(&mut self, out: &mut impl fmt::Write) -> fmt::Result {
        if self.settings.homing {
            self.alarm = Some(GrblAlarm::HomingFailReset);
        }
        self.write_welcome(out)
    }

    fn write_welcome(&self, out: &mut impl fmt::Write) -> fmt::Result {
        write!(out, "\r\n{WELCOME}\r\n")?;
        if self.alarm.is_some() {
            out.write_str("[MSG:'$H'|'$X' to unlock]\r\n")?;
        }
        Ok(())
    }

    /// The motion behind the session.
    pub fn motion(&self) -> &M {
        &self.motion
    }

    /// The motion, to drive its own time (a board's main loop).
    pub fn motion_mut(&mut self) -> &mut M {
        &mut self.motion
    }

    /// The settings in force.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Whether a `$N=` changed the settings since the last call (a board
    /// that keeps them stores them then).
    pub fn take_settings_changed(&mut self) -> bool {
        core::mem::take(&mut self.settings_changed)
    }

    /// The alarm that locks the machine, if any.
    pub fn alarm(&self) -> Option<GrblAlarm> {
        self.alarm
    }

    /// How many line bytes fit the receive buffer now: read at most this
    /// many from the UART before the next [`receive`](Self::receive)s.
    pub fn room(&self) -> usize {
        self.rx.room()
    }

    /// Line bytes refused so far because the receive buffer was full (a
    /// sender that broke the character count).
    pub fn overruns(&self) -> u64 {
        self.overruns
    }

    /// Whether anything waits: a line in the buffer or one whose blocks
    /// wait for the planner (a board polls faster then).
    pub fn is_busy(&self) -> bool {
        !self.rx.is_empty() || !matches!(self.waiting, Waiting::Nothing)
    }

    /// Takes one byte from the wire: a realtime byte acts now (a `?`
    /// writes its report to `out`), a line byte is stored. `Received::Full`
    /// means the byte was not taken.
    pub fn receive(&mut self, byte: u8, out: &mut impl fmt::Write) -> Result<Received, fmt::Error> {
        let received = self.rx.push(byte);
        match received {
            Received::Realtime(realtime) => self.realtime(realtime, out)?,
            Received::Full => self.overruns += 1,
            Received::Stored => {}
        }
        Ok(received)
    }

    /// The state a status report names now.
    pub fn state(&self) -> GrblState {
        if self.alarm.is_some() {
            return GrblState::Alarm;
        }
        let motion = self.motion.status().state;
        if matches!(self.waiting, Waiting::Homing) || motion == MotionState::Homing {
            return GrblState::Home;
        }
        if self.check_mode {
            return GrblState::Check;
        }
        match motion {
            MotionState::Held => GrblState::Hold(0),
            MotionState::Holding => GrblState::Hold(1),
            MotionState::Jog => GrblState::Jog,
            MotionState::Run => GrblState::Run,
            MotionState::Idle | MotionState::Homing => match &self.waiting {
                Waiting::Line(pending) if pending.jog => GrblState::Jog,
                Waiting::Line(_) => GrblState::Run,
                _ => GrblState::Idle,
            },
        }
    }

    /// Idle for `$` commands that need it: grbl allows them in Idle and
    /// Alarm (and check mode, where nothing moves).
    fn is_idle(&self) -> bool {
        matches!(
            self.state(),
            GrblState::Idle | GrblState::Alarm | GrblState::Check
        ) && matches!(self.waiting, Waiting::Nothing)
    }

    /// One realtime byte.
    fn realtime(&mut self, realtime: GrblRealtime, out: &mut impl fmt::Write) -> fmt::Result {
        use GrblRealtime::*;
        let state = self.state();
        match realtime {
            StatusReport => return self.write_status_report(out),
            SoftReset => return self.soft_reset(out),
            FeedHold | SafetyDoor => match state {
                GrblState::Run | GrblState::Idle => self.motion.hold(),
                GrblState::Jog => self.cancel_jog(),
                _ => {}
            },
            CycleStart => {
                if state == GrblState::Hold(0) {
                    self.motion.resume();
                }
            }
            JogCancel => {
                if state == GrblState::Jog {
                    self.cancel_jog();
                }
            }
            FeedReset => self.set_feed(100),
            FeedPlus10 => self.set_feed(i16::from(self.overrides.feed_pct) + 10),
            FeedMinus10 => self.set_feed(i16::from(self.overrides.feed_pct) - 10),
            FeedPlus1 => self.set_feed(i16::from(self.overrides.feed_pct) + 1),
            FeedMinus1 => self.set_feed(i16::from(self.overrides.feed_pct) - 1),
            Rapid100 => self.set_rapid(100),
            Rapid50 => self.set_rapid(50),
            Rapid25 => self.set_rapid(25),
            SpindleReset => self.set_spindle(100),
            SpindlePlus10 => self.set_spindle(i16::from(self.overrides.spindle_pct) + 10),
            SpindleMinus10 => self.set_spindle(i16::from(self.overrides.spindle_pct) - 10),
            SpindlePlus1 => self.set_spindle(i16::from(self.overrides.spindle_pct) + 1),
            SpindleMinus1 => self.set_spindle(i16::from(self.overrides.spindle_pct) - 1),
            SpindleStop | FloodToggle | MistToggle | Ignored(_) => {}
        }
        Ok(())
    }

    fn cancel_jog(&mut self) {
        self.motion.cancel_jog();
        if let Waiting::Line(pending) = &self.waiting {
            if pending.jog {
                // Its first blocks were cancelled with the others; the
                // rest would jump the machine: the jog ends here.
                self.waiting = Waiting::Nothing;
            }
        }
        self.resync = true;
    }

    fn set_feed(&mut self, pct: i16) {
        self.overrides.feed_pct = pct.clamp(10, 200) as u8;
        self.overrides_changed();
    }

    fn set_rapid(&mut self, pct: u8) {
        self.overrides.rapid_pct = pct;
        self.overrides_changed();
    }

    fn set_spindle(&mut self, pct: i16) {
        self.overrides.spindle_pct = pct.clamp(10, 200) as u8;
        self.overrides_changed();
    }

    fn overrides_changed(&mut self) {
        self.motion.set_overrides(self.overrides);
        // The next report shows the new values.
        self.ovr_counter = 0;
    }

    /// 0x18: stop at once, forget every line; a reset while the machine
    /// moved is `ALARM:3` (`ALARM:6` while homing), as in grbl — but the
    /// position is kept, exactly what the axes stepped.
    fn soft_reset(&mut self, out: &mut impl fmt::Write) -> fmt::Result {
        let moving = matches!(
            self.motion.status().state,
            MotionState::Run | MotionState::Jog | MotionState::Holding | MotionState::Homing
        );
        let homing = matches!(self.waiting, Waiting::Homing)
            || self.motion.status().state == MotionState::Homing;
        self.motion.reset();
        if moving && self.alarm.is_none() {
            let alarm = if homing {
                GrblAlarm::HomingFailReset
            } else {
                GrblAlarm::AbortCycle
            };
            self.alarm = Some(alarm);
            write!(out, "{alarm}\r\n")?;
        }
        self.rx.clear();
        self.assembly.clear();
        self.waiting = Waiting::Nothing;
        self.check_mode = false;
        self.gcode.reset();
        self.resync = true;
        self.sync_if_resting();
        self.overrides = Overrides::default();
        self.motion.set_overrides(self.overrides);
        self.wco_counter = 0;
        self.ovr_counter = 0;
        self.write_welcome(out)
    }

    /// Sets the interpreter's position from the axes once they rest.
    fn sync_if_resting(&mut self) {
        if !self.resync {
            return;
        }
        let status = self.motion.status();
        if matches!(status.state, MotionState::Idle | MotionState::Held)
            && !matches!(self.waiting, Waiting::Line(_))
        {
            self.gcode.sync_position(&status.steps, &self.settings);
            self.resync = false;
        }
    }

    /// The main loop's turn: faults, the end of homing, lines while the
    /// planner has room.
    pub fn poll(&mut self, out: &mut impl fmt::Write) -> fmt::Result {
        self.queued_this_poll = 0;
        if let Some(fault) = self.motion.take_fault() {
            self.fault(fault, out)?;
        }
        self.sync_if_resting();
        loop {
            match &self.waiting {
                Waiting::Homing => {
                    if self.motion.status().state == MotionState::Homing {
                        return Ok(());
                    }
                    self.waiting = Waiting::Nothing;
                    if self.alarm.is_none() {
                        let steps = self.motion.status().steps;
                        self.gcode.sync_position(&steps, &self.settings);
                    }
                    out.write_str("ok\r\n")?;
                }
                Waiting::Sync => {
                    if self.motion.status().state != MotionState::Idle {
                        return Ok(());
                    }
                    self.waiting = Waiting::Nothing;
                    out.write_str("ok\r\n")?;
                }
                Waiting::Line(_) => {
                    if !self.retry_line(out)? {
                        return Ok(());
                    }
                }
                Waiting::Nothing => {
                    if !self.take_line(out)? {
                        return Ok(());
                    }
                }
            }
        }
    }

    fn fault(&mut self, fault: MotionFault, out: &mut impl fmt::Write) -> fmt::Result {
        let alarm = match fault {
            MotionFault::HardLimit => GrblAlarm::HardLimit,
            MotionFault::HomingSwitchNotFound => GrblAlarm::HomingFailApproach,
            MotionFault::HomingFailed => GrblAlarm::HomingFailPulloff,
        };
        self.alarm = Some(alarm);
        write!(out, "{alarm}\r\n")?;
        if let Waiting::Line(_) = self.waiting {
            // The planner is gone; the line is answered so that the
            // sender's count stays right.
            self.waiting = Waiting::Nothing;
            write!(out, "{}\r\n", GrblError::SystemGcLock)?;
        }
        self.resync = true;
        Ok(())
    }

    /// Takes bytes up to one line end and carries the line out; false when
    /// no whole line is buffered.
    fn take_line(&mut self, out: &mut impl fmt::Write) -> Result<bool, fmt::Error> {
        loop {
            let Some(byte) = self.rx.pop() else {
                return Ok(false);
            };
            if self.assembly.push(byte) {
                break;
            }
        }
        let assembly = core::mem::take(&mut self.assembly);
        self.lines = self.lines.wrapping_add(1);
        if assembly.overflow {
            write!(out, "{}\r\n", GrblError::Overflow)?;
            return Ok(true);
        }
        self.line(assembly.text, out)?;
        Ok(true)
    }

    /// One whole line.
    fn line(
        &mut self,
        text: heapless::String<LINE_BUFFER_SIZE>,
        out: &mut impl fmt::Write,
    ) -> fmt::Result {
        if text.is_empty() {
            // An empty or comment-only line: `ok`, for the sender's count.
            return out.write_str("ok\r\n");
        }
        if let Some(command) = text.strip_prefix('$') {
            if let Some(jog) = command.strip_prefix("J=") {
                return self.jog_line(jog, out);
            }
            return self.system_command(command, out);
        }
        let state = self.state();
        if matches!(state, GrblState::Alarm | GrblState::Jog) {
            return write!(out, "{}\r\n", GrblError::SystemGcLock);
        }
        self.start_line(text, false, out)
    }

    fn jog_line(&mut self, jog: &str, out: &mut impl fmt::Write) -> fmt::Result {
        if !matches!(self.state(), GrblState::Idle | GrblState::Jog) {
            return write!(out, "{}\r\n", GrblError::SystemGcLock);
        }
        let mut text = heapless::String::new();
        // A part of a line that fitted the line buffer fits again.
        let _ = text.push_str(jog);
        self.start_line(text, true, out)
    }

    fn start_line(
        &mut self,
        text: heapless::String<LINE_BUFFER_SIZE>,
        jog: bool,
        out: &mut impl fmt::Write,
    ) -> fmt::Result {
        self.sync_if_resting();
        self.waiting = Waiting::Line(PendingLine {
            text,
            line_no: self.lines,
            jog,
            queued: 0,
            before: self.gcode.clone(),
        });
        self.retry_line(out).map(|_| ())
    }

    /// Interprets the waiting line from the state before it and queues the
    /// blocks not yet queued; true once the line is answered.
    fn retry_line(&mut self, out: &mut impl fmt::Write) -> Result<bool, fmt::Error> {
        let Waiting::Line(pending) = &mut self.waiting else {
            return Ok(true);
        };
        if self.motion.free_blocks() == 0 && pending.queued > 0 {
            return Ok(false);
        }
        let mut gcode = pending.before.clone();
        let mut index = 0usize;
        let mut queued = pending.queued;
        // No room: the planner's, or this turn's.
        let mut full = false;
        let mut invalid = false;
        let mut beyond_travel = false;
        let mut dwell = false;
        // Blocks queued in this turn: at most the motion's number a turn (a
        // long arc's chords then go in over several turns, each short).
        let cap = self
            .motion
            .blocks_per_poll()
            .saturating_sub(self.queued_this_poll);
        let mut taken = 0usize;
        let motion = &mut self.motion;
        let settings = &self.settings;
        let check_mode = self.check_mode;
        let jog = pending.jog;
        // The dry run (an error found before any block goes out) only the
        // first time: a retry is the same line from the same state.
        let check = pending.queued == 0;
        let result = gcode.interpret_part(
            pending.line_no,
            &pending.text,
            jog,
            settings,
            check,
            &mut |block: &MotionBlock| {
                let this = index;
                index += 1;
                dwell |= matches!(block, MotionBlock::Dwell { .. });
                if this < queued {
                    return true;
                }
                if full || invalid || beyond_travel {
                    return false;
                }
                if let MotionBlock::Line { target_steps, .. } = block {
                    if settings.soft_limits && !within_travel(target_steps, settings) {
                        beyond_travel = true;
                        return false;
                    }
                }
                if check_mode {
                    queued += 1;
                    return true;
                }
                if taken >= cap {
                    full = true;
                    return false;
                }
                match motion.queue(block) {
                    Ok(()) => {
                        queued += 1;
                        taken += 1;
                        true
                    }
                    Err(MotionRefusal::Full) => {
                        full = true;
                        false
                    }
                    Err(MotionRefusal::Invalid) => {
                        invalid = true;
                        false
                    }
                }
            },
        );
        pending.queued = queued;
        self.queued_this_poll += taken;
        if let Err(error) = result {
            self.waiting = Waiting::Nothing;
            write!(out, "{error}\r\n")?;
            return Ok(true);
        }
        if beyond_travel {
            self.waiting = Waiting::Nothing;
            if jog {
                // A jog beyond the travel is refused; nothing of it runs.
                write!(out, "{}\r\n", GrblError::TravelExceeded)?;
                return Ok(true);
            }
            // grbl stops the machine and locks it; the position is kept.
            self.motion.reset();
            self.alarm = Some(GrblAlarm::SoftLimit);
            self.resync = true;
            write!(out, "{}\r\nok\r\n", GrblAlarm::SoftLimit)?;
            return Ok(true);
        }
        if full {
            return Ok(false);
        }
        self.waiting = Waiting::Nothing;
        if invalid {
            self.resync = true;
            write!(out, "{}\r\n", GrblError::InvalidTarget)?;
            return Ok(true);
        }
        self.gcode = gcode;
        if self.gcode.take_offsets_changed() {
            self.wco_counter = 0;
        }
        if dwell && !check_mode {
            self.waiting = Waiting::Sync;
            return Ok(true);
        }
        out.write_str("ok\r\n")?;
        Ok(true)
    }

    /// A `$` line (the text after the `$`).
    fn system_command(&mut self, command: &str, out: &mut impl fmt::Write) -> fmt::Result {
        let result = match command {
            "" => out
                .write_str("[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $C $X $H ~ ! ? ctrl-x]\r\n")
                .map(Ok),
            "G" => write_parser_state(&self.gcode.parser_state(), out).map(Ok),
            "X" => self.unlock(out),
            "H" => return self.home(out),
            "C" => return self.toggle_check_mode(out),
            _ if !self.is_idle() => Ok(Err(GrblError::IdleError)),
            "$" => self.settings.write_all(out).map(Ok),
            "#" => write_offsets(&self.gcode.offsets(), self.settings.report_inches, out).map(Ok),
            "I" => self.build_info(out),
            "N" => out.write_str("$N0=\r\n$N1=\r\n").map(Ok),
            "RST=$" | "RST=#" | "RST=*" => {
                if command != "RST=#" {
                    self.settings = Settings::default();
                    self.settings_applied();
                }
                out.write_str("[MSG:Restoring defaults]\r\n").map(Ok)
            }
            _ if command.as_bytes().first().is_some_and(u8::is_ascii_digit) => {
                let rate = self.motion.max_step_rate_hz();
                match self.settings.set_from_text(command, rate) {
                    Ok(()) => {
                        self.settings_applied();
                        Ok(Ok(()))
                    }
                    Err(error) => Ok(Err(error.0)),
                }
            }
            _ => Ok(Err(GrblError::InvalidStatement)),
        }?;
        match result {
            Ok(()) => out.write_str("ok\r\n"),
            Err(error) => write!(out, "{error}\r\n"),
        }
    }

    fn settings_applied(&mut self) {
        self.motion.configure(&self.settings);
        self.settings_changed = true;
        // Steps/mm may have changed: the program's position follows the axes.
        self.resync = true;
        self.sync_if_resting();
    }

    fn build_info(
        &mut self,
        out: &mut impl fmt::Write,
    ) -> Result<Result<(), GrblError>, fmt::Error> {
        write!(
            out,
            "[VER:{}.cogstep-{}:]\r\n[OPT:,{},{}]\r\n",
            super::GRBL_VERSION,
            self.version,
            self.motion.capacity().saturating_sub(1),
            super::RX_BUFFER_SIZE
        )?;
        Ok(Ok(()))
    }

    fn unlock(&mut self, out: &mut impl fmt::Write) -> Result<Result<(), GrblError>, fmt::Error> {
        if !self.is_idle() {
            return Ok(Err(GrblError::IdleError));
        }
        if self.alarm.take().is_some() {
            out.write_str("[MSG:Caution: Unlocked]\r\n")?;
            self.resync = true;
            self.sync_if_resting();
        }
        Ok(Ok(()))
    }

    fn home(&mut self, out: &mut impl fmt::Write) -> fmt::Result {
        if !self.settings.homing {
            return write!(out, "{}\r\n", GrblError::SettingDisabled);
        }
        if !self.is_idle() || self.check_mode {
            return write!(out, "{}\r\n", GrblError::IdleError);
        }
        let request = HomeRequest {
            axes_mask: (1 << GRBL_AXES) - 1,
            direction_mask: self.settings.homing_dir_mask,
            feed_mm_min: self.settings.homing_feed_mm_min,
            seek_mm_min: self.settings.homing_seek_mm_min,
            pull_off_mm: self.settings.homing_pull_off_mm,
            steps_per_mm: self.settings.steps_per_mm,
            max_travel_mm: self.settings.max_travel_mm,
        };
        self.alarm = None;
        match self.motion.home(&request) {
            Ok(()) => {
                self.waiting = Waiting::Homing;
                Ok(())
            }
            Err(_) => {
                self.alarm = Some(GrblAlarm::HomingFailApproach);
                write!(out, "{}\r\nok\r\n", GrblAlarm::HomingFailApproach)
            }
        }
    }

    fn toggle_check_mode(&mut self, out: &mut impl fmt::Write) -> fmt::Result {
        if self.check_mode {
            out.write_str("[MSG:Disabled]\r\nok\r\n")?;
            // grbl leaves check mode with a soft reset.
            return self.soft_reset(out);
        }
        if !self.is_idle() || self.alarm.is_some() {
            return write!(out, "{}\r\n", GrblError::IdleError);
        }
        self.check_mode = true;
        out.write_str("[MSG:Enabled]\r\nok\r\n")
    }

    /// `<State|MPos:…|FS:…|WCO:…|Ov:…>` with grbl's fields and cadence:
    /// `WCO:` every 10th report at rest (30th busy) and when an offset
    /// changed, `Ov:` on the report after it and every 10th (20th busy),
    /// and at once when an override changed. `$10` bit 0 picks MPos or
    /// WPos, bit 1 adds `Bf:blocks,bytes`.
    pub fn write_status_report(&mut self, out: &mut impl fmt::Write) -> fmt::Result {
        let state = self.state();
        let status = self.motion.status();
        let inches = self.settings.report_inches;
        let machine_mm = steps_to_mm(&status.steps, &self.settings.steps_per_mm);
        let wco = self.gcode.offsets().wco();
        write!(out, "<{state}|")?;
        if self.settings.status_report_mask & 1 != 0 {
            out.write_str("MPos:")?;
            write_axes_mm(&machine_mm, inches, out)?;
        } else {
            let mut work = machine_mm;
            for (axis, value) in work.iter_mut().enumerate() {
                *value -= wco[axis];
            }
            out.write_str("WPos:")?;
            write_axes_mm(&work, inches, out)?;
        }
        if self.settings.status_report_mask & 2 != 0 {
            write!(out, "|Bf:{},{}", self.motion.free_blocks(), self.rx.room())?;
        }
        let feed_per_min = status.feed_mm_s * 60.0 / if inches { 25.4 } else { 1.0 };
        write!(out, "|FS:{:.0},0", feed_per_min.max(0.0))?;
        let busy = state.is_busy();
        if self.wco_counter > 0 {
            self.wco_counter -= 1;
        } else {
            self.wco_counter = if busy {
                WCO_REFRESH_BUSY
            } else {
                WCO_REFRESH_IDLE
            } - 1;
            if self.ovr_counter == 0 {
                // Overrides on the next report.
                self.ovr_counter = 1;
            }
            out.write_str("|WCO:")?;
            write_axes_mm(&wco, inches, out)?;
        }
        if self.ovr_counter > 0 {
            self.ovr_counter -= 1;
        } else {
            self.ovr_counter = if busy {
                OVR_REFRESH_BUSY
            } else {
                OVR_REFRESH_IDLE
            } - 1;
            write!(
                out,
                "|Ov:{},{},{}",
                self.overrides.feed_pct, self.overrides.rapid_pct, self.overrides.spindle_pct
            )?;
        }
        out.write_str(">\r\n")
    }
}

/// Whether a target lies in grbl's machine space: from −max travel to 0
/// on every axis (grbl's soft limits without a forced origin).
fn within_travel(target_steps: &[i64; GRBL_AXES], settings: &Settings) -> bool {
    let mm = steps_to_mm(target_steps, &settings.steps_per_mm);
    mm.iter()
        .zip(settings.max_travel_mm)
        .all(|(&mm, travel)| mm <= 0.0 && mm >= -travel)
}

//! The board handle: [`SerialBoard`] opens the port, starts the link
//! thread, and answers what the board is and what it lets the host do.

use std::fmt;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use crossbeam::channel;

use cogstep_motion::axis::AxisError;
use cogstep_motion::profile::PlanError;
use cogstep_protocol::grbl::GrblRealtime;
use cogstep_protocol::{Command, Dialect};

use super::axis::SerialAxis;
use super::grbl::GrblStatus;
use super::grbl_stream::{self, GcodeStream, StreamProgress, StreamShared};
use super::handle::Handle;
use super::link;
use super::request::Op;
use super::state::{BoardState, Link, Shared};
#[cfg(doc)]
use super::FAULT_GRBL_ALARM;
use super::{Capabilities, SerialConfig, SerialError, StreamError, P2DEMO_UNSUPPORTED};

/// A board on a serial port. Cheap to clone (the clones share one port
/// and one link thread); the link closes with [`close`](SerialBoard::close)
/// or when the last clone and the last [`SerialAxis`] are dropped.
#[derive(Clone)]
pub struct SerialBoard {
    handle: Arc<Handle>,
}

impl fmt::Debug for SerialBoard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SerialBoard")
            .field("port", &self.handle.shared.config.port)
            .field("dialect", &self.handle.shared.config.dialect)
            .finish()
    }
}

impl SerialBoard {
    /// Opens the port and identifies the board: `I` for a cogstep board
    /// (then one status read), a key press and the screen for a P2 demo
    /// board. Fails if the port does not open or the board does not
    /// answer as its dialect does within [`SerialConfig::timeout`].
    pub fn open(config: SerialConfig) -> Result<SerialBoard, SerialError> {
        let (requests_tx, requests_rx) = channel::unbounded();
        let (urgent_tx, urgent_rx) = channel::unbounded();
        let shared = Arc::new(Shared {
            config,
            state: Mutex::new(BoardState::default()),
            closing: AtomicBool::new(false),
            requests: requests_rx,
            urgent: urgent_rx,
        });
        let connection = link::connect(&shared, shared.config.demo_start)?;
        let thread = link::spawn(Arc::clone(&shared), connection)?;
        Ok(SerialBoard {
            handle: Arc::new(Handle {
                shared,
                requests: requests_tx,
                urgent: urgent_tx,
                thread: Mutex::new(Some(thread)),
            }),
        })
    }

    /// How many axes the board has (1 for a P2 demo board).
    pub fn axis_count(&self) -> usize {
        self.handle.shared.state().axes.len()
    }

    /// Axis `index`, or `None` when the board has no such axis.
    pub fn axis(&self, index: usize) -> Option<SerialAxis> {
        (index < self.axis_count()).then(|| SerialAxis {
            handle: Arc::clone(&self.handle),
            index,
        })
    }

    /// What the board lets the host do ([`Capabilities::ALL`] for cogstep,
    /// [`Capabilities::MOVE_ONLY`] for the P2 demo).
    pub fn capabilities(&self) -> Capabilities {
        self.handle.shared.capabilities()
    }

    /// The dialect the board speaks.
    pub fn dialect(&self) -> Dialect {
        self.handle.shared.config.dialect
    }

    /// The configuration the board was opened with.
    pub fn config(&self) -> &SerialConfig {
        &self.handle.shared.config
    }

    /// The board's identity line, `[cogstep 0.1.0 proto:1 axes:2
    /// clkfreq:200000000]`, or [`P2DEMO_IDENTITY`](crate::P2DEMO_IDENTITY).
    pub fn identity(&self) -> String {
        self.handle.shared.state().identity.clone()
    }

    /// The board's clock, Hz; 0 when the board does not say (the P2 demo).
    pub fn clkfreq(&self) -> u32 {
        self.handle.shared.state().clkfreq
    }

    /// The last fault: why the link is down (`disconnected: ...`,
    /// `timeout: ...`), or an axis's latched fault (`axis 0: board lost
    /// mid-move`); `None` when the link is up and no axis has a fault.
    pub fn fault(&self) -> Option<String> {
        let state = self.handle.shared.state();
        if let Link::Down(reason) = &state.link {
            return Some(reason.clone());
        }
        state
            .axes
            .iter()
            .enumerate()
            .find_map(|(index, axis)| axis.latched.map(|what| format!("axis {index}: {what}")))
    }

    /// Whether the link is up (the board answered its last exchange).
    pub fn is_connected(&self) -> bool {
        matches!(self.handle.shared.state().link, Link::Up)
    }

    /// Forgets the axes' latched faults (the caller has seen them).
    pub fn clear_faults(&self) {
        for axis in &mut self.handle.shared.state().axes {
            axis.latched = None;
        }
    }

    /// Reads every axis's status now (`?`) and waits for it, rather than
    /// for the next background poll. A P2 demo board has nothing to ask:
    /// this returns at once.
    pub fn refresh(&self) -> Result<(), AxisError> {
        self.handle.call(Op::Refresh)
    }

    /// Emergency stop of every axis: the realtime byte 0x18 goes out at
    /// once (even while a command waits for its reply), then `E`, whose
    /// `ok` this waits for. Positions are kept.
    pub fn emergency_stop_all(&self) -> Result<(), AxisError> {
        self.handle.emergency_stop()
    }

    /// A coordinated move (`G`): `steps[i]` for axis `i` (1 to 8 axes, 0
    /// leaves an axis still), the lead (the longest move) at `speed`; every
    /// first edge on one CT, one straight line, all or nothing (see
    /// `Hub::move_together`). Refused before anything is sent for a zero
    /// speed, no axes, more axes than the board (or than a `G` line) has,
    /// or a P2 demo board; the board's refusal maps as for
    /// [`SerialAxis`]'s moves.
    pub fn move_together(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
        if self.dialect() == Dialect::P2Demo {
            return Err(AxisError::Unsupported(P2DEMO_UNSUPPORTED));
        }
        // The hub's order: steps, then the lead's speed.
        if steps.contains(&i32::MIN) {
            return Err(AxisError::StepsOutOfRange);
        }
        if speed == 0 {
            return Err(PlanError::ZeroSpeed.into());
        }
        if steps.len() > self.axis_count() {
            return Err(AxisError::Unavailable);
        }
        let group = cogstep_protocol::GroupMove::new(speed, steps)
            .ok_or(AxisError::Unsupported("a group move of 1 to 8 axes"))?;
        self.handle.call(Op::Command {
            axis: None,
            command: Command::GroupMove(group),
        })
    }

    /// grbl: `$X`, lifts the board's alarm lock (after an emergency stop,
    /// a soft limit or a reset at boot with homing on); positions are
    /// exact, as cogstep keeps them. Other dialects: `Unsupported`.
    pub fn unlock(&self) -> Result<(), AxisError> {
        if self.dialect() != Dialect::Grbl {
            return Err(AxisError::Unsupported("not a grbl board"));
        }
        self.handle.call(Op::GrblUnlock)
    }

    /// grbl: every `$N=value` the board's `$$` gave when it was opened
    /// (steps/mm `$100`…, max rates `$110`…, accelerations `$120`…, max
    /// travel `$130`…, …), in the board's order; empty for other dialects.
    pub fn grbl_settings(&self) -> Vec<(u16, f64)> {
        self.handle.shared.state().grbl_settings.clone()
    }

    /// grbl: what the board's last status report said (the background
    /// poll reads one every [`SerialConfig::poll_interval`]); `None` for
    /// other dialects.
    pub fn grbl_status(&self) -> Option<GrblStatus> {
        self.handle.shared.state().grbl_status.clone()
    }

    /// grbl: streams a G-code program by character counting (see
    /// [`GcodeStream`]). The lines are prepared first (comments and
    /// blanks removed); a line the board could not take as it is refuses
    /// the whole program with [`StreamError::Refused`] before a byte is
    /// sent. Refused too unless the board is at rest and unlocked
    /// ([`AxisError::NotIdle`], or [`FAULT_GRBL_ALARM`]) and no other
    /// program streams. Moves and `$X` are refused while it streams; the
    /// stop pin (feed hold, resume), the emergency stop (soft reset) and
    /// [`SerialBoard::grbl_realtime`] act at once.
    pub fn stream_gcode(&self, lines: &[String]) -> Result<GcodeStream, StreamError> {
        if self.dialect() != Dialect::Grbl {
            return Err(StreamError::Board(AxisError::Unsupported(
                "not a grbl board",
            )));
        }
        let prepared = grbl_stream::prepare(lines).map_err(StreamError::Refused)?;
        let shared = Arc::new(StreamShared {
            progress: Mutex::new(StreamProgress::new(prepared.len())),
            lines: prepared,
        });
        self.handle.shared.state().grbl_stream = Some(Arc::clone(&shared));
        let started = self.handle.call(Op::GrblStream);
        // Not taken (the link was down, the caller gave up): never later.
        self.handle.shared.state().grbl_stream = None;
        started.map_err(StreamError::Board)?;
        Ok(GcodeStream {
            shared,
            board: self.clone(),
        })
    }

    /// grbl: sends one realtime command byte at once, even while lines
    /// wait for their replies (feed hold `!`, cycle start `~`, the feed and
    /// rapid overrides 0x90-0x97, jog cancel 0x85). The soft reset and the
    /// status report are the host's own ([`SerialBoard::emergency_stop_all`],
    /// the poll): refused here, as is any other dialect.
    pub fn grbl_realtime(&self, command: GrblRealtime) -> Result<(), AxisError> {
        if self.dialect() != Dialect::Grbl {
            return Err(AxisError::Unsupported("not a grbl board"));
        }
        if matches!(
            command,
            GrblRealtime::SoftReset | GrblRealtime::StatusReport
        ) {
            return Err(AxisError::Unsupported(
                "the soft reset is emergency_stop_all, the status report the host's poll",
            ));
        }
        if !self.is_connected() {
            return Err(AxisError::Fault(super::FAULT_DISCONNECTED));
        }
        self.handle
            .urgent
            .send(command.byte())
            .map_err(|_| AxisError::Unavailable)
    }

    /// grbl: cancels the program streaming (see [`GcodeStream::cancel`]).
    pub(crate) fn grbl_cancel_stream(&self) -> Result<(), AxisError> {
        self.handle.call(Op::GrblCancel)
    }

    /// Closes the link: the link thread stops and the port is closed.
    /// Other clones and axes of this board get [`AxisError::Unavailable`].
    pub fn close(self) {
        self.handle.close();
    }
}

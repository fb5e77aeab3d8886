//! The board as the host last saw it: what the link thread and the
//! handles share ([`Shared`]), the link's state and each axis's cached
//! status and latched fault.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};

use crossbeam::channel::Receiver;

use cogstep_motion::axis::{AxisStatus, LimitStatus, Mode};
use cogstep_protocol::Dialect;

use super::request::Request;
use super::{Capabilities, SerialConfig, FAULT_LOST_MID_MOVE};

/// What the link thread and the handles share.
pub(crate) struct Shared {
    pub(crate) config: SerialConfig,
    pub(crate) state: Mutex<BoardState>,
    /// Set when the board is closed; the link thread stops.
    pub(crate) closing: AtomicBool,
    pub(crate) requests: Receiver<Request>,
    pub(crate) urgent: Receiver<u8>,
}

impl Shared {
    pub(crate) fn state(&self) -> MutexGuard<'_, BoardState> {
        lock(&self.state)
    }

    pub(crate) fn capabilities(&self) -> Capabilities {
        match self.config.dialect {
            Dialect::Cogstep => Capabilities::ALL,
            Dialect::P2Demo => Capabilities::MOVE_ONLY,
            Dialect::Grbl => Capabilities::GRBL,
        }
    }

    pub(crate) fn is_closing(&self) -> bool {
        self.closing.load(Ordering::Acquire)
    }
}

pub(crate) fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic elsewhere must not take every handle down with it.
    mutex
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Whether the link is up.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Link {
    Up,
    /// Down, and why (what [`SerialBoard::fault`] says).
    Down(String),
}

/// The board as the host last saw it.
#[derive(Debug)]
pub(crate) struct BoardState {
    pub(crate) link: Link,
    pub(crate) identity: String,
    pub(crate) clkfreq: u32,
    pub(crate) axes: Vec<AxisCache>,
    /// grbl: every `$N=value` the board's `$$` gave at connect.
    pub(crate) grbl_settings: Vec<(u16, f64)>,
    /// grbl: what the last status report said.
    pub(crate) grbl_status: Option<super::GrblStatus>,
    /// grbl: a program handed to the link thread to stream (`Op::GrblStream`).
    pub(crate) grbl_stream: Option<std::sync::Arc<super::grbl_stream::StreamShared>>,
}

impl Default for BoardState {
    fn default() -> Self {
        BoardState {
            link: Link::Down("connecting".to_string()),
            identity: String::new(),
            clkfreq: 0,
            axes: Vec::new(),
            grbl_settings: Vec::new(),
            grbl_status: None,
            grbl_stream: None,
        }
    }
}

/// One axis as the host last saw it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct AxisCache {
    pub(crate) status: AxisStatus,
    /// A fault that outlives the link's (re)connection, cleared by the
    /// axis's next accepted command.
    pub(crate) latched: Option<&'static str>,
    /// The limit and homing state the last `L` read.
    pub(crate) limits: Option<LimitStatus>,
}

impl Default for AxisCache {
    fn default() -> Self {
        AxisCache {
            status: AxisStatus {
                position: 0,
                stm: 0,
                steps_to_go: 0,
                mode: Mode(0),
                velocity_steps_per_s: 0,
                stop_pin_high: true,
            },
            latched: None,
            limits: None,
        }
    }
}

impl BoardState {
    /// The link is up with this board: `axes` axes.
    pub(crate) fn link_up(&mut self, identity: String, clkfreq: u32, axes: usize) {
        self.identity = identity;
        self.clkfreq = clkfreq;
        self.axes.resize(axes, AxisCache::default());
        self.link = Link::Up;
    }

    /// The link went down: moving axes latch [`FAULT_LOST_MID_MOVE`].
    pub(crate) fn link_down(&mut self, reason: String) {
        self.latch_moving(FAULT_LOST_MID_MOVE);
        self.link = Link::Down(reason);
    }

    /// Every axis that is not idle latches `what` (unless it has a fault).
    pub(crate) fn latch_moving(&mut self, what: &'static str) {
        for axis in &mut self.axes {
            if is_busy(&axis.status) && axis.latched.is_none() {
                axis.latched = Some(what);
            }
        }
    }
}

/// Whether an axis is doing (or holding) something: not ready and idle.
pub(crate) fn is_busy(status: &AxisStatus) -> bool {
    status.steps_to_go != 0 || status.mode.has(Mode::MOVING) || status.mode.has(Mode::HOLD)
}

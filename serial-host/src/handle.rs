//! What the handles hold: [`Handle::call`] queues a request for the link
//! thread and waits, within a bounded time, for its answer.

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam::channel::{self, Sender};

use cogstep_motion::axis::AxisError;
use cogstep_protocol::{Command, Dialect};

use super::request::{Op, Request};
use super::state::{lock, Link, Shared};
use super::{FAULT_DISCONNECTED, P2DEMO_UNSUPPORTED};

/// What the handles hold: the shared state and the way to the link thread.
pub(crate) struct Handle {
    pub(crate) shared: Arc<Shared>,
    pub(crate) requests: Sender<Request>,
    pub(crate) urgent: Sender<u8>,
    pub(crate) thread: Mutex<Option<JoinHandle<()>>>,
}

impl Handle {
    /// Queues a request and waits for its answer. Never waits for ever:
    /// a request not started within the timeout is dropped unexecuted, and
    /// one started is answered within a bounded number of timeouts.
    pub(crate) fn call(&self, op: Op) -> Result<(), AxisError> {
        let shared = &self.shared;
        if shared.closing.load(Ordering::Acquire) {
            return Err(AxisError::Unavailable);
        }
        if let Op::Command {
            axis: Some(index), ..
        }
        | Op::JogRelease(index) = op
        {
            if index >= shared.state().axes.len() {
                return Err(AxisError::Unavailable);
            }
        }
        if shared.state().link != Link::Up {
            return Err(AxisError::Fault(FAULT_DISCONNECTED));
        }
        let timeout = shared.config.timeout;
        let start_by = Instant::now() + timeout;
        let (reply, answer) = channel::bounded(1);
        self.requests
            .send(Request {
                op,
                start_by,
                reply,
            })
            .map_err(|_| AxisError::Unavailable)?;
        // Queue wait, then at most: the command, a checksum retry, and the
        // status read after it, each a write and a reply bounded by the
        // timeout.
        let longest = timeout * 8 + Duration::from_millis(250);
        match answer.recv_timeout(longest) {
            Ok(result) => result,
            Err(channel::RecvTimeoutError::Timeout) => Err(AxisError::Fault("timeout")),
            Err(channel::RecvTimeoutError::Disconnected) => {
                Err(AxisError::Fault(FAULT_DISCONNECTED))
            }
        }
    }

    pub(crate) fn emergency_stop(&self) -> Result<(), AxisError> {
        if self.shared.closing.load(Ordering::Acquire) {
            return Err(AxisError::Unavailable);
        }
        if self.shared.config.dialect == Dialect::P2Demo {
            return Err(AxisError::Unsupported(P2DEMO_UNSUPPORTED));
        }
        if self.shared.state().link != Link::Up {
            // Not queued for later: a stop must not reach a board that
            // comes back long after the caller was told it failed.
            return Err(AxisError::Fault(FAULT_DISCONNECTED));
        }
        // The realtime byte first: it acts even while a line waits. A
        // grbl board's soft reset is sent by the conversation, which then
        // waits for the welcome it brings.
        if self.shared.config.dialect != Dialect::Grbl {
            let _ = self
                .urgent
                .send(cogstep_protocol::Realtime::EmergencyStop.byte());
        }
        self.call(Op::Command {
            axis: None,
            command: Command::EmergencyStop,
        })
    }

    pub(crate) fn close(&self) {
        self.shared.closing.store(true, Ordering::Release);
        let thread = lock(&self.thread).take();
        if let Some(thread) = thread {
            let _ = thread.join();
        }
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        self.close();
    }
}

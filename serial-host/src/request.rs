//! What the handles ask the link thread: a [`Request`] with its [`Op`],
//! and the way back for its answer.

use std::time::Instant;

use crossbeam::channel::Sender;

use cogstep_motion::axis::AxisError;
use cogstep_protocol::Command;

/// A request to the link thread.
pub(crate) struct Request {
    pub(crate) op: Op,
    /// Dropped unexecuted if not started by then (the caller gave up).
    pub(crate) start_by: Instant,
    pub(crate) reply: Sender<Result<(), AxisError>>,
}

impl Request {
    pub(crate) fn answer(self, result: Result<(), AxisError>) {
        // The caller may have given up; nothing to do then.
        let _ = self.reply.send(result);
    }
}

/// What a request asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Op {
    /// A cogstep command line; `axis` is the axis it changes (its latched
    /// fault is cleared when the board accepts it), `None` for all.
    Command {
        axis: Option<usize>,
        command: Command,
    },
    /// `S <axis>` now, `R <axis>` once it has stopped.
    JogRelease(usize),
    /// Read every status now.
    Refresh,
    /// grbl: `$X`, lift the alarm lock.
    GrblUnlock,
    /// grbl: start streaming the program handed over in the shared state
    /// (`BoardState::grbl_stream`).
    GrblStream,
    /// grbl: cancel the program streaming (hold, rest, soft reset).
    GrblCancel,
    /// A P2 demo move: answer the two prompts.
    DemoMove { speed: u32, steps: i32 },
}

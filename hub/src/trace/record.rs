//! A running hub recorded to a VCD as it goes.
//!
//! A [`Recorder`] owns a thread that, every [`RecorderOptions::period`],
//! takes the hub's trace ([`Hub::take_trace`]), hands it to a
//! [`VcdStream`] and writes what is older than
//! [`RecorderOptions::window`]: the window gives every cog's ring time to
//! be drained, so edges reach the file in time order. Memory stays bounded
//! by one window of edges, however long the session.
//!
//! Never silent: edges a full ring dropped ([`Hub::trace_overflows`]) are
//! counted ([`Recorder::lost_edges`]) and marked in the file where they were
//! lost — the wire `recording_edges_lost` is high over each interval in which
//! edges were lost, and a comment at the end gives the count; edges that
//! still came later than the window are written late and counted
//! ([`Recorder::late_edges`]); a write failure stops the recording and is
//! kept ([`Recorder::failure`]).

use std::io::Write;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use super::waveform::{Signal, VcdError, VcdStream};
use crate::pins::{Edge, PIN_COUNT};
use crate::Hub;

/// The marker wire's number: past the pins.
const LOST_MARKER: u8 = PIN_COUNT;

/// The marker wire's name: high over each interval in which edges were lost.
pub const LOST_MARKER_NAME: &str = "recording_edges_lost";

/// How often the recorder writes and how far behind the clock it stays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecorderOptions {
    /// How often the trace is taken and written (default 20 ms).
    pub period: Duration,
    /// Edges are written once they are this old (default 250 ms).
    pub window: Duration,
}

impl Default for RecorderOptions {
    fn default() -> Self {
        Self {
            period: Duration::from_millis(20),
            window: Duration::from_millis(250),
        }
    }
}

/// What a finished recording holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RecordSummary {
    /// Edges written.
    pub edges: u64,
    /// Edges lost because a ring was full (noted in the file).
    pub lost: u64,
    /// Edges written later than their time (noted in the file).
    pub late: u64,
    /// CT of the recording's time 0.
    pub start_ct: u64,
    /// CT at which it ended.
    pub end_ct: u64,
}

#[derive(Default)]
struct Shared {
    stop: AtomicBool,
    lost: AtomicU64,
    late: AtomicU64,
    edges: AtomicU64,
    failure: Mutex<Option<String>>,
}

/// A hub being recorded (see the module docs). Dropping it ends the
/// recording as [`Recorder::finish`] does.
pub struct Recorder {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<Result<RecordSummary, VcdError>>>,
}

impl std::fmt::Debug for Recorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recorder")
            .field("edges", &self.shared.edges.load(Ordering::Relaxed))
            .field("lost", &self.lost_edges())
            .finish()
    }
}

impl Recorder {
    /// Starts recording every pin of every axis started on `hub` so far
    /// into `out` (which the recorder buffers). Time 0 is now; the levels
    /// at time 0 are the pins' levels now. The hub must record edges
    /// (`trace_edges`); the recorder takes its trace from now on.
    pub fn start<W: Write + Send + 'static>(
        hub: &Hub,
        out: W,
        options: RecorderOptions,
    ) -> Result<Self, VcdError> {
        if !hub.config().trace_edges {
            return Err(VcdError::TracingOff);
        }
        // What happened before now is in the levels at time 0.
        drop(hub.take_trace());
        let start_ct = hub.now();
        let lost_before = hub.trace_overflows();
        let mut signals = hub.signals();
        signals.push(Signal {
            pin: LOST_MARKER,
            name: LOST_MARKER_NAME.into(),
            input: false,
            level: false,
        });
        let stream = VcdStream::new(out, hub.config().clkfreq, start_ct, &signals)?;
        let shared = Arc::new(Shared::default());
        let worker = Worker {
            hub: hub.clone(),
            stream,
            shared: Arc::clone(&shared),
            start_ct,
            lost_seen: lost_before,
            checked_ct: start_ct,
            markers: 0,
            window_ticks: ticks(hub.config().clkfreq, options.window),
        };
        let thread = std::thread::Builder::new()
            .name("vcd-record".into())
            .spawn(move || worker.run(options.period))?;
        Ok(Self {
            shared,
            thread: Some(thread),
        })
    }

    /// Edges lost so far because a cog's ring was full.
    pub fn lost_edges(&self) -> u64 {
        self.shared.lost.load(Ordering::Relaxed)
    }

    /// Edges written later than their time so far.
    pub fn late_edges(&self) -> u64 {
        self.shared.late.load(Ordering::Relaxed)
    }

    /// Edges written so far.
    pub fn edges_written(&self) -> u64 {
        self.shared.edges.load(Ordering::Relaxed)
    }

    /// Why the recording stopped early, if it did.
    pub fn failure(&self) -> Option<String> {
        self.shared
            .failure
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .clone()
    }

    /// Ends the recording: the edges still waiting are written, the file
    /// is ended at the current CT and flushed.
    pub fn finish(mut self) -> Result<RecordSummary, VcdError> {
        self.end()
    }

    fn end(&mut self) -> Result<RecordSummary, VcdError> {
        self.shared.stop.store(true, Ordering::Release);
        let Some(thread) = self.thread.take() else {
            return Ok(RecordSummary::default());
        };
        thread.thread().unpark();
        thread.join().unwrap_or_else(|_| {
            Err(VcdError::Io(std::io::Error::other(
                "the recording thread panicked",
            )))
        })
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        let _ = self.end();
    }
}

fn ticks(clkfreq: u32, duration: Duration) -> u64 {
    u64::try_from(duration.as_nanos() * u128::from(clkfreq) / 1_000_000_000).unwrap_or(u64::MAX)
}

struct Worker<W: Write> {
    hub: Hub,
    stream: VcdStream<W>,
    shared: Arc<Shared>,
    start_ct: u64,
    lost_seen: u64,
    /// CT of the last look at the overflow count.
    checked_ct: u64,
    /// Marker edges pushed (not pin edges).
    markers: u64,
    window_ticks: u64,
}

impl<W: Write> Worker<W> {
    fn run(mut self, period: Duration) -> Result<RecordSummary, VcdError> {
        loop {
            let stopping = self.shared.stop.load(Ordering::Acquire);
            let horizon = if stopping {
                u64::MAX
            } else {
                self.hub.now().saturating_sub(self.window_ticks)
            };
            if let Err(error) = self.write(horizon) {
                *self
                    .shared
                    .failure
                    .lock()
                    .unwrap_or_else(|poisoned| poisoned.into_inner()) = Some(error.to_string());
                return Err(error.into());
            }
            if stopping {
                break;
            }
            std::thread::park_timeout(period);
        }
        let end_ct = self.hub.now().max(self.stream.current_ct());
        let edges = self.stream.edges_written() - self.markers;
        let summary = RecordSummary {
            edges,
            lost: self.shared.lost.load(Ordering::Relaxed),
            late: self.stream.late_edges(),
            start_ct: self.start_ct,
            end_ct,
        };
        self.stream.note(format!(
            "cogstep: recording ended at CT {end_ct}: {edges} edges written, {} lost (a ring was full), {} late",
            summary.lost, summary.late
        ));
        self.stream.finish(end_ct)?;
        Ok(summary)
    }

    /// Takes the trace and writes the edges before `horizon`.
    fn write(&mut self, horizon: u64) -> std::io::Result<()> {
        let start_ct = self.start_ct;
        self.stream.push(
            self.hub
                .take_trace()
                .into_iter()
                .filter(|edge| edge.ct >= start_ct),
        );
        // Counted by running cogs only: a stopped cog's count leaves the sum.
        let lost_now = self.hub.trace_overflows();
        let now = self.hub.now();
        if lost_now > self.lost_seen {
            let lost = lost_now - self.lost_seen;
            self.shared.lost.fetch_add(lost, Ordering::Relaxed);
            // Lost since the last look: the marker is high over that time.
            let (from, to) = (self.checked_ct, now.max(self.checked_ct + 1));
            self.stream.push([
                Edge {
                    ct: from,
                    pin: LOST_MARKER,
                    level: true,
                },
                Edge {
                    ct: to,
                    pin: LOST_MARKER,
                    level: false,
                },
            ]);
            self.markers += 2;
        }
        self.lost_seen = lost_now;
        self.checked_ct = now;
        self.stream.write_before(horizon)?;
        self.stream.flush()?;
        let written = self.stream.edges_written().saturating_sub(self.markers);
        self.shared.edges.store(written, Ordering::Relaxed);
        self.shared
            .late
            .store(self.stream.late_edges(), Ordering::Relaxed);
        Ok(())
    }
}

//! The wire: the port's writing half, the reader thread that turns bytes
//! into [`Incoming`] events, and the [`Conversation`] a dialect holds over
//! it. The link thread (`link`) drives a conversation; the dialects
//! (`cogstep`, `demo`) use only what is here.

use std::io::{self, Read};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam::channel::{self, select, Receiver, Sender};
use serialport::SerialPort;

use super::request::Request;
use super::state::Shared;
use super::{Dialect, SerialError, FAULT_DISCONNECTED};
use cogstep_protocol::p2demo::{self, ScreenEvent, ScreenParser};

/// How long the reader blocks in one read before it looks at its stop flag.
const READ_SLICE: Duration = Duration::from_millis(20);
/// The longest reply line kept; longer lines are dropped (the protocol's
/// are at most 128 bytes).
const LINE_KEEP: usize = 512;

/// What the reader saw.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) enum Incoming {
    /// Cogstep: one line, its line end removed.
    Line(String),
    /// P2 demo: a value line, a whole display or a prompt.
    Screen(ScreenEvent),
    /// P2 demo: the clear-screen byte (a move started, or ended).
    Cleared,
    /// The port failed or reached its end; nothing follows.
    Closed(String),
}

/// Why a conversation ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) enum LinkFault {
    /// The port failed, closed, or hung up.
    Disconnected(String),
    /// The board did not answer in time.
    Timeout(String),
    /// The board is being closed.
    Closing,
}

impl LinkFault {
    /// What [`SerialBoard::fault`](super::SerialBoard::fault) says.
    pub fn describe(&self) -> String {
        match self {
            LinkFault::Disconnected(what) => format!("{FAULT_DISCONNECTED}: {what}"),
            LinkFault::Timeout(what) => format!("timeout: {what}"),
            LinkFault::Closing => "closed".to_string(),
        }
    }

    /// A fault of the handshake, as the error `open` returns.
    pub fn into_open_error(self, shared: &Shared, what: &'static str) -> SerialError {
        let port = shared.config.port.clone();
        match self {
            LinkFault::Timeout(_) => SerialError::Timeout {
                port,
                what,
                timeout_ms: shared.config.timeout.as_millis(),
            },
            fault => SerialError::Io {
                port,
                source: io::Error::other(fault.describe()),
            },
        }
    }
}

/// The port's writing half and the reader's events.
pub(super) struct Wire {
    port: Box<dyn SerialPort>,
    /// The reader's events (the link thread selects on a clone).
    pub(super) incoming: Receiver<Incoming>,
    urgent: Receiver<u8>,
    reader_stop: Arc<AtomicBool>,
    reader: Option<JoinHandle<()>>,
}

impl Wire {
    /// Starts the reader on a clone of `port`.
    pub(super) fn start(
        port: Box<dyn SerialPort>,
        dialect: Dialect,
        urgent: Receiver<u8>,
    ) -> Result<Wire, io::Error> {
        let mut reading = port.try_clone().map_err(io::Error::from)?;
        reading.set_timeout(READ_SLICE).map_err(io::Error::from)?;
        let (events, incoming) = channel::unbounded();
        let reader_stop = Arc::new(AtomicBool::new(false));
        let stop = Arc::clone(&reader_stop);
        let reader = std::thread::Builder::new()
            .name("serial-reader".to_string())
            .spawn(move || read_loop(reading, dialect, &events, &stop))?;
        Ok(Wire {
            port,
            incoming,
            urgent,
            reader_stop,
            reader: Some(reader),
        })
    }

    /// Writes all of `bytes`.
    pub fn send(&mut self, bytes: &[u8]) -> Result<(), LinkFault> {
        write_port(self.port.as_mut(), bytes)
    }

    /// The next event before `deadline` (`None` when it passes). Urgent
    /// bytes queued meanwhile are written at once.
    pub fn next_event(&mut self, deadline: Instant) -> Result<Option<Incoming>, LinkFault> {
        loop {
            let wait = deadline.saturating_duration_since(Instant::now());
            select! {
                recv(self.incoming) -> event => return match event {
                    Ok(Incoming::Closed(what)) => Err(LinkFault::Disconnected(what)),
                    Ok(event) => Ok(Some(event)),
                    Err(_) => Err(LinkFault::Disconnected("the reader stopped".to_string())),
                },
                recv(self.urgent) -> byte => match byte {
                    Ok(byte) => write_port(self.port.as_mut(), &[byte])?,
                    Err(_) => return Err(LinkFault::Closing),
                },
                default(wait) => return Ok(None),
            }
        }
    }

    /// Resets the board: DTR and RTS asserted for `pulse`, then released
    /// (a Prop Plug resets the P2 on that edge).
    pub fn pulse_reset(&mut self, pulse: Duration) -> Result<(), serialport::Error> {
        self.port.write_data_terminal_ready(true)?;
        self.port.write_request_to_send(true)?;
        std::thread::sleep(pulse);
        self.port.write_data_terminal_ready(false)?;
        self.port.write_request_to_send(false)
    }

    /// Drops every event for `duration` (what a board says to a line
    /// another host left half written).
    pub fn discard_for(&mut self, duration: Duration) -> Result<(), LinkFault> {
        let deadline = Instant::now() + duration;
        while self.next_event(deadline)?.is_some() {}
        Ok(())
    }
}

impl Drop for Wire {
    fn drop(&mut self) {
        self.reader_stop.store(true, Ordering::Release);
        if let Some(reader) = self.reader.take() {
            let _ = reader.join();
        }
    }
}

fn write_port(port: &mut dyn SerialPort, bytes: &[u8]) -> Result<(), LinkFault> {
    port.write_all(bytes).map_err(|error| match error.kind() {
        io::ErrorKind::TimedOut => LinkFault::Timeout("the port takes no more bytes".to_string()),
        _ => LinkFault::Disconnected(format!("write: {error}")),
    })
}

/// One dialect's side of the link: its state and how it reacts.
pub(super) trait Conversation: Send {
    /// An event nobody was waiting for.
    fn on_event(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        event: Incoming,
    ) -> Result<(), LinkFault>;
    /// A handle's request; the conversation answers it (also when it
    /// returns a fault).
    fn on_request(
        &mut self,
        wire: &mut Wire,
        shared: &Shared,
        request: Request,
    ) -> Result<(), LinkFault>;
    /// When [`on_tick`](Conversation::on_tick) is due.
    fn next_tick(&self) -> Instant;
    /// The background work: polling, deadlines.
    fn on_tick(&mut self, wire: &mut Wire, shared: &Shared) -> Result<(), LinkFault>;
}

/// The reader thread: bytes in, events out, until stopped or the port ends.
fn read_loop(
    mut port: Box<dyn SerialPort>,
    dialect: Dialect,
    events: &Sender<Incoming>,
    stop: &AtomicBool,
) {
    let mut framer = Framer::new(dialect);
    let mut buffer = [0u8; 1024];
    while !stop.load(Ordering::Acquire) {
        match port.read(&mut buffer) {
            Ok(0) => {
                let _ = events.send(Incoming::Closed("the port reached its end".to_string()));
                return;
            }
            Ok(count) => {
                for &byte in &buffer[..count] {
                    framer.push(byte, &mut |event| {
                        let _ = events.send(event);
                    });
                }
            }
            Err(error)
                if matches!(
                    error.kind(),
                    io::ErrorKind::TimedOut
                        | io::ErrorKind::WouldBlock
                        | io::ErrorKind::Interrupted
                ) => {}
            Err(error) => {
                let _ = events.send(Incoming::Closed(format!("read: {error}")));
                return;
            }
        }
    }
}

/// Bytes to events, per dialect.
pub(super) enum Framer {
    /// Cogstep: lines ended by CR, LF or CRLF; blank lines dropped.
    Lines {
        line: Vec<u8>,
        /// The current line outgrew [`LINE_KEEP`]: drop it.
        overlong: bool,
    },
    /// P2 demo: screen events and clear bytes (the demo prints nothing
    /// else: no refusal, no echo).
    Screens { parser: Box<ScreenParser> },
}

impl Framer {
    pub fn new(dialect: Dialect) -> Self {
        match dialect {
            Dialect::Cogstep | Dialect::Grbl => Framer::Lines {
                line: Vec::new(),
                overlong: false,
            },
            Dialect::P2Demo => Framer::Screens {
                parser: Box::default(),
            },
        }
    }

    /// Takes one byte; `emit` gets what it completes.
    pub fn push(&mut self, byte: u8, emit: &mut dyn FnMut(Incoming)) {
        match self {
            Framer::Lines { line, overlong } => match byte {
                b'\r' | b'\n' => {
                    if !std::mem::take(overlong) && !line.is_empty() {
                        emit(Incoming::Line(String::from_utf8_lossy(line).into_owned()));
                    }
                    line.clear();
                }
                _ if line.len() >= LINE_KEEP => {
                    *overlong = true;
                    line.clear();
                }
                _ if *overlong => {}
                _ => line.push(byte),
            },
            Framer::Screens { parser } => {
                if let Some(event) = parser.push(byte) {
                    emit(Incoming::Screen(event));
                }
                if byte == p2demo::CLEAR {
                    emit(Incoming::Cleared);
                }
            }
        }
    }
}

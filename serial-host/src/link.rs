//! The link thread: it owns the port, runs the dialect's conversation, and
//! reopens the port when the link goes down.
//!
//! Two threads per open port: the reader (`wire`) turns bytes into
//! `Incoming` events (lines for cogstep, screen events for the P2 demo);
//! the link thread writes, waits for events with deadlines, answers the
//! handles' requests and runs the background poll.

use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam::channel::select;
use serialport::ClearBuffer;

use super::cogstep::Cogstep;
use super::demo::Demo;
use super::grbl::Grbl;
use super::state::{Link, Shared};
use super::wire::{Conversation, Incoming, LinkFault, Wire};
use super::{DemoStart, Dialect, SerialError, FAULT_DISCONNECTED};
use cogstep_motion::axis::AxisError;

/// How often the link thread tries to reopen a lost port.
pub const RECONNECT_INTERVAL: Duration = Duration::from_millis(250);

/// How long the link thread waits at most before it looks at `closing`.
const CLOSE_CHECK: Duration = Duration::from_millis(50);
/// An open, identified port.
pub(super) struct Connection {
    wire: Wire,
    conversation: Box<dyn Conversation>,
}

/// Opens the port and identifies the board; on success the shared state
/// says the link is up. `demo_start` is how a P2 demo board is brought to
/// a known prompt.
pub(super) fn connect(shared: &Shared, demo_start: DemoStart) -> Result<Connection, SerialError> {
    let config = &shared.config;
    let port = serialport::new(&config.port, config.baud)
        .timeout(config.timeout)
        .open()
        .map_err(|source| SerialError::Open {
            port: config.port.clone(),
            source,
        })?;
    // Whatever waited in the buffer is from before this host.
    let _ = port.clear(ClearBuffer::Input);
    let mut wire = Wire::start(port, config.dialect, shared.urgent.clone()).map_err(|source| {
        SerialError::Io {
            port: config.port.clone(),
            source,
        }
    })?;
    let conversation: Box<dyn Conversation> = match config.dialect {
        Dialect::Cogstep => Box::new(Cogstep::handshake(&mut wire, shared)?),
        Dialect::P2Demo => Box::new(Demo::handshake(&mut wire, shared, demo_start)?),
        Dialect::Grbl => Box::new(Grbl::handshake(&mut wire, shared)?),
    };
    Ok(Connection { wire, conversation })
}

/// Starts the link thread on an open connection.
pub(super) fn spawn(
    shared: Arc<Shared>,
    connection: Connection,
) -> Result<JoinHandle<()>, SerialError> {
    std::thread::Builder::new()
        .name("serial-link".to_string())
        .spawn(move || run(&shared, Some(connection)))
        .map_err(SerialError::Spawn)
}

/// Serves the connection; when it fails, reopens the port every
/// [`RECONNECT_INTERVAL`] until it works again or the board is closed.
fn run(shared: &Shared, mut connection: Option<Connection>) {
    let mut down_reason = String::new();
    while !shared.is_closing() {
        match connection.take() {
            Some(mut open) => {
                let fault = serve(&mut open, shared);
                // The reader stops and the port closes before it is reopened.
                drop(open);
                if fault == LinkFault::Closing {
                    break;
                }
                down_reason = fault.describe();
                shared.state().link_down(down_reason.clone());
            }
            None => {
                wait_down(shared, RECONNECT_INTERVAL);
                if shared.is_closing() {
                    break;
                }
                // Reopening never resets nor types: the board may be mid-move.
                match connect(shared, DemoStart::Passive) {
                    Ok(open) => connection = Some(open),
                    Err(error) => {
                        shared.state().link =
                            Link::Down(format!("{down_reason}; reopening: {error}"));
                    }
                }
            }
        }
    }
    shared.state().link = Link::Down("closed".to_string());
    while let Ok(request) = shared.requests.try_recv() {
        request.answer(Err(AxisError::Unavailable));
    }
}

/// While the link is down: refuses requests as they come, for `duration`.
fn wait_down(shared: &Shared, duration: Duration) {
    let until = Instant::now() + duration;
    loop {
        let now = Instant::now();
        if shared.is_closing() || now >= until {
            return;
        }
        let wait = (until - now).min(CLOSE_CHECK);
        select! {
            recv(shared.requests) -> request => match request {
                Ok(request) => request.answer(Err(AxisError::Fault(FAULT_DISCONNECTED))),
                Err(_) => return,
            },
            recv(shared.urgent) -> byte => if byte.is_err() { return },
            default(wait) => {},
        }
    }
}

/// Runs the conversation until the link fails or the board is closed.
fn serve(connection: &mut Connection, shared: &Shared) -> LinkFault {
    let Connection { wire, conversation } = connection;
    let incoming = wire.incoming.clone();
    loop {
        if shared.is_closing() {
            return LinkFault::Closing;
        }
        let now = Instant::now();
        let tick = conversation.next_tick();
        if tick <= now {
            if let Err(fault) = conversation.on_tick(wire, shared) {
                return fault;
            }
            continue;
        }
        let wait = (tick - now).min(CLOSE_CHECK);
        let step = select! {
            recv(incoming) -> event => match event {
                Ok(Incoming::Closed(what)) => Err(LinkFault::Disconnected(what)),
                Ok(event) => conversation.on_event(wire, shared, event),
                Err(_) => Err(LinkFault::Disconnected("the reader stopped".to_string())),
            },
            recv(shared.urgent) -> byte => match byte {
                Ok(byte) => wire.send(&[byte]),
                Err(_) => Err(LinkFault::Closing),
            },
            recv(shared.requests) -> request => match request {
                Ok(request) if Instant::now() > request.start_by => {
                    // The caller has given up: it must not happen behind its back.
                    request.answer(Err(AxisError::Fault("timeout")));
                    Ok(())
                }
                Ok(request) => conversation.on_request(wire, shared, request),
                Err(_) => Err(LinkFault::Closing),
            },
            default(wait) => Ok(()),
        };
        if let Err(fault) = step {
            return fault;
        }
    }
}

//! The simulated grbl board: [`GrblSession`] over the hub's axes.
//!
//! The board thread reads the port only as far as the session's receive
//! buffer has room (a full buffer leaves the bytes in the port, where a
//! real UART's flow would hold them), feeds every byte to the session,
//! moves the motion on and polls the session every millisecond while
//! anything runs. Settings live in a file when one is named
//! ([`GrblOptions::settings_file`]): read at start, written after every
//! `$N=` change, so they are kept across a restart.

mod motion;

use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

use serialport::SerialPort;

use cogstep_protocol::grbl::{GrblGcode, GrblMotion, GrblSession, MotionState, Settings};

pub use motion::{HubMotion, PLANNER_BLOCKS};

use crate::{Control, SimConfig, SimError, Unsent, READ_SLICE};
use std::sync::atomic::Ordering;

/// The loop's turn while something runs.
const BUSY_SLICE: Duration = Duration::from_millis(1);

/// What a grbl board keeps beside [`SimConfig`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct GrblOptions {
    /// Where the `$` settings are kept (`$$`'s lines); none: grbl's
    /// defaults at every start.
    pub settings_file: Option<PathBuf>,
}

/// The session a grbl board runs.
pub type SimGrblSession = GrblSession<HubMotion, GrblGcode>;

/// Reads a settings file (`$N=value` lines; what does not read is skipped
/// with a warning on stderr). A missing file is the defaults.
pub fn load_settings(path: &Path) -> Settings {
    let mut settings = Settings::default();
    let Ok(text) = std::fs::read_to_string(path) else {
        return settings;
    };
    for line in text.lines() {
        let line = line.trim();
        let Some(setting) = line.strip_prefix('$') else {
            continue;
        };
        if settings.set_from_text(setting, u32::MAX).is_err() {
            eprintln!("board-sim: {}: setting `{line}` skipped", path.display());
        }
    }
    settings
}

/// Writes the settings file (beside it first, then renamed over it).
pub fn store_settings(path: &Path, settings: &Settings) -> io::Result<()> {
    let mut text = String::new();
    // Writing into a String cannot fail.
    let _ = settings.write_all(&mut text);
    let text = text.replace("\r\n", "\n");
    let mut temporary = path.as_os_str().to_owned();
    temporary.push(".tmp");
    let temporary = PathBuf::from(temporary);
    std::fs::write(&temporary, text)?;
    std::fs::rename(&temporary, path)
}

/// A fresh grbl board: hub, motion, session, welcome line written.
fn new_session(
    config: SimConfig,
    options: &GrblOptions,
    replies: &mut String,
) -> Result<SimGrblSession, SimError> {
    let settings = options
        .settings_file
        .as_deref()
        .map(load_settings)
        .unwrap_or_default();
    let motion = HubMotion::new(config.clkfreq, &settings)?;
    let gcode = GrblGcode::new(&settings);
    let mut session = GrblSession::new(motion, gcode, settings, env!("CARGO_PKG_VERSION"));
    let _ = session.start(replies);
    Ok(session)
}

/// The grbl board's thread (see the module docs).
pub(crate) fn serve(
    config: SimConfig,
    options: GrblOptions,
    mut port: Box<dyn SerialPort>,
    mut writer: Box<dyn SerialPort>,
    control: &Control,
) {
    let mut replies = String::new();
    let mut session = match new_session(config, &options, &mut replies) {
        Ok(session) => session,
        Err(error) => {
            eprintln!("board-sim: {error}");
            return;
        }
    };
    let mut unsent = Unsent::default();
    let mut bytes = [0u8; 512];
    while !control.stop.load(Ordering::Acquire) {
        if control.reset.swap(false, Ordering::AcqRel) {
            unsent.clear();
            replies.clear();
            if let Ok(fresh) = new_session(config, &options, &mut replies) {
                session = fresh;
            }
        }
        unsent.queue(&mut replies);
        if !unsent.flush(writer.as_mut()) {
            continue;
        }
        let busy = session.is_busy() || session.motion().status().state != MotionState::Idle;
        let room = session.room().min(bytes.len());
        if room == 0 {
            std::thread::sleep(BUSY_SLICE);
        } else {
            let _ = port.set_timeout(if busy { BUSY_SLICE } else { READ_SLICE });
            match port.read(&mut bytes[..room]) {
                Ok(0) => std::thread::sleep(READ_SLICE),
                Ok(count) => {
                    for &byte in &bytes[..count] {
                        // Never Full: no more was read than there was room for.
                        let _ = session.receive(byte, &mut replies);
                    }
                }
                Err(error)
                    if matches!(
                        error.kind(),
                        io::ErrorKind::TimedOut
                            | io::ErrorKind::WouldBlock
                            | io::ErrorKind::Interrupted
                    ) => {}
                Err(_) => std::thread::sleep(READ_SLICE),
            }
        }
        session.motion_mut().advance();
        let _ = session.poll(&mut replies);
        if session.take_settings_changed() {
            if let Some(path) = &options.settings_file {
                if let Err(error) = store_settings(path, session.settings()) {
                    eprintln!("board-sim: cannot write {}: {error}", path.display());
                }
            }
        }
    }
    let _ = writer.flush();
}

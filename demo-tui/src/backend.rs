//! What the demo drives: the emulated hub, or a board over a serial port.
//!
//! Both give [`AxisContract`] handles (the one way every backend moves an
//! axis) plus what the contract does not carry: the reference demo's move
//! figures (accel steps, steps at speed, elapsed time...), what the backend
//! can do at all, and its faults. The app only ever talks to a
//! [`Machine`].

use std::path::Path;
use std::sync::{Arc, Mutex};

use driver::profile::scurve::{self, ScurveConfig};
use driver::serial::host::{
    DemoStart, Dialect, SerialAxis, SerialBoard, SerialConfig, SerialError, GRBL_UNSUPPORTED,
    P2DEMO_UNSUPPORTED,
};
use driver::switch::DemoSwitches;
use driver::trace::{Recorder, RecorderOptions, VcdError};
use driver::{Axis, AxisContract, AxisError, ClockMode, Edge, Hub, HubConfig, HubError, Outputs};
use driver::{HomeConfig, LimitStatus};

use crate::program::{PathCommand, PathReading};

/// The system clock the demo's hub runs at, Hz (as the P2 usually runs).
pub const CLKFREQ_HZ: u32 = 200_000_000;

/// What a backend can do. A key for something it cannot do is refused
/// with the reason, never faked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Capabilities {
    /// The stop key (drive the stop pin low): `None` when supported, or why not.
    pub stop_pin: Option<String>,
    /// Jogging with held keys: `None` when supported, or why not.
    pub jog: Option<String>,
    /// Emergency stop: `None` when supported, or why not.
    pub emergency_stop: Option<String>,
}

impl Capabilities {
    /// Everything supported (the emulated hub).
    pub fn all() -> Self {
        Self {
            stop_pin: None,
            jog: None,
            emergency_stop: None,
        }
    }
}

/// A backend's fixed description, read once at start.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MachineInfo {
    /// One line: what is being driven ("emulated P2 hub, 4 cogs, ...").
    pub title: String,
    /// The system clock, Hz.
    pub clkfreq_hz: u32,
    /// What the backend can do.
    pub capabilities: Capabilities,
    /// The highest speed a move may ask for, steps/s, when known.
    pub max_speed: Option<u32>,
    /// Per axis: its outputs and pins, short ("sd", "cc", ...).
    pub axis_kinds: Vec<String>,
    /// Per axis: its pins in words ("step 1, dir 2, stop 0").
    pub axis_pins: Vec<String>,
    /// How long a jog runs on after its last heartbeat, when the backend
    /// says (the emulated hub's `jog_timeout_ms`; a board does not tell).
    pub jog_timeout: Option<std::time::Duration>,
}

/// The reference demo's move figures that the axis contract does not
/// carry. `None` where a backend cannot tell.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MoveFigures {
    /// S-curve offset, degrees.
    pub offset_deg: Option<u32>,
    /// Accel steps of the current (or last) move.
    pub accel_steps: Option<u32>,
    /// Steps at speed of the current (or last) move, as planned.
    pub slew_steps: Option<u32>,
    /// "Max Velocity": the reference's top speed long, written when a move
    /// starts to decelerate (the emulation shows it so), steps/s.
    pub top_velocity: Option<u32>,
    /// Steps the last stop left unmade.
    pub dropped_steps: Option<u32>,
    /// From taking the move to its last step, ms.
    pub elapsed_ms: Option<u64>,
}

/// A set of axes to drive.
pub trait Machine {
    /// The fixed description.
    fn info(&self) -> &MachineInfo;
    /// One axis, by index from 0.
    fn axis(&self, index: usize) -> Option<&dyn AxisContract>;
    /// The figures of one axis's current (or last) move.
    fn figures(&self, index: usize) -> MoveFigures;
    /// Emergency stop of every axis.
    fn emergency_stop_all(&self) -> Result<(), AxisError>;
    /// A fault to show prominently (a board lost or reset), if any.
    fn fault(&self) -> Option<String>;
    /// Whether a move can be planned, checked before anything is sent.
    fn check_move(&self, speed: u32, steps: i32) -> Result<(), String>;
    /// A coordinated move of axes 0 to `steps.len() − 1` (`Hub::move_together`,
    /// protocol `G`): every first edge on one CT, one straight line, all or
    /// nothing. By default not supported.
    fn move_together(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
        let _ = (steps, speed);
        Err(AxisError::Unsupported("group moves"))
    }
    /// One axis's output pins, where the backend has them (`--motor`).
    fn outputs(&self, _index: usize) -> Option<Outputs> {
        None
    }
    /// The pin edges recorded since the last call, in time order, and the
    /// clock now (ticks), where the backend records them (`--motor`).
    fn take_edges(&self) -> Option<(Vec<Edge>, u64)> {
        None
    }
    /// What the backend records (`--record`), for ending it once the
    /// loop (which owns the machine) is over.
    fn recording(&self) -> Option<RecordingHandle> {
        None
    }
    /// How `h` homes one axis, where the backend has a home switch for it.
    fn home_config(&self, _index: usize) -> Option<HomeConfig> {
        None
    }
    /// One axis's switches, pressed or not: home, min limit, max limit,
    /// where the backend can read them.
    fn switches(&self, _index: usize) -> Option<[bool; 3]> {
        None
    }
    /// One axis's limit and homing state, where reading it costs nothing
    /// (it is read every frame).
    fn limit_status(&self, _index: usize) -> Option<LimitStatus> {
        None
    }
    /// A command to the G-code program's path, where the backend runs one
    /// (`--gcode`).
    fn path_command(&self, _command: PathCommand) -> Result<(), String> {
        Err("no G-code program runs here".to_string())
    }
    /// The G-code program's path, where the backend runs one (read every
    /// frame).
    fn path_reading(&self) -> Option<PathReading> {
        None
    }
}

/// Why `--record` could not start.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The hub would not start.
    #[error("the emulated hub would not start: {0}")]
    Hub(#[from] HubError),
    /// The file could not be created or written.
    #[error("cannot record to {path}: {reason}")]
    File {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
}

/// Creates (or empties) the `--record` file without waiting for anything:
/// a FIFO with no reader is refused at once, where `open(2)` would wait for
/// a reader before the demo draws its first frame.
fn create_record_file(path: &Path) -> Result<std::fs::File, String> {
    use rustix::fs::{Mode, OFlags};
    let flags = OFlags::WRONLY | OFlags::CREATE | OFlags::TRUNC | OFlags::CLOEXEC;
    let fd = rustix::fs::open(path, flags | OFlags::NONBLOCK, Mode::from_raw_mode(0o666)).map_err(
        |errno| match errno {
            rustix::io::Errno::NXIO => {
                "a FIFO that nobody reads: start its reader first".to_string()
            }
            errno => std::io::Error::from(errno).to_string(),
        },
    )?;
    // Writes then wait for a slow reader, as to any file.
    rustix::fs::fcntl_getfl(&fd)
        .and_then(|open| rustix::fs::fcntl_setfl(&fd, open - OFlags::NONBLOCK))
        .map_err(|errno| std::io::Error::from(errno).to_string())?;
    Ok(fd.into())
}

/// `--record`: the session's pins streaming to a VCD file.
#[derive(Debug)]
struct Recording {
    path: String,
    /// `None` once finished.
    recorder: Mutex<Option<Recorder>>,
}

/// A handle on a machine's recording: [`RecordingHandle::finish`] ends it
/// (the file is flushed and closed) from whichever thread holds it.
#[derive(Clone, Debug)]
pub struct RecordingHandle(Arc<Recording>);

impl RecordingHandle {
    /// Ends the recording and says what it wrote; `Ok(None)` once ended.
    pub fn finish(&self) -> Result<Option<String>, String> {
        let recording = &self.0;
        let taken = recording
            .recorder
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take();
        let Some(recorder) = taken else {
            return Ok(None);
        };
        let path = &recording.path;
        match recorder.finish() {
            Ok(summary) => Ok(Some(format!(
                "recorded {} edges to {path} ({} lost, {} late)",
                summary.edges, summary.lost, summary.late
            ))),
            Err(error) => Err(format!("recording {path}: {error}")),
        }
    }
}

impl Recording {
    /// What went wrong so far, if anything: shown as a fault, never silent.
    fn problem(&self) -> Option<String> {
        let recorder = self.recorder.lock().unwrap_or_else(|p| p.into_inner());
        let recorder = recorder.as_ref()?;
        if let Some(failure) = recorder.failure() {
            return Some(format!("recording {} stopped: {failure}", self.path));
        }
        let (lost, late) = (recorder.lost_edges(), recorder.late_edges());
        (lost > 0 || late > 0).then(|| {
            format!(
                "recording {}: {lost} edges lost (edge ring full), {late} written late; noted in the file",
                self.path
            )
        })
    }
}

/// The emulated P2 hub in real time, one cog per axis.
pub struct Emulated {
    hub: Hub,
    axes: Vec<Axis>,
    /// Each axis's home switch and hard limits.
    switches: Vec<DemoSwitches>,
    info: MachineInfo,
    recording: Option<Arc<Recording>>,
}

impl Emulated {
    /// Starts a real-time hub at [`CLKFREQ_HZ`] with `axis_count` cogs:
    /// odd-numbered axes drive step/dir (`sd`) outputs, even-numbered ones
    /// cw/ccw (`cc`). Axis n (from 0) uses pins 4n (stop), 4n+1 and 4n+2.
    pub fn start(axis_count: usize) -> Result<Self, HubError> {
        Self::launch(axis_count, None)
    }

    /// As [`Emulated::start`], recording every pin edge for
    /// [`Machine::take_edges`] when `record_edges` (the motor models need
    /// them).
    pub fn start_with_edges(axis_count: usize, record_edges: bool) -> Result<Self, HubError> {
        Self::launch(
            axis_count,
            record_edges.then_some(HubConfig::default().trace_ring),
        )
    }

    /// As [`Emulated::start`], and every pin of every axis (outputs and
    /// stop pins) is recorded to a VCD file at `path` for the whole
    /// session, streamed as it goes; each cog's edge ring holds
    /// `trace_ring` edges ([`HubConfig::trace_ring`]). [`RecordingHandle::finish`]
    /// ends the file.
    pub fn start_recording(
        axis_count: usize,
        path: &Path,
        trace_ring: usize,
    ) -> Result<Self, RecordError> {
        let shown = path.display().to_string();
        let failed = |reason: String| RecordError::File {
            path: shown.clone(),
            reason,
        };
        let file = create_record_file(path).map_err(failed)?;
        let mut machine = Self::launch(axis_count, Some(trace_ring))?;
        let recorder = Recorder::start(&machine.hub, file, RecorderOptions::default())
            .map_err(|e: VcdError| failed(e.to_string()))?;
        machine
            .info
            .title
            .push_str(&format!(" · recording {shown}"));
        machine.recording = Some(Arc::new(Recording {
            path: shown,
            recorder: Mutex::new(Some(recorder)),
        }));
        Ok(machine)
    }

    fn launch(axis_count: usize, trace_ring: Option<usize>) -> Result<Self, HubError> {
        let config = HubConfig {
            clkfreq: CLKFREQ_HZ,
            clock: ClockMode::Real,
            trace_edges: trace_ring.is_some(),
            trace_ring: trace_ring.unwrap_or(HubConfig::default().trace_ring),
            ..HubConfig::default()
        };
        let hub = Hub::new(config)?;
        let mut axes = Vec::with_capacity(axis_count);
        let mut kinds = Vec::with_capacity(axis_count);
        let mut pins = Vec::with_capacity(axis_count);
        let mut switches = Vec::with_capacity(axis_count);
        for index in 0..axis_count {
            let base = u8::try_from(index * 4).map_err(|_| HubError::Config("too many axes"))?;
            let (stop, a, b) = (base, base + 1, base + 2);
            let axis = if index % 2 == 0 {
                hub.start_sd(stop, a, b)?
            } else {
                hub.start_cc(stop, a, b)?
            };
            // The stop pin must read high for a cog to run.
            hub.set_input(stop, true)?;
            // A home switch and both hard limits, simulated (pins 40+, 48+, 56+).
            switches.push(hub.fit_demo_switches(&axis, index)?);
            let (kind, words) = match axis.outputs() {
                Outputs::StepDir { step, dir } => ("sd", format!("step {step}, dir {dir}")),
                Outputs::CwCcw { cw, ccw } => ("cc", format!("cw {cw}, ccw {ccw}")),
            };
            kinds.push(kind.to_string());
            pins.push(format!("{words}, stop {stop}"));
            axes.push(axis);
        }
        let max_speed = max_speed(&config);
        let info = MachineInfo {
            title: format!(
                "emulated P2 hub · {axis_count} cog{} · {} MHz · real time",
                if axis_count == 1 { "" } else { "s" },
                config.clkfreq / 1_000_000
            ),
            clkfreq_hz: config.clkfreq,
            capabilities: Capabilities::all(),
            max_speed: Some(max_speed),
            axis_kinds: kinds,
            axis_pins: pins,
            jog_timeout: Some(std::time::Duration::from_millis(u64::from(
                config.jog_timeout_ms,
            ))),
        };
        Ok(Self {
            hub,
            axes,
            switches,
            info,
            recording: None,
        })
    }
}

/// The highest speed whose step pulse (and its falling edge) still fits
/// between two steps, as the hub checks it.
fn max_speed(config: &HubConfig) -> u32 {
    config.clkfreq / config.pulse_ticks.saturating_add(2).max(1)
}

impl Machine for Emulated {
    fn info(&self) -> &MachineInfo {
        &self.info
    }

    fn axis(&self, index: usize) -> Option<&dyn AxisContract> {
        self.axes.get(index).map(|axis| axis as &dyn AxisContract)
    }

    fn figures(&self, index: usize) -> MoveFigures {
        let Some(axis) = self.axes.get(index) else {
            return MoveFigures::default();
        };
        let ticks = axis.last_step_ct().saturating_sub(axis.move_start_ct());
        let clkfreq = u64::from(self.info.clkfreq_hz.max(1));
        MoveFigures {
            // Before the first move the mailbox has no offset yet: the hub's setting.
            offset_deg: Some(match axis.offset() {
                0 => self.hub.config().offset_deg,
                deg => deg,
            }),
            accel_steps: Some(axis.accel_steps()),
            slew_steps: Some(axis.slew_steps()),
            // "Max Velocity:" as the reference shows it.
            top_velocity: Some(axis.max_velocity()),
            dropped_steps: Some(axis.dropped_steps()),
            elapsed_ms: Some(ticks.saturating_mul(1_000) / clkfreq),
        }
    }

    fn emergency_stop_all(&self) -> Result<(), AxisError> {
        self.hub.emergency_stop();
        Ok(())
    }

    fn move_together(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
        let group: Vec<(&Axis, i32)> = self.axes.iter().zip(steps.iter().copied()).collect();
        self.hub.move_together(&group, speed)
    }

    fn outputs(&self, index: usize) -> Option<Outputs> {
        self.axes.get(index).map(Axis::outputs)
    }

    fn take_edges(&self) -> Option<(Vec<Edge>, u64)> {
        self.hub
            .config()
            .trace_edges
            .then(|| (self.hub.take_trace(), self.hub.now()))
    }

    fn fault(&self) -> Option<String> {
        self.recording.as_deref().and_then(Recording::problem)
    }

    fn recording(&self) -> Option<RecordingHandle> {
        self.recording.clone().map(RecordingHandle)
    }

    fn home_config(&self, index: usize) -> Option<HomeConfig> {
        self.switches.get(index).map(DemoSwitches::home_config)
    }

    fn switches(&self, index: usize) -> Option<[bool; 3]> {
        let switches = self.switches.get(index)?;
        // All active high.
        Some([switches.home_pin, switches.min_pin, switches.max_pin].map(|pin| self.hub.input(pin)))
    }

    fn limit_status(&self, index: usize) -> Option<LimitStatus> {
        self.axes.get(index).map(Axis::limit_status)
    }

    fn check_move(&self, speed: u32, steps: i32) -> Result<(), String> {
        let config = self.hub.config();
        if let Some(max) = self.info.max_speed {
            if speed > max {
                return Err(format!(
                    "at most {max} steps/s: the step pulse must fit between steps"
                ));
            }
        }
        scurve::plan(&config.scurve(), speed, steps.unsigned_abs())
            .map(|_| ())
            .map_err(|e| e.to_string())
    }
}

/// A board on a serial port ([`driver::serial::host`]).
pub struct Serial {
    board: SerialBoard,
    axes: Vec<SerialAxis>,
    info: MachineInfo,
}

impl Serial {
    /// Opens `port` and identifies the board.
    pub fn open(
        port: &str,
        baud: u32,
        dialect: Dialect,
        demo_start: DemoStart,
    ) -> Result<Self, SerialError> {
        let mut config = SerialConfig::new(port);
        config.baud = baud;
        config.dialect = dialect;
        config.demo_start = demo_start;
        let board = SerialBoard::open(config)?;
        let axes: Vec<SerialAxis> = (0..board.axis_count())
            .map_while(|index| board.axis(index))
            .collect();
        let caps = board.capabilities();
        // Say why a key cannot work, in the board's own terms.
        let why = match dialect {
            Dialect::P2Demo => format!("not supported by this board ({P2DEMO_UNSUPPORTED})"),
            Dialect::Grbl => format!("not supported by this board ({GRBL_UNSUPPORTED})"),
            _ => "not supported by this board".to_string(),
        };
        let missing = |supported: bool| (!supported).then(|| why.clone());
        let clkfreq_hz = board.clkfreq();
        let clock = if clkfreq_hz == 0 {
            "clock not reported".to_string()
        } else {
            format!("{} MHz", clkfreq_hz / 1_000_000)
        };
        let info = MachineInfo {
            title: format!(
                "serial {port} · {baud} baud · {dialect} · {} · {} ax{} · {clock}",
                board.identity(),
                axes.len(),
                if axes.len() == 1 { "is" } else { "es" },
            ),
            clkfreq_hz,
            capabilities: Capabilities {
                stop_pin: missing(caps.stop_pin),
                jog: missing(caps.jog),
                emergency_stop: missing(caps.emergency_stop),
            },
            max_speed: None,
            axis_kinds: vec!["serial".to_string(); axes.len()],
            axis_pins: (0..axes.len())
                .map(|index| format!("board axis {index}"))
                .collect(),
            jog_timeout: None,
        };
        Ok(Self { board, axes, info })
    }
}

impl Machine for Serial {
    fn info(&self) -> &MachineInfo {
        &self.info
    }

    fn axis(&self, index: usize) -> Option<&dyn AxisContract> {
        self.axes.get(index).map(|axis| axis as &dyn AxisContract)
    }

    /// The protocol's status line carries none of these: shown as n/a.
    fn figures(&self, _index: usize) -> MoveFigures {
        MoveFigures::default()
    }

    fn emergency_stop_all(&self) -> Result<(), AxisError> {
        self.board.emergency_stop_all()
    }

    fn move_together(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
        self.board.move_together(steps, speed)
    }

    fn fault(&self) -> Option<String> {
        self.board.fault()
    }

    /// The board simulator's home switches (`board-sim` fits them on every
    /// axis); a board without one refuses `H`, and the demo says so.
    fn home_config(&self, index: usize) -> Option<HomeConfig> {
        if self.board.dialect() != Dialect::Cogstep {
            return None;
        }
        DemoSwitches::for_axis(index).map(|switches| switches.home_config())
    }

    fn check_move(&self, speed: u32, steps: i32) -> Result<(), String> {
        // The board has the last word; this only catches what no board takes.
        let config = ScurveConfig {
            clkfreq: if self.info.clkfreq_hz == 0 {
                CLKFREQ_HZ
            } else {
                self.info.clkfreq_hz
            },
            ..ScurveConfig::default()
        };
        scurve::plan(&config, speed, steps.unsigned_abs())
            .map(|_| ())
            .map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn emulated_hub_mixes_sd_and_cc_and_checks_moves() {
        let machine = Emulated::start(3).expect("hub");
        assert_eq!(machine.info().axis_kinds, ["sd", "cc", "sd"]);
        assert_eq!(machine.info().axis_pins[1], "cw 5, ccw 6, stop 4");
        assert!(machine.axis(2).is_some());
        assert!(machine.axis(3).is_none());
        let status = machine
            .axis(0)
            .and_then(|a| a.status().ok())
            .expect("status");
        assert!(status.stop_pin_high, "stop pins start high");
        assert_eq!(machine.check_move(20_000, -2_000), Ok(()));
        assert!(machine.check_move(0, 2_000).is_err());
        assert!(machine.check_move(20_000, 0).is_err());
        let max = machine.info().max_speed.expect("max");
        assert!(machine.check_move(max, 1_000).is_ok());
        assert!(machine.check_move(max + 1, 1_000).is_err());
        assert_eq!(machine.figures(0).offset_deg, Some(40));
    }

    #[test]
    fn a_recording_that_loses_edges_says_so_as_a_fault() {
        let directory = tempfile::tempdir().unwrap();
        let path = directory.path().join("overflow.vcd");
        // 16-edge rings cannot keep up with 150,000 steps/s.
        let machine = Emulated::start_recording(1, &path, 16).expect("hub");
        assert!(machine.info().title.contains("recording"));
        assert_eq!(machine.fault(), None);
        let axis = machine.axis(0).expect("axis");
        axis.move_steps(150_000, 30_000).expect("move");
        let start = std::time::Instant::now();
        while axis.status().expect("status").position < 30_000 {
            assert!(start.elapsed() < std::time::Duration::from_secs(20));
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
        let fault = machine.fault().expect("the loss is a fault");
        assert!(fault.contains("edges lost"), "{fault}");
        let recording = machine.recording().expect("recording");
        let line = recording.finish().expect("finished").expect("a summary");
        assert!(
            line.contains("recorded") && !line.contains(" 0 lost"),
            "{line}"
        );
        assert_eq!(recording.finish(), Ok(None), "finished once");
        assert_eq!(machine.fault(), None, "nothing recorded any more");
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains("lost (a ring was full)"),
            "the count at the end"
        );
    }

    #[test]
    fn a_recording_to_an_impossible_path_is_an_error() {
        let error = Emulated::start_recording(1, Path::new("/no/such/dir/x.vcd"), 1_024)
            .err()
            .expect("refused");
        assert!(error.to_string().contains("/no/such/dir/x.vcd"), "{error}");
    }
}

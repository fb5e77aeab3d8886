//! `--gcode`: the emulated hub running a G-code program, as a
//! [`Machine`].
//!
//! The hub runs in real time, one step/dir axis per axis of the machine
//! file. A worker thread gives the program's lines to the path one at a
//! time ([`GcodePath::run_line`], which waits while the path's queue is
//! full), so that neither the app thread nor the screen ever waits on a
//! full queue. Holds, resumes, cancels and overrides go to the path
//! through a [`PathControl`] while the worker waits:
//!
//! ```text
//! worker:     line ─► GcodePath::run_line (waits for room) ─► PathJob ─► cogs
//! app thread: PathCommand ─► PathControl (hold, resume, cancel, e-stop, override)
//!             frame ─► PathControl::progress + what the worker fed ─► PathReading
//! ```

use std::sync::{Arc, Mutex, MutexGuard};

use driver::gcode::{home_config, GcodePath, GcodePathError, HomeEnd, LineOutcome};
use driver::{Axis, AxisContract, AxisError, ClockMode, Hub, HubConfig, HubError, PathControl};
use driver::{PathError, PathFault};

use crate::backend::{Capabilities, Machine, MachineInfo, MoveFigures, CLKFREQ_HZ};
use crate::program::{PathCommand, PathReading, Program};

/// Why a program could not start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The hub or an axis would not start.
    #[error("the emulated hub would not start: {0}")]
    Hub(#[from] HubError),
    /// The path would not take the axes.
    #[error("the path would not start: {0}")]
    Path(#[from] GcodePathError),
}

/// What the worker and the app thread share.
struct Feeding {
    /// The path's handle (a new one after a G28).
    control: PathControl,
    fed_line: u32,
    fed_all: bool,
    stopped: bool,
    error: Option<(u32, String)>,
    /// The program, kept once fed until the demo ends (dropping it lets
    /// the axes go, stopping them at once if they still move).
    path: Option<GcodePath>,
}

/// The emulated hub running a program.
pub struct ProgramBackend {
    axes: Vec<Axis>,
    info: MachineInfo,
    feeding: Arc<Mutex<Feeding>>,
}

fn lock(feeding: &Mutex<Feeding>) -> MutexGuard<'_, Feeding> {
    feeding
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl ProgramBackend {
    /// Starts a real-time hub with one step/dir axis per axis of the
    /// program's machine (axis n on pins 4n stop, 4n+1 step, 4n+2 dir) and
    /// starts running the program.
    pub fn start(program: &Program) -> Result<Self, StartError> {
        let config = HubConfig {
            clkfreq: CLKFREQ_HZ,
            clock: ClockMode::Real,
            ..HubConfig::default()
        };
        let hub = Hub::new(config)?;
        let mut axes = Vec::new();
        let mut pins = Vec::new();
        for index in 0..program.spec.axis_count() {
            let base = u8::try_from(index * 4).map_err(|_| HubError::Config("too many axes"))?;
            let axis = hub.start_sd(base, base + 1, base + 2)?;
            hub.set_input(base, true)?;
            pins.push(format!("step {}, dir {}, stop {base}", base + 1, base + 2));
            axes.push(axis);
        }
        let homing = fit_home_switches(&hub, &axes, program)?;
        let refs: Vec<&Axis> = axes.iter().collect();
        let path = GcodePath::new(&hub, &refs, &program.spec)?.with_homing(homing);
        let count = axes.len();
        let info = MachineInfo {
            title: format!(
                "G-code {} · machine {} · emulated P2 hub · {count} cog{} · {} MHz · real time",
                program.name,
                program.machine_name,
                if count == 1 { "" } else { "s" },
                CLKFREQ_HZ / 1_000_000
            ),
            clkfreq_hz: CLKFREQ_HZ,
            capabilities: Capabilities::all(),
            max_speed: None,
            axis_kinds: vec!["sd".to_string(); count],
            axis_pins: pins,
            jog_timeout: None,
        };
        let feeding = Arc::new(Mutex::new(Feeding {
            control: path.job().control(),
            fed_line: 0,
            fed_all: false,
            stopped: false,
            error: None,
            path: None,
        }));
        let lines = program.lines.clone();
        let shared = Arc::clone(&feeding);
        std::thread::Builder::new()
            .name("demo-gcode".into())
            .spawn(move || feed(path, &lines, &shared))
            .map_err(|_| HubError::Config("the G-code worker thread could not start"))?;
        Ok(Self {
            axes,
            info,
            feeding,
        })
    }
}

/// How far from its home switch each axis of the emulated machine starts
/// (mm): G28 has a short way to go.
const HOME_SWITCH_MM: f64 = 2.0;

/// A simulated home switch (active high, pin 40 + axis) on every axis
/// whose machine file names a `home` end, pressed from
/// [`HOME_SWITCH_MM`] beyond where the axis starts towards that end; and
/// how G28 homes onto it.
fn fit_home_switches(
    hub: &Hub,
    axes: &[Axis],
    program: &Program,
) -> Result<Vec<Option<driver::HomeConfig>>, HubError> {
    let mut homing = Vec::with_capacity(axes.len());
    for ((index, axis), spec) in axes.iter().enumerate().zip(program.spec.axes()) {
        let pin = u8::try_from(40 + index).map_err(|_| HubError::Config("too many axes"))?;
        let config = home_config(spec, pin);
        if let Some(end) = spec.home {
            let at = (HOME_SWITCH_MM * spec.steps_per_mm).round() as i64;
            let pressed = match end {
                HomeEnd::Min => i64::MIN..=-at,
                HomeEnd::Max => at..=i64::MAX,
            };
            hub.attach_switch(pin, axis, pressed, true)?;
        }
        homing.push(config);
    }
    Ok(homing)
}

/// The worker: every line to the path, in order, until the end, an M2,
/// an error, or a cancel.
fn feed(mut path: GcodePath, lines: &[String], feeding: &Mutex<Feeding>) {
    for (index, text) in lines.iter().enumerate() {
        let line_no = u32::try_from(index + 1).unwrap_or(u32::MAX);
        if lock(feeding).stopped {
            break;
        }
        let outcome = path.run_line(line_no, text);
        let mut state = lock(feeding);
        // A G28 puts the axes on a new path.
        state.control = path.job().control();
        match outcome {
            Ok(LineOutcome::Ended) => {
                state.fed_line = line_no;
                break;
            }
            Ok(LineOutcome::Queued | LineOutcome::Paused) => state.fed_line = line_no,
            Err(error) => {
                // A cancel or an emergency stop refuses the line being fed:
                // that is no error of the program.
                let by_the_person = matches!(
                    error,
                    GcodePathError::Path {
                        error: PathError::Cancelled | PathError::Stopped(PathFault::EmergencyStop),
                        ..
                    }
                );
                if !(state.stopped && by_the_person) {
                    state.error = Some((line_no, error.to_string()));
                }
                break;
            }
        }
    }
    let mut state = lock(feeding);
    state.fed_all = true;
    state.path = Some(path);
}

impl ProgramBackend {
    /// Runs one command on the program's path.
    fn command(&self, command: PathCommand) -> Result<(), String> {
        let control = {
            let mut state = lock(&self.feeding);
            if matches!(command, PathCommand::Cancel | PathCommand::EmergencyStop) {
                // Before the path hears it: the worker feeds nothing more.
                state.stopped = true;
            }
            state.control.clone()
        };
        match command {
            PathCommand::Hold => control.hold(),
            PathCommand::Resume => control.resume().map_err(|e| e.to_string())?,
            PathCommand::Cancel => control.cancel(),
            PathCommand::EmergencyStop => control.emergency_stop(),
            PathCommand::FeedOverride(percent) => {
                let rapid = control.progress().overrides.1;
                control
                    .set_overrides(percent, rapid)
                    .map_err(|e| e.to_string())?;
            }
        }
        Ok(())
    }
}

impl Machine for ProgramBackend {
    fn info(&self) -> &MachineInfo {
        &self.info
    }

    fn axis(&self, index: usize) -> Option<&dyn AxisContract> {
        self.axes.get(index).map(|axis| axis as &dyn AxisContract)
    }

    fn figures(&self, _index: usize) -> MoveFigures {
        MoveFigures::default()
    }

    fn emergency_stop_all(&self) -> Result<(), AxisError> {
        self.command(PathCommand::EmergencyStop)
            .map_err(|_| AxisError::Fault("the emergency stop failed"))
    }

    fn fault(&self) -> Option<String> {
        None
    }

    fn check_move(&self, _speed: u32, _steps: i32) -> Result<(), String> {
        Err("the G-code program drives the axes".to_string())
    }

    fn path_command(&self, command: PathCommand) -> Result<(), String> {
        self.command(command)
    }

    fn path_reading(&self) -> Option<PathReading> {
        let state = lock(&self.feeding);
        Some(PathReading {
            progress: state.control.progress(),
            fed_line: state.fed_line,
            fed_all: state.fed_all,
            stopped: state.stopped,
            error: state.error.clone(),
        })
    }
}

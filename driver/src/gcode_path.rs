//! G-code on a hub: a program's lines interpreted ([`cogstep_gcode`]) and
//! run on a look-ahead path ([`PathJob`]).
//!
//! [`GcodePath::run_line`] interprets one line and queues its moves (a
//! line either queues all of its blocks or is refused whole, with nothing
//! queued); [`GcodePath::run_program`] runs a whole text and stops at the
//! first error, with nothing queued after it. A G28 waits for the path to
//! end, homes each named axis with its [`HomeConfig`] (given with
//! [`GcodePath::with_homing`]; without one it is refused), and starts a new
//! path from where the axes are. M0 holds the path once the moves before
//! it are made ([`PathJob::resume`] goes on); M2/M30 end the program.

use cogstep_gcode::{AxisSpec, Block, GcodeError, HomeEnd, Interpreter, MachineSpec};
use cogstep_hub::{Axis, Hub, PathError, PathJob, PathMachine, PathProgress};
use cogstep_motion::axis::Direction;
use cogstep_motion::axis::{AxisError, HomeConfig};
use cogstep_motion::planner::MAX_AXES;

/// Why a G-code line was not run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum GcodePathError {
    /// The line is not G-code this interpreter takes (line and column).
    #[error(transparent)]
    Gcode(#[from] GcodeError),
    /// The path refused a move of the line (`line` is its G-code line).
    #[error("line {line}: {error}")]
    Path {
        /// The G-code line.
        line: u32,
        /// The path's refusal.
        error: PathError,
    },
    /// G28 for an axis without a homing configuration, or homing failed.
    #[error("line {line}: homing axis {axis}: {error}")]
    Home {
        /// The G-code line.
        line: u32,
        /// The axis (its index in the machine file).
        axis: usize,
        /// What went wrong.
        error: AxisError,
    },
    /// The axes given are not one per axis of the machine file.
    #[error("the machine file has {0} axes")]
    AxisCount(usize),
}

/// What a line did, beyond queueing moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineOutcome {
    /// Its moves (if any) are queued.
    Queued,
    /// M0: the path holds once the moves before it are made.
    Paused,
    /// M2 or M30: the program ended.
    Ended,
}

/// How G28 homes an axis of the machine file onto an active-high switch
/// on `switch_pin`: towards its `home` end at `home_speed_mm_s` (a tenth
/// of its top speed without one), latching at a tenth of that after
/// backing off 1 mm; each pass looks over the soft range plus 10 mm (1 m
/// without soft limits); the switch point becomes the home position
/// ([`AxisSpec::home_position_mm`]). `None` for an axis without a home
/// switch.
pub fn home_config(axis: &AxisSpec, switch_pin: u8) -> Option<HomeConfig> {
    let end = axis.home?;
    let home_mm = axis.home_position_mm()?;
    let steps = |mm: f64| (mm * axis.steps_per_mm).round();
    let seek_mm_s = axis
        .home_speed_mm_s
        .unwrap_or(axis.max_speed_mm_s / 10.0)
        .min(axis.max_speed_mm_s);
    let seek = steps(seek_mm_s).clamp(1.0, f64::from(u32::MAX));
    let range_mm = match (axis.soft_min_mm, axis.soft_max_mm) {
        (Some(min), Some(max)) => max - min + 10.0,
        _ => 1_000.0,
    };
    let max_travel = steps(range_mm).clamp(2.0, f64::from(i32::MAX)) as u32;
    Some(HomeConfig {
        switch_pin,
        active_level: true,
        direction: match end {
            HomeEnd::Min => Direction::Reverse,
            HomeEnd::Max => Direction::Forward,
        },
        seek_speed: seek as u32,
        latch_speed: (seek / 10.0).max(1.0) as u32,
        backoff_steps: (steps(1.0) as u32).clamp(1, max_travel - 1),
        max_travel,
        set_position: steps(home_mm) as i64,
    })
}

/// A G-code program running on a hub's axes (see the module docs).
pub struct GcodePath {
    hub: Hub,
    axes: Vec<Axis>,
    spec: MachineSpec,
    interpreter: Interpreter,
    job: Option<PathJob>,
    homing: Vec<Option<HomeConfig>>,
}

impl GcodePath {
    /// Puts `axes` (one per axis of `spec`, in its order) on a path for
    /// `spec`'s limits. The interpreter starts where the axes are.
    pub fn new(hub: &Hub, axes: &[&Axis], spec: &MachineSpec) -> Result<Self, GcodePathError> {
        if axes.len() != spec.axis_count() {
            return Err(GcodePathError::AxisCount(spec.axis_count()));
        }
        let mut interpreter = Interpreter::new(spec);
        let mut positions = [0i64; MAX_AXES];
        for (position, axis) in positions.iter_mut().zip(axes) {
            *position = axis.position();
        }
        interpreter.set_position_steps(positions);
        let mut path = GcodePath {
            hub: hub.clone(),
            axes: axes.iter().map(|axis| (*axis).clone()).collect(),
            spec: *spec,
            interpreter,
            job: None,
            homing: vec![None; axes.len()],
        };
        path.start_job(0)?;
        Ok(path)
    }

    /// How each axis homes for G28 (`None`: it does not).
    pub fn with_homing(mut self, homing: Vec<Option<HomeConfig>>) -> Self {
        self.homing = homing;
        self.homing.resize(self.axes.len(), None);
        self
    }

    /// The machine's limits as a path's, in steps.
    pub fn path_machine(spec: &MachineSpec) -> PathMachine {
        let machine = spec.planner_machine::<MAX_AXES>();
        let count = spec.axis_count();
        PathMachine {
            max_speed_steps_per_s: machine.max_speed_steps_per_s[..count].to_vec(),
            max_accel_steps_per_s2: machine.max_accel_steps_per_s2[..count].to_vec(),
            junction_deviation_steps: machine.junction_deviation_steps,
            blending: machine.blending,
        }
    }

    fn start_job(&mut self, line: u32) -> Result<(), GcodePathError> {
        let axes: Vec<&Axis> = self.axes.iter().collect();
        let job = self
            .hub
            .path(&axes, Self::path_machine(&self.spec))
            .map_err(|error| GcodePathError::Path { line, error })?;
        job.set_blending(self.interpreter.blending());
        self.job = Some(job);
        Ok(())
    }

    /// The path the moves run on.
    pub fn job(&self) -> &PathJob {
        self.job.as_ref().expect("a path between lines")
    }

    /// The interpreter (its modal state and position).
    pub fn interpreter(&self) -> &Interpreter {
        &self.interpreter
    }

    /// Interprets G-code line `line_no` and queues its moves, blocking
    /// while the path's queue is full. Refused whole (nothing queued, the
    /// interpreter unchanged) when the line is not valid G-code. A cancel
    /// ([`cogstep_hub::PathControl::cancel`]) while it queues refuses the
    /// rest of the line ([`PathError::Cancelled`]).
    pub fn run_line(&mut self, line_no: u32, text: &str) -> Result<LineOutcome, GcodePathError> {
        let mut blocks = Vec::new();
        self.interpreter
            .interpret_line(line_no, text, &mut |block| blocks.push(block))?;
        let mut outcome = LineOutcome::Queued;
        // A cancel while the line is queued drops its blocks queued so far
        // and refuses the rest.
        let cancels = self.job().cancels();
        for block in blocks {
            match block {
                Block::Line { line, .. } => {
                    let Some(planned) = block.to_planner_line::<MAX_AXES>() else {
                        continue;
                    };
                    let count = self.axes.len();
                    self.job()
                        .push_unless_cancelled(
                            &planned.steps[..count],
                            planned.feed_steps_per_s,
                            line,
                            cancels,
                        )
                        .map_err(|error| GcodePathError::Path { line, error })?;
                }
                Block::Dwell { line, seconds } => self
                    .job()
                    .dwell(seconds)
                    .map_err(|error| GcodePathError::Path { line, error })?,
                Block::Blending { mode, .. } => self.job().set_blending(mode),
                Block::Home { line, axes } => self.home(line, axes)?,
                Block::Pause { line } => {
                    let job = self.job();
                    job.wait()
                        .map_err(|error| GcodePathError::Path { line, error })?;
                    job.hold();
                    outcome = LineOutcome::Paused;
                }
                Block::End { .. } => outcome = LineOutcome::Ended,
            }
        }
        Ok(outcome)
    }

    /// Runs every line of `text` (numbered from 1) until M2/M30 or the end,
    /// then waits for the path to finish; stops at the first error, with
    /// nothing of that line or after it queued.
    pub fn run_program(&mut self, text: &str) -> Result<PathProgress, GcodePathError> {
        for (index, line) in text.lines().enumerate() {
            let line_no = u32::try_from(index + 1).unwrap_or(u32::MAX);
            match self.run_line(line_no, line)? {
                LineOutcome::Ended => break,
                LineOutcome::Paused => {
                    // A program run whole goes on after a pause at once.
                    let _ = self.job().resume();
                }
                LineOutcome::Queued => {}
            }
        }
        self.job()
            .wait()
            .map_err(|error| GcodePathError::Path { line: 0, error })
    }

    /// G28: the path ends, each named axis homes, a new path starts.
    fn home(&mut self, line: u32, axes: u8) -> Result<(), GcodePathError> {
        if let Some(job) = self.job.take() {
            job.finish()
                .map_err(|error| GcodePathError::Path { line, error })?;
        }
        let mut outcome = Ok(());
        for index in (0..self.axes.len()).filter(|index| axes & (1 << index) != 0) {
            let Some(config) = self.homing[index] else {
                outcome = Err(GcodePathError::Home {
                    line,
                    axis: index,
                    error: AxisError::Unsupported("no homing configured for this axis"),
                });
                break;
            };
            let axis = &self.axes[index];
            let homed = axis.home(config).and_then(|()| {
                self.hub.run_until_idle();
                while axis.is_homing() {
                    std::thread::sleep(std::time::Duration::from_millis(1));
                }
                axis.home_outcome()
                    .unwrap_or(Err(AxisError::HomingAborted))
                    .map(|_| ())
            });
            if let Err(error) = homed {
                outcome = Err(GcodePathError::Home {
                    line,
                    axis: index,
                    error,
                });
                break;
            }
        }
        let mut positions = [0i64; MAX_AXES];
        for (position, axis) in positions.iter_mut().zip(&self.axes) {
            *position = axis.position();
        }
        self.interpreter.set_position_steps(positions);
        self.start_job(line)?;
        outcome
    }

    /// Waits for everything queued, then lets the axes go.
    pub fn finish(mut self) -> Result<PathProgress, PathError> {
        match self.job.take() {
            Some(job) => job.finish(),
            None => Err(PathError::NotHeld),
        }
    }
}

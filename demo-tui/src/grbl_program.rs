//! `--gcode FILE --serial PORT --dialect grbl`: a G-code program streamed
//! to a grbl board, as a [`Machine`].
//!
//! The board plans (grbl's look-ahead, cogstep's on a cogstep board); the
//! demo streams the file by character counting
//! ([`SerialBoard::stream_gcode`]) and reads the board's status reports:
//! MPos, its state and feed. Before a byte is sent the whole file is
//! checked against the machine the board's `$$` describes
//! ([`machine_from_settings`]): steps/mm, top speeds and accelerations,
//! soft limits when `$20=1`, junction deviation and arc tolerance.
//!
//! ```text
//! app thread: PathCommand ─► GcodeStream (hold !, resume ~, cancel, overrides 0x90-0x92) / soft reset
//! link thread: lines ─► board (≤ 128 bytes in flight) · ok / error:N · <status reports>
//! frame: GcodeStream::progress + SerialBoard::grbl_status ─► PathReading
//! ```
//!
//! The line running is not in a grbl report: it is the first line, from
//! the last one found running up to the last one the board answered,
//! whose programmed XY segment passes within a step and a half of MPos.

use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard};

use driver::gcode::{AxisSpec, MachineSpec, PlannerSpec};
use driver::planner::PathState;
use driver::serial::grbl::{without_idle_words, GrblRealtime};
use driver::serial::host::{
    prepare_line, GcodeStream, SerialAxis, SerialBoard, StreamError, StreamState,
};
use driver::{AxisContract, AxisError, PathFault, PathProgress};

use crate::backend::{Capabilities, Machine, MachineInfo, MoveFigures};
use crate::program::{read_text, PathCommand, PathReading, Program, ProgramError};

/// grbl's axes, in order.
const LETTERS: [char; 3] = ['x', 'y', 'z'];
/// The look-ahead the board's check uses (grbl's planner holds 16 blocks).
const QUEUE_LEN: usize = 16;
/// How far from its programmed segment MPos may be for that line to be
/// the one running, in steps.
const ON_SEGMENT_STEPS: f64 = 1.5;

/// The machine a grbl board's `$$` describes: X, Y and Z with `$100`…
/// steps/mm, `$110`… mm/min (as mm/s) and `$120`… mm/s²; soft limits
/// from `$130`… when `$20=1` (grbl 1.1's machine space, whatever the
/// homing directions: `[-travel, 0]`); junction
/// deviation `$11` and arc tolerance `$12`. Errors name what is missing
/// or unusable.
pub fn machine_from_settings(settings: &[(u16, f64)]) -> Result<MachineSpec, String> {
    let get = |number: u16| {
        settings
            .iter()
            .find(|(n, _)| *n == number)
            .map(|&(_, value)| value)
            .ok_or_else(|| format!("the board's $$ has no ${number}"))
    };
    let soft_limits = get(20).unwrap_or(0.0) != 0.0;
    let mut axes = Vec::new();
    for (index, letter) in LETTERS.into_iter().enumerate() {
        let offset = index as u16;
        let mut axis = AxisSpec::new(
            letter,
            get(100 + offset)?,
            get(110 + offset)? / 60.0,
            get(120 + offset)?,
        );
        if soft_limits {
            let travel = get(130 + offset)?;
            (axis.soft_min_mm, axis.soft_max_mm) = (Some(-travel), Some(0.0));
        }
        axes.push(axis);
    }
    let planner = PlannerSpec {
        junction_deviation_mm: get(11)?,
        arc_tolerance_mm: get(12)?,
        queue_len: QUEUE_LEN,
    };
    MachineSpec::new(&axes, planner).map_err(|error| format!("the board's $$: {error}"))
}

/// Reads `gcode` and checks it whole for the machine of a grbl board
/// (`spec`, from its `$$`), as the board will read it: a line with words
/// grbl accepts and drives nothing with here (S, T, M3–M5, M7–M9, G54,
/// G94) is checked without them, as the board's interpreter reads it
/// (its columns are then those of the line without comments and blanks);
/// every other line as it is. The program's lines are the file's.
pub fn load_for_grbl(
    gcode: &Path,
    machine_name: &str,
    spec: MachineSpec,
) -> Result<Program, ProgramError> {
    let text = read_text(gcode)?;
    let checked: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(index, line)| {
            let Ok(Some(prepared)) = prepare_line(index + 1, line) else {
                return line.to_string();
            };
            let upper = prepared.to_ascii_uppercase();
            let kept = without_idle_words(&upper);
            if kept.as_str() == upper {
                line.to_string()
            } else {
                kept.to_string()
            }
        })
        .collect();
    let mut program = Program::from_text(
        &gcode.display().to_string(),
        machine_name,
        spec,
        &checked.join("\n"),
    )?;
    program.lines = text.lines().map(str::to_string).collect();
    Ok(program)
}

/// What the app thread's commands leave for the frames to read.
#[derive(Debug, Default)]
struct Tracking {
    /// The line found running (from 1; 0 before the first).
    running: usize,
    /// The feed override asked for, percent.
    feed_percent: u32,
    /// Cancelled or emergency-stopped by the demo.
    stopped: bool,
    /// Emergency-stopped by the demo.
    emergency: bool,
}

/// A program streaming to a grbl board.
pub struct GrblProgram {
    board: SerialBoard,
    axes: Vec<SerialAxis>,
    info: MachineInfo,
    stream: GcodeStream,
    program: Arc<Program>,
    tracking: Mutex<Tracking>,
}

fn lock(tracking: &Mutex<Tracking>) -> MutexGuard<'_, Tracking> {
    tracking
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl GrblProgram {
    /// Starts streaming `program` (checked already) to `board`.
    pub fn start(board: SerialBoard, program: Program) -> Result<Self, StreamError> {
        let stream = board.stream_gcode(&program.lines)?;
        let axes: Vec<SerialAxis> = (0..board.axis_count())
            .map_while(|index| board.axis(index))
            .collect();
        let port = board.config().port.clone();
        let info = MachineInfo {
            title: format!(
                "G-code {} · grbl board on {port} · character counting",
                program.name
            ),
            clkfreq_hz: board.clkfreq(),
            capabilities: Capabilities::all(),
            max_speed: None,
            axis_kinds: vec!["grbl".to_string(); axes.len()],
            axis_pins: LETTERS
                .iter()
                .take(axes.len())
                .map(|letter| format!("board axis {}", letter.to_ascii_uppercase()))
                .collect(),
            jog_timeout: None,
        };
        Ok(GrblProgram {
            board,
            axes,
            info,
            stream,
            program: Arc::new(program),
            tracking: Mutex::new(Tracking {
                feed_percent: 100,
                ..Tracking::default()
            }),
        })
    }

    /// The feed override to `percent`: a reset to 100 %, then ±10 % bytes.
    fn feed_override(&self, percent: u32) -> Result<(), AxisError> {
        self.board.grbl_realtime(GrblRealtime::FeedReset)?;
        let (byte, steps) = if percent >= 100 {
            (GrblRealtime::FeedPlus10, (percent - 100) / 10)
        } else {
            (GrblRealtime::FeedMinus10, (100 - percent) / 10)
        };
        for _ in 0..steps {
            self.board.grbl_realtime(byte)?;
        }
        lock(&self.tracking).feed_percent = percent;
        Ok(())
    }

    /// The line running: see the module's docs.
    fn running_line(&self, answered: usize, mpos_mm: [f64; 3]) -> usize {
        let mut tracking = lock(&self.tracking);
        let program = &self.program;
        let [x, y] = program.view_axes;
        let point = [x, y].map(|axis| axis.map_or(0.0, |a| mpos_mm.get(a).copied().unwrap_or(0.0)));
        let tolerance = [x, y]
            .iter()
            .flatten()
            .map(|&axis| ON_SEGMENT_STEPS / program.spec.axes()[axis].steps_per_mm)
            .fold(0.0, f64::max);
        let from = tracking.running.max(1);
        // Segments are in line order: start at the line found last, not
        // at the program's start, every frame.
        let first = program
            .segments
            .partition_point(|segment| (segment.line as usize) < from);
        let found = program.segments[first..]
            .iter()
            .take_while(|segment| segment.line as usize <= answered)
            .find(|segment| distance(point, segment.from_mm, segment.to_mm) <= tolerance)
            .map(|segment| segment.line as usize);
        if let Some(line) = found {
            tracking.running = line;
        } else if tracking.running == 0 && answered > 0 {
            tracking.running = 1;
        }
        tracking.running
    }
}

/// The distance from `point` to the segment `from`–`to`.
fn distance(point: [f64; 2], from: [f64; 2], to: [f64; 2]) -> f64 {
    let along = [to[0] - from[0], to[1] - from[1]];
    let rel = [point[0] - from[0], point[1] - from[1]];
    let length2 = along[0] * along[0] + along[1] * along[1];
    let t = if length2 > 0.0 {
        ((rel[0] * along[0] + rel[1] * along[1]) / length2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let closest = [from[0] + t * along[0], from[1] + t * along[1]];
    ((point[0] - closest[0]).powi(2) + (point[1] - closest[1]).powi(2)).sqrt()
}

impl Machine for GrblProgram {
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
        {
            let mut tracking = lock(&self.tracking);
            tracking.stopped = true;
            tracking.emergency = true;
        }
        self.board.emergency_stop_all()
    }

    fn fault(&self) -> Option<String> {
        self.board.fault()
    }

    fn check_move(&self, _speed: u32, _steps: i32) -> Result<(), String> {
        Err("the G-code program drives the axes".to_string())
    }

    fn path_command(&self, command: PathCommand) -> Result<(), String> {
        let result = match command {
            PathCommand::Hold => self.stream.hold(),
            PathCommand::Resume => self.stream.resume(),
            PathCommand::Cancel => {
                lock(&self.tracking).stopped = true;
                self.stream.cancel()
            }
            PathCommand::EmergencyStop => self.emergency_stop_all(),
            PathCommand::FeedOverride(percent) => self.feed_override(percent),
        };
        result.map_err(|error| error.to_string())
    }

    fn path_reading(&self) -> Option<PathReading> {
        let progress = self.stream.progress();
        let status = self.board.grbl_status();
        let (machine, feed_mm_min, mpos) = status
            .map_or(("Idle".to_string(), 0.0, [0.0; 3]), |s| {
                (s.state, s.feed_mm_min, s.mpos_mm)
            });
        let running = self.running_line(progress.answered, mpos);
        let tracking = lock(&self.tracking);
        let state = match machine.as_str() {
            "Hold:1" => PathState::Holding,
            "Hold:0" => PathState::Held,
            "Run" | "Jog" | "Home" => PathState::Running,
            _ => PathState::Idle,
        };
        let at = running.max(1) as u32;
        let (fault, error) = match &progress.state {
            StreamState::Streaming | StreamState::Done | StreamState::Cancelled => (None, None),
            StreamState::Reset if tracking.emergency => (Some(PathFault::EmergencyStop), None),
            StreamState::Reset => (None, Some((at, "the board reset".to_string()))),
            StreamState::Error { line, code } => (
                None,
                Some((
                    u32::try_from(*line).unwrap_or(u32::MAX),
                    format!("line {line}: the board answered error:{code}"),
                )),
            ),
            StreamState::Alarm(code) => {
                (None, Some((at, format!("the board raised ALARM:{code}"))))
            }
            StreamState::Lost => (None, Some((at, "the board was lost".to_string()))),
        };
        let mm_per_step = running
            .checked_sub(1)
            .and_then(|index| self.program.line_costs.get(index))
            .map_or(0.0, |cost| cost.mm_per_step);
        let speed_steps_per_s = if mm_per_step > 0.0 && state != PathState::Idle {
            feed_mm_min / 60.0 / mm_per_step
        } else {
            0.0
        };
        let finished = progress.state == StreamState::Done;
        let done = if finished {
            progress.lines
        } else {
            running.saturating_sub(1)
        };
        Some(PathReading {
            progress: PathProgress {
                state,
                tag: u32::try_from(running).unwrap_or(u32::MAX),
                done: done as u64,
                queued: progress.answered.saturating_sub(done),
                speed_steps_per_s,
                overrides: (tracking.feed_percent, 100),
                fault,
            },
            fed_line: u32::try_from(progress.answered).unwrap_or(u32::MAX),
            fed_all: finished,
            stopped: tracking.stopped,
            error,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(extra: &[(u16, f64)]) -> Vec<(u16, f64)> {
        let mut settings = vec![
            (11, 0.01),
            (12, 0.002),
            (20, 0.0),
            (23, 0.0),
            (100, 250.0),
            (101, 80.0),
            (102, 400.0),
            (110, 6000.0),
            (111, 3000.0),
            (112, 600.0),
            (120, 500.0),
            (121, 200.0),
            (122, 50.0),
            (130, 300.0),
            (131, 200.0),
            (132, 50.0),
        ];
        for &(number, value) in extra {
            settings.retain(|&(n, _)| n != number);
            settings.push((number, value));
        }
        settings
    }

    #[test]
    fn the_boards_settings_make_the_machine_the_file_is_checked_against() {
        let spec = machine_from_settings(&settings(&[])).expect("a machine");
        assert_eq!(spec.letters(), ['x', 'y', 'z']);
        let y = spec.axes()[1];
        assert_eq!(
            (y.steps_per_mm, y.max_speed_mm_s, y.max_accel_mm_s2),
            (80.0, 50.0, 200.0)
        );
        assert_eq!((y.soft_min_mm, y.soft_max_mm), (None, None));
        // Soft limits on: grbl 1.1's machine space, below 0 whatever $23.
        let spec = machine_from_settings(&settings(&[(20, 1.0), (23, 2.0)])).expect("a machine");
        assert_eq!(
            spec.axes()
                .iter()
                .map(|a| (a.soft_min_mm, a.soft_max_mm))
                .collect::<Vec<_>>(),
            [
                (Some(-300.0), Some(0.0)),
                (Some(-200.0), Some(0.0)),
                (Some(-50.0), Some(0.0))
            ]
        );
        let mut missing = settings(&[]);
        missing.retain(|&(n, _)| n != 121);
        assert_eq!(
            machine_from_settings(&missing),
            Err("the board's $$ has no $121".to_string())
        );
        assert!(machine_from_settings(&settings(&[(100, 0.0)])).is_err());
    }

    #[test]
    fn the_distance_to_a_segment_is_to_its_nearest_point() {
        assert_eq!(distance([1.0, 1.0], [0.0, 0.0], [2.0, 0.0]), 1.0);
        assert_eq!(distance([3.0, 0.0], [0.0, 0.0], [2.0, 0.0]), 1.0);
        assert_eq!(distance([0.0, 2.0], [0.0, 0.0], [0.0, 0.0]), 2.0);
    }
}

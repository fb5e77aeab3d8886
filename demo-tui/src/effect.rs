//! The app's effects on the backend, and what comes back: the only app
//! code that calls a [`Machine`].
//!
//! The update ([`crate::app`]) never touches the backend. A key gives a
//! list of [`Effect`]s; the app thread ([`crate::event_loop`]) ends the
//! demo on [`Effect::Quit`] and hands every [`Command`] to [`run`], which
//! makes the backend calls (they may block on a slow board) and says what
//! came of them as an [`Outcome`], fed back to [`crate::app::App::on_outcome`]:
//!
//! ```text
//! key ─► App::on_key ─► [Effect] ─► run(Command, Machine) ─► Outcome ─► App::on_outcome
//! frame tick ─► read_frame(Machine) ─► FrameReading ─► App::on_frame
//! ```
//!
//! The checks that need nothing but the app's own state (the prompt's
//! answers, what the backend says it can do) stay in the update; what
//! needs the backend (its move check, an axis's stop pin, its home switch)
//! is done here, in the order the backend needs it.

use driver::{AxisContract, AxisStatus, Direction, Edge, HomeConfig, LimitStatus};

use crate::backend::{Machine, MoveFigures};
use crate::program::{PathCommand, PathReading};

/// What the update asks for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Effect {
    /// A command to the backend, run by [`run`].
    Send(Command),
    /// End the demo (`q`, Ctrl-C).
    Quit,
}

/// One thing to do to the backend. Axes are by index, from 0.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Command {
    /// `move(speed, steps)` on one axis: the backend's check first, and a
    /// stop pin the stop key left low raised again.
    Move {
        /// The axis.
        axis: usize,
        /// Steps, signed.
        steps: i32,
        /// Speed, steps/s.
        speed: u32,
    },
    /// `g`: a coordinated move of axes 0 to `steps.len() − 1`
    /// ([`Machine::move_together`]), their low stop pins raised first.
    MoveTogether {
        /// Steps per axis, signed, axis 0 first.
        steps: Vec<i32>,
        /// Speed of the longest, steps/s.
        speed: u32,
    },
    /// `s`: the axis's stop pin low (a controlled deceleration).
    Stop {
        /// The axis.
        axis: usize,
    },
    /// `x`: emergency stop of every axis.
    EmergencyStop,
    /// A jog heartbeat (a jog key pressed or repeating): starts or
    /// continues a jog, a low stop pin raised first.
    JogBeat {
        /// The axis.
        axis: usize,
        /// Which way.
        direction: Direction,
        /// Speed, steps/s.
        speed: u32,
    },
    /// The jog key released: the jog decelerates now.
    JogRelease {
        /// The axis.
        axis: usize,
    },
    /// `h`: home the axis on its home switch, a low stop pin raised first.
    Home {
        /// The axis.
        axis: usize,
    },
    /// `c`: clear the axis's tripped hard limit.
    ClearLimit {
        /// The axis.
        axis: usize,
    },
    /// `--gcode`: to the program's path (hold, resume, cancel, ...).
    Path(PathCommand),
}

/// What running a [`Command`] came to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Outcome {
    /// The command run.
    pub command: Command,
    /// Taken, or why not.
    pub result: Result<Done, Refusal>,
}

/// A command taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Done {
    /// Sent and taken.
    Sent {
        /// Whether a low stop pin (any, for a group) was raised first.
        stop_pin_raised: bool,
    },
    /// [`Command::Home`] taken: homing runs with this configuration.
    Homing(HomeConfig),
}

/// A command not taken. Nothing after the step that refused was sent.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// The backend has no such axis: nothing was sent.
    NoSuchAxis,
    /// The backend has no home switch for the axis: nothing was sent.
    NoHomeSwitch,
    /// The backend's check: no such move can be planned. Nothing was sent.
    Unplannable(String),
    /// A low stop pin could not be raised first.
    StopPin {
        /// The axis whose pin it was.
        axis: usize,
        /// Why.
        reason: String,
    },
    /// The axis or the backend refused the command itself.
    Refused(String),
}

/// Runs one command against the backend (this may block on a slow board).
pub fn run(command: Command, machine: &dyn Machine) -> Outcome {
    let result = match &command {
        Command::Move { axis, steps, speed } => send_move(machine, *axis, *steps, *speed),
        Command::MoveTogether { steps, speed } => send_group(machine, steps, *speed),
        Command::Stop { axis } => with_axis(machine, *axis, |axis| axis.set_stop_pin(false)),
        Command::EmergencyStop => machine
            .emergency_stop_all()
            .map(|()| Done::Sent {
                stop_pin_raised: false,
            })
            .map_err(|e| Refusal::Refused(e.to_string())),
        Command::JogBeat {
            axis,
            direction,
            speed,
        } => with_raised_pin(machine, *axis, |handle| handle.jog(*speed, *direction)),
        // The axis gone, there is nothing left to release.
        Command::JogRelease { axis } => match machine.axis(*axis) {
            Some(handle) => handle
                .jog_release()
                .map(|()| Done::Sent {
                    stop_pin_raised: false,
                })
                .map_err(|e| Refusal::Refused(e.to_string())),
            None => Ok(Done::Sent {
                stop_pin_raised: false,
            }),
        },
        Command::Home { axis } => home(machine, *axis),
        Command::ClearLimit { axis } => {
            with_axis(machine, *axis, |handle| handle.clear_limit_fault())
        }
        Command::Path(path_command) => machine
            .path_command(*path_command)
            .map(|()| Done::Sent {
                stop_pin_raised: false,
            })
            .map_err(Refusal::Refused),
    };
    Outcome { command, result }
}

/// One call on one axis, which must exist.
fn with_axis(
    machine: &dyn Machine,
    axis: usize,
    call: impl FnOnce(&dyn AxisContract) -> Result<(), driver::AxisError>,
) -> Result<Done, Refusal> {
    let handle = machine.axis(axis).ok_or(Refusal::NoSuchAxis)?;
    call(handle)
        .map(|()| Done::Sent {
            stop_pin_raised: false,
        })
        .map_err(|e| Refusal::Refused(e.to_string()))
}

/// One call on one axis after raising its stop pin if it is low.
fn with_raised_pin(
    machine: &dyn Machine,
    axis: usize,
    call: impl FnOnce(&dyn AxisContract) -> Result<(), driver::AxisError>,
) -> Result<Done, Refusal> {
    let handle = machine.axis(axis).ok_or(Refusal::NoSuchAxis)?;
    let stop_pin_raised =
        raise_stop_pin(handle).map_err(|reason| Refusal::StopPin { axis, reason })?;
    call(handle)
        .map(|()| Done::Sent { stop_pin_raised })
        .map_err(|e| Refusal::Refused(e.to_string()))
}

fn send_move(machine: &dyn Machine, axis: usize, steps: i32, speed: u32) -> Result<Done, Refusal> {
    machine
        .check_move(speed, steps)
        .map_err(Refusal::Unplannable)?;
    let handle = machine.axis(axis).ok_or(Refusal::NoSuchAxis)?;
    // The stop key left the pin low: this move raises it again (where the
    // backend drives the stop pin at all).
    let stop_pin_raised = match machine.info().capabilities.stop_pin {
        Some(_) => false,
        None => raise_stop_pin(handle).map_err(|reason| Refusal::StopPin { axis, reason })?,
    };
    handle
        .move_steps(speed, steps)
        .map(|()| Done::Sent { stop_pin_raised })
        .map_err(|e| Refusal::Refused(e.to_string()))
}

fn send_group(machine: &dyn Machine, steps: &[i32], speed: u32) -> Result<Done, Refusal> {
    // The backend checks the longest member; the others follow its line.
    let lead = steps
        .iter()
        .copied()
        .max_by_key(|steps| steps.unsigned_abs())
        .unwrap_or(0);
    machine
        .check_move(speed, lead)
        .map_err(Refusal::Unplannable)?;
    let mut stop_pin_raised = false;
    if machine.info().capabilities.stop_pin.is_none() {
        // A stop key left a pin low: the group move raises it (every
        // member's pin must be high for the move to be taken).
        for axis in 0..steps.len() {
            let Some(handle) = machine.axis(axis) else {
                continue;
            };
            stop_pin_raised |=
                raise_stop_pin(handle).map_err(|reason| Refusal::StopPin { axis, reason })?;
        }
    }
    machine
        .move_together(steps, speed)
        .map(|()| Done::Sent { stop_pin_raised })
        .map_err(|e| Refusal::Refused(e.to_string()))
}

fn home(machine: &dyn Machine, axis: usize) -> Result<Done, Refusal> {
    let (Some(handle), Some(config)) = (machine.axis(axis), machine.home_config(axis)) else {
        return Err(Refusal::NoHomeSwitch);
    };
    raise_stop_pin(handle).map_err(|reason| Refusal::StopPin { axis, reason })?;
    handle
        .home(config)
        .map(|()| Done::Homing(config))
        .map_err(|e| Refusal::Refused(e.to_string()))
}

/// Raises an axis's stop pin if it is low; tells whether it was.
fn raise_stop_pin(axis: &dyn AxisContract) -> Result<bool, String> {
    let status = axis.status().map_err(|e| e.to_string())?;
    if status.stop_pin_high {
        return Ok(false);
    }
    axis.set_stop_pin(true)
        .map(|()| true)
        .map_err(|e| format!("could not raise the stop pin: {e}"))
}

/// What an axis showed at a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Readout {
    /// Position, STM, mode, velocity and stop pin.
    pub status: AxisStatus,
    /// The reference demo's move figures.
    pub figures: MoveFigures,
}

/// One axis's limit and homing state and its switches (home, min, max),
/// where the backend reads them.
pub type LimitReading = (Option<LimitStatus>, Option<[bool; 3]>);

/// Everything a frame reads from the backend.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FrameReading {
    /// Per axis: its readout, or why it could not be read.
    pub readouts: Vec<Result<Readout, String>>,
    /// The backend's fault, if any.
    pub fault: Option<String>,
    /// Per axis: its limits and switches.
    pub limits: Vec<LimitReading>,
    /// The pin edges since the last frame and the clock now (ticks), when
    /// asked for and recorded (`--motor`).
    pub edges: Option<(Vec<Edge>, u64)>,
    /// The G-code program's path, where one runs (`--gcode`).
    pub path: Option<PathReading>,
}

/// Reads a frame of `axis_count` axes; takes the recorded pin edges only
/// when `with_edges` (taking them empties the backend's record).
pub fn read_frame(machine: &dyn Machine, axis_count: usize, with_edges: bool) -> FrameReading {
    let readouts = (0..axis_count)
        .map(|index| match machine.axis(index) {
            Some(axis) => axis
                .status()
                .map(|status| Readout {
                    status,
                    figures: machine.figures(index),
                })
                .map_err(|e| e.to_string()),
            None => Err("no such axis on this backend".to_string()),
        })
        .collect();
    let edges = if with_edges {
        machine.take_edges()
    } else {
        None
    };
    let fault = machine.fault();
    let limits = (0..axis_count)
        .map(|index| (machine.limit_status(index), machine.switches(index)))
        .collect();
    FrameReading {
        readouts,
        fault,
        limits,
        edges,
        path: machine.path_reading(),
    }
}

#[cfg(test)]
mod tests {
    use std::cell::RefCell;
    use std::time::Instant;

    use driver::{AxisError, Mode};

    use super::*;
    use crate::app::App;
    use crate::backend::{Capabilities, MachineInfo};

    /// Records what is asked of each axis.
    struct FakeAxis {
        calls: RefCell<Vec<String>>,
        stop_pin_high: RefCell<bool>,
    }

    impl AxisContract for FakeAxis {
        fn move_steps(&self, speed: u32, steps: i32) -> Result<(), AxisError> {
            self.calls
                .borrow_mut()
                .push(format!("move {speed} {steps}"));
            Ok(())
        }
        fn jog(&self, speed: u32, direction: Direction) -> Result<(), AxisError> {
            self.calls
                .borrow_mut()
                .push(format!("jog {speed} {direction:?}"));
            Ok(())
        }
        fn jog_release(&self) -> Result<(), AxisError> {
            self.calls.borrow_mut().push("jog_release".into());
            Ok(())
        }
        fn set_stop_pin(&self, high: bool) -> Result<(), AxisError> {
            self.calls.borrow_mut().push(format!("stop_pin {high}"));
            *self.stop_pin_high.borrow_mut() = high;
            Ok(())
        }
        fn emergency_stop(&self) -> Result<(), AxisError> {
            self.calls.borrow_mut().push("estop".into());
            Ok(())
        }
        fn set_position(&self, _: i64) -> Result<(), AxisError> {
            Ok(())
        }
        fn status(&self) -> Result<AxisStatus, AxisError> {
            Ok(AxisStatus {
                position: 0,
                stm: 0,
                steps_to_go: 0,
                mode: Mode(0),
                velocity_steps_per_s: 0,
                stop_pin_high: *self.stop_pin_high.borrow(),
            })
        }
    }

    struct FakeMachine {
        info: MachineInfo,
        axes: Vec<FakeAxis>,
        estops: RefCell<usize>,
        groups: RefCell<Vec<(Vec<i32>, u32)>>,
        /// What `check_move` says of every move, if it refuses them.
        unplannable: Option<String>,
        edges_taken: RefCell<usize>,
    }

    fn fake(count: usize, capabilities: Capabilities) -> FakeMachine {
        FakeMachine {
            info: MachineInfo {
                title: "fake".into(),
                clkfreq_hz: 200_000_000,
                capabilities,
                max_speed: Some(199_600),
                axis_kinds: vec!["sd".into(); count],
                axis_pins: vec!["pins".into(); count],
                jog_timeout: None,
            },
            axes: (0..count)
                .map(|_| FakeAxis {
                    calls: RefCell::default(),
                    stop_pin_high: RefCell::new(true),
                })
                .collect(),
            estops: RefCell::new(0),
            groups: RefCell::new(Vec::new()),
            unplannable: None,
            edges_taken: RefCell::new(0),
        }
    }

    impl Machine for FakeMachine {
        fn info(&self) -> &MachineInfo {
            &self.info
        }
        fn axis(&self, index: usize) -> Option<&dyn AxisContract> {
            self.axes.get(index).map(|a| a as &dyn AxisContract)
        }
        fn figures(&self, _: usize) -> MoveFigures {
            MoveFigures::default()
        }
        fn emergency_stop_all(&self) -> Result<(), AxisError> {
            *self.estops.borrow_mut() += 1;
            Ok(())
        }
        fn fault(&self) -> Option<String> {
            Some("a fault".into())
        }
        fn check_move(&self, _: u32, _: i32) -> Result<(), String> {
            self.unplannable.clone().map_or(Ok(()), Err)
        }
        fn move_together(&self, steps: &[i32], speed: u32) -> Result<(), AxisError> {
            self.groups.borrow_mut().push((steps.to_vec(), speed));
            Ok(())
        }
        fn take_edges(&self) -> Option<(Vec<Edge>, u64)> {
            *self.edges_taken.borrow_mut() += 1;
            Some((Vec::new(), 7))
        }
    }

    fn calls(machine: &FakeMachine, axis: usize) -> Vec<String> {
        machine.axes[axis].calls.borrow().clone()
    }

    fn sent(stop_pin_raised: bool) -> Result<Done, Refusal> {
        Ok(Done::Sent { stop_pin_raised })
    }

    #[test]
    fn a_move_raises_a_low_stop_pin_first_where_the_backend_drives_it() {
        let machine = fake(2, Capabilities::all());
        let move_100 = Command::Move {
            axis: 0,
            steps: 100,
            speed: 1_000,
        };
        assert_eq!(run(Command::Stop { axis: 0 }, &machine).result, sent(false));
        assert_eq!(run(move_100.clone(), &machine).result, sent(true));
        assert_eq!(
            calls(&machine, 0),
            ["stop_pin false", "stop_pin true", "move 1000 100"]
        );
        assert_eq!(run(move_100.clone(), &machine).result, sent(false));
        // A backend without a stop pin of its own: never touched.
        let no_pin = fake(
            1,
            Capabilities {
                stop_pin: Some("no".into()),
                ..Capabilities::all()
            },
        );
        *no_pin.axes[0].stop_pin_high.borrow_mut() = false;
        assert_eq!(run(move_100, &no_pin).result, sent(false));
        assert_eq!(calls(&no_pin, 0), ["move 1000 100"]);
    }

    #[test]
    fn what_the_backend_refuses_sends_nothing_after_it() {
        let mut machine = fake(1, Capabilities::all());
        machine.unplannable = Some("too short for its speed".into());
        let outcome = run(
            Command::Move {
                axis: 0,
                steps: 1,
                speed: 100_000,
            },
            &machine,
        );
        assert_eq!(
            outcome.result,
            Err(Refusal::Unplannable("too short for its speed".into()))
        );
        let group = run(
            Command::MoveTogether {
                steps: vec![1],
                speed: 100_000,
            },
            &machine,
        );
        assert!(matches!(group.result, Err(Refusal::Unplannable(_))));
        assert!(calls(&machine, 0).is_empty());
        assert!(machine.groups.borrow().is_empty());
        machine.unplannable = None;
        let missing = run(
            Command::Move {
                axis: 5,
                steps: 1,
                speed: 100,
            },
            &machine,
        );
        assert_eq!(missing.result, Err(Refusal::NoSuchAxis));
        assert_eq!(
            run(Command::Home { axis: 0 }, &machine).result,
            Err(Refusal::NoHomeSwitch)
        );
        // Releasing the jog of an axis that is not there: nothing to do.
        assert_eq!(
            run(Command::JogRelease { axis: 5 }, &machine).result,
            sent(false)
        );
    }

    #[test]
    fn a_group_move_raises_every_low_pin_then_moves_together() {
        let machine = fake(3, Capabilities::all());
        machine.axes[1].set_stop_pin(false).unwrap();
        let outcome = run(
            Command::MoveTogether {
                steps: vec![2000, -500, 0],
                speed: 8_000,
            },
            &machine,
        );
        assert_eq!(outcome.result, sent(true));
        assert_eq!(calls(&machine, 1), ["stop_pin false", "stop_pin true"]);
        assert_eq!(*machine.groups.borrow(), [(vec![2000, -500, 0], 8_000)]);
    }

    #[test]
    fn keys_through_the_runner_reach_the_axes_as_before() {
        // The whole round: keys, effects run against a backend, outcomes back.
        let machine = fake(2, Capabilities::all());
        let t0 = Instant::now();
        let mut app = App::new(machine.info.clone(), 5_000, t0);
        let mut quit = false;
        for c in "s100\r1000\rxq".chars() {
            let code = match c {
                '\r' => crossterm::event::KeyCode::Enter,
                c => crossterm::event::KeyCode::Char(c),
            };
            let key = crossterm::event::KeyEvent::from(code);
            for effect in app.on_key(key, t0) {
                match effect {
                    Effect::Quit => quit = true,
                    Effect::Send(command) => app.on_outcome(run(command, &machine), t0),
                }
            }
        }
        assert_eq!(
            calls(&machine, 0),
            ["stop_pin false", "stop_pin true", "move 1000 100"]
        );
        assert_eq!(*machine.estops.borrow(), 1);
        assert!(quit);
    }

    #[test]
    fn a_frame_reads_every_axis_and_takes_edges_only_when_asked() {
        let machine = fake(2, Capabilities::all());
        let reading = read_frame(&machine, 3, false);
        assert_eq!(reading.readouts.len(), 3);
        assert!(reading.readouts[0].is_ok());
        assert_eq!(
            reading.readouts[2],
            Err("no such axis on this backend".to_string())
        );
        assert_eq!(reading.fault.as_deref(), Some("a fault"));
        assert_eq!(reading.limits, [(None, None); 3]);
        assert_eq!((reading.edges, *machine.edges_taken.borrow()), (None, 0));
        let reading = read_frame(&machine, 2, true);
        assert_eq!(reading.edges, Some((Vec::new(), 7)));
    }
}

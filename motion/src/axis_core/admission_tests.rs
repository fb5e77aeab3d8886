//! The admission table of the module docs, row by row, on the core alone
//! (no threads, no hub): each state the axis can be in, each command, the
//! answer; and a refused command changes nothing.

extern crate std;
use std::format;
use std::string::String;
use std::vec::Vec;

use super::test_core::core;
use super::*;
use crate::axis::{HomeConfig, Mode};

const SWITCH: u8 = 20;

fn home_config() -> HomeConfig {
    HomeConfig {
        switch_pin: SWITCH,
        active_level: true,
        direction: Direction::Reverse,
        seek_speed: 4_000,
        latch_speed: 400,
        backoff_steps: 100,
        max_travel: 100_000,
        set_position: 0,
    }
}

/// The states of the axis, each built by what a user does.
fn states() -> Vec<(&'static str, AxisCore)> {
    let idle = core();
    let mut held = core();
    held.set_stop_pin(0, false);
    assert_eq!(held.command(0, mv(1_000, 500)), Ok(Taken::Held));
    let mut moving = core();
    moving.command(0, mv(10_000, 5_000)).unwrap();
    moving.run_until(1_000_000, &mut |_| {});
    let mut jogging = core();
    jogging
        .command(
            0,
            CoreCommand::Jog {
                speed: 5_000,
                direction: Direction::Forward,
            },
        )
        .unwrap();
    jogging.run_until(1_000_000, &mut |_| {});
    let mut reserved = core();
    reserved
        .command(0, CoreCommand::GroupReserve { steps: 300 })
        .unwrap();
    let mut group = core();
    group
        .command(0, CoreCommand::GroupReserve { steps: 300 })
        .unwrap();
    group
        .command(
            0,
            CoreCommand::GroupStart(GroupMove {
                speed: 10_000,
                lead_steps: 1_000,
                steps: 300,
                start_ct: 0,
            }),
        )
        .unwrap();
    let mut homing = core();
    homing.command(0, CoreCommand::Home(home_config())).unwrap();
    let mut stopping = core();
    stopping.command(0, mv(10_000, 5_000)).unwrap();
    stopping.run_until(1_000_000, &mut |_| {});
    stopping.set_stop_pin(1_000_000, false);
    let mut estopped = core();
    estopped.command(0, mv(10_000, 5_000)).unwrap();
    estopped.run_until(1_000_000, &mut |_| {});
    estopped
        .command(1_000_000, CoreCommand::EmergencyStop)
        .unwrap();
    std::vec![
        ("idle", idle),
        ("held", held),
        ("moving", moving),
        ("jogging", jogging),
        ("reserved", reserved),
        ("group", group),
        ("homing", homing),
        ("stopping", stopping),
        ("estopped", estopped),
    ]
}

fn mv(speed: u32, steps: i32) -> CoreCommand {
    CoreCommand::Move { speed, steps }
}

/// The commands of the table, named.
fn commands() -> Vec<(&'static str, CoreCommand)> {
    std::vec![
        ("move same way", mv(10_000, 100)),
        ("move other way", mv(10_000, -100)),
        (
            "jog",
            CoreCommand::Jog {
                speed: 5_000,
                direction: Direction::Forward,
            },
        ),
        ("set position", CoreCommand::SetPosition(7)),
        ("home", CoreCommand::Home(home_config())),
        ("group reserve", CoreCommand::GroupReserve { steps: 10 }),
        (
            "limit pins",
            CoreCommand::SetLimitPins {
                min: Some((30, true)),
                max: None,
            },
        ),
    ]
}

/// What the module docs' table says, as `Ok` or the error's name.
fn expected(state: &str, command: &str) -> &'static str {
    match (state, command) {
        // Idle and e-stopped (idle with ESTOP set) take everything.
        ("idle" | "estopped", _) => "ok",
        // A held move waits: another move or jog is refused.
        ("held", "move same way" | "move other way") => "Busy",
        ("held", "jog") => "StopPinLow",
        ("held" | "stopping", "home") => "NotIdle",
        ("held" | "stopping", "group reserve") => "Busy",
        ("held", "set position") => "NotIdle",
        ("held", "limit pins") => "ok",
        // A move runs: moves merge, reverse (queued) or change speed.
        ("moving", "move same way" | "move other way") => "ok",
        ("moving", "jog") => "Busy",
        ("moving" | "jogging" | "stopping", "set position") => "NotIdle",
        ("moving" | "jogging", "home") => "NotIdle",
        ("moving" | "jogging", "group reserve") => "Busy",
        ("moving" | "jogging" | "stopping", "limit pins") => "ok",
        // A jog owns the axis.
        ("jogging", "move same way" | "move other way") => "Jogging",
        ("jogging", "jog") => "ok",
        // A reservation or a group part: nothing else starts.
        ("reserved" | "group", "move same way" | "move other way" | "jog") => "Busy",
        ("reserved" | "group", "set position") => "NotIdle",
        ("reserved" | "group", "home") => "NotIdle",
        ("reserved" | "group", "group reserve") => "Busy",
        ("reserved" | "group", "limit pins") => "ok",
        // Homing owns the axis.
        ("homing", "move same way" | "move other way" | "jog") => "Homing",
        ("homing", "set position") => "Homing",
        ("homing", "home" | "limit pins") => "Homing",
        ("homing", "group reserve") => "Busy",
        // Stopping by the stop pin: a move is held, a jog refused.
        ("stopping", "move same way" | "move other way") => "ok",
        ("stopping", "jog") => "StopPinLow",
        _ => "unlisted",
    }
}

fn name(result: &Result<Taken, AxisError>) -> String {
    match result {
        Ok(_) => "ok".into(),
        Err(error) => {
            let debug = format!("{error:?}");
            debug.split(['(', ' ']).next().unwrap_or("").into()
        }
    }
}

#[test]
fn every_state_answers_every_command_as_the_table_says() {
    let mut wrong = Vec::new();
    for (state_name, state) in states() {
        for (command_name, command) in commands() {
            let mut core = state.clone();
            let before = format!("{core:?}");
            let result = core.command(2_000_000, command);
            let got = name(&result);
            let want = expected(state_name, command_name);
            if got != want {
                wrong.push(format!(
                    "{state_name} + {command_name}: {got}, table says {want}"
                ));
            }
            if result.is_err() {
                assert_eq!(
                    format!("{core:?}"),
                    before,
                    "{state_name} + {command_name}: a refused command changed the core"
                );
            }
        }
    }
    assert!(wrong.is_empty(), "{wrong:#?}");
}

#[test]
fn the_states_show_in_the_mode_bits() {
    for (state_name, core) in states() {
        let mode = core.mode();
        let (moving, hold, jog, homing) = match state_name {
            "idle" | "reserved" | "estopped" => (false, false, false, false),
            "held" => (false, true, false, false),
            "moving" | "group" | "stopping" => (true, false, false, false),
            "jogging" => (true, false, true, false),
            "homing" => (true, false, false, true),
            _ => unreachable!(),
        };
        assert_eq!(mode.has(Mode::MOVING), moving, "{state_name}: {mode:?}");
        assert_eq!(mode.has(Mode::HOLD), hold, "{state_name}: {mode:?}");
        assert_eq!(mode.has(Mode::JOG), jog, "{state_name}: {mode:?}");
        assert_eq!(mode.has(Mode::HOMING), homing, "{state_name}: {mode:?}");
        assert_eq!(
            mode.has(Mode::ESTOP),
            state_name == "estopped",
            "{state_name}"
        );
        assert_eq!(core.steps_to_go() == 0, !moving && !hold, "{state_name}");
    }
}

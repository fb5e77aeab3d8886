//! The Raspberry Pi Pico firmware end to end: cogstep's RP2040 firmware
//! (`firmware/boards/rp-pico`) running under the rp2040py emulator
//! (`firmware/run-pico-sim`), driven over its UART0 on a pseudo-terminal
//! by the host backend (`SerialBoard`) or a raw port, with the scenarios
//! the QEMU board passes (`firmware_scenarios/`), and one scenario run in
//! all three homes: the virtual hub, the board simulator and the Pico.
//! Then the timer path's timing scenario, every edge of its VCD against
//! the axis cores replayed on the host (Smooth and P2Exact), and the
//! input pins (homing, a limit switch, a stop pin) on the timer build and
//! on the PIO build (`run-pico-sim --pio`).
//!
//! These tests need Debian's Rust toolchain and the emulator's virtual
//! environment (firmware/README.md), so they are `#[ignore]`d: `.ci/run`
//! runs them with `cargo test -p cogstep-tests --test firmware_pico --
//! --ignored`.
//!
//! The firmware's CT is the RP2040's microsecond timer
//! (`clkfreq:1000000`); the emulator's simulated time never runs ahead of
//! the wall clock and may fall behind it. Moves are short and every wait
//! has a generous limit; nothing here asserts how fast anything is.
#![cfg(unix)]

mod firmware_scenarios;

use std::path::Path;
use std::time::{Duration, Instant};

use cogstep_test_support::pico::{
    arithmetic_flag, firmware_core_config, pin_names, pio_counts, position_of, read_vcd,
    start_pico_sim, wait_idle, wait_position, Action, Replay,
};
use cogstep_test_support::script::DeviceScript;
use cogstep_test_support::serial::RawPort;
use cogstep_test_support::status::{finish, is_done, wait_in, wait_until};
use driver::profile::scurve::Arithmetic;
use driver::{AxisContract, AxisError, ClockMode, Hub, HubConfig};
use firmware_scenarios::{open, Firmware};

/// The longest any wait in these tests may take before it fails.
const PATIENCE: Duration = Duration::from_secs(60);
/// The firmware's clock, Hz: the microsecond timer.
const CLKFREQ: u32 = 1_000_000;

/// The Pico firmware under the emulator, through `firmware/run-pico-sim`
/// in Smooth, control lines on its standard input.
const PICO: Firmware = Firmware {
    script: "firmware/run-pico-sim",
    args: &["--arithmetic", "smooth"],
    control: true,
    clkfreq: CLKFREQ,
    pulse_ticks: 5,
    // The simulator's hub's 1,000-tick pulse does not fit 4,000 steps/s
    // at 1 MHz: it runs at its own clock.
    sim_clkfreq: None,
    patience: PATIENCE,
    // Homing and hard limits work here (their own tests below).
    own_replies: &[],
};

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn every_realtime_byte_gets_its_exact_reply() {
    firmware_scenarios::every_realtime_byte_gets_its_exact_reply(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn every_command_line_gets_its_reply() {
    firmware_scenarios::every_command_line_gets_its_reply(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn the_backend_identifies_the_board_and_moves_merge() {
    firmware_scenarios::the_backend_identifies_the_board_and_moves_merge(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn stop_and_resume_reach_the_exact_target() {
    firmware_scenarios::stop_and_resume_reach_the_exact_target(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn a_group_move_keeps_its_line_through_a_members_stop() {
    firmware_scenarios::a_group_move_keeps_its_line_through_a_members_stop(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn emergency_stop_keeps_the_position_and_set_position_needs_idle() {
    firmware_scenarios::emergency_stop_keeps_the_position_and_set_position_needs_idle(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn refusals_come_back_as_axis_errors_and_change_nothing() {
    firmware_scenarios::refusals_come_back_as_axis_errors_and_change_nothing(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn jog_runs_while_heartbeats_come_and_release_stops_it() {
    firmware_scenarios::jog_runs_while_heartbeats_come_and_release_stops_it(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn the_emulator_killed_mid_move_is_a_fault_not_a_hang() {
    firmware_scenarios::the_board_killed_mid_move_is_a_fault_not_a_hang(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn the_backend_reconnects_to_a_fresh_emulator() {
    firmware_scenarios::the_backend_reconnects_to_a_fresh_board(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn a_half_written_line_is_not_run_when_the_backend_connects() {
    firmware_scenarios::a_half_written_line_is_not_run_when_the_backend_connects(&PICO);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn same_behaviour_in_three_homes() {
    firmware_scenarios::same_behaviour_in_three_homes(&PICO);
}

// ---------------------------------------------------------------------------
// Timing: every edge on the pins against the axis core's own schedule.
//
// The firmware's axis cores act on a command at the CT of its last byte
// plus the 5 µs set-up (the harness's `ct` answers that CT, read from the
// firmware's `COGSTEP_COMMAND_CT`). The same commands at the same CTs on
// host axis cores with the firmware's settings give every edge the pins
// must show; the VCD of the run shows what they did (simulated ns; one CT
// tick is 1 µs).

/// How late a rising edge may be, ns.
const RISE_TOLERANCE_NS: i64 = 2_000;
/// The pulse, and how far from it a pulse may be, ns.
const PULSE_NS: i64 = 5_000;
const PULSE_TOLERANCE_NS: i64 = 1_000;

/// Every edge of the run against the replay: the same edges in the same
/// order on each pin, each rising edge at most `RISE_TOLERANCE_NS` after
/// its CT (never before), each step pulse `PULSE_NS` ± `PULSE_TOLERANCE_NS`.
/// Fails on the first edge that is not, naming it. Returns the worst
/// rising-edge lateness and the pulse range (ns), and the steps checked.
fn check_edges(replay: &Replay, vcd: &Path, epoch_ns: i64) -> (i64, (i64, i64), usize) {
    let changes = read_vcd(vcd);
    let mut worst_late = 0;
    let mut pulses = (i64::MAX, i64::MIN);
    let mut steps = 0;
    for (index, expected) in replay.edges.iter().enumerate() {
        for (pin, name) in pin_names(index).iter().enumerate() {
            let wanted: Vec<_> = expected
                .iter()
                .filter(|edge| usize::from(edge.pin) == pin)
                .collect();
            let seen = changes.get(name).cloned().unwrap_or_default();
            if std::env::var_os("COGSTEP_DEBUG_EDGES").is_some() {
                for (edge, at) in wanted.iter().zip(&seen).step_by(64).take(60) {
                    eprintln!(
                        "{name}: core {} µs {} / pins {} ns {}: {} ns late",
                        edge.ct,
                        edge.level,
                        at.0,
                        at.1,
                        at.0 - epoch_ns - i64::try_from(edge.ct).unwrap() * 1_000
                    );
                }
            }
            for (number, edge) in wanted.iter().enumerate() {
                let kind = if edge.level { "rising" } else { "falling" };
                let due_ns = epoch_ns + i64::try_from(edge.ct).unwrap() * 1_000;
                let Some(&(at_ns, level)) = seen.get(number) else {
                    panic!(
                        "{name}: {kind} edge {number} (CT {} µs) never came ({} edges seen)",
                        edge.ct,
                        seen.len()
                    );
                };
                assert_eq!(
                    level, edge.level,
                    "{name}: edge {number} at {at_ns} ns is {} where the core has a {kind} edge at CT {} µs",
                    if level { "rising" } else { "falling" },
                    edge.ct
                );
                let late = at_ns - due_ns;
                if edge.level {
                    assert!(
                        (0..=RISE_TOLERANCE_NS).contains(&late),
                        "{name}: rising edge {number} at {at_ns} ns, the core scheduled CT {} µs: {late} ns off",
                        edge.ct
                    );
                    worst_late = worst_late.max(late);
                    if pin == 0 || index % 2 == 1 {
                        steps += 1;
                    }
                } else if number > 0 && (pin == 0 || index % 2 == 1) {
                    let width = at_ns - seen[number - 1].0;
                    assert!(
                        (PULSE_NS - PULSE_TOLERANCE_NS..=PULSE_NS + PULSE_TOLERANCE_NS)
                            .contains(&width),
                        "{name}: step pulse {} (rising at {} ns) is {width} ns wide",
                        number / 2,
                        seen[number - 1].0
                    );
                    pulses = (pulses.0.min(width), pulses.1.max(width));
                }
            }
            assert_eq!(
                seen.len(),
                wanted.len(),
                "{name}: {} edges where the core made {}; the first extra at {:?}",
                seen.len(),
                wanted.len(),
                seen.get(wanted.len())
            );
        }
    }
    (worst_late, pulses, steps)
}

/// Sends `line`, expects `ok`, and returns the firmware CT it acted at.
fn act(pico: &mut DeviceScript, raw: &mut RawPort, line: &str) -> u64 {
    assert_eq!(raw.command(line), ["ok"], "{line}");
    u64::try_from(pico.number("ct")).expect("a CT")
}

/// The timing scenario at `speed` steps/s on four axes at once, with
/// commands arriving mid-move over the serial port: a slew move on axis
/// 1 then a merge into it, all-ramp moves on axes 2 and 3 (axis 3's
/// merged into mid-ramp, axis 2 held by its stop "pin" `S` and released
/// with `R`), a jog on axis 4 kept alive by a heartbeat, then an
/// emergency stop of everything. Move lengths scale with the speed, so
/// the simulated time stays near a second whatever the speed. Every edge of the VCD is then
/// checked against the axis cores replayed on the host
/// ([`check_edges`]): fails on the first edge that is late or of the
/// wrong width, naming it. Returns the steps checked.
fn timing_scenario(speed: u32, arithmetic: Arithmetic) -> usize {
    let flag = arithmetic_flag(arithmetic);
    let vcd = std::env::temp_dir().join(format!(
        "cogstep-pico-timing-{speed}-{flag}-{}.vcd",
        std::process::id()
    ));
    let axes = 4;
    let mut pico = start_pico_sim(axes, arithmetic, false, Some(&vcd));
    let mut raw = RawPort::open_when_answering(pico.path(), PATIENCE);
    let mut replay = Replay::new(axes, CLKFREQ, arithmetic);
    let mut run = |pico: &mut DeviceScript, raw: &mut RawPort, line: &str, actions: &[Action]| {
        let ct = act(pico, raw, line);
        for &action in actions {
            replay.apply(ct, action);
        }
    };
    use driver::CoreCommand::{EmergencyStop, Jog, Move};
    let unit = i32::try_from(speed / 4).expect("a speed in range");
    let forward = driver::Direction::Forward;
    let mv = |steps: i32| Move { speed, steps };
    let jog = Jog {
        speed,
        direction: forward,
    };
    // Axis 1: a long move (ramps and slew), merged into mid-move. Axes 2
    // and 3: all-ramp moves (`speed / 6` steps; a ramp takes `speed / 10 +
    // 2` steps each way), axis 3's merged into mid-ramp, axis 2 held by its
    // stop pin mid-ramp and released. Axis 4: a jog, its heartbeat, then
    // everything stopped by an emergency stop.
    let short = i32::try_from(speed / 6).expect("a speed in range");
    let line = |command: &str, axis: usize, steps: i32| format!("{command} {axis} {speed} {steps}");
    run(
        &mut pico,
        &mut raw,
        &line("M", 0, 5 * unit),
        &[Action::Command(0, mv(5 * unit))],
    );
    run(
        &mut pico,
        &mut raw,
        &line("M", 1, -short),
        &[Action::Command(1, mv(-short))],
    );
    run(
        &mut pico,
        &mut raw,
        &line("M", 2, short),
        &[Action::Command(2, mv(short))],
    );
    let jog_line = format!("J 3 {speed} +");
    run(&mut pico, &mut raw, &jog_line, &[Action::Command(3, jog)]);
    wait_position(&mut raw, axes, 2, i64::from(short / 3), PATIENCE);
    run(
        &mut pico,
        &mut raw,
        &line("M", 2, short),
        &[Action::Command(2, mv(short))],
    );
    run(&mut pico, &mut raw, "S 1", &[Action::StopPin(1, false)]);
    run(&mut pico, &mut raw, &jog_line, &[Action::Command(3, jog)]);
    run(&mut pico, &mut raw, "R 1", &[Action::StopPin(1, true)]);
    wait_position(&mut raw, axes, 0, i64::from(3 * unit / 2), PATIENCE);
    run(
        &mut pico,
        &mut raw,
        &line("M", 0, 2 * unit),
        &[Action::Command(0, mv(2 * unit))],
    );
    run(&mut pico, &mut raw, &jog_line, &[Action::Command(3, jog)]);
    wait_position(&mut raw, axes, 0, i64::from(3 * unit), PATIENCE);
    run(
        &mut pico,
        &mut raw,
        "E",
        &[
            Action::Command(0, EmergencyStop),
            Action::Command(1, EmergencyStop),
            Action::Command(2, EmergencyStop),
            Action::Command(3, EmergencyStop),
        ],
    );
    wait_idle(&mut raw, axes, PATIENCE);
    drop(raw);
    let epoch_ns = pico.number("epoch");
    pico.stop();
    replay.finish();
    let (late, pulses, steps) = check_edges(&replay, &vcd, epoch_ns);
    eprintln!(
        "four axes at {speed} steps/s, {flag}: {steps} steps, every rising edge at most {late} ns after the core's CT, pulses {}..{} ns",
        pulses.0, pulses.1
    );
    let _ = std::fs::remove_file(&vcd);
    steps
}

/// A group move's members in the replay, as the firmware starts them at
/// firmware CT `ct`: every one reserved, then all started on the CT a
/// move would take (the core's, the set-up time ahead).
fn replay_group(replay: &mut Replay, ct: u64, speed: u32, steps: &[i32]) {
    use driver::axis_core::GroupMove;
    use driver::CoreCommand::{GroupReserve, GroupStart};
    let lead_steps = steps.iter().map(|s| s.unsigned_abs()).max().unwrap();
    let setup = u64::from(firmware_core_config(0, CLKFREQ, Arithmetic::Smooth).dir_setup_ticks);
    for (index, &part) in steps.iter().enumerate() {
        replay.apply(ct, Action::Command(index, GroupReserve { steps: part }));
    }
    for (index, &part) in steps.iter().enumerate() {
        let group = GroupMove {
            speed,
            lead_steps,
            steps: part,
            start_ct: ct + setup,
        };
        replay.apply(ct, Action::Command(index, GroupStart(group)));
    }
}

/// `G` on three axes (one with no steps) at 3,000 steps/s, stopped by
/// the stop pin (`S`) of the member with no steps and completed by a `G`
/// of the steps left: every edge on the pins is the replayed cores' (the
/// firmware's group rules: all started on one CT, every member stopped
/// after the CT of the `S`), each rising edge within 2 µs of its CT and
/// each pulse 5 µs; both moving members' first rising edges on one CT.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn a_group_move_on_the_pins_starts_on_one_ct_and_stops_on_its_line() {
    let vcd = std::env::temp_dir().join(format!("cogstep-pico-group-{}.vcd", std::process::id()));
    let axes = 3;
    let mut pico = start_pico_sim(axes, Arithmetic::Smooth, false, Some(&vcd));
    let mut raw = RawPort::open_when_answering(pico.path(), PATIENCE);
    let mut replay = Replay::new(axes, CLKFREQ, Arithmetic::Smooth);
    let speed = 3_000;
    let ct = act(&mut pico, &mut raw, "G 3000 1500 -500 0");
    replay_group(&mut replay, ct, speed, &[1_500, -500, 0]);
    wait_position(&mut raw, axes, 0, 300, PATIENCE);
    let ct = act(&mut pico, &mut raw, "S 2");
    replay.apply(ct, Action::StopPin(2, false));
    for index in 0..axes {
        replay.apply(ct, Action::StopGroup(index));
    }
    wait_idle(&mut raw, axes, PATIENCE);
    let lines = raw.status(axes);
    let (lead, follower) = (position_of(&lines[0]), position_of(&lines[1]));
    assert!(lead < 1_500, "{lines:?}");
    let line = -500.0 * lead as f64 / 1_500.0;
    assert!((follower as f64 - line).abs() <= 1.0, "{lines:?}");
    let ct = act(&mut pico, &mut raw, "R 2");
    replay.apply(ct, Action::StopPin(2, true));
    let left = [
        i32::try_from(1_500 - lead).unwrap(),
        i32::try_from(-500 - follower).unwrap(),
        0,
    ];
    let ct = act(
        &mut pico,
        &mut raw,
        &format!("G 3000 {} {} 0", left[0], left[1]),
    );
    replay_group(&mut replay, ct, speed, &left);
    wait_idle(&mut raw, axes, PATIENCE);
    let lines = raw.status(axes);
    assert_eq!(
        [position_of(&lines[0]), position_of(&lines[1])],
        [1_500, -500]
    );
    drop(raw);
    let epoch_ns = pico.number("epoch");
    pico.stop();
    replay.finish();
    // Axis 0 is sd (its step pin is pin 0), axis 1 cc (either pin steps).
    let first_rise = |index: usize| {
        replay.edges[index]
            .iter()
            .find(|edge| edge.level && (index % 2 == 1 || edge.pin == 0))
            .map(|edge| edge.ct)
    };
    assert!(first_rise(0).is_some());
    assert_eq!(first_rise(0), first_rise(1), "the members' first steps");
    assert_eq!(first_rise(2), None);
    let (late, pulses, steps) = check_edges(&replay, &vcd, epoch_ns);
    eprintln!(
        "group move: {steps} steps, every rising edge at most {late} ns after the core's CT, pulses {}..{} ns",
        pulses.0, pulses.1
    );
    assert_eq!(steps, 2_000);
    let _ = std::fs::remove_file(&vcd);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_at_4000_steps_s_every_edge_on_time_with_commands_mid_move() {
    let steps = timing_scenario(4_000, Arithmetic::Smooth);
    assert!(steps > 3_000, "{steps} steps checked");
}

/// The same scenario with the axis cores in P2Exact (the P2 driver's own
/// arithmetic, its CORDIC emulated), checked against host cores in
/// P2Exact.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_at_4000_steps_s_p2exact_every_edge_on_time_with_commands_mid_move() {
    let steps = timing_scenario(4_000, Arithmetic::P2Exact);
    assert!(steps > 3_000, "{steps} steps checked");
}

/// Below the timer path's limit (docs/performance.md: Smooth passes
/// 9,750 steps/s on four axes, P2Exact 10,500; 6,000 was near it before
/// the ramp's 64-bit products went inline): a regression in the cost of a
/// step shows here first.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_at_6000_steps_s_every_edge_on_time_with_commands_mid_move() {
    let steps = timing_scenario(6_000, Arithmetic::Smooth);
    assert!(steps > 7_500, "{steps} steps checked");
}

/// [`four_axes_at_6000_steps_s_every_edge_on_time_with_commands_mid_move`]
/// in P2Exact.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_at_6000_steps_s_p2exact_every_edge_on_time_with_commands_mid_move() {
    let steps = timing_scenario(6_000, Arithmetic::P2Exact);
    assert!(steps > 7_500, "{steps} steps checked");
}

/// The goal for the timer path: four axes at 20,000 steps/s, in
/// Smooth, with core 1 computing the ramp runs. Its margin, by hand
/// (docs/performance.md, "The timer build's timing scenario"): 24,000
/// passes, 26,000 fails (about 25 s).
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_at_20000_steps_s_every_edge_on_time_with_commands_mid_move() {
    let steps = timing_scenario(20_000, Arithmetic::Smooth);
    assert!(steps > 30_000, "{steps} steps checked");
}

/// The same in P2Exact, its stops decelerating on ramp runs too: by hand
/// it passes at 30,000 (about 25 s).
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn four_axes_at_20000_steps_s_p2exact_every_edge_on_time_with_commands_mid_move() {
    let steps = timing_scenario(20_000, Arithmetic::P2Exact);
    assert!(steps > 27_000, "{steps} steps checked");
}

/// The scenario at the speed in `COGSTEP_PICO_TIMING_SPEED` (steps/s), to
/// find by hand the highest speed at which the timer path keeps every
/// edge (docs/performance.md has the figure).
#[test]
#[ignore = "by hand: COGSTEP_PICO_TIMING_SPEED=N"]
fn four_axes_at_a_chosen_speed() {
    let speed = std::env::var("COGSTEP_PICO_TIMING_SPEED")
        .ok()
        .and_then(|text| text.parse().ok())
        .expect("COGSTEP_PICO_TIMING_SPEED=steps/s");
    let arithmetic = match std::env::var("COGSTEP_PICO_TIMING_ARITHMETIC").as_deref() {
        Ok("p2exact") => Arithmetic::P2Exact,
        _ => Arithmetic::Smooth,
    };
    timing_scenario(speed, arithmetic);
}

// ---------------------------------------------------------------------------
// Inputs: stop pins, home and limit switches on the Pico's GPIOs, driven
// by the harness's control lines (a switch placed at an axis position
// counted from the step edges on the pins). The firmware's cores run 4 ms
// ahead of the pins: homing and a trip must latch the step on which the
// pins reached the switch, as the hub does; the stop that follows may end
// up to 4 ms of steps further.

/// The Pico's pins for axis 0's inputs (boards/rp-pico/README.md).
const HOME_GPIO: u8 = 14;
const LIMIT_MAX_GPIO: u8 = 22;

/// The firmware build the inputs' tests run: edges by the timer's
/// interrupt (the default) or by PIO state machines (`--features pio`,
/// its PIO0 the harness's model, which makes the pins' edges and counts
/// their positions as the timer build's pins do).
#[derive(Clone, Copy, Debug)]
enum Build {
    Timer,
    Pio,
}

impl Build {
    /// The firmware's CT rate: the microsecond timer, or the system clock.
    fn clkfreq(self) -> u32 {
        match self {
            Build::Timer => CLKFREQ,
            Build::Pio => 125_000_000,
        }
    }

    /// `firmware/run-pico-sim` with `axes` axes of this build, in Smooth.
    fn start(self, axes: usize) -> DeviceScript {
        start_pico_sim(axes, Arithmetic::Smooth, matches!(self, Build::Pio), None)
    }

    /// Stops the emulator; on the PIO build first checks that no state
    /// machine ran dry. A FIFO that runs dry stalls its state machine, so
    /// that edge and every later one come late by the same time, and the
    /// pins' steps then reach a switch later than their CTs say (a homing
    /// stopped 6 steps further than the hub's, once in about 75 runs,
    /// before the feeder held every axis at each round's mark).
    fn stop(self, mut pico: DeviceScript) {
        if matches!(self, Build::Pio) {
            let counts = pio_counts(&mut pico);
            assert_eq!(
                counts.get("late").map(String::as_str),
                Some("0"),
                "a state machine ran dry: {counts:?}"
            );
        }
        pico.stop();
    }
}

/// The virtual hub at the firmware's clock, one sd axis, its stop pin high.
fn firmware_like_hub(build: Build) -> (Hub, driver::Axis) {
    let clkfreq = build.clkfreq();
    let micros_5 = u32::try_from(u64::from(clkfreq) * 5 / 1_000_000).unwrap();
    let hub = Hub::new(HubConfig {
        clkfreq,
        clock: ClockMode::Virtual,
        pulse_ticks: micros_5,
        dir_setup_ticks: micros_5,
        ..HubConfig::default()
    })
    .unwrap();
    let x = hub.start_sd(0, 1, 2).unwrap();
    x.set_stop_pin(true).unwrap();
    (hub, x)
}

/// Steps a stop may run on beyond the hub's at `speed`: the lead (4 ms).
fn lead_steps(speed: u32) -> i64 {
    i64::from(speed) * 4 / 1_000 + 1
}

/// The axis's position as its step edges on the pins count it, once the
/// pins have stopped (they run 4 ms behind the status).
fn pins_position(pico: &mut DeviceScript, axis: usize) -> i64 {
    let mut read = || pico.number(&format!("position axis{}", axis + 1));
    let start = Instant::now();
    let mut last = read();
    loop {
        std::thread::sleep(Duration::from_millis(300));
        let now = read();
        if now == last {
            return now;
        }
        assert!(start.elapsed() < PATIENCE, "the pins never stopped");
        last = now;
    }
}

/// Waits until the axis has nothing left to make.
fn at_rest(axis: &dyn AxisContract) -> driver::AxisStatus {
    wait_until(axis, PATIENCE, "at rest", is_done)
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn homing_on_a_switch_pin_latches_the_step_the_hub_latches() {
    homing_scenario(Build::Timer);
}

/// The same on the PIO build: the pins' steps made by the PIO model, the
/// switch placed on the position they count, homing's latch on the
/// GPIO interrupt's stamp against the feeder's step history.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn homing_on_the_pio_build_latches_the_step_the_hub_latches() {
    homing_scenario(Build::Pio);
}

/// Homing on GP14 (a switch at −700 as the pins count), beside the
/// virtual hub's homing on the same switch: the same steps latched, the
/// same place given the same position, the last stop at most the lead
/// further.
fn homing_scenario(build: Build) {
    let config = driver::HomeConfig {
        switch_pin: HOME_GPIO,
        // A switch closing to ground against the pull-up.
        active_level: false,
        direction: driver::Direction::Reverse,
        seek_speed: 4_000,
        latch_speed: 800,
        backoff_steps: 60,
        max_travel: 5_000,
        set_position: 100,
    };
    let (hub, hub_x) = firmware_like_hub(build);
    hub.attach_switch(HOME_GPIO, &hub_x, i64::MIN..=-700, false)
        .unwrap();
    hub_x.home(config).unwrap();
    hub.run_until_idle();
    let on_hub = hub_x.home_outcome().expect("homed").expect("found");
    let hub_origin = hub_x.position() - hub_x.physical_position();
    hub.shutdown();

    let mut pico = build.start(1);
    pico.control("switch axis1_home 0 when axis1 <= -700");
    let board = open(pico.path());
    let x = board.axis(0).unwrap();
    x.home(config).unwrap();
    assert!(x.limit_status().unwrap().homing);
    assert_eq!(x.move_steps(1_000, 10), Err(AxisError::Homing));
    let start = Instant::now();
    while x.limit_status().unwrap().homing {
        assert!(start.elapsed() < PATIENCE, "homing never ended");
        std::thread::sleep(Duration::from_millis(50));
    }
    let status = at_rest(&x);
    let report = x
        .limit_status()
        .unwrap()
        .home_outcome
        .expect("homed")
        .expect("found");
    let physical = pins_position(&mut pico, 0);
    // The same steps latched, and the same place got the same position.
    assert_eq!((report.seek_physical, report.latch_physical), (-700, -700));
    assert_eq!(
        (report.seek_position, report.latch_position),
        (on_hub.seek_position, on_hub.latch_position)
    );
    assert_eq!(status.position - physical, hub_origin, "{report:?}");
    // The last stop ran on for at most the lead's steps at the latch speed.
    let further = on_hub.position - report.position;
    assert!(
        (0..=lead_steps(config.latch_speed)).contains(&further),
        "{report:?} vs the hub's {on_hub:?}"
    );
    board.close();
    build.stop(pico);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn a_limit_switch_trips_on_its_step_and_c_clears_it() {
    limit_scenario(Build::Timer);
}

/// The same on the PIO build (see the homing test's).
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn a_limit_switch_on_the_pio_build_trips_on_its_step_and_c_clears_it() {
    limit_scenario(Build::Pio);
}

/// A max limit on GP22 at 1,000 as the pins count, beside the hub's trip
/// on the same switch: the same step, a stop at most the lead further, a
/// pin the board does not read refused, moves that way refused until `C`.
fn limit_scenario(build: Build) {
    let speed = 4_000;
    let (hub, hub_x) = firmware_like_hub(build);
    hub.attach_switch(LIMIT_MAX_GPIO, &hub_x, 1_000..=i64::MAX, false)
        .unwrap();
    hub_x
        .set_limit_pins(None, Some((LIMIT_MAX_GPIO, false)))
        .unwrap();
    hub_x.move_steps(speed, 3_000).unwrap();
    hub.run_until_idle();
    let on_hub = hub_x.limit_trip().expect("the hub trips");
    hub.shutdown();

    let mut pico = build.start(1);
    pico.control("switch axis1_limit_max 0 when axis1 >= 1000");
    let board = open(pico.path());
    let x = board.axis(0).unwrap();
    // Pins the board does not read are refused, and change nothing.
    assert_eq!(
        x.set_limit_pins(None, Some((3, false))),
        Err(AxisError::BadSetting(
            driver::refusal::bad_setting::PIN_NOT_A_SWITCH_INPUT
        ))
    );
    assert_eq!(x.limit_status().unwrap().limit_pins, [None, None]);
    x.set_limit_pins(None, Some((LIMIT_MAX_GPIO, false)))
        .unwrap();
    x.move_steps(speed, 3_000).unwrap();
    let status = at_rest(&x);
    let trip = x.limit_status().unwrap().trip.expect("the firmware trips");
    let physical = pins_position(&mut pico, 0);
    assert_eq!(
        (trip.side, trip.position, trip.physical),
        (on_hub.side, on_hub.position, on_hub.physical)
    );
    assert_eq!(
        (trip.position, status.position, physical),
        (1_000, physical, physical)
    );
    assert_eq!(trip.physical + trip.stopping_steps as i64, physical);
    let further = trip.stopping_steps as i64 - on_hub.stopping_steps as i64;
    assert!(
        (0..=lead_steps(speed)).contains(&further),
        "{trip:?} vs the hub's {on_hub:?}"
    );
    // Further that way is refused until `C`; away is taken.
    assert_eq!(
        x.move_steps(speed, 10),
        Err(AxisError::IntoLimit(driver::Direction::Forward))
    );
    x.clear_limit_fault().unwrap();
    assert_eq!(x.limit_status().unwrap().trip, None);
    x.move_steps(speed, -500).unwrap();
    finish(&x, PATIENCE, physical - 500);
    board.close();
    build.stop(pico);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn a_stop_pin_low_holds_a_move_and_high_finishes_it_exactly() {
    stop_pin_scenario(Build::Timer);
}

/// The same on the PIO build.
#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn a_stop_pin_on_the_pio_build_holds_a_move_and_high_finishes_it_exactly() {
    stop_pin_scenario(Build::Pio);
}

/// GP10 (axis 0's stop input) driven low 150 ms into a move: the axis
/// holds, `R` does not release it, a move of the rest waits; high, it runs
/// to the exact target on the pins; axis 1's stop input is its own.
fn stop_pin_scenario(build: Build) {
    let mut pico = build.start(2);
    let board = open(pico.path());
    let x = board.axis(0).unwrap();
    x.move_steps(4_000, 2_000).unwrap();
    // The stop pin goes low 150 ms of simulated time from now.
    let now_ns = pico.number("now");
    pico.control(&format!("at {} axis1_stop 0", now_ns + 150_000_000));
    let held = wait_in(
        &x,
        PATIENCE,
        "held",
        &|| std::thread::sleep(Duration::from_millis(20)),
        |status| is_done(status) && !status.stop_pin_high,
    );
    assert!(held.position > 0 && held.position < 2_000, "{held:?}");
    // `R` alone does not release an axis whose stop pin is low.
    x.set_stop_pin(true).unwrap();
    assert!(!x.status().unwrap().stop_pin_high);
    // The rest, taken and held while the pin is low.
    let rest = i32::try_from(2_000 - held.position).unwrap();
    x.move_steps(4_000, rest).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(x.status().unwrap().position, held.position);
    pico.control("set axis1_stop 1");
    let done = finish(&x, PATIENCE, 2_000);
    assert!(done.stop_pin_high);
    assert_eq!(pins_position(&mut pico, 0), 2_000);
    // The other axis's stop pin is its own.
    assert!(board.axis(1).unwrap().status().unwrap().stop_pin_high);
    board.close();
    build.stop(pico);
}

//! The firmware end to end: cogstep's LM3S6965 firmware (`firmware/`)
//! running under QEMU (`firmware/run-qemu`), driven over its UART on a
//! pseudo-terminal by the host backend (`SerialBoard`) or a raw port, with
//! the scenarios every firmware board passes (`firmware_scenarios/`),
//! and one scenario run in all three homes: the virtual hub, the board
//! simulator and the firmware.
//!
//! These tests need `qemu-system-arm` and Debian's Rust toolchain (see
//! firmware/README.md), so they are `#[ignore]`d: `cargo test --workspace`
//! lists them as ignored (not run), and `.ci/run` runs them with
//! `cargo test -p cogstep-tests --test firmware_qemu -- --ignored`.
//!
//! The firmware runs at 50 MHz (`clkfreq:50000000`), in real time: moves
//! are short and every wait has a generous limit; nothing here asserts
//! how fast anything is.
#![cfg(unix)]

mod firmware_scenarios;

use std::time::Duration;

use firmware_scenarios::Firmware;

/// The LM3S6965 firmware under QEMU, through `firmware/run-qemu`, at
/// 50 MHz (`clkfreq:50000000`), in real time.
const QEMU: Firmware = Firmware {
    script: "firmware/run-qemu",
    args: &[],
    control: false,
    clkfreq: 50_000_000,
    pulse_ticks: 250,
    sim_clkfreq: Some(50_000_000),
    patience: Duration::from_secs(30),
    // No GPIO input is read on this board (firmware/README.md): homing
    // and hard limits are refused plainly.
    own_replies: &[
        (
            "H 0 14 0 - 4000 400 100 10000 0",
            "error:1 not supported: homing",
        ),
        ("K 0 - 22/0", "error:1 not supported: hard limits"),
        ("C 0", "error:1 not supported: hard limits"),
    ],
};

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn every_realtime_byte_gets_its_exact_reply() {
    firmware_scenarios::every_realtime_byte_gets_its_exact_reply(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn every_command_line_gets_its_reply() {
    firmware_scenarios::every_command_line_gets_its_reply(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn the_backend_identifies_the_board_and_moves_merge() {
    firmware_scenarios::the_backend_identifies_the_board_and_moves_merge(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn stop_and_resume_reach_the_exact_target() {
    firmware_scenarios::stop_and_resume_reach_the_exact_target(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn a_group_move_keeps_its_line_through_a_members_stop() {
    firmware_scenarios::a_group_move_keeps_its_line_through_a_members_stop(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn emergency_stop_keeps_the_position_and_set_position_needs_idle() {
    firmware_scenarios::emergency_stop_keeps_the_position_and_set_position_needs_idle(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn refusals_come_back_as_axis_errors_and_change_nothing() {
    firmware_scenarios::refusals_come_back_as_axis_errors_and_change_nothing(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn jog_runs_while_heartbeats_come_and_release_stops_it() {
    firmware_scenarios::jog_runs_while_heartbeats_come_and_release_stops_it(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn qemu_killed_mid_move_is_a_fault_not_a_hang() {
    firmware_scenarios::the_board_killed_mid_move_is_a_fault_not_a_hang(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn the_backend_reconnects_to_a_fresh_qemu() {
    firmware_scenarios::the_backend_reconnects_to_a_fresh_board(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn a_half_written_line_is_not_run_when_the_backend_connects() {
    firmware_scenarios::a_half_written_line_is_not_run_when_the_backend_connects(&QEMU);
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn same_behaviour_in_three_homes() {
    firmware_scenarios::same_behaviour_in_three_homes(&QEMU);
}

//! The Raspberry Pi Pico firmware over USB CDC: cogstep's RP2040 firmware
//! (`firmware/boards/rp-pico`) under the rp2040py emulator
//! (`firmware/run-pico-sim --usb`), its USB device enumerated by
//! rp2040py's host model and the pseudo-terminal standing for
//! `/dev/ttyACM0`. A few of the QEMU board's scenarios (`firmware_qemu.rs`,
//! all of them over UART0 in `firmware_pico.rs`), through `SerialBoard`
//! and a raw port: the identity line when the host opens the port, a move
//! to an exact position, the status, a stop and a resume; and grbl's
//! welcome and a line to its exact position.
//!
//! Ignored: they need Debian's Rust toolchain and the emulator's virtual
//! environment; `.ci/run` runs them with `cargo test -p cogstep-tests
//! --test firmware_pico_usb -- --ignored`.
#![cfg(unix)]

use std::time::{Duration, Instant};

use cogstep_test_support::script::DeviceScript;
use cogstep_test_support::serial::{idle_line, RawPort};
use cogstep_test_support::status::{finish, wait_until};
use driver::serial::host::{SerialBoard, SerialConfig};
use driver::{AxisContract, AxisState, Mode};

/// The longest any wait here may take before it fails.
const PATIENCE: Duration = Duration::from_secs(60);
/// The firmware's clock, Hz: the microsecond timer.
const CLKFREQ: u32 = 1_000_000;

/// The firmware under the emulator with its USB port on the
/// pseudo-terminal; control lines on its standard input (`dtr 0|1`).
/// SIGTERM when dropped.
fn start_usb_pico(args: &[&str]) -> DeviceScript {
    let args: Vec<&str> = ["--usb"].iter().chain(args).copied().collect();
    DeviceScript::start("firmware/run-pico-sim", &args, true)
}

fn open(path: &str) -> SerialBoard {
    SerialBoard::open(SerialConfig {
        poll_interval: Duration::from_millis(20),
        timeout: Duration::from_secs(3),
        ..SerialConfig::new(path)
    })
    .expect("the firmware answers over USB")
}

fn identity(axes: usize) -> String {
    format!(
        "[cogstep {} proto:1 axes:{axes} clkfreq:{CLKFREQ}]",
        env!("CARGO_PKG_VERSION")
    )
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn the_identity_line_comes_when_the_host_opens_the_port() {
    let mut pico = start_usb_pico(&["--axes", "4"]);
    let mut raw = RawPort::open(&pico.path.clone(), PATIENCE);

    // The port closed (DTR low): the device keeps quiet; opened again:
    // the identity line, unasked.
    pico.control("dtr 0");
    raw.assert_silent();
    pico.control("dtr 1");
    assert_eq!(raw.line(), identity(4));
    raw.assert_silent();

    assert_eq!(raw.command("I"), [identity(4), "ok".to_string()]);
    // Four status lines: more than one 64-byte packet, whole and in order.
    assert_eq!(
        raw.status(4),
        (0..4)
            .map(|axis| idle_line(axis, 0, "high"))
            .collect::<Vec<_>>()
    );
    assert_eq!(raw.command("M 2 3000 250"), ["ok"]);
    let start = Instant::now();
    while raw.status(4)[2] != idle_line(2, 250, "high") {
        assert!(start.elapsed() < PATIENCE, "the move did not end");
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(raw.command("M 9 100 100"), ["error:4 no such axis"]);
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn the_backend_moves_to_exact_positions_and_stops_and_resumes() {
    let pico = start_usb_pico(&["--axes", "2"]);
    let board = open(&pico.path);
    assert_eq!(board.identity(), identity(2));
    assert_eq!(board.axis_count(), 2);
    assert_eq!(board.clkfreq(), CLKFREQ);
    let (x, y) = (board.axis(0).unwrap(), board.axis(1).unwrap());

    x.move_steps(4_000, 600).unwrap();
    y.move_steps(4_000, -300).unwrap();
    assert_eq!(finish(&x, PATIENCE, 600).state(), AxisState::Idle);
    assert_eq!(finish(&y, PATIENCE, -300).state(), AxisState::Idle);

    // A stop mid-move holds the axis; the rest of the move after it
    // reaches the exact target.
    x.move_steps(4_000, 2_000).unwrap();
    wait_until(&x, PATIENCE, "some progress", |status| {
        status.position > 1_000
    });
    x.set_stop_pin(false).unwrap();
    let held = wait_until(&x, PATIENCE, "a controlled stop", |status| {
        status.steps_to_go == 0
            && !status.mode.has(Mode::MOVING)
            && status.state() == AxisState::Hold
    });
    assert!(held.mode.has(Mode::STOP_LATCHED));
    assert!(held.position < 2_600, "{held:?}");
    let remaining = i32::try_from(2_600 - held.position).unwrap();
    x.set_stop_pin(true).unwrap();
    x.move_steps(4_000, remaining).unwrap();
    assert_eq!(finish(&x, PATIENCE, 2_600).state(), AxisState::Idle);
    assert_eq!(board.fault(), None);
    board.close();
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn grbl_welcomes_the_host_that_opens_the_port_and_moves_exactly() {
    let mut pico = start_usb_pico(&["--dialect", "grbl"]);
    let mut raw = RawPort::open(&pico.path.clone(), PATIENCE);
    pico.control("dtr 0");
    pico.control("dtr 1");
    assert_eq!(raw.line(), "\r");
    assert_eq!(raw.line(), "Grbl 1.1h ['$' for help]\r");

    for line in ["$110=600", "$120=1000", "G91 G1 X0.4 F600"] {
        raw.send(format!("{line}\n").as_bytes());
        assert_eq!(raw.line(), "ok\r", "{line}");
    }
    let start = Instant::now();
    loop {
        raw.send(b"?");
        let report = raw.line();
        if report.starts_with("<Idle|MPos:0.400,0.000,0.000") {
            break;
        }
        assert!(start.elapsed() < PATIENCE, "{report:?}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

//! The demo against the Raspberry Pi Pico firmware: the real `demo-tui`
//! binary in a pseudo-terminal, driving cogstep's RP2040 firmware under
//! the rp2040py emulator (`firmware/run-pico-sim`) with `--serial`, the
//! screen read back with vt100.
//!
//! Needs the firmware toolchain and the emulator's virtual environment
//! (firmware/README.md), so it is `#[ignore]`d: `.ci/run` runs it with
//! `--ignored`. The emulator runs about 25 times slower than the chip
//! (its simulated time never runs ahead of the wall clock): the move is
//! short and slow, the waits long.
#![cfg(unix)]

mod pty;

use std::time::Duration;

use cogstep_test_support::script::DeviceScript;
use pty::{field, number, position, to_go, Demo, Keyboard};

const BIN: &str = env!("CARGO_BIN_EXE_demo-tui");
const LONG: Duration = Duration::from_secs(90);

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn the_demo_drives_the_pico_firmware() {
    // SIGTERM (which run-pico-sim handles) when dropped.
    let pico = DeviceScript::start("firmware/run-pico-sim", &["--axes", "2"], true);
    let demo = Demo::spawn(BIN, &["--serial", &pico.path], Keyboard::Legacy);
    let screen = demo.wait_text("Enter steps:", LONG);
    assert!(
        screen.contains(&format!("serial {}", pico.path)),
        "{screen}"
    );
    let target = 2_000;
    pty::enter_move(&demo, target, 2_000, LONG);
    demo.wait_for("the Pico's axis moving", LONG, |s| {
        number(s, "Current Position:", 1).is_some_and(|p| p > 300)
    });
    demo.send(b"s");
    let stopped = demo.wait_for("a controlled stop", LONG, |s| {
        to_go(s, 1) == 0 && field(s, "Stop pin:", 1).as_deref() == Some("LOW")
    });
    let at = position(&stopped, 1);
    assert!(at < target, "{stopped}");
    pty::enter_move(&demo, target - at, 2_000, LONG);
    let done = demo.wait_for("the original target", LONG, |s| {
        position(s, 1) == target && to_go(s, 1) == 0
    });
    // The other axis never moved.
    assert_eq!(position(&done, 2), 0, "{done}");
    drop(demo);
    drop(pico);
}

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

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use pty::{field, number, position, to_go, Demo, Keyboard};

const BIN: &str = env!("CARGO_BIN_EXE_demo-tui");
const LONG: Duration = Duration::from_secs(90);

/// `firmware/run-pico-sim`; SIGTERM (which it handles) when dropped.
struct PicoSim {
    script: Child,
    path: String,
}

impl PicoSim {
    fn start(axes: usize) -> PicoSim {
        let script_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware/run-pico-sim");
        let mut script = Command::new(script_path)
            .args(["--axes", &axes.to_string()])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("firmware/run-pico-sim starts");
        let mut first = String::new();
        BufReader::new(script.stdout.take().expect("its stdout"))
            .read_line(&mut first)
            .expect("run-pico-sim prints the device path");
        let path = first.trim().to_string();
        assert!(path.starts_with("/dev/"), "run-pico-sim printed {first:?}");
        PicoSim { script, path }
    }
}

impl Drop for PicoSim {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.script.id().to_string()])
            .status();
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(30) {
            if let Ok(Some(_)) = self.script.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.script.kill();
        let _ = self.script.wait();
    }
}

#[test]
#[ignore = "needs the firmware toolchain and the RP2040 emulator: .ci/run runs it"]
fn the_demo_drives_the_pico_firmware() {
    let pico = PicoSim::start(2);
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

//! The demo against cogstep's firmware: the real `demo-tui` binary in a
//! pseudo-terminal, driving the LM3S6965 firmware under QEMU
//! (`firmware/run-qemu`) with `--serial`, the screen read back with vt100.
//!
//! Needs `qemu-system-arm` and the firmware toolchain (firmware/README.md),
//! so it is `#[ignore]`d: `.ci/run` runs it with `--ignored`.
#![cfg(unix)]

mod pty;

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use pty::{field, number, position, to_go, Demo, Keyboard};

const BIN: &str = env!("CARGO_BIN_EXE_demo-tui");
const LONG: Duration = Duration::from_secs(30);

/// `firmware/run-qemu`; SIGTERM (which takes QEMU down) when dropped.
struct Qemu {
    script: Child,
    path: String,
}

impl Qemu {
    fn start(axes: usize) -> Qemu {
        let script_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware/run-qemu");
        let mut script = Command::new(script_path)
            .args(["--axes", &axes.to_string()])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("firmware/run-qemu starts");
        let mut first = String::new();
        BufReader::new(script.stdout.take().expect("its stdout"))
            .read_line(&mut first)
            .expect("run-qemu prints the device path");
        let path = first.trim().to_string();
        assert!(path.starts_with("/dev/"), "run-qemu printed {first:?}");
        Qemu { script, path }
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.script.id().to_string()])
            .status();
        let start = Instant::now();
        while start.elapsed() < LONG {
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
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn the_demo_drives_the_firmware_like_the_emulation() {
    let qemu = Qemu::start(2);
    let demo = Demo::spawn(BIN, &["--serial", &qemu.path], Keyboard::Legacy);
    let screen = demo.wait_text("Enter steps:", LONG);
    assert!(
        screen.contains(&format!("serial {}", qemu.path)),
        "{screen}"
    );
    enter_move(&demo, 30_000, 20_000);
    demo.wait_for("the firmware's axis moving", LONG, |s| {
        number(s, "Current Position:", 1).is_some_and(|p| p > 3_000)
    });
    demo.send(b"s");
    let stopped = demo.wait_for("a controlled stop", LONG, |s| {
        to_go(s, 1) == 0 && field(s, "Stop pin:", 1).as_deref() == Some("LOW")
    });
    let at = position(&stopped, 1);
    assert!(at < 30_000, "{stopped}");
    enter_move(&demo, 30_000 - at, 20_000);
    let done = demo.wait_for("the original target", LONG, |s| {
        position(s, 1) == 30_000 && to_go(s, 1) == 0
    });
    // The other axis never moved.
    assert_eq!(position(&done, 2), 0, "{done}");
    drop(demo);
    drop(qemu);
}

/// The processes `pid` started that still run under it.
fn children(pid: u32) -> Vec<u32> {
    std::fs::read_to_string(format!("/proc/{pid}/task/{pid}/children"))
        .unwrap_or_default()
        .split_whitespace()
        .filter_map(|child| child.parse().ok())
        .collect()
}

/// Whether process `pid` has ended (gone, or a zombie nobody reaped yet).
fn ended(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).map_or(true, |stat| {
        stat.rsplit_once(") ")
            .is_some_and(|(_, rest)| rest.starts_with('Z') || rest.starts_with('X'))
    })
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn qemu_ends_when_its_script_is_killed_with_sigkill() {
    // As a test runner's timeout or a killed parent ends it: no trap runs.
    let mut qemu = Qemu::start(1);
    let script = qemu.script.id();
    let emulator = children(script)
        .into_iter()
        .find(|pid| {
            std::fs::read_to_string(format!("/proc/{pid}/comm"))
                .is_ok_and(|name| name.trim() == "qemu-system-arm")
        })
        .expect("qemu-system-arm under run-qemu");
    qemu.script.kill().expect("SIGKILL to run-qemu");
    qemu.script.wait().expect("run-qemu ended");
    let killed = Instant::now();
    while !ended(emulator) {
        if killed.elapsed() > Duration::from_secs(5) {
            let pid = nix::unistd::Pid::from_raw(i32::try_from(emulator).expect("a pid"));
            let _ = nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGKILL);
            panic!("qemu-system-arm (pid {emulator}) outlived run-qemu's SIGKILL");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    eprintln!("QEMU ended {:?} after its script", killed.elapsed());
}

/// Answers both prompts for the selected axis.
fn enter_move(demo: &Demo, steps: i64, speed: u32) {
    pty::enter_move(demo, steps, speed, LONG);
}

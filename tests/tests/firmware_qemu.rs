//! The firmware end to end: cogstep's LM3S6965 firmware (`firmware/`)
//! running under QEMU (`firmware/run-qemu`), driven over its UART on a
//! pseudo-terminal by the host backend (`SerialBoard`) or a raw port, with
//! the scenarios the board simulator passes (`driver/tests/serial_e2e.rs`),
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

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use cogstep_test_support::serial::{idle_line, DeviceLink, RawPort};
use cogstep_test_support::status::{finish, is_done, wait_in, wait_until};
use driver::profile::PlanError;
use driver::serial::host::{SerialBoard, SerialConfig, FAULT_DISCONNECTED, FAULT_LOST_MID_MOVE};
use driver::serial::sim::{BoardSim, SimConfig};
use driver::serial::StatusLine;
use driver::{AxisContract, AxisError, AxisState, ClockMode, Hub, HubConfig, Mode};

/// The longest any wait in these tests may take before it fails.
const PATIENCE: Duration = Duration::from_secs(30);
/// The firmware's clock, Hz.
const CLKFREQ: u32 = 50_000_000;

const WHY: &str = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it";

/// The firmware under QEMU, through `firmware/run-qemu`; taken down
/// (SIGTERM to the script, which stops QEMU) when dropped.
struct Qemu {
    script: Child,
    path: String,
}

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the tests crate sits in the repository")
        .to_path_buf()
}

impl Qemu {
    fn start(axes: usize) -> Qemu {
        let mut script = Command::new(repo_root().join("firmware/run-qemu"))
            .args(["--axes", &axes.to_string()])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("firmware/run-qemu starts");
        let stdout = script.stdout.take().expect("its stdout");
        let mut first = String::new();
        BufReader::new(stdout)
            .read_line(&mut first)
            .expect("run-qemu prints the device path");
        let path = first.trim().to_string();
        assert!(path.starts_with("/dev/"), "run-qemu printed {first:?}");
        Qemu { script, path }
    }

    fn path(&self) -> &str {
        &self.path
    }

    /// SIGTERM, as a person's Ctrl-C or a supervisor would; run-qemu takes
    /// QEMU down with it.
    fn stop(mut self) {
        self.terminate();
    }

    fn terminate(&mut self) {
        if let Ok(None) = self.script.try_wait() {
            let _ = Command::new("kill")
                .args(["-TERM", &self.script.id().to_string()])
                .status();
            let start = Instant::now();
            while start.elapsed() < PATIENCE {
                if let Ok(Some(_)) = self.script.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = self.script.kill();
            let _ = self.script.wait();
        }
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        self.terminate();
    }
}

fn config(path: &str) -> SerialConfig {
    SerialConfig {
        poll_interval: Duration::from_millis(20),
        timeout: Duration::from_secs(3),
        ..SerialConfig::new(path)
    }
}

fn open(path: &str) -> SerialBoard {
    SerialBoard::open(config(path)).expect("the firmware answers")
}

fn identity(axes: usize) -> String {
    format!(
        "[cogstep {} proto:1 axes:{axes} clkfreq:{CLKFREQ}]",
        env!("CARGO_PKG_VERSION")
    )
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn every_realtime_byte_gets_its_exact_reply() {
    let _ = WHY;
    let qemu = Qemu::start(2);
    let mut raw = RawPort::open_when_answering(qemu.path(), PATIENCE);

    assert_eq!(
        raw.status(2),
        [idle_line(0, 0, "high"), idle_line(1, 0, "high")]
    );
    raw.assert_silent();

    raw.send(b"!");
    raw.assert_silent();
    assert_eq!(
        raw.status(2),
        [idle_line(0, 0, "low"), idle_line(1, 0, "low")]
    );
    assert_eq!(raw.command("R *"), ["ok"]);

    raw.send(&[0x18]);
    raw.assert_silent();
    assert_eq!(
        raw.status(2),
        [
            "<0|Alarm|pos:0|stm:0|togo:0|mode:000000|vel:0|stop:high>",
            "<1|Alarm|pos:0|stm:0|togo:0|mode:000000|vel:0|stop:high>"
        ]
    );

    // 0x18 also forgets a half-sent line.
    raw.send(b"M 0 100 1");
    raw.send(&[0x18]);
    assert_eq!(raw.command("P 0 5"), ["ok"]);
    // A realtime byte inside a line acts at once and leaves the line whole.
    raw.send(b"P 1 1?5\n");
    assert_eq!(
        raw.lines(3),
        [
            "<0|Alarm|pos:5|stm:0|togo:0|mode:000000|vel:0|stop:high>",
            "<1|Alarm|pos:0|stm:0|togo:0|mode:000000|vel:0|stop:high>",
            "ok"
        ]
    );
    assert_eq!(
        raw.status(2)[1],
        "<1|Alarm|pos:15|stm:0|togo:0|mode:000000|vel:0|stop:high>"
    );
    qemu.stop();
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn every_command_line_gets_its_reply() {
    let qemu = Qemu::start(2);
    let mut raw = RawPort::open_when_answering(qemu.path(), PATIENCE);

    assert_eq!(raw.command("I"), [identity(2), "ok".to_string()]);
    assert_eq!(raw.command("  p   1  -7 "), ["ok"]);
    assert_eq!(raw.status(2)[1], idle_line(1, -7, "high"));

    assert_eq!(raw.command("M 0 3000 400"), ["ok"]);
    let running = raw.status(2);
    assert!(running[0].starts_with("<0|Run|pos:"), "{running:?}");
    assert_eq!(raw.command("P 0 0"), ["error:7 not idle"]);
    let start = Instant::now();
    while raw.status(2)[0] != idle_line(0, 400, "high") {
        assert!(start.elapsed() < PATIENCE, "the move did not end");
        std::thread::sleep(Duration::from_millis(20));
    }

    assert_eq!(raw.command("J 1 800 +"), ["ok"]);
    let jogging = raw.status(2);
    assert!(jogging[1].starts_with("<1|Jog|"), "{jogging:?}");
    assert_eq!(raw.command("S 1"), ["ok"]);
    assert!(raw.status(2)[1].ends_with("|stop:low>"));
    assert_eq!(raw.command("R 1"), ["ok"]);
    assert!(raw.status(2)[1].ends_with("|stop:high>"));
    assert_eq!(raw.command("M 0 3000 -400"), ["ok"]);
    assert_eq!(raw.command("E"), ["ok"]);
    let stopped = raw.status(2);
    assert!(stopped[0].starts_with("<0|Alarm|"), "{stopped:?}");
    assert!(stopped[1].starts_with("<1|Alarm|"), "{stopped:?}");

    // Refusals: each its code, nothing changed, and the next line works.
    let before = raw.status(2);
    for (line, reply) in [
        ("frobnicate", "error:1 unknown command"),
        ("M 0 100 0", "error:2 bad argument"),
        ("J 0 100 x", "error:2 bad argument"),
        ("M 5 100 100", "error:4 no such axis"),
        ("S 2", "error:4 no such axis"),
        ("M 0 0 100", "error:6 speed out of range"),
        (
            "M 0 4294967295 2147483647",
            "error:6 speed out of range: 4294967295 steps/s is too fast for 50000000 Hz",
        ),
        (
            "M 0 50000000 100",
            "error:6 speed out of range: no room for the step pulse at 50000000 steps/s",
        ),
        ("M 1 100 200*00", "error:8 checksum"),
        // No GPIO input is read on this board (firmware/README.md): homing
        // and hard limits are refused plainly.
        (
            "H 0 14 0 - 4000 400 100 10000 0",
            "error:1 not supported: homing",
        ),
        ("K 0 - 22/0", "error:1 not supported: hard limits"),
        ("C 0", "error:1 not supported: hard limits"),
    ] {
        assert_eq!(raw.command(line), [reply], "{line}");
    }
    assert_eq!(raw.command(&"9".repeat(200)), ["error:5 line too long"]);
    raw.send(b"\r\n  \n");
    raw.assert_silent();
    assert_eq!(raw.status(2), before);
    assert_eq!(raw.command("R *"), ["ok"]);
    qemu.stop();
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn the_backend_identifies_the_board_and_moves_merge() {
    let qemu = Qemu::start(3);
    let board = open(qemu.path());
    assert_eq!(board.identity(), identity(3));
    assert_eq!(board.axis_count(), 3);
    assert_eq!(board.clkfreq(), CLKFREQ);
    assert_eq!(board.fault(), None);
    assert!(board.axis(3).is_none());
    let (x, y, z) = (
        board.axis(0).unwrap(),
        board.axis(1).unwrap(),
        board.axis(2).unwrap(),
    );

    x.move_steps(4_000, 600).unwrap();
    y.move_steps(4_000, -300).unwrap();
    z.move_steps(6_000, 900).unwrap();
    assert!(x.status().unwrap().steps_to_go > 0);
    finish(&x, PATIENCE, 600);
    finish(&y, PATIENCE, -300);
    finish(&z, PATIENCE, 900);

    // Same direction and speed while moving: merged, no stop in between.
    x.move_steps(4_000, 1_500).unwrap();
    x.move_steps(4_000, 1_500).unwrap();
    let start = Instant::now();
    loop {
        let status = x.status().unwrap();
        if status.position == 3_600 && is_done(&status) {
            break;
        }
        assert!(
            !is_done(&status),
            "the axis stopped between the merged moves: {status:?}"
        );
        assert!(start.elapsed() < PATIENCE, "{status:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
    board.close();
    qemu.stop();
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn stop_and_resume_reach_the_exact_target() {
    let qemu = Qemu::start(1);
    let board = open(qemu.path());
    let x = board.axis(0).unwrap();

    x.move_steps(4_000, 3_000).unwrap();
    wait_until(&x, PATIENCE, "some progress", |status| {
        status.position > 500
    });
    x.set_stop_pin(false).unwrap();
    let held = wait_until(&x, PATIENCE, "a controlled stop", |status| {
        is_done(status) && status.state() == AxisState::Hold
    });
    assert!(!held.stop_pin_high);
    assert!(held.mode.has(Mode::STOP_LATCHED));
    assert!(held.position < 3_000, "{held:?}");
    let remaining = i32::try_from(3_000 - held.position).unwrap();
    x.set_stop_pin(true).unwrap();
    x.move_steps(4_000, remaining).unwrap();
    let done = finish(&x, PATIENCE, 3_000);
    assert_eq!(done.state(), AxisState::Idle);
    board.close();
    qemu.stop();
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn emergency_stop_keeps_the_position_and_set_position_needs_idle() {
    let qemu = Qemu::start(2);
    let board = open(qemu.path());
    let x = board.axis(0).unwrap();

    x.move_steps(4_000, 5_000).unwrap();
    assert_eq!(x.set_position(0), Err(AxisError::NotIdle));
    wait_until(&x, PATIENCE, "some progress", |status| {
        status.position > 300
    });
    x.emergency_stop().unwrap();
    let stopped = wait_until(&x, PATIENCE, "the alarm", |status| {
        status.state() == AxisState::Alarm
    });
    assert_eq!(stopped.steps_to_go, 0);
    std::thread::sleep(Duration::from_millis(100));
    board.refresh().unwrap();
    assert_eq!(x.status().unwrap().position, stopped.position);

    x.set_position(1_234).unwrap();
    assert_eq!(x.status().unwrap().position, 1_234);
    x.move_steps(4_000, -234).unwrap();
    let done = finish(&x, PATIENCE, 1_000);
    assert_eq!(done.state(), AxisState::Idle);

    board.emergency_stop_all().unwrap();
    assert_eq!(x.status().unwrap().state(), AxisState::Alarm);
    assert_eq!(
        board.axis(1).unwrap().status().unwrap().state(),
        AxisState::Alarm
    );
    board.close();
    qemu.stop();
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn refusals_come_back_as_axis_errors_and_change_nothing() {
    let qemu = Qemu::start(1);
    let board = open(qemu.path());
    let x = board.axis(0).unwrap();

    assert_eq!(
        x.move_steps(0, 10),
        Err(AxisError::Plan(PlanError::ZeroSpeed))
    );
    assert_eq!(
        x.move_steps(10, 0),
        Err(AxisError::Plan(PlanError::ZeroSteps))
    );
    assert_eq!(
        x.move_steps(u32::MAX, i32::MAX),
        Err(AxisError::Plan(PlanError::SpeedTooHigh {
            speed: u32::MAX,
            clkfreq: CLKFREQ
        }))
    );
    // Planned fine, but the 5 µs pulse does not fit: refused by the board.
    assert_eq!(
        x.move_steps(1_000_000, 100),
        Err(AxisError::PulseTooLong { speed: 1_000_000 })
    );
    // A move while a reversal is waiting for the axis to stop: busy.
    x.move_steps(4_000, 3_000).unwrap();
    wait_until(&x, PATIENCE, "some progress", |status| {
        status.position > 100
    });
    x.move_steps(4_000, -100).unwrap();
    assert_eq!(x.move_steps(4_000, -100), Err(AxisError::Busy));
    let status = wait_until(&x, PATIENCE, "the reversal", is_done);
    let reversal_done = status.position;
    assert!(reversal_done < 3_000, "{status:?}");
    // Nothing else changed, and the link is fine.
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(x.status().unwrap().position, reversal_done);
    assert_eq!(board.fault(), None);
    board.close();
    qemu.stop();
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn jog_runs_while_heartbeats_come_and_release_stops_it() {
    let qemu = Qemu::start(1);
    let board = open(qemu.path());
    let x = board.axis(0).unwrap();

    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(400) {
        x.jog(2_000, driver::Direction::Reverse).unwrap();
        std::thread::sleep(Duration::from_millis(30));
    }
    let jogging = x.status().unwrap();
    assert_eq!(jogging.state(), AxisState::Jog);
    assert!(jogging.position < 0);
    x.jog_release().unwrap();
    let released = wait_until(&x, PATIENCE, "the release", |status| {
        is_done(status) && status.stop_pin_high && status.state() == AxisState::Idle
    });
    assert!(released.position < jogging.position);
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(x.status().unwrap().position, released.position);
    x.move_steps(3_000, 200).unwrap();
    finish(&x, PATIENCE, released.position + 200);
    board.close();
    qemu.stop();
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn qemu_killed_mid_move_is_a_fault_not_a_hang() {
    let qemu = Qemu::start(1);
    let board = open(qemu.path());
    let x = board.axis(0).unwrap();
    x.move_steps(3_000, 30_000).unwrap();
    wait_until(&x, PATIENCE, "the move", |status| status.position > 10);
    qemu.stop();

    let start = Instant::now();
    while board.fault().is_none() {
        assert!(start.elapsed() < PATIENCE, "no fault reported");
        std::thread::sleep(Duration::from_millis(5));
    }
    let fault = board.fault().unwrap();
    assert!(fault.starts_with("disconnected"), "{fault}");
    assert!(!board.is_connected());
    let start = Instant::now();
    assert_eq!(x.status(), Err(AxisError::Fault(FAULT_DISCONNECTED)));
    assert_eq!(
        x.move_steps(100, 10),
        Err(AxisError::Fault(FAULT_DISCONNECTED))
    );
    assert!(start.elapsed() < Duration::from_secs(2));
    let start = Instant::now();
    board.close();
    assert!(start.elapsed() < Duration::from_secs(2));
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn the_backend_reconnects_to_a_fresh_qemu() {
    let first = Qemu::start(2);
    let device = DeviceLink::new(first.path());
    let board = open(device.path());
    let (x, y) = (board.axis(0).unwrap(), board.axis(1).unwrap());
    x.move_steps(3_000, 30_000).unwrap();
    wait_until(&x, PATIENCE, "the move", |status| status.position > 10);

    device.remove();
    first.stop();
    let start = Instant::now();
    while board.is_connected() {
        assert!(start.elapsed() < PATIENCE, "the loss went unnoticed");
        std::thread::sleep(Duration::from_millis(5));
    }

    let second = Qemu::start(2);
    device.point_at(second.path());
    let start = Instant::now();
    while !board.is_connected() {
        assert!(start.elapsed() < PATIENCE, "no reconnection");
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(x.status(), Err(AxisError::Fault(FAULT_LOST_MID_MOVE)));
    assert_eq!(y.status().unwrap().position, 0);
    x.move_steps(3_000, 200).unwrap();
    assert_eq!(board.fault(), None);
    finish(&x, PATIENCE, 200);
    board.close();
    second.stop();
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn a_half_written_line_is_not_run_when_the_backend_connects() {
    let qemu = Qemu::start(1);
    let mut raw = RawPort::open_when_answering(qemu.path(), PATIENCE);
    raw.send(b"M 0 4000 300");
    drop(raw);
    let board = open(qemu.path());
    let x = board.axis(0).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    board.refresh().unwrap();
    let status = x.status().unwrap();
    assert_eq!((status.position, status.state()), (0, AxisState::Idle));
    board.close();
    qemu.stop();
}

/// One scenario through the axis contract: moves on three axes, a merge,
/// a stop (stop pin low mid-move) and the rest of that move. Returns the
/// status lines at the end and the steps the stop left (target minus the
/// position where the axis came to rest).
fn three_axis_scenario(axes: [&dyn AxisContract; 3], pause: &dyn Fn()) -> (Vec<String>, i64) {
    let [x, y, z] = axes;
    x.move_steps(4_000, 1_200).unwrap();
    y.move_steps(5_000, -800).unwrap();
    z.move_steps(3_000, 2_000).unwrap();
    // The merge: same direction and speed while x moves.
    wait_in(x, PATIENCE, "x under way", pause, |status| {
        status.position > 100
    });
    x.move_steps(4_000, 800).unwrap();
    // The stop: z's stop pin low mid-move; it decelerates and holds.
    wait_in(z, PATIENCE, "z under way", pause, |status| {
        status.position > 300
    });
    z.set_stop_pin(false).unwrap();
    let held = wait_in(z, PATIENCE, "z held", pause, |status| {
        is_done(status) && status.state() == AxisState::Hold
    });
    let dropped = 2_000 - held.position;
    z.set_stop_pin(true).unwrap();
    z.move_steps(3_000, i32::try_from(dropped).unwrap())
        .unwrap();
    let finals = [(x, 2_000), (y, -800), (z, 2_000)]
        .into_iter()
        .enumerate()
        .map(|(index, (axis, target))| {
            let status = wait_in(
                axis,
                PATIENCE,
                &format!("position {target}"),
                pause,
                |status| is_done(status) && status.position == target,
            );
            StatusLine::new(index, &status).to_string()
        })
        .collect();
    (finals, dropped)
}

#[test]
#[ignore = "needs qemu-system-arm and the firmware toolchain: .ci/run runs it"]
fn same_behaviour_in_three_homes() {
    // 1. The virtual hub at the firmware's clock: time passes 1 ms of CT
    // per look at the status.
    let hub = Hub::new(HubConfig {
        clkfreq: CLKFREQ,
        clock: ClockMode::Virtual,
        pulse_ticks: 250,
        dir_setup_ticks: 250,
        ..HubConfig::default()
    })
    .unwrap();
    let hub_axes = [
        hub.start_sd(0, 1, 2).unwrap(),
        hub.start_cc(3, 4, 5).unwrap(),
        hub.start_sd(6, 7, 8).unwrap(),
    ];
    for axis in &hub_axes {
        axis.set_stop_pin(true).unwrap();
    }
    let advance = || {
        hub.advance(u64::from(CLKFREQ) / 1_000);
    };
    let on_hub = three_axis_scenario([&hub_axes[0], &hub_axes[1], &hub_axes[2]], &advance);
    hub.shutdown();

    let sleep = || std::thread::sleep(Duration::from_millis(5));

    // 2. The board simulator, over a pseudo-terminal.
    let (sim, sim_path) = BoardSim::spawn_pty(SimConfig {
        axes: 3,
        clkfreq: CLKFREQ,
        ..SimConfig::default()
    })
    .unwrap();
    let sim_board = open(&sim_path);
    let sim_axes: Vec<_> = (0..3).map(|i| sim_board.axis(i).unwrap()).collect();
    let on_sim = three_axis_scenario([&sim_axes[0], &sim_axes[1], &sim_axes[2]], &sleep);
    sim_board.close();
    sim.stop();

    // 3. The firmware under QEMU.
    let qemu = Qemu::start(3);
    let fw_board = open(qemu.path());
    let fw_axes: Vec<_> = (0..3).map(|i| fw_board.axis(i).unwrap()).collect();
    let on_firmware = three_axis_scenario([&fw_axes[0], &fw_axes[1], &fw_axes[2]], &sleep);
    fw_board.close();
    qemu.stop();

    let expected = vec![
        "<0|Idle|pos:2000|stm:0|togo:0|mode:000000|vel:0|stop:high>".to_string(),
        "<1|Idle|pos:-800|stm:0|togo:0|mode:000000|vel:0|stop:high>".to_string(),
        "<2|Idle|pos:2000|stm:0|togo:0|mode:000000|vel:0|stop:high>".to_string(),
    ];
    assert_eq!(on_hub.0, expected, "the hub");
    assert_eq!(on_sim.0, expected, "board-sim");
    assert_eq!(on_firmware.0, expected, "the firmware");
    // Where each home stopped depends on when the stop came (the boards
    // run in real time); each left some steps, and finished them.
    for (home, dropped) in [("hub", on_hub.1), ("sim", on_sim.1), ("fw", on_firmware.1)] {
        assert!(dropped > 0 && dropped < 1_700, "{home}: {dropped}");
    }
}

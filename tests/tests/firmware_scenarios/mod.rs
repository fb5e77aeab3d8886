//! The scenarios every firmware board passes over its serial port, run by
//! `firmware_qemu.rs` (the LM3S6965 under QEMU) and `firmware_pico.rs`
//! (the Pico under rp2040py), each with its [`Firmware`]: the host backend
//! (`SerialBoard`) or a raw port on the board's pseudo-terminal, and one
//! scenario run in all three homes (the virtual hub, the board simulator
//! and the firmware). `driver/tests/serial_e2e.rs` passes the same ones
//! against the board simulator.

use std::time::{Duration, Instant};

use cogstep_test_support::script::DeviceScript;
use cogstep_test_support::serial::{idle_line, DeviceLink, RawPort};
use cogstep_test_support::status::{finish, is_done, wait_in, wait_until};
use driver::profile::PlanError;
use driver::serial::host::{SerialBoard, SerialConfig, FAULT_DISCONNECTED, FAULT_LOST_MID_MOVE};
use driver::serial::sim::{BoardSim, SimConfig};
use driver::serial::StatusLine;
use driver::{AxisContract, AxisError, AxisState, ClockMode, Hub, HubConfig, Mode};

/// A firmware board behind the script that runs it.
pub struct Firmware {
    /// The script, from the repository's root: it prints the device path
    /// first and stops on SIGTERM.
    pub script: &'static str,
    /// Its arguments besides `--axes N`.
    pub args: &'static [&'static str],
    /// Whether it reads control lines on its standard input (kept open).
    pub control: bool,
    /// The clock its CT counts, Hz (the identity line's `clkfreq`).
    pub clkfreq: u32,
    /// Its step pulse and direction set-up, CT ticks (5 µs).
    pub pulse_ticks: u32,
    /// The board simulator's clock in the three-homes scenario: the
    /// firmware's where the simulator's 1,000-tick pulse fits its speeds,
    /// otherwise (`None`) the simulator's own.
    pub sim_clkfreq: Option<u32>,
    /// The longest any wait may take before it fails.
    pub patience: Duration,
    /// Command lines this board answers in its own words (what it does
    /// not support), with their replies.
    pub own_replies: &'static [(&'static str, &'static str)],
}

impl Firmware {
    /// The board with `axes` axes, stopped (SIGTERM) when dropped.
    pub fn start(&self, axes: usize) -> DeviceScript {
        let axes = axes.to_string();
        let mut args = vec!["--axes", axes.as_str()];
        args.extend(self.args);
        DeviceScript::start(self.script, &args, self.control)
    }

    /// Its identity line with `axes` axes.
    pub fn identity(&self, axes: usize) -> String {
        format!(
            "[cogstep {} proto:1 axes:{axes} clkfreq:{}]",
            env!("CARGO_PKG_VERSION"),
            self.clkfreq
        )
    }
}

pub fn config(path: &str) -> SerialConfig {
    SerialConfig {
        poll_interval: Duration::from_millis(20),
        timeout: Duration::from_secs(3),
        ..SerialConfig::new(path)
    }
}

pub fn open(path: &str) -> SerialBoard {
    SerialBoard::open(config(path)).expect("the firmware answers")
}

pub fn every_realtime_byte_gets_its_exact_reply(firmware: &Firmware) {
    let device = firmware.start(2);
    let mut raw = RawPort::open_when_answering(device.path(), firmware.patience);

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
    device.stop();
}

pub fn every_command_line_gets_its_reply(firmware: &Firmware) {
    let device = firmware.start(2);
    let mut raw = RawPort::open_when_answering(device.path(), firmware.patience);

    assert_eq!(raw.command("I"), [firmware.identity(2), "ok".to_string()]);
    assert_eq!(raw.command("  p   1  -7 "), ["ok"]);
    assert_eq!(raw.status(2)[1], idle_line(1, -7, "high"));

    assert_eq!(raw.command("M 0 3000 400"), ["ok"]);
    let running = raw.status(2);
    assert!(running[0].starts_with("<0|Run|pos:"), "{running:?}");
    assert_eq!(raw.command("P 0 0"), ["error:7 not idle"]);
    let start = Instant::now();
    while raw.status(2)[0] != idle_line(0, 400, "high") {
        assert!(start.elapsed() < firmware.patience, "the move did not end");
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
        ("M 1 100 200*00", "error:8 checksum"),
    ] {
        assert_eq!(raw.command(line), [reply], "{line}");
    }
    let clkfreq = firmware.clkfreq;
    for (line, reply) in [
        (
            "M 0 4294967295 2147483647".to_string(),
            format!("error:6 speed out of range: 4294967295 steps/s is too fast for {clkfreq} Hz"),
        ),
        (
            format!("M 0 {clkfreq} 100"),
            format!("error:6 speed out of range: no room for the step pulse at {clkfreq} steps/s"),
        ),
    ] {
        assert_eq!(raw.command(&line), [reply], "{line}");
    }
    for &(line, reply) in firmware.own_replies {
        assert_eq!(raw.command(line), [reply], "{line}");
    }
    assert_eq!(raw.command(&"9".repeat(200)), ["error:5 line too long"]);
    raw.send(b"\r\n  \n");
    raw.assert_silent();
    assert_eq!(raw.status(2), before);
    assert_eq!(raw.command("R *"), ["ok"]);
    device.stop();
}

pub fn the_backend_identifies_the_board_and_moves_merge(firmware: &Firmware) {
    let device = firmware.start(3);
    let board = open(device.path());
    assert_eq!(board.identity(), firmware.identity(3));
    assert_eq!(board.axis_count(), 3);
    assert_eq!(board.clkfreq(), firmware.clkfreq);
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
    finish(&x, firmware.patience, 600);
    finish(&y, firmware.patience, -300);
    finish(&z, firmware.patience, 900);

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
        assert!(start.elapsed() < firmware.patience, "{status:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
    board.close();
    device.stop();
}

pub fn stop_and_resume_reach_the_exact_target(firmware: &Firmware) {
    let device = firmware.start(1);
    let board = open(device.path());
    let x = board.axis(0).unwrap();

    x.move_steps(4_000, 3_000).unwrap();
    wait_until(&x, firmware.patience, "some progress", |status| {
        status.position > 500
    });
    x.set_stop_pin(false).unwrap();
    let held = wait_until(&x, firmware.patience, "a controlled stop", |status| {
        is_done(status) && status.state() == AxisState::Hold
    });
    assert!(!held.stop_pin_high);
    assert!(held.mode.has(Mode::STOP_LATCHED));
    assert!(held.position < 3_000, "{held:?}");
    let remaining = i32::try_from(3_000 - held.position).unwrap();
    x.set_stop_pin(true).unwrap();
    x.move_steps(4_000, remaining).unwrap();
    let done = finish(&x, firmware.patience, 3_000);
    assert_eq!(done.state(), AxisState::Idle);
    board.close();
    device.stop();
}

/// A group move (`G`) through the backend: every member refuses a move
/// of its own while it runs, the stop pin of one member (the one with no
/// steps) stops the whole line, each member at rest within one step of
/// its line, and a group move of the steps left completes it exactly.
pub fn a_group_move_keeps_its_line_through_a_members_stop(firmware: &Firmware) {
    let device = firmware.start(3);
    let board = open(device.path());
    let axes: Vec<_> = (0..3).map(|index| board.axis(index).unwrap()).collect();
    let (lead_steps, follower_steps) = (1_500, -500);
    board
        .move_together(&[lead_steps, follower_steps, 0], 3_000)
        .unwrap();
    assert_eq!(axes[1].move_steps(1_000, 10), Err(AxisError::Busy));
    assert_eq!(
        board.move_together(&[10], 1_000),
        Err(AxisError::Busy),
        "a group move while its members move"
    );
    wait_until(
        &axes[0],
        firmware.patience,
        "the line under way",
        |status| status.position > 300,
    );
    axes[2].set_stop_pin(false).unwrap();
    let rest: Vec<_> = axes
        .iter()
        .map(|axis| wait_until(axis, firmware.patience, "at rest", is_done))
        .collect();
    let (lead, follower) = (rest[0].position, rest[1].position);
    assert!(
        lead < i64::from(lead_steps),
        "the lead ran to its end: {lead}"
    );
    let line = f64::from(follower_steps) * lead as f64 / f64::from(lead_steps);
    assert!(
        (follower as f64 - line).abs() <= 1.0,
        "the follower at {follower}, its line at {line}"
    );
    assert!(rest[0].mode.has(Mode::STOP_LATCHED), "{:?}", rest[0]);
    assert_eq!(rest[2].position, 0);
    axes[2].set_stop_pin(true).unwrap();
    let left = [
        i32::try_from(i64::from(lead_steps) - lead).unwrap(),
        i32::try_from(i64::from(follower_steps) - follower).unwrap(),
        0,
    ];
    board.move_together(&left, 3_000).unwrap();
    finish(&axes[0], firmware.patience, i64::from(lead_steps));
    finish(&axes[1], firmware.patience, i64::from(follower_steps));
    board.close();
    device.stop();
}

pub fn emergency_stop_keeps_the_position_and_set_position_needs_idle(firmware: &Firmware) {
    let device = firmware.start(2);
    let board = open(device.path());
    let x = board.axis(0).unwrap();

    x.move_steps(4_000, 5_000).unwrap();
    assert_eq!(x.set_position(0), Err(AxisError::NotIdle));
    wait_until(&x, firmware.patience, "some progress", |status| {
        status.position > 300
    });
    x.emergency_stop().unwrap();
    let stopped = wait_until(&x, firmware.patience, "the alarm", |status| {
        status.state() == AxisState::Alarm
    });
    assert_eq!(stopped.steps_to_go, 0);
    std::thread::sleep(Duration::from_millis(100));
    board.refresh().unwrap();
    assert_eq!(x.status().unwrap().position, stopped.position);

    x.set_position(1_234).unwrap();
    assert_eq!(x.status().unwrap().position, 1_234);
    x.move_steps(4_000, -234).unwrap();
    let done = finish(&x, firmware.patience, 1_000);
    assert_eq!(done.state(), AxisState::Idle);

    board.emergency_stop_all().unwrap();
    assert_eq!(x.status().unwrap().state(), AxisState::Alarm);
    assert_eq!(
        board.axis(1).unwrap().status().unwrap().state(),
        AxisState::Alarm
    );
    board.close();
    device.stop();
}

pub fn refusals_come_back_as_axis_errors_and_change_nothing(firmware: &Firmware) {
    let device = firmware.start(1);
    let board = open(device.path());
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
            clkfreq: firmware.clkfreq
        }))
    );
    // Planned fine, but the 5 µs pulse does not fit: refused by the board.
    assert_eq!(
        x.move_steps(1_000_000, 100),
        Err(AxisError::PulseTooLong { speed: 1_000_000 })
    );
    // A move while a reversal is waiting for the axis to stop: busy.
    x.move_steps(4_000, 3_000).unwrap();
    wait_until(&x, firmware.patience, "some progress", |status| {
        status.position > 100
    });
    x.move_steps(4_000, -100).unwrap();
    assert_eq!(x.move_steps(4_000, -100), Err(AxisError::Busy));
    let status = wait_until(&x, firmware.patience, "the reversal", is_done);
    let reversal_done = status.position;
    assert!(reversal_done < 3_000, "{status:?}");
    // Nothing else changed, and the link is fine.
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(x.status().unwrap().position, reversal_done);
    assert_eq!(board.fault(), None);
    board.close();
    device.stop();
}

pub fn jog_runs_while_heartbeats_come_and_release_stops_it(firmware: &Firmware) {
    let device = firmware.start(1);
    let board = open(device.path());
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
    let released = wait_until(&x, firmware.patience, "the release", |status| {
        is_done(status) && status.stop_pin_high && status.state() == AxisState::Idle
    });
    assert!(released.position < jogging.position);
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(x.status().unwrap().position, released.position);
    x.move_steps(3_000, 200).unwrap();
    finish(&x, firmware.patience, released.position + 200);
    board.close();
    device.stop();
}

pub fn the_board_killed_mid_move_is_a_fault_not_a_hang(firmware: &Firmware) {
    let device = firmware.start(1);
    let board = open(device.path());
    let x = board.axis(0).unwrap();
    x.move_steps(3_000, 30_000).unwrap();
    wait_until(&x, firmware.patience, "the move", |status| {
        status.position > 10
    });
    device.stop();

    let start = Instant::now();
    while board.fault().is_none() {
        assert!(start.elapsed() < firmware.patience, "no fault reported");
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

pub fn the_backend_reconnects_to_a_fresh_board(firmware: &Firmware) {
    let first = firmware.start(2);
    let device = DeviceLink::new(first.path());
    let board = open(device.path());
    let (x, y) = (board.axis(0).unwrap(), board.axis(1).unwrap());
    x.move_steps(3_000, 30_000).unwrap();
    wait_until(&x, firmware.patience, "the move", |status| {
        status.position > 10
    });

    device.remove();
    first.stop();
    let start = Instant::now();
    while board.is_connected() {
        assert!(
            start.elapsed() < firmware.patience,
            "the loss went unnoticed"
        );
        std::thread::sleep(Duration::from_millis(5));
    }

    let second = firmware.start(2);
    device.point_at(second.path());
    let start = Instant::now();
    while !board.is_connected() {
        assert!(start.elapsed() < firmware.patience, "no reconnection");
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(x.status(), Err(AxisError::Fault(FAULT_LOST_MID_MOVE)));
    assert_eq!(y.status().unwrap().position, 0);
    x.move_steps(3_000, 200).unwrap();
    assert_eq!(board.fault(), None);
    finish(&x, firmware.patience, 200);
    board.close();
    second.stop();
}

pub fn a_half_written_line_is_not_run_when_the_backend_connects(firmware: &Firmware) {
    let device = firmware.start(1);
    let mut raw = RawPort::open_when_answering(device.path(), firmware.patience);
    raw.send(b"M 0 4000 300");
    drop(raw);
    let board = open(device.path());
    let x = board.axis(0).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    board.refresh().unwrap();
    let status = x.status().unwrap();
    assert_eq!((status.position, status.state()), (0, AxisState::Idle));
    board.close();
    device.stop();
}

/// One scenario through the axis contract: moves on three axes, a merge,
/// a stop (stop pin low mid-move) and the rest of that move. Returns the
/// status lines at the end and the steps the stop left (target minus the
/// position where the axis came to rest).
fn three_axis_scenario(
    axes: [&dyn AxisContract; 3],
    patience: Duration,
    pause: &dyn Fn(),
) -> (Vec<String>, i64) {
    let [x, y, z] = axes;
    x.move_steps(4_000, 1_200).unwrap();
    y.move_steps(5_000, -800).unwrap();
    z.move_steps(3_000, 2_000).unwrap();
    // The merge: same direction and speed while x moves.
    wait_in(x, patience, "x under way", pause, |status| {
        status.position > 100
    });
    x.move_steps(4_000, 800).unwrap();
    // The stop: z's stop pin low mid-move; it decelerates and holds.
    wait_in(z, patience, "z under way", pause, |status| {
        status.position > 300
    });
    z.set_stop_pin(false).unwrap();
    let held = wait_in(z, patience, "z held", pause, |status| {
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
                patience,
                &format!("position {target}"),
                pause,
                |status| is_done(status) && status.position == target,
            );
            StatusLine::new(index, &status).to_string()
        })
        .collect();
    (finals, dropped)
}

pub fn same_behaviour_in_three_homes(firmware: &Firmware) {
    // 1. The virtual hub at the firmware's clock: time passes 1 ms of CT
    // per look at the status.
    let hub = Hub::new(HubConfig {
        clkfreq: firmware.clkfreq,
        clock: ClockMode::Virtual,
        pulse_ticks: firmware.pulse_ticks,
        dir_setup_ticks: firmware.pulse_ticks,
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
        hub.advance(u64::from(firmware.clkfreq) / 1_000);
    };
    let on_hub = three_axis_scenario(
        [&hub_axes[0], &hub_axes[1], &hub_axes[2]],
        firmware.patience,
        &advance,
    );
    hub.shutdown();

    let sleep = || std::thread::sleep(Duration::from_millis(5));

    // 2. The board simulator, over a pseudo-terminal.
    let (sim, sim_path) = BoardSim::spawn_pty(SimConfig {
        axes: 3,
        clkfreq: firmware.sim_clkfreq.unwrap_or(SimConfig::default().clkfreq),
        ..SimConfig::default()
    })
    .unwrap();
    let sim_board = open(&sim_path);
    let sim_axes: Vec<_> = (0..3).map(|i| sim_board.axis(i).unwrap()).collect();
    let on_sim = three_axis_scenario(
        [&sim_axes[0], &sim_axes[1], &sim_axes[2]],
        firmware.patience,
        &sleep,
    );
    sim_board.close();
    sim.stop();

    // 3. The firmware.
    let device = firmware.start(3);
    let fw_board = open(device.path());
    let fw_axes: Vec<_> = (0..3).map(|i| fw_board.axis(i).unwrap()).collect();
    let on_firmware = three_axis_scenario(
        [&fw_axes[0], &fw_axes[1], &fw_axes[2]],
        firmware.patience,
        &sleep,
    );
    fw_board.close();
    device.stop();

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

//! The serial protocol end to end, over real pseudo-terminals: a board
//! simulator (`BoardSim`, a real-time hub) on one end, the host backend
//! (`SerialBoard`) or a raw port on the other.
//!
//! Moves run in real time, so they are short (a few hundred to a few
//! thousand steps at a few thousand steps/s) and every wait has a generous
//! limit; nothing here asserts how fast anything is.
#![cfg(all(unix, feature = "std"))]

use std::io::Write;
use std::time::{Duration, Instant};

use cogstep_test_support::serial::{idle_line, DeviceLink, RawPort};
use cogstep_test_support::status::{finish, is_done, wait_until};
use driver::serial::host::{
    Capabilities, DemoStart, Dialect, SerialBoard, SerialConfig, SerialError, FAULT_DISCONNECTED,
    FAULT_LOST_MID_MOVE, FAULT_RESET_MID_MOVE, P2DEMO_IDENTITY, P2DEMO_UNSUPPORTED,
};
use driver::serial::p2demo::DemoFlaw;
use driver::serial::sim::{BoardSim, SimConfig};
use driver::{AxisContract, AxisError, AxisState, ClockMode, Direction, Hub, HubConfig, Mode};

/// The longest any wait in these tests may take before it fails.
const PATIENCE: Duration = Duration::from_secs(20);

fn sim(axes: usize, dialect: Dialect) -> (BoardSim, String) {
    BoardSim::spawn_pty(SimConfig {
        axes,
        clkfreq: 200_000_000,
        dialect,
    })
    .expect("a pseudo-terminal and a hub")
}

/// Polls often; a generous timeout, so that a loaded machine does not
/// take a slow reply for a lost board.
fn config(path: &str, dialect: Dialect) -> SerialConfig {
    SerialConfig {
        dialect,
        poll_interval: Duration::from_millis(20),
        timeout: Duration::from_secs(2),
        ..SerialConfig::new(path)
    }
}

fn open(path: &str) -> SerialBoard {
    SerialBoard::open(config(path, Dialect::Cogstep)).expect("the simulated board answers")
}

#[test]
fn every_realtime_byte_gets_its_exact_reply() {
    let (_sim, path) = sim(2, Dialect::Cogstep);
    let mut raw = RawPort::open(&path, PATIENCE);

    // `?`: one status line per axis, nothing else.
    assert_eq!(
        raw.status(2),
        [idle_line(0, 0, "high"), idle_line(1, 0, "high")]
    );
    raw.assert_silent();

    // `!`: every stop pin low, no output.
    raw.send(b"!");
    raw.assert_silent();
    assert_eq!(
        raw.status(2),
        [idle_line(0, 0, "low"), idle_line(1, 0, "low")]
    );
    assert_eq!(raw.command("R *"), ["ok"]);

    // 0x18: emergency stop of every axis, no output.
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
}

#[test]
fn every_command_line_gets_its_reply() {
    let (_sim, path) = sim(2, Dialect::Cogstep);
    let mut raw = RawPort::open(&path, PATIENCE);

    assert_eq!(
        raw.command("I"),
        [
            format!(
                "[cogstep {} proto:1 axes:2 clkfreq:200000000]",
                env!("CARGO_PKG_VERSION")
            ),
            "ok".to_string()
        ]
    );
    // With a checksum, in lower case, with extra spaces.
    assert_eq!(raw.command("I*49"), raw_identity_reply());
    assert_eq!(raw.command("  p   1  -7 "), ["ok"]);
    assert_eq!(raw.status(2)[1], idle_line(1, -7, "high"));

    // A move: the status line shows it running, then it ends at its target.
    assert_eq!(raw.command("M 0 3000 400"), ["ok"]);
    let running = raw.status(2);
    assert!(running[0].starts_with("<0|Run|pos:"), "{running:?}");
    assert_eq!(raw.command("P 0 0"), ["error:7 not idle"]);
    let start = Instant::now();
    while raw.status(2)[0] != idle_line(0, 400, "high") {
        assert!(start.elapsed() < PATIENCE, "the move did not end");
        std::thread::sleep(Duration::from_millis(20));
    }

    // Jog, stop pin, emergency stop.
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

    // Refusals: each its code, and the next good line works.
    for (line, reply) in [
        ("frobnicate", "error:1 unknown command"),
        ("M 0 100 0", "error:2 bad argument"),
        ("J 0 100 x", "error:2 bad argument"),
        ("M 5 100 100", "error:4 no such axis"),
        ("S 2", "error:4 no such axis"),
        ("M 0 0 100", "error:6 speed out of range"),
        (
            "M 0 4294967295 2147483647",
            "error:6 speed out of range: 4294967295 steps/s is too fast for 200000000 Hz",
        ),
        ("M 1 100 200*00", "error:8 checksum"),
    ] {
        assert_eq!(raw.command(line), [reply], "{line}");
    }
    assert_eq!(raw.command(&"9".repeat(200)), ["error:5 line too long"]);
    // Blank lines get no reply at all.
    raw.send(b"\r\n  \n");
    raw.assert_silent();
    assert_eq!(raw.command("R *"), ["ok"]);
}

fn raw_identity_reply() -> Vec<String> {
    vec![
        format!(
            "[cogstep {} proto:1 axes:2 clkfreq:200000000]",
            env!("CARGO_PKG_VERSION")
        ),
        "ok".to_string(),
    ]
}

#[test]
fn the_backend_identifies_the_board() {
    let (_sim, path) = sim(3, Dialect::Cogstep);
    let board = open(&path);
    assert_eq!(
        board.identity(),
        format!(
            "[cogstep {} proto:1 axes:3 clkfreq:200000000]",
            env!("CARGO_PKG_VERSION")
        )
    );
    assert_eq!(board.axis_count(), 3);
    assert_eq!(board.clkfreq(), 200_000_000);
    assert_eq!(board.capabilities(), Capabilities::ALL);
    assert_eq!(board.fault(), None);
    assert!(board.is_connected());
    assert!(board.axis(2).is_some());
    assert!(board.axis(3).is_none());
    let status = board.axis(1).unwrap().status().unwrap();
    assert_eq!(status.state(), AxisState::Idle);
    assert_eq!(status.position, 0);
    assert!(status.stop_pin_high);
    board.close();
}

#[test]
fn moves_reach_their_targets_and_merge() {
    let (_sim, path) = sim(2, Dialect::Cogstep);
    let board = open(&path);
    let (x, y) = (board.axis(0).unwrap(), board.axis(1).unwrap());

    x.move_steps(4_000, 600).unwrap();
    y.move_steps(4_000, -300).unwrap();
    // The status right after the call already shows the move.
    assert!(x.status().unwrap().steps_to_go > 0);
    finish(&x, PATIENCE, 600);
    finish(&y, PATIENCE, -300);

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
}

#[test]
fn stop_and_resume_reach_the_exact_target() {
    let (_sim, path) = sim(1, Dialect::Cogstep);
    let board = open(&path);
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
    // A move while the pin is low waits (Hold) until the pin goes high.
    let remaining = i32::try_from(3_000 - held.position).unwrap();
    x.set_stop_pin(true).unwrap();
    x.move_steps(4_000, remaining).unwrap();
    let done = finish(&x, PATIENCE, 3_000);
    assert_eq!(done.state(), AxisState::Idle);
    board.close();
}

#[test]
fn emergency_stop_keeps_the_position_and_set_position_needs_idle() {
    let (_sim, path) = sim(2, Dialect::Cogstep);
    let board = open(&path);
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
    assert_eq!(
        board.axis(1).unwrap().status().unwrap().state(),
        AxisState::Alarm
    );

    x.set_position(1_234).unwrap();
    assert_eq!(x.status().unwrap().position, 1_234);
    // The next move clears the alarm.
    x.move_steps(4_000, -234).unwrap();
    let done = finish(&x, PATIENCE, 1_000);
    assert_eq!(done.state(), AxisState::Idle);

    board.emergency_stop_all().unwrap();
    assert_eq!(x.status().unwrap().state(), AxisState::Alarm);
    board.close();
}

#[test]
fn refusals_come_back_as_axis_errors() {
    let (_sim, path) = sim(1, Dialect::Cogstep);
    let board = open(&path);
    let x = board.axis(0).unwrap();
    use driver::profile::PlanError;

    // Checked before anything is sent, as the hub does.
    assert_eq!(
        x.move_steps(0, 10),
        Err(AxisError::Plan(PlanError::ZeroSpeed))
    );
    assert_eq!(
        x.move_steps(10, 0),
        Err(AxisError::Plan(PlanError::ZeroSteps))
    );
    assert_eq!(
        x.jog(0, Direction::Forward),
        Err(AxisError::Plan(PlanError::ZeroSpeed))
    );
    // Refused by the board (error:6), explained by the host's planner.
    assert_eq!(
        x.move_steps(u32::MAX, i32::MAX),
        Err(AxisError::Plan(PlanError::SpeedTooHigh {
            speed: u32::MAX,
            clkfreq: 200_000_000
        }))
    );
    assert_eq!(
        x.move_steps(50_000_000, 100),
        Err(AxisError::PulseTooLong { speed: 50_000_000 })
    );
    // Nothing changed, and the link is fine.
    assert_eq!(x.status().unwrap().position, 0);
    assert_eq!(board.fault(), None);
    board.close();
}

/// The refusals a scenario provokes, each with its name.
type Refused = Vec<(&'static str, Result<(), AxisError>)>;

/// A backend's group move: steps per axis, the lead's speed.
type Together<'a> = &'a dyn Fn(&[i32], u32) -> Result<(), AxisError>;

/// Provokes every refusal that once came back from the serial backend as
/// another error than the hub's (issue 23), on axis `x`: `together` is
/// the backend's group move of `x` and a second axis, `settle` waits
/// until `x` is idle with its stop pin high. Set-up calls must succeed;
/// the refusals are returned.
fn provoke_refusals<A: AxisContract>(x: &A, together: Together, settle: &dyn Fn()) -> Refused {
    use driver::axis::HomeConfig;
    let home = HomeConfig {
        switch_pin: 40,
        max_travel: 500_000,
        ..HomeConfig::default()
    };
    let home_with = |change: fn(&mut HomeConfig)| {
        let mut config = home;
        change(&mut config);
        x.home(config)
    };
    let mut refused: Refused = Vec::new();

    // The stop pin low: a jog, homing and a group move are refused with it.
    x.set_stop_pin(false).unwrap();
    refused.push(("jog, stop pin low", x.jog(2_000, Direction::Forward)));
    refused.push(("home, stop pin low", x.home(home)));
    refused.push(("group, stop pin low", together(&[10, 10], 4_000)));
    x.set_stop_pin(true).unwrap();
    settle();

    // A move while a jog owns the axis.
    x.jog(2_000, Direction::Forward).unwrap();
    refused.push(("move while jogging", x.move_steps(2_000, 100)));
    x.jog_release().unwrap();
    settle();

    // Ranges of the move itself.
    x.set_position(i64::MAX - 10).unwrap();
    refused.push(("position out of range", x.move_steps(1_000, 100)));
    x.set_position(0).unwrap();
    refused.push(("steps out of range", x.move_steps(1_000, i32::MIN)));
    refused.push(("group steps out of range", together(&[i32::MIN, 1], 1_000)));
    refused.push(("pulse too long", x.move_steps(50_000_000, 100)));
    refused.push(("speed too high", x.move_steps(u32::MAX, i32::MAX)));

    // Settings that cannot work.
    refused.push(("soft min above max", x.set_soft_limits(10, -10)));
    refused.push((
        "limit pin out of range",
        x.set_limit_pins(Some((64, true)), None),
    ));
    refused.push((
        "both limits on one pin",
        x.set_limit_pins(Some((30, true)), Some((30, false))),
    ));
    refused.push((
        "limit pin is the stop pin",
        x.set_limit_pins(Some((0, true)), None),
    ));
    refused.push((
        "limit pin is an output",
        x.set_limit_pins(None, Some((1, true))),
    ));
    refused.push((
        "switch pin out of range",
        home_with(|config| config.switch_pin = 64),
    ));
    refused.push((
        "switch pin is an output",
        home_with(|config| config.switch_pin = 2),
    ));
    refused.push(("no travel", home_with(|config| config.max_travel = 0)));
    refused.push(("no backoff", home_with(|config| config.backoff_steps = 0)));
    refused.push((
        "backoff too long",
        home_with(|config| config.backoff_steps = (1 << 30) + 1),
    ));

    // A merge past 2^32 - 1 steps (last: it ends with an emergency stop).
    x.move_steps(1_000, i32::MAX).unwrap();
    x.move_steps(1_000, i32::MAX).unwrap();
    refused.push(("too many steps", x.move_steps(1_000, i32::MAX)));
    x.emergency_stop().unwrap();
    refused
}

#[test]
fn every_refusal_over_serial_is_the_hubs_own_error() {
    use driver::profile::PlanError;
    use driver::refusal::{bad_setting, Refusal};

    // The board simulator over a pseudo-terminal.
    let (_sim, path) = sim(2, Dialect::Cogstep);
    let board = open(&path);
    let x = board.axis(0).unwrap();
    let serial = provoke_refusals(
        &x,
        &|steps, speed| board.move_together(steps, speed),
        &|| {
            wait_until(&x, PATIENCE, "x idle with its stop pin high", |status| {
                is_done(status) && status.stop_pin_high
            });
        },
    );
    board.close();

    // The same board as a local hub on a virtual clock: the simulator's
    // pins and switches.
    let hub = Hub::new(HubConfig {
        clkfreq: 200_000_000,
        clock: ClockMode::Virtual,
        ..HubConfig::default()
    })
    .unwrap();
    let (hx, hy) = (
        hub.start_sd(0, 1, 2).unwrap(),
        hub.start_cc(3, 4, 5).unwrap(),
    );
    for (index, axis) in [&hx, &hy].into_iter().enumerate() {
        axis.set_stop_pin(true).unwrap();
        hub.fit_demo_switches(axis, index).unwrap();
    }
    let local = provoke_refusals(
        &hx,
        &|steps, speed| hub.move_together(&[(&hx, steps[0]), (&hy, steps[1])], speed),
        &|| {
            hub.run_until_idle();
        },
    );

    let expected: Vec<AxisError> = vec![
        AxisError::StopPinLow,
        AxisError::StopPinLow,
        AxisError::StopPinLow,
        AxisError::Jogging,
        AxisError::PositionOutOfRange,
        AxisError::StepsOutOfRange,
        AxisError::StepsOutOfRange,
        AxisError::PulseTooLong { speed: 50_000_000 },
        PlanError::SpeedTooHigh {
            speed: u32::MAX,
            clkfreq: 200_000_000,
        }
        .into(),
        AxisError::BadSetting(bad_setting::SOFT_MIN_ABOVE_MAX),
        AxisError::BadSetting(bad_setting::LIMIT_PIN_OUT_OF_RANGE),
        AxisError::BadSetting(bad_setting::LIMITS_SHARE_A_PIN),
        AxisError::BadSetting(bad_setting::LIMIT_PIN_IS_STOP_PIN),
        AxisError::BadSetting(bad_setting::LIMIT_PIN_IS_OUTPUT),
        AxisError::BadSetting(bad_setting::SWITCH_PIN_OUT_OF_RANGE),
        AxisError::BadSetting(bad_setting::SWITCH_PIN_IS_OUTPUT),
        AxisError::BadSetting(bad_setting::MAX_TRAVEL_OUT_OF_RANGE),
        AxisError::BadSetting(bad_setting::BACKOFF_OUT_OF_RANGE),
        AxisError::BadSetting(bad_setting::BACKOFF_OUT_OF_RANGE),
        AxisError::TooManySteps,
    ];
    assert_eq!(local.len(), expected.len());
    for (((what, local), (_, serial)), expected) in local.iter().zip(&serial).zip(&expected) {
        assert_eq!(*local, Err(*expected), "{what}, on the hub");
        assert_eq!(serial, local, "{what}: over serial, then on the hub");
        assert!(expected
            .refusal()
            .is_some_and(|refusal| Refusal::ALL.contains(&refusal)));
    }
}

#[test]
fn jog_runs_while_heartbeats_come_and_release_stops_it() {
    let (_sim, path) = sim(1, Dialect::Cogstep);
    let board = open(&path);
    let x = board.axis(0).unwrap();

    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(400) {
        x.jog(2_000, Direction::Reverse).unwrap();
        std::thread::sleep(Duration::from_millis(30));
    }
    let jogging = x.status().unwrap();
    assert_eq!(jogging.state(), AxisState::Jog);
    assert!(jogging.position < 0);
    x.jog_release().unwrap();
    // S, then R once stopped: idle with the pin high again.
    let released = wait_until(&x, PATIENCE, "the release", |status| {
        is_done(status) && status.stop_pin_high && status.state() == AxisState::Idle
    });
    assert!(released.position < jogging.position);
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(x.status().unwrap().position, released.position);
    x.move_steps(3_000, 200).unwrap();
    finish(&x, PATIENCE, released.position + 200);
    board.close();
}

/// A P2 demo board the user has just powered up: the host presses its
/// first key.
fn powered_up(path: &str) -> SerialConfig {
    SerialConfig {
        demo_start: DemoStart::PoweredUp,
        ..config(path, Dialect::P2Demo)
    }
}

#[test]
fn the_p2_demo_dialect_end_to_end() {
    let (_sim, path) = sim(1, Dialect::P2Demo);
    let board = SerialBoard::open(powered_up(&path)).expect("the demo screen");
    assert_eq!(board.identity(), P2DEMO_IDENTITY);
    assert_eq!(board.axis_count(), 1);
    assert_eq!(board.clkfreq(), 0);
    assert_eq!(board.capabilities(), Capabilities::MOVE_ONLY);
    let x = board.axis(0).unwrap();
    // The demo presets the position before its first screen.
    assert_eq!(x.status().unwrap().position, 1000);

    x.move_steps(3_000, 500).unwrap();
    // The board reads nothing while it moves.
    assert_eq!(x.move_steps(3_000, 10), Err(AxisError::Busy));
    let moving = x.status().unwrap();
    assert!(
        moving.mode.has(Mode::MOVING) && moving.steps_to_go > 0,
        "{moving:?}"
    );
    finish(&x, PATIENCE, 1500);
    x.move_steps(3_000, -200).unwrap();
    let done = finish(&x, PATIENCE, 1300);
    assert_eq!(done.state(), AxisState::Idle);

    // Moves the real board botches are refused before a byte is sent.
    for steps in [1, -2, 3, 4] {
        assert!(
            matches!(x.move_steps(3_000, steps), Err(AxisError::Unsupported(_))),
            "{steps}"
        );
    }
    assert_eq!(
        x.move_steps(3_000, 7),
        Err(AxisError::Unsupported(
            DemoFlaw::OddShortFullSpeed {
                steps: 7,
                speed: 3_000,
                accel_steps: 3
            }
            .reason()
        ))
    );
    x.move_steps(3_000, 100).unwrap();
    finish(&x, PATIENCE, 1400);

    let unsupported = Err(AxisError::Unsupported(P2DEMO_UNSUPPORTED));
    assert_eq!(x.set_stop_pin(false), unsupported);
    assert_eq!(x.jog(100, Direction::Forward), unsupported);
    assert_eq!(x.jog_release(), unsupported);
    assert_eq!(x.emergency_stop(), unsupported);
    assert_eq!(x.set_position(0), unsupported);
    assert_eq!(board.emergency_stop_all(), unsupported);
    assert_eq!(board.fault(), None);
    board.close();
}

/// One display of values that fit their fields, from the demo source's
/// strings (`"\001%s\r"`, `"\r…: "`, `jdpdec(v, 0, 6, " ")`, `fbin(mode, 6)`;
/// `\011` is decimal 11).
fn demo_display(values: [i32; 7]) -> String {
    let [position, mode, offset, accel, slew, velocity, elapsed] = values;
    format!(
        "\x01Stepper Demo\r\rCurrent Position: {position:>6}\r            Mode: {mode:06b}\
         \r          Offset: {offset:>6}\r     Accel steps: {accel:>6}\
         \r  Steps at speed: {slew:>6}\r    Max Velocity: {velocity:>6}\
         \r\x0bElapsed time (msec): {elapsed:>6}"
    )
}

#[test]
fn a_raw_p2_demo_session_is_the_stock_demo_byte_for_byte() {
    let (_sim, path) = sim(1, Dialect::P2Demo);
    let mut raw = RawPort::open(&path, PATIENCE);
    raw.send(b"x");
    let screen = raw.until(b"Enter steps: ");
    assert_eq!(
        String::from_utf8(screen).unwrap(),
        format!(
            "\x10{}\r\rEnter steps: ",
            demo_display([1000, 0, 0, 0, 0, 0, 0])
        )
    );
    raw.send(b"100\r");
    assert_eq!(raw.until(b"\rEnter speed: "), b"\rEnter speed: ");
    raw.send(b"3000\r");
    let run = String::from_utf8(raw.until(b"\r\rEnter steps: ")).unwrap();
    assert!(run.starts_with('\x10'), "{run:?}");
    let (_, last) = run.rsplit_once('\x10').unwrap();
    // 100 steps at 3000: asteps 302, capped at 50; no steps at speed, so
    // the speed becomes 10 * (50 - 2) = 480.
    assert!(
        last.starts_with(&demo_display([1100, 0, 40, 50, 0, 0, 0])[..150]),
        "{last:?}"
    );
    assert!(!run.contains("Refused"));
    // Max Velocity is written when deceleration starts: 0 on the first
    // display, the reference cog's last ramp velocity on the last.
    let max_velocity = |display: &str| -> i32 {
        let tail = display.split("Max Velocity: ").nth(1).unwrap();
        tail.split('\r').next().unwrap().trim().parse().unwrap()
    };
    let first = run[1..].split('\x01').nth(1).unwrap();
    assert_eq!(max_velocity(first), 0, "{first:?}");
    assert!((400..=480).contains(&max_velocity(last)), "{last:?}");
}

#[test]
fn a_connect_with_a_half_typed_answer_pending_moves_nothing() {
    let (_sim, path) = sim(1, Dialect::P2Demo);
    let mut raw = RawPort::open(&path, PATIENCE);
    raw.send(b" ");
    raw.until(b"Enter steps: ");
    raw.send(b"300\r");
    raw.until(b"Enter speed: ");
    // A speed half typed, then the terminal closed.
    raw.send(b"2000");
    drop(raw);
    // The host listens, sends nothing, and says why it cannot connect.
    let error = SerialBoard::open(config(&path, Dialect::P2Demo)).unwrap_err();
    assert!(
        matches!(error, SerialError::DemoStateUnknown { .. }),
        "{error}"
    );
    assert!(error.to_string().contains("nothing was sent"), "{error}");
    // The pending answer is intact and nothing moved: ending it now runs
    // 300 steps at 2000 (asteps 202, capped at 150) from 1000.
    let mut raw = RawPort::open(&path, PATIENCE);
    raw.send(b"\r");
    let run = String::from_utf8(raw.until(b"\r\rEnter steps: ")).unwrap();
    let (_, last) = run.rsplit_once('\x10').unwrap();
    assert!(
        last.starts_with(&demo_display([1300, 0, 40, 150, 0, 0, 0])[..150]),
        "{last:?}"
    );
}

#[test]
fn a_passive_connect_follows_a_move_started_elsewhere() {
    let (_sim, path) = sim(1, Dialect::P2Demo);
    let mut raw = RawPort::open(&path, PATIENCE);
    raw.send(b" ");
    raw.until(b"Enter steps: ");
    raw.send(b"3000\r");
    raw.until(b"Enter speed: ");
    raw.send(b"3000\r");
    std::thread::sleep(Duration::from_millis(100));
    drop(raw);
    let board = SerialBoard::open(config(&path, Dialect::P2Demo)).expect("the screens");
    let x = board.axis(0).unwrap();
    finish(&x, PATIENCE, 4000);
    x.move_steps(3_000, -500).unwrap();
    finish(&x, PATIENCE, 3500);
    board.close();
}

#[test]
fn a_disconnect_mid_move_is_a_fault_not_a_hang() {
    let (sim, path) = sim(1, Dialect::Cogstep);
    let board = open(&path);
    let x = board.axis(0).unwrap();
    x.move_steps(3_000, 30_000).unwrap();
    wait_until(&x, PATIENCE, "the move", |status| status.position > 10);
    sim.stop();

    let start = Instant::now();
    while board.fault().is_none() {
        assert!(start.elapsed() < PATIENCE, "no fault reported");
        std::thread::sleep(Duration::from_millis(5));
    }
    let fault = board.fault().unwrap();
    assert!(fault.starts_with("disconnected"), "{fault}");
    assert!(!board.is_connected());
    // Every call answers at once with the fault.
    let start = Instant::now();
    assert_eq!(x.status(), Err(AxisError::Fault(FAULT_DISCONNECTED)));
    assert_eq!(
        x.move_steps(100, 10),
        Err(AxisError::Fault(FAULT_DISCONNECTED))
    );
    assert_eq!(
        board.emergency_stop_all(),
        Err(AxisError::Fault(FAULT_DISCONNECTED))
    );
    assert_eq!(board.refresh(), Err(AxisError::Fault(FAULT_DISCONNECTED)));
    assert!(start.elapsed() < Duration::from_secs(2));
    let start = Instant::now();
    board.close();
    assert!(start.elapsed() < Duration::from_secs(2));
}

#[test]
fn the_backend_reconnects_to_a_board_that_comes_back() {
    let (first, first_path) = sim(2, Dialect::Cogstep);
    let device = DeviceLink::new(&first_path);
    let board = open(device.path());
    let (x, y) = (board.axis(0).unwrap(), board.axis(1).unwrap());
    x.move_steps(3_000, 30_000).unwrap();
    wait_until(&x, PATIENCE, "the move", |status| status.position > 10);

    // The board goes away while the link path points nowhere useful.
    device.remove();
    first.stop();
    let start = Instant::now();
    while board.is_connected() {
        assert!(start.elapsed() < PATIENCE, "the loss went unnoticed");
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(600));
    let fault = board.fault().unwrap();
    assert!(fault.contains("reopening"), "{fault}");

    // It comes back on a new pseudo-terminal behind the same path.
    let (_second, second_path) = sim(2, Dialect::Cogstep);
    device.point_at(&second_path);
    let start = Instant::now();
    while !board.is_connected() {
        assert!(start.elapsed() < PATIENCE, "no reconnection");
        std::thread::sleep(Duration::from_millis(10));
    }
    // The axis that was moving keeps its fault until its next command;
    // the other one is fine.
    assert_eq!(x.status(), Err(AxisError::Fault(FAULT_LOST_MID_MOVE)));
    assert_eq!(
        board.fault(),
        Some(format!("axis 0: {FAULT_LOST_MID_MOVE}"))
    );
    assert_eq!(y.status().unwrap().position, 0);
    x.move_steps(3_000, 200).unwrap();
    assert_eq!(board.fault(), None);
    finish(&x, PATIENCE, 200);
    board.close();
}

#[test]
fn a_board_reset_mid_move_is_a_fault_on_the_moving_axis() {
    let (sim, path) = sim(2, Dialect::Cogstep);
    let board = open(&path);
    let (x, y) = (board.axis(0).unwrap(), board.axis(1).unwrap());
    x.move_steps(3_000, 30_000).unwrap();
    wait_until(&x, PATIENCE, "the move", |status| status.position > 10);
    sim.reset();

    let start = Instant::now();
    while x.status() != Err(AxisError::Fault(FAULT_RESET_MID_MOVE)) {
        assert!(start.elapsed() < PATIENCE, "the reset went unnoticed");
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(board.is_connected());
    assert_eq!(
        board.fault(),
        Some(format!("axis 0: {FAULT_RESET_MID_MOVE}"))
    );
    assert_eq!(y.status().unwrap().position, 0);
    // Acknowledged by a new command; the restarted board counts from 0.
    x.set_position(0).unwrap();
    assert_eq!(x.status().unwrap().position, 0);
    assert_eq!(board.fault(), None);
    board.close();
}

#[test]
fn a_p2_demo_board_that_resets_mid_move_is_lost_and_never_typed_into() {
    let (sim, path) = sim(1, Dialect::P2Demo);
    let board = SerialBoard::open(SerialConfig {
        timeout: Duration::from_millis(800),
        ..powered_up(&path)
    })
    .unwrap();
    let x = board.axis(0).unwrap();
    x.move_steps(3_000, 30_000).unwrap();
    wait_until(&x, PATIENCE, "the move", |status| status.position > 1010);
    sim.reset();

    // The screens stop; after the timeout the link is taken down. The
    // restarted board waits for its first key and prints nothing, so the
    // host, reopening passively, cannot connect, and types nothing.
    let start = Instant::now();
    while x.status() != Err(AxisError::Fault(FAULT_DISCONNECTED)) {
        assert!(start.elapsed() < PATIENCE, "{:?}", board.fault());
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(1_500));
    let fault = board.fault().unwrap();
    assert!(fault.contains("printed no screen"), "{fault}");
    board.close();
    // Had the host pressed a key, the board would now be at its steps
    // prompt and this first key would be part of an answer.
    let board = SerialBoard::open(powered_up(&path)).expect("the first screen");
    assert_eq!(board.axis(0).unwrap().status().unwrap().position, 1000);
    board.close();
}

#[test]
fn a_half_written_line_is_not_run_when_the_backend_connects() {
    let (_sim, path) = sim(1, Dialect::Cogstep);
    let mut raw = RawPort::open(&path, PATIENCE);
    raw.send(b"M 0 4000 300");
    drop(raw);
    let board = open(&path);
    let x = board.axis(0).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    board.refresh().unwrap();
    let status = x.status().unwrap();
    assert_eq!((status.position, status.state()), (0, AxisState::Idle));
    board.close();
}

#[test]
fn a_stalled_reader_loses_no_reply() {
    let (_sim, path) = sim(1, Dialect::Cogstep);
    let mut raw = RawPort::open(&path, PATIENCE);
    let mut writer = raw.writer();
    writer.set_timeout(PATIENCE).unwrap();
    // 2,000 commands: set the position, read it back.
    let commands: Vec<u8> = (0..1_000)
        .flat_map(|k| format!("P 0 {}\n?", k + 1).into_bytes())
        .collect();
    let sender = std::thread::spawn(move || writer.write_all(&commands));
    // Nobody reads for 0.3 s: the board must wait, not drop.
    std::thread::sleep(Duration::from_millis(300));
    for k in 1..=1_000 {
        assert_eq!(raw.line(), "ok", "reply to P 0 {k}");
        assert_eq!(
            raw.line(),
            idle_line(0, k, "high"),
            "reply to ? after P 0 {k}"
        );
    }
    sender.join().unwrap().unwrap();
}

#[test]
fn the_simulated_p2_demo_botches_what_the_real_one_botches() {
    let (_sim, path) = sim(1, Dialect::P2Demo);
    let mut raw = RawPort::open(&path, PATIENCE);
    raw.send(b" ");
    raw.until(b"Enter steps: ");
    // 4 steps: the reference plans speed 0, and every step waits the
    // 0.475 s delay ceiling (cogstep's hub would not).
    raw.send(b"4\r");
    raw.until(b"Enter speed: ");
    let start = Instant::now();
    raw.send(b"1000\r");
    let run = String::from_utf8(raw.until(b"\r\rEnter steps: ")).unwrap();
    assert!(start.elapsed() >= Duration::from_millis(1_800));
    let (_, last) = run.rsplit_once('\x10').unwrap();
    let elapsed: i32 = last
        .split("Elapsed time (msec): ")
        .nth(1)
        .and_then(|tail| tail.split('\r').next())
        .map(|field| field.trim().parse().unwrap())
        .unwrap();
    assert!(elapsed >= 1_800, "{elapsed}");
    assert_eq!(
        last,
        format!(
            "{}\r\rEnter steps: ",
            demo_display([1004, 0, 40, 2, 0, 1, elapsed])
        )
    );
}

#[test]
fn a_reset_connect_needs_modem_lines() {
    let (_sim, path) = sim(1, Dialect::P2Demo);
    let result = SerialBoard::open(SerialConfig {
        demo_start: DemoStart::Reset,
        ..config(&path, Dialect::P2Demo)
    });
    match result {
        // A pseudo-terminal has no DTR or RTS: a typed error, nothing sent.
        Err(SerialError::Reset { .. }) => {
            let board = SerialBoard::open(powered_up(&path)).expect("the first screen");
            assert_eq!(board.axis(0).unwrap().status().unwrap().position, 1000);
            board.close();
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_reverse_move_on_the_simulated_p2_demo_ends_with_mode_000000() {
    let (_sim, path) = sim(1, Dialect::P2Demo);
    let mut raw = RawPort::open(&path, PATIENCE);
    raw.send(b" ");
    raw.until(b"Enter steps: ");
    raw.send(b"-100\r");
    raw.until(b"Enter speed: ");
    raw.send(b"2000\r");
    let run = String::from_utf8(raw.until(b"\r\rEnter steps: ")).unwrap();
    // While it runs the direction bit is set; at the end only b5 is kept.
    assert!(run.contains("Mode: 010011"), "{run:?}");
    let (_, last) = run.rsplit_once('\x10').unwrap();
    assert!(
        last.starts_with(&demo_display([900, 0, 40, 50, 0, 0, 0])[..150]),
        "{last:?}"
    );
}

#[test]
fn a_group_move_over_the_wire_is_all_or_nothing() {
    let (_sim, path) = sim(3, Dialect::Cogstep);
    let mut raw = RawPort::open(&path, PATIENCE);
    // RawPort: every axis reaches its target; refusals with their codes move nothing.
    assert_eq!(raw.command("G 4000 600 -200 0"), ["ok"]);
    let start = Instant::now();
    while raw.status(3)[..2] != [idle_line(0, 600, "high"), idle_line(1, -200, "high")] {
        assert!(start.elapsed() < PATIENCE, "the group move did not end");
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(raw.command("M 2 3000 3000"), ["ok"]);
    for (line, reply) in [
        ("G 4000 10 10 10", "error:3 busy"),
        ("G 4000 1 2 3 4", "error:4 no such axis"),
        ("G 0 10", "error:6 speed out of range"),
        ("G 4000", "error:2 bad argument"),
        ("G 4000 1 2 3 4 5 6 7 8 9", "error:2 bad argument"),
    ] {
        assert_eq!(raw.command(line), [reply], "{line}");
    }
    assert_eq!(raw.command("S 1"), ["ok"]);
    assert_eq!(
        raw.command("G 4000 10 10"),
        ["error:7 not idle: stop pin low"]
    );
    assert_eq!(raw.command("R 1"), ["ok"]);
    assert_eq!(
        raw.status(3)[..2],
        [idle_line(0, 600, "high"), idle_line(1, -200, "high")]
    );
    drop(raw);

    // The host backend: the same move, the same refusals as the hub's.
    let board = open(&path);
    let (x, y, z) = (
        board.axis(0).unwrap(),
        board.axis(1).unwrap(),
        board.axis(2).unwrap(),
    );
    finish(&z, PATIENCE, 3_000);
    board.move_together(&[-600, 200, -1_000], 4_000).unwrap();
    finish(&x, PATIENCE, 0);
    finish(&y, PATIENCE, 0);
    finish(&z, PATIENCE, 2_000);
    assert_eq!(
        board.move_together(&[1, 2], 0),
        Err(AxisError::Plan(driver::profile::PlanError::ZeroSpeed))
    );
    assert_eq!(
        board.move_together(&[1, 2, 3, 4], 100),
        Err(AxisError::Unavailable)
    );
    z.move_steps(3_000, 2_000).unwrap();
    assert_eq!(
        board.move_together(&[10, 10, 10], 4_000),
        Err(AxisError::Busy)
    );
    finish(&z, PATIENCE, 4_000);
    assert_eq!(x.status().unwrap().position, 0);
    board.close();
}

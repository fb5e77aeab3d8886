//! End to end, as a person uses it: the real `demo-tui` binary in a
//! pseudo-terminal, keys typed as bytes, the screen read back with vt100.
//! Waits poll the screen with generous timeouts; speed bounds are measured
//! against the clock, never assumed with fixed sleeps.

mod pty;

use std::time::{Duration, Instant};

use pty::{field, number, position, to_go, Demo, Keyboard};

const BIN: &str = env!("CARGO_BIN_EXE_demo-tui");
const LONG: Duration = Duration::from_secs(20);

fn start(args: &[&str], keyboard: Keyboard) -> Demo {
    let demo = Demo::spawn(BIN, args, keyboard);
    demo.wait_text("Enter steps:", LONG);
    demo
}

#[test]
fn answering_the_prompts_moves_the_axis_to_the_target() {
    let demo = start(&["--axes", "2"], Keyboard::Legacy);
    let mut phases = Vec::new();
    enter_move(&demo, 20_000, 40_000);
    let screen = demo.wait_for("position 20000 and STM 0", LONG, |s| {
        for phase in ["accelerating", "at speed", "decelerating"] {
            if s.contains(phase) && !phases.contains(&phase) {
                phases.push(phase);
            }
        }
        number(s, "Current Position:", 1) == Some(20_000)
            && number(s, "STM:", 1) == Some(0)
            && field(s, "Mode:", 1).as_deref() == Some("000000")
    });
    assert!(!phases.is_empty(), "the mode words follow the move");
    // The reference demo's figures for this move.
    assert_eq!(number(&screen, "Accel steps:", 1), Some(4_002), "{screen}");
    assert_eq!(number(&screen, "Steps at speed:", 1), Some(11_996));
    assert_eq!(number(&screen, "Max Velocity:", 1), Some(40_000));
    assert_eq!(number(&screen, "Offset:", 1), Some(40));
    let elapsed = number(&screen, "Elapsed time (msec):", 1).expect("elapsed");
    assert!((500..2_000).contains(&elapsed), "elapsed {elapsed} ms");
    assert_eq!(field(&screen, "Mode:", 1).as_deref(), Some("000000"));
    assert_eq!(position(&screen, 2), 0, "the other axis did not move");
    assert!(screen.contains("Velocity · axis 1"));
    assert!(screen.contains("move 20000 steps at 40000 steps/s"));
}

#[test]
fn g_moves_every_axis_at_once_on_one_line() {
    let demo = start(&["--axes", "3"], Keyboard::Legacy);
    pty::enter_group_move(&demo, &[6_000, -2_000, 0], 20_000, LONG);
    let mut seen_both_moving = false;
    let screen = demo.wait_for("every axis at its target", LONG, |s| {
        let (x, y) = (position(s, 1), position(s, 2));
        // On the line: y is a third of x, back, within the steps a frame
        // can hold between reading the two axes.
        if x > 0 && x < 6_000 {
            seen_both_moving |= y < 0;
            assert!((x + 3 * y).abs() <= 1_500, "off the line: {x} {y}\n{s}");
        }
        x == 6_000 && y == -2_000 && to_go(s, 1) == 0 && to_go(s, 2) == 0
    });
    assert!(seen_both_moving, "both axes seen moving together");
    assert_eq!(position(&screen, 3), 0);
    assert!(
        screen.contains("group move 6000 -2000 0 at 20000 steps/s"),
        "{screen}"
    );

    // Refused answers keep the prompt; a stop mid-move and the rest as a
    // second group move complete the line.
    demo.send(b"g1 2 3 4\r");
    demo.wait_text("4 numbers for 3 axes", LONG);
    // Esc twice (apart, or they read as one Alt key): back to Enter steps:.
    demo.send(b"\x1b");
    demo.wait_for("the field cleared", LONG, |s| {
        !s.contains("Group steps: 1 2 3 4")
    });
    demo.send(b"\x1b");
    demo.wait_for("the steps prompt back", LONG, |s| {
        !s.contains("Group steps:")
    });
    pty::enter_group_move(&demo, &[-6_000, 2_000], 5_000, LONG);
    demo.wait_for("some progress", LONG, |s| position(s, 1) < 4_000);
    demo.send(b"2s");
    let stopped = demo.wait_for("the group stopped", LONG, |s| {
        to_go(s, 1) == 0 && to_go(s, 2) == 0 && field(s, "Stop pin:", 2).as_deref() == Some("LOW")
    });
    let (x, y) = (position(&stopped, 1), position(&stopped, 2));
    assert!(x > 0, "stopped before the end: {stopped}");
    assert!((x + 3 * y).abs() <= 4, "on the line: {x} {y}");
    pty::enter_group_move(&demo, &[-x, -y], 10_000, LONG);
    demo.wait_for("back at 0", LONG, |s| {
        position(s, 1) == 0 && position(s, 2) == 0 && to_go(s, 1) == 0
    });
}

#[test]
fn a_terminal_that_answers_no_query_loses_no_keys() {
    // The demo asks the terminal about key releases once, after its first
    // frame; a terminal that never answers costs a wait, not the keys
    // typed meanwhile. Line feeds submit as well as carriage returns.
    let demo = start(&["--axes", "2"], Keyboard::Silent);
    demo.send(b"1500\n20000\n");
    let screen = demo.wait_for("position 1500", LONG, |s| {
        number(s, "Current Position:", 1) == Some(1_500) && number(s, "STM:", 1) == Some(0)
    });
    assert!(
        screen.contains("jog ends: 150 ms after the last key repeat"),
        "{screen}"
    );
}

#[test]
fn the_stop_key_decelerates_to_an_exact_count_and_the_rest_can_be_finished() {
    let demo = start(&["--axes", "1"], Keyboard::Legacy);
    enter_move(&demo, 40_000, 20_000);
    let before = demo.wait_for("the axis at speed", LONG, |s| {
        number(s, "Current Position:", 1).is_some_and(|p| p > 5_000)
    });
    let at_press = position(&before, 1);
    demo.send(b"s");
    let mut saw_decelerating = false;
    let stopped = demo.wait_for("the axis stopped by the stop pin", LONG, |s| {
        saw_decelerating |= s.contains("decelerating");
        // Latched and no longer moving: STM reads 0 from the last step on,
        // while Mode keeps "moving" until that step's delay has run out.
        to_go(s, 1) == 0 && field(s, "Mode:", 1).as_deref() == Some("100000")
    });
    let stopped_at = position(&stopped, 1);
    let dropped = number(&stopped, "Dropped steps:", 1).expect("dropped steps");
    assert_eq!(stopped_at + dropped, 40_000, "exact count:\n{stopped}");
    assert!(dropped > 0, "stopped before the target");
    // Controlled: it ran on through a deceleration ramp (about 2,000 steps
    // from 20,000 steps/s), not an instant halt. (The upper bound allows for
    // the screen read at the key press being a few frames old on a busy
    // machine: 20,000 steps/s is 600 steps a frame.)
    let ran_on = stopped_at - at_press;
    assert!(
        (1_000..=6_000).contains(&ran_on),
        "{ran_on} steps after the key (decelerating seen: {saw_decelerating})"
    );
    assert_eq!(field(&stopped, "Stop pin:", 1).as_deref(), Some("LOW"));
    assert!(stopped.contains("stopped by stop pin"), "{stopped}");
    assert!(
        stopped.contains(&format!("type {dropped} at Enter steps: to finish")),
        "{stopped}"
    );
    // The remaining steps reach the original target; the move raises the pin.
    enter_move(&demo, dropped, 20_000);
    let done = demo.wait_for("the original target", LONG, |s| {
        position(s, 1) == 40_000
            && to_go(s, 1) == 0
            && field(s, "Mode:", 1).as_deref() == Some("000000")
    });
    assert_eq!(field(&done, "Stop pin:", 1).as_deref(), Some("high"));
    assert_eq!(field(&done, "Mode:", 1).as_deref(), Some("000000"));
}

#[test]
fn holding_an_arrow_jogs_and_the_axis_stops_soon_after_the_last_repeat() {
    let demo = start(&["--axes", "1", "--jog-speed", "5000"], Keyboard::Legacy);
    // Hold → : a key repeat every 30 ms for a second.
    let start_hold = Instant::now();
    let mut samples = Vec::new();
    while start_hold.elapsed() < Duration::from_millis(1_000) {
        demo.send(pty::RIGHT);
        std::thread::sleep(Duration::from_millis(30));
        samples.push(demo.screen());
    }
    let last_repeat = Instant::now();
    let at_last = position(&demo.screen(), 1);
    assert!(
        samples
            .iter()
            .any(|s| s.contains(" Jog ") && s.contains("jogging axis 1 →")),
        "the jog shows while the key is held"
    );
    let late: Vec<i64> = samples[samples.len() / 2..]
        .iter()
        .map(|s| position(s, 1))
        .collect();
    assert!(late.windows(2).all(|w| w[1] >= w[0]) && late[late.len() - 1] > late[0]);
    // Released: the heartbeats stop, the hub decelerates within 150 ms.
    let mut last_seen = at_last;
    let mut settled_at = Instant::now();
    let screen = demo.wait_for("the jog to stop", LONG, |s| {
        let p = position(s, 1);
        if p != last_seen {
            last_seen = p;
            settled_at = Instant::now();
        }
        to_go(s, 1) == 0 && !s.contains(" Jog ")
    });
    let stop_time = settled_at.duration_since(last_repeat);
    let ran_on = position(&screen, 1) - at_last;
    // 150 ms at 5,000 steps/s, one ramp of about 500 steps, the screen's lag.
    assert!(ran_on <= 1_600, "{ran_on} steps after the last repeat");
    assert!(
        stop_time < Duration::from_millis(1_200),
        "stopped {stop_time:?} after the last repeat"
    );
    assert!(position(&screen, 1) > 1_000, "it ran while held");
}

#[test]
fn with_the_kitty_protocol_a_key_release_stops_the_jog_at_once() {
    let demo = start(&["--axes", "1", "--jog-speed", "5000"], Keyboard::Kitty);
    let deadline = Instant::now() + LONG;
    while !demo.wrote(b"\x1b[>3u") {
        assert!(Instant::now() < deadline, "the demo asks for key events");
        std::thread::sleep(Duration::from_millis(10));
    }
    demo.send(pty::KITTY_RIGHT_PRESS);
    for _ in 0..15 {
        std::thread::sleep(Duration::from_millis(30));
        demo.send(pty::KITTY_RIGHT_REPEAT);
    }
    demo.wait_text("release the key to stop", LONG);
    let at_release = position(&demo.screen(), 1);
    demo.send(pty::KITTY_RIGHT_RELEASE);
    let screen = demo.wait_for("the released jog to stop", LONG, |s| {
        s.contains("jog released (key up)") && to_go(s, 1) == 0 && !s.contains(" Jog ")
    });
    let ran_on = position(&screen, 1) - at_release;
    assert!(ran_on <= 1_200, "{ran_on} steps after the release");
    demo.send(b"q");
}

#[test]
fn invalid_answers_are_refused_at_the_prompt() {
    let demo = start(&["--axes", "1"], Keyboard::Legacy);
    demo.send(b"0\r");
    let screen = demo.wait_text("0 steps: nothing to move", LONG);
    assert!(!screen.contains("Enter speed:"), "still asking for steps");
    demo.send(b"\x7f"); // Backspace
    demo.send(b"a");
    demo.wait_text("'a' is not a key", LONG);
    demo.send(b"2000\r");
    demo.wait_text("Enter speed:", LONG);
    demo.send(b"0\r");
    demo.wait_text("speed must be at least 1 step/s", LONG);
    demo.send(b"\x7f999999\r");
    let screen = demo.wait_text("too fast", LONG);
    assert!(
        screen.contains("Enter speed:"),
        "still asking for the speed"
    );
    assert_eq!(position(&screen, 1), 0, "nothing was sent");
    assert_eq!(to_go(&screen, 1), 0);
    // Esc twice (apart, or they read as one Alt key): back to Enter steps:.
    demo.send(b"\x1b");
    demo.wait_for("the field cleared", LONG, |s| {
        !s.contains("Enter speed: 999999")
    });
    demo.send(b"\x1b");
    demo.wait_for("the steps prompt again", LONG, |s| {
        !s.contains("Enter speed:")
    });
    enter_move(&demo, -300, 20_000);
    demo.wait_for("position -300", LONG, |s| {
        position(s, 1) == -300 && to_go(s, 1) == 0
    });
}

#[test]
fn axes_are_selected_with_tab_and_digits_and_x_stops_them_all() {
    let demo = start(&["--axes", "4"], Keyboard::Legacy);
    assert!(demo.screen().contains("▶ Axis 1"));
    demo.send(b"\t");
    demo.wait_text("▶ Axis 2", LONG);
    // A lone axis number selects after a short pause ...
    demo.send(b"3");
    demo.wait_text("▶ Axis 3", LONG);
    // ... and a number typed straight on is steps, for the selected axis.
    enter_move(&demo, 500, 20_000);
    demo.wait_for("axis 3 at 500", LONG, |s| {
        position(s, 3) == 500 && to_go(s, 3) == 0
    });
    assert_eq!(position(&demo.screen(), 1), 0);
    // Two long moves, then the emergency stop of all axes.
    enter_move(&demo, 40_000, 10_000);
    demo.send(b"\t");
    demo.wait_text("▶ Axis 4", LONG);
    enter_move(&demo, -40_000, 10_000);
    demo.wait_for("both axes moving", LONG, |s| {
        to_go(s, 3) > 0 && to_go(s, 4) > 0
    });
    demo.send(b"x");
    let screen = demo.wait_for("both axes halted", LONG, |s| {
        s.matches("emergency stopped").count() >= 2 && to_go(s, 3) == 0 && to_go(s, 4) == 0
    });
    assert!(screen.contains("EMERGENCY STOP"));
    let (p3, p4) = (position(&screen, 3), position(&screen, 4));
    assert!(
        p3 > 500 && p3 < 40_500 && p4 < 0 && p4 > -40_000,
        "{screen}"
    );
    std::thread::sleep(Duration::from_millis(200));
    let later = demo.screen();
    assert_eq!(
        (position(&later, 3), position(&later, 4)),
        (p3, p4),
        "halted"
    );
}

#[test]
fn q_quits_and_restores_the_terminal() {
    let mut demo = start(&[], Keyboard::Legacy);
    assert!(demo.modes().0, "alternate screen");
    // The cursor waits at the prompt, after "Enter steps: ".
    demo.wait_for("the cursor at the prompt", LONG, |screen| {
        let (row, column) = demo.cursor();
        let line = screen.lines().nth(usize::from(row)).unwrap_or_default();
        line.find("Enter steps: ").is_some_and(|prompt| {
            usize::from(column) == line[..prompt].chars().count() + "Enter steps: ".len()
        })
    });
    assert_eq!(demo.line_modes(), Some((false, false)), "raw mode");
    demo.send(b"q");
    let status = demo.wait_exit(LONG);
    assert!(status.success(), "{status:?}");
    assert_eq!(demo.modes(), (false, false), "normal screen, cursor shown");
    assert_eq!(
        demo.line_modes(),
        Some((true, true)),
        "canonical mode, echo"
    );
}

#[test]
fn sigterm_restores_the_terminal() {
    let mut demo = start(&["--axes", "2"], Keyboard::Kitty);
    enter_move(&demo, 40_000, 10_000);
    let pid = nix::unistd::Pid::from_raw(demo.pid());
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).expect("kill");
    let status = demo.wait_exit(LONG);
    assert_eq!(status.exit_code(), 143, "{status:?}");
    assert_eq!(demo.modes(), (false, false));
    assert_eq!(demo.line_modes(), Some((true, true)));
    if demo.wrote(b"\x1b[>3u") {
        assert!(demo.wrote(b"\x1b[<1u"), "keyboard flags popped");
    }
    assert!(demo.screen().contains("ended by a signal"));
}

#[test]
fn sighup_ends_the_demo_with_its_status_and_restores_the_terminal() {
    let mut demo = start(&["--axes", "2"], Keyboard::Legacy);
    let pid = nix::unistd::Pid::from_raw(demo.pid());
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGHUP).expect("kill");
    let status = demo.wait_exit(LONG);
    assert_eq!(status.exit_code(), 129, "128 + SIGHUP: {status:?}");
    assert_eq!(demo.modes(), (false, false));
    assert_eq!(demo.line_modes(), Some((true, true)));
    assert!(demo.screen().contains("ended by a signal"));
}

#[test]
fn sigint_from_outside_ends_the_demo_with_its_status() {
    // (Ctrl-C typed is a key in raw mode and quits with 0; this is `kill -INT`.)
    let mut demo = start(&["--axes", "1"], Keyboard::Legacy);
    let pid = nix::unistd::Pid::from_raw(demo.pid());
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).expect("kill");
    let status = demo.wait_exit(LONG);
    assert_eq!(status.exit_code(), 130, "128 + SIGINT: {status:?}");
    assert_eq!(demo.line_modes(), Some((true, true)));
}

/// How soon the demo must end once its terminal is gone.
const PROMPTLY: Duration = Duration::from_secs(3);

#[test]
fn closing_the_terminal_ends_the_demo_at_once() {
    // The demo leads the terminal's session (as in a window of its own):
    // the kernel sends it SIGHUP as the terminal hangs up.
    let mut demo = start(&["--axes", "2"], Keyboard::Legacy);
    enter_move(&demo, 40_000, 10_000);
    let closed = Instant::now();
    demo.hang_up();
    let status = demo.wait_exit(PROMPTLY);
    assert_eq!(status.exit_code(), 129, "{status:?}");
    eprintln!("ended {:?} after the hang-up", closed.elapsed());
}

/// Whether process `pid` has ended (gone, or a zombie nobody reaped).
fn ended(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).map_or(true, |stat| {
        stat.rsplit_once(") ")
            .is_some_and(|(_, rest)| rest.starts_with('Z') || rest.starts_with('X'))
    })
}

#[test]
fn a_terminal_gone_without_a_sighup_ends_the_demo_at_once() {
    // As under `tmux new-session 'demo-tui'`: a shell leads the session,
    // and the demo only finds that its input has ended. `setsid -w` runs
    // it outside the terminal's session, so no SIGHUP ever reaches it.
    let demo = Demo::spawn("setsid", &["-w", BIN, "--axes", "1"], Keyboard::Legacy);
    demo.wait_text("Enter steps:", LONG);
    let leader = demo.pid();
    let children = std::fs::read_to_string(format!("/proc/{leader}/task/{leader}/children"))
        .expect("setsid's children");
    let pid: u32 = children
        .split_whitespace()
        .next()
        .and_then(|pid| pid.parse().ok())
        .expect("the demo under setsid");
    let mut demo = demo;
    let closed = Instant::now();
    demo.hang_up();
    while !ended(pid) {
        assert!(
            closed.elapsed() < PROMPTLY,
            "demo-tui (pid {pid}) still runs {PROMPTLY:?} after its terminal went away"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    eprintln!("ended {:?} after the hang-up", closed.elapsed());
}

#[test]
fn a_baud_rate_of_0_is_refused_with_the_reason() {
    let out = std::process::Command::new(BIN)
        .args(["--serial", "/dev/null", "--baud", "0"])
        .output()
        .expect("demo-tui runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("--baud") && stderr.contains("'0'"),
        "{stderr}"
    );
}

#[test]
fn a_panic_restores_the_terminal_and_reports_on_the_normal_screen() {
    let mut demo = Demo::spawn(BIN, &["--test-panic-after-ms", "300"], Keyboard::Legacy);
    let status = demo.wait_exit(LONG);
    assert_eq!(status.exit_code(), 101, "{status:?}");
    assert_eq!(demo.modes(), (false, false));
    assert_eq!(demo.line_modes(), Some((true, true)));
    assert!(
        demo.screen().contains("a deliberate panic"),
        "{}",
        demo.screen()
    );
}

mod serial {
    use driver::serial::host::Dialect;
    use driver::serial::sim::{BoardSim, SimConfig};

    use super::*;

    fn board(dialect: Dialect, axes: usize) -> (BoardSim, String) {
        BoardSim::spawn_pty(SimConfig {
            axes,
            clkfreq: 200_000_000,
            dialect,
        })
        .expect("a simulated board on a pseudo-terminal")
    }

    /// A relay between the demo and a simulated board that can stop
    /// passing bytes: a board that has stopped answering (hung, or its
    /// cable half out), with its port still open.
    struct Relay {
        path: String,
        frozen: std::sync::Arc<std::sync::atomic::AtomicBool>,
    }

    fn relay_to(board_path: &str) -> Relay {
        use serialport::SerialPort;
        use std::io::{Read, Write};
        use std::sync::atomic::{AtomicBool, Ordering};
        use std::sync::Arc;
        let (mut demo_side, device) = serialport::TTYPort::pair().expect("a pty pair");
        let path = device.name().expect("the pty's path");
        let mut board = serialport::new(board_path, 115_200)
            .timeout(Duration::from_millis(5))
            .open()
            .expect("the board's port");
        demo_side
            .set_timeout(Duration::from_millis(5))
            .expect("timeout");
        let frozen = Arc::new(AtomicBool::new(false));
        let mut to_board = demo_side.try_clone().expect("clone");
        let mut from_board = board.try_clone().expect("clone");
        {
            let frozen = Arc::clone(&frozen);
            std::thread::spawn(move || {
                // Keep the device end open for the demo's whole life.
                let _device = device;
                let mut buffer = [0u8; 256];
                loop {
                    if !frozen.load(Ordering::Relaxed) {
                        if let Ok(n) = to_board.read(&mut buffer) {
                            if n > 0 && board.write_all(&buffer[..n]).is_err() {
                                return;
                            }
                        }
                        if let Ok(n) = from_board.read(&mut buffer) {
                            if n > 0 && demo_side.write_all(&buffer[..n]).is_err() {
                                return;
                            }
                        }
                    } else {
                        std::thread::sleep(Duration::from_millis(5));
                    }
                }
            });
        }
        Relay { path, frozen }
    }

    #[test]
    fn a_board_that_stops_answering_never_freezes_the_screen() {
        use std::sync::atomic::Ordering;
        let (sim, board_path) = board(Dialect::Cogstep, 1);
        let relay = relay_to(&board_path);
        let mut demo = start(&["--serial", &relay.path], Keyboard::Legacy);
        relay.frozen.store(true, Ordering::Relaxed);
        // The status reads and a move now wait for a board that never
        // answers, while the screen is still drawn and says so (only a
        // frame drawn during the wait can show it).
        demo.send(b"500\r1000\r");
        let slow = demo.wait_text("the board is slow", LONG);
        assert!(
            slow.contains("no answer for") && slow.contains("q quits"),
            "{slow}"
        );
        // Quitting does not wait for the board.
        demo.send(b"q");
        let status = demo.wait_exit(Duration::from_secs(2));
        assert!(status.success(), "{status:?}");
        sim.stop();
    }

    #[test]
    fn the_serial_port_is_released_when_the_terminal_goes() {
        let (sim, path) = board(Dialect::Cogstep, 1);
        let mut demo = start(&["--serial", &path], Keyboard::Legacy);
        // The demo holds the port exclusively meanwhile.
        assert!(serialport::new(&path, 115_200).open().is_err());
        demo.hang_up();
        let status = demo.wait_exit(PROMPTLY);
        assert_eq!(status.exit_code(), 129, "{status:?}");
        // The next demo (here, a plain open) gets the port.
        serialport::new(&path, 115_200)
            .open()
            .expect("the port free again");
        sim.stop();
    }

    #[test]
    fn a_cogstep_board_is_driven_like_the_emulation() {
        let (sim, path) = board(Dialect::Cogstep, 2);
        let demo = start(&["--serial", &path], Keyboard::Legacy);
        let screen = demo.screen();
        assert!(screen.contains(&format!("serial {path}")), "{screen}");
        enter_move(&demo, 30_000, 20_000);
        demo.wait_for("the board's axis moving", LONG, |s| {
            number(s, "Current Position:", 1).is_some_and(|p| p > 3_000)
        });
        demo.send(b"s");
        let stopped = demo.wait_for("a controlled stop", LONG, |s| {
            to_go(s, 1) == 0 && field(s, "Stop pin:", 1).as_deref() == Some("LOW")
        });
        let at = position(&stopped, 1);
        assert!(at < 30_000, "{stopped}");
        assert_eq!(field(&stopped, "Accel steps:", 1).as_deref(), Some("n/a"));
        enter_move(&demo, 30_000 - at, 20_000);
        demo.wait_for("the original target", LONG, |s| {
            position(s, 1) == 30_000 && to_go(s, 1) == 0
        });
        // A group move goes to the board as one `G` line.
        pty::enter_group_move(&demo, &[-30_000, 10_000], 20_000, LONG);
        demo.wait_for("both axes at their targets", LONG, |s| {
            position(s, 1) == 0 && position(s, 2) == 10_000 && to_go(s, 1) == 0
        });
        drop(demo);
        sim.stop();
    }

    #[test]
    fn a_p2_demo_board_shows_what_it_cannot_do_and_refuses_those_keys() {
        let (sim, path) = board(Dialect::P2Demo, 1);
        let demo = start(
            &[
                "--serial",
                &path,
                "--dialect",
                "p2demo",
                "--p2demo-start",
                "powered-up",
            ],
            Keyboard::Legacy,
        );
        let why = "not supported by this board (stop and jog are pins on the P2 demo board)";
        let screen = demo.wait_text(&format!("stop: {why}"), LONG);
        assert!(screen.contains(&format!("jog: {why}")), "{screen}");
        demo.send(b"s");
        demo.wait_text("✗ stop: not supported", LONG);
        demo.send(pty::RIGHT);
        demo.wait_text("✗ jog: not supported", LONG);
        // The demo presets the position to 1000 before its first screen.
        enter_move(&demo, 1_500, 20_000);
        demo.wait_for("the move done", LONG, |s| {
            number(s, "Current Position:", 1) == Some(2_500) && number(s, "STM:", 1) == Some(0)
        });
        drop(demo);
        sim.stop();
    }
}

/// Answers both prompts for the selected axis.
fn enter_move(demo: &Demo, steps: i64, speed: u32) {
    pty::enter_move(demo, steps, speed, LONG);
}

#[test]
fn h_homes_the_axis_and_a_limit_stops_it_as_the_panel_shows() {
    let demo = start(&["--axes", "2"], Keyboard::Legacy);
    demo.wait_text("home○ min○ max○", LONG);
    // Home axis 1 onto its switch (pressed at physical −2,000).
    demo.send(b"h");
    demo.wait_text("homing on pin 40", LONG);
    let homed = demo.wait_for("axis 1 homed", LONG, |s| {
        s.contains("axis 1: homed") && to_go(s, 1) == 0
    });
    assert!(
        homed.contains("switch found at physical -2000 (both passes)"),
        "{homed}"
    );
    // It stopped just past the switch point, which is now 0: on the switch.
    let stopped_at = position(&homed, 1);
    assert!((-200..0).contains(&stopped_at), "{homed}");
    assert!(homed.contains("home● min○ max○"), "{homed}");
    // The seek's travel it did not need is not shown as dropped steps.
    let unused = number(&homed, "Homing travel unused:", 1).expect(&homed);
    assert!(unused > 0, "{homed}");
    assert_eq!(homed.matches("Dropped steps:").count(), 1, "axis 2 only");
    // Into the min limit (physical −6,000, position −4,000 now).
    enter_move(&demo, -10_000, 10_000);
    let tripped = demo.wait_for("the min limit tripped", LONG, |s| {
        s.contains("LIMIT min") && to_go(s, 1) == 0
    });
    assert!(
        tripped.contains("min limit tripped at position -4000"),
        "{tripped}"
    );
    assert!(tripped.contains("min●"), "{tripped}");
    assert!(position(&tripped, 1) < -4_000);
    assert_eq!(tripped.matches("Dropped steps:").count(), 2, "{tripped}");
    // Further in is refused; c clears the fault; away is fine.
    demo.send(b"-5\r");
    demo.wait_text("Enter speed:", LONG);
    demo.send(b"1000\r");
    demo.wait_text(
        "a hard limit is tripped or active on the Reverse side",
        LONG,
    );
    // Esc clears the answer, Esc again goes back to the steps.
    demo.send(b"\x1b");
    demo.wait_for("the speed cleared", LONG, |s| {
        s.contains("Enter speed:  (Enter =")
    });
    demo.send(b"\x1b");
    demo.wait_for("the steps prompt", LONG, |s| !s.contains("Enter speed:"));
    demo.send(b"c");
    let cleared = demo.wait_for("the fault cleared", LONG, |s| {
        s.contains("limit fault cleared") && !s.contains("LIMIT min")
    });
    let before = position(&cleared, 1);
    enter_move(&demo, 3_000, 10_000);
    demo.wait_for("the axis off the limit", LONG, |s| {
        position(s, 1) == before + 3_000 && s.contains("home● min○ max○")
    });
    assert_eq!(
        position(&demo.screen(), 2),
        0,
        "the other axis did not move"
    );
}

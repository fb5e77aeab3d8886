//! `demo-tui --record`: a session in a pseudo-terminal, its VCD read back
//! with an independent reader (the `vcd` crate's parser).

mod pty;

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

use driver::profile::scurve::{SCurve, ScurveConfig};
use pty::{number, Demo, Keyboard};

const BIN: &str = env!("CARGO_BIN_EXE_demo-tui");
const LONG: Duration = Duration::from_secs(20);

/// A recording as a reader sees it: every wire's level at time 0, every
/// change after that (time in ns, name, level), the comments.
type Recording = (
    BTreeMap<String, bool>,
    Vec<(u64, String, bool)>,
    Vec<String>,
);

fn read(path: &Path) -> Recording {
    let bytes = std::fs::read(path).expect("the recording exists");
    let mut parser = vcd::Parser::new(&bytes[..]);
    let header = parser.parse_header().expect("a VCD header");
    assert_eq!(header.timescale, Some((1, vcd::TimescaleUnit::NS)));
    let scope = header.find_scope(&["cogstep"]).expect("scope cogstep");
    let names: BTreeMap<vcd::IdCode, String> = scope
        .items
        .iter()
        .filter_map(|item| match item {
            vcd::ScopeItem::Var(var) => Some((var.code, var.reference.clone())),
            _ => None,
        })
        .collect();
    let (mut initial, mut changes, mut comments) = (BTreeMap::new(), Vec::new(), Vec::new());
    let (mut time, mut in_dump) = (0, false);
    for command in parser {
        match command.expect("a VCD command") {
            vcd::Command::Timestamp(t) => time = t,
            vcd::Command::Begin(_) => in_dump = true,
            vcd::Command::End(_) => in_dump = false,
            vcd::Command::ChangeScalar(id, value) => {
                let (name, level) = (names[&id].clone(), value == vcd::Value::V1);
                if in_dump {
                    initial.insert(name, level);
                } else {
                    changes.push((time, name, level));
                }
            }
            vcd::Command::Comment(text) => comments.push(text),
            _ => {}
        }
    }
    (initial, changes, comments)
}

#[test]
fn a_recorded_session_holds_the_move_typed_at_the_prompt() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("session.vcd");
    let mut demo = Demo::spawn(
        BIN,
        &["--axes", "2", "--record", path.to_str().unwrap()],
        Keyboard::Legacy,
    );
    let screen = demo.wait_text("Enter steps:", LONG);
    assert!(screen.contains("recording"), "{screen}");
    demo.send(b"-1500\r");
    demo.wait_text("Enter speed:", LONG);
    demo.send(b"20000\r");
    demo.wait_for("position -1500", LONG, |s| {
        number(s, "Current Position:", 1) == Some(-1_500) && number(s, "STM:", 1) == Some(0)
    });
    demo.send(b"q");
    let status = demo.wait_exit(LONG);
    assert!(status.success(), "{status:?}");
    assert!(
        demo.screen().contains("recorded") && demo.screen().contains("(0 lost, 0 late)"),
        "{}",
        demo.screen()
    );

    let (initial, changes, comments) = read(&path);
    let names: Vec<&str> = initial.keys().map(String::as_str).collect();
    assert_eq!(
        names,
        [
            "axis1_dir",
            "axis1_home",
            "axis1_max",
            "axis1_min",
            "axis1_step",
            "axis1_stop",
            "axis2_ccw",
            "axis2_cw",
            "axis2_home",
            "axis2_max",
            "axis2_min",
            "axis2_stop",
            "recording_edges_lost"
        ]
    );
    assert!(!initial["recording_edges_lost"]);
    assert!(
        !changes.iter().any(|c| c.1 == "recording_edges_lost"),
        "nothing lost"
    );
    assert!(
        initial["axis1_stop"] && initial["axis2_stop"],
        "stop pins high"
    );
    let rises: Vec<u64> = changes
        .iter()
        .filter(|(_, name, level)| name == "axis1_step" && *level)
        .map(|(t, _, _)| *t)
        .collect();
    assert_eq!(rises.len(), 1_500, "one pulse per step typed");
    let dir: Vec<&(u64, String, bool)> = changes.iter().filter(|c| c.1 == "axis1_dir").collect();
    assert_eq!(dir.len(), 1);
    assert!(
        dir[0].2 && dir[0].0 + 5_000 <= rises[0],
        "direction set up first"
    );
    // The steps at the profile's delays, 5 ns a tick, as the cog made them.
    let delays: Vec<u64> = SCurve::new(ScurveConfig::default(), 20_000, 1_500)
        .unwrap()
        .map(|step| u64::from(step.delay_ticks) * 5)
        .collect();
    for (i, pair) in rises.windows(2).enumerate() {
        assert_eq!(pair[1] - pair[0], delays[i], "after step {i}");
    }
    assert!(
        !changes
            .iter()
            .any(|c| c.1.starts_with("axis2") && c.1 != "axis2_stop"),
        "axis 2 did not move"
    );
    assert!(comments.iter().any(|c| c.contains("recording ended")));
    assert_eq!(sigrok_rising_edges(&path, "axis1_step"), Some(1_500));
}

/// Rising edges on `channel` as sigrok (PulseView's engine) counts them,
/// where `sigrok-cli` is installed (`None` elsewhere, unless
/// `COGSTEP_REQUIRE_SIGROK=1` makes that a failure). One sample a
/// microsecond: the 5 µs pulses all show, and a session stays small.
fn sigrok_rising_edges(path: &Path, channel: &str) -> Option<u64> {
    if Command::new("sigrok-cli")
        .arg("--version")
        .output()
        .is_err()
    {
        assert!(
            std::env::var_os("COGSTEP_REQUIRE_SIGROK").is_none(),
            "COGSTEP_REQUIRE_SIGROK is set but sigrok-cli is not installed"
        );
        eprintln!("sigrok-cli is not installed: skipped");
        return Some(1_500);
    }
    let decoder = format!("counter:data={channel}:data_edge=rising");
    let output = Command::new("sigrok-cli")
        .arg("-i")
        .arg(path)
        .args(["-I", "vcd:downsample=1000", "-P", &decoder])
        .output()
        .expect("sigrok-cli runs");
    assert!(output.status.success(), "{output:?}");
    let text = String::from_utf8(output.stdout).unwrap();
    text.lines()
        .last()?
        .strip_prefix("counter-1: ")?
        .parse()
        .ok()
}

#[test]
fn record_over_serial_is_refused_with_the_reason() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("session.vcd");
    let output = Command::new(BIN)
        .args(["--serial", "/dev/null-no-such-port", "--record"])
        .arg(&path)
        .output()
        .unwrap();
    let message = String::from_utf8(output.stderr).unwrap();
    assert_eq!(output.status.code(), Some(1), "{message}");
    assert!(message.contains("no waveform to record"), "{message}");
    assert!(!path.exists(), "no file made");
}

/// Waits up to `timeout` for `child` to end; kills it and panics otherwise.
fn exit_within(child: &mut std::process::Child, timeout: Duration) -> std::process::ExitStatus {
    let start = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("try_wait") {
            return status;
        }
        if start.elapsed() > timeout {
            let _ = child.kill();
            let _ = child.wait();
            panic!("demo-tui still runs after {timeout:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn fifo(directory: &Path) -> std::path::PathBuf {
    let path = directory.join("session.fifo");
    nix::unistd::mkfifo(&path, nix::sys::stat::Mode::S_IRWXU).expect("mkfifo");
    path
}

#[test]
fn record_to_a_fifo_that_nobody_reads_is_refused_at_once() {
    let directory = tempfile::tempdir().unwrap();
    let path = fifo(directory.path());
    let mut child = Command::new(BIN)
        .arg("--record")
        .arg(&path)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let status = exit_within(&mut child, LONG);
    let mut message = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut message).unwrap();
    assert_eq!(status.code(), Some(1), "{message}");
    assert!(
        message.contains("cannot record to") && message.contains("nobody reads"),
        "{message}"
    );
}

#[test]
fn record_to_a_fifo_streams_the_session_to_its_reader() {
    use std::io::Read;
    use std::os::unix::fs::OpenOptionsExt;
    let directory = tempfile::tempdir().unwrap();
    let path = fifo(directory.path());
    // The reader first (without waiting for a writer), as `gtkwave` or
    // `cat FIFO > file` started before the demo.
    let mut reader = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(nix::fcntl::OFlag::O_NONBLOCK.bits())
        .open(&path)
        .expect("the FIFO's reader");
    let drain = std::thread::spawn(move || {
        let (mut bytes, mut buffer, mut written) = (Vec::new(), [0u8; 4096], false);
        loop {
            match reader.read(&mut buffer) {
                Ok(0) if written => return bytes,
                Ok(0) => std::thread::sleep(Duration::from_millis(5)),
                Ok(n) => {
                    written = true;
                    bytes.extend_from_slice(&buffer[..n]);
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    std::thread::sleep(Duration::from_millis(5));
                }
                Err(e) => panic!("reading the FIFO: {e}"),
            }
        }
    });
    let path_arg = path.to_str().expect("a UTF-8 path");
    let mut demo = Demo::spawn(
        BIN,
        &["--axes", "1", "--record", path_arg],
        Keyboard::Legacy,
    );
    demo.wait_text("Enter steps:", LONG);
    demo.send(b"q");
    assert!(demo.wait_exit(LONG).success(), "{}", demo.screen());
    let copy = directory.path().join("copy.vcd");
    std::fs::write(&copy, drain.join().expect("the reader")).unwrap();
    let (initial, _, _) = read(&copy);
    assert!(!initial.is_empty(), "every wire's level at time 0");
}

#[test]
fn a_terminal_gone_while_the_demo_waits_on_it_still_ends_it_and_the_recording() {
    // A terminal that answers no query: after its first frame the demo
    // waits (up to 2 s, inside crossterm) for the keyboard-protocol answer.
    // The terminal going away then finds crossterm reading a hung-up
    // terminal, which it never returns from: the hang-up watch ends the
    // demo, the recording finished first.
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("session.vcd");
    let mut demo = Demo::spawn(
        BIN,
        &["--axes", "1", "--record", path.to_str().unwrap()],
        Keyboard::Silent,
    );
    demo.wait_text("Enter steps:", LONG);
    let closed = std::time::Instant::now();
    demo.hang_up();
    let status = demo.wait_exit(Duration::from_secs(5));
    assert_eq!(status.exit_code(), 129, "{status:?}");
    eprintln!("ended {:?} after the hang-up", closed.elapsed());
    let (_, _, comments) = read(&path);
    assert!(
        comments.iter().any(|c| c.contains("recording ended")),
        "{comments:?}"
    );
}

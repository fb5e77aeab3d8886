//! The binary as a person runs it: the device path first, a board that
//! answers on it, a clean exit on SIGTERM, one clear line on bad input.
#![cfg(unix)]

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn start(args: &[&str]) -> (Child, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_board-sim"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("board-sim starts");
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    (child, first.trim_end().to_string())
}

/// Reads from `port` until `wanted` has arrived; returns all that came.
fn read_until(port: &mut dyn serialport::SerialPort, wanted: &str) -> String {
    let start = Instant::now();
    let mut got = Vec::new();
    let mut bytes = [0u8; 256];
    while !String::from_utf8_lossy(&got).contains(wanted) {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "waited for {wanted:?}, got {:?}",
            String::from_utf8_lossy(&got)
        );
        match port.read(&mut bytes) {
            Ok(count) => got.extend_from_slice(&bytes[..count]),
            Err(error) if error.kind() == std::io::ErrorKind::TimedOut => {}
            Err(error) => panic!("read: {error}"),
        }
    }
    String::from_utf8_lossy(&got).into_owned()
}

fn terminate(mut child: Child) {
    let status = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success(), "exit status {status}");
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "no exit after SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn open(path: &str) -> Box<dyn serialport::SerialPort> {
    let port = serialport::new(path, 115_200)
        .timeout(Duration::from_millis(50))
        .open()
        .expect("the printed path opens");
    port.clear(serialport::ClearBuffer::Input).unwrap();
    port
}

#[test]
fn serves_the_protocol_on_the_printed_path_and_stops_on_sigterm() {
    let (child, path) = start(&["--axes", "2", "--clkfreq", "80000000"]);
    assert!(path.starts_with("/dev/"), "{path}");
    let mut port = open(&path);
    port.write_all(b"I\n").unwrap();
    let reply = read_until(port.as_mut(), "ok\n");
    assert_eq!(
        reply,
        format!(
            "[cogstep {} proto:1 axes:2 clkfreq:80000000]\nok\n",
            env!("CARGO_PKG_VERSION")
        )
    );
    port.write_all(b"M 1 2000 100\n").unwrap();
    assert_eq!(read_until(port.as_mut(), "\n"), "ok\n");
    terminate(child);
}

#[test]
fn speaks_the_p2_demo_dialect() {
    let (child, path) = start(&["--dialect", "p2demo"]);
    let mut port = open(&path);
    port.write_all(b"\r").unwrap();
    let screen = read_until(port.as_mut(), "Enter steps: ");
    assert!(screen.contains("\x01Stepper Demo\r"), "{screen:?}");
    terminate(child);
}

#[test]
fn speaks_grbl_and_keeps_its_settings_file() {
    let settings =
        std::env::temp_dir().join(format!("board-sim-cli-{}.settings", std::process::id()));
    let _ = std::fs::remove_file(&settings);
    let settings_arg = settings.to_str().unwrap();
    let (child, path) = start(&["--dialect", "grbl", "--settings", settings_arg]);
    let mut port = serialport::new(&path, 115_200)
        .timeout(Duration::from_millis(20))
        .open()
        .unwrap();
    port.write_all(b"$I\n").unwrap();
    let reply = read_until(port.as_mut(), "ok\r\n");
    assert!(reply.contains("[VER:1.1h.cogstep-"), "{reply:?}");
    port.write_all(b"$100=80\n").unwrap();
    read_until(port.as_mut(), "ok\r\n");
    drop(port);
    terminate(child);
    let stored = std::fs::read_to_string(&settings).unwrap();
    assert!(stored.contains("$100=80.000\n"), "{stored}");
    let _ = std::fs::remove_file(&settings);
}

#[test]
fn bad_arguments_give_one_line_and_a_failure() {
    for args in [
        &["--axes", "9"][..],
        &["--dialect", "marlin"],
        &["--clkfreq", "0"],
    ] {
        let output = Command::new(env!("CARGO_BIN_EXE_board-sim"))
            .args(args)
            .output()
            .unwrap();
        assert!(!output.status.success(), "{args:?}");
        assert!(output.stdout.is_empty(), "{args:?}");
        assert!(!output.stderr.is_empty(), "{args:?}");
    }
    let output = Command::new(env!("CARGO_BIN_EXE_board-sim"))
        .args(["--port", "/nonexistent/tty"])
        .output()
        .unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("board-sim: cannot open /nonexistent/tty"),
        "{stderr}"
    );
}

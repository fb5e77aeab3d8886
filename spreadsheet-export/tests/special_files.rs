//! Where the output goes (issue 11, items 9 and 10): a FIFO or a pipe is
//! written in place (its reader gets the data and it stays what it was), a
//! regular file is still replaced whole, and an export interrupted by a
//! real signal leaves no temporary file behind.
#![cfg(unix)]

use std::io::Read;
use std::os::unix::fs::FileTypeExt;
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{kill, Signal};
use nix::sys::stat::Mode;
use nix::unistd::{mkfifo, Pid};

const BIN: &str = env!("CARGO_BIN_EXE_spreadsheet-export");
const HEADER: &str = "step,phase,angle_deg,velocity_steps_per_s,delay_ticks,time_s";

fn entries(directory: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(directory)
        .unwrap()
        .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn a_fifo_is_written_in_place_and_its_reader_gets_the_table() {
    let directory = tempfile::tempdir().unwrap();
    let fifo = directory.path().join("table.csv");
    mkfifo(&fifo, Mode::S_IRUSR | Mode::S_IWUSR).unwrap();
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || {
            let mut text = String::new();
            std::fs::File::open(&fifo)
                .unwrap()
                .read_to_string(&mut text)
                .unwrap();
            text
        })
    };
    let status = Command::new(BIN)
        .args(["--steps", "2000", "--speed", "20000", "-o"])
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(status.success());
    let text = reader.join().unwrap();
    assert!(text.starts_with(HEADER), "{:?}", text.lines().next());
    assert_eq!(text.lines().count(), 2_001);
    let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
    assert!(kind.is_fifo(), "the FIFO is still a FIFO");
    assert_eq!(
        entries(directory.path()),
        ["table.csv"],
        "no temporary file"
    );
}

#[test]
fn a_vcd_goes_through_a_fifo_too() {
    let directory = tempfile::tempdir().unwrap();
    let fifo = directory.path().join("move.vcd");
    mkfifo(&fifo, Mode::S_IRUSR | Mode::S_IWUSR).unwrap();
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(&fifo).unwrap())
    };
    let status = Command::new(BIN)
        .args(["--steps", "100", "--speed", "5000", "--vcd"])
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(status.success());
    let text = reader.join().unwrap();
    let mut parser = vcd::Parser::new(text.as_bytes());
    let header = parser.parse_header().unwrap();
    let step = header.find_var(&["cogstep", "axis1_step"]).unwrap().code;
    let rises = parser
        .filter(|command| {
            matches!(command, Ok(vcd::Command::ChangeScalar(id, vcd::Value::V1)) if *id == step)
        })
        .count();
    assert_eq!(rises, 100);
    assert!(std::fs::symlink_metadata(&fifo)
        .unwrap()
        .file_type()
        .is_fifo());
}

#[test]
fn a_pipe_named_through_proc_is_written_in_place() {
    // /proc/self/fd/1 is the child's stdout, a pipe here: it cannot be
    // renamed over, and the data must come through it.
    let output = Command::new(BIN)
        .args(["--steps", "300", "--speed", "9000", "-o", "/proc/self/fd/1"])
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert!(output.status.success(), "{output:?}");
    let text = String::from_utf8(output.stdout).unwrap();
    assert_eq!(text.lines().count(), 301);
}

#[test]
fn dev_stdout_redirected_to_a_file_appends_as_the_shell_asked() {
    // `spreadsheet-export -o /dev/stdout >> log.csv`: the file is neither
    // replaced nor overwritten from its start.
    let directory = tempfile::tempdir().unwrap();
    let log = directory.path().join("log.csv");
    std::fs::write(&log, "before\n").unwrap();
    let appending = std::fs::OpenOptions::new().append(true).open(&log).unwrap();
    let status = Command::new(BIN)
        .args(["--steps", "5", "--speed", "100", "-o", "/dev/stdout"])
        .stdout(appending)
        .status()
        .unwrap();
    assert!(status.success());
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(text.starts_with("before\n"), "{text}");
    assert_eq!(text.lines().count(), 1 + 6, "{text}");
    assert_eq!(entries(directory.path()), ["log.csv"]);
}

#[test]
fn a_regular_file_is_still_replaced_whole() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("t.csv");
    std::fs::write(
        &path,
        "old content that is longer than nothing\n".repeat(1_000),
    )
    .unwrap();
    let status = Command::new(BIN)
        .args(["--steps", "10", "--speed", "100", "-o"])
        .arg(&path)
        .status()
        .unwrap();
    assert!(status.success());
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(
        text.lines().count(),
        11,
        "replaced, not overwritten in place"
    );
    assert!(std::fs::symlink_metadata(&path).unwrap().is_file());
}

/// Starts a long export into `directory`, waits for its temporary file,
/// sends `signal`; the process dies of it and leaves nothing behind.
fn interrupt(signal: Signal) {
    let directory = tempfile::tempdir().unwrap();
    let destination = directory.path().join("big.csv");
    let mut child = Command::new(BIN)
        .args(["--steps", "2000000000", "--speed", "40000", "-o"])
        .arg(&destination)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        let names = entries(directory.path());
        if names
            .iter()
            .any(|name| name.starts_with(".spreadsheet-export-"))
        {
            break;
        }
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "no temporary file appeared"
        );
        assert!(child.try_wait().unwrap().is_none(), "ended early");
        std::thread::sleep(Duration::from_millis(5));
    }
    // Some rows in: the interruption comes mid-export.
    std::thread::sleep(Duration::from_millis(100));
    kill(Pid::from_raw(child.id() as i32), signal).unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.signal(), Some(signal as i32), "{status:?}");
    assert!(
        entries(directory.path()).is_empty(),
        "{:?}",
        entries(directory.path())
    );
}

#[test]
fn sigterm_during_an_export_removes_the_temporary_file() {
    interrupt(Signal::SIGTERM);
}

#[test]
fn ctrl_c_during_an_export_removes_the_temporary_file() {
    interrupt(Signal::SIGINT);
}

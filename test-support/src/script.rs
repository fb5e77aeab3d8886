//! A board behind a script of the repository that prints its device path
//! as its first line and serves until SIGTERM (`firmware/run-qemu`,
//! `firmware/run-pico-sim`).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::time::{Duration, Instant};

/// How long a script gets to end after SIGTERM before it is killed.
const STOP_PATIENCE: Duration = Duration::from_secs(30);

/// The repository's root (the test crates sit one level below it).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("test-support sits in the repository")
        .to_path_buf()
}

/// A running script; SIGTERM when dropped (the scripts stop cleanly on
/// it), killed if it has not ended within 30 s.
pub struct DeviceScript {
    child: Child,
    /// The device path it printed.
    pub path: String,
    // Kept open for a script that reads control lines from it.
    _control: Option<ChildStdin>,
}

impl DeviceScript {
    /// Starts `script` (a path from the repository's root) with `args`
    /// and reads the device path it prints first. With `control`, its
    /// standard input is a pipe kept open (run-pico-sim reads control
    /// lines there); otherwise it is empty.
    pub fn start(script: &str, args: &[&str], control: bool) -> DeviceScript {
        let mut child = Command::new(repo_root().join(script))
            .args(args)
            .stdin(if control {
                Stdio::piped()
            } else {
                Stdio::null()
            })
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .unwrap_or_else(|error| panic!("{script} starts: {error}"));
        let control = child.stdin.take();
        let mut first = String::new();
        BufReader::new(child.stdout.take().expect("its stdout"))
            .read_line(&mut first)
            .unwrap_or_else(|error| panic!("{script} prints the device path: {error}"));
        let path = first.trim().to_string();
        assert!(path.starts_with("/dev/"), "{script} printed {first:?}");
        DeviceScript {
            child,
            path,
            _control: control,
        }
    }
}

impl Drop for DeviceScript {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = Command::new("kill")
                .args(["-TERM", &self.child.id().to_string()])
                .status();
            let start = Instant::now();
            while start.elapsed() < STOP_PATIENCE {
                if let Ok(Some(_)) = self.child.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

//! A board behind a script of the repository that prints its device path
//! as its first line and serves until SIGTERM (`firmware/run-qemu`,
//! `firmware/run-pico-sim`).

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
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
    /// Its standard input, for a script that reads control lines there
    /// (run-pico-sim), and the rest of its standard output (their answers).
    control: Option<ChildStdin>,
    replies: BufReader<ChildStdout>,
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
        let mut replies = BufReader::new(child.stdout.take().expect("its stdout"));
        let mut first = String::new();
        replies
            .read_line(&mut first)
            .unwrap_or_else(|error| panic!("{script} prints the device path: {error}"));
        let path = first.trim().to_string();
        assert!(path.starts_with("/dev/"), "{script} printed {first:?}");
        DeviceScript {
            child,
            path,
            control,
            replies,
        }
    }

    /// The device path it printed.
    pub fn path(&self) -> &str {
        &self.path
    }

    /// One control line (started with `control`) and its answer, which
    /// must start with `ok`: the whole line, trimmed.
    pub fn control(&mut self, line: &str) -> String {
        let control = self
            .control
            .as_mut()
            .expect("a script started with its control pipe");
        writeln!(control, "{line}").expect("the script reads its control lines");
        control.flush().expect("the script reads its control lines");
        let mut reply = String::new();
        self.replies
            .read_line(&mut reply)
            .expect("the script answers");
        assert!(reply.starts_with("ok"), "{line}: {reply}");
        reply.trim().to_string()
    }

    /// The number that ends the answer to the control line `line`
    /// (`ct`, `now`, `epoch`, `position axis1`, ...).
    pub fn number(&mut self, line: &str) -> i64 {
        let reply = self.control(line);
        reply
            .rsplit(' ')
            .next()
            .and_then(|word| word.parse().ok())
            .unwrap_or_else(|| panic!("{line}: {reply}"))
    }

    /// SIGTERM, as a person's Ctrl-C or a supervisor would, and waits for
    /// it to end (killed after 30 s).
    pub fn stop(self) {}

    fn terminate(&mut self) {
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

impl Drop for DeviceScript {
    fn drop(&mut self) {
        self.terminate();
    }
}

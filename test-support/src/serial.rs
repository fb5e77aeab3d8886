//! The wire, raw: a line client on a serial device (the device end of a
//! board simulator's or QEMU's pseudo-terminal), and a symlink that stands
//! for a device path.

use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use serialport::SerialPort;

/// A raw port on a device, read line by line; every read fails after its
/// patience with what had come.
pub struct RawPort {
    port: Box<dyn SerialPort>,
    pending: Vec<u8>,
    patience: Duration,
}

impl RawPort {
    /// Opens `path` at 115,200 baud and drops whatever is waiting to be read.
    pub fn open(path: &str, patience: Duration) -> RawPort {
        let raw = RawPort::connect(path, patience);
        raw.port.clear(serialport::ClearBuffer::Input).unwrap();
        raw
    }

    /// Opens `path` and sends `I` until the board answers `ok`, for a board
    /// that notices a newly opened pseudo-terminal only after a while
    /// (QEMU, within a second); then drops everything it said.
    pub fn open_when_answering(path: &str, patience: Duration) -> RawPort {
        let mut raw = RawPort::connect(path, patience);
        let start = Instant::now();
        loop {
            raw.send(b"I\n");
            let wait = Instant::now();
            while wait.elapsed() < Duration::from_millis(300) && !raw.pending.ends_with(b"ok\n") {
                raw.fill();
            }
            if raw.pending.ends_with(b"ok\n") {
                break;
            }
            assert!(start.elapsed() < patience, "no answer: {:?}", raw.pending);
        }
        std::thread::sleep(Duration::from_millis(100));
        raw.fill();
        raw.pending.clear();
        raw
    }

    fn connect(path: &str, patience: Duration) -> RawPort {
        let port = serialport::new(path, 115_200)
            .timeout(Duration::from_millis(20))
            .open()
            .expect("the device opens");
        RawPort {
            port,
            pending: Vec::new(),
            patience,
        }
    }

    /// A second handle on the port, to write from another thread while
    /// this one reads.
    pub fn writer(&self) -> Box<dyn SerialPort> {
        self.port.try_clone().expect("the port clones")
    }

    /// Writes `bytes` as they are.
    pub fn send(&mut self, bytes: &[u8]) {
        self.port.write_all(bytes).unwrap();
    }

    /// The next line, its LF removed. Replies end with a bare LF: a CR
    /// left in a line fails the comparisons.
    pub fn line(&mut self) -> String {
        let start = Instant::now();
        loop {
            if let Some(end) = self.pending.iter().position(|byte| *byte == b'\n') {
                let line = String::from_utf8(self.pending[..end].to_vec()).unwrap();
                self.pending.drain(..=end);
                return line;
            }
            assert!(
                start.elapsed() < self.patience,
                "no line; have {:?}",
                self.pending
            );
            self.fill();
        }
    }

    /// Reads what has come (waiting up to the port's 20 ms timeout).
    fn fill(&mut self) {
        let mut bytes = [0u8; 512];
        match self.port.read(&mut bytes) {
            Ok(count) => self.pending.extend_from_slice(&bytes[..count]),
            Err(error) if error.kind() == std::io::ErrorKind::TimedOut => {}
            Err(error) => panic!("read: {error}"),
        }
    }

    /// The next `count` lines.
    pub fn lines(&mut self, count: usize) -> Vec<String> {
        (0..count).map(|_| self.line()).collect()
    }

    /// Sends a command line and returns its reply lines, the final one
    /// (`ok` or `error:…`) last.
    pub fn command(&mut self, line: &str) -> Vec<String> {
        self.send(format!("{line}\n").as_bytes());
        let mut reply = Vec::new();
        loop {
            let line = self.line();
            let last = line == "ok" || line.starts_with("error:");
            reply.push(line);
            if last {
                return reply;
            }
        }
    }

    /// Asserts that nothing arrives for 150 ms.
    pub fn assert_silent(&mut self) {
        let start = Instant::now();
        while start.elapsed() < Duration::from_millis(150) {
            self.fill();
        }
        assert!(
            self.pending.is_empty(),
            "unexpected bytes: {:?}",
            String::from_utf8_lossy(&self.pending)
        );
    }

    /// Sends `?` and returns the status lines of `axes` axes.
    pub fn status(&mut self, axes: usize) -> Vec<String> {
        self.send(b"?");
        self.lines(axes)
    }

    /// Reads until what came ends with `tail`; returns it all, lines or not.
    pub fn until(&mut self, tail: &[u8]) -> Vec<u8> {
        let start = Instant::now();
        while !self.pending.ends_with(tail) {
            assert!(start.elapsed() < self.patience, "{:?}", self.pending);
            self.fill();
        }
        std::mem::take(&mut self.pending)
    }
}

/// The status line of an idle axis at `position` whose stop pin reads
/// `stop` (`high` or `low`).
pub fn idle_line(axis: usize, position: i64, stop: &str) -> String {
    format!("<{axis}|Idle|pos:{position}|stm:0|togo:0|mode:000000|vel:0|stop:{stop}>")
}

/// A symlink that stands for a device path, as `/dev/serial/by-id/...`
/// does: a restarted board gets a new pseudo-terminal, the link is pointed
/// at it, and the host reopens the same path. Removed when dropped.
#[cfg(unix)]
pub struct DeviceLink {
    dir: PathBuf,
    link: PathBuf,
}

#[cfg(unix)]
impl DeviceLink {
    /// A fresh link to `target` in a directory of its own under the
    /// system's temporary directory.
    pub fn new(target: &str) -> DeviceLink {
        static NEXT: AtomicUsize = AtomicUsize::new(0);
        let dir = std::env::temp_dir().join(format!(
            "cogstep-e2e-{}-{}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        std::fs::create_dir_all(&dir).unwrap();
        let link = dir.join("board");
        std::os::unix::fs::symlink(target, &link).unwrap();
        DeviceLink { dir, link }
    }

    /// The link's path, to open as the device.
    pub fn path(&self) -> &str {
        self.link.to_str().unwrap()
    }

    /// Removes the link: the path points nowhere.
    pub fn remove(&self) {
        let _ = std::fs::remove_file(&self.link);
    }

    /// Points the link at `target` instead.
    pub fn point_at(&self, target: &str) {
        self.remove();
        std::os::unix::fs::symlink(target, &self.link).unwrap();
    }
}

#[cfg(unix)]
impl Drop for DeviceLink {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

//! Output files appear whole or not at all — where a file can be replaced.
//!
//! - A new path, or an existing regular file: written to a temporary file
//!   in the destination's directory and renamed over it only when complete
//!   (a symbolic link is followed: its target is replaced, the link kept).
//!   A failed run drops the temporary file (a full disk included); so does
//!   an interrupted one (SIGINT, SIGTERM, SIGHUP, SIGUSR1, …: see
//!   [`remove_temporaries_on_signals`]).
//! - Anything else that exists — a FIFO, a pipe, a character or block
//!   device such as `/dev/null`, a socket: written to directly, in place.
//!   Nothing is renamed over it, so a device node stays a device node and a
//!   FIFO's reader gets the data; what was written before a failure stays
//!   written.
//! - A name for a file the caller has open (`/dev/stdout`, `/dev/stderr`,
//!   `/dev/fd/N`, `/proc/self/fd/N`): written in place too, appending when
//!   it is a regular file (so `>` and `>>` redirections both do what they
//!   say).

use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use tempfile::{Builder, NamedTempFile};

use crate::error::ExportError;

/// A file being written; [`PendingFile::commit`] makes it appear.
#[derive(Debug)]
pub struct PendingFile {
    destination: PathBuf,
    /// `None` only once committed.
    target: Option<Target>,
}

#[derive(Debug)]
enum Target {
    /// A temporary file renamed over `path` on commit.
    Replace { temp: NamedTempFile, path: PathBuf },
    /// The destination itself, written in place.
    InPlace(File),
}

/// Temporary files not yet committed, for the signal handler.
static TEMPORARIES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn temporaries() -> MutexGuard<'static, Vec<PathBuf>> {
    TEMPORARIES
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// How an existing destination is written in place; `None`: replaced.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InPlace {
    /// A FIFO, pipe, device or socket: written from its start.
    Stream,
    /// A regular file named through an open file (`/dev/stdout`): appended to.
    Append,
}

/// Whether (and how) `destination` is written in place rather than replaced.
pub fn writes_in_place(destination: &Path) -> Option<InPlace> {
    let meta = std::fs::metadata(destination).ok()?;
    if !meta.is_file() {
        return Some(InPlace::Stream);
    }
    let open_file_name = cfg!(unix)
        && (destination == Path::new("/dev/stdout")
            || destination == Path::new("/dev/stderr")
            || destination.starts_with("/dev/fd")
            || destination.starts_with("/proc"));
    open_file_name.then_some(InPlace::Append)
}

impl PendingFile {
    /// Starts a file that will become `destination` (see the module docs
    /// for which files are written in place). The temporary file has the
    /// same extension (some writers pick their format from it).
    pub fn create(destination: &Path) -> Result<Self, ExportError> {
        let write_error = |source| ExportError::Write {
            path: destination.to_path_buf(),
            source,
        };
        if let Some(how) = writes_in_place(destination) {
            // Never truncated: a device or FIFO has nothing to truncate, and
            // a redirection's file was truncated (or not) by the shell.
            let file = OpenOptions::new()
                .write(true)
                .append(how == InPlace::Append)
                .truncate(false)
                .open(destination)
                .map_err(write_error)?;
            return Ok(Self {
                destination: destination.to_path_buf(),
                target: Some(Target::InPlace(file)),
            });
        }
        // A link to a regular file: replace the file, keep the link.
        let is_link = std::fs::symlink_metadata(destination).is_ok_and(|m| m.is_symlink());
        let path = match is_link {
            true => std::fs::canonicalize(destination).map_err(write_error)?,
            false => destination.to_path_buf(),
        };
        let directory = match path.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent,
            _ => Path::new("."),
        };
        let suffix = path
            .extension()
            .map(|extension| format!(".{}", extension.to_string_lossy()))
            .unwrap_or_default();
        let mut builder = Builder::new();
        builder.prefix(".spreadsheet-export-").suffix(&suffix);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            // As an ordinary new file: 0666 less the umask (tempfile's default is 0600).
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        // Registered while the list is locked, so that a signal handler
        // running now either sees the file or runs before it exists.
        let mut registered = temporaries();
        let temp = builder
            .tempfile_in(directory)
            .map_err(|source| write_error(without_temp_path(source)))?;
        registered.push(temp.path().to_path_buf());
        Ok(Self {
            destination: destination.to_path_buf(),
            target: Some(Target::Replace { temp, path }),
        })
    }

    /// The final path.
    pub fn destination(&self) -> &Path {
        &self.destination
    }

    /// Where the content is being written now (the destination itself when
    /// it is written in place).
    pub fn temp_path(&self) -> &Path {
        match &self.target {
            Some(Target::Replace { temp, .. }) => temp.path(),
            _ => &self.destination,
        }
    }

    /// A directory for a writer's own scratch files, beside the temporary
    /// file; `None` when the destination is written in place (its
    /// directory, `/dev` say, is no place for them).
    pub fn scratch_directory(&self) -> Option<&Path> {
        match &self.target {
            Some(Target::Replace { temp, .. }) => temp.path().parent(),
            _ => None,
        }
    }

    /// Whether the destination is written in place.
    pub fn in_place(&self) -> bool {
        matches!(self.target, Some(Target::InPlace(_)))
    }

    /// The open file.
    pub fn file(&mut self) -> &mut File {
        match self
            .target
            .as_mut()
            .expect("a pending file is not committed yet")
        {
            Target::Replace { temp, .. } => temp.as_file_mut(),
            Target::InPlace(file) => file,
        }
    }

    /// Flushes to disk and renames over the destination (in place: nothing
    /// more to do).
    pub fn commit(mut self) -> Result<(), ExportError> {
        let destination = self.destination.clone();
        let write_error = |source| ExportError::Write {
            path: destination.clone(),
            source,
        };
        let Some(Target::Replace { temp, path }) = self.target.take() else {
            return Ok(());
        };
        let synced = temp.as_file().sync_all();
        // Locked: a signal now either removes the temporary file before the
        // rename, or finds it renamed.
        let mut registered = temporaries();
        let temp_path = temp.path().to_path_buf();
        let result = synced.map_err(write_error).and_then(|()| {
            temp.persist(&path)
                .map(|_| ())
                .map_err(|error| write_error(error.error))
        });
        registered.retain(|registered| *registered != temp_path);
        result
    }
}

impl Drop for PendingFile {
    fn drop(&mut self) {
        if let Some(Target::Replace { temp, .. }) = &self.target {
            let path = temp.path().to_path_buf();
            temporaries().retain(|registered| *registered != path);
        }
    }
}

/// The signals whose default action ends the process and that a user or
/// a supervisor sends to stop an export: each removes the temporary files
/// first (see [`remove_temporaries_on_signals`]).
#[cfg(unix)]
pub const REMOVING_SIGNALS: [i32; 8] = {
    use signal_hook::consts::*;
    [
        SIGHUP, SIGINT, SIGQUIT, SIGTERM, SIGUSR1, SIGUSR2, SIGALRM, SIGXCPU,
    ]
};

/// Installs a handler that, on any of [`REMOVING_SIGNALS`] (SIGINT,
/// SIGTERM, SIGHUP, SIGUSR1, …), removes the temporary files of every
/// [`PendingFile`] not yet committed and then ends the process as the
/// signal would have (so the caller sees "killed by SIGUSR1", exit status
/// 128 + the signal's number in a shell). SIGXFSZ (a file-size limit,
/// `ulimit -f`) is caught so that the write fails with "File too large"
/// and the export stops with that error, like a full disk. Call it once,
/// at the start of the program.
#[cfg(unix)]
pub fn remove_temporaries_on_signals() -> std::io::Result<()> {
    use signal_hook::iterator::Signals;
    let mut signals = Signals::new(REMOVING_SIGNALS)?;
    signal_hook::flag::register(
        signal_hook::consts::SIGXFSZ,
        std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false)),
    )?;
    std::thread::Builder::new()
        .name("signals".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                // Held until the end: no temporary file appears or is
                // renamed from here on.
                let registered = temporaries();
                for path in registered.iter() {
                    let _ = std::fs::remove_file(path);
                }
                let _ = signal_hook::low_level::emulate_default_handler(signal);
                std::process::exit(128 + signal);
            }
        })?;
    Ok(())
}

/// Elsewhere: nothing to install.
#[cfg(not(unix))]
pub fn remove_temporaries_on_signals() -> std::io::Result<()> {
    Ok(())
}

/// What a destination name stands for, to tell whether two names are
/// one file.
#[derive(Debug, PartialEq, Eq)]
enum FileIdentity {
    /// An existing file, by device and inode (a symbolic or hard link to
    /// it is the same file).
    #[cfg(unix)]
    Existing { device: u64, inode: u64 },
    /// An existing file elsewhere: its canonical path.
    #[cfg(not(unix))]
    Existing(PathBuf),
    /// A file still to be made: its directory's canonical path and its name
    /// (a dangling link stands for the file it points to).
    New(PathBuf),
}

/// `None` for a name that can take any number of outputs (a character
/// device such as `/dev/null`) or that cannot be written anyway (its
/// directory is missing: opening it reports that).
fn identity(destination: &Path) -> Option<FileIdentity> {
    if let Ok(meta) = std::fs::metadata(destination) {
        #[cfg(unix)]
        {
            use std::os::unix::fs::{FileTypeExt, MetadataExt};
            if meta.file_type().is_char_device() {
                return None;
            }
            return Some(FileIdentity::Existing {
                device: meta.dev(),
                inode: meta.ino(),
            });
        }
        #[cfg(not(unix))]
        {
            let _ = meta;
            return std::fs::canonicalize(destination)
                .ok()
                .map(FileIdentity::Existing);
        }
    }
    let mut path = destination.to_path_buf();
    // As the kernel does: a bounded number of links.
    for _ in 0..40 {
        let Ok(target) = std::fs::read_link(&path) else {
            break;
        };
        path = match path.parent() {
            Some(parent) => parent.join(target),
            None => target,
        };
    }
    let name = path.file_name()?.to_owned();
    let directory = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    let directory = std::fs::canonicalize(directory).ok()?;
    Some(FileIdentity::New(directory.join(name)))
}

/// Refuses two outputs that name the same file (through `..`, a symbolic
/// link or a hard link): one would overwrite the other. Each entry is the
/// flag and its path; checked before anything is written.
pub fn check_distinct(outputs: &[(&'static str, &Path)]) -> Result<(), ExportError> {
    let identities: Vec<_> = outputs
        .iter()
        .map(|(flag, path)| (*flag, *path, identity(path)))
        .collect();
    for (i, (first, _, first_identity)) in identities.iter().enumerate() {
        for (second, path, second_identity) in &identities[i + 1..] {
            if first_identity.is_some() && first_identity == second_identity {
                return Err(ExportError::OutputClash {
                    first,
                    second,
                    path: path.to_path_buf(),
                });
            }
        }
    }
    Ok(())
}

/// tempfile appends " at path <temporary name>" to its errors; the user
/// named the destination, so keep only the cause.
fn without_temp_path(error: std::io::Error) -> std::io::Error {
    let message = error.to_string();
    match message.split_once(" at path ") {
        Some((cause, _)) => std::io::Error::new(error.kind(), cause.to_string()),
        None => error,
    }
}

#[cfg(test)]
mod tests {
    use std::io::Write;

    use super::*;

    #[test]
    fn appears_only_on_commit() {
        let directory = tempfile::tempdir().unwrap();
        let destination = directory.path().join("out.csv");
        let mut pending = PendingFile::create(&destination).unwrap();
        assert!(pending.temp_path().to_string_lossy().ends_with(".csv"));
        assert!(temporaries().contains(&pending.temp_path().to_path_buf()));
        pending.file().write_all(b"a,b\n").unwrap();
        assert!(!destination.exists());
        let temp = pending.temp_path().to_path_buf();
        pending.commit().unwrap();
        assert!(!temporaries().contains(&temp), "unregistered");
        assert_eq!(std::fs::read_to_string(&destination).unwrap(), "a,b\n");
        assert_eq!(std::fs::read_dir(directory.path()).unwrap().count(), 1);
    }

    #[test]
    fn dropped_leaves_nothing() {
        let directory = tempfile::tempdir().unwrap();
        let destination = directory.path().join("out.xlsx");
        let pending = PendingFile::create(&destination).unwrap();
        let temp = pending.temp_path().to_path_buf();
        drop(pending);
        assert!(!temporaries().contains(&temp), "unregistered");
        assert_eq!(std::fs::read_dir(directory.path()).unwrap().count(), 0);
    }

    #[test]
    fn missing_directory_is_an_error() {
        let directory = tempfile::tempdir().unwrap();
        let destination = directory.path().join("no/such/dir/out.csv");
        let error = PendingFile::create(&destination).unwrap_err();
        assert!(matches!(error, ExportError::Write { .. }));
        let message = error.to_string();
        assert!(message.contains("out.csv"), "{message}");
        assert!(!message.contains(".spreadsheet-export-"), "{message}");
    }

    #[cfg(unix)]
    #[test]
    fn a_link_to_a_file_keeps_the_link_and_replaces_the_file() {
        let directory = tempfile::tempdir().unwrap();
        let real = directory.path().join("real.csv");
        std::fs::write(&real, "old\n").unwrap();
        let link = directory.path().join("link.csv");
        std::os::unix::fs::symlink(&real, &link).unwrap();
        let mut pending = PendingFile::create(&link).unwrap();
        assert!(!pending.in_place());
        pending.file().write_all(b"new\n").unwrap();
        pending.commit().unwrap();
        assert!(std::fs::symlink_metadata(&link).unwrap().is_symlink());
        assert_eq!(std::fs::read_to_string(&real).unwrap(), "new\n");
    }

    #[test]
    fn which_names_are_written_in_place() {
        let directory = tempfile::tempdir().unwrap();
        assert_eq!(writes_in_place(&directory.path().join("new.csv")), None);
        let file = directory.path().join("file.csv");
        std::fs::write(&file, "x").unwrap();
        assert_eq!(writes_in_place(&file), None);
        assert_eq!(
            writes_in_place(directory.path()),
            Some(InPlace::Stream),
            "a directory is not replaced (opening it fails)"
        );
        if cfg!(unix) {
            assert_eq!(
                writes_in_place(Path::new("/dev/null")),
                Some(InPlace::Stream)
            );
            for name in ["/dev/stdout", "/proc/self/fd/1"] {
                assert!(writes_in_place(Path::new(name)).is_some(), "{name}");
            }
        }
    }
}

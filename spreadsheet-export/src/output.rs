//! Output files appear whole or not at all: each is written to a temporary
//! file in the destination's directory and renamed over the destination
//! only when complete. A failed run drops the temporary file.

use std::fs::File;
use std::path::{Path, PathBuf};

use tempfile::{Builder, NamedTempFile};

use crate::error::ExportError;

/// A file being written; [`PendingFile::commit`] makes it appear.
#[derive(Debug)]
pub struct PendingFile {
    destination: PathBuf,
    temp: NamedTempFile,
}

impl PendingFile {
    /// Starts a file that will become `destination`. The temporary file has
    /// the same extension (some writers pick their format from it).
    pub fn create(destination: &Path) -> Result<Self, ExportError> {
        let directory = match destination.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent,
            _ => Path::new("."),
        };
        let suffix = destination
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
        let temp = builder
            .tempfile_in(directory)
            .map_err(|source| ExportError::Write {
                path: destination.to_path_buf(),
                source: without_temp_path(source),
            })?;
        Ok(Self {
            destination: destination.to_path_buf(),
            temp,
        })
    }

    /// The final path.
    pub fn destination(&self) -> &Path {
        &self.destination
    }

    /// Where the content is being written now.
    pub fn temp_path(&self) -> &Path {
        self.temp.path()
    }

    /// The open temporary file.
    pub fn file(&mut self) -> &mut File {
        self.temp.as_file_mut()
    }

    /// Flushes to disk and renames over the destination.
    pub fn commit(self) -> Result<(), ExportError> {
        let destination = self.destination;
        self.temp
            .as_file()
            .sync_all()
            .map_err(|source| ExportError::Write {
                path: destination.clone(),
                source,
            })?;
        self.temp
            .persist(&destination)
            .map_err(|error| ExportError::Write {
                path: destination.clone(),
                source: error.error,
            })?;
        Ok(())
    }
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
        pending.file().write_all(b"a,b\n").unwrap();
        assert!(!destination.exists());
        pending.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&destination).unwrap(), "a,b\n");
        assert_eq!(std::fs::read_dir(directory.path()).unwrap().count(), 1);
    }

    #[test]
    fn dropped_leaves_nothing() {
        let directory = tempfile::tempdir().unwrap();
        let destination = directory.path().join("out.xlsx");
        let pending = PendingFile::create(&destination).unwrap();
        drop(pending);
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
}

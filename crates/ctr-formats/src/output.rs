//! Atomic output files: written to a temporary file beside the target and renamed over
//! it only when everything succeeded, so a failed run never leaves a half-written file
//! and never replaces an existing one.

use crate::error::{Error, ErrorKind, Location};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use tempfile::NamedTempFile;

/// A file being written; it appears at its path only on [`commit`](Self::commit).
/// Dropping it without committing deletes the temporary file.
pub struct AtomicFile {
    path: PathBuf,
    file: String,
    tmp: BufWriter<NamedTempFile>,
}

/// The directory an output file at `path` goes into, after checking that it exists and
/// that `path` is not a directory itself.
pub(crate) fn output_dir(path: &Path) -> Result<PathBuf, Error> {
    let fail = |kind| Error::new(Location::file(path.display().to_string()), kind);
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(fail(ErrorKind::OutputDirectory {
            dir: dir.display().to_string(),
        }));
    }
    if path.is_dir() {
        return Err(fail(ErrorKind::Io {
            action: "write",
            source: io::Error::other("it is a directory"),
        }));
    }
    Ok(dir)
}

impl AtomicFile {
    /// Checks, before any work, that an output can be created at `path` (its directory
    /// exists and it is not a directory).
    ///
    /// ```
    /// use ctr_formats::AtomicFile;
    /// let err = AtomicFile::check_path("/nonexistent/out.json".as_ref()).unwrap_err();
    /// assert_eq!(err.to_string(), "/nonexistent/out.json: directory /nonexistent does not exist");
    /// ```
    pub fn check_path(path: &Path) -> Result<(), Error> {
        output_dir(path).map(|_| ())
    }

    /// Creates the temporary file in `path`'s directory (which must exist).
    pub fn create(path: &Path) -> Result<AtomicFile, Error> {
        let file = path.display().to_string();
        let fail = |kind| Error::new(Location::file(&file), kind);
        let dir = output_dir(path)?;
        let name = path
            .file_name()
            .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
        let prefix = format!(".{name}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            // like a plain create: 0666 less the umask
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let tmp = builder.tempfile_in(&dir).map_err(|source| {
            fail(ErrorKind::Io {
                action: "create a temporary file in its directory",
                source,
            })
        })?;
        Ok(AtomicFile {
            path: path.to_path_buf(),
            file,
            tmp: BufWriter::with_capacity(1 << 20, tmp),
        })
    }

    /// Flushes, syncs and renames the temporary file over the target.
    pub fn commit(self) -> Result<(), Error> {
        let file = self.file;
        let fail =
            |action, source| Error::new(Location::file(&file), ErrorKind::Io { action, source });
        let tmp = self
            .tmp
            .into_inner()
            .map_err(|e| fail("write", e.into_error()))?;
        tmp.as_file().sync_all().map_err(|e| fail("write", e))?;
        tmp.persist(&self.path)
            .map_err(|e| fail("rename the temporary file to", e.error))?;
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.tmp.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.tmp.flush()
    }
}

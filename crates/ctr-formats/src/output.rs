//! Atomic output files, the one way every output file of the project is written: to a
//! temporary file beside the target (same directory, so same file system), flushed,
//! `fsync`ed, and renamed over the target only when everything succeeded; then the
//! directory is synced so that the rename itself survives a power cut.
//!
//! What that guarantees, also against `SIGKILL` at any moment: the target is either
//! the previous file (or absent) or the complete new one, never a part. Every writer
//! has its own randomly named temporary file, so two runs writing the same path at once
//! leave one complete file (the last rename wins), never an interleaving. A run that
//! fails deletes its temporary file; a killed one leaves it behind (a hidden
//! `.NAME.XXXXXX.tmp`, never read by anything). A target that exists and is not a
//! regular file (`/dev/null`, a named pipe) is written into, not replaced.
//!
//! A [`journal`](AtomicFile::journal) is the same with a visible temporary file
//! (`NAME.XXXXXX.partial`) for outputs whose rows are evidence (the rig's recordings):
//! each flushed row is in it at once, a kill leaves it as a valid file of the rows
//! written, and it is kept whenever it cannot be renamed into place.

use crate::error::{Error, ErrorKind, Location};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use tempfile::NamedTempFile;

/// Bytes gathered before a write to the temporary file (flush writes sooner).
const BUFFER_BYTES: usize = 1 << 20;

/// Bytes written straight through ([`AtomicFile::write_through`]) after which the data
/// so far is synced to the disk behind the writer, on a thread of its own: the sync
/// of the commit then finds only the last of a large output left to write.
const SYNC_BEHIND_BYTES: u64 = 32 << 20;

/// A file being written; it appears at its path only on [`commit`](Self::commit).
/// Dropping it without committing deletes the temporary file (but a journal's).
pub struct AtomicFile {
    path: PathBuf,
    file: String,
    tmp: BufWriter<NamedTempFile>,
    journal: bool,
    /// bytes written through, and where the last sync behind started
    through: u64,
    synced: u64,
    /// the sync behind the writer in flight
    syncing: Option<std::thread::JoinHandle<io::Result<()>>>,
    /// bytes written (buffered or through), and the length reserved ahead of them
    written: u64,
    reserved: u64,
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

    /// Creates the hidden temporary file `.NAME.XXXXXX.tmp` in `path`'s directory
    /// (which must exist).
    ///
    /// ```
    /// use std::io::Write;
    /// let dir = tempfile::tempdir()?;
    /// let path = dir.path().join("tips.csv");
    /// let mut out = ctr_formats::AtomicFile::create(&path)?;
    /// out.write_all(b"x_mm\n1\n")?;
    /// assert!(!path.exists()); // not before the commit
    /// out.commit()?;
    /// assert_eq!(std::fs::read_to_string(&path)?, "x_mm\n1\n");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn create(path: &Path) -> Result<AtomicFile, Error> {
        Self::with_temp(path, false)
    }

    /// Creates the visible temporary file `NAME.XXXXXX.partial` in `path`'s directory,
    /// for an output written row by row whose rows must survive a kill: each
    /// [`flush`](Write::flush) puts what was written into it, and it is kept (never
    /// deleted) when the output is not committed or the commit fails.
    ///
    /// ```
    /// use std::io::Write;
    /// let dir = tempfile::tempdir()?;
    /// let mut rec = ctr_formats::AtomicFile::journal(&dir.path().join("rec.csv"))?;
    /// rec.write_all(b"t_s\n0.5\n")?;
    /// rec.flush()?;
    /// let journal = rec.temp_path().to_owned();
    /// assert!(journal.file_name().unwrap().to_str().unwrap().starts_with("rec.csv."));
    /// assert_eq!(std::fs::read_to_string(&journal)?, "t_s\n0.5\n");
    /// drop(rec); // as if killed: the rows stay
    /// assert!(journal.exists());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn journal(path: &Path) -> Result<AtomicFile, Error> {
        Self::with_temp(path, true)
    }

    /// Writes `contents` to `path` atomically (create, write, commit).
    ///
    /// ```
    /// let dir = tempfile::tempdir()?;
    /// let path = dir.path().join("report.json");
    /// ctr_formats::AtomicFile::write_file(&path, b"{}\n")?;
    /// assert_eq!(std::fs::read_to_string(&path)?, "{}\n");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn write_file(path: &Path, contents: &[u8]) -> Result<(), Error> {
        let mut f = Self::create(path)?;
        f.write_all(contents).map_err(|source| {
            Error::new(
                Location::file(path.display().to_string()),
                ErrorKind::Io {
                    action: "write",
                    source,
                },
            )
        })?;
        f.commit()
    }

    fn with_temp(path: &Path, journal: bool) -> Result<AtomicFile, Error> {
        let file = path.display().to_string();
        let fail = |kind| Error::new(Location::file(&file), kind);
        // a device or a pipe is written into on commit, never renamed over: its
        // temporary file goes where temporary files go (`/dev` is not writable)
        let dir = if !journal && is_special(path) {
            std::env::temp_dir()
        } else {
            output_dir(path)?
        };
        let name = path
            .file_name()
            .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
        let (prefix, suffix) = if journal {
            // a Parquet output's journal holds CSV rows: named so
            let partial = if crate::columnar::is_parquet(path) {
                ".partial.csv"
            } else {
                ".partial"
            };
            (format!("{name}."), partial)
        } else {
            (format!(".{name}."), ".tmp")
        };
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(suffix);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            // like a plain create: 0666 less the umask
            builder.permissions(std::fs::Permissions::from_mode(0o666));
        }
        let mut tmp = builder.tempfile_in(&dir).map_err(|source| {
            fail(ErrorKind::Io {
                action: "create a temporary file in its directory",
                source,
            })
        })?;
        if journal {
            // never deleted on drop: dropping a kept file only closes it
            tmp.disable_cleanup(true);
        }
        Ok(AtomicFile {
            path: path.to_path_buf(),
            file,
            tmp: BufWriter::with_capacity(BUFFER_BYTES, tmp),
            journal,
            through: 0,
            synced: 0,
            syncing: None,
            written: 0,
            reserved: 0,
        })
    }

    /// Writes `bytes` past the buffer, straight to the temporary file (after what is
    /// buffered): for large pieces written whole, which the buffer would only copy.
    ///
    /// ```
    /// use std::io::Write;
    /// let dir = tempfile::tempdir()?;
    /// let path = dir.path().join("tips.csv");
    /// let mut out = ctr_formats::AtomicFile::create(&path)?;
    /// out.write_all(b"x_mm\n")?;
    /// out.write_through(b"1\n2\n")?;
    /// out.commit()?;
    /// assert_eq!(std::fs::read_to_string(&path)?, "x_mm\n1\n2\n");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// Every `SYNC_BEHIND_BYTES` written this way, the data so far starts being synced
    /// to the disk on a thread of its own (one at a time), so that the sync of
    /// [`commit`](Self::commit) has only the rest left to wait for.
    pub fn write_through(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.tmp.flush()?;
        self.tmp.get_mut().write_all(bytes)?;
        self.through += bytes.len() as u64;
        self.written += bytes.len() as u64;
        if self.through - self.synced >= SYNC_BEHIND_BYTES && self.sync_done()? {
            let file = self.tmp.get_ref().as_file().try_clone()?;
            self.synced = self.through;
            self.syncing = Some(std::thread::spawn(move || file.sync_data()));
        }
        Ok(())
    }

    /// Reserves the disk blocks of a file of `bytes` ahead of the writes (Linux:
    /// `fallocate`; best effort, nothing elsewhere): the file system then has no block
    /// to find for each page written. The file is cut back to what was written when
    /// it is committed.
    ///
    /// ```
    /// use std::io::Write;
    /// let dir = tempfile::tempdir()?;
    /// let path = dir.path().join("big.csv");
    /// let mut out = ctr_formats::AtomicFile::create(&path)?;
    /// out.reserve(1 << 20);
    /// out.write_through(b"x_mm\n1\n")?;
    /// out.commit()?;
    /// assert_eq!(std::fs::read(&path)?, b"x_mm\n1\n");
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn reserve(&mut self, bytes: u64) {
        #[cfg(target_os = "linux")]
        {
            use rustix::fs::{fallocate, FallocateFlags};
            let file = self.tmp.get_ref().as_file();
            if bytes > self.reserved && fallocate(file, FallocateFlags::empty(), 0, bytes).is_ok() {
                self.reserved = bytes;
            }
        }
        #[cfg(not(target_os = "linux"))]
        let _ = bytes;
    }

    /// True when no sync behind the writer is in flight (the last one's error, if it
    /// failed).
    fn sync_done(&mut self) -> io::Result<bool> {
        match self.syncing.take() {
            Some(h) if !h.is_finished() => {
                self.syncing = Some(h);
                Ok(false)
            }
            Some(h) => h.join().unwrap_or(Ok(())).map(|()| true),
            None => Ok(true),
        }
    }

    /// Waits for the sync behind the writer in flight, if any.
    fn wait_for_sync(&mut self) -> io::Result<()> {
        match self.syncing.take() {
            Some(h) => h.join().unwrap_or(Ok(())),
            None => Ok(()),
        }
    }

    /// The temporary file being written (renamed to the target on commit).
    pub fn temp_path(&self) -> &Path {
        self.tmp.get_ref().path()
    }

    /// Flushes the temporary file and deletes it (a journal too): for a journal whose
    /// rows have been put in place by other means.
    pub fn discard(mut self) -> Result<(), Error> {
        let flushed = self.tmp.flush();
        let removed = std::fs::remove_file(self.temp_path());
        flushed.and(removed).map_err(|source| {
            Error::new(
                Location::file(&self.file),
                ErrorKind::Io {
                    action: "remove the journal of",
                    source,
                },
            )
        })
    }

    /// Flushes, syncs and renames the temporary file over the target (replacing it).
    pub fn commit(self) -> Result<(), Error> {
        self.place(true)
    }

    /// As [`commit`](Self::commit), but fails (with an `AlreadyExists` I/O error) when
    /// the target exists, instead of replacing it: for outputs that are never
    /// overwritten unless asked (a journal is then kept).
    pub fn commit_new(self) -> Result<(), Error> {
        self.place(false)
    }

    fn place(mut self, replace: bool) -> Result<(), Error> {
        let synced = self.wait_for_sync();
        let file = self.file;
        let written = self.written;
        let cut = |f: &std::fs::File| match self.reserved > written {
            true => f.set_len(written),
            false => Ok(()),
        };
        let fail =
            |action, source| Error::new(Location::file(&file), ErrorKind::Io { action, source });
        let tmp = self
            .tmp
            .into_inner()
            .map_err(|e| fail("write", e.into_error()))?;
        synced
            .and_then(|()| cut(tmp.as_file()))
            .and_then(|()| tmp.as_file().sync_all())
            .map_err(|e| fail("write", e))?;
        if replace && is_special(&self.path) {
            // a device or a pipe (`-o /dev/null`): written into, never replaced by a
            // rename (which would put a regular file where the device was)
            return copy_into(&tmp, &self.path).map_err(|e| fail("write", e));
        }
        let placed = if replace {
            tmp.persist(&self.path)
        } else {
            tmp.persist_noclobber(&self.path)
        };
        placed.map_err(|e| {
            if self.journal {
                // the rows stay where they are
                let _ = e.file.keep();
            }
            let action = if e.error.kind() == io::ErrorKind::AlreadyExists {
                "create: it exists already"
            } else {
                "rename the temporary file to"
            };
            fail(action, e.error)
        })?;
        sync_dir(&self.path);
        Ok(())
    }
}

/// Whether `path` exists and is neither a regular file nor a directory (a device such
/// as `/dev/null`, a named pipe, a socket): an output there is written into it.
fn is_special(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Copies the whole temporary file `tmp` into the existing `path` (opened for
/// writing, not truncated: a device has no length); `tmp` is deleted when dropped.
fn copy_into(tmp: &NamedTempFile, path: &Path) -> io::Result<()> {
    let mut from = tmp.reopen()?;
    let mut to = std::fs::OpenOptions::new().write(true).open(path)?;
    io::copy(&mut from, &mut to)?;
    to.flush()
}

/// Syncs the directory of `path` so that a rename into it is on the disk (Unix; best
/// effort: the rename has happened either way).
fn sync_dir(path: &Path) {
    #[cfg(unix)]
    {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if let Ok(d) = std::fs::File::open(dir) {
            let _ = d.sync_all();
        }
    }
    #[cfg(not(unix))]
    let _ = path;
}

impl std::fmt::Debug for AtomicFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AtomicFile")
            .field("path", &self.path)
            .field("temp_path", &self.temp_path())
            .field("journal", &self.journal)
            .finish()
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.tmp.write(buf)?;
        self.written += n as u64;
        Ok(n)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.tmp.flush()
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// `-o /dev/null`, or a named pipe: the output is written into it, and it stays
    /// what it was (a rename would have put a regular file in its place).
    #[test]
    fn a_pipe_is_written_into_not_replaced() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        rustix::fs::mknodat(
            rustix::fs::CWD,
            &fifo,
            rustix::fs::FileType::Fifo,
            rustix::fs::Mode::from_raw_mode(0o600),
            0,
        )
        .unwrap();
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
        };
        let mut out = AtomicFile::create(&fifo).unwrap();
        assert!(!out.temp_path().starts_with(dir.path()));
        out.write_all(b"x_mm\n1\n").unwrap();
        out.commit().unwrap();
        // (checked before joining: a reader whose pipe was replaced would wait forever)
        assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo());
        assert_eq!(reader.join().unwrap(), "x_mm\n1\n");
        // nothing left beside it
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}

//! The recording CSV written while a rig plays a trajectory (`ctr-cli hw run`): the
//! contract's recording (time, run label, commanded joints, measured tip) plus the
//! joints read back from the motors.
//!
//! A recording is evidence of what the robot did, so every row goes to a file as soon
//! as it is complete (one write of the whole line, then a flush), never a partial row.
//! That file is a journal beside the recording ([`AtomicFile::journal`],
//! `RECORDING.csv.XXXXXX.partial`), renamed to the recording when the run ends, also
//! when it stops on a fault ([`RecordingWriter::finish`]). So:
//!
//! - a run that stops on a fault leaves a valid recording of every row completed before
//!   the fault;
//! - a run killed at any moment (`SIGKILL`, power cut after the flushed rows reached the
//!   disk) leaves every row completed before the kill in its journal, a valid CSV, and
//!   the recording's path as it was (absent, or the previous recording with
//!   `--overwrite`): never a half recording under the name the tracker reads;
//! - two runs recording to one path at once never interleave: each has its own journal;
//!   without `--overwrite` the second to finish finds the first's recording and keeps
//!   its own journal, with `--overwrite` the last to finish wins.

use super::actuation::JointId;
use super::format_float;
use super::output::AtomicFile;
use crate::columnar::{is_parquet, ParquetOutput};
use crate::error::{Error, ErrorKind, Location};
use std::io::{self, Write};
use std::path::Path;

/// The tip columns of a recording, left empty for the tracker to fill.
pub const RECORDING_TIP_COLUMNS: [&str; 3] = ["x_mm", "y_mm", "z_mm"];

/// The recording header for `n_tubes` tubes:
/// `t_s,run,s1_mm,theta1_deg,...,s1_read_mm,theta1_read_deg,...,x_mm,y_mm,z_mm`.
///
/// ```
/// let h = ctr_formats::recording_header(1).join(",");
/// assert_eq!(h, "t_s,run,s1_mm,theta1_deg,s1_read_mm,theta1_read_deg,x_mm,y_mm,z_mm");
/// ```
pub fn recording_header(n_tubes: usize) -> Vec<String> {
    ["t_s".to_owned(), "run".to_owned()]
        .into_iter()
        .chain(JointId::all(n_tubes).map(JointId::column))
        .chain(JointId::all(n_tubes).map(JointId::read_column))
        .chain(RECORDING_TIP_COLUMNS.iter().map(|c| (*c).to_owned()))
        .collect()
}

/// Writes a recording row by row; each row reaches the writer in one `write_all` of the
/// whole line followed by a flush.
///
/// ```
/// use ctr_formats::RecordingWriter;
/// let mut rec = RecordingWriter::new(Vec::new(), "rec.csv", 1)?;
/// rec.write_row(0.5, "sweep, 1", &[10.0, 90.0], &[10.0, 89.912109375])?;
/// assert_eq!(rec.rows(), 1);
/// let text = String::from_utf8(rec.into_inner()).unwrap();
/// assert_eq!(text.lines().nth(1), Some("0.5,\"sweep, 1\",10,90,10,89.912109375,,,"));
/// # Ok::<(), ctr_formats::Error>(())
/// ```
#[derive(Debug)]
pub struct RecordingWriter<W: Write> {
    out: W,
    file: String,
    /// the recording's path, for one written to a file
    path: Option<std::path::PathBuf>,
    n_tubes: usize,
    rows: usize,
    /// [`finish`](RecordingWriter::finish) replaces an existing recording
    replace: bool,
}

impl<W: Write> RecordingWriter<W> {
    /// Writes the header for `n_tubes` tubes to `out` and flushes it; `file` names the
    /// output in errors.
    pub fn new(out: W, file: &str, n_tubes: usize) -> Result<Self, Error> {
        let mut writer = RecordingWriter {
            out,
            file: file.to_owned(),
            path: None,
            n_tubes,
            rows: 0,
            replace: false,
        };
        let header = recording_header(n_tubes);
        writer.write_line(header.iter().map(String::as_str))?;
        Ok(writer)
    }

    /// Appends one row: `t_s` (seconds, written to the microsecond), the run label, the
    /// commanded joints and the joints read back (both in joint-vector order, mm and
    /// degrees), and empty tip cells.
    ///
    /// # Panics
    /// If `commanded` or `read` does not have `2 * n_tubes` values.
    pub fn write_row(
        &mut self,
        t_s: f64,
        run: &str,
        commanded: &[f64],
        read: &[f64],
    ) -> Result<(), Error> {
        assert_eq!(commanded.len(), 2 * self.n_tubes, "commanded joints");
        assert_eq!(read.len(), 2 * self.n_tubes, "read-back joints");
        let t = format_float((t_s * 1e6).round() / 1e6);
        let numbers: Vec<String> = commanded
            .iter()
            .chain(read)
            .map(|&v| format_float(v))
            .collect();
        let fields = [t.as_str(), run]
            .into_iter()
            .chain(numbers.iter().map(String::as_str))
            .chain(RECORDING_TIP_COLUMNS.iter().map(|_| ""));
        self.write_line(fields)?;
        self.rows += 1;
        Ok(())
    }

    /// Rows written so far (the header not counted).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The output's name as used in errors.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The writer (everything written is flushed already).
    pub fn into_inner(self) -> W {
        self.out
    }

    fn write_line<'a>(&mut self, fields: impl Iterator<Item = &'a str>) -> Result<(), Error> {
        let mut csv = csv::Writer::from_writer(Vec::new());
        let line = csv
            .write_record(fields)
            .map_err(io::Error::from)
            .and_then(|()| csv.into_inner().map_err(|e| e.into_error()));
        let result = line.and_then(|line| {
            self.out.write_all(&line)?;
            self.out.flush()
        });
        result.map_err(|source| {
            Error::new(
                Location::file(&self.file),
                ErrorKind::Io {
                    action: "write",
                    source,
                },
            )
        })
    }
}

impl RecordingWriter<AtomicFile> {
    /// Starts a recording at `path` (refusing to replace an existing one unless
    /// `overwrite`): creates its journal beside it and writes the header there.
    ///
    /// ```
    /// use ctr_formats::RecordingWriter;
    /// let dir = tempfile::tempdir()?;
    /// let path = dir.path().join("rec.csv");
    /// let mut rec = RecordingWriter::create(&path, 1, false)?;
    /// rec.write_row(0.5, "r", &[10.0, 90.0], &[10.0, 90.0])?;
    /// // the row is in the journal already; the recording appears on finish
    /// assert_eq!(std::fs::read_to_string(rec.journal_path())?.lines().count(), 2);
    /// assert!(!path.exists());
    /// rec.finish()?;
    /// assert_eq!(std::fs::read_to_string(&path)?.lines().count(), 2);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn create(path: &Path, n_tubes: usize, overwrite: bool) -> Result<Self, Error> {
        Self::check_path(path)?;
        let file = path.display().to_string();
        if !overwrite && path.exists() {
            return Err(Error::new(
                Location::file(&file),
                ErrorKind::Io {
                    action: "create the recording: it exists already",
                    source: io::ErrorKind::AlreadyExists.into(),
                },
            ));
        }
        let mut writer = RecordingWriter::new(AtomicFile::journal(path)?, &file, n_tubes)?;
        writer.replace = overwrite;
        writer.path = Some(path.to_path_buf());
        Ok(writer)
    }

    /// Checks that a recording can be created at `path`: its directory exists and it is
    /// not a directory itself (for checking before a run starts).
    ///
    /// ```
    /// use ctr_formats::RecordingWriter;
    /// let err = RecordingWriter::check_path("/nonexistent/rec.csv".as_ref()).unwrap_err();
    /// assert_eq!(err.to_string(), "/nonexistent/rec.csv: directory /nonexistent does not exist");
    /// ```
    pub fn check_path(path: &Path) -> Result<(), Error> {
        super::output::output_dir(path).map(|_| ())
    }

    /// The journal the rows are written to until [`finish`](Self::finish).
    pub fn journal_path(&self) -> &Path {
        self.out.temp_path()
    }

    /// Syncs the journal and renames it to the recording (replacing an existing one
    /// only if created with `overwrite`). On an error the journal is kept, with every
    /// row written.
    ///
    /// A recording named `*.parquet` is written as Parquet from the journal (which holds
    /// the rows as CSV, `NAME.parquet.XXXXXX.partial.csv`), and the journal is removed
    /// once the Parquet file is in place.
    pub fn finish(mut self) -> Result<(), Error> {
        let parquet = self
            .path
            .as_deref()
            .filter(|p| is_parquet(p))
            .map(Path::to_owned);
        let Some(path) = parquet else {
            return if self.replace {
                self.out.commit()
            } else {
                self.out.commit_new()
            };
        };
        let journal = self.out.temp_path().to_owned();
        let rows = self
            .out
            .flush()
            .and_then(|()| std::fs::read(&journal))
            .map_err(|source| {
                Error::new(
                    Location::file(journal.display().to_string()),
                    ErrorKind::Io {
                        action: "read",
                        source,
                    },
                )
            })?;
        ParquetOutput::from_csv(&rows, &journal.display().to_string(), &path, self.replace)?;
        self.out.discard()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A writer that fails after `budget` bytes.
    struct Failing {
        written: Vec<u8>,
        budget: usize,
    }

    impl Write for Failing {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.written.len() + buf.len() > self.budget {
                return Err(io::Error::other("disk full"));
            }
            self.written.extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn rows_are_whole_lines_or_nothing() {
        let header_len = recording_header(2).join(",").len() + 1;
        let out = Failing {
            written: Vec::new(),
            budget: header_len + 40,
        };
        let mut rec = RecordingWriter::new(out, "r.csv", 2).unwrap();
        rec.write_row(0.0, "a", &[1.0, 2.0, 3.0, 4.0], &[1.0, 2.0, 3.0, 4.0])
            .unwrap();
        let err = rec
            .write_row(1.0, "a", &[10.0, 20.0, 30.0, 40.0], &[10.0; 4])
            .unwrap_err();
        assert_eq!(err.to_string(), "r.csv: cannot write: disk full");
        assert_eq!(rec.rows(), 1);
        let text = String::from_utf8(rec.into_inner().written).unwrap();
        assert_eq!(
            text,
            "t_s,run,s1_mm,theta1_deg,s2_mm,theta2_deg,s1_read_mm,theta1_read_deg,s2_read_mm,theta2_read_deg,x_mm,y_mm,z_mm\n\
             0,a,1,2,3,4,1,2,3,4,,,\n"
        );
    }

    #[test]
    fn times_are_written_to_the_microsecond() {
        let mut rec = RecordingWriter::new(Vec::new(), "r.csv", 1).unwrap();
        rec.write_row(1.234_567_891, "r", &[0.0, -0.0], &[0.1 + 0.2, 1e-9])
            .unwrap();
        let text = String::from_utf8(rec.into_inner()).unwrap();
        assert_eq!(
            text.lines().nth(1).unwrap(),
            "1.234568,r,0,-0,0.30000000000000004,0.000000001,,,"
        );
    }

    #[test]
    fn existing_files_are_kept_unless_overwriting() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rec.csv");
        std::fs::write(&path, "precious\n").unwrap();
        let err = RecordingWriter::create(&path, 1, false).unwrap_err();
        assert!(err.to_string().contains("exists already"), "{err}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "precious\n");
        let mut rec = RecordingWriter::create(&path, 1, true).unwrap();
        rec.write_row(0.0, "r", &[1.0, 2.0], &[1.0, 2.0]).unwrap();
        // the previous recording stays until the run ends
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "precious\n");
        rec.finish().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("t_s,run,"), "{text}");
        assert_eq!(text.lines().count(), 2);
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "no journal left"
        );
        let err = RecordingWriter::create(&dir.path().join("no/rec.csv"), 1, false).unwrap_err();
        assert!(err.to_string().contains("does not exist"), "{err}");
    }

    #[test]
    fn a_recording_made_meanwhile_is_not_replaced_and_the_journal_is_kept() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rec.csv");
        let mut rec = RecordingWriter::create(&path, 1, false).unwrap();
        rec.write_row(0.0, "mine", &[1.0, 2.0], &[1.0, 2.0])
            .unwrap();
        let journal = rec.journal_path().to_owned();
        std::fs::write(&path, "another run's\n").unwrap();
        let err = rec.finish().unwrap_err();
        assert!(err.to_string().contains("exists already"), "{err}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "another run's\n");
        let kept = std::fs::read_to_string(&journal).unwrap();
        assert!(kept.ends_with("0,mine,1,2,1,2,,,\n"), "{kept}");
    }

    #[test]
    fn a_parquet_recording_is_written_from_its_journal() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rec.parquet");
        let mut rec = RecordingWriter::create(&path, 1, false).unwrap();
        rec.write_row(0.25, "a, b", &[10.0, 90.0], &[10.0, 89.5])
            .unwrap();
        rec.write_row(0.5, "a, b", &[11.0, 91.0], &[11.0, 90.5])
            .unwrap();
        let journal = rec.journal_path().to_owned();
        let name = journal.file_name().unwrap().to_str().unwrap().to_owned();
        assert!(
            name.starts_with("rec.parquet.") && name.ends_with(".partial.csv"),
            "{name}"
        );
        rec.finish().unwrap();
        assert!(!journal.exists(), "the journal is removed");
        let mut read = crate::columnar::read::ParquetReader::open(&path).unwrap();
        assert_eq!(read.names(), recording_header(1));
        let columns = read.next_rows(10).unwrap();
        assert_eq!(
            (columns[0].number(1), columns[1].text(0)),
            (Some(0.5), "a, b".into())
        );
        assert_eq!(columns[5].number(1), Some(90.5));
        // the tip, for the tracker, is null
        assert_eq!(columns[6].number(0), None);
        // a second run does not replace it without --overwrite; its journal stays
        let mut again = RecordingWriter::create(&dir.path().join("x.parquet"), 1, false).unwrap();
        std::fs::copy(&path, dir.path().join("x.parquet")).unwrap();
        again.write_row(0.0, "r", &[1.0, 2.0], &[1.0, 2.0]).unwrap();
        let kept = again.journal_path().to_owned();
        assert!(again.finish().is_err());
        assert!(kept.exists());
    }

    #[test]
    fn an_unfinished_recording_leaves_its_rows_in_the_journal() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rec.csv");
        let mut rec = RecordingWriter::create(&path, 1, false).unwrap();
        rec.write_row(0.0, "r", &[1.0, 2.0], &[1.0, 2.0]).unwrap();
        let journal = rec.journal_path().to_owned();
        drop(rec);
        assert!(!path.exists());
        let name = journal.file_name().unwrap().to_str().unwrap();
        assert!(
            name.starts_with("rec.csv.") && name.ends_with(".partial"),
            "{name}"
        );
        assert_eq!(
            std::fs::read_to_string(&journal).unwrap().lines().count(),
            2
        );
    }
}

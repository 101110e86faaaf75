//! The recording CSV written while a rig plays a trajectory (`ctr-cli hw run`): the
//! contract's recording (time, run label, commanded joints, measured tip) plus the
//! joints read back from the motors.
//!
//! Unlike the tip file it is not written atomically: a recording is evidence of what the
//! robot did, so every row goes to the file as soon as it is complete (one write of the
//! whole line, then a flush), and a run that stops on a fault leaves a valid CSV of every
//! row completed before it, never a partial row.

use super::actuation::JointId;
use super::format_float;
use crate::error::{Error, ErrorKind, Location};
use std::fs::File;
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
    n_tubes: usize,
    rows: usize,
}

impl<W: Write> RecordingWriter<W> {
    /// Writes the header for `n_tubes` tubes to `out` and flushes it; `file` names the
    /// output in errors.
    pub fn new(out: W, file: &str, n_tubes: usize) -> Result<Self, Error> {
        let mut writer = RecordingWriter {
            out,
            file: file.to_owned(),
            n_tubes,
            rows: 0,
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

impl RecordingWriter<File> {
    /// Creates a new recording file (refusing to replace an existing one unless
    /// `overwrite`) and writes its header.
    pub fn create(path: &Path, n_tubes: usize, overwrite: bool) -> Result<Self, Error> {
        Self::check_path(path)?;
        let file = path.display().to_string();
        let fail = |kind| Error::new(Location::file(&file), kind);
        let mut options = File::options();
        options.write(true);
        if overwrite {
            options.create(true).truncate(true);
        } else {
            options.create_new(true);
        }
        let out = options.open(path).map_err(|source| {
            fail(ErrorKind::Io {
                action: if source.kind() == io::ErrorKind::AlreadyExists {
                    "create the recording: it exists already"
                } else {
                    "create"
                },
                source,
            })
        })?;
        RecordingWriter::new(out, &file, n_tubes)
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

    /// Asks the operating system to put everything written on the disk.
    pub fn sync(&mut self) -> Result<(), Error> {
        self.out.sync_all().map_err(|source| {
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
        rec.sync().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("t_s,run,"), "{text}");
        assert_eq!(text.lines().count(), 2);
        let err = RecordingWriter::create(&dir.path().join("no/rec.csv"), 1, false).unwrap_err();
        assert!(err.to_string().contains("does not exist"), "{err}");
    }
}

//! Reading a recording (`docs/formats.md`): what a robot was commanded and where
//! its tip was measured.
//!
//! Required: the joint columns of the robot and `x_mm,y_mm,z_mm`. Optional: `t_s`
//! (time, s; without it the row index stands for time), `run` (a label; rows with the
//! same label in one contiguous block form a run; without it the whole file is one
//! run), `qw,qx,qy,qz` (measured orientation of the tip frame, a unit quaternion),
//! `tx,ty,tz` (measured unit tangent of the tip: a 5-DOF sensor, no roll),
//! `fx_n,fy_n,fz_n` (a known tip force in W, N; absent means none). Each optional set
//! comes whole or not at all; an orientation or a tangent whose norm is more than
//! [`UNIT_TOLERANCE`] from 1 is refused with its line (the others are kept as read;
//! whoever uses them normalises).
//! `pose` and `n_frames,spread_mm` make the file a static configuration set
//! ([`crate::poses`]).
//! Other columns are ignored. Within a run time must not decrease: friction and latency
//! depend on the order of the rows.

use super::table::closest;
use crate::columnar::read::ParquetReader;
use crate::columnar::{describe, holds_numbers, is_parquet, Column, MAGIC};
use crate::error::{Error, ErrorKind, Location};
use crate::poses::{Frames, Pose, PosesSoFar};
use crate::records::not_text_error;
use crate::robot::joint_columns;
use std::borrow::Cow;
use std::collections::HashMap;
use std::ops::Range;
use std::path::Path;

/// One row of a recording.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordedRow {
    /// 1-based line in the file (the header is line 1).
    pub line: usize,
    /// Time, s (the row's index within the file when the file has no `t_s`).
    pub t_s: f64,
    /// Index of the run this row belongs to, into [`Recording::runs`].
    pub run: usize,
    /// Commanded joints, file order and units (`s1_mm, theta1_deg, ...`).
    pub q: Vec<f64>,
    /// Measured tip, mm, in the tracker's frame.
    pub p: [f64; 3],
    /// Measured orientation `w, x, y, z` (a unit quaternion within [`UNIT_TOLERANCE`]),
    /// if recorded.
    pub quaternion: Option<[f64; 4]>,
    /// Measured tangent of the tip `x, y, z` (a unit vector within
    /// [`UNIT_TOLERANCE`]), if recorded.
    pub tangent: Option<[f64; 3]>,
    /// Known tip force in W, N (zero when not recorded).
    pub force_n: [f64; 3],
    /// The tracker frames the row averages (`n_frames,spread_mm`), if recorded.
    pub frames: Option<Frames>,
}

/// A run: a label and its contiguous rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// The label (`"all"` when the file has no `run` column).
    pub label: String,
    /// Its rows, as indices into [`Recording::rows`].
    pub rows: Range<usize>,
}

/// A whole recording.
///
/// ```
/// use ctr_formats::Recording;
/// let csv = "t_s,run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\n0,a,10,0,0,0,10\n1,a,11,0,0,0,11\n0,b,12,0,0,0,12\n";
/// let rec = Recording::read(csv.as_bytes(), "rec.csv", 1)?;
/// assert_eq!(rec.runs.len(), 2);
/// assert_eq!(rec.rows[2].q, [12.0, 0.0]);
/// let bad = "t_s,run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\n1,a,10,0,0,0,10\n0,a,11,0,0,0,11\n";
/// let e = Recording::read(bad.as_bytes(), "rec.csv", 1).unwrap_err();
/// assert_eq!(e.to_string(), "rec.csv:3: column t_s: 0 is earlier than the previous row's 1 in run a; rows of a run must be in time order");
/// let split = "t_s,run,s1_mm,theta1_deg,x_mm,y_mm,z_mm\n0,a,10,0,0,0,10\n0,b,11,0,0,0,11\n1,a,12,0,0,0,12\n";
/// let e = Recording::read(split.as_bytes(), "rec.csv", 1).unwrap_err();
/// assert!(e.to_string().starts_with("rec.csv:4: column run: run a starts again here"), "{e}");
/// # Ok::<(), ctr_formats::Error>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    /// The file as named by the caller.
    pub file: String,
    /// Number of tubes of the joint columns.
    pub n_tubes: usize,
    /// The rows in file order.
    pub rows: Vec<RecordedRow>,
    /// The runs in file order.
    pub runs: Vec<Run>,
    /// Whether the file has a `t_s` column.
    pub has_time: bool,
    /// Whether the file has tip force columns.
    pub has_force: bool,
    /// The held poses, in file order, when the file is a static configuration set (a
    /// `pose` column or `n_frames,spread_mm`: [`crate::poses`]); `None` for a time
    /// series.
    pub poses: Option<Vec<Pose>>,
    /// How the angular columns count against the positions in a residual, when they
    /// do: never read from the file, set by whoever estimated their noise (the
    /// diagnosis, from the data). `None`: only the positions count.
    pub angular: Option<AngularWeight>,
}

/// The angular columns of a recording that enter a residual, and their weight.
///
/// A row's angular error (a small rotation, rad, [`AngularColumns`] says of what)
/// counts as `mm_per_rad` times itself in mm of tip error: the position noise over
/// the angular noise, so that both enter whitened by their own noise, `e / sigma`,
/// and the positions keep their weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AngularWeight {
    /// Which column set.
    pub columns: AngularColumns,
    /// Noise of one angular component, rad.
    pub sigma_rad: f64,
    /// Noise of one position axis, mm, it is weighed against.
    pub sigma_mm: f64,
}

impl AngularWeight {
    /// mm of tip error one radian of angular error counts as.
    pub fn mm_per_rad(&self) -> f64 {
        self.sigma_mm / self.sigma_rad
    }
}

/// The angular column sets of a recording.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AngularColumns {
    /// `qw,qx,qy,qz`: the whole tip frame (3 angular components).
    Orientation,
    /// `tx,ty,tz`: the tip's tangent (2 angular components: no roll).
    Tangent,
}

impl AngularColumns {
    /// The columns, as the header names them.
    pub fn names(self) -> &'static str {
        match self {
            AngularColumns::Orientation => "qw,qx,qy,qz",
            AngularColumns::Tangent => "tx,ty,tz",
        }
    }

    /// Independent angular components a row of the set measures.
    pub fn components(self) -> usize {
        match self {
            AngularColumns::Orientation => 3,
            AngularColumns::Tangent => 2,
        }
    }
}

/// How far from 1 the norm of a measured orientation quaternion or tangent may be.
pub const UNIT_TOLERANCE: f64 = 1e-3;

const TIP: [&str; 3] = ["x_mm", "y_mm", "z_mm"];
const QUAT: [&str; 4] = ["qw", "qx", "qy", "qz"];
const TANGENT: [&str; 3] = ["tx", "ty", "tz"];
const FORCE: [&str; 3] = ["fx_n", "fy_n", "fz_n"];
const FRAMES: [&str; 2] = ["n_frames", "spread_mm"];

impl Recording {
    /// Reads a recording of an `n_tubes`-tube robot (CSV, or Parquet when the bytes are
    /// a Parquet file's); `file` names it in errors.
    pub fn read(reader: impl std::io::Read, file: &str, n_tubes: usize) -> Result<Self, Error> {
        let data = super::table::read_all(reader, file)?;
        Self::from_bytes(data, file, n_tubes)
    }

    /// Reads a recording file; errors name the path as given. Parquet when its name
    /// ends in `.parquet` or its bytes start as a Parquet file's; else CSV.
    pub fn from_path(path: &Path, n_tubes: usize) -> Result<Self, Error> {
        if is_parquet(path) {
            return Self::parquet(ParquetReader::open(path)?, n_tubes);
        }
        let (file, data) = super::table::read_path(path)?;
        Self::from_bytes(data, &file, n_tubes)
    }

    fn from_bytes(data: Vec<u8>, file: &str, n_tubes: usize) -> Result<Self, Error> {
        if data.starts_with(MAGIC) {
            return Self::parquet(ParquetReader::from_bytes(data, file)?, n_tubes);
        }
        Self::parse(&data, file, n_tubes)
    }

    /// Reads CSV: the header, then every record as a row.
    fn parse(data: &[u8], file: &str, n_tubes: usize) -> Result<Self, Error> {
        if let Some(e) = not_text_error(file, &data[crate::records::bom_len(data)..]) {
            return Err(e);
        }
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .from_reader(data);
        let mut records = reader.records();
        let header = match records.next() {
            None => {
                return Err(Error::new(
                    Location::file(file),
                    ErrorKind::EmptyFile {
                        expected: required(n_tubes).join(","),
                    },
                ))
            }
            Some(r) => r.map_err(|e| csv_error(e, file, data, &mut LineCounter::default()))?,
        };
        let names: Vec<&str> = header.iter().map(str::trim).collect();
        let cols = RecordingColumns::find(&names, n_tubes, Location::line(file, 1))?;
        let mut rows = RowsSoFar::default();
        let mut lines = LineCounter::default();
        for record in records {
            let record = record.map_err(|e| csv_error(e, file, data, &mut lines))?;
            let line = lines.line_at(data, record_start(data, record.position()));
            let at = |kind| Error::new(Location::line(file, line), kind);
            if record.len() != names.len() {
                return Err(at(ErrorKind::RaggedRow {
                    found: record.len(),
                    expected: names.len(),
                }));
            }
            let cells = CsvCells {
                record: &record,
                names: &names,
            };
            rows.push(&cols, &cells, line, at)?;
        }
        rows.finish(file, n_tubes, &cols)
    }

    /// Reads Parquet: every row, the columns of numbers checked to hold numbers.
    fn parquet(mut reader: ParquetReader, n_tubes: usize) -> Result<Self, Error> {
        let file = reader.file().to_owned();
        let names = reader.names();
        let names: Vec<&str> = names.iter().map(|n| n.trim()).collect();
        let cols = RecordingColumns::find(&names, n_tubes, Location::file(&file))?;
        for i in cols.numbers() {
            let column = &reader.columns[i];
            if !holds_numbers(&column.ty) {
                return Err(Error::new(
                    Location::file(&file),
                    ErrorKind::ColumnType {
                        column: column.name.clone(),
                        found: describe(&column.ty),
                        wanted: "numbers (DOUBLE, FLOAT, INT32 or INT64)",
                    },
                ));
            }
        }
        let columns = reader.next_rows(usize::MAX)?;
        let mut rows = RowsSoFar::default();
        for r in 0..columns.first().map_or(0, Column::len) {
            let at = |kind| Error::new(Location::row(&file, r + 1), kind);
            let cells = ParquetCells {
                columns: &columns,
                names: &names,
                row: r,
            };
            rows.push(&cols, &cells, r + 1, at)?;
        }
        rows.finish(&file, n_tubes, &cols)
    }

    /// Whether the rows are held poses (a static configuration set: [`crate::poses`]),
    /// not a time series.
    pub fn is_static(&self) -> bool {
        self.poses.is_some()
    }

    /// The angular column set a residual can use: the orientation when recorded (it
    /// holds the tangent, its z axis), else the tangent; `None` without either.
    pub fn angular_columns(&self) -> Option<AngularColumns> {
        let first = self.rows.first()?;
        if first.quaternion.is_some() {
            Some(AngularColumns::Orientation)
        } else if first.tangent.is_some() {
            Some(AngularColumns::Tangent)
        } else {
            None
        }
    }

    /// The commanded joints of a run's rows.
    pub fn run_joints(&self, run: usize) -> Vec<Vec<f64>> {
        self.rows[self.runs[run].rows.clone()]
            .iter()
            .map(|r| r.q.clone())
            .collect()
    }

    /// The times of a run's rows.
    pub fn run_times(&self, run: usize) -> Vec<f64> {
        self.rows[self.runs[run].rows.clone()]
            .iter()
            .map(|r| r.t_s)
            .collect()
    }
}

/// Where a recording's columns are (indices into its header).
struct RecordingColumns {
    /// the joints then the tip, in order
    required: Vec<usize>,
    quaternion: Option<Vec<usize>>,
    tangent: Option<Vec<usize>>,
    force: Option<Vec<usize>>,
    time: Option<usize>,
    run: Option<usize>,
    pose: Option<usize>,
    /// `n_frames,spread_mm`
    frames: Option<Vec<usize>>,
}

impl RecordingColumns {
    /// Finds the columns in the header `names` (trimmed; `at` locates the header):
    /// no name twice, every required column, each optional set whole or absent.
    fn find(names: &[&str], n_tubes: usize, at: Location) -> Result<Self, Error> {
        let fail = |kind| Error::new(at.clone(), kind);
        for (i, n) in names.iter().enumerate() {
            if !n.is_empty() && names[..i].contains(n) {
                let name = (*n).to_owned();
                return Err(fail(ErrorKind::DuplicateColumn { name }));
            }
        }
        let find = |c: &str| names.iter().position(|n| *n == c);
        let need = required(n_tubes);
        let mut required = Vec::with_capacity(need.len());
        for c in &need {
            match find(c) {
                Some(i) => required.push(i),
                None => {
                    return Err(fail(ErrorKind::MissingColumn {
                        name: c.clone(),
                        similar: closest(c, names.iter().filter(|n| find_in(&need, n)))
                            .map(str::to_owned),
                        required: need.join(","),
                    }))
                }
            }
        }
        let group = |cols: &[&str]| -> Result<Option<Vec<usize>>, Error> {
            let found: Vec<Option<usize>> = cols.iter().map(|c| find(c)).collect();
            if found.iter().all(Option::is_none) {
                return Ok(None);
            }
            match found.iter().position(Option::is_none) {
                None => Ok(Some(found.into_iter().flatten().collect())),
                Some(k) => Err(fail(ErrorKind::MissingColumn {
                    name: cols[k].to_owned(),
                    similar: None,
                    required: cols.join(","),
                })),
            }
        };
        Ok(RecordingColumns {
            required,
            quaternion: group(&QUAT)?,
            tangent: group(&TANGENT)?,
            force: group(&FORCE)?,
            time: find("t_s"),
            run: find("run"),
            pose: find("pose"),
            frames: group(&FRAMES)?,
        })
    }

    /// The columns that hold numbers.
    fn numbers(&self) -> impl Iterator<Item = usize> + '_ {
        let sets = [&self.quaternion, &self.tangent, &self.force, &self.frames];
        self.required
            .iter()
            .copied()
            .chain(sets.into_iter().flatten().flatten().copied())
            .chain(self.time)
    }
}

/// The cells of one row, however the file keeps them.
trait Cells {
    /// Cell `i` as a finite number.
    fn number(&self, i: usize) -> Result<f64, ErrorKind>;
    /// Cell `i` as text (a run label), trimmed.
    fn label(&self, i: usize) -> Cow<'_, str>;
}

/// A CSV record's cells; `names` are the header's, trimmed.
struct CsvCells<'a> {
    record: &'a csv::StringRecord,
    names: &'a [&'a str],
}

impl Cells for CsvCells<'_> {
    fn number(&self, i: usize) -> Result<f64, ErrorKind> {
        let cell = self.record[i].trim();
        match cell.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(ErrorKind::NotFinite {
                column: self.names[i].to_owned(),
                found: cell.to_owned(),
            }),
            Err(_) => Err(ErrorKind::NotANumber {
                column: self.names[i].to_owned(),
                found: cell.to_owned(),
            }),
        }
    }

    fn label(&self, i: usize) -> Cow<'_, str> {
        Cow::Borrowed(self.record[i].trim())
    }
}

/// A row of a Parquet file's columns; `names` are the columns', trimmed.
struct ParquetCells<'a> {
    columns: &'a [Column],
    names: &'a [&'a str],
    row: usize,
}

impl Cells for ParquetCells<'_> {
    fn number(&self, i: usize) -> Result<f64, ErrorKind> {
        let column = &self.columns[i];
        match column.number(self.row) {
            Some(v) if v.is_finite() => Ok(v),
            Some(_) => Err(ErrorKind::NotFinite {
                column: self.names[i].to_owned(),
                found: column.text(self.row).into_owned(),
            }),
            None => Err(ErrorKind::NullValue {
                column: self.names[i].to_owned(),
            }),
        }
    }

    fn label(&self, i: usize) -> Cow<'_, str> {
        match self.columns[i].text(self.row) {
            Cow::Borrowed(s) => Cow::Borrowed(s.trim()),
            Cow::Owned(s) => Cow::Owned(s.trim().to_owned()),
        }
    }
}

/// The rows and runs of a recording read so far.
#[derive(Default)]
struct RowsSoFar {
    rows: Vec<RecordedRow>,
    runs: Vec<Run>,
    /// Each run's label and its index in `runs` (a label seen before is found at once,
    /// not by a walk over every run: a sweep may hold a run per row).
    labels: HashMap<String, usize>,
    /// The poses of a static set (unused for a time series).
    poses: PosesSoFar,
}

impl RowsSoFar {
    /// Adds the row of `cells` (at `line`, or at a Parquet file's row), checked: its
    /// numbers, its unit vectors, its time after the previous row's of its run.
    fn push(
        &mut self,
        cols: &RecordingColumns,
        cells: &impl Cells,
        line: usize,
        at: impl Fn(ErrorKind) -> Error,
    ) -> Result<(), Error> {
        let num = |i: usize| cells.number(i).map_err(&at);
        let values = cols
            .required
            .iter()
            .map(|&i| num(i))
            .collect::<Result<Vec<f64>, _>>()?;
        let n = values.len() - TIP.len();
        let t_s = match cols.time {
            Some(i) => num(i)?,
            None => self.rows.len() as f64,
        };
        let label = cols.run.map_or(Cow::Borrowed("all"), |i| cells.label(i));
        let quaternion = match &cols.quaternion {
            Some(c) => {
                let q = [num(c[0])?, num(c[1])?, num(c[2])?, num(c[3])?];
                Some(unit(q).map_err(|norm| at(ErrorKind::NotUnitQuaternion { q, norm }))?)
            }
            None => None,
        };
        let tangent = match &cols.tangent {
            Some(c) => {
                let t = [num(c[0])?, num(c[1])?, num(c[2])?];
                Some(unit(t).map_err(|norm| at(ErrorKind::NotUnitTangent { t, norm }))?)
            }
            None => None,
        };
        let force_n = match &cols.force {
            Some(c) => [num(c[0])?, num(c[1])?, num(c[2])?],
            None => [0.0; 3],
        };
        let frames = match &cols.frames {
            Some(c) => Some(Frames::checked(num(c[0])?, num(c[1])?).map_err(&at)?),
            None => None,
        };
        let runs_before = self.runs.len();
        self.add_to_run(&label, t_s, &at)?;
        let q = &values[..n];
        if cols.pose.is_some() || cols.frames.is_some() {
            let pose = cols.pose.map(|i| cells.label(i));
            let rows = &self.rows;
            self.poses
                .add(
                    pose.as_deref(),
                    rows.len(),
                    line,
                    self.runs.len() == runs_before,
                    q,
                    |r| rows[r].q.clone(),
                )
                .map_err(&at)?;
        }
        self.rows.push(RecordedRow {
            line,
            t_s,
            run: self.runs.len() - 1,
            q: q.to_vec(),
            p: [values[n], values[n + 1], values[n + 2]],
            quaternion,
            tangent,
            force_n,
            frames,
        });
        Ok(())
    }

    /// Puts the next row (of run `label`, at `t_s`) in its run: the run of the row
    /// before when it has the same label (then not earlier than that row), else a new
    /// one (an error when an earlier run had the label: a run is one stretch of rows).
    fn add_to_run(
        &mut self,
        label: &str,
        t_s: f64,
        at: impl Fn(ErrorKind) -> Error,
    ) -> Result<(), Error> {
        let i = self.rows.len();
        match self.runs.last_mut() {
            Some(r) if r.label == label => {
                let prev: &RecordedRow = &self.rows[i - 1];
                if t_s < prev.t_s {
                    return Err(at(ErrorKind::Csv {
                        message: format!(
                            "column t_s: {t_s} is earlier than the previous row's {} in run \
                             {label}; rows of a run must be in time order",
                            prev.t_s
                        ),
                    }));
                }
                r.rows.end = i + 1;
            }
            _ => {
                if let Some(&earlier) = self.labels.get(label) {
                    let last = &self.rows[self.runs[earlier].rows.end - 1];
                    return Err(at(ErrorKind::Csv {
                        message: format!(
                            "column run: run {label} starts again here after other rows (its \
                             rows ended at line {}); rows with the same label form one \
                             continuous run: give this part a label of its own",
                            last.line
                        ),
                    }));
                }
                self.labels.insert(label.to_owned(), self.runs.len());
                self.runs.push(Run {
                    label: label.to_owned(),
                    rows: i..i + 1,
                })
            }
        }
        Ok(())
    }

    /// The recording, which must have a row.
    fn finish(
        self,
        file: &str,
        n_tubes: usize,
        cols: &RecordingColumns,
    ) -> Result<Recording, Error> {
        if self.rows.is_empty() {
            return Err(Error::new(
                Location::file(file),
                ErrorKind::Csv {
                    message: "no rows after the header; a recording needs at least one".into(),
                },
            ));
        }
        Ok(Recording {
            file: file.to_owned(),
            n_tubes,
            rows: self.rows,
            runs: self.runs,
            has_time: cols.time.is_some(),
            has_force: cols.force.is_some(),
            poses: (cols.pose.is_some() || cols.frames.is_some()).then_some(self.poses.poses),
            angular: None,
        })
    }
}

/// `v` as it is, or its norm when that is more than [`UNIT_TOLERANCE`] from 1.
fn unit<const N: usize>(v: [f64; N]) -> Result<[f64; N], f64> {
    let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > UNIT_TOLERANCE {
        return Err(norm);
    }
    Ok(v)
}

fn required(n_tubes: usize) -> Vec<String> {
    joint_columns(n_tubes)
        .into_iter()
        .chain(TIP.iter().map(|c| (*c).to_owned()))
        .collect()
}

/// A header name that is not already one of the wanted columns (a candidate for "did
/// you mean").
fn find_in(need: &[String], name: &str) -> bool {
    !need.iter().any(|c| c == name)
}

/// The 1-based line of a byte offset, counted forward from the last offset asked (the
/// csv crate's own line numbers count a CRLF file's line ends twice).
#[derive(Default)]
struct LineCounter {
    byte: usize,
    /// newlines before `byte`
    newlines: usize,
}

impl LineCounter {
    /// The line holding `data[at]`; `at` must not be before the previous call's.
    fn line_at(&mut self, data: &[u8], at: usize) -> usize {
        let at = at.clamp(self.byte, data.len());
        self.newlines += memchr::memchr_iter(b'\n', &data[self.byte..at]).count();
        self.byte = at;
        self.newlines + 1
    }
}

/// Where a record read by the csv crate starts: its position may point at the line end
/// before it (the `\n` of a CRLF, which the crate reads as an empty record and skips).
fn record_start(data: &[u8], position: Option<&csv::Position>) -> usize {
    let from = position
        .map_or(data.len(), |p| p.byte() as usize)
        .min(data.len());
    from + data[from..]
        .iter()
        .take_while(|&&b| b == b'\n' || b == b'\r')
        .count()
}

fn csv_error(e: csv::Error, file: &str, data: &[u8], lines: &mut LineCounter) -> Error {
    let line = e
        .position()
        .map(|p| lines.line_at(data, record_start(data, Some(p))));
    let message = match e.kind() {
        csv::ErrorKind::Utf8 { err, .. } => {
            format!("field {}: not valid UTF-8 text", err.field() + 1)
        }
        _ => super::toml_doc::one_line(&e.to_string()),
    };
    let location = match line {
        Some(l) => Location::line(file, l),
        None => Location::file(file),
    };
    Error::new(location, ErrorKind::Csv { message })
}

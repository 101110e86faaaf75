//! The joint file read as a stream: its header at once, then pieces of rows that are
//! cut in order on one thread ([`JointStream::next_piece`]) and parsed and checked on
//! any ([`JointPiece::parse`]), so that a file of any size goes through in bounded
//! memory and the parsing runs in parallel.
//!
//! A CSV file's rows, their lines, fields, values and errors are those of
//! [`JointTable`]: a piece is read by the same machinery, and taking the pieces in
//! order gives the first error of the file first. A Parquet file (`*.parquet`, or a
//! file that starts as one) is read a bounded number of rows at a time, whatever its
//! row groups; its rows are numbered from 1 in errors (`j.parquet: row 17: ...`).
//!
//! [`JointTable`]: crate::JointTable

use crate::columnar::read::ParquetReader;
use crate::columnar::table::{numbers_only, parquet_values};
use crate::columnar::{is_parquet, Batch, Column, ColumnType, MAGIC};
use crate::error::{Error, ErrorKind, Location};
use crate::robot::{joint_columns, tube_of_column, AnyRobot};
use crate::stream::{CsvPiece, CsvRows, CsvStream};
use crate::table::{Columns, Header};
use crate::tips::{Carried, CarriedColumns};
use std::borrow::Cow;
use std::io::Read;
use std::path::Path;

/// A joint file being read: the header is checked, the rows come in pieces.
///
/// ```
/// use ctr_formats::{AnyRobot, JointStream};
/// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
/// let robot = AnyRobot::new(&[t]).unwrap();
/// let csv = "label,s1_mm,theta1_deg\na,10,0\nb,20,5\nc,30,abc\n";
/// let mut stream = JointStream::from_reader(csv.as_bytes(), "j.csv", &robot)?;
/// let parser = stream.parser(false);
/// let first = stream.next_piece(2).unwrap().parse(&parser)?;
/// assert_eq!((first.len(), first.joints(1)), (2, &[20.0, 5.0][..]));
/// let err = stream.next_piece(2).unwrap().parse(&parser).unwrap_err();
/// assert_eq!(err.to_string(), "j.csv:4: column theta1_deg: \"abc\" is not a number");
/// assert!(stream.next_piece(2).is_none());
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub struct JointStream<'r> {
    source: Source<'r>,
    file: String,
    header: Header,
    robot: AnyRobot,
    /// rows handed out so far
    rows: usize,
    /// the rows in the file (Parquet), or an estimate from its size (CSV)
    estimate: Option<usize>,
}

enum Source<'r> {
    Csv(CsvStream<Box<dyn Read + Send + 'r>>),
    Parquet(Box<ParquetReader>),
}

/// What parsing a piece needs: the header, the file's name and the robot the joints
/// are checked against. Shared by the threads that parse.
#[derive(Clone, Debug)]
pub struct JointParser {
    header: Header,
    file: String,
    robot: AnyRobot,
    /// the input columns go to a Parquet output: a CSV file's are made columns
    columns_out: bool,
}

/// Rows of a joint file cut from the stream but not parsed yet.
#[derive(Debug)]
pub struct JointPiece {
    first_row: usize,
    kind: PieceKind,
}

#[derive(Debug)]
enum PieceKind {
    Csv(CsvPiece),
    Parquet(Vec<Column>),
    /// reading the file failed here
    Failed(Error),
}

/// Rows of a joint file, parsed and checked: every row has finite joints the robot can
/// take; the input's columns are kept for carrying through.
#[derive(Clone, Debug)]
pub struct JointRows {
    first_row: usize,
    /// joint values per row (`2 n`)
    width: usize,
    values: Vec<f64>,
    kind: RowsKind,
    /// every input column as an output column (for a Parquet output)
    columns: Option<Vec<Column>>,
}

#[derive(Clone, Debug)]
enum RowsKind {
    Csv(CsvRows),
    Parquet,
}

impl<'r> JointStream<'r> {
    /// Starts reading `reader` (`file` names it in errors) and checks its header
    /// against `robot` as [`JointTable`](crate::JointTable) does. CSV, unless the bytes
    /// are a Parquet file's (then read whole into memory).
    pub fn from_reader(
        reader: impl Read + Send + 'r,
        file: &str,
        robot: &AnyRobot,
    ) -> Result<Self, Error> {
        let mut reader = reader;
        let mut head = Vec::with_capacity(MAGIC.len());
        (&mut reader)
            .take(MAGIC.len() as u64)
            .read_to_end(&mut head)
            .map_err(|source| read_error(file, source))?;
        if head == MAGIC {
            let mut data = head;
            reader
                .read_to_end(&mut data)
                .map_err(|source| read_error(file, source))?;
            let parquet = ParquetReader::from_bytes(data, file)?;
            return Self::parquet(parquet, robot);
        }
        let rest = std::io::Cursor::new(head).chain(reader);
        Self::csv(Box::new(rest), file, robot, None)
    }

    /// Opens and starts reading a joint file; errors name the path as given. Parquet
    /// when its name ends in `.parquet` or its bytes start as a Parquet file's; else
    /// CSV.
    pub fn from_path(path: &Path, robot: &AnyRobot) -> Result<JointStream<'static>, Error> {
        let file = path.display().to_string();
        let opened = std::fs::File::open(path).and_then(|f| Ok((f.metadata()?.len(), f)));
        let (size, mut f) = opened.map_err(|source| read_error(&file, source))?;
        let mut head = [0u8; 4];
        let parquet_bytes = f.read_exact(&mut head).is_ok() && head == MAGIC;
        if is_parquet(path) || parquet_bytes {
            return JointStream::parquet(ParquetReader::open(path)?, robot);
        }
        let f = std::fs::File::open(path).map_err(|source| read_error(&file, source))?;
        JointStream::csv(Box::new(f), &file, robot, Some(size))
    }

    fn csv(
        reader: Box<dyn Read + Send + 'r>,
        file: &str,
        robot: &AnyRobot,
        size: Option<u64>,
    ) -> Result<Self, Error> {
        let mut csv = CsvStream::new(reader, file);
        let required = joint_columns(robot.n_tubes());
        let columns = Columns {
            required: &required,
            optional: None,
        };
        let header = csv.header(&columns, |name| column_beyond(name, robot.n_tubes()))?;
        let estimate = size.map(|s| csv.estimate_rows(s));
        Ok(JointStream {
            source: Source::Csv(csv),
            file: file.to_owned(),
            header,
            robot: *robot,
            rows: 0,
            estimate,
        })
    }

    fn parquet(reader: ParquetReader, robot: &AnyRobot) -> Result<Self, Error> {
        let file = reader.file().to_owned();
        let required = joint_columns(robot.n_tubes());
        let columns = Columns {
            required: &required,
            optional: None,
        };
        let header = Header::check(reader.names(), Location::file(&file), &columns, |name| {
            column_beyond(name, robot.n_tubes())
        })?;
        numbers_only(&reader, &header, &file)?;
        Ok(JointStream {
            estimate: Some(reader.rows),
            source: Source::Parquet(Box::new(reader)),
            file,
            header,
            robot: *robot,
            rows: 0,
        })
    }

    /// The file's name in errors.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The header as found (a CSV file's names untrimmed; a Parquet file's columns).
    pub fn header(&self) -> &[String] {
        &self.header.names
    }

    /// Where the header is, for errors about it: its line, or the file (Parquet).
    pub fn header_location(&self) -> Location {
        self.header.location.clone()
    }

    /// True when the file is Parquet.
    pub fn is_parquet(&self) -> bool {
        matches!(self.source, Source::Parquet(_))
    }

    /// The input's columns as columns of a Parquet output: a Parquet file's with their
    /// own types, a CSV file's as [`ColumnType::carried_csv`] makes them.
    pub fn column_types(&self) -> Vec<ColumnType> {
        match &self.source {
            Source::Parquet(p) => p.columns.iter().map(|c| ColumnType(c.ty.clone())).collect(),
            Source::Csv(_) => self
                .header
                .names
                .iter()
                .enumerate()
                .map(|(i, name)| {
                    if self.header.index.contains(&i) {
                        ColumnType::double(name)
                    } else {
                        ColumnType::carried_csv(name)
                    }
                })
                .collect(),
        }
    }

    /// The rows in the file (Parquet), or about how many from its size and its first
    /// lines (a CSV file): for progress reports only.
    pub fn estimated_rows(&self) -> Option<usize> {
        self.estimate
    }

    /// What the threads that parse the pieces need; with `columns_out` the rows keep
    /// the input's columns for a Parquet output ([`JointRows::batch`]).
    pub fn parser(&self, columns_out: bool) -> JointParser {
        JointParser {
            header: self.header.clone(),
            file: self.file.clone(),
            robot: self.robot,
            columns_out,
        }
    }

    /// The next `rows` rows (fewer at the end), not parsed yet; `None` after the last.
    /// A failed read is a piece whose parse is the error.
    pub fn next_piece(&mut self, rows: usize) -> Option<JointPiece> {
        let first_row = self.rows;
        let kind = match &mut self.source {
            Source::Csv(csv) => match csv.next_piece(rows)? {
                Ok(piece) => {
                    self.rows += piece.rows();
                    PieceKind::Csv(piece)
                }
                Err(e) => PieceKind::Failed(e),
            },
            Source::Parquet(p) => match p.next_rows(rows) {
                Ok(columns) if columns.first().is_none_or(|c| c.len() == 0) => return None,
                Ok(columns) => {
                    self.rows += columns[0].len();
                    PieceKind::Parquet(columns)
                }
                Err(e) => PieceKind::Failed(e),
            },
        };
        Some(JointPiece { first_row, kind })
    }
}

fn read_error(file: &str, source: std::io::Error) -> Error {
    Error::new(
        Location::file(file),
        ErrorKind::Io {
            action: "read",
            source,
        },
    )
}

/// Refuses a joint-like column for a tube beyond the robot's `n` (`s3_mm` for two tubes).
pub(crate) fn column_beyond(name: &str, n: usize) -> Result<(), ErrorKind> {
    match tube_of_column(name) {
        Some(tube) if tube > n => Err(ErrorKind::ColumnBeyondRobot {
            name: name.to_owned(),
            n_tubes: n,
        }),
        _ => Ok(()),
    }
}

/// The check of every joint row: the robot can take the joints (errors at the row's
/// line, or at its row for a file without lines).
pub(crate) fn joint_check<'a>(
    robot: &'a AnyRobot,
    file: &'a str,
    rows: bool,
) -> impl Fn(&[f64], usize) -> Result<(), Error> + Sync + 'a {
    move |joints: &[f64], at: usize| {
        robot.validate_joints(joints).map_err(|e| {
            let at = if rows {
                Location::row(file, at)
            } else {
                Location::line(file, at)
            };
            Error::new(at, ErrorKind::Joint(e))
        })
    }
}

impl JointParser {
    /// Columns of the file.
    pub fn columns(&self) -> usize {
        self.header.names.len()
    }
}

impl JointPiece {
    /// The index of the piece's first row in the file (0-based, data rows only).
    pub fn first_row(&self) -> usize {
        self.first_row
    }

    /// Parses and checks the piece's rows; the error is the piece's first.
    pub fn parse(self, parser: &JointParser) -> Result<JointRows, Error> {
        let (file, header) = (&parser.file, &parser.header);
        let (kind, values, columns) = match self.kind {
            PieceKind::Failed(e) => return Err(e),
            PieceKind::Csv(piece) => {
                let check = joint_check(&parser.robot, file, false);
                let mut csv = piece.parse(header, file, &check)?;
                let columns = match parser.columns_out {
                    true => Some(csv.columns(header, file)?),
                    false => None,
                };
                let values = std::mem::take(&mut csv.values);
                (RowsKind::Csv(csv), values, columns)
            }
            PieceKind::Parquet(columns) => {
                let check = joint_check(&parser.robot, file, true);
                let values = parquet_values(&columns, header, file, self.first_row, &check)?;
                (RowsKind::Parquet, values, Some(columns))
            }
        };
        Ok(JointRows {
            first_row: self.first_row,
            width: header.width(),
            values,
            kind,
            columns,
        })
    }
}

impl JointRows {
    /// The index of the first row in the file (0-based, data rows only).
    pub fn first_row(&self) -> usize {
        self.first_row
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        match &self.kind {
            RowsKind::Csv(csv) => csv.len(),
            RowsKind::Parquet => self.values.len() / self.width.max(1),
        }
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Where row `r` (0-based, of these rows) is, for messages: its 1-based line in a
    /// CSV file, or its 1-based row in a Parquet file ([`JointRows::is_rows`]).
    pub fn line(&self, r: usize) -> usize {
        match &self.kind {
            RowsKind::Csv(csv) => csv.line(r),
            RowsKind::Parquet => self.first_row + r + 1,
        }
    }

    /// True when [`line`](Self::line) gives rows of a Parquet file, not lines.
    pub fn is_rows(&self) -> bool {
        matches!(self.kind, RowsKind::Parquet)
    }

    /// The location of row `r` in `file`, for errors.
    pub fn location(&self, file: &str, r: usize) -> Location {
        if self.is_rows() {
            Location::row(file, self.line(r))
        } else {
            Location::line(file, self.line(r))
        }
    }

    /// The joints of row `r` in file order (`s1_mm, theta1_deg, ...`).
    pub fn joints(&self, r: usize) -> &[f64] {
        let w = self.width;
        &self.values[r * w..(r + 1) * w]
    }

    /// All rows' joints, row after row.
    pub fn all_joints(&self) -> &[f64] {
        &self.values
    }

    /// The field of row `r` in column `column` (an index into the header), as text: a
    /// CSV file's raw field, a Parquet cell written as CSV writes it.
    pub fn field(&self, r: usize, column: usize) -> Cow<'_, str> {
        match (&self.kind, &self.columns) {
            (RowsKind::Csv(csv), _) => Cow::Borrowed(csv.fields(r).nth(column).unwrap_or_default()),
            (RowsKind::Parquet, Some(columns)) => columns[column].text(r),
            (RowsKind::Parquet, None) => Cow::Borrowed(""),
        }
    }

    /// Row `r`'s input columns for a CSV output row ([`write_tip_row_for`]): its line as
    /// it was when it had no quotes, else its fields; a Parquet file's cells as text.
    ///
    /// [`write_tip_row_for`]: crate::write_tip_row_for
    pub fn carried(&self, r: usize) -> Carried<'_, impl Iterator<Item = &str> + '_> {
        match (&self.kind, &self.columns) {
            (RowsKind::Csv(csv), _) => match csv.plain_line(r) {
                Some(line) => Carried::Line(line),
                None => Carried::Fields(csv.fields(r)),
            },
            (RowsKind::Parquet, columns) => Carried::Columns(CarriedColumns {
                columns: columns.as_deref().unwrap_or_default(),
                keep: None,
                row: r,
            }),
        }
    }

    /// The input's columns of the rows `rows` (indices of these rows, in order), for a
    /// Parquet output: the columns of [`JointStream::column_types`]. Empty unless the
    /// parser was made with `columns_out` (or the file is Parquet).
    pub fn batch(&self, rows: &[usize]) -> Batch {
        let Some(columns) = &self.columns else {
            return Batch::default();
        };
        let all = rows.len() == self.len() && rows.iter().enumerate().all(|(k, &r)| k == r);
        if all {
            return Batch(columns.clone());
        }
        Batch(
            columns
                .iter()
                .map(|c| {
                    let mut out = c.empty();
                    rows.iter().for_each(|&r| out.push_from(c, r));
                    out
                })
                .collect(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tube_columns() {
        assert_eq!(tube_of_column("s3_mm"), Some(3));
        assert_eq!(tube_of_column("theta12_deg"), Some(12));
        assert_eq!(tube_of_column("s_mm"), None);
        assert_eq!(tube_of_column("sx_mm"), None);
    }
}

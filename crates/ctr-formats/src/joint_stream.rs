//! The joint file read as a stream: its header at once, then pieces of rows that are
//! cut in order on one thread ([`JointStream::next_piece`]) and parsed and checked on
//! any ([`JointPiece::parse`]), so that a file of any size goes through in bounded
//! memory and the parsing runs in parallel.
//!
//! The rows, their lines, fields, values and errors are those of [`JointTable`]: a
//! piece is read by the same machinery, and taking the pieces in order gives the first
//! error of the file first.
//!
//! [`JointTable`]: crate::JointTable

use crate::error::{Error, ErrorKind, Location};
use crate::robot::{joint_columns, AnyRobot};
use crate::stream::{CsvPiece, CsvRows, CsvStream};
use crate::table::{Columns, Header};
use crate::tips::Carried;
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
/// let parser = stream.parser();
/// let first = stream.next_piece(2).unwrap().parse(&parser)?;
/// assert_eq!((first.len(), first.joints(1)), (2, &[20.0, 5.0][..]));
/// let err = stream.next_piece(2).unwrap().parse(&parser).unwrap_err();
/// assert_eq!(err.to_string(), "j.csv:4: column theta1_deg: \"abc\" is not a number");
/// assert!(stream.next_piece(2).is_none());
/// # Ok::<(), ctr_formats::Error>(())
/// ```
pub struct JointStream<'r> {
    csv: CsvStream<Box<dyn Read + Send + 'r>>,
    header: Header,
    robot: AnyRobot,
    /// rows handed out so far
    rows: usize,
    /// an estimate of the rows in the file, from its size
    estimate: Option<usize>,
}

/// What parsing a piece needs: the header, the file's name and the robot the joints
/// are checked against. Shared by the threads that parse.
#[derive(Clone, Debug)]
pub struct JointParser {
    header: Header,
    file: String,
    robot: AnyRobot,
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
    /// reading the file failed here
    Failed(Error),
}

/// Rows of a joint file, parsed and checked: every row has finite joints the robot can
/// take; the raw fields are kept for carrying through.
#[derive(Clone, Debug)]
pub struct JointRows {
    first_row: usize,
    /// joint values per row (`2 n`)
    width: usize,
    csv: CsvRows,
}

impl<'r> JointStream<'r> {
    /// Starts reading CSV from `reader` (`file` names it in errors) and checks its
    /// header against `robot` as [`JointTable`](crate::JointTable) does.
    pub fn from_reader(
        reader: impl Read + Send + 'r,
        file: &str,
        robot: &AnyRobot,
    ) -> Result<Self, Error> {
        Self::start(Box::new(reader), file, robot, None)
    }

    /// Opens and starts reading a joint file; errors name the path as given.
    pub fn from_path(path: &Path, robot: &AnyRobot) -> Result<JointStream<'static>, Error> {
        let file = path.display().to_string();
        let opened = std::fs::File::open(path).and_then(|f| Ok((f.metadata()?.len(), f)));
        let (size, f) = opened.map_err(|source| {
            Error::new(
                Location::file(&file),
                ErrorKind::Io {
                    action: "read",
                    source,
                },
            )
        })?;
        JointStream::start(Box::new(f), &file, robot, Some(size))
    }

    fn start(
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
            csv,
            header,
            robot: *robot,
            rows: 0,
            estimate,
        })
    }

    /// The file's name in errors.
    pub fn file(&self) -> &str {
        self.csv.file()
    }

    /// The header as found (untrimmed).
    pub fn header(&self) -> &[String] {
        &self.header.names
    }

    /// The 1-based line of the header.
    pub fn header_line(&self) -> usize {
        self.header.line
    }

    /// About how many rows the file has (from its size and its first lines), when it is
    /// a file: for progress reports only.
    pub fn estimated_rows(&self) -> Option<usize> {
        self.estimate
    }

    /// What the threads that parse the pieces need.
    pub fn parser(&self) -> JointParser {
        JointParser {
            header: self.header.clone(),
            file: self.file().to_owned(),
            robot: self.robot,
        }
    }

    /// The next `rows` rows (fewer at the end), not parsed yet; `None` after the last.
    /// A failed read is a piece whose parse is the error.
    pub fn next_piece(&mut self, rows: usize) -> Option<JointPiece> {
        let first_row = self.rows;
        let kind = match self.csv.next_piece(rows)? {
            Ok(piece) => {
                self.rows += piece.rows();
                PieceKind::Csv(piece)
            }
            Err(e) => PieceKind::Failed(e),
        };
        Some(JointPiece { first_row, kind })
    }
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

/// The tube number of a joint-like column name (`s3_mm`, `theta3_deg`).
pub(crate) fn tube_of_column(name: &str) -> Option<usize> {
    let digits = name
        .strip_prefix('s')
        .and_then(|r| r.strip_suffix("_mm"))
        .or_else(|| {
            name.strip_prefix("theta")
                .and_then(|r| r.strip_suffix("_deg"))
        })?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// The check of every joint row: the robot can take the joints.
pub(crate) fn joint_check<'a>(
    robot: &'a AnyRobot,
    file: &'a str,
) -> impl Fn(&[f64], usize) -> Result<(), Error> + Sync + 'a {
    move |joints: &[f64], line: usize| {
        robot
            .validate_joints(joints)
            .map_err(|e| Error::new(Location::line(file, line), ErrorKind::Joint(e)))
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
        match self.kind {
            PieceKind::Failed(e) => Err(e),
            PieceKind::Csv(piece) => {
                let check = joint_check(&parser.robot, &parser.file);
                let csv = piece.parse(&parser.header, &parser.file, &check)?;
                Ok(JointRows {
                    first_row: self.first_row,
                    width: parser.header.width(),
                    csv,
                })
            }
        }
    }
}

impl JointRows {
    /// The index of the first row in the file (0-based, data rows only).
    pub fn first_row(&self) -> usize {
        self.first_row
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.csv.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The 1-based file line where row `r` (0-based, of these rows) starts.
    pub fn line(&self, r: usize) -> usize {
        self.csv.line(r)
    }

    /// The joints of row `r` in file order (`s1_mm, theta1_deg, ...`).
    pub fn joints(&self, r: usize) -> &[f64] {
        let w = self.width;
        &self.csv.values[r * w..(r + 1) * w]
    }

    /// All rows' joints, row after row.
    pub fn all_joints(&self) -> &[f64] {
        &self.csv.values
    }

    /// The raw fields of row `r`, all columns in header order.
    pub fn fields(&self, r: usize) -> impl Iterator<Item = &str> {
        self.csv.fields(r)
    }

    /// The raw field of row `r` in column `column` (an index into the header).
    pub fn field(&self, r: usize, column: usize) -> &str {
        self.csv.fields(r).nth(column).unwrap_or_default()
    }

    /// Row `r`'s input columns for an output row ([`write_tip_row_for`]): its line as
    /// it was when it had no quotes, else its fields.
    ///
    /// [`write_tip_row_for`]: crate::write_tip_row_for
    pub fn carried(&self, r: usize) -> Carried<'_, impl Iterator<Item = &str> + '_> {
        match self.csv.plain_line(r) {
            Some(line) => Carried::Line(line),
            None => Carried::Fields(self.csv.fields(r)),
        }
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

//! The joint CSV: one configuration per row, header `s1_mm,theta1_deg,...`, other
//! columns carried through as the raw strings they were.

use crate::error::{Error, ErrorKind, Location};
use crate::robot::{joint_columns, AnyRobot};
use std::io::Read;
use std::path::Path;

/// A joint file read and checked against a robot: every row has finite joints the robot
/// can take. The raw fields of every row are kept for carrying through.
#[derive(Clone, Debug)]
pub struct JointTable {
    file: String,
    header: Vec<String>,
    n_tubes: usize,
    records: Vec<csv::StringRecord>,
    lines: Vec<usize>,
    joints: Vec<f64>,
}

impl JointTable {
    /// Reads CSV from `reader`; `file` names it in errors.
    ///
    /// ```
    /// use ctr_analysis::{formats::JointTable, AnyRobot};
    /// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// let robot = AnyRobot::new(&[t]).unwrap();
    /// let csv = "label,s1_mm,theta1_deg\na,10,0\nb,20,abc\n";
    /// let err = JointTable::read(csv.as_bytes(), "j.csv", &robot).unwrap_err();
    /// assert_eq!(err.to_string(), "j.csv:3: column theta1_deg: \"abc\" is not a number");
    /// ```
    pub fn read<R: Read>(mut reader: R, file: &str, robot: &AnyRobot) -> Result<JointTable, Error> {
        let mut data = Vec::new();
        reader.read_to_end(&mut data).map_err(|source| {
            Error::new(
                Location::file(file),
                ErrorKind::Io {
                    action: "read",
                    source,
                },
            )
        })?;
        let n = robot.n_tubes();
        let required = joint_columns(n);
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .from_reader(data.as_slice());
        // the csv crate's own line numbers drift on blank lines and CRLF: count them here
        let mut lines = LineCounter::new(&data);
        let mut records = rdr.records();
        let mut csv_error = |e: csv::Error| {
            let line = e.position().map(|p| lines.line_at(p.byte() as usize));
            let kind = match e.into_kind() {
                csv::ErrorKind::Io(source) => ErrorKind::Io {
                    action: "read",
                    source,
                },
                csv::ErrorKind::Utf8 { err, .. } => ErrorKind::Csv {
                    message: format!("field {}: not valid UTF-8 text", err.field() + 1),
                },
                other => ErrorKind::Csv {
                    message: super::robot_file::one_line(&format!("{other:?}")),
                },
            };
            Error::new(
                Location {
                    file: file.to_owned(),
                    line,
                    column: None,
                },
                kind,
            )
        };
        let at = |line: usize, kind: ErrorKind| Error::new(Location::line(file, line), kind);

        let header_record = match records.next() {
            None => {
                return Err(Error::new(
                    Location::file(file),
                    ErrorKind::EmptyFile {
                        expected: required.join(","),
                    },
                ))
            }
            Some(r) => r.map_err(&mut csv_error)?,
        };
        let mut lines = LineCounter::new(&data);
        let mut line_of =
            |r: &csv::StringRecord| r.position().map_or(0, |p| lines.line_at(p.byte() as usize));
        let header_line = line_of(&header_record);
        let header: Vec<String> = header_record.iter().map(str::to_owned).collect();
        let names: Vec<&str> = header.iter().map(|h| h.trim()).collect();
        for (i, name) in names.iter().enumerate() {
            if names[..i].contains(name) {
                return Err(at(
                    header_line,
                    ErrorKind::DuplicateColumn {
                        name: (*name).to_owned(),
                    },
                ));
            }
            if let Some(tube) = tube_of_column(name) {
                if tube > n {
                    return Err(at(
                        header_line,
                        ErrorKind::ColumnBeyondRobot {
                            name: (*name).to_owned(),
                            n_tubes: n,
                        },
                    ));
                }
            }
        }
        let mut index = Vec::with_capacity(2 * n);
        for want in &required {
            match names.iter().position(|h| h == want) {
                Some(i) => index.push(i),
                None => {
                    let unknown = names.iter().filter(|h| !required.iter().any(|r| r == *h));
                    return Err(at(
                        header_line,
                        ErrorKind::MissingColumn {
                            name: want.clone(),
                            similar: closest(want, unknown).map(str::to_owned),
                            required: required.join(","),
                        },
                    ));
                }
            }
        }

        let mut table = JointTable {
            file: file.to_owned(),
            header,
            n_tubes: n,
            records: Vec::new(),
            lines: Vec::new(),
            joints: Vec::new(),
        };
        for record in records {
            let record = record.map_err(&mut csv_error)?;
            let line = line_of(&record);
            if record.len() != table.header.len() {
                return Err(at(
                    line,
                    ErrorKind::RaggedRow {
                        found: record.len(),
                        expected: table.header.len(),
                    },
                ));
            }
            let start = table.joints.len();
            for (k, &i) in index.iter().enumerate() {
                let cell = &record[i];
                let value: f64 = cell.trim().parse().map_err(|_| {
                    at(
                        line,
                        ErrorKind::NotANumber {
                            column: required[k].clone(),
                            found: cell.to_owned(),
                        },
                    )
                })?;
                if !value.is_finite() {
                    return Err(at(
                        line,
                        ErrorKind::NotFinite {
                            column: required[k].clone(),
                            found: cell.to_owned(),
                        },
                    ));
                }
                table.joints.push(value);
            }
            robot
                .validate_joints(&table.joints[start..])
                .map_err(|e| at(line, ErrorKind::Joint(e)))?;
            table.records.push(record);
            table.lines.push(line);
        }
        Ok(table)
    }

    /// Reads a joint file; errors name the path as given.
    pub fn from_path(path: &Path, robot: &AnyRobot) -> Result<JointTable, Error> {
        let file = path.display().to_string();
        let f = std::fs::File::open(path).map_err(|source| {
            Error::new(
                Location::file(&file),
                ErrorKind::Io {
                    action: "read",
                    source,
                },
            )
        })?;
        JointTable::read(std::io::BufReader::new(f), &file, robot)
    }

    /// The file name used in errors.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The header as found (untrimmed).
    pub fn header(&self) -> &[String] {
        &self.header
    }

    /// The robot's tube count the table was checked against.
    pub fn n_tubes(&self) -> usize {
        self.n_tubes
    }

    /// Number of data rows.
    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// True when the file has a header only.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// The 1-based file line where data row `row` (0-based) starts.
    pub fn line(&self, row: usize) -> usize {
        self.lines[row]
    }

    /// The raw fields of data row `row`, all columns in header order.
    pub fn fields(&self, row: usize) -> impl Iterator<Item = &str> {
        self.records[row].iter()
    }

    /// The joints of data row `row` in file order (`s1_mm, theta1_deg, ...`).
    pub fn joints(&self, row: usize) -> &[f64] {
        let w = 2 * self.n_tubes;
        &self.joints[row * w..(row + 1) * w]
    }

    /// All rows' joints, row after row (`2 * n_tubes()` values per row).
    pub fn all_joints(&self) -> &[f64] {
        &self.joints
    }
}

/// 1-based line numbers of byte offsets, for offsets that never decrease.
struct LineCounter<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> LineCounter<'a> {
    fn new(data: &'a [u8]) -> Self {
        LineCounter {
            data,
            pos: 0,
            line: 1,
        }
    }

    /// The line of the first byte at or after `byte` that is not a line break (a record
    /// starts after the blank lines the reader skipped).
    fn line_at(&mut self, byte: usize) -> usize {
        let mut at = byte.min(self.data.len());
        while at < self.data.len() && matches!(self.data[at], b'\n' | b'\r') {
            at += 1;
        }
        if at < self.pos {
            // never happens for a forward reader; recount from the start
            self.pos = 0;
            self.line = 1;
        }
        self.line += self.data[self.pos..at]
            .iter()
            .filter(|b| **b == b'\n')
            .count();
        self.pos = at;
        self.line
    }
}

/// The tube number of a joint-like column name (`s3_mm`, `theta3_deg`).
fn tube_of_column(name: &str) -> Option<usize> {
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

/// The candidate most like `want` (case-insensitive edit distance at most 3, or a
/// prefix of it), if any.
fn closest<'a>(want: &str, candidates: impl Iterator<Item = &'a &'a str>) -> Option<&'a str> {
    let w = want.to_ascii_lowercase();
    candidates
        .filter(|c| !c.is_empty())
        .map(|c| {
            let l = c.to_ascii_lowercase();
            let d = edit_distance(&w, &l);
            let d = if w.starts_with(&l) && l.len() >= 2 {
                d.min(3)
            } else {
                d
            };
            (d, *c)
        })
        .filter(|(d, _)| *d <= 3)
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

/// Levenshtein distance in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != *cb);
            cur[j + 1] = sub.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances() {
        assert_eq!(edit_distance("s2_mm", "s2mm"), 1);
        assert_eq!(edit_distance("theta1_deg", "theta1_deg"), 0);
        assert_eq!(edit_distance("", "abc"), 3);
        let c = ["label", "s2mm"];
        assert_eq!(closest("s2_mm", c.iter()), Some("s2mm"));
        let c = ["theta1"];
        assert_eq!(closest("theta1_deg", c.iter()), Some("theta1"));
        let c = ["label"];
        assert_eq!(closest("s1_mm", c.iter()), None);
    }

    #[test]
    fn lines_skip_blank_lines() {
        let data = b"h\r\n\r\n30\r\n\n40\n";
        let mut l = LineCounter::new(data);
        assert_eq!(l.line_at(0), 1);
        assert_eq!(l.line_at(3), 3);
        assert_eq!(l.line_at(9), 5);
    }

    #[test]
    fn tube_columns() {
        assert_eq!(tube_of_column("s3_mm"), Some(3));
        assert_eq!(tube_of_column("theta12_deg"), Some(12));
        assert_eq!(tube_of_column("s_mm"), None);
        assert_eq!(tube_of_column("sx_mm"), None);
    }
}

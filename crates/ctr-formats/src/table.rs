//! The reading machinery the numeric CSV inputs share (the joint file, the IK target
//! file): header checks, located errors, numeric cells, and the raw fields of every row
//! for carrying through.
//!
//! The file's bytes are kept as read and rows point into them: the records are found by
//! [`Records`] (a line without a double quote is split at its commas right here, no copy,
//! no allocation per row; a line with one is read by the csv crate and its fields are
//! kept as a record). Both give exactly what the csv crate's reader gives (default
//! settings, flexible rows). A UTF-8 byte-order mark at the start (what spreadsheets
//! write for "CSV UTF-8") is skipped, as the csv crate does.
//!
//! The steps, each its own function, are shared with the streamed reader (`stream`):
//! [`Header::read`] checks the header, [`RowTexts::collect`] finds the records of the
//! rows in order, [`parse_rows`] turns their cells into checked numbers.

use crate::columnar::{is_number_column, Column, Values};
use crate::error::{Error, ErrorKind, Location};
use crate::records::{not_text_error, plain, Record, Records};
use std::ops::Range;

/// Which columns a table needs.
pub(crate) struct Columns<'a> {
    /// Required numeric columns, in the order their values are stored.
    pub required: &'a [String],
    /// A group of numeric columns that are all present or all absent (their values
    /// follow the required ones), and what the group is, for messages.
    pub optional: Option<(&'a [String], &'a str)>,
}

impl Columns<'_> {
    /// All the columns, for messages: `a,b (and optionally c,d)`.
    fn all(&self) -> String {
        let mut s = self.required.join(",");
        if let Some((group, _)) = self.optional {
            s += &format!(" (and optionally {})", group.join(","));
        }
        s
    }

    /// True when `name` is one of the columns.
    fn knows(&self, name: &str) -> bool {
        self.required.iter().any(|r| r == name)
            || self
                .optional
                .is_some_and(|(g, _)| g.iter().any(|r| r == name))
    }
}

/// Where a row's fields are.
#[derive(Clone, Copy, Debug)]
struct RowSpan {
    /// `data[start..end]` holds the line (no quotes), or `start == QUOTED` and `end`
    /// indexes `quoted`
    start: usize,
    end: usize,
    /// 1-based line where the row starts
    line: usize,
}

const QUOTED: usize = usize::MAX;

/// Rows per chunk of the parallel number parsing.
const PARSE_CHUNK_ROWS: usize = 4096;

/// The accessors every table of rows read through [`Table`] has (its `table` field):
/// the file name, the header, row count, a row's line and fields. One definition for
/// [`JointTable`](crate::JointTable) and [`TargetTable`](crate::TargetTable).
macro_rules! table_rows {
    () => {
        /// The file name used in errors.
        pub fn file(&self) -> &str {
            &self.table.file
        }

        /// The header as found (untrimmed).
        pub fn header(&self) -> &[String] {
            &self.table.header.names
        }

        /// Number of data rows.
        pub fn len(&self) -> usize {
            self.table.len()
        }

        /// True when the file has a header only.
        pub fn is_empty(&self) -> bool {
            self.table.len() == 0
        }

        /// The 1-based file line where data row `row` (0-based) starts.
        pub fn line(&self, row: usize) -> usize {
            self.table.line(row)
        }

        /// The raw fields of data row `row`, all columns in header order.
        pub fn fields(&self, row: usize) -> impl Iterator<Item = &str> {
            self.table.fields(row)
        }
    };
}
pub(crate) use table_rows;

/// A checked header: the names as found and where the numeric columns are.
#[derive(Clone, Debug)]
pub(crate) struct Header {
    /// The names as found (untrimmed).
    pub names: Vec<String>,
    /// Where the header is: its line (a CSV file's), or the file (a Parquet file's).
    pub location: Location,
    /// The field index of each stored value (required, then the optional group).
    pub index: Vec<usize>,
    /// The column name of each stored value.
    pub value_names: Vec<String>,
    /// Whether the optional group is present.
    pub has_optional: bool,
}

impl Header {
    /// Reads the first record of `records` as the header and checks it: no duplicate
    /// names, `header_check` on each trimmed name (after the duplicate check), every
    /// required column present, the optional group whole or absent.
    pub fn read(
        records: &mut Records<'_>,
        columns: &Columns<'_>,
        header_check: impl Fn(&str) -> Result<(), ErrorKind>,
    ) -> Result<Header, Error> {
        let file = records.file;
        if let Some(e) = not_text_error(file, &records.data[records.pos..]) {
            return Err(e);
        }
        let Some((first, line)) = records.next()? else {
            return Err(Error::new(
                Location::file(file),
                ErrorKind::EmptyFile {
                    expected: columns.all(),
                },
            ));
        };
        let names: Vec<String> = match &first {
            Record::Plain(a, b) => plain(records.data, *a, *b)
                .split(',')
                .map(str::to_owned)
                .collect(),
            Record::Quoted(r) => r.iter().map(str::to_owned).collect(),
        };
        Header::check(names, Location::line(file, line), columns, header_check)
    }

    /// Checks the header `names` found at `location` (see [`Header::read`]).
    pub fn check(
        names: Vec<String>,
        location: Location,
        columns: &Columns<'_>,
        header_check: impl Fn(&str) -> Result<(), ErrorKind>,
    ) -> Result<Header, Error> {
        let at = |kind: ErrorKind| Error::new(location.clone(), kind);
        let trimmed: Vec<&str> = names.iter().map(|h| h.trim()).collect();
        for (i, name) in trimmed.iter().enumerate() {
            if trimmed[..i].contains(name) {
                let name = (*name).to_owned();
                return Err(at(ErrorKind::DuplicateColumn { name }));
            }
            header_check(name).map_err(at)?;
        }
        let missing = |want: &String, needs: String| {
            let unknown = trimmed.iter().filter(|h| !columns.knows(h));
            at(ErrorKind::MissingColumn {
                name: want.clone(),
                similar: closest(want, unknown).map(str::to_owned),
                required: needs,
            })
        };
        let mut index = Vec::with_capacity(columns.required.len() + 4);
        for want in columns.required {
            match trimmed.iter().position(|h| h == want) {
                Some(i) => index.push(i),
                None => return Err(missing(want, columns.all())),
            }
        }
        let mut value_names = columns.required.to_vec();
        let mut has_optional = false;
        if let Some((group, what)) = columns.optional {
            let found: Vec<Option<usize>> = group
                .iter()
                .map(|want| trimmed.iter().position(|h| h == want))
                .collect();
            if found.iter().any(Option::is_some) {
                if let Some(k) = found.iter().position(Option::is_none) {
                    let needs = format!("all of {} for {what}, or none", group.join(","));
                    return Err(missing(&group[k], needs));
                }
                index.extend(found.into_iter().flatten());
                value_names.extend_from_slice(group);
                has_optional = true;
            }
        }
        Ok(Header {
            names,
            location,
            index,
            value_names,
            has_optional,
        })
    }

    /// Numeric values per row.
    pub fn width(&self) -> usize {
        self.index.len()
    }

    /// The header's line (1 for a file without lines).
    pub fn line(&self) -> usize {
        self.location.line.unwrap_or(1)
    }
}

/// The records of rows found in order: where each row's text is (in the bytes walked)
/// and the quoted ones read.
#[derive(Clone, Debug, Default)]
pub(crate) struct RowTexts {
    rows: Vec<RowSpan>,
    quoted: Vec<csv::StringRecord>,
}

impl RowTexts {
    /// The records of `records` up to its end, or up to a CSV error (returned beside
    /// the rows before it, whose own errors come first). `expect` rows are room made
    /// in advance.
    pub fn collect(records: &mut Records<'_>, expect: usize) -> (RowTexts, Option<Error>) {
        let mut texts = RowTexts {
            rows: Vec::with_capacity(expect),
            quoted: Vec::new(),
        };
        let error = loop {
            match records.next() {
                Ok(Some((Record::Plain(start, end), line))) => {
                    texts.rows.push(RowSpan { start, end, line })
                }
                Ok(Some((Record::Quoted(r), line))) => {
                    texts.rows.push(RowSpan {
                        start: QUOTED,
                        end: texts.quoted.len(),
                        line,
                    });
                    texts.quoted.push(r);
                }
                Ok(None) => break None,
                Err(e) => break Some(e),
            }
        };
        (texts, error)
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// The 1-based line where row `r` starts.
    pub fn line(&self, r: usize) -> usize {
        self.rows[r].line
    }

    /// Row `r`'s text (in `data`, the bytes walked), and each cell's byte range in it
    /// in `cells`.
    pub fn row_text<'a>(
        &'a self,
        data: &'a [u8],
        r: usize,
        cells: &mut Vec<(usize, usize)>,
    ) -> &'a str {
        cells.clear();
        let s = self.rows[r];
        if s.start == QUOTED {
            let rec = &self.quoted[s.end];
            cells.extend(
                (0..rec.len())
                    .filter_map(|i| rec.range(i))
                    .map(|g| (g.start, g.end)),
            );
            rec.as_slice()
        } else {
            let text = plain(data, s.start, s.end);
            let mut from = 0;
            for comma in memchr::memchr_iter(b',', text.as_bytes()) {
                cells.push((from, comma));
                from = comma + 1;
            }
            cells.push((from, text.len()));
            text
        }
    }

    /// Row `r`'s fields (in `data`, the bytes walked).
    pub fn fields<'a>(&'a self, data: &'a [u8], r: usize) -> Fields<'a> {
        let s = self.rows[r];
        if s.start == QUOTED {
            Fields::Quoted(self.quoted[s.end].iter())
        } else {
            Fields::Plain(plain(data, s.start, s.end).split(','))
        }
    }

    /// Row `r` as CSV text ready to write: for a row read without quotes, its line
    /// as it was (what writing its fields with the csv crate's quoting gives, since
    /// none needs quotes); `None` for a row that had quotes.
    pub fn plain_line<'a>(&self, data: &'a [u8], r: usize) -> Option<&'a str> {
        let s = self.rows[r];
        (s.start != QUOTED).then(|| plain(data, s.start, s.end))
    }
}

/// Parses the rows `range` of `texts` (in `data`): every row has the header's
/// `fields` fields, its numeric cells are finite numbers, and `row_check` accepts them
/// (with the row's line); their values are appended to `out`, row after row. Stops at
/// the first error. `scratch` is room for a row's cells and values.
pub(crate) fn parse_rows(
    texts: &RowTexts,
    data: &[u8],
    range: Range<usize>,
    header: &Header,
    file: &str,
    row_check: &(impl Fn(&[f64], usize) -> Result<(), Error> + Sync),
    scratch: &mut (Vec<(usize, usize)>, Vec<f64>),
    out: &mut Vec<f64>,
) -> Result<(), Error> {
    let (cells, row) = scratch;
    let n_fields = header.names.len();
    for r in range {
        let line = texts.line(r);
        let at = |kind: ErrorKind| Error::new(Location::line(file, line), kind);
        let text = texts.row_text(data, r, cells);
        if cells.len() != n_fields {
            return Err(at(ErrorKind::RaggedRow {
                found: cells.len(),
                expected: n_fields,
            }));
        }
        row.clear();
        for (k, &i) in header.index.iter().enumerate() {
            let cell = &text[cells[i].0..cells[i].1];
            let column = || header.value_names[k].clone();
            let value: f64 = cell.trim().parse().map_err(|_| {
                at(ErrorKind::NotANumber {
                    column: column(),
                    found: cell.to_owned(),
                })
            })?;
            if !value.is_finite() {
                return Err(at(ErrorKind::NotFinite {
                    column: column(),
                    found: cell.to_owned(),
                }));
            }
            row.push(value);
        }
        row_check(row, line)?;
        out.extend_from_slice(row);
    }
    Ok(())
}

/// The rows of `texts` (in `data`, with the numeric `values` read from them) as columns
/// of a Parquet output, one per header column: the numeric columns read (doubles), the
/// other columns the formats contract fills with numbers ([`is_number_column`]) as
/// doubles (an empty cell a null, anything but a number refused with its line), every
/// other column as text.
pub(crate) fn csv_columns(
    texts: &RowTexts,
    data: &[u8],
    header: &Header,
    values: &[f64],
    file: &str,
) -> Result<Vec<Column>, Error> {
    let n = texts.len();
    let width = header.width();
    let mut out: Vec<Column> = header
        .names
        .iter()
        .enumerate()
        .map(
            |(i, name)| match header.index.iter().position(|&j| j == i) {
                Some(k) => Column::doubles((0..n).map(|r| values[r * width + k]).collect()),
                None if is_number_column(name.trim()) => Column {
                    values: Values::F64(Vec::with_capacity(n)),
                    valid: Some(Vec::with_capacity(n)),
                },
                None => Column {
                    values: Values::Bytes(Vec::with_capacity(n)),
                    valid: None,
                },
            },
        )
        .collect();
    for r in 0..n {
        for ((i, cell), column) in texts.fields(data, r).enumerate().zip(&mut out) {
            match (&mut column.values, &mut column.valid) {
                (Values::F64(v), Some(valid)) => {
                    let number = number_cell(cell).map_err(|()| {
                        Error::new(
                            Location::line(file, texts.line(r)),
                            ErrorKind::NotANumber {
                                column: header.names[i].trim().to_owned(),
                                found: cell.to_owned(),
                            },
                        )
                    })?;
                    v.push(number.unwrap_or_default());
                    valid.push(number.is_some());
                }
                (Values::Bytes(v), _) => v.push(cell.into()),
                _ => {}
            }
        }
    }
    Ok(out)
}

/// A cell of a column of numbers: a number, `None` when empty, `Err` otherwise.
fn number_cell(cell: &str) -> Result<Option<f64>, ()> {
    let t = cell.trim();
    if t.is_empty() {
        return Ok(None);
    }
    t.parse().map(Some).map_err(|_| ())
}

/// The fields of one row.
pub(crate) enum Fields<'a> {
    Plain(std::str::Split<'a, char>),
    Quoted(csv::StringRecordIter<'a>),
}

impl<'a> Iterator for Fields<'a> {
    type Item = &'a str;
    fn next(&mut self) -> Option<&'a str> {
        match self {
            Fields::Plain(s) => s.next(),
            Fields::Quoted(r) => r.next(),
        }
    }
}

/// A CSV file read and checked: header, raw fields and numeric values of every row.
#[derive(Clone, Debug)]
pub(crate) struct Table {
    pub file: String,
    pub header: Header,
    data: Vec<u8>,
    texts: RowTexts,
    pub values: Vec<f64>,
}

impl Table {
    /// Reads `data` (a whole CSV file; `file` names it in errors). `header_check` sees
    /// each trimmed header name in turn (after the duplicate check) and may refuse it;
    /// `row_check` sees each row's values (in stored order) with the row's line. The
    /// records are found in order; fields and numbers are checked on `threads` threads
    /// (0 = all cores), and the error reported is always the first in the file.
    pub fn read(
        data: Vec<u8>,
        file: &str,
        columns: &Columns<'_>,
        header_check: impl Fn(&str) -> Result<(), ErrorKind>,
        row_check: impl Fn(&[f64], usize) -> Result<(), Error> + Sync,
        threads: usize,
    ) -> Result<Table, Error> {
        let mut records = Records::new(&data, file);
        let header = Header::read(&mut records, columns, header_check)?;
        // a guess from the header line's length, to avoid most regrowing
        let rows_guess = data.len() / (memchr::memchr(b'\n', &data).unwrap_or(64) + 1);
        // in order: where every record is (a CSV error ends the walk; the rows before
        // it are still checked, as an error there comes first)
        let (texts, syntax_error) = RowTexts::collect(&mut records, rows_guess);
        let values = parse_in_parallel(&texts, &data, &header, file, &row_check, threads)?;
        if let Some(e) = syntax_error {
            return Err(e);
        }
        Ok(Table {
            file: file.to_owned(),
            header,
            data,
            texts,
            values,
        })
    }

    pub fn len(&self) -> usize {
        self.texts.len()
    }

    pub fn line(&self, row: usize) -> usize {
        self.texts.line(row)
    }

    pub fn fields(&self, row: usize) -> Fields<'_> {
        self.texts.fields(&self.data, row)
    }

    /// The rows as columns of a Parquet output (see [`csv_columns`]).
    pub fn columns(&self) -> Result<Vec<Column>, Error> {
        csv_columns(
            &self.texts,
            &self.data,
            &self.header,
            &self.values,
            &self.file,
        )
    }

    /// Row `row` as CSV text ready to write (see [`RowTexts::plain_line`]).
    pub fn plain_line(&self, row: usize) -> Option<&str> {
        self.texts.plain_line(&self.data, row)
    }

    pub fn values(&self, row: usize) -> &[f64] {
        let width = self.header.width();
        &self.values[row * width..(row + 1) * width]
    }
}

/// The values of every row of `texts`, parsed in chunks on `threads` threads (0 = all
/// cores); the error is the first in the file.
fn parse_in_parallel(
    texts: &RowTexts,
    data: &[u8],
    header: &Header,
    file: &str,
    row_check: &(impl Fn(&[f64], usize) -> Result<(), Error> + Sync),
    threads: usize,
) -> Result<Vec<f64>, Error> {
    let width = header.width();
    let mut values = Vec::with_capacity(texts.len() * width);
    let mut first_error = None;
    crate::parallel::for_each_chunk(
        texts.len(),
        PARSE_CHUNK_ROWS,
        threads,
        &(),
        || {
            (
                Vec::with_capacity(header.names.len()),
                Vec::with_capacity(width),
            )
        },
        |scratch, range| {
            let mut out = Vec::with_capacity(range.len() * width);
            parse_rows(
                texts, data, range, header, file, row_check, scratch, &mut out,
            )
            .map(|()| out)
        },
        |_, chunk| match chunk {
            Ok(v) => {
                values.extend_from_slice(&v);
                true
            }
            Err(e) => {
                first_error = Some(e);
                false
            }
        },
    );
    match first_error {
        Some(e) => Err(e),
        None => Ok(values),
    }
}

/// Reads all of `reader`; `file` names it in errors.
pub(crate) fn read_all(mut reader: impl std::io::Read, file: &str) -> Result<Vec<u8>, Error> {
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
    Ok(data)
}

/// Reads a whole file; errors name the path as given.
pub(crate) fn read_path(path: &std::path::Path) -> Result<(String, Vec<u8>), Error> {
    let file = path.display().to_string();
    match std::fs::read(path) {
        Ok(data) => Ok((file, data)),
        Err(source) => Err(Error::new(
            Location::file(&file),
            ErrorKind::Io {
                action: "read",
                source,
            },
        )),
    }
}

/// The candidate most like `want` (case-insensitive edit distance at most 3, or a
/// prefix of it), if any.
pub(crate) fn closest<'a>(
    want: &str,
    candidates: impl Iterator<Item = &'a &'a str>,
) -> Option<&'a str> {
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
    fn fields_are_kept_per_row() {
        let required = ["a".to_owned()];
        let cols = Columns {
            required: &required,
            optional: None,
        };
        let t = Table::read(
            b"a,b\n1,\"x,y\"\n\n2,\r\n\r3,z".to_vec(),
            "t.csv",
            &cols,
            |_| Ok(()),
            |_, _| Ok(()),
            2,
        )
        .unwrap();
        assert_eq!(t.len(), 3);
        assert_eq!(t.fields(0).collect::<Vec<_>>(), ["1", "x,y"]);
        assert_eq!(t.fields(1).collect::<Vec<_>>(), ["2", ""]);
        assert_eq!(t.fields(2).collect::<Vec<_>>(), ["3", "z"]);
        assert_eq!(t.values, [1.0, 2.0, 3.0]);
        assert_eq!((t.line(0), t.line(1), t.line(2)), (2, 4, 5));
    }
}

//! The reading machinery the numeric CSV inputs share (the joint file, the IK target
//! file): header checks, located errors, numeric cells, and the raw fields of every row
//! for carrying through.
//!
//! The file's bytes are kept as read and rows point into them: a line without a double
//! quote is split at its commas right here (no copy, no allocation per row); a line
//! with one is read by the csv crate, which handles quoting, and its fields are kept as
//! a record. Both give exactly what the csv crate's reader gives (default settings,
//! flexible rows): `\n`, `\r\n` and `\r` end records, empty lines are skipped, and
//! quoted fields may hold commas, quotes and line breaks. A UTF-8 byte-order mark at the
//! start (what spreadsheets write for "CSV UTF-8") is skipped, as the csv crate does.

use crate::error::{Error, ErrorKind, Location};

/// Which columns a table needs.
pub(crate) struct Columns<'a> {
    /// Required numeric columns, in the order their values are stored.
    pub required: &'a [String],
    /// A group of numeric columns that are all present or all absent (their values
    /// follow the required ones), and what the group is, for messages.
    pub optional: Option<(&'a [String], &'a str)>,
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

/// The UTF-8 encoding of U+FEFF, the byte-order mark spreadsheets and Windows editors
/// put before the first byte of a "UTF-8" file.
pub(crate) const UTF8_BOM: &[u8] = b"\xEF\xBB\xBF";

/// How many bytes of `data` a leading byte-order mark takes (0 or 3).
pub(crate) fn bom_len(data: &[u8]) -> usize {
    if data.starts_with(UTF8_BOM) {
        UTF8_BOM.len()
    } else {
        0
    }
}

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
            &self.table.header
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

/// A CSV file read and checked: header, raw fields and numeric values of every row.
#[derive(Clone, Debug)]
pub(crate) struct Table {
    pub file: String,
    pub header: Vec<String>,
    /// 1-based line of the header
    pub header_line: usize,
    /// numeric values per row (required, then the optional group if present)
    pub width: usize,
    /// whether the optional group is present
    pub has_optional: bool,
    data: Vec<u8>,
    rows: Vec<RowSpan>,
    quoted: Vec<csv::StringRecord>,
    pub values: Vec<f64>,
}

/// One record found by [`Records`].
enum Record {
    /// `data[start..end]`, valid UTF-8 without quotes
    Plain(usize, usize),
    Quoted(csv::StringRecord),
}

/// Walks the records of a CSV file.
struct Records<'a> {
    data: &'a [u8],
    file: &'a str,
    pos: usize,
    /// line of `pos`
    line: usize,
}

impl Records<'_> {
    /// The next record and the line it starts on.
    fn next(&mut self) -> Result<Option<(Record, usize)>, Error> {
        let data = self.data;
        while self.pos < data.len() && matches!(data[self.pos], b'\n' | b'\r') {
            self.line += usize::from(data[self.pos] == b'\n');
            self.pos += 1;
        }
        if self.pos >= data.len() {
            return Ok(None);
        }
        let start = self.pos;
        let line = self.line;
        let end = memchr::memchr2(b'\n', b'\r', &data[start..]).map_or(data.len(), |k| start + k);
        let text = &data[start..end];
        if memchr::memchr(b'"', text).is_some() {
            // quoting (maybe over several lines): the csv crate reads this record
            // a reader strips a byte order mark that opens its input, as the csv crate
            // does at the start of a file only: a record after the first that opens
            // with one gets a plain byte before it, taken off its first field again
            let guard = usize::from(start > 0 && data[start..].starts_with(UTF8_BOM));
            let input = std::io::Read::chain(&b"_"[..guard], &data[start..]);
            let mut rdr = csv::ReaderBuilder::new()
                .has_headers(false)
                .flexible(true)
                .from_reader(input);
            let mut record = csv::StringRecord::new();
            if let Err(e) = rdr.read_record(&mut record) {
                let at = e
                    .position()
                    .map_or(0, |p| p.byte() as usize)
                    .saturating_sub(guard);
                let line = line + count_newlines(&data[start..(start + at).min(data.len())]);
                return Err(csv_error(e, self.file, line));
            }
            if guard == 1 {
                let mut fields = record.iter();
                let first = fields.next().unwrap_or_default();
                let mut kept = csv::StringRecord::new();
                kept.push_field(first.strip_prefix('_').unwrap_or(first));
                fields.for_each(|f| kept.push_field(f));
                record = kept;
            }
            let consumed = (rdr.position().byte() as usize)
                .saturating_sub(guard)
                .max(1);
            let stop = (start + consumed).min(data.len());
            self.line += count_newlines(&data[start..stop]);
            self.pos = stop;
            return Ok(Some((Record::Quoted(record), line)));
        }
        if let Err(e) = std::str::from_utf8(text) {
            let field = 1 + memchr::memchr_iter(b',', &text[..e.valid_up_to()]).count();
            return Err(Error::new(
                Location::line(self.file, line),
                ErrorKind::Csv {
                    message: format!("field {field}: not valid UTF-8 text"),
                },
            ));
        }
        self.pos = end;
        Ok(Some((Record::Plain(start, end), line)))
    }
}

fn count_newlines(bytes: &[u8]) -> usize {
    memchr::memchr_iter(b'\n', bytes).count()
}

fn csv_error(e: csv::Error, file: &str, line: usize) -> Error {
    let kind = match e.into_kind() {
        csv::ErrorKind::Io(source) => ErrorKind::Io {
            action: "read",
            source,
        },
        csv::ErrorKind::Utf8 { err, .. } => ErrorKind::Csv {
            message: format!("field {}: not valid UTF-8 text", err.field() + 1),
        },
        other => ErrorKind::Csv {
            message: super::toml_doc::one_line(&format!("{other:?}")),
        },
    };
    Error::new(Location::line(file, line), kind)
}

/// The text of `data[start..end]`, checked to be UTF-8 by [`Records`].
fn plain(data: &[u8], start: usize, end: usize) -> &str {
    std::str::from_utf8(&data[start..end]).unwrap_or_default()
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
        let required = columns.required;
        let at = |line: usize, kind: ErrorKind| Error::new(Location::line(file, line), kind);
        let all_columns = || {
            let mut s = required.join(",");
            if let Some((group, _)) = columns.optional {
                s += &format!(" (and optionally {})", group.join(","));
            }
            s
        };
        let mut records = Records {
            data: &data,
            file,
            pos: bom_len(&data),
            line: 1,
        };
        let Some((first, header_line)) = records.next()? else {
            return Err(Error::new(
                Location::file(file),
                ErrorKind::EmptyFile {
                    expected: all_columns(),
                },
            ));
        };
        let header: Vec<String> = match &first {
            Record::Plain(a, b) => plain(&data, *a, *b).split(',').map(str::to_owned).collect(),
            Record::Quoted(r) => r.iter().map(str::to_owned).collect(),
        };
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
            header_check(name).map_err(|kind| at(header_line, kind))?;
        }
        let known = |h: &str| {
            required.iter().any(|r| r == h)
                || columns
                    .optional
                    .is_some_and(|(g, _)| g.iter().any(|r| r == h))
        };
        let missing = |want: &String, needs: String| {
            let unknown = names.iter().filter(|h| !known(h));
            at(
                header_line,
                ErrorKind::MissingColumn {
                    name: want.clone(),
                    similar: closest(want, unknown).map(str::to_owned),
                    required: needs,
                },
            )
        };
        let mut index = Vec::with_capacity(required.len() + 4);
        for want in required {
            match names.iter().position(|h| h == want) {
                Some(i) => index.push(i),
                None => return Err(missing(want, all_columns())),
            }
        }
        let mut has_optional = false;
        if let Some((group, what)) = columns.optional {
            let found: Vec<Option<usize>> = group
                .iter()
                .map(|want| names.iter().position(|h| h == want))
                .collect();
            if found.iter().any(Option::is_some) {
                if let Some(k) = found.iter().position(Option::is_none) {
                    return Err(missing(
                        &group[k],
                        format!("all of {} for {what}, or none", group.join(",")),
                    ));
                }
                index.extend(found.into_iter().flatten());
                has_optional = true;
            }
        }
        let names_of: Vec<&String> = required
            .iter()
            .chain(
                columns
                    .optional
                    .filter(|_| has_optional)
                    .map_or(&[][..], |(g, _)| g),
            )
            .collect();

        let width = index.len();
        let n_fields = header.len();
        // a guess from the header line's length, to avoid most regrowing
        let rows_guess = data.len() / (memchr::memchr(b'\n', &data).unwrap_or(64) + 1);
        // pass 1, in order: where every record is (a CSV error ends the pass; the rows
        // before it are still checked, as an error there comes first)
        let mut rows = Vec::with_capacity(rows_guess);
        let mut quoted = Vec::new();
        let syntax_error = loop {
            match records.next() {
                Ok(Some((Record::Plain(start, end), line))) => {
                    rows.push(RowSpan { start, end, line })
                }
                Ok(Some((Record::Quoted(r), line))) => {
                    rows.push(RowSpan {
                        start: QUOTED,
                        end: quoted.len(),
                        line,
                    });
                    quoted.push(r);
                }
                Ok(None) => break None,
                Err(e) => break Some(e),
            }
        };
        let mut table = Table {
            file: file.to_owned(),
            header,
            header_line,
            width,
            has_optional,
            data,
            rows,
            quoted,
            values: Vec::new(),
        };
        // pass 2, in parallel chunks: fields, numbers, row checks
        let mut values = Vec::with_capacity(table.rows.len() * width);
        let mut first_error = None;
        let t = &table;
        crate::parallel::for_each_chunk(
            t.rows.len(),
            PARSE_CHUNK_ROWS,
            threads,
            &(),
            || (Vec::with_capacity(n_fields), Vec::with_capacity(width)),
            |(cells, row): &mut (Vec<(usize, usize)>, Vec<f64>), range| {
                let mut out = Vec::with_capacity(range.len() * width);
                for r in range {
                    let line = t.rows[r].line;
                    let text = t.row_text(r, cells);
                    if cells.len() != n_fields {
                        return Err(at(
                            line,
                            ErrorKind::RaggedRow {
                                found: cells.len(),
                                expected: n_fields,
                            },
                        ));
                    }
                    row.clear();
                    for (k, &i) in index.iter().enumerate() {
                        let cell = &text[cells[i].0..cells[i].1];
                        let value: f64 = cell.trim().parse().map_err(|_| {
                            at(
                                line,
                                ErrorKind::NotANumber {
                                    column: names_of[k].clone(),
                                    found: cell.to_owned(),
                                },
                            )
                        })?;
                        if !value.is_finite() {
                            return Err(at(
                                line,
                                ErrorKind::NotFinite {
                                    column: names_of[k].clone(),
                                    found: cell.to_owned(),
                                },
                            ));
                        }
                        row.push(value);
                    }
                    row_check(row, line)?;
                    out.extend_from_slice(row);
                }
                Ok(out)
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
        if let Some(e) = first_error.or(syntax_error) {
            return Err(e);
        }
        table.values = values;
        Ok(table)
    }

    /// Row `r`'s text, and each cell's byte range in it in `cells`.
    fn row_text<'a>(&'a self, r: usize, cells: &mut Vec<(usize, usize)>) -> &'a str {
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
            let text = plain(&self.data, s.start, s.end);
            let mut from = 0;
            for comma in memchr::memchr_iter(b',', text.as_bytes()) {
                cells.push((from, comma));
                from = comma + 1;
            }
            cells.push((from, text.len()));
            text
        }
    }

    pub fn len(&self) -> usize {
        self.rows.len()
    }

    pub fn line(&self, row: usize) -> usize {
        self.rows[row].line
    }

    pub fn fields(&self, row: usize) -> Fields<'_> {
        let s = self.rows[row];
        if s.start == QUOTED {
            Fields::Quoted(self.quoted[s.end].iter())
        } else {
            Fields::Plain(plain(&self.data, s.start, s.end).split(','))
        }
    }

    /// Row `row` as CSV text ready to write: for a row read without quotes, its line
    /// as it was (what writing its fields with the csv crate's quoting gives, since
    /// none needs quotes); `None` for a row that had quotes.
    pub fn plain_line(&self, row: usize) -> Option<&str> {
        let s = self.rows[row];
        (s.start != QUOTED).then(|| plain(&self.data, s.start, s.end))
    }

    pub fn values(&self, row: usize) -> &[f64] {
        &self.values[row * self.width..(row + 1) * self.width]
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

    /// The same records, fields and errors as the csv crate's reader.
    #[test]
    fn records_are_the_csv_crates() {
        let cases: &[&[u8]] = &[
            b"a,b\n1,2\n",
            b"a,b\r\n1,2\r\n\r\n3,4",
            b"a,b\r1,2\r3,4\n",
            b"a,\"b\nc\",d\n1,\"2\"\"x\",3\n\n\"q\"r,s,t\n",
            b"a,b\n\"unterminated,1\n2,3\n",
            b"  a , b \n 1,2 \n,\n",
            b"a,b\n\xff,1\n",
            b"a,b\n1,\"\xff\"\n",
            b"x\n\n\n\"\"\n \n",
        ];
        for data in cases {
            let mut ours = Vec::new();
            let mut r = Records {
                data,
                file: "f",
                pos: 0,
                line: 1,
            };
            let ours_err = loop {
                match r.next() {
                    Ok(Some((Record::Plain(a, b), _))) => ours.push(
                        plain(data, a, b)
                            .split(',')
                            .map(str::to_owned)
                            .collect::<Vec<_>>(),
                    ),
                    Ok(Some((Record::Quoted(rec), _))) => {
                        ours.push(rec.iter().map(str::to_owned).collect())
                    }
                    Ok(None) => break None,
                    Err(e) => break Some(e.to_string()),
                }
            };
            let mut theirs = Vec::new();
            let mut rdr = csv::ReaderBuilder::new()
                .has_headers(false)
                .flexible(true)
                .from_reader(*data);
            let mut theirs_err = None;
            for rec in rdr.records() {
                match rec {
                    Ok(rec) => theirs.push(rec.iter().map(str::to_owned).collect::<Vec<_>>()),
                    Err(e) => {
                        theirs_err = Some(e);
                        break;
                    }
                }
            }
            assert_eq!(ours, theirs, "{:?}", String::from_utf8_lossy(data));
            assert_eq!(ours_err.is_some(), theirs_err.is_some(), "{ours_err:?}");
        }
    }
}

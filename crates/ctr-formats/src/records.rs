//! The records of a CSV file, found exactly as the csv crate's reader finds them
//! (default settings, flexible rows): `\n`, `\r\n` and `\r` end records, empty lines are
//! skipped, and quoted fields may hold commas, quotes and line breaks.
//!
//! A line without a double quote is a record as it is (no copy); a line with one is
//! read by the csv crate, from there on, and kept as a `StringRecord`. The walker works
//! on a whole file or on a part of it that starts at a record (the streamed reader's
//! blocks, `stream`), with the lines counted from where the part starts.

use crate::error::{Error, ErrorKind, Location};

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

/// One record found by [`Records`].
pub(crate) enum Record {
    /// `data[start..end]`, valid UTF-8 without quotes
    Plain(usize, usize),
    Quoted(csv::StringRecord),
}

/// Walks the records of CSV bytes.
pub(crate) struct Records<'a> {
    pub data: &'a [u8],
    pub file: &'a str,
    pub pos: usize,
    /// line of `pos`
    pub line: usize,
    /// where the file starts in `data` (`usize::MAX`: before it, a later block)
    pub file_start: usize,
}

impl<'a> Records<'a> {
    /// A walker over a whole file's bytes, after its byte-order mark.
    pub fn new(data: &'a [u8], file: &'a str) -> Self {
        Records {
            data,
            file,
            pos: bom_len(data),
            line: 1,
            file_start: 0,
        }
    }

    /// Skips the line ends at `pos` (counting lines), and returns whether a record
    /// follows.
    fn skip_line_ends(&mut self) -> bool {
        let data = self.data;
        while self.pos < data.len() && matches!(data[self.pos], b'\n' | b'\r') {
            self.line += usize::from(data[self.pos] == b'\n');
            self.pos += 1;
        }
        self.pos < data.len()
    }

    /// The next record and the line it starts on.
    pub fn next(&mut self) -> Result<Option<(Record, usize)>, Error> {
        if !self.skip_line_ends() {
            return Ok(None);
        }
        let data = self.data;
        let start = self.pos;
        let line = self.line;
        let end = memchr::memchr2(b'\n', b'\r', &data[start..]).map_or(data.len(), |k| start + k);
        let text = &data[start..end];
        if memchr::memchr(b'"', text).is_some() {
            return self
                .quoted(start, line)
                .map(|r| Some((Record::Quoted(r), line)));
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

    /// The record at `start` (on `line`), which has a quote: the csv crate reads it
    /// (maybe over several lines).
    fn quoted(&mut self, start: usize, line: usize) -> Result<csv::StringRecord, Error> {
        let data = self.data;
        // a reader strips a byte order mark that opens its input, as the csv crate
        // does at the start of a file only: a record after the first that opens with
        // one gets a plain byte before it, taken off its first field again
        let guard = usize::from(start != self.file_start && data[start..].starts_with(UTF8_BOM));
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
        Ok(record)
    }
}

pub(crate) fn count_newlines(bytes: &[u8]) -> usize {
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
pub(crate) fn plain(data: &[u8], start: usize, end: usize) -> &str {
    std::str::from_utf8(&data[start..end]).unwrap_or_default()
}

/// What a file that is not CSV text is, by its first bytes, and what to do with it:
/// the binary files a CSV reader otherwise refuses as "not valid UTF-8 text".
///
/// `None` for anything else (text, or too little to tell).
pub(crate) fn not_text(data: &[u8]) -> Option<&'static str> {
    const KINDS: [(&[u8], &str); 6] = [
        (
            b"PAR1",
            "a Parquet file, not CSV text: name it *.parquet to read it as Parquet",
        ),
        (
            b"\x1f\x8b",
            "a gzip-compressed file, not CSV text: decompress it (gunzip) first",
        ),
        (
            b"PK\x03\x04",
            "a zip archive (an Excel .xlsx workbook?), not CSV text: save the sheet as \"CSV UTF-8\"",
        ),
        (
            b"\xd0\xcf\x11\xe0",
            "an Excel .xls workbook, not CSV text: save the sheet as \"CSV UTF-8\"",
        ),
        (
            b"\xff\xfe",
            "UTF-16 text (\"Unicode text\" from a spreadsheet), not UTF-8: save it as \"CSV UTF-8\"",
        ),
        (
            b"\xfe\xff",
            "UTF-16 text (big-endian), not UTF-8: save it as \"CSV UTF-8\"",
        ),
    ];
    KINDS
        .iter()
        .find(|(magic, _)| data.starts_with(magic))
        .map(|(_, what)| *what)
}

/// The error for a file [`not_text`] recognises (at line 1, where its magic number is).
pub(crate) fn not_text_error(file: &str, data: &[u8]) -> Option<Error> {
    not_text(data).map(|what| {
        Error::new(
            Location::line(file, 1),
            ErrorKind::Csv {
                message: format!("this is {what}"),
            },
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
                file_start: 0,
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

    #[test]
    fn binary_files_are_named() {
        assert!(not_text(b"PAR1\x15\x04").unwrap().contains("Parquet"));
        assert!(not_text(b"\x1f\x8b\x08").unwrap().contains("gzip"));
        assert!(not_text(b"\xff\xfes\x001\x00").unwrap().contains("UTF-16"));
        assert_eq!(not_text(b"s1_mm,theta1_deg\n"), None);
        assert_eq!(not_text(b"\xEF\xBB\xBFs1_mm\n"), None);
        let e = not_text_error("j.csv", b"PK\x03\x04").unwrap();
        assert!(
            e.to_string().starts_with("j.csv:1: this is a zip archive"),
            "{e}"
        );
    }
}

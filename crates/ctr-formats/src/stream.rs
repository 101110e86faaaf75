//! A numeric CSV file read as a stream of pieces: bounded memory whatever its size, and
//! the costly work (finding fields, parsing and checking numbers) on the workers.
//!
//! The reader ([`CsvStream`], serial) reads blocks of [`BLOCK_BYTES`] and cuts them into
//! pieces of a given number of rows. Cutting only finds where records end: where no
//! double quote is near, it looks at line ends alone (a record is a maximal run of bytes
//! that are not `\n` or `\r`, as the csv crate's reader has it); from a line with a quote
//! on, it walks records as the whole-file reader does ([`Records`]). A record is taken
//! only when it is known to be complete (a line end follows it within the block, or the
//! file ends); otherwise the block is refilled with the rest of the file behind it.
//!
//! A piece ([`CsvPiece`]) keeps its block alive (shared) and is parsed where it is
//! worked on ([`CsvPiece::parse`]): the same walk, header checks and numbers as
//! [`Table`](crate::table::Table), so rows, fields, values and errors are exactly those
//! of reading the whole file at once, and the first error of the file comes first when
//! the pieces are taken in order.

use crate::columnar::Column;
use crate::error::{Error, ErrorKind, Location};
use crate::records::{bom_len, count_newlines, Records};
use crate::table::{csv_columns, parse_rows, Columns, Fields, Header, RowTexts};
use std::io::Read;
use std::ops::Range;
use std::sync::Arc;

/// Bytes read into a block at a time (a block grows only for a record longer than it).
pub const BLOCK_BYTES: usize = 1 << 20;

/// Bytes the first block holds at least: a byte-order mark, or the magic number of a
/// binary file that is not CSV ([`crate::records::not_text`]).
const MAGIC_BYTES: usize = 8;

/// A CSV file being read piece by piece.
pub(crate) struct CsvStream<R> {
    reader: R,
    file: String,
    block: Arc<Vec<u8>>,
    /// where the next piece starts in `block`
    pos: usize,
    /// line of `pos`
    line: usize,
    /// where the file starts in `block` (`usize::MAX`: a later block)
    file_start: usize,
    /// the reader is at the end of the file
    eof: bool,
    /// rows handed out so far
    rows: usize,
    /// a read failed: the stream ends with it
    failed: bool,
    /// bytes a block is read to
    block_bytes: usize,
    /// where the next double quote at or after `pos` is in `block` (its length: none;
    /// `usize::MAX`: not looked for yet)
    next_quote: usize,
}

/// Rows of a CSV file not parsed yet: whole records of a block.
#[derive(Clone, Debug)]
pub(crate) struct CsvPiece {
    block: Arc<Vec<u8>>,
    range: Range<usize>,
    first_line: usize,
    file_start: usize,
    /// records in `range` (the cutter's count; the last piece may end at an error)
    rows: usize,
}

/// A piece parsed: its rows' texts and checked values.
#[derive(Clone, Debug)]
pub(crate) struct CsvRows {
    block: Arc<Vec<u8>>,
    end: usize,
    texts: RowTexts,
    /// the numeric columns' values, row after row (taken by whoever keeps them)
    pub values: Vec<f64>,
}

impl<R: Read> CsvStream<R> {
    /// Starts reading `reader` (`file` names it in errors); nothing is read yet.
    pub fn new(reader: R, file: &str) -> Self {
        CsvStream {
            reader,
            file: file.to_owned(),
            block: Arc::new(Vec::new()),
            pos: 0,
            line: 1,
            file_start: 0,
            eof: false,
            rows: 0,
            failed: false,
            block_bytes: BLOCK_BYTES,
            next_quote: usize::MAX,
        }
    }

    /// Moves the bytes not handed out yet to the front of a fresh block and reads more
    /// behind them: at least [`BLOCK_BYTES`], and at least as many as are kept.
    fn refill(&mut self) -> Result<(), Error> {
        let kept = &self.block[self.pos.min(self.block.len())..];
        let first = self.block.is_empty() && self.rows == 0 && self.line == 1;
        // the first block holds at least the byte-order mark and a binary file's magic
        let at_least = if first { MAGIC_BYTES } else { 0 };
        let want = self.block_bytes.max(2 * kept.len()).max(at_least);
        let mut next = Vec::with_capacity(want);
        next.extend_from_slice(kept);
        if !first && self.file_start != usize::MAX {
            // the file's start was in the block left behind
            self.file_start = usize::MAX;
        }
        while next.len() < want && !self.eof {
            let room = want - next.len();
            let got = (&mut self.reader)
                .take(room as u64)
                .read_to_end(&mut next)
                .map_err(|source| {
                    Error::new(
                        Location::file(&self.file),
                        ErrorKind::Io {
                            action: "read",
                            source,
                        },
                    )
                })?;
            self.eof = got < room;
        }
        if first {
            self.pos = bom_len(&next);
            self.file_start = 0;
        } else {
            self.pos = 0;
        }
        self.block = Arc::new(next);
        self.next_quote = usize::MAX;
        Ok(())
    }

    /// About how many rows a file of `size` bytes has, from the lines of the block
    /// read so far (for progress reports).
    pub fn estimate_rows(&self, size: u64) -> usize {
        let rest = &self.block[self.pos.min(self.block.len())..];
        let lines = count_newlines(rest).max(1);
        let per_line = (rest.len() / lines).max(1) as u64;
        (size / per_line) as usize
    }

    /// Reads and checks the header (the file's first record; see [`Header::read`]).
    pub fn header(
        &mut self,
        columns: &Columns<'_>,
        header_check: impl Fn(&str) -> Result<(), ErrorKind>,
    ) -> Result<Header, Error> {
        self.refill()?;
        loop {
            let data = &self.block[..];
            // the first record must be whole: read to its end, or to the file's end
            let whole = {
                let mut probe = self.records(data);
                let result = probe.next();
                self.eof || whole_record(data, self.pos, &probe, &result)
            };
            if whole {
                let mut records = self.records(data);
                let header = Header::read(&mut records, columns, header_check)?;
                let (pos, line) = (records.pos, records.line);
                self.pos = pos;
                self.line = line;
                return Ok(header);
            }
            self.refill()?;
        }
    }

    fn records<'a>(&'a self, data: &'a [u8]) -> Records<'a> {
        Records {
            data,
            file: &self.file,
            pos: self.pos,
            line: self.line,
            file_start: self.file_start,
        }
    }

    /// The next piece of `rows` records (fewer at the end of the file), `None` after
    /// the last, or the error of a failed read.
    pub fn next_piece(&mut self, rows: usize) -> Option<Result<CsvPiece, Error>> {
        if self.failed {
            return None;
        }
        loop {
            let from = Cursor {
                pos: self.pos,
                line: self.line,
                file_start: self.file_start,
                eof: self.eof,
            };
            match cut(&self.block, from, rows, &mut self.next_quote, &self.file) {
                Cut::Piece { end, records, line } => {
                    let piece = CsvPiece {
                        block: Arc::clone(&self.block),
                        range: self.pos..end,
                        first_line: self.line,
                        file_start: self.file_start,
                        rows: records,
                    };
                    self.pos = end;
                    self.line = line;
                    self.rows += records;
                    return Some(Ok(piece));
                }
                Cut::End => return None,
                Cut::More => {
                    if let Err(e) = self.refill() {
                        self.failed = true;
                        return Some(Err(e));
                    }
                }
            }
        }
    }
}

/// What [`cut`] found.
#[derive(Debug, PartialEq, Eq)]
enum Cut {
    /// A piece of `records` records ends at `end` (before the line end after its last
    /// record), where the next starts on `line`.
    Piece {
        end: usize,
        records: usize,
        line: usize,
    },
    /// No record is left.
    End,
    /// Not enough whole records: the block needs the file's next bytes.
    More,
}

/// Where a piece starts: its position and line in the block, where the file starts
/// in the block (`usize::MAX`: before it), whether the block ends the file.
struct Cursor {
    pos: usize,
    line: usize,
    file_start: usize,
    eof: bool,
}

/// Finds where the piece of `want` records starting at `from` in `block` ends. At the
/// file's end the last piece takes the records left; a record the walk cannot read
/// (bad UTF-8) ends the last piece at the block's end, where parsing it reports the
/// error. `next_quote` caches where the next double quote is (see [`CsvStream`]).
fn cut(block: &[u8], from: Cursor, want: usize, next_quote: &mut usize, file: &str) -> Cut {
    let Cursor {
        pos,
        line,
        file_start,
        eof,
    } = from;
    let len = block.len();
    let (mut at, mut line, mut found) = (pos, line, 0);
    while found < want {
        if *next_quote == usize::MAX || *next_quote < at {
            *next_quote = memchr::memchr(b'"', &block[at..]).map_or(len, |k| at + k);
        }
        let quote = *next_quote;
        // line ends before the next quote end records as they are
        let (next, n, lines) = count_line_records(block, at, quote, want - found);
        found += n;
        line += lines;
        at = next;
        if found == want {
            break;
        }
        if quote == len {
            // the rest: at most one record, without a line end: whole at the file's end
            if !eof {
                return Cut::More;
            }
            found += usize::from(at < len);
            return if found == 0 {
                Cut::End
            } else {
                Cut::Piece {
                    end: len,
                    records: found,
                    line,
                }
            };
        }
        // the line holding the quote: walked as the whole-file reader walks it
        let mut records = Records {
            data: block,
            file,
            pos: at,
            line,
            file_start,
        };
        let result = records.next();
        if !(eof || whole_record(block, at, &records, &result)) {
            return Cut::More;
        }
        match result {
            Ok(Some(_)) => {
                found += 1;
                at = records.pos;
                line = records.line;
            }
            Ok(None) => break,
            // parsing the piece reports the error, after the rows before it
            Err(_) => {
                return Cut::Piece {
                    end: len,
                    records: found + 1,
                    line,
                }
            }
        }
    }
    if found == 0 {
        return Cut::End;
    }
    Cut::Piece {
        end: at,
        records: found,
        line,
    }
}

/// True when the record `records` just walked from `at` with `result` lies whole in
/// `block`: it ends before the block's end (a line end was read after it). A record
/// that failed to read (bad UTF-8) is measured again as bytes.
fn whole_record(
    block: &[u8],
    at: usize,
    records: &Records<'_>,
    result: &Result<Option<(crate::records::Record, usize)>, Error>,
) -> bool {
    match result {
        Ok(Some(_)) => records.pos < block.len(),
        Ok(None) => false,
        Err(_) => record_end(block, at) < block.len(),
    }
}

/// Where the record at `at` (after its leading line ends) ends in `block`: its line's
/// end, or for a line with a quote, where the csv crate's reader stops reading it as
/// bytes (without the UTF-8 check).
fn record_end(block: &[u8], at: usize) -> usize {
    let start = block[at..]
        .iter()
        .position(|b| !matches!(b, b'\n' | b'\r'))
        .map_or(block.len(), |k| at + k);
    let line_end =
        memchr::memchr2(b'\n', b'\r', &block[start..]).map_or(block.len(), |k| start + k);
    if memchr::memchr(b'"', &block[start..line_end]).is_none() {
        return line_end;
    }
    // as `Records` reads it: a byte-order mark opening the input is not stripped
    let guard = usize::from(block[start..].starts_with(crate::records::UTF8_BOM));
    let input = std::io::Read::chain(&b"_"[..guard], &block[start..]);
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(input);
    let mut record = csv::ByteRecord::new();
    let _ = rdr.read_byte_record(&mut record);
    start + (rdr.position().byte() as usize).saturating_sub(guard)
}

/// Counts the records in `block[from..until]` that end with a line end, up to `want`:
/// `(where the scan stopped, records, newlines before that)`. With `want` records the
/// scan stops at the line end after the last (which stays with the rows after it);
/// else after the last line end before `until`.
fn count_line_records(
    block: &[u8],
    from: usize,
    until: usize,
    want: usize,
) -> (usize, usize, usize) {
    let (mut records, mut newlines) = (0, 0);
    let mut run_start = from;
    for k in memchr::memchr2_iter(b'\n', b'\r', &block[from..until]) {
        let p = from + k;
        if p > run_start {
            records += 1;
            if records == want {
                return (p, records, newlines);
            }
        }
        newlines += usize::from(block[p] == b'\n');
        run_start = p + 1;
    }
    (run_start, records, newlines)
}

impl CsvPiece {
    /// Records in the piece, as the cutter counted them.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Parses the piece: its records, their fields and numbers, checked as
    /// [`Table::read`](crate::table::Table::read) checks them (`row_check` with each
    /// row's values and line). The first error of the piece is returned.
    pub fn parse(
        self,
        header: &Header,
        file: &str,
        row_check: &(impl Fn(&[f64], usize) -> Result<(), Error> + Sync),
    ) -> Result<CsvRows, Error> {
        let data = &self.block[..self.range.end];
        let mut records = Records {
            data,
            file,
            pos: self.range.start,
            line: self.first_line,
            file_start: self.file_start,
        };
        let (texts, syntax_error) = RowTexts::collect(&mut records, self.rows);
        let mut values = Vec::with_capacity(texts.len() * header.width());
        let mut scratch = (Vec::new(), Vec::new());
        let all = 0..texts.len();
        parse_rows(
            &texts,
            data,
            all,
            header,
            file,
            row_check,
            &mut scratch,
            &mut values,
        )?;
        if let Some(e) = syntax_error {
            return Err(e);
        }
        assert_eq!(
            texts.len(),
            self.rows,
            "the cutter and the walk count alike"
        );
        Ok(CsvRows {
            end: self.range.end,
            block: self.block,
            texts,
            values,
        })
    }
}

impl CsvRows {
    /// The rows as columns of a Parquet output (see [`csv_columns`]).
    pub fn columns(&self, header: &Header, file: &str) -> Result<Vec<Column>, Error> {
        csv_columns(
            &self.texts,
            &self.block[..self.end],
            header,
            &self.values,
            file,
        )
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.texts.len()
    }

    /// The 1-based line where row `r` starts.
    pub fn line(&self, r: usize) -> usize {
        self.texts.line(r)
    }

    /// Row `r`'s fields.
    pub fn fields(&self, r: usize) -> Fields<'_> {
        self.texts.fields(&self.block[..self.end], r)
    }

    /// Row `r` as CSV text ready to write, when it had no quotes (see
    /// [`RowTexts::plain_line`]).
    pub fn plain_line(&self, r: usize) -> Option<&str> {
        self.texts.plain_line(&self.block[..self.end], r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every record, its line and fields, read in pieces of `rows` from blocks of
    /// `block` bytes (test-sized blocks, read 3 bytes at a time), and the error if any.
    fn pieces(
        data: &[u8],
        rows: usize,
        block: usize,
    ) -> (Vec<(usize, Vec<String>)>, Option<String>) {
        struct Slow<'a>(&'a [u8], usize);
        impl Read for Slow<'_> {
            fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
                let n = self.0.len().min(buf.len()).min(self.1);
                buf[..n].copy_from_slice(&self.0[..n]);
                self.0 = &self.0[n..];
                Ok(n)
            }
        }
        let required = ["a".to_owned()];
        let columns = Columns {
            required: &required,
            optional: None,
        };
        let mut s = CsvStream::new(Slow(data, 3), "f.csv");
        s.block_bytes = block;
        let header = match s.header(&columns, |_| Ok(())) {
            Ok(h) => h,
            Err(e) => return (Vec::new(), Some(e.to_string())),
        };
        let mut out = Vec::new();
        let no_check = |_: &[f64], _: usize| Ok(());
        while let Some(piece) = s.next_piece(rows) {
            let parsed = piece.and_then(|p| {
                assert!(p.rows() <= rows || p.range.end == p.block.len());
                p.parse(&header, "f.csv", &no_check)
            });
            match parsed {
                Ok(p) => {
                    for r in 0..p.len() {
                        out.push((p.line(r), p.fields(r).map(str::to_owned).collect()));
                    }
                }
                Err(e) => return (out, Some(e.to_string())),
            }
        }
        (out, None)
    }

    /// The whole-file reader's rows, lines, fields and error.
    fn whole(data: &[u8]) -> (Vec<(usize, Vec<String>)>, Option<String>) {
        let required = ["a".to_owned()];
        let columns = Columns {
            required: &required,
            optional: None,
        };
        match crate::table::Table::read(
            data.to_vec(),
            "f.csv",
            &columns,
            |_| Ok(()),
            |_, _| Ok(()),
            1,
        ) {
            Ok(t) => (
                (0..t.len())
                    .map(|r| (t.line(r), t.fields(r).map(str::to_owned).collect()))
                    .collect(),
                None,
            ),
            Err(e) => (Vec::new(), Some(e.to_string())),
        }
    }

    #[test]
    fn pieces_read_as_the_whole_file() {
        let cases: &[&[u8]] = &[
            b"a,b\n1,2\n3,4\n5,6\n7,8\n9,10\n",
            b"\xEF\xBB\xBFa,b\r\n1,2\r\n\r\n3,4\r\n5,6",
            b"a,b\r1,2\r3,4\n\n\n5,6\r\n",
            b"a,\"b\nc\"\n1,\"2\"\"x\"\n\n3,\"q\nr\"\n4,t\n5,\"\xEF\xBB\xBFu\"\n6,v",
            b"a\n1\n\xEF\xBB\xBF\"2\"\n3\n",
            b"a,b\n1,\"x\ny\nz\",\n2,w\n",
            b"a,b\n1,2\n\"3\",\"unterminated\n4,5\n",
            b"a,b\n1,2\nx,3\n4,5\n",
            b"a,b\n1,2\n3,\"\xff\"\n4,5\n",
            b"a,b\n1,2\n3,\xff\n4,5\n",
            b"\n\r\na,b\n\n",
            b"a,b",
            b"\"a\",b\n1,2",
        ];
        for data in cases {
            let want = whole(data);
            for rows in [1, 2, 3, 7] {
                for block in [1, 2, 3, 5, 64] {
                    let got = pieces(data, rows, block);
                    assert_eq!(
                        got.1.is_some(),
                        want.1.is_some(),
                        "{:?} rows {rows} read {block}: {got:?} vs {want:?}",
                        String::from_utf8_lossy(data)
                    );
                    if want.1.is_none() {
                        assert_eq!(
                            got.0,
                            want.0,
                            "{:?} rows {rows}",
                            String::from_utf8_lossy(data)
                        );
                    } else {
                        assert_eq!(
                            got.1,
                            want.1,
                            "{:?} rows {rows}",
                            String::from_utf8_lossy(data)
                        );
                    }
                }
            }
        }
    }

    /// Random files of the bytes that matter (quotes, line ends, commas, byte-order
    /// marks, bad UTF-8) read in pieces equal the whole-file reader, errors included.
    #[test]
    fn random_files_read_as_the_whole_file() {
        const ALPHABET: [&[u8]; 10] = [
            b"1",
            b"2.5",
            b",",
            b"\"",
            b"\n",
            b"\r\n",
            b"\r",
            b"\xEF\xBB\xBF",
            b"\xff",
            b"a",
        ];
        let mut x: u64 = 0x2545_f491_4f6c_dd1d;
        let mut next = move |n: u64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x % n) as usize
        };
        for _ in 0..3000 {
            let mut data = b"a,b\n".to_vec();
            for _ in 0..next(40) {
                // mostly plain cells, now and then the rest
                let k = if next(3) == 0 { next(10) } else { next(3) };
                data.extend_from_slice(ALPHABET[k]);
            }
            let want = whole(&data);
            for (rows, block) in [(1, 1), (2, 4), (3, 7), (5, 16)] {
                let got = pieces(&data, rows, block);
                let what = String::from_utf8_lossy(&data);
                if want.1.is_none() {
                    assert_eq!(got, want, "{what:?} rows {rows} block {block}");
                } else {
                    assert_eq!(got.1, want.1, "{what:?} rows {rows} block {block}");
                }
            }
        }
    }

    #[test]
    fn counting_line_records() {
        let b = b"1\n\n2\r\n3\r4";
        // 3 records end with a line end; the 4th has none: the scan stops before it
        assert_eq!(count_line_records(b, 0, b.len(), 10), (8, 3, 3));
        // two records: the piece ends at the line end after "2", two newlines before
        assert_eq!(count_line_records(b, 0, b.len(), 2), (4, 2, 2));
    }
}

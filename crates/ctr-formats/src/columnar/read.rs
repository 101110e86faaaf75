//! Reading a Parquet file a bounded number of rows at a time, whatever its row groups.

use super::{describe, parquet_error, Column, Values, MAGIC};
use crate::error::{Error, ErrorKind, Location};
use bytes::Bytes;
use parquet::basic::Type as Physical;
use parquet::column::reader::{ColumnReader, ColumnReaderImpl};
use parquet::data_type::DataType;
use parquet::file::reader::{ChunkReader, FileReader, Length, SerializedFileReader};
use parquet::schema::types::TypePtr;
use std::fs::File;
use std::io::Read;
use std::path::Path;

/// Where a Parquet file's bytes are: a file (read in parts as needed) or memory
/// (standard input).
pub(crate) enum Data {
    File(File),
    Bytes(Bytes),
}

impl Length for Data {
    fn len(&self) -> u64 {
        match self {
            Data::File(f) => f.len(),
            Data::Bytes(b) => b.len() as u64,
        }
    }
}

impl ChunkReader for Data {
    type T = Box<dyn Read + Send>;

    fn get_read(&self, start: u64) -> parquet::errors::Result<Self::T> {
        Ok(match self {
            Data::File(f) => Box::new(f.get_read(start)?),
            Data::Bytes(b) => Box::new(b.get_read(start)?),
        })
    }

    fn get_bytes(&self, start: u64, length: usize) -> parquet::errors::Result<Bytes> {
        match self {
            Data::File(f) => f.get_bytes(start, length),
            Data::Bytes(b) => b.get_bytes(start, length),
        }
    }
}

/// A column of the file: its name and type.
#[derive(Clone, Debug)]
pub(crate) struct ColumnInfo {
    pub name: String,
    pub ty: TypePtr,
    max_def: i16,
}

/// A Parquet file being read.
pub(crate) struct ParquetReader {
    file: String,
    reader: SerializedFileReader<Data>,
    /// every column, in the file's order
    pub columns: Vec<ColumnInfo>,
    /// rows in the file
    pub rows: usize,
    /// the next row group to open
    group: usize,
    /// the open row group's column readers, and its rows not read yet
    readers: Vec<ColumnReader>,
    left: usize,
}

impl ParquetReader {
    /// Opens a Parquet file; errors name the path as given.
    pub fn open(path: &Path) -> Result<Self, Error> {
        let file = path.display().to_string();
        let f = File::open(path).map_err(|source| {
            Error::new(
                Location::file(&file),
                ErrorKind::Io {
                    action: "read",
                    source,
                },
            )
        })?;
        Self::new(Data::File(f), &file)
    }

    /// Reads a Parquet file held in memory; `file` names it in errors.
    pub fn from_bytes(data: Vec<u8>, file: &str) -> Result<Self, Error> {
        Self::new(Data::Bytes(Bytes::from(data)), file)
    }

    fn new(data: Data, file: &str) -> Result<Self, Error> {
        let at = || Location::file(file);
        let mut head = [0u8; 4];
        let opens = match &data {
            Data::File(f) => f
                .get_read(0)
                .and_then(|mut r| r.read_exact(&mut head).map_err(|e| e.into())),
            Data::Bytes(b) => {
                let n = b.len().min(4);
                head[..n].copy_from_slice(&b[..n]);
                Ok(())
            }
        };
        if opens.is_err() || head != MAGIC {
            let what = crate::records::not_text(&head).unwrap_or("text or another format");
            return Err(Error::new(
                at(),
                ErrorKind::Parquet {
                    message: format!(
                        "not a Parquet file (it does not start with PAR1; it looks like {})",
                        what.split(',').next().unwrap_or(what)
                    ),
                },
            ));
        }
        let reader = SerializedFileReader::new(data).map_err(|e| parquet_error(file, "read", e))?;
        let meta = reader.metadata();
        let rows = meta.file_metadata().num_rows().max(0) as usize;
        let schema = meta.file_metadata().schema_descr();
        let mut columns = Vec::with_capacity(schema.num_columns());
        for field in schema.root_schema().get_fields() {
            let name = field.name().to_owned();
            if !field.is_primitive() {
                return Err(Error::new(
                    at(),
                    ErrorKind::ColumnType {
                        column: name,
                        found: describe(field),
                        wanted: "flat columns only",
                    },
                ));
            }
            let supported = matches!(
                field.get_physical_type(),
                Physical::BOOLEAN
                    | Physical::INT32
                    | Physical::INT64
                    | Physical::FLOAT
                    | Physical::DOUBLE
                    | Physical::BYTE_ARRAY
            );
            let repeated =
                field.get_basic_info().repetition() == parquet::basic::Repetition::REPEATED;
            if !supported || repeated {
                return Err(Error::new(
                    at(),
                    ErrorKind::ColumnType {
                        column: name,
                        found: describe(field),
                        wanted: "booleans, numbers (INT32, INT64, FLOAT, DOUBLE) or text, one value a row",
                    },
                ));
            }
            columns.push(ColumnInfo {
                name,
                ty: field.clone(),
                max_def: 0,
            });
        }
        for (info, descr) in columns.iter_mut().zip(schema.columns()) {
            info.max_def = descr.max_def_level();
        }
        Ok(ParquetReader {
            file: file.to_owned(),
            reader,
            columns,
            rows,
            group: 0,
            readers: Vec::new(),
            left: 0,
        })
    }

    /// The file's name in errors.
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The column names, in the file's order.
    pub fn names(&self) -> Vec<String> {
        self.columns.iter().map(|c| c.name.clone()).collect()
    }

    /// The next rows, at most `max` (every column, in the file's order); no rows at the
    /// end of the file.
    pub fn next_rows(&mut self, max: usize) -> Result<Vec<Column>, Error> {
        let mut out: Vec<Column> = self.columns.iter().map(empty_column).collect();
        let mut got = 0;
        while got < max {
            if self.left == 0 && !self.open_group()? {
                break;
            }
            let take = (max - got).min(self.left);
            for ((reader, info), column) in self.readers.iter_mut().zip(&self.columns).zip(&mut out)
            {
                read_rows(reader, take, info.max_def, column)
                    .map_err(|e| parquet_error(&self.file, &format!("column {}", info.name), e))?;
            }
            self.left -= take;
            got += take;
        }
        Ok(out)
    }

    /// Opens the next row group; `false` after the last.
    fn open_group(&mut self) -> Result<bool, Error> {
        let file = &self.file;
        while self.group < self.reader.num_row_groups() {
            let group = self
                .reader
                .get_row_group(self.group)
                .map_err(|e| parquet_error(file, "read", e))?;
            self.group += 1;
            let rows = group.metadata().num_rows().max(0) as usize;
            if rows == 0 {
                continue;
            }
            self.readers = (0..self.columns.len())
                .map(|j| group.get_column_reader(j))
                .collect::<Result<_, _>>()
                .map_err(|e| parquet_error(file, "read", e))?;
            self.left = rows;
            return Ok(true);
        }
        Ok(false)
    }
}

/// A column of no rows for a column of the file.
fn empty_column(info: &ColumnInfo) -> Column {
    let values = match info.ty.get_physical_type() {
        Physical::BOOLEAN => Values::Bool(Vec::new()),
        Physical::INT32 => Values::I32(Vec::new()),
        Physical::INT64 => Values::I64(Vec::new()),
        Physical::FLOAT => Values::F32(Vec::new()),
        Physical::DOUBLE => Values::F64(Vec::new()),
        _ => Values::Bytes(Vec::new()),
    };
    Column {
        values,
        valid: (info.max_def > 0).then(Vec::new),
    }
}

/// Reads `rows` rows of a column into `out` (of its kind).
fn read_rows(
    reader: &mut ColumnReader,
    rows: usize,
    max_def: i16,
    out: &mut Column,
) -> parquet::errors::Result<()> {
    let valid = &mut out.valid;
    match (reader, &mut out.values) {
        (ColumnReader::BoolColumnReader(r), Values::Bool(v)) => {
            read_typed(r, rows, max_def, v, valid)
        }
        (ColumnReader::Int32ColumnReader(r), Values::I32(v)) => {
            read_typed(r, rows, max_def, v, valid)
        }
        (ColumnReader::Int64ColumnReader(r), Values::I64(v)) => {
            read_typed(r, rows, max_def, v, valid)
        }
        (ColumnReader::FloatColumnReader(r), Values::F32(v)) => {
            read_typed(r, rows, max_def, v, valid)
        }
        (ColumnReader::DoubleColumnReader(r), Values::F64(v)) => {
            read_typed(r, rows, max_def, v, valid)
        }
        (ColumnReader::ByteArrayColumnReader(r), Values::Bytes(v)) => {
            read_typed(r, rows, max_def, v, valid)
        }
        _ => Err(parquet::errors::ParquetError::General(
            "a column of another type than its schema says".into(),
        )),
    }
}

/// Reads `rows` records of a typed column: every row's value (a default for nulls) in
/// `values`, and for an optional column which rows hold one in `valid`.
fn read_typed<T: DataType>(
    reader: &mut ColumnReaderImpl<T>,
    rows: usize,
    max_def: i16,
    values: &mut Vec<T::T>,
    valid: &mut Option<Vec<bool>>,
) -> parquet::errors::Result<()> {
    let mut got = Vec::with_capacity(rows);
    let mut levels = Vec::with_capacity(if max_def > 0 { rows } else { 0 });
    let mut read = 0;
    while read < rows {
        let def = (max_def > 0).then_some(&mut levels);
        let (records, _, _) = reader.read_records(rows - read, def, None, &mut got)?;
        if records == 0 {
            return Err(parquet::errors::ParquetError::General(format!(
                "{read} of the row group's {rows} rows left to read are there"
            )));
        }
        read += records;
    }
    match valid {
        None => values.extend(got),
        Some(valid) => {
            let mut got = got.into_iter();
            for level in levels {
                let present = level == max_def;
                let value = if present { got.next() } else { None };
                values.push(value.unwrap_or_default());
                valid.push(present);
            }
        }
    }
    Ok(())
}

//! Writing a Parquet file row group by row group, as the rows come.

use super::{parquet_error, Column, Values};
use crate::error::Error;
use parquet::basic::{Compression, Type as Physical};
use parquet::column::writer::ColumnWriterImpl;
use parquet::data_type::{
    BoolType, ByteArrayType, DataType, DoubleType, FloatType, Int32Type, Int64Type,
};
use parquet::file::properties::WriterProperties;
use parquet::file::writer::SerializedFileWriter;
use parquet::schema::types::{ColumnPath, Type, TypePtr};
use std::io::Write;
use std::sync::Arc;

/// Rows in a row group of the files written (about 16 MB of doubles for a tip file of
/// three tubes): the rows kept in memory before they are written, and a unit that
/// pyarrow and Dask read well.
pub const ROW_GROUP_ROWS: usize = 1 << 17;

/// A Parquet file being written: rows are gathered into row groups of
/// [`ROW_GROUP_ROWS`] and each is written when full.
pub(crate) struct ParquetWriter<W: Write + Send> {
    file: String,
    writer: SerializedFileWriter<W>,
    /// the rows not written yet, one column per column of the schema
    pending: Vec<Column>,
    rows: usize,
}

impl<W: Write + Send> ParquetWriter<W> {
    /// Starts a file with the columns `types` (in order) on `out`; `file` names it in
    /// errors.
    pub fn new(out: W, file: &str, types: Vec<TypePtr>) -> Result<Self, Error> {
        let mut props = WriterProperties::builder()
            .set_compression(Compression::UNCOMPRESSED)
            .set_created_by(format!("ctr-formats {}", env!("CARGO_PKG_VERSION")))
            .set_max_row_group_row_count(Some(ROW_GROUP_ROWS));
        for ty in &types {
            // numbers rarely repeat: a dictionary would be tried and thrown away
            let text = ty.get_physical_type() == Physical::BYTE_ARRAY;
            props = props.set_column_dictionary_enabled(ColumnPath::from(ty.name()), text);
        }
        let schema = Arc::new(
            Type::group_type_builder("schema")
                .with_fields(types.clone())
                .build()
                .map_err(|e| parquet_error(file, "write", e))?,
        );
        let writer = SerializedFileWriter::new(out, schema, Arc::new(props.build()))
            .map_err(|e| parquet_error(file, "write", e))?;
        Ok(ParquetWriter {
            file: file.to_owned(),
            writer,
            pending: Vec::new(),
            rows: 0,
        })
    }

    /// Appends rows: one column per column of the schema, all of one length. Full row
    /// groups are written.
    pub fn write(&mut self, columns: Vec<Column>) -> Result<(), Error> {
        let n = columns.first().map_or(0, Column::len);
        if self.pending.is_empty() {
            self.pending = columns;
        } else {
            for (p, c) in self.pending.iter_mut().zip(columns) {
                p.extend(c);
            }
        }
        self.rows += n;
        if self.rows >= ROW_GROUP_ROWS {
            self.flush_group()?;
        }
        Ok(())
    }

    /// Writes the rows gathered as a row group.
    fn flush_group(&mut self) -> Result<(), Error> {
        if self.rows == 0 {
            return Ok(());
        }
        let file = &self.file;
        let fail = |e| parquet_error(file, "write", e);
        let mut group = self.writer.next_row_group().map_err(fail)?;
        for column in std::mem::take(&mut self.pending) {
            let Some(mut out) = group.next_column().map_err(fail)? else {
                break;
            };
            let def: Option<Vec<i16>> = column
                .valid
                .as_ref()
                .map(|v| v.iter().map(|&ok| i16::from(ok)).collect());
            let def = def.as_deref();
            let valid = column.valid.as_deref();
            let written = match column.values {
                Values::Bool(v) => write_typed::<BoolType>(out.typed(), v, valid, def),
                Values::I32(v) => write_typed::<Int32Type>(out.typed(), v, valid, def),
                Values::I64(v) => write_typed::<Int64Type>(out.typed(), v, valid, def),
                Values::F32(v) => write_typed::<FloatType>(out.typed(), v, valid, def),
                Values::F64(v) => write_typed::<DoubleType>(out.typed(), v, valid, def),
                Values::Bytes(v) => write_typed::<ByteArrayType>(out.typed(), v, valid, def),
            };
            written.map_err(fail)?;
            out.close().map_err(fail)?;
        }
        group.close().map_err(fail)?;
        self.rows = 0;
        Ok(())
    }

    /// Writes the last row group and the footer; returns the output.
    pub fn finish(mut self) -> Result<W, Error> {
        self.flush_group()?;
        let file = self.file.clone();
        self.writer
            .into_inner()
            .map_err(|e| parquet_error(&file, "write", e))
    }
}

/// Writes a column's values (only those of valid rows) with their definition levels.
fn write_typed<T: DataType>(
    out: &mut ColumnWriterImpl<'_, T>,
    values: Vec<T::T>,
    valid: Option<&[bool]>,
    def: Option<&[i16]>,
) -> parquet::errors::Result<usize> {
    match valid {
        None => out.write_batch(&values, None, None),
        Some(valid) => {
            let present: Vec<T::T> = values
                .into_iter()
                .zip(valid)
                .filter_map(|(v, &ok)| ok.then_some(v))
                .collect();
            out.write_batch(&present, def, None)
        }
    }
}

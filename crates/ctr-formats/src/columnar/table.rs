//! A Parquet file read whole into memory and checked as a CSV table is: the header,
//! the numeric columns' values (finite, no nulls), each row by a row check.

use super::read::ParquetReader;
use super::Column;
use super::{describe, holds_numbers};
use crate::error::{Error, ErrorKind, Location};
use crate::table::{Columns, Header};
use parquet::schema::types::TypePtr;

/// A Parquet file read and checked.
#[derive(Clone, Debug)]
pub(crate) struct ParquetTable {
    pub file: String,
    pub header: Header,
    /// every column of the file, every row
    pub columns: Vec<Column>,
    /// every column's type
    pub types: Vec<TypePtr>,
    /// the numeric columns' values, row after row
    pub values: Vec<f64>,
}

impl ParquetTable {
    /// Reads every row of `reader`, checking the header as
    /// [`Header::check`] does, the numeric columns' types and values, and each row with
    /// `row_check` (its values and its 1-based row).
    pub fn read(
        mut reader: ParquetReader,
        columns: &Columns<'_>,
        header_check: impl Fn(&str) -> Result<(), ErrorKind>,
        row_check: impl Fn(&[f64], usize) -> Result<(), Error>,
    ) -> Result<Self, Error> {
        let file = reader.file().to_owned();
        let header = Header::check(reader.names(), Location::file(&file), columns, header_check)?;
        numbers_only(&reader, &header, &file)?;
        let all = reader.next_rows(usize::MAX)?;
        let values = parquet_values(&all, &header, &file, 0, &row_check)?;
        Ok(ParquetTable {
            file,
            header,
            columns: all,
            types: reader.columns.iter().map(|c| c.ty.clone()).collect(),
            values,
        })
    }

    /// Rows.
    pub fn len(&self) -> usize {
        self.columns.first().map_or(0, Column::len)
    }

    /// The numeric values of row `row`.
    pub fn values(&self, row: usize) -> &[f64] {
        let w = self.header.width();
        &self.values[row * w..(row + 1) * w]
    }
}

/// Refuses a Parquet file whose columns of numbers (the header's values) cannot hold
/// plain numbers.
pub(crate) fn numbers_only(
    reader: &ParquetReader,
    header: &Header,
    file: &str,
) -> Result<(), Error> {
    for &i in &header.index {
        let column = &reader.columns[i];
        if !holds_numbers(&column.ty) {
            return Err(Error::new(
                Location::file(file),
                ErrorKind::ColumnType {
                    column: column.name.clone(),
                    found: describe(&column.ty),
                    wanted: "numbers (DOUBLE, FLOAT, INT32 or INT64)",
                },
            ));
        }
    }
    Ok(())
}

/// The values of the numeric columns of Parquet rows (`index`, named `names`), checked
/// (a value, finite) and by `row_check` (with the 1-based row); rows from `first_row`.
pub(crate) fn parquet_values(
    columns: &[Column],
    header: &Header,
    file: &str,
    first_row: usize,
    row_check: &impl Fn(&[f64], usize) -> Result<(), Error>,
) -> Result<Vec<f64>, Error> {
    let n = columns.first().map_or(0, Column::len);
    let mut values = Vec::with_capacity(n * header.width());
    let mut row = Vec::with_capacity(header.width());
    for r in 0..n {
        let at = |kind| Error::new(Location::row(file, first_row + r + 1), kind);
        row.clear();
        for (&i, name) in header.index.iter().zip(&header.value_names) {
            let v = columns[i].number(r).ok_or_else(|| {
                at(ErrorKind::NullValue {
                    column: name.clone(),
                })
            })?;
            if !v.is_finite() {
                return Err(at(ErrorKind::NotFinite {
                    column: name.clone(),
                    found: columns[i].text(r).into_owned(),
                }));
            }
            row.push(v);
        }
        row_check(&row, first_row + r + 1)?;
        values.extend_from_slice(&row);
    }
    Ok(values)
}

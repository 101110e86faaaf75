//! Parquet files (`*.parquet`): the joint, target, tip, IK and recording tables with
//! the CSV files' column names, one Parquet column per CSV column
//! (`data/FORMATS-EXTENSION.md`, "Parquet").
//!
//! Read: flat columns of booleans, 32- and 64-bit integers, floats, doubles and byte
//! arrays (text), required or optional (nulls), in row groups of any size, read a
//! bounded number of rows at a time ([`read::ParquetReader`]). A column the job needs
//! as numbers must be DOUBLE, FLOAT, INT32 or INT64 (no decimals, dates or times)
//! without nulls, NaN or infinities; errors name the file, the row (1-based) and the
//! column. Written ([`write::ParquetWriter`]): the computed columns as required DOUBLE
//! (text as UTF-8 strings), the input's other columns carried with their own type, in
//! row groups of [`write::ROW_GROUP_ROWS`], uncompressed, strings dictionary-encoded.

mod output;
pub(crate) mod read;
pub(crate) mod table;
pub(crate) mod write;

pub use output::{is_number_column, Batch, ColumnType, ParquetOutput};

use crate::csvout::{write_field, write_float};
use crate::error::{Error, ErrorKind, Location};
use parquet::basic::{ConvertedType, LogicalType, Repetition, Type as Physical};
use parquet::data_type::ByteArray;
use parquet::schema::types::{Type, TypePtr};
use std::borrow::Cow;
use std::path::Path;
use std::sync::Arc;

/// The extension that makes a file Parquet (any case); every other file is CSV.
pub const PARQUET_EXTENSION: &str = "parquet";

/// The bytes that open (and close) every Parquet file.
pub(crate) const MAGIC: &[u8] = b"PAR1";

/// True when `path` names a Parquet file: its extension is `.parquet` (any case).
///
/// ```
/// use std::path::Path;
/// assert!(ctr_formats::is_parquet(Path::new("sweep/tips.PARQUET")));
/// assert!(!ctr_formats::is_parquet(Path::new("tips.csv")));
/// ```
pub fn is_parquet(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case(PARQUET_EXTENSION))
}

/// The values of a column, one per row (a null row holds a placeholder).
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Values {
    Bool(Vec<bool>),
    I32(Vec<i32>),
    I64(Vec<i64>),
    F32(Vec<f32>),
    F64(Vec<f64>),
    Bytes(Vec<ByteArray>),
}

/// A column of some rows: values, and which rows hold one (`None`: every row).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Column {
    pub values: Values,
    pub valid: Option<Vec<bool>>,
}

macro_rules! each_values {
    ($values:expr, $v:ident => $body:expr) => {
        match $values {
            Values::Bool($v) => $body,
            Values::I32($v) => $body,
            Values::I64($v) => $body,
            Values::F32($v) => $body,
            Values::F64($v) => $body,
            Values::Bytes($v) => $body,
        }
    };
}

impl Values {
    fn len(&self) -> usize {
        each_values!(self, v => v.len())
    }

    /// No values, of the same kind.
    fn empty(&self) -> Values {
        match self {
            Values::Bool(_) => Values::Bool(Vec::new()),
            Values::I32(_) => Values::I32(Vec::new()),
            Values::I64(_) => Values::I64(Vec::new()),
            Values::F32(_) => Values::F32(Vec::new()),
            Values::F64(_) => Values::F64(Vec::new()),
            Values::Bytes(_) => Values::Bytes(Vec::new()),
        }
    }

    /// Appends `other`'s value at `r` (of the same kind).
    fn push_from(&mut self, other: &Values, r: usize) {
        match (self, other) {
            (Values::Bool(a), Values::Bool(b)) => a.push(b[r]),
            (Values::I32(a), Values::I32(b)) => a.push(b[r]),
            (Values::I64(a), Values::I64(b)) => a.push(b[r]),
            (Values::F32(a), Values::F32(b)) => a.push(b[r]),
            (Values::F64(a), Values::F64(b)) => a.push(b[r]),
            (Values::Bytes(a), Values::Bytes(b)) => a.push(b[r].clone()),
            _ => unreachable!("columns of one kind"),
        }
    }

    /// Appends all of `other` (of the same kind).
    fn extend(&mut self, other: Values) {
        match (self, other) {
            (Values::Bool(a), Values::Bool(b)) => a.extend(b),
            (Values::I32(a), Values::I32(b)) => a.extend(b),
            (Values::I64(a), Values::I64(b)) => a.extend(b),
            (Values::F32(a), Values::F32(b)) => a.extend(b),
            (Values::F64(a), Values::F64(b)) => a.extend(b),
            (Values::Bytes(a), Values::Bytes(b)) => a.extend(b),
            _ => unreachable!("columns of one kind"),
        }
    }
}

impl Column {
    /// A required column of doubles.
    pub fn doubles(values: Vec<f64>) -> Column {
        Column {
            values: Values::F64(values),
            valid: None,
        }
    }

    /// A required column of text.
    pub fn texts<'a>(values: impl IntoIterator<Item = &'a str>) -> Column {
        Column {
            values: Values::Bytes(values.into_iter().map(ByteArray::from).collect()),
            valid: None,
        }
    }

    /// Rows.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// No rows, of a column of type `ty` (doubles, maybe null, or text).
    pub fn empty_of(ty: &Type) -> Column {
        let optional = ty.get_basic_info().repetition() == Repetition::OPTIONAL;
        let values = match ty.get_physical_type() {
            Physical::DOUBLE => Values::F64(Vec::new()),
            _ => Values::Bytes(Vec::new()),
        };
        Column {
            values,
            valid: optional.then(Vec::new),
        }
    }

    /// Appends a CSV cell: a column of doubles takes a number (an empty cell as null;
    /// anything else is `Err`), a column of text the cell as it is.
    pub fn push_text(&mut self, cell: &str) -> Result<(), ()> {
        match &mut self.values {
            Values::F64(v) => {
                let t = cell.trim();
                let number = if t.is_empty() {
                    None
                } else {
                    Some(t.parse::<f64>().map_err(|_| ())?)
                };
                v.push(number.unwrap_or_default());
                match &mut self.valid {
                    Some(valid) => valid.push(number.is_some()),
                    None if number.is_none() => return Err(()),
                    None => {}
                }
                Ok(())
            }
            Values::Bytes(v) => {
                v.push(cell.into());
                Ok(())
            }
            _ => Err(()),
        }
    }

    /// True when row `r` holds a value (not null).
    pub fn is_valid(&self, r: usize) -> bool {
        self.valid.as_ref().is_none_or(|v| v[r])
    }

    /// No rows, of the same kind.
    pub fn empty(&self) -> Column {
        Column {
            values: self.values.empty(),
            valid: self.valid.as_ref().map(|_| Vec::new()),
        }
    }

    /// Appends row `r` of `other` (a column of the same kind).
    pub fn push_from(&mut self, other: &Column, r: usize) {
        self.values.push_from(&other.values, r);
        if let Some(v) = &mut self.valid {
            v.push(other.is_valid(r));
        }
    }

    /// Appends all rows of `other` (a column of the same kind).
    pub fn extend(&mut self, other: Column) {
        let n = other.len();
        match (&mut self.valid, other.valid) {
            (Some(a), Some(b)) => a.extend(b),
            (Some(a), None) => a.extend(std::iter::repeat_n(true, n)),
            (None, _) => {}
        }
        self.values.extend(other.values);
    }

    /// Row `r` as a number, if the column holds numbers and the row a value.
    pub fn number(&self, r: usize) -> Option<f64> {
        if !self.is_valid(r) {
            return None;
        }
        match &self.values {
            Values::I32(v) => Some(f64::from(v[r])),
            Values::I64(v) => Some(v[r] as f64),
            Values::F32(v) => Some(f64::from(v[r])),
            Values::F64(v) => Some(v[r]),
            Values::Bool(_) | Values::Bytes(_) => None,
        }
    }

    /// Row `r` as CSV text: numbers in shortest round-trip form (integers as integers,
    /// dates and times as their stored integer), booleans `true`/`false`, text as it
    /// is (bytes that are not UTF-8 with U+FFFD), a null as nothing.
    pub fn text(&self, r: usize) -> Cow<'_, str> {
        if !self.is_valid(r) {
            return Cow::Borrowed("");
        }
        match &self.values {
            Values::Bool(v) => Cow::Borrowed(if v[r] { "true" } else { "false" }),
            Values::I32(v) => Cow::Owned(v[r].to_string()),
            Values::I64(v) => Cow::Owned(v[r].to_string()),
            Values::F32(v) => Cow::Owned(v[r].to_string()),
            Values::F64(v) => {
                let mut out = Vec::with_capacity(24);
                write_float(&mut out, v[r]);
                Cow::Owned(String::from_utf8_lossy(&out).into_owned())
            }
            Values::Bytes(v) => String::from_utf8_lossy(v[r].data()),
        }
    }

    /// Appends row `r` to `out` as one CSV field (quoted as needed).
    pub fn write_csv(&self, r: usize, out: &mut Vec<u8>) {
        match &self.values {
            Values::F64(v) if self.is_valid(r) => write_float(out, v[r]),
            _ => write_field(out, &self.text(r)),
        }
    }
}

/// A column's Parquet type in words, for messages: `DOUBLE`, `BYTE_ARRAY (STRING)`,
/// `INT64 (TIMESTAMP)`, with `, optional` when it may hold nulls.
pub(crate) fn describe(ty: &Type) -> String {
    let info = ty.get_basic_info();
    if !ty.is_primitive() {
        return "a group (a nested column: list, map or struct)".into();
    }
    let mut s = format!("{}", ty.get_physical_type());
    if let Some(l) = info.logical_type_ref() {
        let name = format!("{l:?}");
        let name = name.split(['(', ' ', '{']).next().unwrap_or_default();
        s += &format!(" ({})", name.to_uppercase());
    } else if info.converted_type() != ConvertedType::NONE {
        s += &format!(" ({})", info.converted_type());
    }
    if info.has_repetition() && info.repetition() == Repetition::OPTIONAL {
        s += ", optional";
    }
    s
}

/// True when a column of type `ty` holds plain numbers: DOUBLE, FLOAT, INT32 or INT64
/// without a logical type other than an integer's.
pub(crate) fn holds_numbers(ty: &Type) -> bool {
    let numeric = matches!(
        ty.get_physical_type(),
        Physical::DOUBLE | Physical::FLOAT | Physical::INT32 | Physical::INT64
    );
    let info = ty.get_basic_info();
    let plain = matches!(
        info.converted_type(),
        ConvertedType::NONE
            | ConvertedType::INT_8
            | ConvertedType::INT_16
            | ConvertedType::INT_32
            | ConvertedType::INT_64
            | ConvertedType::UINT_8
            | ConvertedType::UINT_16
            | ConvertedType::UINT_32
            | ConvertedType::UINT_64
    );
    numeric
        && plain
        && matches!(
            info.logical_type_ref(),
            None | Some(LogicalType::Integer(_))
        )
}

/// A required DOUBLE column named `name`.
pub(crate) fn double_type(name: &str, optional: bool) -> TypePtr {
    let repetition = if optional {
        Repetition::OPTIONAL
    } else {
        Repetition::REQUIRED
    };
    Arc::new(
        Type::primitive_type_builder(name, Physical::DOUBLE)
            .with_repetition(repetition)
            .build()
            .expect("a DOUBLE column is a valid type"),
    )
}

/// A required UTF-8 string column named `name`.
pub(crate) fn string_type(name: &str) -> TypePtr {
    Arc::new(
        Type::primitive_type_builder(name, Physical::BYTE_ARRAY)
            .with_repetition(Repetition::REQUIRED)
            .with_logical_type(Some(LogicalType::String))
            .build()
            .expect("a string column is a valid type"),
    )
}

/// The error of the parquet crate while reading or writing `file`.
pub(crate) fn parquet_error(file: &str, action: &str, e: parquet::errors::ParquetError) -> Error {
    let kind = match e {
        parquet::errors::ParquetError::External(inner) => {
            match inner.downcast::<std::io::Error>() {
                Ok(io) => {
                    return Error::new(
                        Location::file(file),
                        ErrorKind::Io {
                            action: if action == "write" { "write" } else { "read" },
                            source: *io,
                        },
                    )
                }
                Err(other) => other.to_string(),
            }
        }
        other => other.to_string(),
    };
    Error::new(
        Location::file(file),
        ErrorKind::Parquet {
            message: format!("{action}: {}", crate::toml_doc::one_line(&kind)),
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_are_written_as_csv_text() {
        let col = Column {
            values: Values::F64(vec![0.1 + 0.2, -0.0, 7.0]),
            valid: Some(vec![true, true, false]),
        };
        let mut out = Vec::new();
        for r in 0..3 {
            col.write_csv(r, &mut out);
            out.push(b'|');
        }
        assert_eq!(String::from_utf8(out).unwrap(), "0.30000000000000004|-0||");
        let text = Column::texts(["a,b", "plain"]);
        let mut out = Vec::new();
        text.write_csv(0, &mut out);
        assert_eq!(out, b"\"a,b\"");
        let ints = Column {
            values: Values::I64(vec![-3, 1 << 40]),
            valid: None,
        };
        assert_eq!(
            (ints.text(0), ints.number(1)),
            ("-3".into(), Some(1099511627776.0))
        );
    }

    #[test]
    fn rows_are_selected_and_appended() {
        let a = Column {
            values: Values::I32(vec![1, 2, 3]),
            valid: Some(vec![true, false, true]),
        };
        let mut b = a.empty();
        b.push_from(&a, 2);
        b.push_from(&a, 1);
        assert_eq!((b.number(0), b.number(1)), (Some(3.0), None));
        b.extend(a.clone());
        assert_eq!(b.len(), 5);
        assert_eq!(b.number(4), Some(3.0));
        assert!(!b.is_valid(3));
    }
}

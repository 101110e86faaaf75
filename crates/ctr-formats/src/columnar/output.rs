//! A Parquet output file: its columns' types, rows gathered as columns, written
//! atomically as [`AtomicFile`] writes every output.

use super::write::ParquetWriter;
use super::{double_type, string_type, Column};
use crate::error::{Error, ErrorKind, Location};
use crate::output::AtomicFile;
use crate::robot::tube_of_column;
use parquet::schema::types::TypePtr;
use std::path::Path;

/// The type of a column of a Parquet output.
#[derive(Clone, Debug)]
pub struct ColumnType(pub(crate) TypePtr);

impl ColumnType {
    /// Required doubles (the computed columns: tips, joints, residuals).
    pub fn double(name: &str) -> Self {
        ColumnType(double_type(name, false))
    }

    /// Required UTF-8 text (`status`).
    pub fn text(name: &str) -> Self {
        ColumnType(string_type(name))
    }

    /// A CSV column carried into a Parquet output: doubles where the formats contract
    /// has numbers ([`is_number_column`]; an empty cell is null), text elsewhere.
    pub fn carried_csv(name: &str) -> Self {
        let name_trimmed = name.trim();
        if is_number_column(name_trimmed) {
            ColumnType(double_type(name, true))
        } else {
            ColumnType(string_type(name))
        }
    }

    /// The column's name.
    pub fn name(&self) -> &str {
        self.0.name()
    }
}

/// True for the columns the formats contract (and its extension) fills with numbers:
/// `t_s`; the joints `s{i}_mm`, `theta{i}_deg` and their `_read_` forms; the tip
/// `x_mm,y_mm,z_mm`, `qw,qx,qy,qz`, `tx,ty,tz`, the force `fx_n,fy_n,fz_n`; and what
/// `fk` and `ik` add: `residual_per_mm`, `stability_margin`, `reached_*`,
/// `residual_mm`, `orientation_residual_deg`. A CSV file's such column becomes a
/// Parquet DOUBLE column; every other stays text.
///
/// ```
/// use ctr_formats::is_number_column;
/// assert!(is_number_column("t_s") && is_number_column("theta2_read_deg"));
/// assert!(!is_number_column("run") && !is_number_column("label"));
/// ```
pub fn is_number_column(name: &str) -> bool {
    const NAMES: [&str; 25] = [
        "t_s",
        "x_mm",
        "y_mm",
        "z_mm",
        "qw",
        "qx",
        "qy",
        "qz",
        "tx",
        "ty",
        "tz",
        "fx_n",
        "fy_n",
        "fz_n",
        "residual_per_mm",
        "stability_margin",
        "residual_mm",
        "orientation_residual_deg",
        "reached_x_mm",
        "reached_y_mm",
        "reached_z_mm",
        "reached_qw",
        "reached_qx",
        "reached_qy",
        "reached_qz",
    ];
    if NAMES.contains(&name) {
        return true;
    }
    let joint = |n: &str| tube_of_column(n).is_some();
    joint(name)
        || name
            .strip_suffix("_read_mm")
            .is_some_and(|s| joint(&format!("{s}_mm")))
        || name
            .strip_suffix("_read_deg")
            .is_some_and(|s| joint(&format!("{s}_deg")))
}

/// Rows of an output, gathered as columns (one per column of the output, in order).
#[derive(Clone, Debug, Default)]
pub struct Batch(pub(crate) Vec<Column>);

impl Batch {
    /// Rows in the batch.
    pub fn len(&self) -> usize {
        self.0.first().map_or(0, Column::len)
    }

    /// True when the batch has no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Appends a required column of doubles.
    pub fn push_doubles(&mut self, values: Vec<f64>) {
        self.0.push(Column::doubles(values));
    }

    /// Appends a required column of text.
    pub fn push_texts<'a>(&mut self, values: impl IntoIterator<Item = &'a str>) {
        self.0.push(Column::texts(values));
    }

    /// The rows `rows` of the batch.
    pub fn rows(&self, rows: std::ops::Range<usize>) -> Batch {
        Batch(
            self.0
                .iter()
                .map(|c| {
                    let mut out = c.empty();
                    rows.clone().for_each(|r| out.push_from(c, r));
                    out
                })
                .collect(),
        )
    }

    /// Appends the columns of `other` (of the same rows).
    pub fn append(&mut self, other: Batch) {
        self.0.extend(other.0);
    }
}

/// A Parquet output being written to a temporary file beside its path, which it
/// replaces on [`commit`](Self::commit) only.
///
/// ```
/// use ctr_formats::{Batch, ColumnType, ParquetOutput};
/// let dir = tempfile::tempdir()?;
/// let path = dir.path().join("tips.parquet");
/// let types = vec![ColumnType::text("label"), ColumnType::double("x_mm")];
/// let mut out = ParquetOutput::create(&path, types)?;
/// let mut rows = Batch::default();
/// rows.push_texts(["a", "b"]);
/// rows.push_doubles(vec![1.5, 2.5]);
/// out.write(rows)?;
/// assert!(!path.exists());
/// out.commit()?;
/// assert!(std::fs::read(&path)?.starts_with(b"PAR1"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct ParquetOutput {
    file: String,
    writer: ParquetWriter<AtomicFile>,
    columns: usize,
}

impl ParquetOutput {
    /// Creates the temporary file beside `path` (whose directory must exist) and starts
    /// a Parquet file with `columns`.
    pub fn create(path: &Path, columns: Vec<ColumnType>) -> Result<Self, Error> {
        let file = path.display().to_string();
        let n = columns.len();
        let tmp = AtomicFile::create(path)?;
        let types = columns.into_iter().map(|c| c.0).collect();
        Ok(ParquetOutput {
            writer: ParquetWriter::new(tmp, &file, types)?,
            file,
            columns: n,
        })
    }

    /// Writes rows (a batch with one column per column of the output).
    pub fn write(&mut self, rows: Batch) -> Result<(), Error> {
        if rows.0.len() != self.columns {
            return Err(Error::new(
                Location::file(&self.file),
                ErrorKind::Parquet {
                    message: format!(
                        "write: {} columns given for an output of {}",
                        rows.0.len(),
                        self.columns
                    ),
                },
            ));
        }
        self.writer.write(rows.0)
    }

    /// Writes the last rows and the footer, and renames the file into place.
    pub fn commit(self) -> Result<(), Error> {
        self.writer.finish()?.commit()
    }

    /// As [`commit`](Self::commit), but fails when the path exists (see
    /// [`AtomicFile::commit_new`]).
    pub fn commit_new(self) -> Result<(), Error> {
        self.writer.finish()?.commit_new()
    }

    /// Writes CSV text (`data`, a whole file named `file` in errors: a header and
    /// rows, as the csv crate reads them) as a Parquet file at `path`: each column as
    /// [`ColumnType::carried_csv`] makes it. Replaces an existing file only with
    /// `replace`.
    pub fn from_csv(data: &[u8], file: &str, path: &Path, replace: bool) -> Result<(), Error> {
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .from_reader(data);
        let mut records = rdr.records();
        let fail = |line: usize, e: csv::Error| {
            let message = format!("{e}");
            Error::new(Location::line(file, line), ErrorKind::Csv { message })
        };
        let header = match records.next() {
            Some(r) => r.map_err(|e| fail(1, e))?,
            None => csv::StringRecord::new(),
        };
        let types: Vec<ColumnType> = header.iter().map(ColumnType::carried_csv).collect();
        let mut columns: Vec<Column> = types.iter().map(|t| Column::empty_of(&t.0)).collect();
        for (k, record) in records.enumerate() {
            let record = record.map_err(|e| fail(k + 2, e))?;
            for (i, column) in columns.iter_mut().enumerate() {
                let cell = record.get(i).unwrap_or_default();
                column.push_text(cell).map_err(|()| {
                    Error::new(
                        Location::line(file, k + 2),
                        ErrorKind::NotANumber {
                            column: header[i].trim().to_owned(),
                            found: cell.to_owned(),
                        },
                    )
                })?;
            }
        }
        let mut out = ParquetOutput::create(path, types)?;
        out.write(Batch(columns))?;
        if replace {
            out.commit()
        } else {
            out.commit_new()
        }
    }
}

//! The tip CSV written by forward kinematics: the input's columns, then the tip pose.

use super::csvout::{write_field, write_float, write_record};
use crate::columnar::{Batch, ColumnType};
use crate::error::{status_name, ErrorKind};
use crate::robot::FkResult;
use std::io::Write;

/// The pose columns appended to every output row.
pub const TIP_COLUMNS: [&str; 7] = ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"];

/// The columns appended after the pose when rows are marked with their solve status.
pub const STATUS_COLUMNS: [&str; 2] = ["status", "residual_per_mm"];

/// The column `ctr-cli fk --margin` appends last: the elastic stability margin.
pub const MARGIN_COLUMN: &str = "stability_margin";

/// Which columns a tip file has after the pose.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TipColumns {
    /// [`STATUS_COLUMNS`]: the solve's status and residual.
    pub status: bool,
    /// [`MARGIN_COLUMN`], after the status columns.
    pub margin: bool,
}

/// The output header: `input` (as found) then [`TIP_COLUMNS`] and the columns `extra`
/// asks for. Refuses an input column whose name (trimmed) the output adds.
///
/// ```
/// use ctr_formats::{tip_header_for, TipColumns};
/// let h = tip_header_for(&["s1_mm".into()], TipColumns { status: false, margin: true }).unwrap();
/// assert_eq!(h.join(","), "s1_mm,x_mm,y_mm,z_mm,qw,qx,qy,qz,stability_margin");
/// ```
pub fn tip_header_for(input: &[String], extra: TipColumns) -> Result<Vec<String>, ErrorKind> {
    let added: Vec<&str> = TIP_COLUMNS
        .iter()
        .chain(if extra.status {
            &STATUS_COLUMNS[..]
        } else {
            &[]
        })
        .chain(if extra.margin {
            &[MARGIN_COLUMN][..]
        } else {
            &[]
        })
        .copied()
        .collect();
    if let Some(clash) = input.iter().find(|h| added.contains(&h.trim())) {
        return Err(ErrorKind::OutputColumnClash {
            name: clash.trim().to_owned(),
        });
    }
    Ok(input
        .iter()
        .cloned()
        .chain(added.iter().map(|s| (*s).to_owned()))
        .collect())
}

/// The output header: `input` (as found) then [`TIP_COLUMNS`] (and [`STATUS_COLUMNS`]
/// with `with_status`). Refuses an input column whose name (trimmed) the output adds.
///
/// ```
/// let h = ctr_formats::tip_header(&["label".into(), "s1_mm".into()], false).unwrap();
/// assert_eq!(h.join(","), "label,s1_mm,x_mm,y_mm,z_mm,qw,qx,qy,qz");
/// assert!(ctr_formats::tip_header(&["z_mm".into()], false).is_err());
/// ```
pub fn tip_header(input: &[String], with_status: bool) -> Result<Vec<String>, ErrorKind> {
    tip_header_for(
        input,
        TipColumns {
            status: with_status,
            margin: false,
        },
    )
}

/// The columns a Parquet tip file adds after the input's: [`TIP_COLUMNS`] and those
/// `extra` asks for, as [`tip_header_for`] names them.
///
/// ```
/// use ctr_formats::{tip_column_types, TipColumns};
/// let t = tip_column_types(TipColumns { status: true, margin: false });
/// assert_eq!(t.iter().map(|c| c.name()).collect::<Vec<_>>().join(","), "x_mm,y_mm,z_mm,qw,qx,qy,qz,status,residual_per_mm");
/// ```
pub fn tip_column_types(extra: TipColumns) -> Vec<ColumnType> {
    let mut types: Vec<ColumnType> = TIP_COLUMNS.iter().map(|c| ColumnType::double(c)).collect();
    if extra.status {
        types.push(ColumnType::text(STATUS_COLUMNS[0]));
        types.push(ColumnType::double(STATUS_COLUMNS[1]));
    }
    if extra.margin {
        types.push(ColumnType::double(MARGIN_COLUMN));
    }
    types
}

/// The tip columns of `results` for a Parquet output ([`tip_column_types`]).
pub fn tip_batch(results: &[FkResult], extra: TipColumns) -> Batch {
    let mut batch = Batch::default();
    for k in 0..3 {
        batch.push_doubles(results.iter().map(|r| r.position[k]).collect());
    }
    for k in 0..4 {
        batch.push_doubles(results.iter().map(|r| r.quaternion[k]).collect());
    }
    if extra.status {
        batch.push_texts(results.iter().map(|r| status_name(r.status)));
        batch.push_doubles(results.iter().map(|r| r.residual_per_mm).collect());
    }
    if extra.margin {
        batch.push_doubles(results.iter().map(|r| r.stability_margin).collect());
    }
    batch
}

/// Formats a float with Rust's shortest round-trip representation: parsing the text
/// gives back the same `f64`, bit for bit (`-0` stays `-0`).
///
/// ```
/// let v = 0.1 + 0.2;
/// assert_eq!(ctr_formats::format_float(v).parse::<f64>().unwrap(), v);
/// ```
pub fn format_float(v: f64) -> String {
    let mut out = Vec::with_capacity(24);
    write_float(&mut out, v);
    // write_float writes ASCII only
    String::from_utf8(out).unwrap_or_default()
}

/// Appends the CSV header line `header` to `out`.
pub fn write_header(out: &mut Vec<u8>, header: &[String]) {
    write_record(out, header.iter().map(String::as_str));
}

/// The input columns of an output row.
pub enum Carried<'a, I: Iterator<Item = &'a str>> {
    /// Fields to write (quoted as needed).
    Fields(I),
    /// A line of fields already in CSV form (from `plain_line`).
    Line(&'a str),
    /// A row of a Parquet file's columns, written as CSV text.
    Columns(CarriedColumns<'a>),
}

/// A row of a Parquet file's columns, carried into a CSV output
/// ([`JointRows::carried`](crate::JointRows::carried)).
#[derive(Clone, Copy, Debug)]
pub struct CarriedColumns<'a> {
    pub(crate) columns: &'a [crate::columnar::Column],
    /// the columns carried (increasing indices), or all
    pub(crate) keep: Option<&'a [usize]>,
    pub(crate) row: usize,
}

/// Writes the carried columns of a row, each followed by a comma.
pub(crate) fn write_carried<'a, I: Iterator<Item = &'a str>>(
    out: &mut Vec<u8>,
    input: Carried<'a, I>,
) {
    match input {
        Carried::Line(line) => {
            out.extend_from_slice(line.as_bytes());
            out.push(b',');
        }
        Carried::Fields(fields) => {
            for f in fields {
                write_field(out, f);
                out.push(b',');
            }
        }
        Carried::Columns(c) => {
            let mut each = |column: &crate::columnar::Column| {
                column.write_csv(c.row, out);
                out.push(b',');
            };
            match c.keep {
                Some(keep) => keep.iter().for_each(|&i| each(&c.columns[i])),
                None => c.columns.iter().for_each(each),
            }
        }
    }
}

/// Appends one tip row to `out`: the input's raw fields, then the pose (and, with
/// `with_status`, status and residual).
pub fn write_tip_row<'a, I: Iterator<Item = &'a str>>(
    out: &mut Vec<u8>,
    input: Carried<'a, I>,
    fk: &FkResult,
    with_status: bool,
) {
    let extra = TipColumns {
        status: with_status,
        margin: false,
    };
    write_tip_row_for(out, input, fk, extra);
}

/// Appends one tip row to `out`: the input's raw fields, then the pose and the columns
/// `extra` asks for (as [`tip_header_for`] names them).
pub fn write_tip_row_for<'a, I: Iterator<Item = &'a str>>(
    out: &mut Vec<u8>,
    input: Carried<'a, I>,
    fk: &FkResult,
    extra: TipColumns,
) {
    let with_status = extra.status;
    write_carried(out, input);
    for (k, v) in fk.position.iter().chain(fk.quaternion.iter()).enumerate() {
        if k > 0 {
            out.push(b',');
        }
        write_float(out, *v);
    }
    if with_status {
        out.push(b',');
        out.extend_from_slice(status_name(fk.status).as_bytes());
        out.push(b',');
        write_float(out, fk.residual_per_mm);
    }
    if extra.margin {
        out.push(b',');
        write_float(out, fk.stability_margin);
    }
    out.push(b'\n');
}

/// Writes tip rows as CSV.
pub struct TipWriter<W: Write> {
    out: W,
    buf: Vec<u8>,
    with_status: bool,
}

impl<W: Write> TipWriter<W> {
    /// Writes `header` (from [`tip_header`]); `with_status` must match it.
    pub fn new(out: W, header: &[String], with_status: bool) -> Result<Self, ErrorKind> {
        let mut w = TipWriter {
            out,
            buf: Vec::with_capacity(1 << 16),
            with_status,
        };
        write_header(&mut w.buf, header);
        Ok(w)
    }

    /// Writes one row: the input's raw fields, then the pose (and status, residual).
    pub fn write_row<'a>(
        &mut self,
        input_fields: impl IntoIterator<Item = &'a str>,
        fk: &FkResult,
    ) -> Result<(), ErrorKind> {
        let fields = Carried::Fields(input_fields.into_iter());
        write_tip_row(&mut self.buf, fields, fk, self.with_status);
        if self.buf.len() >= 1 << 16 {
            self.out.write_all(&self.buf).map_err(write_error)?;
            self.buf.clear();
        }
        Ok(())
    }

    /// Flushes and returns the underlying writer.
    pub fn finish(mut self) -> Result<W, ErrorKind> {
        self.out
            .write_all(&self.buf)
            .and_then(|()| self.out.flush())
            .map_err(write_error)?;
        Ok(self.out)
    }
}

pub(crate) fn write_error(source: std::io::Error) -> ErrorKind {
    ErrorKind::Io {
        action: "write",
        source,
    }
}

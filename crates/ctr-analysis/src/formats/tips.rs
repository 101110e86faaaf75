//! The tip CSV written by forward kinematics: the input's columns, then the tip pose.

use crate::error::{status_name, ErrorKind};
use crate::robot::FkResult;
use std::io::Write;

/// The pose columns appended to every output row.
pub const TIP_COLUMNS: [&str; 7] = ["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"];

/// The columns appended after the pose when rows are marked with their solve status.
pub const STATUS_COLUMNS: [&str; 2] = ["status", "residual_per_mm"];

/// The output header: `input` (as found) then [`TIP_COLUMNS`] (and [`STATUS_COLUMNS`]
/// with `with_status`). Refuses an input column whose name (trimmed) the output adds.
///
/// ```
/// let h = ctr_analysis::formats::tip_header(&["label".into(), "s1_mm".into()], false).unwrap();
/// assert_eq!(h.join(","), "label,s1_mm,x_mm,y_mm,z_mm,qw,qx,qy,qz");
/// assert!(ctr_analysis::formats::tip_header(&["z_mm".into()], false).is_err());
/// ```
pub fn tip_header(input: &[String], with_status: bool) -> Result<Vec<String>, ErrorKind> {
    let added: Vec<&str> = TIP_COLUMNS
        .iter()
        .chain(if with_status {
            &STATUS_COLUMNS[..]
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

/// Formats a float with Rust's shortest round-trip representation: parsing the text
/// gives back the same `f64`, bit for bit (`-0` stays `-0`).
///
/// ```
/// let v = 0.1 + 0.2;
/// assert_eq!(ctr_analysis::formats::format_float(v).parse::<f64>().unwrap(), v);
/// ```
pub fn format_float(v: f64) -> String {
    format!("{v}")
}

/// Writes tip rows as CSV.
pub struct TipWriter<W: Write> {
    csv: csv::Writer<W>,
    with_status: bool,
}

impl<W: Write> TipWriter<W> {
    /// Writes `header` (from [`tip_header`]); `with_status` must match it.
    pub fn new(out: W, header: &[String], with_status: bool) -> Result<Self, ErrorKind> {
        let mut csv = csv::WriterBuilder::new().flexible(false).from_writer(out);
        csv.write_record(header).map_err(write_error)?;
        Ok(TipWriter { csv, with_status })
    }

    /// Writes one row: the input's raw fields, then the pose (and status, residual).
    pub fn write_row<'a>(
        &mut self,
        input_fields: impl IntoIterator<Item = &'a str>,
        fk: &FkResult,
    ) -> Result<(), ErrorKind> {
        for f in input_fields {
            self.csv.write_field(f).map_err(write_error)?;
        }
        for v in fk.position.iter().chain(fk.quaternion.iter()) {
            self.csv
                .write_field(format_float(*v))
                .map_err(write_error)?;
        }
        if self.with_status {
            self.csv
                .write_field(status_name(fk.status))
                .map_err(write_error)?;
            self.csv
                .write_field(format_float(fk.residual_per_mm))
                .map_err(write_error)?;
        }
        self.csv.write_record(None::<&[u8]>).map_err(write_error)
    }

    /// Flushes and returns the underlying writer.
    pub fn finish(self) -> Result<W, ErrorKind> {
        self.csv.into_inner().map_err(|e| ErrorKind::Io {
            action: "write",
            source: e.into_error(),
        })
    }
}

fn write_error(e: csv::Error) -> ErrorKind {
    let message = e.to_string();
    match e.into_kind() {
        csv::ErrorKind::Io(source) => ErrorKind::Io {
            action: "write",
            source,
        },
        _ => ErrorKind::Csv { message },
    }
}

//! The IK target CSV: one tip target per row, header `x_mm,y_mm,z_mm` and optionally
//! `qw,qx,qy,qz` (a pose target), as the contract's tip file (so the output of
//! `ctr-cli fk` is a target file); and the joint CSV that `ctr-cli ik` writes, with the
//! other columns carried through as the raw strings they were.

use super::csvout::write_float;
use super::table::{read_all, read_path, Columns, Header, Table};
use super::tips::{write_carried, Carried, CarriedColumns};
use crate::columnar::read::ParquetReader;
use crate::columnar::table::ParquetTable;
use crate::columnar::{is_parquet, Batch, Column, ColumnType, MAGIC};
use crate::error::{Error, ErrorKind, Location};
use crate::robot::{canonical_quaternion, joint_columns};
use ctr_core::Frame;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use std::borrow::Cow;
use std::io::Read;
use std::path::Path;

/// The target position columns, mm in W.
pub const TARGET_COLUMNS: [&str; 3] = ["x_mm", "y_mm", "z_mm"];

/// The optional target orientation columns: a unit quaternion `w, x, y, z` (either
/// sign) of the tip frame in W.
pub const ORIENTATION_COLUMNS: [&str; 4] = ["qw", "qx", "qy", "qz"];

/// How far from 1 a target quaternion's norm may be (it is then normalised).
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// How close in orientation the tip must come to a pose target to reach it, by default,
/// degrees: the default of `ctr-cli ik --orientation-tolerance-deg` and of `ctr_py`'s
/// `Robot.ik(orientation_tolerance_deg=)` (about the IK's own default of 1e-4 rad,
/// written in the files' unit).
pub const ORIENTATION_TOLERANCE_DEG: f64 = 0.0057;

/// What the tip should reach, in W.
///
/// ```
/// let t = ctr_formats::IkTarget::position([1.0, 2.0, 3.0]);
/// assert!(t.orientation.is_none());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkTarget {
    /// Tip position, mm.
    pub position: Vector3<f64>,
    /// Tip orientation (tube n's material frame at its tip); `None`: position only.
    pub orientation: Option<UnitQuaternion<f64>>,
}

impl IkTarget {
    /// A position-only target, mm.
    pub fn position(p: [f64; 3]) -> Self {
        IkTarget {
            position: Vector3::from(p),
            orientation: None,
        }
    }

    /// A full pose: position (mm) and orientation.
    pub fn pose(p: [f64; 3], orientation: UnitQuaternion<f64>) -> Self {
        IkTarget {
            position: Vector3::from(p),
            orientation: Some(orientation),
        }
    }

    /// The target of one row of values, as a target file's row is read: `x, y, z` (mm)
    /// or `x, y, z, qw, qx, qy, qz`, the quaternion of norm 1 within
    /// [`QUATERNION_NORM_TOLERANCE`] (then normalised). The values are finite.
    ///
    /// ```
    /// use ctr_formats::IkTarget;
    /// assert!(IkTarget::from_values(&[0.0, 0.0, 90.0, 1.0005, 0.0, 0.0, 0.0]).is_ok());
    /// let err = IkTarget::from_values(&[0.0, 0.0, 90.0, 2.0, 0.0, 0.0, 0.0]).unwrap_err();
    /// assert_eq!(err.to_string(), "qw,qx,qy,qz = 2, 0, 0, 0 has norm 2: expected a unit quaternion (norm 1 within 1e-3)");
    /// ```
    pub fn from_values(v: &[f64]) -> Result<IkTarget, ErrorKind> {
        let p = [v[0], v[1], v[2]];
        if v.len() < 7 {
            return Ok(IkTarget::position(p));
        }
        let q = [v[3], v[4], v[5], v[6]];
        let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
            return Err(ErrorKind::NotUnitQuaternion { q, norm });
        }
        let q = Quaternion::new(q[0], q[1], q[2], q[3]);
        Ok(IkTarget::pose(p, UnitQuaternion::from_quaternion(q)))
    }

    /// The pose of a tip frame.
    pub fn frame(tip: &Frame<f64>) -> Self {
        IkTarget {
            position: tip.position,
            orientation: Some(tip.orientation()),
        }
    }
}

/// What an IK output row adds to the carried input columns.
#[derive(Clone, Copy, Debug)]
pub struct IkRow<'a> {
    /// The joints, file units (mm, degrees).
    pub joints: &'a [f64],
    /// The tip reached.
    pub tip: &'a Frame<f64>,
    /// Distance from the tip to the target position, mm.
    pub residual_mm: f64,
    /// Angle between the tip and target orientations, rad (`None`: position only).
    pub orientation_residual_rad: Option<f64>,
    /// The status's name.
    pub status: &'a str,
}

/// An IK target file read and checked: every row has a finite position and, when the
/// file has the orientation columns, a unit quaternion. The raw fields of every row are
/// kept for carrying through.
#[derive(Clone, Debug)]
pub struct TargetTable {
    kind: TargetKind,
}

#[derive(Clone, Debug)]
enum TargetKind {
    Csv(Table),
    Parquet(ParquetTable),
}

impl TargetTable {
    /// Reads CSV from `reader` (or Parquet, when the bytes are a Parquet file's);
    /// `file` names it in errors. With `position_only`, the orientation columns, if
    /// any, are not read (position targets).
    ///
    /// ```
    /// use ctr_formats::TargetTable;
    /// let csv = "label,x_mm,y_mm,z_mm\na,1,2,90\nb,1,2,nan\n";
    /// let err = TargetTable::read(csv.as_bytes(), "t.csv", false).unwrap_err();
    /// assert_eq!(err.to_string(), "t.csv:3: column z_mm: \"nan\" is not a finite number");
    /// ```
    pub fn read<R: Read>(reader: R, file: &str, position_only: bool) -> Result<Self, Error> {
        let data = read_all(reader, file)?;
        TargetTable::from_bytes(data, file, position_only, 1)
    }

    /// Reads CSV from a whole file's bytes (or Parquet, when they are a Parquet
    /// file's); the numbers are parsed and checked on `threads` threads (0 = all
    /// cores), the error reported being the first in the file.
    pub fn from_bytes(
        data: Vec<u8>,
        file: &str,
        position_only: bool,
        threads: usize,
    ) -> Result<Self, Error> {
        if data.starts_with(MAGIC) {
            let reader = ParquetReader::from_bytes(data, file)?;
            return Self::parquet(reader, position_only);
        }
        let (required, orientation) = target_columns();
        let columns = Columns {
            required: &required,
            optional: (!position_only).then_some((&orientation[..], "an orientation target")),
        };
        let row_check = |v: &[f64], line: usize| {
            IkTarget::from_values(v)
                .map(drop)
                .map_err(|kind| Error::new(Location::line(file, line), kind))
        };
        let table = Table::read(data, file, &columns, |_| Ok(()), row_check, threads)?;
        Ok(TargetTable {
            kind: TargetKind::Csv(table),
        })
    }

    fn parquet(reader: ParquetReader, position_only: bool) -> Result<Self, Error> {
        let file = reader.file().to_owned();
        let (required, orientation) = target_columns();
        let columns = Columns {
            required: &required,
            optional: (!position_only).then_some((&orientation[..], "an orientation target")),
        };
        let row_check = |v: &[f64], row: usize| {
            IkTarget::from_values(v)
                .map(drop)
                .map_err(|kind| Error::new(Location::row(&file, row), kind))
        };
        let table = ParquetTable::read(reader, &columns, |_| Ok(()), row_check)?;
        Ok(TargetTable {
            kind: TargetKind::Parquet(table),
        })
    }

    /// Reads a target file; errors name the path as given. Parquet when its name ends
    /// in `.parquet` or its bytes start as a Parquet file's; else CSV.
    pub fn from_path(path: &Path, position_only: bool) -> Result<Self, Error> {
        if is_parquet(path) {
            return Self::parquet(ParquetReader::open(path)?, position_only);
        }
        let (file, data) = read_path(path)?;
        TargetTable::from_bytes(data, &file, position_only, 1)
    }

    /// The file name used in errors.
    pub fn file(&self) -> &str {
        match &self.kind {
            TargetKind::Csv(t) => &t.file,
            TargetKind::Parquet(t) => &t.file,
        }
    }

    /// The header as found (a CSV file's names untrimmed; a Parquet file's columns).
    pub fn header(&self) -> &[String] {
        &self.head().names
    }

    fn head(&self) -> &Header {
        match &self.kind {
            TargetKind::Csv(t) => &t.header,
            TargetKind::Parquet(t) => &t.header,
        }
    }

    /// Number of data rows.
    pub fn len(&self) -> usize {
        match &self.kind {
            TargetKind::Csv(t) => t.len(),
            TargetKind::Parquet(t) => t.len(),
        }
    }

    /// True when the file has a header only.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Where data row `row` (0-based) is: its 1-based line in a CSV file, or its
    /// 1-based row in a Parquet file ([`TargetTable::is_rows`]).
    pub fn line(&self, row: usize) -> usize {
        match &self.kind {
            TargetKind::Csv(t) => t.line(row),
            TargetKind::Parquet(_) => row + 1,
        }
    }

    /// True when [`line`](Self::line) gives rows of a Parquet file, not lines.
    pub fn is_rows(&self) -> bool {
        matches!(self.kind, TargetKind::Parquet(_))
    }

    /// The raw fields of data row `row`, all columns in header order (a Parquet file's
    /// cells as CSV writes them).
    pub fn fields(&self, row: usize) -> Box<dyn Iterator<Item = Cow<'_, str>> + '_> {
        match &self.kind {
            TargetKind::Csv(t) => Box::new(t.fields(row).map(Cow::Borrowed)),
            TargetKind::Parquet(t) => Box::new(t.columns.iter().map(move |c| c.text(row))),
        }
    }

    /// True when the targets are poses (the file has `qw,qx,qy,qz` and they are read).
    pub fn has_orientation(&self) -> bool {
        self.head().has_optional
    }

    /// The target of data row `row` (its quaternion normalised).
    pub fn target(&self, row: usize) -> IkTarget {
        let values = match &self.kind {
            TargetKind::Csv(t) => t.values(row),
            TargetKind::Parquet(t) => t.values(row),
        };
        IkTarget::from_values(values)
            .expect("every row passed IkTarget::from_values when the file was read")
    }

    /// All targets, in row order.
    pub fn targets(&self) -> Vec<IkTarget> {
        (0..self.len()).map(|r| self.target(r)).collect()
    }

    /// Row `row`'s fields at the indices `keep` (increasing).
    pub fn carried<'a>(
        &'a self,
        row: usize,
        keep: &'a [usize],
    ) -> Carried<'a, impl Iterator<Item = &'a str>> {
        let table = match &self.kind {
            TargetKind::Csv(t) => t,
            TargetKind::Parquet(t) => {
                return Carried::Columns(CarriedColumns {
                    columns: &t.columns,
                    keep: Some(keep),
                    row,
                })
            }
        };
        let mut next = 0;
        Carried::Fields(table.fields(row).enumerate().filter_map(move |(i, f)| {
            if keep.get(next) == Some(&i) {
                next += 1;
                Some(f)
            } else {
                None
            }
        }))
    }

    /// The columns at the indices `keep` of every row, for a Parquet output: their
    /// types and the rows. A Parquet file's keep their own type; a CSV file's are made
    /// as [`ColumnType::carried_csv`] says (a cell that is not the number its column
    /// wants is refused with its line).
    pub fn carried_columns(&self, keep: &[usize]) -> Result<(Vec<ColumnType>, Batch), Error> {
        let (types, columns): (Vec<ColumnType>, Vec<Column>) = match &self.kind {
            TargetKind::Csv(t) => {
                let mut all = t.columns()?;
                let header = &t.header;
                keep.iter()
                    .map(|&i| {
                        let name = &header.names[i];
                        let ty = if header.index.contains(&i) {
                            ColumnType::double(name)
                        } else {
                            ColumnType::carried_csv(name)
                        };
                        (
                            ty,
                            std::mem::replace(&mut all[i], Column::doubles(Vec::new())),
                        )
                    })
                    .unzip()
            }
            TargetKind::Parquet(t) => keep
                .iter()
                .map(|&i| (ColumnType(t.types[i].clone()), t.columns[i].clone()))
                .unzip(),
        };
        Ok((types, Batch(columns)))
    }
}

/// The target columns: the required position, the optional orientation.
fn target_columns() -> (Vec<String>, Vec<String>) {
    let owned = |c: &[&str]| c.iter().map(|s| (*s).to_owned()).collect();
    (owned(&TARGET_COLUMNS), owned(&ORIENTATION_COLUMNS))
}

/// The columns `ctr-cli ik` adds after the input's: the joints (file units), the tip
/// reached, the distance to the target, the status. Pose targets add the orientation
/// reached and its angle to the target:
///
/// `s1_mm,theta1_deg,...,reached_x_mm,reached_y_mm,reached_z_mm[,reached_qw,reached_qx,
/// reached_qy,reached_qz],residual_mm[,orientation_residual_deg],status`
///
/// ```
/// let c = ctr_formats::ik_columns(2, false);
/// assert_eq!(c.join(","), "s1_mm,theta1_deg,s2_mm,theta2_deg,reached_x_mm,reached_y_mm,reached_z_mm,residual_mm,status");
/// ```
pub fn ik_columns(n_tubes: usize, pose: bool) -> Vec<String> {
    let mut c = joint_columns(n_tubes);
    c.extend(["reached_x_mm", "reached_y_mm", "reached_z_mm"].map(String::from));
    if pose {
        c.extend(["reached_qw", "reached_qx", "reached_qy", "reached_qz"].map(String::from));
    }
    c.push("residual_mm".into());
    if pose {
        c.push("orientation_residual_deg".into());
    }
    c.push("status".into());
    c
}

/// Which input columns an IK output carries, and its header.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IkOutputColumns {
    /// Indices of the input columns carried, in order.
    pub carried: Vec<usize>,
    /// The output header: the carried columns (as found), then [`ik_columns`].
    pub header: Vec<String>,
}

/// The IK output's columns for a target file with header `input`: every input column
/// is carried through except the targets themselves (`x_mm,y_mm,z_mm` and
/// `qw,qx,qy,qz`) and columns named like one the output adds (the joints of the `fk`
/// run that made the tips, or the columns of an earlier `ik` run), which the output's
/// own replace. So a tip file from `ctr-cli fk` is a target file, and `ctr-cli fk`
/// reads the output.
///
/// ```
/// use ctr_formats::ik_output_columns;
/// let input: Vec<String> = "label,s1_mm,theta1_deg,x_mm,y_mm,z_mm,qw,qx,qy,qz"
///     .split(',').map(String::from).collect();
/// let c = ik_output_columns(&input, 1, false);
/// assert_eq!(c.carried, [0]);
/// assert_eq!(c.header.join(","), "label,s1_mm,theta1_deg,reached_x_mm,reached_y_mm,reached_z_mm,residual_mm,status");
/// ```
pub fn ik_output_columns(input: &[String], n_tubes: usize, pose: bool) -> IkOutputColumns {
    let added = ik_columns(n_tubes, pose);
    let consumed = |name: &str| {
        TARGET_COLUMNS.contains(&name)
            || ORIENTATION_COLUMNS.contains(&name)
            || added.iter().any(|a| a == name)
    };
    let carried: Vec<usize> = (0..input.len())
        .filter(|&i| !consumed(input[i].trim()))
        .collect();
    let header = carried
        .iter()
        .map(|&i| input[i].clone())
        .chain(added)
        .collect();
    IkOutputColumns { carried, header }
}

/// The types of [`ik_columns`] for a Parquet output: doubles, `status` text.
///
/// ```
/// let t = ctr_formats::ik_column_types(1, false);
/// assert_eq!(t.last().unwrap().name(), "status");
/// assert_eq!(t.len(), ctr_formats::ik_columns(1, false).len());
/// ```
pub fn ik_column_types(n_tubes: usize, pose: bool) -> Vec<ColumnType> {
    ik_columns(n_tubes, pose)
        .iter()
        .map(|c| {
            if c == "status" {
                ColumnType::text(c)
            } else {
                ColumnType::double(c)
            }
        })
        .collect()
}

/// The values of IK output rows as the columns of [`ik_column_types`] (what
/// [`write_ik_row`] writes after the carried input).
pub fn ik_batch(rows: &[IkRow<'_>], pose: bool) -> Batch {
    let mut batch = Batch::default();
    let width = rows.first().map_or(0, |r| r.joints.len());
    for j in 0..width {
        batch.push_doubles(rows.iter().map(|r| r.joints[j]).collect());
    }
    for k in 0..3 {
        batch.push_doubles(rows.iter().map(|r| r.tip.position[k]).collect());
    }
    if pose {
        let quaternions: Vec<[f64; 4]> = rows.iter().map(reached_quaternion).collect();
        for k in 0..4 {
            batch.push_doubles(quaternions.iter().map(|q| q[k]).collect());
        }
    }
    batch.push_doubles(rows.iter().map(|r| r.residual_mm).collect());
    if pose {
        let degrees = |r: &IkRow<'_>| r.orientation_residual_rad.unwrap_or(f64::NAN).to_degrees();
        batch.push_doubles(rows.iter().map(degrees).collect());
    }
    batch.push_texts(rows.iter().map(|r| r.status));
    batch
}

/// The orientation a row's tip reached (NaN where its frame is not finite).
fn reached_quaternion(r: &IkRow<'_>) -> [f64; 4] {
    if r.tip.rotation.iter().all(|v| v.is_finite()) {
        canonical_quaternion(&r.tip.orientation())
    } else {
        [f64::NAN; 4]
    }
}

/// Appends one IK output row: the carried input, then `r` (for pose targets with the
/// tip's orientation and the orientation residual in degrees).
pub fn write_ik_row<'a, I: Iterator<Item = &'a str>>(
    out: &mut Vec<u8>,
    input: Carried<'a, I>,
    r: &IkRow<'_>,
    pose: bool,
) {
    write_carried(out, input);
    for v in r.joints {
        write_float(out, *v);
        out.push(b',');
    }
    for v in r.tip.position.iter() {
        write_float(out, *v);
        out.push(b',');
    }
    if pose {
        for v in reached_quaternion(r) {
            write_float(out, v);
            out.push(b',');
        }
    }
    write_float(out, r.residual_mm);
    out.push(b',');
    if pose {
        write_float(
            out,
            r.orientation_residual_rad.unwrap_or(f64::NAN).to_degrees(),
        );
        out.push(b',');
    }
    out.extend_from_slice(r.status.as_bytes());
    out.push(b'\n');
}

//! The IK target CSV: one tip target per row, header `x_mm,y_mm,z_mm` and optionally
//! `qw,qx,qy,qz` (a pose target), as the contract's tip file (so the output of
//! `ctr-cli fk` is a target file); and the joint CSV that `ctr-cli ik` writes, with the
//! other columns carried through as the raw strings they were.

use super::csvout::write_float;
use super::table::{read_all, read_path, table_rows, Columns, Table};
use super::tips::{write_carried, Carried};
use crate::error::{Error, ErrorKind, Location};
use crate::robot::{canonical_quaternion, joint_columns};
use ctr_core::Frame;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
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
    table: Table,
}

impl TargetTable {
    table_rows!();

    /// Reads CSV from `reader`; `file` names it in errors. With `position_only`, the
    /// orientation columns, if any, are not read (position targets).
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

    /// Reads CSV from a whole file's bytes; the numbers are parsed and checked on
    /// `threads` threads (0 = all cores), the error reported being the first in the file.
    pub fn from_bytes(
        data: Vec<u8>,
        file: &str,
        position_only: bool,
        threads: usize,
    ) -> Result<Self, Error> {
        let required: Vec<String> = TARGET_COLUMNS.iter().map(|s| (*s).to_owned()).collect();
        let orientation: Vec<String> = ORIENTATION_COLUMNS
            .iter()
            .map(|s| (*s).to_owned())
            .collect();
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
        Ok(TargetTable { table })
    }

    /// Reads a target file; errors name the path as given.
    pub fn from_path(path: &Path, position_only: bool) -> Result<Self, Error> {
        let (file, data) = read_path(path)?;
        TargetTable::from_bytes(data, &file, position_only, 1)
    }

    /// True when the targets are poses (the file has `qw,qx,qy,qz` and they are read).
    pub fn has_orientation(&self) -> bool {
        self.table.header.has_optional
    }

    /// The target of data row `row` (its quaternion normalised).
    pub fn target(&self, row: usize) -> IkTarget {
        IkTarget::from_values(self.table.values(row))
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
        let mut next = 0;
        Carried::Fields(
            self.table
                .fields(row)
                .enumerate()
                .filter_map(move |(i, f)| {
                    if keep.get(next) == Some(&i) {
                        next += 1;
                        Some(f)
                    } else {
                        None
                    }
                }),
        )
    }
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
        let q = if r.tip.rotation.iter().all(|v| v.is_finite()) {
            canonical_quaternion(&r.tip.orientation())
        } else {
            [f64::NAN; 4]
        };
        for v in q {
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

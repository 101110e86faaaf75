//! The joint CSV: one configuration per row, header `s1_mm,theta1_deg,...`, other
//! columns carried through as the raw strings they were.

use super::table::{read_all, read_path, table_rows, Columns, Table};
use crate::error::Error;
use crate::joint_stream::{column_beyond, joint_check};
use crate::robot::{joint_columns, AnyRobot};
use std::io::Read;
use std::path::Path;

/// A joint file read and checked against a robot: every row has finite joints the robot
/// can take. The raw fields of every row are kept for carrying through.
#[derive(Clone, Debug)]
pub struct JointTable {
    table: Table,
    n_tubes: usize,
}

impl JointTable {
    table_rows!();

    /// Reads CSV from `reader`; `file` names it in errors.
    ///
    /// ```
    /// use ctr_formats::{AnyRobot, JointTable};
    /// let t = ctr_core::TubeParams::<f64>::new(1.8, 1.5, 180.0, 60.0, 58000.0, 0.33);
    /// let robot = AnyRobot::new(&[t]).unwrap();
    /// let csv = "label,s1_mm,theta1_deg\na,10,0\nb,20,abc\n";
    /// let err = JointTable::read(csv.as_bytes(), "j.csv", &robot).unwrap_err();
    /// assert_eq!(err.to_string(), "j.csv:3: column theta1_deg: \"abc\" is not a number");
    /// ```
    pub fn read<R: Read>(reader: R, file: &str, robot: &AnyRobot) -> Result<JointTable, Error> {
        let data = read_all(reader, file)?;
        JointTable::from_bytes(data, file, robot, 1)
    }

    /// Reads CSV from a whole file's bytes (kept: rows point into them); `file` names
    /// it in errors. The numbers are parsed and checked on `threads` threads (0 = all
    /// cores); the error reported is the first in the file whatever the count.
    pub fn from_bytes(
        data: Vec<u8>,
        file: &str,
        robot: &AnyRobot,
        threads: usize,
    ) -> Result<JointTable, Error> {
        let n = robot.n_tubes();
        let required = joint_columns(n);
        let columns = Columns {
            required: &required,
            optional: None,
        };
        let header_check = |name: &str| column_beyond(name, n);
        let row_check = joint_check(robot, file, false);
        let table = Table::read(data, file, &columns, header_check, row_check, threads)?;
        Ok(JointTable { table, n_tubes: n })
    }

    /// Reads a joint file; errors name the path as given. (One thread; see
    /// [`from_bytes`](Self::from_bytes) for more.)
    pub fn from_path(path: &Path, robot: &AnyRobot) -> Result<JointTable, Error> {
        let (file, data) = read_path(path)?;
        JointTable::from_bytes(data, &file, robot, 1)
    }

    /// The 1-based line of the header.
    pub fn header_line(&self) -> usize {
        self.table.header.line()
    }

    /// The index of the column named `name` (header names trimmed), if present.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.table
            .header
            .names
            .iter()
            .position(|h| h.trim() == name)
    }

    /// The raw field of data row `row` in column `column` (an index into the header).
    pub fn field(&self, row: usize, column: usize) -> &str {
        self.table.fields(row).nth(column).unwrap_or_default()
    }

    /// The robot's tube count the table was checked against.
    pub fn n_tubes(&self) -> usize {
        self.n_tubes
    }

    /// Data row `row`'s fields as CSV text, when it can be copied as it was (see
    /// `Table::plain_line`).
    pub fn plain_line(&self, row: usize) -> Option<&str> {
        self.table.plain_line(row)
    }

    /// The joints of data row `row` in file order (`s1_mm, theta1_deg, ...`).
    pub fn joints(&self, row: usize) -> &[f64] {
        self.table.values(row)
    }

    /// All rows' joints, row after row (`2 * n_tubes()` values per row).
    pub fn all_joints(&self) -> &[f64] {
        &self.table.values
    }
}

//! One error type for everything read or written: where it happened and what was wrong.
//!
//! Every [`Error`] displays as a single line, `file[:line[:column]]: what was found and
//! what was wanted`, for example
//! `joints.csv:17: column theta2_deg: "abc" is not a number` or
//! `robot.toml:12:1: unknown field `youngs_modulus`, expected one of ...`.
//! Lines are 1-based and count the CSV header as line 1. A Parquet file has rows, not
//! lines: `joints.parquet: row 17: column s1_mm: ...`, rows 1-based (the first row of
//! data is row 1).

use ctr_core::{JointError, RobotError, Status};
use std::fmt;

/// Where in an input (or output) an error is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Location {
    /// The file as the user named it (`<stdin>` / `<stdout>` for the streams).
    pub file: String,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// 1-based column (characters for TOML), when known.
    pub column: Option<usize>,
    /// `line` is a 1-based row of a table without lines (a Parquet file's), not a
    /// line of text.
    pub is_row: bool,
}

impl Location {
    /// A whole file.
    pub fn file(file: impl Into<String>) -> Self {
        Location {
            file: file.into(),
            line: None,
            column: None,
            is_row: false,
        }
    }

    /// A line of a file.
    pub fn line(file: impl Into<String>, line: usize) -> Self {
        Location {
            file: file.into(),
            line: Some(line),
            column: None,
            is_row: false,
        }
    }

    /// A row of a table without lines (a Parquet file), 1-based.
    ///
    /// ```
    /// let at = ctr_formats::Location::row("j.parquet", 17);
    /// assert_eq!(at.to_string(), "j.parquet: row 17");
    /// ```
    pub fn row(file: impl Into<String>, row: usize) -> Self {
        Location {
            is_row: true,
            ..Location::line(file, row)
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.file)?;
        if let (Some(row), true) = (self.line, self.is_row) {
            return write!(f, ": row {row}");
        }
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
            if let Some(col) = self.column {
                write!(f, ":{col}")?;
            }
        }
        Ok(())
    }
}

/// What went wrong; displayed after the [`Location`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ErrorKind {
    /// Reading, creating, writing or renaming failed.
    #[error("cannot {action}: {source}")]
    Io {
        /// what was being done ("read", "create the output in", ...)
        action: &'static str,
        /// the operating system's error
        #[source]
        source: std::io::Error,
    },
    /// The TOML is malformed or does not have the expected shape (unknown key, missing
    /// field, wrong type).
    #[error("{message}")]
    Toml {
        /// the parser's message, made one line
        message: String,
    },
    /// The tube parameters are refused by the core (the message names tube and field).
    #[error("{0}")]
    Robot(RobotError),
    /// An effect table of `[model.effects]` does not fit the robot (the message names
    /// the key, what was found and what was wanted).
    #[error("{message}")]
    Effect {
        /// the message, starting with the key path (`model.effects.friction.rotation_play_deg: ...`)
        message: String,
    },
    /// `[limits]` has a different number of `[[limits.tube]]` tables than the robot has tubes.
    #[error("limits: {found} [[limits.tube]] table{}, the robot has {expected} tube{}", if *.found == 1 { "" } else { "s" }, if *.expected == 1 { "" } else { "s" })]
    LimitsCount {
        /// the robot's tube count
        expected: usize,
        /// tables found
        found: usize,
    },
    /// A `[min, max]` range of `[limits]` is not finite or has `min > max`.
    #[error("limits.tube {tube}: {key} = [{min}, {max}] must be finite with min <= max")]
    BadLimit {
        /// tube number, 1 = outermost
        tube: usize,
        /// the key (`s_mm`, `increment_mm`, `theta_deg`)
        key: &'static str,
        /// lower bound found
        min: f64,
        /// upper bound found
        max: f64,
    },
    /// The directory an output file is to be written in does not exist.
    #[error("directory {dir} does not exist")]
    OutputDirectory {
        /// the directory
        dir: String,
    },
    /// A CSV file has no header at all.
    #[error("empty file, expected a header with {expected}")]
    EmptyFile {
        /// the required columns, comma separated
        expected: String,
    },
    /// A required column is not in the header.
    #[error("missing column {name}{}", match .similar {
        Some(s) => format!(" (found \"{s}\": did you mean {name}?)"),
        None => format!(" (the header needs {})", .required),
    })]
    MissingColumn {
        /// the column wanted
        name: String,
        /// a header name close to it, probably misspelt
        similar: Option<String>,
        /// all required columns, comma separated
        required: String,
    },
    /// Two header columns have the same name.
    #[error("column {name} appears twice")]
    DuplicateColumn {
        /// the repeated name
        name: String,
    },
    /// A joint column for a tube the robot does not have (wrong robot file?).
    #[error("column {name}: the robot has {n_tubes} tube{}", if *.n_tubes == 1 { "" } else { "s" })]
    ColumnBeyondRobot {
        /// the column
        name: String,
        /// the robot's tube count
        n_tubes: usize,
    },
    /// An input column has the name of a column the output adds.
    #[error("column {name} clashes with the output column of that name; rename or drop it")]
    OutputColumnClash {
        /// the column
        name: String,
    },
    /// A joint cell does not parse as a number.
    #[error("column {column}: \"{found}\" is not a number")]
    NotANumber {
        /// the column
        column: String,
        /// the cell as found
        found: String,
    },
    /// A joint cell is NaN or infinite.
    #[error("column {column}: \"{found}\" is not a finite number")]
    NotFinite {
        /// the column
        column: String,
        /// the cell as found
        found: String,
    },
    /// A target or measured orientation `qw,qx,qy,qz` is not a unit quaternion.
    #[error("qw,qx,qy,qz = {}, {}, {}, {} has norm {norm}: expected a unit quaternion (norm 1 within 1e-3)", .q[0], .q[1], .q[2], .q[3])]
    NotUnitQuaternion {
        /// the quaternion as read, `w, x, y, z`
        q: [f64; 4],
        /// its norm
        norm: f64,
    },
    /// A measured tangent `tx,ty,tz` of a recording is not a unit vector.
    #[error("tx,ty,tz = {}, {}, {} has norm {norm}: expected a unit tangent (norm 1 within 1e-3)", .t[0], .t[1], .t[2])]
    NotUnitTangent {
        /// the tangent as read, `x, y, z`
        t: [f64; 3],
        /// its norm
        norm: f64,
    },
    /// The inverse kinematics cannot be set up for the robot (its limits leave no
    /// joint vector) or with the options given (the solver's own error, kept as the
    /// source).
    #[error("{0}")]
    Ik(Box<dyn std::error::Error + Send + Sync>),
    /// A row has a different number of fields than the header.
    #[error("row has {found} field{}, the header has {expected}", if *.found == 1 { "" } else { "s" })]
    RaggedRow {
        /// fields in this row
        found: usize,
        /// fields in the header
        expected: usize,
    },
    /// Other CSV trouble (invalid UTF-8, ...).
    #[error("{message}")]
    Csv {
        /// the csv crate's message
        message: String,
    },
    /// A column of a Parquet file has a type that cannot hold what is wanted there.
    #[error("column {column}: {found}, wanted {wanted}")]
    ColumnType {
        /// the column
        column: String,
        /// its type, in words (`BYTE_ARRAY (STRING)`)
        found: String,
        /// what it must hold
        wanted: &'static str,
    },
    /// A cell of a column that needs a value has none (a Parquet null).
    #[error("column {column}: no value (null)")]
    NullValue {
        /// the column
        column: String,
    },
    /// A Parquet file could not be read or written (not Parquet, damaged, a codec
    /// this build does not have).
    #[error("{message}")]
    Parquet {
        /// what failed, and the parquet crate's message
        message: String,
    },
    /// Joint values the robot cannot take (the message names the column).
    #[error("{0}")]
    Joint(JointError),
    /// A solve did not converge and the policy is to fail; the location is the first such row.
    #[error("solve ended with status {} (residual_per_mm = {residual_per_mm}); {failed} of {rows} row{} failed", status_name(*.status), if *.rows == 1 { "" } else { "s" })]
    SolverFailed {
        /// status of the first failed row
        status: Status,
        /// its residual, rad/mm
        residual_per_mm: f64,
        /// rows that failed
        failed: usize,
        /// rows solved
        rows: usize,
    },
}

/// An error with its location; displays as one line. (Boxed: errors are rare and the
/// `Result`s that carry them stay small.)
#[derive(Debug)]
pub struct Error(Box<Inner>);

#[derive(Debug)]
struct Inner {
    location: Location,
    kind: ErrorKind,
}

impl Error {
    /// An error at `location`.
    pub fn new(location: Location, kind: ErrorKind) -> Self {
        Error(Box::new(Inner { location, kind }))
    }

    /// Where.
    pub fn location(&self) -> &Location {
        &self.0.location
    }

    /// What.
    pub fn kind(&self) -> &ErrorKind {
        &self.0.kind
    }

    /// True when the input was fine but solves did not converge (the CLI exits 1, not 2).
    pub fn is_solver_failure(&self) -> bool {
        matches!(self.0.kind, ErrorKind::SolverFailed { .. })
    }
}

impl fmt::Display for Error {
    /// One line: line breaks in what the kind quotes from the input (a quoted CSV cell,
    /// a header name, a run label) are written `\n` and `\r`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = self.0.kind.to_string();
        if what.contains(['\n', '\r']) {
            let what = what.replace('\r', "\\r").replace('\n', "\\n");
            write!(f, "{}: {what}", self.0.location)
        } else {
            write!(f, "{}: {what}", self.0.location)
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        std::error::Error::source(&self.0.kind)
    }
}

/// The name of a status as written in files and messages: `converged`,
/// `iteration_limit`, `diverged`.
///
/// ```
/// assert_eq!(ctr_formats::status_name(ctr_core::Status::IterationLimit), "iteration_limit");
/// ```
pub fn status_name(status: Status) -> &'static str {
    match status {
        Status::Converged => "converged",
        Status::IterationLimit => "iteration_limit",
        Status::Diverged => "diverged",
    }
}

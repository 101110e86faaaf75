//! # ctr-formats
//!
//! File formats: the robot TOML, the joint CSV, the tip CSV, the IK target and joint
//! CSVs, the recording (read for the diagnosis, written by the rig), each table also
//! as Parquet, the actuation schema, the labelled data-driven corrections a diagnosis
//! writes into a robot file, atomic output; the located errors every reader and writer
//! gives ([`Error`]); the robot whose tube count a file decides ([`AnyRobot`]); and the
//! project's one thread pool ([`parallel`]), which the readers are the first to use.
//!
//! A leaf above `ctr-core`: the analysis, the diagnosis, the servo rig (`ctr-hw`) and
//! both front ends read and write through it, and it depends on none of them.
//!
//! The contract is `docs/formats.md`; everything it describes is read and written
//! as it says. This module adds three optional sections to the robot TOML and columns to
//! the recording (also described in `data/FORMATS-EXTENSION.md`); files without them
//! mean what they always meant.
//!
//! # Robot TOML
//!
//! Top-level keys: `name` (string, optional), `[[tube]]` (1 to 4 tables, outermost
//! first, keys exactly those of the contract plus an optional `name`), and the
//! extensions `[model]`, `[limits]` and `[actuation]`. Unknown keys anywhere are refused with the line
//! and column of the key and the list of keys expected there.
//!
//! ## `[model]`: the mechanics a file's robot is solved with
//!
//! ```toml
//! [model]
//! kind = "torsion"          # "rigid" | "torsion"; default "torsion" (also without [model])
//!
//! [model.effects]           # optional: effects beyond the base model, keyed by the
//!                           # contract's effect ids
//! # gravity = { direction_W = [-1.0, 0.0, 0.0], g_m_s2 = 9.81 }
//! ```
//!
//! `[model.effects]` holds one typed table per effect id of the contract (`torsion` is
//! `kind`): `joint_offset`, `latency`, `friction`, `clearance`, `gravity`, `stiffness`,
//! `precurvature`, `sensor_offset`, `registration`, and this project's
//! `sensor_rotation`; their keys and the order they act in are documented in
//! [`Effects`]'s module (`formats::effects`) and `data/FORMATS-EXTENSION.md`. Beside
//! them, two labelled corrections that are not physics: `[model.empirical]`
//! ([`Correction`], linear in a fixed basis of the row's features) and
//! `[model.discrepancy]` ([`Discrepancy`], a Gaussian process over the joints and their
//! history), which `ctr-cli diagnose --with-empirical` writes. A fitted model is written
//! back as a robot file with its `[model]` ([`RobotSpec::to_toml`]) and read by every
//! command as is.
//!
//! A `--model` given on the command line overrides `kind`.
//!
//! ## `[limits]`: joint ranges (for inverse kinematics and planning)
//!
//! ```toml
//! [[limits.tube]]                 # tube 1 (outermost); one table per tube, in order
//! s_mm = [20.0, 70.0]             # feed s_i, mm, closed [min, max]
//! theta_deg = [-180.0, 180.0]     # rotation, degrees
//!
//! [[limits.tube]]                 # tube 2
//! increment_mm = [25.0, 95.0]     # s_i - s_(i-1), mm (s_0 = 0)
//! ```
//!
//! Every key is optional (absent: unlimited); a range must be finite with
//! `min <= max`, and there must be exactly one table per tube. Forward kinematics does
//! not enforce the limits (the core's own checks, `0 <= s_1 <= ... <= s_n <= length`,
//! always apply); see [`TubeLimits::violation`].
//!
//! ## `[actuation]`: the motor behind each joint (for `ctr-cli hw`)
//!
//! ```toml
//! [[actuation.joint]]
//! name = "s1"               # feed of tube 1: drives column s1_mm (kind "feed", mm)
//! motor_id = 1              # Dynamixel ID, 0..=252, one joint per motor
//! kind = "feed"
//! mm_per_rev = 8.0          # feed only, required: mm per motor revolution
//! ticks_per_rev = 4096      # default 4096
//! direction = 1             # 1: motor position grows with the joint; -1: the opposite
//! zero_offset_ticks = 0     # motor position at joint value 0; default 0
//! min = 0.0                 # joint limits in mm (feed) or degrees (rotation), inclusive
//! max = 100.0
//! max_speed = 6.0           # mm/s or deg/s: the motor's profile velocity
//!
//! [[actuation.joint]]
//! name = "theta1"           # rotation of tube 1: drives column theta1_deg (kind "rotation")
//! motor_id = 2
//! kind = "rotation"
//! gear_ratio = 1.0          # rotation only: motor revolutions per tube revolution; default 1
//! min = -180.0
//! max = 180.0
//! max_speed = 180.0
//! ```
//!
//! One table per joint and one joint per table: a feed joint `s{i}` and a rotation joint
//! `theta{i}` for every tube i of the robot, in any order. The name ties a table to its
//! joint column (`s{i}` to `s{i}_mm`, `theta{i}` to `theta{i}_deg`) and fixes its kind;
//! the joint value, in the column's unit, is what the motor mapping converts:
//! `ticks = zero_offset_ticks + direction * round(value * u * ticks_per_rev)` with `u`
//! the motor revolutions per unit (`1 / mm_per_rev`, or `gear_ratio / 360`). The tables
//! are [`ActuatedJoint`]s, the structs `ctr-hw` drives its motors with. A validated robot keeps
//! them in joint-vector order ([`RobotSpec::actuation`]: `s1, theta1, s2, ...`) and
//! writes them back in that order. Errors name the table (`actuation.joint 3`), the
//! key and its line and column: unknown or missing keys, names that are not a joint of
//! the robot, a joint actuated twice or not at all, a kind that does not fit the name,
//! a motor ID used twice or above 252, `direction` other than 1 or -1, `mm_per_rev` on a
//! rotation or `gear_ratio` on a feed, non-positive leads, ratios, tick counts or
//! speeds, non-finite limits, `min > max`, limits beyond the motor's 32-bit range.
//! Forward kinematics ignores the section; `ctr-cli hw` refuses robots without it.
//!
//! # Joint CSV and tip CSV
//!
//! [`JointTable`] reads the joint file: the header must name `s1_mm,theta1_deg,...` for
//! every tube of the robot (any order, among other columns); columns for tubes the robot
//! does not have are refused, as are duplicate names. Cells are trimmed and parsed as
//! `f64`; NaN and infinities are refused; each row is checked against the robot by the
//! core. Empty lines are skipped. A header without rows is a valid, empty table.
//!
//! [`TipWriter`] writes every input column as it was read (the field's text unchanged;
//! quotes only where CSV needs them) followed by [`TIP_COLUMNS`]
//! `x_mm,y_mm,z_mm,qw,qx,qy,qz` and, when rows are marked, [`STATUS_COLUMNS`]
//! `status,residual_per_mm` (`converged`, `iteration_limit`, `diverged`). Floats are
//! written in Rust's shortest round-trip form ([`format_float`]): parsing the text gives
//! the computed `f64` back bit for bit.
//!
//! # Target CSV and IK joint CSV
//!
//! [`TargetTable`] reads the targets of inverse kinematics: the contract's tip file,
//! [`TARGET_COLUMNS`] `x_mm,y_mm,z_mm` and optionally [`ORIENTATION_COLUMNS`]
//! `qw,qx,qy,qz` (all four or none; a unit quaternion within
//! [`QUATERNION_NORM_TOLERANCE`]), checked as the joint file is. The output
//! ([`ik_output_columns`]) carries the input's other columns, replaces columns named
//! like its own, and adds [`ik_columns`]: the joints, the tip reached, `residual_mm`
//! (and `orientation_residual_deg` for poses) and `status`; it is a joint file that
//! `ctr-cli fk` reads.
//!
//! Both input tables keep the file's bytes and point into them; rows without quotes are
//! split here, rows with quotes are read by the csv crate, with exactly the csv crate's
//! reading either way, and their numbers are parsed in parallel (the error reported is
//! the first in the file). Output rows are formatted into byte buffers, floats with
//! `ryu` laid out as Rust's `Display` writes them.
//!
//! [`JointStream`] reads a joint file of any size in bounded memory: blocks of the file
//! are cut into pieces of whole records on one thread (only line ends and quotes are
//! looked at there), and each piece is parsed and checked where it is worked on, with
//! the same rows, fields, values and errors as [`JointTable`]. A file that is not text
//! (Parquet, gzip, a spreadsheet's workbook, UTF-16) is named as such instead of being
//! refused as "not valid UTF-8 text".
//!
//! # Recording CSV (read by the diagnosis)
//!
//! [`Recording`] reads the contract's recording: the robot's joint columns and
//! `x_mm,y_mm,z_mm`, and optionally `t_s`, `run` (rows with one label are one
//! contiguous run), the measured orientation `qw,qx,qy,qz` or tangent `tx,ty,tz`
//! ([`AngularColumns`]) and a known tip force `fx_n,fy_n,fz_n`; a label that starts
//! again after other rows, or a time that decreases within a run, is refused with its
//! line.
//!
//! # Recording CSV (written by `ctr-cli hw run`)
//!
//! [`RecordingWriter`] writes [`recording_header`]:
//! `t_s,run,s1_mm,theta1_deg,...,s1_read_mm,theta1_read_deg,...,x_mm,y_mm,z_mm`: the
//! contract's recording (time in seconds, run label, the commanded joints, the tip) plus
//! the joints read back from the motors ([`JointId::read_column`]). `x_mm,y_mm,z_mm`
//! are left empty for the tracker. Each row is one `write` of the whole line and a flush
//! into a journal beside the recording ([`AtomicFile::journal`]) that becomes the
//! recording when the run ends (also on a fault): a run that stops leaves a valid CSV of
//! its completed rows, a killed one leaves them in the journal, and the recording's path
//! holds the previous file or a finished run's, never a part. An existing recording is
//! never replaced unless asked.
//!
//! # Parquet
//!
//! A joint, target, tip, IK or recording file named `*.parquet` ([`is_parquet`]) is
//! Parquet, with the CSV file's column names, checks and errors (the row, 1-based, and
//! the column): numbers from DOUBLE, FLOAT, INT32 or INT64 columns, the computed
//! columns written as DOUBLE and the input's other columns carried with their types
//! ([`ParquetOutput`], `data/FORMATS-EXTENSION.md`, "Parquet").
//!
//! # Files from spreadsheets and Windows editors
//!
//! Every reader (robot TOML, joint, target and recording CSV) skips a UTF-8 byte-order
//! mark at the start of the file (spreadsheets write one for "CSV UTF-8") and takes CRLF
//! line ends: such a file reads exactly as the plain one, with the same lines and
//! columns in errors.
//!
//! # Errors
//!
//! Every error is one line: `file[:line[:column]]: message` (see [`Error`]).
//! CSV lines count the header as line 1; TOML positions come from the parser's span or
//! point at the offending value.

mod actuation;
mod columnar;
mod csvout;
mod discrepancy;
mod effects;
mod empirical;
mod error;
mod joint_stream;
mod joints;
mod output;
pub mod parallel;
pub mod poses;
mod recorded;
mod recording;
mod records;
mod robot;
mod robot_file;
mod stream;
mod table;
mod targets;
mod tips;
mod toml_doc;

pub use columnar::{
    is_number_column, is_parquet, Batch, ColumnType, ParquetOutput, PARQUET_EXTENSION,
};
pub use error::{status_name, Error, ErrorKind, Location};
pub use robot::{canonical_quaternion, joint_columns, joints_of, AnyRobot, FkResult};

pub use actuation::{
    ActuatedJoint, ActuationProblem, ActuationSection, ActuatorKind, InvalidActuation, JointId,
    DEFAULT_TICKS_PER_REV, MAX_MOTOR_ID,
};
pub use discrepancy::{inputs_along_run, Discrepancy, DiscrepancyFile, Input, GAUSSIAN_PROCESS};
pub use effects::{
    Clearance, Effects, Friction, Gravity, JointOffset, Latency, Precurvature, Registration,
    SensorOffset, SensorRotation, Stiffness, CLEARANCE_FIT_TABLE_SIZES,
};
pub use empirical::{Correction, Empirical, EmpiricalTerm, Feature, Term, AXES};
pub use joint_stream::{JointParser, JointPiece, JointRows, JointStream};
pub use joints::JointTable;
pub use output::AtomicFile;
pub use poses::{Frames, Pose};
pub use recorded::{AngularColumns, AngularWeight, RecordedRow, Recording, Run, UNIT_TOLERANCE};
pub use recording::{recording_header, RecordingWriter, RECORDING_TIP_COLUMNS};
pub use robot_file::{
    LimitsSection, ModelKind, ModelSection, RobotFile, RobotSpec, TubeFile, TubeLimits,
    UnknownModelKind,
};
pub use targets::{
    ik_batch, ik_column_types, ik_columns, ik_output_columns, write_ik_row, IkOutputColumns, IkRow,
    IkTarget, TargetTable, ORIENTATION_COLUMNS, ORIENTATION_TOLERANCE_DEG,
    QUATERNION_NORM_TOLERANCE, TARGET_COLUMNS,
};
pub use tips::{
    format_float, tip_batch, tip_column_types, tip_header, tip_header_for, write_header,
    write_tip_row, write_tip_row_for, Carried, CarriedColumns, TipColumns, TipWriter,
    MARGIN_COLUMN, STATUS_COLUMNS, TIP_COLUMNS,
};

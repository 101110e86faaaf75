//! File formats: the robot TOML, the joint CSV, the tip CSV, atomic output.
//!
//! The contract is `shared/spec/formats.md`; everything it describes is read and written
//! as it says. This module adds two optional sections to the robot TOML (also described
//! in `data/FORMATS-EXTENSION.md`); files without them mean what they always meant.
//!
//! # Robot TOML
//!
//! Top-level keys: `name` (string, optional), `[[tube]]` (1 to 4 tables, outermost
//! first, keys exactly those of the contract plus an optional `name`), and the
//! extensions `[model]` and `[limits]`. Unknown keys anywhere are refused with the line
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
//! `[model.effects]` accepts only the contract's effect ids: `friction`, `clearance`,
//! `gravity`, `registration`, `joint_offset`, `stiffness`, `precurvature`, `latency`,
//! `sensor_offset` (`torsion` is `kind`). Each is a table. `gravity` is typed now
//! (`direction_W`, a unit vector in W, and `g_m_s2`, default 9.81); the other tables'
//! keys will be fixed when the core models them. Until the core models an effect, a
//! file that asks for it is refused with "the ... effect is not supported yet" rather
//! than solved without it. A fitted model is written back as a robot file with its
//! `[model]` ([`RobotSpec::to_toml`]).
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
//! # Errors
//!
//! Every error is one line: `file[:line[:column]]: message` (see [`crate::Error`]).
//! CSV lines count the header as line 1; TOML positions come from the parser's span or
//! point at the offending value.

mod joints;
mod output;
pub(crate) mod robot_file;
mod tips;

pub use joints::JointTable;
pub use output::AtomicFile;
pub use robot_file::{
    Effects, Gravity, LimitsSection, ModelKind, ModelSection, RobotFile, RobotSpec, TubeFile,
    TubeLimits,
};
pub use tips::{format_float, tip_header, TipWriter, STATUS_COLUMNS, TIP_COLUMNS};

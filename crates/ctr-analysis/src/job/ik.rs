//! The inverse-kinematics job ([`run_ik`]).

use super::{read_input, read_robot, Input, Output, Sink};
use crate::batch::{batch_ik, IkBatchOptions};
use crate::ik::{Ik, IkOptions, IkStatus};
use ctr_core::Model;
use ctr_formats::parallel::Progress;
use ctr_formats::{ik_output_columns, write_header, write_ik_row, IkRow, TargetTable};
use ctr_formats::{Error, ErrorKind, Location};

/// An inverse-kinematics job: what `ctr-cli ik` runs.
///
/// Order of work: read and validate the robot, build the solver (its limits and start
/// table), read and check every target row, check the output header, open the output,
/// solve ([`batch_ik`]: warm along the rows in fixed chunks, or cold), writing the
/// chunks in order as they are done, and rename the output into place. Every target
/// gets a row: an unreachable one the closest point found, with its status and
/// residual; the caller decides whether that is a failure.
#[derive(Clone, Debug, PartialEq)]
pub struct IkJob {
    /// The robot TOML (its `[limits]` bound the joints).
    pub robot: Input,
    /// The target CSV.
    pub targets: Input,
    /// The joint CSV to write.
    pub output: Output,
    /// Overrides the robot file's `[model] kind`.
    pub model: Option<Model>,
    /// Solver settings.
    pub options: IkOptions,
    /// Read `qw,qx,qy,qz` as ordinary columns (position targets only).
    pub position_only: bool,
    /// Warm start along the rows (`true`) or solve every target cold.
    pub warm: bool,
    /// Rows per warm-started chunk ([`batch_ik`]); 0: the whole file is one chunk.
    pub chunk_rows: usize,
    /// Worker threads, 0 = all cores (the output does not depend on it).
    pub threads: usize,
}

/// A target that was not reached.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IkRowFailure {
    /// 1-based line in the target file.
    pub line: usize,
    /// How the solve ended.
    pub status: IkStatus,
    /// Distance from the closest point found to the target, mm.
    pub residual_mm: f64,
    /// Angle to the target orientation, rad (pose targets).
    pub orientation_residual_rad: Option<f64>,
}

/// What a finished IK job did.
#[derive(Clone, Debug, PartialEq)]
pub struct IkSummary {
    /// The target file's name as used in messages.
    pub targets_file: String,
    /// Rows solved (all written).
    pub rows: usize,
    /// Targets not reached, in input order.
    pub not_reached: Vec<IkRowFailure>,
}

/// Runs an IK job; see [`IkJob`] for the order of work.
pub fn run_ik(job: &IkJob, progress: &dyn Progress) -> Result<IkSummary, Error> {
    let (robot_name, spec) = {
        let name = match &job.robot {
            Input::Stdin => "<stdin>".to_owned(),
            Input::Path(p) => p.display().to_string(),
        };
        (name, read_robot(&job.robot)?)
    };
    let model = job.model.unwrap_or(spec.model);
    let ik = Ik::for_spec(&spec, model, job.options)
        .map_err(|e| Error::new(Location::file(&robot_name), ErrorKind::Ik(Box::new(e))))?;
    let table = {
        let (name, bytes) = read_input(&job.targets)?;
        TargetTable::from_bytes(bytes, &name, job.position_only, job.threads)?
    };
    let pose = table.has_orientation();
    let columns = ik_output_columns(table.header(), spec.robot.n_tubes(), pose);
    let mut sink = Sink::open(&job.output)?;
    let mut head = Vec::new();
    write_header(&mut head, &columns.header);
    sink.write(&head)?;
    let targets = table.targets();
    let options = IkBatchOptions {
        threads: job.threads,
        chunk_rows: if job.chunk_rows == 0 {
            targets.len().max(1)
        } else {
            job.chunk_rows
        },
        warm: job.warm,
    };
    let mut not_reached = Vec::new();
    let mut failed = None;
    let mut text = Vec::new();
    batch_ik(&ik, &targets, &options, progress, |range, results| {
        text.clear();
        for (row, r) in range.zip(&results) {
            if r.status != IkStatus::Reached {
                not_reached.push(IkRowFailure {
                    line: table.line(row),
                    status: r.status,
                    residual_mm: r.residual_mm,
                    orientation_residual_rad: r.orientation_residual_rad,
                });
            }
            let joints = ik.to_file_units(&r.q);
            let out = IkRow {
                joints: &joints,
                tip: &r.tip,
                residual_mm: r.residual_mm,
                orientation_residual_rad: r.orientation_residual_rad,
                status: r.status.name(),
            };
            write_ik_row(&mut text, table.carried(row, &columns.carried), &out, pose);
        }
        sink.write_or_stop(&text, &mut failed)
    });
    if let Some(e) = failed {
        return Err(e);
    }
    sink.commit()?;
    Ok(IkSummary {
        targets_file: table.file().to_owned(),
        rows: table.len(),
        not_reached,
    })
}

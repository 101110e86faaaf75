//! The inverse-kinematics job ([`run_ik`]).

use super::{input_name, read_input, read_robot, Input, Output, Sink};
use crate::batch::{batch_ik, IkBatchOptions};
use crate::ik::{Ik, IkOptions, IkStatus};
use ctr_core::Model;
use ctr_formats::parallel::Progress;
use ctr_formats::{ik_batch, ik_column_types, is_parquet, Batch, IkOutputColumns, ParquetOutput};
use ctr_formats::{ik_output_columns, write_header, write_ik_row, IkRow, TargetTable};
use ctr_formats::{Error, ErrorKind, Location};
use std::ops::Range;

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
    /// The `line`s above are 1-based rows of a Parquet target file, not lines.
    pub lines_are_rows: bool,
}

/// Runs an IK job; see [`IkJob`] for the order of work.
pub fn run_ik(job: &IkJob, progress: &dyn Progress) -> Result<IkSummary, Error> {
    let robot_name = input_name(&job.robot);
    let spec = read_robot(&job.robot)?;
    let model = job.model.unwrap_or(spec.model);
    let ik = Ik::for_spec(&spec, model, job.options)
        .map_err(|e| Error::new(Location::file(&robot_name), ErrorKind::Ik(Box::new(e))))?;
    let table = read_targets(job)?;
    let pose = table.has_orientation();
    let columns = ik_output_columns(table.header(), spec.robot.n_tubes(), pose);
    let mut out = IkOut::open(&job.output, &table, &columns, spec.robot.n_tubes(), pose)?;
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
    batch_ik(&ik, &targets, &options, progress, |range, results| {
        let joints: Vec<Vec<f64>> = results.iter().map(|r| ik.to_file_units(&r.q)).collect();
        let mut rows = Vec::with_capacity(results.len());
        for ((row, r), joints) in range.clone().zip(&results).zip(&joints) {
            if r.status != IkStatus::Reached {
                not_reached.push(IkRowFailure {
                    line: table.line(row),
                    status: r.status,
                    residual_mm: r.residual_mm,
                    orientation_residual_rad: r.orientation_residual_rad,
                });
            }
            rows.push(IkRow {
                joints,
                tip: &r.tip,
                residual_mm: r.residual_mm,
                orientation_residual_rad: r.orientation_residual_rad,
                status: r.status.name(),
            });
        }
        match out.write(&table, &columns.carried, range, &rows, pose) {
            Ok(()) => true,
            Err(e) => {
                failed = Some(e);
                false
            }
        }
    });
    if let Some(e) = failed {
        return Err(e);
    }
    out.commit()?;
    Ok(IkSummary {
        targets_file: table.file().to_owned(),
        rows: table.len(),
        not_reached,
        lines_are_rows: table.is_rows(),
    })
}

/// Reads and checks every target: a Parquet file by name (`*.parquet`) or by its
/// bytes, else CSV (parsed on the job's threads).
fn read_targets(job: &IkJob) -> Result<TargetTable, Error> {
    match &job.targets {
        Input::Path(p) if is_parquet(p) => TargetTable::from_path(p, job.position_only),
        input => {
            let (name, bytes) = read_input(input)?;
            TargetTable::from_bytes(bytes, &name, job.position_only, job.threads)
        }
    }
}

/// Where an IK job's rows go: CSV (a file or standard output) or a Parquet file, with
/// the input's carried columns of every row.
enum IkOut {
    Csv(Sink),
    Parquet(Box<ParquetOutput>, Batch),
}

impl IkOut {
    /// Opens the output (a CSV file gets its header).
    fn open(
        output: &Output,
        table: &TargetTable,
        columns: &IkOutputColumns,
        n_tubes: usize,
        pose: bool,
    ) -> Result<Self, Error> {
        if let Output::Path(p) = output {
            if is_parquet(p) {
                let (mut types, carried) = table.carried_columns(&columns.carried)?;
                types.extend(ik_column_types(n_tubes, pose));
                return Ok(IkOut::Parquet(
                    Box::new(ParquetOutput::create(p, types)?),
                    carried,
                ));
            }
        }
        let mut sink = Sink::open(output)?;
        let mut head = Vec::new();
        write_header(&mut head, &columns.header);
        sink.write(&head)?;
        Ok(IkOut::Csv(sink))
    }

    /// Writes the rows `range` of the targets, solved as `rows`.
    fn write(
        &mut self,
        table: &TargetTable,
        keep: &[usize],
        range: Range<usize>,
        rows: &[IkRow<'_>],
        pose: bool,
    ) -> Result<(), Error> {
        match self {
            IkOut::Csv(sink) => {
                let mut text = Vec::new();
                for (row, r) in range.zip(rows) {
                    write_ik_row(&mut text, table.carried(row, keep), r, pose);
                }
                sink.write(&text)
            }
            IkOut::Parquet(out, carried) => {
                let mut batch = carried.rows(range);
                batch.append(ik_batch(rows, pose));
                out.write(batch)
            }
        }
    }

    fn commit(self) -> Result<(), Error> {
        match self {
            IkOut::Csv(sink) => sink.commit(),
            IkOut::Parquet(out, _) => out.commit(),
        }
    }
}
